/* SPDX-License-Identifier: MIT
 * The ltca mesh model (docs/explanation/ltca.md) at low speed against the
 * quasi-static analysis its tables came from. On contact_drive as shipped
 * (`fidelity: "ltca"`: rigid gears, the tables of the pair's quasi-static
 * analysis at its default settings; read from deploy/ltca or the cache),
 * over the second half of 60 ms (steady speed, mesh frequency 141 Hz, far
 * below the mesh mode):
 *  - the mean dynamic TE (line-of-action deflection from the initial
 *    position, backlash closing included) within 1 % of the mean of the
 *    quasi-static TE over the table's positions at the run's mean mesh
 *    force (the scene's load: a knot of the table);
 *  - its rms about the mean (DTE rms) within 2 % of the quasi-static TE's;
 *  - the output speed within 0.5 % of the closed form M0 (z2/z1) / c;
 *  - the energy balance residual at round-off (1e-12 of the energy scale)
 *    at every step;
 *  - the same tables read twice give the same numbers bit for bit (the
 *    cache), and their key changes with the load and the geometry.
 * contact_drive with pair_relief's tip relief on both gears the same way
 * (its tables carry the relieved flanks' TE; built on first use, about
 * 30 CPU s, then cached).
 * Pitch errors on the ltca mesh (test_pitch_pairs): the TE they add, by
 * the tables' tooth pairs and load shares, against the quasi-static FE
 * analysis of the elastic pair with and without them (2 mesh cycles,
 * within 0.1 um rms and under half the lumped mesh's windows' misfit).
 * planetary_contact the same way (its six meshes' tables are shipped; a
 * checkout without them builds them on first use, about 3 CPU minutes),
 * and its tables' default case: every mesh at its static share of the
 * sun's moment, with the bodies' compliance measured. */
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

#include "gearsim/geometry.h"
#include "gearsim/ltca.h"
#include "gearsim/stiffness.h"
#include "gearsim/step.h"
#include "gearsim/util.h"
#include "../common/steady_half.h"

/* contact_drive with pair_relief's linear tip relief on both gears (the
 * variant of bench_tradeoff's contact_drive_relief rows). */
static char *relief_scene(void)
{
    json_object *root = json_tokener_parse(gs_scene_builtin("contact_drive"));
    assert_non_null(root);
    json_object *bs = json_object_object_get(root, "bodies");
    for (size_t i = 0; i < json_object_array_length(bs); i++) {
        json_object *tr = json_object_new_object(), *mod = json_object_new_object();
        json_object_object_add(tr, "amount_um", json_object_new_double(10.3));
        json_object_object_add(tr, "length_mm", json_object_new_double(4.466));
        json_object_object_add(tr, "shape", json_object_new_string("linear"));
        json_object_object_add(mod, "tip_relief", tr);
        json_object_object_add(json_object_array_get_idx(bs, i), "modification", mod);
    }
    const char *js = json_object_to_json_string(root);
    char *txt = malloc(strlen(js) + 1);
    assert_non_null(txt);
    memcpy(txt, js, strlen(js) + 1);
    json_object_put(root);
    return txt;
}

static gs_system *build(const char *name, double h)
{
    char *own = !strcmp(name, "contact_drive_relief") ? relief_scene() : NULL;
    const char *txt = own ? own : gs_scene_builtin(name);
    assert_non_null(txt);
    /* the shipped scene at the ltca rung */
    size_t n = strlen(txt);
    char *s = malloc(n + 64);
    assert_non_null(s);
    const char *brace = strchr(txt, '{');
    assert_non_null(brace);
    size_t pre = (size_t)(brace - txt) + 1;
    memcpy(s, txt, pre);
    int k = sprintf(s + pre, "\"fidelity\": \"ltca\", ");
    memcpy(s + pre + k, txt + pre, n - pre + 1);
    free(own);
    gs_scene *sc;
    gs_diag d;
    gs_err e = gs_scene_parse(s, strlen(s), &sc, &d);
    free(s);
    if (e != GS_OK)
        fprintf(stderr, "%s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    sc->time_step = h;
    gs_system *sys;
    e = gs_system_new(sc, 0, 1, &sys, &d);
    if (e != GS_OK)
        fprintf(stderr, "%s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    return sys;
}

/* Deflection of row j of t under force F (its monotone inverse). */
static double row_inverse(const gs_ltca_table *t, int j, double F)
{
    double lo = t->d[(size_t)j * t->m], hi = t->d[(size_t)j * t->m + t->m - 1];
    while (gs_ltca_row_force(t, j, lo, NULL) > F)
        lo -= hi - lo;
    while (gs_ltca_row_force(t, j, hi, NULL) < F)
        hi += hi - lo;
    for (int it = 0; it < 200 && hi - lo > 1e-16; it++) {
        double mid = 0.5 * (lo + hi);
        if (gs_ltca_row_force(t, j, mid, NULL) < F)
            lo = mid;
        else
            hi = mid;
    }
    return 0.5 * (lo + hi);
}

/* Mean and rms about it of the table's static TE at the mesh force F (the
 * run's mean: the scene's load on a pair, its share on a planet's mesh). */
static void static_te(const gs_scene *sc, int mesh, double F, double *mean, double *rms)
{
    gs_ltca_table t;
    gs_diag d;
    assert_int_equal(gs_ltca_tables(sc, mesh, NULL, &t, &d), GS_OK);
    double s1 = 0, s2 = 0;
    for (int j = 0; j < t.n; j++) {
        double x = row_inverse(&t, j, F);
        s1 += x;
        s2 += x * x;
    }
    *mean = s1 / t.n;
    *rms = sqrt(fmax(s2 / t.n - *mean * *mean, 0));
    /* read again: the same bits */
    gs_ltca_table u;
    assert_int_equal(gs_ltca_tables(sc, mesh, NULL, &u, &d), GS_OK);
    assert_int_equal(t.n, u.n);
    assert_int_equal(t.m, u.m);
    assert_memory_equal(t.d, u.d, (size_t)t.n * t.m * sizeof(double));
    assert_memory_equal(t.f, u.f, (size_t)t.n * t.m * sizeof(double));
    gs_ltca_table_clear(&t);
    gs_ltca_table_clear(&u);
}

static void lowspeed(const char *name, double duration, const char *out, double speed_expect)
{
    double h = 1e-4;
    gs_system *sys = build(name, h);
    steady_half r = sh_start((int)lround(duration / h), gs_scene_find_body(sys->scene, out));
    for (int i = 0; i < r.n; i++)
        assert_true(sh_step(&r, sys, i));
    double speed = fabs(gs_system_angle(sys, r.body) - r.th0) / (r.half * h);
    double mean = sh_mean(&r), rms = sh_rms(&r);
    double smean, srms;
    static_te(sys->scene, 0, r.fsum / r.half, &smean, &srms);
    printf("# %s ltca: mean TE %.4f um (static %.4f, %+.3f %%), DTE rms %.4f um (static %.4f, %+.2f %%), "
           "speed %.4f rad/s (closed form %.4f), balance %.2e of %.3g J\n",
           name, mean * 1e6, smean * 1e6, 100 * (mean / smean - 1), rms * 1e6, srms * 1e6, 100 * (rms / srms - 1),
           speed, speed_expect, r.worst / r.scale, r.scale);
    assert_true(fabs(mean / smean - 1) < 0.01);
    assert_true(fabs(rms / srms - 1) < 0.02);
    assert_true(fabs(speed / speed_expect - 1) < 0.005);
    assert_true(r.worst <= 1e-12 * r.scale);
    gs_system_free(&sys);
}

static void test_pair(void **state)
{
    (void)state;
    lowspeed("contact_drive", 0.06, "pinion", 20.0 * (20.0 / 30.0) / 0.3);
}

static void test_relief(void **state)
{
    (void)state;
    lowspeed("contact_drive_relief", 0.06, "pinion", 20.0 * (20.0 / 30.0) / 0.3);
}

static void test_planetary(void **state)
{
    (void)state;
    lowspeed("planetary_contact", 0.05, "carrier", 10.0);
    /* A train's tables: the default case at each mesh's static share of
     * the sun's moment, a third of it over the sun's base radius (closed
     * form of three equal planets; the planet's mesh with the ring loaded
     * on the other side of its coordinate: the planet turns against the
     * sun), and the bodies' compliance measured on every mesh. */
    gs_system *sys = build("planetary_contact", 1e-4);
    const gs_scene *sc = sys->scene;
    double rb = gs_gear_base_radius(&sc->bodies[gs_scene_find_body(sc, "sun")].gear);
    double F = sc->loads[0].moment / (3 * rb);
    for (int i = 0; i < sc->n_meshes; i++) {
        gs_ltca_table t;
        gs_diag d;
        assert_int_equal(gs_ltca_tables(sc, i, NULL, &t, &d), GS_OK);
        double Fi = t.f[t.knot_scene], want = strstr(sc->meshes[i].name, "ring") ? -F : F;
        printf("# %s: tables at %.4f N (static share %.4f N), body compliance %.3e m/N\n", sc->meshes[i].name, Fi,
               want, t.body_compliance);
        assert_true(fabs(Fi / want - 1) < 1e-9);
        assert_true(t.body_compliance > 1e-10 && t.body_compliance < 0.5 / t.k_mean);
        gs_ltca_table_clear(&t);
    }
    gs_system_free(&sys);
}

/* contact_drive with the pitch-error tables of bench_tradeoff's
 * contact_drive_errors rows on both gears (a long-wave deviation of 2 um
 * plus +-0.5 um tooth to tooth; no run-out), its gears and mesh `model`s
 * as given (NULL: as shipped). */
static gs_scene *pitch_scene(const char *body_model, const char *mesh_model, int errors)
{
    json_object *root = json_tokener_parse(gs_scene_builtin("contact_drive"));
    assert_non_null(root);
    json_object *bs = json_object_object_get(root, "bodies");
    for (size_t i = 0; i < json_object_array_length(bs); i++) {
        json_object *b = json_object_array_get_idx(bs, i), *pe = json_object_new_array();
        int z = json_object_get_int(json_object_object_get(b, "teeth")), wheel = z == 30;
        for (int k = 0; k < z; k++)
            json_object_array_add(pe, json_object_new_double(2.0 * sin(2 * GS_PI * k / z + (wheel ? 0.3 : 1.1)) +
                                                             (k % 2 ? 0.5 : -0.5)));
        if (errors)
            json_object_object_add(b, "pitch_errors_um", pe);
        else
            json_object_put(pe);
        if (body_model)
            json_object_object_add(b, "model", json_object_new_string(body_model));
    }
    if (mesh_model)
        json_object_object_add(json_object_array_get_idx(json_object_object_get(root, "meshes"), 0), "model",
                               json_object_new_string(mesh_model));
    const char *js = json_object_to_json_string(root);
    gs_scene *sc;
    gs_diag d;
    gs_err e = gs_scene_parse(js, strlen(js), &sc, &d);
    if (e != GS_OK)
        fprintf(stderr, "%s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    json_object_put(root);
    return sc;
}

/* The tooth errors' displacement E of mesh 0 of sc at the driver (wheel,
 * body 0) turned by a from the scene's angles and the pinion kinematically
 * with it. */
static double error_at(gs_system *sys, const double *q0, double a)
{
    int cw = sys->bodies[0].coord, cp = sys->bodies[1].coord;
    memcpy(sys->q, q0, (size_t)sys->n_coords * sizeof(double));
    sys->q[cw] += a;
    sys->q[cp] -= a * 30.0 / 20.0;
    return gs_gmesh_error(&sys->meshes[0], sys->q);
}

/* Pitch errors on an ltca mesh: the TE they add at low speed against the
 * quasi-static FE analysis of the elastic pair with and without them (the
 * plain FE, two mesh cycles, 24 positions each): the ltca mesh's -E (the
 * tables' tooth pairs and load shares) and the lumped mesh's (the teeth's
 * windows about the line of centres) at the same kinematic positions. */
static void test_pitch_pairs(void **state)
{
    (void)state;
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    o.positions = 48;
    o.cycles = 2;
    o.nearfield = 0;
    o.tangent = 0;
    gs_stiffness_result r[2];
    gs_diag d;
    for (int k = 0; k < 2; k++) {
        gs_scene *sc = pitch_scene(NULL, NULL, k);
        assert_int_equal(gs_stiffness_analyse(sc, 0, &o, &r[k], &d), GS_OK);
        gs_scene_free(&sc);
    }
    double fit[2];
    for (int v = 0; v < 2; v++) {
        gs_system *sys;
        assert_int_equal(gs_system_new(pitch_scene("rigid", v ? "lumped" : "ltca", 1), 0, 1, &sys, &d), GS_OK);
        assert_true(v || sys->meshes[0].pair_err != NULL);
        double *q0 = malloc((size_t)sys->n_coords * sizeof(double));
        assert_non_null(q0);
        memcpy(q0, sys->q, (size_t)sys->n_coords * sizeof(double));
        double s1 = 0, s2 = 0, f1 = 0, f2 = 0;
        for (int j = 0; j < o.positions; j++) {
            double fe = (r[1].pt[j].te_raw_um - r[0].pt[j].te_raw_um) * 1e-6;
            double x = fe + error_at(sys, q0, r[0].pt[j].angle_rad);
            s1 += x, s2 += x * x, f1 += fe, f2 += fe * fe;
        }
        int n = o.positions;
        fit[v] = sqrt(fmax(s2 / n - (s1 / n) * (s1 / n), 0));
        printf("# pitch errors, %s mesh: the FE's TE they add %.4f um rms about its mean; the mesh's misfit "
               "%.4f um rms, mean %+.4f um\n", v ? "lumped" : "ltca", sqrt(fmax(f2 / n - (f1 / n) * (f1 / n), 0)) * 1e6,
               fit[v] * 1e6, s1 / n * 1e6);
        free(q0);
        gs_system_free(&sys);
    }
    gs_stiffness_result_clear(&r[0]);
    gs_stiffness_result_clear(&r[1]);
    assert_true(fit[0] < 0.1e-6);
    assert_true(fit[0] < 0.5 * fit[1]);
}

static void test_key(void **state)
{
    (void)state;
    gs_system *sys = build("contact_drive", 1e-4);
    gs_scene *sc = sys->scene;
    uint64_t k0 = gs_ltca_key(sc, 0, NULL);
    double T = sc->loads[0].moment;
    sc->loads[0].moment = 1.5 * T;
    uint64_t k1 = gs_ltca_key(sc, 0, NULL);
    sc->loads[0].moment = T;
    double th = sc->bodies[0].gear.thinning_m;
    sc->bodies[0].gear.thinning_m = 0.5 * th;
    uint64_t k2 = gs_ltca_key(sc, 0, NULL);
    sc->bodies[0].gear.thinning_m = th;
    int r = sc->bodies[1].mesh.refine;
    sc->bodies[1].mesh.refine = r + 1;
    uint64_t k3 = gs_ltca_key(sc, 0, NULL);
    sc->bodies[1].mesh.refine = r;
    setenv("GEARSIM_LTCA_NEARFIELD", "0", 1); /* the plain FE's tables: a key of their own */
    uint64_t k4 = gs_ltca_key(sc, 0, NULL);
    unsetenv("GEARSIM_LTCA_NEARFIELD");
    assert_true(k0 != k1 && k0 != k2 && k0 != k3 && k0 != k4);
    /* the settings of both analyses are in the key: the tables built while
     * the modal analysis that measures the bodies' compliance held the
     * plain FE contact (its key below) are not read back */
    assert_true(k0 != 0x030b2d79686af59dull);
    assert_true(gs_ltca_key(sc, 0, NULL) == k0);
    gs_system_free(&sys);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_key),
        cmocka_unit_test(test_pitch_pairs),
        cmocka_unit_test(test_pair),
        cmocka_unit_test(test_relief),
        cmocka_unit_test(test_planetary),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
