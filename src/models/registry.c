/* SPDX-License-Identifier: MIT
 * Registry of body and mesh models by the names the scene uses. Adding a
 * fidelity level is adding a table here. */
#include <string.h>

#include "gearsim/mesh.h"
#include "gearsim/models.h"

extern const gs_body_ops gsi_body_rigid, gsi_body_elastic;
extern const gs_gmesh_ops gsi_gmesh_kinematic, gsi_gmesh_lumped, gsi_gmesh_contact;

static const gs_body_ops *const body_models[] = {&gsi_body_rigid, &gsi_body_elastic, NULL};
static const gs_gmesh_ops *const mesh_models[] = {&gsi_gmesh_kinematic, &gsi_gmesh_lumped, &gsi_gmesh_contact, NULL};

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
    gs_gear_mesh_opts o;
    gs_gear_mesh_opts_defaults(&o);
    o.flank = sb->mesh.flank;
    o.across = sb->mesh.across;
    o.rim = sb->mesh.rim;
    o.refine = sb->mesh.refine;
    o.grading = sb->mesh.grading;
    return gs_gear_mesh(&sb->gear, &o, out, d);
}
