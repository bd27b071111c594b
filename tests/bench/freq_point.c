/* SPDX-License-Identifier: MIT
 * One point of the frequency response (tests/bench/freq_response.py,
 * docs/explanation/modal.md "Frequency response") with what the sweep's row does not
 * show: how often the teeth lose contact. Builds the point exactly as
 * gearsim-sweep does (gs_sweep_point_scene: steady state at the driver
 * speed, brake at the power balance), steps it with the sweep's meter (so
 * the row is the sweep's), and over the measured window counts
 *
 *   sep     steps in which the mesh carries no force (no active contact
 *           row: the flanks fly apart within the backlash),
 *   low     steps whose mesh force is below a quarter of its window mean,
 *   spike   steps whose mesh force exceeds twice its window mean,
 *   closure the contact work booked over the window (the gap closure's
 *           impact losses, numerics.contact "closure") against the driver's
 *           work over it,
 *   h1      the amplitude of the DTE's first mesh harmonic (its Fourier
 *           coefficient at the row's measured mesh frequency over the
 *           window, um): the resonant part of the DTE rms, without the
 *           higher harmonics of the flanks' chords.
 *
 *   freq_point SCENE.json --rpm RPM --settle S --measure S --h H [--csv FILE]
 *
 * --csv writes t, DTE (deflection about nothing: s - s_ref, um), force (N)
 * and active rows per measured step, for a spectrum. Prints one JSON object.
 * freq_response.py runs its contact points through this tool when it is
 * built (the same row, plus these fractions in points.csv). Not a test: an
 * order-2 point is 1000-2000 steps of the elastic pair. */
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/bench_args.h"
#include "gearsim/scene.h"
#include "gearsim/step.h"
#include "gearsim/sweep.h"
#include "gearsim/util.h"

int main(int argc, char **argv)
{
    const char *path = NULL, *csv = NULL;
    double rpm = NAN, settle = 2e-3, measure = 1.2e-3, h = 2.5e-6;
    const bench_opt opts[] = {
        {"--rpm", 'd', &rpm},
        {"--settle", 'd', &settle},
        {"--measure", 'd', &measure},
        {"--h", 'd', &h},
        {"--csv", 's', &csv},
    };
    if (bench_args(argc, argv, &path, opts, sizeof opts / sizeof *opts))
        return 2;
    if (!path || !isfinite(rpm) || !(h > 0) || !(measure > 0) || !(settle >= 0)) {
        fprintf(stderr, "usage: freq_point SCENE.json --rpm RPM --settle S --measure S --h H [--csv FILE]\n");
        return 2;
    }
    json_object *scene = json_object_from_file(path);
    if (!scene) {
        fprintf(stderr, "%s: cannot read the scene\n", path);
        return 2;
    }
    json_object *spec = json_object_new_object(), *arr = json_object_new_array(), *prm = json_object_new_object(),
                *vals = json_object_new_array();
    json_object_object_add(spec, "scene", scene);
    json_object_object_add(prm, "path", json_object_new_string("driver_rpm"));
    json_object_array_add(vals, json_object_new_double(rpm));
    json_object_object_add(prm, "values", vals);
    json_object_array_add(arr, prm);
    json_object_object_add(spec, "parameters", arr);
    json_object_object_add(spec, "settle", json_object_new_double(settle));
    json_object_object_add(spec, "measure", json_object_new_double(measure));
    json_object_object_add(spec, "time_step", json_object_new_double(h));
    gs_sweep *sw = NULL;
    gs_diag d;
    if (gs_sweep_parse(spec, "", NULL, &sw, &d) != GS_OK) {
        fprintf(stderr, "sweep: %s: %s\n", d.field, d.message);
        return 1;
    }
    json_object_put(spec);
    char *text = NULL;
    gs_scene *sc = NULL;
    gs_system *s = NULL;
    if (gs_sweep_point_scene(sw, 0, &text, &d) != GS_OK || gs_scene_parse(text, strlen(text), &sc, &d) != GS_OK ||
        gs_system_new(sc, 0, 1, &s, &d) != GS_OK) {
        fprintf(stderr, "point: %s: %s\n", d.field, d.message);
        return 1;
    }
    free(text);
    gs_sweep_meter *m = NULL;
    if (gs_sweep_meter_new(sw, 0, s, &m) != GS_OK)
        return 1;
    int64_t n_settle = gs_sweep_meter_steps_total(m) - lround(measure / s->h);
    if (n_settle < 0)
        n_settle = 0;
    const gs_gmesh_rt *g = &s->meshes[0];
    FILE *out = csv ? fopen(csv, "w") : NULL;
    if (out)
        fprintf(out, "t_s,dte_um,force_n,active\n");
    /* Forces are kept to compare them with the window's mean at the end. */
    int64_t cap = gs_sweep_meter_steps_total(m) + 1, n = 0;
    double *F = calloc((size_t)cap, sizeof(double)), *X = calloc((size_t)cap, sizeof(double)),
           *T = calloc((size_t)cap, sizeof(double));
    int *act = calloc((size_t)cap, sizeof(int));
    if (!F || !act || !X || !T)
        return 1;
    double cw0 = 0, win0 = 0, t0 = 0, cpu0 = gs_cpu_now();
    for (int64_t k = 0; gs_sweep_meter_steps_left(m) > 0; k++) {
        if (gs_step_serial(s) != GS_OK) {
            fprintf(stderr, "t %.6f: %s: %s\n", s->time, s->diag.field, s->diag.message);
            return 1;
        }
        gs_sweep_meter_step(m, s);
        gs_energy en;
        gs_system_energy(s, &en);
        if (k + 1 == n_settle || (n_settle == 0 && k == 0)) {
            cw0 = en.contact_work;
            win0 = en.work_in;
            t0 = s->time;
        }
        if (k >= n_settle) {
            F[n] = fabs(g->force);
            X[n] = g->deflection;
            T[n] = s->time;
            act[n] = g->n_active;
            n++;
            if (out)
                fprintf(out, "%.9g,%.6g,%.6g,%d\n", s->time, g->deflection * 1e6, g->force, g->n_active);
        }
    }
    double cpu = gs_cpu_now() - cpu0;
    gs_energy en;
    gs_system_energy(s, &en);
    double fmean = 0;
    for (int64_t i = 0; i < n; i++)
        fmean += F[i];
    fmean /= (double)(n > 0 ? n : 1);
    int64_t sep = 0, low = 0, spike = 0;
    for (int64_t i = 0; i < n; i++) {
        sep += act[i] == 0 || F[i] == 0.0;
        low += F[i] < 0.25 * fmean;
        spike += F[i] > 2.0 * fmean;
    }
    double row[GS_SWEEP_MAX_COLUMNS];
    gs_sweep_meter_row(m, row);
    json_object *o = json_object_new_object();
    double fmesh = NAN;
    for (int c = 0; c < gs_sweep_columns(sw); c++) {
        json_object_object_add(o, gs_sweep_column(sw, c), json_object_new_double(row[c]));
        if (!strcmp(gs_sweep_column(sw, c), "mesh_hz"))
            fmesh = row[c];
    }
    /* First mesh harmonic of the DTE over the window (the mean taken out;
     * the window holds whole cycles at the nominal speed). */
    double xm = 0, ac = 0, as = 0;
    for (int64_t i = 0; i < n; i++)
        xm += X[i] / (double)n;
    for (int64_t i = 0; i < n; i++) {
        double w = 2.0 * 3.14159265358979323846 * fmesh * T[i];
        ac += (X[i] - xm) * cos(w);
        as += (X[i] - xm) * sin(w);
    }
    json_object_object_add(o, "dte_h1_um",
                           json_object_new_double(n > 0 ? 2.0 * hypot(ac, as) / (double)n * 1e6 : NAN));
    json_object_object_add(o, "steps", json_object_new_int64(n));
    json_object_object_add(o, "force_mean_n", json_object_new_double(fmean));
    json_object_object_add(o, "separated_fraction", json_object_new_double((double)sep / (double)n));
    json_object_object_add(o, "low_force_fraction", json_object_new_double((double)low / (double)n));
    json_object_object_add(o, "spike_fraction", json_object_new_double((double)spike / (double)n));
    json_object_object_add(o, "window_s", json_object_new_double(s->time - t0));
    json_object_object_add(o, "contact_work_j", json_object_new_double(en.contact_work - cw0));
    json_object_object_add(o, "work_in_j", json_object_new_double(en.work_in - win0));
    json_object_object_add(o, "cpu_seconds", json_object_new_double(cpu));
    printf("%s\n", json_object_to_json_string_ext(o, JSON_C_TO_STRING_PLAIN));
    json_object_put(o);
    if (out)
        fclose(out);
    free(F);
    free(X);
    free(T);
    free(act);
    gs_sweep_meter_free(&m);
    gs_system_free(&s);
    gs_sweep_free(&sw);
    return 0;
}
