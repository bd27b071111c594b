/* SPDX-License-Identifier: MIT
 * gearsim internal: the parts of the step split over files of src/step. */
#ifndef GEARSIM_STEP_INTERNAL_H
#define GEARSIM_STEP_INTERNAL_H

#include "gearsim/step.h"

/* Rank 0: the step with contact meshes, a QP (src/step/contact_step.c). */
gs_err gsi_contact_solve(gs_system *sys, const double *rec, double *sol);
/* Rank 0, before the solve, from the free part of the records (d0, node
 * displacements): the rows of the step, kept for the solve that follows,
 * and mask (one per plan dof, bodies in order) set where the solve reads
 * that dof's compliance entries. */
gs_err gsi_contact_select(gs_system *sys, const double *rec, int *mask);
/* The discrete-gradient forces g (n_coords) of the meshes that have a force
 * (lumped, compliant, impact, kinematic) over the increment dq, their
 * approximate Jacobian J (n x n, row-major), each one's force along its
 * line of action in force[mesh] (untouched for the others); returns their
 * dissipation in the step. */
double gsi_mesh_forces(const gs_system *sys, const double *dq, double *g, double *J, double *force);
/* Free the contact solve's scratch (sys->solver). */
void gsi_contact_free(gs_system *sys);
/* Free the plan's arrays. */
void gsi_plan_free(gs_step_plan *p, int n_bodies);
/* Allocate the plan for the system's bodies. */
gs_err gsi_plan_new(gs_system *sys);
/* Moving gear centres in the contact step (src/step/contact_centre.c):
 * body b's centre terms of a row with dg/dc = dgdc added to G (columns:
 * coordinates; its translation, or its carrier's turn); the translation's
 * part of dg/dc . dc from x (NULL: the free increment h w); the
 * translations' free-mass blocks 2 m / h^2 into H (N columns) and c. */
void gsi_centre_row(const gs_system *sys, int b, const double dgdc[2], double *G);
double gsi_centre_translation_dot(const gs_system *sys, int b, const double dgdc[2], const double *x);
void gsi_centre_mass(const gs_system *sys, double *H, double *c, int N);
/* Position of mesh node `node` in body i's plan list, -1 if absent. */
int gsi_plan_find(const gs_step_plan *p, int body, gs_index node);

#endif
