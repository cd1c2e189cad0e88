/* State of gearctl's exported controllers (all of it: a controller is one such struct, statically
 * allocatable, with nothing else kept anywhere). Fields mirror the Python objects' attributes; read them
 * for diagnostics if you like, never write them (gearctl_ctrl_init sets them). */

/* PID (gearctl/design/pid.py): integrator, filtered measurement, last reference acceleration */
typedef struct {
    double integral, y_filtered, v_filtered, dy, rdd_prev, integral_moving;
    int yf_set, vf_set, rdd_set; /* 0 until the first sample (Python: None) */
    int moving;
    /* not in Python, which misses no sample: samples the C API missed (bad input) before this one, and the last
     * measurement and reference speed the filters took, to carry them over the gap (gcx_pid_gap) */
    double gap, y_last, v_last;
} gcx_pid_s;

/* an offset moving between values along a ramp (deadzone.py: OffsetRamp) [rad, s] */
typedef struct {
    double o0, o1, t0, T, span;
} gcx_ramp_s;

/* load-disturbance observer (deadzone.py: LoadObserver): [theta, omega, d] */
typedef struct {
    double x[3];
    int set; /* 0 until the first update (Python: x is None) */
} gcx_obs_s;

/* reversal offset (reversal.py) */
typedef struct {
    gcx_pid_s pid;
    gcx_ramp_s ramp;
    double r_prev;
    int dir, has_prev;
} gcx_rev_s;

/* dead-zone inverse (deadzone.py) */
typedef struct {
    gcx_pid_s pid;
    gcx_ramp_s ramp;
    gcx_obs_s obs;
    double backlash, offset, sigma, t, cross_end, free[2], lag[4];
    double y_hist[2], u_hist[2], rattle, reach;
    double rdd_prev; /* |r''| of the last step (_one_way) */
    double crossing_time; /* set_crossing_time: the crossing time and ramp shape now (init: the parameters') */
    double jump_threshold; /* set_backlash: the rattle guard's motor speed jump, b / jump_den */
    double motor_free[2], motor_free_since; /* the free motor's predicted angle and speed; the crossing's start */
    int motor_free_set, motor_free_new, motor_free_anchor; /* predicted; its start torque yet to act; not re-anchored */
    int ramp_shape;
    int was_free, moving_ref, has_lag, contacts, free_load_exits, y_hist_n, rattling, trusted;
    int stopped, one_way_prev; /* at rest with the push-back withheld; withheld at the last step (_one_way) */
    double press_t, press_y; /* since when, and from where, the motor at rest presses the other flank */
    int press_set;           /* (_presses_other_flank) */
    double lead[2]; /* the lead the load would take on the driving flank, free, and its speed (_braking_needed) */
} gcx_inv_s;

#ifdef GCX_ADA_WINDOW
/* adaptive inverse (adaptive.py): the inverse, the estimate and the window of s */
typedef struct {
    gcx_inv_s inv;
    double b, u;
    int head, len, count, fresh;
    double flank;     /* the inverse's held flank at the last sample (0: centred, no decision yet) */
    int since_change; /* samples since the inverse changed flank, at most the window */
    int converged, agree; /* the estimate counts as converged; consecutive measurements that agree with it */
    double recent[GCX_ADA_WINDOW];
} gcx_ada_s;
#endif
