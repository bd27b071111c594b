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
 *     corrected analysis; the springs are in (the elastic TE over the
 *     corrected analysis's no-load closing within 1 % of its elastic TE and
 *     at least 3 % above the plain analysis's, so the comparison tells the
 *     two apart); the energy balance (the
 *     springs' energy in the potential) below 1e-9 of the scale with
 *     closure_energy and with closure;
 *     and the DTE rms within 4 % of the corrected analysis's TE rms, which
 *     needs the analysis's gap offsets on the dynamic rows (without them the
 *     rows keep the FE flanks' node-sampling ripple: +5.6 %; with them
 *     +3.1 %, of which the part locked to the mesh phase is +0.7 % and the
 *     rest a vibration of the mesh mode (7-9 kHz) not locked to the mesh,
 *     fed in every cycle where a pair leaves contact and at one node
 *     passage in single contact, not by the start-up and not by the step
 *     (+2.5 % at h = 5e-6 s): the 2 % bar on the total is not met with
 *     closure_energy, docs/explanation/contact.md "Where the part not locked
 *     comes from"); with `closure` (the closure's work booked, not given back
 *     by a velocity update that kicks the gears at those handovers) the DTE
 *     rms within 2 % of the corrected analysis's and the mean within 1 %;
 *  3. GEARSIM_LONG=1: h = 2e-5 s against 1e-5 s: mean within 1 % of the
 *     analysis, DTE rms of the two steps within 2 % of each other;
 *  4. the gap offsets' table: sampled finely enough to follow the
 *     node-sampling scallops (each step between samples small against the
 *     offsets' range), and the slope the rows take in their derivative
 *     w.r.t. gear 1's angle and the centres is that of the offset they take
 *     off their gap (central differences), so the rows linearise the gap
 *     they are held to.
 * The corrected analysis without its gap offsets is printed too: its total
 * rms is below the corrected analysis's (asserted); the offsets raise the
 * low harmonics as they take the node-sampling ripple off
 * (tests/bench/te_harmonics.py; docs/explanation/contact.md).
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
#include "contact/contact_mesh.h"
#include "contact/nearfield_dyn.h"
#include "contact/stiffness_hook.h"
#include "gearsim/stiffness.h"
#include "gearsim/step.h"
#include "gearsim/util.h"
#include "../common/dyn_window.h"
#include "scene_build.h"

#define MEAN_BAR 0.01
#define RMS_BAR 0.04
#define RMS_BAR_CLOSURE 0.02 /* with `closure`: the bar */
#define STARTUP 0.015         /* the start-up, whose balance is reported on its own */

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
    double mean, rms, te0, balance, work; /* work: the contact work booked (J) */
    double balance_startup;                /* the balance over the first STARTUP seconds */
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
    double startup = -1;
    while (s->time < t1 - 0.5 * s->h) {
        if (gs_step_serial(s) != GS_OK)
            fail_msg("t %.6f: %s: %s", s->time, s->diag.field, s->diag.message);
        dw_energy(&w, s);
        if (startup < 0 && s->time >= STARTUP)
            startup = w.worst / w.scale;
        if (s->time >= t0 - 0.5 * s->h)
            assert_int_equal(dw_sample(&w, s, 0, -1, -1), 0);
    }
    dyn_figures f;
    assert_int_equal(dw_finish(&w, &f), 0);
    te_stats r = {.mean = f.te_mean * 1e6, .rms = f.te_rms * 1e6, .balance = f.balance_rel, .cycles = f.cycles,
                  .work = w.contact_work, .balance_startup = startup};
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
    /* closure (the work booked, not returned) over 50-90 ms: no velocity
     * update gives the closure's work back, so no kick at the contact's
     * handovers rings the mesh mode; and its balance over the start-up */
    te_stats dclr = dynamic_te("closure", 1, 0, 0, 0.05, 0.09);
    te_stats dcl = {.balance = dclr.balance_startup};
    printf("# nearfield, closure, default mesh, 0-15 ms: balance %.1e\n", dcl.balance);
    report("nearfield, closure, default mesh, 50-90 ms, against the corrected analysis", &dclr, &snf);
    printf("# nearfield, closure: contact work booked %.3e J\n", dclr.work);
    assert_true(fabs(dclr.mean / snf.mean - 1) < MEAN_BAR);
    assert_true(fabs(dclr.rms / snf.rms - 1) < RMS_BAR_CLOSURE);
    assert_true(dclr.balance < 1e-9);
    assert_true(dnf.cycles >= 4);
    assert_true(fabs(dnf.mean / snf.mean - 1) < MEAN_BAR);
    assert_true(fabs(dnf.rms / snf.rms - 1) < RMS_BAR);
    assert_true(dnf.balance < 1e-9);
    /* the springs are in: the elastic TE (over the corrected analysis's
     * no-load closing, te0, which the gap offsets share) within 1 % of the
     * corrected analysis's and at least 3 % above the plain one's */
    double el = dnf.mean - snf.te0;
    assert_true(fabs(el / (snf.mean - snf.te0) - 1) < 0.01);
    assert_true(el / (splain.mean - splain.te0) - 1 > 0.03);
    assert_true(dcl.balance < 1e-9);
    /* Measured: without its offsets the analysis's total rms is lower, not
     * higher (0.683 against 0.703 um): the offsets raise the low harmonics
     * while they take the ripple off. */
    assert_true(snoff.rms < snf.rms);
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

/* 4. */
static void test_offset_table(void **state)
{
    (void)state;
    gs_scene *sc = vt_scene_parse(tree("closure_energy", 1, 0));
    gsi_nf_table *t = NULL;
    gs_diag d;
    if (gsi_nf_table_build(sc, 0, &t, &d) != GS_OK)
        fail_msg("table: %s", d.message);
    const double *key;
    const double(*off)[2];
    int n = gsi_nf_table_offsets(t, &key, &off);
    double lo = INFINITY, hi = -INFINITY, jump = 0.0;
    for (int i = 0; i < n; i++) {
        lo = fmin(lo, fmin(off[i][0], off[i][1]));
        hi = fmax(hi, fmax(off[i][0], off[i][1]));
    }
    /* the largest step between samples within the offsets' central 90 %
     * of the range of keys (the tip corners at the ends jump) */
    double k0 = key[0] + 0.05 * (key[n - 1] - key[0]), k1 = key[n - 1] - 0.05 * (key[n - 1] - key[0]);
    for (int i = 1; i < n; i++)
        if (key[i - 1] >= k0 && key[i] <= k1)
            jump = fmax(jump, fabs(off[i][0] - off[i - 1][0]));
    printf("# gap offsets: %d samples, keys %.4f..%.4f rad, offsets %.3f..%.3f um, largest step %.4f um\n", n,
           key[0], key[n - 1], lo * 1e6, hi * 1e6, jump * 1e6);
    assert_true(n > 1000);
    assert_true(hi > 0.2e-6 && hi < 10e-6 && lo > -1e-6); /* a sampling error of the flanks: below a micron or so */
    assert_true(jump < 0.1 * (hi - lo));
    /* The rows' derivatives against central differences of the offset. */
    const gs_mesh *m[2];
    gs_system *sys = vt_system(tree("closure_energy", 1, 0));
    for (int i = 0; i < 5; i++) /* the contact search of the first steps: candidates */
        assert_int_equal(gs_step_serial(sys), GS_OK);
    const gsi_contact_mesh *cm = sys->meshes[0].contact;
    for (int k = 0; k < 2; k++)
        m[k] = cm->mesh[k];
    int checked = 0;
    double worst = 0.0;
    for (gs_index j = 0; j < cm->n_cand && checked < 200; j++) {
        gs_contact_pose pose[2];
        for (int k = 0; k < 2; k++) {
            gs_system_body_pose(sys, cm->body[k], pose[k].c, &pose[k].theta);
            pose[k].u = NULL;
        }
        gs_contact_row r0;
        if (gs_contact_eval(cm->search, pose, &cm->cand[j], &r0) != GS_OK)
            continue;
        /* scan gear 1's angle over a few scallops about the current pose */
        for (int q = 0; q < 40; q++) {
            gs_contact_pose p[2] = {pose[0], pose[1]};
            p[1].theta += (q - 20) * 2e-4;
            gs_contact_row r = r0, rp = r0, rm = r0;
            r.gap.g = rp.gap.g = rm.gap.g = 0.0;
            gsi_nf_row_offset(cm->nf, m[0], m[1], &cm->cand[j], p, &r);
            if (r.gap.g == 0.0)
                continue; /* the other flanks, or no offset here */
            const double eps = 1e-7;
            gs_contact_pose pp[2] = {p[0], p[1]}, pm[2] = {p[0], p[1]};
            pp[1].theta += eps, pm[1].theta -= eps;
            gsi_nf_row_offset(cm->nf, m[0], m[1], &cm->cand[j], pp, &rp);
            gsi_nf_row_offset(cm->nf, m[0], m[1], &cm->cand[j], pm, &rm);
            double fd = (rp.gap.g - rm.gap.g) / (2 * eps), an = r.dg_dtheta[1] - r0.dg_dtheta[1];
            /* centre of gear 0 moved across the centre line */
            double dc[2] = {-(p[1].c[1] - p[0].c[1]), p[1].c[0] - p[0].c[0]}, l = hypot(dc[0], dc[1]);
            const double epc = 1e-7;
            gs_contact_pose qp[2] = {p[0], p[1]}, qm[2] = {p[0], p[1]};
            gs_contact_row rq = r0, rn = r0;
            rq.gap.g = rn.gap.g = 0.0;
            for (int i = 0; i < 2; i++)
                qp[0].c[i] += epc * dc[i] / l, qm[0].c[i] -= epc * dc[i] / l;
            gsi_nf_row_offset(cm->nf, m[0], m[1], &cm->cand[j], qp, &rq);
            gsi_nf_row_offset(cm->nf, m[0], m[1], &cm->cand[j], qm, &rn);
            double fdc = (rq.gap.g - rn.gap.g) / (2 * epc);
            double anc = ((r.dg_dc[0][0] - r0.dg_dc[0][0]) * dc[0] + (r.dg_dc[0][1] - r0.dg_dc[0][1]) * dc[1]) / l;
            /* A sample of the table between the points (a kink of the
             * piecewise linear offset) shows as one-sided differences that
             * disagree: those points are left out. */
            double scale = fmax(fabs(fd), 1e-7), scalec = fmax(fabs(fdc), 1e-7);
            if (fabs((rp.gap.g - r.gap.g) - (r.gap.g - rm.gap.g)) / eps > 1e-6 * scale ||
                fabs((rq.gap.g - r.gap.g) - (r.gap.g - rn.gap.g)) / epc > 1e-6 * scalec)
                continue;
            worst = fmax(worst, fabs(fd - an) / scale);
            worst = fmax(worst, fabs(fdc - anc) / scalec);
            checked++;
        }
    }
    printf("# offset slopes against central differences: %d rows and angles, worst %.2e relative\n", checked,
           worst);
    assert_true(checked >= 50);
    assert_true(worst < 1e-4);
    gs_system_free(&sys);
    gsi_nf_table_free(&t);
    gs_scene_free(&sc);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_setting),
        cmocka_unit_test(test_offset_table),
        cmocka_unit_test(test_follows_corrected_static),
    };
    const struct CMUnitTest long_tests[] = {
        cmocka_unit_test(test_step_converged),
    };
    return RUN_GROUPS_LONG(tests, long_tests);
}
