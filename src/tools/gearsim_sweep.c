/* SPDX-License-Identifier: MIT
 * gearsim-sweep: parameter sweeps outside the daemon (docs/explanation/modal.md,
 * "Sweeps"); the points are those of the daemon's `sweep` job
 * (src/sweep), computed here one after the other in one process.
 *
 *   gearsim-sweep SCENE.json --from RPM --to RPM [--points N] [--settle S]
 *                 [--measure S] [--time-step H] [--mesh NAME]
 *       a speed sweep: one CSV row per point on stdout as it finishes;
 *   gearsim-sweep --spec SWEEP.json [--task I --tasks N] [--out PART.csv]
 *       the sweep of a file holding the `sweep` command's arguments (scene,
 *       builtin or scene_file, parameters, settle, measure, time_step, mesh,
 *       driver_rpm; groups, path and resume are ignored): all its points, or
 *       with --task the points p with p % N == I (one Slurm array task,
 *       deploy/sweep_slurm.sh); the table to --out or stdout;
 *   gearsim-sweep --spec SWEEP.json --collect PART.csv... --out BASE
 *       the parts into one table, BASE.csv and BASE.h5; fails naming the
 *       missing points unless every point is there.
 *
 * The driver is the body of the scene's first moment load (made constant);
 * every body starts at the rigid speeds of the driver's speed and the brake
 * coefficient is set to the power balance, so each point starts in steady
 * state. Columns: point, the parameters, mesh frequency (Hz), DTE rms (um),
 * dynamic factor, load-sharing factor (empty without planets), each body's
 * mean speed (rpm), the balance residual over the energy scale. Progress on
 * stderr. Exit status 0, 1 an error (message naming the field), 2 bad
 * usage. Not an MPI program. */
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/sweep.h"
#include "gearsim/util.h"
#include "tool.h"

static void usage(void)
{
    fprintf(stderr, "usage: gearsim-sweep SCENE.json --from RPM --to RPM [--points N] [--settle S] [--measure S]\n"
                    "                     [--time-step H] [--mesh NAME]\n"
                    "       gearsim-sweep --spec SWEEP.json [--task I --tasks N] [--out PART.csv]\n"
                    "       gearsim-sweep --spec SWEEP.json --collect PART.csv... --out BASE\n");
}

static void print_row(const gs_sweep *sw, int p, const double *row)
{
    char buf[16 + 25 * GS_SWEEP_MAX_COLUMNS];
    fwrite(buf, 1, gs_sweep_format_row(sw, p, row, buf, sizeof buf), stdout);
    fflush(stdout);
}

/* The spec of a --spec file: its scene_file (relative to the file) becomes
 * the scene, then as the daemon's job does (gs_sweep_spec_from_args): a
 * builtin becomes the scene, the daemon's own keys are dropped. */
static json_object *read_spec(const char *path)
{
    json_object *o = json_object_from_file(path);
    if (!o || json_object_get_type(o) != json_type_object) {
        fprintf(stderr, "gearsim-sweep: %s: not a JSON object (%s)\n", path, json_util_get_last_err());
        json_object_put(o);
        return NULL;
    }
    json_object *v;
    if (json_object_object_get_ex(o, "scene_file", &v)) {
        char p[4096];
        const char *f = json_object_get_string(v), *slash = strrchr(path, '/');
        if (f[0] == '/' || !slash)
            snprintf(p, sizeof p, "%s", f);
        else
            snprintf(p, sizeof p, "%.*s/%s", (int)(slash - path), path, f);
        json_object *sc = json_object_from_file(p);
        if (!sc) {
            fprintf(stderr, "gearsim-sweep: %s: scene_file: cannot read '%s'\n", path, p);
            json_object_put(o);
            return NULL;
        }
        json_object_object_add(o, "scene", sc);
        json_object_object_del(o, "scene_file");
    }
    json_object *spec;
    gs_diag d;
    gs_diag_clear(&d);
    if (gs_sweep_spec_from_args(o, "", &spec, &d) != GS_OK) {
        fprintf(stderr, "gearsim-sweep: %s: %s: %s\n", path, d.field, d.message);
        spec = NULL;
    }
    json_object_put(o);
    return spec;
}

int main(int argc, char **argv)
{
    const char *path = NULL, *mesh_name = NULL, *spec_path = NULL, *out = NULL;
    double from = NAN, to = NAN, settle = 0.01, measure = 0.01, h = 0;
    int points = 40, task = -1, tasks = 0, first_part = 0, n_parts = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (i + 1 < argc && !strcmp(a, "--from"))
            from = atof(argv[++i]);
        else if (i + 1 < argc && !strcmp(a, "--to"))
            to = atof(argv[++i]);
        else if (i + 1 < argc && !strcmp(a, "--points"))
            points = atoi(argv[++i]);
        else if (i + 1 < argc && !strcmp(a, "--settle"))
            settle = atof(argv[++i]);
        else if (i + 1 < argc && !strcmp(a, "--measure"))
            measure = atof(argv[++i]);
        else if (i + 1 < argc && !strcmp(a, "--time-step"))
            h = atof(argv[++i]);
        else if (i + 1 < argc && !strcmp(a, "--mesh"))
            mesh_name = argv[++i];
        else if (i + 1 < argc && !strcmp(a, "--spec"))
            spec_path = argv[++i];
        else if (i + 1 < argc && !strcmp(a, "--task"))
            task = atoi(argv[++i]);
        else if (i + 1 < argc && !strcmp(a, "--tasks"))
            tasks = atoi(argv[++i]);
        else if (i + 1 < argc && !strcmp(a, "--out"))
            out = argv[++i];
        else if (!strcmp(a, "--collect")) {
            first_part = i + 1;
            while (i + 1 < argc && strncmp(argv[i + 1], "--", 2))
                i++, n_parts++;
        } else if (a[0] != '-' && !path)
            path = a;
        else {
            usage();
            return TOOL_USAGE;
        }
    }
    json_object *spec;
    const char *what;
    if (spec_path) {
        if (path || (task >= 0) != (tasks > 0) || (tasks > 0 && task >= tasks) || (first_part && (!n_parts || !out)) ||
            (first_part && task >= 0)) {
            usage();
            return TOOL_USAGE;
        }
        if (!(spec = read_spec(spec_path)))
            return TOOL_FAIL;
        what = spec_path;
    } else {
        if (!path || !isfinite(from) || !isfinite(to) || points < 1 || points > GS_SWEEP_MAX_POINTS ||
            !(settle >= 0) || !(measure > 0) || !(h >= 0) || first_part || task >= 0) {
            usage();
            return TOOL_USAGE;
        }
        json_object *scene = json_object_from_file(path);
        if (!scene) {
            fprintf(stderr, "gearsim-sweep: %s: cannot read the scene (%s)\n", path, json_util_get_last_err());
            return TOOL_FAIL;
        }
        spec = json_object_new_object();
        json_object_object_add(spec, "scene", scene);
        json_object *prm = json_object_new_object(), *arr = json_object_new_array();
        json_object_object_add(prm, "path", json_object_new_string("driver_rpm"));
        json_object_object_add(prm, "from", json_object_new_double(from));
        json_object_object_add(prm, "to", json_object_new_double(to));
        json_object_object_add(prm, "points", json_object_new_int(points));
        json_object_array_add(arr, prm);
        json_object_object_add(spec, "parameters", arr);
        json_object_object_add(spec, "settle", json_object_new_double(settle));
        json_object_object_add(spec, "measure", json_object_new_double(measure));
        if (h > 0)
            json_object_object_add(spec, "time_step", json_object_new_double(h));
        if (mesh_name)
            json_object_object_add(spec, "mesh", json_object_new_string(mesh_name));
        what = path;
    }
    gs_sweep *sw;
    gs_diag d;
    gs_diag_clear(&d);
    gs_err e = gs_sweep_parse(spec, "", NULL, &sw, &d);
    json_object_put(spec);
    if (e != GS_OK) {
        fprintf(stderr, "gearsim-sweep: %s: %s: %s (%s)\n", what, d.field, d.message, gs_errcode(e));
        return TOOL_FAIL;
    }
    int n = gs_sweep_points(sw), nc = gs_sweep_columns(sw);
    double *rows = gs_calloc((size_t)n * nc, sizeof(double));
    unsigned char *done = gs_calloc((size_t)n, 1);
    int status = 0;
    if (first_part) {
        for (int k = 0; k < n_parts && e == GS_OK; k++)
            e = gs_sweep_read_csv(sw, argv[first_part + k], rows, done, &d);
        int missing = 0;
        for (int p = 0; p < n && e == GS_OK; p++)
            if (!done[p]) {
                fprintf(stderr, "%s%d", missing++ ? "," : "gearsim-sweep: missing points: ", p);
            }
        if (missing)
            fprintf(stderr, "\n");
        char f[4096];
        snprintf(f, sizeof f, "%s.csv", out);
        if (e == GS_OK && !missing)
            e = gs_sweep_write_csv(sw, rows, done, f, NULL, &d);
        snprintf(f, sizeof f, "%s.h5", out);
        if (e == GS_OK && !missing)
            e = gs_sweep_write_h5(sw, rows, done, f, &d);
        if (e != GS_OK)
            fprintf(stderr, "gearsim-sweep: %s: %s\n", d.field, d.message);
        status = e != GS_OK || missing ? TOOL_FAIL : 0;
    } else {
        if (!out) {
            printf("point");
            for (int c = 0; c < nc; c++)
                printf(",%s", gs_sweep_column(sw, c));
            printf("\n");
        }
        for (int p = 0; p < n; p++) {
            if (tasks > 0 && p % tasks != task)
                continue;
            e = gs_sweep_point_serial(sw, p, rows + (size_t)p * nc, &d);
            if (e != GS_OK) {
                fprintf(stderr, "gearsim-sweep: point %d: %s: %s\n", p, d.field, d.message);
                status = TOOL_FAIL;
                continue;
            }
            done[p] = 1;
            if (!out)
                print_row(sw, p, rows + (size_t)p * nc);
            fprintf(stderr, "point %d/%d done\n", p + 1, n);
        }
        if (out && gs_sweep_write_csv(sw, rows, done, out, NULL, &d) != GS_OK) {
            fprintf(stderr, "gearsim-sweep: %s: %s\n", out, d.message);
            status = TOOL_FAIL;
        }
    }
    free(rows);
    free(done);
    gs_sweep_free(&sw);
    return status;
}
