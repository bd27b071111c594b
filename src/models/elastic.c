/* SPDX-License-Identifier: MIT
 * Elastic body model: a gear meshed with finite elements (src/mesh), its
 * constant matrices (src/fe model, built on every rank: cheap, and every
 * rank then knows the inertia and can recover stresses) and, on the owner
 * rank only, the body in the step with its Cholesky factor and compliance
 * cache (src/fe body). METHOD.md sections 1, 2 and 4.
 *
 * Interface to the step solver: the body's rotation and, when a contact
 * mesh found them near the other gear, the displacements of a few flank
 * nodes (the step's plan, in the view). Per step the owner solves for the free motion
 * and offers the free increments d0 and the compliance block C of A^-1 at
 * those unknowns (from the per-node cache: teeth come back every turn), the
 * condensed midpoint equation d = d0 + C f. After the global solve the
 * interface forces f are applied back and the step ends (q += dq,
 * w = 2 dq / h - w for every elastic unknown). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/fe.h"
#include "gearsim/mesh.h"
#include "gearsim/models.h"
#include "gearsim/util.h"

typedef struct elastic elastic;

/* The body in the step: the full FE body (gs_fe_body) or the reduced one
 * (gs_fe_reduced, bodies[i].reduction); the same operations. */
typedef struct elastic_backend {
    const char *name;
    void (*destroy)(elastic *el);
    gs_err (*set_state)(elastic *el, double theta, double omega, const double *u, const double *v);
    gs_err (*hold_theta)(elastic *el, bool held);
    gs_err (*set_step)(elastic *el, double h, double c);
    gs_err (*begin_step)(elastic *el, double moment);
    void (*cancel_step)(elastic *el);
    gs_err (*increment)(elastic *el, int n, const gs_index *dofs, double *dq);
    /* current displacement of a node (body frame; zero when fixed) */
    void (*node_u)(elastic *el, gs_index node, double u[2]);
    gs_err (*compliance)(elastic *el, int n, const gs_index *dofs, double *C);
    gs_err (*compliance_sub)(elastic *el, int n, const gs_index *dofs, int k, const int *sel, double *C);
    gs_err (*apply)(elastic *el, int n, const gs_index *dofs, const double *f);
    gs_err (*end_step)(elastic *el, bool energies);
    double (*damped)(const elastic *el);
    double (*angular_momentum)(const elastic *el);
    void (*spin)(elastic *el, double dw);
    void (*energy)(const elastic *el, double *T, double *V);
    void (*save)(const elastic *el, double *x);
    gs_err (*load)(elastic *el, const double *x);
    gs_err (*nodal)(elastic *el, double *u);
} elastic_backend;

struct elastic {
    gs_mesh *mesh;
    gs_fe_model *model;
    const elastic_backend *be; /* owner rank only, with one of: */
    gs_fe_body *body;       /* the full FE body */
    gs_fe_reduced *red;     /* the reduced body */
    bool reduced;           /* bodies[i].reduction given (every rank) */
    gs_index ne;            /* elastic unknowns */
    double h, c;            /* time step and brake the body is factorised for */
    gs_index *dofs;         /* interface dofs of this step (FE body names) */
    size_t cap_dofs;
    bool begun;             /* a step is begun in the FE body */
};

/* ---- the full FE body --------------------------------------------------- */

static void full_destroy(elastic *el) { gs_fe_body_free(&el->body); }
static gs_err full_set_state(elastic *el, double th, double om, const double *u, const double *v)
{
    return gs_fe_body_set_state(el->body, th, om, u, v);
}
static gs_err full_hold(elastic *el, bool held) { return gs_fe_body_hold_theta(el->body, held); }
static gs_err full_set_step(elastic *el, double h, double c) { return gs_fe_body_set_step(el->body, h, c); }
static gs_err full_begin(elastic *el, double M) { return gs_fe_body_begin_step(el->body, M, NULL); }
static void full_cancel(elastic *el) { gs_fe_body_cancel_step(el->body); }
static gs_err full_increment(elastic *el, int n, const gs_index *dofs, double *dq)
{
    return gs_fe_body_increment(el->body, n, dofs, dq);
}
static void full_node_u(elastic *el, gs_index node, double u[2])
{
    const double *q = gs_fe_body_q(el->body);
    for (int comp = 0; comp < 2; comp++) {
        gs_index k = gs_fe_model_dof(el->model, node, comp);
        u[comp] = k >= 0 ? q[k] : 0.0;
    }
}
static gs_err full_compliance(elastic *el, int n, const gs_index *dofs, double *C)
{
    return gs_fe_body_compliance(el->body, n, dofs, C);
}
static gs_err full_compliance_sub(elastic *el, int n, const gs_index *dofs, int k, const int *sel, double *C)
{
    return gs_fe_body_compliance_sub(el->body, n, dofs, k, sel, C);
}
static gs_err full_apply(elastic *el, int n, const gs_index *dofs, const double *f)
{
    return gs_fe_body_apply(el->body, n, dofs, f);
}
/* Without energies the end-of-step pass skips the M stream (fe_body.c). */
static gs_err full_end(elastic *el, bool energies)
{
    gs_fe_body_defer_energy(el->body, !energies);
    return gs_fe_body_end_step(el->body);
}
static double full_damped(const elastic *el) { return gs_fe_body_damped(el->body); }
static double full_L(const elastic *el) { return gs_fe_body_angular_momentum(el->body); }
static void full_spin(elastic *el, double dw) { gs_fe_body_spin(el->body, dw); }
static void full_energy(const elastic *el, double *T, double *V) { gs_fe_body_energy(el->body, T, V); }

/* Snapshot state: q then w of the FE body (ne + 1 each, theta last). */
static void full_save(const elastic *el, double *x)
{
    size_t n = (size_t)(el->ne + 1);
    memcpy(x, gs_fe_body_q(el->body), n * sizeof(double));
    memcpy(x + n, gs_fe_body_w(el->body), n * sizeof(double));
}
static gs_err full_load(elastic *el, const double *x)
{
    gs_index nn = el->mesh->n_nodes, ne = el->ne;
    double *u = gs_calloc((size_t)(4 * nn), sizeof(double));
    if (!u)
        return GS_ENOMEM;
    double *v = u + 2 * nn;
    for (gs_index i = 0; i < nn; i++)
        for (int c = 0; c < 2; c++) {
            gs_index k = gs_fe_model_dof(el->model, i, c);
            if (k >= 0) {
                u[2 * i + c] = x[k];
                v[2 * i + c] = x[ne + 1 + k];
            }
        }
    gs_fe_body_cancel_step(el->body);
    gs_err e = gs_fe_body_set_state(el->body, x[ne], x[2 * ne + 1], u, v);
    free(u);
    return e;
}
static gs_err full_nodal(elastic *el, double *u)
{
    gs_fe_body_nodal(el->body, u, NULL);
    return GS_OK;
}

static const elastic_backend backend_full = {
    "full", full_destroy, full_set_state, full_hold, full_set_step, full_begin, full_cancel, full_increment,
    full_node_u, full_compliance, full_compliance_sub, full_apply, full_end, full_damped, full_L, full_spin,
    full_energy, full_save, full_load, full_nodal,
};

/* ---- the reduced body ---------------------------------------------------- */

static void red_destroy(elastic *el) { gs_fe_reduced_free(&el->red); }
static gs_err red_set_state(elastic *el, double th, double om, const double *u, const double *v)
{
    return gs_fe_reduced_set_state(el->red, th, om, u, v);
}
static gs_err red_hold(elastic *el, bool held) { return gs_fe_reduced_hold_theta(el->red, held); }
static gs_err red_set_step(elastic *el, double h, double c) { return gs_fe_reduced_set_step(el->red, h, c); }
static gs_err red_begin(elastic *el, double M) { return gs_fe_reduced_begin_step(el->red, M, NULL); }
static void red_cancel(elastic *el) { gs_fe_reduced_cancel_step(el->red); }
static gs_err red_increment(elastic *el, int n, const gs_index *dofs, double *dq)
{
    return gs_fe_reduced_increment(el->red, n, dofs, dq);
}
static void red_node_u(elastic *el, gs_index node, double u[2])
{
    if (gs_fe_reduced_node_displacement(el->red, node, u) != GS_OK)
        u[0] = u[1] = NAN;
}
static gs_err red_compliance(elastic *el, int n, const gs_index *dofs, double *C)
{
    return gs_fe_reduced_compliance(el->red, n, dofs, C);
}
static gs_err red_compliance_sub(elastic *el, int n, const gs_index *dofs, int k, const int *sel, double *C)
{
    return gs_fe_reduced_compliance_sub(el->red, n, dofs, k, sel, C);
}
static gs_err red_apply(elastic *el, int n, const gs_index *dofs, const double *f)
{
    return gs_fe_reduced_apply(el->red, n, dofs, f);
}
/* The reduced body sums its energies only when asked (red_energy). */
static gs_err red_end(elastic *el, bool energies)
{
    (void)energies;
    return gs_fe_reduced_end_step(el->red);
}
static double red_damped(const elastic *el) { return gs_fe_reduced_damped(el->red); }
static double red_L(const elastic *el) { return gs_fe_reduced_angular_momentum(el->red); }
static void red_spin(elastic *el, double dw) { gs_fe_reduced_spin(el->red, dw); }
static void red_energy(const elastic *el, double *T, double *V) { gs_fe_reduced_energy(el->red, T, V); }
/* Snapshot state: the reduced body's own (modal q, v, residual forces, books). */
static void red_save(const elastic *el, double *x) { gs_fe_reduced_save(el->red, x); }
static gs_err red_load(elastic *el, const double *x) { return gs_fe_reduced_load(el->red, x); }
static gs_err red_nodal(elastic *el, double *u) { return gs_fe_reduced_nodal(el->red, u, NULL); }

static const elastic_backend backend_reduced = {
    "reduced", red_destroy, red_set_state, red_hold, red_set_step, red_begin, red_cancel, red_increment,
    red_node_u, red_compliance, red_compliance_sub, red_apply, red_end, red_damped, red_L, red_spin,
    red_energy, red_save, red_load, red_nodal,
};

static void elastic_destroy(gs_body_rt *b)
{
    elastic *el = b->model;
    if (!el)
        return;
    if (el->be)
        el->be->destroy(el);
    gs_fe_model_free(&el->model);
    free(el->dofs);
    gs_mesh_free(&el->mesh);
    free(el);
    b->model = NULL;
}

/* The static deflection under a tangential load F spread evenly over the tip
 * of tooth 0 (tip arc and both tip corners): a reproducible elastic
 * disturbance for free-vibration runs. */
static gs_err tip_deflection(const elastic *el, double F, double *u)
{
    const gs_mesh *m = el->mesh;
    gs_index nn = m->n_nodes;
    double *f = gs_calloc((size_t)(2 * nn), sizeof(double));
    gs_index *sel = gs_calloc((size_t)nn, sizeof(gs_index));
    if (!f || !sel) {
        free(f), free(sel);
        return GS_ENOMEM;
    }
    gs_index k = 0;
    /* Tip corners: the last node of each flank of tooth 0 (root to tip). */
    sel[k++] = m->flank_nodes[m->flank_ptr[1] - 1];
    sel[k++] = m->flank_nodes[m->flank_ptr[2] - 1];
    double half = GS_PI / m->n_teeth;
    for (gs_index i = 0; i < nn; i++) {
        if (!m->node_tag || m->node_tag[i] != GS_NODE_TIP)
            continue;
        double a = atan2(m->xy[2 * i + 1], m->xy[2 * i]);
        if (fabs(a) < half)
            sel[k++] = i;
    }
    for (gs_index j = 0; j < k; j++) {
        gs_index i = sel[j];
        double x = m->xy[2 * i], y = m->xy[2 * i + 1], r = hypot(x, y);
        f[2 * i] += -F / (double)k * y / r;
        f[2 * i + 1] += F / (double)k * x / r;
    }
    gs_err e = gs_fe_model_static(el->model, f, u);
    free(f), free(sel);
    return e;
}

static gs_err elastic_init(const gs_model_view *sys, gs_body_rt *b, gs_diag *d)
{
    const gs_scene_body *sb = &sys->scene->bodies[b->index];
    char field[160];
    snprintf(field, sizeof field, "bodies[%d].mesh", b->index);
    if (sb->type != GS_BODY_GEAR)
        return gs_diag_set(d, GS_ERANGE, field, "only gears can be elastic");
    elastic *el = gs_calloc(1, sizeof *el);
    if (!el)
        return GS_ENOMEM;
    b->model = el;
    gs_diag md;
    gs_diag_clear(&md);
    gs_err e = GS_OK;
    if (b->mesh) /* made when the system was built */
        el->mesh = b->mesh, b->mesh = NULL;
    else
        e = gs_scene_gear_mesh(sb, &el->mesh, &md);
    if (e != GS_OK) {
        /* a mesh field the mesher names (e.g. mesh.fine_teeth) under this body */
        if (strncmp(md.field, "mesh.", 5) == 0)
            snprintf(field, sizeof field, "bodies[%d].%.120s", b->index, md.field);
        return gs_diag_set(d, e, field, "cannot mesh '%s': %s (%s)", sb->name, md.message, md.field);
    }
    /* Rigid core: the solid hub disc of an external gear; a ring's elastic
     * part reaches its outer rim, which is fixed (held or on its bearing). */
    const gs_gear_params *g = &sb->gear;
    double core = 0.0;
    if (g->kind == GS_GEAR_EXTERNAL) {
        double rh = gs_gear_hub_radius(g);
        core = 0.5 * GS_PI * sb->material.density * g->face_width_m * rh * rh * rh * rh;
    }
    e = gs_fe_model_new(el->mesh, &sb->material, g->face_width_m, 0.0, &el->model);
    if (e != GS_OK)
        return gs_diag_set(d, e, field, "finite element model of '%s' failed: %s", sb->name,
                           gs_strerror(e));
    gs_fe_model_info info;
    gs_fe_model_get_info(el->model, &info);
    if (sb->inertia_given) {
        core = sb->inertia - info.inertia_elastic;
        if (core < 0) {
            snprintf(field, sizeof field, "bodies[%d].inertia", b->index);
            return gs_diag_set(d, GS_ERANGE, field,
                               "'%s': inertia %.6g kg m^2 is below that of its elastic part (%.6g)",
                               sb->name, sb->inertia, info.inertia_elastic);
        }
    }
    gs_fe_model_free(&el->model);
    e = gs_fe_model_new(el->mesh, &sb->material, g->face_width_m, core, &el->model);
    if (e != GS_OK)
        return gs_diag_set(d, e, field, "finite element model of '%s' failed: %s", sb->name,
                           gs_strerror(e));
    gs_fe_model_get_info(el->model, &info);
    el->ne = info.n_elastic;
    el->reduced = sb->reduce_f_max_hz > 0;
    b->inertia_eff = info.inertia_total;
    if (b->owner != sys->rank)
        return GS_OK;
    if (sb->reduce_f_max_hz > 0) {
        /* candidate rows: the toothed boundary (every node a contact search may name) */
        gs_fe_reduced_opts ro = {sb->reduce_f_max_hz, b->coord < 0, el->mesh->n_boundary, el->mesh->boundary, 0,
                                  sb->reduce_static};
        e = gs_fe_reduced_new(el->model, &ro, &el->red);
        if (e != GS_OK) {
            snprintf(field, sizeof field, "bodies[%d].reduction.f_max_hz", b->index);
            return gs_diag_set(d, e, field, "'%s': the reduced body cannot be built (%s)", sb->name,
                               gs_strerror(e));
        }
        el->be = &backend_reduced;
        if (gs_fe_reduced_state_size(el->red) != gs_fe_reduced_state_size_for(el->ne, el->mesh->n_boundary))
            return gs_diag_set(d, GS_EINTERNAL, field, "'%s': the boundary loop repeats a node", sb->name);
    } else {
        GS_TRY(gs_fe_body_new(el->model, &el->body));
        el->be = &backend_full;
    }
    double *u0 = NULL;
    if (sb->tip_load != 0.0) {
        u0 = gs_calloc((size_t)(2 * el->mesh->n_nodes), sizeof(double));
        if (!u0)
            return GS_ENOMEM;
        e = tip_deflection(el, sb->tip_load, u0);
        if (e != GS_OK) {
            free(u0);
            snprintf(field, sizeof field, "initial.%s.tip_load", sb->name);
            return gs_diag_set(d, e, field, "static deflection of '%s' failed", sb->name);
        }
    }
    e = el->be->set_state(el, b->coord >= 0 ? sb->angle0 : 0.0, b->coord >= 0 ? sb->omega0 : 0.0, u0, NULL);
    free(u0);
    if (e == GS_OK && b->coord < 0)
        e = el->be->hold_theta(el, true);
    if (e != GS_OK)
        return gs_diag_set(d, e, field, "cannot set the state of '%s'", sb->name);
    double T, V;
    b->ops->energy(sys, b, &T, &V);
    b->T = T;
    b->V = V;
    return GS_OK;
}

/* The interface unknowns in FE body names: theta (when the body has a
 * coordinate), then x, y of the plan's nodes. */
static gs_err interface_dofs(const gs_model_view *sys, const gs_body_rt *b, elastic *el, int *n)
{
    int nd = sys->n_dof[b->index], k = 0;
    gs_index *nw = gs_grow(el->dofs, &el->cap_dofs, (size_t)nd, sizeof(gs_index));
    if (!nw)
        return GS_ENOMEM;
    el->dofs = nw;
    if (b->coord >= 0)
        el->dofs[k++] = GS_FE_DOF_THETA;
    for (int j = 0; j < sys->n_nodes[b->index]; j++) {
        el->dofs[k++] = gs_fe_dof_node(sys->nodes[b->index][j], 0);
        el->dofs[k++] = gs_fe_dof_node(sys->nodes[b->index][j], 1);
    }
    *n = k;
    return GS_OK;
}

/* Begin the body's step and write d0 and the nodes' displacements into rec
 * (its C block untouched); the number of interface dofs in *n. */
static gs_err interface_begin(const gs_model_view *sys, gs_body_rt *b, double h, double *rec, int *n)
{
    elastic *el = b->model;
    double M = 0, c = 0;
    *n = 0;
    if (b->coord >= 0)
        gs_model_body_load(sys, b->index, sys->time + 0.5 * h, &M, &c);
    if (el->begun) /* the previous global solve failed: start again */
        el->be->cancel_step(el);
    el->begun = false;
    if (h != el->h || c != el->c) {
        gs_err e = el->be->set_step(el, h, c);
        el->h = e == GS_OK ? h : 0;
        if (e != GS_OK)
            return e;
        el->c = c;
    }
    GS_TRY(el->be->begin_step(el, M));
    el->begun = true;
    GS_TRY(interface_dofs(sys, b, el, n));
    if (*n == 0)
        return GS_OK;
    GS_TRY(el->be->increment(el, *n, el->dofs, rec + (size_t)*n * *n));
    /* Current displacements of the nodes (body frame). */
    double *u = rec + (size_t)*n * *n + *n;
    for (int j = 0; j < sys->n_nodes[b->index]; j++)
        el->be->node_u(el, sys->nodes[b->index][j], u + 2 * j);
    return GS_OK;
}

static void elastic_interface(const gs_model_view *sys, gs_body_rt *b, double h, double *rec)
{
    elastic *el = b->model;
    int n = 0;
    gs_err e = interface_begin(sys, b, h, rec, &n);
    if (e == GS_OK && n > 0)
        e = el->be->compliance(el, n, el->dofs, rec);
    if (e != GS_OK || (n > 0 && !(rec[0] > 0)))
        rec[0] = NAN;
}

static void elastic_interface_free(const gs_model_view *sys, gs_body_rt *b, double h, double *rec)
{
    int n = 0;
    gs_err e = interface_begin(sys, b, h, rec, &n);
    int nd = sys->n_dof[b->index];
    if (e != GS_OK && nd > 0)
        rec[(size_t)nd * nd] = NAN;
}

static void elastic_compliance(const gs_model_view *sys, gs_body_rt *b, int k, const int *sel, double *Cs)
{
    elastic *el = b->model;
    int n = sys->n_dof[b->index];
    if (k == 0)
        return;
    /* The dofs are still those of interface_free() (the plan has not changed). */
    gs_err e = el->begun ? el->be->compliance_sub(el, n, el->dofs, k, sel, Cs) : GS_ESTATE;
    if (e != GS_OK || !(Cs[0] > 0))
        Cs[0] = NAN;
}

static gs_err elastic_finish(const gs_model_view *sys, gs_body_rt *b, const double *f)
{
    elastic *el = b->model;
    if (!el->begun)
        return GS_ESTATE;
    int n = sys->n_dof[b->index];
    bool any = false;
    for (int k = 0; k < n; k++)
        any |= f[k] != 0.0;
    /* The dofs are still those of interface() (the plan has not changed). */
    if (any)
        GS_TRY(el->be->apply(el, n, el->dofs, f));
    el->begun = false;
    double damped = el->be->damped(el);
    /* Energies on the engine's schedule only (sys->energy_deferred;
     * the engine keeps every step of closure_energy, which books on them). */
    const bool due = !sys->energy_deferred;
    GS_TRY(el->be->end_step(el, due));
    b->D_step = el->be->damped(el) - damped;
    if (due)
        b->ops->energy(sys, b, &b->T, &b->V);
    else
        b->T = b->V = NAN;
    /* The angular momentum (a pass over every elastic unknown) is read only
     * by closure_energy's velocity update (sys->momentum). */
    b->L = sys->momentum ? el->be->angular_momentum(el) : 0.0;
    return GS_OK;
}

static void elastic_spin(gs_body_rt *b, double dw)
{
    elastic *el = b->model;
    if (el->be)
        el->be->spin(el, dw);
}

static void elastic_energy(const gs_model_view *sys, const gs_body_rt *b, double *T, double *V)
{
    (void)sys;
    const elastic *el = b->model;
    if (!el->be) { /* not the owner: the last reported values */
        *T = b->T;
        *V = b->V;
        return;
    }
    el->be->energy(el, T, V);
}

/* Snapshot state: the backend's (full: q then w, ne + 1 each, theta last). */
static size_t elastic_state_size(const gs_body_rt *b)
{
    const elastic *el = b->model;
    /* the same on every rank: the reduced layout from the mesh's candidate rows */
    return el->reduced ? gs_fe_reduced_state_size_for(el->ne, el->mesh->n_boundary) : 2 * (size_t)(el->ne + 1);
}

static void elastic_save(const gs_body_rt *b, double *x)
{
    const elastic *el = b->model;
    el->be->save(el, x);
}

static gs_err elastic_load(gs_body_rt *b, const double *x)
{
    elastic *el = b->model;
    el->be->cancel_step(el);
    el->begun = false;
    b->D_step = 0.0;
    return el->be->load(el, x);
}

static gs_index elastic_field_nodes(const gs_body_rt *b)
{
    const elastic *el = b->model;
    return el->mesh->n_nodes;
}

static void elastic_fields(const gs_body_rt *b, double *u, double *vm)
{
    elastic *el = b->model;
    if (el->be->nodal(el, u) == GS_OK)
        gs_fe_model_stress(el->model, u, NULL, NULL, vm);
}

static const gs_mesh *elastic_mesh(const gs_body_rt *b)
{
    const elastic *el = b->model;
    return el ? el->mesh : NULL;
}

const gs_body_ops gsi_body_elastic = {
    .name = "elastic",
    .init = elastic_init,
    .destroy = elastic_destroy,
    .interface = elastic_interface,
    .interface_free = elastic_interface_free,
    .compliance = elastic_compliance,
    .finish = elastic_finish,
    .energy = elastic_energy,
    .spin = elastic_spin,
    .state_size = elastic_state_size,
    .save = elastic_save,
    .load = elastic_load,
    .field_nodes = elastic_field_nodes,
    .fields = elastic_fields,
    .mesh = elastic_mesh,
};

/* The elastic model of body b, or NULL (another model, or another rank's). */
static const elastic *elastic_of(const gs_body_rt *b)
{
    return b && b->ops == &gsi_body_elastic ? b->model : NULL;
}

bool gs_elastic_reduced_info(const gs_body_rt *b, gs_fe_reduced_info *out)
{
    const elastic *el = elastic_of(b);
    if (!out || !el || !el->red)
        return false;
    gs_fe_reduced_get_info(el->red, out);
    return true;
}

bool gs_elastic_fe_stats(const gs_body_rt *b, gs_fe_stats *out)
{
    const elastic *el = elastic_of(b);
    if (!out || !el || !el->body)
        return false;
    gs_fe_body_get_stats(el->body, out);
    return true;
}
