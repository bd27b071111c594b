/* SPDX-License-Identifier: MIT
 * Mesh model `ltca`: rigid gears joined along the line of action by the
 * mesh potential of the pair's loaded tooth contact analysis
 * (include/gearsim/ltca.h, docs/explanation/ltca.md). The force is the
 * exact discrete gradient of V(delta, phi) between the step's ends, in the
 * deflection and in the mesh phase alike, so the energy balance holds to
 * round-off; tooth errors (pitch tables, run-out) enter the deflection as
 * for the lumped mesh (mesh_common.c). The damper acts over the share of
 * the step either flank spends in contact. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/ltca.h"
#include "gearsim/models.h"
#include "gearsim/util.h"
#include "ltca_helical.h"
#include "mesh_common.h"

typedef struct ltca_rt {
    gs_ltca_table tab;
    double phase0; /* mesh phase c . q at the scene's initial state */
    struct gs_pair_errors pe; /* the pitch errors by the tables' tooth pairs */
} ltca_rt;

static double dot(const double *a, const double *b, int n)
{
    double s = 0;
    for (int i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}

static void ltca_destroy(gs_gmesh_rt *m)
{
    ltca_rt *L = m->contact;
    if (L)
        gs_ltca_table_clear(&L->tab);
    free(L);
    m->contact = NULL;
}

/* The damper of the mesh mode. With material damping on the gears (the
 * elastic models' D = damping_m M + damping_s K), the damping those gears'
 * material gives the mesh mode when its strain energy is in the teeth:
 * c = beta k_t + alpha m_eq, beta and alpha the gears' mean coefficients,
 * k_t the table's mean tangent stiffness at the scene's load. Otherwise (or
 * with the mesh's own damping / damping_ratio given) the lumped rule of
 * gsi_mesh_damping at k_t. */
static double ltca_damping(const gs_model_view *sys, const gs_gmesh_rt *m, double kt)
{
    const gs_scene_mesh *sm = &sys->scene->meshes[m->index];
    if (sm->damping >= 0)
        return sm->damping;
    double inv = 0, beta = 0, alpha = 0; /* inv: 1 / m_eq */
    for (int i = 0; i < sys->n_bodies; i++) {
        const gs_body_rt *b = &sys->bodies[i];
        if (b->coord >= 0 && m->a[b->coord] != 0)
            inv += m->a[b->coord] * m->a[b->coord] / b->inertia_eff;
    }
    for (int k = 0; k < 2; k++) {
        const gs_material *mt = &sys->scene->bodies[sm->gear[k]].material;
        beta += 0.5 * mt->damping_s;
        alpha += 0.5 * mt->damping_m;
    }
    if (sm->damping_ratio < 0 && (beta > 0 || alpha > 0))
        return beta * kt + (inv > 0 ? alpha / inv : 0);
    double zeta = sm->damping_ratio >= 0 ? sm->damping_ratio : 0.05;
    return inv > 0 ? 2 * zeta * sqrt(kt / inv) : 0;
}

/* Pitch errors through the tables' tooth pairs: the analysis at the
 * scene's load says which teeth are in contact at each roll position and
 * the share of the force each pair carries, so a pair's error shifts the
 * TE by its share of it where it is in contact (at the first order in the
 * error: the pairs' load sharing of the analysis). The gears' run-out
 * stays the lumped mesh's (a displacement of every pair alike). Tables
 * without tooth pairs at some position would keep the lumped mesh's
 * windows of the teeth. */
static void pair_errors(const gs_model_view *sys, gs_gmesh_rt *m, ltca_rt *L)
{
    const gs_scene *sc = sys->scene;
    const gs_scene_mesh *sm = &sc->meshes[m->index];
    const gs_ltca_table *t = &L->tab;
    struct gs_pair_errors *pe = &L->pe;
    int any = 0;
    for (int k = 0; k < 2; k++) {
        const gs_scene_body *b = &sc->bodies[sm->gear[k]];
        pe->z[k] = b->gear.teeth;
        pe->kp[k] = (b->gear.kind == GS_GEAR_INTERNAL ? -1.0 : 1.0) * gs_gear_base_radius(&b->gear) /
                    gs_gear_pitch_radius(&b->gear);
        pe->pitch[k] = b->mods && b->mods->n_pitch == b->gear.teeth ? b->mods->pitch_m : NULL;
        any |= pe->pitch[k] != NULL;
        pe->step[k] = gs_ltca_tooth_step(sc, m->index, k);
    }
    for (int j = 0; any && j < t->n; j++) { /* every position must have its pairs */
        double sum = 0;
        for (int r = 0; r < t->np; r++)
            sum += t->pair_tooth[2 * ((size_t)j * t->np + r)] >= 0 ? t->pair_share[(size_t)j * t->np + r] : 0.0;
        any = sum > 0.5;
    }
    if (!any)
        return;
    pe->n = t->n;
    pe->np = t->np;
    pe->tooth = t->pair_tooth;
    pe->share = t->pair_share;
    pe->phase0 = L->phase0;
    pe->n_coords = sys->n_coords;
    m->pair_err = pe;
}

static gs_err ltca_init(const gs_model_view *sys, gs_gmesh_rt *m, gs_diag *d)
{
    const gs_scene_mesh *sm = &sys->scene->meshes[m->index];
    GS_TRY(gsi_mesh_needs_rigid(sys, m, "ltca", d));
    GS_TRY(gsi_ltca_sliced_check(sys, m, d)); /* helical: tables of the slice analysis */
    for (int k = 0; k < 2; k++) {
        const gs_scene_body *b = &sys->scene->bodies[sm->gear[k]];
        if (b->pitch_error_tooth >= 0 && b->pitch_error != 0.0 && (!b->mods || b->mods->n_pitch == 0)) {
            char field[64];
            snprintf(field, sizeof field, "bodies[%d].pitch_error", sm->gear[k]);
            return gs_diag_set(d, GS_ERANGE, field, "an ltca mesh takes pitch errors as the pitch_errors_um table");
        }
    }
    ltca_rt *L = gs_calloc(1, sizeof *L);
    if (!L)
        return GS_ENOMEM;
    m->contact = L; /* freed by ltca_destroy */
    GS_TRY(gs_ltca_tables(sys->scene, m->index, NULL, &L->tab, d));
    /* the bodies' compliance carries the mean load: the scene's (a train's
     * mesh: its static share of it), a knot of every row */
    GS_TRY(gs_ltca_table_dynamic(&L->tab, L->tab.f[L->tab.knot_scene], d));
    L->phase0 = dot(m->c, sys->q, sys->n_coords);
    pair_errors(sys, m, L);
    m->n_table = L->tab.n; /* the time-step check of a wave over the mesh cycle */
    m->k_single = m->k_double = L->tab.k_mean;
    m->damping = ltca_damping(sys, m, L->tab.k_mean);
    return GS_OK;
}

static void ltca_force(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q0, const double *dq, double h,
                       double *g, double *J, double *diss, double *force)
{
    const ltca_rt *L = m->contact;
    int n = sys->n_coords;
    const double *ab = gsi_mesh_grad(sys, m, q0, dq);
    double s0 = gsi_mesh_s(sys, m, q0) - m->s_ref, ds = dot(ab, dq, n);
    double p0 = dot(m->c, q0, n) - L->phase0, dp = dot(m->c, dq, n);
    double gs, gp, jac[4];
    gs_ltca_grad(&L->tab, s0, ds, p0, dp, &gs, &gp, jac);
    /* damping over the share of the step in contact on either flank */
    double b0, f0, b1, f1, dwf, dwb;
    gs_ltca_closing(&L->tab, p0, &b0, &f0);
    gs_ltca_closing(&L->tab, p0 + dp, &b1, &f1);
    double W = gsi_mesh_wet(s0 - f0, s0 + ds - f1, &dwf) + gsi_mesh_wet(b0 - s0, b1 - s0 - ds, &dwb);
    double dW = dwf - dwb;
    double cd = m->damping * W, fd = cd * ds / h;
    for (int i = 0; i < n; i++)
        g[i] += ab[i] * (gs + fd) + m->c[i] * gp;
    double jss = jac[0] + (cd + m->damping * dW * ds) / h;
    gsi_mesh_add_jacobian_c(m, m->c, n, J, jss, jac[1], jac[2], jac[3]);
    gsi_mesh_error_jacobian(m, n, q0, dq, gs + fd, J);
    *diss = fd * ds;
    *force = gs + fd;
}

static double ltca_energy(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q)
{
    const ltca_rt *L = m->contact;
    double s = gsi_mesh_s(sys, m, q) - m->s_ref, p = dot(m->c, q, sys->n_coords) - L->phase0;
    return gs_ltca_energy(&L->tab, s, p);
}

const gs_gmesh_ops gsi_gmesh_ltca = {
    .name = "ltca", .init = ltca_init, .n_eq = 0, .force = ltca_force, .energy = ltca_energy,
    .destroy = ltca_destroy,
};
