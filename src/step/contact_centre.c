/* SPDX-License-Identifier: MIT
 * The contact step with moving gear centres (docs/explanation/planetary.md,
 * "Contact meshes on moving members"), rank 0.
 *
 * A gear's centre c moves in one of three ways:
 *  - a planet on a rigid pin turns with its carrier: dc = J (c - c_C) dtheta_C
 *    (J: a quarter turn), a term of the carrier's coordinate;
 *  - a gear on a bearing joint, or a planet on a pin bearing, translates:
 *    c = c_0 + X with X = (tcoord, tcoord + 1) in the scene frame, two more
 *    unknowns of the step (the planet's pin bearing couples X to its
 *    carrier through the joint's force, not through the rows);
 *  - otherwise it stays.
 * A contact row depends on the centre through dg/dc (gs_contact_row), so
 * its linearisation gains dg/dc . dX. The translation carries the gear's
 * mass as a rigid body: its block of the step's Hessian is the free
 * mass's 2 m / h^2 (the midpoint step's m (w1 - w0) / h with
 * X1 - X0 = h (w0 + w1) / 2), the free increment h w; the supports act
 * through the joints' discrete-gradient forces, solved with the contact
 * rows like the force meshes'. An elastic gear's body frame translates with
 * X: its nodes' displacements stay relative to the frame, and the inertial
 * coupling of the frame's acceleration with the elastic displacements
 * (the mass moment of the deformation) is left out, the same in the
 * kinetic energy, so the balance stays exact. */
#include "step_internal.h"

/* Row terms of gear body b's centre, dg/dc = dgdc, into G (columns are
 * the coordinates): its translation, or its carrier's turn. */
void gsi_centre_row(const gs_system *sys, int b, const double dgdc[2], double *G)
{
    const gs_body_rt *br = &sys->bodies[b];
    if (br->tcoord >= 0) {
        G[br->tcoord] += dgdc[0];
        G[br->tcoord + 1] += dgdc[1];
        return;
    }
    if (br->carrier < 0)
        return;
    int cc = sys->bodies[br->carrier].coord;
    if (cc < 0)
        return;
    double pc[2], th;
    gs_system_body_pose(sys, b, pc, &th);
    const double *cC = sys->bodies[br->carrier].centre;
    G[cc] += dgdc[0] * -(pc[1] - cC[1]) + dgdc[1] * (pc[0] - cC[0]);
}

double gsi_centre_translation_dot(const gs_system *sys, int b, const double dgdc[2], const double *x)
{
    int tc = sys->bodies[b].tcoord;
    if (tc < 0)
        return 0.0;
    if (x)
        return dgdc[0] * x[tc] + dgdc[1] * x[tc + 1];
    return sys->h_sub * (dgdc[0] * sys->w[tc] + dgdc[1] * sys->w[tc + 1]);
}

void gsi_centre_mass(const gs_system *sys, double *H, double *c, int N)
{
    double h = sys->h_sub;
    for (int i = 0; i < sys->n_bodies; i++) {
        int tc = sys->bodies[i].tcoord;
        if (tc < 0)
            continue;
        double m2 = 2.0 * sys->bodies[i].mass / (h * h);
        for (int k = 0; k < 2; k++) {
            H[(size_t)(tc + k) * (size_t)N + (size_t)(tc + k)] += m2;
            c[tc + k] += m2 * h * sys->w[tc + k];
        }
    }
}
