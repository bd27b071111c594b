/* SPDX-License-Identifier: MIT
 * gearsim: gear meshes to and from HDF5, with an XDMF 3 file beside so that
 * ParaView opens them (docs/explanation/geometry.md, "HDF5 layout").
 *
 * Layout of a mesh file (all lengths in metres, angles in radians):
 *
 *   /                      attrs: format = "gearsim-mesh", version = 1
 *   /gears                 attrs: count (int), names (newline-separated, in order)
 *   /gears/<name>/         attrs: index (int, order in the file), kind ("external" |
 *                          "internal"), teeth, module_m, pressure_angle_rad,
 *                          addendum, dedendum, fillet, profile_shift, thinning_m,
 *                          face_width_m, hub_radius_m, pitch_radius_m, base_radius_m,
 *                          tip_radius_m, root_radius_m, form_radius_m (gear ones only
 *                          when the parameters were given), centre_m (double[2]),
 *                          rotation_rad (double)
 *     nodes        (n_nodes, 2) float64  body frame
 *     nodes_placed (n_nodes, 2) float64  scene frame: centre + R(rotation) nodes
 *     triangles    (n_tris, 3)  int64    counter-clockwise, 0-based
 *     fixed        (n_fixed)    int64    nodes on the rigid-core interface
 *     node_tag     (n_nodes)    int8     gs_node_tag
 *     boundary     (n_boundary) int64    toothed boundary loop (gear meshes)
 *     flank_ptr    (2 z + 1)    int64    flank tables (gear meshes), see mesh.h
 *     flank_nodes  (...)        int64
 *
 * The XDMF file has one spatial collection with a grid per gear (Topology
 * Triangle, Geometry XY from nodes_placed, node attribute node_tag).
 *
 * Not collective: one process writes, with HDF5's default (sec2) driver. */
#ifndef GEARSIM_MESH_IO_H
#define GEARSIM_MESH_IO_H

#include "gearsim/geometry.h"
#include "gearsim/mesh.h"
#include "gearsim/types.h"

typedef struct gs_mesh_io_gear {
    const char *name;             /* group name: unique, non-empty, no '/' or '.' alone */
    const gs_mesh *mesh;          /* borrowed */
    const gs_gear_params *params; /* borrowed; may be NULL (no gear attributes) */
    double centre[2];             /* placement in the scene frame, m */
    double rotation;              /* rad, counter-clockwise */
} gs_mesh_io_gear;

/* Write n meshes to h5_path (created or truncated) and the XDMF description
 * to xmf_path (NULL: h5_path with its extension replaced by ".xmf"). The
 * XDMF refers to the HDF5 file by its base name, so keep the two side by
 * side. Errors: GS_EINVAL (field "gears[i].name") for a bad or repeated
 * name, GS_EIO (field "path") when a file cannot be written. */
gs_err gs_mesh_io_write(const char *h5_path, const char *xmf_path, const gs_mesh_io_gear *gears,
                        int n, gs_diag *d);

/* Read gear `name` back: the mesh in the body frame (owned by the caller,
 * free with gs_mesh_free) and its placement (either pointer may be NULL).
 * Errors: GS_EIO (field "path"), GS_ENOTFOUND (field "name"). */
gs_err gs_mesh_io_read(const char *h5_path, const char *name, gs_mesh **out, double centre[2],
                       double *rotation, gs_diag *d);

/* The default XDMF path for h5_path into buf (len bytes). GS_EINVAL if it
 * does not fit. */
gs_err gs_mesh_io_xmf_path(const char *h5_path, char *buf, size_t len);

#endif
