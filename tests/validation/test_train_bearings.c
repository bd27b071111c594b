/* SPDX-License-Identifier: MIT
 * The elastic planetary train (deploy/scenes/planetary_contact.json,
 * linear triangles, `contact` meshes) on moving members
 * (docs/explanation/planetary.md, "Contact meshes on moving members"):
 *  - planets on pin bearings (1e8 N/m, 500 N s/m) and the sun floating:
 *    the DTE rms (each mesh's deflection about its mean over three mesh
 *    cycles, rms over the six meshes) at h = 2e-5, 1e-5 and 5e-6 s, the two
 *    finest within 2 %; at every h the energy balance at round-off and
 *    each planet's bearing carrying the mean force on its centre (k e
 *    against the contact forces plus the centripetal force) to 1e-3;
 *    GEARSIM_LONG=1 adds the fixed-axis train (rigid pins, sun on its axis)
 *    at the same steps;
 *  - the train held at its carrier and ring, the sun (rigid) floating and
 *    the planets (elastic) on pin bearings, loaded to 20 N m and let go:
 *    the free response of the contact model projected on the modes of the
 *    modal analysis (gs_modal_analyse) of the same train with lumped
 *    meshes of the contact's tangent stiffness, each mode's frequency
 *    within 2 % of the modal one under the midpoint rule for the modes
 *    below 5 kHz (the six lowest; the others printed).
 * The floating ring is in test_planetary_floating.c. */
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

static bool long_runs(void)
{
    const char *v = getenv("GEARSIM_LONG");
    return v && *v && strcmp(v, "0") != 0;
}

static json_object *body_of(json_object *root, const char *name)
{
    json_object *bs = json_object_object_get(root, "bodies");
    for (size_t i = 0; i < json_object_array_length(bs); i++) {
        json_object *b = json_object_array_get_idx(bs, i);
        if (!strcmp(json_object_get_string(json_object_object_get(b, "name")), name))
            return b;
    }
    fail_msg("no body %s", name);
    return NULL;
}

static void set_bearing(json_object *root, const char *body, double k, double c)
{
    json_object *j = vt_joint_of(root, body);
    json_object_object_del(j, "centre_mm");
    json_object_object_add(j, "type", json_object_new_string("bearing"));
    json_object_object_add(j, "stiffness", json_object_new_double(k));
    json_object_object_add(j, "damping", json_object_new_double(c));
}

static void set_pin_bearings(json_object *root, double k, double c)
{
    for (int p = 1; p <= 3; p++) {
        char name[16];
        snprintf(name, sizeof name, "planet%d", p);
        json_object *j = vt_joint_of(root, name);
        json_object_object_add(j, "bearing_stiffness", json_object_new_double(k));
        json_object_object_add(j, "bearing_damping", json_object_new_double(c));
    }
}

/* ---------------------------------------------------------------------- */
/* DTE rms against h */

typedef struct train_run {
    double dte;          /* rms over the six meshes of the deflection about its mean */
    double worst, scale; /* balance residual, energy scale */
    double bear;         /* worst |k e - F'| / |F'| over the planets (pin bearings) */
    double off;          /* largest planet offset from its pin */
} train_run;

/* planetary_contact to t_end = 50 ms at step h, means over the last three
 * mesh cycles (26.18 ms: the sun turns 30 rad/s against the carrier at the
 * steady state, 24 teeth). moving: planets on pin bearings of k (N/m),
 * 500 N s/m, the sun floating (zero stiffness, 50 N s/m). */
static train_run run_train(bool moving, double k, double h)
{
    json_object *root = vt_scene_linear("planetary_contact");
    if (moving) {
        set_pin_bearings(root, k, 500.0);
        set_bearing(root, "sun", 0.0, 50.0);
    }
    json_object_object_add(json_object_object_get(root, "numerics"), "time_step", json_object_new_double(h));
    gs_system *s = vt_system(root);
    int car = gs_scene_find_body(s->scene, "carrier");
    int pl[3];
    for (int p = 0; p < 3; p++) {
        char name[16];
        snprintf(name, sizeof name, "planet%d", p + 1);
        pl[p] = gs_scene_find_body(s->scene, name);
        assert_true((s->bodies[pl[p]].tcoord >= 0) == moving);
    }
    assert_int_equal(s->scene->n_meshes, 6);
    long n = lround(0.050 / h), tail = lround(0.02618 / h);
    double d1[6] = {0}, d2[6] = {0}, ex[3][2] = {{0}}, fc[3][2] = {{0}}, w2 = 0;
    train_run r = {0};
    gs_energy e;
    for (long i = 0; i < n; i++) {
        vt_step_balance(s, &e, &r.worst, &r.scale);
        if (i < n - tail)
            continue;
        for (int m = 0; m < 6; m++) {
            d1[m] += s->meshes[m].deflection;
            d2[m] += s->meshes[m].deflection * s->meshes[m].deflection;
        }
        if (!moving)
            continue;
        double thc = gs_system_angle(s, car), cs = cos(thc), sn = sin(thc);
        w2 += gs_system_omega(s, car) * gs_system_omega(s, car);
        for (int p = 0; p < 3; p++) {
            const gs_scene_body *sb = &s->scene->bodies[pl[p]];
            double c[2], th, a = sb->carrier_angle + thc, F[2];
            gs_system_body_pose(s, pl[p], c, &th);
            const double *cc = s->bodies[car].centre;
            double dx = c[0] - cc[0] - sb->carrier_radius * cos(a), dy = c[1] - cc[1] - sb->carrier_radius * sin(a);
            vt_centre_force(s, pl[p], F);
            ex[p][0] += cs * dx + sn * dy, ex[p][1] += -sn * dx + cs * dy;
            fc[p][0] += cs * F[0] + sn * F[1], fc[p][1] += -sn * F[0] + cs * F[1];
            r.off = fmax(r.off, hypot(dx, dy));
        }
    }
    double var = 0;
    for (int m = 0; m < 6; m++)
        var += fmax(d2[m] / (double)tail - (d1[m] / (double)tail) * (d1[m] / (double)tail), 0.0);
    r.dte = sqrt(var / 6);
    for (int p = 0; moving && p < 3; p++) {
        /* k e = F + m w_c^2 R along the pin's direction (carrier frame) */
        const gs_scene_body *sb = &s->scene->bodies[pl[p]];
        double mc = s->bodies[pl[p]].mass * w2 * sb->carrier_radius;
        double fx0 = fc[p][0] + mc * cos(sb->carrier_angle), fy0 = fc[p][1] + mc * sin(sb->carrier_angle);
        r.bear = fmax(r.bear, hypot(k * ex[p][0] - fx0, k * ex[p][1] - fy0) / hypot(fx0, fy0));
    }
    gs_system_free(&s);
    return r;
}

static void train_dte_converges_in_h(void **state)
{
    (void)state;
    const double hs[3] = {2e-5, 1e-5, 5e-6}, k = 1e8;
    double dte[2][3] = {{0}};
    int cases = long_runs() ? 2 : 1;
    for (int b = 0; b < cases; b++)
        for (int i = 0; i < 3; i++) {
            bool moving = b == 0;
            train_run r = run_train(moving, k, hs[i]);
            dte[b][i] = r.dte;
            if (moving)
                print_message("train, planets on pin bearings %.0e N/m, sun floating, h %.0e s: DTE rms %.5f um; "
                              "bearings |k e - F| / |F| %.2e; planets up to %.3f um off their pins; balance "
                              "%.2e of %.2e J\n", k, hs[i], r.dte * 1e6, r.bear, r.off * 1e6, r.worst, r.scale);
            else
                print_message("train, fixed axes, h %.0e s: DTE rms %.5f um; balance %.2e of %.2e J\n", hs[i],
                              r.dte * 1e6, r.worst, r.scale);
            assert_true(r.worst < 1e-9 * r.scale);
            if (moving) {
                assert_true(r.off > 1e-6); /* the planets really move on their pins */
                assert_true(r.bear < 1e-3); /* the bearing carries the mean force on the centre */
            }
        }
    for (int b = 0; b < cases; b++)
        print_message("train %s: DTE rms change %.2f %% (2e-5 -> 1e-5), %.2f %% (1e-5 -> 5e-6)\n",
                      b ? "on fixed axes" : "on pin bearings, sun floating", 100 * fabs(dte[b][1] / dte[b][0] - 1),
                      100 * fabs(dte[b][2] / dte[b][1] - 1));
    for (int b = 0; b < cases; b++)
        assert_true(fabs(dte[b][2] / dte[b][1] - 1) < 0.02);
}

/* ---------------------------------------------------------------------- */
/* Modal analysis against the free response */

enum { N_MODE_MAX = 12 };
/* Modes checked against the 2 % bar: those below F_CHECKED (Hz) */
#define F_CHECKED 5000.0

/* The train held at its carrier and ring, the sun rigid (1 kg, 1e-3 kg
 * m^2) on a bearing of zero stiffness, the planets on pin bearings of 1e8
 * N/m with their inertia given (the elastic ones' as the modal analysis
 * takes it). contact: the `contact` meshes, the sun's bearing and the pins
 * damped while the moment rises (1 N m per ms to 21 N m at 21 ms, back to
 * 20 N m at 22 ms, then held); else lumped meshes of stiffness kt[6]
 * and rigid planets of the same mass and inertia. */
static json_object *modal_train(bool contact, const double *kt, double planet_inertia)
{
    json_object *root = vt_scene_linear("planetary_contact");
    json_object *sun = body_of(root, "sun");
    json_object_object_add(sun, "model", json_object_new_string("rigid"));
    json_object_object_del(sun, "mesh");
    json_object_object_add(sun, "mass", json_object_new_double(1.0));
    json_object_object_add(sun, "inertia", json_object_new_double(1e-3));
    for (int p = 1; p <= 3; p++) {
        char name[16];
        snprintf(name, sizeof name, "planet%d", p);
        json_object *b = body_of(root, name);
        json_object_object_add(b, "inertia", json_object_new_double(planet_inertia));
        if (!contact) {
            json_object_object_add(b, "model", json_object_new_string("rigid"));
            json_object_object_del(b, "mesh");
        }
    }
    if (!contact) {
        json_object *ring = body_of(root, "ring");
        json_object_object_add(ring, "model", json_object_new_string("rigid"));
        json_object_object_del(ring, "mesh");
    }
    set_pin_bearings(root, 1e8, contact ? 500.0 : 0.0);
    set_bearing(root, "sun", 0.0, contact ? 2000.0 : 0.0);
    if (contact)
        json_object_object_add(vt_joint_of(root, "sun"), "torsional_damping", json_object_new_double(2.0));
    json_object *cj = vt_joint_of(root, "carrier");
    json_object_object_del(cj, "centre_mm");
    json_object_object_add(cj, "type", json_object_new_string("held"));
    if (!contact) {
        json_object *meshes = json_object_object_get(root, "meshes");
        for (size_t i = 0; i < json_object_array_length(meshes); i++) {
            json_object *m = json_object_array_get_idx(meshes, i);
            json_object_object_add(m, "model", json_object_new_string("lumped"));
            json_object_object_add(m, "stiffness", json_object_new_double(kt[i]));
        }
    }
    const double t[4] = {0.0, 0.021, 0.022, 1.0}, mo[4] = {0.0, 21.0, 20.0, 20.0};
    vt_moment_table(root, "sun", t, mo, 4);
    return root;
}

/* The frequency (Hz) of the largest peak of the spectrum of x (n samples,
 * stride `stride`, step h) between f_lo and f_hi: the Hann-windowed
 * discrete-time Fourier transform of x less its mean, searched on a grid of
 * 2e-4 of f_lo; a peak at either end of the band (none inside) returns it
 * as found, which the caller's bar then judges. */
static double peak_hz(const double *x, int stride, long n, double h, double f_lo, double f_hi)
{
    double mean = 0;
    for (long k = 0; k < n; k++)
        mean += x[(size_t)stride * k];
    mean /= (double)n;
    double best = -1, fb = f_lo, df = 2e-4 * f_lo;
    for (double f = f_lo; f <= f_hi; f += df) {
        double re = 0, im = 0, dth = 2 * M_PI * f * h;
        for (long k = 0; k < n; k++) {
            double win = 0.5 - 0.5 * cos(2 * M_PI * (double)k / (double)(n - 1));
            double v = win * (x[(size_t)stride * k] - mean);
            re += v * cos(dth * (double)k);
            im -= v * sin(dth * (double)k);
        }
        if (re * re + im * im > best)
            best = re * re + im * im, fb = f;
    }
    return fb;
}

/* At step h (s); prints the modes and fails on a checked one off by more
 * than 2 %. */
static void modal_run(double h_step)
{
    /* the planets' inertia: 1.2 times the scene's figure for the gear (at
     * least that of the elastic part; the rigid core takes the rest) */
    json_object *probe = vt_scene_linear("planetary_contact");
    gs_scene *ps = vt_scene_parse(probe);
    double Ip = 1.2 * ps->bodies[gs_scene_find_body(ps, "planet1")].inertia;
    gs_scene_free(&ps);
    json_object *cr = modal_train(true, NULL, Ip);
    json_object_object_add(json_object_object_get(cr, "numerics"), "time_step", json_object_new_double(h_step));
    gs_system *s = vt_system(cr);
    assert_int_equal(s->scene->n_meshes, 6);
    double h = s->h, f1[6] = {0}, dd1[6] = {0}, f2[6] = {0}, dd2[6] = {0};
    int n1 = 0, n2 = 0;
    long ramp = lround(0.021 / h), kick = lround(0.026 / h), rec = lround(0.020 / h);
    for (long i = 0; i < kick; i++) {
        assert_int_equal(gs_step_serial(s), GS_OK);
        bool a = i >= ramp - lround(0.002 / h) && i < ramp - lround(0.001 / h);
        bool b = i >= ramp - lround(0.001 / h) && i < ramp;
        for (int m = 0; m < 6 && (a || b); m++) {
            double *f = a ? f1 : f2, *dd = a ? dd1 : dd2;
            f[m] += s->meshes[m].force;
            dd[m] += s->meshes[m].deflection;
        }
        n1 += a, n2 += b;
    }
    double kt[6];
    for (int m = 0; m < 6; m++) {
        kt[m] = (f2[m] / n2 - f1[m] / n1) / fabs(dd2[m] / n2 - dd1[m] / n1);
        print_message("mesh %s: F %.3f -> %.3f N, deflection %.5f -> %.5f um, tangent stiffness %.4e N/m\n",
                      s->scene->meshes[m].name, f1[m] / n1, f2[m] / n2, dd1[m] / n1 * 1e6, dd2[m] / n2 * 1e6, kt[m]);
        assert_true(kt[m] > 1e7 && kt[m] < 1e10);
    }
    /* the three sun-planet meshes are in phase, so are the planet-ring
     * ones (24 / 3 and 72 / 3 whole teeth): the modal analysis takes the
     * mean of each three, so that the train's symmetry groups its modes */
    double ks = (kt[0] + kt[1] + kt[2]) / 3, kr = (kt[3] + kt[4] + kt[5]) / 3;
    print_message("mean tangent stiffness: sun-planet %.4e N/m, planet-ring %.4e N/m\n", ks, kr);
    for (int q = 0; q < 3; q++)
        kt[q] = ks, kt[3 + q] = kr;
    json_object *lr = modal_train(false, kt, Ip);
    gs_modal *m = vt_modal(lr);
    int n = m->n;
    assert_int_equal(n, 12);
    assert_int_equal(m->n_modes, n);
    int map[N_MODE_MAX];
    for (int b = 0; b < n; b++) {
        const gs_body_rt *br = &s->bodies[m->dof_body[b]];
        map[b] = m->dof_comp[b] == 2 ? br->coord : br->tcoord + m->dof_comp[b];
        assert_true(map[b] >= 0);
    }
    /* undamped from here */
    for (int j = 0; j < s->n_joints; j++)
        s->joints[j].c[0] = s->joints[j].c[1] = s->joints[j].c[2] = 0.0;
    double *q0 = malloc(sizeof(double) * (size_t)s->n_coords);
    assert_non_null(q0);
    for (int a = 0; a < s->n_coords; a++)
        q0[a] = s->q[a];
    /* kick every mode: modal velocity a_j = w_j * 0.05 um * sqrt(1 kg)
     * (a displacement of about 0.05 um in each) */
    for (int j = 0; j < n; j++) {
        double a = sqrt(fmax(m->omega2[j], 0.0)) * 5e-8 * (j % 2 ? 1.0 : -1.0);
        for (int b = 0; b < n; b++)
            s->w[map[b]] += a * m->shape[(size_t)j * n + b];
    }
    double *eta = calloc((size_t)(n * (rec + 1)), sizeof(double));
    assert_non_null(eta);
    for (long k = 0; k <= rec; k++) {
        if (k > 0)
            assert_int_equal(gs_step_serial(s), GS_OK);
        for (int j = 0; j < n; j++) {
            double v = 0;
            for (int a = 0; a < n; a++) {
                double mq = 0;
                for (int b = 0; b < n; b++)
                    mq += m->M[(size_t)b * n + a] * (s->q[map[b]] - q0[map[b]]);
                v += m->shape[(size_t)j * n + a] * mq;
            }
            eta[(size_t)n * k + j] = v;
        }
    }
    double worst = 0;
    for (int j = 0; j < n; j++) {
        double w = sqrt(m->omega2[j]), fmid = 2 / h * atan(w * h / 2) / (2 * M_PI);
        double fm = peak_hz(eta + j, n, rec + 1, h, 0.85 * fmid, 1.15 * fmid);
        int g = m->group[j];
        print_message("train on bearings, h %.0e s: mode %2d (%s, x%d) modal %.2f Hz (midpoint rule %.2f Hz), free response "
                      "of the contact model %.2f Hz (rel. %+.2e)\n", h, j + 1, gs_mode_kind_name(m->group_kind[g]),
                      m->group_mult[g], w / (2 * M_PI), fmid, fm, fm / fmid - 1);
        if (fmid < F_CHECKED)
            worst = fmax(worst, fabs(fm / fmid - 1));
    }
    free(eta);
    free(q0);
    gs_modal_free(&m);
    gs_system_free(&s);
    assert_true(worst < 0.02);
}

/* h = 1e-5 s (the scene's); GEARSIM_LONG=1 also 5e-6 s (the modes above
 * F_CHECKED printed against the step) */
static void train_modal_against_free_response(void **state)
{
    (void)state;
    modal_run(1e-5);
    if (long_runs())
        modal_run(5e-6);
}

int main(void)
{
    if (getenv("GEARSIM_TEST_FILTER"))
        cmocka_set_test_filter(getenv("GEARSIM_TEST_FILTER"));
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(train_modal_against_free_response),
        cmocka_unit_test(train_dte_converges_in_h),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
