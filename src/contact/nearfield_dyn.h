/* SPDX-License-Identifier: MIT
 * gearsim internal: the near-field (Hertz) series compliance of the contact
 * rows of a `contact` mesh with "nearfield": true (src/contact/nearfield_dyn.c),
 * read by the contact step (src/step/contact_step.c). Not part of the public API. */
#ifndef GEARSIM_NEARFIELD_DYN_H
#define GEARSIM_NEARFIELD_DYN_H

#include "gearsim/contact.h"
#include "gearsim/scene.h"
#include "gearsim/stiffness.h"

typedef struct gsi_nf_table gsi_nf_table;

/* The table of mesh mesh_index of the scene: the quasi-static analysis of
 * the pair at its default settings (near-field correction on, the scene's
 * moment, 24 roll positions), per loaded tooth pair its near-field
 * compliance and where along the path of contact it is. */
gs_err gsi_nf_table_build(const gs_scene *sc, int mesh_index, gsi_nf_table **t, gs_diag *d);
void gsi_nf_table_free(gsi_nf_table **t);

/* Series compliance (m/N) of the tooth pair of contact row r, gear centres
 * c0, c1 (scene frame): the table's at the row's slave point along the path
 * of contact; 0 for a row on the other flanks. */
double gsi_nf_row_compliance(const gsi_nf_table *t, const gs_contact_row *r, const double c0[2],
                             const double c1[2]);

/* The pair's gap offset (the node-sampling part of its rigid gap, the
 * quasi-static analysis's gsi_stiff_nf_offsets) taken off row r of
 * candidate c, evaluated at the poses: r->gap.g less the offset at the
 * angle of the pair's tooth of gear 1 from the centre line, and the
 * offset's slope in r's derivatives w.r.t. gear 1's angle and both centres.
 * Nothing for a row on the other flanks. */
void gsi_nf_row_offset(const gsi_nf_table *t, const gs_mesh *m0, const gs_mesh *m1, const gs_contact_candidate *c,
                       const gs_contact_pose pose[2], gs_contact_row *r);

/* Tooth pair of candidate c of a search between meshes m0 and m1 (gear 0's
 * tooth times gear 1's tooth count plus gear 1's tooth). */
int gsi_nf_pair(const gsi_nf_table *t, const gs_mesh *m0, const gs_mesh *m1, const gs_contact_candidate *c);

/* As gs_stiffness_run_nearfield, the secant compliance c = delta_H / P - L
 * of each corrected pair (the dynamic springs') instead of the tangent. */
int gsi_nf_run_secant(const gs_stiffness_run *run, int *pair, double *c_sec);

/* Samples of the table (for tests and tools): key (m along the normal of
 * the centre line from gear 0's centre), secant and tangent compliance (m/N),
 * the pair's load (N). Returns the number of samples. */
int gsi_nf_table_samples(const gsi_nf_table *t, const double **key, const double **c_sec,
                         const double **c_tan, const double **load);

/* The gap offsets' samples (for tests and tools): key (rad, the angle of
 * the pair's tooth of gear 1 from the centre line), offset per slave gear
 * (m). Returns the number of samples. */
int gsi_nf_table_offsets(const gsi_nf_table *t, const double **key, const double (**off)[2]);

#endif
