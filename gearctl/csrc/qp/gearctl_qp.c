/* SPDX-License-Identifier: MIT -- part of gearctl, written for it (no third-party code). */
/*
 * gearctl_qp.c: dense dual active-set QP solver (Goldfarb-Idnani). API and conventions: gearctl_qp.h.
 *
 * Method
 * ------
 * D. Goldfarb and A. Idnani, "A numerically stable dual method for solving strictly convex quadratic
 * programs", Math. Programming 27 (1983) 1-33 (below: GI), with the bookkeeping of its section 4.
 *
 * Every constraint is written as n_i'x >= b_i: a lower bound as (a, lb), an upper bound as (-a, -ub).
 * The method keeps a working set W of linearly independent constraints, the minimiser x of the cost
 * on {x : n_i'x = b_i, i in W} and its multipliers u (u_i >= 0 for inequalities), so x is always dual
 * feasible. Starting from the unconstrained minimiser x = -H^-1 g it repeatedly picks the most
 * violated constraint p (largest violation divided by |a_p|, i.e. farthest in x) and moves along
 * z = J2 J2' n_p (the direction H^-1 n_p restricted to the null space of W) until p holds ("full
 * step": p joins W) or an inequality multiplier reaches zero first ("partial step": that constraint
 * leaves W and the step towards p continues). The dual objective never decreases and, without
 * degeneracy, rises with every step, so no working set repeats and the method ends after finitely
 * many steps with either the optimum or a proof of infeasibility (a violated constraint whose normal
 * is a combination of the working set's normals, none of whose multipliers can give way: GI step
 * 2(a)).
 *
 * Why this method here: the MPC solves many small dense QPs whose Hessians are fixed per mode pattern,
 * so the Cholesky factor of H, the expensive part of GI's setup, is computed once; each iteration
 * then costs O(n^2) (no refactorisation), the result is exact (the EQP solution of the final working
 * set, with exact zeros for inactive multipliers) and the code is short enough to carry in exported C.
 *
 * Factorisation (GI section 4): with H = R_H'R_H (Cholesky), L = R_H' and N the matrix of the working
 * set's normals, keep the QR factorisation L^-1 N = Q [R; 0] through
 *     J = L^-T Q = [J1 J2]   (n x n; J1 has |W| columns),   R (|W| x |W|, upper triangular).
 * Then z = J2 J2' n_p, the change of the multipliers is r = R^-1 J1' n_p, and the EQP solution on W is
 *     x = J1 R^-T b_W - J2 J2' g,   u = R^-1 (R^-T b_W + J1' g).
 * J starts as U = R_H^-1 = L^-T, the "factor" the caller computes once per Hessian, so a solve does no
 * O(n^3) work on H. Adding a constraint: one Householder reflection of J2 maps d2 = J2' n_p onto its
 * first axis, O(n (n - |W|)) (the reflection's product J2 v equals z + sigma |d2| J2 e1, which the step
 * has already computed). Removing one: Givens rotations restore R to triangular form, O(n |W|).
 * Neither ever refactorises. At the end x and u are recomputed from the factorisation (not from the
 * accumulated steps) and checked once more.
 *
 * Equalities join W first (their multipliers are free in sign and never leave W). A warm start adds
 * the caller's working set without steps, computes its EQP solution and removes the most negative
 * multiplier until all have the right sign, which restores the method's invariant.
 */
#include "gearctl_qp.h"

#include <math.h>
#include <string.h>

/* No fused multiply-adds (see Reproducibility in gearctl_qp.h): clang contracts within an expression in every mode
 * wherever the target has FMA; GCC's ISO mode does not, and GCC ignores this standard pragma (warning with -Wall). */
#if defined(__clang__) || !defined(__GNUC__)
#pragma STDC FP_CONTRACT OFF
#endif

/* states of a constraint (one int8 per constraint: bounds of x first, then rows) */
enum {
    ST_INACTIVE = 0, /* an inequality not in W */
    ST_LOWER = 1,    /* in W at its lower bound (side +1) */
    ST_UPPER = 2,    /* in W at its upper bound (side -1) */
    ST_EQ_LO = 3,    /* an equality in W, written as a lower bound (side +1) */
    ST_EQ_UP = 4,    /* an equality in W, written as an upper bound (side -1) */
    ST_FREE = 5,     /* no bound at all: never looked at */
    ST_EQ_NEW = 6,   /* an equality not yet in W (only before the equality phase ends) */
    ST_REDUNDANT = 7 /* an equality dependent on the equalities in W: holds with them */
};

/* the solver's state for one solve: pointers into the caller's data and the workspace */
typedef struct {
    int n, m, q;          /* sizes; q = |W| */
    const double *U;      /* factor R_H^-1, n x n column-major */
    const double *g, *a, *lbx, *ubx, *lba, *uba;
    double *x;            /* the iterate (the caller's result array) */
    double *J;            /* n x n column-major */
    double *R;            /* n x n column-major, upper triangular in its leading q x q block */
    double *d, *z, *r, *u, *t; /* n-vectors (u: multipliers of W, in W's order) */
    double *nrm;          /* m: Euclidean norms of the rows */
    int32_t *act;         /* n: constraint index of each member of W, in W's order */
    int8_t *state;        /* n + m */
    double inf, ptol, dtol;
    int iter, max_iter;
} qp_ws;

/* ---- small helpers ------------------------------------------------------------------------------- */

static double lower_of(const qp_ws *w, int c) { return c < w->n ? w->lbx[c] : w->lba[c - w->n]; }
static double upper_of(const qp_ws *w, int c) { return c < w->n ? w->ubx[c] : w->uba[c - w->n]; }

/* side +1 writes the constraint as n'x >= lb, side -1 as -a'x >= -ub */
static int side_of_state(int st) { return (st == ST_LOWER || st == ST_EQ_LO) ? 1 : -1; }
static int is_equality_state(int st) { return st == ST_EQ_LO || st == ST_EQ_UP; }

/* a'x with four partial sums (the summation order is fixed by the source, so every compiler that
 * honours ISO C semantics gives the same bits; the four chains hide the latency of the additions) */
static double row_dot(int n, const double *restrict a, const double *restrict x)
{
    double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
    int k = 0;
    for (; k + 4 <= n; k += 4) {
        s0 += a[k] * x[k];
        s1 += a[k + 1] * x[k + 1];
        s2 += a[k + 2] * x[k + 2];
        s3 += a[k + 3] * x[k + 3];
    }
    for (; k < n; ++k) s0 += a[k] * x[k];
    return (s0 + s1) + (s2 + s3);
}

/* y = R^-1 y in place, R the leading q x q upper triangle of an n-row column-major array
 * (column-oriented: each step is an axpy on a contiguous column) */
static void solve_upper(int q, int n, const double *restrict R, double *restrict y)
{
    int i, k;
    for (k = q - 1; k >= 0; --k) {
        const double *restrict col = R + (long)k * n;
        const double yk = y[k] / col[k];
        y[k] = yk;
        for (i = 0; i < k; ++i) y[i] -= yk * col[i];
    }
}

/* Euclidean norm of row i of A, computed on first use in a solve (nrm[i] < 0: not yet) */
static double row_norm(double *nrm, int i, int n, const double *a)
{
    if (nrm[i] < 0.0) {
        const double *row = a + (long)i * n;
        nrm[i] = sqrt(row_dot(n, row, row));
    }
    return nrm[i];
}

/* a_c'x for constraint c (a bound of x, or a row) */
static double constraint_value(const qp_ws *w, int c)
{
    if (c < w->n) return w->x[c];
    return row_dot(w->n, w->a + (long)(c - w->n) * w->n, w->x);
}

/* right-hand side b of constraint c written on side s (n'x >= b) */
static double rhs_of(const qp_ws *w, int c, int side) { return side > 0 ? lower_of(w, c) : -upper_of(w, c); }

/* Givens rotation (c, s) with c*a + s*b = rho >= 0 and -s*a + c*b = 0; returns rho */
static double givens(double a, double b, double *c, double *s)
{
    double aa = fabs(a), ab = fabs(b), scale = aa > ab ? aa : ab, rho;
    if (scale == 0.0) {
        *c = 1.0;
        *s = 0.0;
        return 0.0;
    }
    a /= scale;
    b /= scale;
    rho = sqrt(a * a + b * b); /* no overflow after scaling; hypot() is several times slower here */
    *c = a / rho;
    *s = b / rho;
    return rho * scale;
}

/* ---- the factorisation of the working set ---------------------------------------------------------- */

/* d = J' n_p for constraint c on side s; returns |d|^2 split: *nd2 = |d2|^2 (components q..n-1) */
static double compute_d(qp_ws *w, int c, int side, double *nd2)
{
    const int n = w->n, q = w->q;
    const double *restrict J = w->J;
    double *restrict d = w->d;
    double all = 0.0, tail = 0.0, sgn = (double)side;
    int j;
    if (c < n) { /* a bound: J' e_c is row c of J */
        for (j = 0; j < n; ++j) d[j] = sgn * J[c + (long)j * n];
    } else {
        const double *restrict a = w->a + (long)(c - n) * n;
        for (j = 0; j < n; ++j) d[j] = sgn * row_dot(n, J + (long)j * n, a);
    }
    for (j = 0; j < q; ++j) all += d[j] * d[j];
    for (j = q; j < n; ++j) tail += d[j] * d[j];
    *nd2 = tail;
    return all + tail;
}

/* z = J2 d2 (the primal step direction) */
static void compute_z(qp_ws *w)
{
    const int n = w->n, q = w->q;
    const double *restrict J = w->J;
    const double *restrict d = w->d;
    double *restrict z = w->z;
    int i, j;
    memset(z, 0, (size_t)n * sizeof(double));
    for (j = q; j < n; ++j) {
        const double dj = d[j];
        const double *restrict col = J + (long)j * n;
        if (dj == 0.0) continue;
        for (i = 0; i < n; ++i) z[i] += dj * col[i];
    }
}

/* r = R^-1 d1 (back substitution in the leading q x q block) */
static void compute_r(qp_ws *w)
{
    if (w->q > 0) memcpy(w->r, w->d, (size_t)w->q * sizeof(double));
    solve_upper(w->q, w->n, w->R, w->r);
}

/* Append constraint c (side s) to W, with d = J'n_c and z = J2 d2 current and |d2| = nd > 0.
 * A Householder reflection P of J2 with P d2 = -sigma |d2| e1 (sigma = sign of d2[0]):
 * J2 <- J2 - beta (J2 v) v',  v = d2 + sigma |d2| e1,  beta = 1 / (|d2| (|d2| + |d2[0]|)),
 * and J2 v = z + sigma |d2| J2 e1. Overwrites z. */
static void add_to_w(qp_ws *w, int c, int side, int equality, double nd, double mult)
{
    const int n = w->n, q = w->q;
    double *restrict J = w->J;
    double *restrict z = w->z;
    const double *restrict d = w->d;
    const double d0 = d[q], sigma = d0 < 0.0 ? -1.0 : 1.0;
    double *restrict Rq = w->R + (long)q * n;
    int i, j;
    if (q + 1 == n) { /* d2 = (d0): nothing to reflect */
        for (i = 0; i < q; ++i) Rq[i] = d[i];
        Rq[q] = d0;
    } else {
        const double *Jq = J + (long)q * n; /* not restrict: column q is rewritten below */
        const double beta = 1.0 / (nd * (nd + fabs(d0)));
        for (i = 0; i < n; ++i) z[i] += sigma * nd * Jq[i]; /* z <- J2 v */
        for (j = q; j < n; ++j) {
            const double vj = (j == q ? d0 + sigma * nd : d[j]) * beta;
            double *restrict col = J + (long)j * n;
            if (vj == 0.0) continue;
            for (i = 0; i < n; ++i) col[i] -= vj * z[i];
        }
        for (i = 0; i < q; ++i) Rq[i] = d[i];
        Rq[q] = -sigma * nd;
    }
    w->act[q] = c;
    w->u[q] = mult;
    w->state[c] = (int8_t)(equality ? (side > 0 ? ST_EQ_LO : ST_EQ_UP) : (side > 0 ? ST_LOWER : ST_UPPER));
    w->q = q + 1;
    w->iter++;
}

/* Remove member k of W: delete column k of R, restore the triangle with Givens rotations on rows
 * (j, j+1) and the same rotations on columns (j, j+1) of J (J <- J G', R <- G R). */
static void drop_from_w(qp_ws *w, int k)
{
    const int n = w->n, q = w->q;
    double *restrict R = w->R;
    double *restrict J = w->J;
    int i, j, l;
    w->state[w->act[k]] = ST_INACTIVE;
    for (j = k; j + 1 < q; ++j) { /* shift the later columns left (rows 0..j+1 of column j+1) */
        memcpy(R + (long)j * n, R + (long)(j + 1) * n, (size_t)(j + 2) * sizeof(double));
        w->act[j] = w->act[j + 1];
        w->u[j] = w->u[j + 1];
    }
    for (j = k; j + 1 < q; ++j) { /* column j has one entry below the diagonal, R[j+1, j] */
        double c, s;
        double *restrict a = J + (long)j * n, *restrict b = J + (long)(j + 1) * n;
        const double sub = R[j + 1 + (long)j * n];
        if (sub == 0.0) continue;
        R[j + (long)j * n] = givens(R[j + (long)j * n], sub, &c, &s);
        R[j + 1 + (long)j * n] = 0.0;
        for (l = j + 1; l + 1 < q; ++l) {
            const double r1 = R[j + (long)l * n], r2 = R[j + 1 + (long)l * n];
            R[j + (long)l * n] = c * r1 + s * r2;
            R[j + 1 + (long)l * n] = -s * r1 + c * r2;
        }
        for (i = 0; i < n; ++i) {
            const double p1 = a[i], p2 = b[i];
            a[i] = c * p1 + s * p2;
            b[i] = -s * p1 + c * p2;
        }
    }
    w->q = q - 1;
    w->iter++;
}

/* The EQP solution on W from the factorisation: x = J1 v - J2 y2 and u = R^-1 (v + y1), where y = J'g
 * and R'v = b_W. Uses d (y) and r (v). */
static void solve_eqp(qp_ws *w)
{
    const int n = w->n, q = w->q;
    const double *restrict J = w->J;
    const double *restrict R = w->R;
    double *restrict y = w->d, *restrict v = w->r, *restrict u = w->u, *restrict x = w->x;
    int i, j;
    for (j = 0; j < n; ++j) y[j] = row_dot(n, J + (long)j * n, w->g);
    for (i = 0; i < q; ++i) { /* forward substitution with R': row i of R' is column i of R */
        const int c = w->act[i];
        const double *restrict col = R + (long)i * n;
        v[i] = (rhs_of(w, c, side_of_state(w->state[c])) - row_dot(i, col, v)) / col[i];
    }
    memset(x, 0, (size_t)n * sizeof(double));
    for (j = 0; j < n; ++j) {
        const double cj = j < q ? v[j] : -y[j];
        const double *restrict col = J + (long)j * n;
        if (cj == 0.0) continue;
        for (i = 0; i < n; ++i) x[i] += cj * col[i];
    }
    for (i = 0; i < q; ++i) u[i] = v[i] + y[i];
    solve_upper(q, n, R, u);
}

/* ---- one GI iteration: bring constraint c (side s) into W -------------------------------------------- */

enum { ADD_DONE = 0, ADD_INFEASIBLE = 1, ADD_LIMIT = 2, ADD_REDUNDANT = 3 };

/* GI step 2: move towards constraint c until it holds (it joins W) or it is proved inconsistent,
 * removing the inequalities whose multipliers reach zero on the way. An equality (equality != 0) that
 * is dependent on W and holds is reported ADD_REDUNDANT. */
static int add_constraint(qp_ws *w, int c, int side, int equality)
{
    const int n = w->n;
    const double b = rhs_of(w, c, side);
    double uplus = 0.0; /* multiplier of c, grown by every step */
    int i;
    for (;;) {
        double nd2, dd, t1 = HUGE_VAL, t2, t, slack, rmin = 0.0;
        int k = -1, dependent;
        if (w->iter >= w->max_iter) return ADD_LIMIT;
        dd = compute_d(w, c, side, &nd2);
        dependent = !(nd2 > w->dtol * w->dtol * dd); /* |d2| <= dtol |d| (also catches d = 0) */
        compute_r(w);
        if (dependent) { /* r is then the combination n_c = N r: a coefficient at rounding level is zero */
            for (i = 0; i < w->q; ++i)
                if (fabs(w->r[i]) > rmin) rmin = fabs(w->r[i]);
            rmin *= w->dtol;
        }
        for (i = 0; i < w->q; ++i) { /* GI step 2(b): largest dual step, over inequalities only */
            const int st = w->state[w->act[i]];
            if (w->r[i] > rmin && !is_equality_state(st)) {
                const double ti = w->u[i] / w->r[i];
                if (ti < t1) {
                    t1 = ti;
                    k = i;
                }
            }
        }
        slack = (double)side * constraint_value(w, c) - b; /* < 0 while c is violated */
        if (dependent) { /* a dual step alone (no primal direction), unbounded if nothing can give way */
            if (k < 0) { /* GI step 2(a): nothing can give way */
                if (equality && fabs(slack) <= w->ptol * (c < n ? 1.0 : row_norm(w->nrm, c - n, n, w->a)))
                    return ADD_REDUNDANT;
                return ADD_INFEASIBLE;
            }
            for (i = 0; i < w->q; ++i) w->u[i] -= t1 * w->r[i]; /* dual step only */
            uplus += t1;
            drop_from_w(w, k);
            continue;
        }
        compute_z(w);
        t2 = slack < 0.0 ? -slack / nd2 : 0.0; /* z'n_c = |d2|^2 */
        t = t2 <= t1 ? t2 : t1;
        for (i = 0; i < n; ++i) w->x[i] += t * w->z[i];
        for (i = 0; i < w->q; ++i) w->u[i] -= t * w->r[i];
        uplus += t;
        if (t2 <= t1) { /* full step: c holds */
            add_to_w(w, c, side, equality, sqrt(nd2), uplus);
            return ADD_DONE;
        }
        drop_from_w(w, k); /* partial step: member k's multiplier is zero */
    }
}

/* ---- the public functions ------------------------------------------------------------------------ */

void gearctl_qp_default_settings(gearctl_qp_settings *settings)
{
    settings->max_iter = 1000;
    settings->primal_tol = 1e-12;
    settings->dependence_tol = 1e-10;
    settings->infinity = GEARCTL_QP_INF;
}

long gearctl_qp_factor_size(int n) { return n < 1 ? 0 : GEARCTL_QP_FACTOR_SIZE(n); }

long gearctl_qp_work_size(int n, int m) { return (n < 1 || m < 0) ? 0 : GEARCTL_QP_WORK_SIZE(n, m); }

void gearctl_qp_matvec(int rows, int cols, const double *a, const double *x, double *y)
{
    for (int i = 0; i < rows; i++) {
        const double *ai = a + (long)i * cols;
        double acc = 0.0;
        for (int j = 0; j < cols; j++) acc += ai[j] * x[j];
        y[i] = acc;
    }
}

const char *gearctl_qp_status_name(int status)
{
    switch (status) {
    case GEARCTL_QP_SOLVED: return "solved";
    case GEARCTL_QP_INFEASIBLE: return "infeasible";
    case GEARCTL_QP_ITERATION_LIMIT: return "iteration limit";
    case GEARCTL_QP_NUMERICAL: return "numerical failure";
    case GEARCTL_QP_NOT_POSDEF: return "Hessian not positive definite";
    case GEARCTL_QP_INVALID: return "invalid input";
    default: return "unknown status";
    }
}

int gearctl_qp_factor(int n, const double *h, double *factor)
{
    const double eps = 2.220446049250313e-16; /* DBL_EPSILON, without <float.h> */
    double *restrict U = factor;
    int i, j, k;
    if (n < 1 || h == 0 || factor == 0) return GEARCTL_QP_INVALID;
    /* Cholesky H = R'R, R upper triangular, column by column (reads h[i + j*n], i <= j only) */
    for (j = 0; j < n; ++j) {
        double piv = 0.0;
        for (i = 0; i <= j; ++i) {
            double s = h[i + (long)j * n];
            if (!isfinite(s)) return GEARCTL_QP_INVALID;
            for (k = 0; k < i; ++k) s -= U[k + (long)i * n] * U[k + (long)j * n];
            if (i < j) U[i + (long)j * n] = s / U[i + (long)i * n];
            else piv = s;
        }
        /* a pivot that rounding alone could produce means H is numerically singular or indefinite */
        if (!(piv > (double)n * eps * fabs(h[j + (long)j * n]))) return GEARCTL_QP_NOT_POSDEF;
        U[j + (long)j * n] = sqrt(piv);
        for (i = j + 1; i < n; ++i) U[i + (long)j * n] = 0.0;
    }
    /* invert R in place, column by column: for i < j, U_ij = -U_jj sum_{i <= k < j} U_ik R_kj */
    for (j = 0; j < n; ++j) {
        double *restrict col = U + (long)j * n;
        const double ujj = 1.0 / col[j];
        col[j] = ujj;
        for (i = 0; i < j; ++i) { /* rows ascending: R_kj for k > i is still unread when row i is written */
            double s = 0.0;
            for (k = i; k < j; ++k) s += U[i + (long)k * n] * col[k];
            col[i] = -ujj * s;
        }
    }
    return GEARCTL_QP_SOLVED;
}

int gearctl_qp_solve(const gearctl_qp_problem *qp, const gearctl_qp_settings *settings, int warm,
                     gearctl_qp_result *res, double *work)
{
    gearctl_qp_settings defaults;
    qp_ws W, *w = &W;
    int n, m, nc, c, i, j, status = GEARCTL_QP_SOLVED, refined = 1; /* x is exact until a step is taken */
    double xmax;

    /* ---- checks, before anything is written ---- */
    if (qp == 0 || res == 0 || work == 0 || res->x == 0) return GEARCTL_QP_INVALID;
    n = qp->n;
    m = qp->m;
    if (n < 1 || m < 0 || qp->factor == 0 || qp->g == 0 || qp->lbx == 0 || qp->ubx == 0) return GEARCTL_QP_INVALID;
    if (m > 0 && (qp->a == 0 || qp->lba == 0 || qp->uba == 0)) return GEARCTL_QP_INVALID;
    if (settings == 0) {
        gearctl_qp_default_settings(&defaults);
        settings = &defaults;
    }
    if (settings->max_iter < 1 || !(settings->primal_tol >= 0.0) || !(settings->dependence_tol >= 0.0) ||
        !(settings->infinity > 0.0))
        return GEARCTL_QP_INVALID;
    nc = n + m;
    for (i = 0; i < n; ++i)
        if (!isfinite(qp->g[i]) || isnan(qp->lbx[i]) || isnan(qp->ubx[i])) return GEARCTL_QP_INVALID;
    for (i = 0; i < m; ++i)
        if (isnan(qp->lba[i]) || isnan(qp->uba[i])) return GEARCTL_QP_INVALID;

    /* ---- workspace ---- */
    w->n = n;
    w->m = m;
    w->q = 0;
    w->U = qp->factor;
    w->g = qp->g;
    w->a = qp->a;
    w->lbx = qp->lbx;
    w->ubx = qp->ubx;
    w->lba = qp->lba;
    w->uba = qp->uba;
    w->x = res->x;
    w->J = work;
    w->R = w->J + (long)n * n;
    w->d = w->R + (long)n * n;
    w->z = w->d + n;
    w->r = w->z + n;
    w->u = w->r + n;
    w->t = w->u + n;
    w->nrm = w->t + n;
    w->act = (int32_t *)(void *)(w->nrm + m); /* int32 and int8 after the doubles: alignment holds */
    w->state = (int8_t *)(void *)(w->nrm + m + (n + 1L) / 2L);
    w->inf = settings->infinity;
    w->ptol = settings->primal_tol;
    w->dtol = settings->dependence_tol;
    w->iter = 0;
    w->max_iter = settings->max_iter;

    for (i = 0; i < m; ++i) w->nrm[i] = -1.0; /* row norms: computed when first needed */

    /* classify the constraints; lb > ub is infeasible, found here before any work */
    for (c = 0; c < nc; ++c) {
        const double lb = lower_of(w, c), ub = upper_of(w, c);
        const int has_lo = lb > -w->inf, has_up = ub < w->inf;
        if (has_lo && has_up && lb > ub) status = GEARCTL_QP_INFEASIBLE;
        w->state[c] = (int8_t)(!has_lo && !has_up ? ST_FREE : (has_lo && has_up && lb == ub ? ST_EQ_NEW : ST_INACTIVE));
    }

    /* ---- the unconstrained minimiser x = -U U' g, and J = U ---- */
    memcpy(w->J, w->U, (size_t)n * (size_t)n * sizeof(double));
    memset(w->x, 0, (size_t)n * sizeof(double));
    for (j = 0; j < n; ++j) { /* column j of U has rows 0..j */
        const double *restrict col = w->U + (long)j * n;
        const double tj = row_dot(j + 1, col, w->g);
        for (i = 0; i <= j; ++i) w->x[i] -= tj * col[i];
    }
    if (status != GEARCTL_QP_SOLVED) goto finish;

    /* ---- equalities first (GI: their multipliers are free and they never leave W) ---- */
    for (c = 0; c < nc; ++c) {
        int side, rc;
        if (w->state[c] != ST_EQ_NEW) continue;
        side = constraint_value(w, c) <= lower_of(w, c) ? 1 : -1; /* the side on which x lies */
        rc = add_constraint(w, c, side, 1);
        if (rc == ADD_REDUNDANT) w->state[c] = ST_REDUNDANT;
        else if (rc == ADD_INFEASIBLE) status = GEARCTL_QP_INFEASIBLE;
        else if (rc == ADD_LIMIT) status = GEARCTL_QP_ITERATION_LIMIT;
        if (status != GEARCTL_QP_SOLVED) goto finish;
    }
    refined = w->iter == 0; /* after steps, x is recomputed from the factorisation at the end */

    /* ---- warm start: take the requested working set, then restore dual feasibility ---- */
    if (warm && res->active != 0) {
        int added = 0;
        for (c = 0; c < nc; ++c) {
            const int want = res->active[c];
            double nd2, dd;
            if (w->state[c] != ST_INACTIVE || (want != 1 && want != -1) || w->q >= n) continue;
            if (want == -1 ? !(lower_of(w, c) > -w->inf) : !(upper_of(w, c) < w->inf)) continue;
            dd = compute_d(w, c, -want, &nd2); /* active[] = -1 is the lower bound: side +1 */
            if (!(nd2 > w->dtol * w->dtol * dd)) continue; /* dependent on those taken: skip */
            compute_z(w);
            add_to_w(w, c, -want, 0, sqrt(nd2), 0.0);
            added = 1;
        }
        while (added) {
            int k = -1;
            double most = 0.0;
            solve_eqp(w);
            for (i = 0; i < w->q; ++i)
                if (!is_equality_state(w->state[w->act[i]]) && w->u[i] < most) {
                    most = w->u[i];
                    k = i;
                }
            if (k < 0) break;
            drop_from_w(w, k);
        }
        if (added) refined = 1; /* solve_eqp made x exact */
    }

    /* ---- GI iterations ---- */
    for (;;) {
        int best = -1, best_side = 0;
        double best_v = 0.0, tol;
        int finite = 1;
        xmax = 1.0;
        for (i = 0; i < n; ++i) {
            const double ax = fabs(w->x[i]);
            if (ax > xmax) xmax = ax;
            else if (!(ax <= xmax)) finite = 0; /* NaN */
        }
        if (!finite || !isfinite(xmax)) {
            status = GEARCTL_QP_NUMERICAL;
            break;
        }
        tol = w->ptol * xmax;
        /* GI step 1: the most violated constraint, measured as a distance (violation / |a_c|) */
        for (c = 0; c < nc; ++c) {
            double v, viol, lb, ub;
            int side;
            if (w->state[c] != ST_INACTIVE) continue;
            v = constraint_value(w, c);
            if (!isfinite(v)) { /* x is finite here: a non-finite entry of A */
                finite = 0;
                break;
            }
            lb = lower_of(w, c);
            ub = upper_of(w, c);
            if (lb > -w->inf && lb - v > 0.0) {
                viol = lb - v;
                side = 1;
            } else if (ub < w->inf && v - ub > 0.0) {
                viol = v - ub;
                side = -1;
            } else {
                continue;
            }
            { /* compare the distance viol / |a_c| with the tolerance */
                const double nr = c < n ? 1.0 : row_norm(w->nrm, c - n, n, w->a);
                const double dist = nr > 0.0 ? viol / nr : HUGE_VAL;
                if (viol > tol * nr && dist > best_v) {
                    best_v = dist;
                    best = c;
                    best_side = side;
                }
            }
        }
        if (!finite) {
            status = GEARCTL_QP_NUMERICAL;
            break;
        }
        if (best < 0) {
            int k = -1;
            double most = 0.0;
            if (refined) break; /* optimal */
            /* recompute x and u from the factorisation, not from the accumulated steps, and look again */
            solve_eqp(w);
            refined = 1;
            for (i = 0; i < w->q; ++i)
                if (!is_equality_state(w->state[w->act[i]]) && w->u[i] < most) {
                    most = w->u[i];
                    k = i;
                }
            if (k >= 0) { /* a multiplier of the wrong sign (rounding): drop it, solve again */
                if (w->iter >= w->max_iter) {
                    status = GEARCTL_QP_ITERATION_LIMIT;
                    break;
                }
                drop_from_w(w, k);
                refined = 0;
            }
            continue;
        }
        {
            const int rc = add_constraint(w, best, best_side, 0);
            refined = 0;
            if (rc == ADD_INFEASIBLE) status = GEARCTL_QP_INFEASIBLE;
            else if (rc == ADD_LIMIT) status = GEARCTL_QP_ITERATION_LIMIT;
            if (status != GEARCTL_QP_SOLVED) break;
        }
    }

finish:
    res->iterations = w->iter;
    if (res->lam_x != 0) memset(res->lam_x, 0, (size_t)n * sizeof(double));
    if (res->lam_a != 0 && m > 0) memset(res->lam_a, 0, (size_t)m * sizeof(double));
    for (i = 0; i < w->q; ++i) {
        const int ci = w->act[i];
        const double lam = -(double)side_of_state(w->state[ci]) * w->u[i];
        if (!isfinite(lam) && status == GEARCTL_QP_SOLVED) status = GEARCTL_QP_NUMERICAL;
        if (ci < n) {
            if (res->lam_x != 0) res->lam_x[ci] = lam;
        } else if (res->lam_a != 0) {
            res->lam_a[ci - n] = lam;
        }
    }
    if (res->active != 0) {
        for (c = 0; c < nc; ++c) {
            const int st = w->state[c];
            res->active[c] = (int8_t)(st == ST_LOWER ? -1 : st == ST_UPPER ? 1 : is_equality_state(st) ? 2 : 0);
        }
    }
    if (res->cost != 0) { /* 1/2 |R_H x|^2 + g'x, with R_H x = U^-1 x by back substitution */
        memcpy(w->t, w->x, (size_t)n * sizeof(double));
        solve_upper(n, n, w->U, w->t);
        res->cost[0] = 0.5 * row_dot(n, w->t, w->t) + row_dot(n, w->g, w->x);
    }
    return status;
}
