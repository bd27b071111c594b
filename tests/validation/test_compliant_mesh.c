/* SPDX-License-Identifier: MIT
 * Validation of the `compliant` mesh model (rigid gears, tooth pairs through
 * the compliant contact patch model; docs/explanation/impact.md "The compliant mesh"):
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
 *    engaged pair (pair geometry from the model, the same tooth law in
 *    series: beam and fillet foundation by default), in single and double
 *    contact: within 0.5 % (the model interpolates a table of 24 loads x 25
 *    stations; seen 0.001 % and 0.026 %);
 *  - mesh stiffness for `bending` none / beam / beam_foundation: single
 *    pair at the pitch point (c'), single- and two-pair zone means and the
 *    mean over a cycle (c_gamma) per mm of face width, at the scene's load
 *    and hubs and at the FE analysis' (docs/explanation/stiffness.md: default hubs,
 *    200 N/mm), printed with the FE and ISO 6336 figures; beam_foundation
 *    within 25 % of the FE cycle mean and zone means (seen -9 % .. -14 %),
 *    the beam alone outside it, and within a factor 3 of ISO's 14 and 20
 *    N/(mm um) at the scene's load;
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
#include "compliant_static.h"
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
        double xd = direct_static(me, phi, W, info.patches, &npairs), xm = vt_compliant_static(me, phi, W);
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

/* The compliant pair with a `bending` option; default_hubs drops the
 * scene's hub radii (10 and 15 mm) for the default 0.6 r_f, the hubs of the
 * FE stiffness analysis (docs/explanation/stiffness.md, deploy/scenes/stiffness_pair.json). */
static gs_system *stiffness_pair(const char *bending, bool default_hubs)
{
    json_object *root = compliant_pair();
    json_object_object_add(mesh0(root), "bending", json_object_new_string(bending));
    for (int k = 0; k < 2 && default_hubs; k++)
        json_object_object_del(json_object_array_get_idx(json_object_object_get(root, "bodies"), (size_t)k),
                               "hub_radius_mm");
    return vt_system(root);
}

typedef struct stiff {
    double c1, cbeam, cfound, ccontact; /* one pair at the pitch point, N/(mm um) */
    double single, dbl, kmin, kmax, cg; /* single- and two-pair zone means, cycle min, max, mean */
} stiff;

/* Secant stiffnesses per mm of face width at total force W (N) along the
 * line of action: one pair at the pitch point, and the mesh over one cycle
 * (200 phases) from the model's own law. */
static stiff measure(gs_system *s, double W)
{
    gs_gmesh_rt *m = &s->meshes[0];
    int pin = gs_scene_find_body(s->scene, "pinion");
    const gs_gear_params *g = &s->scene->bodies[pin].gear;
    double b = g->face_width_m * 1e3; /* mm */
    gs_pair_info pi;
    assert_int_equal(gs_pair_analyse(g, &s->scene->bodies[1 - pin].gear, 62.5e-3, &pi, NULL), GS_OK);
    double vp = pi.r1w * sin(pi.alpha_w) - sqrt(pi.r1_start * pi.r1_start - pow(gs_gear_base_radius(g), 2));
    double lo = 0, hi = 1e-4;
    for (int it = 0; it < 80; it++) {
        double mid = 0.5 * (lo + hi);
        *(gsi_compliant_pair_force(m, vp, mid) < W ? &lo : &hi) = mid;
    }
    stiff r;
    r.c1 = W / lo * 1e-6 / b; /* N/m per mm of face width -> N/(mm um) */
    gsi_compliant_point pt;
    gsi_compliant_point_at(m, vp, &pt);
    r.cbeam = pt.k_beam * 1e-6 / b;
    r.cfound = pt.k_found * 1e-6 / b;
    r.ccontact = 1.0 / (1.0 / r.c1 - 1.0 / (pt.k_bend * 1e-6 / b));
    double sum = 0, ssum = 0, dsum = 0;
    int n = 200, ns = 0, nd = 0;
    r.kmin = INFINITY;
    r.kmax = 0;
    for (int i = 0; i < n; i++) {
        double phi = (i + 0.5) / n, k = W / vt_compliant_static(m, phi, W) * 1e-6 / b, v[8], wt[8];
        int np = gsi_compliant_pairs(m, phi, 1, v, wt, 8), engaged = 0;
        for (int j = 0; j < np; j++)
            engaged += wt[j] > 0;
        if (engaged == 1) {
            ssum += k;
            ns++;
        } else {
            dsum += k;
            nd++;
        }
        sum += k;
        r.kmin = fmin(r.kmin, k);
        r.kmax = fmax(r.kmax, k);
    }
    r.cg = sum / n;
    r.single = ns ? ssum / ns : NAN;
    r.dbl = nd ? dsum / nd : NAN;
    return r;
}

static void print_stiff(const char *what, const stiff *r)
{
    print_message("  %-40s c' %.2f (beam %.2f, foundation %.2f, contact %.2f); zones: single %.2f, two "
                  "pairs %.2f; cycle %.2f .. %.2f, mean c_gamma %.2f\n",
                  what, r->c1, r->cbeam, r->cfound, r->ccontact, r->single, r->dbl, r->kmin, r->kmax, r->cg);
}

static void stiffness_iso(void **state)
{
    (void)state;
    /* FE analysis of the same pair (docs/explanation/stiffness.md: both gears elastic,
     * plane stress, default hubs, 200 N/mm), refine 0 / 1 / 2: cycle mean
     * 19.91 / 19.83 / 19.21, single-pair zone 16.59 / 15.09 / 14.26, two-pair
     * zone 21.28 / 21.41 / 20.86. ISO 6336-1 method B: c' 12.26 (c'_th
     * 15.72), c_gamma 17.83 .. 22.86. */
    const double fe_mean[2] = {19.21, 19.91}, fe_single = 14.26, fe_double = 20.86;
    const char *opts[3] = {"none", "beam", "beam_foundation"};
    stiff at_scene[3], at_fe[3];
    print_message("secant stiffness, N/(mm um):\n");
    for (int o = 0; o < 3; o++) {
        for (int hubs = 0; hubs < 2; hubs++) {
            gs_system *s = stiffness_pair(opts[o], hubs == 1);
            int pin = gs_scene_find_body(s->scene, "pinion");
            const gs_gear_params *g = &s->scene->bodies[pin].gear;
            double bw = g->face_width_m * 1e3;
            /* the scene's 20 N m (85 N/mm) with its hubs; the FE analysis'
             * 200 N/mm with its default hubs */
            double W = hubs ? 200.0 * bw : 20.0 / gs_gear_base_radius(g);
            gsi_compliant_info info;
            assert_true(gsi_compliant_info_get(&s->meshes[0], &info));
            assert_int_equal(info.bending, o);
            stiff *r = hubs ? &at_fe[o] : &at_scene[o];
            *r = measure(s, W);
            char what[96];
            snprintf(what, sizeof what, "%s, %s hubs, %.0f N/mm:", opts[o], hubs ? "default" : "scene", W / bw);
            print_stiff(what, r);
            for (int k = 0; k < 2 && o == 2; k++)
                print_message("    %s foundation: h_fi = r_f/r_int %.3f, theta_f %.4f rad, "
                              "L* %.3f M* %.3f P* %.3f Q* %.3f\n",
                              k == 0 ? "pinion" : "wheel", info.h_fi[k], info.theta_f[k], info.lmpq[k][0],
                              info.lmpq[k][1], info.lmpq[k][2], info.lmpq[k][3]);
            gs_system_free(&s);
        }
    }
    const stiff *f = &at_fe[2];
    print_message("FE (default hubs, 200 N/mm): mean %.2f .. %.2f (refine 2 .. 0), single zone %.2f, two-pair "
                  "zone %.2f (refine 2); ISO 6336: c' 12.26 .. 15.72, c_gamma 17.83 .. 22.86\n",
                  fe_mean[0], fe_mean[1], fe_single, fe_double);
    print_message("beam_foundation against FE: mean %+.1f %% (refine 2) %+.1f %% (refine 0), single zone %+.1f %%, "
                  "two-pair zone %+.1f %%; beam alone: mean %+.1f %%, single zone %+.1f %%\n",
                  100 * (f->cg / fe_mean[0] - 1), 100 * (f->cg / fe_mean[1] - 1), 100 * (f->single / fe_single - 1),
                  100 * (f->dbl / fe_double - 1), 100 * (at_fe[1].cg / fe_mean[0] - 1),
                  100 * (at_fe[1].single / fe_single - 1));
    /* each option adds a compliance in series */
    for (int o = 1; o < 3; o++) {
        assert_true(at_scene[o].cg < at_scene[o - 1].cg);
        assert_true(at_fe[o].cg < at_fe[o - 1].cg);
    }
    /* the beam does not see the hubs; the foundation does: the scene's
     * smaller hubs (r_f/r_int 2.2-2.3 against 1.67) leave more body to
     * deform */
    assert_true(fabs(at_fe[2].cbeam / at_scene[2].cbeam - 1) < 1e-12);
    assert_true(at_scene[2].cfound < at_fe[2].cfound);
    /* Against the FE analysis at its own hubs and load: within 25 % of its
     * cycle mean (refine 0..2) and of its converged (refine 2) single- and
     * two-pair zone means. Seen -9 % / -12 %, -14 % and -2 %: the single
     * pair is the softest figure (see docs/explanation/impact.md for what is left out:
     * the beam's section below the form circle, the loaded contact ratio);
     * 25 % keeps that margin while the beam alone (+50 % on the mean) fails. */
    assert_true(f->cg > 0.75 * fe_mean[1] && f->cg < 1.25 * fe_mean[0]);
    assert_true(fabs(f->single / fe_single - 1) < 0.25);
    assert_true(fabs(f->dbl / fe_double - 1) < 0.25);
    assert_false(at_fe[1].cg < 1.25 * fe_mean[0]);
    /* and the order of magnitude against ISO at the scene's load */
    assert_true(at_scene[2].c1 > 14.0 / 3 && at_scene[2].c1 < 14.0 * 3);
    assert_true(at_scene[2].cg > 20.0 / 3 && at_scene[2].cg < 20.0 * 3);
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
    assert_int_equal(info.bending, 0);
    gs_system_free(&s);
    /* the default is beam_foundation, both external gears founded; "beam"
     * leaves the foundation out */
    for (int o = 0; o < 2; o++) {
        root = compliant_pair();
        if (o == 1)
            json_object_object_add(mesh0(root), "bending", json_object_new_string("beam"));
        s = vt_system(root);
        assert_true(gsi_compliant_info_get(&s->meshes[0], &info));
        assert_int_equal(info.bending, o == 0 ? 2 : 1);
        gsi_compliant_point_at(&s->meshes[0], 0.5 * info.path_length, &pt);
        assert_true(isfinite(pt.k_beam));
        assert_true(o == 0 ? isfinite(pt.k_found) && info.h_fi[0] > 1 && info.h_fi[1] > 1 : isinf(pt.k_found));
        assert_true(fabs(pt.k_bend / (o == 0 ? 1.0 / (1.0 / pt.k_beam + 1.0 / pt.k_found) : pt.k_beam) - 1) < 1e-12);
        gs_system_free(&s);
    }
    /* a ring keeps its teeth clamped, the planet is founded */
    root = vt_scene("planetary");
    json_object_object_add(root, "fidelity", json_object_new_string("compliant"));
    s = vt_system(root);
    int rings = 0;
    for (int i = 0; i < s->n_meshes; i++) {
        assert_true(gsi_compliant_info_get(&s->meshes[i], &info));
        bool ring = s->scene->bodies[s->scene->meshes[i].gear[0]].gear.kind == GS_GEAR_INTERNAL ||
                    s->scene->bodies[s->scene->meshes[i].gear[1]].gear.kind == GS_GEAR_INTERNAL;
        rings += ring;
        assert_true(info.h_fi[0] > 1);
        assert_true(ring ? info.h_fi[1] == 0 : info.h_fi[1] > 1);
    }
    assert_int_equal(rings, 3);
    gs_system_free(&s);
    /* far outside the fit (a 400-tooth wheel: theta_f 0.0075 rad) the
     * formula's bracket turns negative: refused, field named */
    root = compliant_pair();
    json_object *wheel = json_object_array_get_idx(json_object_object_get(root, "bodies"), 1);
    json_object_object_add(wheel, "teeth", json_object_new_int(400));
    json_object_object_del(wheel, "hub_radius_mm");
    json_object *cen = json_object_new_array();
    json_object_array_add(cen, json_object_new_double(525.0));
    json_object_array_add(cen, json_object_new_double(0.0));
    json_object_object_add(json_object_array_get_idx(json_object_object_get(root, "joints"), 1), "centre_mm", cen);
    txt = json_object_to_json_string(root);
    assert_int_equal(gs_scene_parse(txt, strlen(txt), &sc, &d), GS_OK);
    json_object_put(root);
    s = NULL;
    assert_int_not_equal(gs_system_new(sc, 0, 1, &s, &d), GS_OK);
    print_message("400-tooth wheel: %s: %s\n", d.field, d.message);
    assert_string_equal(d.field, "meshes[0].bending");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(driven_braked), cmocka_unit_test(free_conservation), cmocka_unit_test(static_deflection),
        cmocka_unit_test(stiffness_iso), cmocka_unit_test(scene_checks),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
