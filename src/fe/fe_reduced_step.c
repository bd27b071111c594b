/* SPDX-License-Identifier: MIT
 * A reduced elastic body (fe_reduced.c, docs/explanation/elastic_body.md "Reduced elastic body"):
 * its step (free increment, compliance among the rows, forces applied, the
 * end of the step with the massless residual's update). */
#include <cholmod.h>
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fe/fe_internal.h"
#include "fe/fe_reduced_internal.h"
#include "gearsim/util.h"

/* ---- the step ----------------------------------------------------------- */

static void fl_add(gs_fe_reduced *b, gs_index r)
{
    if (!b->fin[r]) {
        b->fin[r] = 1;
        b->fl[b->nfl++] = r;
    }
}

/* Row of a dof name: >= 0, -1 immovable (fixed node, held theta), -2 bad. */
static gs_index row_of(const gs_fe_reduced *b, gs_index dof)
{
    if (dof == GS_FE_DOF_THETA)
        return b->held ? -1 : 0;
    if (dof < 0 || dof >= 2 * b->m->n_nodes)
        return -2;
    gs_index node = dof >> 1;
    if (b->m->dof[dof] < 0)
        return -1;
    gs_index k = b->cand_of[node];
    return k < 0 ? -2 : 1 + 2 * k + (dof & 1);
}

gs_err gs_fe_reduced_begin_step(gs_fe_reduced *b, double moment_nm, const double *f_nodes)
{
    if (!b)
        return GS_EINVAL;
    if (!b->have_step || b->in_step)
        return GS_ESTATE;
    double h = b->h;
    /* applied forces on the rows */
    b->nfl = 0;
    b->moment = b->held ? 0.0 : moment_nm;
    if (b->moment != 0.0) {
        b->Fa[0] = b->moment;
        fl_add(b, 0);
    }
    for (gs_index i = 0; f_nodes && i < 2 * b->m->n_nodes; i++) {
        if (f_nodes[i] == 0.0)
            continue;
        gs_index r = row_of(b, i);
        if (r == -1)
            continue;
        if (r < 0) {
            for (gs_index a = 0; a < b->nfl; a++)
                b->Fa[b->fl[a]] = 0, b->fin[b->fl[a]] = 0;
            b->nfl = 0;
            return GS_EINVAL; /* a load on a node that is not a candidate */
        }
        GS_TRY(gsi_fe_red_ensure_row(b, r));
        b->Fa[r] += f_nodes[i];
        fl_add(b, r);
    }
    for (gs_index a = 0; a < b->nys; a++)
        fl_add(b, b->ysup[a]);
    for (gs_index a = 0; a < b->nfl; a++) {
        gs_index r = b->fl[a];
        b->Rf[r] = (b->Fa[r] - b->Y[r]) / b->dr;
    }
    /* modal free increments: g = Phi_rows^T Fa row by row (each row's modes
     * contiguous; the same order of sums per mode), then the scheme */
    double hb = 0.5 * h + b->beta;
    memset(b->dqm, 0, (size_t)b->N * sizeof *b->dqm);
    for (gs_index a = 0; a < b->nfl; a++) {
        gs_index r = b->fl[a];
        if (b->Fa[r] == 0.0)
            continue;
        const double *p = b->PR + (size_t)r * (size_t)b->N;
        for (int i = 0; i < b->N; i++)
            b->dqm[i] += p[i] * b->Fa[r];
    }
    if (b->alpha > 0) { /* - alpha (E + t t^T) v on the right-hand side, then H */
        double tv = gsi_fe_red_dotn(b->N, b->tt, b->vm);
        for (int i = 0; i < b->N; i++)
            b->dqm[i] -= b->alpha * ((gsi_fe_red_is_elastic(b, i) ? b->vm[i] : 0.0) + b->tt[i] * tv);
        double wr = 0;
        for (int i = 0; i < b->N; i++)
            wr += b->ww[i] * (b->dqm[i] - b->om2[i] * (b->qm[i] + hb * b->vm[i]));
        for (int i = 0; i < b->N; i++)
            b->dqm[i] = h * b->vm[i] + (b->dqm[i] - b->om2[i] * (b->qm[i] + hb * b->vm[i])) * b->inv_a[i] -
                        b->kap * b->ww[i] * wr;
    } else {
        for (int i = 0; i < b->N; i++)
            b->dqm[i] = h * b->vm[i] + (b->dqm[i] - b->om2[i] * (b->qm[i] + hb * b->vm[i])) * b->inv_a[i];
    }
    b->in_step = true;
    return GS_OK;
}

gs_err gs_fe_reduced_step(gs_fe_reduced *b, double moment_nm, const double *f_nodes)
{
    GS_TRY(gs_fe_reduced_begin_step(b, moment_nm, f_nodes));
    return gs_fe_reduced_end_step(b);
}

/* The unbraked increment at row r for the forces so far (r's column
 * present). */
static double row_inc_bar(const gs_fe_reduced *b, gs_index r)
{
    if (b->rowq[r] < 0)
        return 0.0;
    double v = gsi_fe_red_dotn(b->N, b->PR + (size_t)r * (size_t)b->N, b->dqm);
    /* column r (symmetric): its entries at the force rows lie close together */
    for (gs_index a = 0; a < b->nfl; a++)
        v += gsi_fe_red_gres(b, b->fl[a], r) * b->Rf[b->fl[a]];
    if (b->az != 0.0)
        v += (b->r - 1.0) * b->az * b->z0R[r];
    return v;
}

/* The unbraked compliance column of theta at row r. */
static double ycol(const gs_fe_reduced *b, gs_index r)
{
    if (b->held || b->rowq[r] < 0)
        return 0.0;
    double v = b->tcol[r] / b->dr;
    const double *p = b->PR + (size_t)r * (size_t)b->N;
    for (int i = 0; i < b->N; i++)
        v += p[i] * b->PR[i] * b->inv_a[i];
    if (b->kap != 0.0)
        v -= b->kap * gsi_fe_red_dotn(b->N, b->ww, p) * gsi_fe_red_dotn(b->N, b->ww, b->PR);
    return v;
}

gs_err gs_fe_reduced_increment(gs_fe_reduced *b, int n, const gs_index *dofs, double *dq_out)
{
    if (!b || n < 0 || (n > 0 && (!dofs || !dq_out)))
        return GS_EINVAL;
    if (!b->in_step)
        return GS_ESTATE;
    double ut = b->kc != 0.0 ? row_inc_bar(b, 0) : 0.0;
    for (int k = 0; k < n; k++) {
        gs_index r = row_of(b, dofs[k]);
        if (r == -2)
            return GS_EINVAL;
        if (r < 0) {
            dq_out[k] = 0.0;
            continue;
        }
        GS_TRY(gsi_fe_red_ensure_row(b, r));
        dq_out[k] = row_inc_bar(b, r) - (b->kc != 0.0 ? b->kc * ycol(b, r) * ut : 0.0);
    }
    return GS_OK;
}

gs_err gs_fe_reduced_node_displacement(const gs_fe_reduced *b, gs_index node, double u[2])
{
    u[0] = u[1] = 0;
    if (!b || node < 0 || node >= b->m->n_nodes)
        return GS_EINVAL;
    for (int c = 0; c < 2; c++) {
        gs_index r = row_of(b, 2 * node + c);
        if (r == -2)
            return GS_EINVAL;
        if (r < 0)
            continue;
        double v = gsi_fe_red_dotn(b->N, b->PR + (size_t)r * (size_t)b->N, b->qm);
        for (gs_index a = 0; a < b->nys; a++)
            v += gsi_fe_red_gres(b, r, b->ysup[a]) * b->Y[b->ysup[a]];
        v += b->az * b->z0R[r];
        u[c] = v;
    }
    return GS_OK;
}

gs_err gs_fe_reduced_compliance_sub(gs_fe_reduced *b, int n, const gs_index *dofs, int k, const int *sel,
                                    double *C)
{
    if (!b || n < 0 || k < 0 || (n > 0 && !dofs) || (k > 0 && (!sel || !C)))
        return GS_EINVAL;
    if (!b->have_step)
        return GS_ESTATE;
    gs_index *rr = gs_calloc((size_t)(k > 0 ? k : 1), sizeof *rr);
    double *yy = gs_calloc((size_t)(k > 0 ? k : 1), sizeof *yy);
    if (!rr || !yy) {
        free(rr), free(yy);
        return GS_ENOMEM;
    }
    gs_err e = GS_OK;
    for (int j = 0; j < n && e == GS_OK; j++) {
        gs_index r = row_of(b, dofs[j]);
        if (r == -2)
            e = GS_EINVAL;
        else if (r >= 0)
            e = gsi_fe_red_ensure_row(b, r);
    }
    for (int j = 0; j < k && e == GS_OK; j++) {
        if (sel[j] < 0 || sel[j] >= n) {
            e = GS_EINVAL;
            break;
        }
        rr[j] = row_of(b, dofs[sel[j]]);
        if (rr[j] >= 0 && b->rowq[rr[j]] < 0)
            rr[j] = -1;
        yy[j] = rr[j] >= 0 && b->kc != 0.0 ? ycol(b, rr[j]) : 0.0;
    }
    /* raw G_res and the modal sums over the selected rows: copied from the
     * last block where both rows were in it (the modal sums only for the
     * same h), else computed (bit for bit the same values) */
    double *G = NULL, *Mm = NULL;
    gs_index *nrw = NULL;
    size_t need = (size_t)k * (size_t)k + 1;
    bool same_h = b->blk_M && b->blk_h == b->h;
    /* the same rows in the same order, h and brake as the last block: its C */
    bool same = e == GS_OK && b->blk_C_ok && same_h && (gs_index)k == b->blk_n && b->blk_dr == b->dr &&
                b->blk_kc == b->kc;
    for (int j = 0; same && j < k; j++)
        same = rr[j] == b->blk_rr[j];
    if (same) {
        memcpy(C, b->blk_C, (size_t)k * (size_t)k * sizeof *C);
        free(rr), free(yy);
        return GS_OK;
    }
    if (e == GS_OK && b->sp_cap < need) {
        free(b->sp_G), free(b->sp_M), free(b->sp_r), free(b->sp_C), free(b->sp_rr);
        b->sp_G = malloc(need * sizeof *b->sp_G);
        b->sp_M = malloc(need * sizeof *b->sp_M);
        b->sp_r = malloc(need * sizeof *b->sp_r);
        b->sp_C = malloc(need * sizeof *b->sp_C);
        b->sp_rr = malloc(need * sizeof *b->sp_rr);
        b->sp_cap = (b->sp_G && b->sp_M && b->sp_r && b->sp_C && b->sp_rr) ? need : 0;
        if (!b->sp_cap)
            e = GS_ENOMEM;
    }
    if (e == GS_OK) {
        G = b->sp_G;
        Mm = b->sp_M;
        nrw = b->sp_r;
    }
    /* positions in the last block (-1: new or immovable) */
    gs_index *pos = e == GS_OK ? b->sp_rr : NULL;
    for (int j = 0; j < k && e == GS_OK; j++)
        pos[j] = rr[j] >= 0 ? b->blk_pos[rr[j]] : -1;
    for (int j = 0; j < k && e == GS_OK; j++) {
        gs_index pj = pos[j];
        double *Gj = G + (size_t)j * (size_t)k, *Mj = Mm + (size_t)j * (size_t)k, *Cj = C + (size_t)j * (size_t)k;
        for (int i = 0; i <= j; i++) {
            double g = 0, v = 0, cv = 0;
            if (rr[i] >= 0 && rr[j] >= 0) {
                gs_index pi = pos[i];
                bool old = pi >= 0 && pj >= 0;
                g = old ? b->blk_G[pi + pj * b->blk_n] : gsi_fe_red_gres(b, rr[i], rr[j]);
                if (old && same_h) {
                    v = b->blk_M[pi + pj * b->blk_n];
                } else {
                    const double *p = b->PR + (size_t)rr[i] * (size_t)b->N,
                                 *q = b->PR + (size_t)rr[j] * (size_t)b->N;
                    for (int t = 0; t < b->N; t++)
                        v += p[t] * q[t] * b->inv_a[t];
                    if (b->kap != 0.0)
                        v -= b->kap * gsi_fe_red_dotn(b->N, b->ww, p) * gsi_fe_red_dotn(b->N, b->ww, q);
                }
                cv = v + g / b->dr - b->kc * yy[i] * yy[j];
            }
            Gj[i] = G[j + (size_t)i * (size_t)k] = g;
            Mj[i] = Mm[j + (size_t)i * (size_t)k] = v;
            Cj[i] = C[j + (size_t)i * (size_t)k] = cv;
        }
    }
    if (e == GS_OK) { /* keep this block: rows listed in blk_r, positions in blk_pos */
        double *tc = b->blk_C;
        b->blk_C = b->sp_C;
        b->sp_C = tc;
        gs_index *tr = b->blk_rr;
        b->blk_rr = b->sp_rr;
        b->sp_rr = tr;
        memcpy(b->blk_C, C, (size_t)k * (size_t)k * sizeof *C);
        memcpy(b->blk_rr, rr, (size_t)k * sizeof *rr);
        b->blk_dr = b->dr;
        b->blk_kc = b->kc;
        b->blk_C_ok = true;
        for (gs_index t = 0; t < b->blk_rows; t++)
            b->blk_pos[b->blk_r[t]] = -1;
        /* swap: the last block's buffers become the spares */
        b->sp_G = b->blk_G;
        b->sp_M = b->blk_M;
        b->sp_r = b->blk_r;
        size_t cap = b->blk_cap;
        b->blk_cap = b->sp_cap;
        b->sp_cap = b->sp_G && b->sp_M && b->sp_r && b->sp_C && b->sp_rr ? cap : 0;
        if (!b->sp_cap) {
            free(b->sp_G), free(b->sp_M), free(b->sp_r), free(b->sp_C), free(b->sp_rr);
            b->sp_G = b->sp_M = b->sp_C = NULL;
            b->sp_r = b->sp_rr = NULL;
        }
        b->blk_G = G;
        b->blk_M = Mm;
        b->blk_h = b->h;
        b->blk_r = nrw;
        b->blk_n = k;
        b->blk_rows = 0;
        for (int j = 0; j < k; j++)
            if (rr[j] >= 0 && b->blk_pos[rr[j]] < 0) {
                b->blk_pos[rr[j]] = j;
                b->blk_r[b->blk_rows++] = rr[j];
            }
    }
    free(rr), free(yy);
    return e;
}

gs_err gs_fe_reduced_compliance(gs_fe_reduced *b, int n, const gs_index *dofs, double *C)
{
    int *sel = gs_calloc((size_t)(n > 0 ? n : 1), sizeof *sel);
    if (!sel)
        return GS_ENOMEM;
    for (int j = 0; j < n; j++)
        sel[j] = j;
    gs_err e = gs_fe_reduced_compliance_sub(b, n, dofs, n, sel, C);
    free(sel);
    return e;
}

/* Add force f on row r to the step (modal and residual parts). */
static void add_force(gs_fe_reduced *b, gs_index r, double f)
{
    const double *p = b->PR + (size_t)r * (size_t)b->N;
    for (int i = 0; i < b->N; i++)
        b->dqm[i] += p[i] * f * b->inv_a[i];
    if (b->kap != 0.0) {
        double c = b->kap * gsi_fe_red_dotn(b->N, b->ww, p) * f;
        for (int i = 0; i < b->N; i++)
            b->dqm[i] -= c * b->ww[i];
    }
    fl_add(b, r);
    b->Rf[r] += f / b->dr;
}

gs_err gs_fe_reduced_apply(gs_fe_reduced *b, int n, const gs_index *dofs, const double *f)
{
    if (!b || n < 0 || (n > 0 && (!dofs || !f)))
        return GS_EINVAL;
    if (!b->in_step)
        return GS_ESTATE;
    for (int k = 0; k < n; k++) {
        gs_index r = row_of(b, dofs[k]);
        if (r == -2)
            return GS_EINVAL;
    }
    for (int k = 0; k < n; k++) {
        gs_index r = row_of(b, dofs[k]);
        if (r < 0 || b->rowq[r] < 0 || f[k] == 0.0)
            continue;
        GS_TRY(gsi_fe_red_ensure_row(b, r));
        b->Fi[r] += f[k];
        add_force(b, r, f[k]);
    }
    return GS_OK;
}

static void step_clear(gs_fe_reduced *b)
{
    for (gs_index a = 0; a < b->nfl; a++) {
        gs_index r = b->fl[a];
        b->Fa[r] = b->Fi[r] = b->Rf[r] = 0;
        b->fin[r] = 0;
    }
    b->nfl = 0;
    b->in_step = false;
}

void gs_fe_reduced_cancel_step(gs_fe_reduced *b)
{
    if (b && b->in_step)
        step_clear(b);
}

gs_err gs_fe_reduced_end_step(gs_fe_reduced *b)
{
    if (!b)
        return GS_EINVAL;
    if (!b->in_step)
        return GS_ESTATE;
    double h = b->h;
    /* the brake: a force on theta from the unbraked increment */
    double fb = 0;
    if (b->kc != 0.0) {
        fb = -b->kc * row_inc_bar(b, 0);
        add_force(b, 0, fb);
    }
    /* increments at the force rows: work and the brake's dissipation */
    double win = 0, wif = 0, dt = 0;
    for (gs_index a = 0; a < b->nfl; a++) {
        gs_index r = b->fl[a];
        if (b->Fa[r] == 0.0 && b->Fi[r] == 0.0 && !(r == 0 && fb != 0.0))
            continue;
        double dq = row_inc_bar(b, r);
        win += b->Fa[r] * dq;
        wif += b->Fi[r] * dq;
        if (r == 0)
            dt = dq;
    }
    double dis = -fb * dt;
    /* material damping: modal part and the residual's */
    double dmp = 0;
    for (int i = 0; i < b->N; i++)
        dmp += b->om2[i] * b->dqm[i] * b->dqm[i];
    double dres = gsi_fe_red_ygy(b, b->Rf, b->fl, b->nfl);
    if (b->az != 0.0) {
        double zr = 0, f = (b->r - 1.0) * b->az;
        for (gs_index a = 0; a < b->nfl; a++)
            zr += b->z0R[b->fl[a]] * b->Rf[b->fl[a]];
        dres += 2 * f * zr + f * f * b->e0;
    }
    /* the static rule's own loss (gamma - 1/2) dY^T G_res dY, booked */
    double rloss = (b->gamma - 0.5) * dres;
    dmp = b->beta / h * (dmp + dres);
    if (b->alpha > 0) { /* dq^T alpha (E + t t^T) dq / h on the modes */
        double me = 0, td = gsi_fe_red_dotn(b->N, b->tt, b->dqm);
        for (int i = 0; i < b->N; i++)
            me += gsi_fe_red_is_elastic(b, i) ? b->dqm[i] * b->dqm[i] : 0.0;
        dmp += b->alpha / h * (me + td * td);
    }
    /* the new state */
    for (int i = 0; i < b->N; i++) {
        b->qm[i] += b->dqm[i];
        b->vm[i] = 2.0 * b->dqm[i] / h - b->vm[i];
    }
    double ymax = 0;
    for (gs_index a = 0; a < b->nfl; a++) {
        gs_index r = b->fl[a];
        b->Y[r] += b->Rf[r];
        ymax = fmax(ymax, fabs(b->Y[r]));
    }
    b->az *= b->r;
    if (fabs(b->az) < 1e-300)
        b->az = 0;
    /* the support: rows with |Y| above round-off of the largest */
    b->nys = 0;
    for (gs_index a = 0; a < b->nfl; a++) {
        gs_index r = b->fl[a];
        if (fabs(b->Y[r]) > 1e-15 * ymax) {
            b->ysup[b->nys++] = r;
            b->yin[r] = 1;
        } else {
            b->Y[r] = 0;
            b->yin[r] = 0;
        }
    }
    b->work_in += win;
    b->work_iface += wif;
    b->damped += dmp + rloss; /* the body's own dissipation, as the step books it */
    b->dissipated += dis + dmp + rloss;
    b->residual_loss += rloss;
    b->steps++;
    step_clear(b);
    return GS_OK;
}
