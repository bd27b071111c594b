/* SPDX-License-Identifier: MIT
 * Material damping of elastic gears in tooth contact (docs/explanation/elastic_body.md, "Material
 * damping"; METHOD.md section 2): `contact_drive` with Rayleigh damping
 * stated in the scene.
 *
 *  1. Energy balance with damping: E - E0 - W_in + D stays below 1e-9 of the
 *     energy scale at every step, the booked dissipation is the brake's plus
 *     the gears' material damping, and the damping removes vibration energy
 *     (elastic strain + elastic motion: E minus the rigid rotation's
 *     1/2 I w^2 of each gear) against the undamped run.
 *  2. Damping keys at zero leave the run unchanged bit for bit.
 *  3. GEARSIM_LONG=1: 300 ms undamped and at 2% and 5% of critical at the
 *     first torsional mesh mode (9.2 kHz, docs/explanation/contact.md): vibration energy
 *     in windows, DTE rms and mean TE over 150-300 ms, the loss booked to
 *     damping, the balance; printed as the table of docs/explanation/elastic_body.md. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>

#include <cmocka.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/long_mode.h"
#include "gearsim/step.h"
#include "gearsim/util.h"
#include "scene_build.h"

#define MESH_HZ 9230.0 /* first torsional mesh mode of contact_drive, ~5.8e4 rad/s */

/* contact_drive with material damping zeta at MESH_HZ on both gears
 * (zeta < 0: no material key at all; zeta = 0: the keys given as zeros). */
static gs_system *build(double zeta)
{
    json_object *root = json_tokener_parse(gs_scene_builtin("contact_drive"));
    assert_non_null(root);
    vt_contact_scheme(root, "seed"); /* the seed's scheme, measured */
    json_object *bs = json_object_object_get(root, "bodies");
    for (size_t i = 0; zeta >= 0 && i < json_object_array_length(bs); i++) {
        json_object *mat = json_object_new_object();
        if (zeta > 0) {
            json_object_object_add(mat, "damping_ratio", json_object_new_double(zeta));
            json_object_object_add(mat, "damping_hz", json_object_new_double(MESH_HZ));
        } else {
            json_object_object_add(mat, "damping_s", json_object_new_double(0.0));
            json_object_object_add(mat, "damping_m", json_object_new_double(0.0));
        }
        json_object_object_add(json_object_array_get_idx(bs, i), "material", mat);
    }
    vt_pin_linear(root); /* linear triangles: figures measured on them (scene_build.h) */
    const char *txt = json_object_to_json_string(root);
    gs_scene *sc;
    gs_diag d;
    gs_system *sys = NULL;
    if (gs_scene_parse(txt, strlen(txt), &sc, &d) != GS_OK || gs_system_new(sc, 0, 1, &sys, &d) != GS_OK)
        fail_msg("%s: %s", d.field, d.message);
    json_object_put(root);
    return sys;
}

/* Strain energy plus the energy of the elastic motion of every gear. */
static double vibration(const gs_system *sys)
{
    double e = 0;
    for (int i = 0; i < sys->n_bodies; i++) {
        const gs_body_rt *b = &sys->bodies[i];
        if (!b->ops->state_size)
            continue;
        double w = b->coord >= 0 ? sys->w[b->coord] : 0.0;
        e += b->T + b->V - 0.5 * b->inertia_eff * w * w;
    }
    return e;
}

typedef struct run_out {
    double vib[3];     /* mean vibration energy over the windows */
    double dte, te;    /* rms about the mean and mean of the mesh deflection, second half */
    double damped;     /* energy booked to material damping (all booked less the brakes') */
    double dissipated; /* all booked dissipation (brake + damping) */
    double balance;    /* worst |residual| / scale */
} run_out;

static run_out run(double zeta, int steps, const int win[3][2])
{
    gs_system *sys = build(zeta);
    run_out r = {0};
    int nw[3] = {0};
    double scale = 0, d1 = 0, d2 = 0;
    int half = steps / 2;
    double brake = 0, *q0 = calloc((size_t)sys->n_coords, sizeof *q0);
    assert_non_null(q0);
    for (int k = 0; k < steps; k++) {
        memcpy(q0, sys->q, (size_t)sys->n_coords * sizeof *q0);
        double t = sys->time;
        assert_int_equal(gs_step_serial(sys), GS_OK);
        /* the brakes' share of the booked dissipation, c dq^2 / h */
        for (int i = 0; i < sys->n_bodies; i++) {
            int c = sys->bodies[i].coord;
            double M, cb = 0, h = sys->time - t;
            if (c < 0)
                continue;
            gs_system_body_load(sys, i, t + 0.5 * h, &M, &cb);
            brake += cb * (sys->q[c] - q0[c]) * (sys->q[c] - q0[c]) / h;
        }
        gs_energy e;
        gs_system_energy(sys, &e);
        scale = fmax(scale, fmax(e.total, fmax(e.work_in, e.dissipated)));
        r.balance = fmax(r.balance, fabs(e.balance_residual));
        double v = vibration(sys);
        for (int w = 0; w < 3; w++)
            if (k >= win[w][0] && k < win[w][1]) {
                r.vib[w] += v;
                nw[w]++;
            }
        if (k >= steps - half) {
            double x = sys->meshes[0].deflection;
            d1 += x;
            d2 += x * x;
        }
        r.dissipated = e.dissipated;
    }
    r.damped = r.dissipated - brake;
    free(q0);
    for (int w = 0; w < 3; w++)
        r.vib[w] /= nw[w] > 0 ? nw[w] : 1;
    r.te = d1 / half;
    r.dte = sqrt(fmax(d2 / half - r.te * r.te, 0.0));
    r.balance /= scale;
    gs_system_free(&sys);
    return r;
}

static void print_row(const char *label, const run_out *r)
{
    print_message("# | %s | %.2f | %.2f | %.2f | %.3f | %.3f | %.4f | %.2e |\n", label, 1e3 * r->vib[0],
                  1e3 * r->vib[1], 1e3 * r->vib[2], 1e6 * r->dte, 1e6 * r->te, r->damped, r->balance);
}

/* 1. 30 ms (the ramp and 10 ms of steady load): balance, booking, effect. */
static void balance_with_damping(void **state)
{
    (void)state;
    const int win[3][2] = {{1000, 2000}, {2000, 2500}, {2500, 3000}};
    print_message("# | run | E_vib 10-20 ms (mJ) | 20-25 ms | 25-30 ms | DTE rms 15-30 ms (um) | mean TE (um) | "
                  "damping loss (J) | balance / scale |\n");
    run_out u = run(-1, 3000, win), dmp = run(0.05, 3000, win);
    print_row("undamped", &u);
    print_row("5% at 9.2 kHz", &dmp);
    assert_true(u.balance < 1e-9);
    assert_true(dmp.balance < 1e-9);
    assert_true(fabs(u.damped) < 1e-9 * u.dissipated); /* all of it is the brake's */
    assert_true(dmp.damped > 1e-6 * dmp.dissipated);
    /* the booked dissipation is the brake's plus the damping's: the
     * damping part is a fraction of it, not more */
    assert_true(dmp.damped < dmp.dissipated);
    assert_true(dmp.vib[2] < u.vib[2]);
}

/* 2. Keys at zero: the same run bit for bit. */
static void zero_damping_is_identical(void **state)
{
    (void)state;
    gs_system *a = build(-1), *b = build(0);
    for (int k = 0; k < 300; k++) {
        assert_int_equal(gs_step_serial(a), GS_OK);
        assert_int_equal(gs_step_serial(b), GS_OK);
    }
    assert_memory_equal(a->q, b->q, (size_t)a->n_coords * sizeof(double));
    assert_memory_equal(a->w, b->w, (size_t)a->n_coords * sizeof(double));
    for (int i = 0; i < a->n_bodies; i++)
        assert_true(a->bodies[i].T == b->bodies[i].T && a->bodies[i].V == b->bodies[i].V);
    gs_system_free(&a);
    gs_system_free(&b);
}

/* The scene keys: the ratio converted, bad combinations refused naming the
 * field. */
static gs_err parse_material(const char *mat, gs_scene **sc, gs_diag *d)
{
    json_object *root = json_tokener_parse(gs_scene_builtin("contact_drive"));
    json_object *b0 = json_object_array_get_idx(json_object_object_get(root, "bodies"), 0);
    json_object_object_add(b0, "material", json_tokener_parse(mat));
    const char *txt = json_object_to_json_string(root);
    gs_err e = gs_scene_parse(txt, strlen(txt), sc, d);
    json_object_put(root);
    return e;
}

static void scene_keys(void **state)
{
    (void)state;
    gs_scene *sc = NULL;
    gs_diag d;
    assert_int_equal(parse_material("{\"damping_ratio\": 0.05, \"damping_hz\": 9230, \"damping_m\": 100}", &sc, &d),
                     GS_OK);
    assert_true(fabs(sc->bodies[0].material.damping_s - 0.05 / (GS_PI * 9230)) <= 1e-18);
    assert_true(sc->bodies[0].material.damping_m == 100);
    assert_true(sc->bodies[1].material.damping_s == 0 && sc->bodies[1].material.damping_m == 0);
    gs_scene_free(&sc);
    const struct {
        const char *mat, *field;
    } bad[] = {
        {"{\"damping_ratio\": 0.05}", "bodies[0].material.damping_hz"},
        {"{\"damping_hz\": 9230}", "bodies[0].material.damping_ratio"},
        {"{\"damping_ratio\": 0.05, \"damping_hz\": 9230, \"damping_s\": 1e-6}", "bodies[0].material.damping_ratio"},
        {"{\"damping_ratio\": 2, \"damping_hz\": 9230}", "bodies[0].material.damping_ratio"},
        {"{\"damping_ratio\": 0.05, \"damping_hz\": 0}", "bodies[0].material.damping_hz"},
        {"{\"damping_m\": -1}", "bodies[0].material.damping_m"},
    };
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        gs_err e = parse_material(bad[k].mat, &sc, &d);
        print_message("# %s -> %s: %s\n", bad[k].mat, d.field, d.message);
        assert_int_not_equal(e, GS_OK);
        assert_string_equal(d.field, bad[k].field);
    }
}

/* 3. GEARSIM_LONG=1: 300 ms, three runs. */
static void long_runs(void **state)
{
    (void)state;
    const int win[3][2] = {{2000, 5000}, {14000, 16000}, {28000, 30000}};
    print_message("# | run | E_vib 20-50 ms (mJ) | 140-160 ms | 280-300 ms | DTE rms 150-300 ms (um) | "
                  "mean TE (um) | damping loss (J) | balance / scale |\n");
    const double zs[3] = {-1, 0.02, 0.05};
    const char *lab[3] = {"undamped", "2% at 9.2 kHz", "5% at 9.2 kHz"};
    for (int k = 0; k < 3; k++) {
        run_out r = run(zs[k], 30000, win);
        print_row(lab[k], &r);
        assert_true(r.balance < 1e-9);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(balance_with_damping),
        cmocka_unit_test(zero_damping_is_identical),
        cmocka_unit_test(scene_keys),
    };
    const struct CMUnitTest long_tests[] = {
        cmocka_unit_test(long_runs),
    };
    return RUN_GROUPS_LONG(tests, long_tests);
}
