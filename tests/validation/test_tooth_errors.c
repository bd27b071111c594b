/* SPDX-License-Identifier: MIT
 * Tooth errors (pitch errors, run-out) in the lumped and calibrated lumped
 * meshes against the DYNAMIC FE contact model at low speed (issue 17;
 * docs/explanation/geometry.md "Tooth errors: dynamic comparison with the contact
 * model" and "Run-out: the TE spectrum"). The 20/30 pair, 150 N m on the
 * pinion ramped up over 10 ms, the pinion at 40 rad/s (mesh frequency
 * 127 Hz, 0.013 of the mesh mode), h 1e-5 s, undamped gears, the contact
 * model with the `closure` contact treatment (numerics.contact; docs/
 * CONTACT.md "Contact treatments": with the seed its undamped vibration
 * scatters the statistics by 7-21 %); the runs and
 * the statistics in tests/common/te_run.h (shared with
 * tests/bench/te_errors.c). Checks (each can fail):
 *  - the once-per-revolution TE of a 20 um pinion run-out over one
 *    revolution of the lumped and calibrated meshes within TE_DYNAMIC_BAR
 *    (5 %) of the contact model's;
 *  - the window mean TE shift of +10 um pitch errors on pinion teeth 0, 4,
 *    8, 12, 16 (below) and the mean shift over the whole revolution of the
 *    lumped and calibrated meshes within TE_DYNAMIC_BAR of the contact
 *    model's; the contact model's windows scatter by less than
 *    TE_WINDOW_SCATTER_BAR (1 %) about their mean;
 *  - the contact model's perfect pair quiet at orders 19 and 21: below
 *    TE_QUIET_BAR (20 %) of the run-out sidebands' prediction;
 *  - the calibrated mesh's sidebands at orders 19 and 21 (f_mesh -+ f_rot)
 *    at the phase modulation's A_20 pi e / p_b (mean within 5 %, each
 *    within 10 %; the perfect pair's below a tenth of it);
 *  - the window mean TE shift of +10 um on pinion teeth 0, 4, 8, 12, 16
 *    (the TE over the 3 mesh cycles about a faulty tooth, minus the same
 *    angles without errors) of lumped and calibrated at linear sharing's
 *    closed form (0.5 %);
 *  - every run's energy balance within 1e-10 of the energy scale;
 *  - long mode (GEARSIM_LONG=1): the contact model over two revolutions
 *    (10 windows) against lumped and calibrated over one (5 windows: they
 *    repeat exactly), the window shift compared as above. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "../common/te_run.h"

/* Agreement of the lumped and calibrated meshes' tooth-error TE with the
 * dynamic contact model at low speed (issue 17). */
#define TE_DYNAMIC_BAR 0.05
/* Largest deviation of a single window's shift from the windows' mean in
 * the contact model (closure: 0.4 % measured; the seed's 21 %). */
#define TE_WINDOW_SCATTER_BAR 0.01
/* The contact model's perfect pair at orders z -+ 1, as a fraction of the
 * run-out sidebands' prediction A_z pi e / p_b (closure: 0.06-0.08; the
 * seed's 10-12 times the prediction). */
#define TE_QUIET_BAR 0.2

/* Tooth errors in the lumped and calibrated meshes against the dynamic
 * contact model at low speed (docs/explanation/geometry.md "Tooth errors: dynamic
 * comparison"): the 20/30 pair, 150 N m ramped up over 10 ms, the pinion at
 * 40 rad/s, undamped gears, the closure contact treatment; the statistic and
 * its scatter are printed. */
static void tooth_errors_dynamic(void **state)
{
    (void)state;
    int long_mode = getenv("GEARSIM_LONG") != NULL;
    te_study_opts o = {TE_CONTACT, 150, 40, 1e-5, 0.01, 0.01, long_mode ? 2.0 : 1.0, 0, 10, 20, 30,
                       {0, 4, 8, 12, 16}, 5, NULL, 0, "closure", 0, 0};
    te_study_result r[3];
    for (int mi = 0; mi < 3; mi++) {
        o.model = (te_model)mi;
        /* the lumped meshes' window shifts repeat every revolution to 2e-4 (no
         * noise to average), but they run 2 revolutions (cheap): the
         * rectangular law's Newton once failed near step 30 000 of this run
         * (its residual floor, docs/explanation/geometry.md), now with its phase
         * modulated by the run-out too */
        o.revs = mi != TE_CONTACT || long_mode ? 2.0 : 1.0;
        assert_int_equal(te_study(&o, &r[mi]), 0);
        for (int q = 0; q < 3; q++) {
            print_message("%-10s %-7s %ld steps: mean TE %.4f um, orders 1 %.4f, 19 %.4f, 20 %.4f, 21 %.4f um; "
                          "balance %.1e of %.1e J\n", te_model_names[mi], te_case_names[q], r[mi].steps[q],
                          r[mi].mean_te[q] * 1e6, r[mi].order[q][0] * 1e6, r[mi].order[q][1] * 1e6,
                          r[mi].order[q][2] * 1e6, r[mi].order[q][3] * 1e6, r[mi].worst[q], r[mi].scale[q]);
            assert_true(r[mi].worst[q] < 1e-10 * r[mi].scale[q]);
        }
        print_message("%-10s pitch error +10 um: mean TE shift over the 3 cycles of a faulty tooth %.4f um "
                      "(standard error %.4f, median %.4f, %d windows), over the record %.4f um; run-out 20 um: "
                      "once-per-revolution TE %.4f um\n", te_model_names[mi], r[mi].shift_mean * 1e6,
                      r[mi].shift_sem * 1e6, r[mi].shift_median * 1e6, r[mi].n_windows, r[mi].record_shift * 1e6,
                      r[mi].runout_1x * 1e6);
    }
    /* the contact model's windows: each near their mean (no vibration left
     * to average away) */
    const te_study_result *c = &r[TE_CONTACT];
    assert_true(c->n_windows >= (long_mode ? 10 : 5));
    double spread = 0;
    for (int i = 0; i < c->n_windows; i++)
        spread = fmax(spread, fabs(c->shift[i] / c->shift_mean - 1));
    print_message("contact    window shifts within %.2f%% of their mean (bar %.0f%%)\n", 100 * spread,
                  100 * TE_WINDOW_SCATTER_BAR);
    assert_true(spread < TE_WINDOW_SCATTER_BAR);
    /* the window statistic itself: lumped and calibrated at linear sharing's
     * closed form, the faulty tooth's whole contact (sigma r_b / r e) over 3 cycles */
    double closed = -cos(20 * GS_PI / 180) * 10e-6 / 3;
    for (int mi = 1; mi < 3; mi++) {
        assert_true(r[mi].n_windows >= 5);
        assert_true(fabs(r[mi].shift_mean / closed - 1) < 0.005);
        double d1x = r[mi].runout_1x / r[TE_CONTACT].runout_1x - 1;
        double dp = r[mi].shift_mean / c->shift_mean - 1;
        print_message("%-10s against contact: run-out %+.2f%%, pitch-error window shift %+.2f%% (contact's "
                      "standard error %.2f%%)", te_model_names[mi], 100 * d1x, 100 * dp,
                      100 * fabs(c->shift_sem / c->shift_mean));
        assert_true(fabs(d1x) < TE_DYNAMIC_BAR);
        assert_true(fabs(dp) < TE_DYNAMIC_BAR);
        if (!long_mode) { /* the same revolution recorded in all three */
            double dr = r[mi].record_shift / c->record_shift - 1;
            print_message(", over the revolution %+.2f%%", 100 * dr);
            assert_true(fabs(dr) < TE_DYNAMIC_BAR);
        }
        print_message(" (bar %.0f%%)\n", 100 * TE_DYNAMIC_BAR);
        /* run-out sidebands: the mesh order's phase modulated by the
         * contact point's shift along the line of action, index 2 pi e / p_b */
        double pb = GS_PI * 2.5e-3 * cos(20 * GS_PI / 180);
        double pred = r[mi].order[0][2] * GS_PI * 20e-6 / pb;
        double lo = r[mi].order[2][1], hi = r[mi].order[2][3];
        print_message("%-10s run-out sidebands: orders 19 %.4f, 21 %.4f um against A_20 pi e / p_b = %.4f um "
                      "(%+.2f%%, %+.2f%%; mean %+.2f%%); perfect gears %.4f, %.4f um\n", te_model_names[mi],
                      lo * 1e6, hi * 1e6, pred * 1e6, 100 * (lo / pred - 1), 100 * (hi / pred - 1),
                      100 * (0.5 * (lo + hi) / pred - 1), r[mi].order[0][1] * 1e6, r[mi].order[0][3] * 1e6);
        if (mi != TE_CONTACT) { /* both lumped laws carry the modulation (meshes.c, lumped_init) */
            assert_true(fabs(0.5 * (lo + hi) / pred - 1) < TE_DYNAMIC_BAR);
            assert_true(fabs(lo / pred - 1) < 2 * TE_DYNAMIC_BAR && fabs(hi / pred - 1) < 2 * TE_DYNAMIC_BAR);
            assert_true(r[mi].order[0][1] < 0.1 * pred && r[mi].order[0][3] < 0.1 * pred);
        }
    }
    /* the contact model's perfect pair: its vibration no longer hides the
     * run-out sidebands (the sidebands themselves stand at about twice the
     * prediction on the default mesh: docs/explanation/geometry.md) */
    {
        double pb = GS_PI * 2.5e-3 * cos(20 * GS_PI / 180);
        double pred = c->order[0][2] * GS_PI * 20e-6 / pb;
        print_message("contact    run-out sidebands: orders 19 %.4f, 21 %.4f um against A_20 pi e / p_b = %.4f um; "
                      "perfect gears %.4f, %.4f um (bar %.0f%% of the prediction)\n", c->order[2][1] * 1e6,
                      c->order[2][3] * 1e6, pred * 1e6, c->order[0][1] * 1e6, c->order[0][3] * 1e6,
                      100 * TE_QUIET_BAR);
        assert_true(c->order[0][1] < TE_QUIET_BAR * pred && c->order[0][3] < TE_QUIET_BAR * pred);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(tooth_errors_dynamic)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
