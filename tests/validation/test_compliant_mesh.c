/* SPDX-License-Identifier: MIT
 * Validation of the `compliant` mesh model (rigid gears, tooth pairs through
 * the compliant contact patch model; docs/IMPACT.md "The compliant mesh"):
 *  - the `pair` scene with a compliant mesh, ramp-driven and braked, 0.2 s:
 *    energy balance E - E0 - W_in + D at round-off (1e-11 of the energy
 *    scale), mean speed ratio z2/z1 over the second half (1e-4: the mesh
 *    deflection, micrometres, against ~0.2 m rolled) and the steady wheel
 *    speed M0 (z2/z1) / c = 100 rad/s (1e-3, the mesh ripple);
 *  - free pair with backlash, no damping, no loads, the pinion thrown at a
 *    wheel at rest: total energy constant to round-off through the
 *    compliant impacts (Newton solved to 1e-16: 1e-11 of E per step, 1e-10
 *    over the 2e4 steps of continuous rattle; seen 1.7e-12 at worst, in a
 *    step where the flanks switch and Newton stops at its step floor, and
 *    2.4e-11 accumulated);
 *  - static deflection: the wheel all but held (inertia 1e9 kg m^2), a
 *    constant moment on the pinion,
 *    heavy mesh damping until it settles; the deflection against the
 *    static balance solved directly with gs_compliant_solve for each
 *    engaged pair (pair geometry from the model, bending in series), in
 *    single and double contact: within 0.5 % (the model interpolates a
 *    table of 24 loads x 25 stations; seen 0.005 % and 0.026 %);
 *  - mesh stiffness against ISO 6336: single-pair stiffness at the pitch
 *    point (c') and mean mesh stiffness over a cycle (c_gamma) per mm of
 *    face width at the scene's load, printed; the order of magnitude
 *    checked (within a factor 3 of ISO's 14 and 20 N/(mm um));
 *  - scene checks: every compliant field validated with its field named. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <json-c/json.h>

#include "gearsim/geometry.h"
#include "gearsim/impact.h"
#include "gearsim/step.h"
#include "models/compliant_mesh.h"
#include "scene_build.h"

static json_object *mesh0(json_object *root)
{
    return json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
}

/* The `pair` scene with a compliant mesh. */
static json_object *compliant_pair(void)
{
    json_object *root = vt_scene("pair");
    json_object *m = mesh0(root);
    json_object_object_del(m, "stiffness");
    json_object_object_add(m, "model", json_object_new_string("compliant"));
    return root;
}

static void driven_braked(void **state)
{
    (void)state;
    gs_system *s = vt_system(compliant_pair());
    gs_gmesh_rt *m = &s->meshes[0];
    assert_string_equal(m->ops->name, "compliant");
    int pin = gs_scene_find_body(s->scene, "pinion"), whl = gs_scene_find_body(s->scene, "wheel");
    int steps = 20000, half = steps / 2;
    double worst = 0, scale = 0, th_p = 0, th_w = 0, fmax_ = 0;
    gs_energy e;
    for (int i = 0; i < steps; i++) {
        if (i == half) {
            th_p = gs_system_angle(s, pin);
            th_w = gs_system_angle(s, whl);
        }
        assert_int_equal(gs_step_serial(s), GS_OK);
        gs_system_energy(s, &e);
        scale = fmax(scale, fmax(e.total, fmax(e.work_in, e.dissipated)));
        worst = fmax(worst, fabs(e.balance_residual));
        if (i >= half)
            fmax_ = fmax(fmax_, m->force);
    }
    double ratio = (gs_system_angle(s, pin) - th_p) / (gs_system_angle(s, whl) - th_w);
    double wspeed = fabs(gs_system_angle(s, whl) - th_w) / (half * s->h);
    print_message("compliant pair, 0.2 s: worst |balance residual| %.3e J = %.3e "
                  "of the energy scale %.3e J "
                  "(W_in %.4f J, D %.4f J)\n",
                  worst, worst / scale, scale, e.work_in, e.dissipated);
    print_message("compliant pair: mean speed ratio %.9f (expect -1.5), mean wheel speed "
                  "%.5f rad/s "
                  "(closed form 100), peak mesh force %.1f N, last deflection %.3f um\n",
                  ratio, wspeed, fmax_, m->deflection * 1e6);
    assert_true(worst < 1e-11 * scale);
    assert_true(fabs(ratio / -1.5 - 1) < 1e-4);
    assert_true(fabs(wspeed / 100.0 - 1) < 1e-3);
    gs_system_free(&s);
}

static void free_conservation(void **state)
{
    (void)state;
    json_object *root = compliant_pair();
    json_object_object_del(root, "loads");
    json_object *m = mesh0(root);
    json_object_object_del(m, "damping_ratio");
    json_object_object_add(m, "damping", json_object_new_double(0.0));
    json_object_object_add(m, "backlash_mm", json_object_new_double(0.02));
    json_object *init = json_object_new_object(), *p = json_object_new_object();
    json_object_object_add(p, "omega", json_object_new_double(20.0));
    json_object_object_add(init, "pinion", p);
    json_object_object_add(root, "initial", init);
    /* The balance is the Newton residual times dq: solve to round-off. */
    json_object_object_add(json_object_object_get(root, "numerics"), "newton_tol", json_object_new_double(1e-16));
    gs_system *s = vt_system(root);
    gs_energy e0, e;
    gs_system_energy(s, &e0);
    double worst = 0, vmax = 0;
    double prev = e0.total, step_worst = 0;
    for (int i = 0; i < 20000; i++) {
        assert_int_equal(gs_step_serial(s), GS_OK);
        gs_system_energy(s, &e);
        step_worst = fmax(step_worst, fabs(e.total - prev));
        prev = e.total;
        worst = fmax(worst, fabs(e.total - e0.total));
        vmax = fmax(vmax, e.potential);
    }
    print_message("free compliant pair with backlash, 0.2 s: |E - E0| <= %.3e of "
                  "E0 = %.6e J, per step <= %.3e; "
                  "largest mesh potential %.3e J\n",
                  worst / e0.total, e0.total, step_worst / e0.total, vmax);
    assert_true(vmax > 0.5 * e0.total); /* the teeth did meet, hard */
    assert_true(step_worst < 1e-11 * e0.total);
    assert_true(worst < 1e-10 * e0.total);
    gs_system_free(&s);
}

/* Approach of one pair carrying line load P, straight from the patch model. */
static double direct_approach(const gsi_compliant_point *pt, int patches, double P)
{
    double pr[400];
    double a = sqrt(4 * P * pt->radius / (GS_PI * pt->e_star));
    gs_compliant_problem pb = {.n = patches,
                               .x0 = -1.25 * a,
                               .x1 = 1.25 * a,
                               .radius = pt->radius,
                               .e_star = pt->e_star,
                               .load = P,
                               .datum = fmax(pt->datum, 2.5 * a)};
    gs_compliant_result r = {.pressure = pr};
    assert_int_equal(gs_compliant_solve(&pb, &r, NULL), GS_OK);
    return r.approach + P * pt->face_width / pt->k_bend;
}

/* Force of one pair at approach delta, by bisection on the line load. */
static double direct_force(const gsi_compliant_point *pt, int patches, double delta)
{
    double lo = 0, hi = 1e4 * 1e3;
    for (int it = 0; it < 60; it++) {
        double mid = 0.5 * (lo + hi);
        if (direct_approach(pt, patches, mid) < delta)
            lo = mid;
        else
            hi = mid;
    }
    return 0.5 * (lo + hi) * pt->face_width;
}

/* Static approach under total force W at phase phi (drive flank), direct. */
static double direct_static(const gs_gmesh_rt *m, double phi, double W, int patches, int *npairs)
{
    double v[8], wt[8];
    int n = gsi_compliant_pairs(m, phi, 1, v, wt, 8);
    gsi_compliant_point pt[8];
    *npairs = 0;
    for (int j = 0; j < n; j++) {
        gsi_compliant_point_at(m, v[j], &pt[j]);
        *npairs += wt[j] > 0;
    }
    double lo = 0, hi = 1e-4;
    for (int it = 0; it < 50; it++) {
        double mid = 0.5 * (lo + hi), F = 0;
        for (int j = 0; j < n; j++)
            if (wt[j] > 0)
                F += wt[j] * direct_force(&pt[j], patches, mid);
        if (F < W)
            lo = mid;
        else
            hi = mid;
    }
    return 0.5 * (lo + hi);
}

/* Same from the model's own tabulated law. */
static double model_static(const gs_gmesh_rt *m, double phi, double W)
{
    double v[8], wt[8];
    int n = gsi_compliant_pairs(m, phi, 1, v, wt, 8);
    double lo = 0, hi = 1e-4;
    for (int it = 0; it < 80; it++) {
        double mid = 0.5 * (lo + hi), F = 0;
        for (int j = 0; j < n; j++)
            F += wt[j] * gsi_compliant_pair_force(m, v[j], mid);
        if (F < W)
            lo = mid;
        else
            hi = mid;
    }
    return 0.5 * (lo + hi);
}

static void static_deflection(void **state)
{
    (void)state;
    const double M = 20.0;                 /* N m on the pinion, the `pair` scene's moment */
    const double fractions[] = {0.8, 0.3}; /* single, double contact (eps = 1.6) */
    for (int k = 0; k < 2; k++) {
        json_object *root = compliant_pair();
        json_object *m = mesh0(root);
        json_object_object_add(m, "damping_ratio", json_object_new_double(0.5));
        /* the wheel all but held: an inertia of 1e9 kg m^2 (a held joint
         * sits on the origin, for rings) */
        json_object_object_add(json_object_array_get_idx(json_object_object_get(root, "bodies"), 1), "inertia",
                               json_object_new_double(1e9));
        json_object *loads = json_object_new_array(), *l = json_object_new_object();
        json_object_object_add(l, "body", json_object_new_string("pinion"));
        json_object_object_add(l, "type", json_object_new_string("constant"));
        json_object_object_add(l, "moment", json_object_new_double(M));
        json_object_array_add(loads, l);
        json_object_object_add(root, "loads", loads);
        json_object *init = json_object_new_object(), *p = json_object_new_object();
        json_object_object_add(p, "angle", json_object_new_double(2 * GS_PI * fractions[k] / 20));
        json_object_object_add(init, "pinion", p);
        json_object_object_add(root, "initial", init);
        gs_system *s = vt_system(root);
        gs_gmesh_rt *me = &s->meshes[0];
        int pin = gs_scene_find_body(s->scene, "pinion");
        for (int i = 0; i < 4000; i++) {
            gs_err e = gs_step_serial(s);
            if (e != GS_OK)
                print_error("step %d: Newton residual %.3e after %d iterations, "
                            "deflection %.4g um\n",
                            i, s->last_residual, s->last_iterations, me->deflection * 1e6);
            assert_int_equal(e, GS_OK);
        }
        double x = me->deflection, w = gs_system_omega(s, pin);
        double rb = gs_gear_base_radius(&s->scene->bodies[pin].gear), W = M / rb;
        double phi = 0;
        for (int i = 0; i < s->n_coords; i++)
            phi += me->c[i] * s->q[i];
        gsi_compliant_info info;
        assert_true(gsi_compliant_info_get(me, &info));
        int npairs;
        double xd = direct_static(me, phi, W, info.patches, &npairs), xm = model_static(me, phi, W);
        print_message("static, phase %.3f (%d pair%s): settled deflection %.6f um "
                      "(omega %.2e rad/s, force %.3f N, "
                      "W = M/rb = %.3f N); direct patch-model balance %.6f um "
                      "(%+.3f %%); model's law %.6f um\n",
                      phi - floor(phi), npairs, npairs > 1 ? "s" : "", x * 1e6, w, me->force, W, xd * 1e6,
                      100 * (x / xd - 1), xm * 1e6);
        assert_int_equal(npairs, k == 0 ? 1 : 2);
        assert_true(fabs(w) < 1e-6);
        /* V depends on the roll too: the static moment is rb F + c dV/dphi,
         * so F differs from M / rb by that small share (seen 2e-5). */
        assert_true(fabs(me->force / W - 1) < 1e-4);
        assert_true(fabs(x / xm - 1) < 1e-4);
        assert_true(fabs(x / xd - 1) < 5e-3);
        gs_system_free(&s);
    }
}

static void stiffness_iso(void **state)
{
    (void)state;
    gs_system *s = vt_system(compliant_pair());
    gs_gmesh_rt *m = &s->meshes[0];
    int pin = gs_scene_find_body(s->scene, "pinion");
    const gs_gear_params *g = &s->scene->bodies[pin].gear;
    double W = 20.0 / gs_gear_base_radius(g), b = g->face_width_m * 1e3; /* N, mm */
    gsi_compliant_info info;
    assert_true(gsi_compliant_info_get(m, &info));
    /* c': one pair at the pitch point (secant at the scene's load) */
    gs_pair_info pi;
    assert_int_equal(gs_pair_analyse(g, &s->scene->bodies[1 - pin].gear, 62.5e-3, &pi, NULL), GS_OK);
    double vp = pi.r1w * sin(pi.alpha_w) - sqrt(pi.r1_start * pi.r1_start - pow(gs_gear_base_radius(g), 2));
    double lo = 0, hi = 1e-4;
    for (int it = 0; it < 80; it++) {
        double mid = 0.5 * (lo + hi);
        *(gsi_compliant_pair_force(m, vp, mid) < W ? &lo : &hi) = mid;
    }
    double c1 = W / lo * 1e-6 / b; /* N/m per mm of face width -> N/(mm um) */
    gsi_compliant_point pt;
    gsi_compliant_point_at(m, vp, &pt);
    double cb = pt.k_bend * 1e-6 / b;
    /* c_gamma: mean over one mesh cycle of the mesh's secant stiffness */
    double sum = 0, kmin = INFINITY, kmax = 0;
    int n = 100;
    for (int i = 0; i < n; i++) {
        double k = W / model_static(m, (i + 0.5) / n, W) * 1e-6 / b;
        sum += k;
        kmin = fmin(kmin, k);
        kmax = fmax(kmax, k);
    }
    double cg = sum / n;
    print_message("stiffness at %.1f N (%.1f N/mm): single pair at the pitch point c' = "
                  "%.2f N/(mm um) "
                  "(bending alone %.2f, contact alone %.2f); mesh over a cycle %.2f .. "
                  "%.2f, mean c_gamma = %.2f "
                  "N/(mm um); ISO 6336: c' ~ 14, c_gamma ~ 14-23 (20 for eps_alpha %.2f)\n",
                  W, W / b, c1, cb, 1.0 / (1.0 / c1 - 1.0 / cb), kmin, kmax, cg, pi.contact_ratio);
    assert_true(c1 > 14.0 / 3 && c1 < 14.0 * 3);
    assert_true(cg > 20.0 / 3 && cg < 20.0 * 3);
    gs_system_free(&s);
}

/* A compliant pair scene with one mesh field set; returns the parse error. */
static gs_err with_field(const char *model, const char *key, json_object *val, gs_diag *d)
{
    json_object *root = compliant_pair();
    json_object *m = mesh0(root);
    json_object_object_add(m, "model", json_object_new_string(model));
    json_object_object_add(m, key, val);
    const char *txt = json_object_to_json_string(root);
    gs_scene *sc = NULL;
    gs_err e = gs_scene_parse(txt, strlen(txt), &sc, d);
    gs_scene_free(&sc);
    json_object_put(root);
    return e;
}

static void scene_checks(void **state)
{
    (void)state;
    gs_diag d;
    struct {
        const char *model, *key;
        json_object *val;
        const char *field;
    } bad[] = {
        {"compliant", "patches", json_object_new_int(3), "meshes[0].patches"},
        {"compliant", "patches", json_object_new_double(40.5), "meshes[0].patches"},
        {"compliant", "bending", json_object_new_string("plate"), "meshes[0].bending"},
        {"compliant", "transition", json_object_new_double(0.9), "meshes[0].transition"},
        {"compliant", "max_line_load_n_per_mm", json_object_new_double(-5), "meshes[0].max_line_load_n_per_mm"},
        {"compliant", "stiffness", json_object_new_double(1e8), "meshes[0].stiffness"},
        {"compliant", "friction", json_object_new_double(0.1), "meshes[0].friction"},
        {"compliant", "backlash_mm", json_object_new_double(-1), "meshes[0].backlash_mm"},
        {"lumped", "patches", json_object_new_int(40), "meshes[0].patches"},
        {"contact", "bending", json_object_new_string("beam"), "meshes[0].bending"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        gs_err e = with_field(bad[i].model, bad[i].key, bad[i].val, &d);
        print_message("%s mesh, '%s': %s: %s\n", bad[i].model, bad[i].key, d.field, d.message);
        assert_int_not_equal(e, GS_OK);
        assert_string_equal(d.field, bad[i].field);
    }
    /* elastic gears are refused at build time */
    json_object *root = compliant_pair();
    json_object_object_add(json_object_array_get_idx(json_object_object_get(root, "bodies"), 0), "model",
                           json_object_new_string("elastic"));
    const char *txt = json_object_to_json_string(root);
    gs_scene *sc;
    assert_int_equal(gs_scene_parse(txt, strlen(txt), &sc, &d), GS_OK);
    json_object_put(root);
    gs_system *s = NULL;
    assert_int_not_equal(gs_system_new(sc, 0, 1, &s, &d), GS_OK);
    assert_string_equal(d.field, "meshes[0].gears");
    /* the fidelity level */
    root = vt_scene("pair");
    json_object_object_add(root, "fidelity", json_object_new_string("compliant"));
    s = vt_system(root);
    assert_string_equal(s->meshes[0].ops->name, "compliant");
    gs_system_free(&s);
    /* options taken */
    root = compliant_pair();
    json_object_object_add(mesh0(root), "patches", json_object_new_int(24));
    json_object_object_add(mesh0(root), "bending", json_object_new_string("none"));
    s = vt_system(root);
    gsi_compliant_info info;
    assert_true(gsi_compliant_info_get(&s->meshes[0], &info));
    assert_int_equal(info.patches, 24);
    gsi_compliant_point pt;
    gsi_compliant_point_at(&s->meshes[0], 0.5 * info.path_length, &pt);
    assert_true(isinf(pt.k_bend));
    gs_system_free(&s);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(driven_braked), cmocka_unit_test(free_conservation), cmocka_unit_test(static_deflection),
        cmocka_unit_test(stiffness_iso), cmocka_unit_test(scene_checks),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
