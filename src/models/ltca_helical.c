/* SPDX-License-Identifier: MIT
 * LTCA tables of a helical (or lead-modified, misaligned) mesh
 * (docs/explanation/helical.md "Helical pairs in the ltca rung").
 *
 * The tables are built by the same loads and positions as a spur pair's
 * (ltca.c): the quasi-static analysis of such a mesh is the slice analysis
 * (stiffness_slices.c) on top of the planar analysis of the transverse
 * section, so each row is the loaded static TE of the whole face at one
 * roll position and load, the lead modifications and the misalignment in
 * its gaps and the contact loss along the face (a crowned face carries on
 * part of its width at a light load) in its shape. What this file adds is
 * what tells such tables apart in the cache, and what the rung refuses. */
#include <stdio.h>
#include <string.h>

#include "gearsim/stiffness.h"
#include "gearsim/util.h"
#include "ltca_helical.h"
#include "mesh_common.h"

static int lead_set(const gs_lead_mods *l)
{
    return l->crowning != 0 || l->end_relief != 0 || l->slope != 0;
}

int gsi_ltca_sliced(const gs_scene *sc, int mesh)
{
    const gs_scene_mesh *sm = &sc->meshes[mesh];
    int s = sm->misalign_in != 0 || sm->misalign_out != 0;
    for (int k = 0; k < 2; k++) {
        const gs_scene_body *b = &sc->bodies[sm->gear[k]];
        s |= b->gear.helix_angle > 0 || lead_set(&b->lead);
    }
    return s;
}

int gsi_ltca_key_sliced(const gs_scene *sc, int mesh, double *v)
{
    if (!gsi_ltca_sliced(sc, mesh))
        return 0;
    const gs_scene_mesh *sm = &sc->meshes[mesh];
    int n = 0;
    for (int k = 0; k < 2; k++) {
        const gs_scene_body *b = &sc->bodies[sm->gear[k]];
        const gs_gear_params *g = &b->gear;
        const gs_lead_mods *l = &b->lead;
        double x[] = {g->hand, g->helix_angle, g->normal_module_m, g->normal_pressure_angle, l->crowning,
                      l->end_relief, l->end_relief_length, l->end_relief_parabolic, l->slope};
        for (size_t i = 0; i < sizeof x / sizeof x[0]; i++)
            v[n++] = x[i];
    }
    v[n++] = sm->misalign_in;
    v[n++] = sm->misalign_out;
    /* the slice settings the tables are built with: the analysis's defaults
     * (slices 0: 320; coupling 0: 1.1 m_n) */
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    v[n++] = o.slices;
    v[n++] = o.coupling_mm;
    return n;
}

gs_err gsi_ltca_sliced_check(const gs_model_view *sys, const gs_gmesh_rt *m, gs_diag *d)
{
    const gs_scene_mesh *sm = &sys->scene->meshes[m->index];
    for (int k = 0; k < 2; k++) {
        int bi = sm->gear[k];
        const gs_scene_body *b = &sys->scene->bodies[bi];
        const gs_gear_mods *md = b->mods;
        if (!(b->gear.helix_angle > 0) || !md)
            continue;
        int errs = md->runout_m != 0.0;
        for (int t = 0; t < md->n_pitch; t++)
            errs |= md->pitch_m[t] != 0.0;
        if (errs) { /* their load share would follow the spur wave */
            char field[64];
            snprintf(field, sizeof field, "bodies[%d].%s", bi, md->runout_m != 0.0 ? "runout" : "pitch_errors_um");
            return gs_diag_set(d, GS_ERANGE, field,
                               "an ltca mesh ('%s') on the helical gear '%s' cannot take pitch errors or run-out",
                               sm->name, b->name);
        }
    }
    return GS_OK;
}
