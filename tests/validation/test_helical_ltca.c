/* SPDX-License-Identifier: MIT
 * The ltca mesh on helical pairs (docs/explanation/helical.md "Helical
 * pairs in the ltca rung"): tables of the slice analysis, rigid gears in
 * the transverse plane.
 *  - helical_pair (as shipped, `fidelity: "ltca"`) and helical_crowned
 *    (crowned pinion, 20 um misalignment in the plane of action), their
 *    brakes raised so that the wheel turns at 20 rad/s (mesh frequency
 *    95.5 Hz, far below the mesh mode near 8.3 kHz), over the second half of
 *    a run whose half spans 12 mesh cycles: the mean dynamic TE within 1 %
 *    and its rms about the mean (DTE rms) within 3 % of the quasi-static
 *    TE of the slice analysis run here at the run's mean mesh force, at 24
 *    roll positions that are none of the table's 48; the energy balance
 *    residual at round-off (1e-12 of the energy scale) at every step;
 *  - helical_pair as shipped (lumped mesh) at its own speed: the energy
 *    balance at round-off;
 *  - the table key: changed by the crowning, the misalignment, the helix
 *    angle; the spur pairs' keys as before (their shipped tables found);
 *  - refusals naming the field: lead modifications on a lumped mesh, a
 *    run-out on a helical ltca mesh.
 * The tables of both scenes are shipped in deploy/ltca (a checkout without
 * them builds them on first use, about 30 CPU s each). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "gearsim/ltca.h"
#include "gearsim/stiffness.h"
#include "gearsim/step.h"
#include "gearsim/util.h"
#include "../common/steady_half.h"

/* The scene text txt parsed with add inserted at `at` (a place in txt). */
static gs_scene *spliced(const char *txt, const char *at, const char *add)
{
    assert_non_null(at);
    size_t n = strlen(txt), pre = (size_t)(at - txt), k = strlen(add);
    char *s = malloc(n + k + 1);
    assert_non_null(s);
    memcpy(s, txt, pre);
    memcpy(s + pre, add, k);
    memcpy(s + pre + k, txt + pre, n - pre + 1);
    gs_scene *sc;
    gs_diag d;
    gs_err e = gs_scene_parse(s, strlen(s), &sc, &d);
    free(s);
    if (e != GS_OK)
        fprintf(stderr, "%s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    return sc;
}

/* The shipped scene, at the ltca rung when `ltca`. */
static gs_scene *scene(const char *name, int ltca)
{
    const char *txt = gs_scene_builtin(name);
    assert_non_null(txt);
    const char *brace = strchr(txt, '{');
    assert_non_null(brace);
    return spliced(txt, brace + 1, ltca ? "\"fidelity\": \"ltca\", " : "");
}

static gs_system *system_of(gs_scene *sc, double h)
{
    sc->time_step = h;
    gs_system *sys;
    gs_diag d;
    gs_err e = gs_system_new(sc, 0, 1, &sys, &d);
    if (e != GS_OK)
        fprintf(stderr, "%s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    return sys;
}

/* Mean and rms about it of the slice analysis's loaded static TE (m) at
 * the mesh force F (N): 24 positions at phase 0.25 / 24. */
static void slice_te(const gs_scene *sc, double F, double *mean, double *rms)
{
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    o.positions = 24;
    o.phase = 0.25 / 24;
    o.tangent = 0;
    gs_stiffness_result r;
    gs_diag d;
    assert_int_equal(gs_stiffness_analyse(sc, 0, &o, &r, &d), GS_OK);
    o.torque_nm = (r.torque_nm < 0 ? -1.0 : 1.0) * F * r.base_radius_m;
    gs_stiffness_result_clear(&r);
    gs_err e = gs_stiffness_analyse(sc, 0, &o, &r, &d);
    if (e != GS_OK)
        fprintf(stderr, "%s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    assert_true(r.slices > 0);
    double s1 = 0, s2 = 0;
    for (int j = 0; j < r.positions; j++) {
        double x = fabs(r.pt[j].te_raw_um) * 1e-6;
        s1 += x;
        s2 += x * x;
    }
    *mean = s1 / r.positions;
    *rms = sqrt(fmax(s2 / r.positions - *mean * *mean, 0));
    gs_stiffness_result_clear(&r);
}

/* Low speed: the wheel (body 1) at 20 rad/s through the brake. */
static void lowspeed(const char *name)
{
    gs_scene *sc = scene(name, 1);
    const double w = 20.0, z1 = 20, z2 = 30, h = 1e-4;
    double M0 = sc->loads[0].moment;
    assert_int_equal(sc->loads[1].type, GS_LOAD_BRAKE);
    sc->loads[1].coefficient = M0 * (z2 / z1) / w;
    double period = 2 * GS_PI / (w * z2); /* one mesh cycle */
    int half = (int)lround(12 * period / h);
    gs_system *sys = system_of(sc, h);
    steady_half r = sh_start(2 * half, gs_scene_find_body(sys->scene, "wheel"));
    for (int i = 0; i < r.n; i++)
        assert_true(sh_step(&r, sys, i));
    double speed = fabs(gs_system_angle(sys, r.body) - r.th0) / (r.half * h);
    double mean = fabs(sh_mean(&r)), rms = sh_rms(&r), F = fabs(r.fsum / r.half);
    double smean, srms;
    slice_te(sys->scene, F, &smean, &srms);
    printf("# %s ltca at %.0f rad/s (wheel), mesh force %.1f N: mean TE %.4f um (slices %.4f, %+.3f %%), "
           "DTE rms %.5f um (slices %.5f, %+.2f %%), balance %.2e of %.3g J\n",
           name, speed, F, mean * 1e6, smean * 1e6, 100 * (mean / smean - 1), rms * 1e6, srms * 1e6,
           100 * (rms / srms - 1), r.worst / r.scale, r.scale);
    assert_true(fabs(speed / w - 1) < 0.005);
    assert_true(fabs(mean / smean - 1) < 0.01);
    assert_true(fabs(rms / srms - 1) < 0.03);
    assert_true(r.worst <= 1e-12 * r.scale);
    gs_system_free(&sys);
}

static void test_pair(void **state)
{
    (void)state;
    lowspeed("helical_pair");
}

static void test_crowned(void **state)
{
    (void)state;
    lowspeed("helical_crowned");
}

/* helical_pair as shipped (lumped mesh), 60 ms at h = 1e-5. */
static void test_lumped_energy(void **state)
{
    (void)state;
    gs_system *sys = system_of(scene("helical_pair", 0), 1e-5);
    steady_half r = sh_start(6000, -1);
    for (int i = 0; i < r.n; i++)
        assert_true(sh_step(&r, sys, i));
    printf("# helical_pair lumped: balance %.2e of %.3g J over %d steps\n", r.worst / r.scale, r.scale, r.n);
    assert_true(r.scale > 0);
    assert_true(r.worst <= 1e-12 * r.scale);
    gs_system_free(&sys);
}

static void test_key(void **state)
{
    (void)state;
    gs_scene *sc = scene("helical_crowned", 0);
    uint64_t k0 = gs_ltca_key(sc, 0, NULL);
    double c = sc->bodies[0].lead.crowning;
    sc->bodies[0].lead.crowning = 0.5 * c;
    uint64_t k1 = gs_ltca_key(sc, 0, NULL);
    sc->bodies[0].lead.crowning = c;
    double mi = sc->meshes[0].misalign_in;
    sc->meshes[0].misalign_in = -mi;
    uint64_t k2 = gs_ltca_key(sc, 0, NULL);
    sc->meshes[0].misalign_in = mi;
    sc->meshes[0].misalign_out = 1e-6;
    uint64_t k3 = gs_ltca_key(sc, 0, NULL);
    sc->meshes[0].misalign_out = 0;
    double b = sc->bodies[0].gear.helix_angle;
    for (int k = 0; k < 2; k++)
        sc->bodies[k].gear.helix_angle = 1.01 * b;
    uint64_t k4 = gs_ltca_key(sc, 0, NULL);
    for (int k = 0; k < 2; k++)
        sc->bodies[k].gear.helix_angle = b;
    assert_true(k0 != k1 && k0 != k2 && k0 != k3 && k0 != k4);
    assert_true(gs_ltca_key(sc, 0, NULL) == k0);
    gs_scene_free(&sc);
    /* a spur pair's key as before: its shipped tables are found */
    const char *dir = getenv("GEARSIM_LTCA_DATA");
    assert_non_null(dir);
    sc = scene("contact_drive", 1);
    char path[4200];
    snprintf(path, sizeof path, "%s/%016llx.ltca", dir, (unsigned long long)gs_ltca_key(sc, 0, NULL));
    assert_int_equal(access(path, R_OK), 0);
    gs_scene_free(&sc);
}

static void expect_refusal(gs_scene *sc, const char *field)
{
    gs_system *sys = NULL;
    gs_diag d;
    sc->time_step = 1e-5;
    gs_err e = gs_system_new(sc, 0, 1, &sys, &d);
    printf("# refused: %s: %s\n", d.field, d.message);
    assert_int_not_equal(e, GS_OK);
    assert_string_equal(d.field, field); /* the scene went with gs_system_new */
}

static void test_refusals(void **state)
{
    (void)state;
    gs_scene *sc = scene("helical_pair", 0);
    sc->bodies[0].lead.crowning = 10e-6;
    expect_refusal(sc, "bodies[0].lead");
    sc = scene("helical_pair", 0);
    sc->meshes[0].misalign_in = 20e-6;
    expect_refusal(sc, "meshes[0].misalignment");
    /* run-out on a helical ltca mesh */
    const char *txt = gs_scene_builtin("helical_crowned");
    sc = spliced(txt, strstr(txt, "\"lead\""), "\"runout\": {\"eccentricity_um\": 5, \"phase_deg\": 0}, ");
    expect_refusal(sc, "bodies[0].runout");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_key),
        cmocka_unit_test(test_refusals),
        cmocka_unit_test(test_lumped_energy),
        cmocka_unit_test(test_pair),
        cmocka_unit_test(test_crowned),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
