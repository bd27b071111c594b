/* SPDX-License-Identifier: MIT
 * Flank friction on elastic tooth contact (docs/explanation/contact_treatments.md,
 * "Flank friction"): the driven and braked pair of deploy/scenes/contact_drive.json
 * (both gears elastic, linear triangles, closure_energy) with Coulomb
 * friction mu = 0.05, no material damping, checked against
 *  - ISO/TR 14179-2: mesh efficiency 1 - mu H_v of the same pair, H_v from
 *    the geometry (tests/common/iso14179.h), within 0.3 points;
 *  - itself in h: the friction loss over four mesh cycles of the steady
 *    state at h = 2e-5, 1e-5 and 5e-6 s, the two finest within 2 %;
 *  - Coulomb's law at the pitch point: the friction force on the tooth pair
 *    passing it changes sign once, with no other sign change within 5 steps
 *    (the explicit scheme, whose force follows the sign of the rigid sliding
 *    velocity at the step's start, is run beside it and its count printed);
 *  - Coulomb's law on every loaded row: |F_t| <= mu F_n, with rows in stick
 *    (|F_t| < mu F_n) and in slip (|F_t| = mu F_n) both seen;
 *  - the energy balance at round-off (the friction work booked as
 *    dissipated).
 * Scene keys refused where they do not belong are checked too. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include <json-c/json.h>

#include "../common/iso14179.h"
#include "gearsim/contact.h"
#include "gearsim/step.h"
#include "scene_build.h"

#define MU 0.05
/* The pair (deploy/scenes/contact_drive.json): wheel 30 teeth at the
 * origin, pinion 20 teeth at 62.5 mm, module 2.5 mm, 20 deg. */
#define Z_WHEEL 30.0
#define Z_PINION 20.0
#define MODULE 2.5e-3
#define ALPHA (20.0 * GS_PI / 180.0)

typedef struct run_result {
    double h;
    double loss, work_in, eff;        /* over four mesh cycles from 30 ms */
    double worst, scale;              /* balance residual, energy scale */
    int episodes, reversals;          /* pitch passages seen whole, sign changes in them */
    int chatter;                      /* sign changes with another within 5 steps */
    int max_changes;                  /* most sign changes in one passage */
    long stick, slip;                 /* loaded friction rows in stick / in slip */
    double coulomb;                   /* max (|F_t| - mu F_n) / (mu F_n) over loaded rows */
    double seconds;
} run_result;

/* One run: time step, friction_scheme (NULL: the default), material
 * damping_s of both gears (0: none), the default quadratic mesh instead of
 * linear triangles. */
typedef struct run_opts {
    double h;
    const char *scheme;
    double damping_s;
    bool quadratic;
} run_opts;

static gs_system *build(const run_opts *o)
{
    json_object *root = o->quadratic ? vt_scene("contact_drive") : vt_scene_linear("contact_drive");
    json_object *m = json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
    json_object_object_add(m, "friction", json_object_new_double(MU));
    if (o->scheme)
        json_object_object_add(m, "friction_scheme", json_object_new_string(o->scheme));
    json_object_object_add(json_object_object_get(root, "numerics"), "time_step", json_object_new_double(o->h));
    json_object *bs = json_object_object_get(root, "bodies");
    for (size_t i = 0; i < 2 && o->damping_s > 0; i++) {
        json_object *mat = json_object_new_object();
        json_object_object_add(mat, "damping_s", json_object_new_double(o->damping_s));
        json_object_object_add(json_object_array_get_idx(bs, i), "material", mat);
    }
    return vt_system(root);
}

/* The friction force on the pinion along x (the line of centres: the
 * friction force lies within 20 deg of it) from the loaded rows whose slave
 * is within rho of the pitch point, and the Coulomb figures (coefficient
 * mu) of every loaded row; NAN when no loaded row is near the pitch point. */
static double pitch_force(const gs_system *s, double mu, double rho, run_result *r)
{
    const double P[2] = {0.5 * Z_WHEEL * MODULE, 0.0};
    double fx = 0.0;
    bool any = false;
    for (int i = 0; i < gs_step_contact_rows(s); i++) {
        int mesh;
        double lam;
        const gs_contact_row *row = gs_step_contact_row(s, i, &mesh, &lam);
        if (!(lam > 0))
            continue;
        double gn = hypot(row->gap.grad[0], row->gap.grad[1]), fn = lam * gn;
        double ft = gs_step_contact_friction(s, i);
        double ex = (fabs(ft) - mu * fn) / (mu * fn);
        r->coulomb = fmax(r->coulomb, ex);
        if (ex < -1e-6)
            r->stick++;
        else
            r->slip++;
        if (hypot(row->x[0][0] - P[0], row->x[0][1] - P[1]) > rho)
            continue;
        /* t = (-n_y, n_x) on the slave; the pinion is gear 1 of the mesh */
        double tx = -row->gap.grad[1] / gn;
        fx += (row->body[0] == 1 ? 1.0 : -1.0) * ft * tx;
        any = true;
    }
    return any ? fx : NAN;
}

/* Sign changes of the passage f[0..n): their count, and those with another
 * within 5 steps. */
static void passage(const double *f, int n, run_result *r)
{
    int idx[1024], k = 0;
    for (int i = 1; i < n; i++)
        if ((f[i] > 0) != (f[i - 1] > 0) && f[i] != 0 && f[i - 1] != 0 && k < 1024)
            idx[k++] = i;
    r->episodes++;
    r->reversals += k;
    r->max_changes = k > r->max_changes ? k : r->max_changes;
    for (int a = 0; a < k; a++)
        for (int b = 0; b < k; b++)
            if (a != b && abs(idx[a] - idx[b]) <= 5) {
                r->chatter++;
                break;
            }
}

static run_result run(const run_opts *o)
{
    gs_system *s = build(o);
    const double h = o->h;
    run_result r = {.h = h};
    int pinion = gs_scene_find_body(s->scene, "pinion");
    const double pitch = 2 * GS_PI / Z_PINION, rho = 0.15 * GS_PI * MODULE * cos(ALPHA);
    int n0 = (int)lround(0.03 / h), cap = (int)lround(0.05 / h), n = 0;
    double *f = malloc((size_t)cap * sizeof *f);
    assert_non_null(f);
    gs_energy e;
    double th0 = 0, l0 = 0, w0 = 0;
    bool in = false;
    clock_t c0 = clock();
    for (int i = 0;; i++) {
        if (i == n0) {
            gs_system_energy(s, &e);
            th0 = gs_system_angle(s, pinion);
            l0 = s->meshes[0].friction_loss;
            w0 = e.work_in;
        }
        vt_step_balance(s, &e, &r.worst, &r.scale);
        if (i < n0)
            continue;
        double fx = pitch_force(s, MU, rho, &r);
        if (!isnan(fx) && n < cap) {
            f[n++] = fx;
            in = true;
        } else if (in) {
            if (n < cap)
                passage(f, n, &r);
            n = 0;
            in = false;
        }
        if (fabs(gs_system_angle(s, pinion) - th0) >= 4 * pitch)
            break;
    }
    r.seconds = (double)(clock() - c0) / CLOCKS_PER_SEC;
    r.loss = s->meshes[0].friction_loss - l0;
    r.work_in = e.work_in - w0;
    r.eff = 1.0 - r.loss / r.work_in;
    free(f);
    gs_system_free(&s);
    return r;
}

static void print_run(const char *what, const run_result *r)
{
    char coulomb[128] = "";
    if (strncmp(what, "implicit", 8) == 0) /* explicit: F_t is mu times the frictionless solve's F_n */
        snprintf(coulomb, sizeof coulomb, "; rows stick %ld slip %ld, max (|F_t| - mu F_n)/(mu F_n) %.1e",
                 r->stick, r->slip, r->coulomb);
    print_message("%s, h %.0e s: loss %.5f J of %.4f J in, efficiency %.3f%%; pitch passages %d, sign changes "
                  "%d (at most %d in one), %d with another within 5 steps%s; balance %.1e of %.1e J; %.0f s\n",
                  what, r->h, r->loss, r->work_in, 100 * r->eff, r->episodes, r->reversals, r->max_changes,
                  r->chatter, coulomb, r->worst, r->scale, r->seconds);
}

static run_result implicit[3]; /* h = 2e-5, 1e-5, 5e-6, run by the first test that reads them */

static void ensure_runs(void)
{
    static bool done = false;
    const double hs[3] = {2e-5, 1e-5, 5e-6};
    for (int k = 0; k < 3 && !done; k++) {
        implicit[k] = run(&(run_opts){.h = hs[k]});
        print_run("implicit", &implicit[k]);
    }
    done = true;
}

/* Mesh efficiency at h = 1e-5 s within 0.3 points of ISO/TR 14179-2. */
static void efficiency_iso(void **state)
{
    (void)state;
    ensure_runs();
    double hv = iso14179_hv(Z_PINION, Z_WHEEL, MODULE, ALPHA), eff_iso = 1 - MU * hv;
    const run_result *r = &implicit[1];
    print_message("ISO/TR 14179-2: H_v %.4f, efficiency %.3f%%; implicit at h 1e-5 s %.3f%% (%+.3f points)\n", hv,
                  100 * eff_iso, 100 * r->eff, 100 * (r->eff - eff_iso));
    assert_true(r->loss > 0);
    assert_true(fabs(r->eff - eff_iso) < 0.003);
}

/* The loss over the same four mesh cycles converges in h. */
static void loss_converges_in_h(void **state)
{
    (void)state;
    ensure_runs();
    double d1 = implicit[1].loss / implicit[0].loss - 1, d2 = implicit[2].loss / implicit[1].loss - 1;
    print_message("implicit friction loss against h: 2e-5 -> 1e-5 %+.3f%%, 1e-5 -> 5e-6 %+.3f%%\n", 100 * d1,
                  100 * d2);
    assert_true(fabs(d2) < 0.02);
}

/* The force reverses at the pitch point once per passage, without a second
 * sign change within 5 steps; Coulomb's law holds on every loaded row, with
 * stick and slip both present. */
static void pitch_reversal(void **state)
{
    (void)state;
    ensure_runs();
    run_result ex = run(&(run_opts){.h = 1e-5, .scheme = "explicit"});
    print_run("explicit", &ex);
    for (int k = 0; k < 3; k++) {
        const run_result *r = &implicit[k];
        assert_true(r->episodes >= 3);
        assert_true(r->reversals >= r->episodes);
        assert_int_equal(r->chatter, 0);
        assert_true(r->coulomb < 1e-8);
        assert_true(r->stick > 0 && r->slip > 0);
    }
}

/* The friction work and everything else booked exactly: round-off. */
static void balance(void **state)
{
    (void)state;
    ensure_runs();
    for (int k = 0; k < 3; k++)
        assert_true(implicit[k].worst < 1e-11 * implicit[k].scale);
}

/* Every mesh of the elastic planetary train (deploy/scenes/planetary_contact.json,
 * linear triangles) with implicit friction 0.05, 10 ms from rest: sun-planet
 * and planet-ring meshes (a carrier coordinate in the rows) all dissipate,
 * Coulomb's law holds on every loaded row, and the balance closes. */
static void planetary(void **state)
{
    (void)state;
    json_object *root = vt_scene_linear("planetary_contact");
    json_object *ms = json_object_object_get(root, "meshes");
    for (size_t i = 0; i < json_object_array_length(ms); i++)
        json_object_object_add(json_object_array_get_idx(ms, i), "friction", json_object_new_double(MU));
    gs_system *s = vt_system(root);
    run_result r = {0};
    gs_energy e;
    int n = (int)lround(0.01 / s->h);
    clock_t c0 = clock();
    for (int i = 0; i < n; i++) {
        vt_step_balance(s, &e, &r.worst, &r.scale);
        pitch_force(s, MU, 0.0, &r);
    }
    double lmin = INFINITY, lsum = 0;
    for (int m = 0; m < s->n_meshes; m++) {
        lmin = fmin(lmin, s->meshes[m].friction_loss);
        lsum += s->meshes[m].friction_loss;
    }
    print_message("planetary_contact, friction %.2f on its %d meshes, %d steps: friction loss %.4e J (least on a mesh "
                  "%.3e J) of %.4e J in; rows stick %ld slip %ld, max (|F_t| - mu F_n)/(mu F_n) %.1e; balance %.1e "
                  "of %.1e J; %.0f s\n",
                  MU, s->n_meshes, n, lsum, lmin, e.work_in, r.stick, r.slip, r.coulomb, r.worst, r.scale,
                  (double)(clock() - c0) / CLOCKS_PER_SEC);
    assert_true(lmin > 0);
    assert_true(r.coulomb < 1e-8);
    assert_true(r.worst < 1e-11 * r.scale);
    gs_system_free(&s);
}

/* The impacts of seed experiment 7.1 (deploy/scenes/contact_impact.json,
 * linear triangles, h = 1e-6 s) with implicit friction 0.3, under the
 * default closure_energy and the seed's rows, 2 ms: the teeth strike and
 * rebound through stick and slip, friction dissipates, Coulomb's law holds
 * on every loaded row and the balance closes. */
static void impacts(void **state)
{
    (void)state;
    const char *schemes[2] = {"closure_energy", "seed"};
    for (int k = 0; k < 2; k++) {
        json_object *root = vt_contact_scheme(vt_scene_linear("contact_impact"), schemes[k]);
        json_object *m = json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
        json_object_object_add(m, "friction", json_object_new_double(0.3));
        gs_system *s = vt_system(root);
        run_result r = {0};
        gs_energy e;
        int n = (int)lround(0.002 / s->h), hits = 0;
        bool touching = false;
        for (int i = 0; i < n; i++) {
            vt_step_balance(s, &e, &r.worst, &r.scale);
            pitch_force(s, 0.3, 0.0, &r);
            bool now = s->meshes[0].n_active > 0;
            hits += now && !touching;
            touching = now;
        }
        print_message("contact_impact (%s), friction 0.3, %d steps: %d impacts; friction loss %.4e J of %.4e J; "
                      "rows stick %ld slip %ld, max (|F_t| - mu F_n)/(mu F_n) %.1e; balance %.1e of %.1e J\n",
                      schemes[k], n, hits, s->meshes[0].friction_loss, r.scale, r.stick, r.slip, r.coulomb,
                      r.worst, r.scale);
        assert_true(hits >= 5);
        assert_true(s->meshes[0].friction_loss > 0);
        assert_true(r.coulomb < 1e-8);
        assert_true(r.worst < 1e-11 * r.scale);
        gs_system_free(&s);
    }
}

/* friction_scheme: contact meshes only, a known name. */
static void refusals(void **state)
{
    (void)state;
    const char *bad[][3] = {{"contact", "friction_scheme", "\"sometimes\""},
                            {"lumped", "friction_scheme", "\"implicit\""}};
    for (int k = 0; k < 2; k++) {
        json_object *root = vt_scene("contact_drive");
        json_object *m = json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
        json_object_object_add(m, "model", json_object_new_string(bad[k][0]));
        json_object_object_add(m, bad[k][1], json_tokener_parse(bad[k][2]));
        if (strcmp(bad[k][0], "contact") != 0) {
            json_object *bs = json_object_object_get(root, "bodies");
            for (size_t i = 0; i < json_object_array_length(bs); i++)
                json_object_object_add(json_object_array_get_idx(bs, i), "model", json_object_new_string("rigid"));
        }
        const char *txt = json_object_to_json_string(root);
        gs_scene *sc = NULL;
        gs_diag d;
        gs_err e = gs_scene_parse(txt, strlen(txt), &sc, &d);
        print_message("%s mesh with %s %s: %s, field '%s': %s\n", bad[k][0], bad[k][1], bad[k][2], gs_errcode(e),
                      d.field, d.message);
        assert_int_not_equal(e, GS_OK);
        assert_string_equal(d.field, "meshes[0].friction_scheme");
        json_object_put(root);
    }
}

/* GEARSIM_LONG=1: the figures of the documentation beside the checked
 * ones: the explicit scheme in h, both schemes with material damping
 * (damping_s 1.7e-6 s, 5 % of critical at the first torsional mesh mode),
 * and both on the default quadratic mesh; the implicit one checked there
 * as on the linear mesh. */
static void long_figures(void **state)
{
    (void)state;
    if (!getenv("GEARSIM_LONG") || strcmp(getenv("GEARSIM_LONG"), "1") != 0) {
        print_message("GEARSIM_LONG=1 for the explicit scheme in h, with damping and on the default mesh\n");
        return;
    }
    const double hs[3] = {2e-5, 1e-5, 5e-6};
    for (int k = 0; k < 3; k++) {
        run_result r = run(&(run_opts){.h = hs[k], .scheme = "explicit"});
        print_run("explicit", &r);
    }
    const char *schemes[2] = {"implicit", "explicit"};
    for (int k = 0; k < 2; k++) {
        run_result r = run(&(run_opts){.h = 1e-5, .scheme = schemes[k], .damping_s = 1.7e-6});
        print_run(k ? "explicit, damping_s 1.7e-6 s" : "implicit, damping_s 1.7e-6 s", &r);
    }
    double eff_iso = 1 - MU * iso14179_hv(Z_PINION, Z_WHEEL, MODULE, ALPHA);
    run_result q[3];
    for (int k = 0; k < 3; k++) {
        q[k] = run(&(run_opts){.h = hs[k], .quadratic = true});
        print_run("implicit, default mesh", &q[k]);
        /* at 5e-6 s the net force of the patch jitters across zero in one
         * passage (rows entering and leaving it; docs "Flank friction") */
        if (k < 2)
            assert_int_equal(q[k].chatter, 0);
        assert_true(q[k].reversals >= q[k].episodes && q[k].episodes >= 3);
        assert_true(q[k].coulomb < 1e-8);
        assert_true(q[k].worst < 1e-11 * q[k].scale);
    }
    print_message("implicit friction loss against h, default mesh: 2e-5 -> 1e-5 %+.3f%%, 1e-5 -> 5e-6 %+.3f%%; "
                  "efficiency at 1e-5 s %+.3f points from ISO/TR 14179-2\n",
                  100 * (q[1].loss / q[0].loss - 1), 100 * (q[2].loss / q[1].loss - 1), 100 * (q[1].eff - eff_iso));
    assert_true(fabs(q[1].eff - eff_iso) < 0.003);
    assert_true(fabs(q[2].loss / q[1].loss - 1) < 0.02);
    run_result r = run(&(run_opts){.h = 1e-5, .scheme = "explicit", .quadratic = true});
    print_run("explicit, default mesh", &r);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(refusals),
        cmocka_unit_test(efficiency_iso),
        cmocka_unit_test(loss_converges_in_h),
        cmocka_unit_test(pitch_reversal),
        cmocka_unit_test(balance),
        cmocka_unit_test(planetary),
        cmocka_unit_test(impacts),
        cmocka_unit_test(long_figures),
    };
    if (getenv("GEARSIM_TEST_FILTER"))
        cmocka_set_test_filter(getenv("GEARSIM_TEST_FILTER"));
    return cmocka_run_group_tests(tests, NULL, NULL);
}
