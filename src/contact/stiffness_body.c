/* SPDX-License-Identifier: MIT
 * Quasi-static mesh stiffness (stiffness.c): the elastic bodies, their mesh,
 * model and factor, and the cache of compliance columns among the boundary
 * dofs the contact rows need, with the zones of teeth they cover. */
#include <hdf5.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "contact/stiffness_hook.h"
#include "contact/stiffness_internal.h"
#include "gearsim/contact.h"
#include "gearsim/fe.h"
#include "gearsim/fe_static.h"
#include "gearsim/mesh.h"
#include "gearsim/models.h"
#include "gearsim/qp.h"
#include "gearsim/stiffness.h"
#include "io/h5attr.h"
#include "gearsim/util.h"

void gsi_stiff_sbody_free(sbody *b)
{
    for (int j = 0; j < b->nd; j++) {
        free(b->yi[j]);
        free(b->yv[j]);
    }
    free(b->slot);
    free(b->ynz);
    for (int j = 0; j < b->ncol; j++)
        free(b->col[j]);
    free(b->yi);
    free(b->yv);
    free(b->col);
    free(b->G);
    free(b->gk);
    free(b->fd);
    free(b->z);
    free(b->bpos);
    free(b->bdof);
    free(b->btooth);
    free(b->zt);
    free(b->zk);
    free(b->zdof);
    free(b->xy_ref);
    free(b->u);
    gs_fe_static_free(&b->fs);
    gs_fe_model_free(&b->model);
    gs_mesh_free(&b->mesh);
}

/* The tooth of gear `g` (centre c, turned by theta) nearest the line of
 * centres towards the other gear (centre co): where it meets that gear. */
static int contact_tooth(const gs_gear_params *g, const double c[2], const double co[2],
                         bool other_internal, double theta)
{
    double phic = atan2(co[1] - c[1], co[0] - c[0]) + (other_internal ? GS_PI : 0.0);
    long t = lround((phic - theta) / (2.0 * GS_PI / g->teeth));
    return (int)((t % g->teeth + g->teeth) % g->teeth);
}

/* Local refinement (mesh.fine_teeth): centre the fine teeth of both gears
 * on the teeth in contact halfway through the roll range (docs/explanation/geometry.md
 * "Local refinement"), the rotations those of gs_stiffness_next. */
void gsi_stiff_fine_centres(const gs_scene *sc, const int bidx[2], const gs_stiffness_opts *o,
                            int centre[2])
{
    const gs_scene_body *A = &sc->bodies[bidx[0]], *B = &sc->bodies[bidx[1]];
    double cA[2], cB[2];
    gs_scene_body_centre(sc, bidx[0], cA);
    gs_scene_body_centre(sc, bidx[1], cB);
    double rb = gs_gear_base_radius(&A->gear);
    double bw = fmin(A->gear.face_width_m, B->gear.face_width_m);
    double T = o->torque_nm != 0.0 ? o->torque_nm : gsi_stiff_default_torque(sc, bidx[0], rb, bw);
    double sgn = T > 0 ? 1.0 : -1.0, pitch = 2.0 * GS_PI / A->gear.teeth, roll = 0.5 * o->cycles;
    double ratio = (double)A->gear.teeth / B->gear.teeth *
                   (A->gear.kind == GS_GEAR_INTERNAL || B->gear.kind == GS_GEAR_INTERNAL ? 1.0 : -1.0);
    double thB0 = gs_pair_mesh_phase(&A->gear, cA, A->angle0 + sgn * o->phase * pitch, &B->gear, cB,
                                     B->angle0);
    double thA = A->angle0 + sgn * (o->phase + roll) * pitch;
    double thB = gs_pair_mesh_phase(&A->gear, cA, thA, &B->gear, cB, thB0 + ratio * sgn * roll * pitch);
    centre[0] = contact_tooth(&A->gear, cA, cB, B->gear.kind == GS_GEAR_INTERNAL, thA);
    centre[1] = contact_tooth(&B->gear, cB, cA, A->gear.kind == GS_GEAR_INTERNAL, thB);
}

/* fine: 0, or the number of teeth of the `fine` setting (its mesh replaces
 * the scene's density) */
gs_err gsi_stiff_sbody_init(const gs_scene *sc, int bi, int refine, int order, int fine,
                            int fine_centre, sbody *b, gs_diag *d)
{
    char field[64];
    snprintf(field, sizeof field, "bodies[%d]", bi);
    b->sb = &sc->bodies[bi];
    if (b->sb->type != GS_BODY_GEAR)
        return gs_diag_set(d, GS_ERANGE, field, "'%s' is not a gear", b->sb->name);
    gs_scene_body_centre(sc, bi, b->c);
    gs_scene_body sbo = *b->sb; /* the scene's body with the analysis' element order */
    if (fine) { /* the `fine` setting: local refinement on the teeth in contact */
        gs_gear_mesh_opts fo;
        gs_gear_mesh_opts_fine(&fo);
        sbo.mesh = (gs_mesh_density){fo.flank, fo.across, fo.rim, fo.refine, fo.grading,
                                     fo.order, fine, fo.fine_refine, 0};
        refine = -1;
    } else if (order > 0)
        sbo.mesh.order = order;
    sbo.mesh.fine_centre = fine_centre;
    gs_diag md;
    gs_diag_clear(&md);
    double t0 = gs_cpu_now();
    gs_err e = gs_scene_gear_mesh_refined(&sbo, refine, &b->mesh, &md);
    if (e != GS_OK)
        return gs_diag_set(d, e, field, "cannot mesh '%s': %s (%s)", b->sb->name, md.message,
                           md.field);
    if (gs_gear_mods_any(b->sb->mods) ||
        (b->sb->pitch_error_tooth >= 0 && b->sb->pitch_error != 0.0)) {
        /* The perfect gear's nodes, for the no-load reference of te_loaded. */
        gs_mesh *pm = NULL;
        e = gs_scene_gear_mesh_perfect(&sbo, refine, &pm, &md);
        if (e == GS_OK && pm->n_nodes != b->mesh->n_nodes)
            e = GS_EINTERNAL;
        if (e == GS_OK) {
            b->xy_ref = pm->xy;
            pm->xy = NULL;
        }
        gs_mesh_free(&pm);
        if (e != GS_OK)
            return gs_diag_set(d, e, field, "cannot mesh the perfect '%s'", b->sb->name);
    }
    e = gs_fe_model_new(b->mesh, &b->sb->material, b->sb->gear.face_width_m, 0.0, &b->model);
    double t1 = gs_cpu_now();
    if (e == GS_OK)
        e = gs_fe_static_new(b->model, &b->fs);
    b->t_mesh = t1 - t0;
    b->t_factor = gs_cpu_now() - t1;
    if (e != GS_OK)
        return gs_diag_set(d, e, field, "static finite element model of '%s' failed: %s",
                           b->sb->name, gs_strerror(e));
    gs_index n = b->mesh->n_nodes;
    b->nb = b->mesh->n_boundary;
    b->bpos = malloc((size_t)n * sizeof *b->bpos);
    b->bdof = malloc((size_t)(2 * b->nb) * sizeof *b->bdof);
    b->slot = malloc((size_t)(2 * b->nb) * sizeof *b->slot);
    b->u = gs_calloc((size_t)(2 * n), sizeof *b->u);
    b->z = gs_calloc((size_t)gs_fe_static_size(b->fs) + (size_t)(2 * b->nb) + 1, sizeof *b->z);
    b->btooth = malloc(((size_t)b->nb + 1) * sizeof *b->btooth);
    b->zt = gs_calloc((size_t)b->sb->gear.teeth + 1, 1);
    b->zk = malloc(((size_t)b->nb + 1) * sizeof *b->zk);
    b->zdof = malloc((size_t)(2 * b->nb + 1) * sizeof *b->zdof);
    if (!b->bpos || !b->bdof || !b->slot || !b->u || !b->z || !b->btooth || !b->zt || !b->zk ||
        !b->zdof)
        return GS_ENOMEM;
    for (gs_index k = 0; k < b->nb; k++)
        b->btooth[k] = gsi_stiff_node_tooth(b->mesh, b->sb->gear.teeth, b->mesh->boundary[k]);
    for (gs_index j = 0; j < 2 * b->nb; j++)
        b->slot[j] = -1;
    for (gs_index i = 0; i < n; i++)
        b->bpos[i] = -1;
    for (gs_index k = 0; k < b->nb; k++) {
        b->bpos[b->mesh->boundary[k]] = k;
        b->bdof[2 * k] = gs_fe_dof_node(b->mesh->boundary[k], 0);
        b->bdof[2 * k + 1] = gs_fe_dof_node(b->mesh->boundary[k], 1);
    }
    return GS_OK;
}

/* Grow the cache of body b to hold n dofs. */
static gs_err sbody_grow(sbody *b, int n)
{
    if (n <= b->capd)
        return GS_OK;
    int c = n > 2 * b->capd ? n : 2 * b->capd;
    size_t cn = (size_t)c;
    GROW(b->ynz, cn);
    GROW(b->yi, cn);
    GROW(b->yv, cn);
    GROW(b->fd, cn);
    GROW(b->col, cn);
    double *G = malloc(cn * cn * sizeof *G);
    unsigned char *gk = gs_calloc(cn * cn, 1);
    if (!G || !gk) {
        free(G);
        free(gk);
        return GS_ENOMEM;
    }
    for (int i = 0; i < b->nd; i++) {
        memcpy(G + (size_t)i * cn, b->G + (size_t)i * (size_t)b->capd, (size_t)b->nd * sizeof *G);
        memcpy(gk + (size_t)i * cn, b->gk + (size_t)i * (size_t)b->capd, (size_t)b->nd);
    }
    free(b->G);
    free(b->gk);
    b->G = G;
    b->gk = gk;
    b->capd = c;
    return GS_OK;
}

/* The boundary-dof columns of the cached dofs b->ncol.. (for the
 * displacements the search needs): back substitutions of their half
 * columns, in batches (one multi-right-hand-side solve each). */
static gs_err sbody_columns(sbody *b)
{
    size_t ne = (size_t)gs_fe_static_size(b->fs), len = (size_t)(2 * b->nb);
    for (int d0 = b->ncol; d0 < b->nd; d0 += STIFF_BATCH) {
        int k = b->nd - d0 < STIFF_BATCH ? b->nd - d0 : STIFF_BATCH;
        double *Z = gs_calloc((size_t)k * ne + 1, sizeof *Z);
        double *out = malloc((size_t)k * len * sizeof *out + 1);
        if (!Z || !out) {
            free(Z);
            free(out);
            return GS_ENOMEM;
        }
        for (int j = 0; j < k; j++)
            for (gs_index q = 0; q < b->ynz[d0 + j]; q++)
                Z[(size_t)j * ne + (size_t)b->yi[d0 + j][q]] = b->yv[d0 + j][q];
        gs_err e = gs_fe_static_back(b->fs, k, Z, 2 * b->nb, b->bdof, out);
        for (int j = 0; j < k && e == GS_OK; j++) {
            b->col[d0 + j] = malloc(len * sizeof *out);
            if (!b->col[d0 + j])
                e = GS_ENOMEM;
            else
                memcpy(b->col[d0 + j], out + (size_t)j * len, len * sizeof *out);
            b->ncol = d0 + j + 1;
        }
        free(Z);
        free(out);
        GS_TRY(e);
    }
    return GS_OK;
}

/* Make sure the half columns of the dofs of the listed nodes (mesh
 * numbering, boundary nodes) are cached. */
gs_err gsi_stiff_sbody_need(sbody *b, int n, const gs_index *nodes)
{
    double t0 = gs_cpu_now();
    int nd0 = b->nd;
    for (int i = 0; i < n; i++) {
        gs_index k = b->bpos[nodes[i]];
        if (k < 0)
            return GS_EINTERNAL;
        for (int comp = 0; comp < 2; comp++) {
            if (b->slot[2 * k + comp] >= 0)
                continue;
            GS_TRY(sbody_grow(b, b->nd + 1));
            gs_index nz;
            const gs_index *idx;
            const double *val;
            GS_TRY(gs_fe_static_half_column(b->fs, b->bdof[2 * k + comp], &nz, &idx, &val));
            int d = b->nd;
            b->yi[d] = malloc(((size_t)nz + 1) * sizeof *b->yi[d]);
            b->yv[d] = malloc(((size_t)nz + 1) * sizeof *b->yv[d]);
            if (!b->yi[d] || !b->yv[d]) {
                free(b->yi[d]);
                free(b->yv[d]);
                return GS_ENOMEM;
            }
            memcpy(b->yi[d], idx, (size_t)nz * sizeof *idx);
            memcpy(b->yv[d], val, (size_t)nz * sizeof *val);
            b->ynz[d] = nz;
            b->slot[2 * k + comp] = d;
            b->nd++;
        }
    }
    if (b->ncol > 0)
        GS_TRY(sbody_columns(b));
    b->columns += b->nd - nd0;
    b->t_columns += gs_cpu_now() - t0;
    return GS_OK;
}

/* Make sure the Gram entries G_de = y_d . y_e among the n cached dofs sl
 * (repeats allowed) are known: per dof that lacks one, one scatter of its
 * half column and one gather per missing partner. */
void gsi_stiff_sbody_gram(sbody *b, int n, const int *sl)
{
    double t0 = gs_cpu_now();
    size_t cap = (size_t)b->capd;
    for (int i = 0; i < n; i++) {
        int d = sl[i];
        const unsigned char *kd = b->gk + (size_t)d * cap;
        int need = 0;
        for (int j = 0; j < n && !need; j++)
            need = !kd[sl[j]];
        if (!need)
            continue;
        for (gs_index q = 0; q < b->ynz[d]; q++)
            b->z[b->yi[d][q]] = b->yv[d][q];
        for (int j = 0; j < n; j++) {
            int e = sl[j];
            if (b->gk[(size_t)d * cap + (size_t)e])
                continue;
            /* four partial sums: the gathered dot product is otherwise
             * bound by the latency of one chain of additions */
            const double *yv = b->yv[e], *z = b->z;
            const gs_index *yi = b->yi[e];
            gs_index nz = b->ynz[e], q = 0;
            double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
            for (; q + 4 <= nz; q += 4) {
                s0 += yv[q] * z[yi[q]];
                s1 += yv[q + 1] * z[yi[q + 1]];
                s2 += yv[q + 2] * z[yi[q + 2]];
                s3 += yv[q + 3] * z[yi[q + 3]];
            }
            for (; q < nz; q++)
                s0 += yv[q] * z[yi[q]];
            double sum = (s0 + s1) + (s2 + s3);
            b->G[(size_t)d * cap + (size_t)e] = b->G[(size_t)e * cap + (size_t)d] = sum;
            b->gk[(size_t)d * cap + (size_t)e] = b->gk[(size_t)e * cap + (size_t)d] = 1;
        }
        for (gs_index q = 0; q < b->ynz[d]; q++)
            b->z[b->yi[d][q]] = 0.0;
    }
    b->t_columns += gs_cpu_now() - t0;
}

/* The boundary displacements u = C f from the forces f_d on the cached
 * dofs (b->fd). Two ways with the same result: one back substitution of
 * sum_d f_d y_d (its cost is one pass over L per linearisation), or the
 * sum of the cached dofs' boundary columns (a batched back substitution
 * per new dof, then nearly free per linearisation). The first is used
 * until the back substitutions outnumber half the cached dofs (many
 * linearisations per new contact dof, as with the near-field fixed point),
 * then the columns of all cached dofs are computed and used from there on:
 * never more than about twice the cheaper way's cost. */
gs_err gsi_stiff_sbody_displace(sbody *b)
{
    double t0 = gs_cpu_now();
    size_t len = (size_t)(2 * b->nb);
    if (b->ncol == 0 && 2.0 * b->backw >= (double)b->nd) {
        double t1 = gs_cpu_now();
        GS_TRY(sbody_columns(b));
        b->t_columns += gs_cpu_now() - t1;
        t0 += gs_cpu_now() - t1;
    }
    double *v = b->z + (size_t)gs_fe_static_size(b->fs);
    if (b->ncol > 0) {
        memset(v, 0, len * sizeof *v);
        for (int d = 0; d < b->nd; d++) {
            double f = b->fd[d];
            if (f != 0.0)
                for (size_t q = 0; q < len; q++)
                    v[q] += f * b->col[d][q];
        }
    } else {
        for (int d = 0; d < b->nd; d++) {
            double f = b->fd[d];
            if (f != 0.0)
                for (gs_index q = 0; q < b->ynz[d]; q++)
                    b->z[b->yi[d][q]] += f * b->yv[d][q];
        }
        gs_err e;
        if (b->zone_on && !b->zall) {
            e = gs_fe_static_back_rows(b->fs, b->z, 2 * b->nzn, b->zdof, v, &b->zfrac);
            b->backw += b->zfrac;
        } else {
            e = gs_fe_static_back(b->fs, 1, b->z, 2 * b->nb, b->bdof, v);
            b->backw += 1.0;
        }
        memset(b->z, 0, (size_t)gs_fe_static_size(b->fs) * sizeof *b->z);
        GS_TRY(e);
        b->nback++;
        if (b->zone_on && !b->zall) {
            for (gs_index i = 0; i < b->nzn; i++) {
                gs_index node = b->mesh->boundary[b->zk[i]];
                b->u[2 * node] = v[2 * i];
                b->u[2 * node + 1] = v[2 * i + 1];
            }
            b->dirty = 1;
            b->t_solves += gs_cpu_now() - t0;
            return GS_OK;
        }
    }
    for (gs_index q = 0; q < b->nb; q++) {
        gs_index node = b->mesh->boundary[q];
        b->u[2 * node] = v[2 * q];
        b->u[2 * node + 1] = v[2 * q + 1];
    }
    b->dirty = 1;
    b->t_solves += gs_cpu_now() - t0;
    return GS_OK;
}

/* Tooth of a node of a gear from its polar angle (tooth t centred at 2 pi t / z). */
int gsi_stiff_node_tooth(const gs_mesh *m, int z, gs_index node)
{
    double ang = atan2(m->xy[2 * node + 1], m->xy[2 * node]);
    long t = lround(ang / (2.0 * GS_PI / z));
    return (int)(((t % z) + z) % z);
}

/* The zone's node and dof lists from its teeth (zt). */
void gsi_stiff_zone_rebuild(sbody *b)
{
    int z = b->sb->gear.teeth, all = 1;
    for (int t = 0; t < z; t++)
        all = all && b->zt[t];
    b->zall = all;
    b->nzn = 0;
    for (gs_index k = 0; k < b->nb; k++)
        if (b->zt[b->btooth[k]]) {
            b->zk[b->nzn] = k;
            b->zdof[2 * b->nzn] = b->bdof[2 * k];
            b->zdof[2 * b->nzn + 1] = b->bdof[2 * k + 1];
            b->nzn++;
        }
}

/* Add tooth t and its neighbours to the zone; 1 when one was new. */
int gsi_stiff_zone_add(sbody *b, int t)
{
    int z = b->sb->gear.teeth, grew = 0;
    for (int o = -1; o <= 1; o++) {
        int u = ((t + o) % z + z) % z;
        if (!b->zt[u]) {
            b->zt[u] = 1;
            grew = 1;
        }
    }
    return grew;
}
