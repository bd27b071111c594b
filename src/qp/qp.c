/* SPDX-License-Identifier: MIT
 * Dual active-set QP solver of Goldfarb and Idnani (1983), for the small dense
 * QP of every time step (METHOD.md section 4). See include/gearsim/qp.h for
 * the contract and docs/explanation/qp.md for the algorithm and its tolerances.
 *
 * Notation. H = U^T U (U upper, from dpotrf; L = U^T). The active set A holds
 * nact linearly independent rows n_i (equalities first, never released), and
 * the workspace keeps J = L^{-T} Q with J^T N_A = [R; 0], R upper triangular
 * nact x nact: then H^{-1} = J J^T, the columns of J2 = J(:, nact:) span the
 * null space of N_A^T in the H-metric. Adding a row is one Householder
 * reflection of the columns nact: of J; dropping one, Givens rotations of
 * adjacent columns of J and rows of R; both O(n^2). The pair (x, u) is
 * always the minimiser on the manifold N_A^T x = b_A with its multipliers u
 * (>= 0 for inequalities): the dual objective rises with every full step,
 * so the method terminates. The final pair is recomputed from the factors
 * and refined against the data (recompute, refine_kkt). */
#include <cblas.h>
#include <float.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/qp.h"
#include "gearsim/util.h"

struct gs_qp {
    int n_max, eq_max, in_max;
    gs_qp_options opt;
    int nf;         /* order of the stored factor, 0 when none */
    double *U;      /* nf*nf column-major upper: H = U^T U */
    double *J0;     /* U^{-1} = L^{-T}, column-major upper */
    double *J;      /* n*n column-major, current L^{-T} Q */
    double *R;      /* n*n column-major, upper nact x nact used */
    double *d, *z, *r, *u, *v, *x, *x0; /* n each */
    double *an;     /* n: |L^{-1} n_k| of the active rows, by position */
    double *hv, *hw; /* n: Householder vector and product */
    double dn;      /* |L^{-1} np| of the last direction() */
    double x0n;     /* |x0|, x0 = H^{-1} c */
    int *act;       /* n: active rows; id < n_eq equality id, else inequality id - n_eq */
    double *s;      /* in_max: residuals G x - g */
    double *nrm_in; /* in_max: row norms of G */
    double *nrm_eq; /* eq_max: row norms of E */
    unsigned char *in_act; /* in_max: 0 free, 1 active, 2 parked (see solve_state) */
};

/* State of one solve, to keep the helpers' argument lists short. */
typedef struct {
    gs_qp *q;
    const gs_qp_problem *p;
    int n;
    int nact;     /* active rows */
    int neq_act;  /* of which equalities (positions 0 .. neq_act-1) */
    int n_parked; /* inequalities parked: dependent on the active rows and
                   * holding to the round-off of that combination */
} solve_state;

void gs_qp_options_default(gs_qp_options *o)
{
    o->feas_tol = 1e-12;
    o->dep_tol = 1e-11;
    o->rcond_min = 100.0 * DBL_EPSILON;
    o->max_iter = 0;
}

gs_err gs_qp_new(int n_max, int max_eq, int max_ineq, gs_qp **out)
{
    if (!out)
        return GS_EINVAL;
    *out = NULL;
    if (n_max < 1 || max_eq < 0 || max_ineq < 0 || n_max > 46340)
        return GS_EINVAL;
    gs_qp *q = gs_calloc(1, sizeof *q);
    if (!q)
        return GS_ENOMEM;
    q->n_max = n_max;
    q->eq_max = max_eq;
    q->in_max = max_ineq;
    gs_qp_options_default(&q->opt);
    size_t n = (size_t)n_max, n2 = n * n;
    q->U = gs_calloc(n2, sizeof(double));
    q->J0 = gs_calloc(n2, sizeof(double));
    q->J = gs_calloc(n2, sizeof(double));
    q->R = gs_calloc(n2, sizeof(double));
    q->d = gs_calloc(n, sizeof(double));
    q->z = gs_calloc(n, sizeof(double));
    q->r = gs_calloc(n, sizeof(double));
    q->u = gs_calloc(n, sizeof(double));
    q->v = gs_calloc(n, sizeof(double));
    q->x = gs_calloc(n, sizeof(double));
    q->x0 = gs_calloc(n, sizeof(double));
    q->act = gs_calloc(n, sizeof(int));
    q->an = gs_calloc(n, sizeof(double));
    q->hv = gs_calloc(n, sizeof(double));
    q->hw = gs_calloc(n, sizeof(double));
    q->s = gs_calloc((size_t)max_ineq, sizeof(double));
    q->nrm_in = gs_calloc((size_t)max_ineq, sizeof(double));
    q->nrm_eq = gs_calloc((size_t)max_eq, sizeof(double));
    q->in_act = gs_calloc((size_t)max_ineq, 1);
    if (!q->U || !q->J0 || !q->J || !q->R || !q->d || !q->z || !q->r || !q->u || !q->v ||
        !q->x || !q->x0 || !q->act || !q->an || !q->hv || !q->hw || !q->s || !q->nrm_in ||
        !q->nrm_eq || !q->in_act) {
        gs_qp_free(&q);
        return GS_ENOMEM;
    }
    *out = q;
    return GS_OK;
}

void gs_qp_free(gs_qp **qp)
{
    if (!qp || !*qp)
        return;
    gs_qp *q = *qp;
    free(q->U);
    free(q->J0);
    free(q->J);
    free(q->R);
    free(q->d);
    free(q->z);
    free(q->r);
    free(q->u);
    free(q->v);
    free(q->x);
    free(q->x0);
    free(q->act);
    free(q->an);
    free(q->hv);
    free(q->hw);
    free(q->s);
    free(q->nrm_in);
    free(q->nrm_eq);
    free(q->in_act);
    free(q);
    *qp = NULL;
}

gs_err gs_qp_set_options(gs_qp *q, const gs_qp_options *o)
{
    if (!q || !o)
        return GS_EINVAL;
    if (!(o->feas_tol >= 0.0 && o->feas_tol < 1.0) || !(o->dep_tol >= 0.0 && o->dep_tol < 1.0) ||
        !(o->rcond_min >= 0.0 && o->rcond_min < 1.0) || o->max_iter < 0)
        return GS_EINVAL;
    q->opt = *o;
    return GS_OK;
}

static int all_finite(const double *a, size_t n)
{
    for (size_t i = 0; i < n; i++)
        if (!isfinite(a[i]))
            return 0;
    return 1;
}

/* With U (upper, H = U^T U) in place: check conditioning, form J0 = U^{-1}.
 * anorm is the 1-norm of H. */
static gs_err finish_factor(gs_qp *q, int n, double anorm)
{
    double rcond = 0.0;
    if (LAPACKE_dpocon(LAPACK_COL_MAJOR, 'U', n, q->U, n, anorm, &rcond) != 0)
        return GS_ESINGULAR;
    if (!(rcond >= q->opt.rcond_min) || rcond == 0.0)
        return GS_ESINGULAR;
    size_t n2 = (size_t)n * (size_t)n;
    memcpy(q->J0, q->U, n2 * sizeof(double));
    if (LAPACKE_dtrtri(LAPACK_COL_MAJOR, 'U', 'N', n, q->J0, n) != 0)
        return GS_ESINGULAR;
    q->nf = n;
    return GS_OK;
}

/* Zero the strict lower triangle of the column-major n x n matrix a. */
static void zero_lower(double *a, int n)
{
    for (int j = 0; j < n; j++)
        for (int i = j + 1; i < n; i++)
            a[i + (size_t)j * n] = 0.0;
}

gs_err gs_qp_set_hessian(gs_qp *q, int n, const double *H)
{
    if (!q)
        return GS_EINVAL;
    q->nf = 0;
    if (!H || n < 1 || n > q->n_max)
        return GS_EINVAL;
    /* Row-major lower triangle == column-major upper triangle. */
    for (int i = 0; i < n; i++)
        if (!all_finite(H + (size_t)i * n, (size_t)i + 1))
            return GS_EINVAL;
    memcpy(q->U, H, (size_t)n * n * sizeof(double));
    zero_lower(q->U, n);
    double anorm = LAPACKE_dlansy(LAPACK_COL_MAJOR, '1', 'U', n, q->U, n);
    if (LAPACKE_dpotrf(LAPACK_COL_MAJOR, 'U', n, q->U, n) != 0)
        return GS_ESINGULAR;
    return finish_factor(q, n, anorm);
}

gs_err gs_qp_set_cholesky(gs_qp *q, int n, const double *L)
{
    if (!q)
        return GS_EINVAL;
    q->nf = 0;
    if (!L || n < 1 || n > q->n_max)
        return GS_EINVAL;
    for (int i = 0; i < n; i++)
        if (!all_finite(L + (size_t)i * n, (size_t)i + 1))
            return GS_EINVAL;
    memcpy(q->U, L, (size_t)n * n * sizeof(double));
    zero_lower(q->U, n);
    for (int i = 0; i < n; i++)
        if (!(q->U[i + (size_t)i * n] > 0.0))
            return GS_ESINGULAR;
    /* H = U^T U into the scratch J, only for its norm (condition estimate). */
    cblas_dsyrk(CblasColMajor, CblasUpper, CblasTrans, n, n, 1.0, q->U, n, 0.0, q->J, n);
    double anorm = LAPACKE_dlansy(LAPACK_COL_MAJOR, '1', 'U', n, q->J, n);
    return finish_factor(q, n, anorm);
}

/* Row and right-hand side of constraint id (equalities first). */
static const double *row_of(const solve_state *st, int id, double *b)
{
    const gs_qp_problem *p = st->p;
    if (id < p->n_eq) {
        *b = p->e[id];
        return p->E + (size_t)id * st->n;
    }
    id -= p->n_eq;
    *b = p->g[id];
    return p->G + (size_t)id * st->n;
}

/* Scale of |x| for round-off: x = x0 + H^{-1} N_A u is computed with an
 * error relative to the larger of its terms, and may be much smaller than
 * them (a vertex at the origin), so the residual tolerances use |x| + |x0|. */
static double x_scale(const solve_state *st)
{
    return cblas_dnrm2(st->n, st->q->x, 1) + st->q->x0n;
}

/* Round-off scale of a row that direction() found to be the combination
 * sum_k r_k n_k of the active rows: its residual inherits the residuals of
 * those rows weighted by |r_k|, so "holds to round-off" means
 * |s| <= feas_tol * (own scale + this). */
static double combination_scale(const solve_state *st, double xn)
{
    const gs_qp *q = st->q;
    double sc = 0.0;
    for (int k = 0; k < st->nact; k++) {
        double b;
        int id = q->act[k];
        (void)row_of(st, id, &b);
        double nrm = id < st->p->n_eq ? q->nrm_eq[id] : q->nrm_in[id - st->p->n_eq];
        sc += fabs(q->r[k]) * (fabs(b) + nrm * xn);
    }
    return sc;
}

/* For a candidate row np: d = J^T np, the primal step direction
 * z = J2 d2 and the dual one r = R^{-1} d1 (np = N_A r + H z). Returns
 * |d2|, the size of np outside the span of the active rows in the metric
 * of H^{-1}; sets *dependent when that is round-off: below dep_tol times
 * |d| = |L^{-1} np| plus sum_k |r_k| |L^{-1} n_k|, the size of the
 * combination that expresses np through the active rows (a row that is an
 * exact combination with large weights leaves a residue of that order). */
static double direction(solve_state *st, const double *np, int *dependent)
{
    gs_qp *q = st->q;
    int n = st->n, k = st->nact;
    cblas_dgemv(CblasColMajor, CblasTrans, n, n, 1.0, q->J, n, np, 1, 0.0, q->d, 1);
    double dn = cblas_dnrm2(n, q->d, 1);
    double d2 = k < n ? cblas_dnrm2(n - k, q->d + k, 1) : 0.0;
    if (k < n)
        cblas_dgemv(CblasColMajor, CblasNoTrans, n, n - k, 1.0, q->J + (size_t)k * n, n,
                    q->d + k, 1, 0.0, q->z, 1);
    else
        memset(q->z, 0, (size_t)n * sizeof(double));
    double comb = 0.0;
    if (k > 0) {
        memcpy(q->r, q->d, (size_t)k * sizeof(double));
        cblas_dtrsv(CblasColMajor, CblasUpper, CblasNoTrans, CblasNonUnit, k, q->R, n, q->r, 1);
        for (int i = 0; i < k; i++)
            comb += fabs(q->r[i]) * q->an[i];
    }
    *dependent = d2 <= q->opt.dep_tol * (dn + comb);
    q->dn = dn;
    return d2;
}

/* Append row id (whose d = J^T n was just computed by direction) to the active
 * set: a Householder reflection P maps d(nact:) onto its first entry, the
 * columns nact: of J are multiplied by P (J^T N_A keeps its zeros below R,
 * since P only mixes those columns), and d(0:nact] becomes the new column of
 * R. One reflection is 4 n (n - nact) flops in two BLAS-2 calls, against
 * 6 n (n - nact) in n - nact Givens rotations, and as stable. */
static void add_row(solve_state *st, int id, double mult)
{
    gs_qp *q = st->q;
    const int n = st->n, k = st->nact, m = n - k;
    double *d = q->d;
    if (m > 1) {
        double *v = q->hv, *w = q->hw;
        double alpha = cblas_dnrm2(m, d + k, 1);
        if (alpha > 0.0) {
            double beta = d[k] >= 0.0 ? -alpha : alpha; /* new d[k], no cancellation */
            memcpy(v, d + k, (size_t)m * sizeof(double));
            v[0] -= beta;
            double tau = 1.0 / (-beta * v[0]); /* 2 / v^T v */
            cblas_dgemv(CblasColMajor, CblasNoTrans, n, m, 1.0, q->J + (size_t)k * n, n, v, 1, 0.0,
                        w, 1);
            cblas_dger(CblasColMajor, n, m, -tau, w, 1, v, 1, q->J + (size_t)k * n, n);
            d[k] = beta;
        }
    }
    memcpy(q->R + (size_t)k * n, d, (size_t)(k + 1) * sizeof(double));
    q->act[k] = id;
    q->u[k] = mult;
    q->an[k] = q->dn;
    if (id >= st->p->n_eq)
        q->in_act[id - st->p->n_eq] = 1;
    st->nact++;
}

/* Remove the active row at position k: delete column k of R, restore the
 * triangle with rotations of adjacent rows, and rotate J's columns alike. */
static void drop_row(solve_state *st, int k)
{
    gs_qp *q = st->q;
    int n = st->n, m = st->nact;
    int id = q->act[k];
    if (id >= st->p->n_eq)
        q->in_act[id - st->p->n_eq] = 0;
    /* A smaller active set may no longer span the parked rows. */
    if (st->n_parked > 0) {
        for (int j = 0; j < st->p->n_in; j++)
            if (q->in_act[j] == 2)
                q->in_act[j] = 0;
        st->n_parked = 0;
    }
    for (int j = k; j < m - 1; j++) {
        memcpy(q->R + (size_t)j * n, q->R + (size_t)(j + 1) * n, (size_t)(j + 2) * sizeof(double));
        q->act[j] = q->act[j + 1];
        q->u[j] = q->u[j + 1];
        q->an[j] = q->an[j + 1];
    }
    for (int j = k; j < m - 1; j++) {
        double *a = q->R + j + (size_t)j * n;
        double h = hypot(a[0], a[1]);
        if (h == 0.0)
            continue;
        double cs = a[0] / h, sn = a[1] / h;
        a[0] = h;
        a[1] = 0.0;
        if (j + 1 < m - 1)
            cblas_drot(m - 2 - j, q->R + j + (size_t)(j + 1) * n, n,
                       q->R + j + 1 + (size_t)(j + 1) * n, n, cs, sn);
        cblas_drot(n, q->J + (size_t)j * n, 1, q->J + (size_t)(j + 1) * n, 1, cs, sn);
    }
    st->nact--;
}

/* Recompute (x, u) from scratch as the minimiser on the active manifold:
 * x = x0 + J1 v, R^T v = b_A - N_A^T x0, u = R^{-1} v. This removes the drift
 * of the incremental updates, and makes the active rows hold to round-off. */
static void recompute(solve_state *st)
{
    gs_qp *q = st->q;
    int n = st->n, k = st->nact;
    memcpy(q->x, q->x0, (size_t)n * sizeof(double));
    if (k == 0)
        return;
    for (int i = 0; i < k; i++) {
        double b;
        const double *row = row_of(st, q->act[i], &b);
        q->v[i] = b - cblas_ddot(n, row, 1, q->x0, 1);
    }
    cblas_dtrsv(CblasColMajor, CblasUpper, CblasTrans, CblasNonUnit, k, q->R, n, q->v, 1);
    cblas_dgemv(CblasColMajor, CblasNoTrans, n, k, 1.0, q->J, n, q->v, 1, 1.0, q->x, 1);
    /* One step of iterative refinement on the active rows' residuals. */
    double *w = q->d;
    for (int i = 0; i < k; i++) {
        double b;
        const double *row = row_of(st, q->act[i], &b);
        w[i] = b - cblas_ddot(n, row, 1, q->x, 1);
    }
    cblas_dtrsv(CblasColMajor, CblasUpper, CblasTrans, CblasNonUnit, k, q->R, n, w, 1);
    cblas_daxpy(k, 1.0, w, 1, q->v, 1);
    cblas_dgemv(CblasColMajor, CblasNoTrans, n, k, 1.0, q->J, n, w, 1, 1.0, q->x, 1);
    memcpy(q->u, q->v, (size_t)k * sizeof(double));
    cblas_dtrsv(CblasColMajor, CblasUpper, CblasNoTrans, CblasNonUnit, k, q->R, n, q->u, 1);
}

/* One step of iterative refinement of the whole KKT system of the active
 * set, with residuals from the data (H = U^T U, the rows themselves), so
 * that the drift of J and R over many rotations does not reach the answer:
 *     r1 = c - H x + N_A u,  r2 = b_A - N_A^T x,
 *     w = J^T r1,  R du = R^{-T} r2 - w(0:k),  dx = J2 w(k:) + J1 R^{-T} r2. */
static void refine_kkt(solve_state *st)
{
    gs_qp *q = st->q;
    const int n = st->n, k = st->nact;
    double *r1 = q->z, *w = q->d, *r2 = q->v, *t = q->r;
    /* r1 = c - U^T (U x) + sum_i u_i n_i; r2 = b - N^T x */
    memcpy(t, q->x, (size_t)n * sizeof(double));
    cblas_dtrmv(CblasColMajor, CblasUpper, CblasNoTrans, CblasNonUnit, n, q->U, n, t, 1);
    cblas_dtrmv(CblasColMajor, CblasUpper, CblasTrans, CblasNonUnit, n, q->U, n, t, 1);
    for (int i = 0; i < n; i++)
        r1[i] = st->p->c[i] - t[i];
    for (int i = 0; i < k; i++) {
        double b;
        const double *row = row_of(st, q->act[i], &b);
        cblas_daxpy(n, q->u[i], row, 1, r1, 1);
        r2[i] = b - cblas_ddot(n, row, 1, q->x, 1);
    }
    cblas_dgemv(CblasColMajor, CblasTrans, n, n, 1.0, q->J, n, r1, 1, 0.0, w, 1);
    if (k > 0) {
        cblas_dtrsv(CblasColMajor, CblasUpper, CblasTrans, CblasNonUnit, k, q->R, n, r2, 1);
        for (int i = 0; i < k; i++)
            t[i] = r2[i] - w[i];
        cblas_dtrsv(CblasColMajor, CblasUpper, CblasNoTrans, CblasNonUnit, k, q->R, n, t, 1);
        cblas_daxpy(k, 1.0, t, 1, q->u, 1);
        cblas_dgemv(CblasColMajor, CblasNoTrans, n, k, 1.0, q->J, n, r2, 1, 1.0, q->x, 1);
    }
    if (k < n)
        cblas_dgemv(CblasColMajor, CblasNoTrans, n, n - k, 1.0, q->J + (size_t)k * n, n, w + k, 1,
                    1.0, q->x, 1);
}

/* While an active inequality has a multiplier below -thr (thr relative to the
 * largest inequality multiplier), release the most negative one and
 * recompute. Leaves an S-pair: minimiser on the manifold, multipliers >= -thr.
 * Returns the number of rows released. */
static int release_negative(solve_state *st, double thr)
{
    gs_qp *q = st->q;
    int released = 0;
    for (;;) {
        double umax = 0.0;
        for (int i = st->neq_act; i < st->nact; i++)
            umax = fmax(umax, fabs(q->u[i]));
        int kmin = -1;
        double umin = -thr * umax;
        for (int i = st->neq_act; i < st->nact; i++)
            if (q->u[i] < umin) {
                umin = q->u[i];
                kmin = i;
            }
        if (kmin < 0)
            return released;
        drop_row(st, kmin);
        recompute(st);
        released++;
    }
}

/* Residuals s = G x - g; returns the most violated inactive inequality
 * (largest violation relative to its row norm) or -1. */
static int most_violated(solve_state *st)
{
    gs_qp *q = st->q;
    const gs_qp_problem *p = st->p;
    int n = st->n;
    if (p->n_in == 0)
        return -1;
    cblas_dgemv(CblasRowMajor, CblasNoTrans, p->n_in, n, 1.0, p->G, n, q->x, 1, 0.0, q->s, 1);
    double xn = x_scale(st);
    int best = -1;
    double worst = 0.0;
    for (int j = 0; j < p->n_in; j++) {
        q->s[j] -= p->g[j];
        if (q->in_act[j])
            continue;
        double tol = q->opt.feas_tol * (fabs(p->g[j]) + q->nrm_in[j] * xn);
        if (q->s[j] < -tol) {
            double rel = q->s[j] / q->nrm_in[j];
            if (best < 0 || rel < worst) {
                worst = rel;
                best = j;
            }
        }
    }
    return best;
}

static gs_err check_problem(const gs_qp *q, const gs_qp_problem *p, const int *warm, int n_warm,
                            const gs_qp_result *r)
{
    if (!p || !r || !r->x)
        return GS_EINVAL;
    if (p->n < 1 || p->n > q->n_max || p->n_eq < 0 || p->n_eq > q->eq_max || p->n_in < 0 ||
        p->n_in > q->in_max || n_warm < 0 || (n_warm > 0 && !warm))
        return GS_EINVAL;
    size_t n = (size_t)p->n;
    if (!p->c || !all_finite(p->c, n))
        return GS_EINVAL;
    if (p->n_eq > 0 && (!p->E || !p->e || !all_finite(p->E, n * (size_t)p->n_eq) ||
                        !all_finite(p->e, (size_t)p->n_eq)))
        return GS_EINVAL;
    if (p->n_in > 0 && (!p->G || !p->g || !all_finite(p->G, n * (size_t)p->n_in) ||
                        !all_finite(p->g, (size_t)p->n_in)))
        return GS_EINVAL;
    for (int i = 0; i < n_warm; i++)
        if (warm[i] < 0 || warm[i] >= p->n_in)
            return GS_EINVAL;
    return GS_OK;
}

gs_err gs_qp_solve_factored(gs_qp *q, const gs_qp_problem *p, const int *warm, int n_warm,
                            gs_qp_result *r)
{
    if (!q)
        return GS_EINVAL;
    GS_TRY(check_problem(q, p, warm, n_warm, r));
    if (q->nf != p->n)
        return GS_EINVAL;
    r->iterations = 0;
    r->n_warm_kept = 0;
    r->n_eq_dependent = 0;
    r->n_weak = 0;
    r->n_active = 0;
    r->conflict_eq = -1;
    r->conflict_in = -1;
    r->objective = 0.0;

    const int n = p->n;
    const size_t nn = (size_t)n * (size_t)n;
    const gs_qp_options *o = &q->opt;
    const int max_iter = o->max_iter > 0 ? o->max_iter : 10 * (n + p->n_eq + p->n_in) + 100;
    solve_state st = {.q = q, .p = p, .n = n, .nact = 0, .neq_act = 0, .n_parked = 0};

    for (int i = 0; i < p->n_eq; i++)
        q->nrm_eq[i] = cblas_dnrm2(n, p->E + (size_t)i * n, 1);
    for (int j = 0; j < p->n_in; j++) {
        q->nrm_in[j] = cblas_dnrm2(n, p->G + (size_t)j * n, 1);
        q->in_act[j] = 0;
        /* 0 >= g with g > 0: no x satisfies this row. */
        if (q->nrm_in[j] == 0.0 && p->g[j] > 0.0) {
            r->conflict_in = j;
            return GS_EINFEASIBLE;
        }
    }

    /* Unconstrained minimiser x0 = H^{-1} c; J = L^{-T}. */
    memcpy(q->x0, p->c, (size_t)n * sizeof(double));
    cblas_dtrsv(CblasColMajor, CblasUpper, CblasTrans, CblasNonUnit, n, q->U, n, q->x0, 1);
    cblas_dtrsv(CblasColMajor, CblasUpper, CblasNoTrans, CblasNonUnit, n, q->U, n, q->x0, 1);
    memcpy(q->x, q->x0, (size_t)n * sizeof(double));
    q->x0n = cblas_dnrm2(n, q->x0, 1);
    memcpy(q->J, q->J0, nn * sizeof(double));

    /* Equalities: each is a full step of the method (its multiplier may take
     * either sign), or, when dependent on the earlier ones, checked for
     * consistency and skipped. */
    for (int i = 0; i < p->n_eq; i++) {
        const double *row = p->E + (size_t)i * n;
        double s = cblas_ddot(n, row, 1, q->x, 1) - p->e[i];
        double tol = o->feas_tol * (fabs(p->e[i]) + q->nrm_eq[i] * x_scale(&st));
        int dependent;
        double d2 = direction(&st, row, &dependent);
        if (dependent) {
            /* A combination of earlier rows: consistent, to the round-off
             * of that combination, or the equalities contradict. */
            if (fabs(s) > tol + o->feas_tol * combination_scale(&st, x_scale(&st))) {
                r->conflict_eq = i;
                return GS_EINFEASIBLE;
            }
            r->n_eq_dependent++;
            continue;
        }
        double t = -s / (d2 * d2);
        cblas_daxpy(n, t, q->z, 1, q->x, 1);
        cblas_daxpy(st.nact, -t, q->r, 1, q->u, 1);
        add_row(&st, i, t);
        st.neq_act++;
    }
    if (st.nact > 0)
        recompute(&st);

    /* Warm start: install the guessed rows as if they were equalities, then
     * release those with negative multipliers; what remains is a valid
     * starting pair for the dual method (its objective is a lower bound). */
    if (n_warm > 0) {
        for (int w = 0; w < n_warm; w++) {
            int j = warm[w];
            if (q->in_act[j] || q->nrm_in[j] == 0.0)
                continue;
            int dependent;
            (void)direction(&st, p->G + (size_t)j * n, &dependent);
            if (dependent)
                continue;
            add_row(&st, p->n_eq + j, 0.0);
        }
        if (st.nact > st.neq_act) {
            recompute(&st);
            release_negative(&st, 0.0);
        }
        r->n_warm_kept = st.nact - st.neq_act;
    }

    /* Dual iterations. */
    int refined = 1; /* (x, u) fresh from recompute (or the start) */
    for (;;) {
        int pj = most_violated(&st);
        if (pj < 0) {
            if (refined)
                break;
            /* Converged on the incremental pair: recompute it exactly and look
             * again; round-off may have hidden or faked a violation. */
            recompute(&st);
            int rel = release_negative(&st, 1e3 * DBL_EPSILON);
            r->iterations += rel;
            refined = 1;
            continue;
        }
        refined = 0;
        const double *np = p->G + (size_t)pj * n;
        const double bp = p->g[pj];
        double unew = 0.0;
        for (;;) {
            if (r->iterations >= max_iter)
                return GS_ENOCONV;
            r->iterations++;
            double s = cblas_ddot(n, np, 1, q->x, 1) - bp;
            int dependent;
            double d2 = direction(&st, np, &dependent);
            /* Longest step keeping the active inequalities' multipliers >= 0. */
            int kdrop = -1;
            double t1 = INFINITY;
            for (int k = st.neq_act; k < st.nact; k++)
                if (q->r[k] > 0.0) {
                    double tk = fmax(q->u[k], 0.0) / q->r[k];
                    if (tk < t1) {
                        t1 = tk;
                        kdrop = k;
                    }
                }
            /* Step that makes row pj hold (z^T np = |d2|^2). */
            double t2 = dependent ? INFINITY : fmax(-s / (d2 * d2), 0.0);
            if (dependent && kdrop < 0) {
                /* np is a combination of active rows with non-positive
                 * weights on the inequalities: no x satisfies them all,
                 * unless the violation is only the round-off of that
                 * combination (degenerate, e.g. a duplicated row): then
                 * park the row until the active set shrinks. */
                double xn = x_scale(&st);
                double sc = fabs(bp) + q->nrm_in[pj] * xn + combination_scale(&st, xn);
                if (fabs(s) > o->feas_tol * sc) {
                    r->conflict_in = pj;
                    return GS_EINFEASIBLE;
                }
                q->in_act[pj] = 2;
                st.n_parked++;
                if (unew != 0.0) {
                    /* Partial steps gave pj a multiplier: restore the pair
                     * of the active set without it. */
                    recompute(&st);
                    r->iterations += release_negative(&st, 0.0);
                }
                break;
            }
            double t = fmin(t1, t2);
            if (!dependent)
                cblas_daxpy(n, t, q->z, 1, q->x, 1);
            cblas_daxpy(st.nact, -t, q->r, 1, q->u, 1);
            unew += t;
            if (t2 <= t1) {
                add_row(&st, p->n_eq + pj, unew);
                break;
            }
            q->u[kdrop] = 0.0;
            drop_row(&st, kdrop);
        }
    }

    /* Polish the final pair against the data (see refine_kkt). */
    if (st.nact > 0)
        refine_kkt(&st);

    /* Outputs. */
    memcpy(r->x, q->x, (size_t)n * sizeof(double));
    if (r->lambda_eq)
        memset(r->lambda_eq, 0, (size_t)p->n_eq * sizeof(double));
    if (r->lambda_in)
        memset(r->lambda_in, 0, (size_t)p->n_in * sizeof(double));
    for (int k = 0; k < st.nact; k++) {
        int id = q->act[k];
        if (id < p->n_eq) {
            if (r->lambda_eq)
                r->lambda_eq[id] = q->u[k];
        } else {
            double lam = fmax(q->u[k], 0.0);
            if (r->lambda_in)
                r->lambda_in[id - p->n_eq] = lam;
            if (r->active)
                r->active[r->n_active] = id - p->n_eq;
            r->n_active++;
        }
    }
    if (p->n_in > 0) {
        cblas_dgemv(CblasRowMajor, CblasNoTrans, p->n_in, n, 1.0, p->G, n, q->x, 1, 0.0, q->s, 1);
        cblas_daxpy(p->n_in, -1.0, p->g, 1, q->s, 1);
    }
    double xn = x_scale(&st);
    for (int j = 0; j < p->n_in; j++) {
        double tol = o->feas_tol * (fabs(p->g[j]) + q->nrm_in[j] * xn);
        if (q->in_act[j] == 2 || (q->in_act[j] == 0 && fabs(q->s[j]) <= tol))
            r->n_weak++;
    }
    /* Objective 1/2 |U x|^2 - c^T x. */
    memcpy(q->v, q->x, (size_t)n * sizeof(double));
    cblas_dtrmv(CblasColMajor, CblasUpper, CblasNoTrans, CblasNonUnit, n, q->U, n, q->v, 1);
    double xhx = cblas_ddot(n, q->v, 1, q->v, 1);
    r->objective = 0.5 * xhx - cblas_ddot(n, p->c, 1, q->x, 1);
    return GS_OK;
}

gs_err gs_qp_solve(gs_qp *q, const gs_qp_problem *p, const int *warm, int n_warm,
                   gs_qp_result *r)
{
    if (!q || !p)
        return GS_EINVAL;
    GS_TRY(gs_qp_set_hessian(q, p->n, p->H));
    return gs_qp_solve_factored(q, p, warm, n_warm, r);
}
