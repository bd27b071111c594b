/* SPDX-License-Identifier: MIT
 * Registry of body and mesh models by the names the scene uses. Adding a
 * fidelity level is adding a table here. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/mesh.h"
#include "gearsim/modification.h"
#include "gearsim/models.h"
#include "gearsim/util.h"

extern const gs_body_ops gsi_body_rigid, gsi_body_elastic;
extern const gs_gmesh_ops gsi_gmesh_kinematic, gsi_gmesh_lumped, gsi_gmesh_contact, gsi_gmesh_impact,
    gsi_gmesh_compliant, gsi_gmesh_ltca;

static const gs_body_ops *const body_models[] = {&gsi_body_rigid, &gsi_body_elastic, NULL};
static const gs_gmesh_ops *const mesh_models[] = {&gsi_gmesh_kinematic, &gsi_gmesh_lumped, &gsi_gmesh_contact,
                                                   &gsi_gmesh_impact, &gsi_gmesh_compliant, &gsi_gmesh_ltca,
                                                   NULL};

extern const gs_joint_ops gsi_joint_bearing, gsi_joint_pin_bearing;
static const gs_joint_ops *const joint_models[] = {&gsi_joint_bearing, &gsi_joint_pin_bearing, NULL};

const gs_joint_ops *gs_joint_ops_find(const char *name)
{
    for (int i = 0; joint_models[i]; i++)
        if (strcmp(joint_models[i]->name, name) == 0)
            return joint_models[i];
    return NULL;
}

const gs_body_ops *gs_body_ops_find(const char *name)
{
    for (int i = 0; body_models[i]; i++)
        if (strcmp(body_models[i]->name, name) == 0)
            return body_models[i];
    return NULL;
}

const gs_gmesh_ops *gs_gmesh_ops_find(const char *name)
{
    for (int i = 0; mesh_models[i]; i++)
        if (strcmp(mesh_models[i]->name, name) == 0)
            return mesh_models[i];
    return NULL;
}

gs_err gs_scene_gear_mesh(const gs_scene_body *sb, gs_mesh **out, gs_diag *d)
{
    if (sb->mesh.fine_teeth > 0) {
        /* every tooth comes round in a dynamic model: a mesh fine on a few
         * teeth only is for the quasi-static analysis */
        *out = NULL;
        return gs_diag_set(d, GS_EINVAL, "mesh.fine_teeth",
                           "mesh.fine_teeth (local refinement) is for the quasi-static stiffness "
                           "analysis only: in a dynamic model every tooth comes round; use refine");
    }
    return gs_scene_gear_mesh_refined(sb, -1, out, d);
}

gs_err gs_scene_gear_mesh_perfect(const gs_scene_body *sb, int refine, gs_mesh **out, gs_diag *d)
{
    gs_gear_mesh_opts o;
    gs_gear_mesh_opts_defaults(&o);
    o.flank = sb->mesh.flank;
    o.across = sb->mesh.across;
    o.rim = sb->mesh.rim;
    o.refine = refine >= 0 ? refine : sb->mesh.refine;
    o.grading = sb->mesh.grading;
    o.order = sb->mesh.order;
    o.fine_teeth = sb->mesh.fine_teeth;
    o.fine_refine = sb->mesh.fine_refine;
    o.fine_centre = sb->mesh.fine_centre;
    return gs_gear_mesh(&sb->gear, &o, out, d);
}

gs_err gs_scene_gear_mesh_refined(const gs_scene_body *sb, int refine, gs_mesh **out, gs_diag *d)
{
    GS_TRY(gs_scene_gear_mesh_perfect(sb, refine, out, d));
    /* The single pitch_error of a body (the scene folds it into mods; a
     * body filled by hand may carry it alone). */
    const gs_gear_mods *mods = sb->mods;
    gs_gear_mods one;
    double *table = NULL;
    if (sb->pitch_error_tooth >= 0 && sb->pitch_error != 0.0 && sb->pitch_error_tooth < sb->gear.teeth &&
        (!mods || mods->n_pitch == 0)) {
        table = gs_calloc((size_t)sb->gear.teeth, sizeof *table);
        if (!table) {
            gs_mesh_free(out);
            return GS_ENOMEM;
        }
        if (mods)
            one = *mods;
        else
            memset(&one, 0, sizeof one);
        table[sb->pitch_error_tooth] = sb->pitch_error;
        one.n_pitch = sb->gear.teeth;
        one.pitch_m = table;
        mods = &one;
    }
    if (gs_gear_mods_any(mods)) {
        /* Profile modifications, pitch errors and run-out
         * (include/gearsim/modification.h). */
        gs_gear_geom g;
        gs_err e = gs_gear_geometry(&sb->gear, &g, d);
        if (e == GS_OK)
            e = gs_gear_mods_apply_mesh(&g, mods, *out, d);
        free(table);
        table = NULL;
        if (e != GS_OK) {
            gs_mesh_free(out);
            return e;
        }
    }
    free(table);
    return GS_OK;
}
