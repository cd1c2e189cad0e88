/* SPDX-License-Identifier: MIT -- part of gearctl, written for it (no third-party code). */
/*
 * gearctl_qp: a dense, exact, dual active-set QP solver (Goldfarb-Idnani) for small convex QPs.
 *
 *     minimise    1/2 x'Hx + g'x
 *     subject to  lbx <= x <= ubx            (n simple bounds)
 *                 lba <= A x <= uba          (m general rows)
 *
 * H (n x n) is symmetric positive definite. A bound (of x or of a row) whose magnitude is at least
 * settings.infinity (1e20 by default; +-INFINITY also works) is absent; lb == ub makes an equality.
 *
 * Use
 *   1. once per Hessian:  gearctl_qp_factor(n, H, factor)  with factor[gearctl_qp_factor_size(n)];
 *   2. once per problem size: a workspace  double work[gearctl_qp_work_size(n, m)]  (or the macro
 *      GEARCTL_QP_WORK_SIZE(n, m) for a static array) and a gearctl_qp_problem / gearctl_qp_result
 *      pointing at the caller's arrays;
 *   3. per QP: fill g, the bounds (and A), set problem.factor, call gearctl_qp_solve.
 *
 * The code is C99, allocates nothing, performs no I/O, keeps no global or static state (any number of
 * problems may be solved concurrently, each with its own workspace) and uses only <math.h>, <string.h>
 * and <stdint.h>.
 *
 * Method: the dual active-set method of D. Goldfarb and A. Idnani, "A numerically stable dual method
 * for solving strictly convex quadratic programs", Math. Programming 27 (1983) 1-33. See gearctl_qp.c.
 *
 * Units: the solver attaches none; the multipliers have the units of the cost per unit of the
 * constraint. Sign convention of the multipliers (CasADi's): at the optimum
 *     H x + g + lam_x + A' lam_a = 0,
 * lam > 0 where the upper bound is active, lam < 0 where the lower bound is active, 0 where inactive
 * (exact zeros). An equality's multiplier has either sign.
 *
 * Reproducibility: the same source compiled without floating-point contraction or reassociation
 * (ISO C mode, e.g. -std=c99, which implies -ffp-contract=off in GCC; clang's default contraction is turned off
 * in gearctl_qp.c by #pragma STDC FP_CONTRACT OFF; no -ffast-math) gives the same bits on any IEEE-754 target.
 */
#ifndef GEARCTL_QP_H
#define GEARCTL_QP_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- status codes (return values of gearctl_qp_factor and gearctl_qp_solve) ---------------------- */
#define GEARCTL_QP_SOLVED 0          /* optimal: x, multipliers and cost satisfy the KKT conditions */
#define GEARCTL_QP_INFEASIBLE 1      /* no x satisfies the constraints (or some lb > ub) */
#define GEARCTL_QP_ITERATION_LIMIT 2 /* settings.max_iter working-set changes made, not yet optimal */
#define GEARCTL_QP_NUMERICAL 3       /* a non-finite number appeared during the solve */
#define GEARCTL_QP_NOT_POSDEF 4      /* gearctl_qp_factor: H is not (numerically) positive definite */
#define GEARCTL_QP_INVALID 5         /* bad sizes or settings, a NULL required pointer, bad data */

/* Bounds at or beyond +-GEARCTL_QP_INF are absent (the default of settings.infinity). */
#define GEARCTL_QP_INF 1e20

/* Number of doubles of a factor of an n x n Hessian (same as gearctl_qp_factor_size). */
#define GEARCTL_QP_FACTOR_SIZE(n) ((long)(n) * (long)(n))

/* Number of doubles of the workspace for n variables and m rows (same as gearctl_qp_work_size):
 * two n x n matrices, five n-vectors, one m-vector, then n int32 and n + m int8, each group rounded
 * up to whole doubles. For n = 20, m = 22: 938 doubles (7.5 kB). */
#define GEARCTL_QP_WORK_SIZE(n, m)                                                                  \
    (2L * (long)(n) * (long)(n) + 5L * (long)(n) + (long)(m) + ((long)(n) + 1L) / 2L +              \
     ((long)(n) + (long)(m) + 7L) / 8L)

/* Solver settings; fill with gearctl_qp_default_settings, then change what you need. */
typedef struct gearctl_qp_settings {
    int max_iter;          /* cap on working-set changes (additions + removals) per solve; >= 1.
                              default 1000 */
    double primal_tol;     /* a constraint counts as violated when its violation exceeds
                              primal_tol * |a_i|_2 * max(1, |x|_inf)  (|a_i| = 1 for a bound of x).
                              default 1e-12 */
    double dependence_tol; /* a constraint whose normal, in the metric of H^-1, has a component
                              orthogonal to the active normals smaller than dependence_tol times its
                              length is linearly dependent on them. default 1e-10 */
    double infinity;       /* a lower bound <= -infinity or an upper bound >= infinity is absent.
                              default GEARCTL_QP_INF = 1e20 */
} gearctl_qp_settings;

/* The data of one QP. The solver only reads through these pointers. */
typedef struct gearctl_qp_problem {
    int n;                 /* number of variables, >= 1 */
    int m;                 /* number of general rows, >= 0 */
    const double *factor;  /* gearctl_qp_factor(n, H, .) output: GEARCTL_QP_FACTOR_SIZE(n) doubles */
    const double *g;       /* linear cost, n */
    const double *a;       /* rows, m x n, ROW-major (C order): row i is a[i*n .. i*n+n-1]; may be
                              NULL if m == 0 */
    const double *lbx;     /* lower bounds of x, n (<= -infinity: none) */
    const double *ubx;     /* upper bounds of x, n (>= +infinity: none) */
    const double *lba;     /* lower bounds of A x, m (may be NULL if m == 0) */
    const double *uba;     /* upper bounds of A x, m (may be NULL if m == 0) */
} gearctl_qp_problem;

/* Where the solver writes its results. Pointers marked "may be NULL" are then skipped. */
typedef struct gearctl_qp_result {
    double *x;       /* primal solution, n (required) */
    double *lam_x;   /* multipliers of the bounds of x, n, CasADi's sign convention (may be NULL) */
    double *lam_a;   /* multipliers of the rows, m, CasADi's sign convention (may be NULL) */
    double *cost;    /* 1/2 x'Hx + g'x at x, 1 double (may be NULL) */
    int8_t *active;  /* n + m entries, bounds of x first, then the rows (may be NULL).
                        Output: -1 active at the lower bound, +1 at the upper bound, 2 an equality
                        (lb == ub) in the working set, 0 inactive (or an equality dependent on the
                        other equalities; its multiplier is then 0).
                        Input, with warm != 0: the working set to start from; -1 and +1 request the
                        lower or upper bound of that constraint, anything else is ignored, and so are
                        requests for an absent bound (equalities are always in the working set). */
    int iterations;  /* output: working-set changes made (equalities, warm start and drops included) */
} gearctl_qp_result;

/* Fill *settings with the defaults listed in gearctl_qp_settings. settings must not be NULL. */
void gearctl_qp_default_settings(gearctl_qp_settings *settings);

/* Number of doubles of the factor of an n x n Hessian: n * n. Returns 0 if n < 1. */
long gearctl_qp_factor_size(int n);

/* Number of doubles of the workspace of gearctl_qp_solve for n variables and m rows
 * (GEARCTL_QP_WORK_SIZE(n, m)). Returns 0 if n < 1 or m < 0. The workspace must be aligned as a
 * double array; its contents need not be kept between calls. */
long gearctl_qp_work_size(int n, int m);

/* Factor the Hessian once: factor = U = R^-1, where H = R'R is the Cholesky factorisation
 * (R upper triangular, positive diagonal), so that U U' = H^-1.
 *   n       number of variables, >= 1
 *   h       n x n symmetric positive definite matrix. Only the entries h[i + j*n] with i <= j are read
 *           (the upper triangle in column-major order = the lower triangle in row-major order), so a
 *           symmetric array may be passed in either order.
 *   factor  output, GEARCTL_QP_FACTOR_SIZE(n) doubles: U, column-major, upper triangular (the strictly
 *           lower part is set to 0). Must not overlap h.
 * Returns GEARCTL_QP_SOLVED (0) on success, GEARCTL_QP_NOT_POSDEF if a pivot of the factorisation is
 * not larger than n * DBL_EPSILON times the corresponding diagonal entry of H (H singular, indefinite,
 * or too ill-conditioned; factor is then unusable), GEARCTL_QP_INVALID for n < 1, a NULL pointer or a
 * non-finite entry. O(n^3) flops. */
int gearctl_qp_factor(int n, const double *h, double *factor);

/* Solve one QP.
 *   qp        the data (see gearctl_qp_problem); qp->factor from gearctl_qp_factor for the same n
 *   settings  the settings, or NULL for the defaults
 *   warm      0: start from the unconstrained minimiser (with the equalities imposed);
 *             nonzero: also start from the working set in res->active (ignored if res->active is NULL).
 *             A requested constraint that is linearly dependent on those already taken is skipped,
 *             and requested constraints whose multipliers come out with the wrong sign are removed
 *             (most negative first) before the iterations start, so any guess is safe.
 *   res       where the results go (see gearctl_qp_result)
 *   work      workspace of gearctl_qp_work_size(n, m) doubles, not shared with a concurrent solve
 * Returns
 *   GEARCTL_QP_SOLVED           x optimal; lam_x, lam_a, cost, active filled
 *   GEARCTL_QP_INFEASIBLE       the constraints are inconsistent (including some lb > ub): a violated
 *                               constraint is a combination of the working set's with no multiplier
 *                               that can give way (GI step 2(a)); x and the rest hold the last iterate
 *   GEARCTL_QP_ITERATION_LIMIT  settings->max_iter reached; x, multipliers, cost and active describe the
 *                               last iterate (optimal for the constraints in its working set only)
 *   GEARCTL_QP_NUMERICAL        a non-finite number appeared in x, in a row value A x (from a
 *                               non-finite entry of A: A is not scanned beforehand) or in the multipliers
 *   GEARCTL_QP_INVALID          n < 1, m < 0, a required pointer NULL, a NaN bound, a non-finite
 *                               entry of g, or a bad setting; nothing is written
 * In every case but GEARCTL_QP_INVALID, res->iterations is set and res->x holds an iterate. */
int gearctl_qp_solve(const gearctl_qp_problem *qp, const gearctl_qp_settings *settings, int warm,
                     gearctl_qp_result *res, double *work);

/* y = A x for a dense (rows x cols) A in C order, each row summed in index order (j = 0, 1, ...): a product
 * whose rounding does not depend on a BLAS kernel, so that the QP data a caller forms with it is the same
 * on every machine and in an exported controller that sums its rows the same way. */
void gearctl_qp_matvec(int rows, int cols, const double *a, const double *x, double *y);

/* A short English name of a status code ("solved", "infeasible", ...), or "unknown status". */
const char *gearctl_qp_status_name(int status);

#ifdef __cplusplus
}
#endif

#endif /* GEARCTL_QP_H */
