/* SPDX-License-Identifier: MIT
 * Validation of the rigid end of the fidelity ladder against closed forms
 * and conservation laws (METHOD.md section 8):
 *  - kinematic planetary train: sun/carrier ratio 1 + z_ring/z_sun to 1e-12;
 *  - pair driven by M0 and braked by -c w2 settles at w2 = M0 (z2/z1)/c (0.5%);
 *  - lumped meshes (stiffness jumps, backlash, damping, moments, brake):
 *    balance residual below 1e-9 of the energy scale over 1e5 steps;
 *  - free lumped train without damping: energy constant to round-off,
 *    through thousands of single/double-tooth stiffness jumps. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include <json-c/json.h>

#include "gearsim/step.h"
#include "scene_build.h"

/* Load a builtin scene, edit it with a callback, build the system. */
static gs_system *build(const char *builtin, void (*edit)(json_object *))
{
    json_object *root = vt_scene(builtin);
    if (edit)
        edit(root);
    return vt_system(root);
}

static void set_mesh_model(json_object *root, const char *model)
{
    json_object *ms = json_object_object_get(root, "meshes");
    for (size_t i = 0; i < json_object_array_length(ms); i++) {
        json_object *m = json_object_array_get_idx(ms, i);
        json_object_object_del(m, "stiffness");
        json_object_object_del(m, "damping_ratio");
        json_object_object_del(m, "backlash_mm");
        json_object_object_add(m, "model", json_object_new_string(model));
    }
}

static void kinematic(json_object *root) { set_mesh_model(root, "kinematic"); }

static int body(const gs_system *s, const char *name)
{
    return gs_scene_find_body(s->scene, name);
}

static void planetary_kinematic_ratio(void **state)
{
    (void)state;
    gs_system *s = build("planetary", kinematic);
    int sun = body(s, "sun"), car = body(s, "carrier");
    double expect = 1.0 + 72.0 / 24.0, worst = 0;
    for (int i = 0; i < 20000; i++) {
        assert_int_equal(gs_step_serial(s), GS_OK);
        double ws = gs_system_omega(s, sun), wc = gs_system_omega(s, car);
        if (fabs(wc) > 1e-9)
            worst = fmax(worst, fabs(ws / wc / expect - 1));
    }
    double ratio = gs_system_angle(s, sun) / gs_system_angle(s, car);
    print_message("kinematic planetary: sun/carrier speed ratio worst rel. error %.3e, angle ratio %.15f (expect %.15f)\n",
                  worst, ratio, expect);
    /* The constraint rows hold exactly up to the KKT solve's round-off. */
    assert_true(worst < 1e-12);
    assert_true(fabs(ratio / expect - 1) < 1e-12);
    gs_energy e;
    gs_system_energy(s, &e);
    print_message("kinematic planetary: balance residual %.3e J of %.3e J in\n", e.balance_residual, e.work_in);
    assert_true(fabs(e.balance_residual) < 1e-9 * e.work_in);
    gs_system_free(&s);
}

static void pair_steady_speed(void **state)
{
    (void)state;
    gs_system *s = build("pair", NULL);
    int wheel = body(s, "wheel");
    double M0 = 20.0, c = 0.3, z1 = 20, z2 = 30;
    double expect = M0 * (z2 / z1) / c;
    /* 0.15 s: the ramp ends at 0.02 s and the brake's time constant
     * J/c is about 1.2 ms, so the last 0.05 s is deep in steady state. */
    int n = (int)lround(0.15 / s->h), from = (int)lround(0.10 / s->h);
    double sum = 0;
    int cnt = 0;
    for (int i = 0; i < n; i++) {
        assert_int_equal(gs_step_serial(s), GS_OK);
        if (i >= from) {
            sum += gs_system_omega(s, wheel);
            cnt++;
        }
    }
    double mean = fabs(sum / cnt);
    print_message("pair: steady wheel speed %.6f rad/s, analytic M0 (z2/z1)/c = %.6f, rel. error %.2e\n",
                  mean, expect, mean / expect - 1);
    assert_true(fabs(mean / expect - 1) < 0.005);
    gs_system_free(&s);
}

static void planetary_lumped_balance(void **state)
{
    (void)state;
    gs_system *s = build("planetary", NULL);
    int n = 100000;
    double worst = 0;
    for (int i = 0; i < n; i++) {
        assert_int_equal(gs_step_serial(s), GS_OK);
        if (i % 100 == 99) {
            gs_energy e;
            gs_system_energy(s, &e);
            double scale = fmax(fabs(e.total), fmax(e.work_in, e.dissipated));
            worst = fmax(worst, fabs(e.balance_residual) / scale);
        }
    }
    gs_energy e;
    gs_system_energy(s, &e);
    int sun = body(s, "sun"), car = body(s, "carrier");
    double ratio = gs_system_angle(s, sun) / gs_system_angle(s, car);
    print_message("lumped planetary, 1e5 steps: worst |balance residual| / energy scale = %.3e "
                  "(E = %.4f J, W_in = %.4f J, D = %.4f J); mean speed ratio %.6f (kinematic 4)\n",
                  worst, e.total, e.work_in, e.dissipated, ratio);
    assert_true(worst < 1e-9);
    /* Elastic mesh deflection is tiny next to the rotation: ratio within 0.1%. */
    assert_true(fabs(ratio / 4.0 - 1) < 1e-3);
    gs_system_free(&s);
}

static void free_undamped(json_object *root)
{
    json_object *ms = json_object_object_get(root, "meshes");
    for (size_t i = 0; i < json_object_array_length(ms); i++) {
        json_object *m = json_object_array_get_idx(ms, i);
        json_object_object_del(m, "damping_ratio");
        json_object_object_add(m, "damping", json_object_new_double(0.0));
        json_object_object_add(m, "backlash_mm", json_object_new_double(0.02));
    }
    json_object_object_add(root, "loads", json_object_new_array());
    json_object *ini = json_object_new_object(), *p = json_object_new_object(), *w = json_object_new_object();
    json_object_object_add(p, "omega", json_object_new_double(150.0));
    json_object_object_add(w, "omega", json_object_new_double(-90.0));
    json_object_object_add(ini, "pinion", p);
    json_object_object_add(ini, "wheel", w);
    json_object_object_add(root, "initial", ini);
}

static void pair_free_energy_conserved(void **state)
{
    (void)state;
    gs_system *s = build("pair", free_undamped);
    gs_energy e0;
    gs_system_energy(s, &e0);
    double worst = 0, maxV = 0;
    for (int i = 0; i < 10000; i++) {
        assert_int_equal(gs_step_serial(s), GS_OK);
        gs_energy e;
        gs_system_energy(s, &e);
        worst = fmax(worst, fabs(e.total - e0.total) / e0.total);
        maxV = fmax(maxV, e.potential);
    }
    int pin = body(s, "pinion");
    double cycles = fabs(gs_system_angle(s, pin)) * 20 / (2 * GS_PI);
    print_message("free undamped pair with backlash: %.0f mesh cycles (2 stiffness jumps each), "
                  "max mesh energy %.3e J, relative energy drift %.3e\n", cycles, maxV, worst);
    /* Discrete gradient: exact up to the Newton tolerance and round-off. */
    assert_true(maxV > 1e-6 * e0.total);
    assert_true(worst < 1e-11);
    gs_system_free(&s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(planetary_kinematic_ratio),
        cmocka_unit_test(pair_steady_speed),
        cmocka_unit_test(planetary_lumped_balance),
        cmocka_unit_test(pair_free_energy_conserved),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
