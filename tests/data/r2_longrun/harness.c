/* r2's long-run harness for an exported controller, written from the README's export section alone (the documented
 * API: gearctl_ctrl_init, gearctl_ctrl_step, the GEARCTL_ macros). The plant is its own: a chain of shafts joined by
 * dead-zone springs (stiffness k and damping c in contact beyond the half-gap b along each stage's line of action,
 * nothing in the gap), viscous friction, RK4 at fixed sub-steps of at most 0.5 / (the stiffest mesh's frequency);
 * the encoders are quantised as gearctl's (q floor(angle / q + 0.5)). plant_params.h (written by the test from
 * gearctl.build_plant) gives NS, WMAX, LOAD_TORQUE, CPR_M, CPR_L and the per-shaft and per-stage tables.
 *
 * The plant integrates small local angles; the offset OFF (a zero far away, a spindle that has turned for hours) is
 * added in long double where the encoders read and where the error is taken, so the plant itself loses nothing.
 *
 * usage: harness N REF OFF [PERIOD_ERROR [PRE_BAD [JITTER]]]
 *   N             samples to run
 *   REF           sine (0.2 rad, 0.5 Hz about OFF) or sine_moves (the same plus a 1 rad cosine move over 2 s every
 *                 10 s, accumulating: the reference keeps moving on)
 *   OFF           the reference's zero [rad at the load]
 *   PERIOD_ERROR  the caller's sample interval is GEARCTL_TS (1 + PERIOD_ERROR) (the plant's time; 0 by default)
 *   PRE_BAD       bad-input steps (NaN readings) before the run: the controller's clock k runs on cheaply
 *   JITTER        each interval also varies by up to +-JITTER GEARCTL_TS, uniformly at random (fixed seed)
 * prints one line: key value pairs (the load error's RMS from 10 s on, and its RMS and max over the 10 s pattern
 * period from 10 s and over the last one; the statuses; the saturated steps; the steps beyond the limit; max |u|) */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearctl_ctrl.h"
#include "plant_params.h"

#define NX (2 * (NS + 1))
#define PI_L 3.14159265358979323846L

static void deriv(const double *x, double u, double *dx) {
    const double *th = x, *w = x + NS + 1;
    double tq[NS + 1];
    for (int i = 0; i <= NS; i++) tq[i] = -PD[i] * w[i];
    tq[0] += u;
    tq[NS] -= LOAD_TORQUE;
    for (int i = 0; i < NS; i++) {
        double s = P_rb1[i] * th[i] - P_rb2[i] * th[i + 1], sd = P_rb1[i] * w[i] - P_rb2[i] * w[i + 1], f = 0.0;
        if (s > P_backlash[i]) f = P_k[i] * (s - P_backlash[i]) + P_c[i] * sd;
        else if (s < -P_backlash[i]) f = P_k[i] * (s + P_backlash[i]) + P_c[i] * sd;
        tq[i] -= P_rb1[i] * f;
        tq[i + 1] += P_rb2[i] * f;
    }
    for (int i = 0; i <= NS; i++) dx[i] = w[i], dx[NS + 1 + i] = tq[i] / PJ[i];
}

static void rk4(double *x, double u, double h) {
    double k1[NX], k2[NX], k3[NX], k4[NX], t[NX];
    deriv(x, u, k1);
    for (int i = 0; i < NX; i++) t[i] = x[i] + 0.5 * h * k1[i];
    deriv(t, u, k2);
    for (int i = 0; i < NX; i++) t[i] = x[i] + 0.5 * h * k2[i];
    deriv(t, u, k3);
    for (int i = 0; i < NX; i++) t[i] = x[i] + h * k3[i];
    deriv(t, u, k4);
    for (int i = 0; i < NX; i++) x[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
}

static double encoder(long double angle, long cpr) {
    if (cpr <= 0) return (double)angle;
    long double q = 2.0L * PI_L / (long double)cpr;
    return (double)(q * floorl(angle / q + 0.5L));
}

static int MOVES;
static double OFF;

static void reference(int64_t k, double ts, double *r) {
    int64_t period = (int64_t)llround(10.0 / ts), n = k / period;
    double tl = (double)(k % period) * ts, w = 2.0 * (double)PI_L * 0.5, a = 0.2;
    double p = a * sin(w * tl), pd = a * w * cos(w * tl), pdd = -a * w * w * sin(w * tl);
    if (MOVES) {
        double mv = (double)n;
        if (tl >= 5.0 && tl < 7.0) {
            double s = (tl - 5.0) / 2.0, pi = (double)PI_L;
            mv += 0.5 * (1.0 - cos(pi * s));
            pd += 0.25 * pi * sin(pi * s);
            pdd += 0.125 * pi * pi * cos(pi * s);
        } else if (tl >= 7.0) {
            mv += 1.0;
        }
        p += mv;
    }
    r[0] = OFF + p, r[1] = pd, r[2] = pdd;
}

int main(int argc, char **argv) {
    if (argc < 4) {
        fprintf(stderr, "usage: harness N sine|sine_moves OFF [PERIOD_ERROR [PRE_BAD [JITTER]]]\n");
        return 2;
    }
    int64_t n = atoll(argv[1]);
    MOVES = strcmp(argv[2], "sine_moves") == 0;
    OFF = atof(argv[3]);
    double period_error = argc > 4 ? atof(argv[4]) : 0.0;
    int64_t pre = argc > 5 ? atoll(argv[5]) : 0;
    double jitter = argc > 6 ? atof(argv[6]) : 0.0;
    double ts = GEARCTL_TS;
    int nsub = (int)ceil(ts * WMAX / 0.5);
    if (nsub < 4) nsub = 4;
    double ratio = 1.0;
    for (int i = 0; i < NS; i++) ratio *= P_rb2[i] / P_rb1[i];
    long double off_l = (long double)OFF, off_m = off_l * (long double)ratio;
    double x[NX];
    memset(x, 0, sizeof x); /* at rest, every stage centred in its gap */
    static gearctl_ctrl_t c;
    gearctl_ctrl_init(&c);
    double ref[3 * GEARCTL_PREVIEW], u;
    {
        double yn[2] = {NAN, NAN};
        for (int j = 0; j < GEARCTL_PREVIEW; j++) reference(j, ts, ref + 3 * j);
        for (int64_t k = 0; k < pre; k++) {
            if (gearctl_ctrl_step(&c, yn, ref, &u) != GEARCTL_STEP_BAD_INPUT || u != 0.0) {
                printf("error: bad-input step %lld was not refused\n", (long long)k);
                return 1;
            }
        }
    }
    int64_t period = (int64_t)llround(10.0 / ts);
    double se_all = 0.0, se_first = 0.0, se_last = 0.0, max_first = 0.0, max_last = 0.0, umax = 0.0;
    int64_t status[5] = {0, 0, 0, 0, 0}, saturated = 0, beyond = 0;
    srand(12345);
    for (int64_t k = 0; k < n; k++) {
        for (int j = 0; j < GEARCTL_PREVIEW; j++) reference(k + j, ts, ref + 3 * j);
        double y[2] = {encoder(off_m + (long double)x[0], CPR_M),
                       GEARCTL_USES_LOAD_ENCODER ? encoder(off_l + (long double)x[NS], CPR_L) : NAN};
        int s = gearctl_ctrl_step(&c, y, ref, &u);
        if (s < 0 || s > 4) {
            printf("error: status %d\n", s);
            return 1;
        }
        status[s]++;
        if (!(fabs(u) <= GEARCTL_TORQUE_LIMIT)) beyond++;
        if (fabs(u) == GEARCTL_TORQUE_LIMIT) saturated++;
        if (fabs(u) > umax) umax = fabs(u);
        double e = (double)((off_l + (long double)x[NS]) - (long double)ref[0]);
        if (k >= period) se_all += e * e;
        if (k >= period && k < 2 * period) {
            se_first += e * e;
            if (fabs(e) > max_first) max_first = fabs(e);
        }
        if (k >= n - period) {
            se_last += e * e;
            if (fabs(e) > max_last) max_last = fabs(e);
        }
        double dt = ts * (1.0 + period_error + jitter * (2.0 * (double)rand() / (double)RAND_MAX - 1.0));
        for (int i = 0; i < nsub; i++) rk4(x, u, dt / nsub);
    }
    printf("rms_all %.6e rms_first %.6e max_first %.6e rms_last %.6e max_last %.6e ok %lld fallback %lld bad %lld fault %lld "
           "not_init %lld saturated %lld beyond %lld umax %.17g k %lld\n",
           n > period ? sqrt(se_all / (double)(n - period)) : 0.0, sqrt(se_first / (double)period), max_first, sqrt(se_last / (double)period), max_last, (long long)status[0],
           (long long)status[1], (long long)status[2], (long long)status[3], (long long)status[4],
           (long long)saturated, (long long)beyond, umax, (long long)c.k);
    return 0;
}
