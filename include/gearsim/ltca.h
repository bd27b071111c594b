/* SPDX-License-Identifier: MIT
 * gearsim: the loaded tooth contact analysis (LTCA) tables of a gear mesh
 * and the mesh potential built from them (docs/explanation/ltca.md).
 *
 * The quasi-static analysis of include/gearsim/stiffness.h is run on the
 * scene's own pair, at its default settings (near-field correction where it
 * applies, profile modifications included; pitch errors and run-out are
 * left to the dynamic mesh, which adds them along the line of action), at a
 * set of loads on both flanks. At every roll position j of one mesh cycle
 * that gives a table of mesh force against line-of-action deflection,
 * F_j(delta), monotone and piecewise linear through the knots
 *   back-flank loads ... back no-load closing (F = 0)
 *   front no-load closing (F = 0) ... front loads
 * (zero force between the two closings: contact loss), continued linearly
 * beyond the last knots. delta is the mesh coordinate s - s_ref of
 * include/gearsim/step.h: the static TE from the scene's initial position,
 * the no-load closing included. The potential is
 *   V(delta, p) = sum_j w_j(p) V_j(delta),  V_j = integral of F_j from the
 *   dead zone (V_j = 0 there),
 * with w_j the periodic linear interpolation weights over the mesh phase p
 * (cycles; position j at p = (j + 1/2) / n). Its force dV/ddelta
 * reproduces the table at every roll position and is monotone in delta at
 * every phase.
 *
 * The tables are cached in a file named by a hash of everything they depend
 * on (gs_ltca_key): the first use builds them, later uses (every sweep
 * point, every rank, every run) read them back bit for bit. */
#ifndef GEARSIM_LTCA_H
#define GEARSIM_LTCA_H

#include <stdint.h>

#include "gearsim/scene.h"
#include "gearsim/types.h"

/* Bump when the analysis or the table's construction changes: part of the
 * cache key. */
#define GS_LTCA_VERSION "ltca-table-3"

typedef struct gs_ltca_table {
    int n;            /* roll positions over one mesh cycle */
    int m;            /* knots per position */
    int zero_back;    /* knot index of the back flank's no-load closing (the front's is + 1) */
    double *d;        /* n x m deflections, m, increasing along each position's row */
    double *f;        /* n x m forces along the line of action, N (increasing) */
    double *v;        /* n x m potential at the knots, J (0 at the closings) */
    double force_scene; /* the load of the analysis's default case (the scene's load on the
                         * driver, else 200 N/mm; a train's mesh: its static share of the
                         * scene's moments), N: one of the front knots */
    int knot_scene;   /* its knot index */
    double base_radius_m; /* of the driver */
    double k_mean;    /* mean over the positions of the tangent stiffness at force_scene, N/m */
    double body_compliance; /* m/N along the line of action: the share of the static compliance
                             * in the gears' bodies (web, hub; linear, the same at every position),
                             * from the FE pair's own torsional mesh modes, each gear on its own
                             * axis (a train's meshes too: internal gears, planets) */
    int np;           /* tooth-pair slots per position */
    int *pair_tooth;  /* n x np x 2: the teeth of mesh gears 0 and 1 of each tooth pair the
                       * analysis at force_scene found in contact (-1: empty slot), in the
                       * table's first mesh cycle (position j at (j + 1/2) / n) */
    double *pair_share; /* n x np: the pair's share of the mesh force there (summing to 1) */
    double build_cpu_s; /* CPU seconds the analyses took (0 when read from a cache) */
    int from_cache;   /* 1 when read from a cache file */
    uint64_t key;
} gs_ltca_table;

void gs_ltca_table_clear(gs_ltca_table *t);

/* Build from n positions and m knots per position given in any order per
 * position as (d, f) pairs (n x m each, copied): sorts each row by force,
 * checks that the deflection grows strictly with the force and that one
 * zero-force pair on each side marks the dead zone (zero_back: the index
 * of the back closing after sorting, the pair whose force is 0 and
 * deflection the smaller), and integrates V. GS_ERANGE when a row is not
 * monotone (d names "ltca"). */
gs_err gs_ltca_table_set(gs_ltca_table *t, int n, int m, const double *d, const double *f, gs_diag *dg);

/* The dynamic tables (docs/explanation/ltca.md "Body compliance"): in the
 * vibration of the mesh the gears' inertia sits mostly on the teeth's side
 * of the bodies' compliance, which carries the mean load; so the mesh force
 * acts through the teeth's compliance alone and the bodies' stays at the
 * mean force F_mean: every knot's deflection moves by
 *   d -> d - body_compliance (f - F_mean),
 * the same static TE at F_mean, the tangent stiffer. Re-integrates V and
 * updates k_mean; GS_ERANGE when a row would not stay monotone. */
gs_err gs_ltca_table_dynamic(gs_ltca_table *t, double f_mean, gs_diag *dg);

/* Force F_j(x) of position j, its slope dF/dx, and the potential V_j(x). */
double gs_ltca_row_force(const gs_ltca_table *t, int j, double x, double *slope);
double gs_ltca_row_energy(const gs_ltca_table *t, int j, double x);
/* The mesh potential and its partial derivatives at deflection x and phase
 * p (cycles from the table's start; any real number, periodic). */
double gs_ltca_energy(const gs_ltca_table *t, double x, double p);
double gs_ltca_force(const gs_ltca_table *t, double x, double p, double *dvdp);

/* The exact discrete gradient between (x0, p0) and (x0 + dx, p0 + dp):
 * the symmetrised coordinate-increment gradient
 *   gx = 1/2 [V(x1, p0) - V(x0, p0) + V(x1, p1) - V(x0, p1)] / dx,
 *   gp = 1/2 [V(x0, p1) - V(x0, p0) + V(x1, p1) - V(x1, p0)] / dp,
 * so that gx dx + gp dp = V(x1, p1) - V(x0, p0), each quotient formed
 * without cancellation (the mean of a piecewise-linear function over the
 * interval); the limits when dx or dp is 0. jac (may be NULL): the
 * derivatives of (gx, gp) in (dx, dp): jac[0] dgx/ddx, jac[1] dgx/ddp,
 * jac[2] dgp/ddx, jac[3] dgp/ddp. */
void gs_ltca_grad(const gs_ltca_table *t, double x0, double dx, double p0, double dp, double *gx, double *gp,
                  double jac[4]);

/* The closings (zero-force knots, back and front) interpolated at phase p. */
void gs_ltca_closing(const gs_ltca_table *t, double p, double *back, double *front);

typedef struct gs_ltca_opts {
    int positions;    /* roll positions per mesh cycle (default 48, or $GEARSIM_LTCA_POSITIONS) */
    const char *cache_dir; /* NULL: $GEARSIM_LTCA_CACHE, else $XDG_CACHE_HOME/gearsim/ltca,
                            * else $HOME/.cache/gearsim/ltca; "" no cache */
} gs_ltca_opts;
void gs_ltca_opts_defaults(gs_ltca_opts *o);

/* The hash of everything the tables of mesh `mesh` of sc depend on: both
 * gears' parameters, materials, mesh densities and profile modifications,
 * their placement and scene angles, the scene's load on the driver, the
 * positions, the load set, the settings of the quasi-static analyses and
 * of the modal analysis that measures the bodies' compliance (as their
 * defaults give them), GS_LTCA_VERSION and $GEARSIM_LTCA_NEARFIELD
 * when set (0: the analysis with the plain FE contact, as the elastic
 * gears' dynamic contact; 1, 2: gs_stiffness_opts.nearfield) (pitch errors
 * and run-out are not in it: the tables are of the gears without them). */
uint64_t gs_ltca_key(const gs_scene *sc, int mesh, const gs_ltca_opts *o);

/* The tables of mesh `mesh` of sc: read from the cache when a file of its
 * key is there, else built by the quasi-static analyses and written to the
 * cache (atomically; a cache that cannot be written is skipped). Errors:
 * those of the analysis (d names meshes[i]), GS_ENOMEM. */
gs_err gs_ltca_tables(const gs_scene *sc, int mesh, const gs_ltca_opts *o, gs_ltca_table *t, gs_diag *d);

/* The change of the tooth index in contact of gear k (0, 1) of mesh `mesh`
 * per mesh cycle of its phase (c . q, growing with the driver's rotation):
 * -1 for the driver (each pitch brings the tooth before into the contact),
 * +1 for an external mate, -1 for a ring. */
int gs_ltca_tooth_step(const gs_scene *sc, int mesh, int k);

/* The cache directory o selects (NULL when none). */
const char *gs_ltca_cache_dir(const gs_ltca_opts *o, char *buf, size_t size);

#endif
