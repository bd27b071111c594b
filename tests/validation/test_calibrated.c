/* SPDX-License-Identifier: MIT
 * The lumped mesh model calibrated from the FE model (`stiffness:
 * {type: "calibrated"}`): its stiffness over the mesh cycle comes from the
 * quasi-static FE contact analysis of the same pair (docs/STIFFNESS.md).
 * On the moment-induced 30/20 pair (contact_drive) the calibrated lumped run
 * (rigid gears) is compared with the FE contact run (elastic gears):
 *  - both reach the closed-form steady speed M0 (z2/z1) / c (1%);
 *  - the mean line-of-action deflection of the lumped run (its dynamic
 *    transmission error at this load) agrees with the FE quasi-static
 *    transmission error at the same load within 10%;
 *  - the balance residual of the lumped run stays at round-off through the
 *    tabulated stiffness (discrete gradient);
 * and the wall-time ratio of the two runs is printed (not asserted: speed is
 * the benchmarks' business). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include <json-c/json.h>

#include "gearsim/stiffness.h"
#include "gearsim/step.h"
#include "gearsim/util.h"
#include "scene_build.h"

typedef struct run_out {
    double speed, defl, residual, scale, wall;
} run_out;

static run_out run(gs_system *s, int n, int tail)
{
    int p = gs_scene_find_body(s->scene, "pinion");
    double th = 0, defl = 0, worst = 0, scale = 0;
    gs_energy e;
    double t0 = gs_now();
    for (int i = 0; i < n; i++) {
        if (i == n - tail)
            th = gs_system_angle(s, p);
        assert_int_equal(gs_step_serial(s), GS_OK);
        gs_system_energy(s, &e);
        worst = fmax(worst, fabs(e.balance_residual));
        scale = fmax(scale, fmax(e.total, fmax(e.work_in, e.dissipated)));
        if (i >= n - tail)
            defl += s->meshes[0].deflection;
    }
    run_out r = {-(gs_system_angle(s, p) - th) / (tail * s->h), defl / tail, worst, scale, gs_now() - t0};
    return r;
}

static void calibrated_against_fe(void **state)
{
    (void)state;
    const int n = 6000, tail = 3000;
    /* The lumped, calibrated pair: the same scene at fidelity "lumped", the
     * mesh's stiffness from the FE analysis, no backlash (the FE transmission
     * error is measured from the contact-just-closing position). */
    json_object *root = vt_scene("contact_drive");
    json_object_object_add(root, "fidelity", json_object_new_string("lumped"));
    json_object *tree = NULL;
    json_object_deep_copy(root, &tree, NULL);
    json_object_put(root);
    json_object *bs = json_object_object_get(tree, "bodies");
    for (size_t i = 0; i < json_object_array_length(bs); i++)
        json_object_object_add(json_object_array_get_idx(bs, i), "model", json_object_new_string("rigid"));
    json_object_object_del(tree, "fidelity");
    json_object *m = json_object_array_get_idx(json_object_object_get(tree, "meshes"), 0);
    json_object_object_add(m, "model", json_object_new_string("lumped"));
    json_object *st = json_object_new_object();
    json_object_object_add(st, "type", json_object_new_string("calibrated"));
    json_object_object_add(st, "positions", json_object_new_int(24));
    json_object_object_add(m, "stiffness", st);
    gs_system *lum = vt_system(tree);
    const gs_gmesh_rt *gm = &lum->meshes[0];
    double kmin = 1e300, kmax = 0, kmean = 0;
    for (int j = 0; j < gm->n_table; j++) {
        kmin = fmin(kmin, gm->k_table[j]);
        kmax = fmax(kmax, gm->k_table[j]);
        kmean += gm->k_table[j] / gm->n_table;
    }
    print_message("calibrated stiffness: %d positions, min/mean/max %.4g / %.4g / %.4g N/m\n", gm->n_table, kmin,
                  kmean, kmax);
    assert_int_equal(gm->n_table, 24);
    assert_true(kmax > kmin); /* it follows the single/double-tooth cycle */

    /* The FE quasi-static transmission error at the steady load: the brake
     * moment c w2 on the driven gear, i.e. M0 on the driver. */
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    o.positions = 24;
    o.tangent = 0;
    o.torque_nm = 20.0;
    gs_stiffness_result sr;
    gs_diag d;
    gs_system *fe = vt_system(vt_scene("contact_drive"));
    assert_int_equal(gs_stiffness_analyse(fe->scene, 0, &o, &sr, &d), GS_OK);
    double te = sr.te_mean * 1e-6;
    gs_stiffness_result_clear(&sr);

    run_out a = run(lum, n, tail);
    run_out b = run(fe, n, tail);
    double expect = 20.0 * (20.0 / 30.0) / 0.3;
    print_message("lumped calibrated: speed %.5f rad/s (%.2e), mean deflection %.4e m, balance %.2e of %.2e J, "
                  "wall %.3f s\n", a.speed, a.speed / expect - 1, a.defl, a.residual, a.scale, a.wall);
    print_message("FE contact:        speed %.5f rad/s (%.2e), FE quasi-static TE at 20 N m %.4e m, wall %.3f s\n",
                  b.speed, b.speed / expect - 1, te, b.wall);
    print_message("mean dynamic TE of the calibrated lumped run vs FE static TE: %+.2f%%; wall-time ratio FE / "
                  "lumped %.0f\n", 100 * (fabs(a.defl) / te - 1), b.wall / a.wall);
    assert_true(fabs(a.speed / expect - 1) < 1e-2);
    assert_true(fabs(b.speed / expect - 1) < 1e-2);
    assert_true(a.residual < 1e-11 * a.scale);
    assert_true(fabs(fabs(a.defl) / te - 1) < 0.10);
    gs_system_free(&lum);
    gs_system_free(&fe);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(calibrated_against_fe),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
