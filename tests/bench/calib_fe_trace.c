/* SPDX-License-Identifier: MIT
 * The FE reference run of the calibrated lumped mesh (docs/STIFFNESS.md
 * "A non-rattling FE reference run"), stepped once and written out so the
 * spectral and separation figures can be redone without rerunning it: a
 * scene with one `contact` mesh (a JSON file) from its start to --to; every
 * step from --from on one CSV line: time, mesh phase c . q (cycles),
 * line-of-action deflection
 * a . q - s_ref (m), its rate a . w (m/s), the mesh force along the line
 * of action (N), the contact rows with a positive multiplier and in all,
 * the deepest penetration at the step's start (m). The last line on stdout
 * gives the steps of the window, the share of them with no loaded row (the
 * teeth apart) and the CPU seconds of the process.
 *
 *   calib_fe_trace SCENE.json --csv FILE [--from 0.03] [--to 0.06]
 *
 * Not a test: an order-2 run of 6000 steps takes about a minute of CPU. */
#define _POSIX_C_SOURCE 200809L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "gearsim/scene.h"
#include "gearsim/step.h"

static double cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int main(int argc, char **argv)
{
    const char *path = NULL, *csv = NULL;
    double t0 = 0.03, t1 = 0.06;
    for (int i = 1; i < argc; i++) {
        if (argv[i][0] != '-') {
            path = argv[i];
            continue;
        }
        if (i + 1 >= argc) {
            fprintf(stderr, "%s: value missing\n", argv[i]);
            return 2;
        }
        if (!strcmp(argv[i], "--from"))
            t0 = atof(argv[++i]);
        else if (!strcmp(argv[i], "--to"))
            t1 = atof(argv[++i]);
        else if (!strcmp(argv[i], "--csv"))
            csv = argv[++i];
        else {
            fprintf(stderr, "unknown option %s\n", argv[i]);
            return 2;
        }
    }
    if (!path || !csv || !(t1 > t0 && t0 >= 0)) {
        fprintf(stderr, "usage: calib_fe_trace SCENE.json --csv FILE [--from T0] [--to T1]\n");
        return 2;
    }
    FILE *f = fopen(path, "rb");
    if (!f) {
        perror(path);
        return 2;
    }
    static char txt[1 << 20];
    size_t len = fread(txt, 1, sizeof txt - 1, f);
    fclose(f);
    txt[len] = 0;
    gs_scene *sc = NULL;
    gs_diag d;
    if (gs_scene_parse(txt, len, &sc, &d) != GS_OK) {
        fprintf(stderr, "scene: %s: %s\n", d.field, d.message);
        return 1;
    }
    gs_system *s = NULL;
    if (gs_system_new(sc, 0, 1, &s, &d) != GS_OK) {
        fprintf(stderr, "system: %s: %s\n", d.field, d.message);
        return 1;
    }
    FILE *out = fopen(csv, "w");
    if (!out) {
        perror(csv);
        return 2;
    }
    fprintf(out, "t_s,phase_cycles,deflection_m,rate_m_s,force_n,active,rows,penetration_m\n");
    long steps = 0, apart = 0;
    while (s->time < t1 - 0.5 * s->h) {
        if (gs_step_serial(s) != GS_OK) {
            fprintf(stderr, "t %.6f: %s: %s\n", s->time, s->diag.field, s->diag.message);
            return 1;
        }
        if (s->time < t0 - 0.5 * s->h)
            continue;
        const gs_gmesh_rt *m = &s->meshes[0];
        double v = 0, ph = 0;
        for (int j = 0; j < s->n_coords; j++) {
            v += m->a[j] * s->w[j];
            ph += m->c[j] * s->q[j];
        }
        steps++;
        apart += m->n_active == 0;
        fprintf(out, "%.9g,%.9f,%.9e,%.9e,%.6e,%d,%d,%.4e\n", s->time, ph, m->deflection, v, m->force, m->n_active,
                m->n_rows, m->penetration);
    }
    fclose(out);
    printf("{\"scene\": \"%s\", \"h\": %.3g, \"steps\": %ld, \"apart\": %.5f, \"cpu_s\": %.1f}\n", path, s->h, steps,
           steps ? (double)apart / (double)steps : 0.0, cpu_now());
    gs_system_free(&s);
    return 0;
}
