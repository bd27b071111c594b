/* SPDX-License-Identifier: MIT
 * Compliant line contact: the candidate contact region split into strips
 * of uniform pressure, the normal displacements from the influence
 * coefficients of the elastic half-plane (plane strain), frictionless
 * contact as the QP of minimum complementary energy (METHOD.md section 6,
 * docs/explanation/impact.md "Compliant contact"). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/impact.h"
#include "gearsim/qp.h"

/* u - u ln(|u| / datum): the integral of -ln(|u| / datum). */
static double F(double u, double datum)
{
    return u == 0.0 ? 0.0 : u - u * log(fabs(u) / datum);
}

double gs_compliant_influence(double s, double width, double e_star, double datum)
{
    return 2.0 / (GS_PI * e_star) * (F(s + 0.5 * width, datum) - F(s - 0.5 * width, datum));
}

/* Where the pressure vanishes beyond the outermost loaded strip j (towards
 * neighbour j + dir): p^2 is linear in x near a Hertzian edge, so extrapolate
 * p^2 from strips j - dir and j to zero, kept within the strip j + dir. */
static double edge(const double *x, const double *p, int n, int j, int dir, double w)
{
    int in = j - dir;
    double xe = x[j] + dir * 0.5 * w;
    if (in >= 0 && in < n && p[in] > p[j]) {
        double a = p[in] * p[in], b = p[j] * p[j];
        xe = x[j] + (x[j] - x[in]) * b / (a - b);
    }
    double lim = x[j] + dir * w;
    return dir > 0 ? fmin(fmax(xe, x[j]), lim) : fmax(fmin(xe, x[j]), lim);
}

gs_err gs_compliant_solve(const gs_compliant_problem *p, gs_compliant_result *r, gs_diag *d)
{
    if (!p || !r || !r->pressure)
        return gs_diag_set(d, GS_EINVAL, "", "NULL argument");
    if (p->n < 1 || p->n > 2000)
        return gs_diag_set(d, GS_ERANGE, "patches", "'patches' = %d is outside [1, 2000]", p->n);
    if (!(p->x1 > p->x0) || !isfinite(p->x0) || !isfinite(p->x1))
        return gs_diag_set(d, GS_ERANGE, "region", "the region [%g, %g] is empty", p->x0, p->x1);
    if (!p->gap && (!(p->radius > 0.0) || !isfinite(p->radius)))
        return gs_diag_set(d, GS_ERANGE, "radius", "'radius' = %g must be > 0", p->radius);
    if (!(p->e_star > 0.0) || !isfinite(p->e_star))
        return gs_diag_set(d, GS_ERANGE, "e_star", "'e_star' = %g must be > 0", p->e_star);
    if (!(p->load > 0.0) || !isfinite(p->load))
        return gs_diag_set(d, GS_ERANGE, "load", "'load' = %g must be > 0", p->load);
    const int n = p->n;
    const double w = (p->x1 - p->x0) / n;
    /* -ln(|u| / datum) is positive definite on an interval shorter than
     * 4 datum (logarithmic capacity); the default keeps C well inside. */
    const double datum = p->datum > 0.0 ? p->datum : 10.0 * (p->x1 - p->x0);
    if (datum < p->x1 - p->x0)
        return gs_diag_set(d, GS_ERANGE, "datum", "'datum' = %g must be at least the region length",
                           datum);

    double *x = malloc((size_t)n * sizeof *x), *H = malloc((size_t)n * n * sizeof *H);
    double *c = malloc((size_t)n * sizeof *c), *G = calloc((size_t)n * n, sizeof *G);
    double *g = calloc((size_t)n, sizeof *g), *E = malloc((size_t)n * sizeof *E);
    double *f = malloc((size_t)n * sizeof *f), *gap = malloc((size_t)n * sizeof *gap);
    gs_qp *qp = NULL;
    gs_err err = GS_OK;
    if (!x || !H || !c || !G || !g || !E || !f || !gap) {
        err = GS_ENOMEM;
        goto out;
    }
    /* Unknowns f_j = p_j w (force per unit length of strip j). C_ij is the
     * displacement at x_i per unit force at strip j. Scaled by E* so the QP
     * data are of order one (the solver's tolerances are relative anyway). */
    for (int i = 0; i < n; i++)
        x[i] = p->x0 + (i + 0.5) * w;
    for (int i = 0; i < n; i++) {
        for (int j = 0; j <= i; j++)
            H[i * n + j] = H[j * n + i] =
                p->e_star * gs_compliant_influence(x[i] - x[j], w, p->e_star, datum) / w;
        double h = p->gap ? p->gap[i] : x[i] * x[i] / (2.0 * p->radius);
        if (!isfinite(h)) {
            err = gs_diag_set(d, GS_ERANGE, "gap", "gap[%d] is not finite", i);
            goto out;
        }
        c[i] = -p->e_star * h;
        G[i * n + i] = 1.0;
        E[i] = 1.0;
    }
    double load = p->load;
    err = gs_qp_new(n, 1, n, &qp);
    if (err != GS_OK)
        goto out;
    gs_qp_problem qpp = {n, H, c, 1, E, &load, n, G, g};
    double lam_eq;
    gs_qp_result res = {.x = f, .lambda_eq = &lam_eq, .lambda_in = gap};
    err = gs_qp_solve(qp, &qpp, NULL, 0, &res);
    if (err != GS_OK) {
        gs_diag_set(d, err, "patches", "the contact QP failed: %s", gs_strerror(err));
        goto out;
    }
    r->approach = lam_eq / p->e_star;
    r->qp_iterations = res.iterations;
    r->peak = 0.0;
    r->n_loaded = 0;
    int lo = -1, hi = -1;
    for (int i = 0; i < n; i++) {
        r->pressure[i] = fmax(f[i], 0.0) / w;
        if (r->x)
            r->x[i] = x[i];
        r->peak = fmax(r->peak, r->pressure[i]);
    }
    for (int i = 0; i < n; i++)
        if (r->pressure[i] > 1e-12 * r->peak) {
            r->n_loaded++;
            if (lo < 0)
                lo = i;
            hi = i;
        }
    r->half_width = lo < 0 ? 0.0
                           : 0.5 * (edge(x, r->pressure, n, hi, +1, w) -
                                    edge(x, r->pressure, n, lo, -1, w));
out:
    gs_qp_free(&qp);
    free(x);
    free(H);
    free(c);
    free(G);
    free(g);
    free(E);
    free(f);
    free(gap);
    return err;
}

/* Tangential strip forces on the loaded strips as an LCP (docs/explanation/impact.md,
 * "Partial slip"). Unknowns scaled by the normal load P (forces) and by
 * P / E* (displacements), z = (t+, t-, sigma, shift), size 3 m + 1:
 *   w+    = -shift + H (t+ - t-) + sigma >= 0  _|_  t+ >= 0
 *   w-    =  shift - H (t+ - t-) + sigma >= 0  _|_  t- >= 0
 *   wsig  =  mu f - t+ - t-               >= 0  _|_  sigma >= 0
 *   wsh   =  1.(t+ - t-) - Q              >= 0  _|_  shift >= 0   (Q >= 0)
 * sigma >= |slip| and sigma > 0 only at the friction limit: Coulomb's law
 * with the slip s = shift - H t (stick: s = 0). A is a positive
 * semidefinite block (H) plus skew-symmetric blocks, so copositive-plus:
 * Lemke's method finds a solution whenever one exists. */
gs_err gs_compliant_solve_friction(const gs_compliant_problem *p, gs_compliant_result *r, gs_diag *d)
{
    if (!p || !r || !r->pressure || !r->traction)
        return gs_diag_set(d, GS_EINVAL, "", "NULL argument");
    if (!(p->mu >= 0.0) || !isfinite(p->mu))
        return gs_diag_set(d, GS_ERANGE, "mu", "'mu' = %g must be >= 0", p->mu);
    if (!isfinite(p->load_t))
        return gs_diag_set(d, GS_ERANGE, "load_t", "'load_t' is not finite");
    if (fabs(p->load_t) > p->mu * p->load * (1.0 + 1e-12))
        return gs_diag_set(d, GS_ERANGE, "load_t",
                           "'load_t' = %g exceeds mu P = %g: the contact slides as a whole", p->load_t,
                           p->mu * p->load);
    GS_TRY(gs_compliant_solve(p, r, d));
    const int n = p->n;
    const double w = (p->x1 - p->x0) / n;
    const double datum = p->datum > 0.0 ? p->datum : 10.0 * (p->x1 - p->x0);
    double sign = p->load_t < 0.0 ? -1.0 : 1.0, Q = fabs(p->load_t) / p->load;
    memset(r->traction, 0, (size_t)n * sizeof(double));
    memset(&r->lcp, 0, sizeof r->lcp);
    r->shift = 0.0;
    r->stick_half_width = 0.0;
    r->n_stick = 0;
    int *idx = malloc((size_t)n * sizeof *idx);
    if (!idx)
        return GS_ENOMEM;
    int m = 0;
    for (int i = 0; i < n; i++)
        if (r->pressure[i] > 0.0)
            idx[m++] = i;
    if (Q == 0.0 || m == 0) {
        r->lcp.status = GS_LCP_SOLVED;
        free(idx);
        return GS_OK;
    }
    const int N = 3 * m + 1;
    double *A = calloc((size_t)N * N, sizeof *A), *q = calloc((size_t)N, sizeof *q);
    double *z = malloc((size_t)N * sizeof *z), *wv = malloc((size_t)N * sizeof *wv);
    double *x = malloc((size_t)n * sizeof *x), *def = calloc((size_t)n, sizeof *def);
    gs_err err = GS_OK;
    if (!A || !q || !z || !wv || !x || !def) {
        err = GS_ENOMEM;
        goto out;
    }
    for (int i = 0; i < n; i++)
        x[i] = p->x0 + (i + 0.5) * w;
#define AT(i, j) A[(size_t)(i) * N + (j)]
    for (int a = 0; a < m; a++) {
        for (int b = 0; b < m; b++) {
            double h = p->e_star * gs_compliant_influence(x[idx[a]] - x[idx[b]], w, p->e_star, datum) / w;
            AT(a, b) = h;
            AT(a, m + b) = -h;
            AT(m + a, b) = -h;
            AT(m + a, m + b) = h;
        }
        AT(a, 2 * m + a) = 1.0;
        AT(m + a, 2 * m + a) = 1.0;
        AT(a, 3 * m) = -1.0;
        AT(m + a, 3 * m) = 1.0;
        AT(2 * m + a, a) = -1.0;
        AT(2 * m + a, m + a) = -1.0;
        q[2 * m + a] = p->mu * r->pressure[idx[a]] * w / p->load;
        AT(3 * m, a) = 1.0;
        AT(3 * m, m + a) = -1.0;
    }
    q[3 * m] = -Q;
#undef AT
    err = gs_lcp_lemke(N, A, q, z, wv, 0, &r->lcp);
    if (err != GS_OK) {
        gs_diag_set(d, err, "load_t", "the partial-slip LCP failed: %s (%d pivots)",
                    gs_lcp_status_name(r->lcp.status), r->lcp.pivots);
        goto out;
    }
    double flim = 0.0;
    for (int a = 0; a < m; a++)
        flim = fmax(flim, r->pressure[idx[a]] * w);
    int lo = -1, hi = -1;
    for (int a = 0; a < m; a++) {
        int i = idx[a];
        double t = (z[a] - z[m + a]) * p->load;
        r->traction[i] = sign * t / w;
        /* Stick where the traction stays below the limit by more than the
         * solver's round-off. */
        double deficit = p->mu * r->pressure[i] * w - fabs(t);
        if (deficit > 1e-9 * p->mu * flim) {
            def[i] = deficit / w;
            r->n_stick++;
            if (lo < 0)
                lo = i;
            hi = i;
        }
    }
    r->shift = sign * z[3 * m] * p->load / p->e_star;
    if (lo >= 0)
        r->stick_half_width = 0.5 * (edge(x, def, n, hi, +1, w) - edge(x, def, n, lo, -1, w));
out:
    free(idx);
    free(A);
    free(q);
    free(z);
    free(wv);
    free(x);
    free(def);
    return err;
}
