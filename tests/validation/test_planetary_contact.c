/* SPDX-License-Identifier: MIT
 * The planetary train with elastic gears in tooth contact (the seed's
 * section 7.3, scene deploy/scenes/planetary_contact.json): sun 24,
 * three planets 24 on a rigid carrier, held ring 72, all gears elastic,
 * six contact meshes solved as one QP per step. Checked against closed forms:
 *  - mean sun/carrier speed ratio 1 + z_ring/z_sun = 4 within 0.5%;
 *  - steady carrier speed M0 * 4 / c = 10 rad/s within 1%;
 *  - energy balance residual at round-off;
 *  - load sharing: the three sun-planet meshes carry equal mean forces
 *    within 2% in the perfect train; a tangential pin position error on
 *    planet 1 makes the sharing unequal in the expected direction;
 *  - the one-field fidelity switch: the rigid demo scene (planetary.json)
 *    with "fidelity": "contact" builds elastic gears and contact meshes,
 *    phased into mesh automatically, and runs with the same balance.
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

#include "gearsim/mesh.h"
#include "gearsim/models.h"
#include "gearsim/step.h"
#include "scene_build.h"

typedef struct run_result {
    double ratio, carrier, residual, scale, share[3];
} run_result;

/* Run n steps; means over the last `tail` steps. */
static run_result run(gs_system *s, int n, int tail)
{
    const gs_scene *sc = s->scene;
    int sun = gs_scene_find_body(sc, "sun"), car = gs_scene_find_body(sc, "carrier");
    int sm[3] = {-1, -1, -1};
    for (int i = 0; i < sc->n_meshes; i++)
        for (int p = 0; p < 3; p++) {
            char name[32];
            snprintf(name, sizeof name, "sun-planet%d", p + 1);
            if (!strcmp(sc->meshes[i].name, name))
                sm[p] = i;
        }
    double th_s = 0, th_c = 0, f[3] = {0, 0, 0}, worst = 0, scale = 0;
    gs_energy e;
    for (int i = 0; i < n; i++) {
        if (i == n - tail) {
            th_s = gs_system_angle(s, sun);
            th_c = gs_system_angle(s, car);
        }
        vt_step_balance(s, &e, &worst, &scale);
        if (i >= n - tail)
            for (int p = 0; p < 3; p++)
                f[p] += sm[p] >= 0 ? s->meshes[sm[p]].force : 0.0;
    }
    run_result r;
    double T = tail * s->h;
    r.ratio = (gs_system_angle(s, sun) - th_s) / (gs_system_angle(s, car) - th_c);
    r.carrier = (gs_system_angle(s, car) - th_c) / T;
    r.residual = worst;
    r.scale = scale;
    double sum = f[0] + f[1] + f[2];
    for (int p = 0; p < 3; p++)
        r.share[p] = 3.0 * f[p] / sum;
    return r;
}

static void report(const char *what, run_result r)
{
    print_message("%-28s ratio %.6f (err %+.2e)  carrier %.4f rad/s (err %+.2e)  shares %.4f %.4f %.4f  "
                  "balance %.2e of %.2e J\n",
                  what, r.ratio, r.ratio / 4 - 1, r.carrier, r.carrier / 10 - 1, r.share[0], r.share[1],
                  r.share[2], r.residual, r.scale);
}

/* 5000 steps at 1e-5 s: ramp 20 ms, carrier time constant I_eff / c below
 * 1 ms; means over the last 26.18 ms, three whole mesh cycles at the steady
 * state (the sun turns relative to the carrier at 3 w_c = 30 rad/s: a tooth
 * every 2 pi / (24 * 30) s), so that the shares do not depend on where in a
 * cycle the window ends. */
enum { N_STEPS = 5000, TAIL = 2618 };

static void perfect_train(void **state)
{
    (void)state;
    gs_system *s = vt_system(vt_contact_scheme(vt_scene_linear("planetary_contact"), "seed"));
    run_result r = run(s, N_STEPS, TAIL);
    report("perfect train:", r);
    /* Kinematics of the planetary train (0.5%), power balance (1%). */
    assert_true(fabs(r.ratio / 4 - 1) < 5e-3);
    assert_true(fabs(r.carrier / 10 - 1) < 1e-2);
    /* Round-off over 6000 steps of six contact meshes. */
    assert_true(r.residual < 1e-11 * r.scale);
    /* Equal sharing: symmetric train, 2%. */
    for (int p = 0; p < 3; p++)
        assert_true(fabs(r.share[p] - 1) < 0.02);
    gs_system_free(&s);
}

static void pin_error(void **state)
{
    (void)state;
    json_object *root = vt_contact_scheme(vt_scene_linear("planetary_contact"), "seed");
    json_object *js = json_object_object_get(root, "joints");
    for (size_t i = 0; i < json_object_array_length(js); i++) {
        json_object *j = json_object_array_get_idx(js, i);
        if (!strcmp(json_object_get_string(json_object_object_get(j, "body")), "planet1")) {
            json_object *pe = json_object_new_array();
            json_object_array_add(pe, json_object_new_double(0.0));
            json_object_array_add(pe, json_object_new_double(10.0));
            json_object_object_add(j, "pin_error_um", pe);
        }
    }
    gs_system *s = vt_system(root);
    run_result r = run(s, N_STEPS, TAIL);
    report("pin 1 +10 um tangential:", r);
    /* The pin of planet 1 is advanced by 10 um in the direction the carrier
     * turns: the sun must turn further before its teeth reach that planet,
     * which then carries less than its third, the others more. */
    assert_true(r.share[0] < 0.98);
    assert_true(r.share[1] > 1.0 && r.share[2] > 1.0);
    assert_true(r.residual < 1e-11 * r.scale);
    gs_system_free(&s);
}

static void fidelity_switch(void **state)
{
    (void)state;
    json_object *root = vt_scene_linear("planetary");
    json_object_object_add(root, "fidelity", json_object_new_string("contact"));
    gs_system *s = vt_system(root);
    int elastic = 0, contact = 0;
    for (int i = 0; i < s->n_bodies; i++)
        elastic += s->scene->bodies[i].model == GS_MODEL_ELASTIC;
    for (int i = 0; i < s->n_meshes; i++)
        contact += s->meshes[i].ops->contact;
    print_message("planetary.json with \"fidelity\": \"contact\": %d elastic gears, %d contact meshes\n",
                  elastic, contact);
    assert_int_equal(elastic, 5);
    assert_int_equal(contact, 6);
    run_result r = run(s, 600, 300);
    report("fidelity switch, 6 ms:", r);
    assert_true(r.residual < 1e-11 * r.scale);
    gs_system_free(&s);
}

/* A pitch error turns one tooth's flanks along the pitch circle by e / r
 * and leaves the other teeth where they were. */
static void pitch_error_geometry(void **state)
{
    (void)state;
    gs_scene *sc = NULL;
    gs_diag d;
    const char *t = gs_scene_builtin("planetary_contact");
    assert_int_equal(gs_scene_parse(t, strlen(t), &sc, &d), GS_OK);
    gs_scene_body b = sc->bodies[gs_scene_find_body(sc, "sun")];
    gs_mesh *m0 = NULL, *m1 = NULL;
    assert_int_equal(gs_scene_gear_mesh(&b, &m0, &d), GS_OK);
    b.pitch_error_tooth = 5;
    b.pitch_error = 20e-6;
    assert_int_equal(gs_scene_gear_mesh(&b, &m1, &d), GS_OK);
    double r = gs_gear_pitch_radius(&b.gear), worst_on = 0, worst_off = 0;
    for (int tooth = 0; tooth < m0->n_teeth; tooth++)
        for (int side = 0; side < 2; side++)
            for (gs_index k = m0->flank_ptr[2 * tooth + side]; k < m0->flank_ptr[2 * tooth + side + 1]; k++) {
                gs_index n = m0->flank_nodes[k];
                double a0 = atan2(m0->xy[2 * n + 1], m0->xy[2 * n]);
                double a1 = atan2(m1->xy[2 * n + 1], m1->xy[2 * n]);
                double rad = hypot(m0->xy[2 * n], m0->xy[2 * n + 1]);
                double da = remainder(a1 - a0, 2 * GS_PI);
                if (rad < 0.5 * (r + gs_gear_root_radius(&b.gear)))
                    continue; /* the fading band near the root */
                if (tooth == 5)
                    worst_on = fmax(worst_on, fabs(da * r - 20e-6));
                else
                    worst_off = fmax(worst_off, fabs(da));
            }
    print_message("pitch error 20 um on tooth 5 of the sun: flank nodes of tooth 5 off by at most %.2e m, "
                  "others moved by at most %.2e rad\n", worst_on, worst_off);
    assert_true(worst_on < 1e-12);
    assert_true(worst_off == 0.0);
    gs_mesh_free(&m0);
    gs_mesh_free(&m1);
    gs_scene_free(&sc);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(perfect_train),
        cmocka_unit_test(pin_error),
        cmocka_unit_test(fidelity_switch),
        cmocka_unit_test(pitch_error_geometry),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
