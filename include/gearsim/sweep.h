/* SPDX-License-Identifier: MIT
 * gearsim: parameter sweeps (src/sweep, docs/explanation/modal.md "Sweeps").
 *
 * A sweep is a scene and one to four parameters, each a list of values:
 * `driver_rpm` (the driver's speed; every point then starts in steady state
 * at that speed) or a JSON path into the scene ("loads[0].moment",
 * "meshes[2].stiffness.single", "joints[3].pin_error_um", ...). The points
 * are the grid of all values (the last parameter varies fastest). Each point
 * is an independent run of `settle` + `measure` seconds; its row holds the
 * parameter values and the response measured over `measure`: mesh
 * frequency, dynamic transmission error rms, dynamic factor, load-sharing
 * factor (trains with planets), the mean speed of every body and the energy
 * balance residual. A point's row depends only on the sweep and the point,
 * never on which ranks computed it.
 *
 * Points run on groups of MPI ranks (gs_sweep_run_*: rank 0 of the world
 * coordinates, every group computes points one after the other, each with a
 * replicated engine over its group's communicator), as separate processes
 * (gs_sweep_point_serial: gearsim-sweep, a Slurm array task), and are
 * collected into one table (CSV and HDF5). */
#ifndef GEARSIM_SWEEP_H
#define GEARSIM_SWEEP_H

#include <json-c/json.h>
#include <mpi.h>

#include "gearsim/engine.h"

#define GS_SWEEP_MAX_PARAMS 4
#define GS_SWEEP_MAX_POINTS 4096
#define GS_SWEEP_MAX_COLUMNS 96

typedef struct gs_sweep gs_sweep;

/* Parse and check a sweep specification (an object: scene, parameters,
 * settle, measure, time_step, mesh, driver_rpm; other keys are refused
 * unless listed in `extra`, NULL-terminated, which the caller reads).
 * Errors name the field under `prefix` ("args" -> "args.parameters[0].path").
 * Every point's scene is built and parsed here, so a bad value is refused
 * before anything runs. */
gs_err gs_sweep_parse(json_object *spec, const char *prefix, const char *const *extra, gs_sweep **out,
                      gs_diag *d);
/* The same for a specification gs_sweep_parse has accepted elsewhere (the
 * other ranks of a sweep, from rank 0's text): the points' scenes are not
 * built again (gs_sweep_max_scene_bytes and gs_sweep_max_steps are 0). */
gs_err gs_sweep_parse_trusted(json_object *spec, gs_sweep **out, gs_diag *d);
void gs_sweep_free(gs_sweep **sw);
int gs_sweep_points(const gs_sweep *sw);
/* The largest memory estimate of a point's scene (gs_scene_estimate_bytes)
 * and the most steps a point takes (settle + measure at its time step),
 * over every point, with the point where each is reached. */
double gs_sweep_max_scene_bytes(const gs_sweep *sw, int *point);
/* A function gs_sweep_parse calls between points while it validates them
 * (the daemon answers requests meanwhile); NULL: none. */
void gs_sweep_set_poll(void (*fn)(void *user), void *user);
double gs_sweep_max_steps(const gs_sweep *sw, int *point);
int gs_sweep_columns(const gs_sweep *sw);            /* row length (point index excluded) */
const char *gs_sweep_column(const gs_sweep *sw, int c); /* column name */
/* The canonical JSON text of what determines the results (scene, parameters,
 * times, mesh, driver speed): equal texts give equal tables. */
const char *gs_sweep_canonical(const gs_sweep *sw);
const char *gs_sweep_scene_name(const gs_sweep *sw);
/* The specification as parsed (its own keys only), as JSON text. */
const char *gs_sweep_spec_text(const gs_sweep *sw);

/* The scene JSON text of point p (malloc'd). */
gs_err gs_sweep_point_scene(const gs_sweep *sw, int p, char **text, gs_diag *d);

/* The response of one point, accumulated step by step. */
typedef struct gs_sweep_meter gs_sweep_meter;
gs_err gs_sweep_meter_new(const gs_sweep *sw, int p, const gs_system *sys, gs_sweep_meter **out);
/* After each step; false once the point's steps are all taken. */
bool gs_sweep_meter_step(gs_sweep_meter *m, const gs_system *sys);
int64_t gs_sweep_meter_steps_left(const gs_sweep_meter *m);
int64_t gs_sweep_meter_steps_total(const gs_sweep_meter *m);
/* The row (gs_sweep_columns values; NAN where a column does not apply). */
void gs_sweep_meter_row(const gs_sweep_meter *m, double *row);
void gs_sweep_meter_free(gs_sweep_meter **m);

/* One point in this process (no MPI): its row, or an error naming the field. */
gs_err gs_sweep_point_serial(const gs_sweep *sw, int p, double *row, gs_diag *d);

/* The table: rows[p * columns .. ] for every point, done[p] non-zero where
 * computed, err[p] (may be NULL) a message for failed points. CSV: a header
 * `point,<columns>` and one line per point with %.17g numbers (empty for
 * NAN and for points not done). HDF5: group /sweep with one dataset per
 * column, `point`, `done`, and attributes scene, spec (canonical text).
 * Each file is written whole to a new file beside `path` (unguessable name,
 * O_CREAT|O_EXCL|O_NOFOLLOW, mode 0644) and renamed over `path`: a symlink
 * or file planted at `path` or at a temporary name is never written
 * through. The daemon passes /proc/self/fd/<dirfd>/<name> of a checked
 * directory. With keep_fd the CSV stays open (*keep_fd, positioned at its
 * end) for gs_sweep_append_csv; otherwise keep_fd is NULL. */
gs_err gs_sweep_write_csv(const gs_sweep *sw, const double *rows, const unsigned char *done, const char *path,
                          int *keep_fd, gs_diag *d);
/* Append the rows of points[0..n) to a CSV kept open by gs_sweep_write_csv,
 * in one write: an interruption leaves at most an unterminated last line. */
gs_err gs_sweep_append_csv(const gs_sweep *sw, int fd, const double *rows, const int *points, int n, gs_diag *d);
/* One CSV row ("p,v1,...\n") into buf; its length (truncated to cap - 1). */
size_t gs_sweep_format_row(const gs_sweep *sw, int p, const double *row, char *buf, size_t cap);
gs_err gs_sweep_write_h5(const gs_sweep *sw, const double *rows, const unsigned char *done, const char *path,
                         gs_diag *d);
/* Rows back from a CSV written by gs_sweep_write_csv (and appended to) for
 * the same sweep (columns checked); points present get done[p] = 1; an
 * unterminated last line (an interrupted append) is ignored. */
gs_err gs_sweep_read_csv(const gs_sweep *sw, const char *path, double *rows, unsigned char *done, gs_diag *d);
/* The resume state beside a table (BASE.sweep.json: points, finished, the
 * canonical text), written like the tables. */
gs_err gs_sweep_write_state(const gs_sweep *sw, bool finished, const char *path, gs_diag *d);
/* What a state file's text says of sw: 0 nothing (NULL or not JSON), 1 an
 * unfinished sweep with sw's canonical text, 2 an unfinished other sweep,
 * 3 a finished sweep. */
int gs_sweep_state(const gs_sweep *sw, const char *text);
/* The `sweep` command's arguments (or a gearsim-sweep --spec file) as a
 * specification for gs_sweep_parse: the daemon's own keys (groups, path,
 * resume) dropped, `builtin` replaced by that builtin scene as `scene`.
 * Errors name prefix (both scene and builtin) or prefix.builtin. */
gs_err gs_sweep_spec_from_args(json_object *args, const char *prefix, json_object **spec, gs_diag *d);

/* ------------------------------------------------------------------ groups
 * Points on groups of ranks inside one MPI job. Rank 0 of `world` calls
 * gs_sweep_run_begin, which broadcasts GS_OP_SWEEP through the world
 * engine (every other rank enters gs_sweep_serve from gs_engine_serve),
 * splits the world into `groups` groups of consecutive ranks and hands out
 * the points of todo[] in batches, keeping every group a few points ahead.
 * Unless `dedicated`, rank 0 leads group 0 and computes its points in
 * slices of about `slice_s` seconds inside gs_sweep_run_poll, so its
 * caller stays responsive; `dedicated`, the groups are made of ranks 1 to
 * n-1 (groups <= n-1) and rank 0 only hands out points and collects rows. */
typedef struct gs_sweep_run gs_sweep_run;
typedef struct gs_sweep_result {
    int point;
    gs_err err;
    char message[480];   /* "field: message" of a failed point */
    double row[GS_SWEEP_MAX_COLUMNS];
} gs_sweep_result;

gs_err gs_sweep_run_begin(gs_engine *world, const gs_sweep *sw, const unsigned char *todo, int groups,
                          bool dedicated, gs_sweep_run **out, gs_diag *d);
/* Receive what the groups finished, hand out points, compute a slice of
 * group 0's point. Finished points are returned through gs_sweep_run_take. */
void gs_sweep_run_poll(gs_sweep_run *r, double slice_s);
/* The next finished point (true) since the last call. */
bool gs_sweep_run_take(gs_sweep_run *r, gs_sweep_result *out);
bool gs_sweep_run_finished(const gs_sweep_run *r);
/* True when rank 0 has no point of its own to compute now (dedicated, or
 * none left): the caller may wait for requests with a timeout instead of
 * polling again at once; the groups' rows wait in MPI meanwhile. */
bool gs_sweep_run_idle(const gs_sweep_run *r);
int gs_sweep_run_groups(const gs_sweep_run *r);
/* Points computed in this run per second of wall time so far. */
double gs_sweep_run_rate(const gs_sweep_run *r);
/* End the run (the groups stop at their next slice; a point under way is
 * dropped unless it finishes first, then it is returned by take) and
 * release the other ranks. Collective with them; call it once. */
void gs_sweep_run_end(gs_sweep_run *r);
void gs_sweep_run_free(gs_sweep_run **r);

/* Ranks other than 0: the GS_OP_SWEEP payload (called by the engine). */
gs_err gs_sweep_serve(MPI_Comm world, const char *payload, size_t len);

#endif
