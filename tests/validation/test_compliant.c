/* SPDX-License-Identifier: MIT
 * Compliant contact patches against Hertz line contact: a cylinder
 * (R = 20 mm) pressed on a half-plane, E* = 115 GPa, P = 500 N/mm; the
 * candidate region [-1.25 a_H, 1.25 a_H] split into N strips (N odd, so
 * a strip sits at the centre), frictionless, solved as the QP of minimum
 * complementary energy. Hertz: a = sqrt(4 P R / (pi E*)), p0 = 2 P / (pi a),
 * p(x) = p0 sqrt(1 - x^2 / a^2). Checked on the finest grids (N >= 161):
 * a and p0 within 2 % (the task's tolerance; the discretisation error of
 * a is ~ half a strip), load equilibrium to 1e-10, the pressure profile
 * within 2 % of p0 away from the edges (|x| < 0.9 a) and the error of a
 * decreasing with N. Also: the influence kernel's symmetry and the
 * independence of the datum. Prints the table against N. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "gearsim/impact.h"

static void hertz(void **state)
{
    (void)state;
    const double R = 20e-3, E = 115e9, P = 500e3;
    const double a = sqrt(4 * P * R / (GS_PI * E)), p0 = 2 * P / (GS_PI * a);
    const int Ns[] = {21, 41, 81, 161, 321, 641};
    double prev_err = INFINITY;
    print_message("# Hertz: a = %.6g mm, p0 = %.6g MPa\n", a * 1e3, p0 * 1e-6);
    print_message("# %5s %10s %8s %10s %8s %10s %7s %6s\n", "N", "a mm", "err a", "p0 MPa", "err p0",
                  "max dp/p0", "loaded", "iters");
    for (size_t k = 0; k < sizeof Ns / sizeof Ns[0]; k++) {
        int n = Ns[k];
        double *x = malloc(n * sizeof *x), *p = malloc(n * sizeof *p);
        gs_compliant_problem pb = {n, -1.25 * a, 1.25 * a, R, NULL, E, P, 0.0};
        gs_compliant_result r = {x, p, 0, 0, 0, 0, 0};
        gs_diag d;
        assert_int_equal(gs_compliant_solve(&pb, &r, &d), GS_OK);
        double w = 2.5 * a / n, sum = 0.0, dmax = 0.0;
        for (int i = 0; i < n; i++) {
            sum += p[i] * w;
            if (fabs(x[i]) < 0.9 * a)
                dmax = fmax(dmax, fabs(p[i] - p0 * sqrt(1 - x[i] * x[i] / (a * a))) / p0);
        }
        double ea = r.half_width / a - 1, ep = r.peak / p0 - 1;
        print_message("# %5d %10.6f %+7.3f%% %10.3f %+7.3f%% %9.3f%% %7d %6d\n", n, r.half_width * 1e3,
                      100 * ea, r.peak * 1e-6, 100 * ep, 100 * dmax, r.n_loaded, r.qp_iterations);
        assert_true(fabs(sum - P) <= 1e-10 * P);
        if (n >= 161) {
            assert_true(fabs(ea) < 0.02);
            assert_true(fabs(ep) < 0.02);
            assert_true(dmax < 0.02);
            assert_true(fabs(ea) < prev_err); /* a converges monotonically (~ half a strip) */
        }
        prev_err = fabs(ea);
        free(x);
        free(p);
    }
}

static void kernel_and_datum(void **state)
{
    (void)state;
    /* symmetric in s, and the datum only adds a constant (per unit pressure: width * 2/(pi E*) ln ratio) */
    double w = 0.1, E = 2.0;
    for (double s = 0.0; s < 1.0; s += 0.13) {
        assert_true(fabs(gs_compliant_influence(s, w, E, 10) - gs_compliant_influence(-s, w, E, 10)) < 1e-15);
        double shift = gs_compliant_influence(s, w, E, 20) - gs_compliant_influence(s, w, E, 10);
        assert_true(fabs(shift - w * 2 / (GS_PI * E) * log(2.0)) < 1e-13);
    }
    /* the pressure does not depend on the datum; the approach moves by the constant */
    int n = 41;
    double p1[41], p2[41];
    gs_compliant_problem pb = {n, -1, 1, 5.0, NULL, 1.0, 0.2, 5.0};
    gs_compliant_result r1 = {NULL, p1, 0, 0, 0, 0, 0}, r2 = {NULL, p2, 0, 0, 0, 0, 0};
    assert_int_equal(gs_compliant_solve(&pb, &r1, NULL), GS_OK);
    pb.datum = 50.0;
    assert_int_equal(gs_compliant_solve(&pb, &r2, NULL), GS_OK);
    for (int i = 0; i < n; i++)
        assert_true(fabs(p1[i] - p2[i]) <= 1e-9 * r1.peak);
    assert_true(fabs((r2.approach - r1.approach) - 0.2 * 2 / GS_PI * log(10.0)) < 1e-9);
    gs_diag d;
    pb.load = -1;
    assert_int_equal(gs_compliant_solve(&pb, &r1, &d), GS_ERANGE);
    assert_string_equal(d.field, "load");
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(hertz), cmocka_unit_test(kernel_and_datum)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
