/* SPDX-License-Identifier: MIT
 * Elastic tooth contact (`contact` meshes) with gear centres that
 * translate (docs/explanation/planetary.md, "Contact meshes on moving
 * members"), against conservation laws and closed forms:
 *  - the contact_drive pair (seed 7.2, linear triangles) with the pinion on
 *    a bearing joint: the energy balance stays at round-off, and in the
 *    steady state the bearing carries the mean mesh force (sum of the
 *    normal contact forces): k |mean X| against it to 1e-3, and that force
 *    against c w_p / r_b,p, the normal force that holds the brake's moment
 *    c w_p at the base radius, to 1e-2;
 *  - the same with both gears on bearings and the pinion's on a soft
 *    bearing: balance at round-off;
 *  - the DTE rms (line-of-action deflection of the mesh, the bearing's
 *    give included) of the pair with the pinion on its bearing converges
 *    in h like the fixed-axis pair's (two finest steps within 2 %);
 *  - the impact mesh (rattle) with the wheel on a bearing: balance;
 *  - a free response of the contact model on a bearing against the modal
 *    analysis of the same pair with a lumped mesh of the contact's tangent
 *    stiffness: three modes within 2 %. */
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

#include "gearsim/modal.h"
#include "gearsim/step.h"
#include "scene_build.h"

/* contact_drive (linear triangles) with the named gears on bearing joints
 * of stiffness k (N/m) and damping c (N s/m), time step h (0: the scene's). */
static gs_system *pair_on_bearings(const char *const *names, int n, double k, double c, double h)
{
    json_object *root = vt_scene_linear("contact_drive");
    json_object *joints = json_object_object_get(root, "joints");
    for (size_t i = 0; i < json_object_array_length(joints); i++) {
        json_object *j = json_object_array_get_idx(joints, i);
        const char *b = json_object_get_string(json_object_object_get(j, "body"));
        for (int a = 0; a < n; a++)
            if (!strcmp(b, names[a])) {
                json_object_object_add(j, "type", json_object_new_string("bearing"));
                json_object_object_add(j, "stiffness", json_object_new_double(k));
                json_object_object_add(j, "damping", json_object_new_double(c));
            }
    }
    if (h > 0)
        json_object_object_add(json_object_object_get(root, "numerics"), "time_step", json_object_new_double(h));
    return vt_system(root);
}

typedef struct pair_run {
    double worst, scale;   /* balance residual, energy scale */
    double fk, fn, fm;     /* mean k |X| of the pinion, mean c w_p / r_b, mean mesh force */
    double dte;            /* rms of the mesh deflection about its mean */
    double moved;          /* largest |X| of the pinion */
} pair_run;

/* Run t_end seconds, averaging over [t_avg, t_end]. */
static pair_run run_pair(const char *const *names, int n, double k, double c, double h, double t_avg, double t_end)
{
    gs_system *s = pair_on_bearings(names, n, k, c, h);
    int p = gs_scene_find_body(s->scene, "pinion");
    int tc = s->bodies[p].tcoord;
    assert_true((tc >= 0) == (n > 0));
    const double cb = 0.3; /* the scene's brake on the pinion, N m s */
    double rb = gs_gear_base_radius(&s->scene->bodies[p].gear);
    pair_run r = {0};
    gs_energy e;
    double sx = 0, sy = 0, sw = 0, d1 = 0, d2 = 0;
    long steps = lround(t_end / s->h), from = lround(t_avg / s->h), cnt = 0;
    for (long i = 0; i < steps; i++) {
        vt_step_balance(s, &e, &r.worst, &r.scale);
        if (tc >= 0)
            r.moved = fmax(r.moved, hypot(s->q[tc], s->q[tc + 1]));
        if (i < from)
            continue;
        if (tc >= 0) {
            sx += s->q[tc];
            sy += s->q[tc + 1];
        }
        sw += fabs(gs_system_omega(s, p));
        r.fm += s->meshes[0].force;
        d1 += s->meshes[0].deflection;
        d2 += s->meshes[0].deflection * s->meshes[0].deflection;
        cnt++;
    }
    r.fk = k * hypot(sx / cnt, sy / cnt);
    r.fn = cb * (sw / cnt) / rb;
    r.fm /= cnt;
    r.dte = sqrt(fmax(d2 / cnt - (d1 / cnt) * (d1 / cnt), 0.0));
    gs_system_free(&s);
    return r;
}

static void pinion_bearing_carries_tooth_force(void **state)
{
    (void)state;
    const char *const names[] = {"pinion"};
    const double k = 5e7;
    /* three whole mesh cycles at the steady speed 44.4 rad/s (20 teeth) */
    const double cycle = 2 * M_PI / (20 * 20.0 * (20.0 / 30.0) / 0.3);
    pair_run r = run_pair(names, 1, k, 2000.0, 0, 0.060 - 3 * cycle, 0.060);
    print_message("pair, pinion on a bearing %.0e N/m: balance %.2e of %.2e J; k|X| %.3f N, c w_p / r_b %.3f N "
                  "(rel. %.2e), mean mesh force %.3f N (rel. %.2e); pinion up to %.2f um off centre\n",
                  k, r.worst, r.scale, r.fk, r.fn, r.fk / r.fn - 1, r.fm, r.fk / r.fm - 1, r.moved * 1e6);
    assert_true(r.worst < 1e-9 * r.scale);
    assert_true(r.moved > 1e-6); /* the centre really moves */
    /* the bearing carries the mean mesh force */
    assert_true(fabs(r.fk / r.fm - 1) < 1e-3);
    /* and that force holds the brake at about the base radius (the elastic
     * flanks' contact strays a little off the rigid line of action) */
    assert_true(fabs(r.fk / r.fn - 1) < 1e-2);
}

/* DTE rms (mesh deflection about its mean over three mesh cycles at the
 * steady state) against h, the pinion on its bearing and on a fixed axis:
 * the two finest steps within 2 % in both. */
static void dte_converges_in_h(void **state)
{
    (void)state;
    const char *const names[] = {"pinion"};
    const double hs[3] = {2e-5, 1e-5, 5e-6};
    const double cycle = 2 * M_PI / (20 * 20.0 * (20.0 / 30.0) / 0.3);
    double dte[2][3];
    for (int b = 0; b < 2; b++)
        for (int i = 0; i < 3; i++) {
            pair_run r = run_pair(names, b ? 1 : 0, 5e7, 2000.0, hs[i], 0.050 - 3 * cycle, 0.050);
            dte[b][i] = r.dte;
            print_message("pair, pinion %s, h %.0e s: DTE rms %.5f um; balance %.2e of %.2e J\n",
                          b ? "on a bearing 5e7 N/m" : "on a fixed axis", hs[i], r.dte * 1e6, r.worst, r.scale);
            assert_true(r.worst < 1e-9 * r.scale);
        }
    for (int b = 0; b < 2; b++)
        print_message("pinion %s: DTE rms change %.2f %% (2e-5 -> 1e-5), %.2f %% (1e-5 -> 5e-6)\n",
                      b ? "on a bearing" : "fixed", 100 * fabs(dte[b][1] / dte[b][0] - 1),
                      100 * fabs(dte[b][2] / dte[b][1] - 1));
    assert_true(fabs(dte[1][2] / dte[1][1] - 1) < 0.02);
    assert_true(fabs(dte[0][2] / dte[0][1] - 1) < 0.02);
}

static void both_on_bearings_balance(void **state)
{
    (void)state;
    const char *const names[] = {"pinion", "wheel"};
    pair_run r = run_pair(names, 2, 2e7, 0.0, 0, 0.0, 0.025);
    print_message("pair, both gears on undamped bearings 2e7 N/m: balance %.2e of %.2e J; pinion up to %.2f um off "
                  "centre\n", r.worst, r.scale, r.moved * 1e6);
    assert_true(r.worst < 1e-9 * r.scale);
    assert_true(r.moved > 1e-6);
}

/* The rattle scene (impact mesh, rigid gears) with the wheel on a bearing:
 * the impacts go through the bearing (the impulse along the line of action
 * moves the wheel's centre by its mass, the projection back onto the flank
 * books the bearing's potential it changes): balance at round-off over
 * 0.1 s, impacts happen and the centre moves. */
static void impact_mesh_on_bearing(void **state)
{
    (void)state;
    json_object *root = vt_scene("rattle");
    json_object *joints = json_object_object_get(root, "joints");
    for (size_t i = 0; i < json_object_array_length(joints); i++) {
        json_object *j = json_object_array_get_idx(joints, i);
        if (!strcmp(json_object_get_string(json_object_object_get(j, "body")), "wheel")) {
            json_object_object_add(j, "type", json_object_new_string("bearing"));
            json_object_object_add(j, "stiffness", json_object_new_double(2e7));
            json_object_object_add(j, "damping", json_object_new_double(100.0));
        }
    }
    gs_system *s = vt_system(root);
    int w = gs_scene_find_body(s->scene, "wheel"), tc = s->bodies[w].tcoord;
    assert_true(tc >= 0);
    double worst = 0, scale = 0, moved = 0;
    gs_energy e;
    long n = lround(0.1 / s->h);
    for (long i = 0; i < n; i++) {
        vt_step_balance(s, &e, &worst, &scale);
        moved = fmax(moved, hypot(s->q[tc], s->q[tc + 1]));
    }
    print_message("rattle, wheel on a bearing 2e7 N/m: %lld impacts, loss %.3e J, balance %.2e of %.2e J, wheel up to "
                  "%.3f um off centre\n", (long long)s->meshes[0].impacts, s->meshes[0].impact_loss, worst, scale,
                  moved * 1e6);
    assert_true(s->meshes[0].impacts > 10);
    assert_true(moved > 1e-7);
    assert_true(worst < 1e-9 * scale);
    gs_system_free(&s);
}

/* The pair on a bearing, free response of the contact model against the
 * modal analysis: the pinion rigid (1 kg, 1e-3 kg m^2, so that its modes
 * sit well below the teeth's) on a bearing of 5e7 N/m, the wheel elastic
 * and held; a moment rises by 1 N m per ms to 21 N m, falls back to 20 N m
 * over the next ms and is held, with the bearing damped (2000 N s/m: the
 * first contact's impact dies out); at 26 ms the damper is taken off, the
 * pinion kicked and its free response recorded over 15 ms.
 * The modal analysis of the same pair with a lumped mesh of the contact's
 * tangent stiffness k_t (dF/d delta over 19-21 ms of the rise, 19.5 to
 * 20.5 N m, from
 * the contact run) gives three modes (a pure bearing one and two of the
 * mesh with the bearing); each one's frequency measured from the response
 * projected on it (least squares, cos(w h) = sum (e_k+1 + e_k-1) e_k / sum
 * 2 e_k^2) against the modal frequency under the midpoint rule,
 * 2/h atan(w h / 2), within 2 %. */
static json_object *modal_pair(bool contact, double kt)
{
    json_object *root = vt_scene_linear("contact_drive");
    json_object *bodies = json_object_object_get(root, "bodies");
    for (size_t i = 0; i < json_object_array_length(bodies); i++) {
        json_object *b = json_object_array_get_idx(bodies, i);
        const char *n = json_object_get_string(json_object_object_get(b, "name"));
        if (!strcmp(n, "pinion")) {
            json_object_object_add(b, "model", json_object_new_string("rigid"));
            json_object_object_del(b, "mesh");
            json_object_object_add(b, "mass", json_object_new_double(1.0));
            json_object_object_add(b, "inertia", json_object_new_double(1e-3));
        } else if (!contact) {
            json_object_object_add(b, "model", json_object_new_string("rigid"));
            json_object_object_del(b, "mesh");
        }
    }
    json_object *joints = json_object_object_get(root, "joints");
    for (size_t i = 0; i < json_object_array_length(joints); i++) {
        json_object *j = json_object_array_get_idx(joints, i);
        const char *b = json_object_get_string(json_object_object_get(j, "body"));
        if (!strcmp(b, "pinion")) {
            json_object_object_add(j, "type", json_object_new_string("bearing"));
            json_object_object_add(j, "stiffness", json_object_new_double(5e7));
            if (contact) /* damped while loaded, then let free (below) */
                json_object_object_add(j, "damping", json_object_new_double(2000.0));
        } else {
            json_object_object_del(j, "centre_mm");
            json_object_object_add(j, "type", json_object_new_string("held"));
        }
    }
    json_object *m0 = json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
    if (!contact) {
        json_object_object_add(m0, "model", json_object_new_string("lumped"));
        json_object_object_add(m0, "stiffness", json_object_new_double(kt));
    }
    /* 1 N m per ms to 21 N m at 21 ms, back to 20 N m at 22 ms, then held */
    const double t[4] = {0.0, 0.021, 0.022, 1.0}, mo[4] = {0.0, 21.0, 20.0, 20.0};
    vt_moment_table(root, "pinion", t, mo, 4);
    return root;
}

static void modal_against_free_response(void **state)
{
    (void)state;
    gs_system *s = vt_system(modal_pair(true, 0));
    int p = gs_scene_find_body(s->scene, "pinion"), c = s->bodies[p].coord, tc = s->bodies[p].tcoord;
    assert_true(c >= 0 && tc >= 0);
    double h = s->h, f1 = 0, d1 = 0, f2 = 0, d2 = 0;
    int n1 = 0, n2 = 0;
    long ramp = lround(0.021 / h), kick = lround(0.026 / h), rec = lround(0.015 / h);
    for (long i = 0; i < kick; i++) {
        assert_int_equal(gs_step_serial(s), GS_OK);
        if (i >= ramp - lround(0.002 / h) && i < ramp - lround(0.001 / h))
            f1 += s->meshes[0].force, d1 += s->meshes[0].deflection, n1++;
        else if (i >= ramp - lround(0.001 / h) && i < ramp)
            f2 += s->meshes[0].force, d2 += s->meshes[0].deflection, n2++;
    }
    double kt = (f2 / n2 - f1 / n1) / fabs(d2 / n2 - d1 / n1);
    print_message("ramp: F %.4f -> %.4f N, deflection %.5f -> %.5f um\n", f1 / n1, f2 / n2, d1 / n1 * 1e6, d2 / n2 * 1e6);
    /* the modal analysis of the pair with a lumped mesh of stiffness k_t */
    json_object *lr = modal_pair(false, kt);
    gs_modal *m = vt_modal(lr);
    assert_int_equal(m->n, 3);
    int map[3];
    for (int b = 0; b < 3; b++)
        map[b] = m->dof_comp[b] == 2 ? c : tc + m->dof_comp[b];
    /* undamped from here: kick and record */
    assert_int_equal(s->n_joints, 1);
    s->joints[0].c[0] = s->joints[0].c[1] = 0.0;
    double q0[8];
    for (int a = 0; a < s->n_coords && a < 8; a++)
        q0[a] = s->q[a];
    s->w[tc] += 3e-3;
    s->w[c] += 3e-3 / 0.0235;
    double *eta = calloc((size_t)(3 * (rec + 1)), sizeof(double));
    assert_non_null(eta);
    for (long k = 0; k <= rec; k++) {
        if (k > 0)
            assert_int_equal(gs_step_serial(s), GS_OK);
        for (int j = 0; j < 3; j++) {
            double v = 0;
            for (int a = 0; a < 3; a++) {
                double mq = 0;
                for (int b = 0; b < 3; b++)
                    mq += m->M[(size_t)b * 3 + a] * (s->q[map[b]] - q0[map[b]]);
                v += m->shape[(size_t)j * 3 + a] * mq;
            }
            eta[3 * k + j] = v;
        }
    }
    double worst = 0;
    for (int j = 0; j < 3; j++) {
        /* about the mode's mean (the equilibrium is the ramp's end, up to a
         * small residual of the quasi-static loading) */
        double mean = 0;
        for (long k = 0; k <= rec; k++)
            mean += eta[3 * k + j];
        mean /= (double)(rec + 1);
        double num = 0, den = 0;
        for (long k = 1; k < rec; k++) {
            double e0 = eta[3 * k + j] - mean;
            num += (eta[3 * (k + 1) + j] - mean + eta[3 * (k - 1) + j] - mean) * e0;
            den += 2 * e0 * e0;
        }
        double wm = acos(num / den) / h, w = sqrt(m->omega2[j]), wmid = 2 / h * atan(w * h / 2);
        print_message("pair on a bearing, k_t %.4e N/m: mode %d modal %.2f Hz (midpoint rule %.2f Hz), free response "
                      "of the contact model %.2f Hz (rel. %+.2e)\n",
                      kt, j + 1, w / (2 * M_PI), wmid / (2 * M_PI), wm / (2 * M_PI), wm / wmid - 1);
        worst = fmax(worst, fabs(wm / wmid - 1));
    }
    free(eta);
    gs_modal_free(&m);
    gs_system_free(&s);
    assert_true(worst < 0.02);
}

int main(void)
{
    if (getenv("GEARSIM_TEST_FILTER"))
        cmocka_set_test_filter(getenv("GEARSIM_TEST_FILTER"));
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(pinion_bearing_carries_tooth_force),
        cmocka_unit_test(both_on_bearings_balance),
        cmocka_unit_test(dte_converges_in_h),
        cmocka_unit_test(impact_mesh_on_bearing),
        cmocka_unit_test(modal_against_free_response),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
