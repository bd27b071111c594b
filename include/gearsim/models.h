/* SPDX-License-Identifier: MIT
 * gearsim: fidelity levels as implementations of operations tables
 * (METHOD.md section 7, STYLE.md convention 5).
 *
 * A body model (rigid, elastic) presents its rigid coordinate (and, for
 * contact, a few nodal displacements) to the step solver through a condensed
 * interface: per step it returns the compliance C and free increment d0 such
 * that its interface increments obey d = d0 + C f,  f being the generalised
 * forces the meshes, joints and contacts apply. For a rigid body
 * 1/C = 2/h^2 I + c/h and d0 = C (2/h I w + M(t_mid)); an elastic body gives
 * the entries of the inverse of its step matrix (METHOD.md section 4). A mesh model (kinematic, lumped;
 * impact and contact later) contributes equality rows and/or a potential
 * with its discrete gradient (METHOD.md section 2). The step solver knows
 * only these tables. */
#ifndef GEARSIM_MODELS_H
#define GEARSIM_MODELS_H

#include "gearsim/scene.h"
#include "gearsim/types.h"

typedef struct gs_system gs_system;
typedef struct gs_body_rt gs_body_rt;
typedef struct gs_gmesh_rt gs_gmesh_rt;

typedef struct gs_body_ops {
    const char *name;
    /* Build model data for body `index` of the system's scene (every rank;
     * heavy per-step data such as a factorisation only on the owner). */
    gs_err (*init)(gs_system *sys, gs_body_rt *b, gs_diag *d);
    void (*destroy)(gs_body_rt *b);
    /* Condensed interface for the step from t to t+h (owner rank only;
     * called for held bodies too). The body's interface unknowns are its
     * coordinate (when it has one) and the x, y displacements of the plan's
     * nodes for it (sys->plan, step.h); their increments obey
     * d = d0 + C f,  f the generalised forces of meshes, joints and contact,
     * d0 the free increment, C the compliance (symmetric positive definite).
     * Writes C (n_dof^2, column-major), d0 (n_dof) and the nodes' current
     * displacements (2 n_nodes, body frame) into rec. A failure is reported
     * as a non-finite C[0]. */
    void (*interface)(const gs_system *sys, gs_body_rt *b, double h, double *rec);
    /* The same record in two phases (both NULL: interface() only). The
     * step solver reads only the compliance entries of the unknowns its
     * rows touch, known once the free increments and node positions are
     * (gs_step_select). interface_free: as interface() without C (rec's C
     * block left untouched), a failure reported as a non-finite d0[0].
     * compliance: then the k x k sub-block C[sel, sel] (column-major) of the
     * plan dofs sel[0..k) (ascending), bit for bit the entries interface()
     * writes; a failure as a non-finite Cs[0]. */
    void (*interface_free)(const gs_system *sys, gs_body_rt *b, double h, double *rec);
    void (*compliance)(const gs_system *sys, gs_body_rt *b, int k, const int *sel, double *Cs);
    /* Owner rank, after the solve: complete the body's own step under the
     * interface forces f (n_dof, same order). NULL: nothing to do (a rigid
     * body's state is the system's q, w). */
    gs_err (*finish)(const gs_system *sys, gs_body_rt *b, const double *f);
    /* Kinetic and potential energy of the body's own state (owner rank;
     * rigid bodies use the system's w, which every rank holds). */
    void (*energy)(const gs_system *sys, const gs_body_rt *b, double *T, double *V);
    /* Add dw to the rotation speed of the body's own state on its owner
     * (a rigid spin increment: the elastic velocities relative to the
     * body's frame are kept; nothing on other ranks). The caller updates
     * b->T and b->L. NULL: no own state (its speed is the system's w). */
    void (*spin)(gs_body_rt *b, double dw);
    /* Internal state beyond the rigid coordinate, for snapshots: its size in
     * doubles (every rank, same value), save and load (owner rank). NULL
     * when the model has none. */
    size_t (*state_size)(const gs_body_rt *b);
    void (*save)(const gs_body_rt *b, double *x);
    gs_err (*load)(gs_body_rt *b, const double *x);
    /* Field snapshot (owner rank): nodal displacements u (2 n, body frame)
     * and von Mises stress vm (n) on the body's mesh; n = field_nodes().
     * NULL when the model has no fields. */
    gs_index (*field_nodes)(const gs_body_rt *b);
    void (*fields)(const gs_body_rt *b, double *u, double *vm);
    /* The body's mesh (every rank), NULL for models without one. */
    const struct gs_mesh *(*mesh)(const gs_body_rt *b);
} gs_body_ops;

typedef struct gs_gmesh_ops {
    const char *name;
    gs_err (*init)(gs_system *sys, gs_gmesh_rt *m, gs_diag *d);
    /* Equality rows on dq (kinematic): number of rows. */
    int n_eq;
    /* Add the discrete-gradient force and damping between q0 and q0+dq to
     * g (n_coords) and an approximate Jacobian to J (n x n row-major).
     * Returns the mesh's dissipated energy of the step in *diss and its
     * force along the line of action in *force. */
    void (*force)(const gs_system *sys, const gs_gmesh_rt *m, const double *q0, const double *dq,
                  double h, double *g, double *J, double *diss, double *force);
    double (*energy)(const gs_system *sys, const gs_gmesh_rt *m, const double *q);
    /* Contact meshes: no force or potential; the step adds their
     * linearised non-penetration rows and solves a QP (src/step/contact_step.c).
     * destroy frees m->contact; may be NULL. */
    bool contact;
    void (*destroy)(gs_gmesh_rt *m);
    /* Optional, every rank, after the step updated q and w: velocity jumps
     * (impacts of rigid gears). May change sys->w of rigid coordinates;
     * returns the energy it dissipated in the step (>= 0, J), booked in the
     * balance. Must be deterministic (it runs on every rank alike). */
    double (*after_step)(gs_system *sys, gs_gmesh_rt *m);
} gs_gmesh_ops;

/* A compliant support (joint) with a potential and a damper on rigid
 * coordinates (docs/explanation/modal.md): the `bearing` joint holds a body's centre
 * displacement (x, y) with an isotropic radial spring and damper and its
 * rotation with a torsional one. Its force is the discrete gradient of its
 * potential between q0 and q0 + dq (exact: V(q1) - V(q0) = g . dq) plus the
 * damper's, whose work it returns in *diss. */
typedef struct gs_joint_rt gs_joint_rt;
typedef struct gs_joint_ops {
    const char *name;
    void (*force)(const gs_system *sys, const gs_joint_rt *j, const double *q0, const double *dq, double h,
                  double *g, double *J, double *diss);
    double (*energy)(const gs_system *sys, const gs_joint_rt *j, const double *q);
} gs_joint_ops;
struct gs_joint_rt {
    int body;
    const gs_joint_ops *ops;
    int coord[3];            /* x, y, rotation coordinates (-1: absent) */
    double k[3], c[3];       /* stiffness and damping on each */
    double q_ref[3];         /* where each spring is relaxed */
    /* `pin_bearing` (a planet on its carrier pin): coord[0..1] the planet's
     * centre displacement X_p (inertial), carrier its rotation coordinate,
     * carrier_t its centre displacement X_C (-1: none), pin0 the pin's offset
     * from the carrier centre at carrier angle 0 and d0 = R(theta_C0) pin0;
     * the spring stretch is e = X_p - X_C + d0 - R(theta_C) pin0. */
    int carrier, carrier_t;
    double pin0[2], d0[2];
};
const gs_joint_ops *gs_joint_ops_find(const char *name);

/* The FE mesh of a scene gear at its scene mesh density (elastic bodies;
 * the outline of a rigid gear in a contact mesh). d->message says why it
 * failed; the caller names the field. */
struct gs_mesh;
gs_err gs_scene_gear_mesh(const gs_scene_body *sb, struct gs_mesh **out, gs_diag *d);
/* The same with `refine` uniform refinements instead of the scene's (< 0:
 * the scene's). Profile modifications, pitch errors and run-out of the body
 * (sb->mods) are applied to the mesh (gs_gear_mods_apply_mesh). */
gs_err gs_scene_gear_mesh_refined(const gs_scene_body *sb, int refine, struct gs_mesh **out,
                                  gs_diag *d);
/* The mesh of the same gear without its modifications and tooth errors (the
 * perfect involute gear; same topology and numbering as the modified one). */
gs_err gs_scene_gear_mesh_perfect(const gs_scene_body *sb, int refine, struct gs_mesh **out,
                                  gs_diag *d);

/* The reduced elastic body's figures (gs_fe_reduced_info: modes, cached
 * residual columns and their CPU seconds, the static rule's loss) of body
 * b: false when b is not a reduced elastic body or lives on another rank. */
struct gs_fe_reduced_info;
bool gs_elastic_reduced_info(const gs_body_rt *b, struct gs_fe_reduced_info *out);

/* The full elastic body's counters (gs_fe_stats: solves, column cache,
 * group solves) of body b: false when b is not a full elastic body or
 * lives on another rank. */
struct gs_fe_stats;
bool gs_elastic_fe_stats(const gs_body_rt *b, struct gs_fe_stats *out);

/* Registered implementations, by name (the scene's `model`). */
const gs_body_ops *gs_body_ops_find(const char *name);
const gs_gmesh_ops *gs_gmesh_ops_find(const char *name);

#endif
