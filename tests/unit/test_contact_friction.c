/* SPDX-License-Identifier: MIT
 * The frictional solve of the contact step (src/step/contact_friction.c):
 *  - one contact in closed form: a block pressed by delta into a plane and
 *    pushed along it by s, stiffness k both ways: normal force k delta,
 *    stick (x_t = 0, friction -k s) while |s| <= mu delta, else slip
 *    (friction -mu k delta sign s, x_t = s - mu delta sign s);
 *  - random problems with equalities, several rows and some without
 *    friction: the solution checked against the conditions themselves
 *    (stationarity, equalities, non-penetration and complementarity,
 *    Coulomb's bound, stick without slip, slip against the force), and,
 *    without friction rows, against the QP (src/qp). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define TEST_RNG_SEED 0x5eed33f1ull
#include "../common/rand.h"
#include "gearsim/qp.h"
#include "step/contact_friction.h"

/* A workspace with nf friction rows: T (nf x N), their contact rows and bounds. */
static gsi_friction *workspace(int N, int ni, int nf, const double *T, const int *row, const double *mu)
{
    gsi_friction *f = NULL;
    assert_int_equal(gsi_friction_begin(&f, N, ni), GS_OK);
    f->T = malloc((size_t)(nf ? nf : 1) * N * sizeof(double));
    f->row = malloc((size_t)(nf ? nf : 1) * sizeof(int));
    f->mesh = calloc((size_t)(nf ? nf : 1), sizeof(int));
    f->mu = malloc((size_t)(nf ? nf : 1) * sizeof(double));
    assert_true(f->T && f->row && f->mesh && f->mu);
    f->cap_T = (size_t)(nf ? nf : 1) * N;
    f->cap_row = f->cap_mesh = f->cap_mu = (size_t)(nf ? nf : 1);
    if (nf) {
        memcpy(f->T, T, (size_t)nf * N * sizeof(double));
        memcpy(f->row, row, (size_t)nf * sizeof(int));
        memcpy(f->mu, mu, (size_t)nf * sizeof(double));
    }
    f->n_fric = nf;
    return f;
}

static void block_on_plane(void **state)
{
    (void)state;
    const double k = 2e8, delta = 1e-6, mu = 0.3;
    const double cases[][2] = {{delta, 0.5 * mu * delta}, {delta, 2 * mu * delta}, {delta, -3 * mu * delta},
                               {delta, 0.0}, {-delta, 5 * mu * delta}};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        double dn = cases[c][0], s = cases[c][1];
        double H[4] = {k, 0, 0, k}, cc[2] = {-k * dn, k * s}, G[2] = {1, 0}, g[1] = {0}, T[2] = {0, 1};
        int row[1] = {0};
        double mus[1] = {mu};
        gsi_friction *f = workspace(2, 1, 1, T, row, mus);
        gs_qp_problem p = {.n = 2, .H = H, .c = cc, .n_in = 1, .G = G, .g = g};
        double x[2], lam[1];
        gs_qp_result r = {.x = x, .lambda_in = lam};
        assert_int_equal(gsi_friction_solve(f, &p, &r), GS_OK);
        double lam_e = dn > 0 ? k * dn : 0.0, beta_e, xt_e;
        if (fabs(s) <= mu * fmax(dn, 0.0)) {
            beta_e = -k * s;
            xt_e = 0.0;
        } else {
            beta_e = -mu * lam_e * (s > 0 ? 1 : -1);
            xt_e = s + beta_e / k;
        }
        print_message("delta %+.1e s %+.2e: lambda %.6e (%.6e) beta %+.6e (%+.6e) x_t %+.6e (%+.6e)\n", dn, s,
                      lam[0], lam_e, f->beta[0], beta_e, x[1], xt_e);
        assert_true(fabs(lam[0] - lam_e) <= 1e-12 * k * delta);
        assert_true(fabs(f->beta[0] - beta_e) <= 1e-12 * k * delta);
        assert_true(fabs(x[1] - xt_e) <= 1e-12 * delta);
        assert_true(fabs(x[0] - (dn > 0 ? 0.0 : -dn)) <= 1e-12 * delta);
        gsi_friction_free(&f);
        assert_null(f);
    }
}

static double dot(int n, const double *a, const double *b)
{
    double s = 0;
    for (int i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}

/* A random QP: H = M M^T + I/2 (n x n), c, ne equalities E x = e, ni
 * rows G x >= g with g mostly positive (the free motion crosses them). */
static void random_qp(int n, int ne, int ni, double *H, double *c, double *E, double *e, double *G, double *g)
{
    double *M = malloc((size_t)n * n * sizeof *M);
    assert_non_null(M);
    for (int i = 0; i < n * n; i++)
        M[i] = urand() - 0.5;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++)
            H[i * n + j] = dot(n, M + i * n, M + j * n) + (i == j ? 0.5 : 0.0);
    free(M);
    for (int i = 0; i < n; i++)
        c[i] = urand() - 0.5;
    for (int i = 0; i < ne * n; i++)
        E[i] = urand() - 0.5;
    for (int i = 0; i < ne; i++)
        e[i] = 0.1 * (urand() - 0.5);
    for (int i = 0; i < ni * n; i++)
        G[i] = urand() - 0.5;
    for (int i = 0; i < ni; i++)
        g[i] = 0.3 * (urand() - 0.2);
}

static void random_problems(void **state)
{
    (void)state;
    enum { N = 8, NE = 1, NI = 4, NF = 3 };
    int stick = 0, slip = 0, open = 0;
    double worst = 0;
    for (int trial = 0; trial < 300; trial++) {
        double H[N * N], c[N], E[NE * N], e[NE], G[NI * N], g[NI], T[NF * N], mu[NF];
        int row[NF] = {0, 1, 3};
        random_qp(N, NE, NI, H, c, E, e, G, g);
        for (int i = 0; i < NF * N; i++)
            T[i] = urand() - 0.5;
        for (int i = 0; i < NF; i++)
            mu[i] = 0.05 + 0.5 * urand();
        gsi_friction *f = workspace(N, NI, NF, T, row, mu);
        gs_qp_problem p = {.n = N, .H = H, .c = c, .n_eq = NE, .E = E, .e = e, .n_in = NI, .G = G, .g = g};
        double x[N], le[NE], li[NI];
        gs_qp_result r = {.x = x, .lambda_eq = le, .lambda_in = li};
        assert_int_equal(gsi_friction_solve(f, &p, &r), GS_OK);
        /* scales */
        double xs = 1e-300, fs = 1e-300;
        for (int i = 0; i < N; i++)
            xs = fmax(xs, fabs(x[i]));
        for (int i = 0; i < NI; i++)
            fs = fmax(fs, fabs(li[i]));
        /* stationarity: H x - c = E^T le + G^T li + T^T beta */
        for (int j = 0; j < N; j++) {
            double v = dot(N, H + j * N, x) - c[j] - E[j] * le[0];
            for (int i = 0; i < NI; i++)
                v -= G[i * N + j] * li[i];
            for (int k = 0; k < NF; k++)
                v -= T[k * N + j] * f->beta[row[k]];
            worst = fmax(worst, fabs(v) / (fs + 1));
        }
        worst = fmax(worst, fabs(dot(N, E, x) - e[0]) / xs);
        for (int i = 0; i < NI; i++) {
            double w = dot(N, G + i * N, x) - g[i];
            assert_true(li[i] >= 0);
            assert_true(w >= -1e-10 * xs);
            worst = fmax(worst, fmin(li[i] / fs, fabs(w) / xs));
        }
        for (int k = 0; k < NF; k++) {
            double b = f->beta[row[k]], bound = mu[k] * li[row[k]], sl = dot(N, T + k * N, x);
            assert_true(fabs(b) <= bound + 1e-10 * fs);
            if (li[row[k]] <= 1e-12 * fs) {
                open++;
            } else if (fabs(b) < bound * (1 - 1e-9)) {
                stick++;
                worst = fmax(worst, fabs(sl) / xs); /* no slip */
            } else {
                slip++;
                assert_true(b * sl <= 1e-12 * fs * xs); /* slip against the force */
            }
        }
        /* every friction row's force vanishes off contact: the same with the
         * frictionless rows through the QP when nothing is loaded */
        gsi_friction_free(&f);
    }
    print_message("300 random problems: friction rows stick %d, slip %d, open %d; worst relative residual %.2e\n",
                  stick, slip, open, worst);
    assert_true(stick > 20 && slip > 20 && open > 20);
    assert_true(worst < 1e-9);
}

/* No friction rows: the LCP of the normal contact alone is the QP's KKT system. */
static void frictionless_matches_qp(void **state)
{
    (void)state;
    enum { N = 7, NE = 2, NI = 5 };
    double dmax = 0;
    gs_qp *qp = NULL;
    assert_int_equal(gs_qp_new(N, NE, NI, &qp), GS_OK);
    for (int trial = 0; trial < 200; trial++) {
        double H[N * N], c[N], E[NE * N], e[NE], G[NI * N], g[NI];
        random_qp(N, NE, NI, H, c, E, e, G, g);
        gs_qp_problem p = {.n = N, .H = H, .c = c, .n_eq = NE, .E = E, .e = e, .n_in = NI, .G = G, .g = g};
        double x[N], le[NE], li[NI], xq[N], leq[NE], liq[NI];
        gs_qp_result r = {.x = x, .lambda_eq = le, .lambda_in = li};
        gs_qp_result rq = {.x = xq, .lambda_eq = leq, .lambda_in = liq};
        gsi_friction *f = workspace(N, NI, 0, NULL, NULL, NULL);
        gs_err ef = gsi_friction_solve(f, &p, &r), eq = gs_qp_solve(qp, &p, NULL, 0, &rq);
        gsi_friction_free(&f);
        if (eq == GS_EINFEASIBLE)
            continue;
        assert_int_equal(eq, GS_OK);
        assert_int_equal(ef, GS_OK);
        double xs = 1e-300;
        for (int i = 0; i < N; i++)
            xs = fmax(xs, fabs(xq[i]));
        for (int i = 0; i < N; i++)
            dmax = fmax(dmax, fabs(x[i] - xq[i]) / xs);
    }
    gs_qp_free(&qp);
    print_message("200 random frictionless problems: max |x - x_QP| / |x_QP| %.2e\n", dmax);
    assert_true(dmax < 1e-9);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(block_on_plane),
        cmocka_unit_test(random_problems),
        cmocka_unit_test(frictionless_matches_qp),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
