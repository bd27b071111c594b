/* SPDX-License-Identifier: MIT
 * LTCA tables of a helical (or lead-modified, misaligned) mesh: the slice
 * analysis in the tables (ltca_helical.c, docs/explanation/helical.md
 * "Helical pairs in the ltca rung"). */
#ifndef GS_MODELS_LTCA_HELICAL_H
#define GS_MODELS_LTCA_HELICAL_H

#include "gearsim/models.h"
#include "gearsim/scene.h"

/* 1 when the quasi-static analysis of the mesh is the slice analysis
 * (a helical gear, lead modifications or a misalignment), else 0. */
int gsi_ltca_sliced(const gs_scene *sc, int mesh);

/* The values the table key adds for what only the slice analysis reads
 * (helix angle and hand, the normal section, both gears' lead
 * modifications, the misalignment, the slice settings) into v (at least
 * GSI_LTCA_KEY_SLICED entries); returns their count, 0 for a spur pair
 * without them (its key stays). */
#define GSI_LTCA_KEY_SLICED 24
int gsi_ltca_key_sliced(const gs_scene *sc, int mesh, double *v);

/* What an ltca mesh on a sliced pair cannot take: pitch errors and run-out
 * of a helical gear (their load share follows the spur wave). */
gs_err gsi_ltca_sliced_check(const gs_model_view *sys, const gs_gmesh_rt *m, gs_diag *d);

#endif
