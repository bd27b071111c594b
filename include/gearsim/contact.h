/* SPDX-License-Identifier: MIT
 * gearsim: contact geometry of a gear mesh (METHOD.md sections 3 and 5).
 * Owned by the contact module; the contact *step* (linearised
 * non-penetration rows, the QP) is built on top of it elsewhere.
 *
 * Two parts:
 *
 *   sign functions  localised Rvachev gap functions g(x) of a slave point x
 *                   against a short master polyline: positive outside the
 *                   master body, zero on its boundary, negative inside, with
 *                   analytic gradients w.r.t. the slave point and every
 *                   master node. Plain doubles, no allocation, pure. For
 *                   order-2 masters, the signed distance to a chain of
 *                   parabolic edges (gs_gap_eval_quad).
 *   search          the candidate (slave node, master window) pairs of one
 *                   gear mesh, from the rigid states of the two gears (their
 *                   nodal displacements are used only to measure distances),
 *                   and the gap of a candidate in the scene frame chained to
 *                   each body's rotation, centre and nodal displacements.
 *
 * Orientation convention. A master polyline p_0 .. p_{k-1} is traversed with
 * the master body's material on its LEFT. The outward unit normal of a
 * segment a -> b is then (b - a) turned by -90 degrees:
 * n = (dy, -dx) / |b - a|. A vertex where the polyline turns left
 * (cross(b - a, c - b) > 0) is convex (the body is locally the intersection
 * of the two half-planes), otherwise concave (the union).
 *
 * Gradient layout. Every sign function fills grad[8]: grad[0..1] = dg/dx
 * (slave point), grad[2 + 2 j .. 3 + 2 j] = dg/d(master node j), j = 0, 1, 2
 * (a, b, c; for a line the last pair is zero). All lengths in metres, all
 * points in one common frame (whatever frame the caller uses: g is invariant
 * under rigid motions of all points together, so the gradients rotate with
 * the frame).
 *
 * Nothing here is collective. Sign functions are thread-safe; a search
 * object must be used by one thread at a time (gs_contact_eval only reads
 * it, so several threads may evaluate candidates concurrently). */
#ifndef GEARSIM_CONTACT_H
#define GEARSIM_CONTACT_H

#include <stdbool.h>

#include "gearsim/geometry.h"
#include "gearsim/mesh.h"
#include "gearsim/types.h"

/* ------------------------------------------------------------------------ */
/* Sign (gap) functions                                                      */
/* ------------------------------------------------------------------------ */

/* Point-to-line gap g1 = (x - a).n of the segment a -> b (the whole line,
 * not clamped to the segment): the signed distance of x to the line,
 * positive on the side of the outward normal. Gradients (tau the projection
 * parameter of x on a -> b): dg/dx = n, dg/da = -(1 - tau) n,
 * dg/db = -tau n; grad[6..7] = 0.
 * Errors: GS_EINVAL (NULL pointer), GS_EGEOMETRY (a == b, or a coordinate
 * that is not finite). */
gs_err gs_gap_line(const double x[2], const double a[2], const double b[2], double *g,
                   double grad[8]);

/* Wedge at vertex b of the segments a -> b and b -> c (R-functions,
 * METHOD.md section 3), g1 and g2 the two line gaps:
 *   convex  (body = {g1 <= 0} and {g2 <= 0}; outside = union, R-disjunction)
 *           g = g1 + g2 + sqrt(g1^2 + g2^2), sign(g) = sign(max(g1, g2));
 *   concave (body = {g1 <= 0} or {g2 <= 0}; outside = intersection,
 *           R-conjunction) g = g1 + g2 - sqrt(g1^2 + g2^2),
 *           sign(g) = sign(min(g1, g2)).
 * The zero set is exactly the two boundary rays from b; on it, away from b,
 * the gradient w.r.t. x is the unit normal of the segment it lies on. At
 * g1 = g2 = 0 (x at the vertex, or on the line of two collinear segments)
 * the square root is not differentiable: the subgradient taken is the limit
 * from outside along the bisector, g1/r = g2/r = 1/sqrt(2), so
 * dg/dx = (1 +- 1/sqrt 2)(n1 + n2). Never NaN.
 * Errors: as gs_gap_line for either segment. */
gs_err gs_gap_wedge(const double x[2], const double a[2], const double b[2], const double c[2],
                    bool convex, double *g, double grad[8]);

typedef enum {
    GS_GAP_LINE = 0,    /* point-to-line of one segment */
    GS_GAP_CONVEX = 1,  /* convex wedge, blended with a line (see gs_gap_eval) */
    GS_GAP_CONCAVE = 2, /* concave wedge, blended with a line */
    GS_GAP_PARABOLA = 3, /* signed distance to parabolic edges (gs_gap_eval_quad) */
    GS_GAP_CORNER = 4    /* order 1 at a tip corner of the master: signed distance to the
                          * corner's two segments (gs_contact_eval) */
} gs_gap_kind;

/* The gap of a slave point against a polyline, and what it was built from. */
typedef struct gs_gap {
    double g;           /* gap, m: > 0 outside the master, < 0 inside */
    gs_gap_kind kind;
    int segment;        /* nearest segment i (p_i -> p_{i+1}) */
    double blend;       /* weight phi of the wedge in [0, 1] (0 for a pure line) */
    int n_master;       /* 2 or 3 master nodes used */
    int master[3];      /* their indices in the polyline, increasing */
    double grad[8];     /* dg/dx (slave), then dg/d(p_master[j]), j < n_master; rest 0 */
    double xi;          /* GS_GAP_PARABOLA: the closest point's parameter on edge
                         * `segment` (0 at its first node, 1 at its last); 0 otherwise */
} gs_gap;

/* Gap of slave point x against the master polyline pts (k >= 2 nodes,
 * 2 k doubles, material on the left). The rule (docs/explanation/contact.md):
 *
 *  1. The nearest segment i (Euclidean distance to the closed segment; ties
 *     go to the lower index) gives the line gap gL of p_i -> p_{i+1}
 *     (extended beyond the polyline's first and last node).
 *  2. Each interior vertex v (0 < v < k-1) has a wedge W_v (convex or
 *     concave by its turn) and a weight phi_v = S((rho - r1) / (r2 - r1)),
 *     rho = |x - p_v|, r2 = min(L_{v-1}, L_v) / 2, r1 = r2 / 2 (L the segment
 *     lengths), S(t) = 1 - 3 t^2 + 2 t^3 on [0, 1], 1 below, 0 above. At most
 *     one end of segment i has phi > 0; with it, g = phi W_v + (1 - phi) gL,
 *     master nodes v-1, v, v+1; otherwise g = gL, nodes i, i+1.
 *
 * g and its gradient w.r.t. x are continuous (C1 across the blend) along any
 * path that stays within r1 of the polyline (the switch from one nearest
 * segment to the next then happens where phi = 1 or, inside a convex / outside
 * a concave corner, on the bisector where both line gaps are equal); further
 * away g keeps the right sign but may jump. g depends only on the nodes
 * i-1 .. i+2, so any window that contains them gives the same value. The
 * gradient includes the dependence of phi on x and on the master nodes (also
 * through r1, r2).
 * Errors: GS_EINVAL (NULL, k < 2), GS_EGEOMETRY (two consecutive nodes
 * equal, a value not finite). */
gs_err gs_gap_eval(const double x[2], const double *pts, int k, gs_gap *out);

/* Gap of slave point x against a chain of E = (k - 1) / 2 parabolic edges
 * (order-2 boundary: k odd >= 3 nodes, 2 k doubles, material on the left;
 * edge e runs through pts[2e] (corner), pts[2e+1] (mid-side, at xi = 1/2),
 * pts[2e+2] (corner), P_e(xi) = sum_i N_i(xi) p_i with the quadratic shape
 * functions N = ((1-xi)(1-2xi), 4xi(1-xi), xi(2xi-1)), xi in [0, 1]). The
 * rule (docs/explanation/contact.md "Quadratic edges"):
 *
 *  1. Closest point: on each edge the xi minimising |x - P_e(xi)| (the roots
 *     of the cubic (P - x).P' by safeguarded Newton in each sign-change
 *     bracket, and the interval ends); the first and last edge are extended
 *     to xi in [-1, 1] and [0, 2] (the window's ends, like the extended line
 *     of gs_gap_eval). The nearest edge wins (ties: lower index).
 *  2. Interior point (P' . (x - P) = 0): g = (x - P).n, n the outward unit
 *     normal (P'_y, -P'_x) / |P'| at xi, so |g| is the Euclidean distance;
 *     dg/dx = n, dg/dp_i = -N_i(xi) n (stationarity of the projection: the
 *     terms through xi and through n vanish).
 *  3. Joint vertex V of two edges (the projection clamped to their shared
 *     corner): g = s |x - V|, s the sign of (x - V).(n_a + n_b) (outside a
 *     convex joint, inside a concave one); dg/dx = s (x - V) / |x - V| = nu,
 *     dg/dV = -nu (the formula of 2 with N = (0, 0, 1)); at x = V, g = 0 and
 *     nu is the mean normal.
 *
 * So |g| is the distance to the union of the edges and g changes sign only
 * across them: g is continuous, exactly zero on the parabolic edges, and its
 * gradient is continuous except on the ridge of a joint (the bisector inside
 * a convex joint, outside a concave one), where it turns by the joint's turn
 * angle (small between the parabolas of a smooth curve: h^3 / (16 R^3) on
 * a circle of radius R, edge chord h; the tip corner's angle there). master = the 3 nodes of the winning edge (2e, 2e+1, 2e+2),
 * n_master = 3, segment = e, kind GS_GAP_PARABOLA, blend 0.
 * Errors: GS_EINVAL (NULL, k < 3 or even), GS_EGEOMETRY (two consecutive
 * nodes equal, a degenerate edge, a value not finite). */
gs_err gs_gap_eval_quad(const double x[2], const double *pts, int k, gs_gap *out);

/* Chain rule for one node of a body at x = c + R(theta)(X + u): given
 * dg/dx (scene frame) and the node's current x - c, adds to dg_dtheta the
 * term dg/dx . J (x - c) (J = rotation by +90 degrees, since
 * dx/dtheta = R'(theta)(X + u) = J (x - c)) and writes
 * dg_du = R(theta)^T dg/dx (body frame). dg/dc is dg/dx itself. */
void gs_gap_chain(const double dg_dx[2], double theta, const double x_minus_c[2],
                  double *dg_dtheta, double dg_du[2]);

/* ------------------------------------------------------------------------ */
/* Contact search of one gear mesh                                          */
/* ------------------------------------------------------------------------ */

#define GS_CONTACT_WINDOW_MAX 7

typedef enum {
    GS_CONTACT_TWO_PASS = 0, /* every candidate node of both gears is a slave (default) */
    GS_CONTACT_ONE_PASS = 1  /* flank nodes are slaves only on the gear with the finer
                              * flank spacing (ties: gear 0); tip corners and tip arc
                              * nodes are slaves on both gears (a corner must be a
                              * slave: as a master vertex it could pass through a
                              * flank unseen) */
} gs_contact_passes;

typedef struct gs_contact_opts {
    double band_m;       /* a node is a candidate when its distance to the other gear's
                          * boundary is at most band_m (m); 0 selects 0.1 module */
    double depth_m;      /* ... or when it is inside the other gear by at most depth_m;
                          * 0 selects 0.5 module */
    int window;          /* nodes in a master window, odd, 3 .. GS_CONTACT_WINDOW_MAX
                          * (default 5) */
    gs_contact_passes passes;
} gs_contact_opts;

/* band 0 (0.1 m), depth 0 (0.5 m), window 5, two passes. Both flanks of
 * every candidate tooth are always searched (torque reverses in rattle and
 * impact; the cost is twice a small number). */
void gs_contact_opts_defaults(gs_contact_opts *o);

/* Rigid placement of a gear, and optionally its nodal displacements:
 * node X is at x = c + R(theta)(X + u). */
typedef struct gs_contact_pose {
    double c[2];        /* axis position, scene frame, m */
    double theta;       /* rotation, rad */
    const double *u;    /* 2 * n_nodes, body frame, m; NULL = zero */
} gs_contact_pose;

/* One candidate pair: a slave node and a master window. */
typedef struct gs_contact_candidate {
    int slave;              /* gear index 0 / 1 */
    int master;             /* 1 - slave */
    gs_index slave_node;    /* mesh node of the slave gear */
    int slave_tooth;        /* tooth of the slave node */
    int slave_where;        /* 0 / 1: flank s of the tooth (mesh.h); 2: tip arc */
    int n_window;           /* k */
    gs_index window[GS_CONTACT_WINDOW_MAX]; /* master mesh nodes, consecutive on its
                                             * boundary loop, material on the left
                                             * (reversed loop order for a ring); an
                                             * order-2 master: whole parabolic edges,
                                             * corners at even positions */
    double distance;        /* distance to the master boundary at search time, m */
    double gap;             /* gs_gap_eval of the window at search time, m, for a
                             * node beyond the band (the depth test); NAN within it */
} gs_contact_candidate;

/* What the last search did (for logs and tests). */
typedef struct gs_contact_stats {
    double pitch_point[2];  /* scene frame */
    int n_teeth[2];         /* candidate teeth of each gear */
    int teeth[2][16];       /* their indices (the first 16), in search order */
    gs_index nodes_tested;  /* slave nodes whose distance was measured */
    gs_index n_candidates;
} gs_contact_stats;

typedef struct gs_contact_search gs_contact_search;

/* Prepare the search of the mesh of two gears. The meshes are borrowed (they
 * must outlive the search and not change); the parameters are copied. Each
 * mesh must come from gs_gear_mesh() for those parameters (flank tables,
 * node tags, boundary loop). At most one gear may be internal. o may be
 * NULL (defaults). *out is owned by the caller (gs_contact_search_free).
 * Errors (d, when given, names the field): GS_EINVAL ("gears": NULL
 * pointers, two internal gears; "mesh": a mesh without flank tables, node
 * tags or boundary loop, or with another tooth count), GS_ERANGE
 * ("contact.window", "contact.band", "contact.depth", "contact.passes"),
 * the errors of gs_gear_geometry() (field "gears"), GS_ENOMEM. */
gs_err gs_contact_search_new(const gs_mesh *m0, const gs_gear_params *g0, const gs_mesh *m1,
                             const gs_gear_params *g1, const gs_contact_opts *o,
                             gs_contact_search **out, gs_diag *d);

void gs_contact_search_free(gs_contact_search **s);

/* Find the candidates for the poses pose[0], pose[1]. The rigid states give
 * the pitch point and the candidate teeth (those of each gear that reach
 * into the other gear's tip circle, plus the band); on them the flank nodes,
 * tip corners and tip arc nodes within the band of the other gear's boundary
 * (measured with the displacements) are the slaves, each with the window of
 * `window` master boundary nodes centred on its nearest master node.
 * Cost O(candidate teeth x nodes per tooth x log(boundary nodes)).
 * Deterministic: gear 0's slaves first, then gear 1's; per gear, teeth in
 * increasing angle from the most clockwise candidate; per tooth flank 0 (root
 * to tip), tip arc, flank 1 (tip to root), so the list walks the boundary.
 * *cand points to an array owned by the search, valid until the next call or
 * free; *n receives its length. stats may be NULL.
 * Errors: GS_EINVAL (NULL, a pose not finite, centres coincident),
 * GS_ENOMEM. */
gs_err gs_contact_search_run(gs_contact_search *s, const gs_contact_pose pose[2],
                             const gs_contact_candidate **cand, gs_index *n,
                             gs_contact_stats *stats);

/* A candidate's gap in the scene frame and its derivatives w.r.t. the
 * coordinates of both bodies, for the contact step to collect. */
typedef struct gs_contact_row {
    gs_gap gap;             /* from gs_gap_eval (order-2 master: gs_gap_eval_quad,
                             * window corners at even positions) on scene positions; gap.grad is
                             * w.r.t. scene positions (slave, then master[j]) */
    int n_nodes;            /* 1 + gap.n_master */
    int body[4];            /* gear of each node: slave first, then masters */
    gs_index node[4];       /* mesh node indices */
    double x[4][2];         /* their scene positions */
    double dg_du[4][2];     /* dg/du of each node, body frame of its gear */
    double dg_dtheta[2];    /* dg/dtheta of gear 0, gear 1 (sum over its nodes) */
    double dg_dc[2][2];     /* dg/dc of gear 0, gear 1 */
    gs_index fan_corner;    /* the master's tip corner (mesh node) whose outer normal
                             * cone holds the slave (the corner is the master's
                             * nearest point, the slave outside it), -1 otherwise:
                             * the step leaves such a row out when the corner is a
                             * slave itself (docs/explanation/contact.md "Tip corners") */
} gs_contact_row;

/* Evaluate a candidate at the poses (current displacements included):
 * positions x = c + R(theta)(X + u), gs_gap_eval on the window, then the
 * chain rule of gs_gap_chain for every node used. The linearised
 * constraint of METHOD.md section 3 is then
 *   sum_b dg_dtheta[b] dtheta_b + dg_dc[b].dc_b + sum_n dg_du[n].du_n >= 0.
 * Errors: those of gs_gap_eval, GS_EINVAL (NULL, candidate not of this
 * search). */
gs_err gs_contact_eval(const gs_contact_search *s, const gs_contact_pose pose[2],
                       const gs_contact_candidate *cand, gs_contact_row *row);

#endif
