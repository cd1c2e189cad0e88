/* r4's own geared-servo simulator: RK4 at a fixed internal step, PD loop on the motor encoder, ZOH torque.
   Options: hertz, tvms, Hunt-Crossley damping, Stribeck load friction, arm inertia, load encoder eccentricity,
   clock jitter, clock offset. Writes t,torque,theta1,theta2,reference (raw) to stdout. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
static double rb1 = 0.018793852415718168, rb2 = 0.07517540966287267, pb = 0.005904262868187099, eps = 1.6912923264235975;
static double k = 138544672.97790593, c = 798.5767215559957, J1 = 0.00021960353815840032, J2 = 0.01001850576855048;
static double d1 = 1e-4, d2 = 2e-3, Tc1 = 0.0, Tc2 = 0.2, Tstat = 0.2, wstr = 0.01, wt = 1e-4, b = 5e-5;
static int hertz = 0, tvms = 0, terse = 0; static double alpha = 20.0, kh = 0.0, ml2 = 0.0, armphi = 0.0;
static double u_app = 0.0;
static double mult(double th1) { if (!tvms) return 1.0; double ph = rb1 * th1 / pb; ph -= floor(ph);
  return (ph < eps - 1.0 ? 2.0 : 1.0) / eps; }
static double force(const double *x) {
  double s = rb1 * x[0] - rb2 * x[2], v = rb1 * x[1] - rb2 * x[3], m = mult(x[0]);
  if (!hertz) {
    if (s > b) return m * k * (s - b) + c * v;
    if (s < -b) return m * k * (s + b) + c * v;
    return 0.0; }
  if (s > b) { double d = s - b, F = m * kh * pow(d, 1.5) * (1.0 + 1.5 * alpha * v); return F > 0 ? F : 0; }
  if (s < -b) { double d = -s - b, F = m * kh * pow(d, 1.5) * (1.0 - 1.5 * alpha * v); return F > 0 ? -F : 0; }
  return 0.0; }
static void rhs(const double *x, double *dx) {
  double F = force(x), w1 = x[1], w2 = x[3];
  double f1 = d1 * w1 + Tc1 * tanh(w1 / wt);
  double mag = Tc2 + (Tstat - Tc2) * exp(-(w2 / wstr) * (w2 / wstr));
  double f2 = d2 * w2 + mag * tanh(w2 / wt);
  double J2t = J2 + ml2 * cos(x[2] + armphi) * cos(x[2] + armphi), dJ = -ml2 * sin(2 * (x[2] + armphi));
  dx[0] = w1; dx[1] = (u_app - f1 - rb1 * F) / J1;
  dx[2] = w2; dx[3] = (rb2 * F - f2 - 0.5 * dJ * w2 * w2) / J2t; }
static double gauss(void) { double u1 = (rand() + 1.0) / (RAND_MAX + 2.0), u2 = (rand() + 1.0) / (RAND_MAX + 2.0);
  return sqrt(-2 * log(u1)) * cos(2 * M_PI * u2); }
int main(int argc, char **argv) {
  /* key=value args */
  const char *ref = "ref.csv"; double Ts = 1e-3, h = 5e-7, jitter = 0, t0 = 0, ecc = 0, cpr = 1048576, dur = 10, kp = 13, kd = 0.21;
  int seed = 1;
  for (int i = 1; i < argc; i++) { char key[64]; double val; char sval[512];
    if (sscanf(argv[i], "ref=%511s", sval) == 1) { ref = strdup(sval); continue; }
    if (sscanf(argv[i], "%63[^=]=%lf", key, &val) != 2) { fprintf(stderr, "bad arg %s\n", argv[i]); return 2; }
#define K(n, v) if (!strcmp(key, n)) { v = val; continue; }
    K("Ts", Ts) K("h", h) K("jitter", jitter) K("t0", t0) K("ecc", ecc) K("cpr", cpr) K("dur", dur) K("kp", kp) K("kd", kd)
    K("b", b) K("alpha", alpha) K("ml2", ml2) K("Tc2", Tc2) K("Tstat", Tstat) K("wstr", wstr) K("d1", d1) K("d2", d2)
    K("Tc1", Tc1) K("J1", J1) K("J2", J2) K("k", k) K("armphi", armphi)
    if (!strcmp(key, "hertz")) { hertz = (int)val; continue; }
    if (!strcmp(key, "tvms")) { tvms = (int)val; continue; }
    if (!strcmp(key, "seed")) { seed = (int)val; continue; }
    if (!strcmp(key, "terse")) { terse = (int)val; continue; }
    fprintf(stderr, "unknown %s\n", key); return 2; }
  srand(seed);
  { double Fr = 5.0; kh = pow(k / (1.5 * cbrt(Fr)), 1.5); }
  /* reference table: t,reference,velocity,acceleration at 1 ms, after one comment line and a header */
  FILE *f = fopen(ref, "r"); if (!f) { perror(ref); return 2; }
  static double R[2000000][3]; int nr = 0; char line[512];
  while (fgets(line, sizeof line, f)) { double a, r, v, ac; if (sscanf(line, "%lf,%lf,%lf,%lf", &a, &r, &v, &ac) == 4) {
      R[nr][0] = r; R[nr][1] = v; R[nr][2] = ac; nr++; } }
  fclose(f);
  double N = rb2 / rb1, Jeq = J1 + J2 / (N * N), q = 2 * M_PI / cpr;
  double x[4] = {0, 0, 0, 0};
  /* start on the front flank at rest */
  x[0] = b / rb1; 
  long nsamp = (long)(dur / Ts); double t = 0.0, prev1 = 0.0; int have = 0;
  if (terse) printf("t,torque,theta1,theta2\n"); else printf("t,torque,theta1,theta2,reference\n");
  for (long kk = 0; kk < nsamp; kk++) {
    double ts = kk * Ts + (jitter > 0 ? jitter * gauss() : 0.0); if (ts < t) ts = t;
    /* integrate to ts */
    while (t < ts - 1e-15) { double hh = fmin(h, ts - t), k1[4], k2[4], k3[4], k4[4], y[4];
      rhs(x, k1); for (int i = 0; i < 4; i++) y[i] = x[i] + 0.5 * hh * k1[i];
      rhs(y, k2); for (int i = 0; i < 4; i++) y[i] = x[i] + 0.5 * hh * k2[i];
      rhs(y, k3); for (int i = 0; i < 4; i++) y[i] = x[i] + hh * k3[i];
      rhs(y, k4); for (int i = 0; i < 4; i++) x[i] += hh / 6 * (k1[i] + 2 * k2[i] + 2 * k3[i] + k4[i]);
      t += hh; }
    double m1 = floor(x[0] / q) * q;
    double th2e = x[2] + ecc * q * sin(x[2] + 0.7);
    double m2 = floor(th2e / q) * q;
    double rt = ts / 1e-3; int i0 = (int)floor(rt); if (i0 >= nr - 1) i0 = nr - 2; double fr = rt - i0;
    double r = R[i0][0] * (1 - fr) + R[i0 + 1][0] * fr, v = R[i0][1] * (1 - fr) + R[i0 + 1][1] * fr, a = R[i0][2] * (1 - fr) + R[i0 + 1][2] * fr;
    double w1e = have ? (m1 - prev1) / Ts : 0.0; prev1 = m1; have = 1;
    double u = kp * (N * r + b / rb1 * 0 - m1) + kd * (N * v - w1e) + Jeq * N * a;
    if (u > 1) u = 1; if (u < -1) u = -1;
    u_app = u;
    if (terse) printf("%.3f,%.6g,%.9g,%.9g\n", t0 + ts, u, m1, m2); else printf("%.9f,%.10g,%.12g,%.12g,%.10g\n", t0 + ts, u, m1, m2, r);
  }
  return 0; }
