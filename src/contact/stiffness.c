/* SPDX-License-Identifier: MIT
 * Quasi-static mesh stiffness and static transmission error of a gear pair
 * (include/gearsim/stiffness.h, docs/STIFFNESS.md).
 *
 * Per load case the unknowns are the contact forces lambda (one per contact
 * row i, gap g_i) and the driver's rotation delta; the elastic displacements
 * are condensed with the static compliance C_b = K_b^{-1} of each body,
 * restricted to its boundary loop (columns computed once per node and
 * cached). Linearised at the current state (delta_k, u_k):
 *     g_i(delta, u) ~ gbar_i + a_i delta + B_i u,
 *     gbar_i = g_i(q_k) - a_i delta_k - B_i u_k,   a_i = dg_i/dtheta_driver,
 * and u = C B^T lambda. The minimum of the total potential energy
 * 1/2 u^T K u - T delta under g >= 0 has the dual
 *     minimise 1/2 lambda^T W lambda + gbar^T lambda,  W = B C B^T,
 *     subject to a^T lambda = -T (torque balance), lambda >= 0,
 * whose equality multiplier is -delta. Solved with the Goldfarb-Idnani QP;
 * then the gaps are re-evaluated at the deformed position and the step
 * repeats until delta settles (twice below 1e-7 of the elastic rotation). */
#include <hdf5.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "contact/stiffness_hook.h"
#include "gearsim/contact.h"
#include "gearsim/fe.h"
#include "gearsim/fe_static.h"
#include "gearsim/mesh.h"
#include "gearsim/models.h"
#include "gearsim/qp.h"
#include "gearsim/stiffness.h"
#include "io/h5attr.h"
#include "gearsim/util.h"

/* Compliance columns per back substitution (bounds the dense work to
 * STIFF_BATCH free-dof vectors). */
#define STIFF_BATCH 32
/* Automatic near-field depth, in modules. */
#define GS_NF_DEPTH 0.2
/* A contact point within this many modules of a tip circle is a corner contact. */
#define GS_NF_CORNER 0.02
/* Near-field correction: half-width of the gap fit along the flank, module. */
#define GS_NF_FIT 0.25
/* ... and whose parabola is no more curved than this many times the
 * flanks' own relative curvature (a neighbour whose foot lies beyond the
 * master's tip or form point is far off the flanks' gap: no vertex). */
#define GS_NF_FIT_CURV 2.0

void gs_stiffness_opts_defaults(gs_stiffness_opts *o)
{
    o->positions = 24;
    o->torque_nm = 0.0;
    o->driver = 0;
    o->refine = -1;
    o->phase = 0.0;
    o->tangent = 1;
    o->tangent_step = 0.0;
    o->max_iter = 12;
    o->cycles = 1;
    o->order = 0;
    o->nearfield = 2;
    o->nearfield_depth_mm = 0.0;
    o->fine = 0;
    o->all_rows = 0;
    o->all_dofs = 0;
}

void gs_stiffness_result_clear(gs_stiffness_result *r)
{
    if (!r)
        return;
    free(r->pt);
    memset(r, 0, sizeof *r);
}

/* One elastic body: mesh, model, factor, and the compliance among the
 * boundary dofs that contact rows have needed so far (a cache across
 * linearisations and roll positions): their half columns y_d
 * (gs_fe_static_half_column) and the Gram matrix G_de = y_d . y_e =
 * (K^{-1})_de. */
typedef struct sbody {
    const gs_scene_body *sb;
    gs_mesh *mesh;
    gs_fe_model *model;
    gs_fe_static *fs;
    gs_index nb;          /* boundary nodes */
    gs_index *bpos;       /* n_nodes: position on the boundary loop, or -1 */
    gs_index *bdof;       /* 2 nb: boundary dofs (gs_fe_dof_node) */
    int *slot;            /* 2 nb: cache slot of boundary dof j, or -1 */
    int nd, capd;         /* cached dofs, capacity */
    gs_index *ynz;        /* capd: nonzeros of each half column */
    gs_index **yi;        /* capd: its pattern (factor positions, ascending) */
    double **yv;          /* capd: its values */
    double *G;            /* capd x capd: Gram matrix of the cached dofs (the entries
                           * flagged in gk: computed when two dofs first meet in the rows
                           * of one linearisation) */
    unsigned char *gk;    /* capd x capd: G entry known */
    double **col;         /* capd: compliance column of each cached dof at the boundary dofs
                           * (the first ncol; ncol = 0 while the displacements come from
                           * one back substitution per linearisation) */
    int ncol;
    long nback;           /* back substitutions for displacements so far */
    double backw;         /* their cost in full back substitutions (partial ones: the
                           * fraction of L visited) */
    /* Displacement zone (docs/STIFFNESS.md "Displacement zone"): the
     * displacements are computed only at the boundary nodes of the teeth the
     * contact search reads (gs_fe_static_back_rows), the others stay 0. */
    int zone_on;          /* 0: every boundary dof (gs_stiffness_opts.all_dofs) */
    int *btooth;          /* nb: tooth of each boundary node */
    unsigned char *zt;    /* teeth: in the zone */
    gs_index nzn;         /* boundary nodes in the zone */
    gs_index *zk;         /* nb: their boundary positions */
    gs_index *zdof;       /* 2 nb: their dofs */
    int zall;             /* the zone holds every tooth: full back substitutions */
    int dirty;            /* displacements computed since the last reset of u */
    double zfrac;         /* fraction of L the last partial back substitution visited */
    double *fd;           /* capd: scratch, the force on each cached dof */
    double *z;            /* max(ne, 2 nb): dense work (zero between uses) */
    double *u;            /* 2 n_nodes: current displacement */
    double c[2];          /* axis */
    double *xy_ref;       /* 2 n_nodes: the perfect gear's nodes (NULL: not modified) */
    double t_mesh;        /* CPU s: meshing and the FE model */
    double t_factor;      /* CPU s: factorisation of K */
    double t_columns;     /* CPU s: compliance columns (half columns and Gram entries) */
    double t_solves;      /* CPU s: the displacements (back substitutions or column sums) */
    long columns;         /* compliance columns cached (dofs) */
} sbody;

static void sbody_free(sbody *b)
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

static double default_torque(const gs_scene *sc, int body, double rb, double b_m);

/* Local refinement (mesh.fine_teeth): centre the fine teeth of both gears
 * on the teeth in contact halfway through the roll range (docs/GEOMETRY.md
 * "Local refinement"), the rotations those of gs_stiffness_next. */
static void fine_centres(const gs_scene *sc, const int bidx[2], const gs_stiffness_opts *o,
                         int centre[2])
{
    const gs_scene_body *A = &sc->bodies[bidx[0]], *B = &sc->bodies[bidx[1]];
    double cA[2], cB[2];
    gs_scene_body_centre(sc, bidx[0], cA);
    gs_scene_body_centre(sc, bidx[1], cB);
    double rb = gs_gear_base_radius(&A->gear);
    double bw = fmin(A->gear.face_width_m, B->gear.face_width_m);
    double T = o->torque_nm != 0.0 ? o->torque_nm : default_torque(sc, bidx[0], rb, bw);
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

static int node_tooth(const gs_mesh *m, int z, gs_index node);

/* fine: 0, or the number of teeth of the `fine` setting (its mesh replaces
 * the scene's density) */
static gs_err sbody_init(const gs_scene *sc, int bi, int refine, int order, int fine,
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
        b->btooth[k] = node_tooth(b->mesh, b->sb->gear.teeth, b->mesh->boundary[k]);
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

/* Reallocate array p to count elements; return GS_ENOMEM from the calling
 * function on failure (p is then unchanged). */
#define GROW(p, count)                                         \
    do {                                                       \
        void *q_ = realloc((p), (count) * sizeof *(p));        \
        if (!q_)                                               \
            return GS_ENOMEM;                                  \
        (p) = q_;                                              \
    } while (0)

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
static gs_err sbody_need(sbody *b, int n, const gs_index *nodes)
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
static void sbody_gram(sbody *b, int n, const int *sl)
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
static gs_err sbody_displace(sbody *b)
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
static int node_tooth(const gs_mesh *m, int z, gs_index node)
{
    double ang = atan2(m->xy[2 * node + 1], m->xy[2 * node]);
    long t = lround(ang / (2.0 * GS_PI / z));
    return (int)(((t % z) + z) % z);
}

/* The zone's node and dof lists from its teeth (zt). */
static void zone_rebuild(sbody *b)
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
static int zone_add(sbody *b, int t)
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

/* The dofs of one contact row in one body: cache slots and dg/du. */
typedef struct rowdofs {
    int m;                /* nodes (the dofs are 2 m) */
    int slot[8];
    double g[8];
} rowdofs;

/* Working state of one analysis. */
typedef struct work {
    sbody b[2];            /* 0 driver, 1 driven */
    int si[2];             /* search gear index of driver, driven */
    gs_contact_search *search;
    double theta0[2];      /* kinematic angles of the current position */
    double rb, sgn;
    /* rows */
    int cap;
    gs_contact_row *row;
    const gs_contact_candidate **cand;
    double *H, *cvec, *x, *lam_in, *Gm, *gz, *gbar, *a;
    rowdofs *rd[2];        /* per row and body: its dofs' cache slots and dg/du */
    int (*teeth)[2];       /* per row: tooth pair of its candidate (cand_teeth) */
    int *gsl;              /* 8 cap: the rows' cache slots of one body (sbody_gram) */
    int n_prev;            /* 1 when the last linearisation changed delta by little */
    /* Contact window: the QP takes the rows whose gap is below win (m); the
     * others are checked at the solution (window_missed). */
    double win;
    const gs_contact_candidate *call; /* every candidate of the last search */
    gs_index ncall;
    unsigned char *kept;   /* per candidate of call: in the rows */
    gs_index capk;
    int win_on;            /* the window is used (not gs_stiffness_opts.all_rows) */
    long win_dropped, win_widened;
    long zone_restarts;    /* positions solved again for it */
    int restart;           /* the displacement zone grew after displacements were computed:
                            * the roll position is solved again (gs_stiffness_next) */
    gs_qp *qp;
    int qp_n;
    /* Near-field correction: the extra compliance c (m/N) of each loaded tooth
     * pair from the previous linearisation, added to its rows' block of W. */
    int nf;                /* on */
    double nf_depth;       /* depth d, m */
    double nf_estar;       /* contact modulus E* of the pair, Pa */
    double nf_bw;          /* face width in contact, m */
    int nf_conj;           /* conjugate involute flanks (nf_offsets) */
    double nf_dc;          /* the driver's turn from the kinematic angle that closes
                            * their backlash (0 at the tight mesh), rad: nf_offsets
                            * evaluates the rows there */
    double nf_rform[2];    /* form radius of each body (involute above it), m */
    double ftot;           /* the load case's force T / r_b1, N (pairs below 1e-6 of it: none) */
    int n_pc;
    struct {
        int tooth[2];
        double c;          /* m/N */
        double L;          /* FE near-field compliance (surface to Q, both bodies), m/N */
        double depth[2];   /* depth of Q in each body, m */
        double reff;       /* effective radius of curvature, m */
        int kc;            /* contact next to a tip corner: the corner body (-1: none) */
        double xv;         /* the flanks' touching point from the corner, m (corner_loa) */
        double kw;         /* the corner's wedge apex factor (gs_wedge_apex_factor) */
        int skip;          /* Q not found, or a corner on a concave flank: no correction */
    } pc[GS_STIFF_MAX_PAIRS];
    double *fq, *uq;       /* scratch 2 n_nodes of the larger body */
    /* Near-field correction: per tooth pair the node-sampling part of its
     * rows' rigid gap (nf_offsets), taken off their gaps in collect. */
    int n_go;
    struct gap_off {
        int tooth[2];
        double off;        /* m */
        int slave;         /* search gear of the rows it applies to (-1: all) */
        int flank;         /* a conjugate contact inside both flanks next to a tip
                            * corner (corner_loa): a flank contact at xb */
        int kc;            /* next to a tip corner of this body (-1: no) */
        double xv;         /* the touching point from the corner (corner_loa), m */
        int has_x;         /* the flanks' contact point found: */
        double xb[2];      /* it, in the driver's body frame, m */
        double ref;        /* the flanks' gap where nf_offsets evaluates the rows
                            * (offset taken off; 0 for conjugate flanks), m: the
                            * reference of the rows' rigid gaps */
    } go[2 * GS_STIFF_MAX_PAIRS];
} work;

static void work_free(work *w)
{
    for (int k = 0; k < 2; k++) {
        sbody_free(&w->b[k]);
        free(w->rd[k]);
    }
    gs_contact_search_free(&w->search);
    free(w->row);
    free(w->cand);
    free(w->teeth);
    free(w->gsl);
    free(w->kept);
    free(w->H);
    free(w->cvec);
    free(w->x);
    free(w->lam_in);
    free(w->Gm);
    free(w->gz);
    free(w->gbar);
    free(w->a);
    free(w->fq);
    free(w->uq);
    gs_qp_free(&w->qp);
}

static gs_err work_reserve(work *w, int n)
{
    if (n <= w->cap)
        return GS_OK;
    int c = n > 2 * w->cap ? n : 2 * w->cap;
    size_t cn = (size_t)c;
    GROW(w->row, cn);
    GROW(w->cand, cn);
    GROW(w->H, cn * cn);
    GROW(w->Gm, cn * cn);
    GROW(w->cvec, cn);
    GROW(w->x, cn);
    GROW(w->lam_in, cn);
    GROW(w->gz, cn);
    GROW(w->gbar, cn);
    GROW(w->a, cn);
    GROW(w->teeth, cn);
    GROW(w->gsl, 8 * cn);
    for (int k = 0; k < 2; k++)
        GROW(w->rd[k], cn);
    w->cap = c;
    return GS_OK;
}

static void set_poses(const work *w, double delta, gs_contact_pose pose[2])
{
    for (int k = 0; k < 2; k++) {
        int s = w->si[k];
        pose[s].c[0] = w->b[k].c[0];
        pose[s].c[1] = w->b[k].c[1];
        pose[s].theta = w->theta0[k] + (k == 0 ? delta : 0.0);
        pose[s].u = w->b[k].u;
    }
}

/* Tooth pair (driver tooth, driven tooth) of a candidate. */
static void cand_teeth(const work *w, const gs_contact_candidate *c, int tooth[2])
{
    gs_index mnode = c->window[c->n_window / 2];
    for (int k = 0; k < 2; k++) {
        const sbody *b = &w->b[k];
        tooth[k] = c->slave == w->si[k] ? c->slave_tooth
                                        : node_tooth(b->mesh, b->sb->gear.teeth, mnode);
    }
}

/* The near-field entry of tooth pair t (nf_offsets; one per pair), or NULL. */
static const struct gap_off *gap_off_find(const work *w, const int t[2])
{
    for (int p = 0; p < w->n_go; p++)
        if (w->go[p].tooth[0] == t[0] && w->go[p].tooth[1] == t[1])
            return &w->go[p];
    return NULL;
}

/* The gap offset of the rows of tooth pair t whose slave is search gear
 * slave (nf_offsets; 0 when none). */
static double gap_offset(const work *w, const int t[2], int slave)
{
    const struct gap_off *go = gap_off_find(w, t);
    return go && (go->slave < 0 || go->slave == slave) ? go->off : 0.0;
}

/* Make the displacement zones cover what the last search read: the teeth
 * it visited on each gear and their neighbours (the master segments near a
 * slave node), and every node of its candidates. A zone that grows after
 * displacements were computed in this roll position leaves wrong (zero)
 * displacements behind at the new nodes: w->restart is set and the
 * position is solved again from the start (GS_EINTERNAL here). */
int gsi_stiffness_zone_late = 0; /* src/contact/stiffness_hook.h */

static gs_err zone_cover(work *w, const gs_contact_stats *st, const gs_contact_candidate *cand,
                         gs_index nc)
{
    for (int k = 0; k < 2; k++) {
        sbody *b = &w->b[k];
        if (!b->zone_on || b->zall || (gsi_stiffness_zone_late && !(b->dirty && w->n_prev == 1)))
            continue;
        int s = w->si[k], grew = 0, z = b->sb->gear.teeth;
        if (st->n_teeth[s] > 16)
            for (int t = 0; t < z; t++)
                grew |= zone_add(b, t);
        else
            for (int i = 0; i < st->n_teeth[s]; i++)
                grew |= zone_add(b, st->teeth[s][i]);
        for (gs_index j = 0; j < nc; j++) {
            const gs_contact_candidate *c = &cand[j];
            if (c->slave == s && !b->zt[b->btooth[b->bpos[c->slave_node]]])
                grew |= zone_add(b, b->btooth[b->bpos[c->slave_node]]);
            if (c->master == s)
                for (int q = 0; q < c->n_window; q++)
                    if (!b->zt[b->btooth[b->bpos[c->window[q]]]])
                        grew |= zone_add(b, b->btooth[b->bpos[c->window[q]]]);
        }
        if (grew) {
            zone_rebuild(b);
            if (b->dirty)
                w->restart = 1;
        }
    }
    return w->restart ? GS_EINTERNAL : GS_OK;
}

/* Search and evaluate at the current state; keep the rows the driver's
 * rotation in the torque direction closes (a_i s < 0) and any row already
 * penetrated, of those only the rows whose gap is below win (the contact
 * window; INFINITY: all). Returns their number in *nr and the smallest gap
 * in *gmin. */
static gs_err collect(work *w, double delta, double win, int *nr, double *gmin)
{
    gs_contact_pose pose[2];
    set_poses(w, delta, pose);
    const gs_contact_candidate *cand;
    gs_index nc;
    gs_contact_stats st;
    GS_TRY(gs_contact_search_run(w->search, pose, &cand, &nc, &st));
    GS_TRY(zone_cover(w, &st, cand, nc));
    GS_TRY(work_reserve(w, (int)nc + 1));
    if (nc + 1 > w->capk) {
        GROW(w->kept, (size_t)nc + 1);
        w->capk = nc + 1;
    }
    w->call = cand;
    w->ncall = nc;
    int n = 0;
    double lo = INFINITY;
    double tiny = 1e-6 * w->rb;
    for (gs_index j = 0; j < nc; j++) {
        gs_contact_row r;
        w->kept[j] = 0;
        GS_TRY(gs_contact_eval(w->search, pose, &cand[j], &r));
        int tp[2];
        bool have_tp = w->n_go > 0; /* near-field gap offsets: only they need the pair here */
        if (have_tp) {
            cand_teeth(w, &cand[j], tp);
            r.gap.g -= gap_offset(w, tp, cand[j].slave);
        }
        double a = r.dg_dtheta[w->si[0]];
        if (!(a * w->sgn < -tiny || r.gap.g < 0.0))
            continue;
        if (!(r.gap.g < win)) {
            w->win_dropped++;
            continue;
        }
        if (r.gap.g < lo)
            lo = r.gap.g;
        w->kept[j] = 1;
        w->row[n] = r;
        w->cand[n] = &cand[j];
        if (!have_tp)
            cand_teeth(w, &cand[j], tp);
        w->teeth[n][0] = tp[0];
        w->teeth[n][1] = tp[1];
        n++;
    }
    *nr = n;
    *gmin = lo;
    return GS_OK;
}

/* Per row: the body-k nodes and their dg/du. */
static int row_nodes(const work *w, const gs_contact_row *r, int k, gs_index *node, double (*g)[2])
{
    int n = 0;
    for (int t = 0; t < r->n_nodes; t++)
        if (r->body[t] == w->si[k]) {
            node[n] = r->node[t];
            g[n][0] = r->dg_du[t][0];
            g[n][1] = r->dg_du[t][1];
            n++;
        }
    return n;
}

/* Near-field correction of the compliance of row i: c of its tooth pair
 * from the previous linearisation (0 when none). */
static double nf_compliance(const work *w, int i)
{
    const int *t = w->teeth[i];
    for (int p = 0; p < w->n_pc; p++)
        if (w->pc[p].tooth[0] == t[0] && w->pc[p].tooth[1] == t[1])
            return w->pc[p].c;
    return 0.0;
}

/* Shape functions of the element of body b containing the reference point
 * q (corner barycentrics; 6-node elements with their mid-side nodes taken
 * at the edge midpoints, true away from curved boundary edges). Returns the
 * number of nodes (3 or 6) in node/N, 0 when q is in no element. */
static int locate(const gs_mesh *m, const double q[2], gs_index node[6], double N[6])
{
    for (gs_index e = 0; e < m->n_tris; e++) {
        const gs_index *t = m->tri + 3 * e;
        const double *p0 = m->xy + 2 * t[0], *p1 = m->xy + 2 * t[1], *p2 = m->xy + 2 * t[2];
        double det = (p1[0] - p0[0]) * (p2[1] - p0[1]) - (p2[0] - p0[0]) * (p1[1] - p0[1]);
        double l1 = ((q[0] - p0[0]) * (p2[1] - p0[1]) - (p2[0] - p0[0]) * (q[1] - p0[1])) / det;
        double l2 = ((p1[0] - p0[0]) * (q[1] - p0[1]) - (q[0] - p0[0]) * (p1[1] - p0[1])) / det;
        double l0 = 1.0 - l1 - l2, tol = -1e-10;
        if (l0 < tol || l1 < tol || l2 < tol)
            continue;
        double L[3] = {l0, l1, l2};
        for (int i = 0; i < 3; i++)
            node[i] = t[i];
        if (!m->mid) {
            for (int i = 0; i < 3; i++)
                N[i] = L[i];
            return 3;
        }
        for (int i = 0; i < 3; i++) {
            N[i] = L[i] * (2.0 * L[i] - 1.0);
            node[3 + i] = m->mid[3 * e + i];
            N[3 + i] = 4.0 * L[i] * L[(i + 1) % 3];
        }
        return 6;
    }
    return 0;
}

/* Near-field approach of body k from its surface to depth d under the line
 * load Pm (N/m) of a pair of effective radius reff: the Hertzian law at the
 * contact centre; next to a tip corner of body kc (kc >= 0), the flanks'
 * touching point xv from the corner, gs_corner_line_approach (the corner
 * body a wedge of factor kw where the load reaches the corner). */
static double nf_body_approach(const work *w, double reff, int kc, double xv, double kw, int k,
                               double Pm, double depth)
{
    const gs_material *mk = &w->b[k].sb->material;
    if (kc < 0) {
        double a = gs_hertz_line_half_width(Pm, reff, w->nf_estar);
        return gs_hertz_line_approach(Pm, a, depth, mk->youngs_pa, mk->poisson, mk->plane);
    }
    return gs_corner_line_approach(Pm, reff, xv, depth, mk->youngs_pa, mk->poisson, mk->plane,
                                   w->nf_estar, k == kc ? kw : 2.0 / GS_PI);
}

/* Near-field approach (both bodies, surface to their depths) of pair p under
 * the normal load lam (N), divided by lam. */
static double nf_hertz(const work *w, int p, double lam)
{
    double Pm = lam / w->nf_bw, s = 0.0;
    for (int k = 0; k < 2; k++)
        s += nf_body_approach(w, w->pc[p].reff, w->pc[p].kc, w->pc[p].xv, w->pc[p].kw, k, Pm,
                              w->pc[p].depth[k]);
    return s / lam;
}

/* Unit normal of the involute of body k through the point X (scene frame):
 * the line through X tangent to the base circle; of its two directions
 * (either flank) the one nearest +-nref. */
static void involute_normal(const work *w, int k, const double X[2], const double nref[2], double n[2])
{
    const gs_gear_params *gp = &w->b[k].sb->gear;
    double ex = X[0] - w->b[k].c[0], ey = X[1] - w->b[k].c[1], r = hypot(ex, ey);
    double rb = gs_gear_base_radius(gp), sb = fmin(rb / r, 1.0), cb = sqrt(1.0 - sb * sb);
    ex /= r;
    ey /= r;
    double best = -1.0;
    for (int sg = -1; sg <= 1; sg += 2) {
        double m[2] = {cb * ex - sg * sb * ey, cb * ey + sg * sb * ex};
        double dp = fabs(m[0] * nref[0] + m[1] * nref[1]);
        if (dp > best) {
            best = dp;
            n[0] = m[0];
            n[1] = m[1];
        }
    }
}

/* Normal load of every stored pair in the current solution; c from it. */
static void nearfield_refresh(work *w, int nr)
{
    for (int p = 0; p < w->n_pc; p++) {
        double lam = 0.0;
        for (int i = 0; i < nr; i++) {
            if (w->x[i] <= 0.0)
                continue;
            const int *t = w->teeth[i];
            if (t[0] == w->pc[p].tooth[0] && t[1] == w->pc[p].tooth[1])
                lam += w->x[i];
        }
        if (w->pc[p].skip || !(lam > 1e-6 * w->ftot))
            w->pc[p].c = 0.0;
        else
            w->pc[p].c = fmax(nf_hertz(w, p, lam) - w->pc[p].L, 0.0);
    }
}

/* Relative curvature 1/R_1 + 1/R_2 (*curv, 1/m) of the flanks at the
 * contact point X (scene frame): involute radii sqrt(r^2 - r_b^2), concave
 * for an internal gear; each body's signed curvature in kb (may be NULL).
 * Returns a mask of the bodies (bit k) for which X is within GS_NF_CORNER
 * module of the tip circle: a tip-corner contact, not a Hertzian line
 * contact (0: a flank contact). */
static int pair_curvature(const work *w, const double X[2], double *curv, double kb[2])
{
    int corner = 0;
    *curv = 0.0;
    for (int k = 0; k < 2; k++) {
        const gs_gear_params *gp = &w->b[k].sb->gear;
        double rr = hypot(X[0] - w->b[k].c[0], X[1] - w->b[k].c[1]);
        double rt = gs_gear_tip_radius(gp), eps = GS_NF_CORNER * gp->module_m;
        if (gp->kind == GS_GEAR_INTERNAL ? rr < rt + eps : rr > rt - eps)
            corner |= 1 << k;
        double rb = gs_gear_base_radius(gp);
        double Rk = fmax(sqrt(fmax(rr * rr - rb * rb, 0.0)), 0.05 * gp->module_m);
        double ck = (gp->kind == GS_GEAR_INTERNAL ? -1.0 : 1.0) / Rk;
        *curv += ck;
        if (kb)
            kb[k] = ck;
    }
    return corner;
}

/* The exact rigid gap (*g, m) of a tip corner, the slave node of row r
 * (candidate cd; rigid bodies, u = 0), against the involute flank of the
 * master body kf: its involute's base angle phi0 from the master window's
 * nodes on the involute (r_form <= r <= r_tip; the boundary nodes lie on
 * the exact outline), F(X) = theta_X - s inv(alpha_X) (constant, phi0, on
 * an involute unwound in the sense s = +-1, the sense for which the nodes
 * agree), and the distance of the corner P from it along P's normal line to
 * the base circle, s r_b (phi0 - F(P)), signed by the master's outward
 * normal (the row's gap gradient). Returns 0 (no *g) when fewer than two
 * window nodes are on the involute, they do not agree, or the foot of P
 * is off the involute (a corner on the fillet). */
static int corner_exact_gap(const work *w, int kf, const gs_contact_row *r,
                            const gs_contact_candidate *cd, double *g)
{
    const sbody *b = &w->b[kf];
    const gs_gear_params *gp = &b->sb->gear;
    double rb = gs_gear_base_radius(gp), ra = gs_gear_tip_radius(gp), rf = w->nf_rform[kf];
    double rlo = fmin(rf, ra), rhi = fmax(rf, ra);
    double th = w->theta0[kf] + (kf == 0 ? w->nf_dc : 0.0), cs = cos(th), sn = sin(th);
    double best = INFINITY, phi0 = 0.0;
    int sbest = 0;
    for (int sg = -1; sg <= 1; sg += 2) {
        double f0 = 0.0, lo = INFINITY, hi = -INFINITY;
        int n = 0;
        for (int j = 0; j < cd->n_window; j++) {
            const double *X = b->mesh->xy + 2 * cd->window[j];
            double rr = hypot(X[0], X[1]);
            if (!(rr >= rlo * (1.0 + 1e-9) && rr <= rhi * (1.0 - 1e-9) && rr > rb))
                continue;
            double ang = atan2(sn * X[0] + cs * X[1], cs * X[0] - sn * X[1]);
            double F = ang - sg * gs_involute(acos(rb / rr));
            if (n == 0)
                f0 = F;
            double dF = remainder(F - f0, 2.0 * GS_PI);
            lo = fmin(lo, dF);
            hi = fmax(hi, dF);
            n++;
        }
        if (n >= 2 && hi - lo < best) {
            best = hi - lo;
            sbest = sg;
            phi0 = f0 + 0.5 * (hi + lo);
        }
    }
    if (!(best * rb < 1e-8))
        return 0;
    const double *P = r->x[0];
    double px = P[0] - b->c[0], py = P[1] - b->c[1], rp = hypot(px, py);
    if (!(rp > rb))
        return 0;
    double al = acos(rb / rp), thp = atan2(py, px);
    double dF = remainder(thp - sbest * gs_involute(al) - phi0, 2.0 * GS_PI);
    double phT = thp + sbest * al;
    double T[2] = {rb * cos(phT), rb * sin(phT)};
    double u[2] = {px - T[0], py - T[1]}, lt = hypot(u[0], u[1]);
    double foot = lt + sbest * rb * dF; /* |Y'T|: the involute's point on P's normal line */
    double rfoot = hypot(rb, foot);
    if (!(rfoot >= rlo && rfoot <= rhi + 1e-3 * gp->module_m))
        return 0;
    double dn = -sbest * rb * dF;
    double gn = hypot(r->gap.grad[0], r->gap.grad[1]);
    if (!(gn > 0.0))
        return 0;
    double side = (u[0] * r->gap.grad[0] + u[1] * r->gap.grad[1]) / (lt * gn);
    *g = side >= 0.0 ? dn : -dn;
    return 1;
}

/* Where a pair flagged as a tip-corner contact (the corner P of body kc is
 * its nearest node) touches, for conjugate involutes of two external gears:
 * the line of action (the common internal tangent of the base circles
 * nearest the corner's involute normal) crosses the corner's involute at
 * roll length rho_v = rho_tip + s r_b (phi(T_v) - phi(T_tip)) (T the
 * tangent points of the involute's normals at the crossing and at P, s its
 * unwinding sense). Returns 1 with the crossing in X (scene frame) when it
 * is inside the corner's flank (rho_v < rho_tip) and on both involutes
 * (above both form radii): a flank contact next to the corner, whose rows
 * sample it with no node beyond the corner; 0 when the crossing is beyond
 * the tip: a true corner contact. */
static int corner_loa(const work *w, int kc, const double P[2], const double nref[2], double X[2],
                      double *xv)
{
    const sbody *bc = &w->b[kc], *bf = &w->b[1 - kc];
    if (bc->sb->gear.kind == GS_GEAR_INTERNAL || bf->sb->gear.kind == GS_GEAR_INTERNAL)
        return 0;
    double rbc = gs_gear_base_radius(&bc->sb->gear), rbf = gs_gear_base_radius(&bf->sb->gear);
    double px = P[0] - bc->c[0], py = P[1] - bc->c[1], rp = hypot(px, py);
    if (!(rp > rbc))
        return 0;
    /* The corner's involute normal: of the two tangents from P, the one
     * nearest the flank body's involute normal at P. */
    double nf_[2], nc_[2];
    involute_normal(w, 1 - kc, P, nref, nf_);
    involute_normal(w, kc, P, nf_, nc_);
    /* Tangent point of the corner's normal line on base circle kc. */
    double tpar = px * nc_[0] + py * nc_[1];
    double T[2] = {px - tpar * nc_[0], py - tpar * nc_[1]};
    double rho_tip = sqrt(rp * rp - rbc * rbc);
    double sg = (T[0] * py - T[1] * px) < 0.0 ? 1.0 : -1.0; /* -sign(e_T x (P - T)) */
    /* The line of action: unit normal m, m.X = h, tangent to both base
     * circles with the circles on opposite sides. */
    double D[2] = {bf->c[0] - bc->c[0], bf->c[1] - bc->c[1]}, a = hypot(D[0], D[1]);
    double cg = (rbc + rbf) / a;
    if (!(cg < 1.0))
        return 0;
    double sgm = sqrt(1.0 - cg * cg), Dh[2] = {D[0] / a, D[1] / a}, Dp[2] = {-Dh[1], Dh[0]};
    double m[2] = {0.0, 0.0}, best = INFINITY;
    for (int i = 0; i < 4; i++) {
        double c1 = (i & 1) ? -cg : cg, s1 = (i & 2) ? -sgm : sgm;
        double mm[2] = {c1 * Dh[0] + s1 * Dp[0], c1 * Dh[1] + s1 * Dp[1]};
        double q = fabs(mm[0] * nc_[0] + mm[1] * nc_[1]);
        if (q < best) {
            best = q;
            m[0] = mm[0];
            m[1] = mm[1];
        }
    }
    /* Circle kc at the origin here: m.C_c - h = sc rbc, m.D = -sc (rbc + rbf). */
    double sc = -(m[0] * D[0] + m[1] * D[1]) / (rbc + rbf);
    double Tv[2] = {-sc * rbc * m[0], -sc * rbc * m[1]}; /* foot from the centre */
    double dphi = remainder(atan2(Tv[1], Tv[0]) - atan2(T[1], T[0]), 2.0 * GS_PI);
    double rho_v = rho_tip + sg * rbc * dphi;
    /* Along the common tangent: the involute's arc between the roll lengths. */
    *xv = (rho_tip * rho_tip - rho_v * rho_v) / (2.0 * rbc);
    if (!(rho_v < rho_tip) || !(rho_v > 0.0))
        return 0;
    double e[2] = {Tv[0] / rbc, Tv[1] / rbc};
    double Xl[2] = {Tv[0] + rho_v * sg * e[1], Tv[1] - rho_v * sg * e[0]};
    double rcv = hypot(Xl[0], Xl[1]);
    X[0] = bc->c[0] + Xl[0];
    X[1] = bc->c[1] + Xl[1];
    double rfv = hypot(X[0] - bf->c[0], X[1] - bf->c[1]);
    double raf = gs_gear_tip_radius(&bf->sb->gear);
    return rcv >= w->nf_rform[kc] && rfv >= w->nf_rform[1 - kc] && rfv <= raf;
}

/* Near-field correction, rigid bodies at the kinematic position turned by
 * nf_dc (conjugate flanks with backlash: where every pair touches; else
 * delta 0), u = 0: per tooth pair the part of its rows' gap that comes from sampling
 * the flanks at nodes. The rows of one pass sample the gap between the two
 * flanks at the slave nodes along the common tangent (coordinate s); near a
 * line contact it is smooth and convex, g(s) = g0 + (s - s0)^2 / (2 R) to
 * leading order, and the nearest node sits up to h^2 / (8 R) above the
 * minimum g0 (h the node spacing). Per pass the parabola through the row of
 * smallest gap and its neighbours on either side (within GS_NF_FIT module)
 * gives g0 at its vertex (when the vertex lies between them), taken from
 * the pass whose master flank has the larger involute radius (the flatter
 * one, whose parabolic edges depart least from it: near a form point the
 * other pass sees the edges' bulge). The offset min_i g_i - g0 is taken off every row of
 * the pair (collect): the pair first touches where its flanks do, not
 * where its nearest node does, and the Hertz law (nearfield_measure) gives
 * the approach about that contact. Tip-corner contacts, and pairs without
 * a vertex, keep 0. */
static gs_err nf_offsets(work *w)
{
    w->n_go = 0;
    int nr;
    double gmin;
    GS_TRY(collect(w, w->nf_dc, INFINITY, &nr, &gmin));
    for (int i = 0; i < nr; i++) {
        const int *t = w->teeth[i];
        if (gap_off_find(w, t) || w->n_go == (int)(sizeof w->go / sizeof w->go[0]))
            continue;
        /* The pair's row of smallest gap: its contact point and tangent. */
        int im = -1;
        for (int j = 0; j < nr; j++)
            if (w->teeth[j][0] == t[0] && w->teeth[j][1] == t[1] &&
                (im < 0 || w->row[j].gap.g < w->row[im].gap.g))
                im = j;
        const gs_contact_row *rm = &w->row[im];
        double curv, nn = hypot(rm->gap.grad[0], rm->gap.grad[1]);
        bool corner = pair_curvature(w, rm->x[0], &curv, NULL) != 0;
        double off = 0.0, g0best = 0.0, win = GS_NF_FIT * w->b[0].sb->gear.module_m;
        double rho_best = 0.0, xv[2] = {0.0, 0.0};
        int ng0 = 0;
        for (int pass = 0; pass < 2 && !corner && nn > 0.0; pass++) {
            double tg[2] = {-rm->gap.grad[1] / nn, rm->gap.grad[0] / nn};
            int jm = -1, jl = -1, jh = -1;
            double sl = -INFINITY, sh = INFINITY;
            for (int j = 0; j < nr; j++)
                if (w->teeth[j][0] == t[0] && w->teeth[j][1] == t[1] &&
                    (w->cand[j]->slave == w->si[pass]) &&
                    (jm < 0 || w->row[j].gap.g < w->row[jm].gap.g))
                    jm = j;
            if (jm < 0)
                continue;
            const double *xm = w->row[jm].x[0];
            for (int j = 0; j < nr; j++) {
                if (j == jm || w->teeth[j][0] != t[0] || w->teeth[j][1] != t[1] ||
                    w->cand[j]->slave != w->si[pass])
                    continue;
                double sj = (w->row[j].x[0][0] - xm[0]) * tg[0] + (w->row[j].x[0][1] - xm[1]) * tg[1];
                if (sj < 0.0 && sj > sl && sj >= -win) {
                    sl = sj;
                    jl = j;
                }
                if (sj > 0.0 && sj < sh && sj <= win) {
                    sh = sj;
                    jh = j;
                }
            }
            if (jl < 0 || jh < 0)
                continue;
            double gm = w->row[jm].gap.g, sv, g0;
            if (!gs_gap_vertex3(sl, w->row[jl].gap.g, gm, sh, w->row[jh].gap.g, GS_NF_FIT_CURV * 0.5 * curv,
                                &sv, &g0))
                continue;
            /* The pass whose master flank is the flatter (larger involute
             * radius: its parabolic edges follow it more closely) wins. */
            const gs_gear_params *gpm = &w->b[1 - pass].sb->gear;
            double rr = hypot(xm[0] - w->b[1 - pass].c[0], xm[1] - w->b[1 - pass].c[1]);
            double rbm = gs_gear_base_radius(gpm);
            double rho = sqrt(fmax(rr * rr - rbm * rbm, 0.0));
            if (ng0 == 0 || rho > rho_best) {
                rho_best = rho;
                g0best = g0;
                xv[0] = xm[0] + sv * tg[0];
                xv[1] = xm[1] + sv * tg[1];
            }
            ng0 = 1;
        }
        int oslave = -1, flank = 0, okc = -1;
        double oxv = 0.0;
        int cmask = corner ? pair_curvature(w, rm->x[0], &(double){0.0}, NULL) : 0;
        if ((cmask == 1 || cmask == 2) && w->nf_conj) {
            /* A tip corner of body kc: its row (the corner node as slave). */
            int kc = cmask == 1 ? 0 : 1, ic = -1;
            double rtc = gs_gear_tip_radius(&w->b[kc].sb->gear);
            for (int j = 0; j < nr; j++) {
                if (w->teeth[j][0] != t[0] || w->teeth[j][1] != t[1] ||
                    w->cand[j]->slave != w->si[kc])
                    continue;
                double rr = hypot(w->row[j].x[0][0] - w->b[kc].c[0], w->row[j].x[0][1] - w->b[kc].c[1]);
                if (fabs(rr - rtc) < 1e-3 * w->b[kc].sb->gear.module_m &&
                    (ic < 0 || w->row[j].gap.g < w->row[ic].gap.g))
                    ic = j;
            }
            double gex, gn = ic >= 0 ? hypot(w->row[ic].gap.grad[0], w->row[ic].gap.grad[1]) : 0.0;
            double nref[2] = {gn > 0.0 ? w->row[ic].gap.grad[0] / gn : 0.0,
                              gn > 0.0 ? w->row[ic].gap.grad[1] / gn : 0.0};
            double xvc = NAN;
            int inside = gn > 0.0 && corner_loa(w, kc, w->row[ic].x[0], nref, xv, &xvc);
            if (isfinite(xvc) && (inside || xvc < 0.0)) {
                okc = kc;
                oxv = xvc;
            }
            if (inside) {
                /* Conjugate flanks touching next to the corner: a flank
                 * contact at xv, g0 = 0 (as below). */
                flank = 1;
                ng0 = 1;
            } else if (okc >= 0 && corner_exact_gap(w, 1 - kc, &w->row[ic], w->cand[ic], &gex)) {
                /* A true corner contact: the rows of the corner node take
                 * its exact gap (the master's parabolic edges near its form
                 * point may sit ~1 um off the involute at the default
                 * density). */
                off = w->row[ic].gap.g - gex;
                oslave = w->si[kc];
            }
        }
        if (ng0 > 0)
            off = rm->gap.g - (w->nf_conj ? 0.0 : g0best);
        w->go[w->n_go].tooth[0] = t[0];
        w->go[w->n_go].tooth[1] = t[1];
        w->go[w->n_go].off = off;
        w->go[w->n_go].slave = oslave;
        w->go[w->n_go].flank = flank;
        w->go[w->n_go].kc = okc;
        w->go[w->n_go].xv = oxv;
        w->go[w->n_go].has_x = ng0 > 0;
        w->go[w->n_go].ref = rm->gap.g - off;
        if (ng0 > 0) {
            /* Driver's body frame at the rows' angle. */
            double th = w->theta0[0] + w->nf_dc, cs = cos(th), sn = sin(th);
            double dx = xv[0] - w->b[0].c[0], dy = xv[1] - w->b[0].c[1];
            w->go[w->n_go].xb[0] = cs * dx + sn * dy;
            w->go[w->n_go].xb[1] = -sn * dx + cs * dy;
        }
        w->n_go++;
    }
    return GS_OK;
}

/* At the converged plain FE solution (rows w->row, forces w->x,
 * displacements in the bodies): the near-field data of every loaded tooth
 * pair. Per pair and body k the FE approach of the contact point
 * (load-weighted over the pair's rows) is to be replaced by the approach of
 * the point Q_k at depth d below it (FE, by reciprocity: one static solve
 * with a unit load at Q_k) plus the Hertzian approach between the surface
 * and depth d (gs_hertz_line_approach, with the half-width of the pair's
 * load and the involute curvature radii at the contact point). Stored: the
 * FE's surface-to-Q approach per unit load L (frozen: it is a property of
 * the mesh under the FE's own load distribution), the depths and the
 * effective radius; nearfield_refresh then sets c = Hertz(lam)/lam - L. */
static gs_err nearfield_measure(work *w, int nr, double delta)
{
    struct {
        int tooth[2];
        double lam, x[2], n[2];
    } g[GS_STIFF_MAX_PAIRS];
    int ng = 0;
    for (int i = 0; i < nr; i++) {
        double l = w->x[i];
        if (l <= 0.0)
            continue;
        const int *t = w->teeth[i];
        int p = 0;
        while (p < ng && (g[p].tooth[0] != t[0] || g[p].tooth[1] != t[1]))
            p++;
        if (p == ng) {
            if (ng == GS_STIFF_MAX_PAIRS)
                continue;
            memset(&g[p], 0, sizeof g[p]);
            g[p].tooth[0] = t[0];
            g[p].tooth[1] = t[1];
            ng++;
        }
        const gs_contact_row *r = &w->row[i];
        /* dg/dx_slave is the master's outward normal: the driver's outward
         * normal is +that when the driven gear is the master. */
        double sd = w->cand[i]->slave == w->si[0] ? -1.0 : 1.0;
        g[p].lam += l;
        g[p].x[0] += l * r->x[0][0];
        g[p].x[1] += l * r->x[0][1];
        g[p].n[0] += l * sd * r->gap.grad[0];
        g[p].n[1] += l * sd * r->gap.grad[1];
    }
    int np = 0;
    for (int p = 0; p < ng; p++) {
        double lam = g[p].lam, X[2] = {g[p].x[0] / lam, g[p].x[1] / lam};
        double nn = hypot(g[p].n[0], g[p].n[1]);
        if (!(lam > 1e-6 * w->ftot) || !(nn > 0.0))
            continue;
        /* The flanks' contact point (nf_offsets) when known, else the rows'
         * load centre. */
        const struct gap_off *go = gap_off_find(w, g[p].tooth);
        bool has_x = go && go->has_x;
        if (has_x) {
            double th = w->theta0[0] + delta, cs = cos(th), sn = sin(th);
            X[0] = w->b[0].c[0] + cs * go->xb[0] - sn * go->xb[1];
            X[1] = w->b[0].c[1] + sn * go->xb[0] + cs * go->xb[1];
        }
        double nD[2] = {g[p].n[0] / nn, g[p].n[1] / nn};
        double curv, kb[2];
        int corner = pair_curvature(w, X, &curv, kb);
        if (go && go->flank)
            corner = 0;
        /* Next to a tip corner of body kc (nf_offsets found where the
         * flanks touch, xv from the corner): both bodies get
         * gs_corner_line_approach with both flanks' curvature, the corner
         * body a wedge of half-angle (pi/2 + alpha_tip)/2 loaded normal to
         * its flank face. */
        int kc = -1, only = -1;
        double xvc = 0.0, kw = 0.0;
        if (go && go->kc >= 0) {
            kc = go->kc;
            xvc = go->xv;
            corner = 0;
            const gs_gear_params *gc = &w->b[kc].sb->gear;
            double at = acos(fmin(gs_gear_base_radius(gc) / gs_gear_tip_radius(gc), 1.0));
            double al = 0.25 * GS_PI + 0.5 * at;
            kw = gs_wedge_apex_factor(al, 0.5 * GS_PI - al);
        } else if ((corner == 1 || corner == 2) && kb[corner == 1 ? 1 : 0] > 0.0) {
            /* Otherwise (modified flanks, a ring) the flank body alone gets
             * the half-plane law with its own flank curvature; a concave
             * flank, a ring's, under a corner keeps the plain FE. */
            only = corner == 1 ? 1 : 0;
            curv = kb[only];
            corner = 0;
        }
        if (corner) {
            memset(&w->pc[np], 0, sizeof w->pc[np]);
            w->pc[np].tooth[0] = g[p].tooth[0];
            w->pc[np].tooth[1] = g[p].tooth[1];
            w->pc[np].skip = 1;
            w->pc[np].kc = -1;
            np++;
            continue;
        }
        double Pm = lam / w->nf_bw, reff = 1.0 / fmax(curv, 1e-9);
        double c = 0.0, L = 0.0, dep[2] = {0.0, 0.0};
        bool skip = false;
        for (int k = 0; k < 2 && !skip; k++) {
            if (only >= 0 && k != only)
                continue;
            sbody *b = &w->b[k];
            const gs_mesh *m = b->mesh;
            double nk[2] = {k == 0 ? nD[0] : -nD[0], k == 0 ? nD[1] : -nD[1]};
            double th = w->theta0[k] + (k == 0 ? delta : 0.0), cs = cos(th), sn = sin(th);
            double eb[2] = {-(cs * nk[0] + sn * nk[1]), -(-sn * nk[0] + cs * nk[1])};
            gs_index node[6];
            double N[6];
            int nq = 0;
            double depth = w->nf_depth;
            /* Q in the body; near a tip the normal may leave the tooth
             * before depth d: a smaller depth then, else no correction. */
            for (int tries = 0; tries < 4 && nq == 0; tries++, depth *= 0.75) {
                double Q[2] = {X[0] - depth * nk[0] - b->c[0], X[1] - depth * nk[1] - b->c[1]};
                double qb[2] = {cs * Q[0] + sn * Q[1], -sn * Q[0] + cs * Q[1]};
                nq = locate(m, qb, node, N);
            }
            depth /= 0.75;
            if (nq == 0) {
                skip = true;
                break;
            }
            size_t len = (size_t)(2 * m->n_nodes);
            memset(w->fq, 0, len * sizeof *w->fq);
            for (int t = 0; t < nq; t++) {
                w->fq[2 * node[t]] += N[t] * eb[0];
                w->fq[2 * node[t] + 1] += N[t] * eb[1];
            }
            GS_TRY(gs_fe_static_solve(b->fs, 1, w->fq, w->uq));
            /* FE approach at Q (reciprocity) and at the surface, all rows' loads. */
            double aq = 0.0, as = 0.0;
            for (int i = 0; i < nr; i++) {
                double l = w->x[i];
                if (l <= 0.0)
                    continue;
                gs_index nd[4];
                double gg[4][2];
                int mm = row_nodes(w, &w->row[i], k, nd, gg);
                double bq = 0.0, bs = 0.0;
                for (int t = 0; t < mm; t++) {
                    bq += gg[t][0] * w->uq[2 * nd[t]] + gg[t][1] * w->uq[2 * nd[t] + 1];
                    bs += gg[t][0] * b->u[2 * nd[t]] + gg[t][1] * b->u[2 * nd[t] + 1];
                }
                aq += l * bq;
                const int *t = w->teeth[i];
                if (t[0] == g[p].tooth[0] && t[1] == g[p].tooth[1])
                    as += l * bs;
            }
            as /= lam;
            /* The FE carries the pair's load on its slave nodes, up to half
             * a node spacing from the flanks' contact point; Q's
             * displacement under the load there instead (by reciprocity,
             * the unit solve's field at the contact point, just inside the
             * surface) less the one under the nodal loads. */
            double dself = 0.0;
            if (has_x) {
                double xc[2] = {X[0] - b->c[0], X[1] - b->c[1]};
                double xbk[2] = {cs * xc[0] + sn * xc[1], -sn * xc[0] + cs * xc[1]};
                double Qb[2] = {xbk[0] + depth * eb[0], xbk[1] + depth * eb[1]};
                double pin[2] = {xbk[0] + 1e-2 * (Qb[0] - xbk[0]), xbk[1] + 1e-2 * (Qb[1] - xbk[1])};
                gs_index nx[6];
                double Nx[6];
                int nxn = locate(m, pin, nx, Nx);
                if (nxn > 0) {
                    double ux = 0.0, own = 0.0;
                    for (int t = 0; t < nxn; t++)
                        ux += Nx[t] * (eb[0] * w->uq[2 * nx[t]] + eb[1] * w->uq[2 * nx[t] + 1]);
                    for (int i = 0; i < nr; i++) {
                        const int *ti = w->teeth[i];
                        if (w->x[i] <= 0.0 || ti[0] != g[p].tooth[0] || ti[1] != g[p].tooth[1])
                            continue;
                        gs_index nd[4];
                        double gg[4][2];
                        int mm = row_nodes(w, &w->row[i], k, nd, gg);
                        for (int t = 0; t < mm; t++)
                            own += w->x[i] * (gg[t][0] * w->uq[2 * nd[t]] + gg[t][1] * w->uq[2 * nd[t] + 1]);
                    }
                    dself = lam * ux - own;
                }
            }
            double dh = nf_body_approach(w, reff, kc, xvc, kw, k, Pm, depth);
            c += (dh - (as - aq - dself)) / lam;
            L += (as - aq - dself) / lam;
            dep[k] = depth;
        }
        /* The Hertz law is the approach at the contact centre; a loaded row
         * at distance x from it starts x^2 / (2 R) apart (its rigid gap
         * above the pair's, offset taken off) and moves that much less:
         * the FE's centre approach is the rows' plus their load-weighted
         * rigid gap (a^2 / (8 R) once the mesh resolves the pressure). */
        if (!skip && has_x) {
            double gs = 0.0;
            for (int i = 0; i < nr; i++) {
                const int *ti = w->teeth[i];
                if (w->x[i] <= 0.0 || ti[0] != g[p].tooth[0] || ti[1] != g[p].tooth[1])
                    continue;
                const gs_contact_row *r = &w->row[i];
                double du = 0.0;
                for (int t = 0; t < r->n_nodes; t++) {
                    const sbody *b = &w->b[r->body[t] == w->si[0] ? 0 : 1];
                    du += r->dg_du[t][0] * b->u[2 * r->node[t]] + r->dg_du[t][1] * b->u[2 * r->node[t] + 1];
                }
                gs += w->x[i] * (r->gap.g - du - r->dg_dtheta[w->si[0]] * (delta - w->nf_dc) - go->ref);
            }
            c -= gs / (lam * lam);
            L += gs / (lam * lam);
        }
        /* The FE's point load is stiffer than the Hertzian one while the
         * mesh does not resolve a; never add a negative compliance (W must
         * stay positive definite). */
        c = skip ? 0.0 : fmax(c, 0.0);
        w->pc[np].tooth[0] = g[p].tooth[0];
        w->pc[np].tooth[1] = g[p].tooth[1];
        w->pc[np].c = c;
        w->pc[np].L = L;
        w->pc[np].depth[0] = dep[0];
        w->pc[np].depth[1] = dep[1];
        w->pc[np].reff = reff;
        w->pc[np].kc = kc;
        w->pc[np].xv = xvc;
        w->pc[np].kw = kw;
        w->pc[np].skip = skip;
        np++;
    }
    w->n_pc = np;
    return GS_OK;
}

/* One load case from the current state (delta in *delta, displacements in
 * the bodies): iterate linearisations. Fills lambda in w->x, the rows in
 * w->row (nr), and the outcome. */
/* The contact window (docs/STIFFNESS.md "Contact window"): the first
 * linearisation takes the rows whose gap is below the TE of a soft mesh
 * (GS_WIN_K, a quarter of a usual steel spur mesh stiffness) under the load,
 * the next ones those below GS_WIN_FACTOR times the current elastic TE; the
 * window is widened fourfold whenever a row left out is found penetrated at
 * a settled solution. */
#define GS_WIN_K 5e9      /* N/m^2: 5 N/(mm um) */
#define GS_WIN_FACTOR 2.0

/* 1 when a candidate of the last search left out of the rows by the window
 * is penetrated at the current state (delta, u): the window missed it. */
static gs_err window_missed(work *w, double delta, int *missed)
{
    gs_contact_pose pose[2];
    set_poses(w, delta, pose);
    *missed = 0;
    for (gs_index j = 0; j < w->ncall && !*missed; j++) {
        if (w->kept[j])
            continue;
        gs_contact_row r;
        GS_TRY(gs_contact_eval(w->search, pose, &w->call[j], &r));
        *missed = r.gap.g < 0.0;
    }
    return GS_OK;
}

static gs_err solve_load(work *w, double T, int max_iter, double delta0, double *delta, int *nr_out,
                         int *iters, int *converged, double *pen, gs_diag *d)
{
    int nr = 0;
    *converged = 0;
    w->n_prev = 0;
    w->n_pc = 0;
    w->ftot = fabs(T) / w->rb;
    int phase = w->nf ? 0 : 1; /* 0: plain FE; 1: with the near-field correction */
    if (w->nf)
        max_iter *= 4; /* the fixed point on the pair loads converges linearly */
    double bw = fmin(w->b[0].sb->gear.face_width_m, w->b[1].sb->gear.face_width_m);
    double wscale = 1.0;
    double win = w->win_on ? w->ftot / (bw * GS_WIN_K) : INFINITY;
    for (int it = 0; it < max_iter; it++) {
        double gmin;
        GS_TRY(collect(w, *delta, win, &nr, &gmin));
        if (nr == 0)
            return gs_diag_set(d, GS_EINFEASIBLE, "meshes",
                               "no contact row can carry the torque at this position");
        /* Columns of every node in a row. */
        for (int k = 0; k < 2; k++) {
            gs_index nodes[4 * 512];
            int nn = 0;
            for (int i = 0; i < nr; i++) {
                gs_index nd[4];
                double gg[4][2];
                int m = row_nodes(w, &w->row[i], k, nd, gg);
                for (int t = 0; t < m; t++) {
                    if (nn == (int)(sizeof nodes / sizeof nodes[0])) {
                        GS_TRY(sbody_need(&w->b[k], nn, nodes));
                        nn = 0;
                    }
                    nodes[nn++] = nd[t];
                }
            }
            GS_TRY(sbody_need(&w->b[k], nn, nodes));
        }
        /* W = sum_k B_k C_k B_k^T from the cached compliance among the
         * rows' dofs: row i of body k is sum_t g_it . u(node_it). */
        size_t n = (size_t)nr;
        memset(w->H, 0, n * n * sizeof *w->H);
        for (int k = 0; k < 2; k++) {
            sbody *b = &w->b[k];
            rowdofs *rd = w->rd[k];
            for (int i = 0; i < nr; i++) {
                gs_index nd[4];
                double gg[4][2];
                rd[i].m = row_nodes(w, &w->row[i], k, nd, gg);
                for (int t = 0; t < rd[i].m; t++)
                    for (int c = 0; c < 2; c++) {
                        rd[i].slot[2 * t + c] = b->slot[2 * b->bpos[nd[t]] + c];
                        rd[i].g[2 * t + c] = gg[t][c];
                    }
            }
            int ns = 0;
            for (int i = 0; i < nr; i++)
                for (int p = 0; p < 2 * rd[i].m; p++)
                    w->gsl[ns++] = rd[i].slot[p];
            sbody_gram(b, ns, w->gsl);
            size_t cap = (size_t)b->capd;
            for (int i = 0; i < nr; i++)
                for (int j = 0; j <= i; j++) {
                    double sum = 0.0;
                    for (int p = 0; p < 2 * rd[i].m; p++) {
                        const double *Gp = b->G + (size_t)rd[i].slot[p] * cap;
                        double sp = 0.0;
                        for (int q = 0; q < 2 * rd[j].m; q++)
                            sp += Gp[rd[j].slot[q]] * rd[j].g[q];
                        sum += rd[i].g[p] * sp;
                    }
                    w->H[(size_t)i * n + (size_t)j] += sum;
                }
        }
        if (w->nf && w->n_pc > 0) {
            /* The pair's extra compliance on its rows' block (rank one). */
            for (int i = 0; i < nr; i++) {
                double ci = nf_compliance(w, i);
                if (ci == 0.0)
                    continue;
                const int *ti = w->teeth[i];
                for (int j = 0; j <= i; j++) {
                    const int *tj = w->teeth[j];
                    if (ti[0] == tj[0] && ti[1] == tj[1])
                        w->H[(size_t)i * n + (size_t)j] += ci;
                }
            }
        }
        double dmax = 0.0;
        for (int i = 0; i < nr; i++)
            dmax = fmax(dmax, w->H[(size_t)i * n + (size_t)i]);
        for (int i = 0; i < nr; i++) {
            w->H[(size_t)i * n + (size_t)i] += 1e-9 * dmax;
            for (int j = 0; j < i; j++)
                w->H[(size_t)j * n + (size_t)i] = w->H[(size_t)i * n + (size_t)j];
        }
        /* Linear term and constraint data. */
        for (int i = 0; i < nr; i++) {
            const gs_contact_row *r = &w->row[i];
            double a = r->dg_dtheta[w->si[0]];
            double bu = 0.0;
            for (int t = 0; t < r->n_nodes; t++) {
                const sbody *b = &w->b[r->body[t] == w->si[0] ? 0 : 1];
                bu += r->dg_du[t][0] * b->u[2 * r->node[t]] + r->dg_du[t][1] * b->u[2 * r->node[t] + 1];
            }
            w->a[i] = a;
            w->gbar[i] = r->gap.g - a * *delta - bu;
            w->cvec[i] = -w->gbar[i];
            w->gz[i] = 0.0;
        }
        memset(w->Gm, 0, n * n * sizeof *w->Gm);
        for (int i = 0; i < nr; i++)
            w->Gm[(size_t)i * n + (size_t)i] = 1.0;
        if (!w->qp || w->qp_n < nr) {
            gs_qp_free(&w->qp);
            GS_TRY(gs_qp_new(w->cap, 1, w->cap, &w->qp));
            w->qp_n = w->cap;
        }
        double e = -T, lam_eq = 0.0;
        gs_qp_problem p = {.n = nr, .H = w->H, .c = w->cvec, .n_eq = 1, .E = w->a, .e = &e,
                           .n_in = nr, .G = w->Gm, .g = w->gz};
        gs_qp_result res;
        memset(&res, 0, sizeof res);
        res.x = w->x;
        res.lambda_eq = &lam_eq;
        res.lambda_in = w->lam_in;
        gs_err qe = gs_qp_solve(w->qp, &p, NULL, 0, &res);
        if (qe != GS_OK)
            return gs_diag_set(d, qe, "meshes", "static contact QP failed (%d rows): %s", nr,
                               gs_strerror(qe));
        double dnew = -lam_eq;
        /* Displacements: u_k = C_k B_k^T lambda. */
        for (int k = 0; k < 2; k++) {
            sbody *b = &w->b[k];
            memset(b->fd, 0, (size_t)b->nd * sizeof *b->fd);
            for (int j = 0; j < nr; j++) {
                double l = w->x[j];
                if (l <= 0.0)
                    continue;
                for (int q = 0; q < 2 * w->rd[k][j].m; q++)
                    b->fd[w->rd[k][j].slot[q]] += l * w->rd[k][j].g[q];
            }
            GS_TRY(sbody_displace(b));
        }
        /* Settled when delta changed by less than 1e-7 of the elastic
         * rotation twice in a row. The active set is not a criterion: the
         * two passes give two nearly parallel rows per flank contact, whose
         * split of the load is degenerate (the QP may flip between them)
         * while delta, the gaps and the force per tooth pair do not move. */
        if (phase == 1 && w->n_pc > 0)
            nearfield_refresh(w, nr);
        double scale = fabs(dnew - delta0) + 1e-9 / w->rb;
        bool small = fabs(dnew - *delta) <= 1e-7 * scale;
        *delta = dnew;
        *iters = it + 1;
        *nr_out = nr;
        if (w->win_on)
            win = wscale * fmax(GS_WIN_FACTOR * fabs(dnew - delta0) * w->rb,
                                1e-3 * w->ftot / (bw * GS_WIN_K));
        if (small && it > 0 && w->n_prev == 1 && w->win_on) {
            int missed;
            GS_TRY(window_missed(w, dnew, &missed));
            if (missed) {
                wscale *= 4.0;
                win *= 4.0;
                w->win_widened++;
                w->n_prev = 0;
                continue;
            }
        }
        if (small && it > 0 && w->n_prev == 1) {
            if (phase == 0) {
                /* Plain FE settled: measure the near field, then iterate
                 * with the correction. */
                GS_TRY(nearfield_measure(w, nr, dnew));
                phase = 1;
                w->n_prev = 0;
                continue;
            }
            *converged = 1;
            break;
        }
        w->n_prev = small ? 1 : 0;
    }
    /* Penetration left at the final deformed position: the solution's rows
     * re-evaluated there (the candidates stay valid: no search since). */
    gs_contact_pose pose[2];
    set_poses(w, *delta, pose);
    double lo = 0.0;
    for (int i = 0; i < *nr_out; i++) {
        gs_contact_row r;
        GS_TRY(gs_contact_eval(w->search, pose, w->cand[i], &r));
        r.gap.g -= gap_offset(w, w->teeth[i], w->cand[i]->slave);
        if (r.gap.g < lo)
            lo = r.gap.g;
    }
    *pen = -lo;
    return GS_OK;
}

static int cmp_pair(const void *pa, const void *pb)
{
    const gs_stiffness_pair *a = pa, *b = pb;
    return (a->force_n < b->force_n) - (a->force_n > b->force_n);
}

/* Tooth pairs of the solution in w->x / w->row (nr rows). */
static void pairs_of(const work *w, int nr, double F, gs_stiffness_point *pt)
{
    gs_stiffness_pair acc[64];
    int na = 0;
    for (int i = 0; i < nr; i++) {
        double l = w->x[i];
        if (l <= 0.0)
            continue;
        const int *tooth = w->teeth[i];
        double f = -l * w->a[i] * w->sgn / w->rb;
        int j = 0;
        while (j < na && (acc[j].tooth[0] != tooth[0] || acc[j].tooth[1] != tooth[1]))
            j++;
        if (j == na) {
            if (na == 64)
                continue;
            acc[na].tooth[0] = tooth[0];
            acc[na].tooth[1] = tooth[1];
            acc[na].force_n = 0.0;
            na++;
        }
        acc[j].force_n += f;
    }
    qsort(acc, (size_t)na, sizeof acc[0], cmp_pair);
    pt->pairs = 0;
    for (int j = 0; j < na; j++)
        if (acc[j].force_n >= 0.01 * F)
            pt->pairs++;
    while (na > 0 && acc[na - 1].force_n < 1e-6 * F)
        na--; /* round-off shares */
    pt->n_pair = na < GS_STIFF_MAX_PAIRS ? na : GS_STIFF_MAX_PAIRS;
    for (int j = 0; j < pt->n_pair; j++)
        pt->pair[j] = acc[j];
}

static double default_torque(const gs_scene *sc, int body, double rb, double b_m)
{
    for (int i = 0; i < sc->n_loads; i++) {
        const gs_scene_load *l = &sc->loads[i];
        if (l->body != body)
            continue;
        if (l->type == GS_LOAD_CONSTANT || l->type == GS_LOAD_RAMP)
            if (l->moment != 0.0)
                return l->moment;
        if (l->type == GS_LOAD_TABLE) {
            double best = 0.0;
            for (int k = 0; k < l->n_table; k++)
                if (fabs(l->moments[k]) > fabs(best))
                    best = l->moments[k];
            if (best != 0.0)
                return best;
        }
    }
    return 200.0 * (b_m * 1e3) * rb; /* 200 N/mm line load */
}

/* An analysis under way: the roll positions are solved one at a time
 * (gs_stiffness_next) so that a caller can do other work in between. */
struct gs_stiffness_run {
    const gs_scene *sc;
    const gs_scene_mesh *sm;
    gs_stiffness_opts o;
    work w;
    double *uT[2];          /* displacements at T (central tangent) */
    double T, F, bmm, pitch, thB_first, ratio, t_start, cpu_start;
    int next;               /* next roll position */
    gs_stiffness_result out;
};

static void run_free(gs_stiffness_run *r)
{
    work_free(&r->w);
    free(r->uT[0]);
    free(r->uT[1]);
    gs_stiffness_result_clear(&r->out);
    free(r);
}

void gs_stiffness_run_free(gs_stiffness_run **run)
{
    if (run && *run) {
        run_free(*run);
        *run = NULL;
    }
}

int gs_stiffness_run_done(const gs_stiffness_run *run) { return run ? run->next : 0; }
int gs_stiffness_run_positions(const gs_stiffness_run *run) { return run ? run->o.positions : 0; }

int gs_stiffness_run_rows(const gs_stiffness_run *run, const gs_contact_row **rows,
                          const double **force)
{
    if (!run || run->next == 0)
        return 0;
    *rows = run->w.row;
    *force = run->w.x;
    return run->out.pt[run->next - 1].rows;
}

const gs_mesh *gs_stiffness_run_mesh(const gs_stiffness_run *run, int k)
{
    return run && (k == 0 || k == 1) ? run->w.b[k].mesh : NULL;
}

gs_err gs_stiffness_begin(const gs_scene *sc, int mesh_index, const gs_stiffness_opts *opt,
                          gs_stiffness_run **run, gs_diag *d)
{
    if (!sc || !run)
        return gs_diag_set(d, GS_EINVAL, "", "NULL scene or run");
    *run = NULL;
    gs_stiffness_opts o;
    if (opt)
        o = *opt;
    else
        gs_stiffness_opts_defaults(&o);
    if (mesh_index < 0 || mesh_index >= sc->n_meshes)
        return gs_diag_set(d, GS_ERANGE, "meshes", "mesh index %d: the scene has %d meshes",
                           mesh_index, sc->n_meshes);
    if (o.positions < 1 || o.positions > 100000)
        return gs_diag_set(d, GS_ERANGE, "positions", "positions must be 1..100000, not %d",
                           o.positions);
    if (o.driver != 0 && o.driver != 1)
        return gs_diag_set(d, GS_ERANGE, "driver", "driver must be gear 0 or 1 of the mesh");
    if (o.refine < -1 || o.refine > 6)
        return gs_diag_set(d, GS_ERANGE, "refine", "refine must be -1 (scene) or 0..6");
    if (o.order < 0 || o.order > 2)
        return gs_diag_set(d, GS_ERANGE, "order", "order must be 0 (scene), 1 or 2");
    if (!isfinite(o.torque_nm) || !isfinite(o.phase))
        return gs_diag_set(d, GS_ERANGE, "torque", "torque and phase must be finite");
    if (!(o.tangent_step >= 0.0 && o.tangent_step <= 0.5))
        return gs_diag_set(d, GS_ERANGE, "tangent_step", "the tangent's load step must be in [0, 0.5]");
    if (o.max_iter < 1)
        o.max_iter = 12;
    if (o.cycles < 1 || o.cycles > 10000)
        return gs_diag_set(d, GS_ERANGE, "cycles", "cycles must be 1..10000, not %d", o.cycles);
    if (o.all_rows != 0 && o.all_rows != 1)
        return gs_diag_set(d, GS_ERANGE, "all_rows", "all_rows must be 0 or 1");
    if (o.all_dofs != 0 && o.all_dofs != 1)
        return gs_diag_set(d, GS_ERANGE, "all_dofs", "all_dofs must be 0 or 1");
    if (o.fine != 0 && o.fine != 1)
        return gs_diag_set(d, GS_ERANGE, "fine", "fine must be 0 or 1");
    if (o.fine && (o.refine >= 0 || o.order > 0))
        return gs_diag_set(d, GS_EINVAL, "fine",
                           "the fine setting is a mesh of its own: not with refine or order");
    if (o.nearfield < 0 || o.nearfield > 2)
        return gs_diag_set(d, GS_ERANGE, "nearfield", "nearfield must be 0 (off), 1 (on) or 2 (auto)");
    if (!(o.nearfield_depth_mm >= 0.0 && o.nearfield_depth_mm <= 100.0))
        return gs_diag_set(d, GS_ERANGE, "nearfield_depth_mm",
                           "the near-field depth must be in [0, 100] mm (0: automatic)");
    gs_stiffness_run *r = gs_calloc(1, sizeof *r);
    if (!r)
        return GS_ENOMEM;
    r->t_start = gs_now();
    r->cpu_start = gs_cpu_now();
    r->sc = sc;
    r->o = o;
    const gs_scene_mesh *sm = r->sm = &sc->meshes[mesh_index];
    work *wp = &r->w;
#define w (*wp)
    gs_stiffness_result *out = &r->out;
    double **uT = r->uT;
    gs_err e = GS_OK;
    int bidx[2] = {sm->gear[o.driver], sm->gear[1 - o.driver]};
    w.si[0] = o.driver;
    w.si[1] = 1 - o.driver;
    w.win_on = !o.all_rows;
    int fc[2] = {0, 0};
    if (sc->bodies[bidx[0]].type == GS_BODY_GEAR && sc->bodies[bidx[1]].type == GS_BODY_GEAR)
        fine_centres(sc, bidx, &o, fc);
    for (int k = 0; k < 2 && e == GS_OK; k++)
        e = sbody_init(sc, bidx[k], o.refine, o.order,
                       /* the teeth in contact over the cycles, an odd count (centred) */
                       o.fine ? o.cycles + 2 + (o.cycles % 2 == 0) : 0,
                       fc[k], &w.b[k], d);
    if (e != GS_OK)
        goto done;
    for (int k = 0; k < 2; k++)
        w.b[k].zone_on = !o.all_dofs;
    const gs_gear_params *gA = &w.b[0].sb->gear, *gB = &w.b[1].sb->gear;
    {
        gs_contact_opts co;
        gs_contact_opts_defaults(&co);
        co.passes = sm->one_pass ? GS_CONTACT_ONE_PASS : GS_CONTACT_TWO_PASS;
        const gs_mesh *m[2];
        m[w.si[0]] = w.b[0].mesh;
        m[w.si[1]] = w.b[1].mesh;
        gs_diag cd;
        gs_diag_clear(&cd);
        e = gs_contact_search_new(m[0], &sc->bodies[sm->gear[0]].gear, m[1],
                                  &sc->bodies[sm->gear[1]].gear, &co, &w.search, &cd);
        if (e != GS_OK) {
            gs_diag_set(d, e, "meshes", "contact search of '%s': %s", sm->name, cd.message);
            goto done;
        }
    }
    w.rb = gs_gear_base_radius(gA);
    /* auto (2): on quadratic meshes of unmodified gears, where it is
     * validated against the reference; on linear triangles it left positions
     * unconverged, and on modified flanks there is no reference (it doubled
     * the relieved TE of the Harris map against the plain FE before the
     * vertex fit's curvature bound and the rigid gaps against the flank
     * gap; 0.89 times it since: docs/STIFFNESS.md). */
    double nf_gap = 0.0; /* conjugate flanks' gap at the kinematic angle, m */
    w.nf = o.nearfield == 2 ? gs_mesh_order(w.b[0].mesh) == 2 && gs_mesh_order(w.b[1].mesh) == 2 &&
                                  !w.b[0].xy_ref && !w.b[1].xy_ref
                            : o.nearfield;
    if (w.nf) {
        /* Depth of the FE field point below the contact: given, or a fixed
         * fraction of the smaller module (docs/STIFFNESS.md). */
        double mmin = fmin(gA->module_m, gB->module_m);
        w.nf_depth = o.nearfield_depth_mm > 0.0 ? o.nearfield_depth_mm * 1e-3 : GS_NF_DEPTH * mmin;
        if (w.nf_depth > mmin) {
            e = gs_diag_set(d, GS_ERANGE, "nearfield_depth_mm",
                            "the near-field depth %.3g mm is beyond one module (%.3g mm)",
                            w.nf_depth * 1e3, mmin * 1e3);
            goto done;
        }
        const gs_material *m0 = &w.b[0].sb->material, *m1 = &w.b[1].sb->material;
        w.nf_estar = gs_hertz_line_modulus(m0->youngs_pa, m0->poisson, m1->youngs_pa,
                                           m1->poisson, m0->plane);
        w.nf_bw = fmin(gA->face_width_m, gB->face_width_m);
        for (int k = 0; k < 2 && e == GS_OK; k++) {
            gs_gear_geom gg;
            e = gs_gear_geometry(&w.b[k].sb->gear, &gg, d);
            w.nf_rform[k] = gg.r_form;
        }
        if (e != GS_OK)
            goto done;
        /* Unmodified gears are conjugate involutes at any centre distance
         * they mesh at: the kinematic angles (gs_pair_mesh_phase) share the
         * backlash equally, so every loaded flank pair is apart by half the
         * normal backlash along the line of action, the same for all (0 at
         * the tight-mesh distance, to 0.01 um; nf_offsets). Thinning and
         * profile shift change the backlash, not the conjugacy. */
        gs_pair_info pinfo;
        gs_diag td;
        gs_diag_clear(&td);
        double ac = hypot(w.b[1].c[0] - w.b[0].c[0], w.b[1].c[1] - w.b[0].c[1]);
        w.nf_conj = !w.b[0].xy_ref && !w.b[1].xy_ref &&
                    gs_pair_analyse(gA, gB, ac, &pinfo, &td) == GS_OK;
        if (w.nf_conj && fabs(ac - pinfo.a_tight) >= 1e-8)
            nf_gap = 0.5 * pinfo.backlash_normal;
        gs_index nmax = w.b[0].mesh->n_nodes > w.b[1].mesh->n_nodes ? w.b[0].mesh->n_nodes
                                                                   : w.b[1].mesh->n_nodes;
        w.fq = malloc((size_t)(2 * nmax) * sizeof *w.fq);
        w.uq = malloc((size_t)(2 * nmax) * sizeof *w.uq);
        if (!w.fq || !w.uq) {
            e = GS_ENOMEM;
            goto done;
        }
    }
    double bw = fmin(gA->face_width_m, gB->face_width_m);
    double T = r->T = o.torque_nm != 0.0 ? o.torque_nm : default_torque(sc, bidx[0], w.rb, bw);
    w.sgn = T > 0 ? 1.0 : -1.0;
    w.nf_dc = w.sgn * nf_gap / w.rb;
    double F = r->F = fabs(T) / w.rb, bmm = r->bmm = bw * 1e3;
    snprintf(out->mesh_name, sizeof out->mesh_name, "%s", sm->name);
    out->mesh_index = mesh_index;
    out->driver = o.driver;
    for (int k = 0; k < 2; k++) {
        out->body[k] = bidx[k];
        out->teeth[k] = w.b[k].sb->gear.teeth;
        out->refine[k] = o.refine >= 0 ? o.refine : w.b[k].sb->mesh.refine;
        out->nodes[k] = w.b[k].mesh->n_nodes;
    }
    out->torque_nm = T;
    out->force_n = F;
    out->base_radius_m = w.rb;
    out->face_width_mm = bmm;
    {
        double a = hypot(w.b[1].c[0] - w.b[0].c[0], w.b[1].c[1] - w.b[0].c[1]);
        double cr = NAN;
        if (gs_pair_contact_ratio(gA, gB, a, &cr, NULL, NULL) == GS_OK)
            out->contact_ratio = cr;
        else
            out->contact_ratio = NAN;
    }
    out->positions = o.positions;
    out->pt = gs_calloc((size_t)o.positions, sizeof *out->pt);
    if (!out->pt) {
        e = GS_ENOMEM;
        goto done;
    }
    for (int k = 0; k < 2 && o.tangent && o.tangent_step > 0.0; k++) {
        uT[k] = malloc((size_t)(2 * w.b[k].mesh->n_nodes) * sizeof *uT[k]);
        if (!uT[k]) {
            e = GS_ENOMEM;
            goto done;
        }
    }
    r->pitch = 2.0 * GS_PI / gA->teeth;
    /* The driven gear's kinematic angle: the mesh phase nearest to its
     * expected rotation (ratio z_A / z_B; opposite sense for an external
     * pair, same sense for an internal one), so the same tooth pairs follow
     * each other whatever the number of positions. */
    r->thB_first = gs_pair_mesh_phase(gA, w.b[0].c, w.b[0].sb->angle0 + w.sgn * o.phase * r->pitch,
                                      gB, w.b[1].c, w.b[1].sb->angle0);
    r->ratio = (double)gA->teeth / gB->teeth *
               (gA->kind == GS_GEAR_INTERNAL || gB->kind == GS_GEAR_INTERNAL ? 1.0 : -1.0);
done:
#undef w
    if (e != GS_OK) {
        if (d && !d->message[0])
            gs_diag_set(d, e, "meshes", "stiffness analysis failed: %s", gs_strerror(e));
        run_free(r);
        return e;
    }
    *run = r;
    return GS_OK;
}

/* No-load closing rotation: rigid bodies (u = 0) turned until the first row
 * closes, the rows re-evaluated at each new angle (with backlash the
 * linearisation at the kinematic angle alone is too crude). */
static gs_err close_rigid(work *w, double *delta0, double roll, const char *name, gs_diag *d)
{
    int nr;
    double gmin;
    for (int it = 0; it < 30; it++) {
        GS_TRY(collect(w, *delta0, INFINITY, &nr, &gmin));
        double close = INFINITY;
        for (int i = 0; i < nr; i++) {
            double a = w->row[i].dg_dtheta[w->si[0]];
            if (a * w->sgn < -1e-6 * w->rb)
                close = fmin(close, w->row[i].gap.g / fabs(a));
        }
        if (!isfinite(close))
            return gs_diag_set(d, GS_EINFEASIBLE, "meshes",
                               "'%s' at roll %.3f: no flank closes in the torque direction", name,
                               roll);
        *delta0 += w->sgn * close;
        if (fabs(close) * w->rb < 1e-12)
            break;
    }
    return GS_OK;
}

/* Roll position r->next: its no-load closing rotation, the loaded solve
 * and the tangent. */
static gs_err solve_position(gs_stiffness_run *r, gs_diag *d)
{
    work *wp = &r->w;
#define w (*wp)
    const gs_stiffness_opts o = r->o;
    const gs_scene_mesh *sm = r->sm;
    gs_stiffness_result *out = &r->out;
    double **uT = r->uT;
    const gs_gear_params *gA = &w.b[0].sb->gear, *gB = &w.b[1].sb->gear;
    double T = r->T, F = r->F, bmm = r->bmm, pitch = r->pitch;
    gs_err e = GS_OK;
    {
        int j = r->next;
        gs_stiffness_point *pt = &out->pt[j];
        double roll = (double)j / o.positions * o.cycles;
        pt->roll = roll;
        pt->angle_rad = roll * pitch;
        w.theta0[0] = w.b[0].sb->angle0 + w.sgn * (o.phase + roll) * pitch;
        w.theta0[1] = gs_pair_mesh_phase(gA, w.b[0].c, w.theta0[0], gB, w.b[1].c,
                                         r->thB_first + r->ratio * w.sgn * roll * pitch);
        for (int k = 0; k < 2; k++) {
            memset(w.b[k].u, 0, (size_t)(2 * w.b[k].mesh->n_nodes) * sizeof *w.b[k].u);
            w.b[k].dirty = 0;
        }
        w.n_go = 0;
        if (w.nf) {
            e = nf_offsets(&w);
            if (e != GS_OK)
                goto done;
        }
        /* No-load closing rotation: rigid bodies turned until the first row
         * closes, the rows re-evaluated at each new angle (with backlash the
         * linearisation at the kinematic angle alone is too crude). */
        int nr;
        double delta0 = 0.0, delta_ref = 0.0;
        if (w.b[0].xy_ref || w.b[1].xy_ref) {
            /* The perfect gears' no-load closing: the reference of the loaded
             * TE with modifications (their geometric TE included). */
            double *keep[2];
            for (int k = 0; k < 2; k++) {
                keep[k] = w.b[k].mesh->xy;
                if (w.b[k].xy_ref)
                    w.b[k].mesh->xy = w.b[k].xy_ref;
            }
            e = close_rigid(&w, &delta_ref, roll, sm->name, d);
            for (int k = 0; k < 2; k++)
                w.b[k].mesh->xy = keep[k];
            if (e != GS_OK)
                goto done;
        }
        e = close_rigid(&w, &delta0, roll, sm->name, d);
        if (e != GS_OK)
            goto done;
        if (!w.b[0].xy_ref && !w.b[1].xy_ref)
            delta_ref = delta0;
        double delta = delta0;
        int iters = 0, conv = 0;
        double pen = 0.0;
        e = solve_load(&w, T, o.max_iter, delta0, &delta, &nr, &iters, &conv, &pen, d);
        if (e != GS_OK)
            goto done;
        pt->delta_rad = delta;
        pt->te_raw_um = w.rb * w.sgn * delta * 1e6;
        pt->te0_um = w.rb * w.sgn * delta0 * 1e6;
        pt->te_um = pt->te_raw_um - pt->te0_um;
        pt->te_ref_um = w.rb * w.sgn * delta_ref * 1e6;
        pt->te_loaded_um = pt->te_raw_um - pt->te_ref_um;
        pt->k = F / pt->te_um / bmm;
        pt->rows = nr;
        pt->active = 0;
        for (int i = 0; i < nr; i++)
            pt->active += w.x[i] > 0.0;
        pt->iterations = iters;
        pt->converged = conv;
        pt->penetration_um = pen * 1e6;
        pairs_of(&w, nr, F, pt);
        for (int k = 0; k < 2 && uT[k]; k++)
            memcpy(uT[k], w.b[k].u, (size_t)(2 * w.b[k].mesh->n_nodes) * sizeof *uT[k]);
        pt->te_half_um = NAN;
        pt->k_tan = NAN;
        if (o.tangent && o.tangent_step > 0.0) {
            /* Central difference about T, each load started from the
             * solution at T. */
            double hs = o.tangent_step, dd[2];
            for (int q = 0; q < 2; q++) {
                int ih, ch;
                double ph;
                for (int k = 0; k < 2; k++)
                    memcpy(w.b[k].u, uT[k], (size_t)(2 * w.b[k].mesh->n_nodes) * sizeof *w.b[k].u);
                dd[q] = delta;
                e = solve_load(&w, (q ? 1.0 - hs : 1.0 + hs) * T, o.max_iter, delta0, &dd[q], &nr, &ih, &ch,
                               &ph, d);
                if (e != GS_OK)
                    goto done;
                pt->converged = pt->converged && ch;
            }
            pt->k_tan = 2.0 * hs * F / (w.rb * w.sgn * (dd[0] - dd[1]) * 1e6) / bmm;
        } else if (o.tangent) {
            double dh = delta;
            int ih, ch;
            double ph;
            e = solve_load(&w, 0.5 * T, o.max_iter, delta0, &dh, &nr, &ih, &ch, &ph, d);
            if (e != GS_OK)
                goto done;
            pt->te_half_um = w.rb * w.sgn * dh * 1e6;
            pt->k_tan = 0.5 * F / (pt->te_raw_um - pt->te_half_um) / bmm;
            pt->converged = pt->converged && ch;
        }
    }
done:
#undef w
    return e;
}

gs_err gs_stiffness_next(gs_stiffness_run *r, gs_diag *d)
{
    if (!r || r->next >= r->o.positions)
        return gs_diag_set(d, GS_EINVAL, "", "no roll position left to solve");
    gs_err e;
    /* A displacement zone that grew mid-position (zone_cover): again, with
     * the larger zone (they only grow: at most once per tooth). */
    for (;;) {
        r->w.restart = 0;
        e = solve_position(r, d);
        if (!(e == GS_EINTERNAL && r->w.restart))
            break;
        r->w.zone_restarts++;
    }
    if (e == GS_OK)
        r->next++;
    else if (d && !d->message[0])
        gs_diag_set(d, e, "meshes", "stiffness analysis failed: %s", gs_strerror(e));
    return e;
}

gs_err gs_stiffness_end(gs_stiffness_run **run, gs_stiffness_result *out, gs_diag *d)
{
    gs_stiffness_run *r = run ? *run : NULL;
    if (!r || !out || r->next < r->o.positions)
        return gs_diag_set(d, GS_EINVAL, "", "the analysis has roll positions left");
    work *wp = &r->w;
#define w (*wp)
    const gs_stiffness_opts o = r->o;
    *out = r->out;
    memset(&r->out, 0, sizeof r->out);
    /* Summary. */
    out->k_min = out->te_min = out->te_loaded_min = INFINITY;
    out->k_max = out->te_max = out->te_loaded_max = -INFINITY;
    double ks = 0, ts = 0, kt = 0, tl = 0;
    int multi = 0;
    for (int j = 0; j < o.positions; j++) {
        const gs_stiffness_point *pt = &out->pt[j];
        out->k_min = fmin(out->k_min, pt->k);
        out->k_max = fmax(out->k_max, pt->k);
        out->te_min = fmin(out->te_min, pt->te_um);
        out->te_max = fmax(out->te_max, pt->te_um);
        out->te_loaded_min = fmin(out->te_loaded_min, pt->te_loaded_um);
        out->te_loaded_max = fmax(out->te_loaded_max, pt->te_loaded_um);
        tl += pt->te_loaded_um;
        ks += pt->k;
        ts += pt->te_um;
        kt += pt->k_tan;
        multi += pt->pairs >= 2;
    }
    out->k_mean = ks / o.positions;
    out->te_mean = ts / o.positions;
    out->te_loaded_mean = tl / o.positions;
    out->modified = w.b[0].xy_ref || w.b[1].xy_ref;
    out->k_tan_mean = o.tangent ? kt / o.positions : NAN;
    out->frac_multi = (double)multi / o.positions;
    out->solves = gs_fe_static_solves(w.b[0].fs) + gs_fe_static_solves(w.b[1].fs);
    out->seconds = gs_now() - r->t_start;
    out->cpu_seconds = gs_cpu_now() - r->cpu_start;
    out->columns = 0;
    out->window_widened = w.win_widened;
    out->zone_restarts = w.zone_restarts;
    {
        double fw = 0.0;
        long nb = 0;
        for (int k = 0; k < 2; k++) {
            fw += w.b[k].backw;
            nb += w.b[k].nback;
        }
        out->zone_fraction = nb > 0 ? fw / (double)nb : 1.0;
    }
    out->cpu_mesh = out->cpu_factor = out->cpu_columns = out->cpu_solves = 0.0;
    for (int k = 0; k < 2; k++) {
        out->columns += w.b[k].columns;
        out->cpu_mesh += w.b[k].t_mesh;
        out->cpu_factor += w.b[k].t_factor;
        out->cpu_columns += w.b[k].t_columns;
        out->cpu_solves += w.b[k].t_solves;
    }
    out->cpu_contact = out->cpu_seconds - out->cpu_mesh - out->cpu_factor - out->cpu_columns -
                       out->cpu_solves;
#undef w
    gs_stiffness_run_free(run);
    return GS_OK;
}

gs_err gs_stiffness_analyse(const gs_scene *sc, int mesh_index, const gs_stiffness_opts *opt,
                            gs_stiffness_result *out, gs_diag *d)
{
    if (!sc || !out)
        return gs_diag_set(d, GS_EINVAL, "", "NULL scene or result");
    memset(out, 0, sizeof *out);
    gs_stiffness_run *r;
    GS_TRY(gs_stiffness_begin(sc, mesh_index, opt, &r, d));
    gs_err e = GS_OK;
    while (e == GS_OK && gs_stiffness_run_done(r) < gs_stiffness_run_positions(r))
        e = gs_stiffness_next(r, d);
    if (e == GS_OK)
        return gs_stiffness_end(&r, out, d);
    gs_stiffness_run_free(&r);
    return e;
}

/* ------------------------------------------------------------------------ */
/* HDF5                                                                      */
/* ------------------------------------------------------------------------ */

static herr_t put_ds(hid_t g, const char *name, hid_t type, int rank, const hsize_t *dims,
                     const void *data)
{
    hid_t sp = H5Screate_simple(rank, dims, NULL);
    hid_t ds = H5Dcreate2(g, name, type, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    herr_t st = ds < 0 ? -1 : H5Dwrite(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data);
    if (ds >= 0)
        H5Dclose(ds);
    H5Sclose(sp);
    return st;
}

gs_err gs_stiffness_write_h5(const char *path, const gs_scene *sc, const gs_stiffness_result *r,
                             gs_diag *d)
{
    if (!path || !r || (r->positions > 0 && !r->pt))
        return gs_diag_set(d, GS_EINVAL, "out", "NULL path or empty result");
    int n = r->positions;
    size_t nn = n > 0 ? (size_t)n : 1;
    double *col = malloc(nn * 10 * sizeof *col);
    int *pairs = malloc(nn * sizeof *pairs);
    int *pt_tooth = malloc(nn * GS_STIFF_MAX_PAIRS * 2 * sizeof *pt_tooth);
    double *pf = malloc(nn * GS_STIFF_MAX_PAIRS * sizeof *pf);
    if (!col || !pairs || !pt_tooth || !pf) {
        free(col);
        free(pairs);
        free(pt_tooth);
        free(pf);
        return GS_ENOMEM;
    }
    for (int j = 0; j < n; j++) {
        const gs_stiffness_point *p = &r->pt[j];
        double v[10] = {p->roll, p->angle_rad * 180.0 / GS_PI, p->te_um, p->te_raw_um, p->te0_um,
                        p->k, p->te_half_um, p->k_tan, p->te_ref_um, p->te_loaded_um};
        for (int c = 0; c < 10; c++)
            col[(size_t)c * nn + (size_t)j] = v[c];
        pairs[j] = p->pairs;
        for (int q = 0; q < GS_STIFF_MAX_PAIRS; q++) {
            bool used = q < p->n_pair;
            pt_tooth[((size_t)j * GS_STIFF_MAX_PAIRS + (size_t)q) * 2] = used ? p->pair[q].tooth[0] : -1;
            pt_tooth[((size_t)j * GS_STIFF_MAX_PAIRS + (size_t)q) * 2 + 1] =
                used ? p->pair[q].tooth[1] : -1;
            pf[(size_t)j * GS_STIFF_MAX_PAIRS + (size_t)q] = used ? p->pair[q].force_n : 0.0;
        }
    }
    gs_err err = GS_EIO;
    hid_t f = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    hid_t g = f < 0 ? -1 : H5Gcreate2(f, "stiffness", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (g >= 0) {
        static const char *const names[10] = {"roll", "angle_deg", "te_um", "te_raw_um",
                                              "te0_um", "k", "te_half_um", "k_tan",
                                              "te_ref_um", "te_loaded_um"};
        hsize_t d1[1] = {(hsize_t)n}, d2[2] = {(hsize_t)n, GS_STIFF_MAX_PAIRS},
                d3[3] = {(hsize_t)n, GS_STIFF_MAX_PAIRS, 2};
        herr_t st = 0;
        for (int c = 0; c < 10; c++)
            st |= put_ds(g, names[c], H5T_NATIVE_DOUBLE, 1, d1, col + (size_t)c * nn);
        st |= put_ds(g, "pairs", H5T_NATIVE_INT, 1, d1, pairs);
        st |= put_ds(g, "pair_tooth", H5T_NATIVE_INT, 3, d3, pt_tooth);
        st |= put_ds(g, "pair_force_n", H5T_NATIVE_DOUBLE, 2, d2, pf);
        st |= gsi_h5_string_attr(g, "scene", sc && sc->json ? sc->json : "");
        st |= gsi_h5_string_attr(g, "mesh", r->mesh_name);
        st |= gsi_h5_scalar_attr(g, "driver", H5T_NATIVE_INT, &r->driver);
        st |= gsi_h5_scalar_attr(g, "teeth", H5T_NATIVE_INT, &r->teeth[0]);
        st |= gsi_h5_scalar_attr(g, "teeth_driven", H5T_NATIVE_INT, &r->teeth[1]);
        st |= gsi_h5_scalar_attr(g, "refine", H5T_NATIVE_INT, &r->refine[0]);
        const struct {
            const char *name;
            double v;
        } sc_attr[] = {{"torque_nm", r->torque_nm},         {"force_n", r->force_n},
                       {"face_width_mm", r->face_width_mm}, {"base_radius_m", r->base_radius_m},
                       {"contact_ratio", r->contact_ratio}, {"k_min", r->k_min},
                       {"k_mean", r->k_mean},               {"k_max", r->k_max},
                       {"te_min", r->te_min},               {"te_mean", r->te_mean},
                       {"te_max", r->te_max},               {"te_loaded_min", r->te_loaded_min},
                       {"te_loaded_mean", r->te_loaded_mean}, {"te_loaded_max", r->te_loaded_max}};
        for (size_t c = 0; c < sizeof sc_attr / sizeof sc_attr[0]; c++)
            st |= gsi_h5_scalar_attr(g, sc_attr[c].name, H5T_NATIVE_DOUBLE, &sc_attr[c].v);
        if (st >= 0)
            err = GS_OK;
        H5Gclose(g);
    }
    if (f >= 0 && H5Fclose(f) < 0)
        err = GS_EIO;
    free(col);
    free(pairs);
    free(pt_tooth);
    free(pf);
    if (err != GS_OK)
        return gs_diag_set(d, err, "out", "cannot write %s", path);
    return GS_OK;
}

/* JSON number, or null for NaN / infinity. */
static json_object *json_num(double v)
{
    return isfinite(v) ? json_object_new_double(v) : NULL;
}

/* {min, mean, max, peak_to_peak} of a TE over the positions. */
static json_object *json_te_range(double lo, double mean, double hi)
{
    json_object *t = json_object_new_object();
    json_object_object_add(t, "min", json_num(lo));
    json_object_object_add(t, "mean", json_num(mean));
    json_object_object_add(t, "max", json_num(hi));
    json_object_object_add(t, "peak_to_peak", json_num(hi - lo));
    return t;
}

json_object *gs_stiffness_json(const gs_stiffness_result *r, const gs_scene *s)
{
    json_object *o = json_object_new_object();
    json_object_object_add(o, "mesh", json_object_new_string(r->mesh_name));
    json_object_object_add(o, "driver", json_object_new_string(s->bodies[r->body[0]].name));
    json_object_object_add(o, "driven", json_object_new_string(s->bodies[r->body[1]].name));
    json_object *teeth = json_object_new_array();
    json_object_array_add(teeth, json_object_new_int(r->teeth[0]));
    json_object_array_add(teeth, json_object_new_int(r->teeth[1]));
    json_object_object_add(o, "teeth", teeth);
    json_object *ref = json_object_new_array();
    json_object_array_add(ref, json_object_new_int(r->refine[0]));
    json_object_array_add(ref, json_object_new_int(r->refine[1]));
    json_object_object_add(o, "refine", ref);
    json_object *nodes = json_object_new_array();
    json_object_array_add(nodes, json_object_new_int64(r->nodes[0]));
    json_object_array_add(nodes, json_object_new_int64(r->nodes[1]));
    json_object_object_add(o, "nodes", nodes);
    json_object_object_add(o, "positions", json_object_new_int(r->positions));
    json_object_object_add(o, "torque_nm", json_num(r->torque_nm));
    json_object_object_add(o, "force_n", json_num(r->force_n));
    json_object_object_add(o, "base_radius_mm", json_num(r->base_radius_m * 1e3));
    json_object_object_add(o, "face_width_mm", json_num(r->face_width_mm));
    json_object_object_add(o, "contact_ratio", json_num(r->contact_ratio));
    json_object_object_add(o, "units", json_object_new_string("k: N/(mm um) per mm face width; te: um along the line of action"));
    json_object *pts = json_object_new_array();
    for (int j = 0; j < r->positions; j++) {
        const gs_stiffness_point *p = &r->pt[j];
        json_object *q = json_object_new_object();
        json_object_object_add(q, "roll", json_num(p->roll));
        json_object_object_add(q, "angle_deg", json_num(p->angle_rad * 180.0 / 3.14159265358979323846));
        json_object_object_add(q, "k", json_num(p->k));
        json_object_object_add(q, "te_um", json_num(p->te_um));
        json_object_object_add(q, "te_raw_um", json_num(p->te_raw_um));
        json_object_object_add(q, "te0_um", json_num(p->te0_um));
        json_object_object_add(q, "te_ref_um", json_num(p->te_ref_um));
        json_object_object_add(q, "te_loaded_um", json_num(p->te_loaded_um));
        json_object_object_add(q, "k_tan", json_num(p->k_tan));
        json_object_object_add(q, "pairs", json_object_new_int(p->pairs));
        json_object *fa = json_object_new_array();
        for (int k = 0; k < p->n_pair; k++) {
            json_object *pp = json_object_new_object();
            json_object *tt = json_object_new_array();
            json_object_array_add(tt, json_object_new_int(p->pair[k].tooth[0]));
            json_object_array_add(tt, json_object_new_int(p->pair[k].tooth[1]));
            json_object_object_add(pp, "teeth", tt);
            json_object_object_add(pp, "force_n", json_num(p->pair[k].force_n));
            json_object_array_add(fa, pp);
        }
        json_object_object_add(q, "pair_forces", fa);
        json_object_object_add(q, "converged", json_object_new_boolean(p->converged));
        json_object_object_add(q, "penetration_um", json_num(p->penetration_um));
        json_object_array_add(pts, q);
    }
    json_object_object_add(o, "points", pts);
    json_object *k = json_object_new_object();
    json_object_object_add(k, "min", json_num(r->k_min));
    json_object_object_add(k, "mean", json_num(r->k_mean));
    json_object_object_add(k, "max", json_num(r->k_max));
    json_object_object_add(k, "tangent_mean", json_num(r->k_tan_mean));
    json_object_object_add(o, "k", k);
    json_object_object_add(o, "te_um", json_te_range(r->te_min, r->te_mean, r->te_max));
    json_object_object_add(o, "te_loaded_um",
                           json_te_range(r->te_loaded_min, r->te_loaded_mean, r->te_loaded_max));
    json_object_object_add(o, "modified", json_object_new_boolean(r->modified));
    json_object_object_add(o, "fraction_multi_pair", json_num(r->frac_multi));
    json_object_object_add(o, "seconds", json_num(r->seconds));
    json_object_object_add(o, "solves", json_object_new_int64(r->solves));
    json_object_object_add(o, "columns", json_object_new_int64(r->columns));
    json_object_object_add(o, "window_widened", json_object_new_int64(r->window_widened));
    json_object_object_add(o, "zone_fraction", json_num(r->zone_fraction));
    json_object_object_add(o, "zone_restarts", json_object_new_int64(r->zone_restarts));
    json_object *tm = json_object_new_object();
    json_object_object_add(tm, "cpu_s", json_num(r->cpu_seconds));
    json_object_object_add(tm, "mesh_s", json_num(r->cpu_mesh));
    json_object_object_add(tm, "factor_s", json_num(r->cpu_factor));
    json_object_object_add(tm, "columns_s", json_num(r->cpu_columns));
    json_object_object_add(tm, "solves_s", json_num(r->cpu_solves));
    json_object_object_add(tm, "contact_s", json_num(r->cpu_contact));
    json_object_object_add(o, "cpu", tm);
    return o;
}
