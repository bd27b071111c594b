/* SPDX-License-Identifier: MIT
 * Library-internal pieces shared by the mesh models with a force along the
 * line of action (src/models/meshes.c, compliant_mesh.c, impact_mesh.c) and
 * the joints (joints.c). */
#ifndef GEARSIM_MODELS_MESH_COMMON_H
#define GEARSIM_MODELS_MESH_COMMON_H

#include <math.h>

#include "gearsim/modification.h"
#include "gearsim/models.h"

/* Refuse a mesh of model `kind` whose gears are not both rigid, naming
 * meshes[i].gears. */
gs_err gsi_mesh_needs_rigid(const gs_model_view *sys, const gs_gmesh_rt *m, const char *kind, gs_diag *d);

/* Refuse modifications a mesh model of `kind` cannot represent, naming
 * bodies[i].modification (profile) or bodies[i].pitch_errors_um / runout
 * (tooth errors): `profile` and `errors` say what the model can carry. */
gs_err gsi_mesh_mods_supported(const gs_model_view *sys, const gs_gmesh_rt *m, const char *kind, int profile,
                               int errors, gs_diag *d);

/* Helical pairs and lead data in a planar mesh model of `kind`
 * (docs/explanation/helical.md): `helical` says whether the model takes a
 * helical pair in its transverse plane (else the error names
 * bodies[i].helix_angle_deg); lead modifications (bodies[i].lead) and
 * misalignment (meshes[i].misalignment) belong to the slice analysis and
 * are refused by every planar model. */
gs_err gsi_mesh_helical_supported(const gs_model_view *sys, const gs_gmesh_rt *m, const char *kind, int helical,
                                  gs_diag *d);

/* The mesh's damper coefficient (N s/m): the scene's `damping`, or from its
 * `damping_ratio` zeta at the mesh mode of mean stiffness k_mean:
 * c = 2 zeta sqrt(k_mean m_eq), m_eq = 1 / sum a_i^2 / I_i over the
 * coordinates the mesh moves. */
double gsi_mesh_damping(const gs_model_view *sys, const gs_gmesh_rt *m, double k_mean);
/* Fraction of the step segment [x0, x1] on which x > 0 (the share of a step
 * a flank spends in contact, continuous in the step's end) and its
 * derivative in x1. */
double gsi_mesh_wet(double x0, double x1, double *dw1);
/* The damping coefficient of a mesh whose line-of-action coordinate moves
 * from x0 by dx past a dead zone |x| <= hb: m->damping while in contact at
 * the step's midpoint; in scenes with sys->smooth_contact (bearings, pin
 * errors) m->damping times the share of the step either flank spends in
 * contact (gsi_mesh_wet on both), continuous in the step's end, with dW its
 * derivative in the end (0 otherwise). */
double gsi_mesh_contact_damping(const gs_model_view *sys, const gs_gmesh_rt *m, double x0, double dx, double hb,
                                double *dW);

/* 2 sin(t / 2) / t, its series near 0: (R(th + t) - R(th)) v = t times this
 * times R(th + t / 2) J v for a rotation R (J: quarter turn), the exact
 * discrete gradient of a rotating direction over a step (mesh_common.c,
 * joints.c). */
static inline double gsi_half_sinc(double t)
{
    return fabs(t) > 1e-6 ? 2.0 * sin(0.5 * t) / t : 1.0 - t * t / 24.0;
}

/* Add to J (n x n, row-major) the Jacobian of a force law in the line-of-
 * action coordinate s = a.q and the phase p = c.q: the derivatives of the
 * s-force (jss by s, jsp by p) and of the p-force (jps, jpp). */
void gsi_mesh_add_jacobian(const gs_gmesh_rt *m, int n, double *J, double jss, double jsp, double jps, double jpp);
/* The same with the step's discrete gradient c of the phase in place of m->c
 * (inline: a tenth of the lumped planetary's step as a call,
 * tests/bench/bench_lumped.c). */
static inline void gsi_mesh_add_jacobian_c(const gs_gmesh_rt *m, const double *restrict c, int n,
                                           double *restrict J, double jss, double jsp, double jps, double jpp)
{
    const double *restrict a = m->n_tr || m->n_err ? m->abar : m->a; /* the step's discrete gradient of s */
    for (int i = 0; i < n; i++) {
        if (a[i] == 0.0 && c[i] == 0.0)
            continue;
        for (int j = 0; j < n; j++)
            J[i * n + j] += a[i] * (jss * a[j] + jsp * c[j]) + c[i] * (jps * a[j] + jpp * c[j]);
    }
}

/* Line-of-action displacement s(q) = a . q plus the translations (step.h,
 * gs_gmesh_rt.n_tr) and the tooth errors (gs_gmesh_rt.n_err). */
double gsi_mesh_s(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q);
/* The tooth errors' part of s (lumped meshes, gs_gmesh_rt.n_err): the
 * pitch errors of the teeth in contact, weighted by their load share, times
 * sigma r_b / r, plus each run-out offset along the line of action. */
double gsi_mesh_error(const gs_gmesh_rt *m, const double *q);
/* Add to J the part of a force f along the line of action that comes from
 * the step's discrete gradient of the tooth errors moving with dq. */
void gsi_mesh_error_jacobian(const gs_gmesh_rt *m, int n, const double *q0, const double *dq, double f, double *J);
/* The run-out part R(q) of the tooth errors (the gears' centre offsets
 * along the line of action; lumped meshes modulate their mesh phase with
 * it, meshes.c), whether there is one, the addition of scale times its
 * exact discrete gradient over the step to v, and the Jacobian of a
 * phase force f through that gradient. */
bool gsi_mesh_has_runout(const gs_gmesh_rt *m);
double gsi_mesh_runout(const gs_gmesh_rt *m, const double *q);
void gsi_mesh_runout_grad(const gs_gmesh_rt *m, const double *q0, const double *dq, double scale, double *v);
void gsi_mesh_runout_jacobian(const gs_gmesh_rt *m, int n, const double *q0, const double *dq, double f, double *J);
/* Its discrete gradient over the step from q0 by dq: a vector abar with
 * abar . dq = s(q0 + dq) - s(q0) exactly (m->a itself when nothing
 * translates; else written into m->abar). */
const double *gsi_mesh_grad(const gs_model_view *sys, const gs_gmesh_rt *m, const double *q0, const double *dq);

/* The scene sc without the tooth errors (pitch tables, run-out) of mesh
 * `mesh`'s gears, for the quasi-static analyses the lumped meshes are
 * built from (the meshes add the errors along the line of action
 * themselves): *clean shares sc's data but for its bodies, a copy in
 * *bodies (to free) whose two gears point at mods[0..1]. */
gs_err gsi_mesh_clean_scene(const gs_scene *sc, int mesh, gs_scene *clean, gs_scene_body **bodies,
                            gs_gear_mods mods[2]);

#endif
