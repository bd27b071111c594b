/* SPDX-License-Identifier: MIT
 * Contact locking at tooth tip corners (issue 15; docs/explanation/contact.md "Tip
 * corners"): runs a builtin scene with one `contact` mesh (default
 * contact_drive) and reports, over the window from --from on, the largest
 * mesh force against the mean, the largest strain energy against the static
 * one, the steps whose force exceeds --factor x the mean, and the steps and
 * episodes in which a loaded contact row's normal lies more than --off
 * degrees off the lines of action, naming the row's slave and master nodes
 * (tests/common/corner_stats.h). Every contact mesh of the scene is
 * watched and reported (planetary_contact: its six meshes); the CSV holds
 * the first.
 *
 *   corner_stats [--scene contact_drive] [--scheme closure_energy] [--h 1e-5]
 *                [--order 2] [--refine 0] [--t 0.2] [--from 0.02] [--off 30]
 *                [--factor 2] [--static-se 1e-3] [--episodes 8] [--csv FILE]
 *                [--zeta 0 --fhz 9200]
 *
 * --static-se is the static strain energy at the running load (J; about
 * 1 mJ for contact_drive, docs/explanation/contact.md). Not a test: 0.2 s at h = 1e-5 s
 * is 2e4 steps of the pair. --zeta Z --fhz F: material damping
 * (damping_ratio Z at damping_hz F) on every elastic gear; the CSV's
 * dissipated energy then holds its loss (docs/explanation/contact.md "Vibration energy
 * without damping"). */
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/bench_args.h"
#include "../common/corner_stats.h"
#include "gearsim/scene.h"
#include "gearsim/step.h"
#include "gearsim/util.h"

#define GS_MAX_MESHES_CS 16

int main(int argc, char **argv)
{
    const char *scene = "contact_drive", *scheme = "closure_energy", *csv = NULL;
    double h = 1e-5, t_end = 0.2, t_from = 0.02, off = 30, factor = 2, se_static = 1e-3, zeta = 0, fhz = 9200;
    int order = 2, refine = 0, n_print = 8;
    const bench_opt opts[] = {
        {"--scene", 's', &scene},
        {"--scheme", 's', &scheme},
        {"--h", 'd', &h},
        {"--order", 'i', &order},
        {"--refine", 'i', &refine},
        {"--t", 'd', &t_end},
        {"--from", 'd', &t_from},
        {"--off", 'd', &off},
        {"--factor", 'd', &factor},
        {"--static-se", 'd', &se_static},
        {"--episodes", 'i', &n_print},
        {"--zeta", 'd', &zeta},
        {"--fhz", 'd', &fhz},
        {"--csv", 's', &csv},
    };
    if (bench_args(argc, argv, NULL, opts, sizeof opts / sizeof *opts))
        return 2;
    const char *txt0 = gs_scene_builtin(scene);
    json_object *root = txt0 ? json_tokener_parse(txt0) : NULL;
    if (!root) {
        fprintf(stderr, "no builtin scene %s\n", scene);
        return 2;
    }
    json_object *num = json_object_object_get(root, "numerics"), *bs = json_object_object_get(root, "bodies");
    json_object_object_add(num, "contact", json_object_new_string(scheme));
    json_object_object_add(num, "time_step", json_object_new_double(h));
    for (size_t i = 0; bs && i < json_object_array_length(bs); i++) {
        json_object *b = json_object_array_get_idx(bs, i), *m, *t;
        if (json_object_object_get_ex(b, "type", &t) && strcmp(json_object_get_string(t), "gear") != 0)
            continue;
        if (!json_object_object_get_ex(b, "mesh", &m)) {
            m = json_object_new_object();
            json_object_object_add(b, "mesh", m);
        }
        json_object_object_add(m, "order", json_object_new_int(order));
        json_object_object_add(m, "refine", json_object_new_int(refine));
        if (zeta > 0) {
            json_object *mat;
            if (!json_object_object_get_ex(b, "material", &mat)) {
                mat = json_object_new_object();
                json_object_object_add(b, "material", mat);
            }
            json_object_object_add(mat, "damping_ratio", json_object_new_double(zeta));
            json_object_object_add(mat, "damping_hz", json_object_new_double(fhz));
        }
    }
    const char *txt = json_object_to_json_string(root);
    gs_scene *sc = NULL;
    gs_diag d;
    if (gs_scene_parse(txt, strlen(txt), &sc, &d) != GS_OK) {
        fprintf(stderr, "scene: %s: %s\n", d.field, d.message);
        return 1;
    }
    json_object_put(root);
    gs_system *s = NULL;
    if (gs_system_new(sc, 0, 1, &s, &d) != GS_OK) {
        fprintf(stderr, "system: %s: %s\n", d.field, d.message);
        return 1;
    }
    FILE *out = csv ? fopen(csv, "w") : NULL;
    int nm = 0, mi[GS_MAX_MESHES_CS];
    for (int i = 0; i < s->scene->n_meshes && nm < GS_MAX_MESHES_CS; i++)
        if (s->scene->meshes[i].model == GS_MESH_CONTACT)
            mi[nm++] = i;
    if (!nm) {
        fprintf(stderr, "scene %s has no contact mesh\n", scene);
        return 2;
    }
    cs_stats *c = calloc((size_t)nm, sizeof *c);
    if (!c)
        return 1;
    for (int j = 0; j < nm; j++)
        cs_init(&c[j], s, mi[j], t_from, off, factor, j == 0 ? out : NULL);
    long n = lround(t_end / s->h);
    double cpu0 = gs_cpu_now();
    for (long i = 0; i < n; i++) {
        gs_err e = gs_step_serial(s);
        if (e != GS_OK) {
            fprintf(stderr, "step %ld: error %d\n", i, (int)e);
            return 1;
        }
        for (int j = 0; j < nm; j++)
            cs_step(&c[j], s);
    }
    double cpu = gs_cpu_now() - cpu0;
    gs_energy en;
    gs_system_energy(s, &en);
    for (int j = 0; j < nm; j++) {
        char label[200];
        cs_finish(&c[j]);
        snprintf(label, sizeof label, "%s mesh %s %s order %d refine %d h %.3g zeta %.3g, %.0f ms", scene,
                 s->scene->meshes[mi[j]].name, scheme, order, refine, h, zeta, t_end * 1e3);
        cs_print(&c[j], stdout, label, se_static, n_print);
    }
    printf("  balance residual %.2e J, contact work still booked %.2e J, dissipated %.4g J of %.4g J in, "
           "%.1f CPU s\n",
           en.balance_residual, en.contact_work, en.dissipated, en.work_in, cpu);
    free(c);
    if (out)
        fclose(out);
    gs_system_free(&s);
    return 0;
}
