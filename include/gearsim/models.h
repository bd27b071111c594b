/* SPDX-License-Identifier: MIT
 * gearsim: fidelity levels as implementations of operations tables
 * (METHOD.md section 7, STYLE.md convention 5).
 *
 * A body model (rigid; elastic later) presents its rigid coordinate to the
 * step solver through a condensed interface: per step it returns H and rhs
 * such that its coordinate increment d obeys  H d - rhs = f,  f being the
 * generalised force the meshes and joints apply. For a rigid body
 * H = 2/h^2 I + c/h and rhs = 2/h I w + M(t_mid); an elastic body gives the
 * inverse of its condensed compliance. A mesh model (kinematic, lumped;
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
    /* Build model data for body `index` of the system's scene. */
    gs_err (*init)(gs_system *sys, gs_body_rt *b, gs_diag *d);
    void (*destroy)(gs_body_rt *b);
    /* Condensed interface for the step from t to t+h (owner rank only). */
    void (*interface)(const gs_system *sys, const gs_body_rt *b, double h, double *H, double *rhs);
    /* Kinetic and potential energy of the body's own state (rigid energy uses
     * the system's w; elastic bodies add their internal parts). */
    void (*energy)(const gs_system *sys, const gs_body_rt *b, double *T, double *V);
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
} gs_gmesh_ops;

/* Registered implementations, by name (the scene's `model`). */
const gs_body_ops *gs_body_ops_find(const char *name);
const gs_gmesh_ops *gs_gmesh_ops_find(const char *name);

#endif
