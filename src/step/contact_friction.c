/* SPDX-License-Identifier: MIT
 * Implicit Coulomb friction on the flanks of contact meshes
 * (docs/explanation/contact_treatments.md, "Flank friction").
 *
 * The contact step (src/step/contact_step.c) solves for the step's
 * increments x of the rigid coordinates and of the contact nodes'
 * displacements the QP  min 1/2 x^T H x - c^T x,  E x = e,  G x >= g.
 * Each contact row i of a mesh with implicit friction gets a tangent row
 * T_i: T_i x is the slip over the step of the slave node over the master's
 * material point under it, along t = (-n_y, n_x) (n the direction of the
 * slave's gap gradient), from the rigid rotations (and carriers) and the
 * nodes' elastic increments. The friction force beta_i t on the slave (and
 * -N_j beta_i t on master node j, N_j its weight in the gap) obeys Coulomb's
 * law over the step:
 *
 *   |beta_i| <= mu F_n,i = mu |dg/dx_s| lambda_i,
 *   stick:  T_i x = 0,
 *   slip:   beta_i = -mu F_n,i sign(T_i x),
 *
 * solved together with the normal contact as the linear complementarity
 * problem of Stewart and Trinkle (the same as gs_impact_multi_solve's for
 * rigid bodies, docs/explanation/impact.md "Several contacts"), in the
 * step's displacements instead of velocities:
 *
 *   0 <= lambda  _|_  G x - g              >= 0
 *   0 <= beta+   _|_  gamma + T x          >= 0
 *   0 <= beta-   _|_  gamma - T x          >= 0
 *   0 <= gamma   _|_  mu_i lambda - beta+ - beta-  >= 0
 *
 * with x = x_f + W (G^T lambda + T^T (beta+ - beta-)), x_f and W from H and
 * the equalities (W = H^{-1} - H^{-1} E^T (E H^{-1} E^T)^+ E H^{-1}), by
 * Lemke's method (gs_lcp_lemke). The friction force's work over the step,
 * beta^T T x = -sum mu F_n |T x| <= 0, is what the contact step books as
 * dissipation; it is exact for the forces the bodies are given, whatever
 * the solver's tolerance. */
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "contact_friction.h"
#include "gearsim/impact.h"
#include "gearsim/util.h"

static bool grow_d(double **p, size_t *cap, size_t n)
{
    double *q = gs_grow(*p, cap, n ? n : 1, sizeof(double));
    if (!q)
        return false;
    *p = q;
    return true;
}

static bool grow_i(int **p, size_t *cap, size_t n)
{
    int *q = gs_grow(*p, cap, n ? n : 1, sizeof(int));
    if (!q)
        return false;
    *p = q;
    return true;
}

void gsi_friction_free(gsi_friction **f)
{
    if (!f || !*f)
        return;
    gsi_friction *p = *f;
    free(p->row), free(p->mesh), free(p->T), free(p->mu), free(p->beta);
    free(p->L), free(p->x0), free(p->Z), free(p->Y), free(p->S), free(p->A), free(p->q);
    free(p->z), free(p->w), free(p->r), free(p->t);
    free(p);
    *f = NULL;
}

bool gsi_friction_any(const gs_system *sys, bool implicit)
{
    for (int mi = 0; mi < sys->n_meshes; mi++) {
        const gsi_contact_mesh *cm = sys->meshes[mi].contact;
        if (sys->meshes[mi].ops->contact && cm && cm->friction > 0 && !(implicit && cm->friction_explicit))
            return true;
    }
    return false;
}

gs_err gsi_friction_begin(gsi_friction **f, int N, int n_rows)
{
    if (!*f) {
        *f = gs_calloc(1, sizeof **f);
        if (!*f)
            return GS_ENOMEM;
    }
    gsi_friction *p = *f;
    if (!grow_d(&p->beta, &p->cap_beta, (size_t)n_rows))
        return GS_ENOMEM;
    memset(p->beta, 0, (size_t)(n_rows ? n_rows : 1) * sizeof(double));
    p->N = N;
    p->n_rows = n_rows;
    p->n_fric = 0;
    return GS_OK;
}

gs_err gsi_friction_add(gsi_friction *f, const gs_system *sys, int row, int mesh, const gs_contact_row *r,
                        const int *unk, const size_t *base)
{
    const gsi_contact_mesh *cm = sys->meshes[mesh].contact;
    if (!(cm->friction > 0) || cm->friction_explicit)
        return GS_OK;
    double gs2 = r->gap.grad[0] * r->gap.grad[0] + r->gap.grad[1] * r->gap.grad[1];
    if (!(gs2 > 0))
        return GS_OK;
    int k = f->n_fric, N = f->N;
    if (!grow_i(&f->row, &f->cap_row, (size_t)k + 1) || !grow_i(&f->mesh, &f->cap_mesh, (size_t)k + 1) ||
        !grow_d(&f->mu, &f->cap_mu, (size_t)k + 1) || !grow_d(&f->T, &f->cap_T, (size_t)(k + 1) * N))
        return GS_ENOMEM;
    double gn = sqrt(gs2), t[2] = {-r->gap.grad[1] / gn, r->gap.grad[0] / gn};
    double *T = f->T + (size_t)k * N;
    memset(T, 0, (size_t)N * sizeof(double));
    /* The slave's displacement along t, less the master's material point
     * under it: sum_j N_j of its nodes, N_j = -(dg/dp_j . dg/dx_s) / |dg/dx_s|^2
     * (signed: quadratic edges have negative corner weights; they sum to 1
     * since the gap does not change under a common translation). */
    gsi_contact_point_force(sys, cm, r->body[0], r->node[0], r->x[0], t, unk, base, T);
    for (int j = 1; j < r->n_nodes; j++) {
        double Nj = -(r->gap.grad[2 * j] * r->gap.grad[0] + r->gap.grad[2 * j + 1] * r->gap.grad[1]) / gs2;
        double F[2] = {-Nj * t[0], -Nj * t[1]};
        gsi_contact_point_force(sys, cm, r->body[j], r->node[j], r->x[j], F, unk, base, T);
    }
    f->row[k] = row;
    f->mesh[k] = mesh;
    f->mu[k] = cm->friction * gn;
    f->n_fric = k + 1;
    return GS_OK;
}

/* y (n) = M^+ v for the symmetric positive semidefinite ne x ne matrix
 * whose eigen-decomposition V diag(ev) V^T is given (V column-major):
 * eigenvalues below 1e-12 of the largest count as zero (dependent
 * equalities, as the QP skips them). */
static void pinv_apply(int ne, const double *V, const double *ev, const double *v, double *y, double *tmp)
{
    double emax = 0.0;
    for (int a = 0; a < ne; a++)
        emax = fmax(emax, ev[a]);
    for (int a = 0; a < ne; a++) {
        double s = 0.0;
        for (int b = 0; b < ne; b++)
            s += V[(size_t)a * ne + b] * v[b];
        tmp[a] = ev[a] > 1e-12 * emax ? s / ev[a] : 0.0;
    }
    for (int b = 0; b < ne; b++) {
        double s = 0.0;
        for (int a = 0; a < ne; a++)
            s += V[(size_t)a * ne + b] * tmp[a];
        y[b] = s;
    }
}

/* Row k of the stacked [G; T] (k < n_in: contact row k, else tangent row k - n_in). */
static const double *brow(const gsi_friction *f, const gs_qp_problem *p, int k)
{
    return k < p->n_in ? p->G + (size_t)k * p->n : f->T + (size_t)(k - p->n_in) * p->n;
}

static double dot(int n, const double *a, const double *b)
{
    double s = 0.0;
    for (int i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}

/* x = H^{-1} c' with c' = c + sum_k z_k B_k, then the equalities:
 * nu = (E H^{-1} E^T)^+ (e - E x), x += H^{-1} E^T nu. */
static void kkt_solve(gsi_friction *f, const gs_qp_problem *p, const double *bz, double *x, double *nu)
{
    int N = p->n, ne = p->n_eq;
    for (int j = 0; j < N; j++)
        x[j] = p->c[j] + bz[j];
    LAPACKE_dpotrs(LAPACK_COL_MAJOR, 'L', N, 1, f->L, N, x, N);
    if (ne == 0)
        return;
    const double *V = f->S, *ev = f->S + (size_t)ne * ne;
    for (int a = 0; a < ne; a++)
        f->r[a] = p->e[a] - dot(N, p->E + (size_t)a * N, x);
    pinv_apply(ne, V, ev, f->r, nu, f->t);
    for (int a = 0; a < ne; a++)
        for (int j = 0; j < N; j++)
            x[j] += f->Y[(size_t)a * N + j] * nu[a];
}

/* 1/2 x^T H x - c^T x from the lower triangle of H. */
static double objective(const gs_qp_problem *p, const double *x)
{
    double o = 0.0;
    for (int i = 0; i < p->n; i++) {
        double hx = 0.5 * p->H[(size_t)i * p->n + i] * x[i];
        for (int j = 0; j < i; j++)
            hx += p->H[(size_t)i * p->n + j] * x[j];
        o += x[i] * (hx - p->c[i]);
    }
    return o;
}

gs_err gsi_friction_solve(gsi_friction *f, const gs_qp_problem *p, gs_qp_result *res)
{
    const int N = p->n, ne = p->n_eq, ni = p->n_in, nf = f->n_fric, m = ni + nf, L = ni + 3 * nf;
    const size_t n2 = (size_t)N * N;
    if (!grow_d(&f->L, &f->cap_L, n2) || !grow_d(&f->x0, &f->cap_x0, (size_t)N) ||
        !grow_d(&f->Z, &f->cap_Z, (size_t)m * N + (size_t)m * m) ||
        !grow_d(&f->Y, &f->cap_Y, (size_t)ne * N) || !grow_d(&f->S, &f->cap_S, (size_t)ne * ne + ne) ||
        !grow_d(&f->A, &f->cap_A, (size_t)L * L) || !grow_d(&f->q, &f->cap_q, (size_t)L + m) ||
        !grow_d(&f->z, &f->cap_z, (size_t)L) || !grow_d(&f->w, &f->cap_w, (size_t)L) ||
        !grow_d(&f->r, &f->cap_r, (size_t)(ne > N ? ne : N)) || !grow_d(&f->t, &f->cap_t, 3 * (size_t)ne))
        return GS_ENOMEM;
    /* H (lower triangle of the row-major problem), factored. */
    for (int i = 0; i < N; i++)
        for (int j = 0; j <= i; j++)
            f->L[(size_t)j * N + i] = f->L[(size_t)i * N + j] = p->H[(size_t)i * N + j];
    if (LAPACKE_dpotrf(LAPACK_COL_MAJOR, 'L', N, f->L, N) != 0)
        return GS_ESINGULAR;
    /* Z: columns H^{-1} B_k^T; Y: columns H^{-1} E_a^T, and E H^{-1} E^T
     * decomposed (S: eigenvectors, then eigenvalues). */
    double *Z = f->Z, *D = f->Z + (size_t)m * N;
    for (int k = 0; k < m; k++)
        memcpy(Z + (size_t)k * N, brow(f, p, k), (size_t)N * sizeof(double));
    if (m > 0)
        LAPACKE_dpotrs(LAPACK_COL_MAJOR, 'L', N, m, f->L, N, Z, N);
    memset(f->x0, 0, (size_t)N * sizeof(double));
    if (ne > 0) {
        memcpy(f->Y, p->E, (size_t)ne * N * sizeof(double));
        LAPACKE_dpotrs(LAPACK_COL_MAJOR, 'L', N, ne, f->L, N, f->Y, N);
        double *V = f->S, *ev = f->S + (size_t)ne * ne;
        for (int a = 0; a < ne; a++)
            for (int b = 0; b <= a; b++)
                V[(size_t)a * ne + b] = V[(size_t)b * ne + a] = dot(N, p->E + (size_t)a * N, f->Y + (size_t)b * N);
        if (LAPACKE_dsyev(LAPACK_COL_MAJOR, 'V', 'L', ne, V, ne, ev) != 0)
            return GS_ESINGULAR;
        /* the columns of Z made to keep E x = e: Z_k -= Y (E Y)^+ E Z_k */
        for (int k = 0; k < m; k++) {
            double *zk = Z + (size_t)k * N;
            for (int a = 0; a < ne; a++)
                f->r[a] = dot(N, p->E + (size_t)a * N, zk);
            double *y = f->t + ne;
            pinv_apply(ne, V, ev, f->r, y, f->t);
            for (int a = 0; a < ne; a++)
                for (int j = 0; j < N; j++)
                    zk[j] -= f->Y[(size_t)a * N + j] * y[a];
        }
    }
    /* The free solution x_f (no contact force) and b = B x_f - [g; 0]. */
    double *xf = res->x, *b = f->q + L, *nu = res->lambda_eq ? res->lambda_eq : f->t + 2 * ne;
    kkt_solve(f, p, f->x0, xf, nu);
    for (int k = 0; k < m; k++)
        b[k] = dot(N, brow(f, p, k), xf) - (k < ni ? p->g[k] : 0.0);
    /* The Delassus matrix D = B W B^T. */
    double kappa = 0.0;
    for (int k = 0; k < m; k++)
        for (int l = 0; l < m; l++) {
            D[(size_t)k * m + l] = dot(N, brow(f, p, k), Z + (size_t)l * N);
            if (k == l)
                kappa = fmax(kappa, D[(size_t)k * m + k]);
        }
    if (!(kappa > 0) || !isfinite(kappa))
        return GS_ESINGULAR;
    /* The LCP in force units: the displacement rows divided by kappa, the
     * slip magnitude gamma carried as gamma / kappa. Unknowns: lambda (ni),
     * beta+ (nf), beta- (nf), gamma (nf). */
    double *A = f->A, *q = f->q;
    memset(A, 0, (size_t)L * L * sizeof(double));
#define AA(i, j) A[(size_t)(i) * L + (j)]
#define DD(k, l) (D[(size_t)(k) * m + (l)] / kappa)
    for (int i = 0; i < ni + nf; i++) {
        /* row i of B: contact row i, or tangent row i - ni (then also its mirror) */
        for (int j = 0; j < ni; j++)
            AA(i, j) = DD(i, j);
        for (int l = 0; l < nf; l++) {
            AA(i, ni + l) = DD(i, ni + l);
            AA(i, ni + nf + l) = -DD(i, ni + l);
        }
        q[i] = b[i] / kappa;
        if (i < ni)
            continue;
        int k = i - ni, im = ni + nf + k;
        for (int j = 0; j < ni + 2 * nf; j++)
            AA(im, j) = -AA(i, j);
        q[im] = -q[i];
        AA(i, ni + 2 * nf + k) = 1.0;
        AA(im, ni + 2 * nf + k) = 1.0;
        int ic = ni + 2 * nf + k;
        AA(ic, f->row[k]) = f->mu[k];
        AA(ic, ni + k) = -1.0;
        AA(ic, ni + nf + k) = -1.0;
        q[ic] = 0.0;
    }
#undef AA
#undef DD
    gs_lcp_info info;
    gs_err err = gs_lcp_lemke(L, A, q, f->z, f->w, 0, &info);
    f->pivots = info.pivots;
    res->iterations = info.pivots;
    if (err != GS_OK)
        return err;
    /* The forces, and x from them (the same KKT system as x_f). */
    double *bz = f->x0;
    memset(bz, 0, (size_t)N * sizeof(double));
    for (int k = 0; k < m; k++) {
        double zk = k < ni ? f->z[k] : f->z[k] - f->z[k + nf];
        if (k < ni) {
            if (res->lambda_in)
                res->lambda_in[k] = zk;
        } else {
            f->beta[f->row[k - ni]] = zk;
        }
        if (zk == 0.0)
            continue;
        const double *B = brow(f, p, k);
        for (int j = 0; j < N; j++)
            bz[j] += zk * B[j];
    }
    kkt_solve(f, p, bz, res->x, nu);
    res->objective = objective(p, res->x);
    return GS_OK;
}

void gsi_friction_forces(const gsi_friction *f, double *ffm)
{
    const int N = f->N;
    for (int k = 0; k < f->n_fric; k++) {
        double bk = f->beta[f->row[k]];
        const double *T = f->T + (size_t)k * N;
        double *fm = ffm + (size_t)f->mesh[k] * N;
        for (int j = 0; j < N; j++)
            fm[j] += bk * T[j];
    }
}
