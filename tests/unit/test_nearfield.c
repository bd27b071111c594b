/* SPDX-License-Identifier: MIT
 * The near-field (Hertz) formulas of the quasi-static stiffness analysis
 * (include/gearsim/stiffness.h, docs/explanation/stiffness.md "Near-field correction")
 * against closed forms and an independent quadrature. */
#include <math.h>
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>

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
    assert_int_equal(gs_gap_vertex3(-0.2, G(-0.2), G(0.0), 0.25, G(0.25), INFINITY, &sv, &g0), 1);
    assert_true(fabs(sv - s0) < 1e-12 && fabs(g0 - gv) < 1e-12);
    /* Vertex beyond the samples, concave samples, unordered abscissae. */
    s0 = 0.4;
    sv = g0 = -1.0;
    assert_int_equal(gs_gap_vertex3(-0.2, G(-0.2), G(0.0), 0.25, G(0.25), INFINITY, &sv, &g0), 0);
    assert_true(sv == -1.0 && g0 == -1.0);
#undef G
    assert_int_equal(gs_gap_vertex3(-0.2, 0.0, 1.0, 0.25, 0.0, INFINITY, &sv, &g0), 0);
    assert_int_equal(gs_gap_vertex3(0.1, 1.0, 0.0, 0.25, 1.0, INFINITY, &sv, &g0), 0);
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
    assert_int_equal(gs_gap_vertex3(ss[0], gs[0], gs[1], ss[2], gs[2], INFINITY, &sv, &g0), 1);
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

/* Tip-corner law (gs_corner_line_*): a Hertzian zone that just reaches the
 * corner (xv = a) is Hertz's; the law is continuous there. */
static void corner_law_is_hertz_at_the_corner(void **state)
{
    (void)state;
    double P = 8e4, R = 5e-3, E = 210e9, nu = 0.3, d = 5e-4;
    double es = gs_hertz_line_modulus(E, nu, E, nu, GS_PLANE_STRAIN);
    double a = gs_hertz_line_half_width(P, R, es);
    double h = gs_hertz_line_approach(P, a, d, E, nu, GS_PLANE_STRAIN);
    double lo = gs_corner_line_approach(P, R, a * (1.0 - 1e-9), d, E, nu, GS_PLANE_STRAIN, es,
                                        2.0 / M_PI);
    double hi = gs_corner_line_approach(P, R, a * (1.0 + 1e-9), d, E, nu, GS_PLANE_STRAIN, es,
                                        2.0 / M_PI);
    print_message("xv = a: Hertz %.6e, corner law %.6e / %.6e m\n", h, lo, hi);
    assert_true(fabs(hi - h) <= 1e-12 * h);
    assert_true(fabs(lo - h) <= 1e-6 * h);
    assert_true(fabs(gs_corner_line_width(P, R, a * (1.0 - 1e-9), es) - 2.0 * a) < 1e-6 * a);
    /* A zone cut by the corner is softer than the whole one, more so the
     * more of it is cut (xv from a down to beyond the corner). */
    double prev = h;
    for (double f = 0.75; f > -3.0; f -= 0.5) {
        double v = gs_corner_line_approach(P, R, f * a, d, E, nu, GS_PLANE_STRAIN, es, 2.0 / M_PI);
        assert_true(v > prev);
        prev = v;
    }
}

/* The contact length balances the load, P = pi E* c (3 c - 4 xv) / (16 R),
 * and far beyond the corner (a flat face at angle beta = -xv / R) tends to
 * 4 P / (pi E* beta). */
static void corner_width_balances_the_load(void **state)
{
    (void)state;
    double P = 3e4, es = 1.154e11;
    const double xvs[] = {-2e-4, -5e-5, 0.0, 2e-5};
    for (int i = 0; i < 4; i++) {
        double R = 4.6e-3, c = gs_corner_line_width(P, R, xvs[i], es);
        double Pc = M_PI * es * c * (3.0 * c - 4.0 * xvs[i]) / (16.0 * R);
        assert_true(fabs(Pc - P) < 1e-9 * P);
        assert_true(c >= 2.0 * xvs[i]); /* the pressure at the corner is not negative */
    }
    double beta = 0.05, R = 1e3, c = gs_corner_line_width(P, R, -beta * R, es);
    double c0 = 4.0 * P / (M_PI * es * beta);
    print_message("flat face: c %.4e m, 4 P / (pi E* beta) %.4e m\n", c, c0);
    assert_true(fabs(c / c0 - 1.0) < 1e-3);
}

/* The law's closed forms (log energy and moments of the pressure
 * w(t) (A0 + A1 t)) against a quadrature: with t = -cos(th) the load is
 * (1 + cos th)(A0 - A1 cos th) d th, smooth; the logarithmic energy
 * int int ln|x - y| by the midpoint rule on a staggered pair of grids (the
 * diagonal singularity is integrable). */
static void corner_law_matches_quadrature(void **state)
{
    (void)state;
    double P = 3e4, E = 210e9, nu = 0.3, d = 5e-4, R = 4.6e-3;
    double Ep = E / (1.0 - nu * nu), es = 0.5 * Ep;
    const double xvs[] = {-2.4e-4, -3e-5, 1e-5};
    for (int i = 0; i < 3; i++) {
        double xv = xvs[i], c = gs_corner_line_width(P, R, xv, es);
        double A1 = c, A0 = 2.0 * (c - xv);
        int n = 4000;
        double *x = malloc(sizeof *x * (size_t)n), *wq = malloc(sizeof *wq * (size_t)n);
        double *y = malloc(sizeof *y * (size_t)n), *wy = malloc(sizeof *wy * (size_t)n);
        double W = 0.0, Wy = 0.0, m2 = 0.0;
        for (int k = 0; k < n; k++) {
            double th = M_PI * (k + 0.5) / n, th2 = M_PI * (k + 0.25) / n;
            x[k] = 0.5 * c * (1.0 - cos(th));
            wq[k] = (1.0 + cos(th)) * (A0 - A1 * cos(th));
            y[k] = 0.5 * c * (1.0 - cos(th2));
            wy[k] = (1.0 + cos(th2)) * (A0 - A1 * cos(th2));
            W += wq[k];
            Wy += wy[k];
            m2 += wq[k] * (x[k] - xv) * (x[k] - xv);
        }
        m2 /= W;
        double en = 0.0;
        for (int k = 0; k < n; k++)
            for (int j = 0; j < n; j++)
                en += wq[k] * wy[j] * log(fabs(x[k] - y[j]));
        en /= W * Wy;
        free(x);
        free(wq);
        free(y);
        free(wy);
        double aeq = 2.0 * exp(en + 0.25);
        double g = m2 - (xv < 0.0 ? xv * xv : 0.0);
        double want = gs_hertz_line_approach(P, aeq, d, E, nu, GS_PLANE_STRAIN) -
                      P / (2.0 * M_PI * Ep) + es / Ep * g / (2.0 * R);
        double got = gs_corner_line_approach(P, R, xv, d, E, nu, GS_PLANE_STRAIN, es, 2.0 / M_PI);
        print_message("xv %.1e m: c %.3e m, approach %.6e (quadrature %.6e) m\n", xv, c, got, want);
        assert_true(fabs(got - want) < 2e-3 * want);
    }
}

/* Michell's wedge: the half-plane's 2/pi at any angle; a narrower wedge is
 * more compliant, most across its bisector. */
static void wedge_apex_factor(void **state)
{
    (void)state;
    for (double psi = -1.5; psi <= 1.5; psi += 0.5)
        assert_true(fabs(gs_wedge_apex_factor(M_PI / 2.0, psi) - 2.0 / M_PI) < 1e-12);
    double al = M_PI / 3.0;
    assert_true(fabs(gs_wedge_apex_factor(al, 0.0) - 1.0 / (al + sin(al) * cos(al))) < 1e-12);
    assert_true(gs_wedge_apex_factor(al, 0.0) > 2.0 / M_PI);
    assert_true(gs_wedge_apex_factor(al, 0.5) > gs_wedge_apex_factor(al, 0.0));
    assert_true(isnan(gs_wedge_apex_factor(al, 1.2)));
    assert_true(isnan(gs_wedge_apex_factor(0.0, 0.0)));
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(approach_matches_quadrature),
        cmocka_unit_test(approach_far_field_is_johnson),
        cmocka_unit_test(half_width_and_modulus),
        cmocka_unit_test(gap_vertex_parabola),
        cmocka_unit_test(gap_vertex_circles),
        cmocka_unit_test(corner_law_is_hertz_at_the_corner),
        cmocka_unit_test(corner_width_balances_the_load),
        cmocka_unit_test(corner_law_matches_quadrature),
        cmocka_unit_test(wedge_apex_factor),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
