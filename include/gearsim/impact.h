/* SPDX-License-Identifier: MIT
 * gearsim: frictional impact of rigid bodies and compliant contact patches
 * (METHOD.md section 6; docs/explanation/impact.md for the derivations and figures).
 *
 * Three layers:
 *  1. one planar frictional impact at a point, integrated in the normal
 *     impulse (Routh's method) in closed form per phase, with Newton's,
 *     Poisson's or Stronge's restitution hypothesis (gs_impact_solve);
 *  2. several simultaneous contacts as a velocity-level time step
 *     (Stewart-Trinkle LCP, friction cone as two directions), solved by
 *     Lemke's method (gs_lcp_lemke, gs_impact_multi_solve) and, frictionless,
 *     cross-checked as a QP with gs_qp;
 *  3. a compliant line contact split into N strips with the influence
 *     coefficients of the elastic half-plane, frictionless, solved as the QP
 *     of minimum complementary energy (gs_compliant_solve), and with
 *     Coulomb friction under a tangential load (partial slip) as an LCP
 *     (gs_compliant_solve_friction).
 *
 * Planar vectors are {x, y}; angular quantities are about +z. Units are any
 * consistent set (SI in the tools). No call involves MPI; nothing keeps
 * state between calls, so every call is thread-safe. */
#ifndef GEARSIM_IMPACT_H
#define GEARSIM_IMPACT_H

#include "gearsim/types.h"

/* ------------------------------------------------------------ one impact */

/* A rigid body in the plane. A fixed body (ground) has infinite mass and
 * inertia: mass and inertia are then ignored and its velocity is kept. */
typedef struct gs_impact_body {
    double mass;        /* > 0 unless fixed */
    double inertia;     /* about the centre of mass, > 0 unless fixed */
    double centre[2];   /* centre of mass */
    double velocity[2]; /* of the centre of mass, before impact */
    double omega;       /* angular velocity before impact */
    bool fixed;
} gs_impact_body;

typedef enum {
    GS_RESTITUTION_NEWTON,  /* kinematic: v_n,final = -e v_n,0 */
    GS_RESTITUTION_POISSON, /* kinetic: P_n,final = (1 + e) P_n,compression */
    GS_RESTITUTION_STRONGE  /* energetic: normal work of restitution = -e^2 x that of compression */
} gs_restitution;

/* Name ("newton", "poisson", "stronge") and parse; parse returns false on an unknown name. */
const char *gs_restitution_name(gs_restitution law);
bool gs_restitution_parse(const char *name, gs_restitution *law);

/* What happened to the slip during the impact (docs/explanation/impact.md, "processes"). */
typedef enum {
    GS_IMPACT_NONE,                  /* not approaching (v_n,0 >= 0): no impulse */
    GS_IMPACT_FRICTIONLESS,          /* mu = 0 */
    GS_IMPACT_SLIDING,               /* slip in one direction throughout (forward sliding) */
    GS_IMPACT_STICK_COMPRESSION,     /* slip stops in compression (or at rest), then sticks */
    GS_IMPACT_STICK_RESTITUTION,     /* slip stops in restitution, then sticks */
    GS_IMPACT_REVERSAL_COMPRESSION,  /* slip stops in compression and reverses */
    GS_IMPACT_REVERSAL_RESTITUTION   /* slip stops in restitution and reverses */
} gs_impact_process;

/* Stable lower-case name ("none", "frictionless", "sliding", "stick_compression", ...). */
const char *gs_impact_process_name(gs_impact_process p);

/* Two bodies touching at `point`. `normal` points from body 1 into body 0
 * (it is normalised here); the impulse on body 0 is +P, on body 1 -P. The
 * tangent is t = (-n_y, n_x). At most one body may be fixed. */
typedef struct gs_impact_case {
    gs_impact_body body[2];
    double point[2];
    double normal[2];
    double e;  /* coefficient of restitution, [0, 1] */
    double mu; /* Coulomb friction coefficient, >= 0 */
    gs_restitution law;
} gs_impact_case;

/* The impact in contact coordinates (t, n): v(P) = v0 + W P. */
typedef struct gs_impact_contact_problem {
    double W[3];  /* W_tt, W_tn, W_nn: symmetric positive definite */
    double v0[2]; /* v_t0, v_n0: relative contact velocity before impact */
    double e, mu;
    gs_restitution law;
} gs_impact_contact_problem;

typedef struct gs_impact_result {
    gs_impact_process process;
    double impulse_n, impulse_t;  /* P_n >= 0 and P_t, on body 0, along n and t */
    double impulse_n_compression; /* P_n at the end of compression (v_n = 0) */
    double impulse_n_slip_stop;   /* P_n where the initial slip stops; < 0 if it does not within the impact */
    double v0[2], v[2];           /* relative contact velocity (t, n) before and after */
    double work_n_compression;    /* int v_n dP_n over compression (<= 0) */
    double work_n_restitution;    /* int v_n dP_n over restitution (>= 0) */
    double dissipation_n;         /* -(work_n_compression + work_n_restitution) */
    double dissipation_t;         /* -int v_t dP_t (>= 0: friction opposes slip) */
    double dissipation;           /* dissipation_n + dissipation_t = kinetic energy lost */
    /* Filled by gs_impact_solve only: */
    double velocity[2][2];        /* body velocities after impact */
    double omega[2];
    double energy_before, energy_after; /* kinetic energy of the free bodies */
    double W[3];                  /* inverse effective mass in (t, n) */
    double tangent[2], normal[2]; /* the contact frame used */
} gs_impact_result;

/* Solve one impact in contact coordinates (Routh's method, closed form per
 * phase). Errors: GS_EINVAL (NULL), GS_ERANGE (W not positive definite,
 * e outside [0, 1], mu < 0, non-finite data), with the field named in d. */
gs_err gs_impact_contact(const gs_impact_contact_problem *p, gs_impact_result *r, gs_diag *d);

/* Solve one impact between two bodies: builds W and v0 from the bodies and
 * the contact point, calls gs_impact_contact and applies the impulse.
 * Errors: those of gs_impact_contact; GS_ERANGE for non-positive mass or
 * inertia of a free body, both bodies fixed, a zero normal; fields named as
 * in the case JSON ("bodies[1].mass", "normal", ...). */
gs_err gs_impact_solve(const gs_impact_case *c, gs_impact_result *r, gs_diag *d);

/* ------------------------------------------------------------ LCP */

/* w = A z + q, z >= 0, w >= 0, z^T w = 0, by Lemke's complementary pivoting
 * with covering vector 1 and a lexicographic ratio test. */
typedef enum {
    GS_LCP_SOLVED,     /* z, w a solution (verified against A and q) */
    GS_LCP_RAY,        /* secondary ray: no solution found; for copositive-plus A, none exists */
    GS_LCP_MAX_ITER,   /* pivot cap reached */
    GS_LCP_INACCURATE  /* terminated, but the verified residual exceeds the tolerance */
} gs_lcp_status;

const char *gs_lcp_status_name(gs_lcp_status s);

typedef struct gs_lcp_info {
    gs_lcp_status status;
    int pivots;
    double residual;  /* max over i of |min(z_i, w_i)| and the negative parts, relative to scale */
    int n_degenerate; /* indices with z_i = w_i = 0 (to tolerance): other solutions may branch off */
    int n_active;     /* indices with z_i > 0 */
    int rank_active;  /* numerical rank of A restricted to the active indices */
    bool multiple;    /* rank_active < n_active: a line of solutions z + t d passes
                       * through z. Lemke ends on a basis, so this shows only for
                       * data given to other solvers; see also n_degenerate. */
} gs_lcp_info;

/* Solve the LCP (A n*n row-major). z and w (n each) are written. max_pivots
 * <= 0 means 50 n + 100. Returns GS_OK when solved; GS_EINFEASIBLE on ray
 * termination, GS_ENOCONV on the pivot cap or an inaccurate result (info
 * says which); GS_EINVAL, GS_ENOMEM. */
gs_err gs_lcp_lemke(int n, const double *A, const double *q, double *z, double *w, int max_pivots,
                    gs_lcp_info *info);

/* ------------------------------------------------------------ several contacts */

/* A contact between bodies body[0] and body[1] (indices into the body
 * array; a fixed body may be used as ground), normal from body[1] into
 * body[0], as in gs_impact_case. */
typedef struct gs_impact_point {
    int body[2];
    double point[2];
    double normal[2];
    double e, mu;
} gs_impact_point;

typedef struct gs_impact_multi {
    int n_body;
    const gs_impact_body *bodies;
    int n_contact;
    const gs_impact_point *contacts;
    double h;          /* time step (0: a pure impact) */
    double gravity[2]; /* acceleration applied to the free bodies over h */
} gs_impact_multi;

/* Caller-owned arrays, filled by gs_impact_multi_solve. */
typedef struct gs_impact_multi_result {
    double *velocity;  /* [2 n_body] after the step */
    double *omega;     /* [n_body] */
    double *impulse_n; /* [n_contact] */
    double *impulse_t; /* [n_contact], along t = (-n_y, n_x) */
    gs_lcp_info lcp;
    int lcp_size;      /* 4 n_contact (normal, two friction directions, slip speed) */
    bool several;      /* the impulses are not unique: impulse can be moved between
                        * contacts without changing velocities (docs/explanation/impact.md) */
    double energy_before, energy_after;
} gs_impact_multi_result;

/* One velocity-level step with Newton restitution (N v+ >= -e N v-) and
 * Coulomb friction, posed as the Stewart-Trinkle LCP and solved by Lemke's
 * method. Errors: GS_EINVAL/GS_ERANGE for bad input (field named),
 * GS_EINFEASIBLE (ray termination), GS_ENOCONV, GS_ENOMEM. */
gs_err gs_impact_multi_solve(const gs_impact_multi *m, gs_impact_multi_result *r, gs_diag *d);

/* The same step without friction (mu ignored) as the QP
 *   min 1/2 (v - v_free)^T M (v - v_free)  s.t.  N v >= -e N v-
 * with gs_qp: a cross-check of the LCP. r->lcp is zeroed. Errors: as above,
 * plus those of gs_qp. */
gs_err gs_impact_multi_solve_qp(const gs_impact_multi *m, gs_impact_multi_result *r, gs_diag *d);

/* ------------------------------------------------------------ compliant contact */

/* A frictionless line contact (plane strain) under a load per unit length,
 * between profiles whose initial separation at x is h(x) = x^2 / (2 R)
 * (cylinder of radius R on a plane, or two cylinders with 1/R = 1/R1 + 1/R2),
 * or a given h sampled at the strip centres. */
typedef struct gs_compliant_problem {
    int n;              /* strips, >= 1 */
    double x0, x1;      /* the candidate contact region [x0, x1], split into n equal strips */
    double radius;      /* R > 0, used when gap is NULL */
    const double *gap;  /* [n] initial separation at the strip centres, or NULL */
    double e_star;      /* plane-strain contact modulus E* > 0 */
    double load;        /* P > 0, force per unit length */
    double datum;       /* distance of the displacement datum; <= 0: 10 (x1 - x0) */
    /* Friction (gs_compliant_solve_friction only): */
    double mu;          /* Coulomb coefficient >= 0 */
    double load_t;      /* tangential load Q per unit length on body 1, |Q| <= mu P */
} gs_compliant_problem;

typedef struct gs_compliant_result {
    double *x;        /* [n] strip centres (caller-owned, or NULL) */
    double *pressure; /* [n] (caller-owned) */
    double approach;  /* rigid approach delta relative to the datum */
    double half_width;   /* contact half-width from the pressure edges (docs/explanation/impact.md) */
    double peak;         /* max pressure */
    int n_loaded;        /* strips with p > 0 */
    int qp_iterations;
    /* Filled by gs_compliant_solve_friction only: */
    double *traction;    /* [n] tangential traction q (caller-owned, or NULL) */
    double shift;        /* rigid tangential shift of body 1 relative to body 2 */
    double stick_half_width; /* half-width of the stick zone from the traction deficit
                              * mu p - |q| (docs/explanation/impact.md); 0 in full slip */
    int n_stick;         /* loaded strips that stick */
    gs_lcp_info lcp;
} gs_compliant_result;

/* Influence coefficient: normal displacement (sum of both bodies) at
 * distance s from the centre of a strip of width w carrying unit uniform
 * pressure, half-plane plane strain, relative to a datum at distance datum:
 *   u = (2 / (pi E*)) [ F(s + w/2) - F(s - w/2) ],  F(u) = u - u ln(|u| / datum). */
double gs_compliant_influence(double s, double width, double e_star, double datum);

/* Solve the frictionless patch problem as the QP
 *   min 1/2 f^T C f + h^T f   s.t.  f >= 0, sum f = P      (f = p w)
 * whose KKT conditions are non-penetration, f >= 0 and complementarity, with
 * the approach as the equality's multiplier. Errors: GS_ERANGE (field
 * named), GS_ENOMEM, and those of gs_qp. */
gs_err gs_compliant_solve(const gs_compliant_problem *p, gs_compliant_result *r, gs_diag *d);

/* The same contact under a tangential load Q = p->load_t (per unit length)
 * with Coulomb friction p->mu: first the normal pressure as above, then the
 * tangential strip forces t_j on the loaded strips as the LCP (Lemke)
 *   stick:  u_t(x_j) = shift,            |t_j| <  mu f_j
 *   slip:   slip along t_j,              |t_j| =  mu f_j
 *   sum t_j = Q,
 * with the tangential influence coefficients equal to the normal ones
 * (plane strain half-plane). Normal and tangential problems are solved
 * uncoupled: exact for identical materials (Dundurs beta = 0), the Goodman
 * approximation otherwise. One loading from zero to Q (Cattaneo–Mindlin:
 * the final state does not depend on the path for a monotonic load).
 * r->traction must be non-NULL. Errors: those of gs_compliant_solve;
 * GS_ERANGE "mu" (< 0 or not finite), "load_t" (|Q| > mu P: gross sliding,
 * or not finite); GS_EINFEASIBLE / GS_ENOCONV from Lemke (r->lcp says). */
gs_err gs_compliant_solve_friction(const gs_compliant_problem *p, gs_compliant_result *r, gs_diag *d);

#endif
