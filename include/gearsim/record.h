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
 * on disk (H5Fflush) and readable by a serial reader. Not collective.
 *
 * Field snapshots of elastic bodies (docs/reference/hdf5.md, "Field snapshots"); only
 * present after gs_record_add_meshes(), a record without them is laid out
 * exactly as above. For body <name> (T = frames written, n = nodes):
 *   /bodies        attr names (JSON list, in the order given to add_meshes)
 *   /bodies/<name> attrs index (int), centre_m (double[2])
 *     nodes        (n, 2)    float64  body (material) frame, m
 *     triangles    (m, 3)    int64    counter-clockwise, 0-based
 *     fixed        (k)       int64    nodes of the rigid-core interface
 *     node_tag     (n)       int8     gs_node_tag (zeros for non-gear meshes)
 *   /fields        attr names (JSON list, same order)
 *   /fields/<name>
 *     time         (T)       float64  s
 *     step         (T)       int64
 *     theta        (T)       float64  rotation of the body, rad
 *     displacement (T, n, 3) float64  u in the body frame, m; third column 0
 *                                     (XDMF vectors have 3 components)
 *     von_mises    (T, n)    float64  Pa; NaN in frames given without stress
 *     position     (T, n, 2) float64  centre + R(theta) (nodes + u), scene frame
 * The field datasets are extendable and chunked by frame (several frames per
 * chunk only when a frame is under 64 KiB). Frames are written directly (no
 * buffering beyond one frame of scratch) and made durable by gs_record_flush();
 * the length of `time` is the number of complete frames (it is extended last).
 * With bodies, an XDMF 3 file sits beside the record (same base name, ".xmf",
 * refers to the record by base name): a Temporal collection with, per distinct
 * frame time, a Spatial collection holding a grid per body (its latest frame at
 * or before that time). It is rewritten atomically (tmp + rename) by
 * add_meshes, gs_record_flush and gs_record_close, and lists only flushed
 * frames. ParaView 5.11: open it with the "XDMF Reader"; its Xdmf3 readers
 * cannot read a HyperSlab geometry (docs/reference/hdf5.md). */
#ifndef GEARSIM_RECORD_H
#define GEARSIM_RECORD_H

#include "gearsim/mesh.h"
#include "gearsim/step.h"

typedef struct gs_record gs_record;

gs_err gs_record_open(const char *path, const gs_system *sys, gs_record **out, gs_diag *d);
/* The same, but HDF5 creates the file through `create_as` (e.g.
 * /proc/self/fd/N of a file the caller created and checked), while `path`
 * remains the record's name (gs_record_path, the XDMF file beside it). */
gs_err gs_record_open_as(const char *path, const char *create_as, const gs_system *sys, gs_record **out,
                         gs_diag *d);
/* Buffer one sample of the current state. */
gs_err gs_record_sample(gs_record *r, const gs_system *sys);
gs_err gs_record_flush(gs_record *r);
/* Flush and close; safe on NULL; sets *r = NULL. */
gs_err gs_record_close(gs_record **r);
const char *gs_record_path(const gs_record *r);
int64_t gs_record_rows(const gs_record *r);

/* An elastic body whose fields will be recorded. */
typedef struct gs_record_mesh {
    const char *name;      /* body name (group name): 1-200 characters, unique, none of
                            * / : < > & " ' or control characters, not "." */
    const gs_mesh *mesh;   /* borrowed for the call (the nodes are copied) */
    double centre[2];      /* axis position in the scene frame, m */
} gs_record_mesh;

/* Declare the elastic bodies whose fields will be recorded: writes
 * /bodies/<name>/{nodes, triangles, fixed, node_tag}, creates the empty
 * /fields/<name>/ datasets, flushes and writes the XDMF file (no frames yet).
 * Call once, after gs_record_open and before the first field frame.
 * Errors: GS_EINVAL (field "bodies[i].name" or "bodies[i].mesh", or "bodies"
 * when n < 1), GS_ESTATE (field "bodies") on a second call, GS_ENOMEM,
 * GS_EIO (field "path"). */
gs_err gs_record_add_meshes(gs_record *r, const gs_record_mesh *bodies, int n, gs_diag *d);

/* Number of bodies declared by gs_record_add_meshes (0 before). */
int gs_record_n_meshes(const gs_record *r);

/* Append one field frame of body `body` (index into the array given to
 * add_meshes) at (step, time): rotation theta (rad), nodal displacements u
 * (2 * n_nodes, body frame, m) and nodal von Mises stress vm (n_nodes, Pa;
 * NULL stores NaN). Written to the file at once (one frame per call, by
 * hyperslab); durable and listed in the XDMF at the next gs_record_flush.
 * Bodies may be recorded at different steps. Errors: GS_ESTATE before
 * add_meshes, GS_EINVAL (bad body index, NULL u), GS_EIO; a failed frame is
 * not counted and the next one takes its place. */
gs_err gs_record_field_frame(gs_record *r, int body, int64_t step, double time, double theta,
                             const double *u, const double *vm);

/* Frames written for body `body` (0 if out of range). */
int64_t gs_record_field_frames(const gs_record *r, int body);

/* Checkpoint files: the engine snapshot bytes in an HDF5 file with the scene
 * as an attribute for people who look inside. */
gs_err gs_checkpoint_write(const char *path, const char *bytes, size_t len, const char *scene_json,
                           int64_t step, double time, gs_diag *d);
/* Reading a checkpoint treats the file as input: the snapshot dataset must
 * be one dimension of bytes, stored whole, at most max_bytes (checked
 * before anything is allocated); its content is checked by the engine
 * (gs_engine_snapshot_check). */
gs_err gs_checkpoint_read(const char *path, size_t max_bytes, char **bytes, size_t *len, gs_diag *d);

/* The largest step count a checkpoint may hold (2^53: exact as a double,
 * far from the overflow of int64 steps plus any advance). */
#define GS_CHECKPOINT_MAX_STEP ((int64_t)1 << 53)

/* Automatic checkpoints (docs/RELIABILITY.md, "Automatic checkpoints and
 * --resume"): a checkpoint file as above plus the group /autosave with what
 * the daemon needs to continue the interrupted advance and its record:
 *   attrs parent_id (string), start_step, target_step (int64),
 *         record (string, relative to the data directory, "" for none),
 *         record_rows (int64: telemetry rows flushed at the checkpoint)
 *   field_frames (int64, one per recorded elastic body; absent without) */
#define GS_AUTOSAVE_MAX_BODIES 64
typedef struct gs_autosave_info {
    char parent_id[160];
    int64_t start_step, target_step;
    char record[1024];
    int64_t record_rows;
    int n_field_bodies;
    int64_t field_frames[GS_AUTOSAVE_MAX_BODIES];
} gs_autosave_info;
gs_err gs_autosave_write(const char *path, const char *bytes, size_t len, const char *scene_json,
                         int64_t step, double time, const gs_autosave_info *info, gs_diag *d);
/* The /autosave group of `path` (GS_ENOTFOUND when it has none). */
gs_err gs_autosave_read_info(const char *path, gs_autosave_info *info, gs_diag *d);

/* Reopen an existing record for appending after a resume: keep the first
 * `rows` telemetry rows and the first field_frames[b] frames of each body
 * (n_frames entries, in the order of /fields names; the rest is cut with
 * H5Dset_extent), rewrite the XDMF file, and go on as gs_record_open would
 * have. The layout must match sys (same bodies and meshes). Errors: GS_EIO or
 * GS_EINVAL (field "path") naming what does not match. */
gs_err gs_record_reopen(const char *path, const gs_system *sys, int64_t rows,
                        const int64_t *field_frames, int n_frames, gs_record **out, gs_diag *d);
/* The same, HDF5 opening the file through `open_as` (/proc/self/fd/N). */
gs_err gs_record_reopen_as(const char *path, const char *open_as, const gs_system *sys, int64_t rows,
                           const int64_t *field_frames, int n_frames, gs_record **out, gs_diag *d);

#endif
