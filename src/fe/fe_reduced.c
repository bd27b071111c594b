/* SPDX-License-Identifier: MIT
 * A reduced elastic body: the FE body of fe_body.c with its modes above
 * f_max taken as massless (docs/explanation/elastic_body.md "Reduced elastic body").
 *
 * The FE body is linear with constant matrices: x = [u; theta], mass
 * M_f = [[M, s], [s^T, I]], stiffness K_f = [[K, 0], [0, 0]], damping
 * beta K on u, brake c on theta. Its midpoint step, projected on the
 * M_f-orthonormal modes phi_i (K_f phi_i = w_i^2 M_f phi_i), decouples:
 *
 *     a_i delta_i = g_i - w_i^2 (q_i + (h/2 + beta) v_i),
 *     a_i = 2/h^2 + (1/2 + beta/h) w_i^2,   dq_i = h v_i + delta_i,
 *
 * g_i = phi_i^T F. Kept: the rigid rotation phi_0 = e_theta / sqrt(I) (a
 * free body) and the elastic modes with f_i <= f_max, those of
 * (K, M - s s^T / I) with theta = -s^T u / I (of (K, M) for a held body).
 * The modes above are massless: their displacement is z = G_res Y with
 *
 *     G_res = G_ir - sum_{0 < i <= N} phi_i phi_i^T / w_i^2,
 *
 * G_ir the inertia-relief flexibility (K u = f_e - s f_t / I, theta =
 * -s^T u / I; K^{-1} for a held body), and Y a force-like state over the
 * dofs that ever carried force, stepped by the rule (gs_fe_reduced_opts
 * residual_static: g = 1, else the midpoint rule g = 1/2)
 *
 *     (1 - g) Y_n + g Y_{n+1} + (beta / h) (Y_{n+1} - Y_n) = F_step,
 *
 * so dz = G_res (F_step - Y_n) / d, d = g + beta/h: free increment
 * -G_res Y_n / d, compliance G_res / d. The potential 1/2 Y^T G_res Y and
 * the dissipation (g - 1/2 + beta/h) dY^T G_res dY make the energy balance
 * exact (the g - 1/2 part is the static rule's loss, booked with the
 * material damping). Y on a node no longer loaded decays by
 * r = (beta/h + g - 1) / (beta/h + g) per step and is dropped below 1e-15
 * of the largest entry; midpoint and undamped (r = -1) it alternates and
 * stays, static and undamped (r = 0) it follows F_step.
 *
 * A state given by set_state (nodal fields) is projected: q = Phi^T M_f x,
 * v = Phi^T M_f x'; the rest of x, z0 = x - Phi q, is a residual
 * displacement that decays as r^n (a scalar times the stored z0, its
 * force-like vector K z0 implicit); the rest of the velocity is dropped
 * (massless). Mass-proportional damping alpha M on u' is, in the modes,
 * alpha (E + t t^T) (E: 1 on the elastic modes; t_i = sqrt(I) theta_i,
 * zero held): the step's modal matrix is diagonal plus rank one and is
 * inverted by Sherman-Morrison (H = diag(1/a') - kap w w^T); the massless
 * residual carries none.
 *
 * The brake -c theta' is a force on theta: with y the (unbraked) column of
 * the step's compliance at theta, dq = dq_bar - y k dq_bar_theta,
 * C = C_bar - k y y^T, k = (c/h) / (1 + (c/h) y_theta) (Sherman-Morrison,
 * as fe_body.c's Schur border). A held theta is not a coordinate of the
 * modes; the body is created held or free (gs_fe_reduced_opts.held).
 *
 * Rows: the theta row and the x, y rows of the candidate nodes (those that
 * may ever carry force; the tooth boundary of a gear). The modes are kept
 * whole (fields, projection) and as a row table; the columns of G_res are
 * computed per node when first needed (two solves with the factor of K, in
 * fixed groups of 8 candidates: bits independent of the history) and kept
 * on the rows only. A step is then O(N |I| + |I| |supp Y|).
 *
 * Snapshots hold q, v, Y with the order of its support, the initial
 * residual amplitude and the energy books: a body loaded from one in a new
 * process steps on bit for bit. No process-wide state: a body's figures
 * are in its gs_fe_reduced_info.
 *
 * Modes: dense LAPACK (dsygvd) up to DENSE_MAX unknowns, else Lanczos with
 * shift-invert on the factor of K (the operator K^{-1} Mbar, self-adjoint
 * in the Mbar inner product, full reorthogonalisation), restarted deflated
 * against the modes found until a run finds no more below f_max (a gear's
 * cyclic symmetry makes double eigenvalues, which one Krylov space holds
 * only once). */
#include <cholmod.h>
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fe/fe_internal.h"
#include "fe/fe_reduced_internal.h"
#include "gearsim/util.h"

/* ---- small helpers ------------------------------------------------------ */

double gsi_fe_red_dotn(gs_index n, const double *a, const double *b)
{
    double s = 0;
    for (gs_index i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}

/* y = Mbar x on the elastic block (Mbar = M - s s^T / I, or M held). */
void gsi_fe_red_mbar(const gs_fe_reduced *b, const double *x, double *y)
{
    memset(y, 0, (size_t)b->ne * sizeof *y);
    gsi_fe_symv2(b->m, 1.0, x, 0.0, x, y);
    if (!b->held) {
        double st = gsi_fe_red_dotn(b->ne, b->m->s, x) / b->Itot;
        for (gs_index i = 0; i < b->ne; i++)
            y[i] -= b->m->s[i] * st;
    }
}

/* x = K^{-1} f (ncol right-hand sides of length ne, column-major). */
gs_err gsi_fe_red_ksolve(gs_fe_reduced *b, int ncol, const double *f, double *x)
{
    cholmod_dense *B = cholmod_l_allocate_dense((size_t)b->ne, (size_t)ncol, (size_t)b->ne, CHOLMOD_REAL, &b->cc);
    if (!B)
        return GS_ENOMEM;
    memcpy(B->x, f, (size_t)b->ne * (size_t)ncol * sizeof(double));
    cholmod_dense *X = cholmod_l_solve(CHOLMOD_A, b->L, B, &b->cc);
    cholmod_l_free_dense(&B, &b->cc);
    if (!X)
        return GS_ENOMEM;
    memcpy(x, X->x, (size_t)b->ne * (size_t)ncol * sizeof(double));
    cholmod_l_free_dense(&X, &b->cc);
    return GS_OK;
}

/* The full mode of an elastic vector: theta = -s^T u / I (0 held). */
double gsi_fe_red_theta_of(const gs_fe_reduced *b, const double *u)
{
    return b->held ? 0.0 : -gsi_fe_red_dotn(b->ne, b->m->s, u) / b->Itot;
}

/* ---- lifecycle ---------------------------------------------------------- */

void gs_fe_reduced_free(gs_fe_reduced **pb)
{
    if (!pb || !*pb)
        return;
    gs_fe_reduced *b = *pb;
    if (b->col)
        for (gs_index k = 0; k < b->ncand; k++)
            free(b->col[k]);
    free(b->col);
    free(b->tcol);
    cholmod_l_free_dense(&b->cB, &b->cc);
    cholmod_l_free_dense(&b->cX, &b->cc);
    cholmod_l_free_dense(&b->cY, &b->cc);
    cholmod_l_free_dense(&b->cE, &b->cc);
    free(b->cf);
    cholmod_l_free_factor(&b->L, &b->cc);
    cholmod_l_free_sparse(&b->K, &b->cc);
    cholmod_l_finish(&b->cc);
    free(b->Phi), free(b->om2), free(b->PR), free(b->cand_of), free(b->rowq), free(b->inv_a);
    free(b->tt), free(b->ww);
    free(b->qm), free(b->vm), free(b->Y), free(b->ysup), free(b->yin), free(b->z0), free(b->z0R);
    free(b->dqm), free(b->Fa), free(b->Fi), free(b->Rf), free(b->fl), free(b->fin), free(b->scratch);
    free(b->blk_r), free(b->blk_pos), free(b->blk_G), free(b->blk_M);
    free(b->sp_G), free(b->sp_M), free(b->sp_r);
    free(b->blk_C), free(b->sp_C), free(b->blk_rr), free(b->sp_rr);
    free(b);
    *pb = NULL;
}

/* G_res column of the force f (length n, x order) at the rows, into out (nr).
 * The solve runs in the body's kept dense arrays (cholmod_l_solve2 reuses
 * them when their size fits): the same arithmetic as a fresh
 * cholmod_l_solve, without tens of MB allocated per group of columns. */
static gs_err gres_column(gs_fe_reduced *b, int ncol, const double *f, double **out)
{
    gs_index ne = b->ne, n = b->n;
    if (b->cB && b->cB->ncol != (size_t)ncol)
        cholmod_l_free_dense(&b->cB, &b->cc);
    if (!b->cB)
        b->cB = cholmod_l_allocate_dense((size_t)ne, (size_t)ncol, (size_t)ne, CHOLMOD_REAL, &b->cc);
    if (!b->cB)
        return GS_ENOMEM;
    double *rhs = b->cB->x;
    for (int c = 0; c < ncol; c++) {
        const double *fc = f + (size_t)c * (size_t)n;
        double ft = b->held ? 0.0 : fc[ne] / b->Itot;
        for (gs_index i = 0; i < ne; i++)
            rhs[(size_t)c * (size_t)ne + (size_t)i] = fc[i] - (b->held ? 0.0 : b->m->s[i] * ft);
    }
    if (!cholmod_l_solve2(CHOLMOD_A, b->L, b->cB, NULL, &b->cX, NULL, &b->cY, &b->cE, &b->cc) || !b->cX)
        return GS_ENOMEM;
    const double *x = b->cX->x;
    for (int c = 0; c < ncol; c++) {
        const double *xc = x + (size_t)c * (size_t)ne, *fc = f + (size_t)c * (size_t)n;
        double xt = gsi_fe_red_theta_of(b, xc);
        /* modal part phi_i^T f / w_i^2 of the kept elastic modes */
        double *pf = b->scratch;
        gs_index nz[8], nnz = 0;
        for (gs_index j = 0; j < n && nnz < 8; j++)
            if (fc[j] != 0.0)
                nz[nnz++] = j;
        for (int i = 0; i < b->N; i++) {
            const double *p = b->Phi + (size_t)i * (size_t)n;
            double v = 0;
            if (nnz < 8)
                for (gs_index t = 0; t < nnz; t++)
                    v += p[nz[t]] * fc[nz[t]];
            else
                v = gsi_fe_red_dotn(n, p, fc);
            pf[i] = b->om2[i] > 0 ? v / b->om2[i] : 0.0;
        }
        for (gs_index r = 0; r < b->nr; r++) {
            gs_index k = b->rowq[r];
            double v = k < 0 ? 0.0 : (k == ne ? xt : xc[k]);
            if (k >= 0)
                v -= gsi_fe_red_dotn(b->N, b->PR + (size_t)r * (size_t)b->N, pf);
            out[c][r] = v;
        }
    }
    return GS_OK;
}

static gs_err ensure_node_now(gs_fe_reduced *b, gs_index k);

/* Make the G_res columns of candidate node k's x and y rows present. */
static gs_err ensure_node(gs_fe_reduced *b, gs_index k)
{
    if (b->col[k])
        return GS_OK;
    double t0 = gs_cpu_now();
    gs_err e = ensure_node_now(b, k);
    b->col_cpu += gs_cpu_now() - t0;
    return e;
}

/* Node k's columns and those of its group of BATCH_NODES consecutive
 * candidates along the boundary in one multi-column solve (the contact
 * moves along a flank, and a solve of 16 columns costs far less than 8 of
 * 2). */
static gs_err ensure_node_now(gs_fe_reduced *b, gs_index k)
{
    gs_index nr = b->nr, n = b->n, batch[BATCH_NODES];
    int cnt = 0;
    /* the group of BATCH_NODES candidates k belongs to, always computed
     * whole: a column's bits do not depend on which nodes were needed
     * first (a run resumed from a checkpoint computes the same columns) */
    gs_index g0 = k - k % BATCH_NODES;
    for (gs_index j = g0; j < b->ncand && j < g0 + BATCH_NODES; j++)
        if (!b->col[j])
            batch[cnt++] = j;
    double *c = gs_calloc((size_t)(2 * nr) * (size_t)cnt, sizeof *c);
    if (!b->cf)
        b->cf = gs_calloc((size_t)(2 * n) * BATCH_NODES, sizeof *b->cf); /* zero between groups */
    double *f = b->cf;
    double *outs[2 * BATCH_NODES];
    if (!c || !f) {
        free(c);
        return GS_ENOMEM;
    }
    for (int t = 0; t < cnt; t++)
        for (int comp = 0; comp < 2; comp++) {
            gs_index q = b->rowq[1 + 2 * batch[t] + comp];
            if (q >= 0)
                f[(size_t)(2 * t + comp) * (size_t)n + (size_t)q] = 1.0;
            outs[2 * t + comp] = c + (size_t)(2 * t + comp) * (size_t)nr;
        }
    gs_err e = gres_column(b, 2 * cnt, f, outs);
    for (int t = 0; t < cnt; t++) /* back to zero */
        for (int comp = 0; comp < 2; comp++) {
            gs_index q = b->rowq[1 + 2 * batch[t] + comp];
            if (q >= 0)
                f[(size_t)(2 * t + comp) * (size_t)n + (size_t)q] = 0.0;
        }
    if (e != GS_OK) {
        free(c);
        return e;
    }
    /* each node owns a copy of its two columns (freed one by one) */
    for (int t = 0; t < cnt && e == GS_OK; t++) {
        double *own = t == 0 ? c : gs_calloc((size_t)(2 * nr), sizeof *own);
        if (!own) {
            e = GS_ENOMEM;
            break;
        }
        if (t > 0)
            memcpy(own, c + (size_t)(2 * t) * (size_t)nr, (size_t)(2 * nr) * sizeof *own);
        b->col[batch[t]] = own;
        b->ncols++;
    }
    if (e == GS_OK && cnt > 1) { /* node batch[0] keeps the head of the buffer */
        double *sh = realloc(c, (size_t)(2 * nr) * sizeof *c);
        if (sh)
            b->col[batch[0]] = sh;
    }
    if (e != GS_OK && !b->col[batch[0]])
        free(c);
    return e;
}

gs_err gsi_fe_red_ensure_row(gs_fe_reduced *b, gs_index r)
{
    return r > 0 ? ensure_node(b, (r - 1) >> 1) : GS_OK;
}

gs_err gs_fe_reduced_new(const gs_fe_model *m, const gs_fe_reduced_opts *o, gs_fe_reduced **out)
{
    if (!out)
        return GS_EINVAL;
    *out = NULL;
    if (!m || !o || !(o->f_max_hz > 0) || o->eigensolver < 0 || o->eigensolver > 2 || o->n_nodes < 0 || (o->n_nodes > 0 && !o->nodes))
        return GS_EINVAL;
    if (!(m->mat.damping_m >= 0.0) || !isfinite(m->mat.damping_m))
        return GS_ERANGE;
    gs_fe_reduced *b = gs_calloc(1, sizeof *b);
    if (!b)
        return GS_ENOMEM;
    gsi_cholmod_start(&b->cc);
    b->m = m;
    b->ne = m->ne;
    b->n = m->ne + 1;
    b->held = o->held;
    b->fmax = o->f_max_hz;
    b->Itot = m->inertia_total;
    b->beta = m->mat.damping_s;
    b->alpha = m->mat.damping_m;
    b->gamma = o->residual_static ? 1.0 : 0.5;
    gs_index nn = m->n_nodes;
    b->cand_of = gs_calloc((size_t)nn + 1, sizeof *b->cand_of);
    b->scratch = gs_calloc((size_t)(b->n > MODES_MAX ? b->n : MODES_MAX), sizeof *b->scratch);
    gs_err e = (!b->cand_of || !b->scratch) ? GS_ENOMEM : GS_OK;
    for (gs_index i = 0; e == GS_OK && i < nn; i++)
        b->cand_of[i] = -1;
    gs_index nc = 0;
    for (gs_index j = 0; e == GS_OK && j < (o->nodes ? o->n_nodes : nn); j++) {
        gs_index node = o->nodes ? o->nodes[j] : j;
        if (node < 0 || node >= nn) {
            e = GS_EINVAL;
            break;
        }
        if (b->cand_of[node] < 0)
            b->cand_of[node] = nc++;
    }
    b->ncand = nc;
    b->nr = 1 + 2 * nc;
    if (e == GS_OK) {
        b->rowq = gs_calloc((size_t)b->nr, sizeof *b->rowq);
        b->col = gs_calloc((size_t)nc + 1, sizeof *b->col);
        b->tcol = gs_calloc((size_t)b->nr, sizeof *b->tcol);
        b->Y = gs_calloc((size_t)b->nr, sizeof *b->Y);
        b->ysup = gs_calloc((size_t)b->nr, sizeof *b->ysup);
        b->yin = gs_calloc((size_t)b->nr, 1);
        b->z0R = gs_calloc((size_t)b->nr, sizeof *b->z0R);
        b->Fa = gs_calloc((size_t)b->nr, sizeof *b->Fa);
        b->Fi = gs_calloc((size_t)b->nr, sizeof *b->Fi);
        b->Rf = gs_calloc((size_t)b->nr, sizeof *b->Rf);
        b->fl = gs_calloc((size_t)b->nr, sizeof *b->fl);
        b->fin = gs_calloc((size_t)b->nr, 1);
        b->blk_pos = gs_calloc((size_t)b->nr, sizeof *b->blk_pos);
        if (!b->rowq || !b->col || !b->tcol || !b->Y || !b->ysup || !b->yin || !b->z0R || !b->Fa || !b->Fi ||
            !b->Rf || !b->fl || !b->fin || !b->blk_pos)
            e = GS_ENOMEM;
        for (gs_index r = 0; e == GS_OK && r < b->nr; r++)
            b->blk_pos[r] = -1;
    }
    if (e == GS_OK) {
        b->rowq[0] = b->held ? -1 : b->ne;
        for (gs_index i = 0; i < nn; i++) {
            gs_index k = b->cand_of[i];
            if (k >= 0) {
                b->rowq[1 + 2 * k] = m->dof[2 * i];
                b->rowq[2 + 2 * k] = m->dof[2 * i + 1];
            }
        }
        b->K = gsi_fe_cholmod_matrix(m, 0.0, 1.0, &b->cc);
        b->L = b->K ? cholmod_l_analyze(b->K, &b->cc) : NULL;
        if (!b->L || !cholmod_l_factorize(b->K, b->L, &b->cc))
            e = GS_ENOMEM;
        else if (b->cc.status == CHOLMOD_NOT_POSDEF)
            e = GS_ESINGULAR;
    }
    if (e == GS_OK) {
        e = gsi_fe_red_compute_modes(b, o->eigensolver);
        if (e == GS_OK && getenv("GEARSIM_REDUCED_LOG"))
            fprintf(stderr, "reduced body: %ld elastic unknowns, %d modes kept (f_max %.6g Hz, highest %.6g Hz), "
                            "%ld candidate nodes; Lanczos runs %d, modes added by the first %d %d %d\n",
                    (long)b->ne, b->N, b->fmax, b->N ? sqrt(b->om2[b->N - 1]) / (2 * GS_PI) : 0.0, (long)nc,
                    b->lz_runs, b->lz_added[0], b->lz_added[1], b->lz_added[2]);
    }
    if (e == GS_OK) {
        int N = b->N;
        b->PR = gs_calloc((size_t)b->nr * (size_t)(N ? N : 1), sizeof *b->PR);
        b->inv_a = gs_calloc((size_t)(N ? N : 1), sizeof *b->inv_a);
        b->qm = gs_calloc((size_t)(N ? N : 1), sizeof *b->qm);
        b->vm = gs_calloc((size_t)(N ? N : 1), sizeof *b->vm);
        b->dqm = gs_calloc((size_t)(N ? N : 1), sizeof *b->dqm);
        b->tt = gs_calloc((size_t)(N ? N : 1), sizeof *b->tt);
        b->ww = gs_calloc((size_t)(N ? N : 1), sizeof *b->ww);
        if (!b->PR || !b->inv_a || !b->qm || !b->vm || !b->dqm || !b->tt || !b->ww)
            e = GS_ENOMEM;
        /* the rotation of the free body's elastic modes (the rigid one, 0, has no u) */
        for (int i = 1; e == GS_OK && !b->held && i < N; i++)
            b->tt[i] = sqrt(b->Itot) * b->Phi[(size_t)i * (size_t)b->n + (size_t)b->ne];
    }
    if (e == GS_OK) {
        for (gs_index r = 0; r < b->nr; r++)
            for (int i = 0; i < b->N; i++)
                b->PR[(size_t)r * (size_t)b->N + (size_t)i] =
                    b->rowq[r] < 0 ? 0.0 : b->Phi[(size_t)i * (size_t)b->n + (size_t)b->rowq[r]];
        if (!b->held) {
            double *f = gs_calloc((size_t)b->n, sizeof *f);
            if (!f)
                e = GS_ENOMEM;
            else {
                f[b->ne] = 1.0;
                double *outs[1] = {b->tcol};
                e = gres_column(b, 1, f, outs);
                free(f);
            }
        }
    }
    if (e != GS_OK) {
        gs_fe_reduced_free(&b);
        return e;
    }
    *out = b;
    return GS_OK;
}

void gs_fe_reduced_get_info(const gs_fe_reduced *b, gs_fe_reduced_info *info)
{
    memset(info, 0, sizeof *info);
    info->modes = b->N;
    info->elastic_modes = b->held ? b->N : b->N - 1;
    info->f_top_hz = b->N > 0 ? sqrt(b->om2[b->N - 1]) / (2 * GS_PI) : 0.0;
    info->rows = b->nr;
    info->cached_nodes = b->ncols;
    info->residual_support = b->nys;
    info->steps = b->steps;
    info->column_cpu_s = b->col_cpu;
    info->residual_loss = b->residual_loss;
}

/* ---- energies ----------------------------------------------------------- */

/* Y^T G_res Y over the support (columns present for every row of it). */
double gsi_fe_red_ygy(const gs_fe_reduced *b, const double *Yv, const gs_index *sup, gs_index ns)
{
    double s = 0;
    for (gs_index a = 0; a < ns; a++) {
        gs_index c = sup[a];
        double t = 0;
        for (gs_index k = 0; k < ns; k++)
            t += gsi_fe_red_gres(b, sup[k], c) * Yv[sup[k]];
        s += Yv[c] * t;
    }
    return s;
}

void gs_fe_reduced_energy(const gs_fe_reduced *b, double *T, double *V)
{
    double t = 0, v = 0;
    for (int i = 0; i < b->N; i++) {
        t += b->vm[i] * b->vm[i];
        v += b->om2[i] * b->qm[i] * b->qm[i];
    }
    v += gsi_fe_red_ygy(b, b->Y, b->ysup, b->nys);
    if (b->az != 0.0) {
        double zy = 0;
        for (gs_index a = 0; a < b->nys; a++)
            zy += b->z0R[b->ysup[a]] * b->Y[b->ysup[a]];
        v += 2 * b->az * zy + b->az * b->az * b->e0;
    }
    *T = 0.5 * t;
    *V = 0.5 * v;
}

double gs_fe_reduced_damped(const gs_fe_reduced *b)
{
    return b->damped;
}

void gs_fe_reduced_get_balance(const gs_fe_reduced *b, gs_fe_balance *o)
{
    gs_fe_reduced_energy(b, &o->kinetic, &o->elastic);
    o->energy0 = b->energy0;
    o->work_in = b->work_in;
    o->work_iface = b->work_iface;
    o->dissipated = b->dissipated;
    o->damped = b->damped;
    o->residual = o->kinetic + o->elastic - b->energy0 - b->work_in - b->work_iface + b->dissipated;
}

double gs_fe_reduced_angular_momentum(const gs_fe_reduced *b)
{
    return b->held ? 0.0 : sqrt(b->Itot) * b->vm[0];
}

void gs_fe_reduced_spin(gs_fe_reduced *b, double dw)
{
    if (!b->held)
        b->vm[0] += sqrt(b->Itot) * dw;
}

/* ---- state -------------------------------------------------------------- */

static void y_clear(gs_fe_reduced *b)
{
    for (gs_index a = 0; a < b->nys; a++) {
        b->Y[b->ysup[a]] = 0;
        b->yin[b->ysup[a]] = 0;
    }
    b->nys = 0;
}

gs_err gs_fe_reduced_set_state(gs_fe_reduced *b, double theta, double omega, const double *u_nodes,
                               const double *v_nodes)
{
    if (!b)
        return GS_EINVAL;
    if (b->in_step)
        return GS_ESTATE;
    gs_index n = b->n, ne = b->ne;
    const gs_fe_model *m = b->m;
    double *x = gs_calloc((size_t)(3 * n), sizeof *x);
    if (!x)
        return GS_ENOMEM;
    double *mx = x + n, *z = x + 2 * n;
    y_clear(b);
    b->az = 0;
    for (int pass = 0; pass < 2; pass++) {
        const double *src = pass ? v_nodes : u_nodes;
        memset(x, 0, (size_t)n * sizeof *x);
        for (gs_index i = 0; src && i < m->n_nodes; i++)
            for (int c = 0; c < 2; c++)
                if (m->dof[2 * i + c] >= 0)
                    x[m->dof[2 * i + c]] = src[2 * i + c];
        x[ne] = b->held ? 0.0 : (pass ? omega : theta);
        memset(mx, 0, (size_t)n * sizeof *mx);
        gsi_fe_symv2(m, 1.0, x, 0.0, x, mx);
        double st = gsi_fe_red_dotn(ne, m->s, x);
        for (gs_index i = 0; i < ne; i++)
            mx[i] += m->s[i] * x[ne];
        mx[ne] = st + b->Itot * x[ne];
        if (b->held)
            mx[ne] = 0;
        double *qv = pass ? b->vm : b->qm;
        for (int i = 0; i < b->N; i++)
            qv[i] = gsi_fe_red_dotn(n, b->Phi + (size_t)i * (size_t)n, mx);
        if (pass == 0) { /* the residual displacement z0 = x - Phi q */
            memcpy(z, x, (size_t)n * sizeof *z);
            for (int i = 0; i < b->N; i++) {
                const double *p = b->Phi + (size_t)i * (size_t)n;
                for (gs_index j = 0; j < n; j++)
                    z[j] -= b->qm[i] * p[j];
            }
            double zn = 0, xn = 0;
            for (gs_index j = 0; j < n; j++) {
                zn = fmax(zn, fabs(z[j]));
                xn = fmax(xn, fabs(x[j]));
            }
            if (zn > 1e-14 * xn && zn > 0) {
                if (!b->z0 && !(b->z0 = gs_calloc((size_t)n, sizeof *b->z0))) {
                    free(x);
                    return GS_ENOMEM;
                }
                memcpy(b->z0, z, (size_t)n * sizeof *z);
                b->e0 = gsi_fe_quadform(m, 0.0, 1.0, z);
                for (gs_index r = 0; r < b->nr; r++)
                    b->z0R[r] = b->rowq[r] < 0 ? 0.0 : z[b->rowq[r]];
                b->az = 1.0;
            }
        }
    }
    free(x);
    double T, V;
    gs_fe_reduced_energy(b, &T, &V);
    b->energy0 = T + V;
    b->work_in = b->work_iface = b->dissipated = b->damped = b->residual_loss = 0;
    return GS_OK;
}

gs_err gs_fe_reduced_hold_theta(gs_fe_reduced *b, bool held)
{
    if (!b)
        return GS_EINVAL;
    return held == b->held ? GS_OK : GS_EINVAL; /* the basis is made held or free */
}

gs_err gs_fe_reduced_set_step(gs_fe_reduced *b, double h, double brake_c)
{
    if (!b || !(h > 0) || !isfinite(h) || !(brake_c >= 0) || !isfinite(brake_c))
        return GS_EINVAL;
    if (b->in_step)
        return GS_ESTATE;
    b->h = h;
    b->c = brake_c;
    b->d = 0.5 + b->beta / h;
    b->dr = b->gamma + b->beta / h;
    b->r = (b->beta / h + b->gamma - 1.0) / b->dr;
    for (int i = 0; i < b->N; i++)
        b->inv_a[i] = 1.0 / (2.0 / (h * h) + b->d * b->om2[i] + (b->alpha > 0 && gsi_fe_red_is_elastic(b, i) ? b->alpha / h : 0.0));
    b->kap = 0;
    if (b->alpha > 0 && !b->held) {
        double tw = 0;
        for (int i = 0; i < b->N; i++) {
            b->ww[i] = b->tt[i] * b->inv_a[i];
            tw += b->tt[i] * b->ww[i];
        }
        b->kap = (b->alpha / h) / (1.0 + (b->alpha / h) * tw);
    }
    /* the brake's Sherman-Morrison factor: y_theta = C_bar(theta, theta) */
    double yt = b->held ? 0.0 : b->tcol[0] / b->dr;
    for (int i = 0; i < b->N; i++)
        yt += b->PR[i] * b->PR[i] * b->inv_a[i];
    if (b->kap != 0.0) {
        double w0 = gsi_fe_red_dotn(b->N, b->ww, b->PR);
        yt -= b->kap * w0 * w0;
    }
    b->kc = (b->held || brake_c == 0) ? 0.0 : (brake_c / h) / (1.0 + (brake_c / h) * yt);
    b->have_step = true;
    return GS_OK;
}

/* ---- fields, snapshots -------------------------------------------------- */

double gs_fe_reduced_theta(const gs_fe_reduced *b)
{
    if (b->held)
        return 0.0;
    double v = gsi_fe_red_dotn(b->N, b->PR, b->qm);
    for (gs_index a = 0; a < b->nys; a++)
        v += gsi_fe_red_gres(b, 0, b->ysup[a]) * b->Y[b->ysup[a]];
    return v + b->az * b->z0R[0];
}

double gs_fe_reduced_omega(const gs_fe_reduced *b)
{
    return b->held ? 0.0 : gsi_fe_red_dotn(b->N, b->PR, b->vm);
}

gs_err gs_fe_reduced_nodal(gs_fe_reduced *b, double *u_nodes, double *v_nodes)
{
    if (!b)
        return GS_EINVAL;
    gs_index n = b->n, ne = b->ne;
    const gs_fe_model *m = b->m;
    double *x = gs_calloc((size_t)(2 * n), sizeof *x);
    if (!x)
        return GS_ENOMEM;
    double *v = x + n;
    for (int i = 0; i < b->N; i++) {
        const double *p = b->Phi + (size_t)i * (size_t)n;
        for (gs_index j = 0; j < n; j++) {
            x[j] += b->qm[i] * p[j];
            v[j] += b->vm[i] * p[j];
        }
    }
    if (b->az != 0.0)
        for (gs_index j = 0; j < n; j++)
            x[j] += b->az * b->z0[j];
    gs_err e = GS_OK;
    if (b->nys > 0 && u_nodes) { /* G_res Y: one solve */
        double *f = gs_calloc((size_t)n, sizeof *f);
        double *o = gs_calloc((size_t)n, sizeof *o);
        if (!f || !o)
            e = GS_ENOMEM;
        for (gs_index a = 0; e == GS_OK && a < b->nys; a++)
            f[b->rowq[b->ysup[a]]] = b->Y[b->ysup[a]];
        if (e == GS_OK) {
            double ft = b->held ? 0.0 : f[ne] / b->Itot;
            for (gs_index i = 0; i < ne; i++)
                f[i] -= b->held ? 0.0 : b->m->s[i] * ft;
            e = gsi_fe_red_ksolve(b, 1, f, o);
        }
        if (e == GS_OK) {
            for (gs_index i = 0; i < ne; i++)
                x[i] += o[i];
            /* minus the kept elastic modes' share; Y on the rows */
            for (int i = 0; i < b->N; i++) {
                if (!(b->om2[i] > 0))
                    continue;
                double c = 0;
                for (gs_index a = 0; a < b->nys; a++)
                    c += b->PR[(size_t)b->ysup[a] * (size_t)b->N + (size_t)i] * b->Y[b->ysup[a]];
                c /= b->om2[i];
                const double *p = b->Phi + (size_t)i * (size_t)n;
                for (gs_index j = 0; j < ne; j++)
                    x[j] -= c * p[j];
            }
        }
        free(f), free(o);
    }
    for (gs_index i = 0; e == GS_OK && i < m->n_nodes; i++)
        for (int c = 0; c < 2; c++) {
            gs_index k = m->dof[2 * i + c];
            if (u_nodes)
                u_nodes[2 * i + c] = k >= 0 ? x[k] : 0.0;
            if (v_nodes)
                v_nodes[2 * i + c] = k >= 0 ? v[k] : 0.0;
        }
    free(x);
    return e;
}

/* Snapshot layout (the same size on every rank of a scene: it does not
 * depend on the modes): N, q (N), v (N), zeros up to 2 (ne + 1) + 1, then
 * Y (nr, by row), the residual amplitude, the support's size and its rows
 * in their order (nr slots; the sums over the support run in that order),
 * then the body's books: energy0, work_in, work_iface, dissipated, damped,
 * residual_loss and the step count (a resumed run books on from them). */
#define SNAP_BOOKS 7

size_t gs_fe_reduced_state_size_for(gs_index ne, gs_index n_candidates)
{
    size_t nr = 1 + 2 * (size_t)n_candidates;
    return 2 * ((size_t)ne + 1) + 2 * nr + 3 + SNAP_BOOKS;
}

size_t gs_fe_reduced_state_size(const gs_fe_reduced *b)
{
    return gs_fe_reduced_state_size_for(b->ne, b->ncand);
}

void gs_fe_reduced_save(const gs_fe_reduced *b, double *x)
{
    size_t off = 2 * (size_t)b->n + 1, nr = (size_t)b->nr;
    memset(x, 0, gs_fe_reduced_state_size(b) * sizeof *x);
    x[0] = (double)b->N;
    memcpy(x + 1, b->qm, (size_t)b->N * sizeof *x);
    memcpy(x + 1 + b->N, b->vm, (size_t)b->N * sizeof *x);
    memcpy(x + off, b->Y, nr * sizeof *x);
    x[off + nr] = b->az;
    x[off + nr + 1] = (double)b->nys;
    for (gs_index a = 0; a < b->nys; a++)
        x[off + nr + 2 + (size_t)a] = (double)b->ysup[a];
    double *bk = x + off + 2 * nr + 2;
    bk[0] = b->energy0;
    bk[1] = b->work_in;
    bk[2] = b->work_iface;
    bk[3] = b->dissipated;
    bk[4] = b->damped;
    bk[5] = b->residual_loss;
    bk[6] = (double)b->steps;
}

gs_err gs_fe_reduced_load(gs_fe_reduced *b, const double *x)
{
    if (!b || !x)
        return GS_EINVAL;
    if (x[0] != (double)b->N)
        return GS_EINVAL; /* another basis */
    size_t off = 2 * (size_t)b->n + 1, nr = (size_t)b->nr;
    double nys = x[off + nr + 1];
    if (!(nys >= 0 && nys <= (double)nr))
        return GS_EINVAL;
    /* the support: rows in range, each once, Y nonzero exactly there */
    gs_index ns = (gs_index)nys;
    unsigned char *seen = gs_calloc(nr, 1);
    if (!seen)
        return GS_ENOMEM;
    gs_err e = GS_OK;
    for (gs_index a = 0; a < ns && e == GS_OK; a++) {
        double rv = x[off + nr + 2 + (size_t)a];
        if (!(rv >= 0 && rv < (double)nr) || rv != floor(rv) || seen[(size_t)rv] || x[off + (size_t)rv] == 0.0)
            e = GS_EINVAL;
        else
            seen[(size_t)rv] = 1;
    }
    for (size_t r = 0; r < nr && e == GS_OK; r++)
        if (x[off + r] != 0.0 && !seen[r])
            e = GS_EINVAL;
    free(seen);
    if (e != GS_OK)
        return e;
    /* the residual displacement z0 is that of the initial state (set_state
     * at creation, the same in a new process for the same scene) */
    double az = x[off + nr];
    if (az != 0.0 && !b->z0)
        return GS_EINVAL; /* a residual displacement this body was not given */
    gs_fe_reduced_cancel_step(b);
    y_clear(b);
    memcpy(b->qm, x + 1, (size_t)b->N * sizeof *x);
    memcpy(b->vm, x + 1 + b->N, (size_t)b->N * sizeof *x);
    for (gs_index a = 0; a < ns; a++) {
        gs_index r = (gs_index)x[off + nr + 2 + (size_t)a];
        GS_TRY(gsi_fe_red_ensure_row(b, r));
        b->Y[r] = x[off + (size_t)r];
        b->yin[r] = 1;
        b->ysup[b->nys++] = r;
    }
    b->az = az;
    const double *bk = x + off + 2 * nr + 2;
    b->energy0 = bk[0];
    b->work_in = bk[1];
    b->work_iface = bk[2];
    b->dissipated = bk[3];
    b->damped = bk[4];
    b->residual_loss = bk[5];
    b->steps = bk[6] >= 0 ? (uint64_t)bk[6] : 0;
    return GS_OK;
}
