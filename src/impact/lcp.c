/* SPDX-License-Identifier: MIT
 * Lemke's complementary pivoting method for the LCP
 *     w = A z + q,  z >= 0,  w >= 0,  z^T w = 0
 * (docs/explanation/impact.md, "Lemke"). Dense tableau, covering vector 1, a
 * lexicographic minimum-ratio test against cycling on degenerate problems,
 * and at the end the basis system re-solved from A and q (LU with partial
 * pivoting) and the solution verified against the data. */
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <lapacke.h>

#include "gearsim/impact.h"

const char *gs_lcp_status_name(gs_lcp_status s)
{
    switch (s) {
    case GS_LCP_SOLVED: return "solved";
    case GS_LCP_RAY: return "ray";
    case GS_LCP_MAX_ITER: return "max_iter";
    case GS_LCP_INACCURATE: return "inaccurate";
    }
    return "unknown";
}

/* Variables: 0..n-1 are w, n..2n-1 are z, 2n is the artificial z0. The
 * tableau holds B^{-1} [I, -A, -1 | q] row-major with width 2n+2. */
typedef struct {
    int n, width;
    double *T;
    int *basis;
} tableau;

#define TAB(t, i, j) ((t)->T[(size_t)(i) * (t)->width + (j)])

static void pivot(tableau *t, int r, int col)
{
    double inv = 1.0 / TAB(t, r, col);
    for (int j = 0; j < t->width; j++)
        TAB(t, r, j) *= inv;
    TAB(t, r, col) = 1.0;
    for (int i = 0; i < t->n; i++) {
        if (i == r)
            continue;
        double f = TAB(t, i, col);
        if (f == 0.0)
            continue;
        for (int j = 0; j < t->width; j++)
            TAB(t, i, j) -= f * TAB(t, r, j);
        TAB(t, i, col) = 0.0;
    }
    t->basis[r] = col;
}

/* Lexicographic minimum ratio over rows with c_i > tol: compare
 * (rhs_i, B^{-1}_i.) / c_i; the columns of B^{-1} are the tableau's w columns.
 * The artificial variable leaves whenever it ties for the minimum ratio.
 * Right-hand sides below rtol (round-off at the data's scale, which the
 * small differences of large numbers in the tableau carry) count as 0, and
 * ratios that differ by less than that round-off tie, so that degenerate
 * rows are resolved by the lexicographic rule, not by noise. */
static int ratio_test(const tableau *t, int col, double tol, double rtol)
{
    const int n = t->n, rhs = t->width - 1;
    int best = -1;
    for (int i = 0; i < n; i++) {
        double ci = TAB(t, i, col);
        if (!(ci > tol))
            continue;
        if (best < 0) {
            best = i;
            continue;
        }
        double cb = TAB(t, best, col);
        /* right-hand sides within round-off of zero are degenerate: exact ties */
        double ri = TAB(t, i, rhs), rb = TAB(t, best, rhs);
        double a = (ri > rtol ? ri : 0.0) / ci, b = (rb > rtol ? rb : 0.0) / cb;
        /* ratios within the round-off of their right-hand sides tie */
        double tie = 1e-12 * fmax(a, b) + rtol * (1.0 / ci + 1.0 / cb);
        if (a < b - tie) {
            best = i;
            continue;
        }
        if (a > b + tie)
            continue;
        /* tie */
        if (t->basis[i] == 2 * n) {
            best = i;
            continue;
        }
        if (t->basis[best] == 2 * n)
            continue;
        for (int j = 0; j < n; j++) {
            double x = TAB(t, i, j) / ci, y = TAB(t, best, j) / cb;
            if (x < y - 1e-14 * fmax(fabs(x), fabs(y))) {
                best = i;
                break;
            }
            if (x > y + 1e-14 * fmax(fabs(x), fabs(y)))
                break;
        }
    }
    return best;
}

/* Numerical rank of the k x k matrix M (overwritten) by Gaussian elimination
 * with complete pivoting, pivots below tol * max|M| counted as zero. */
static int rank_full_pivot(int k, double *M, double tol)
{
    double mx = 0.0;
    for (int i = 0; i < k * k; i++)
        mx = fmax(mx, fabs(M[i]));
    if (mx == 0.0)
        return 0;
    int rank = 0;
    for (int s = 0; s < k; s++) {
        int pi = s, pj = s;
        double best = -1.0;
        for (int i = s; i < k; i++)
            for (int j = s; j < k; j++)
                if (fabs(M[i * k + j]) > best) {
                    best = fabs(M[i * k + j]);
                    pi = i;
                    pj = j;
                }
        if (best <= tol * mx)
            break;
        for (int j = 0; j < k; j++) { /* swap rows */
            double x = M[s * k + j];
            M[s * k + j] = M[pi * k + j];
            M[pi * k + j] = x;
        }
        for (int i = 0; i < k; i++) { /* swap columns */
            double x = M[i * k + s];
            M[i * k + s] = M[i * k + pj];
            M[i * k + pj] = x;
        }
        for (int i = s + 1; i < k; i++) {
            double f = M[i * k + s] / M[s * k + s];
            for (int j = s; j < k; j++)
                M[i * k + j] -= f * M[s * k + j];
        }
        rank++;
    }
    return rank;
}

/* Residual of a candidate z: w = A z + q; the largest of the negative parts of
 * z and w and of min(z_i, w_i), relative to max|q| + max|A| max|z|. */
static double verify(int n, const double *A, const double *q, const double *z, double *w)
{
    double amax = 0.0, qmax = 0.0, zmax = 0.0;
    for (int i = 0; i < n * n; i++)
        amax = fmax(amax, fabs(A[i]));
    for (int i = 0; i < n; i++) {
        qmax = fmax(qmax, fabs(q[i]));
        zmax = fmax(zmax, fabs(z[i]));
    }
    double scale = qmax + amax * zmax;
    if (scale == 0.0)
        scale = 1.0;
    double res = 0.0;
    for (int i = 0; i < n; i++) {
        double s = q[i];
        for (int j = 0; j < n; j++)
            s += A[(size_t)i * n + j] * z[j];
        w[i] = s;
        res = fmax(res, fmax(-z[i], -w[i]));
        res = fmax(res, fmin(fabs(z[i]), fabs(w[i])));
    }
    return res / scale;
}

/* Re-solve B x = q for the final basis from the original data. */
static bool resolve_basis(int n, const double *A, const double *q, const int *basis, double *z)
{
    double *B = malloc((size_t)n * n * sizeof *B), *x = malloc((size_t)n * sizeof *x);
    lapack_int *ipiv = malloc((size_t)n * sizeof *ipiv);
    bool ok = B && x && ipiv;
    if (ok) {
        for (int i = 0; i < n; i++)
            for (int c = 0; c < n; c++) {
                int v = basis[c];
                B[(size_t)i * n + c] = v < n ? (i == v ? 1.0 : 0.0) : -A[(size_t)i * n + (v - n)];
            }
        memcpy(x, q, (size_t)n * sizeof *x);
        ok = LAPACKE_dgesv(LAPACK_ROW_MAJOR, n, 1, B, n, ipiv, x, 1) == 0;
    }
    if (ok) {
        memset(z, 0, (size_t)n * sizeof *z);
        for (int c = 0; c < n; c++)
            if (basis[c] >= n && basis[c] < 2 * n)
                z[basis[c] - n] = fmax(x[c], 0.0);
    }
    free(B);
    free(x);
    free(ipiv);
    return ok;
}

static void classify(int n, const double *A, const double *z, const double *w, gs_lcp_info *info)
{
    double zmax = 0.0, wmax = 0.0;
    for (int i = 0; i < n; i++) {
        zmax = fmax(zmax, fabs(z[i]));
        wmax = fmax(wmax, fabs(w[i]));
    }
    const double ztol = 1e-9 * zmax, wtol = 1e-9 * fmax(wmax, DBL_MIN);
    int *act = malloc((size_t)n * sizeof *act);
    int k = 0;
    info->n_degenerate = 0;
    for (int i = 0; i < n; i++) {
        if (z[i] > ztol && zmax > 0.0)
            act[k++] = i;
        else if (fabs(w[i]) <= wtol)
            info->n_degenerate++;
    }
    info->n_active = k;
    info->rank_active = 0;
    if (k > 0 && act) {
        double *M = malloc((size_t)k * k * sizeof *M);
        if (M) {
            for (int a = 0; a < k; a++)
                for (int b = 0; b < k; b++)
                    M[a * k + b] = A[(size_t)act[a] * n + act[b]];
            info->rank_active = rank_full_pivot(k, M, 1e-10);
        }
        free(M);
    }
    info->multiple = info->rank_active < info->n_active;
    free(act);
}

gs_err gs_lcp_lemke(int n, const double *A, const double *q, double *z, double *w, int max_pivots,
                    gs_lcp_info *info)
{
    gs_lcp_info dummy;
    if (!info)
        info = &dummy;
    memset(info, 0, sizeof *info);
    if (n < 1 || !A || !q || !z || !w)
        return GS_EINVAL;
    for (int i = 0; i < n; i++) {
        if (!isfinite(q[i]))
            return GS_EINVAL;
        for (int j = 0; j < n; j++)
            if (!isfinite(A[(size_t)i * n + j]))
                return GS_EINVAL;
    }
    if (max_pivots <= 0)
        max_pivots = 50 * n + 100;

    int r0 = 0;
    for (int i = 1; i < n; i++)
        if (q[i] < q[r0])
            r0 = i;
    if (q[r0] >= 0.0) { /* z = 0 */
        memset(z, 0, (size_t)n * sizeof *z);
        memcpy(w, q, (size_t)n * sizeof *w);
        info->status = GS_LCP_SOLVED;
        classify(n, A, z, w, info);
        return GS_OK;
    }

    tableau t = {n, 2 * n + 2, NULL, NULL};
    t.T = calloc((size_t)n * t.width, sizeof *t.T);
    t.basis = malloc((size_t)n * sizeof *t.basis);
    if (!t.T || !t.basis) {
        free(t.T);
        free(t.basis);
        return GS_ENOMEM;
    }
    for (int i = 0; i < n; i++) {
        TAB(&t, i, i) = 1.0;
        for (int j = 0; j < n; j++)
            TAB(&t, i, n + j) = -A[(size_t)i * n + j];
        TAB(&t, i, 2 * n) = -1.0;
        TAB(&t, i, 2 * n + 1) = q[i];
        t.basis[i] = i;
    }

    double qmax = 0.0;
    for (int i = 0; i < n; i++)
        qmax = fmax(qmax, fabs(q[i]));
    const double rtol = 1e-11 * qmax;
    gs_err err = GS_OK;
    pivot(&t, r0, 2 * n); /* z0 enters at the most negative q, w_r0 leaves */
    int entering = n + r0, pivots = 1;
    for (;;) {
        if (pivots >= max_pivots) {
            info->status = GS_LCP_MAX_ITER;
            err = GS_ENOCONV;
            break;
        }
        double cmax = 0.0;
        for (int i = 0; i < n; i++)
            cmax = fmax(cmax, fabs(TAB(&t, i, entering)));
        int r = ratio_test(&t, entering, 1e-12 * fmax(cmax, 1e-300), rtol);
        if (r < 0) {
            info->status = GS_LCP_RAY;
            err = GS_EINFEASIBLE;
            break;
        }
        int leaving = t.basis[r];
        pivot(&t, r, entering);
        pivots++;
        if (leaving == 2 * n) {
            info->status = GS_LCP_SOLVED;
            break;
        }
        entering = leaving < n ? leaving + n : leaving - n;
    }
    info->pivots = pivots;

    if (err == GS_OK) {
        memset(z, 0, (size_t)n * sizeof *z);
        for (int i = 0; i < n; i++)
            if (t.basis[i] >= n && t.basis[i] < 2 * n)
                z[t.basis[i] - n] = fmax(TAB(&t, i, 2 * n + 1), 0.0);
        double res = verify(n, A, q, z, w);
        double *z2 = malloc((size_t)n * sizeof *z2), *w2 = malloc((size_t)n * sizeof *w2);
        if (z2 && w2 && resolve_basis(n, A, q, t.basis, z2)) {
            double res2 = verify(n, A, q, z2, w2);
            if (res2 <= res) {
                memcpy(z, z2, (size_t)n * sizeof *z);
                memcpy(w, w2, (size_t)n * sizeof *w);
                res = res2;
            }
        }
        free(z2);
        free(w2);
        info->residual = res;
        if (!(res <= 1e-8)) {
            info->status = GS_LCP_INACCURATE;
            err = GS_ENOCONV;
        }
        classify(n, A, z, w, info);
    }
    free(t.T);
    free(t.basis);
    return err;
}
