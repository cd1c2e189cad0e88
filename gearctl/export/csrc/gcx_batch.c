/* SPDX-License-Identifier: MIT -- part of gearctl, written for it. */
/*
 * The compiled batch loop (issue 15): gearctl's closed loop (gearctl/closedloop.py: simulate_closed_loop)
 * in C, for the controllers of the PID family. Per sample, exactly as the Python loop: the encoders read
 * the state (noise drawn beforehand in Python with the same generator calls, then quantised as
 * Encoder.read), the controller's C step (gcx_pid.c) gives the command, the torque limit clips it, and the
 * kernel's own gc_step (called through the pointer the kernel's library exports, so it is the very code
 * Kernel.advance runs) advances the plant over the sample; the divergence test follows.
 *
 * The loop returns to Python only when the kernel asks for it (a pattern to build, a full event buffer, or
 * events to drain: Kernel.advance's continuation), then resumes where it stopped; and at the end.
 *
 * The gc_params / gc_state structs (gearctl/kernel.py: c_structs) precede this text, and so do the
 * controller family's parameter structs, state structs and functions.
 */

typedef int (*gcx_kernel_step)(const gc_params *p, gc_state *st);

/* the reference (gearctl/references.py: Reference._scalar, move_point), for gearctl's Reference objects */
typedef struct {
    int kind; /* 0 sine, 1 step, 2 ramp, 3 move */
    int trapezoid;
    double amplitude, frequency, start, rate, accel, disturbance_time, disturbance;
    double ta, tc, v; /* move_times(|amplitude|, rate, accel, profile) */
} gcx_ref_p;

/* the loop's data and outputs (gearctl/export/batch.py fills it) */
typedef struct {
    int64_t n;     /* samples to run */
    int64_t i;     /* the sample being run (resumable) */
    int64_t phase; /* 0: sample i not started; 1: its kernel call returned to Python, which finished it */
    int64_t pending; /* with phase 1: the status Python's continuation gave */
    int64_t last;  /* samples completed */
    int64_t status; /* the kernel's status that ended the run (0: none) */
    int64_t diverged; /* the run ended by the divergence test */
    int64_t use_load, nx, w, ns, kind;
    double Ts, lim, load_torque, div_limit;
    double q_m, q_l, noise_m, noise_l; /* quanta (0: none), noise std [rad] */
    const double *z;   /* standard normals, k_per per sample */
    int64_t k_per, zi_l; /* normals per sample; index of the load's within a sample (-1: none) */
    const gcx_ref_p *ref; /* or NULL: rows[] holds ref.at(t_i) per sample */
    const double *rows;
    double *xs;   /* (n + 1) x nx */
    int32_t *modes; /* (n + 1) x ns */
    double *u, *cmd, *ym, *yl;
} gcx_loop;

static void gcx_move_point(const gcx_ref_p *R, double tau, double distance, double out[3]) {
    double ta = R->ta, tc = R->tc, v = R->v;
    double T = 2 * ta + tc;
    if (tau <= 0.0 || T == 0.0) {
        out[0] = tau <= 0.0 ? 0.0 : distance, out[1] = 0.0, out[2] = 0.0;
        return;
    }
    if (tau >= T) {
        out[0] = distance, out[1] = 0.0, out[2] = 0.0;
        return;
    }
    double u, sgn_p = 1.0;
    if (tau <= ta) {
        u = tau;
    } else if (tau <= ta + tc) {
        out[0] = v * ta / 2 + v * (tau - ta), out[1] = v, out[2] = 0.0;
        return;
    } else {
        u = T - tau;
        sgn_p = -1.0;
    }
    double p, dp, ddp;
    if (R->trapezoid) {
        double a = v / ta;
        p = 0.5 * a * u * u, dp = a * u, ddp = a;
    } else {
        double w = 2 * GCX_PI / ta;
        p = (v / ta) * (u * u / 2 + (cos(w * u) - 1) / (w * w));
        dp = (v / ta) * (u - sin(w * u) / w);
        ddp = (v / ta) * (1 - cos(w * u));
    }
    if (sgn_p > 0.0) {
        out[0] = p, out[1] = dp, out[2] = ddp;
    } else {
        out[0] = distance - p, out[1] = dp, out[2] = -ddp;
    }
}

static void gcx_ref_at(const gcx_ref_p *R, double t, double out[3]) {
    if (R->kind == 0) {
        double w = 2 * GCX_PI * R->frequency;
        double a = R->amplitude;
        double sn = sin(w * t), cs = cos(w * t);
        out[0] = a * sn, out[1] = a * w * cs, out[2] = -a * w * w * sn;
        return;
    }
    if (R->kind == 1) {
        out[0] = t >= R->start ? R->amplitude : 0.0, out[1] = 0.0, out[2] = 0.0;
        return;
    }
    double tau = t - R->start;
    double sgn = copysign(1.0, R->amplitude);
    if (tau < 0) {
        out[0] = out[1] = out[2] = 0.0;
        return;
    }
    if (R->kind == 2) {
        double T = fabs(R->amplitude) / R->rate;
        out[0] = sgn * R->rate * gcx_min(tau, T), out[1] = tau < T ? sgn * R->rate : 0.0, out[2] = 0.0;
        return;
    }
    double m[3];
    gcx_move_point(R, tau, fabs(R->amplitude), m);
    out[0] = sgn * m[0], out[1] = sgn * m[1], out[2] = sgn * m[2];
}

/* Encoder.read */
static double gcx_encoder(double angle, double noise, double z, double q) {
    if (noise > 0.0) angle += noise * z;
    if (q > 0.0) angle = q * floor(angle / q + 0.5);
    return angle;
}

/* the controller kinds of the runtime library */
typedef struct {
    int64_t k;
    union {
        gcx_pid_s pid;
        gcx_rev_s rev;
        gcx_inv_s inv;
    } s;
} gcx_any_s;

long gcx_runtime_state_size(void) { return (long)sizeof(gcx_any_s); }

void gcx_runtime_init(int kind, const void *P, gcx_any_s *S) {
    memset(S, 0, sizeof *S);
    if (kind == 1) gcx_pid_init((const gcx_pid_p *)P, &S->s.pid);
    if (kind == 2) gcx_rev_init((const gcx_rev_p *)P, &S->s.rev);
    if (kind == 3) gcx_inv_init((const gcx_inv_p *)P, &S->s.inv);
}

int gcx_runtime_step(int kind, const void *P, gcx_any_s *S, const double y[2], const double *ref, double *u) {
    int flag = 0;
    if (kind == 1) flag = gcx_pid_run((const gcx_pid_p *)P, &S->s.pid, S->k, y, ref, u);
    if (kind == 2) flag = gcx_rev_run((const gcx_rev_p *)P, &S->s.rev, S->k, y, ref, u);
    if (kind == 3) flag = gcx_inv_run((const gcx_inv_p *)P, &S->s.inv, S->k, y, ref, u);
    S->k++;
    return flag;
}

/* the divergence test of simulate_closed_loop (Python's max over |omega|, then the NaN test on omega_0) */
static int gcx_diverged(const gcx_loop *L, const double *x) {
    double m = fabs(x[L->w]);
    for (int64_t j = L->w + 1; j < L->nx; j++)
        if (fabs(x[j]) > m) m = fabs(x[j]);
    return m >= L->div_limit || x[L->w] != x[L->w];
}

/* Run (or resume) the loop. Returns 0 when it ended (L->last samples done; L->status / L->diverged say
 * why it stopped early), 1 when the kernel's call of sample L->i needs Python (Kernel.advance's
 * continuation: drain events, build a pattern, call again); Python then sets L->pending and calls again. */
int gcx_batch_run(gcx_kernel_step kstep, const gc_params *p, gc_state *st, gcx_loop *L, const void *cp,
                  gcx_any_s *cs) {
    const int64_t nx = L->nx, ns = L->ns;
    for (; L->i < L->n; L->i++) {
        int64_t i = L->i;
        int status;
        if (L->phase == 0) {
            const double *x = L->xs + i * nx;
            double ti = (double)i * L->Ts;
            const double *z = L->z + i * L->k_per;
            double y[2];
            y[0] = gcx_encoder(x[0], L->noise_m, L->noise_m > 0.0 ? z[0] : 0.0, L->q_m);
            y[1] = L->use_load ? gcx_encoder(x[L->w - 1], L->noise_l, L->zi_l >= 0 ? z[L->zi_l] : 0.0, L->q_l) : (double)NAN;
            double row[3];
            const double *ref = row;
            if (L->ref)
                gcx_ref_at(L->ref, ti, row);
            else
                ref = L->rows + 3 * i;
            double c = 0.0;
            gcx_runtime_step((int)L->kind, cp, cs, y, ref, &c);
            double ui;
            if (isfinite(c))
                ui = (-L->lim <= c && c <= L->lim) ? c : copysign(L->lim, c);
            else /* Python records the fallback from cmd afterwards */
                ui = 0.0;
            L->ym[i] = y[0], L->yl[i] = y[1], L->cmd[i] = c, L->u[i] = ui;
            double dist = 0.0;
            if (L->ref) dist = ti >= L->ref->disturbance_time ? L->ref->disturbance : 0.0;
            else dist = L->rows[3 * L->n + i]; /* the disturbance column after the rows */
            st->u1 = ui, st->u2 = L->load_torque + dist;
            st->t_end = st->t + L->Ts;
            status = kstep(p, st);
            if (status != 0 || st->n_events != 0) {
                L->phase = 1;
                L->pending = status;
                return 1;
            }
        } else {
            status = (int)L->pending;
            L->phase = 0;
        }
        double *xn = L->xs + (i + 1) * nx;
        memcpy(xn, st->x, sizeof(double) * (size_t)nx);
        for (int64_t j = 0; j < ns; j++) L->modes[(i + 1) * ns + j] = st->mode[j];
        L->last = i + 1;
        if (status != 0) {
            L->status = status;
            L->i++;
            return 0;
        }
        if (gcx_diverged(L, xn)) {
            L->diverged = 1;
            L->i++;
            return 0;
        }
    }
    return 0;
}
