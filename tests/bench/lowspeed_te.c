/* SPDX-License-Identifier: MIT
 * Dynamic TE at low speed against the quasi-static TE (docs/validation/lowspeed.md):
 * runs a scene with one `contact` mesh from its
 * start and records the kinematic TE a . q - s_ref of its first mesh every
 * step; over the whole mesh cycles (counted on the mesh phase c . q) that
 * lie in [--from, --to] seconds it prints the
 * mean and the rms about the mean, the mean mesh frequency, the largest
 * |balance residual| against the energy scale and the booked contact work.
 * The CSV also has per step the TE's rate a . w (m/s), the mesh force (N),
 * the loaded and all contact rows and the deepest penetration (m); the JSON
 * the share of the window's steps with no loaded row ("apart": the teeth
 * separated; docs/explanation/stiffness.md "A non-rattling FE reference run").
 * The dynamic TE includes the no-load closing of the flanks (backlash and
 * chord sag, `te0` of gearsim-stiffness): subtract its mean to compare the
 * mean with the static TE.
 *
 *   lowspeed_te SCENE.json [--from 0.1] [--to 0.2] [--csv FILE] [--nf-offsets 1|0]
 *
 * --nf-offsets 0: a "nearfield" mesh's rows keep the FE flanks' node-sampled
 * gaps (the test hook gsi_stiffness_nf_no_offsets; docs/explanation/contact.md
 * "Near-field compliance").
 *
 * Not a test: a run of 0.2 s at h = 1e-5 s takes 2e4 steps of the pair. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/bench_args.h"
#include "../common/dyn_window.h"
#include "contact/stiffness_hook.h"
#include "gearsim/scene.h"
#include "gearsim/step.h"

int main(int argc, char **argv)
{
    const char *path = NULL, *csv = NULL;
    double t0 = 0.1, t1 = 0.2;
    int nf_offsets = 1;
    const bench_opt opts[] = {
        {"--from", 'd', &t0},
        {"--to", 'd', &t1},
        {"--csv", 's', &csv},
        {"--nf-offsets", 'i', &nf_offsets},
    };
    if (bench_args(argc, argv, &path, opts, sizeof opts / sizeof *opts))
        return 2;
    if (!path || !(t1 > t0 && t0 >= 0)) {
        fprintf(stderr, "usage: lowspeed_te SCENE.json [--from T0] [--to T1] [--csv FILE] [--nf-offsets 1|0]\n");
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
    gsi_stiffness_nf_no_offsets = !nf_offsets;
    gs_err se = gs_system_new(sc, 0, 1, &s, &d);
    gsi_stiffness_nf_no_offsets = 0;
    if (se != GS_OK) {
        fprintf(stderr, "system: %s: %s\n", d.field, d.message);
        return 1;
    }
    FILE *out = csv ? fopen(csv, "w") : NULL;
    if (out)
        fprintf(out, "t_s,phase_cycles,te_um,rate_m_s,force_n,active,rows,penetration_m\n");
    dyn_window w = {0};
    long steps = 0, apart = 0; /* window steps, those with no loaded contact row (the teeth apart) */
    while (s->time < t1 - 0.5 * s->h) {
        if (gs_step_serial(s) != GS_OK) {
            fprintf(stderr, "t %.6f: %s: %s\n", s->time, s->diag.field, s->diag.message);
            return 1;
        }
        dw_energy(&w, s);
        if (s->time < t0 - 0.5 * s->h)
            continue;
        if (dw_sample(&w, s, 0, -1, -1) != 0) {
            fprintf(stderr, "out of memory\n");
            return 1;
        }
        const dw_sample_t *x = &w.s[w.n - 1];
        const gs_gmesh_rt *m = &s->meshes[0];
        steps++;
        apart += m->ops->contact && m->n_active == 0;
        double v = 0; /* the deflection's rate a . w */
        for (int j = 0; j < s->n_coords; j++)
            v += m->a[j] * s->w[j];
        if (out)
            fprintf(out, "%.9g,%.12g,%.6f,%.9e,%.6e,%d,%d,%.4e\n", x->t, x->phase, x->te * 1e6, v, m->force,
                    m->n_active, m->n_rows, m->penetration);
    }
    if (out)
        fclose(out);
    dyn_figures fig;
    if (dw_finish(&w, &fig) != 0) {
        fprintf(stderr, "the window holds no whole mesh cycle\n");
        return 1;
    }
    printf("{\"scene\": \"%s\", \"h\": %.3g, \"from\": %.4f, \"cycles\": %d, \"seconds\": %.5f, "
           "\"mesh_hz\": %.2f, \"mean_um\": %.5f, \"rms_um\": %.5f, \"pp_um\": %.5f, \"balance_rel\": %.2e, "
           "\"contact_work_j\": %.4e, \"samples\": %ld, \"apart\": %.5f}\n",
           path, s->h, t0, fig.cycles, fig.seconds, fig.mesh_hz, fig.te_mean * 1e6, fig.te_rms * 1e6, fig.te_pp * 1e6,
           fig.balance_rel, w.contact_work, fig.used, steps ? (double)apart / (double)steps : 0.0);
    dw_free(&w);
    gs_system_free(&s);
    return 0;
}
