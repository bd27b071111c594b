/* SPDX-License-Identifier: MIT
 * Helical gear geometry (docs/explanation/helical.md): the transverse
 * section from the normal basic rack on the exact involute, contact ratios
 * against the closed forms of ISO 21771 written out here, the total
 * contact-line length against its closed-form extremes and mean, and bad
 * helical input refused with the scene field named. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "gearsim/geometry.h"
#include "gearsim/scene.h"
#include "../common/gears.h"

#define DEG (GS_PI / 180.0)

static double inv(double a)
{
    return tan(a) - a;
}

/* A helical gear given in the normal section. */
static gs_gear_params helical(gs_gear_kind kind, int z, double mn, double xn, double beta_deg, int hand, double b)
{
    gs_gear_params p = gear(kind, z, mn, xn);
    p.face_width_m = b;
    gs_diag d;
    assert_int_equal(gs_gear_params_helical(&p, beta_deg * DEG, hand, &d), GS_OK);
    return p;
}

/* Transverse flank points on the involute of the transverse base circle:
 * radius and polar angle from the normal-section data alone,
 * m_t = m_n / cos(beta), tan(alpha_t) = tan(alpha_n) / cos(beta),
 * s_t = m_t (pi/2 + 2 x_n tan(alpha_n)), distance error below 1e-9 mm. */
static void transverse_involute(void **state)
{
    (void)state;
    const struct {
        gs_gear_kind kind;
        int z;
        double mn, xn, beta;
    } c[] = {{GS_GEAR_EXTERNAL, 23, 3e-3, 0.3, 15}, {GS_GEAR_EXTERNAL, 41, 2e-3, -0.1, 30},
             {GS_GEAR_INTERNAL, 71, 2e-3, 0.0, 20}, {GS_GEAR_INTERNAL, 60, 2.5e-3, 0.2, 12}};
    for (size_t i = 0; i < sizeof c / sizeof c[0]; i++) {
        gs_gear_params p = helical(c[i].kind, c[i].z, c[i].mn, c[i].xn, c[i].beta, 1, 0.02);
        gs_gear_geom g;
        gs_diag d;
        assert_int_equal(gs_gear_geometry(&p, &g, &d), GS_OK);
        double be = c[i].beta * DEG, an = 20 * DEG;
        double mt = c[i].mn / cos(be), at = atan(tan(an) / cos(be));
        double r = 0.5 * c[i].z * mt, rb = r * cos(at), st = mt * (GS_PI / 2 + 2 * c[i].xn * tan(an));
        bool ring = c[i].kind == GS_GEAR_INTERNAL;
        double lo = fmax(rb, ring ? g.ra : g.r_form), hi = ring ? g.r_form : g.ra, worst = 0;
        for (int k = 0; k <= 200; k++) {
            double R = lo + (hi - lo) * k / 200.0, xy[2], tn[2];
            gs_gear_flank_point(&g, R, xy, tn);
            double ph = acos(rb / R);
            double psi = ring ? st / (2 * r) - inv(at) + inv(ph) : st / (2 * r) + inv(at) - inv(ph);
            double dx = xy[0] - R * cos(psi), dy = xy[1] - R * sin(psi);
            worst = fmax(worst, hypot(dx, dy));
        }
        print_message("# %s z %d m_n %.1f mm x_n %.2f beta %.0f deg: m_t %.9f mm alpha_t %.9f deg, worst distance "
                      "from the involute %.3e mm\n",
                      ring ? "ring" : "gear", c[i].z, c[i].mn * 1e3, c[i].xn, c[i].beta, g.m * 1e3, g.alpha / DEG,
                      worst * 1e3);
        assert_true(fabs(g.m - mt) <= 1e-15 * mt);
        assert_true(fabs(g.alpha - at) <= 1e-15);
        assert_true(fabs(g.rb - rb) <= 1e-15 * rb);
        assert_true(worst * 1e3 < 1e-9);
        /* the tip and root circles keep the normal-section lengths */
        /* (a ring's positive shift moves both circles towards the centre) */
        double ha = c[i].mn * (1.0 + c[i].xn), hf = c[i].mn * (1.25 - c[i].xn);
        assert_true(fabs(g.ra - (ring ? r - ha : r + ha)) < 1e-15);
        assert_true(fabs(g.rf - (ring ? r + hf : r - hf)) < 1e-15);
    }
    /* beta = 0 leaves a spur gear bit for bit */
    gs_gear_params s = gear(GS_GEAR_EXTERNAL, 20, 2e-3, 0.2), t = s;
    gs_diag d;
    assert_int_equal(gs_gear_params_helical(&t, 0.0, 0, &d), GS_OK);
    assert_memory_equal(&s, &t, sizeof s);
}

/* ISO 21771 for a helical pair at centre distance a (x, z of the ring
 * negative in ISO's convention: here written per kind):
 *   eps_alpha = (sqrt(r_a1^2 - r_b1^2) +- sqrt(r_a2^2 - r_b2^2) -+ a sin(alpha_wt)) / p_et
 *   p_et = pi m_n cos(alpha_t) / cos(beta), cos(alpha_wt) = r_b-sum / a,
 *   eps_beta = b sin(beta) / (pi m_n), eps_gamma = eps_alpha + eps_beta. */
static void contact_ratios(void **state)
{
    (void)state;
    const struct {
        int z1, z2, ring;
        double mn, x1, x2, beta, b1, b2;
    } c[] = {{20, 30, 0, 2.5e-3, 0, 0, 15, 30e-3, 30e-3},
             {17, 41, 0, 2e-3, 0.3, -0.1, 25, 20e-3, 24e-3},
             {21, 70, 1, 2e-3, 0.2, 0.2, 20, 25e-3, 25e-3}};
    for (size_t i = 0; i < sizeof c / sizeof c[0]; i++) {
        gs_gear_params p1 = helical(GS_GEAR_EXTERNAL, c[i].z1, c[i].mn, c[i].x1, c[i].beta, 1, c[i].b1);
        gs_gear_params p2 = helical(c[i].ring ? GS_GEAR_INTERNAL : GS_GEAR_EXTERNAL, c[i].z2, c[i].mn, c[i].x2,
                                    c[i].beta, c[i].ring ? 1 : -1, c[i].b2);
        double be = c[i].beta * DEG, an = 20 * DEG, at = atan(tan(an) / cos(be)), mt = c[i].mn / cos(be);
        double rb1 = 0.5 * c[i].z1 * mt * cos(at), rb2 = 0.5 * c[i].z2 * mt * cos(at);
        /* tight centre distance: inv(alpha_wt) = inv(alpha_t) + 2 tan(alpha_n) (x1 + x2) / (z1 + z2),
         * z2 negative for the ring */
        double iw = c[i].ring ? inv(at) - 2 * tan(an) * (c[i].x1 + c[i].x2) / (c[i].z2 - c[i].z1)
                              : inv(at) + 2 * tan(an) * (c[i].x1 + c[i].x2) / (c[i].z1 + c[i].z2);
        double awt = gs_involute_inverse(iw);
        double a = (c[i].ring ? rb2 - rb1 : rb1 + rb2) / cos(awt);
        double ra1 = 0.5 * c[i].z1 * mt + c[i].mn * (1 + c[i].x1);
        double ra2 = c[i].ring ? 0.5 * c[i].z2 * mt - c[i].mn * (1 + c[i].x2) : 0.5 * c[i].z2 * mt + c[i].mn * (1 + c[i].x2);
        double pet = GS_PI * c[i].mn * cos(at) / cos(be);
        double g1 = sqrt(ra1 * ra1 - rb1 * rb1), g2 = sqrt(ra2 * ra2 - rb2 * rb2);
        double ea = c[i].ring ? (g1 - g2 + a * sin(awt)) / pet : (g1 + g2 - a * sin(awt)) / pet;
        double b = fmin(c[i].b1, c[i].b2), eb = b * sin(be) / (GS_PI * c[i].mn);
        gs_pair_info info;
        gs_diag d;
        gs_err e = gs_pair_analyse(&p1, &p2, a, &info, &d);
        if (e != GS_OK)
            print_error("%s: %s\n", d.field, d.message);
        assert_int_equal(e, GS_OK);
        print_message("# %d/%d%s beta %.0f: eps_alpha %.12f (ISO 21771 %.12f; involute flanks %.12f), eps_beta "
                      "%.12f (%.12f), eps_gamma %.12f (%.12f)\n",
                      c[i].z1, c[i].z2, c[i].ring ? " internal" : "", c[i].beta, info.contact_ratio_tips, ea,
                      info.contact_ratio, info.overlap_ratio, eb, info.total_contact_ratio, ea + eb);
        assert_true(fabs(info.contact_ratio_tips - ea) < 1e-9);
        assert_true(fabs(info.overlap_ratio - eb) < 1e-12);
        if (!info.form_limited) {
            assert_true(fabs(info.contact_ratio - ea) < 1e-9);
            assert_true(fabs(info.total_contact_ratio - (ea + eb)) < 1e-9);
        }
        /* contact lines: extremes in closed form (n_a, n_b the fractional
         * parts of eps_alpha, eps_beta) and the mean b eps_alpha / cos(beta_b) */
        double A = info.contact_ratio, B = info.overlap_ratio, na = A - floor(A), nb = B - floor(B);
        double bb = atan(tan(be) * cos(at)), Lu = b / cos(bb);
        double lmin = Lu * (A - (na + nb <= 1 ? na * nb : (1 - na) * (1 - nb)) / B);
        double lmax = Lu * (A + fmin(na * (1 - nb), (1 - na) * nb) / B);
        int n = 100000;
        double mean = 0, lo = INFINITY, hi = -INFINITY;
        for (int k = 0; k < n; k++) {
            double L = gs_pair_contact_line_length(&info, (k + 0.5) / n);
            mean += L / n;
            lo = fmin(lo, L);
            hi = fmax(hi, L);
        }
        print_message("#   contact lines: min %.9f mm (closed form %.9f), max %.9f mm (%.9f), mean %.9f mm (%.9f)\n",
                      info.line_min * 1e3, lmin * 1e3, info.line_max * 1e3, lmax * 1e3, mean * 1e3, Lu * A * 1e3);
        assert_true(fabs(info.line_min - lmin) < 1e-12);
        assert_true(fabs(info.line_max - lmax) < 1e-12);
        assert_true(lo >= lmin - 1e-12 && hi <= lmax + 1e-12);
        assert_true(fabs(mean - Lu * A) < 1e-6 * Lu * A);
    }
}

static void parse_fails(const char *bodies_extra0, const char *bodies_extra1, const char *mesh_extra, const char *field)
{
    char txt[2048];
    snprintf(txt, sizeof txt,
             "{\"name\":\"h\",\"bodies\":["
             "{\"name\":\"p\",\"teeth\":20,\"module_mm\":2.5,\"face_width_mm\":30%s},"
             "{\"name\":\"w\",\"teeth\":30,\"module_mm\":2.5,\"face_width_mm\":30%s}],"
             "\"joints\":[{\"body\":\"p\",\"type\":\"fixed_axis\",\"centre_mm\":[0,0]},"
             "{\"body\":\"w\",\"type\":\"fixed_axis\",\"centre_mm\":[64.71,0]}],"
             "\"meshes\":[{\"name\":\"m\",\"gears\":[\"p\",\"w\"],\"model\":\"lumped\"%s}]}",
             bodies_extra0, bodies_extra1, mesh_extra);
    gs_scene *s = NULL;
    gs_diag d;
    gs_diag_clear(&d);
    gs_err e = gs_scene_parse(txt, strlen(txt), &s, &d);
    if (!field) {
        if (e != GS_OK)
            print_error("%s: %s\n", d.field, d.message);
        assert_int_equal(e, GS_OK);
        gs_scene_free(&s);
        return;
    }
    print_message("# refused: %s: %s\n", d.field, d.message);
    assert_int_not_equal(e, GS_OK);
    assert_string_equal(d.field, field);
    gs_scene_free(&s);
}

static void bad_input(void **state)
{
    (void)state;
#define R ",\"helix_angle_deg\":15,\"hand\":\"right\""
#define L ",\"helix_angle_deg\":15,\"hand\":\"left\""
    parse_fails(R, L, "", NULL);
    parse_fails(",\"helix_angle_deg\":50,\"hand\":\"right\"", L, "", "bodies[0].helix_angle_deg");
    parse_fails(",\"helix_angle_deg\":-1,\"hand\":\"right\"", L, "", "bodies[0].helix_angle_deg");
    parse_fails(",\"helix_angle_deg\":15", L, "", "bodies[0].hand");
    parse_fails(",\"hand\":\"right\"", "", "", "bodies[0].hand");
    parse_fails(R, ",\"helix_angle_deg\":15,\"hand\":\"up\"", "", "bodies[1].hand");
    parse_fails(R, R, "", "meshes[0].gears");
    parse_fails(R, ",\"helix_angle_deg\":16,\"hand\":\"left\"", "", "meshes[0].gears");
    parse_fails(R, ",\"helix_angle_deg\":15,\"hand\":\"left\",\"model\":\"elastic\"", "", "bodies[1].helix_angle_deg");
    parse_fails(R ",\"lead\":{\"crowning_um\":-3}", L, "", "bodies[0].lead.crowning_um");
    parse_fails(R ",\"lead\":{\"crowning_um\":3,\"tilt\":1}", L, "", "bodies[0].lead.tilt");
    parse_fails(R ",\"lead\":{\"end_relief_um\":10}", L, "", "bodies[0].lead.end_relief_length_mm");
    parse_fails(R ",\"lead\":{\"end_relief_um\":10,\"end_relief_length_mm\":20}", L, "",
                "bodies[0].lead.end_relief_length_mm");
    parse_fails(R ",\"lead\":{\"end_relief_um\":10,\"end_relief_length_mm\":5,\"end_relief_shape\":\"cubic\"}", L, "",
                "bodies[0].lead.end_relief_shape");
    parse_fails(R ",\"lead\":{\"slope_um\":2000}", L, "", "bodies[0].lead.slope_um");
    parse_fails(R, L, ",\"misalignment\":{\"in_plane_um\":5000}", "meshes[0].misalignment.in_plane_um");
    parse_fails(R, L, ",\"misalignment\":{\"sideways_um\":5}", "meshes[0].misalignment.sideways_um");
#undef R
#undef L
    /* valid lead and misalignment are parsed and stored */
    const char *txt =
        "{\"name\":\"h\",\"bodies\":[{\"name\":\"p\",\"teeth\":20,\"module_mm\":2.5,\"face_width_mm\":30,"
        "\"helix_angle_deg\":15,\"hand\":\"right\",\"lead\":{\"crowning_um\":8,\"end_relief_um\":6,"
        "\"end_relief_length_mm\":4,\"end_relief_shape\":\"parabolic\",\"slope_um\":-5}},"
        "{\"name\":\"w\",\"teeth\":30,\"module_mm\":2.5,\"face_width_mm\":30,\"helix_angle_deg\":15,\"hand\":\"left\"}],"
        "\"joints\":[{\"body\":\"p\",\"type\":\"fixed_axis\",\"centre_mm\":[0,0]},"
        "{\"body\":\"w\",\"type\":\"fixed_axis\",\"centre_mm\":[64.71,0]}],"
        "\"meshes\":[{\"name\":\"m\",\"gears\":[\"p\",\"w\"],\"model\":\"lumped\","
        "\"misalignment\":{\"in_plane_um\":20,\"out_of_plane_um\":-10}}]}";
    gs_scene *s = NULL;
    gs_diag d;
    assert_int_equal(gs_scene_parse(txt, strlen(txt), &s, &d), GS_OK);
    const gs_lead_mods *l = &s->bodies[0].lead;
    assert_true(fabs(l->crowning - 8e-6) < 1e-18 && fabs(l->end_relief - 6e-6) < 1e-18);
    assert_true(fabs(l->end_relief_length - 4e-3) < 1e-18 && l->end_relief_parabolic == 1);
    assert_true(fabs(l->slope + 5e-6) < 1e-18);
    assert_true(fabs(s->meshes[0].misalign_in - 20e-6) < 1e-18 && fabs(s->meshes[0].misalign_out + 10e-6) < 1e-18);
    assert_true(fabs(s->bodies[0].gear.normal_module_m - 2.5e-3) < 1e-18);
    assert_int_equal(s->bodies[0].gear.hand, 1);
    assert_int_equal(s->bodies[1].gear.hand, -1);
    gs_scene_free(&s);
}

/* The plane state of a gear's section: a helical gear whose face is at least
 * GS_HELICAL_STRAIN_FACE normal modules wide defaults to plane strain, a
 * narrower one and a spur gear to plane stress; material.plane overrides. */
static gs_plane plane_of(double beta_deg, double face_mm, const char *material)
{
    char txt[2048];
    const char *hand0 = beta_deg > 0 ? ",\"hand\":\"right\"" : "", *hand1 = beta_deg > 0 ? ",\"hand\":\"left\"" : "";
    snprintf(txt, sizeof txt,
             "{\"name\":\"h\",\"bodies\":["
             "{\"name\":\"p\",\"teeth\":20,\"module_mm\":2.5,\"face_width_mm\":%.17g,\"helix_angle_deg\":%g%s%s},"
             "{\"name\":\"w\",\"teeth\":30,\"module_mm\":2.5,\"face_width_mm\":%.17g,\"helix_angle_deg\":%g%s}],"
             "\"joints\":[{\"body\":\"p\",\"type\":\"fixed_axis\",\"centre_mm\":[0,0]},"
             "{\"body\":\"w\",\"type\":\"fixed_axis\",\"centre_mm\":[%.17g,0]}],"
             "\"meshes\":[{\"name\":\"m\",\"gears\":[\"p\",\"w\"],\"model\":\"lumped\"}]}",
             face_mm, beta_deg, hand0, material, face_mm, beta_deg, hand1,
             62.5 / cos(beta_deg * DEG) + 0.005);
    gs_scene *s = NULL;
    gs_diag d;
    gs_diag_clear(&d);
    if (gs_scene_parse(txt, strlen(txt), &s, &d) != GS_OK)
        fail_msg("%s: %s", d.field, d.message);
    gs_plane pl = s->bodies[0].material.plane;
    /* the wheel never gives a material: the rule alone */
    gs_plane pw = s->bodies[1].material.plane;
    gs_scene_free(&s);
    if (!material[0])
        assert_int_equal(pl, pw);
    return pl;
}

static void plane_default(void **state)
{
    (void)state;
    double edge = GS_HELICAL_STRAIN_FACE * 2.5; /* mm, m_n 2.5 */
    assert_int_equal(plane_of(15, edge, ""), GS_PLANE_STRAIN);
    assert_int_equal(plane_of(15, 30, ""), GS_PLANE_STRAIN);
    assert_int_equal(plane_of(15, edge * 0.99, ""), GS_PLANE_STRESS);
    assert_int_equal(plane_of(15, 5, ""), GS_PLANE_STRESS);
    assert_int_equal(plane_of(0, 30, ""), GS_PLANE_STRESS); /* spur: unchanged */
    assert_int_equal(plane_of(15, 30, ",\"material\":{\"plane\":\"stress\"}"), GS_PLANE_STRESS);
    assert_int_equal(plane_of(15, 30, ",\"material\":{\"E\":2e11}"), GS_PLANE_STRAIN);
    assert_int_equal(plane_of(15, 5, ",\"material\":{\"plane\":\"strain\"}"), GS_PLANE_STRAIN);
    assert_int_equal(plane_of(0, 30, ",\"material\":{\"plane\":\"strain\"}"), GS_PLANE_STRAIN);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(transverse_involute),
        cmocka_unit_test(contact_ratios),
        cmocka_unit_test(bad_input),
        cmocka_unit_test(plane_default),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
