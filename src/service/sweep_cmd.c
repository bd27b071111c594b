/* SPDX-License-Identifier: MIT
 * The `sweep` service job (docs/PROTOCOL.md, docs/MODAL.md "Sweeps"): a
 * scene and parameters to vary, points run concurrently on groups of ranks
 * (src/sweep/group.c), one progress event per finished point, the table
 * written as CSV after every point (the sweep's checkpoint) and as CSV and
 * HDF5 at the end, cancel, and resume of an unfinished sweep (only its
 * missing points are computed). */
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "gearsim/sweep.h"
#include "gearsim/util.h"
#include "scene/jsonv.h"
#include "service/options.h"
#include "service/service_internal.h"

struct svc_sweep {
    gs_sweep *sw;
    gs_sweep_run *run;
    char parent_id[160];
    char rel[600];                       /* base path as given, without .csv */
    char csv[PATH_MAX], h5[PATH_MAX], spec[PATH_MAX];
    double *rows;
    unsigned char *done;
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
    free(w->rows);
    free(w->done);
    json_object_put(w->failed);
    free(w);
    *pw = NULL;
}

/* The spec file: the canonical sweep and whether it finished. */
static gs_err write_spec(svc_sweep *w, bool finished, gs_diag *d)
{
    json_object *o = json_object_new_object();
    json_object_object_add(o, "points", json_object_new_int(w->n_points));
    json_object_object_add(o, "finished", json_object_new_boolean(finished));
    json_object_object_add(o, "sweep", json_object_new_string(gs_sweep_canonical(w->sw)));
    char tmp[PATH_MAX + 8];
    snprintf(tmp, sizeof tmp, "%s.tmp", w->spec);
    gs_err e = json_object_to_file_ext(tmp, o, JSON_C_TO_STRING_PLAIN) == 0 && rename(tmp, w->spec) == 0
                   ? GS_OK
                   : gs_diag_set(d, GS_EIO, "args.path", "cannot write '%s.sweep.json'", w->rel);
    json_object_put(o);
    return e;
}

/* 1: an unfinished sweep with this canonical text, 2: one with another,
 * 3: a finished one, 0: none. */
static int spec_state(const char *path, const char *canonical)
{
    json_object *o = json_object_from_file(path);
    if (!o)
        return 0;
    json_object *f, *c;
    int st = 2;
    if (json_object_object_get_ex(o, "finished", &f) && json_object_get_boolean(f))
        st = 3;
    else if (json_object_object_get_ex(o, "sweep", &c) && !strcmp(json_object_get_string(c), canonical))
        st = 1;
    json_object_put(o);
    return st;
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

static const char *const sweep_only[] = {"groups", "path", "resume", "builtin", NULL};

gs_err gsi_cmd_sweep(gs_service *s, json_object *args, const char *id, json_object **res, gs_diag *d)
{
    if (s->sweep)
        return gs_diag_set(d, GS_EBUSY, "cmd", "a sweep ('%.128s') is running; cancel ends it", s->sweep->parent_id);
    /* The specification: args without the service's own keys, the builtin
     * scene given as the scene. */
    json_object *spec = json_object_new_object(), *b = NULL;
    json_object_object_foreach(args, k, v)
    {
        bool own = false;
        for (int i = 0; sweep_only[i]; i++)
            own |= !strcmp(k, sweep_only[i]);
        if (!own)
            json_object_object_add(spec, k, json_object_get(v));
    }
    if (json_object_object_get_ex(args, "builtin", &b)) {
        const char *text = json_object_get_type(b) == json_type_string ? gs_scene_builtin(json_object_get_string(b)) : NULL;
        if (json_object_object_get_ex(args, "scene", NULL)) {
            json_object_put(spec);
            return gs_diag_set(d, GS_ESCHEMA, "args", "give exactly one of 'scene' (an object) or 'builtin' (a name)");
        }
        if (!text) {
            json_object_put(spec);
            return gs_diag_set(d, GS_ENOTFOUND, "args.builtin", "no builtin scene '%.64s'",
                               json_object_get_type(b) == json_type_string ? json_object_get_string(b) : "");
        }
        json_object_object_add(spec, "scene", json_tokener_parse(text));
    }
    gs_sweep *sw = NULL;
    gs_err e = gs_sweep_parse(spec, "args", sweep_only, &sw, d);
    json_object_put(spec);
    if (e != GS_OK)
        return e;
    /* Each group loads the scene: the daemon's scene size limit holds. */
    char *pt = NULL;
    gs_scene *sc = NULL;
    if ((e = gs_sweep_point_scene(sw, 0, &pt, d)) == GS_OK && (e = gs_scene_parse(pt, strlen(pt), &sc, d)) == GS_OK) {
        int big;
        double mb = gs_scene_estimate_bytes(sc, &big) / 1048576.0;
        if (mb > (double)gsi_opt_max_scene_mb())
            e = gs_diag_set(d, GS_ETOOBIG, "args.scene", "a point's scene would need about %.0f MiB (estimate); this "
                            "daemon's limit is %lld MiB (--max-scene-mb)", mb, (long long)gsi_opt_max_scene_mb());
    }
    free(pt);
    gs_scene_free(&sc);
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
    if (e == GS_OK)
        e = gsi_json_string(args, "path", "args", false, "sweep", rel, sizeof rel - 16, d);
    size_t rl = strlen(rel);
    if (e == GS_OK && rl > 4 && !strcmp(rel + rl - 4, ".csv"))
        rel[rl - 4] = '\0';
    svc_sweep *w = gs_calloc(1, sizeof *w);
    if (e == GS_OK && !w)
        e = GS_ENOMEM;
    if (e != GS_OK) {
        free(w);
        gs_sweep_free(&sw);
        return e;
    }
    w->sw = sw;
    snprintf(w->rel, sizeof w->rel, "%s", rel);
    const char *ext[] = {".csv", ".h5", ".sweep.json"};
    char *full[] = {w->csv, w->h5, w->spec};
    for (int i = 0; i < 3 && e == GS_OK; i++) {
        char r[640];
        snprintf(r, sizeof r, "%s%s", rel, ext[i]);
        e = gsi_resolve_path(s, r, full[i], PATH_MAX, true, d);
        if (e != GS_OK)
            snprintf(d->field, sizeof d->field, "args.path");
    }
    w->n_points = gs_sweep_points(sw);
    w->rows = gs_calloc((size_t)w->n_points * (size_t)gs_sweep_columns(sw), sizeof(double));
    w->done = gs_calloc((size_t)w->n_points, 1);
    w->failed = json_object_new_array();
    if (e == GS_OK && (!w->rows || !w->done))
        e = GS_ENOMEM;
    if (e == GS_OK) {
        int st = spec_state(w->spec, gs_sweep_canonical(sw));
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
        else if (resume)
            e = gs_sweep_read_csv(sw, w->csv, w->rows, w->done, d);
    }
    if (e == GS_OK)
        e = write_spec(w, false, d);
    if (e == GS_OK && !resume)
        e = gs_sweep_write_csv(sw, w->rows, w->done, w->csv, d);
    if (e != GS_OK) {
        if (!strcmp(d->field, "path"))
            snprintf(d->field, sizeof d->field, "args.path");
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
    e = gs_sweep_run_begin(s->eng, sw, todo, (int)groups, &w->run, d);
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
    bool any = false;
    int nc = gs_sweep_columns(w->sw);
    while (gs_sweep_run_take(w->run, &x)) {
        any = true;
        w->n_computed++;
        if (x.err == GS_OK) {
            memcpy(w->rows + (size_t)x.point * nc, x.row, (size_t)nc * sizeof(double));
            w->done[x.point] = 1;
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
    if (any) {
        gs_diag d;
        if (gs_sweep_write_csv(w->sw, w->rows, w->done, w->csv, &d) != GS_OK) {
            json_object *er = json_object_new_object();
            json_object_object_add(er, "code", json_object_new_string("io_error"));
            json_object_object_add(er, "message", json_object_new_string(d.message));
            json_object_object_add(er, "parent_id", json_object_new_string(w->parent_id));
            gsi_publish(s, "error", er);
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
    bool complete = k == w->n_points;
    gs_diag d;
    gs_diag_clear(&d);
    gs_err e = gs_sweep_write_csv(w->sw, w->rows, w->done, w->csv, &d);
    if (e == GS_OK)
        e = gs_sweep_write_h5(w->sw, w->rows, w->done, w->h5, &d);
    if (e == GS_OK)
        e = write_spec(w, complete, &d);
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
