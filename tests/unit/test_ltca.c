/* SPDX-License-Identifier: MIT
 * The LTCA table and its mesh potential (include/gearsim/ltca.h) on a
 * synthetic table of known shape (no FE): the force reproduces the table
 * at every roll position and knot and is monotone in the deflection; the
 * potential's derivative is the force; the discrete gradient is exact
 * (gx dx + gp dp = V(x1, p1) - V(x0, p0) to round-off) for increments from
 * 1e-14 m to across several knots and cells, across the dead zone, and
 * reduces to the derivatives as the increments vanish; its Jacobian agrees
 * with finite differences; bad tables are refused. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdlib.h>

#include "gearsim/ltca.h"
#include <stdio.h>

#define TEST_RNG_SEED 0x17ca
#include "../common/rand.h"

#define NP 12
#define NK 9

/* A table like a spur pair's: closings at -50 um and 45 + 2 sin um, front
 * loads 0 .. 2000 N with a stiffness that varies over the cycle (single /
 * double contact) and softens near the closing, two back loads. */
static void synth(gs_ltca_table *t)
{
    double d[NP * NK], f[NP * NK];
    for (int j = 0; j < NP; j++) {
        double ph = (j + 0.5) / NP, close = 45e-6 + 2e-6 * sin(2 * M_PI * ph);
        double k = ph < 0.6 ? 2.0e8 : 1.2e8;
        double *dd = d + j * NK, *ff = f + j * NK;
        int c = 0;
        dd[c] = -50e-6 - 0.3e-6 * cos(2 * M_PI * ph), ff[c++] = 0.0; /* back closing */
        dd[c] = -52e-6, ff[c++] = -300.0;
        dd[c] = -55e-6, ff[c++] = -900.0;
        dd[c] = close, ff[c++] = 0.0; /* front closing */
        double loads[] = {30, 150, 500, 1000, 2000};
        for (int i = 0; i < 5; i++) {
            dd[c] = close + loads[i] / k + 0.4e-6 * sqrt(loads[i] / 2000.0);
            ff[c++] = loads[i];
        }
    }
    gs_diag dg;
    assert_int_equal(gs_ltca_table_set(t, NP, NK, d, f, &dg), GS_OK);
}

static void test_reproduces_table(void **state)
{
    (void)state;
    gs_ltca_table t;
    synth(&t);
    assert_int_equal(t.zero_back, 2);
    for (int j = 0; j < NP; j++) {
        double p = (j + 0.5) / NP;
        for (int k = 0; k < NK; k++) {
            double x = t.d[j * NK + k];
            double F = gs_ltca_force(&t, x, p, NULL);
            assert_true(fabs(F - t.f[j * NK + k]) <= 1e-9 * (1 + fabs(t.f[j * NK + k])));
            /* the same a whole number of cycles away */
            assert_true(fabs(gs_ltca_force(&t, x, p - 3.0, NULL) - F) <= 1e-9 * (1 + fabs(F)));
        }
        /* dead zone: no force, no energy */
        double b, fr;
        gs_ltca_closing(&t, p, &b, &fr);
        assert_true(fabs(gs_ltca_force(&t, 0.5 * (b + fr), p, NULL)) == 0.0);
        assert_true(gs_ltca_energy(&t, 0.5 * (b + fr), p) == 0.0);
    }
    /* monotone in x at every phase, V' = F */
    for (int i = 0; i < 200; i++) {
        double p = i / 137.0, xprev = -70e-6, fprev = -1e30;
        for (double x = -70e-6; x < 70e-6; x += 0.37e-6) {
            double F = gs_ltca_force(&t, x, p, NULL);
            assert_true(F >= fprev - 1e-9);
            fprev = F;
            double hstep = 1e-10;
            double dV = (gs_ltca_energy(&t, x + hstep, p) - gs_ltca_energy(&t, x - hstep, p)) / (2 * hstep);
            assert_true(fabs(dV - F) <= 1e-4 * (1 + fabs(F)));
            xprev = x;
        }
        (void)xprev;
    }
    gs_ltca_table_clear(&t);
}

static void check_grad(const gs_ltca_table *t, double x0, double dx, double p0, double dp)
{
    double gx, gp, jac[4];
    gs_ltca_grad(t, x0, dx, p0, dp, &gx, &gp, jac);
    double dV = gs_ltca_energy(t, x0 + dx, p0 + dp) - gs_ltca_energy(t, x0, p0);
    /* round-off of the values (x F: each V carries eps |x F|) and of the terms summed */
    double scale = fabs(gs_ltca_energy(t, x0, p0)) + fabs(gs_ltca_energy(t, x0 + dx, p0 + dp)) + fabs(gx * dx) +
                   fabs(gp * dp) +
                   fmax(fabs(x0), fabs(x0 + dx)) *
                       fmax(fabs(gs_ltca_force(t, x0, p0, NULL)), fabs(gs_ltca_force(t, x0 + dx, p0 + dp, NULL)));
    double err = fabs(gx * dx + gp * dp - dV);
    if (!(err <= 2e-14 * scale + 1e-25)) {
        fprintf(stderr, "x0 %.6e dx %.3e p0 %.6f dp %.3e: err %.3e scale %.3e\n", x0, dx, p0, dp, err, scale);
        fail();
    }
}

static void test_discrete_gradient_exact(void **state)
{
    (void)state;
    gs_ltca_table t;
    synth(&t);
    double sizes_x[] = {0.0, 1e-14, 1e-11, 1e-9, 3e-7, 5e-6, 4e-5, 1e-4};
    double sizes_p[] = {0.0, 1e-12, 1e-7, 1e-4, 0.02, 0.2, 0.45};
    for (int i = 0; i < 4000; i++) {
        double x0 = -60e-6 + 120e-6 * urand(), p0 = 4.0 * urand() - 2.0;
        double sx = sizes_x[i % 8] * (urand() < 0.5 ? -1 : 1);
        double sp = sizes_p[(i / 8) % 7] * (urand() < 0.5 ? -1 : 1);
        check_grad(&t, x0, sx, p0, sp);
    }
    /* vanishing increments: the derivatives */
    for (int i = 0; i < 50; i++) {
        double x0 = 46e-6 + 1e-6 * i, p0 = 0.013 * i + 0.001;
        double gx, gp;
        gs_ltca_grad(&t, x0, 0.0, p0, 0.0, &gx, &gp, NULL);
        double dvdp, F = gs_ltca_force(&t, x0, p0, &dvdp);
        assert_true(fabs(gx - F) <= 1e-9 * (1 + fabs(F)));
        assert_true(fabs(gp - dvdp) <= 1e-9 * (1 + fabs(dvdp)));
    }
    gs_ltca_table_clear(&t);
}

/* The Jacobian against central differences of (gx, gp) in (dx, dp), away
 * from the kinks (knots, cell edges). */
static void test_jacobian(void **state)
{
    (void)state;
    gs_ltca_table t;
    synth(&t);
    int checked = 0;
    for (int i = 0; i < 40; i++) {
        double x0 = 48.3e-6 + 0.11e-6 * i, p0 = 0.004 + 0.0191 * i;
        double dx = 0.02e-6, dp = 0.0013, hx = 1e-13, hp = 1e-8;
        double g[2], jac[4], a[2], b[2], tmp[4];
        gs_ltca_grad(&t, x0, dx, p0, dp, &g[0], &g[1], jac);
        gs_ltca_grad(&t, x0, dx + hx, p0, dp, &a[0], &a[1], tmp);
        gs_ltca_grad(&t, x0, dx - hx, p0, dp, &b[0], &b[1], tmp);
        double fx0 = (a[0] - b[0]) / (2 * hx), fx1 = (a[1] - b[1]) / (2 * hx);
        gs_ltca_grad(&t, x0, dx, p0, dp + hp, &a[0], &a[1], tmp);
        gs_ltca_grad(&t, x0, dx, p0, dp - hp, &b[0], &b[1], tmp);
        double fp0 = (a[0] - b[0]) / (2 * hp), fp1 = (a[1] - b[1]) / (2 * hp);
        assert_true(fabs(fx0 - jac[0]) <= 1e-4 * fabs(jac[0]) + 1e-3);
        assert_true(fabs(fp0 - jac[1]) <= 1e-4 * fabs(jac[1]) + 1e-3);
        assert_true(fabs(fx1 - jac[2]) <= 1e-4 * fabs(jac[2]) + 1e-3);
        assert_true(fabs(fp1 - jac[3]) <= 1e-4 * fabs(jac[3]) + 1e-7);
        checked++;
    }
    assert_int_equal(checked, 40);
    gs_ltca_table_clear(&t);
}

static void test_bad_tables(void **state)
{
    (void)state;
    gs_ltca_table t;
    gs_diag dg;
    /* deflection falling while the force grows */
    double d[2 * 4] = {-1e-5, 0, 1e-5, 0.5e-5, -1e-5, 0, 1e-5, 2e-5};
    double f[2 * 4] = {0, 0, 100, 200, 0, 0, 100, 200};
    assert_int_equal(gs_ltca_table_set(&t, 2, 4, d, f, &dg), GS_ERANGE);
    /* no dead zone */
    double d2[2 * 3] = {0, 1e-5, 2e-5, 0, 1e-5, 2e-5};
    double f2[2 * 3] = {0, 100, 200, 0, 100, 200};
    assert_int_equal(gs_ltca_table_set(&t, 2, 3, d2, f2, &dg), GS_ERANGE);
    assert_int_equal(gs_ltca_table_set(&t, 1, 3, d2, f2, &dg), GS_ERANGE);
}

/* The dynamic tables with a body compliance c in series (frozen at the
 * mean force): the deflection at the mean force's knot stays, every
 * segment's compliance loses c, the closings move by c F_mean, the
 * potential is re-integrated (its derivative the force) and k_mean is the
 * new tangent; a compliance larger than a segment's is refused. */
static void test_body_compliance(void **state)
{
    (void)state;
    gs_ltca_table t, u;
    synth(&t);
    synth(&u);
    const int ks = 7; /* the 1000 N knot */
    assert_true(fabs(t.f[ks] - 1000.0) < 1e-12);
    t.knot_scene = u.knot_scene = ks;
    t.body_compliance = 1e-9;
    gs_diag dg;
    assert_int_equal(gs_ltca_table_dynamic(&t, 1000.0, &dg), GS_OK);
    double kmean = 0;
    for (int j = 0; j < NP; j++) {
        const double *d0 = u.d + j * NK, *f0 = u.f + j * NK, *d1 = t.d + j * NK, *f1 = t.f + j * NK;
        assert_true(fabs(d1[ks] - d0[ks]) < 1e-18);
        assert_true(fabs(d1[2] - (d0[2] + 1e-9 * 1000.0)) < 1e-18); /* the back closing */
        for (int a = 0; a + 1 < NK; a++) {
            assert_true(f1[a] == f0[a]);
            if (f0[a + 1] == f0[a])
                continue;
            double c0 = (d0[a + 1] - d0[a]) / (f0[a + 1] - f0[a]), c1 = (d1[a + 1] - d1[a]) / (f1[a + 1] - f1[a]);
            assert_true(fabs(c1 - (c0 - 1e-9)) < 1e-12 * c0);
        }
        kmean += 0.5 * ((f1[ks] - f1[ks - 1]) / (d1[ks] - d1[ks - 1]) + (f1[ks + 1] - f1[ks]) / (d1[ks + 1] - d1[ks]));
        double x = 0.3 * d1[5] + 0.7 * d1[6], hx = 1e-10;
        double dv = (gs_ltca_row_energy(&t, j, x + hx) - gs_ltca_row_energy(&t, j, x - hx)) / (2 * hx);
        assert_true(fabs(dv - gs_ltca_row_force(&t, j, x, NULL)) < 1e-6 * 1000.0);
    }
    assert_true(fabs(t.k_mean - kmean / NP) < 1e-9 * t.k_mean);
    u.body_compliance = 1e-8; /* stiffer than the 2e8 N/m segments' 5e-9 m/N */
    assert_int_equal(gs_ltca_table_dynamic(&u, 1000.0, &dg), GS_ERANGE);
    gs_ltca_table_clear(&t);
    gs_ltca_table_clear(&u);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_reproduces_table),
        cmocka_unit_test(test_discrete_gradient_exact),
        cmocka_unit_test(test_jacobian),
        cmocka_unit_test(test_bad_tables),
        cmocka_unit_test(test_body_compliance),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
