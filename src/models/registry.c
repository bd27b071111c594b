/* SPDX-License-Identifier: MIT
 * Registry of body and mesh models by the names the scene uses. Adding a
 * fidelity level is adding a table here. */
#include <math.h>
#include <string.h>

#include "gearsim/mesh.h"
#include "gearsim/models.h"

extern const gs_body_ops gsi_body_rigid, gsi_body_elastic;
extern const gs_gmesh_ops gsi_gmesh_kinematic, gsi_gmesh_lumped, gsi_gmesh_contact, gsi_gmesh_impact,
    gsi_gmesh_compliant;

static const gs_body_ops *const body_models[] = {&gsi_body_rigid, &gsi_body_elastic, NULL};
static const gs_gmesh_ops *const mesh_models[] = {&gsi_gmesh_kinematic, &gsi_gmesh_lumped, &gsi_gmesh_contact,
                                                   &gsi_gmesh_impact, &gsi_gmesh_compliant, NULL};

extern const gs_joint_ops gsi_joint_bearing;
static const gs_joint_ops *const joint_models[] = {&gsi_joint_bearing, NULL};

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
    gs_gear_mesh_opts o;
    gs_gear_mesh_opts_defaults(&o);
    o.flank = sb->mesh.flank;
    o.across = sb->mesh.across;
    o.rim = sb->mesh.rim;
    o.refine = sb->mesh.refine;
    o.grading = sb->mesh.grading;
    GS_TRY(gs_gear_mesh(&sb->gear, &o, out, d));
    if (sb->pitch_error_tooth >= 0 && sb->pitch_error != 0.0) {
        /* A pitch error on one tooth: the tooth turned along the pitch
         * circle by e / r. The rotation is full from half-way between root
         * and pitch circles outwards and fades to nothing at the root
         * circle, so the elements there take up the step (micrometres
         * against millimetre elements); flank nodes above stay on the
         * (turned) involute. */
        gs_mesh *m = *out;
        const gs_gear_params *g = &sb->gear;
        double r = gs_gear_pitch_radius(g), rr = gs_gear_root_radius(g);
        double span = 0.5 * fabs(r - rr), dphi = sb->pitch_error / r;
        double c0 = 2.0 * GS_PI * sb->pitch_error_tooth / g->teeth, half = GS_PI / g->teeth;
        bool internal = g->kind == GS_GEAR_INTERNAL;
        for (gs_index i = 0; i < m->n_nodes; i++) {
            double x = m->xy[2 * i], y = m->xy[2 * i + 1], rad = hypot(x, y);
            double a = remainder(atan2(y, x) - c0, 2.0 * GS_PI);
            if (fabs(a) > half)
                continue;
            /* depth into the tooth from the root circle (the ring's root is
             * outside its pitch circle), 0 at the root, 1 half-way to pitch */
            double w = (internal ? rr - rad : rad - rr) / span;
            w = w < 0 ? 0 : (w > 1 ? 1 : w);
            double t = dphi * w, ct = cos(t), st = sin(t);
            m->xy[2 * i] = ct * x - st * y;
            m->xy[2 * i + 1] = st * x + ct * y;
        }
    }
    return GS_OK;
}
