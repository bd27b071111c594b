/* SPDX-License-Identifier: MIT
 * gearsim mesh module, library-internal: the gear mesher's working types and
 * the steps its files share (docs/explanation/geometry.md "Meshes"): node and triangle
 * lists, distributions and row-by-row blocks (gear_mesh_blocks.c), the tooth
 * sector template (gear_mesh_sector.c), the rings between the band and the
 * hub and the smoothing of poor elements (gear_mesh_rings.c), the assembly
 * (gear_mesh.c). */
#ifndef GEARSIM_GEAR_MESH_INTERNAL_H
#define GEARSIM_GEAR_MESH_INTERNAL_H

#include <stddef.h>

#include "gearsim/mesh.h"

typedef struct {
    double *xy;
    signed char *tag;
    gs_index n, cap;
} nodes_t;

typedef struct {
    gs_index *t;
    gs_index n;
    size_t cap;
} tris_t;

typedef struct {
    nodes_t nd;
    tris_t tr;
    int nleft, nright;      /* nodes on each sector side (rim + 1 at the sector's refinement,
                             * or at its fine neighbour's: local refinement) */
    gs_index *left, *right; /* sector sides from R0 to the space centre */
    int nbot;
    gs_index *bottom;       /* R0 arc from -pi/z to +pi/z */
    int nflank;
    gs_index *flank_cw, *flank_ccw; /* form point -> tip corner */
    int nbnd;
    gs_index *bnd;          /* profile from S- to S+, both included */
} sector_t;

/* Counts and shapes fixed at refine 0 (so that refinement is nested). */
typedef struct {
    int nf, na, nr, ns;           /* at the requested refinement; nr = all layers of R, S */
    int nband;                    /* layers of nr in the band below the root circle */
    double fband;                 /* fraction of the R/S interface taken by the band */
    int ntip;                     /* elements on the tip arc */
    double gtip;                  /* flank steps shrink towards a thin tip by this ratio */
    int nrb;                      /* elements on the band circle under R (under each S: ns) */
    double grading;
    double R0;                    /* band circle */
    double psiB;                  /* angle of the R/S block corner on R0 */
    double lfil;                  /* fillet length */
    double tfil[1025], sfil[1025];/* fillet parameter vs arc length fraction */
    double fR[1025], fpsi[1025];  /* fillet samples: radius and polar angle */
} plan_t;

typedef struct {
    int n;
    double *R;     /* radii, R[0] = R0 ... R[n-1] = hub */
    gs_index *N;   /* node counts at refine 0 */
} rings_t;

double gsi_gmesh_grade_both(double u, double g);
double gsi_gmesh_grade_top(double u, double g);
double gsi_gmesh_tri_shape(const double *xy, gs_index a, gs_index b, gs_index c);
gs_err gsi_gmesh_build_sector(const gs_gear_geom *g, const plan_t *pl, const plan_t *pt, int nc_lo,
                              int nc_hi, sector_t *s);
gs_err gsi_gmesh_make_plan(const gs_gear_geom *g, const gs_gear_mesh_opts *o, plan_t *pl, gs_diag *d);
gs_index gsi_gmesh_node_add(nodes_t *nb, double x, double y, int tag);
int gsi_gmesh_layered_block(nodes_t *nb, tris_t *tb, int nrow, const int *cnt, const gs_index *bot,
                            const gs_index *top, const gs_index *lef, const gs_index *rig);
int gsi_gmesh_plan_rings(const gs_gear_geom *g, double R0, gs_index N0, double h0, rings_t *rp);
int gsi_gmesh_smooth_poor(nodes_t *nb, const tris_t *tb, int iters, double thresh);
int gsi_gmesh_tri_add(tris_t *tb, gs_index a, gs_index b, gs_index c);
int gsi_gmesh_zipper(nodes_t *nb, tris_t *tb, const gs_index *A, gs_index na, const gs_index *B,
                     gs_index nbn, int a_outer);
void gsi_gmesh_sector_free(sector_t *s);

#endif
