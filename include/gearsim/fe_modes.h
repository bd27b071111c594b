/* SPDX-License-Identifier: MIT
 * gearsim: the torsional mesh modes of an elastic gear pair from the FE
 * model's own generalised eigenproblem (docs/explanation/modal.md "FE mesh modes").
 *
 * Both gears of a scene mesh are the FE bodies of the time integration: the
 * elastic unknowns u of each (CST or quadratic triangles, fixed hub nodes
 * held) and its rigid rotation theta, with the consistent mass matrix
 * M = [[M_e, s], [s', I]] (s the angular coupling, I the whole inertia with
 * the rigid core) and the stiffness K = [[K_e, 0], [0, 0]]; each axis turns
 * freely (the rigid rotation of the pair is a mode at 0 Hz). They are
 * coupled at the loaded static contact of the quasi-static analysis
 * (include/gearsim/stiffness.h) at each roll position: the rows that carry
 * force there, linearised at the deformed position (G q = 0: the contact
 * constraint of the dynamic model held closed), each row made conjugate to
 * the rolling (gs_fe_modes_conjugate_row). Modes:
 *
 *     K q = w^2 M q,   G q = 0,
 *
 * by Lanczos (M inner product, full reorthogonalisation) on the shifted,
 * constrained inverse (K + c M)^{-1} M restricted to G q = 0, each body's
 * K_e + c M_e factored once with CHOLMOD (theta a border, as in the time
 * step), c = (2 pi f_est)^2 from the secant mesh stiffness. The first mode
 * above 0 Hz is the first torsional mesh mode; `rotation` (the share of a
 * mode's kinetic energy in the rigid rotations I theta^2 / 2) tells it from
 * body modes. The lumped check: two inertias on a spring along the line of
 * action, w^2 = k (rb1^2 / I1 + rb2^2 / I2), with the tangent mesh
 * stiffness of the same position and the FE bodies' inertias.
 *
 * Not collective; allocates; the scene is only read. */
#ifndef GEARSIM_FE_MODES_H
#define GEARSIM_FE_MODES_H

#include "gearsim/scene.h"
#include "gearsim/types.h"

#define GS_FE_MODES_MAX 8

typedef struct gs_fe_modes_opts {
    int positions;    /* roll positions over one mesh cycle (default 12) */
    int modes;        /* modes above 0 Hz reported per position, 1..GS_FE_MODES_MAX (default 4) */
    int refine;       /* -1 (default): the scene's mesh density; else 0..6 for both gears */
    int order;        /* 0 (default): the scene's element order; else 1 or 2 */
    double torque_nm; /* as gs_stiffness_opts (0: the scene's load on gear 0 of the mesh) */
    int lanczos;      /* Lanczos steps (default 60) */
    double phase;     /* start of the roll in driver pitches beyond the scene angle, as
                       * gs_stiffness_opts (default 0) */
    int nearfield;    /* the static contact's near-field (Hertz) correction, as
                       * gs_stiffness_opts.nearfield: 2 (default, auto), 1 on, 0 off (the
                       * plain FE). On, each corrected tooth pair's rows are held with its
                       * tangent series compliance (gs_stiffness_run_nearfield):
                       * G q + C lambda = 0 instead of G q = 0 */
    int nearfield_secant; /* 1: each pair's secant compliance (approach / load) instead of the
                       * tangent, as the dynamic contact's "nearfield" springs hold it
                       * (the linearisation of the time-stepped model); default 0 */
} gs_fe_modes_opts;

void gs_fe_modes_opts_defaults(gs_fe_modes_opts *o);

typedef struct gs_fe_modes_point {
    double roll;                    /* position in the mesh cycle, [0, 1) */
    int rows;                       /* contact rows held closed (force > 0) */
    double hz[GS_FE_MODES_MAX];     /* the lowest modes above 0 Hz, ascending */
    double rotation[GS_FE_MODES_MAX]; /* share of each mode's kinetic energy in the rigid
                                     * rotations */
    double residual[GS_FE_MODES_MAX]; /* |K q - w^2 M q| / |w^2 M q| of each mode, on the
                                     * constrained space (G q = 0 holds to round-off) */
    double k_tan;                   /* tangent mesh stiffness here, N/m (central difference, 10 %) */
    double lumped_hz;               /* sqrt(k_tan (rb1^2/I1 + rb2^2/I2)) / 2 pi */
    double lever_departure;         /* largest |departure| of gs_fe_modes_conjugate_row over
                                     * the rows held (relative, before the correction) */
} gs_fe_modes_point;

typedef struct gs_fe_modes_result {
    int positions, modes;
    gs_fe_modes_point *pt;          /* positions entries (owned) */
    gs_index nodes[2];              /* FE nodes of gear 0, gear 1 of the mesh */
    gs_index unknowns;              /* elastic unknowns of both + 2 rotations */
    double inertia[2];              /* I of each FE body (elastic part and core), kg m^2 */
    double base_radius[2];          /* m */
    double torque_nm;               /* the load of the static contact */
    double mean_hz, min_hz, max_hz; /* first mesh mode over the positions */
    double k_tan_mean;              /* N/m */
    double lumped_mean_hz;          /* closed form with k_tan_mean */
    double seconds;
} gs_fe_modes_result;

/* Analyse mesh mesh_index of sc (both gears elastic in the analysis, whatever
 * their scene model). Errors (d names the field): those of
 * gs_stiffness_begin / next ("meshes", "positions", "refine", "torque", ...),
 * GS_ERANGE ("modes", "lanczos"), GS_ESINGULAR (a factorisation failed),
 * GS_ENOMEM. */
gs_err gs_fe_modes_analyse(const gs_scene *sc, int mesh_index, const gs_fe_modes_opts *o,
                           gs_fe_modes_result *out, gs_diag *d);
void gs_fe_modes_result_clear(gs_fe_modes_result *r);

/* Make one contact row's rigid part conjugate to the rolling of the pair.
 * The exact involute pair rolls freely: a row's lever arms dg/dtheta are
 * -+ rb of each gear (the normal on the line of action), so the rolling
 * theta = (1 / rb0, sigma / rb1) (sigma = -1 external, +1 internal: the
 * opposite of the sign of a0 a1) leaves every gap closed. On the discretised
 * flanks the normal at a loaded node departs from the line of action (the
 * parabolic edges' normals and the tip corners: up to 0.5 % of the lever arm
 * on the default order-2 mesh of contact_drive, two rows' lever ratios up to
 * 1.6 % apart), and two rows held closed
 * whose lever ratios differ then lock the rolling through the teeth's
 * elasticity: a spurious mode of 17-144 Hz with the whole kinetic energy in
 * the rotations (docs/explanation/modal.md). The correction gives both lever arms the
 * mean of their relative departures from the base radii:
 * eps = a0 / rb0 + sigma a1 / rb1, a0 -= eps rb0 / 2, a1 -= sigma eps rb1 / 2
 * (then a0 / rb0 + sigma a1 / rb1 = 0). Returns |eps| / (|a0| / rb0 + |a1| / rb1)
 * (the relative departure before the correction; 0 when the lever arms
 * are zero). */
double gs_fe_modes_conjugate_row(double dg_dtheta[2], const double rb[2]);

/* The result as JSON (gearsim-modal --fe --json): positions, modes,
 * nodes, unknowns, inertia, base_radius_mm, torque_nm, mean_hz, min_hz,
 * max_hz, k_tan_mean, lumped_mean_hz, seconds, points[] (roll, rows, hz[],
 * rotation[], residual[], k_tan, lumped_hz, lever_departure). */
struct json_object;
struct json_object *gs_fe_modes_json(const gs_fe_modes_result *r);

#endif
