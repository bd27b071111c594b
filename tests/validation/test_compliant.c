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
 * independence of the datum. Prints the table against N. Then partial slip
 * under a tangential load (Cattaneo–Mindlin, the friction LCP): see
 * partial_slip. */
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
        gs_compliant_problem pb = {.n = n, .x0 = -1.25 * a, .x1 = 1.25 * a, .radius = R, .e_star = E, .load = P};
        gs_compliant_result r = {.x = x, .pressure = p};
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
    gs_compliant_problem pb = {.n = n, .x0 = -1, .x1 = 1, .radius = 5.0, .e_star = 1.0, .load = 0.2, .datum = 5.0};
    gs_compliant_result r1 = {.pressure = p1}, r2 = {.pressure = p2};
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

/* Cattaneo–Mindlin partial slip of a cylinder on a half-plane (identical
 * materials, so the normal and tangential problems are uncoupled) under a
 * tangential load Q < mu P applied monotonically from zero: stick zone
 * |x| < c with c / a = sqrt(1 - Q / (mu P)), traction
 *   q(x) = mu p0 sqrt(1 - x^2/a^2) - [|x| < c] mu p0 (c/a) sqrt(1 - x^2/c^2).
 * Same contact as `hertz`, mu = 0.3, N = 81 and 161. Tolerances: c within
 * 0.01 a (a third of a strip at N = 81, 2.5 a / N = 0.031 a: the stick edge
 * is extrapolated from the square of the traction deficit mu p - |q|, which
 * is linear in x at a square-root edge, as the Hertz edge is; seen: 0.0033 a
 * at worst), the traction within 1 % of mu p0 away from the edges of the
 * contact and of the stick zone (2 strips either side left out, where the
 * square-root edges make a strip model least accurate; seen: 0.09 %),
 * equilibrium sum q w = Q and |q| <= mu p to 1e-9.
 * At Q = mu P the whole contact slips: q = mu p on every strip. */
static void partial_slip(void **state)
{
    (void)state;
    const double R = 20e-3, E = 115e9, P = 500e3, mu = 0.3;
    const double a = sqrt(4 * P * R / (GS_PI * E)), p0 = 2 * P / (GS_PI * a);
    const double ratios[] = {0.2, 0.5, 0.8, 0.95, 1.0};
    const int Ns[] = {81, 161};
    print_message("# partial slip: %5s %6s %10s %10s %8s %10s %6s %7s\n", "N", "Q/muP", "c/a exact", "c/a num",
                  "err/a", "max dq/mup0", "stick", "pivots");
    for (size_t kn = 0; kn < sizeof Ns / sizeof Ns[0]; kn++) {
        int n = Ns[kn];
        double w = 2.5 * a / n;
        for (size_t k = 0; k < sizeof ratios / sizeof ratios[0]; k++) {
            double *x = malloc(n * sizeof *x), *p = malloc(n * sizeof *p), *q = malloc(n * sizeof *q);
            gs_compliant_problem pb = {.n = n, .x0 = -1.25 * a, .x1 = 1.25 * a, .radius = R, .e_star = E, .load = P,
                                       .mu = mu, .load_t = ratios[k] * mu * P};
            gs_compliant_result r = {.x = x, .pressure = p, .traction = q};
            gs_diag d;
            gs_err e = gs_compliant_solve_friction(&pb, &r, &d);
            if (e != GS_OK)
                print_error("%s: %s\n", d.field, d.message);
            assert_int_equal(e, GS_OK);
            double c = a * sqrt(1 - ratios[k]), sum = 0, dmax = 0;
            for (int i = 0; i < n; i++) {
                sum += q[i] * w;
                assert_true(fabs(q[i]) <= mu * p[i] * (1 + 1e-9) + 1e-9 * mu * p0);
                double ax = fabs(x[i]), qe = ax < a ? mu * p0 * sqrt(1 - x[i] * x[i] / (a * a)) : 0;
                if (ax < c)
                    qe -= mu * p0 * (c / a) * sqrt(1 - x[i] * x[i] / (c * c));
                if (ax < a - 2 * w && fabs(ax - c) > 2 * w)
                    dmax = fmax(dmax, fabs(q[i] - qe) / (mu * p0));
            }
            double err = (r.stick_half_width - c) / a;
            print_message("# partial slip: %5d %6.2f %10.4f %10.4f %+8.4f %10.4f %6d %7d\n", n, ratios[k], c / a,
                          r.stick_half_width / a, err, dmax, r.n_stick, r.lcp.pivots);
            assert_true(fabs(sum - ratios[k] * mu * P) <= 1e-9 * P);
            assert_true(fabs(err) < 0.01);
            assert_true(dmax < 0.01);
            assert_true(r.shift > 0);
            if (ratios[k] == 1.0) {
                assert_int_equal(r.n_stick, 0);
                for (int i = 0; i < n; i++)
                    assert_true(fabs(q[i] - mu * p[i]) <= 1e-9 * mu * p0);
            }
            /* the reversed load: the mirror image */
            double *q2 = malloc(n * sizeof *q2);
            pb.load_t = -pb.load_t;
            r.traction = q2;
            assert_int_equal(gs_compliant_solve_friction(&pb, &r, &d), GS_OK);
            for (int i = 0; i < n; i++)
                assert_true(fabs(q2[i] + q[i]) <= 1e-9 * mu * p0);
            assert_true(r.shift < 0);
            free(q2);
            free(x);
            free(p);
            free(q);
        }
    }
    /* gross sliding and bad data are refused, naming the field */
    double p[21], q[21];
    gs_compliant_problem pb = {.n = 21, .x0 = -1.25 * a, .x1 = 1.25 * a, .radius = R, .e_star = E, .load = P,
                               .mu = mu, .load_t = 1.01 * mu * P};
    gs_compliant_result r = {.pressure = p, .traction = q};
    gs_diag d;
    assert_int_equal(gs_compliant_solve_friction(&pb, &r, &d), GS_ERANGE);
    assert_string_equal(d.field, "load_t");
    pb.mu = -0.1;
    assert_int_equal(gs_compliant_solve_friction(&pb, &r, &d), GS_ERANGE);
    assert_string_equal(d.field, "mu");
    /* Q = 0: no traction */
    pb.mu = mu;
    pb.load_t = 0;
    assert_int_equal(gs_compliant_solve_friction(&pb, &r, &d), GS_OK);
    for (int i = 0; i < 21; i++)
        assert_true(q[i] == 0.0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(hertz), cmocka_unit_test(kernel_and_datum),
                                       cmocka_unit_test(partial_slip)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
