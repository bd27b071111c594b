/* SPDX-License-Identifier: MIT
 * The near-field (Hertz) compliance in the dynamic contact step
 * (`"nearfield": true` on a contact mesh; docs/explanation/contact.md
 * "Near-field compliance"). On `contact_drive` (mesh frequency ~141 Hz,
 * first mesh mode ~9 kHz) at h = 1e-5 s, the kinematic TE of the mesh over
 * whole mesh cycles from 50 ms against the quasi-static TE of the analysis
 * with its near-field correction (the analysis the springs come from,
 * 192 roll positions):
 *
 *  1. the setting: refused on other mesh models, with the seed's rows, and
 *     when not a boolean, and on linear triangles (the correction is
 *     measured on quadratic ones); the error names the field;
 *  2. the default (quadratic) mesh, 50-90 ms: mean TE within 1 % of the
 *     corrected analysis; the springs are in (the elastic TE over the FE
 *     mesh's own no-load closing at least 3 % above the plain analysis's,
 *     so the comparison tells the two apart); the energy balance (the
 *     springs' energy in the potential) below 1e-9 of the scale with
 *     closure_energy and with closure;
 *  3. GEARSIM_LONG=1: h = 2e-5 s against 1e-5 s: mean within 1 % of the
 *     analysis, DTE rms of the two steps within 2 % of each other.
 * Measured, not asserted (docs/explanation/contact.md "Near-field
 * compliance"): the DTE rms is 5.6 % above the corrected analysis's TE rms
 * at h = 1e-5 s (the 2 % bar is not met). The corrected analysis without
 * its gap offsets (the node-sampled gaps the dynamic rows keep) is printed
 * too: its total rms is below the corrected analysis's (asserted); the
 * offsets raise the low harmonics as they take the node-sampling ripple
 * off, and the dynamic TE keeps that ripple (the harmonics from the 4th up,
 * tests/bench/te_harmonics.py; docs/explanation/contact.md).
 */
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
#include "contact/stiffness_hook.h"
#include "gearsim/stiffness.h"
#include "gearsim/step.h"
#include "gearsim/util.h"
#include "../common/dyn_window.h"
#include "scene_build.h"

#define MEAN_BAR 0.01

/* contact_drive with the scheme, "nearfield" nf, linear or default mesh. */
static json_object *tree(const char *scheme, int nf, int linear)
{
    json_object *root = linear ? vt_scene_linear("contact_drive") : vt_scene("contact_drive");
    vt_contact_scheme(root, scheme);
    json_object *m = json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
    json_object_object_add(m, "nearfield", json_object_new_boolean(nf));
    return root;
}

typedef struct te_stats {
    double mean, rms, te0, balance;
    int cycles;
} te_stats;

/* no_off: the correction's compliance without its gap offsets
 * (gsi_stiffness_nf_no_offsets: the rows keep the node-sampled gaps, as the
 * dynamic rows do). */
static te_stats static_te_off(int nf, int linear, int no_off)
{
    gs_scene *sc = vt_scene_parse(tree("closure_energy", 0, linear));
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    o.nearfield = nf; /* forced on (1) as the dynamic springs' table is built */
    o.positions = 192;
    o.tangent = false;
    gs_stiffness_result r;
    gs_diag d;
    gsi_stiffness_nf_no_offsets = no_off;
    gs_err e = gs_stiffness_analyse(sc, 0, &o, &r, &d);
    gsi_stiffness_nf_no_offsets = 0;
    if (e != GS_OK)
        fail_msg("stiffness: %s: %s", d.field, d.message);
    te_stats s = {0};
    for (int i = 0; i < r.positions; i++)
        s.mean += r.pt[i].te_raw_um / r.positions, s.te0 += r.pt[i].te0_um / r.positions;
    for (int i = 0; i < r.positions; i++)
        s.rms += (r.pt[i].te_raw_um - s.mean) * (r.pt[i].te_raw_um - s.mean) / r.positions;
    s.rms = sqrt(s.rms);
    gs_stiffness_result_clear(&r);
    gs_scene_free(&sc);
    return s;
}

static te_stats static_te(int nf, int linear) { return static_te_off(nf, linear, 0); }

/* h > 0: that time step instead of the scene's. */
static te_stats dynamic_te(const char *scheme, int nf, int linear, double h, double t0, double t1)
{
    json_object *root = tree(scheme, nf, linear);
    if (h > 0)
        json_object_object_add(json_object_object_get(root, "numerics"), "time_step", json_object_new_double(h));
    gs_system *s = vt_system(root);
    dyn_window w = {0};
    while (s->time < t1 - 0.5 * s->h) {
        if (gs_step_serial(s) != GS_OK)
            fail_msg("t %.6f: %s: %s", s->time, s->diag.field, s->diag.message);
        dw_energy(&w, s);
        if (s->time >= t0 - 0.5 * s->h)
            assert_int_equal(dw_sample(&w, s, 0, -1, -1), 0);
    }
    dyn_figures f;
    assert_int_equal(dw_finish(&w, &f), 0);
    te_stats r = {.mean = f.te_mean * 1e6, .rms = f.te_rms * 1e6, .balance = f.balance_rel, .cycles = f.cycles};
    dw_free(&w);
    gs_system_free(&s);
    return r;
}

static void report(const char *label, const te_stats *dy, const te_stats *st)
{
    printf("# %s, %d cycles: mean %.4f um (static %.4f, %+.3f%%), rms %.4f um (static %.4f, %+.2f%%), "
           "elastic mean %.4f um (static %.4f, %+.3f%%), balance %.1e\n",
           label, dy->cycles, dy->mean, st->mean, 100 * (dy->mean / st->mean - 1), dy->rms, st->rms,
           100 * (dy->rms / st->rms - 1), dy->mean - st->te0, st->mean - st->te0,
           100 * ((dy->mean - st->te0) / (st->mean - st->te0) - 1), dy->balance);
}

/* 1. */
static void test_setting(void **state)
{
    (void)state;
    struct {
        const char *scheme, *model;
        json_object *value;
        const char *field;
    } bad[] = {
        {"closure_energy", "lumped", json_object_new_boolean(1), "nearfield"},
        {"closure_energy", "contact", json_object_new_string("yes"), "nearfield"},
        {"seed", "contact", json_object_new_boolean(1), "meshes[0]"},
        {"closure_energy", "contact", json_object_new_boolean(1), "meshes[0]"}, /* linear triangles */
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        json_object *root = vt_scene_linear("contact_drive");
        vt_contact_scheme(root, bad[i].scheme);
        json_object *m = json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
        json_object_object_add(m, "model", json_object_new_string(bad[i].model));
        json_object_object_add(m, "nearfield", bad[i].value);
        const char *txt = json_object_to_json_string(root);
        gs_scene *sc = NULL;
        gs_system *sys = NULL;
        gs_diag d;
        gs_err e = gs_scene_parse(txt, strlen(txt), &sc, &d);
        if (e == GS_OK) { /* the system owns the scene from here */
            e = gs_system_new(sc, 0, 1, &sys, &d);
            sc = NULL;
            if (e == GS_OK)
                gs_system_free(&sys);
        }
        printf("# %s, %s: %s: %s\n", bad[i].scheme, bad[i].model, d.field, d.message);
        assert_int_not_equal(e, GS_OK);
        assert_non_null(strstr(d.field, bad[i].field));
        if (i >= 2)
            assert_non_null(strstr(d.message, i == 2 ? "closure" : "quadratic"));
        gs_scene_free(&sc);
        json_object_put(root);
    }
}

/* 2. */
static void test_follows_corrected_static(void **state)
{
    (void)state;
    te_stats snf = static_te(2, 0), splain = static_te(0, 0);
    te_stats dnf = dynamic_te("closure_energy", 1, 0, 0, 0.05, 0.09);
    report("nearfield, closure_energy, default mesh, 50-90 ms, against the corrected analysis", &dnf, &snf);
    report("nearfield, closure_energy, default mesh, 50-90 ms, against the plain analysis", &dnf, &splain);
    /* What the gap offsets account for: the corrected analysis without them
     * (its rows keep the node-sampled gaps, as the dynamic rows do). */
    te_stats snoff = static_te_off(2, 0, 1);
    report("nearfield, closure_energy, default mesh, 50-90 ms, against the analysis without gap offsets", &dnf,
           &snoff);
    printf("# corrected analysis without its gap offsets: mean %.4f um (%+.3f%%), rms %.4f um (%+.2f%%)\n",
           snoff.mean, 100 * (snoff.mean / snf.mean - 1), snoff.rms, 100 * (snoff.rms / snf.rms - 1));
    /* closure (the work booked, not returned): the balance over the start-up */
    gs_system *sc = vt_system(tree("closure", 1, 0));
    gs_energy en;
    double worst = 0, scale = 0;
    while (sc->time < 0.015)
        vt_step_balance(sc, &en, &worst, &scale);
    gs_system_free(&sc);
    te_stats dcl = {.balance = worst / scale};
    printf("# nearfield, closure, default mesh, 0-15 ms: balance %.1e of %.3g J\n", dcl.balance, scale);
    assert_true(dnf.cycles >= 4);
    assert_true(fabs(dnf.mean / snf.mean - 1) < MEAN_BAR);
    assert_true(dnf.balance < 1e-9);
    /* the springs are in: the elastic TE (over the FE mesh's own no-load
     * closing, the plain analysis' te0) at least 3 % above the plain one */
    assert_true((dnf.mean - splain.te0) / (splain.mean - splain.te0) - 1 > 0.03);
    assert_true(dcl.balance < 1e-9);
    /* Measured: without its offsets the analysis's total rms is lower, not
     * higher (0.683 against 0.703 um; the dynamic 0.7425 um): the total
     * alone does not show the ripple the dynamic rows keep. */
    assert_true(snoff.rms < snf.rms && dnf.rms > snf.rms);
}

/* 3. */
static void test_step_converged(void **state)
{
    (void)state;
    te_stats snf = static_te(2, 0);
    te_stats d1 = dynamic_te("closure_energy", 1, 0, 0, 0.05, 0.09);
    te_stats d2 = dynamic_te("closure_energy", 1, 0, 2e-5, 0.05, 0.09);
    report("nearfield, closure_energy, default mesh, h 2e-5 s, 50-90 ms", &d2, &snf);
    printf("# h 2e-5 against 1e-5 s: mean %+.3f%%, rms %+.2f%%\n", 100 * (d2.mean / d1.mean - 1),
           100 * (d2.rms / d1.rms - 1));
    assert_true(fabs(d2.mean / snf.mean - 1) < MEAN_BAR);
    assert_true(d2.balance < 1e-9);
    assert_true(fabs(d2.rms / d1.rms - 1) < 0.02); /* the two steps' DTE rms within 2 % */
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_setting),
        cmocka_unit_test(test_follows_corrected_static),
    };
    const struct CMUnitTest long_tests[] = {
        cmocka_unit_test(test_step_converged),
    };
    return RUN_GROUPS_LONG(tests, long_tests);
}
