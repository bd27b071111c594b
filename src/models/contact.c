/* SPDX-License-Identifier: MIT
 * Mesh model `contact`: the tooth contact of METHOD.md sections 3 to 5.
 * At load it prepares the contact search of the two gears (their FE meshes;
 * a rigid gear gets a mesh of its outline, used as geometry only). The
 * search itself runs every step in the plan (src/step/plan.c) and the rows
 * and QP are the contact step's (src/step/contact_step.c). It adds no force and
 * no potential: the constraint reactions do no work. */
#include <stdio.h>
#include <stdlib.h>

#include "contact/contact_mesh.h"
#include "contact/nearfield_dyn.h"
#include "gearsim/models.h"
#include "gearsim/util.h"
#include "mesh_common.h"

static void contact_destroy(gs_gmesh_rt *m)
{
    gsi_contact_mesh *cm = m->contact;
    if (!cm)
        return;
    gs_contact_search_free(&cm->search);
    gsi_nf_table_free(&cm->nf);
    for (int k = 0; k < 2; k++)
        gs_mesh_free(&cm->own[k]);
    free(cm);
    m->contact = NULL;
}

static gs_err contact_init(const gs_model_view *sys, gs_gmesh_rt *m, gs_diag *d)
{
    const gs_scene *sc = sys->scene;
    const gs_scene_mesh *sm = &sc->meshes[m->index];
    char field[64];
    GS_TRY(gsi_mesh_helical_supported(sys, m, "contact", 0, d));
    snprintf(field, sizeof field, "meshes[%d]", m->index);
    gsi_contact_mesh *cm = gs_calloc(1, sizeof *cm);
    if (!cm)
        return GS_ENOMEM;
    m->contact = cm;
    cm->predict = sm->predict != 0;
    cm->friction = sm->friction;
    cm->friction_explicit = sm->friction_explicit != 0;
    for (int k = 0; k < 2; k++) {
        int b = sm->gear[k];
        const gs_scene_body *sb = &sc->bodies[b];
        cm->body[k] = b;
        const gs_body_rt *br = &sys->bodies[b];
        cm->elastic[k] = sb->model == GS_MODEL_ELASTIC;
        if (cm->elastic[k]) {
            cm->mesh[k] = br->ops->mesh(br);
            continue;
        }
        gs_diag md;
        gs_err e = gs_scene_gear_mesh(sb, &cm->own[k], &md);
        if (e != GS_OK)
            return gs_diag_set(d, e, field, "cannot mesh the outline of '%s': %s", sb->name, md.message);
        cm->mesh[k] = cm->own[k];
    }
    if (!cm->elastic[0] && !cm->elastic[1])
        return gs_diag_set(d, GS_ERANGE, field,
                           "contact mesh '%s' joins two rigid gears: make one elastic (or use a "
                           "lumped or kinematic mesh)", sm->name);
    gs_contact_opts o;
    gs_contact_opts_defaults(&o);
    o.passes = sm->one_pass ? GS_CONTACT_ONE_PASS : GS_CONTACT_TWO_PASS;
    gs_diag cd;
    gs_err e = gs_contact_search_new(cm->mesh[0], &sc->bodies[sm->gear[0]].gear, cm->mesh[1],
                                     &sc->bodies[sm->gear[1]].gear, &o, &cm->search, &cd);
    if (e != GS_OK)
        return gs_diag_set(d, e, field, "contact mesh '%s': %s", sm->name, cd.message);
    if (sm->nearfield) {
        if (sc->contact_scheme == GS_CONTACT_SEED)
            return gs_diag_set(d, GS_ERANGE, field,
                               "contact mesh '%s': \"nearfield\" needs numerics.contact \"closure\" or "
                               "\"closure_energy\" (the seed's rows drop the gap)", sm->name);
        gs_diag nd;
        e = gsi_nf_table_build(sc, m->index, &cm->nf, &nd);
        if (e != GS_OK)
            return gs_diag_set(d, e, field, "contact mesh '%s', nearfield: %s", sm->name, nd.message);
    }
    return GS_OK;
}

static double contact_energy(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q)
{
    (void)sys, (void)q;
    return m->nf_energy; /* the near-field springs' (0 without "nearfield") */
}

const gs_gmesh_ops gsi_gmesh_contact = {
    .name = "contact",
    .init = contact_init,
    .n_eq = 0,
    .force = NULL,
    .energy = contact_energy,
    .contact = true,
    .destroy = contact_destroy,
};
