/* SPDX-License-Identifier: MIT
 * gearsim internal: implicit Coulomb friction on the flanks of contact
 * meshes (src/step/contact_friction.c), for the contact step
 * (src/step/contact_step.c). Not part of the public API. */
#ifndef GEARSIM_CONTACT_FRICTION_H
#define GEARSIM_CONTACT_FRICTION_H

#include "contact/contact_mesh.h"
#include "gearsim/qp.h"
#include "step_internal.h"

/* Workspace of the frictional solve of one step: the tangent rows of the
 * contact rows of meshes with implicit friction, and the last solution's
 * friction forces. Owned by the contact step's solver. */
typedef struct gsi_friction {
    int N;          /* unknowns of the step */
    int n_rows;     /* contact rows of the step */
    int n_fric;     /* of them, rows with implicit friction */
    int *row;       /* [n_fric] the contact row of each friction row */
    int *mesh;      /* [n_fric] its mesh */
    double *T;      /* [n_fric * N] tangent rows: T x is the slip of the slave over the master */
    double *mu;     /* [n_fric] mu |dg/dx_s|: the bound on the friction force per unit multiplier */
    double *beta;   /* [n_rows] friction force on the slave along t = (-n_y, n_x), n the
                     * slave's gap gradient direction (implicit: the last solve's; explicit:
                     * the force put on the row) */
    size_t cap_row, cap_mesh, cap_T, cap_mu, cap_beta;
    /* scratch of the solve */
    double *L, *x0, *Z, *Y, *S, *A, *q, *z, *w, *r, *t;
    size_t cap_L, cap_x0, cap_Z, cap_Y, cap_S, cap_A, cap_q, cap_z, cap_w, cap_r, cap_t;
    int pivots;     /* Lemke pivots of the last solve */
} gsi_friction;

/* Free the workspace and its arrays; safe on NULL, sets *f = NULL. */
void gsi_friction_free(gsi_friction **f);

/* True when some contact mesh of the system has friction (mu > 0), with
 * implicit only those with friction_scheme "implicit". */
bool gsi_friction_any(const gs_system *sys, bool implicit);

/* Start the rows of a pass of the step: N unknowns, n_rows contact rows,
 * no friction row yet, every beta 0. Allocates *f when NULL. */
gs_err gsi_friction_begin(gsi_friction **f, int N, int n_rows);

/* Contact row `row` of mesh `mesh` (evaluated as r, unknown maps unk and
 * base of the step): on a mesh with implicit friction, its tangent row. */
gs_err gsi_friction_add(gsi_friction *f, const gs_system *sys, int row, int mesh, const gs_contact_row *r,
                        const int *unk, const size_t *base);

/* The step's problem p (the QP of the contact step: H, c, E x = e,
 * G x >= g) with Coulomb friction on the friction rows, as the LCP of
 * normal multipliers, friction forces along +t and -t and slip magnitudes
 * (Stewart and Trinkle's, in the step's displacements), solved by Lemke's
 * method (gs_lcp_lemke). Writes res->x, lambda_eq, lambda_in, iterations
 * (Lemke's pivots) and f->beta. Errors: GS_ESINGULAR (H not positive
 * definite), GS_ENOMEM, those of gs_lcp_lemke. */
gs_err gsi_friction_solve(gsi_friction *f, const gs_qp_problem *p, gs_qp_result *res);

/* Add the last solve's friction forces T^T beta, per mesh, to ffm
 * (n_meshes blocks of N). */
void gsi_friction_forces(const gsi_friction *f, double *ffm);

/* Generalised forces (into fm, N unknowns) of a force F (scene frame) at x
 * on gear k of contact mesh cm, at mesh node `node` (-1: none): the moment
 * on its rotation and on its carrier's, and R^T F on the node's displacement
 * unknowns when the node is one (src/step/contact_step.c). */
void gsi_contact_point_force(const gs_system *sys, const gsi_contact_mesh *cm, int k, gs_index node,
                             const double x[2], const double F[2], const int *unk, const size_t *base,
                             double *fm);

#endif
