
#ifdef GCX_MPC_N
#define GCX_FAULT_RESTARTS 3 /* mpc.py: _FAULT_RESTARTS */
/* backlash-aware MPC (gearctl/design/mpc.py: MPC): observer, plan, flank schedule, the QP's buffers */
typedef struct {
    double z[5];            /* observer [phi, omega, s, v, d] */
    double u;               /* last torque [N m] */
    double plan[GCX_MPC_N]; /* last plan (torques) */
    double x0[GCX_MPC_N];   /* the plan shifted: the fallback */
    double p[GCX_MPC_NP];   /* parameter vector */
    double v_land_now;      /* landing-speed bound of the step being solved */
    double flanks[2], reach[2]; /* the flanks learned from the gap, the furthest it has been [m] */
    int revisits[2];
    double stall[2], base[2]; /* where a landing stalled (0: none), the flanks without the stalls [m] */
    int overdue;            /* samples in a row a landing has been due and the gap still floats */
    double f1;              /* the motor's Coulomb friction the last step planned with [N m] */
    double f2;              /* the load's Coulomb friction the observer predicts the next sample with [N m] */
    double dir;             /* the direction of the reference's last motion (0 before any) */
    int z_set, flank, land, has_land;
    int held;               /* holding at standstill (MPC._held) */
    int rejects;            /* samples in a row whose readings the gate rejected */
    double gate[2];         /* the readings' gate on the motor and the load shaft [rad] */
    double inn[2];          /* the last accepted readings' innovations, motor and load [rad] */
    double gap_inn[2];      /* the floating gap's last two innovations, the latest first [m] (0 in contact) */
    double gap_s[2];        /* the floating gap's last two readings, the latest first [m] */
    int gap_s_n;            /* how many of them there are since contact (0..2; Python: NaN for a missing one) */
    int64_t n_obs;          /* samples observed (MPC._n_obs) */
    int64_t k_run;          /* the sample after the last step that ran (MPC._k_run; missed samples do not run) */
    int64_t restarts[GCX_FAULT_RESTARTS]; /* the samples of the last restarts of the estimate */
    int fault;              /* latched: the motor braked, then zero torque (MPC.fault) */
    double brake_y, brake_dy, brake_w; /* after a fault: last motor reading, its step, the speed (MPC._brake) */
    int64_t brake_k;        /* the sample of the last motor reading's change */
    int gov_set, gov_on;    /* the reference governor (MPC._gov): started; on the reference */
    double gov_g, gov_w;    /* ... the governed angle [rad] and speed [rad/s] at the step's sample */
    double gref[3 * (GCX_MPC_N + 1)]; /* the governed reference over the preview, laid out as the step's ref */
    /* QP buffers */
    double g[GCX_MPC_N], lbx[GCX_MPC_N], ubx[GCX_MPC_N], lba[GCX_MPC_N + 2], uba[GCX_MPC_N + 2];
    double x[GCX_MPC_N], lam_x[GCX_MPC_N], lam_a[GCX_MPC_N + 2], cost;
    double keep_x[GCX_MPC_N];                /* a solution set aside while another is tried */
    double factor[GCX_MPC_N * GCX_MPC_N];    /* the pattern's Hessian factor, unpacked */
    double rows[(GCX_MPC_N + 2) * GCX_MPC_N]; /* the pattern's rows for the back flank (sign-flipped) */
    int factor_q, rows_q;                    /* which pattern they hold (-1: none) */
    int8_t active[2 * GCX_MPC_N + 2];
    double work[GCX_MPC_WORK]; /* the QP solver's workspace */
} gcx_mpc_s;
#endif
