/* SPDX-License-Identifier: MIT
 * The planetary train with elastic gears in tooth contact
 * (deploy/scenes/planetary_contact.json, linear triangles) with moving
 * members (docs/explanation/planetary.md, "Contact meshes on moving
 * members"):
 *  - planets on pin bearings (1e8 N/m): the energy balance at round-off;
 *    each planet's mean offset from its pin times k equals the mean
 *    contact force on its centre (the rows' reactions) plus the
 *    centripetal force m w_c^2 R of its going round with the carrier, as
 *    vectors in the carrier's frame, to 1e-3, and the
 *    resultant of its two meshes' normal forces along the rigid lines of
 *    action, (F_s + F_r) cos(alpha_w) across the carrier radius and
 *    (F_s - F_r) sin(alpha_w) along it, to 1e-2;
 *  - a 10 um tangential pin error on planet1 with the sun on a fixed axis
 *    and floating (a bearing joint of zero stiffness): with the sun fixed
 *    planet1 is nearly unloaded, floating the three share nearly equally;
 *    the balance at round-off;
 *  - the same pin error with the sun on its axis and the ring floating (a
 *    bearing of zero radial stiffness, its rotation held by a torsional
 *    spring): the three share nearly equally, the balance at round-off.
 * The figures are printed (docs/explanation/planetary.md). */
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

#include "gearsim/contact.h"
#include "gearsim/step.h"
#include "scene_build.h"

/* 5000 steps at 1e-5 s; means over the last 2618 (three whole mesh cycles
 * of the sun relative to the carrier, as tests/validation/test_planetary_contact.c). */
enum { N_STEPS = 5000, TAIL = 2618 };

static int mesh_index(const gs_system *s, const char *name)
{
    for (int i = 0; i < s->scene->n_meshes; i++)
        if (!strcmp(s->scene->meshes[i].name, name))
            return i;
    fail_msg("no mesh %s", name);
    return -1;
}

static void pin_bearings_carry_mesh_forces(void **state)
{
    (void)state;
    const double k = 1e8;
    json_object *root = vt_scene_linear("planetary_contact");
    for (int p = 1; p <= 3; p++) {
        char name[16];
        snprintf(name, sizeof name, "planet%d", p);
        json_object *j = vt_joint_of(root, name);
        json_object_object_add(j, "bearing_stiffness", json_object_new_double(k));
        json_object_object_add(j, "bearing_damping", json_object_new_double(500.0));
    }
    gs_system *s = vt_system(root);
    int car = gs_scene_find_body(s->scene, "carrier");
    int pl[3], ms[3], mr[3];
    for (int p = 0; p < 3; p++) {
        char name[32];
        snprintf(name, sizeof name, "planet%d", p + 1);
        pl[p] = gs_scene_find_body(s->scene, name);
        assert_true(s->bodies[pl[p]].tcoord >= 0);
        snprintf(name, sizeof name, "sun-planet%d", p + 1);
        ms[p] = mesh_index(s, name);
        snprintf(name, sizeof name, "planet%d-ring", p + 1);
        mr[p] = mesh_index(s, name);
    }
    const double alpha = 20.0 * M_PI / 180.0; /* standard centre distances: alpha_w = alpha */
    double er[3] = {0}, et[3] = {0}, fs[3] = {0}, fr[3] = {0}, worst = 0, scale = 0, off = 0;
    double ex[3][2] = {{0}}, fc[3][2] = {{0}}, w2 = 0;
    gs_energy e;
    for (int i = 0; i < N_STEPS; i++) {
        vt_step_balance(s, &e, &worst, &scale);
        if (i < N_STEPS - TAIL)
            continue;
        double thc = gs_system_angle(s, car);
        w2 += gs_system_omega(s, car) * gs_system_omega(s, car);
        for (int p = 0; p < 3; p++) {
            /* the planet's offset from its pin, in the carrier's frame:
             * radial along the pin's direction, tangential across it */
            const gs_scene_body *sb = &s->scene->bodies[pl[p]];
            double c[2], th, a = sb->carrier_angle + thc;
            gs_system_body_pose(s, pl[p], c, &th);
            const double *cc = s->bodies[car].centre;
            double dx = c[0] - cc[0] - sb->carrier_radius * cos(a), dy = c[1] - cc[1] - sb->carrier_radius * sin(a);
            double F[2];
            vt_centre_force(s, pl[p], F);
            /* in the carrier's frame, like the offsets */
            double cs = cos(thc), sn = sin(thc);
            ex[p][0] += cs * dx + sn * dy, ex[p][1] += -sn * dx + cs * dy;
            fc[p][0] += cs * F[0] + sn * F[1], fc[p][1] += -sn * F[0] + cs * F[1];
            er[p] += dx * cos(a) + dy * sin(a);
            et[p] += -dx * sin(a) + dy * cos(a);
            off = fmax(off, hypot(dx, dy));
            fs[p] += s->meshes[ms[p]].force;
            fr[p] += s->meshes[mr[p]].force;
        }
    }
    double worst_rel = 0, worst_line = 0;
    for (int p = 0; p < 3; p++) {
        /* m a = F - k e, the planet's mean acceleration the centripetal
         * -w_c^2 R along its pin's direction (carrier frame) */
        const gs_scene_body *sb = &s->scene->bodies[pl[p]];
        double mc = s->bodies[pl[p]].mass * (w2 / TAIL) * sb->carrier_radius * TAIL;
        double fx0 = fc[p][0] + mc * cos(sb->carrier_angle), fy0 = fc[p][1] + mc * sin(sb->carrier_angle);
        double d = hypot(k * ex[p][0] - fx0, k * ex[p][1] - fy0) / hypot(fx0, fy0);
        print_message("planet%d: k e against the contact forces on its centre plus the centripetal m w_c^2 R "
                      "(%.4f N; mean vectors, carrier frame): |k e - F'| / |F'| = %.2e, |k e| = %.3f N, |F'| = "
                      "%.3f N\n", p + 1, mc / TAIL, d, k * hypot(ex[p][0], ex[p][1]) / TAIL, hypot(fx0, fy0) / TAIL);
        worst_rel = fmax(worst_rel, d);
        double F_s = fs[p] / TAIL, F_r = fr[p] / TAIL;
        double ft = (F_s + F_r) * cos(alpha), fq = (F_s - F_r) * sin(alpha);
        double kx = k * hypot(er[p], et[p]) / TAIL, fx = hypot(ft, fq);
        print_message("planet%d on its pin bearing %.0e N/m: offset %.4f um (radial %+.4f, tangential %+.4f); "
                      "k |e| %.3f N, mesh resultant %.3f N (sun %.3f, ring %.3f); rel. %.2e\n",
                      p + 1, k, kx / k * 1e6, er[p] / TAIL * 1e6, et[p] / TAIL * 1e6, kx, fx, F_s, F_r,
                      kx / fx - 1);
        worst_line = fmax(worst_line, fabs(kx / fx - 1));
    }
    print_message("planets on pin bearings: balance %.2e of %.2e J; largest offset %.3f um\n", worst, scale,
                  off * 1e6);
    assert_true(worst < 1e-9 * scale);
    assert_true(off > 1e-6);
    /* the bearing carries the mean mesh force */
    assert_true(worst_rel < 1e-3);
    /* which acts along the lines of action (the elastic flanks' contact
     * strays a little off the rigid involute's) */
    assert_true(worst_line < 1e-2);
    gs_system_free(&s);
}

/* Run the train `root` (consumed) n steps with the pin error; the shares
 * of the planets (from their mean normalised shares over the last `tail`
 * steps) into sh, the mean offset of `mover`'s centre (the sun or the
 * ring) into *sun_off; returns the LSF (largest share over the mean).
 * Prints them under `what`; the balance at round-off. */
static double share_run(json_object *root, int n, int tail, const char *what, const char *mover, bool floating,
                        double sh[3], double *sun_off)
{
    gs_system *s = vt_system(root);
    int sun = gs_scene_find_body(s->scene, mover);
    double acc[3] = {0, 0, 0}, worst = 0, scale = 0, off = 0;
    gs_energy e;
    for (int i = 0; i < n; i++) {
        vt_step_balance(s, &e, &worst, &scale);
        if (i < n - tail)
            continue;
        int pl[8];
        double share[8];
        assert_int_equal(gs_system_planet_shares(s, pl, share, 8), 3);
        for (int p = 0; p < 3; p++)
            acc[p] += share[p];
        int tc = s->bodies[sun].tcoord;
        if (tc >= 0)
            off += hypot(s->q[tc], s->q[tc + 1]);
    }
    double mx = 0, sum = acc[0] + acc[1] + acc[2];
    for (int p = 0; p < 3; p++) {
        sh[p] = 3.0 * acc[p] / sum;
        mx = fmax(mx, sh[p]);
    }
    *sun_off = off / tail;
    print_message("%s, pin error 10 um on planet1, %s %s: LSF %.4f (shares %.4f %.4f %.4f), %s off centre %.2f um; "
                  "balance %.2e of %.2e J\n", what, mover, floating ? "floating" : "fixed", mx, sh[0], sh[1], sh[2],
                  mover, *sun_off * 1e6, worst, scale);
    assert_true(worst < 1e-9 * scale);
    gs_system_free(&s);
    return mx;
}

/* LSF (largest planet share / mean) with a 10 um tangential pin error on
 * planet1, the sun floating or fixed; shares into sh. */
static double sharing(bool floating, double sh[3], double *sun_off)
{
    json_object *root = vt_scene_linear("planetary_contact");
    json_object *pe = json_object_new_array();
    json_object_array_add(pe, json_object_new_double(0.0));
    json_object_array_add(pe, json_object_new_double(10.0));
    json_object_object_add(vt_joint_of(root, "planet1"), "pin_error_um", pe);
    if (floating) {
        json_object *j = vt_joint_of(root, "sun");
        json_object_object_del(j, "centre_mm");
        json_object_object_add(j, "type", json_object_new_string("bearing"));
        json_object_object_add(j, "stiffness", json_object_new_double(0.0));
        json_object_object_add(j, "damping", json_object_new_double(50.0));
    }
    return share_run(root, N_STEPS, TAIL, "contact meshes", "sun", floating, sh, sun_off);
}

static void floating_sun_shares_load(void **state)
{
    (void)state;
    double fl[3], fx[3], off_fl, off_fx;
    double lsf_fl = sharing(true, fl, &off_fl), lsf_fx = sharing(false, fx, &off_fx);
    assert_true(lsf_fx > 1.3);
    assert_true(lsf_fl < 1.05);
    assert_true(off_fl > 5e-6); /* the sun moves towards planet1, about the pin error */
}

/* The ring floating: the same pin error, the sun on its axis, the ring on
 * a bearing of zero radial stiffness (1000 N s/m) with its rotation held
 * by a torsional spring of 1e7 N m/rad (10 N m s/rad): it moves about the
 * pin error and the planets share nearly equally (against the held ring,
 * floating_sun_shares_load's fixed case: LSF about 1.5). */
static void floating_ring_shares_load(void **state)
{
    (void)state;
    json_object *root = vt_scene_linear("planetary_contact");
    json_object *pe = json_object_new_array();
    json_object_array_add(pe, json_object_new_double(0.0));
    json_object_array_add(pe, json_object_new_double(10.0));
    json_object_object_add(vt_joint_of(root, "planet1"), "pin_error_um", pe);
    json_object *j = vt_joint_of(root, "ring");
    json_object_object_add(j, "type", json_object_new_string("bearing"));
    json_object_object_add(j, "stiffness", json_object_new_double(0.0));
    json_object_object_add(j, "damping", json_object_new_double(1000.0));
    json_object_object_add(j, "torsional_stiffness", json_object_new_double(1e7));
    json_object_object_add(j, "torsional_damping", json_object_new_double(10.0));
    double sh[3], off;
    double lsf = share_run(root, N_STEPS, TAIL, "contact meshes", "ring", true, sh, &off);
    assert_true(lsf < 1.05);
    assert_true(off > 5e-6); /* the ring moves, about the pin error */
}

/* The same train and pin error with calibrated lumped meshes (the
 * quasi-static FE analysis of each pair at its load: the figures to set
 * beside the contact meshes'; planetary_floating with the meshes
 * calibrated, 25000 steps, means over the last 5000). */
static double sharing_calibrated(bool floating, double sh[3], double *sun_off)
{
    json_object *root = vt_scene_linear("planetary_floating");
    json_object *meshes = json_object_object_get(root, "meshes");
    for (size_t i = 0; i < json_object_array_length(meshes); i++) {
        json_object *st = json_object_new_object();
        json_object_object_add(st, "type", json_object_new_string("calibrated"));
        json_object_object_add(json_object_array_get_idx(meshes, i), "stiffness", st);
    }
    if (!floating) {
        json_object *j = vt_joint_of(root, "sun");
        json_object_object_del(j, "stiffness");
        json_object_object_del(j, "damping");
        json_object_object_add(j, "type", json_object_new_string("fixed_axis"));
    }
    return share_run(root, 25000, 5000, "calibrated lumped meshes", "sun", floating, sh, sun_off);
}

static void calibrated_meshes_share_load(void **state)
{
    (void)state;
    double fl[3], fx[3], off_fl, off_fx;
    double lsf_fl = sharing_calibrated(true, fl, &off_fl), lsf_fx = sharing_calibrated(false, fx, &off_fx);
    assert_true(lsf_fx > 1.3);
    assert_true(lsf_fl < 1.05);
}

int main(void)
{
    if (getenv("GEARSIM_TEST_FILTER"))
        cmocka_set_test_filter(getenv("GEARSIM_TEST_FILTER"));
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(pin_bearings_carry_mesh_forces),
        cmocka_unit_test(floating_sun_shares_load),
        cmocka_unit_test(floating_ring_shares_load),
        cmocka_unit_test(calibrated_meshes_share_load),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
