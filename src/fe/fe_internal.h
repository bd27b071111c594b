/* SPDX-License-Identifier: MIT
 * gearsim fe module, library-internal: the model's data (shared with the body
 * code), symmetric sparse kernels, and helpers for the tests and the
 * benchmark (an annulus mesh, a bare solve timer). */
#ifndef GEARSIM_FE_INTERNAL_H
#define GEARSIM_FE_INTERNAL_H

#include "gearsim/fe.h"

/* Mass properties of one element (rho t included): area (m^2, without
 * rho t), first moments rho t int X, rho t int Y, polar rho t int |X|^2,
 * and the angular coupling s_i = sum_j m_ij J X_j per node (x, y). */
typedef struct gsi_fe_props {
    double area, mx, my, polar;
    double s[12];
} gsi_fe_props;

/* An element type: the operations the model needs. Nodes in the mesh's
 * order (corners, then mid-side nodes for quadratic elements; docs/explanation/elastic_body.md).
 * matrices: stiffness ke (2 nn x 2 nn, row-major, dofs x1 y1 x2 y2 ...,
 *   thickness t included), consistent mass me (nn x nn per direction, rho t
 *   included) and the mass properties; GS_EGEOMETRY for an inverted or
 *   degenerate element.
 * stress: sigma_xx, sigma_yy, tau_xy at each node (sn, 3 nn) and at the
 *   centroid (sc, 3) from the element displacements ue (2 nn), and the
 *   element's area. */
typedef struct gsi_fe_element {
    const char *name;
    int nn;
    gs_err (*matrices)(const double *x, const double *y, const double D[9], double t, double rho,
                       double *ke, double *me, gsi_fe_props *props);
    void (*stress)(const double *x, const double *y, const double D[9], const double *ue,
                   double *sn, double *sc, double *area);
} gsi_fe_element;

extern const gsi_fe_element gsi_fe_tri3, gsi_fe_tri6;
/* The element of a mesh: 6-node triangles when it has mid-side nodes. */
const gsi_fe_element *gsi_fe_element_of(const gs_mesh *m);

/* The matrices live in one compressed-column pattern of the upper triangle of
 * the elastic block (rows sorted, diagonal last in each column), which is
 * exactly CHOLMOD's packed, sorted, stype = 1 layout. K and M share it: every
 * node pair of an element contributes a full 2x2 block to both (M's
 * off-diagonal xy entries are stored zeros). */
struct gs_fe_model {
    gs_index n_nodes, n_tris, n_free_nodes, ne, nnz;
    double *xy;          /* 2 * n_nodes (copy of the mesh) */
    const gsi_fe_element *el; /* element operations */
    int nn;              /* nodes per element */
    gs_index *en;        /* nn * n_tris element nodes (corners, then mid-side nodes) */
    gs_index *dof;       /* 2 * n_nodes: index in q, or -1 for fixed nodes */
    gs_index *free_node; /* n_free_nodes: mesh node of free node k (dofs 2k, 2k+1) */
    /* The order in which the compliance columns of free nodes are solved
     * for, in groups of GSI_FE_GROUP consecutive entries (gs_fe_body's
     * column cache): the free nodes of the mesh's boundary loop in loop
     * order (a flank, root to tip, then the next), then the other free
     * nodes by index, from position n_col_boundary on (where the groups
     * start again; the last group of each list may be shorter). Contact
     * candidates are runs of boundary nodes, so a group's solve yields the
     * columns of neighbours that the moving contact asks for next.
     * col_pos: the position of free node k in col_order. */
    gs_index *col_order, *col_pos, n_col_boundary;
    gs_index *colp;      /* ne + 1 */
    gs_index *rowi;      /* nnz */
    double *kx, *mx;     /* nnz values of K and M */
    /* For the end-of-step pass (gsi_fe_step_pass): the rows of column 2k
     * (and of 2k + 1 before its last two) are the pairs 2l, 2l + 1 of the
     * nodes l above k; their node indices l, node after node (32 bits: a
     * quarter of the row indices' bytes). NULL if the pattern had another
     * form: the pass then goes column by column. */
    int32_t *pass_nb;
    double *s;           /* ne: angular coupling vector */
    gs_material mat;
    double thickness, Dmat[9];
    double area, mass, centroid[2], inertia_elastic, inertia_core, inertia_total;
};

/* Free nodes per group of gsi_fe_model.col_order. */
#define GSI_FE_GROUP 8

/* y += alpha * M xm + beta * K xk on the elastic block (length ne), in one
 * pass over the shared pattern; xm and xk may be the same vector. */
void gsi_fe_symv2(const gs_fe_model *m, double alpha, const double *xm, double beta,
                  const double *xk, double *y);

/* x^T (alpha M + beta K) x on the elastic block, without workspace. */
double gsi_fe_quadform(const gs_fe_model *m, double alpha, double beta, const double *x);

/* x_m^T M x_m and x_k^T K x_k in one pass over the pattern, each summed in
 * the order of gsi_fe_quadform (the same values as its two calls). */
void gsi_fe_quadform2(const gs_fe_model *m, const double *xm, const double *xk, double *qm, double *qk);

/* The end of a step of an FE body in one pass over the pattern (column j
 * updates entry j just before the columns after it read it):
 * q += h w + delta, then w += 2 delta / h, y = -K x with x = q + c w of the
 * new q, w (y needs no initial value; x is formed where it is read, never
 * stored), *qm = w^T M w and *qk = q^T K q of the new q, w: bit for bit the
 * values of those loops, gsi_fe_symv2(m, 0, x, -1, x, y) on a zero y and
 * gsi_fe_quadform2(m, w, q, qm, qk) taken one after the other. With qm or
 * qk NULL the energies are not summed and M is not read (q, w, y the same
 * bit for bit). */
void gsi_fe_step_pass(const gs_fe_model *m, double h, double c, const double *delta, double *q,
                      double *w, double *y, double *qm, double *qk);

/* y = -K x with x = q + c w (y needs no initial value), by the pass of
 * gsi_fe_step_pass without its state update or energies: bit for bit its y
 * for the state it left, and gsi_fe_symv2(m, 0, x, -1, x, y) on a zero y.
 * A step's right-hand side formed just before its solve, so that K and
 * then the factor stream back to back (gs_fe_body). */
void gsi_fe_rhs_pass(const gs_fe_model *m, double c, const double *q, const double *w, double *y);

/* A new CHOLMOD matrix (allocated in common c) holding alpha M + beta K of
 * the elastic block, upper triangle; NULL when out of memory. */
struct cholmod_sparse_struct;
struct cholmod_common_struct;
struct cholmod_sparse_struct *gsi_fe_cholmod_matrix(const gs_fe_model *m, double alpha,
                                                    double beta, struct cholmod_common_struct *c);
/* cholmod_l_start with the project's settings: no printing, and CHOLMOD's
 * OpenMP regions (a fixed 4 threads in the supernodal factorisation, which
 * ignores OMP_NUM_THREADS) run on the calling thread alone: on a shared
 * machine the extra threads only spin and wait (docs/performance/index.md). */
void gsi_cholmod_start(struct cholmod_common_struct *c);
/* calloc for the large arrays the step streams (CHOLMOD's, the model's K
 * and M): from 2 MiB on, aligned to and advised as transparent huge pages
 * (fewer TLB misses); freed with free(). */
void *gsi_huge_calloc(size_t n, size_t size);

/* An annulus r_in <= r <= r_out of n_r radial by n_t circumferential cells,
 * each split into two counter-clockwise triangles (diagonals alternate), the
 * nodes on the inner circle fixed: a gear-like rim on a rigid hub, for the
 * tests and the benchmark until the gear mesher is there. Freed with
 * gs_mesh_free. Errors: GS_EINVAL, GS_ENOMEM. */
gs_err gsi_fe_mesh_annulus(double r_in, double r_out, int n_r, int n_t, gs_mesh **out);

/* The same annulus with elements of order 1 or 2; for order 2 the mid-side
 * nodes of the edges on the two circles lie on the circles (curved
 * quadratic elements), those on the inner circle fixed. */
gs_err gsi_fe_mesh_annulus_order(double r_in, double r_out, int n_r, int n_t, int order,
                                 gs_mesh **out);

/* Time `reps` bare CHOLMOD solves (solve2, one right-hand side, preallocated
 * workspace) on the body's current factor; returns seconds per solve, or a
 * negative value if no factor exists. For the benchmark. */
double gsi_fe_body_time_bare_solve(gs_fe_body *b, int reps);

#endif
