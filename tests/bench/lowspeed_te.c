/* SPDX-License-Identifier: MIT
 * Dynamic TE at low speed against the quasi-static TE (docs/CONVERGENCE.md
 * "Dynamic TE at low speed"): runs a scene with one `contact` mesh from its
 * start and records the kinematic TE a . q - s_ref of its first mesh every
 * step; over the whole mesh cycles (pitches of the mesh's second gear,
 * counted on its rotation) that lie in [--from, --to] seconds it prints the
 * mean and the rms about the mean, the mean mesh frequency, the largest
 * |balance residual| against the energy scale and the booked contact work.
 * The dynamic TE includes the no-load closing of the flanks (backlash and
 * chord sag, `te0` of gearsim-stiffness): subtract its mean to compare the
 * mean with the static TE.
 *
 *   lowspeed_te SCENE.json [--from 0.1] [--to 0.2] [--csv FILE]
 *
 * Not a test: a run of 0.2 s at h = 1e-5 s takes 2e4 steps of the pair. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/scene.h"
#include "gearsim/step.h"

int main(int argc, char **argv)
{
    const char *path = NULL, *csv = NULL;
    double t0 = 0.1, t1 = 0.2;
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
    if (!path || !(t1 > t0 && t0 >= 0)) {
        fprintf(stderr, "usage: lowspeed_te SCENE.json [--from T0] [--to T1] [--csv FILE]\n");
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
    const gs_gmesh_rt *m = &s->meshes[0];
    int g2 = s->scene->meshes[0].gear[1];
    int c2 = s->bodies[g2].coord, nc = s->n_coords;
    double pitch = 2 * GS_PI / s->scene->bodies[g2].gear.teeth;
    long cap = (long)ceil((t1 - t0) / s->h) + 16, n = 0;
    double *te = malloc(sizeof(double) * (size_t)cap), *th = malloc(sizeof(double) * (size_t)cap);
    FILE *out = csv ? fopen(csv, "w") : NULL;
    if (out)
        fprintf(out, "t_s,angle_rad,te_um\n");
    double worst = 0, scale = 1e-300, cw = 0;
    gs_energy en;
    while (s->time < t1 - 0.5 * s->h) {
        if (gs_step_serial(s) != GS_OK) {
            fprintf(stderr, "t %.6f: %s: %s\n", s->time, s->diag.field, s->diag.message);
            return 1;
        }
        gs_system_energy(s, &en);
        worst = fmax(worst, fabs(en.balance_residual));
        scale = fmax(scale, fmax(fabs(en.total), fmax(en.work_in, en.dissipated)));
        cw = en.contact_work;
        if (s->time < t0 - 0.5 * s->h || n >= cap)
            continue;
        double v = -m->s_ref;
        for (int k = 0; k < nc; k++)
            v += m->a[k] * s->q[k];
        te[n] = v, th[n] = s->q[c2];
        if (out)
            fprintf(out, "%.9g,%.12g,%.6f\n", s->time, th[n], v * 1e6);
        n++;
    }
    if (out)
        fclose(out);
    if (n < 2) {
        fprintf(stderr, "no samples in the window\n");
        return 1;
    }
    /* whole pitches of gear 2 from the first sample (it turns either way) */
    double sgn = th[n - 1] >= th[0] ? 1 : -1, turned = sgn * (th[n - 1] - th[0]);
    int cycles = (int)floor(turned / pitch);
    if (cycles < 1) {
        fprintf(stderr, "the window holds no whole mesh cycle (%.3f)\n", turned / pitch);
        return 1;
    }
    double sx = 0, sxx = 0, lo = INFINITY, hi = -INFINITY;
    long used = 0, last = 0;
    for (long i = 0; i < n && sgn * (th[i] - th[0]) < cycles * pitch; i++) {
        sx += te[i];
        last = i;
        used++;
    }
    double mean = sx / (double)used;
    for (long i = 0; i < used; i++) {
        sxx += (te[i] - mean) * (te[i] - mean);
        lo = fmin(lo, te[i]), hi = fmax(hi, te[i]);
    }
    double rms = sqrt(sxx / (double)used), dt = (double)last * s->h;
    printf("{\"scene\": \"%s\", \"h\": %.3g, \"from\": %.4f, \"cycles\": %d, \"seconds\": %.5f, "
           "\"mesh_hz\": %.2f, \"mean_um\": %.5f, \"rms_um\": %.5f, \"pp_um\": %.5f, \"balance_rel\": %.2e, "
           "\"contact_work_j\": %.4e, \"samples\": %ld}\n",
           path, s->h, t0, cycles, dt, cycles / dt, mean * 1e6, rms * 1e6, (hi - lo) * 1e6, worst / scale, cw, used);
    free(te);
    free(th);
    gs_system_free(&s);
    return 0;
}
