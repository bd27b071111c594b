/* SPDX-License-Identifier: MIT
 * gearsim: finite element meshes of the elastic part of a body.
 *
 * Triangles (3 corner nodes, counter-clockwise; quadratic meshes add a node
 * on every edge, see `mid`), coordinates in the body's material frame
 * (origin on the axis), metres. Nodes on the interface with the
 * rigid core carry zero elastic displacement (METHOD.md section 1); they are
 * listed in `fixed`. The geometry/mesh module may add fields (flank tables
 * for the contact search, etc.), but the fields below keep their meaning: the
 * FE module relies on them.
 *
 * No function here is collective; meshes are plain data, read-only after
 * creation, safe to share between threads. */
#ifndef GEARSIM_MESH_H
#define GEARSIM_MESH_H

#include "gearsim/geometry.h"
#include "gearsim/modification.h"
#include "gearsim/types.h"

/* What a node is (gs_mesh.node_tag). */
typedef enum {
    GS_NODE_INTERIOR = 0,
    GS_NODE_FLANK = 1,   /* on an involute flank, form point and tip corner included */
    GS_NODE_FILLET = 2,  /* on a root fillet (its end on the root circle included) */
    GS_NODE_ROOT = 3,    /* on a root arc */
    GS_NODE_TIP = 4,     /* on a tip arc (corners excluded: they are flank nodes) */
    GS_NODE_CORE = 5,    /* on the rigid-core interface circle (fixed) */
    GS_NODE_OTHER = 6    /* on another boundary (e.g. of gs_mesh_rectangle) */
} gs_node_tag;

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
     * flank_nodes[flank_ptr[2t+s] .. flank_ptr[2t+s+1]) ordered root to tip.
     *
     * Gear meshes: tooth t is centred at polar angle 2 pi t / z. The nodes of a
     * flank are those of its involute, from the form point (where the fillet
     * ends) to the tip corner, both included; they lie exactly on the
     * involute. "Outside the tooth looking at its tip" means, for an external
     * gear, a viewer beyond the tip circle looking at the axis: s = 0 is the
     * clockwise flank (polar angle below the tooth centre), s = 1 the
     * counter-clockwise one. For an internal gear the viewer stands inside
     * the ring looking outwards: s = 0 is the counter-clockwise flank, s = 1
     * the clockwise one. "Root to tip" is increasing radius for external
     * gears and decreasing radius for internal ones. */
    gs_index *flank_ptr;
    gs_index *flank_nodes;
    /* Gear meshes (NULL / 0 otherwise): */
    signed char *node_tag;   /* n_nodes gs_node_tag values */
    gs_index n_boundary;     /* the toothed boundary as one closed loop, in order of */
    gs_index *boundary;      /* increasing polar angle (counter-clockwise about the axis);
                              * the material is on its left for an external gear, on its
                              * right for an internal one. Not repeated at the end. */
    /* Element order. NULL: linear triangles (3 nodes). Otherwise quadratic
     * 6-node triangles: mid[3e + i] is the node on edge i of element e, the
     * edge from tri[3e + i] to tri[3e + (i + 1) % 3] (the Triangle_6 / VTK
     * node order is tri[3e..3e+2] then mid[3e..3e+2]). Mid-side nodes of
     * gear boundary edges lie on the exact curve (involute, fillet, tip,
     * root) and carry the curve's tag; they are part of the flank tables and
     * of the boundary loop, which then alternate corner and mid-side nodes. */
    gs_index *mid;
} gs_mesh;

/* 1 for linear, 2 for quadratic triangles. */
static inline int gs_mesh_order(const gs_mesh *m)
{
    return m->mid ? 2 : 1;
}

/* Free all arrays and the struct; safe on NULL; sets *m = NULL. */
void gs_mesh_free(gs_mesh **m);

/* A rectangle [0,lx] x [-ly/2, ly/2] of nx by ny cells, each split into two
 * triangles with alternating diagonals; the nodes on x = 0 are fixed (a clamp).
 * For FE verification (cantilever strip) and the contact tests. */
gs_err gs_mesh_rectangle(double lx, double ly, int nx, int ny, gs_mesh **out);

/* ------------------------------------------------------------------------ */
/* Gear meshes (docs/explanation/geometry.md: layout, grading, refinement)              */
/* ------------------------------------------------------------------------ */

typedef struct gs_gear_mesh_opts {
    int flank;       /* elements along the involute of each flank (>= 1; scene mesh.flank) */
    int across;      /* elements across a tooth (>= 1; scene mesh.across) */
    int rim;         /* element layers in the band under the teeth (>= 1; scene mesh.rim) */
    int refine;      /* uniform refinements: every count above times 2^refine (0..8) */
    double grading;  /* ratio of the largest to the smallest element size across a tooth
                      * (smallest at the flanks, where teeth touch) and through the band
                      * under the teeth (smallest at the root); 1 = uniform; 1..8 */
    int order;       /* element order: 1 linear (CST), 2 quadratic 6-node triangles with
                      * curved boundary edges (scene mesh.order) */
    /* Local refinement (docs/explanation/geometry.md "Local refinement"; 0 = none): the
     * teeth of the fine_teeth sectors centred on tooth fine_centre are meshed
     * fine_refine levels finer than `refine` (rim band and fillets under
     * them one level less, the sectors beside them graded one level per tooth),
     * the coarser of two neighbouring sectors takes the finer node count on the shared
     * side, and the rings under them start fine and halve their extra density
     * ring by ring: a conforming mesh. For the quasi-static analysis, which
     * centres them on the teeth in contact. */
    int fine_teeth;  /* 0..z (scene mesh.fine_teeth) */
    int fine_refine; /* 1..4 when fine_teeth > 0, else 0 (scene mesh.fine_refine) */
    int fine_centre; /* tooth the fine teeth are centred on (taken modulo z) */
} gs_gear_mesh_opts;

/* The default mesh (the scene's): quadratic elements (order 2) with the
 * default counts of that order, refine 0. */
void gs_gear_mesh_opts_defaults(gs_gear_mesh_opts *o);

/* The default counts of element order `order` (1 or 2; anything else: the
 * default order), refine 0. The one table of default counts (gear_mesh.c):
 * order 2 {flank 8, across 4, rim 2, grading 3} (38 060 unknowns for the
 * 20/30 pair of docs/validation/calculix.md), order 1 {flank 8, across 4, rim 3,
 * grading 2} (the linear default before order 2 was: 11 224 unknowns). */
void gs_gear_mesh_opts_for_order(gs_gear_mesh_opts *o, int order);

/* The `fine` setting of the quasi-static analysis (gearsim-stiffness --fine;
 * docs/validation/calculix.md): order 2
 * {flank 8, across 4, rim 1, grading 3}, the 3 teeth centred on fine_centre
 * (the analysis puts it on the teeth in contact) 3 levels finer (their rim
 * band and fillets 2). The
 * cheapest local setting measured within 1 % of the CalculiX reference at
 * every roll position of the 20/30 pair. */
void gs_gear_mesh_opts_fine(gs_gear_mesh_opts *o);

/* Mesh the elastic part of a gear: for an external gear the region between
 * the hub circle and the toothed outline, for an internal gear between the
 * toothed outline and the outer rim circle. Fills every field of gs_mesh,
 * including n_teeth, flank tables, node tags and the boundary loop; `fixed`
 * is the hub (or outer rim) circle. Nodes of flanks and fillets lie exactly
 * on the involute and on the fillet curve. The caller owns *out (free with
 * gs_mesh_free). Errors: those of gs_gear_validate() (field named as there),
 * GS_ERANGE with field "mesh.flank", "mesh.across", "mesh.rim", "refine" or
 * "mesh.grading" for bad options, GS_ETOOBIG (field "refine") beyond 2^26
 * triangles, GS_EGEOMETRY (field "mesh") if an element came out inverted,
 * GS_ENOMEM. */
gs_err gs_gear_mesh(const gs_gear_params *p, const gs_gear_mesh_opts *o, gs_mesh **out,
                    gs_diag *d);

/* Element quality of a mesh. Aspect ratio is circumradius / (2 inradius):
 * 1 for an equilateral triangle, growing without bound as it degenerates. */
typedef struct gs_mesh_quality {
    gs_index n_tris;
    gs_index n_bad;          /* inverted or degenerate (area <= 1e-12 longest edge^2) */
    double area;             /* total (signed) area, m^2 */
    double min_area, max_area;
    double min_angle_deg, max_angle_deg;
    double max_aspect, mean_aspect;
    double min_edge, max_edge;
} gs_mesh_quality;

void gs_mesh_quality_eval(const gs_mesh *m, gs_mesh_quality *q);

/* Make a linear mesh quadratic: one new node at the middle of every edge
 * (shared by the two elements of an interior edge), on the straight chord
 * (fixed when both ends are fixed);
 * tag GS_NODE_INTERIOR for interior edges and the common tag of the ends
 * (else GS_NODE_OTHER) on the boundary. Flank tables and the boundary loop,
 * when present, get the new nodes inserted. For gear meshes gs_gear_mesh
 * (order 2) places boundary mid-side nodes on the exact curves instead.
 * Errors: GS_EINVAL (NULL, already quadratic), GS_ENOMEM. */
gs_err gs_mesh_make_quadratic(gs_mesh *m);

/* The connectivity of a quadratic mesh in Triangle_6 order (6 * n_tris:
 * corners, then mid-side nodes), newly allocated (free()); NULL for a linear
 * mesh or when out of memory. For field output (XDMF Triangle_6). */
gs_index *gs_mesh_triangle6(const gs_mesh *m);

/* Topology: every edge in at most two triangles, no repeated node in a
 * triangle, every node used. Returns the number of boundary edges in
 * *n_boundary_edges and the number of boundary loops in *n_loops (either
 * may be NULL). GS_EINVAL when the mesh is not a conforming 2-manifold. */
gs_err gs_mesh_check_topology(const gs_mesh *m, gs_index *n_boundary_edges, int *n_loops);

/* Apply a set to a mesh of the gear (gs_gear_mesh of g's parameters): flank
 * nodes (tag GS_NODE_FLANK) move to the modified flank at their radius;
 * each tooth's pitch error turns the tooth about the axis (fully from half
 * way between root and pitch circle outwards, fading to nothing at the root
 * circle, so the elements there take up the step); run-out translates every
 * node. Checks that no element turned over (GS_EGEOMETRY, field
 * "modification"). A NULL or empty set leaves the mesh untouched
 * (src/mesh/mesh_mods.c). */
gs_err gs_gear_mods_apply_mesh(const gs_gear_geom *g, const gs_gear_mods *m, gs_mesh *mesh,
                               gs_diag *d);

#endif
