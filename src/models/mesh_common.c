/* SPDX-License-Identifier: MIT
 * Pieces shared by the mesh models with a force (mesh_common.h). */
#include <math.h>
#include <stdio.h>

#include "mesh_common.h"

gs_err gsi_mesh_needs_rigid(const gs_system *sys, const gs_gmesh_rt *m, const char *kind, gs_diag *d)
{
    const gs_scene *sc = sys->scene;
    const gs_scene_mesh *sm = &sc->meshes[m->index];
    for (int k = 0; k < 2; k++) {
        const gs_scene_body *b = &sc->bodies[sm->gear[k]];
        if (b->model == GS_MODEL_ELASTIC) {
            char field[64];
            snprintf(field, sizeof field, "meshes[%d].gears", m->index);
            return gs_diag_set(d, GS_ERANGE, field,
                               "%s mesh '%s' needs rigid gears: '%s' is elastic (use a contact "
                               "mesh for elastic teeth)", kind, sm->name, b->name);
        }
    }
    return GS_OK;
}

gs_err gsi_mesh_mods_supported(const gs_system *sys, const gs_gmesh_rt *m, const char *kind, int profile,
                               int errors, gs_diag *d)
{
    const gs_scene *sc = sys->scene;
    const gs_scene_mesh *sm = &sc->meshes[m->index];
    for (int k = 0; k < 2; k++) {
        int bi = sm->gear[k];
        const gs_scene_body *b = &sc->bodies[bi];
        const gs_gear_mods *md = b->mods;
        char field[64];
        if (!profile && gs_gear_mods_has_profile(md)) {
            snprintf(field, sizeof field, "bodies[%d].modification", bi);
            return gs_diag_set(d, GS_ERANGE, field,
                               "a %s mesh ('%s') cannot represent the profile modifications of '%s': use a "
                               "contact, compliant or calibrated lumped mesh", kind, sm->name, b->name);
        }
        int errs = (b->pitch_error_tooth >= 0 && b->pitch_error != 0.0) || (md && md->runout_m != 0.0);
        for (int t = 0; md && t < md->n_pitch; t++)
            errs |= md->pitch_m[t] != 0.0;
        if (!errors && errs) {
            snprintf(field, sizeof field, "bodies[%d].%s", bi,
                     md && md->runout_m != 0.0 ? "runout" : "pitch_errors_um");
            return gs_diag_set(d, GS_ERANGE, field,
                               "a %s mesh ('%s') cannot represent the pitch errors or run-out of '%s': use a "
                               "contact mesh", kind, sm->name, b->name);
        }
    }
    return GS_OK;
}

double gsi_mesh_damping(const gs_system *sys, const gs_gmesh_rt *m, double k_mean)
{
    const gs_scene_mesh *sm = &sys->scene->meshes[m->index];
    if (sm->damping >= 0)
        return sm->damping;
    double inv = 0;
    for (int i = 0; i < sys->n_bodies; i++) {
        const gs_body_rt *b = &sys->bodies[i];
        if (b->coord >= 0 && m->a[b->coord] != 0)
            inv += m->a[b->coord] * m->a[b->coord] / b->inertia_eff;
    }
    return inv > 0 ? 2 * sm->damping_ratio * sqrt(k_mean / inv) : 0;
}

void gsi_mesh_add_jacobian(const gs_gmesh_rt *m, int n, double *J, double jss, double jsp, double jps, double jpp)
{
    for (int i = 0; i < n; i++) {
        if (m->a[i] == 0.0 && m->c[i] == 0.0)
            continue;
        for (int j = 0; j < n; j++)
            J[i * n + j] += m->a[i] * (jss * m->a[j] + jsp * m->c[j]) + m->c[i] * (jps * m->a[j] + jpp * m->c[j]);
    }
}
