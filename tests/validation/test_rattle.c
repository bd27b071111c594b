/* SPDX-License-Identifier: MIT
 * Validation of the impact mesh (rigid gears with backlash and impacts,
 * METHOD.md sections 6 and 7, rung 2; docs/explanation/impact.md, "The impact mesh"):
 *  - the builtin `rattle` scene rattles: more than 10 impacts in 0.2 s,
 *    their loss counted, the teeth never inside each other (1e-9 of the
 *    half backlash), and the energy
 *    balance E - E0 - W_in + D at round-off (1e-11 of the energy scale)
 *    with the impact losses in D;
 *  - e = 1 without loads: kinetic energy constant through the impacts
 *    (1e-12 relative);
 *  - sustained contact under a steady load (the `pair` scene): no chatter,
 *    steady wheel speed in closed form (1e-9);
 *  - one impact of a spinning pinion on a wheel at rest: final speeds and
 *    loss from e and W = rb1^2/I1 + rb2^2/I2 in closed form (1e-12), for
 *    each restitution hypothesis;
 *  - scene checks: default backlash from tooth thinning, refused fields,
 *    elastic gears refused. */
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
#include "scene_build.h"

static json_object *mesh0(json_object *root)
{
    return json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
}

/* The rattle pair without loads, pinion at w1, wheel at w2, restitution e. */
static gs_system *free_pair(double w1, double w2, double e, const char *law)
{
    json_object *root = vt_scene("rattle");
    json_object_object_del(root, "loads");
    json_object *m = mesh0(root);
    json_object_object_add(m, "restitution", json_object_new_double(e));
    json_object_object_add(m, "law", json_object_new_string(law));
    json_object *init = json_object_new_object(), *p = json_object_new_object(), *w = json_object_new_object();
    json_object_object_add(p, "omega", json_object_new_double(w1));
    json_object_object_add(w, "omega", json_object_new_double(w2));
    json_object_object_add(init, "pinion", p);
    json_object_object_add(init, "wheel", w);
    json_object_object_add(root, "initial", init);
    return vt_system(root);
}

static void rattle_scene(void **state)
{
    (void)state;
    gs_system *s = vt_system(vt_scene("rattle"));
    gs_gmesh_rt *m = &s->meshes[0];
    assert_string_equal(m->ops->name, "impact");
    double hb = m->half_backlash, worst_pen = 0, worst_res = 0, scale = 0;
    int steps = 20000;
    gs_energy e;
    for (int i = 0; i < steps; i++) {
        assert_int_equal(gs_step_serial(s), GS_OK);
        worst_pen = fmax(worst_pen, fabs(m->deflection) - hb);
        gs_system_energy(s, &e);
        scale = fmax(scale, fmax(e.work_in, fmax(e.dissipated, e.kinetic)));
        worst_res = fmax(worst_res, fabs(e.balance_residual));
    }
    print_message("rattle: %lld impacts in %.3f s, impact loss %.6e J of %.6e J dissipated, "
                  "%.6e J in, kinetic %.6e J\n", (long long)m->impacts, s->time, m->impact_loss,
                  e.dissipated, e.work_in, e.kinetic);
    print_message("rattle: worst balance residual %.3e J (%.3e of the energy scale %.3e J), "
                  "worst penetration %.3e m of half backlash %.3e m\n",
                  worst_res, worst_res / scale, scale, worst_pen, hb);
    assert_true(m->impacts > 10);
    assert_true(m->impact_loss > 0 && m->impact_loss < e.dissipated);
    /* The position projection keeps the teeth on the flank to the
     * round-off of s = a . q (q reaches tens of rad: ~1e-16 m). */
    assert_true(worst_pen < 1e-9 * hb);
    assert_true(worst_res < 1e-11 * scale);
    gs_system_free(&s);
}

static void elastic_bounce_conserves(void **state)
{
    (void)state;
    gs_system *s = free_pair(12.0, 3.5, 1.0, "stronge");
    gs_gmesh_rt *m = &s->meshes[0];
    gs_energy e;
    gs_system_energy(s, &e);
    double T0 = e.kinetic, worst = 0;
    for (int i = 0; i < 20000; i++) {
        assert_int_equal(gs_step_serial(s), GS_OK);
        gs_system_energy(s, &e);
        worst = fmax(worst, fabs(e.kinetic / T0 - 1));
    }
    print_message("e = 1, no loads: %lld impacts, kinetic energy %.15e J (start %.15e J), worst rel. "
                  "change %.3e, loss booked %.3e J, residual %.3e J\n", (long long)m->impacts, e.kinetic,
                  T0, worst, m->impact_loss, e.balance_residual);
    assert_true(m->impacts > 10);
    assert_true(worst < 1e-12);
    assert_true(fabs(m->impact_loss) < 1e-12 * T0);
    assert_true(fabs(e.balance_residual) < 1e-12 * T0);
    gs_system_free(&s);
}

/* Sustained contact: the `pair` scene (ramp moment M0 on the pinion,
 * brake c on the wheel) with an impact mesh, e = 0.7. After the first
 * impacts the teeth stay on the drive flank: no chatter (no new impacts
 * once settled), and each step is the kinematic mesh's step with a plastic
 * impulse. Steady state: the free step changes the braked wheel's speed by
 * -2 c h w2 / (2 I2 + c h), the impulse along u = (rb1/I1, rb2/I2) restores
 * it, so |w2| = (M0 / c) (z2 / z1) (1 + c h / (2 I2)): the kinematic
 * steady speed with an O(h) bias from the implicit brake. */
static void sustained_contact(void **state)
{
    (void)state;
    json_object *root = vt_scene("pair");
    json_object *m = mesh0(root);
    json_object_object_del(m, "stiffness");
    json_object_object_del(m, "damping_ratio");
    json_object_object_add(m, "model", json_object_new_string("impact"));
    json_object_object_add(m, "backlash_mm", json_object_new_double(0.1));
    json_object_object_add(m, "restitution", json_object_new_double(0.7));
    gs_system *s = vt_system(root);
    gs_gmesh_rt *g = &s->meshes[0];
    int w = gs_scene_find_body(s->scene, "wheel");
    double M0 = 20.0, c = 0.3, I2 = s->bodies[w].inertia_eff, h = s->h;
    int64_t settled = -1;
    for (int i = 0; i < 100000; i++) {
        assert_int_equal(gs_step_serial(s), GS_OK);
        if (i == 50000)
            settled = g->impacts;
    }
    double w2 = fabs(gs_system_omega(s, w)), expect = M0 / c * 1.5 * (1 + c * h / (2 * I2));
    gs_energy e;
    gs_system_energy(s, &e);
    double scale = fmax(e.work_in, e.dissipated);
    print_message("sustained contact: %lld impacts, %lld of them by t = 0.5 s, deflection %.6e m "
                  "(half backlash %.6e m); wheel %.12f rad/s, closed form %.12f (kinematic %.6f), rel. error "
                  "%.2e; residual %.2e of %.3e J\n", (long long)g->impacts, (long long)settled, g->deflection, g->half_backlash, w2, expect, M0 / c * 1.5,
                  fabs(w2 / expect - 1), fabs(e.balance_residual) / scale, scale);
    assert_true(g->impacts > 0);
    assert_true(g->impacts == settled);
    assert_true(fabs(g->deflection - g->half_backlash) < 1e-9 * g->half_backlash);
    assert_true(fabs(w2 / expect - 1) < 1e-9);
    assert_true(fabs(e.balance_residual) < 1e-11 * scale);
    gs_system_free(&s);
}

/* One impact: pinion at w0, wheel at rest. Along the line of action
 * v = rb1 w0 (approach), P = (1 + e) v / W, W = rb1^2/I1 + rb2^2/I2, so
 *   w1 = w0 - (1 + e) rb1^2 w0 / (I1 W),   w2 = -(1 + e) rb1 rb2 w0 / (I2 W),
 * loss (1 - e^2) v^2 / (2 W). */
static void one_impact_closed_form(void **state)
{
    (void)state;
    const char *laws[] = {"newton", "poisson", "stronge"};
    const double es[] = {0.0, 0.35, 0.8, 1.0};
    double worst = 0;
    for (int l = 0; l < 3; l++)
        for (int k = 0; k < 4; k++) {
            double w0 = 50.0, ee = es[k];
            gs_system *s = free_pair(w0, 0.0, ee, laws[l]);
            gs_gmesh_rt *m = &s->meshes[0];
            int p = gs_scene_find_body(s->scene, "pinion"), w = gs_scene_find_body(s->scene, "wheel");
            double I1 = s->bodies[p].inertia_eff, I2 = s->bodies[w].inertia_eff;
            double rb1 = gs_gear_base_radius(&s->scene->bodies[p].gear);
            double rb2 = gs_gear_base_radius(&s->scene->bodies[w].gear);
            double W = rb1 * rb1 / I1 + rb2 * rb2 / I2, v = rb1 * w0;
            double T0 = 0.5 * I1 * w0 * w0;
            int steps = 0;
            while (m->impacts == 0 && steps < 100000) {
                assert_int_equal(gs_step_serial(s), GS_OK);
                steps++;
            }
            assert_int_equal(m->impacts, 1);
            double w1x = w0 - (1 + ee) * rb1 * rb1 * w0 / (I1 * W);
            double w2x = -(1 + ee) * rb1 * rb2 * w0 / (I2 * W);
            double lossx = (1 - ee * ee) * 0.5 * v * v / W;
            double w1 = gs_system_omega(s, p), w2 = gs_system_omega(s, w);
            double e1 = fabs(w1 - w1x) / w0, e2 = fabs(w2 - w2x) / w0;
            double el = fabs(m->impact_loss - lossx) / T0;
            gs_energy en;
            gs_system_energy(s, &en);
            double er = fabs(en.balance_residual) / T0;
            print_message("one impact, %-7s e = %.2f after %5d steps: w1 %+.15f (closed form %+.15f), "
                          "w2 %+.15f (%+.15f), loss %.12e J (%.12e J), residual %.1e\n", laws[l], ee,
                          steps, w1, w1x, w2, w2x, m->impact_loss, lossx, er);
            worst = fmax(worst, fmax(fmax(e1, e2), fmax(el, er)));
            gs_system_free(&s);
        }
    print_message("one impact: worst relative error %.3e (speeds / w0, loss and residual / T0)\n", worst);
    assert_true(worst < 1e-12);
}

static gs_err try_scene(json_object *root, gs_diag *d, gs_system **out)
{
    const char *txt = json_object_to_json_string(root);
    gs_scene *sc;
    *out = NULL;
    gs_err e = gs_scene_parse(txt, strlen(txt), &sc, d);
    if (e == GS_OK)
        e = gs_system_new(sc, 0, 1, out, d);
    json_object_put(root);
    return e;
}

/* The builtin scene `name` with `key` = val added to its first mesh is
 * refused, naming that field. Consumes val. */
static void mesh_field_refused(const char *name, const char *key, json_object *val)
{
    gs_diag d;
    gs_system *s;
    json_object *root = vt_scene(name);
    json_object_object_add(mesh0(root), key, val);
    assert_int_not_equal(try_scene(root, &d, &s), GS_OK);
    char field[64];
    snprintf(field, sizeof field, "meshes[0].%s", key);
    assert_string_equal(d.field, field);
}

static void scene_fields(void **state)
{
    (void)state;
    gs_diag d;
    gs_system *s;
    /* Default backlash: the pair's, from tooth thinning. */
    json_object *root = vt_scene("rattle");
    json_object_object_del(mesh0(root), "backlash_mm");
    json_object *bs = json_object_object_get(root, "bodies");
    for (size_t i = 0; i < 2; i++)
        json_object_object_add(json_object_array_get_idx(bs, i), "thinning_mm", json_object_new_double(0.05));
    assert_int_equal(try_scene(root, &d, &s), GS_OK);
    gs_pair_info info;
    assert_int_equal(gs_pair_analyse(&s->scene->bodies[0].gear, &s->scene->bodies[1].gear, 0.0625, &info, &d),
                     GS_OK);
    print_message("default backlash from thinning 0.05 mm per gear: %.6e m (pair: %.6e m)\n",
                  2 * s->meshes[0].half_backlash, info.backlash_normal);
    assert_true(info.backlash_normal > 0);
    assert_true(fabs(2 * s->meshes[0].half_backlash - info.backlash_normal) <= 1e-15);
    gs_system_free(&s);
    /* No thinning and no backlash_mm: refused, naming the field. */
    root = vt_scene("rattle");
    json_object_object_del(mesh0(root), "backlash_mm");
    assert_int_not_equal(try_scene(root, &d, &s), GS_OK);
    assert_string_equal(d.field, "meshes[0].backlash_mm");
    /* Lumped-only fields on an impact mesh, impact fields on a lumped one. */
    mesh_field_refused("rattle", "damping_ratio", json_object_new_double(0.1));
    mesh_field_refused("pair", "restitution", json_object_new_double(0.5));
    mesh_field_refused("rattle", "law", json_object_new_string("coulomb"));
    mesh_field_refused("rattle", "restitution", json_object_new_double(1.5));
    /* Elastic gears belong in contact meshes. */
    root = vt_scene("rattle");
    bs = json_object_object_get(root, "bodies");
    json_object_object_add(json_object_array_get_idx(bs, 1), "model", json_object_new_string("elastic"));
    assert_int_not_equal(try_scene(root, &d, &s), GS_OK);
    print_message("elastic gear refused: %s: %s\n", d.field, d.message);
    assert_string_equal(d.field, "meshes[0].gears");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(rattle_scene),
        cmocka_unit_test(elastic_bounce_conserves),
        cmocka_unit_test(sustained_contact),
        cmocka_unit_test(one_impact_closed_form),
        cmocka_unit_test(scene_fields),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
