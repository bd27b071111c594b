/* SPDX-License-Identifier: MIT
 * gearsim: the measured trade-off table (docs/data/tradeoff.csv, installed as
 * share/gearsim/tradeoff.csv) and the choice of the cheapest setting that
 * meets relative-error targets on its outputs: the logic of `gearctl
 * advise` (clients/python/gearsim/advise.py), used by the scene's
 * `"fidelity": {"targets": {...}}` (docs/reference/scene.md). */
#ifndef GEARSIM_TRADEOFF_H
#define GEARSIM_TRADEOFF_H

#include <stdbool.h>
#include <stddef.h>

#include "gearsim/error.h"

#define GS_TRADEOFF_MAX_OUT 8   /* err_<output> columns read */
#define GS_TRADEOFF_MAX_ROWS 4096

/* One measured setting: the scene it was measured on, the level and its
 * numerics, the cost (CPU or wall seconds per simulated second) and the
 * relative error of every output against the scene's reference (NaN: not
 * measured). */
typedef struct gs_tradeoff_row {
    char scene[64], level[32], scheme[32];
    double h, cost, scale, zeta;
    int refine;
    double err[GS_TRADEOFF_MAX_OUT];
} gs_tradeoff_row;

typedef struct gs_tradeoff {
    int n_rows, n_out;
    char out[GS_TRADEOFF_MAX_OUT][24]; /* the outputs, as the err_ columns name them */
    bool cpu;                          /* costs in CPU seconds (tables with the damping column) */
    gs_tradeoff_row *rows;
} gs_tradeoff;

/* The choice: the row taken, the targets (output indices, values) and the
 * cheaper rows that miss one (cost order). */
typedef struct gs_tradeoff_choice {
    int row;
    int n_targets;
    int target_out[GS_TRADEOFF_MAX_OUT];
    double target[GS_TRADEOFF_MAX_OUT];
    int n_rejected;
    int *rejected;                     /* owned: gs_tradeoff_choice_clear */
    int n_candidates;                  /* measured settings on the scene, the reference excluded */
} gs_tradeoff_choice;

/* Where the table is read: $GEARSIM_TRADEOFF_TABLE, else the installed
 * share/gearsim/tradeoff.csv, else the source checkout's
 * docs/data/tradeoff.csv (a build run in place); the first that exists
 * (the installed path when none does). */
const char *gs_tradeoff_path(void);
/* Parse the CSV text (header: scene, level, h, cost required; refine,
 * scheme, scale, zeta and err_<output> columns read when present). */
gs_err gs_tradeoff_parse(const char *csv, size_t len, gs_tradeoff *t, gs_diag *d);
/* Read and parse the file at path. */
gs_err gs_tradeoff_load(const char *path, gs_tradeoff *t, gs_diag *d);
void gs_tradeoff_free(gs_tradeoff *t);
/* Output index of a target name (the err_ column's name, or its longer
 * alias dte_rms, peak_force, mesh_order, output_speed); -1 if none. */
int gs_tradeoff_output(const gs_tradeoff *t, const char *name);
/* The cheapest row of `scene` that is not the reference (every error 0)
 * and whose errors on the targets are all measured and at most the
 * targets; diagnostics name `field` (e.g. "fidelity.targets"). */
gs_err gs_tradeoff_choose(const gs_tradeoff *t, const char *scene, int n, const int *out, const double *target,
                          gs_tradeoff_choice *c, const char *field, gs_diag *d);
void gs_tradeoff_choice_clear(gs_tradeoff_choice *c);
/* "ltca h 0.0001" (+ " refine R", " counts x S", " (scheme)"), as advise
 * labels a setting. */
void gs_tradeoff_label(const gs_tradeoff_row *r, char *out, size_t cap);

#endif
