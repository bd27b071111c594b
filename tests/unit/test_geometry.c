/* SPDX-License-Identifier: MIT
 * Involute gear geometry (METHOD.md section 5, docs/explanation/geometry.md): radii,
 * tooth thickness, the involute and the fillet, outline moments, checks with
 * errors naming the field, contact ratios against textbook formulas
 * computed here independently, planetary assembly. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "gearsim/geometry.h"
#include "../common/gears.h"

#define DEG (GS_PI / 180.0)

static double inv(double a)
{
    return tan(a) - a;
}

/* Relative comparison with a stated tolerance. */
#define assert_close(a, b, rel)                                                                  \
    do {                                                                                         \
        double a_ = (a), b_ = (b);                                                               \
        if (!(fabs(a_ - b_) <= (rel) * fmax(fabs(b_), 1e-300))) {                                \
            print_error("%s = %.17g, %s = %.17g (rel %.3g > %.3g)\n", #a, a_, #b, b_,              \
                        fabs(a_ - b_) / fmax(fabs(b_), 1e-300), (double)(rel));                   \
            fail();                                                                              \
        }                                                                                        \
    } while (0)

static void defaults(void **state)
{
    (void)state;
    gs_gear_params p;
    gs_gear_params_defaults(&p);
    assert_true(p.addendum_coef == 1.0 && p.dedendum_coef == 1.25 && p.fillet_coef == 0.38);
    assert_close(p.pressure_angle, 20 * DEG, 1e-15);
    assert_true(p.profile_shift == 0 && p.thinning_m == 0 && p.hub_radius_m == 0);
    assert_close(p.face_width_m, 0.01, 1e-15);
    /* hub radius 0 means: 0.6 root radius (external), root + 3 m (internal) */
    gs_gear_params e = gear(GS_GEAR_EXTERNAL, 20, 0.002, 0), r = gear(GS_GEAR_INTERNAL, 72, 0.002, 0);
    assert_close(gs_gear_hub_radius(&e), 0.6 * gs_gear_root_radius(&e), 1e-15);
    assert_close(gs_gear_hub_radius(&r), gs_gear_root_radius(&r) + 3 * 0.002, 1e-15);
}

/* Radii in closed form; relative 1e-15: a few roundings of products. */
static void radii(void **state)
{
    (void)state;
    const double m = 0.0025, a = 20 * DEG;
    gs_gear_params p = gear(GS_GEAR_EXTERNAL, 24, m, 0.3);
    assert_close(gs_gear_pitch_radius(&p), 0.030, 1e-15);
    assert_close(gs_gear_base_radius(&p), 0.030 * cos(a), 1e-15);
    assert_close(gs_gear_tip_radius(&p), 0.030 + 1.3 * m, 1e-15);
    assert_close(gs_gear_root_radius(&p), 0.030 - 0.95 * m, 1e-15);
    gs_gear_params r = gear(GS_GEAR_INTERNAL, 72, m, 0.2);
    assert_close(gs_gear_tip_radius(&r), 0.090 - 1.2 * m, 1e-15);
    assert_close(gs_gear_root_radius(&r), 0.090 + 1.05 * m, 1e-15);
    gs_gear_geom g;
    assert_int_equal(gs_gear_geometry(&p, &g, NULL), GS_OK);
    assert_close(g.r, 0.030, 1e-15);
    assert_close(g.ra, gs_gear_tip_radius(&p), 1e-15);
    assert_close(g.rf, gs_gear_root_radius(&p), 1e-15);
}

/* Tooth thickness on the pitch circle: pi m / 2 + 2 x m tan(alpha) minus
 * thinning; on the base circle d_b (s/d + inv alpha) (external) and
 * d_b (s/d - inv alpha) (internal, the ring's tooth). Tolerance 1e-14
 * relative: the involute function is evaluated through acos. */
static void tooth_thickness(void **state)
{
    (void)state;
    const double m = 0.004;
    for (int kind = 0; kind < 2; kind++)
        for (double x = -0.4; x <= 0.61; x += 0.5) {
            gs_gear_params p = gear(kind, kind ? 80 : 30, m, x);
            p.thinning_m = 0.05 * m;
            gs_gear_geom g;
            assert_int_equal(gs_gear_geometry(&p, &g, NULL), GS_OK);
            double s = GS_PI * m / 2 + 2 * x * m * tan(p.pressure_angle) - p.thinning_m;
            double r = gs_gear_pitch_radius(&p), rb = gs_gear_base_radius(&p);
            assert_close(gs_gear_tooth_thickness(&g, r), s, 1e-14);
            double sb = 2 * rb * (s / (2 * r) + (kind ? -1 : 1) * inv(p.pressure_angle));
            assert_close(gs_gear_tooth_thickness(&g, rb), sb, 1e-13);
        }
}

/* The flank follows the involute polar equation (METHOD.md section 5) and
 * the flank's tangent is the derivative of the curve (finite difference,
 * O(h^2) with h = 1e-6 r: 1e-8 rad). */
static void involute_flank(void **state)
{
    (void)state;
    gs_gear_params p = gear(GS_GEAR_EXTERNAL, 20, 0.003, 0.2);
    gs_gear_geom g;
    assert_int_equal(gs_gear_geometry(&p, &g, NULL), GS_OK);
    double s = GS_PI * 0.003 / 2 + 2 * 0.2 * 0.003 * tan(20 * DEG);
    for (int k = 0; k <= 20; k++) {
        double R = g.r_form + (g.ra - g.r_form) * k / 20.0, P[2], T[2];
        gs_gear_flank_point(&g, R, P, T);
        double phi = acos(g.rb / R);
        double psi = s / (2 * g.r) + inv(20 * DEG) - inv(phi);
        assert_close(hypot(P[0], P[1]), R, 1e-15);
        assert_true(fabs(atan2(P[1], P[0]) - psi) < 1e-15);
        double h = 1e-6 * g.r, Pa[2], Pb[2], Ta[2];
        gs_gear_flank_point(&g, R + h, Pa, Ta);
        gs_gear_flank_point(&g, R - h, Pb, Ta);
        double dx = Pa[0] - Pb[0], dy = Pa[1] - Pb[1], n = hypot(dx, dy);
        assert_true(fabs(asin((dx * T[1] - dy * T[0]) / n)) < 1e-8);
        assert_true(dx * T[0] + dy * T[1] > 0); /* towards the tip */
    }
    assert_close(gs_involute_inverse(inv(0.35)), 0.35, 1e-14);
    assert_close(gs_involute_inverse(inv(0.01)), 0.01, 1e-12);
}

static double angle_between(const double a[2], const double b[2])
{
    return atan2(fabs(a[0] * b[1] - a[1] * b[0]), a[0] * b[0] + a[1] * b[1]);
}

/* The fillet meets the flank and the root circle tangentially (below 1e-9
 * rad; the construction is exact, so what is left is round-off), starts at
 * the form point and ends on the root circle. External gears without
 * undercut (trochoid) and internal gears (circle). */
static void fillet_tangency(void **state)
{
    (void)state;
    struct {
        int kind, z;
        double x, adeg;
    } cases[] = {{0, 20, 0, 20},  {0, 30, 0.5, 20}, {0, 40, -0.3, 25}, {0, 40, 0, 14.5},
                 {0, 200, 0, 20}, {1, 72, 0, 20},   {1, 60, 0.3, 20},  {1, 90, -0.2, 25}};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        gs_gear_params p = gear(cases[c].kind, cases[c].z, 0.002, cases[c].x);
        p.pressure_angle = cases[c].adeg * DEG;
        if (cases[c].adeg > 24)
            p.fillet_coef = 0.25;
        gs_gear_geom g;
        gs_diag d;
        assert_int_equal(gs_gear_geometry(&p, &g, &d), GS_OK);
        assert_false(g.undercut);
        double F[2], Tf[2], Q[2], Tq[2], E[2], Te[2];
        gs_gear_flank_point(&g, g.r_form, F, Tf);
        gs_gear_fillet_point(&g, 0.0, Q, Tq);
        gs_gear_fillet_point(&g, 1.0, E, Te);
        assert_true(hypot(F[0] - Q[0], F[1] - Q[1]) < 1e-12 * g.r);
        double back[2] = {-Tf[0], -Tf[1]}; /* flank towards the root */
        double a1 = angle_between(back, Tq);
        double rad[2] = {E[0] / hypot(E[0], E[1]), E[1] / hypot(E[0], E[1])};
        double a2 = fabs(0.5 * GS_PI - angle_between(rad, Te));
        print_message("# fillet %s z=%d x=%+.1f alpha=%.1f: flank angle %.2e rad, root angle %.2e rad\n",
                      cases[c].kind ? "internal" : "external", cases[c].z, cases[c].x,
                      cases[c].adeg, a1, a2);
        assert_true(a1 < 1e-9);
        assert_true(a2 < 1e-9);
        assert_close(hypot(E[0], E[1]), g.rf, 1e-13);
        assert_close(atan2(E[1], E[0]), g.psi_root, 1e-12);
    }
}

/* The trochoid is the envelope of the rack cutter's tip circle: every
 * fillet point lies at exactly rho from the path of that circle's centre,
 * Q(theta) = R(pi/z - pi/2 - theta) (uc - r theta, yc) in the frame of tooth
 * 0 (rack rolling on the pitch circle, textbook construction, computed here
 * without the library's contour parametrisation). Tolerance 1e-9 rho: the
 * distance minimum is found by golden section to ~1e-12 in theta. */
static double dist_to_centre_path(double px, double py, double r, double z, double uc, double yc)
{
    double lo = -1.0, hi = 2.0, best = INFINITY, tb = 0;
    for (int i = 0; i <= 3000; i++) { /* bracket */
        double th = lo + (hi - lo) * i / 3000.0, ph = GS_PI / z - GS_PI / 2 - th;
        double wx = uc - r * th, wy = yc;
        double qx = cos(ph) * wx - sin(ph) * wy, qy = sin(ph) * wx + cos(ph) * wy;
        double dd = hypot(px - qx, py - qy);
        if (dd < best) {
            best = dd;
            tb = th;
        }
    }
    double a = tb - 1e-3, b = tb + 1e-3, gr = 0.5 * (sqrt(5.0) - 1);
    for (int it = 0; it < 200; it++) {
        double c = b - gr * (b - a), e = a + gr * (b - a);
        double fc, fe;
        for (int k = 0; k < 2; k++) {
            double th = k ? e : c, ph = GS_PI / z - GS_PI / 2 - th;
            double wx = uc - r * th, wy = yc;
            double qx = cos(ph) * wx - sin(ph) * wy, qy = sin(ph) * wx + cos(ph) * wy;
            *(k ? &fe : &fc) = hypot(px - qx, py - qy);
        }
        if (fc < fe)
            b = e;
        else
            a = c;
    }
    double th = 0.5 * (a + b), ph = GS_PI / z - GS_PI / 2 - th;
    double wx = uc - r * th, wy = yc;
    return hypot(px - (cos(ph) * wx - sin(ph) * wy), py - (sin(ph) * wx + cos(ph) * wy));
}

static void trochoid_is_envelope(void **state)
{
    (void)state;
    for (int c = 0; c < 3; c++) {
        int z = c == 0 ? 20 : c == 1 ? 12 : 40;
        double x = c == 2 ? 0.4 : 0.0;
        const double m = 0.002, al = 20 * DEG;
        gs_gear_params p = gear(GS_GEAR_EXTERNAL, z, m, x);
        gs_gear_geom g;
        assert_int_equal(gs_gear_geometry(&p, &g, NULL), GS_OK);
        double r = m * z / 2, rho = 0.38 * m, rf = r - (1.25 - x) * m;
        double e = GS_PI * m / 2 - 2 * x * m * tan(al); /* cutter tooth on the rolling line */
        double yc = rf + rho, uc = e / 2 + (yc - r) * tan(al) - rho / cos(al);
        double worst = 0;
        for (int k = 0; k <= 40; k++) {
            double P[2], T[2];
            gs_gear_fillet_point(&g, k / 40.0, P, T);
            double dd = dist_to_centre_path(P[0], P[1], r, z, uc, yc);
            worst = fmax(worst, fabs(dd - rho));
        }
        print_message("# trochoid z=%d x=%.1f (undercut %d): max |distance to cutter centre path - rho| "
                      "= %.2e rho\n",
                      z, x, g.undercut, worst / rho);
        assert_true(worst < 1e-9 * rho);
    }
}

/* Undercut: the classic limit z_min = 2 h_a0 / sin^2(alpha), h_a0 the
 * cutter's straight-flank depth below the datum: (1.25 - 0.38 (1 - sin a))
 * = 0.99996 for the standard rack, so 17 teeth undercut (barely), 18 not. */
static void undercut(void **state)
{
    (void)state;
    char w[512];
    int nw;
    for (int z = 10; z <= 20; z++) {
        gs_gear_params p = gear(GS_GEAR_EXTERNAL, z, 0.001, 0);
        gs_gear_geom g;
        assert_int_equal(gs_gear_geometry(&p, &g, NULL), GS_OK);
        double ha0 = 1.25 - 0.38 * (1 - sin(20 * DEG));
        int expect = z < 2 * ha0 / pow(sin(20 * DEG), 2);
        assert_int_equal(g.undercut, expect);
        assert_int_equal(gs_gear_check(&p, NULL, w, sizeof w, &nw), GS_OK);
        assert_int_equal(strstr(w, "undercut") != NULL, expect);
        if (expect) /* the involute starts above the base circle */
            assert_true(g.r_form > g.rb);
    }
    /* a positive shift x >= 1 - z sin^2(a) / 2 removes it */
    gs_gear_params p = gear(GS_GEAR_EXTERNAL, 12, 0.001, 0.35);
    gs_gear_geom g;
    assert_int_equal(gs_gear_geometry(&p, &g, NULL), GS_OK);
    assert_false(g.undercut);
}

/* Outline area and polar moment against a fine polygon of the same exact
 * curves (1e-9 relative: the polygon's own O(h^2) error with 20000 points
 * per piece is ~1e-10). Mass properties: density * face width * (area, moment). */
static void outline_moments(void **state)
{
    (void)state;
    for (int kind = 0; kind < 2; kind++) {
        gs_gear_params p = gear(kind, kind ? 72 : 20, 0.002, kind ? 0 : 0.2);
        gs_gear_geom g;
        assert_int_equal(gs_gear_geometry(&p, &g, NULL), GS_OK);
        double A, J, Ap = 0, Jp = 0;
        gs_gear_outline_moments(&g, &A, &J);
        enum { N = 20000 };
        double prev[2] = {g.ra, 0.0};
        for (int piece = 0; piece < 4; piece++)
            for (int i = 1; i <= N; i++) {
                double P[2], T[2], t = (double)i / N;
                if (piece == 0) {
                    P[0] = g.ra * cos(t * g.psi_tip);
                    P[1] = g.ra * sin(t * g.psi_tip);
                } else if (piece == 1) {
                    gs_gear_flank_point(&g, g.ra + (g.r_form - g.ra) * t, P, T);
                } else if (piece == 2) {
                    gs_gear_fillet_point(&g, t, P, T);
                } else {
                    double ps = g.psi_root + (g.half_pitch - g.psi_root) * t;
                    P[0] = g.rf * cos(ps);
                    P[1] = g.rf * sin(ps);
                }
                /* triangle (0, prev, P): area and polar moment about 0 */
                double cr = prev[0] * P[1] - prev[1] * P[0];
                Ap += 0.5 * cr;
                Jp += cr / 12.0 *
                      (prev[0] * prev[0] + prev[1] * prev[1] + P[0] * P[0] + P[1] * P[1] +
                       prev[0] * P[0] + prev[1] * P[1]);
                prev[0] = P[0];
                prev[1] = P[1];
            }
        Ap *= 2 * g.z;
        Jp *= 2 * g.z;
        assert_close(A, Ap, 1e-9);
        assert_close(J, Jp, 1e-9);
        /* between the root and tip disks */
        assert_true(A > GS_PI * fmin(g.ra, g.rf) * fmin(g.ra, g.rf));
        assert_true(A < GS_PI * fmax(g.ra, g.rf) * fmax(g.ra, g.rf));
        double mass, I, rho = 7850, b = p.face_width_m;
        assert_int_equal(gs_gear_mass_properties(&p, rho, &mass, &I), GS_OK);
        if (!kind) {
            assert_close(mass, rho * b * A, 1e-14);
            assert_close(I, rho * b * J, 1e-14);
        } else {
            double Ro = gs_gear_hub_radius(&p);
            assert_close(mass, rho * b * (GS_PI * Ro * Ro - A), 1e-13);
            assert_close(I, rho * b * (0.5 * GS_PI * pow(Ro, 4) - J), 1e-13);
        }
        print_message("# %s z=%d: outline area %.12e m^2 (polygon %.12e), polar %.12e m^4, mass %.6g kg, "
                      "I %.6g kg m^2\n",
                      kind ? "internal" : "external", g.z, A, Ap, J, mass, I);
    }
    assert_int_equal(gs_gear_mass_properties(&(gs_gear_params){0}, 7850, NULL, NULL) != GS_OK, 1);
}

/* Impossible inputs: an error naming the scene field. */
static void rejects_naming_field(void **state)
{
    (void)state;
    struct {
        const char *field;
        gs_gear_params p;
    } c[32];
    int n = 0;
    gs_gear_params base = gear(GS_GEAR_EXTERNAL, 20, 0.002, 0);
#define CASE(f, stmt)      \
    do {                   \
        c[n].field = f;    \
        c[n].p = base;     \
        {                  \
            gs_gear_params *q = &c[n].p; \
            stmt;          \
        }                  \
        n++;               \
    } while (0)
    CASE("teeth", q->teeth = 3);
    CASE("teeth", q->teeth = -20);
    CASE("teeth", (q->kind = GS_GEAR_INTERNAL, q->teeth = 24)); /* ring tips inside base circle */
    CASE("module_mm", q->module_m = 0);
    CASE("module_mm", q->module_m = NAN);
    CASE("module_mm", q->module_m = 5.0);
    CASE("pressure_angle_deg", q->pressure_angle = 50 * DEG);
    CASE("pressure_angle_deg", q->pressure_angle = INFINITY);
    CASE("addendum", q->addendum_coef = 3);
    CASE("addendum", q->addendum_coef = -1);
    CASE("dedendum", q->dedendum_coef = 0);
    CASE("dedendum", (q->teeth = 6, q->dedendum_coef = 3.0, q->profile_shift = -0.5)); /* rf <= 0 */
    CASE("fillet", q->fillet_coef = 0);
    CASE("fillet", q->fillet_coef = 0.6); /* does not fit the rack tooth */
    CASE("fillet", (q->kind = GS_GEAR_INTERNAL, q->teeth = 72, q->fillet_coef = 0.9));
    CASE("profile_shift", q->profile_shift = 2);
    CASE("profile_shift", (q->teeth = 8, q->profile_shift = 0.8)); /* pointed tip */
    CASE("thinning_mm", q->thinning_m = -1e-6);
    CASE("thinning_mm", q->thinning_m = 0.002);
    CASE("face_width_mm", q->face_width_m = 0);
    CASE("hub_radius_mm", q->hub_radius_m = 0.019); /* above the root circle */
    CASE("hub_radius_mm", q->hub_radius_m = -0.001);
    CASE("hub_radius_mm", (q->kind = GS_GEAR_INTERNAL, q->teeth = 72, q->hub_radius_m = 0.0725));
    CASE("kind", q->kind = (gs_gear_kind)7);
#undef CASE
    for (int i = 0; i < n; i++) {
        gs_diag d;
        gs_diag_clear(&d);
        gs_err e = gs_gear_validate(&c[i].p, &d);
        if (e == GS_OK || strcmp(d.field, c[i].field) != 0)
            print_error("case %d: expected an error on %s, got %s (%s: %s)\n", i, c[i].field,
                        gs_errcode(e), d.field, d.message);
        assert_int_not_equal(e, GS_OK);
        assert_string_equal(d.field, c[i].field);
        assert_true(strlen(d.message) > 10);
        assert_true(e == GS_EGEOMETRY || e == GS_ERANGE || e == GS_EINVAL);
    }
    print_message("# %d impossible gears rejected, each naming its field\n", n);
}

/* Textbook transverse contact ratio (e.g. Niemann/Winter, Maitra):
 * external  eps = (sqrt(ra1^2-rb1^2) + sqrt(ra2^2-rb2^2) - a sin aw) / (pi m cos a),
 * internal  eps = (sqrt(ra1^2-rb1^2) - sqrt(ra2^2-rb2^2) + a sin aw) / (pi m cos a),
 * aw from cos aw = (rb2 +- rb1) / a. */
static double textbook_eps(int internal, double m, double al, int z1, double x1, double ha1,
                           int z2, double x2, double ha2, double a, double *aw)
{
    double r1 = m * z1 / 2, r2 = m * z2 / 2, rb1 = r1 * cos(al), rb2 = r2 * cos(al);
    double ra1 = r1 + (ha1 + x1) * m;
    double ra2 = internal ? r2 - (ha2 + x2) * m : r2 + (ha2 + x2) * m;
    *aw = acos((internal ? rb2 - rb1 : rb2 + rb1) / a);
    double g = internal ? sqrt(ra1 * ra1 - rb1 * rb1) - sqrt(ra2 * ra2 - rb2 * rb2) + a * sin(*aw)
                        : sqrt(ra1 * ra1 - rb1 * rb1) + sqrt(ra2 * ra2 - rb2 * rb2) - a * sin(*aw);
    return g / (GS_PI * m * cos(al));
}

static void contact_ratio_pair(void **state)
{
    (void)state;
    const double m = 0.002, al = 20 * DEG;
    gs_gear_params p1 = gear(GS_GEAR_EXTERNAL, 20, m, 0), p2 = gear(GS_GEAR_EXTERNAL, 30, m, 0);
    double eps, aw, awt;
    gs_diag d;
    /* standard centre distance; the textbook value for 20/30 is 1.605 */
    double a = m * 25;
    assert_int_equal(gs_pair_contact_ratio(&p1, &p2, a, &eps, &aw, &d), GS_OK);
    double et = textbook_eps(0, m, al, 20, 0, 1, 30, 0, 1, a, &awt);
    print_message("# 20/30 at a = %.4g mm: eps %.12f, textbook %.12f, alpha_w %.10f deg\n", a * 1e3,
                  eps, et, aw / DEG);
    assert_close(eps, et, 1e-12);
    assert_close(eps, 1.6052, 1e-4); /* the tabulated value */
    assert_close(aw, al, 1e-12);
    /* pulled apart by 0.1 m: larger working pressure angle, smaller ratio */
    a = m * 25.1;
    assert_int_equal(gs_pair_contact_ratio(&p1, &p2, a, &eps, &aw, &d), GS_OK);
    et = textbook_eps(0, m, al, 20, 0, 1, 30, 0, 1, a, &awt);
    print_message("# 20/30 at a = %.4g mm: eps %.12f, textbook %.12f, alpha_w %.10f deg (textbook %.10f)\n",
                  a * 1e3, eps, et, aw / DEG, awt / DEG);
    assert_close(eps, et, 1e-12);
    assert_close(aw, awt, 1e-12);
    /* shifted pair: tight centre distance from inv(aw) = inv(a) + 2 (x1+x2) tan(a) / (z1+z2) */
    gs_gear_params s1 = gear(GS_GEAR_EXTERNAL, 14, m, 0.4), s2 = gear(GS_GEAR_EXTERNAL, 31, m, 0.1);
    double at;
    assert_int_equal(gs_pair_tight_centre_distance(&s1, &s2, &at, &d), GS_OK);
    double iw = inv(al) + 2 * 0.5 * tan(al) / 45.0;
    double awx = gs_involute_inverse(iw); /* inverse checked in involute_flank */
    assert_close(at, m * 45 / 2 * cos(al) / cos(awx), 1e-13);
    assert_int_equal(gs_pair_contact_ratio(&s1, &s2, at, &eps, &aw, &d), GS_OK);
    et = textbook_eps(0, m, al, 14, 0.4, 1, 31, 0.1, 1, at, &awt);
    print_message("# 14(x=0.4)/31(x=0.1) at tight a = %.6g mm: eps %.12f, textbook %.12f, alpha_w %.6f deg\n",
                  at * 1e3, eps, et, aw / DEG);
    assert_close(eps, et, 1e-12);
    /* pairs that cannot mesh */
    gs_gear_params q = p2;
    q.module_m = 0.0025;
    assert_int_equal(gs_pair_contact_ratio(&p1, &q, 0.05, &eps, &aw, &d), GS_EGEOMETRY);
    assert_string_equal(d.field, "gears");
    q = p2;
    q.pressure_angle = 25 * DEG;
    q.fillet_coef = 0.25;
    assert_int_equal(gs_pair_contact_ratio(&p1, &q, 0.05, &eps, &aw, &d), GS_EGEOMETRY);
    assert_string_equal(d.field, "gears");
    assert_int_equal(gs_pair_contact_ratio(&p1, &p2, m * 24.9, &eps, &aw, &d), GS_EGEOMETRY);
    assert_non_null(strstr(d.message, "overlap"));
    assert_int_equal(gs_pair_contact_ratio(&p1, &p2, m * 26.3, &eps, &aw, &d), GS_EGEOMETRY);
    print_message("# 20/30 at a = %.4g mm: %s\n", m * 26.3e3, d.message);
    assert_non_null(strstr(d.message, "below 1"));
    assert_int_equal(gs_pair_contact_ratio(&p1, &p2, m * 27.5, &eps, &aw, &d), GS_EGEOMETRY);
    assert_non_null(strstr(d.message, "do not reach"));
}

static void contact_ratio_planetary(void **state)
{
    (void)state;
    /* sun 24, planets 24, ring 72 (addendum 0.8, the usual shortened ring
     * tooth: at 1.0 its tips would clip the planets' fillets, see
     * docs/explanation/geometry.md), module 2.5 mm, 3 planets */
    const double m = 0.0025, al = 20 * DEG;
    gs_gear_params sun = gear(GS_GEAR_EXTERNAL, 24, m, 0), pl = gear(GS_GEAR_EXTERNAL, 24, m, 0);
    gs_gear_params ring = gear(GS_GEAR_INTERNAL, 72, m, 0);
    ring.addendum_coef = 0.8;
    gs_diag d;
    assert_int_equal(gs_planetary_check(&sun, &pl, &ring, 3, &d), GS_OK);
    double a;
    assert_int_equal(gs_planetary_centre_distance(&sun, &pl, &ring, &a, &d), GS_OK);
    assert_close(a, 0.060, 1e-14);
    double e1, e2, aw1, aw2, t1, t2, w;
    assert_int_equal(gs_pair_contact_ratio(&sun, &pl, a, &e1, &aw1, &d), GS_OK);
    assert_int_equal(gs_pair_contact_ratio(&pl, &ring, a, &e2, &aw2, &d), GS_OK);
    t1 = textbook_eps(0, m, al, 24, 0, 1, 24, 0, 1, a, &w);
    t2 = textbook_eps(1, m, al, 24, 0, 1, 72, 0, 0.8, a, &w);
    print_message("# sun/planet 24/24: eps %.12f, textbook %.12f\n", e1, t1);
    print_message("# planet/ring 24/72 (ring addendum 0.8): eps %.12f, textbook %.12f\n", e2, t2);
    assert_close(e1, t1, 1e-12);
    assert_close(e2, t2, 1e-12);
    assert_close(aw2, al, 1e-12);
    /* a full-depth ring: the textbook ratio is reported, but contact is cut
     * short by the planet's form radius and the tips clip its fillet */
    ring.addendum_coef = 1.0;
    gs_pair_info info;
    assert_int_equal(gs_pair_analyse(&pl, &ring, a, &info, &d), GS_OK);
    t2 = textbook_eps(1, m, al, 24, 0, 1, 72, 0, 1, a, &w);
    print_message("# planet/ring 24/72 (ring addendum 1.0): tips-only %.6f (textbook %.6f), involute %.6f, "
                  "fillet clipped %.4f module\n",
                  info.contact_ratio_tips, t2, info.contact_ratio, info.interference / m);
    assert_close(info.contact_ratio_tips, t2, 1e-12);
    assert_true(info.contact_ratio < info.contact_ratio_tips);
    assert_true(info.form_limited == 1);
    assert_true(info.interference > 1e-3 * m && info.interference < 0.05 * m);
    assert_true(strlen(info.warning) > 0);
    ring.addendum_coef = 0.8;
    /* assembly conditions */
    assert_int_equal(gs_planetary_check(&sun, &pl, &ring, 5, &d), GS_EGEOMETRY); /* 96 / 5 */
    assert_non_null(strstr(d.message, "multiple"));
    assert_int_equal(gs_planetary_check(&sun, &pl, &ring, 6, &d), GS_EGEOMETRY); /* overlap */
    assert_non_null(strstr(d.message, "overlap"));
    gs_gear_params r74 = ring;
    r74.teeth = 74;
    assert_int_equal(gs_planetary_check(&sun, &pl, &r74, 2, &d), GS_EGEOMETRY);
    assert_non_null(strstr(d.message, "z_sun + 2 z_planet"));
    assert_int_equal(gs_planetary_check(&sun, &pl, &ring, 0, &d), GS_ERANGE);
    assert_string_equal(d.field, "planets");
    assert_int_equal(gs_planetary_check(&sun, &pl, &sun, 3, &d), GS_EGEOMETRY);
    /* internal pair with too few teeth of difference: tip interference */
    gs_gear_params pin = gear(GS_GEAR_EXTERNAL, 40, m, 0), r46 = gear(GS_GEAR_INTERNAL, 46, m, 0);
    double at;
    assert_int_equal(gs_pair_tight_centre_distance(&pin, &r46, &at, &d), GS_OK);
    assert_int_equal(gs_pair_contact_ratio(&pin, &r46, at, &e1, &aw1, &d), GS_EGEOMETRY);
    assert_string_equal(d.field, "gears");
    assert_non_null(strstr(d.message, "interference"));
    print_message("# 40 in 46: %s\n", d.message);
}

/* The mesh phase puts a space of gear 2 on the line of centres when a tooth
 * of gear 1 is on it, and follows the speed ratio. */
static void mesh_phase(void **state)
{
    (void)state;
    gs_gear_params p1 = gear(GS_GEAR_EXTERNAL, 20, 0.002, 0), p2 = gear(GS_GEAR_EXTERNAL, 30, 0.002, 0);
    double c1[2] = {0, 0}, c2[2] = {0.05, 0};
    double t2 = gs_pair_mesh_phase(&p1, c1, 0.0, &p2, c2, 0.0);
    /* a space centre of gear 2 (angle t2 + pi/z2 + k 2pi/z2) points at gear 1 (angle pi) */
    double rel = (GS_PI - (t2 + GS_PI / 30)) / (2 * GS_PI / 30);
    assert_true(fabs(rel - round(rel)) < 1e-12);
    /* turn gear 1 by a small angle: gear 2 turns back by z1/z2 of it */
    double t2b = gs_pair_mesh_phase(&p1, c1, 0.01, &p2, c2, t2);
    assert_close(t2b - t2, -0.01 * 20 / 30, 1e-12);
    /* ring: same direction */
    gs_gear_params r = gear(GS_GEAR_INTERNAL, 72, 0.002, 0);
    double cr[2] = {-0.048, 0};
    double a = gs_pair_mesh_phase(&p1, c1, 0.0, &r, cr, 0.0);
    double b = gs_pair_mesh_phase(&p1, c1, 0.02, &r, cr, a);
    assert_close(b - a, 0.02 * 20 / 72, 1e-12);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(defaults),
        cmocka_unit_test(radii),
        cmocka_unit_test(tooth_thickness),
        cmocka_unit_test(involute_flank),
        cmocka_unit_test(fillet_tangency),
        cmocka_unit_test(trochoid_is_envelope),
        cmocka_unit_test(undercut),
        cmocka_unit_test(outline_moments),
        cmocka_unit_test(rejects_naming_field),
        cmocka_unit_test(contact_ratio_pair),
        cmocka_unit_test(contact_ratio_planetary),
        cmocka_unit_test(mesh_phase),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
