/* SPDX-License-Identifier: MIT
 * Unit tests of the Goldfarb-Idnani QP solver: closed-form cases, KKT
 * conditions on random problems, warm start, degenerate, infeasible and
 * singular problems, argument checking. (The cross-check against an
 * independent solver is tests/validation/test_qp_cvxopt.py.) */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/qp.h"

#define TEST_RNG_SEED 0x9e3779b97f4a7c15ull
#include "../common/rand.h"

/* ------------------------------------------------------------ helpers */

static int irand(int lo, int hi) /* in [lo, hi] */
{
    return lo + (int)(urand() * (hi - lo + 1));
}

/* A problem with its own storage. */
typedef struct {
    int n, neq, nin;
    double *H, *c, *E, *e, *G, *g;
} owned;

static owned owned_new(int n, int neq, int nin)
{
    owned o = {n, neq, nin, NULL, NULL, NULL, NULL, NULL, NULL};
    o.H = calloc((size_t)n * n, sizeof(double));
    o.c = calloc((size_t)n, sizeof(double));
    o.E = calloc((size_t)n * neq + 1, sizeof(double));
    o.e = calloc((size_t)neq + 1, sizeof(double));
    o.G = calloc((size_t)n * nin + 1, sizeof(double));
    o.g = calloc((size_t)nin + 1, sizeof(double));
    return o;
}

static void owned_free(owned *o)
{
    free(o->H);
    free(o->c);
    free(o->E);
    free(o->e);
    free(o->G);
    free(o->g);
}

static gs_qp_problem view(const owned *o)
{
    gs_qp_problem p = {.n = o->n, .H = o->H, .c = o->c, .n_eq = o->neq, .E = o->E, .e = o->e,
                       .n_in = o->nin, .G = o->G, .g = o->g};
    return p;
}

static gs_qp_result result_new(int n, int neq, int nin)
{
    gs_qp_result r = {0};
    r.x = calloc((size_t)n, sizeof(double));
    r.lambda_eq = calloc((size_t)neq + 1, sizeof(double));
    r.lambda_in = calloc((size_t)nin + 1, sizeof(double));
    r.active = calloc((size_t)nin + 1, sizeof(int));
    return r;
}

static void result_free(gs_qp_result *r)
{
    free(r->x);
    free(r->lambda_eq);
    free(r->lambda_in);
    free(r->active);
}

/* Random feasible problem: rows through or around a point x_f away from the
 * unconstrained minimum, so many rows bind. */
static owned rand_problem(int n, int neq, int nin)
{
    owned o = owned_new(n, neq, nin);
    rand_spd(n, 0.1 + urand(), o.H);
    double *xf = malloc((size_t)n * sizeof *xf);
    for (int i = 0; i < n; i++) {
        o.c[i] = 3.0 * nrand();
        xf[i] = nrand();
    }
    for (int i = 0; i < neq; i++) {
        double s = 0.0;
        for (int j = 0; j < n; j++) {
            o.E[i * n + j] = nrand();
            s += o.E[i * n + j] * xf[j];
        }
        o.e[i] = s;
    }
    for (int i = 0; i < nin; i++) {
        double s = 0.0;
        for (int j = 0; j < n; j++) {
            o.G[i * n + j] = nrand();
            s += o.G[i * n + j] * xf[j];
        }
        o.g[i] = s - (urand() < 0.3 ? 0.0 : urand());
    }
    free(xf);
    return o;
}

/* Largest relative KKT residual: stationarity, equalities, inequalities,
 * sign of the multipliers, complementarity. */
static double kkt_residual(const owned *o, const gs_qp_result *r)
{
    int n = o->n;
    double xn = 0.0, worst = 0.0;
    for (int i = 0; i < n; i++)
        xn += r->x[i] * r->x[i];
    xn = sqrt(xn);
    double lmax = 1.0;
    for (int j = 0; j < o->nin; j++)
        lmax = fmax(lmax, fabs(r->lambda_in[j]));
    for (int i = 0; i < o->neq; i++)
        lmax = fmax(lmax, fabs(r->lambda_eq[i]));
    for (int i = 0; i < n; i++) {
        double gi = -o->c[i], sc = fabs(o->c[i]);
        for (int j = 0; j < n; j++) {
            gi += o->H[i * n + j] * r->x[j];
            sc += fabs(o->H[i * n + j] * r->x[j]);
        }
        for (int k = 0; k < o->neq; k++) {
            gi -= o->E[k * n + i] * r->lambda_eq[k];
            sc += fabs(o->E[k * n + i] * r->lambda_eq[k]);
        }
        for (int k = 0; k < o->nin; k++) {
            gi -= o->G[k * n + i] * r->lambda_in[k];
            sc += fabs(o->G[k * n + i] * r->lambda_in[k]);
        }
        worst = fmax(worst, fabs(gi) / (sc + 1.0));
    }
    for (int k = 0; k < o->neq + o->nin; k++) {
        int eq = k < o->neq;
        const double *row = eq ? o->E + (size_t)k * n : o->G + (size_t)(k - o->neq) * n;
        double b = eq ? o->e[k] : o->g[k - o->neq];
        double s = -b, nr = 0.0;
        for (int j = 0; j < n; j++) {
            s += row[j] * r->x[j];
            nr += row[j] * row[j];
        }
        double sc = fabs(b) + sqrt(nr) * fmax(1.0, xn) + 1e-300;
        if (eq) {
            worst = fmax(worst, fabs(s) / sc);
        } else {
            double lam = r->lambda_in[k - o->neq];
            worst = fmax(worst, fmax(-s, 0.0) / sc);
            worst = fmax(worst, fmax(-lam, 0.0) / lmax);
            worst = fmax(worst, fabs(lam * s) / (sc * lmax));
        }
    }
    return worst;
}

static double max_rel_diff(const double *a, const double *b, int n)
{
    double d = 0.0, m = 1.0;
    for (int i = 0; i < n; i++) {
        d = fmax(d, fabs(a[i] - b[i]));
        m = fmax(m, fabs(b[i]));
    }
    return d / m;
}

/* ------------------------------------------------------------ closed forms */

static void unconstrained(void **state)
{
    (void)state;
    int n = 12;
    owned o = owned_new(n, 0, 0);
    rand_spd(n, 0.5, o.H);
    for (int i = 0; i < n; i++)
        o.c[i] = nrand();
    gs_qp *q = NULL;
    assert_int_equal(gs_qp_new(n, 0, 0, &q), GS_OK);
    gs_qp_problem p = view(&o);
    gs_qp_result r = result_new(n, 0, 0);
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_OK);
    /* H x = c, objective -1/2 c^T x. */
    double ctx = 0.0;
    for (int i = 0; i < n; i++) {
        double s = -o.c[i];
        for (int j = 0; j < n; j++)
            s += o.H[i * n + j] * r.x[j];
        assert_true(fabs(s) < 1e-13);
        ctx += o.c[i] * r.x[i];
    }
    assert_true(fabs(r.objective + 0.5 * ctx) < 1e-13 * fmax(1.0, fabs(ctx)));
    assert_int_equal(r.n_active, 0);
    assert_int_equal(r.iterations, 0);
    result_free(&r);
    gs_qp_free(&q);
    assert_null(q);
    owned_free(&o);
}

static void single_equality(void **state)
{
    (void)state;
    /* min 1/2 sum h_i x_i^2 - c^T x  s.t.  a^T x = b:
     * x = D^{-1}(c + a lam), lam = (b - a^T D^{-1} c) / (a^T D^{-1} a). */
    int n = 7;
    owned o = owned_new(n, 1, 0);
    double h[7], aDc = 0.0, aDa = 0.0;
    for (int i = 0; i < n; i++) {
        h[i] = 0.5 + urand();
        o.H[i * n + i] = h[i];
        o.c[i] = nrand();
        o.E[i] = nrand();
        aDc += o.E[i] * o.c[i] / h[i];
        aDa += o.E[i] * o.E[i] / h[i];
    }
    o.e[0] = 1.5;
    double lam = (o.e[0] - aDc) / aDa;
    gs_qp *q = NULL;
    assert_int_equal(gs_qp_new(n, 1, 0, &q), GS_OK);
    gs_qp_problem p = view(&o);
    gs_qp_result r = result_new(n, 1, 0);
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_OK);
    for (int i = 0; i < n; i++)
        assert_true(fabs(r.x[i] - (o.c[i] + o.E[i] * lam) / h[i]) < 1e-14);
    assert_true(fabs(r.lambda_eq[0] - lam) < 1e-13 * fmax(1.0, fabs(lam)));
    result_free(&r);
    gs_qp_free(&q);
    owned_free(&o);
}

static void box(void **state)
{
    (void)state;
    /* Diagonal H, lo <= x <= hi: x = clamp(c_i / h_i), multipliers of the
     * bound that binds = |h_i x_i - c_i|. */
    int n = 20;
    owned o = owned_new(n, 0, 2 * n);
    double h[20], lo[20], hi[20];
    for (int i = 0; i < n; i++) {
        h[i] = 0.5 + urand();
        lo[i] = -urand();
        hi[i] = urand();
        o.H[i * n + i] = h[i];
        o.c[i] = 2.0 * nrand();
        o.G[i * n + i] = 1.0; /* x_i >= lo_i */
        o.g[i] = lo[i];
        o.G[(n + i) * n + i] = -1.0; /* -x_i >= -hi_i */
        o.g[n + i] = -hi[i];
    }
    gs_qp *q = NULL;
    assert_int_equal(gs_qp_new(n, 0, 2 * n, &q), GS_OK);
    gs_qp_problem p = view(&o);
    gs_qp_result r = result_new(n, 0, 2 * n);
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_OK);
    int nb = 0;
    for (int i = 0; i < n; i++) {
        double xu = o.c[i] / h[i];
        double x = fmin(fmax(xu, lo[i]), hi[i]);
        assert_true(fabs(r.x[i] - x) < 1e-14);
        double lam_lo = xu < lo[i] ? h[i] * lo[i] - o.c[i] : 0.0;
        double lam_hi = xu > hi[i] ? o.c[i] - h[i] * hi[i] : 0.0;
        assert_true(fabs(r.lambda_in[i] - lam_lo) < 1e-14);
        assert_true(fabs(r.lambda_in[n + i] - lam_hi) < 1e-14);
        nb += (xu < lo[i]) + (xu > hi[i]);
    }
    assert_int_equal(r.n_active, nb);
    result_free(&r);
    gs_qp_free(&q);
    owned_free(&o);
}

static int cmp_desc(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x < y) - (x > y);
}

static void simplex_projection(void **state)
{
    (void)state;
    /* min 1/2 |x - y|^2, sum x = 1, x >= 0: x = max(y - tau, 0) with tau
     * from the sorted y (Held-Wolfe-Crowder); lambda_eq = -tau,
     * lambda_in_i = tau - y_i where x_i = 0. */
    for (int trial = 0; trial < 50; trial++) {
        int n = irand(2, 40);
        owned o = owned_new(n, 1, n);
        double *ys = malloc((size_t)n * sizeof *ys);
        for (int i = 0; i < n; i++) {
            o.H[i * n + i] = 1.0;
            o.c[i] = ys[i] = nrand();
            o.E[i] = 1.0;
            o.G[i * n + i] = 1.0;
        }
        o.e[0] = 1.0;
        qsort(ys, (size_t)n, sizeof *ys, cmp_desc);
        double cum = 0.0, tau = 0.0;
        for (int k = 0; k < n; k++) {
            cum += ys[k];
            double t = (cum - 1.0) / (k + 1);
            if (ys[k] - t > 0.0)
                tau = t;
        }
        gs_qp *q = NULL;
        assert_int_equal(gs_qp_new(n, 1, n, &q), GS_OK);
        gs_qp_problem p = view(&o);
        gs_qp_result r = result_new(n, 1, n);
        assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_OK);
        for (int i = 0; i < n; i++) {
            double x = fmax(o.c[i] - tau, 0.0);
            assert_true(fabs(r.x[i] - x) < 1e-14);
            if (x == 0.0)
                assert_true(fabs(r.lambda_in[i] - (tau - o.c[i])) < 1e-13);
            else
                assert_true(r.lambda_in[i] == 0.0);
        }
        assert_true(fabs(r.lambda_eq[0] + tau) < 1e-13);
        result_free(&r);
        gs_qp_free(&q);
        owned_free(&o);
        free(ys);
    }
}

/* ------------------------------------------------------------ random KKT */

static void kkt_random(void **state)
{
    (void)state;
    double worst = 0.0;
    int total_active = 0;
    for (int trial = 0; trial < 300; trial++) {
        int n = irand(2, 50);
        int neq = irand(0, n / 2);
        int nin = irand(0, 3 * n);
        owned o = rand_problem(n, neq, nin);
        gs_qp *q = NULL;
        assert_int_equal(gs_qp_new(n, neq, nin, &q), GS_OK);
        gs_qp_problem p = view(&o);
        gs_qp_result r = result_new(n, neq, nin);
        assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_OK);
        double k = kkt_residual(&o, &r);
        worst = fmax(worst, k);
        assert_true(k < 1e-12);
        /* lambda_in is zero off the active set, >= 0 on it. */
        int cnt = 0;
        for (int j = 0; j < nin; j++)
            cnt += r.lambda_in[j] != 0.0;
        assert_true(cnt <= r.n_active);
        total_active += r.n_active;
        result_free(&r);
        gs_qp_free(&q);
        owned_free(&o);
    }
    printf("# kkt_random: 300 problems, n 2..50, max relative KKT residual %.2e, "
           "%d active rows in all\n", worst, total_active);
}

/* ------------------------------------------------------------ warm start */

static void warm_start(void **state)
{
    (void)state;
    /* A sequence of "time steps": the same rows, a slowly drifting linear
     * term (as the free motion drifts), each step warm-started from the
     * previous step's active set, against cold solves. */
    int n = 40, neq = 4, nin = 80, steps = 50;
    owned o = rand_problem(n, neq, nin);
    double *c0 = malloc((size_t)n * sizeof *c0), *dc = malloc((size_t)n * sizeof *dc);
    for (int i = 0; i < n; i++) {
        c0[i] = o.c[i];
        dc[i] = 0.1 * nrand();
    }
    gs_qp *qc = NULL, *qw = NULL;
    assert_int_equal(gs_qp_new(n, neq, nin, &qc), GS_OK);
    assert_int_equal(gs_qp_new(n, neq, nin, &qw), GS_OK);
    assert_int_equal(gs_qp_set_hessian(qw, n, o.H), GS_OK);
    gs_qp_result rc = result_new(n, neq, nin), rw = result_new(n, neq, nin);
    int *warm = calloc((size_t)nin, sizeof *warm), nwarm = 0;
    long it_cold = 0, it_warm = 0, kept = 0, changes = 0;
    double dev = 0.0;
    for (int s = 0; s < steps; s++) {
        for (int i = 0; i < n; i++)
            o.c[i] = c0[i] + s * dc[i];
        gs_qp_problem p = view(&o);
        assert_int_equal(gs_qp_solve(qc, &p, NULL, 0, &rc), GS_OK);
        assert_int_equal(gs_qp_solve_factored(qw, &p, warm, nwarm, &rw), GS_OK);
        dev = fmax(dev, max_rel_diff(rw.x, rc.x, n));
        dev = fmax(dev, max_rel_diff(rw.lambda_in, rc.lambda_in, nin));
        assert_true(fabs(rw.objective - rc.objective) < 1e-12 * fmax(1.0, fabs(rc.objective)));
        if (s > 0) {
            it_cold += rc.iterations;
            it_warm += rw.iterations;
            kept += rw.n_warm_kept;
            changes += rw.iterations > 0 || rw.n_warm_kept != nwarm;
        }
        nwarm = rw.n_active;
        memcpy(warm, rw.active, (size_t)nwarm * sizeof *warm);
    }
    assert_true(dev < 1e-11);
    assert_true(it_warm < it_cold);
    printf("# warm_start: %d steps, n=%d, %d equalities, %d inequalities (%d active at the end), "
           "active set changed in %ld steps: dual iterations cold %ld, warm %ld (%.2f vs %.2f per "
           "step), %ld warm rows kept, max deviation %.1e\n",
           steps - 1, n, neq, nin, nwarm, changes, it_cold, it_warm, (double)it_cold / (steps - 1),
           (double)it_warm / (steps - 1), kept, dev);

    /* From the exact active set: no dual iteration at all. */
    gs_qp_problem p = view(&o);
    assert_int_equal(gs_qp_solve(qc, &p, NULL, 0, &rc), GS_OK);
    assert_int_equal(gs_qp_solve_factored(qw, &p, rc.active, rc.n_active, &rw), GS_OK);
    assert_int_equal(rw.iterations, 0);
    assert_int_equal(rw.n_warm_kept, rc.n_active);
    assert_true(max_rel_diff(rw.x, rc.x, n) < 1e-12);
    printf("# warm_start: exact active set (%d rows): cold %d iterations, warm %d\n", rc.n_active,
           rc.iterations, rw.iterations);

    /* A wrong guess (every row) costs iterations, not accuracy. */
    for (int j = 0; j < nin; j++)
        warm[j] = j;
    assert_int_equal(gs_qp_solve_factored(qw, &p, warm, nin, &rw), GS_OK);
    assert_true(max_rel_diff(rw.x, rc.x, n) < 1e-11);
    assert_true(kkt_residual(&o, &rw) < 1e-12);
    /* Duplicates in the warm list are ignored. */
    for (int j = 0; j < nin; j++)
        warm[j] = rc.n_active ? rc.active[j % rc.n_active] : 0;
    assert_int_equal(gs_qp_solve_factored(qw, &p, warm, nin, &rw), GS_OK);
    assert_true(max_rel_diff(rw.x, rc.x, n) < 1e-12);

    result_free(&rc);
    result_free(&rw);
    gs_qp_free(&qc);
    gs_qp_free(&qw);
    free(warm);
    free(c0);
    free(dc);
    owned_free(&o);
}

/* ------------------------------------------------------------ factored */

static void factored_variants(void **state)
{
    (void)state;
    int n = 25, neq = 3, nin = 40;
    owned o = rand_problem(n, neq, nin);
    gs_qp *q = NULL;
    assert_int_equal(gs_qp_new(n, neq, nin, &q), GS_OK);
    gs_qp_problem p = view(&o);
    gs_qp_result r0 = result_new(n, neq, nin), r1 = result_new(n, neq, nin);
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r0), GS_OK);

    /* Cached factor, several right-hand sides. */
    assert_int_equal(gs_qp_set_hessian(q, n, o.H), GS_OK);
    p.H = NULL; /* ignored by solve_factored */
    assert_int_equal(gs_qp_solve_factored(q, &p, NULL, 0, &r1), GS_OK);
    assert_true(max_rel_diff(r1.x, r0.x, n) == 0.0);
    assert_int_equal(gs_qp_solve_factored(q, &p, NULL, 0, &r1), GS_OK);
    assert_true(max_rel_diff(r1.x, r0.x, n) == 0.0);

    /* A Cholesky factor from the caller (computed here by hand). */
    double *L = calloc((size_t)n * n, sizeof *L);
    for (int j = 0; j < n; j++) {
        double s = o.H[j * n + j];
        for (int k = 0; k < j; k++)
            s -= L[j * n + k] * L[j * n + k];
        L[j * n + j] = sqrt(s);
        for (int i = j + 1; i < n; i++) {
            double t = o.H[i * n + j];
            for (int k = 0; k < j; k++)
                t -= L[i * n + k] * L[j * n + k];
            L[i * n + j] = t / L[j * n + j];
        }
    }
    assert_int_equal(gs_qp_set_cholesky(q, n, L), GS_OK);
    assert_int_equal(gs_qp_solve_factored(q, &p, NULL, 0, &r1), GS_OK);
    assert_true(max_rel_diff(r1.x, r0.x, n) < 1e-13);
    assert_true(fabs(r1.objective - r0.objective) < 1e-13 * fmax(1.0, fabs(r0.objective)));

    /* The factor has a size: another n is refused. */
    p.n = n - 1;
    assert_int_equal(gs_qp_solve_factored(q, &p, NULL, 0, &r1), GS_EINVAL);

    /* The workspace serves smaller problems too. */
    owned s = rand_problem(5, 1, 6);
    gs_qp_problem ps = view(&s);
    assert_int_equal(gs_qp_solve(q, &ps, NULL, 0, &r1), GS_OK);
    assert_true(kkt_residual(&s, &r1) < 1e-13);

    free(L);
    result_free(&r0);
    result_free(&r1);
    gs_qp_free(&q);
    owned_free(&o);
    owned_free(&s);
}

/* ------------------------------------------------------------ degenerate */

static void degenerate(void **state)
{
    (void)state;
    gs_qp *q = NULL;
    int n = 6;
    assert_int_equal(gs_qp_new(n, 8, 40, &q), GS_OK);

    /* Vertex of a pyramid: x* = 0 on 2n rows through the origin (twice as
     * many as unknowns), n of them carrying the force, the others weakly
     * active; plus each binding row duplicated and scaled, and zero rows. */
    owned o = owned_new(n, 0, 4 * n + 2);
    rand_spd(n, 0.5, o.H);
    double lam[6];
    for (int k = 0; k < n; k++) {
        lam[k] = 0.5 + urand();
        for (int j = 0; j < n; j++)
            o.G[k * n + j] = nrand();
    }
    for (int k = n; k < 2 * n; k++) /* weak: other rows through the origin */
        for (int j = 0; j < n; j++)
            o.G[k * n + j] = nrand();
    for (int k = 0; k < n; k++) /* duplicates, one scaled by 3 */
        for (int j = 0; j < n; j++) {
            o.G[(2 * n + k) * n + j] = o.G[k * n + j];
            o.G[(3 * n + k) * n + j] = 3.0 * o.G[k * n + j];
        }
    o.g[4 * n + 1] = -1.0; /* zero rows 0 >= 0 and 0 >= -1 */
    for (int i = 0; i < n; i++) { /* c = H x* - G_A^T lam with x* = 0 */
        o.c[i] = 0.0;
        for (int k = 0; k < n; k++)
            o.c[i] -= o.G[k * n + i] * lam[k];
    }
    /* x* = 0 satisfies every row (all pass through 0 or are 0 >= -1) and
     * the KKT conditions with lam on the first n rows: it is the optimum,
     * a vertex with 3n + 1 rows tight and multipliers that are not unique. */
    gs_qp_problem p = view(&o);
    gs_qp_result r = result_new(n, 8, 40);
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_OK);
    double xmax = 0.0;
    for (int i = 0; i < n; i++)
        xmax = fmax(xmax, fabs(r.x[i]));
    assert_true(xmax < 1e-14);
    assert_true(kkt_residual(&o, &r) < 1e-13);
    printf("# degenerate vertex: %d rows (%d tight at x*), %d active, %d weakly active, "
           "|x - x*| %.1e, %d iterations\n",
           o.nin, 4 * n + 1, r.n_active, r.n_weak, xmax, r.iterations);
    assert_true(r.n_active <= n);
    assert_int_equal(r.n_active + r.n_weak, 4 * n + 1);

    /* Warm start from all rows, duplicates included: same answer. */
    int all[26];
    for (int j = 0; j < o.nin; j++)
        all[j] = j;
    gs_qp_result r2 = result_new(n, 8, 40);
    assert_int_equal(gs_qp_solve(q, &p, all, o.nin, &r2), GS_OK);
    for (int i = 0; i < n; i++)
        assert_true(fabs(r2.x[i]) < 1e-14);
    assert_true(kkt_residual(&o, &r2) < 1e-13);
    result_free(&r2);
    owned_free(&o);

    /* Redundant, consistent equalities: row 2 = row 0 + 2 row 1, row 3 =
     * row 0, plus a zero row with zero right-hand side. */
    o = rand_problem(n, 5, 6);
    for (int j = 0; j < n; j++) {
        o.E[2 * n + j] = o.E[j] + 2.0 * o.E[n + j];
        o.E[3 * n + j] = o.E[j];
        o.E[4 * n + j] = 0.0;
    }
    o.e[2] = o.e[0] + 2.0 * o.e[1];
    o.e[3] = o.e[0];
    o.e[4] = 0.0;
    p = view(&o);
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_OK);
    assert_int_equal(r.n_eq_dependent, 3);
    assert_true(kkt_residual(&o, &r) < 1e-13);
    owned_free(&o);

    /* Nearly parallel binding rows (1e-7 apart) through one point. */
    o = owned_new(n, 0, 3);
    rand_spd(n, 0.5, o.H);
    for (int j = 0; j < n; j++) {
        double b = nrand();
        o.G[j] = b;
        o.G[n + j] = b + 1e-7 * nrand();
        o.G[2 * n + j] = b + 1e-7 * nrand();
        o.c[j] = -10.0 * b;
    }
    p = view(&o);
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_OK);
    assert_true(kkt_residual(&o, &r) < 1e-12);
    owned_free(&o);

    result_free(&r);
    gs_qp_free(&q);
}

/* ------------------------------------------------------------ failures */

static void infeasible(void **state)
{
    (void)state;
    int n = 4;
    gs_qp *q = NULL;
    assert_int_equal(gs_qp_new(n, 4, 8, &q), GS_OK);
    gs_qp_result r = result_new(n, 4, 8);
    owned o;
    gs_qp_problem p;

    /* x0 >= 1 and -x0 >= 0. */
    o = owned_new(n, 0, 2);
    rand_spd(n, 0.5, o.H);
    o.G[0] = 1.0;
    o.g[0] = 1.0;
    o.G[n] = -1.0;
    o.g[1] = 0.0;
    p = view(&o);
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_EINFEASIBLE);
    assert_true(r.conflict_in == 0 || r.conflict_in == 1);
    assert_int_equal(r.conflict_eq, -1);
    /* and warm-started from both rows */
    int both[2] = {0, 1};
    assert_int_equal(gs_qp_solve(q, &p, both, 2, &r), GS_EINFEASIBLE);
    owned_free(&o);

    /* Three rows with a positive combination 0 but positive right-hand
     * side (Farkas): x0 >= 1, x1 >= 1, -x0 - x1 >= -1. */
    o = owned_new(n, 0, 3);
    rand_spd(n, 0.5, o.H);
    o.G[0] = 1.0;
    o.g[0] = 1.0;
    o.G[n + 1] = 1.0;
    o.g[1] = 1.0;
    o.G[2 * n] = -1.0;
    o.G[2 * n + 1] = -1.0;
    o.g[2] = -1.0;
    p = view(&o);
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_EINFEASIBLE);
    assert_true(r.conflict_in >= 0);
    owned_free(&o);

    /* Inconsistent equalities: x0 + x1 = 1, 2 x0 + 2 x1 = 3. */
    o = owned_new(n, 2, 0);
    rand_spd(n, 0.5, o.H);
    o.E[0] = o.E[1] = 1.0;
    o.e[0] = 1.0;
    o.E[n] = o.E[n + 1] = 2.0;
    o.e[1] = 3.0;
    p = view(&o);
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_EINFEASIBLE);
    assert_int_equal(r.conflict_eq, 1);
    owned_free(&o);

    /* Equality against an inequality: x0 = 0, x0 >= 1. */
    o = owned_new(n, 1, 1);
    rand_spd(n, 0.5, o.H);
    o.E[0] = 1.0;
    o.G[0] = 1.0;
    o.g[0] = 1.0;
    p = view(&o);
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_EINFEASIBLE);
    assert_int_equal(r.conflict_in, 0);
    owned_free(&o);

    /* A zero row with a positive right-hand side: 0 >= 1e-3. */
    o = owned_new(n, 0, 2);
    rand_spd(n, 0.5, o.H);
    o.G[0] = 1.0;
    o.g[1] = 1e-3;
    p = view(&o);
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_EINFEASIBLE);
    assert_int_equal(r.conflict_in, 1);
    owned_free(&o);

    result_free(&r);
    gs_qp_free(&q);
}

static void singular_hessian(void **state)
{
    (void)state;
    int n = 5;
    gs_qp *q = NULL;
    assert_int_equal(gs_qp_new(n, 0, 2, &q), GS_OK);
    gs_qp_result r = result_new(n, 0, 2);
    owned o = owned_new(n, 0, 0);
    gs_qp_problem p = view(&o);

    /* Indefinite: diag(1, 1, -1, 1, 1). */
    for (int i = 0; i < n; i++)
        o.H[i * n + i] = i == 2 ? -1.0 : 1.0;
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_ESINGULAR);
    assert_int_equal(gs_qp_set_hessian(q, n, o.H), GS_ESINGULAR);
    /* The failed factorisation leaves no factor behind. */
    assert_int_equal(gs_qp_solve_factored(q, &p, NULL, 0, &r), GS_EINVAL);

    /* Positive semidefinite of rank n - 1: the Gram matrix B B^T, B 5 x 4. */
    double B[5][4];
    for (int i = 0; i < n; i++)
        for (int k = 0; k < n - 1; k++)
            B[i][k] = nrand();
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            double s = 0.0;
            for (int k = 0; k < n - 1; k++)
                s += B[i][k] * B[j][k];
            o.H[i * n + j] = s;
        }
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_ESINGULAR);

    /* Zero matrix; and a Cholesky factor with a zero pivot. */
    memset(o.H, 0, (size_t)n * n * sizeof(double));
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_ESINGULAR);
    double L[25] = {0};
    for (int i = 0; i < n; i++)
        L[i * n + i] = i == 3 ? 0.0 : 1.0;
    assert_int_equal(gs_qp_set_cholesky(q, n, L), GS_ESINGULAR);

    /* Definite but with condition 1e17: numerically singular. */
    for (int i = 0; i < n; i++)
        o.H[i * n + i] = i == 0 ? 1e-17 : 1.0;
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_ESINGULAR);

    result_free(&r);
    gs_qp_free(&q);
    owned_free(&o);
}

static void bad_arguments(void **state)
{
    (void)state;
    gs_qp *q = NULL;
    assert_int_equal(gs_qp_new(0, 0, 0, &q), GS_EINVAL);
    assert_null(q);
    assert_int_equal(gs_qp_new(3, -1, 0, &q), GS_EINVAL);
    assert_int_equal(gs_qp_new(3, 0, 0, NULL), GS_EINVAL);
    gs_qp_free(NULL);
    gs_qp_free(&q); /* q == NULL */

    int n = 3;
    assert_int_equal(gs_qp_new(n, 1, 2, &q), GS_OK);
    owned o = rand_problem(n, 1, 2);
    gs_qp_problem p = view(&o);
    gs_qp_result r = result_new(n, 1, 2);
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_OK);

    gs_qp_problem bad = p;
    bad.n = 4; /* beyond the workspace */
    assert_int_equal(gs_qp_solve(q, &bad, NULL, 0, &r), GS_EINVAL);
    bad = p;
    bad.n_in = 3;
    assert_int_equal(gs_qp_solve(q, &bad, NULL, 0, &r), GS_EINVAL);
    bad = p;
    bad.G = NULL;
    assert_int_equal(gs_qp_solve(q, &bad, NULL, 0, &r), GS_EINVAL);
    assert_int_equal(gs_qp_solve(q, NULL, NULL, 0, &r), GS_EINVAL);
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, NULL), GS_EINVAL);
    gs_qp_result nox = r;
    nox.x = NULL;
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &nox), GS_EINVAL);
    int w[1] = {2}; /* out of range */
    assert_int_equal(gs_qp_solve(q, &p, w, 1, &r), GS_EINVAL);
    assert_int_equal(gs_qp_solve(q, &p, NULL, 1, &r), GS_EINVAL);
    o.c[1] = NAN;
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_EINVAL);
    o.c[1] = 0.0;
    o.H[0] = INFINITY;
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &r), GS_EINVAL);

    /* Optional outputs may be NULL. */
    o.H[0] = 2.0;
    gs_qp_result lean = {.x = r.x};
    assert_int_equal(gs_qp_solve(q, &p, NULL, 0, &lean), GS_OK);

    gs_qp_options opt;
    gs_qp_options_default(&opt);
    assert_true(opt.feas_tol > 0.0 && opt.dep_tol > 0.0 && opt.rcond_min > 0.0);
    opt.feas_tol = -1.0;
    assert_int_equal(gs_qp_set_options(q, &opt), GS_EINVAL);
    gs_qp_options_default(&opt);
    opt.max_iter = 1; /* too few: reported, not looped on */
    assert_int_equal(gs_qp_set_options(q, &opt), GS_OK);
    owned big = rand_problem(3, 0, 2);
    for (int j = 0; j < 2 * 3; j++) /* make both rows bind */
        big.G[j] = 0.0;
    big.G[0] = big.G[3 + 1] = 1.0;
    big.g[0] = big.g[1] = 100.0;
    gs_qp_problem pb = view(&big);
    assert_int_equal(gs_qp_solve(q, &pb, NULL, 0, &r), GS_ENOCONV);

    result_free(&r);
    gs_qp_free(&q);
    owned_free(&o);
    owned_free(&big);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(unconstrained),
        cmocka_unit_test(single_equality),
        cmocka_unit_test(box),
        cmocka_unit_test(simplex_projection),
        cmocka_unit_test(kkt_random),
        cmocka_unit_test(warm_start),
        cmocka_unit_test(factored_variants),
        cmocka_unit_test(degenerate),
        cmocka_unit_test(infeasible),
        cmocka_unit_test(singular_hessian),
        cmocka_unit_test(bad_arguments),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
