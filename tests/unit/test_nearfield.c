/* SPDX-License-Identifier: MIT
 * The near-field (Hertz) formulas of the quasi-static stiffness analysis
 * (include/gearsim/stiffness.h, docs/STIFFNESS.md "Near-field correction")
 * against closed forms and an independent quadrature. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include "gearsim/stiffness.h"

/* -int_0^d eps_z dz on the axis of the Hertzian line load, from McEwen's
 * stresses (Johnson eq. 4.75) integrated by composite Simpson in s = asinh(z/a)
 * (smooth integrand): an evaluation independent of the closed form. */
static double approach_quadrature(double P, double a, double d, double E, double nu, int strain)
{
    double p0 = 2.0 * P / (3.14159265358979323846 * a);
    double Ep = strain ? E / (1.0 - nu * nu) : E, nup = strain ? nu / (1.0 - nu) : nu;
    int n = 20000;
    double smax = asinh(d / a), h = smax / n, sum = 0.0;
    for (int i = 0; i <= n; i++) {
        double s = i * h, z = a * sinh(s), dz = a * cosh(s); /* dz/ds */
        double r = sqrt(a * a + z * z);
        double sz = -p0 * a / r;
        double sx = -(p0 / a) * ((a * a + 2.0 * z * z) / r - 2.0 * z);
        double ez = (sz - nup * sx) / Ep;
        double w = (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0);
        sum += w * (-ez) * dz;
    }
    return sum * h / 3.0;
}

static void approach_matches_quadrature(void **state)
{
    (void)state;
    double P = 2e5, E = 210e9, nu = 0.3, a = 1.1e-4;
    const double ratios[] = {0.05, 0.5, 1.0, 3.0, 10.0, 50.0};
    for (int strain = 0; strain < 2; strain++)
        for (size_t k = 0; k < sizeof ratios / sizeof ratios[0]; k++) {
            double d = ratios[k] * a;
            double f = gs_hertz_line_approach(P, a, d, E, nu, strain ? GS_PLANE_STRAIN : GS_PLANE_STRESS);
            double q = approach_quadrature(P, a, d, E, nu, strain);
            assert_true(q > 0.0);
            assert_true(fabs(f - q) <= 1e-9 * q);
        }
}

static void approach_far_field_is_johnson(void **state)
{
    (void)state;
    /* d >> a: 2 P / (pi E') (ln(2 d / a) - nu'/2), error O((a/d)^2). */
    double P = 1.5e5, E = 200e9, nu = 0.29, a = 1e-4, d = 1e3 * a;
    double Ep = E / (1.0 - nu * nu), nup = nu / (1.0 - nu);
    double j = 2.0 * P / (3.14159265358979323846 * Ep) * (log(2.0 * d / a) - 0.5 * nup);
    double f = gs_hertz_line_approach(P, a, d, E, nu, GS_PLANE_STRAIN);
    assert_true(fabs(f - j) <= 1e-6 * j);
    /* Linear in the load at fixed a, zero at depth 0. */
    assert_true(fabs(gs_hertz_line_approach(2 * P, a, d, E, nu, GS_PLANE_STRAIN) - 2 * f) <= 1e-12 * f);
    assert_true(gs_hertz_line_approach(P, a, 0.0, E, nu, GS_PLANE_STRAIN) == 0.0);
}

static void half_width_and_modulus(void **state)
{
    (void)state;
    double E = 210e9, nu = 0.3;
    /* Equal materials in plane strain: E* = E / (2 (1 - nu^2)); plane stress E / 2. */
    double es = gs_hertz_line_modulus(E, nu, E, nu, GS_PLANE_STRAIN);
    assert_true(fabs(es - E / (2.0 * (1.0 - nu * nu))) <= 1e-12 * es);
    assert_true(fabs(gs_hertz_line_modulus(E, nu, E, nu, GS_PLANE_STRESS) - 0.5 * E) <= 1e-3);
    /* The peak pressure of the Hertzian line contact, p0 = 2 P / (pi a),
     * equals sqrt(P E* / (pi R)) (Johnson eq. 4.45). The 20/30 pair at its
     * pitch point: P = 200 N/mm, R = 5.35 mm, a about 0.11 mm. */
    double P = 2e5, R = 5.35e-3;
    double a = gs_hertz_line_half_width(P, R, es);
    double p0 = 2.0 * P / (3.14159265358979323846 * a);
    assert_true(fabs(p0 - sqrt(P * es / (3.14159265358979323846 * R))) <= 1e-9 * p0);
    assert_true(a > 1.0e-4 && a < 1.2e-4);
    /* Invalid arguments: NaN, never a number. */
    assert_true(isnan(gs_hertz_line_half_width(-1.0, R, es)));
    assert_true(isnan(gs_hertz_line_half_width(P, 0.0, es)));
    assert_true(isnan(gs_hertz_line_approach(P, 0.0, 1e-3, E, nu, GS_PLANE_STRAIN)));
    assert_true(isnan(gs_hertz_line_approach(P, a, -1e-3, E, nu, GS_PLANE_STRAIN)));
    assert_true(isnan(gs_hertz_line_approach(P, a, 1e-3, 0.0, nu, GS_PLANE_STRAIN)));
}

/* gs_gap_vertex3: exact on a parabola; rejects a concave or an
 * extrapolated vertex. */
static void gap_vertex_parabola(void **state)
{
    (void)state;
    double sv = 0.0, g0 = 0.0;
    /* g(s) = 0.3 + (s - 0.07)^2 / (2 * 5): samples at -0.2, 0, 0.25. */
    double R = 5.0, s0 = 0.07, gv = 0.3;
#define G(s) (gv + ((s) - s0) * ((s) - s0) / (2.0 * R))
    assert_int_equal(gs_gap_vertex3(-0.2, G(-0.2), G(0.0), 0.25, G(0.25), &sv, &g0), 1);
    assert_true(fabs(sv - s0) < 1e-12 && fabs(g0 - gv) < 1e-12);
    /* Vertex beyond the samples, concave samples, unordered abscissae. */
    s0 = 0.4;
    sv = g0 = -1.0;
    assert_int_equal(gs_gap_vertex3(-0.2, G(-0.2), G(0.0), 0.25, G(0.25), &sv, &g0), 0);
    assert_true(sv == -1.0 && g0 == -1.0);
#undef G
    assert_int_equal(gs_gap_vertex3(-0.2, 0.0, 1.0, 0.25, 0.0, &sv, &g0), 0);
    assert_int_equal(gs_gap_vertex3(0.1, 1.0, 0.0, 0.25, 1.0, &sv, &g0), 0);
}

/* The smallest gap of two circles (radii R1, R2, the flanks' curvature
 * radii near a gear contact) from their gaps sampled at nodes of spacing h
 * on one of them, the nearest node at an arbitrary place: the nearest
 * node's gap is up to h^2 / (8 R) above the true one, the vertex of the
 * three nearest samples is far closer and converges under refinement. */
static double circles_vertex_error(double h, double phase, double *nearest_err)
{
    double R1 = 3e-3, R2 = 20e-3, gap = 0.5e-6;   /* m */
    double cA[2] = {0.0, -R1}, cB[2] = {0.0, R2 + gap};
    double best = INFINITY, gs[3] = {0}, ss[3] = {0};
    int nb = 0;
    for (int i = -40; i <= 40; i++) {
        double ang = (i + phase) * h / R2;             /* node on B's lower arc */
        double p[2] = {cB[0] + R2 * sin(ang), cB[1] - R2 * cos(ang)};
        double g = hypot(p[0] - cA[0], p[1] - cA[1]) - R1;
        if (g < best) {
            best = g;
            nb = i;
        }
    }
    for (int k = -1; k <= 1; k++) {
        double ang = (nb + k + phase) * h / R2;
        double p[2] = {cB[0] + R2 * sin(ang), cB[1] - R2 * cos(ang)};
        ss[k + 1] = p[0];
        gs[k + 1] = hypot(p[0] - cA[0], p[1] - cA[1]) - R1;
    }
    for (int k = 0; k < 3; k += 2)
        ss[k] -= ss[1];
    double sv, g0;
    assert_int_equal(gs_gap_vertex3(ss[0], gs[0], gs[1], ss[2], gs[2], &sv, &g0), 1);
    *nearest_err = gs[1] - gap;
    return fabs(g0 - gap);
}

static void gap_vertex_circles(void **state)
{
    (void)state;
    double prev = 0.0;
    for (int lev = 0; lev < 3; lev++) {
        double h = 0.3e-3 / (1 << lev), worst = 0.0, worst_near = 0.0;
        for (int j = 0; j < 8; j++) {
            double en, e = circles_vertex_error(h, 0.0625 + j / 8.0, &en);
            worst = fmax(worst, e);
            worst_near = fmax(worst_near, en);
        }
        print_message("h %.4f mm: nearest node %.4f um, vertex %.2e um\n", h * 1e3,
                      worst_near * 1e6, worst * 1e6);
        assert_true(worst_near > 0.3 * h * h / (8.0 * 2.6e-3)); /* the sampling error is real */
        assert_true(worst < 0.05 * worst_near);
        if (lev > 0)
            assert_true(worst < prev / 4.0);               /* at least second order */
        prev = worst;
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(approach_matches_quadrature),
        cmocka_unit_test(approach_far_field_is_johnson),
        cmocka_unit_test(half_width_and_modulus),
        cmocka_unit_test(gap_vertex_parabola),
        cmocka_unit_test(gap_vertex_circles),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
