/* SPDX-License-Identifier: MIT
 * The `sweep` service job (docs/reference/protocol.md, docs/explanation/modal.md "Sweeps"): a
 * scene and parameters to vary, points run concurrently on groups of ranks
 * (src/sweep/group.c), one progress event per finished point, the table
 * written as CSV at the start and the finished points' rows appended to it
 * (the sweep's checkpoint), the table as CSV and HDF5 at the end, cancel,
 * and resume of an unfinished sweep (only its missing points are computed).
 * Every file follows the data directory's file rules (docs/RELIABILITY.md):
 * checked with gsi_check_write / gsi_open_read and written through the
 * checked directory's descriptor. */
#include <fcntl.h>
#include <limits.h>
#include <math.h>
#include <unistd.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "gearsim/sweep.h"
#include "gearsim/util.h"
#include "scene/jsonv.h"
#include "service/files.h"
#include "service/options.h"
#include "service/service_internal.h"

enum { F_CSV, F_H5, F_SPEC, N_FILES };
static const char *const file_ext[N_FILES] = {".csv", ".h5", ".sweep.json"};

struct svc_sweep {
    gs_sweep *sw;
    gs_sweep_run *run;
    char parent_id[160];
    char rel[600];                       /* base path as given, without .csv */
    char file[N_FILES][640];             /* each file relative to the data directory */
    int csv_fd;                          /* the CSV being appended to, or -1 */
    double *rows;
    unsigned char *done;
    int *fresh;                          /* points taken since the last append */
    int n_points, n_before, n_todo, n_computed;
    json_object *failed;                 /* [{point, message}] */
    double wall_start;
};

static void sweep_free(svc_sweep **pw)
{
    svc_sweep *w = *pw;
    if (!w)
        return;
    gs_sweep_run_free(&w->run);
    gs_sweep_free(&w->sw);
    if (w->csv_fd >= 0)
        close(w->csv_fd);
    free(w->rows);
    free(w->done);
    free(w->fresh);
    json_object_put(w->failed);
    free(w);
    *pw = NULL;
}

/* Write one of the sweep's files (the file rules: no symlink anywhere in its
 * path, not a FIFO or device, none of the daemon's own files), through the
 * checked directory's descriptor: /proc/self/fd/<dirfd>/<name> resolves no
 * name but the last, which the writer replaces by rename. `last`: the CSV is
 * closed (else kept open for appends); the state says finished. Errors name
 * args.path. */
static gs_err write_file(gs_service *s, svc_sweep *w, int which, bool last, gs_diag *d)
{
    gsi_beneath b;
    GS_TRY(gsi_check_write(s, w->file[which], "args.path", false, &b, d));
    char target[PATH_MAX];
    snprintf(target, sizeof target, "/proc/self/fd/%d/%s", b.dirfd, b.leaf);
    gs_err e;
    if (which == F_CSV) {
        if (w->csv_fd >= 0)
            close(w->csv_fd);
        w->csv_fd = -1;
        e = gs_sweep_write_csv(w->sw, w->rows, w->done, target, last ? NULL : &w->csv_fd, d);
    } else if (which == F_H5) {
        e = gs_sweep_write_h5(w->sw, w->rows, w->done, target, d);
    } else {
        e = gs_sweep_write_state(w->sw, last, target, d);
    }
    if (e != GS_OK)
        gs_diag_set(d, e, "args.path", "cannot write '%s'%s", w->file[which],
                    e == GS_EIO ? " (disk full, or the directory not writable?)" : "");
    gsi_beneath_close(&b);
    return e;
}

/* A sweep's file read back (its state, the table to resume) must be the
 * daemon's own (it writes them 0644): a file of another user, or one others
 * may write, could hold rows the daemon never computed. */
static gs_err read_checked(gs_service *s, const char *rel, gsi_beneath *b, char *via_fd, size_t cap, gs_diag *d)
{
    struct stat st;
    GS_TRY(gsi_open_read(s, rel, "args.path", b, &st, d));
    if (st.st_uid != geteuid() || (st.st_mode & 022)) {
        gsi_beneath_close(b);
        return gs_diag_set(d, GS_ERANGE, "args.path", "'%s' belongs to another user or is writable by others "
                           "(mode %03o); a sweep does not read it (remove it or choose another path)", rel,
                           (unsigned)(st.st_mode & 0777));
    }
    gsi_fd_path(b->fd, via_fd, cap);
    return GS_OK;
}

/* The state of the sweep file (gs_sweep_state) into *st; 0 when there is
 * none. A file that breaks the file rules is an error. */
static gs_err spec_state(gs_service *s, svc_sweep *w, int *st, gs_diag *d)
{
    *st = 0;
    gsi_beneath b;
    struct stat sb;
    GS_TRY(gsi_check_write(s, w->file[F_SPEC], "args.path", false, &b, d));
    bool exists = fstatat(b.dirfd, b.leaf, &sb, AT_SYMLINK_NOFOLLOW) == 0;
    gsi_beneath_close(&b);
    if (!exists)
        return GS_OK;
    char via_fd[64];
    GS_TRY(read_checked(s, w->file[F_SPEC], &b, via_fd, sizeof via_fd, d));
    size_t len;
    char *text = gs_read_file(via_fd, 1u << 26, &len);
    gsi_beneath_close(&b);
    *st = gs_sweep_state(w->sw, text);
    free(text);
    return GS_OK;
}

/* The table's files as the client named them (relative to the data directory). */
static void add_paths(json_object *o, const char *rel)
{
    char r[640];
    snprintf(r, sizeof r, "%s.csv", rel);
    json_object_object_add(o, "csv", json_object_new_string(r));
    snprintf(r, sizeof r, "%s.h5", rel);
    json_object_object_add(o, "h5", json_object_new_string(r));
}

gs_err gsi_cmd_sweep(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    if (s->sweep)
        return gs_diag_set(d, GS_EBUSY, "cmd", "a sweep ('%.128s') is running; cancel ends it", s->sweep->parent_id);
    json_object *spec;
    GS_TRY(gs_sweep_spec_from_args(args, "args", &spec, d));
    gs_sweep *sw = NULL;
    /* Every point is validated here (seconds for thousands): requests that
     * change nothing are answered meanwhile. */
    s->validating = true;
    gs_sweep_set_poll(gsi_poll_during, s);
    gs_err e = gs_sweep_parse(spec, "args", NULL, &sw, d);
    gs_sweep_set_poll(NULL, NULL);
    s->validating = false;
    json_object_put(spec);
    if (e != GS_OK)
        return e;
    /* Each group loads every point's scene: the daemon's scene size limit
     * and step cap hold at every point, not only the first. */
    int bp, sp;
    double mb = gs_sweep_max_scene_bytes(sw, &bp) / 1048576.0, steps = gs_sweep_max_steps(sw, &sp);
    if (mb > (double)gsi_opt_max_scene_mb())
        e = gs_diag_set(d, GS_ETOOBIG, "args.parameters", "point %d's scene would need about %.0f MiB (estimate); "
                        "this daemon's limit is %lld MiB (--max-scene-mb)", bp, mb, (long long)gsi_opt_max_scene_mb());
    else if (steps > (double)GSI_MAX_STEPS_PER_ADVANCE)
        e = gs_diag_set(d, GS_ETOOBIG, "args.measure", "point %d takes %.3g steps (settle + measure at its time "
                        "step); at most %lld steps per point, as per advance", sp, steps,
                        (long long)GSI_MAX_STEPS_PER_ADVANCE);
    if (e != GS_OK) {
        gs_sweep_free(&sw);
        return e;
    }
    int64_t groups;
    bool resume;
    char rel[600];
    e = gsi_json_int(args, "groups", "args", 1, 1 << 20, false, gs_engine_size(s->eng), &groups, d);
    if (e == GS_OK && groups > gs_engine_size(s->eng))
        e = gs_diag_set(d, GS_ERANGE, "args.groups", "%lld group(s) of ranks asked; this daemon has %d rank(s)",
                        (long long)groups, gs_engine_size(s->eng));
    if (e == GS_OK)
        e = gsi_json_bool(args, "resume", "args", false, &resume, d);
    char disp[16] = "shared";
    if (e == GS_OK)
        e = gsi_json_string(args, "dispatcher", "args", false, "shared", disp, sizeof disp, d);
    if (e == GS_OK && strcmp(disp, "shared") && strcmp(disp, "dedicated"))
        e = gs_diag_set(d, GS_ESCHEMA, "args.dispatcher", "'%s': the dispatcher is 'shared' (rank 0 also computes "
                        "points) or 'dedicated' (rank 0 only hands them out)", disp);
    bool dedicated = e == GS_OK && !strcmp(disp, "dedicated");
    if (dedicated && !json_object_object_get_ex(args, "groups", NULL))
        groups = gs_engine_size(s->eng) - 1; /* one per rank but rank 0 */
    if (e == GS_OK && dedicated && groups > gs_engine_size(s->eng) - 1)
        e = gs_diag_set(d, GS_ERANGE, "args.groups", "%lld group(s) of ranks asked besides a dedicated dispatcher; "
                        "this daemon has %d rank(s), so at most %d", (long long)groups, gs_engine_size(s->eng),
                        gs_engine_size(s->eng) - 1);
    if (e == GS_OK)
        e = gsi_json_string(args, "path", "args", false, "sweep", rel, sizeof rel - 16, d);
    size_t rl = strlen(rel);
    if (e == GS_OK && rl > 4 && !strcmp(rel + rl - 4, ".csv"))
        rel[rl - 4] = '\0';
    /* The files are <path>.csv, .h5, .sweep.json: the last component must
     * be a name ('.', '..' or a trailing '/' would make '..csv'). */
    const char *leaf = strrchr(rel, '/');
    leaf = leaf ? leaf + 1 : rel;
    if (e == GS_OK && (!leaf[0] || !strcmp(leaf, ".") || !strcmp(leaf, "..")))
        e = gs_diag_set(d, GS_ERANGE, "args.path", "'%s' does not end in a file name: the sweep writes "
                        "<path>.csv, <path>.h5 and <path>.sweep.json", rel);
    svc_sweep *w = gs_calloc(1, sizeof *w);
    if (e == GS_OK && !w)
        e = GS_ENOMEM;
    if (e != GS_OK) {
        free(w);
        gs_sweep_free(&sw);
        return e;
    }
    w->sw = sw;
    w->csv_fd = -1;
    snprintf(w->rel, sizeof w->rel, "%s", rel);
    for (int i = 0; i < N_FILES && e == GS_OK; i++) {
        char full[PATH_MAX];
        snprintf(w->file[i], sizeof w->file[i], "%s%s", rel, file_ext[i]);
        e = gsi_resolve_path(s, w->file[i], full, sizeof full, true, d);
        if (e != GS_OK)
            snprintf(d->field, sizeof d->field, "args.path");
        else
            snprintf(w->file[i], sizeof w->file[i], "%s", gsi_data_relative(s, full));
    }
    /* Every name checked before anything is computed or written. */
    for (int i = 0; i < N_FILES && e == GS_OK; i++) {
        gsi_beneath b;
        e = gsi_check_write(s, w->file[i], "args.path", false, &b, d);
        gsi_beneath_close(&b);
    }
    w->n_points = gs_sweep_points(sw);
    w->rows = gs_calloc((size_t)w->n_points * (size_t)gs_sweep_columns(sw), sizeof(double));
    w->done = gs_calloc((size_t)w->n_points, 1);
    w->fresh = gs_calloc((size_t)w->n_points, sizeof(int));
    w->failed = json_object_new_array();
    if (e == GS_OK && (!w->rows || !w->done || !w->fresh))
        e = GS_ENOMEM;
    int st = 0;
    if (e == GS_OK)
        e = spec_state(s, w, &st, d);
    if (e == GS_OK) {
        if (resume && st != 1)
            e = gs_diag_set(d, st == 0 ? GS_ENOTFOUND : GS_ESTATE, "args.resume",
                            st == 0   ? "no unfinished sweep at '%s' to resume"
                            : st == 3 ? "the sweep at '%s' has finished; nothing to resume"
                                      : "the unfinished sweep at '%s' has other arguments (scene, parameters, "
                                        "times or mesh): resume it with the same ones",
                            rel);
        else if (!resume && (st == 1 || st == 2))
            e = gs_diag_set(d, GS_ESTATE, "args.resume",
                            "an unfinished sweep is at '%s': pass resume: true to continue it, or choose another path",
                            rel);
    }
    if (e == GS_OK && resume) {
        gsi_beneath b;
        char via_fd[64];
        e = read_checked(s, w->file[F_CSV], &b, via_fd, sizeof via_fd, d);
        if (e == GS_OK) {
            e = gs_sweep_read_csv(sw, via_fd, w->rows, w->done, d);
            gsi_beneath_close(&b);
            if (e != GS_OK) {
                /* the message names the file as the client does */
                char m[2 * sizeof d->message + sizeof w->file[F_CSV]];
                const char *q = strstr(d->message, via_fd);
                snprintf(m, sizeof m, "%.*s%s%s", q ? (int)(q - d->message) : 0, d->message, w->file[F_CSV],
                         q ? q + strlen(via_fd) : "");
                if (q)
                    gs_diag_set(d, e, "args.path", "%.300s", m);
                else
                    snprintf(d->field, sizeof d->field, "args.path");
            }
        }
    }
    /* The state first (unfinished), then the table, written whole once:
     * the rows read back (without a torn last line) or only its header. */
    if (e == GS_OK)
        e = write_file(s, w, F_SPEC, false, d);
    if (e == GS_OK)
        e = write_file(s, w, F_CSV, false, d);
    if (e != GS_OK) {
        sweep_free(&w);
        return e;
    }
    unsigned char *todo = gs_calloc((size_t)w->n_points, 1);
    if (!todo) {
        sweep_free(&w);
        return GS_ENOMEM;
    }
    for (int p = 0; p < w->n_points; p++) {
        todo[p] = !w->done[p];
        w->n_todo += todo[p];
        w->n_before += w->done[p];
    }
    e = gs_sweep_run_begin(s->eng, sw, todo, (int)groups, dedicated, &w->run, d);
    free(todo);
    if (e != GS_OK) {
        if (!strcmp(d->field, "groups"))
            snprintf(d->field, sizeof d->field, "args.groups");
        sweep_free(&w);
        return e;
    }
    snprintf(w->parent_id, sizeof w->parent_id, "%s", id);
    w->wall_start = gs_now();
    s->sweep = w;
    *res = json_object_new_object();
    json_object_object_add(*res, "accepted", json_object_new_boolean(1));
    json_object_object_add(*res, "points", json_object_new_int(w->n_points));
    json_object_object_add(*res, "todo", json_object_new_int(w->n_todo));
    json_object_object_add(*res, "groups", json_object_new_int((int)groups));
    json_object_object_add(*res, "dispatcher", json_object_new_string(disp));
    json_object *cols = json_object_new_array();
    for (int c = 0; c < gs_sweep_columns(sw); c++)
        json_object_array_add(cols, json_object_new_string(gs_sweep_column(sw, c)));
    json_object_object_add(*res, "columns", cols);
    add_paths(*res, rel);
    return GS_OK;
}

static int points_done(const svc_sweep *w)
{
    int k = 0;
    for (int p = 0; p < w->n_points; p++)
        k += w->done[p];
    return k;
}

/* Take the finished points: into the table, one progress event each. */
static void take_points(gs_service *s)
{
    svc_sweep *w = s->sweep;
    gs_sweep_result x;
    int nfresh = 0, nc = gs_sweep_columns(w->sw);
    while (gs_sweep_run_take(w->run, &x)) {
        w->n_computed++;
        if (x.err == GS_OK) {
            memcpy(w->rows + (size_t)x.point * nc, x.row, (size_t)nc * sizeof(double));
            w->done[x.point] = 1;
            w->fresh[nfresh++] = x.point;
        } else {
            json_object *f = json_object_new_object();
            json_object_object_add(f, "point", json_object_new_int(x.point));
            json_object_object_add(f, "code", json_object_new_string(gs_errcode(x.err)));
            json_object_object_add(f, "message", json_object_new_string(x.message));
            json_object_array_add(w->failed, f);
        }
        json_object *o = json_object_new_object();
        json_object_object_add(o, "parent_id", json_object_new_string(w->parent_id));
        json_object_object_add(o, "kind", json_object_new_string("sweep"));
        json_object_object_add(o, "point", json_object_new_int(x.point));
        json_object_object_add(o, "points", json_object_new_int(w->n_points));
        int k = points_done(w);
        json_object_object_add(o, "points_done", json_object_new_int(k));
        json_object_object_add(o, "fraction", json_object_new_double(w->n_todo > 0 ? (double)w->n_computed / w->n_todo : 1.0));
        double rate = gs_sweep_run_rate(w->run);
        json_object_object_add(o, "steps_per_second", json_object_new_double(rate));
        json_object_object_add(o, "points_per_second", json_object_new_double(rate));
        if (x.err == GS_OK) {
            json_object *vals = json_object_new_object();
            for (int c = 0; c < nc; c++)
                json_object_object_add(vals, gs_sweep_column(w->sw, c),
                                       isfinite(x.row[c]) ? json_object_new_double(x.row[c]) : NULL);
            json_object_object_add(o, "values", vals);
        } else {
            json_object *e = json_object_new_object();
            json_object_object_add(e, "code", json_object_new_string(gs_errcode(x.err)));
            json_object_object_add(e, "message", json_object_new_string(x.message));
            json_object_object_add(o, "error", e);
        }
        gsi_publish(s, "progress", o);
    }
    if (nfresh > 0 && w->csv_fd >= 0) {
        gs_diag d;
        if (gs_sweep_append_csv(w->sw, w->csv_fd, w->rows, w->fresh, nfresh, &d) != GS_OK) {
            json_object *er = json_object_new_object();
            json_object_object_add(er, "code", json_object_new_string("io_error"));
            json_object_object_add(er, "message", json_object_new_string(d.message));
            json_object_object_add(er, "parent_id", json_object_new_string(w->parent_id));
            gsi_publish(s, "error", er);
            /* No more appends (the table's end may be torn); the whole
             * table is still written at the end. */
            close(w->csv_fd);
            w->csv_fd = -1;
        }
    }
}

void gsi_sweep_stop(gs_service *s, bool cancelled)
{
    svc_sweep *w = s->sweep;
    if (!w)
        return;
    gs_sweep_run_end(w->run); /* the groups stop; points that finished meanwhile are kept */
    take_points(s);
    int k = points_done(w);
    /* Complete when every point is in the table, or when the run went to
     * its end and the missing points failed (listed in the done event): a
     * resume would only fail them again, and the path stays usable. */
    bool complete = k == w->n_points || (!cancelled && w->n_computed >= w->n_todo);
    gs_diag d;
    gs_diag_clear(&d);
    /* The table whole, in point order, and closed; then the HDF5 table and
     * the state. */
    gs_err e = write_file(s, w, F_CSV, true, &d);
    if (e == GS_OK)
        e = write_file(s, w, F_H5, true, &d);
    if (e == GS_OK)
        e = write_file(s, w, F_SPEC, complete, &d);
    json_object *o = json_object_new_object();
    json_object_object_add(o, "parent_id", json_object_new_string(w->parent_id));
    json_object_object_add(o, "cancelled", json_object_new_boolean(cancelled));
    json_object_object_add(o, "points", json_object_new_int(w->n_points));
    json_object_object_add(o, "points_done", json_object_new_int(k));
    json_object_object_add(o, "computed", json_object_new_int(w->n_computed));
    json_object_object_add(o, "resumed", json_object_new_int(w->n_before));
    json_object_object_add(o, "groups", json_object_new_int(gs_sweep_run_groups(w->run)));
    double wall = gs_now() - w->wall_start;
    json_object_object_add(o, "wall_seconds", json_object_new_double(wall));
    json_object_object_add(o, "points_per_second", json_object_new_double(wall > 0 ? w->n_computed / wall : 0.0));
    add_paths(o, w->rel);
    json_object_object_add(o, "failed", json_object_get(w->failed));
    if (e != GS_OK) {
        json_object *er = json_object_new_object();
        json_object_object_add(er, "code", json_object_new_string(gs_errcode(e)));
        json_object_object_add(er, "message", json_object_new_string(d.message));
        json_object_object_add(er, "field", json_object_new_string("args.path"));
        json_object_object_add(o, "error", er);
    }
    s->sweep = NULL;
    sweep_free(&w);
    gsi_publish_done(s, "sweep", o);
}

void gsi_sweep_chunk(gs_service *s)
{
    svc_sweep *w = s->sweep;
    gs_sweep_run_poll(w->run, 0.02);
    take_points(s);
    if (gs_sweep_run_finished(w->run))
        gsi_sweep_stop(s, false);
}

json_object *gsi_sweep_status(gs_service *s)
{
    svc_sweep *w = s->sweep;
    if (!w)
        return NULL;
    json_object *a = json_object_new_object();
    json_object_object_add(a, "parent_id", json_object_new_string(w->parent_id));
    json_object_object_add(a, "points", json_object_new_int(w->n_points));
    json_object_object_add(a, "points_done", json_object_new_int(points_done(w)));
    json_object_object_add(a, "groups", json_object_new_int(gs_sweep_run_groups(w->run)));
    json_object_object_add(a, "fraction", json_object_new_double(w->n_todo > 0 ? (double)w->n_computed / w->n_todo : 1.0));
    return a;
}

bool gsi_sweep_idle(gs_service *s) { return s->sweep && gs_sweep_run_idle(s->sweep->run); }

const char *gsi_sweep_parent(gs_service *s) { return s->sweep ? s->sweep->parent_id : ""; }

bool gsi_sweep_allows(const char *cmd)
{
    /* Commands that do not use the other ranks (they are in the sweep). */
    static const char *const ok[] = {"hello", "status", "state", "jobs", "fetch", "cancel", "modal",
                                     "shutdown", "submit", "pause", "resume", NULL};
    for (int i = 0; ok[i]; i++)
        if (!strcmp(cmd, ok[i]))
            return true;
    return false;
}
