/* SPDX-License-Identifier: MIT
 * gearsim: finite element meshes of the elastic part of a body.
 *
 * Linear triangles (3 nodes, counter-clockwise), coordinates in the body's
 * material frame (origin on the axis), metres. Nodes on the interface with the
 * rigid core carry zero elastic displacement (METHOD.md section 1); they are
 * listed in `fixed`. The geometry/mesh module may add fields (flank tables
 * for the contact search, etc.), but the fields below keep their meaning: the
 * FE module relies on them. */
#ifndef GEARSIM_MESH_H
#define GEARSIM_MESH_H

#include "gearsim/types.h"

typedef struct gs_mesh {
    gs_index n_nodes;
    double *xy;          /* 2 * n_nodes: x0 y0 x1 y1 ... */
    gs_index n_tris;
    gs_index *tri;       /* 3 * n_tris node indices, counter-clockwise */
    gs_index n_fixed;
    gs_index *fixed;     /* nodes whose displacement is zero (rigid core interface / clamp) */
    /* Fields added by the geometry/mesh module follow (flank node tables...). */
    int n_teeth;
    /* flank_ptr has 2*n_teeth+1 entries; flank s of tooth t (s = 0 left, 1 right,
     * seen from outside the tooth looking at its tip) holds the nodes
     * flank_nodes[flank_ptr[2t+s] .. flank_ptr[2t+s+1]) ordered root to tip. */
    gs_index *flank_ptr;
    gs_index *flank_nodes;
} gs_mesh;

/* Free all arrays and the struct; safe on NULL; sets *m = NULL. */
void gs_mesh_free(gs_mesh **m);

/* A rectangle [0,lx] x [-ly/2, ly/2] of nx by ny cells, each split into two
 * triangles with alternating diagonals; the nodes on x = 0 are fixed (a clamp).
 * For FE verification (cantilever strip) and the contact tests. */
gs_err gs_mesh_rectangle(double lx, double ly, int nx, int ny, gs_mesh **out);

#endif
