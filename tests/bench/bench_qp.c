/* SPDX-License-Identifier: MIT
 * Benchmark of the QP solver: solve time against size, cold against warm
 * start, as a ratio to one dense Cholesky factorisation (LAPACKE dpotrf) of
 * H of the same size timed in the same run. Prints a table; not a test.
 *
 * Each size is a "time-stepping" sequence of problems with the same H and
 * rows and a slowly drifting linear term (the free motion), like successive
 * steps of the simulator; about half of the inequalities bind. Columns:
 *   chol     one dpotrf of H (plus the copy of H it works on)
 *   setup    gs_qp_set_hessian: dpotrf + condition estimate + L^{-T}
 *   cold     gs_qp_solve without warm start (factorises H each time)
 *   cold/f   gs_qp_solve_factored without warm start (factor cached)
 *   warm/f   gs_qp_solve_factored warm-started from the previous step's
 *            active set (factor cached): the simulator's steady state
 *   it       mean dual iterations per solve
 * Times are the best of 5 batches, per solve, in microseconds. Level-2 BLAS
 * on matrices this small gains nothing from threads and loses much on a
 * shared machine: run with OPENBLAS_NUM_THREADS=1 (the header echoes it). */
#include <lapacke.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/qp.h"
#include "gearsim/util.h"

#define TEST_RNG_SEED 0x243f6a8885a308d3ull
#include "../common/rand.h"

#define STEPS 20 /* problems per sequence */

typedef struct {
    int n, neq, nin;
    double *H, *E, *e, *G, *g;
    double *c[STEPS];
} sequence;

static sequence make_sequence(int n, int neq, int nin)
{
    sequence s = {.n = n, .neq = neq, .nin = nin};
    s.H = malloc((size_t)n * n * sizeof(double));
    s.E = malloc(((size_t)n * neq + 1) * sizeof(double));
    s.e = malloc(((size_t)neq + 1) * sizeof(double));
    s.G = malloc(((size_t)n * nin + 1) * sizeof(double));
    s.g = malloc(((size_t)nin + 1) * sizeof(double));
    rand_spd(n, 0.1, s.H);
    double *xf = malloc((size_t)n * sizeof(double)), *dc = malloc((size_t)n * sizeof(double));
    for (int i = 0; i < n; i++)
        xf[i] = nrand();
    for (int i = 0; i < neq; i++) {
        double t = 0.0;
        for (int j = 0; j < n; j++)
            t += (s.E[i * n + j] = nrand()) * xf[j];
        s.e[i] = t;
    }
    for (int i = 0; i < nin; i++) {
        double t = 0.0;
        for (int j = 0; j < n; j++)
            t += (s.G[i * n + j] = nrand()) * xf[j];
        s.g[i] = t - urand();
    }
    /* Unconstrained minimum on the far side of the rows. */
    double *c0 = malloc((size_t)n * sizeof(double));
    for (int i = 0; i < n; i++) {
        c0[i] = 0.0;
        for (int k = 0; k < nin; k++)
            c0[i] -= 3.0 * s.G[k * n + i] / sqrt((double)nin);
        dc[i] = 0.02 * nrand();
    }
    for (int k = 0; k < STEPS; k++) {
        s.c[k] = malloc((size_t)n * sizeof(double));
        for (int i = 0; i < n; i++)
            s.c[k][i] = c0[i] + k * dc[i];
    }
    free(c0);
    free(xf);
    free(dc);
    return s;
}

static void free_sequence(sequence *s)
{
    free(s->H);
    free(s->E);
    free(s->e);
    free(s->G);
    free(s->g);
    for (int k = 0; k < STEPS; k++)
        free(s->c[k]);
}

/* Repetitions so that a batch of the operation lasts about 20 ms. */
static int reps_for(double t_one)
{
    int r = (int)(0.02 / fmax(t_one, 1e-9));
    return r < 1 ? 1 : r;
}

static double time_chol(const sequence *s, double *A)
{
    size_t nn = (size_t)s->n * s->n;
    double t0 = gs_now();
    memcpy(A, s->H, nn * sizeof(double));
    LAPACKE_dpotrf(LAPACK_ROW_MAJOR, 'L', s->n, A, s->n);
    int reps = reps_for(gs_now() - t0);
    double best = INFINITY;
    for (int b = 0; b < 5; b++) {
        t0 = gs_now();
        for (int r = 0; r < reps; r++) {
            memcpy(A, s->H, nn * sizeof(double));
            if (LAPACKE_dpotrf(LAPACK_ROW_MAJOR, 'L', s->n, A, s->n) != 0)
                return NAN;
        }
        best = fmin(best, (gs_now() - t0) / reps);
    }
    return best;
}

static double time_setup(gs_qp *q, const sequence *s)
{
    double t0 = gs_now();
    gs_qp_set_hessian(q, s->n, s->H);
    int reps = reps_for(gs_now() - t0);
    double best = INFINITY;
    for (int b = 0; b < 5; b++) {
        t0 = gs_now();
        for (int r = 0; r < reps; r++)
            if (gs_qp_set_hessian(q, s->n, s->H) != GS_OK)
                return NAN;
        best = fmin(best, (gs_now() - t0) / reps);
    }
    return best;
}

enum mode { COLD, COLD_FACTORED, WARM_FACTORED };

/* One pass over the sequence; returns the time per solve, adds iterations. */
static double run_sequence(gs_qp *q, const sequence *s, enum mode m, gs_qp_result *r, int *warm,
                           long *iters, int *n_active_last, int *fail)
{
    gs_qp_problem p = {.n = s->n, .H = s->H, .n_eq = s->neq, .E = s->E, .e = s->e,
                       .n_in = s->nin, .G = s->G, .g = s->g};
    int nwarm = 0;
    if (m != COLD)
        gs_qp_set_hessian(q, s->n, s->H);
    double t0 = gs_now();
    for (int k = 0; k < STEPS; k++) {
        p.c = s->c[k];
        gs_err e;
        if (m == COLD)
            e = gs_qp_solve(q, &p, NULL, 0, r);
        else if (m == COLD_FACTORED)
            e = gs_qp_solve_factored(q, &p, NULL, 0, r);
        else
            e = gs_qp_solve_factored(q, &p, warm, nwarm, r);
        if (e != GS_OK)
            *fail = 1;
        *iters += r->iterations;
        nwarm = r->n_active;
        memcpy(warm, r->active, (size_t)nwarm * sizeof(int));
    }
    *n_active_last = r->n_active;
    return (gs_now() - t0) / STEPS;
}

static double time_mode(gs_qp *q, const sequence *s, enum mode m, gs_qp_result *r, int *warm,
                        double *mean_iters, int *n_active, int *fail)
{
    long it = 0;
    double t1 = run_sequence(q, s, m, r, warm, &it, n_active, fail);
    *mean_iters = (double)it / STEPS;
    int reps = reps_for(t1 * STEPS);
    double best = INFINITY;
    for (int b = 0; b < 5; b++) {
        double t = 0.0;
        for (int k = 0; k < reps; k++) {
            long dummy = 0;
            t += run_sequence(q, s, m, r, warm, &dummy, n_active, fail);
        }
        best = fmin(best, t / reps);
    }
    return best;
}

int main(void)
{
    const int sizes[] = {10, 20, 50, 100, 150, 200};
    printf("QP solver (Goldfarb-Idnani) against one Cholesky factorisation (dpotrf) of H\n");
    const char *thr = getenv("OPENBLAS_NUM_THREADS");
    printf("n unknowns, n_in = n inequalities, n_eq = n/10 equalities; %d-step sequences,\n"
           "drifting linear term; times per solve in microseconds, best of 5 batches;\n"
           "OPENBLAS_NUM_THREADS=%s\n\n",
           STEPS, thr ? thr : "(unset)");
    printf("| n   | n_eq | n_in | active | chol µs | setup µs | cold µs | cold it | cold/f µs "
           "| warm/f µs | warm it | cold/chol | warm/chol |\n");
    printf("|-----|------|------|--------|---------|----------|---------|---------|-----------"
           "|-----------|---------|-----------|-----------|\n");
    int failed = 0;
    for (size_t si = 0; si < sizeof sizes / sizeof sizes[0]; si++) {
        int n = sizes[si], neq = n / 10, nin = n;
        sequence s = make_sequence(n, neq, nin);
        gs_qp *q = NULL;
        if (gs_qp_new(n, neq, nin, &q) != GS_OK) {
            fprintf(stderr, "bench_qp: out of memory\n");
            return 1;
        }
        gs_qp_result r = {0};
        r.x = malloc((size_t)n * sizeof(double));
        r.lambda_eq = malloc(((size_t)neq + 1) * sizeof(double));
        r.lambda_in = malloc((size_t)nin * sizeof(double));
        r.active = malloc((size_t)nin * sizeof(int));
        int *warm = malloc((size_t)nin * sizeof(int));
        double *A = malloc((size_t)n * n * sizeof(double));

        double t_chol = time_chol(&s, A);
        double t_setup = time_setup(q, &s);
        double it_cold, it_cf, it_warm;
        int na = 0, fail = 0;
        double t_cold = time_mode(q, &s, COLD, &r, warm, &it_cold, &na, &fail);
        double t_cf = time_mode(q, &s, COLD_FACTORED, &r, warm, &it_cf, &na, &fail);
        double t_warm = time_mode(q, &s, WARM_FACTORED, &r, warm, &it_warm, &na, &fail);
        printf("| %3d | %4d | %4d | %6d | %7.1f | %8.1f | %7.1f | %7.1f | %9.1f | %9.1f | %7.2f "
               "| %9.1f | %9.1f |\n",
               n, neq, nin, na, 1e6 * t_chol, 1e6 * t_setup, 1e6 * t_cold, it_cold, 1e6 * t_cf,
               1e6 * t_warm, it_warm, t_cold / t_chol, t_warm / t_chol);
        fflush(stdout);
        failed |= fail;
        free(A);
        free(warm);
        free(r.x);
        free(r.lambda_eq);
        free(r.lambda_in);
        free(r.active);
        gs_qp_free(&q);
        free_sequence(&s);
    }
    if (failed)
        printf("\nsome solves failed\n");
    return failed;
}
