/* SPDX-License-Identifier: MIT
 * Library-internal view of the `compliant` mesh model (src/models/
 * compliant_mesh.c), for its validation test: the pair geometry the model
 * uses at a point of the path of contact, and its tabulated laws, so that a
 * test can solve the static balance directly with gs_compliant_solve. */
#ifndef GEARSIM_MODELS_COMPLIANT_MESH_H
#define GEARSIM_MODELS_COMPLIANT_MESH_H

#include "gearsim/models.h"

/* One tooth pair in contact at distance v (m) along the path of contact from
 * the start of active profile of the phase gear ("pinion", the mesh's
 * external gear that counts the mesh phase), v in [0, L]. */
typedef struct gsi_compliant_point {
    double rho[2];     /* radii of curvature of the pinion's and the other's flank, m */
    double radius;     /* relative radius R: 1/R = 1/rho_p +- 1/rho_o (- for a ring),
                          m */
    double datum;      /* displacement datum of the patch model, m */
    double e_star;     /* plane-strain contact modulus, Pa */
    double k_bend;     /* pair tooth stiffness (both teeth, every term of the
                        * `bending` option in series), N/m over the face width;
                        * INFINITY with "bending": "none" */
    double k_beam;     /* the cantilevers alone (both teeth in series), N/m;
                        * INFINITY with "none" */
    double k_found;    /* the fillet-foundation terms alone (both gears in
                        * series), N/m; INFINITY unless "beam_foundation" */
    double face_width; /* contact line length b, m */
} gsi_compliant_point;

typedef struct gsi_compliant_info {
    double path_length, base_pitch, transition; /* m, m, fraction of a base pitch */
    int stations, loads, patches;
    double max_line_load; /* N/m */
    int bending;          /* 0 none, 1 beam, 2 beam_foundation */
    /* Sainsot's fillet-foundation coefficients of each gear ([0] the
     * pinion), for the record: h_fi = r_f / r_int, theta_f (rad), L*, M*,
     * P*, Q*; zero for a ring (no foundation term) */
    double h_fi[2], theta_f[2], lmpq[2][4];
} gsi_compliant_info;

/* The model's data of a built `compliant` mesh; false for another model. */
bool gsi_compliant_info_get(const gs_gmesh_rt *m, gsi_compliant_info *info);
/* The pair geometry at v (clamped to the path). */
void gsi_compliant_point_at(const gs_gmesh_rt *m, double v, gsi_compliant_point *pt);
/* The model's force-approach law of one pair at v: force (N) at approach
 * delta (m) from the tabulation (interpolated between stations). */
double gsi_compliant_pair_force(const gs_gmesh_rt *m, double v, double delta);
/* Positions v of the pairs in contact at phase phi on flank sigma (+1: the
 * drive side x > 0, -1 the coast side) with their weights (1 inside the
 * path, ramping over the transition at its ends); returns the count (<= max).
 */
int gsi_compliant_pairs(const gs_gmesh_rt *m, double phi, int sigma, double *v, double *weight, int max);

#endif
