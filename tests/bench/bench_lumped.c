/* SPDX-License-Identifier: MIT
 * Benchmark of the rigid lumped planetary step alone (no service): steps per
 * second on one rank for the builtin `planetary` (sun, three planets on a
 * carrier, held ring, six lumped meshes: 5 coordinates) and
 * `planetary_floating` (sun on a bearing joint: 7 coordinates), against the
 * small dense solve inside each Newton iteration (LAPACKE dgesv of the same
 * size, timed in the same run). Prints a table; not a test. Times are the
 * best of 3 batches. Run with OPENBLAS_NUM_THREADS=1. */
#include <lapacke.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/step.h"
#include "gearsim/util.h"

static gs_system *build(const char *name)
{
    const char *txt = gs_scene_builtin(name);
    gs_scene *sc;
    gs_diag d;
    if (gs_scene_parse(txt, strlen(txt), &sc, &d) != GS_OK) {
        fprintf(stderr, "%s: %s\n", d.field, d.message);
        exit(1);
    }
    gs_system *s;
    if (gs_system_new(sc, 0, 1, &s, &d) != GS_OK) {
        fprintf(stderr, "%s: %s\n", d.field, d.message);
        exit(1);
    }
    return s;
}

static double time_solve(int k, int reps)
{
    double *A = malloc(sizeof(double) * (size_t)k * k), *A0 = malloc(sizeof(double) * (size_t)k * k);
    double b[64];
    lapack_int piv[64];
    for (int i = 0; i < k; i++)
        for (int j = 0; j < k; j++)
            A0[i * k + j] = (i == j ? 2.0 : 0.0) + 1.0 / (1.0 + i + j);
    double best = 1e30;
    for (int batch = 0; batch < 3; batch++) {
        double t0 = gs_now();
        for (int r = 0; r < reps; r++) {
            memcpy(A, A0, sizeof(double) * (size_t)k * k);
            for (int i = 0; i < k; i++)
                b[i] = 1.0;
            LAPACKE_dgesv(LAPACK_ROW_MAJOR, k, 1, A, k, piv, b, 1);
        }
        double t = (gs_now() - t0) / reps;
        best = t < best ? t : best;
    }
    free(A), free(A0);
    return best;
}

int main(int argc, char **argv)
{
    int steps = argc > 1 ? atoi(argv[1]) : 100000;
    const char *env = getenv("OPENBLAS_NUM_THREADS");
    printf("# rigid lumped planetary step alone, one rank, best of 3 batches of %d steps (OPENBLAS_NUM_THREADS=%s)\n",
           steps, env ? env : "unset");
    printf("%-20s %6s %12s %10s %10s %12s %10s\n", "scene", "coords", "steps/s", "us/step", "iter/step",
           "dgesv us", "step/solve");
    const char *names[] = {"planetary", "planetary_floating"};
    int only = getenv("BENCH_ONLY") ? atoi(getenv("BENCH_ONLY")) : -1;
    for (int k = 0; k < 2; k++) {
        if (only >= 0 && k != only)
            continue;
        gs_system *s = build(names[k]);
        for (int i = 0; i < 3000; i++) /* past the ramp's start */
            gs_step_serial(s);
        double best = 1e30, iters = 0;
        for (int batch = 0; batch < 3; batch++) {
            long it = 0;
            double t0 = gs_now();
            for (int i = 0; i < steps; i++) {
                if (gs_step_serial(s) != GS_OK) {
                    fprintf(stderr, "%s: step failed\n", names[k]);
                    return 1;
                }
                it += s->last_iterations;
            }
            double t = (gs_now() - t0) / steps;
            best = t < best ? t : best;
            iters = (double)it / steps;
        }
        double ts = time_solve(s->n_coords + s->n_eq, getenv("BENCH_NOSOLVE") ? 10 : 200000);
        printf("%-20s %6d %12.0f %10.3f %10.2f %12.3f %10.1f\n", names[k], s->n_coords, 1.0 / best, best * 1e6,
               iters, ts * 1e6, best / ts);
        gs_system_free(&s);
    }
    return 0;
}
