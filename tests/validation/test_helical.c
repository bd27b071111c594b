/* SPDX-License-Identifier: MIT
 * Helical pairs in the planar mesh models (docs/explanation/helical.md):
 *  - the lumped and compliant meshes of the helical_pair scene, driven and
 *    braked: energy balance E - E0 - W_in + D at round-off, the speed ratio
 *    and the steady speed of the closed form;
 *  - the helical planetary scene: energy balance and the sun/carrier ratio;
 *  - the contact mesh refuses a helical pair naming
 *    bodies[i].helix_angle_deg, the ltca mesh a helical gear's run-out; lead modifications and misalignment are
 *    refused by the planar models naming the field; the quasi-static
 *    analysis takes the pair through its slice analysis (its figures:
 *    tests/validation/test_helical_slices.py). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include <json-c/json.h>

#include "gearsim/geometry.h"
#include "gearsim/step.h"
#include "gearsim/stiffness.h"
#include "scene_build.h"

static json_object *mesh0(json_object *root)
{
    return json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
}

static json_object *body(json_object *root, int i)
{
    return json_object_array_get_idx(json_object_object_get(root, "bodies"), (size_t)i);
}

/* Drive and brake for `steps` steps; over the second half the speed ratio
 * of bodies `in` and `out` and the mean speed of `out`. Energy balance
 * checked at every step; returns the worst residual over the energy scale. */
static double run_balance(json_object *root, const char *in, const char *out, int steps, double *ratio,
                          double *speed)
{
    gs_system *s = vt_system(root);
    for (int i = 0; i < s->scene->n_meshes; i++)
        assert_true(s->meshes[i].overlap_ratio > 0.87);
    int bi = gs_scene_find_body(s->scene, in), bo = gs_scene_find_body(s->scene, out), half = steps / 2;
    double worst = 0, scale = 0, th_i = 0, th_o = 0;
    gs_energy e;
    for (int i = 0; i < steps; i++) {
        if (i == half) {
            th_i = gs_system_angle(s, bi);
            th_o = gs_system_angle(s, bo);
        }
        vt_step_balance(s, &e, &worst, &scale);
    }
    *ratio = (gs_system_angle(s, bi) - th_i) / (gs_system_angle(s, bo) - th_o);
    *speed = fabs(gs_system_angle(s, bo) - th_o) / (half * s->h);
    print_message("#   W_in %.4f J, D %.4f J, worst |balance residual| %.3e J of the energy scale %.3e J\n", e.work_in,
                  e.dissipated, worst, scale);
    gs_system_free(&s);
    return worst / scale;
}

/* The pair for 0.2 s: balance, ratio -z2/z1 and the closed-form steady
 * wheel speed M0 (z2/z1) / c = 100 rad/s. */
static void pair_balance(json_object *root, const char *what)
{
    double ratio, wspeed, rel = run_balance(root, "pinion", "wheel", 20000, &ratio, &wspeed);
    print_message("# helical %s pair, 0.2 s: balance residual %.3e of the energy scale; speed ratio %.9f (expect "
                  "-1.5), wheel speed %.5f rad/s (closed form 100)\n",
                  what, rel, ratio, wspeed);
    assert_true(rel < 1e-11);
    assert_true(fabs(ratio / -1.5 - 1) < 1e-4);
    assert_true(fabs(wspeed / 100.0 - 1) < 1e-3);
}

static void lumped_balance(void **state)
{
    (void)state;
    pair_balance(vt_scene("helical_pair"), "lumped");
}

static void compliant_balance(void **state)
{
    (void)state;
    json_object *root = vt_scene("helical_pair");
    json_object *m = mesh0(root);
    json_object_object_del(m, "stiffness");
    json_object_object_add(m, "model", json_object_new_string("compliant"));
    pair_balance(root, "compliant");
}

/* The helical planetary scene (lumped meshes): energy balance and the
 * kinematic ratio sun / carrier = 1 + z_ring / z_sun = 4. */
static void planetary_balance(void **state)
{
    (void)state;
    double ratio, speed, rel = run_balance(vt_scene("helical_planetary"), "sun", "carrier", 10000, &ratio, &speed);
    print_message("# helical planetary, 0.1 s: balance residual %.3e of the energy scale; sun/carrier ratio %.9f "
                  "(expect 4)\n",
                  rel, ratio);
    assert_true(rel < 1e-11);
    assert_true(fabs(ratio / 4.0 - 1) < 1e-4);
}

static const char *fails(json_object *root, gs_diag *d)
{
    gs_scene *sc = vt_scene_parse(root);
    gs_system *s = NULL;
    gs_err e = gs_system_new(sc, 0, 1, &s, d);
    if (e == GS_OK) {
        gs_system_free(&s);
        return NULL;
    }
    print_message("# refused: %s: %s\n", d->field, d->message);
    return d->field;
}

static void expect_refused(json_object *root, const char *field, gs_diag *d)
{
    const char *f = fails(root, d);
    assert_non_null(f);
    assert_string_equal(f, field);
}

static void refusals(void **state)
{
    (void)state;
    gs_diag d;
    json_object *root = vt_scene("helical_pair");
    json_object *m = mesh0(root);
    json_object_object_del(m, "stiffness");
    json_object_object_del(m, "damping_ratio");
    json_object_object_del(m, "backlash_mm");
    json_object_object_add(m, "model", json_object_new_string("contact"));
    expect_refused(root, "bodies[0].helix_angle_deg", &d);
    assert_non_null(strstr(d.message, "contact mesh"));

    root = vt_scene("helical_pair");
    m = mesh0(root);
    json_object_object_del(m, "stiffness");
    json_object_object_del(m, "backlash_mm");
    json_object_object_add(m, "model", json_object_new_string("ltca"));
    json_object *ro = json_object_new_object(); /* ltca takes the pair, not its run-out */
    json_object_object_add(ro, "eccentricity_um", json_object_new_double(5));
    json_object_object_add(ro, "phase_deg", json_object_new_double(0));
    json_object_object_add(body(root, 0), "runout", ro);
    expect_refused(root, "bodies[0].runout", &d);

    root = vt_scene("helical_pair");
    json_object *lead = json_object_new_object();
    json_object_object_add(lead, "crowning_um", json_object_new_double(10));
    json_object_object_add(body(root, 1), "lead", lead);
    expect_refused(root, "bodies[1].lead", &d);

    root = vt_scene("helical_pair");
    json_object *mis = json_object_new_object();
    json_object_object_add(mis, "in_plane_um", json_object_new_double(20));
    json_object_object_add(mesh0(root), "misalignment", mis);
    expect_refused(root, "meshes[0].misalignment", &d);

    root = vt_scene("helical_pair");
    json_object *st = json_object_new_object();
    json_object_object_add(st, "type", json_object_new_string("calibrated"));
    json_object_object_add(mesh0(root), "stiffness", st);
    expect_refused(root, "meshes[0].stiffness.type", &d);

    /* the quasi-static analysis (stiffness command): by slices, and it
     * names its own limits */
    gs_scene *sc = vt_scene_parse(vt_scene("helical_pair"));
    gs_stiffness_result r;
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    o.positions = 4;
    assert_int_not_equal(gs_stiffness_analyse(sc, 0, &o, &r, &d), GS_OK);
    print_message("# refused: %s: %s\n", d.field, d.message);
    assert_string_equal(d.field, "positions");
    o.positions = 8;
    o.tangent = 0;
    o.slices = 20;
    assert_int_equal(gs_stiffness_analyse(sc, 0, &o, &r, &d), GS_OK);
    assert_int_equal(r.slices, 20);
    assert_true(fabs(r.overlap_ratio - 0.988616) < 1e-5);
    assert_true(r.k_min > 0.0 && r.k_max / r.k_min < 1.05);
    gs_stiffness_result_clear(&r);
    gs_scene_free(&sc);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(lumped_balance),
        cmocka_unit_test(compliant_balance),
        cmocka_unit_test(planetary_balance),
        cmocka_unit_test(refusals),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
