/* SPDX-License-Identifier: MIT
 * gearsim: profile modifications and tooth errors of a spur gear
 * (docs/explanation/geometry.md "Profile modifications and tooth errors").
 *
 * Owned by the geometry module. A modification is a normal offset of a
 * flank from its involute, a function of the roll length
 * L(R) = sqrt(R^2 - rb^2) of the involute point at radius R (rb times the
 * roll angle tan(phi)). The modified flank is, in the polar form of
 * gs_gear_involute_psi(),
 *
 *     psi_mod(R) = psi(R) + f(L(R)) / rb,
 *
 * f the offset in metres, positive adding material (a turned involute is
 * the parallel curve at distance rb x angle, so f is the normal offset from
 * the involute); relief removes material, f = -C. The radius of every point
 * is kept: the tip corner stays on the tip circle and the form point on
 * its radius.
 *
 * Tip relief of amount Ca starting at radius R_s (roll length L_s):
 *     C(L) = Ca u^p,   u = (L - L_s) / (L_tip - L_s) for u in (0, 1], else 0,
 * p = 1 linear, 2 parabolic; root relief alike towards the form point. For a
 * ring the tip is the smaller radius; the formula is the same. A measured
 * deviation table adds f = table(roll angle), piecewise linear, constant
 * beyond its ends.
 *
 * Tooth errors: tooth k turned along the pitch circle by e_k (a table, one
 * value per tooth, counter-clockwise positive: its position deviation, i.e.
 * the cumulative pitch deviation), and run-out: the toothed body's centre
 * offset from the rotation axis by the eccentricity at a phase angle in the
 * body frame.
 *
 * Plain data; the functions are pure. Applying a set to a gear's FE mesh
 * belongs to the mesh layer (gs_gear_mods_apply_mesh, gearsim/mesh.h). */
#ifndef GEARSIM_MODIFICATION_H
#define GEARSIM_MODIFICATION_H

#include "gearsim/geometry.h"
#include "gearsim/types.h"

#define GS_MOD_TABLE_MAX 64

typedef struct gs_relief {
    double amount_m;       /* material removed at the end (tip / form point), 0: none */
    double start_radius_m; /* where the relief begins (resolved from the scene's diameter or roll length) */
    int parabolic;         /* 0 linear, 1 parabolic */
} gs_relief;

typedef struct gs_flank_mod {
    gs_relief tip, root;
    int n_dev;                        /* measured deviation table points, 0: none */
    double dev_roll[GS_MOD_TABLE_MAX];/* roll angle tan(phi), rad, increasing */
    double dev_m[GS_MOD_TABLE_MAX];   /* deviation, m, positive = material added */
} gs_flank_mod;

/* Flank sides: GS_FLANK_CW the clockwise side of each tooth (polar angle
 * below its centreline), GS_FLANK_CCW the counter-clockwise side. Which one
 * drives depends on the direction of the torque (docs/explanation/geometry.md). */
enum { GS_FLANK_CW = 0, GS_FLANK_CCW = 1 };

typedef struct gs_gear_mods {
    gs_flank_mod flank[2];  /* [GS_FLANK_CW], [GS_FLANK_CCW] */
    int n_pitch;            /* 0 or the tooth count */
    double *pitch_m;        /* n_pitch: tooth position deviation along the pitch circle, m (owned) */
    double runout_m;        /* eccentricity of the toothed body, m */
    double runout_phase;    /* polar angle of the offset in the body frame, rad */
} gs_gear_mods;

/* Allocate a zeroed modification set (free with gs_gear_mods_free). */
gs_gear_mods *gs_gear_mods_new(void);
void gs_gear_mods_free(gs_gear_mods **m);
/* Deep copy (NULL for NULL); NULL on allocation failure with src non-NULL sets *err. */
gs_err gs_gear_mods_copy(const gs_gear_mods *src, gs_gear_mods **dst);

/* 1 when the set changes the flank profile (relief or deviation table) on
 * either side. */
int gs_gear_mods_has_profile(const gs_gear_mods *m);
/* 1 when any field is non-zero (profile, pitch errors or run-out). */
int gs_gear_mods_any(const gs_gear_mods *m);

/* Check a set against its gear: relief amounts 0..0.5 m_n (field
 * "<prefix>.tip_relief.amount_um" ...), start radii strictly inside the
 * active flank (between form radius and tip), deviation roll angles
 * increasing, pitch table of `teeth` entries within 0.1 module, run-out
 * within 0.1 module. Field names are prefixed by `prefix` (e.g.
 * "bodies[0].modification"); pitch and run-out use `prefix_body`. */
gs_err gs_gear_mods_check(const gs_gear_geom *g, const gs_gear_mods *m, const char *prefix,
                          const char *prefix_body, gs_diag *d);

/* Normal offset f (m, + adds material) of flank `side` at radius R
 * (involute radius of the unmodified gear). 0 when m is NULL. */
double gs_gear_flank_offset(const gs_gear_geom *g, const gs_gear_mods *m, int side, double R);

/* Half tooth angle of the modified flank `side` at radius R: the polar angle
 * from the tooth centreline, psi(R) + f(R) / rb. */
double gs_gear_modified_psi(const gs_gear_geom *g, const gs_gear_mods *m, int side, double R);

/* Roll length L = sqrt(R^2 - rb^2) and its inverse. */
double gs_gear_roll_length(const gs_gear_geom *g, double R);
double gs_gear_roll_radius(const gs_gear_geom *g, double L);

#endif
