/* h3's independent geared-servo rig simulator (not gearctl's code).
 *
 * Plant: two shafts coupled by a Hunt-Crossley contact on either flank of a gap of +-b along the line of action,
 *   F = K d^n (1 + alpha d'), clamped >= 0 (no pull), d the flank penetration.
 * Friction on each shaft: LuGre (bristle state z, Stribeck curve g(v) = Tc + (Ts - Tc) exp(-(v/vs)^2)), plus viscous d v.
 *   The bristle state is advanced with the exact exponential for v held over the step (stiff otherwise).
 * Motor: torque command u held per controller sample, applied through a first-order current loop (time constant tau).
 * Integration: semi-implicit (symplectic) Euler at a fixed micro step h.
 * Controller: discrete PD(+I) on the load angle read from the motor encoder (theta1/N quantised) or load encoder,
 *   with velocity and acceleration feedforward from a reference table; or open loop (u = table).
 * Sampling: controller fires at the true instants tk[] (given by the caller: drift + jitter), reads quantised encoders.
 */
#include <math.h>
#include <stdint.h>

typedef struct {
    double rb1, rb2, b, K, n, alpha;
    double J1, J2;
    double d1, Tc1, Ts1, vs1, s01, s11;   /* motor friction: viscous, Coulomb, static, Stribeck speed, sigma0, sigma1 */
    double d2, Tc2, Ts2, vs2, s02, s12;
    double TL;                            /* load torque on shaft 2 */
    double tau;                           /* current loop time constant [s] (0: none) */
    double h;                             /* micro step [s] */
    double umax;                          /* torque limit */
    double kp, kd, ki, kff_v, kff_a;      /* controller gains (on load angle, torque units) */
    int mode;                             /* 0: closed loop on motor enc, 1: on load enc, 2: open loop */
    double q1, q2;                        /* encoder quanta [rad] used by the controller */
    double N;
} rig_t;

static double lugre_step(double v, double *z, double Tc, double Ts, double vs, double s0, double s1, double d,
                         double h)
{
    if (s0 < 0.0) { /* a plain smooth Coulomb law instead of LuGre: Tc tanh(v / vs) */
        return Tc * tanh(v / vs) + d * v;
    }
    if (s0 == 0.0) {
        return d * v;
    }
    double g = Tc + (Ts - Tc) * exp(-(v / vs) * (v / vs));
    if (g < 1e-12) {
        *z = 0.0;
        return d * v;
    }
    double a = s0 * fabs(v) / g;
    double zss = (fabs(v) > 0.0) ? g / s0 * (v > 0 ? 1.0 : -1.0) : *z;
    double znew = (a * h > 1e-12) ? zss + (*z - zss) * exp(-a * h) : *z + v * h;
    double zdot = (znew - *z) / h;
    *z = znew;
    double damp = s1 * exp(-(v / vs) * (v / vs));
    return s0 * znew + damp * zdot + d * v;
}

static double contact(double d, double dd, const rig_t *p)
{
    if (d <= 0.0) {
        return 0.0;
    }
    double f = p->K * pow(d, p->n) * (1.0 + p->alpha * dd);
    return f > 0.0 ? f : 0.0;
}

/* Run ns controller samples at the instants tk[0..ns-1] (tk[ns] is the end), refs r[], rv[], ra[] (load angle) or
 * the open-loop torque in r[]. Noise samples n1[], n2[] (rad) are added to the encoder readings the controller uses.
 * Outputs at each sample instant: u[] the command, th1[], th2[] the true angles, and the contact force fc[]. */
int rig_run(const rig_t *p, int ns, const double *tk, const double *r, const double *rv, const double *ra,
            const double *n1, const double *n2, double *u, double *th1, double *th2, double *fc, double *st)
{
    double x1 = st[0], w1 = st[1], x2 = st[2], w2 = st[3];
    double z1 = 0.0, z2 = 0.0, cur = 0.0, integ = 0.0, prev_y = NAN;
    double t = tk[0];
    double F = 0.0;
    for (int k = 0; k < ns; k++) {
        th1[k] = x1;
        th2[k] = x2;
        fc[k] = F;
        /* controller */
        double uk;
        if (p->mode == 2) {
            uk = r[k];
        } else {
            double y;
            if (p->mode == 0) {
                y = floor((x1 + n1[k]) / p->q1) * p->q1 / p->N;
            } else {
                y = floor((x2 + n2[k]) / p->q2) * p->q2;
            }
            double dt = (k > 0) ? tk[k] - tk[k - 1] : (tk[1] - tk[0]);
            double e = r[k] - y;
            double vel = isnan(prev_y) ? 0.0 : (y - prev_y) / dt;
            prev_y = y;
            integ += e * dt;
            uk = p->kp * e + p->ki * integ + p->kd * (rv[k] - vel) + p->kff_v * rv[k] + p->kff_a * ra[k];
        }
        if (uk > p->umax) uk = p->umax;
        if (uk < -p->umax) uk = -p->umax;
        u[k] = uk;
        /* plant over [tk[k], tk[k+1]) */
        double tend = tk[k + 1];
        while (t < tend - 1e-15) {
            double h = p->h;
            if (t + h > tend) h = tend - t;
            if (p->tau > 0.0) {
                cur = uk + (cur - uk) * exp(-h / p->tau);
            } else {
                cur = uk;
            }
            double s = p->rb1 * x1 - p->rb2 * x2;
            double sd = p->rb1 * w1 - p->rb2 * w2;
            double Ff = contact(s - p->b, sd, p);
            double Fb = contact(-s - p->b, -sd, p);
            F = Ff - Fb;
            double T1 = lugre_step(w1, &z1, p->Tc1, p->Ts1, p->vs1, p->s01, p->s11, p->d1, h);
            double T2 = lugre_step(w2, &z2, p->Tc2, p->Ts2, p->vs2, p->s02, p->s12, p->d2, h);
            w1 += h * (cur - p->rb1 * F - T1) / p->J1;
            w2 += h * (p->rb2 * F - T2 + p->TL) / p->J2;
            x1 += h * w1;
            x2 += h * w2;
            t += h;
            if (!isfinite(x1) || !isfinite(x2)) {
                return -1;
            }
        }
    }
    st[0] = x1;
    st[1] = w1;
    st[2] = x2;
    st[3] = w2;
    return 0;
}
