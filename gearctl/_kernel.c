/* gearctl simulation kernel: the gear pair advanced over one interval of constant torque, with every
 * contact-mode switch located exactly. Compiled on first use by gearctl/kernel.py; gearctl/kernel.py
 * also holds a pure-Python mirror of the same algorithm (the fallback and the test oracle).
 *
 * Two solvers:
 *  - gc_advance_pwl: the improved plant is affine inside each contact mode, x' = A x + a, so between
 *    events its solution is exact (matrix exponential). Full sub-steps use precomputed Phi(h), Gamma(h);
 *    partial steps and event roots use the Taylor series of the same exact solution, summed to 1e-17.
 *  - gc_advance_ode: Yang-Sun, time-varying stiffness and Coulomb friction are nonlinear: Dormand-Prince
 *    5(4) with error control and its 4th-order dense output; events located on the dense output.
 *
 * Modes: -2 back contact without load (no_pull), -1 back contact, 0 separation, 1 front contact,
 *        2 front contact without load (no_pull). State x = [theta1, theta2, omega1, omega2].
 */
#include <math.h>
#include <string.h>

#define EV_IMPACT 1
#define EV_SEPARATION 2
#define EV_LIFT 3
#define EV_RELOAD 4
#define EV_PLASTIC 5

#define ST_OK 0
#define ST_NAN 2
#define ST_EVENTS 3
#define ST_STEP 4
#define ST_BUFFER 5 /* the event buffer is full: the state stops at the last event; call again */

typedef struct {
    double J1, J2, rb1, rb2, b, k, c, d1, d2, tc1, tc2, ws;
    double mesh_period, mesh_phase;
    double zeno_v;
    double rtol, atol_angle, atol_rate, h_max;
    /* piecewise-linear data, index 0: contact dynamics, 1: free dynamics */
    double A[2][16], Phi[2][16], Gam[2][16], h[2], rho[2];
    const double *table;
    long n_table;
    long max_events;
    int law;  /* 0 linear, 1 no_pull */
    int kind; /* 0 improved, 1 yang-sun, 2 tvms */
} gc_params;

typedef struct {
    double t;
    double v; /* relative velocity along the line of action at the event [m/s] */
    long kind;
    long side;
} gc_event;

typedef struct {
    double x[4];
    double t;
    double d_ys;    /* Yang-Sun damping factor of the current contact [N s/m^2] */
    double h_ode;   /* last accepted ODE step [s] */
    double max_pen; /* largest |s| - b seen [m] */
    long n_events;  /* events located in the last call (may exceed the buffer) */
    long n_steps;   /* sub-steps taken in total */
    int mode;
    /* inputs of gc_step (one call per controller sample with two pointer arguments: cheap from ctypes) */
    double u1, u2, T;
    gc_event *ev;
    long cap;
} gc_state;

/* ---------------------------------------------------------------- shared helpers */

static inline double s_of(const gc_params *p, const double *x) { return p->rb1 * x[0] - p->rb2 * x[1]; }
static inline double v_of(const gc_params *p, const double *x) { return p->rb1 * x[2] - p->rb2 * x[3]; }

static inline int sgn_mode(int mode) { return mode > 0 ? 1 : (mode < 0 ? -1 : 0); }
static inline int loaded(int mode) { return mode == 1 || mode == -1; }

static void record(gc_state *st, gc_event *ev, long cap, double t, long kind, long side, double v) {
    if (st->n_events < cap) {
        ev[st->n_events].t = t;
        ev[st->n_events].kind = kind;
        ev[st->n_events].side = side;
        ev[st->n_events].v = v;
    }
    st->n_events++;
}

/* Remove the relative velocity along the line of action (perfectly plastic impact), conserving the
 * angular impulse balance J1 dw1 = -rb1 P, J2 dw2 = rb2 P. */
static void plastic(const gc_params *p, double *x) {
    double v = v_of(p, x);
    double inv_m = p->rb1 * p->rb1 / p->J1 + p->rb2 * p->rb2 / p->J2;
    double P = v / inv_m;
    x[2] -= p->rb1 * P / p->J1;
    x[3] += p->rb2 * P / p->J2;
}

/* Event functions of a mode, each positive inside the mode; returns how many (<= 2).
 * g = cg . x + g0; target[i] is the mode entered when g[i] reaches zero. */
static int event_functions(const gc_params *p, int mode, double cg[2][4], double g0[2], int target[2]) {
    double sv[4] = {p->rb1, -p->rb2, 0.0, 0.0}, vv[4] = {0.0, 0.0, p->rb1, -p->rb2};
    int n = 0, i;
    double kk = p->k, cc = p->c;
    int no_pull = p->law == 1;
    switch (mode) {
    case 0: /* separation: b - s > 0 and s + b > 0 */
        for (i = 0; i < 4; i++) { cg[0][i] = -sv[i]; cg[1][i] = sv[i]; }
        g0[0] = p->b; g0[1] = p->b; target[0] = 1; target[1] = -1; n = 2;
        break;
    case 1: case 2: /* front: s - b > 0; loaded F > 0 / unloaded -F > 0 */
        for (i = 0; i < 4; i++) cg[0][i] = sv[i];
        g0[0] = -p->b; target[0] = 0; n = 1;
        if (no_pull) {
            double sg = mode == 1 ? 1.0 : -1.0;
            for (i = 0; i < 4; i++) cg[1][i] = sg * (kk * sv[i] + cc * vv[i]);
            g0[1] = -sg * kk * p->b; target[1] = mode == 1 ? 2 : 1; n = 2;
        }
        break;
    case -1: case -2: /* back: -s - b > 0; loaded F_B = k(-s-b) - c v > 0 */
        for (i = 0; i < 4; i++) cg[0][i] = -sv[i];
        g0[0] = -p->b; target[0] = 0; n = 1;
        if (no_pull) {
            double sg = mode == -1 ? 1.0 : -1.0;
            for (i = 0; i < 4; i++) cg[1][i] = -sg * (kk * sv[i] + cc * vv[i]);
            g0[1] = -sg * kk * p->b; target[1] = mode == -1 ? -2 : -1; n = 2;
        }
        break;
    }
    return n;
}

/* Mode entered after crossing boundary `target` from `mode` at state x; records the event.
 * Handles b = 0 (no gap: straight from one flank to the other) and the Zeno rule. */
static int transition(const gc_params *p, gc_state *st, gc_event *ev, long cap, int mode, int target,
                      double *x, double t) {
    double v = v_of(p, x);
    int side = sgn_mode(mode != 0 ? mode : target);
    if (target == 0) {
        if (p->b > 0.0 || p->k <= 0.0) {
            record(st, ev, cap, t, EV_SEPARATION, side, v);
            return 0;
        }
        /* b = 0: no gap, the other flank takes over at once (not an impact) */
        if (p->law == 1) {
            double fb = -side * (p->k * s_of(p, x) + p->c * v); /* force of the other flank */
            return fb > 0.0 ? -side : -2 * side;
        }
        return -side;
    }
    if (mode == 0) { /* separation -> contact: an impact */
        if (fabs(v) < p->zeno_v) {
            plastic(p, x);
            record(st, ev, cap, t, EV_PLASTIC, side, v);
        } else {
            record(st, ev, cap, t, EV_IMPACT, side, v);
        }
        return target;
    }
    record(st, ev, cap, t, loaded(target) ? EV_RELOAD : EV_LIFT, side, v);
    return target;
}

/* ---------------------------------------------------------------- piecewise-linear exact solver */

static inline void matvec4(const double *M, const double *x, double *y) {
    for (int i = 0; i < 4; i++)
        y[i] = M[4 * i] * x[0] + M[4 * i + 1] * x[1] + M[4 * i + 2] * x[2] + M[4 * i + 3] * x[3];
}

/* affine term a = B u + e of mode's dynamics */
static void affine(const gc_params *p, int mode, double u1, double u2, double *a) {
    a[0] = 0.0;
    a[1] = 0.0;
    a[2] = u1 / p->J1;
    a[3] = u2 / p->J2;
    if (loaded(mode)) { /* F = k (s - sigma b) + c v: the constant part -k sigma b */
        double sigma = (double)mode;
        a[2] += p->rb1 * p->k * sigma * p->b / p->J1;
        a[3] -= p->rb2 * p->k * sigma * p->b / p->J2;
    }
}

#define NTAY 48
/* Taylor coefficient vectors D[n] = x^(n)(0) / n! of x' = A x + a from x0, enough terms for |tau| <= tmax */
static int taylor(const double *A, double rho, const double *x0, const double *a, double tmax,
                  double D[NTAY][4]) {
    int n, i;
    double tmp[4];
    memcpy(D[0], x0, sizeof(double) * 4);
    matvec4(A, x0, tmp);
    for (i = 0; i < 4; i++) D[1][i] = tmp[i] + a[i];
    double bound = rho * tmax, term = bound;
    for (n = 2; n < NTAY; n++) {
        matvec4(A, D[n - 1], tmp);
        for (i = 0; i < 4; i++) D[n][i] = tmp[i] / n;
        term *= bound / n;
        if (term < 1e-18 && n >= 4) return n + 1;
    }
    return NTAY;
}

static void taylor_eval(double D[NTAY][4], int nt, double tau, double *x) {
    for (int i = 0; i < 4; i++) {
        double acc = D[nt - 1][i];
        for (int n = nt - 2; n >= 0; n--) acc = acc * tau + D[n][i];
        x[i] = acc;
    }
}

/* value and derivative of the scalar polynomial sum q[n] tau^n */
static inline void poly_eval(const double *q, int nt, double tau, double *f, double *df) {
    double acc = q[nt - 1], dacc = 0.0;
    for (int n = nt - 2; n >= 0; n--) {
        dacc = dacc * tau + acc;
        acc = acc * tau + q[n];
    }
    *f = acc;
    *df = dacc;
}

/* Root of q in [lo, hi] with q(lo) > 0 >= q(hi): safeguarded Newton; returns a point with q <= 0
 * (just past the crossing) within a few ulps of the root. */
static double poly_root(const double *q, int nt, double lo, double hi) {
    double f, df, x = 0.5 * (lo + hi);
    for (int it = 0; it < 100; it++) {
        poly_eval(q, nt, x, &f, &df);
        if (f > 0.0) lo = x; else hi = x;
        double xn = (df != 0.0) ? x - f / df : 0.5 * (lo + hi);
        if (!(xn > lo && xn < hi)) xn = 0.5 * (lo + hi);
        if (hi - lo <= 4e-16 * fabs(hi) + 1e-300 || xn == x) break;
        x = xn;
    }
    return hi;
}

/* Earliest time in [0, h] at which g (q[0] = g(0) >= 0) reaches zero, or -1. q: Taylor polynomial of g;
 * g1, dg0, dg1: g(h), g'(0), g'(h) from the exact step. With rho h <= 0.6, g has at most one minimum in
 * the step: a sign change at the end, or a minimum (g' from - to +) at or below zero, is a crossing. */
static double first_root(const double *q, int nt, double h, double g1, double dg0, double dg1) {
    if (dg0 < 0.0 && dg1 > 0.0) {
        double dq[NTAY], lo = 0.0, hi = h, f, df, gm;
        int m = nt - 1;
        for (int n = 0; n < m; n++) dq[n] = (n + 1) * q[n + 1];
        for (int it = 0; it < 200 && hi - lo > 1e-15 * h; it++) { /* q' < 0 at lo, >= 0 at hi */
            double x = 0.5 * (lo + hi);
            poly_eval(dq, m, x, &f, &df);
            if (f < 0.0) lo = x; else hi = x;
        }
        poly_eval(q, nt, hi, &gm, &df);
        if (gm <= 0.0) return poly_root(q, nt, 0.0, hi);
        return g1 <= 0.0 ? poly_root(q, nt, hi, h) : -1.0;
    }
    return g1 <= 0.0 ? poly_root(q, nt, 0.0, h) : -1.0;
}

int gc_advance_pwl(const gc_params *p, gc_state *st, double u1, double u2, double T, gc_event *ev,
                   long cap) {
    double t_end = st->t + T;
    st->n_events = 0;
    long guard = 0;
    /* per mode and call: the affine term a, Gamma(h) a, and x' carried from step to step (x'(h) = Phi x'(0)) */
    int cached_mode = 99, have_dx = 0;
    double a[4], gam_a[4], dx0[4], dx1[4];
    while (st->t < t_end) {
        int mode = st->mode;
        int dyn = loaded(mode) ? 0 : 1;
        const double *A = p->A[dyn];
        double x0[4], x1[4];
        double D[NTAY][4];
        int nt = 0, i;
        if (mode != cached_mode) {
            affine(p, mode, u1, u2, a);
            matvec4(p->Gam[dyn], a, gam_a);
            cached_mode = mode;
            have_dx = 0;
        }
        memcpy(x0, st->x, sizeof x0);
        if (!have_dx) {
            matvec4(A, x0, dx0);
            for (i = 0; i < 4; i++) dx0[i] += a[i];
        }
        double remaining = t_end - st->t, h = p->h[dyn];
        int lands = fabs(remaining - h) <= 1e-9 * h; /* this step ends the interval */
        int full = lands || remaining > h;
        if (full) { /* a full step: precomputed exact propagator */
            matvec4(p->Phi[dyn], x0, x1);
            for (i = 0; i < 4; i++) x1[i] += gam_a[i];
            matvec4(p->Phi[dyn], dx0, dx1);
        } else { /* the last, partial step: Taylor series of the same exact solution */
            h = remaining;
            lands = 1;
            nt = taylor(A, p->rho[dyn], x0, a, h, D);
            taylor_eval(D, nt, h, x1);
            matvec4(A, x1, dx1);
            for (i = 0; i < 4; i++) dx1[i] += a[i];
        }
        /* events: each g_e is positive inside the mode */
        double cg[2][4], g0[2];
        int target[2];
        /* no gap and the linear law: one linear system on both flanks, nothing to locate */
        int ne = (p->b == 0.0 && p->law == 0) ? 0 : event_functions(p, mode, cg, g0, target);
        double best = -1.0;
        int which = -1;
        for (int e = 0; e < ne; e++) {
            double ga = g0[e], gb = g0[e], da = 0.0, db = 0.0, dscale = 0.0;
            for (i = 0; i < 4; i++) {
                ga += cg[e][i] * x0[i];
                gb += cg[e][i] * x1[i];
                da += cg[e][i] * dx0[i];
                db += cg[e][i] * dx1[i];
                dscale += fabs(cg[e][i] * dx0[i]);
            }
            if (ga < 0.0) ga = 0.0; /* rounding just after a switch onto this boundary */
            /* a rate that is zero up to cancellation (e.g. the residue of a plastic impulse) is zero:
               then the curvature over the step (db) decides whether the flanks leave the boundary */
            if (ga == 0.0 && fabs(da) <= 1e-12 * dscale) da = 0.0;
            if (!(gb <= 0.0 || (da < 0.0 && db > 0.0) || (ga == 0.0 && da <= 0.0))) continue;
            double tau;
            if (ga == 0.0 && (da < 0.0 || (da == 0.0 && db < 0.0))) {
                tau = 0.0; /* on the boundary and heading out */
            } else {
                if (nt == 0) nt = taylor(A, p->rho[dyn], x0, a, h, D);
                double q[NTAY];
                for (int n = 0; n < nt; n++) {
                    q[n] = 0.0;
                    for (i = 0; i < 4; i++) q[n] += cg[e][i] * D[n][i];
                }
                q[0] = ga;
                tau = first_root(q, nt, h, gb, da, db);
            }
            /* strictly earlier only: on a tie (both functions vanish together, e.g. no_pull with c = 0)
               the geometric boundary, evaluated first, wins */
            if (tau >= 0.0 && (which < 0 || tau < best - 1e-12 * h)) {
                best = tau;
                which = e;
            }
        }
        st->n_steps++;
        if (which < 0) {
            memcpy(st->x, x1, sizeof x1);
            memcpy(dx0, dx1, sizeof dx1);
            have_dx = 1;
            st->t = lands ? t_end : st->t + h;
            if (ne == 0 && p->b == 0.0) st->mode = s_of(p, x1) >= 0.0 ? 1 : -1; /* the label only */
        } else {
            have_dx = 0; /* the state jumped to the event (and a plastic impact may change it) */
            if (nt == 0) nt = taylor(A, p->rho[dyn], x0, a, h, D);
            taylor_eval(D, nt, best, st->x);
            st->t += best;
            if (st->t > t_end) st->t = t_end;
            st->mode = transition(p, st, ev, cap, mode, target[which], st->x, st->t);
            if (st->n_events > p->max_events || ++guard > 4 * p->max_events) return ST_EVENTS;
            if (st->n_events >= cap && st->t < t_end) return ST_BUFFER;
        }
        if (loaded(mode)) { /* penetration peaks where v = 0 inside a contact step: Hermite estimate */
            double pen = fabs(s_of(p, st->x)) - p->b;
            if (pen > st->max_pen) st->max_pen = pen;
            double va = v_of(p, x0), vb = v_of(p, x1);
            if (which < 0 && va * vb < 0.0) {
                double sa = s_of(p, x0), sb = s_of(p, x1);
                /* cubic Hermite of s on [0, h]; its extremum near the zero of the linear v model */
                double th = va / (va - vb), hh = h;
                double h00 = 2 * th * th * th - 3 * th * th + 1, h10 = th * th * th - 2 * th * th + th;
                double h01 = -2 * th * th * th + 3 * th * th, h11 = th * th * th - th * th;
                double sm = h00 * sa + h10 * hh * va + h01 * sb + h11 * hh * vb;
                pen = fabs(sm) - p->b;
                if (pen > st->max_pen) st->max_pen = pen;
            }
        }
        for (i = 0; i < 4; i++)
            if (!isfinite(st->x[i])) return ST_NAN;
    }
    return ST_OK;
}

/* ---------------------------------------------------------------- nonlinear ODE solver */

static double table_k(const gc_params *p, double theta1) {
    double pos = fmod(theta1 + p->mesh_phase, p->mesh_period);
    if (pos < 0.0) pos += p->mesh_period;
    pos = pos / p->mesh_period * (double)p->n_table;
    long i = (long)floor(pos);
    double frac = pos - (double)i;
    i = i % p->n_table;
    long j = (i + 1) % p->n_table;
    return p->table[i] * (1.0 - frac) + p->table[j] * frac;
}

/* contact force along the line of action, signed like the front flank's (eq 3 / eq 10 / Yang-Sun) */
static double force(const gc_params *p, int mode, double d_ys, const double *x) {
    if (mode == 0) return 0.0;
    double s = s_of(p, x), v = v_of(p, x);
    double sigma = (double)sgn_mode(mode);
    double delta = sigma * s - p->b, ddelta = sigma * v; /* delta_F or delta_B */
    double F;
    if (p->kind == 1) {
        F = (d_ys * ddelta + p->k) * delta; /* Yang-Sun: F = (d x' + k) x */
    } else {
        double kk = p->kind == 2 ? table_k(p, x[0]) : p->k;
        F = kk * delta + p->c * ddelta;
    }
    if (p->law == 1 && F < 0.0) F = 0.0;
    return sigma * F;
}

static void rhs(const gc_params *p, int mode, double d_ys, double u1, double u2, const double *x, double *dx) {
    double F = force(p, mode, d_ys, x);
    double f1 = p->d1 * x[2], f2 = p->d2 * x[3];
    if (p->tc1 > 0.0) f1 += p->tc1 * tanh(x[2] / p->ws);
    if (p->tc2 > 0.0) f2 += p->tc2 * tanh(x[3] / p->ws);
    dx[0] = x[2];
    dx[1] = x[3];
    dx[2] = (u1 - p->rb1 * F - f1) / p->J1;
    dx[3] = (u2 + p->rb2 * F - f2) / p->J2;
}

/* In the ODE solver no_pull is part of the force law (a kink, not an event); the contact modes are
 * only front (1), separation (0), back (-1). */
static int ode_events(const gc_params *p, int mode, double cg[2][4], double g0[2], int target[2]) {
    double sv[4] = {p->rb1, -p->rb2, 0.0, 0.0};
    int i;
    if (mode == 0) {
        for (i = 0; i < 4; i++) { cg[0][i] = -sv[i]; cg[1][i] = sv[i]; }
        g0[0] = p->b; g0[1] = p->b; target[0] = 1; target[1] = -1;
        return 2;
    }
    double sg = (double)sgn_mode(mode);
    for (i = 0; i < 4; i++) cg[0][i] = sg * sv[i];
    g0[0] = -p->b;
    target[0] = 0;
    return 1;
}

static inline double dot_g(const double *cg, double g0, const double *x) {
    return g0 + cg[0] * x[0] + cg[1] * x[1] + cg[2] * x[2] + cg[3] * x[3];
}

static void dense(const double r[5][4], double th, double *y) {
    for (int i = 0; i < 4; i++)
        y[i] = r[0][i] + th * (r[1][i] + (1.0 - th) * (r[2][i] + th * (r[3][i] + (1.0 - th) * r[4][i])));
}

int gc_advance_ode(const gc_params *p, gc_state *st, double u1, double u2, double T, gc_event *ev,
                   long cap) {
    /* Dormand-Prince 5(4) tableau (the system is autonomous: the nodes c_i are not needed) */
    static const double a21 = 0.2, a31 = 3.0 / 40.0, a32 = 9.0 / 40.0, a41 = 44.0 / 45.0, a42 = -56.0 / 15.0,
                        a43 = 32.0 / 9.0, a51 = 19372.0 / 6561.0, a52 = -25360.0 / 2187.0,
                        a53 = 64448.0 / 6561.0, a54 = -212.0 / 729.0, a61 = 9017.0 / 3168.0,
                        a62 = -355.0 / 33.0, a63 = 46732.0 / 5247.0, a64 = 49.0 / 176.0,
                        a65 = -5103.0 / 18656.0, a71 = 35.0 / 384.0, a73 = 500.0 / 1113.0,
                        a74 = 125.0 / 192.0, a75 = -2187.0 / 6784.0, a76 = 11.0 / 84.0;
    static const double e1 = 71.0 / 57600.0, e3 = -71.0 / 16695.0, e4 = 71.0 / 1920.0,
                        e5 = -17253.0 / 339200.0, e6 = 22.0 / 525.0, e7 = -1.0 / 40.0;
    static const double d1 = -12715105075.0 / 11282082432.0, d3 = 87487479700.0 / 32700410799.0,
                        d4 = -10690763975.0 / 1880347072.0, d5 = 701980252875.0 / 199316789632.0,
                        d6 = -1453857185.0 / 822651844.0, d7 = 69997945.0 / 29380423.0;
    double t_end = st->t + T;
    st->n_events = 0;
    double k1[4], k2[4], k3[4], k4[4], k5[4], k6[4], k7[4], y1[4], yt[4];
    double h = st->h_ode > 0.0 ? st->h_ode : p->h_max * 0.1;
    int have_k1 = 0;
    long rejects = 0;
    while (st->t < t_end) {
        int mode = st->mode;
        double *y = st->x;
        if (!have_k1) rhs(p, mode, st->d_ys, u1, u2, y, k1);
        have_k1 = 1;
        if (h > p->h_max) h = p->h_max;
        int last = 0;
        if (st->t + h >= t_end - 1e-15 * fabs(t_end)) { h = t_end - st->t; last = 1; }
        int i;
        for (i = 0; i < 4; i++) yt[i] = y[i] + h * a21 * k1[i];
        rhs(p, mode, st->d_ys, u1, u2, yt, k2);
        for (i = 0; i < 4; i++) yt[i] = y[i] + h * (a31 * k1[i] + a32 * k2[i]);
        rhs(p, mode, st->d_ys, u1, u2, yt, k3);
        for (i = 0; i < 4; i++) yt[i] = y[i] + h * (a41 * k1[i] + a42 * k2[i] + a43 * k3[i]);
        rhs(p, mode, st->d_ys, u1, u2, yt, k4);
        for (i = 0; i < 4; i++) yt[i] = y[i] + h * (a51 * k1[i] + a52 * k2[i] + a53 * k3[i] + a54 * k4[i]);
        rhs(p, mode, st->d_ys, u1, u2, yt, k5);
        for (i = 0; i < 4; i++)
            yt[i] = y[i] + h * (a61 * k1[i] + a62 * k2[i] + a63 * k3[i] + a64 * k4[i] + a65 * k5[i]);
        rhs(p, mode, st->d_ys, u1, u2, yt, k6);
        for (i = 0; i < 4; i++)
            y1[i] = y[i] + h * (a71 * k1[i] + a73 * k3[i] + a74 * k4[i] + a75 * k5[i] + a76 * k6[i]);
        rhs(p, mode, st->d_ys, u1, u2, y1, k7);
        double err = 0.0;
        for (i = 0; i < 4; i++) {
            double sk = (i < 2 ? p->atol_angle : p->atol_rate) + p->rtol * fmax(fabs(y[i]), fabs(y1[i]));
            double ei = h * (e1 * k1[i] + e3 * k3[i] + e4 * k4[i] + e5 * k5[i] + e6 * k6[i] + e7 * k7[i]) / sk;
            err += ei * ei;
        }
        err = sqrt(err / 4.0);
        if (!isfinite(err)) return ST_NAN;
        double fac = err > 0.0 ? 0.9 * pow(err, -0.2) : 5.0;
        if (fac > 5.0) fac = 5.0;
        if (err > 1.0) {
            if (fac < 0.2) fac = 0.2;
            h *= fac;
            if (++rejects > 100000 || h < 1e-16 * (fabs(st->t) + 1e-9)) return ST_STEP;
            continue;
        }
        st->n_steps++;
        /* events on the dense output */
        double cg[2][4], g0[2];
        int target[2];
        int ne = ode_events(p, mode, cg, g0, target);
        double best = 2.0;
        int which = -1;
        double r[5][4];
        int have_dense = 0;
        for (int e = 0; e < ne; e++) {
            double ga = dot_g(cg[e], g0[e], y), gb = dot_g(cg[e], g0[e], y1);
            if (!(gb <= 0.0) || ga < 0.0) continue;
            if (!have_dense) {
                for (i = 0; i < 4; i++) {
                    r[0][i] = y[i];
                    r[1][i] = y1[i] - y[i];
                    r[2][i] = h * k1[i] - r[1][i];
                    r[3][i] = r[1][i] - h * k7[i] - r[2][i];
                    r[4][i] = h * (d1 * k1[i] + d3 * k3[i] + d4 * k4[i] + d5 * k5[i] + d6 * k6[i] + d7 * k7[i]);
                }
                have_dense = 1;
            }
            double lo = 0.0, hi = 1.0, flo = ga, fhi = gb;
            if (ga == 0.0) { /* started on this boundary: search just inside */
                lo = 1e-12;
                dense(r, lo, yt);
                flo = dot_g(cg[e], g0[e], yt);
                if (flo <= 0.0) { best = 0.0; which = e; break; }
            }
            for (int it = 0; it < 200 && hi - lo > 1e-15; it++) { /* Illinois regula falsi */
                double th = hi - fhi * (hi - lo) / (fhi - flo);
                if (!(th > lo && th < hi)) th = 0.5 * (lo + hi);
                dense(r, th, yt);
                double ft = dot_g(cg[e], g0[e], yt);
                if (ft > 0.0) { lo = th; flo = ft; fhi *= 0.5; }
                else { hi = th; fhi = ft; flo *= 0.5; }
            }
            if (hi < best) { best = hi; which = e; }
        }
        if (which >= 0) {
            dense(r, best, st->x);
            st->t += best * h;
            int nm = sgn_mode(transition(p, st, ev, cap, mode, target[which], st->x, st->t));
            if (p->kind == 1 && nm != 0) {
                double vi = fabs(v_of(p, st->x));
                /* eq 36/37: d from the impact velocity (in/s reading of eq 37, see stiffness.py) */
                double v = vi < 1e-3 ? 1e-3 : vi;
                double e = 1.0 - 0.022 * pow(v / 0.0254, 0.36);
                if (e < 0.05) e = 0.05;
                if (e > 1.0) e = 1.0;
                st->d_ys = 6.0 * (1.0 - e) / ((2.0 * e - 1.0) * (2.0 * e - 1.0) + 3.0) * p->k / v;
            }
            st->mode = nm;
            have_k1 = 0;
            if (st->n_events > p->max_events) return ST_EVENTS;
            if (st->n_events >= cap && st->t < t_end) return ST_BUFFER;
        } else {
            memcpy(st->x, y1, sizeof y1);
            memcpy(k1, k7, sizeof k7);
            st->t = last ? t_end : st->t + h;
            if (!last) st->h_ode = h * fac;
            h = h * fac;
        }
        if (st->mode != 0) {
            double pen = fabs(s_of(p, st->x)) - p->b;
            if (pen > st->max_pen) st->max_pen = pen;
        }
        for (i = 0; i < 4; i++)
            if (!isfinite(st->x[i])) return ST_NAN;
    }
    return ST_OK;
}

/* ---------------------------------------------------------------- open-loop runs */

/* n intervals of length dt with constant torques; states after each interval to out_x (4 per row),
 * the mode and Yang-Sun factor to out_mode/out_dys. Returns the status and stops at the first failure;
 * *done is the number of intervals completed. Events of all intervals go to ev (n_events counts all). */
int gc_run(const gc_params *p, gc_state *st, double u1, double u2, double dt, long n, double *out_x,
           int *out_mode, double *out_dys, gc_event *ev, long cap, long *done) {
    long total = 0;
    int status = ST_OK;
    *done = 0;
    for (long i = 0; i < n; i++) {
        status = p->kind == 0 && p->tc1 == 0.0 && p->tc2 == 0.0
                     ? gc_advance_pwl(p, st, u1, u2, dt, ev + (total < cap ? total : cap), cap > total ? cap - total : 0)
                     : gc_advance_ode(p, st, u1, u2, dt, ev + (total < cap ? total : cap), cap > total ? cap - total : 0);
        total += st->n_events;
        if (status == ST_BUFFER) break; /* interval i unfinished: Python drains and resumes */
        memcpy(out_x + 4 * i, st->x, sizeof(double) * 4);
        out_mode[i] = st->mode;
        out_dys[i] = st->d_ys;
        *done = i + 1;
        if (status != ST_OK) break;
        if (fabs(st->x[2]) > 1e6 || fabs(st->x[3]) > 1e6) break;
    }
    st->n_events = total;
    return status;
}

/* One interval with the inputs stored in the state (u1, u2, T, ev, cap): the closed loop's per-sample call. */
int gc_step(const gc_params *p, gc_state *st) {
    if (p->kind == 0 && p->tc1 == 0.0 && p->tc2 == 0.0)
        return gc_advance_pwl(p, st, st->u1, st->u2, st->T, st->ev, st->cap);
    return gc_advance_ode(p, st, st->u1, st->u2, st->T, st->ev, st->cap);
}
