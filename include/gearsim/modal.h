/* SPDX-License-Identifier: MIT
 * gearsim: modal analysis of the linearised rigid/lumped train
 * (docs/explanation/modal.md).
 *
 * Every body that moves gets generalised coordinates from its joint:
 * fixed_axis a rotation; bearing x, y and the rotation; on_carrier the
 * rotation (rigid pin: its centre follows the carrier) or x, y and the
 * rotation (bearing_stiffness: a radial spring to its pin); held none. Each
 * body's physical displacement (x, y, theta) is T q; the mass matrix is
 * T' diag(m, m, I) T. Meshes act with their mean stiffness along the true
 * line of action, translations included:
 *   external  delta = n.(P_A - P_B) + rb_A th_A + rb_B th_B,
 *             n = sin(a) u + cos(a) u_perp,  u from A's centre to B's
 *   internal  delta = n.(P_R - P_P) + rb_R th_R - rb_P th_P,
 *             n = -sin(a) u + cos(a) u_perp, u from the ring's centre to the pinion's
 * a the operating pressure angle acos((rb_A +- rb_B) / centre distance); the flanks are those a
 * counter-clockwise moment on the sun (gear A) loads. Bearings add isotropic
 * radial springs and torsional springs. K q = w^2 M q is solved with LAPACK
 * dsygv; kinematic meshes are exact constraints (delta = 0): the problem is
 * solved on the null space of their rows (SVD), rigid meshes in the modes.
 * Modes of equal frequency form groups; a group is classified from
 * the kinetic energy it puts in the central members (bodies not on a
 * carrier) after Lin and Parker (1999): rotational (central members only
 * rotate), translational (they only translate), planet (they do not move),
 * mixed otherwise. Pure function of the scene; not collective. */
#ifndef GEARSIM_MODAL_H
#define GEARSIM_MODAL_H

#include "gearsim/scene.h"
#include "gearsim/types.h"

typedef enum {
    GS_MODE_ROTATIONAL = 0,
    GS_MODE_TRANSLATIONAL = 1,
    GS_MODE_PLANET = 2,
    GS_MODE_MIXED = 3
} gs_mode_kind;

typedef struct gs_modal {
    int n;                  /* generalised coordinates */
    int n_modes;            /* modes: n less the rank of the kinematic meshes' rows */
    int n_bodies;
    int *dof_body;          /* n: body of each coordinate */
    int *dof_comp;          /* n: 0 x, 1 y, 2 rotation */
    double *T;              /* 3 n_bodies x n, column-major: body (x, y, theta) = T q */
    double *M, *K;          /* n x n, column-major */
    double *G;              /* n_con x n, row-major: the kinematic meshes' rows (delta = G q) */
    int n_con;
    double *omega2;         /* n_modes eigenvalues w^2, ascending */
    double *freq_hz;        /* n_modes: sqrt(max(w^2, 0)) / 2 pi */
    double *shape;          /* n x n_modes column-major: mode j in column j, q' M q = 1 */
    double *body_shape;     /* 3 n_bodies x n_modes: body (x, y, theta) of each mode */
    int *group;             /* n_modes: group index of each mode (equal frequencies) */
    int n_groups;
    int *group_first, *group_mult; /* n_groups: first mode and multiplicity */
    int *group_kind;        /* n_groups: gs_mode_kind */
    double *group_central;  /* n_groups: share of kinetic energy in the central members */
    double *lever;          /* n_bodies: radius turning a rotation into a displacement
                             * (base radius of a gear, planet radius of a carrier) */
} gs_modal;

/* Build and solve. Errors name the field: meshes[i].model or .stiffness for
 * a mesh without a mean stiffness (contact, compliant, calibrated, impact),
 * meshes[i].gears for impossible geometry, meshes when kinematic meshes
 * lock the whole train. */
gs_err gs_modal_analyse(const gs_scene *s, gs_modal **out, gs_diag *d);
void gs_modal_free(gs_modal **m);
const char *gs_mode_kind_name(int kind);
/* Relative frequency gap below which modes count as one group. */
#define GS_MODAL_GROUP_TOL 1e-7
/* The result as JSON (docs/explanation/modal.md, proto/v1/results/modal.json). */
struct json_object;
struct json_object *gs_modal_json(const gs_modal *m, const gs_scene *s);

#endif
