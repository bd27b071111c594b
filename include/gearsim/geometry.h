/* SPDX-License-Identifier: MIT
 * gearsim: involute spur gear geometry (METHOD.md section 5).
 *
 * Owned by the geometry module. The parameter struct below is the contract
 * with the scene module, which fills it from a scene's gear body; everything
 * after it belongs to the geometry module. All lengths in metres, angles in
 * radians. */
#ifndef GEARSIM_GEOMETRY_H
#define GEARSIM_GEOMETRY_H

#include "gearsim/types.h"

typedef enum { GS_GEAR_EXTERNAL = 0, GS_GEAR_INTERNAL = 1 } gs_gear_kind;

typedef struct gs_gear_params {
    gs_gear_kind kind;
    int teeth;                 /* z */
    double module_m;           /* m, metres */
    double pressure_angle;     /* alpha, rad (20 deg default) */
    double addendum_coef;      /* h_a*, default 1.0 */
    double dedendum_coef;      /* h_f*, default 1.25 */
    double fillet_coef;        /* rho_f*, default 0.38 */
    double profile_shift;      /* x, default 0 */
    double thinning_m;         /* backlash thinning of the tooth on the pitch circle, metres */
    double face_width_m;       /* b */
    double hub_radius_m;       /* rigid core radius (external); for a ring, the outer rim radius */
} gs_gear_params;

/* Defaults for everything except kind, teeth, module and face width. */
void gs_gear_params_defaults(gs_gear_params *p);

/* Pitch radius m z / 2. */
static inline double gs_gear_pitch_radius(const gs_gear_params *p)
{
    return 0.5 * p->module_m * (double)p->teeth;
}

#endif
