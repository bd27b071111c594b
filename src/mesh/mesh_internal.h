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

#endif
