/* SPDX-License-Identifier: MIT
 * Free response of a scene's meshes (tests/bench/train_modes.py,
 * docs/explanation/ltca.md "Planetary trains"): the scene is stepped from
 * its initial state as it stands and every mesh's deflection (s - s_ref,
 * um) and force (N) are written per step, for the frequencies of the mesh
 * modes the loads ring up.
 *
 *   free_response SCENE.json --h H --duration S --csv FILE
 *
 * Prints one JSON object: steps, CPU seconds, the worst energy balance
 * residual over the energy scale. Not a test. */
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/bench_args.h"
#include "gearsim/scene.h"
#include "gearsim/step.h"
#include "gearsim/util.h"

int main(int argc, char **argv)
{
    const char *path = NULL, *csv = NULL;
    double h = NAN, duration = NAN;
    const bench_opt opts[] = {
        {"--h", 'd', &h},
        {"--duration", 'd', &duration},
        {"--csv", 's', &csv},
    };
    if (bench_args(argc, argv, &path, opts, sizeof opts / sizeof *opts))
        return 2;
    if (!path || !csv || !(h > 0) || !(duration > 0)) {
        fprintf(stderr, "usage: free_response SCENE.json --h H --duration S --csv FILE\n");
        return 2;
    }
    json_object *js = json_object_from_file(path);
    if (!js) {
        fprintf(stderr, "%s: cannot read the scene\n", path);
        return 2;
    }
    const char *txt = json_object_to_json_string(js);
    gs_scene *sc = NULL;
    gs_system *s = NULL;
    gs_diag d;
    double cpu0 = gs_cpu_now();
    if (gs_scene_parse(txt, strlen(txt), &sc, &d) != GS_OK) {
        fprintf(stderr, "scene: %s: %s\n", d.field, d.message);
        return 1;
    }
    json_object_put(js);
    sc->time_step = h;
    if (gs_system_new(sc, 0, 1, &s, &d) != GS_OK) {
        fprintf(stderr, "system: %s: %s\n", d.field, d.message);
        return 1;
    }
    double cpu_setup = gs_cpu_now() - cpu0;
    FILE *out = fopen(csv, "w");
    if (!out) {
        perror(csv);
        return 1;
    }
    fprintf(out, "t_s");
    for (int i = 0; i < s->n_meshes; i++)
        fprintf(out, ",x%d_um,f%d_n", i, i);
    fprintf(out, "\n");
    long n = lround(duration / h);
    double worst = 0, scale = 0, cpu1 = gs_cpu_now();
    for (long k = 0; k < n; k++) {
        if (gs_step_serial(s) != GS_OK) {
            fprintf(stderr, "t %.6f: %s: %s\n", s->time, s->diag.field, s->diag.message);
            return 1;
        }
        gs_energy en;
        gs_system_energy(s, &en);
        worst = fmax(worst, fabs(en.balance_residual));
        scale = fmax(scale, fmax(en.total, fmax(en.work_in, en.dissipated)));
        fprintf(out, "%.9g", s->time);
        for (int i = 0; i < s->n_meshes; i++)
            fprintf(out, ",%.9g,%.9g", s->meshes[i].deflection * 1e6, s->meshes[i].force);
        fprintf(out, "\n");
    }
    fclose(out);
    printf("{\"steps\": %ld, \"cpu_setup_s\": %.4g, \"cpu_steps_s\": %.4g, \"balance\": %.3g}\n", n, cpu_setup,
           gs_cpu_now() - cpu1, scale > 0 ? worst / scale : worst);
    gs_system_free(&s);
    return 0;
}
