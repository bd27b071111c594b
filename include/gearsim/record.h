/* SPDX-License-Identifier: MIT
 * gearsim: HDF5 output of a run (rank 0 only, serial HDF5 driver).
 *
 * Record layout (read by `gearctl plot` and users' scripts):
 *   attributes  scene (JSON), gearsim_version, time_step
 *   /telemetry  time (n), step (n, int64), energy (n x 6) with attribute
 *               columns, angle (n x bodies), omega (n x bodies) with attribute
 *               bodies (JSON list), mesh_force and mesh_deflection
 *               (n x meshes) with attribute meshes.
 * Rows are buffered and appended at gs_record_flush(); everything flushed is
 * on disk (H5Fflush) and readable by a serial reader. Not collective. */
#ifndef GEARSIM_RECORD_H
#define GEARSIM_RECORD_H

#include "gearsim/step.h"

typedef struct gs_record gs_record;

gs_err gs_record_open(const char *path, const gs_system *sys, gs_record **out, gs_diag *d);
/* Buffer one sample of the current state. */
gs_err gs_record_sample(gs_record *r, const gs_system *sys);
gs_err gs_record_flush(gs_record *r);
/* Flush and close; safe on NULL; sets *r = NULL. */
gs_err gs_record_close(gs_record **r);
const char *gs_record_path(const gs_record *r);
int64_t gs_record_rows(const gs_record *r);

/* Checkpoint files: the engine snapshot bytes in an HDF5 file with the scene
 * as an attribute for people who look inside. */
gs_err gs_checkpoint_write(const char *path, const char *bytes, size_t len, const char *scene_json,
                           int64_t step, double time, gs_diag *d);
gs_err gs_checkpoint_read(const char *path, char **bytes, size_t *len, gs_diag *d);

#endif
