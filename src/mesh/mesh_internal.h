/* SPDX-License-Identifier: MIT
 * gearsim mesh module, library-internal. */
#ifndef GEARSIM_MESH_INTERNAL_H
#define GEARSIM_MESH_INTERNAL_H

#include "gearsim/geometry.h"
#include "gearsim/mesh.h"

/* Add the mid-side nodes of quadratic triangles to linear mesh m (see
 * gs_mesh.mid). With g (the gear the mesh belongs to, same module and
 * frame) the mid-side nodes of boundary edges go onto the exact outline;
 * without, onto the chords. Fails with GS_EGEOMETRY when an element's
 * Jacobian would not stay positive, GS_ENOMEM; m is unchanged on failure. */
gs_err gsi_mesh_quadratic(gs_mesh *m, const gs_gear_geom *g);

/* Shape functions of the 6-node triangle at area coordinates (l1, l2,
 * l3 = 1 - l1 - l2), Triangle_6 node order (corners at l1, l2, l3, then
 * mid-side nodes of edges 0-1, 1-2, 2-0): N = l1(2l1-1), l2(2l2-1),
 * l3(2l3-1), 4 l1 l2, 4 l2 l3, 4 l3 l1, and their derivatives d1 = dN/dl1,
 * d2 = dN/dl2 with l3 eliminated. Any output may be NULL. */
void gsi_t6_shape(double l1, double l2, double N[6], double d1[6], double d2[6]);

/* Jacobian determinant of a 6-node triangle (node coordinates x, y) at
 * (l1, l2), and the Cartesian derivatives of N when dNx, dNy are given. */
double gsi_t6_jacobian(const double *x, const double *y, double l1, double l2, double N[6],
                       double dNx[6], double dNy[6]);

#endif
