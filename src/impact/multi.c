/* SPDX-License-Identifier: MIT
 * Several simultaneous contacts: one velocity-level step with Newton
 * restitution and Coulomb friction (Stewart-Trinkle; friction cone in the
 * plane as the two directions +t, -t), posed as an LCP and solved by
 * Lemke's method; frictionless, also as a QP with gs_qp for a cross-check
 * (docs/explanation/impact.md, "Several contacts"). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/impact.h"
#include "gearsim/qp.h"

/* Generalised coordinates: 3 per free body (x, y, angle). */
typedef struct {
    int ndof, nc;
    int *dof;      /* [n_body] first dof of a free body, -1 when fixed */
    double *minv;  /* [ndof] diagonal inverse mass */
    double *vminus, *vfree; /* [ndof] */
    double *N, *T; /* [nc * ndof] normal and tangent rows */
} system_t;

static void system_free(system_t *s)
{
    free(s->dof);
    free(s->minv);
    free(s->vminus);
    free(s->vfree);
    free(s->N);
    free(s->T);
}

static gs_err build(const gs_impact_multi *m, system_t *s, gs_diag *d)
{
    char f[64];
    memset(s, 0, sizeof *s);
    if (!m || m->n_body < 1 || !m->bodies || m->n_contact < 1 || !m->contacts)
        return gs_diag_set(d, GS_EINVAL, "", "no bodies or no contacts");
    if (!(m->h >= 0.0) || !isfinite(m->h) || !isfinite(m->gravity[0]) || !isfinite(m->gravity[1]))
        return gs_diag_set(d, GS_ERANGE, "time_step", "time step and gravity must be finite, h >= 0");
    s->dof = malloc((size_t)m->n_body * sizeof *s->dof);
    if (!s->dof)
        return GS_ENOMEM;
    for (int b = 0; b < m->n_body; b++) {
        const gs_impact_body *B = &m->bodies[b];
        s->dof[b] = -1;
        if (B->fixed)
            continue;
        if (!(B->mass > 0.0) || !isfinite(B->mass) || !(B->inertia > 0.0) || !isfinite(B->inertia)) {
            snprintf(f, sizeof f, "bodies[%d]", b);
            return gs_diag_set(d, GS_ERANGE, f, "mass and inertia must be finite and > 0");
        }
        if (!isfinite(B->velocity[0]) || !isfinite(B->velocity[1]) || !isfinite(B->omega) ||
            !isfinite(B->centre[0]) || !isfinite(B->centre[1])) {
            snprintf(f, sizeof f, "bodies[%d]", b);
            return gs_diag_set(d, GS_ERANGE, f, "centre and velocities must be finite");
        }
        s->dof[b] = s->ndof;
        s->ndof += 3;
    }
    if (s->ndof == 0)
        return gs_diag_set(d, GS_ERANGE, "bodies", "every body is fixed");
    s->nc = m->n_contact;
    const int nd = s->ndof, nc = s->nc;
    s->minv = calloc((size_t)nd, sizeof *s->minv);
    s->vminus = calloc((size_t)nd, sizeof *s->vminus);
    s->vfree = calloc((size_t)nd, sizeof *s->vfree);
    s->N = calloc((size_t)nc * nd, sizeof *s->N);
    s->T = calloc((size_t)nc * nd, sizeof *s->T);
    if (!s->minv || !s->vminus || !s->vfree || !s->N || !s->T)
        return GS_ENOMEM;
    for (int b = 0; b < m->n_body; b++) {
        int o = s->dof[b];
        if (o < 0)
            continue;
        const gs_impact_body *B = &m->bodies[b];
        s->minv[o] = s->minv[o + 1] = 1.0 / B->mass;
        s->minv[o + 2] = 1.0 / B->inertia;
        s->vminus[o] = B->velocity[0];
        s->vminus[o + 1] = B->velocity[1];
        s->vminus[o + 2] = B->omega;
        s->vfree[o] = B->velocity[0] + m->h * m->gravity[0];
        s->vfree[o + 1] = B->velocity[1] + m->h * m->gravity[1];
        s->vfree[o + 2] = B->omega;
    }
    for (int k = 0; k < nc; k++) {
        const gs_impact_point *c = &m->contacts[k];
        for (int i = 0; i < 2; i++)
            if (c->body[i] < 0 || c->body[i] >= m->n_body) {
                snprintf(f, sizeof f, "contacts[%d].bodies", k);
                return gs_diag_set(d, GS_ERANGE, f, "body index %d out of [0, %d)", c->body[i],
                                   m->n_body);
            }
        if (c->body[0] == c->body[1]) {
            snprintf(f, sizeof f, "contacts[%d].bodies", k);
            return gs_diag_set(d, GS_ERANGE, f, "a contact needs two different bodies");
        }
        double nl = hypot(c->normal[0], c->normal[1]);
        if (!(nl > 0.0) || !isfinite(nl) || !isfinite(c->point[0]) || !isfinite(c->point[1])) {
            snprintf(f, sizeof f, "contacts[%d].normal", k);
            return gs_diag_set(d, GS_ERANGE, f, "point and normal must be finite, normal non-zero");
        }
        if (!(c->e >= 0.0 && c->e <= 1.0)) {
            snprintf(f, sizeof f, "contacts[%d].e", k);
            return gs_diag_set(d, GS_ERANGE, f, "'e' = %g is outside [0, 1]", c->e);
        }
        if (!(c->mu >= 0.0) || !isfinite(c->mu)) {
            snprintf(f, sizeof f, "contacts[%d].mu", k);
            return gs_diag_set(d, GS_ERANGE, f, "'mu' = %g must be finite and >= 0", c->mu);
        }
        const double n[2] = {c->normal[0] / nl, c->normal[1] / nl}, t[2] = {-n[1], n[0]};
        for (int i = 0; i < 2; i++) {
            int o = s->dof[c->body[i]];
            if (o < 0)
                continue;
            const gs_impact_body *B = &m->bodies[c->body[i]];
            double q[2] = {-(c->point[1] - B->centre[1]), c->point[0] - B->centre[0]};
            double sg = i == 0 ? 1.0 : -1.0;
            double *Nr = s->N + (size_t)k * nd, *Tr = s->T + (size_t)k * nd;
            Nr[o] += sg * n[0];
            Nr[o + 1] += sg * n[1];
            Nr[o + 2] += sg * (q[0] * n[0] + q[1] * n[1]);
            Tr[o] += sg * t[0];
            Tr[o + 1] += sg * t[1];
            Tr[o + 2] += sg * (q[0] * t[0] + q[1] * t[1]);
        }
    }
    return GS_OK;
}

static double dot(int n, const double *a, const double *b)
{
    double s = 0.0;
    for (int i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}

static double dot_m(int n, const double *a, const double *minv, const double *b)
{
    double s = 0.0;
    for (int i = 0; i < n; i++)
        s += a[i] * minv[i] * b[i];
    return s;
}

static double energy(const gs_impact_multi *m, const double *v, const double *w)
{
    double e = 0.0;
    for (int b = 0; b < m->n_body; b++) {
        const gs_impact_body *B = &m->bodies[b];
        if (!B->fixed)
            e += 0.5 * B->mass * (v[2 * b] * v[2 * b] + v[2 * b + 1] * v[2 * b + 1]) +
                 0.5 * B->inertia * w[b] * w[b];
    }
    return e;
}

/* Numerical rank of the rows x k matrix C (column j at C + j*rows, overwritten)
 * by Gram-Schmidt with column pivoting, relative tolerance tol. */
static int col_rank(int rows, int k, double *C, double tol)
{
    double cmax = 0.0;
    for (int j = 0; j < k; j++)
        cmax = fmax(cmax, sqrt(dot(rows, C + (size_t)j * rows, C + (size_t)j * rows)));
    int rank = 0;
    for (int s = 0; s < k; s++) {
        int best = -1;
        double bn = tol * cmax;
        for (int j = s; j < k; j++) {
            double nj = sqrt(dot(rows, C + (size_t)j * rows, C + (size_t)j * rows));
            if (nj > bn) {
                bn = nj;
                best = j;
            }
        }
        if (best < 0)
            break;
        for (int i = 0; i < rows; i++) {
            double x = C[(size_t)s * rows + i];
            C[(size_t)s * rows + i] = C[(size_t)best * rows + i];
            C[(size_t)best * rows + i] = x;
        }
        double *u = C + (size_t)s * rows;
        for (int i = 0; i < rows; i++)
            u[i] /= bn;
        for (int j = s + 1; j < k; j++) {
            double *v = C + (size_t)j * rows, a = dot(rows, u, v);
            for (int i = 0; i < rows; i++)
                v[i] -= a * u[i];
        }
        rank++;
    }
    return rank;
}

/* Whether the impulses are not unique (docs/explanation/impact.md, "Several solutions").
 * The loaded contacts give generalised impulse directions M^{-1/2} J^T: a
 * sticking contact both n and t, a sliding one n + (p_t / p_n) t. If these are
 * dependent, or the normal of a contact that is tight (w_n = 0) but unloaded
 * lies in their span, impulse can be moved between contacts without changing
 * any velocity or complementarity: a second solution. A sufficient test. */
static bool several_solutions(const system_t *s, const gs_impact_multi *m, const double *pn,
                              const double *pt, const double *wn)
{
    const int nd = s->ndof, nc = s->nc;
    double pmax = 0.0, wmax = 0.0;
    for (int k = 0; k < nc; k++) {
        pmax = fmax(pmax, pn[k]);
        wmax = fmax(wmax, fabs(wn[k]));
    }
    double *C = malloc((size_t)(2 * nc + 1) * nd * sizeof *C);
    if (!C || pmax == 0.0) {
        free(C);
        return false;
    }
    int k_act = 0;
#define COL(j) (C + (size_t)(j) * nd)
    for (int k = 0; k < nc; k++) {
        if (!(pn[k] > 1e-9 * pmax))
            continue;
        const double *Nk = s->N + (size_t)k * nd, *Tk = s->T + (size_t)k * nd;
        bool sticking = fabs(pt[k]) < m->contacts[k].mu * pn[k] * (1.0 - 1e-9);
        for (int i = 0; i < nd; i++)
            COL(k_act)[i] = sqrt(s->minv[i]) * (sticking ? Nk[i] : Nk[i] + pt[k] / pn[k] * Tk[i]);
        k_act++;
        if (sticking && m->contacts[k].mu > 0.0) {
            for (int i = 0; i < nd; i++)
                COL(k_act)[i] = sqrt(s->minv[i]) * Tk[i];
            k_act++;
        }
    }
    double *W = malloc((size_t)(2 * nc + 1) * nd * sizeof *W);
    bool several = false;
    if (W) {
        memcpy(W, C, (size_t)k_act * nd * sizeof *W);
        int r0 = col_rank(nd, k_act, W, 1e-9);
        several = r0 < k_act;
        for (int k = 0; k < nc && !several; k++) {
            if (pn[k] > 1e-9 * pmax || fabs(wn[k]) > 1e-9 * fmax(wmax, 1e-300))
                continue;
            memcpy(W, C, (size_t)k_act * nd * sizeof *W);
            for (int i = 0; i < nd; i++)
                W[(size_t)k_act * nd + i] = sqrt(s->minv[i]) * s->N[(size_t)k * nd + i];
            several = col_rank(nd, k_act + 1, W, 1e-9) == r0;
        }
    }
#undef COL
    free(W);
    free(C);
    return several;
}

/* v+ = v_free + M^{-1} (N^T p_n + T^T p_t), written per body. */
static void finish(const gs_impact_multi *m, const system_t *s, gs_impact_multi_result *r)
{
    const int nd = s->ndof;
    double *v = malloc((size_t)nd * sizeof *v);
    if (!v)
        return;
    memcpy(v, s->vfree, (size_t)nd * sizeof *v);
    for (int k = 0; k < s->nc; k++)
        for (int j = 0; j < nd; j++)
            v[j] += s->minv[j] * (s->N[(size_t)k * nd + j] * r->impulse_n[k] +
                                  s->T[(size_t)k * nd + j] * r->impulse_t[k]);
    double *vb = malloc((size_t)2 * m->n_body * sizeof *vb), *wb = malloc((size_t)m->n_body * sizeof *wb);
    for (int b = 0; b < m->n_body && vb && wb; b++) {
        int o = s->dof[b];
        const gs_impact_body *B = &m->bodies[b];
        vb[2 * b] = B->velocity[0];
        vb[2 * b + 1] = B->velocity[1];
        wb[b] = B->omega;
        r->velocity[2 * b] = o < 0 ? B->velocity[0] : v[o];
        r->velocity[2 * b + 1] = o < 0 ? B->velocity[1] : v[o + 1];
        r->omega[b] = o < 0 ? B->omega : v[o + 2];
    }
    if (vb && wb) {
        r->energy_before = energy(m, vb, wb);
        r->energy_after = energy(m, r->velocity, r->omega);
    }
    free(vb);
    free(wb);
    free(v);
}

static bool result_ok(const gs_impact_multi_result *r)
{
    return r && r->velocity && r->omega && r->impulse_n && r->impulse_t;
}

gs_err gs_impact_multi_solve(const gs_impact_multi *m, gs_impact_multi_result *r, gs_diag *d)
{
    if (!result_ok(r))
        return gs_diag_set(d, GS_EINVAL, "", "result arrays missing");
    system_t s;
    gs_err err = build(m, &s, d);
    const int nc = m ? m->n_contact : 0, nd = s.ndof, L = 4 * nc;
    double *A = NULL, *q = NULL, *z = NULL, *w = NULL;
    if (err != GS_OK)
        goto out;
    A = calloc((size_t)L * L, sizeof *A);
    q = calloc((size_t)L, sizeof *q);
    z = calloc((size_t)L, sizeof *z);
    w = calloc((size_t)L, sizeof *w);
    if (!A || !q || !z || !w) {
        err = GS_ENOMEM;
        goto out;
    }
    /* Unknowns: p_n (nc), beta (2 nc: +t, -t per contact), lambda (nc). */
#define IDX_N(i) (i)
#define IDX_B(i, s) (nc + 2 * (i) + (s))
#define IDX_L(i) (3 * nc + (i))
#define AA(i, j) A[(size_t)(i) * L + (j)]
    for (int i = 0; i < nc; i++) {
        const double *Ni = s.N + (size_t)i * nd, *Ti = s.T + (size_t)i * nd;
        for (int j = 0; j < nc; j++) {
            const double *Nj = s.N + (size_t)j * nd, *Tj = s.T + (size_t)j * nd;
            double nn = dot_m(nd, Ni, s.minv, Nj), nt = dot_m(nd, Ni, s.minv, Tj);
            double tn = dot_m(nd, Ti, s.minv, Nj), tt = dot_m(nd, Ti, s.minv, Tj);
            AA(IDX_N(i), IDX_N(j)) = nn;
            for (int a = 0; a < 2; a++) {
                double sa = a == 0 ? 1.0 : -1.0;
                AA(IDX_N(i), IDX_B(j, a)) = sa * nt;
                AA(IDX_B(i, a), IDX_N(j)) = sa * tn;
                for (int b = 0; b < 2; b++)
                    AA(IDX_B(i, a), IDX_B(j, b)) = sa * (b == 0 ? 1.0 : -1.0) * tt;
            }
        }
        for (int a = 0; a < 2; a++) {
            AA(IDX_B(i, a), IDX_L(i)) = 1.0;
            AA(IDX_L(i), IDX_B(i, a)) = -1.0;
        }
        AA(IDX_L(i), IDX_N(i)) = m->contacts[i].mu;
        double vn_minus = dot(nd, Ni, s.vminus);
        q[IDX_N(i)] = dot(nd, Ni, s.vfree) + m->contacts[i].e * fmin(vn_minus, 0.0);
        double vt = dot(nd, Ti, s.vfree);
        q[IDX_B(i, 0)] = vt;
        q[IDX_B(i, 1)] = -vt;
    }
    err = gs_lcp_lemke(L, A, q, z, w, 0, &r->lcp);
    r->lcp_size = L;
    if (err == GS_EINFEASIBLE) {
        gs_diag_set(d, err, "contacts", "Lemke's method ended on a ray after %d pivots: no solution found",
                    r->lcp.pivots);
        goto out;
    }
    if (err != GS_OK) {
        gs_diag_set(d, err, "contacts", "Lemke's method: %s (residual %.3g)",
                    gs_lcp_status_name(r->lcp.status), r->lcp.residual);
        goto out;
    }
    for (int i = 0; i < nc; i++) {
        r->impulse_n[i] = z[IDX_N(i)];
        r->impulse_t[i] = z[IDX_B(i, 0)] - z[IDX_B(i, 1)];
        q[i] = w[IDX_N(i)]; /* normal velocity slack, reused as scratch */
    }
    r->several = several_solutions(&s, m, r->impulse_n, r->impulse_t, q);
    finish(m, &s, r);
#undef IDX_N
#undef IDX_B
#undef IDX_L
#undef AA
out:
    free(A);
    free(q);
    free(z);
    free(w);
    system_free(&s);
    return err;
}

gs_err gs_impact_multi_solve_qp(const gs_impact_multi *m, gs_impact_multi_result *r, gs_diag *d)
{
    if (!result_ok(r))
        return gs_diag_set(d, GS_EINVAL, "", "result arrays missing");
    memset(&r->lcp, 0, sizeof r->lcp);
    r->lcp_size = 0;
    system_t s;
    gs_err err = build(m, &s, d);
    const int nc = m ? m->n_contact : 0, nd = s.ndof;
    double *H = NULL, *c = NULL, *g = NULL, *x = NULL, *lam = NULL;
    gs_qp *qp = NULL;
    if (err != GS_OK)
        goto out;
    H = calloc((size_t)nd * nd, sizeof *H);
    c = calloc((size_t)nd, sizeof *c);
    g = calloc((size_t)nc, sizeof *g);
    x = calloc((size_t)nd, sizeof *x);
    lam = calloc((size_t)nc, sizeof *lam);
    if (!H || !c || !g || !x || !lam) {
        err = GS_ENOMEM;
        goto out;
    }
    for (int j = 0; j < nd; j++) {
        H[(size_t)j * nd + j] = 1.0 / s.minv[j];
        c[j] = s.vfree[j] / s.minv[j];
    }
    for (int i = 0; i < nc; i++)
        g[i] = -m->contacts[i].e * fmin(dot(nd, s.N + (size_t)i * nd, s.vminus), 0.0);
    err = gs_qp_new(nd, 0, nc, &qp);
    if (err != GS_OK)
        goto out;
    gs_qp_problem p = {nd, H, c, 0, NULL, NULL, nc, s.N, g};
    gs_qp_result res = {.x = x, .lambda_in = lam};
    err = gs_qp_solve(qp, &p, NULL, 0, &res);
    if (err != GS_OK) {
        gs_diag_set(d, err, "contacts", "the frictionless QP failed: %s", gs_strerror(err));
        goto out;
    }
    for (int i = 0; i < nc; i++) {
        r->impulse_n[i] = lam[i];
        r->impulse_t[i] = 0.0;
        g[i] = dot(nd, s.N + (size_t)i * nd, x) - g[i]; /* slack of N v >= g */
    }
    r->several = several_solutions(&s, m, r->impulse_n, r->impulse_t, g);
    finish(m, &s, r);
out:
    gs_qp_free(&qp);
    free(H);
    free(c);
    free(g);
    free(x);
    free(lam);
    system_free(&s);
    return err;
}
