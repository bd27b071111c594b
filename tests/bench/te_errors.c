/* SPDX-License-Identifier: MIT
 * Tooth errors in the dynamic models (docs/explanation/geometry.md "Tooth errors:
 * dynamic comparison"): the 20/30 pair at low speed in the `contact`,
 * rectangular `lumped` and calibrated `lumped` meshes, each run without
 * errors, with pitch errors on some pinion teeth and with run-out of the
 * pinion, over --revs pinion revolutions after the ramp-up
 * (tests/common/te_run.h). Prints per model the mean TE shift of the pitch
 * errors (over the 3 mesh cycles centred on each faulty tooth, and over
 * the whole record), the
 * once-per-revolution TE of the run-out and the orders 1, z-1, z, z+1,
 * 2z-1, 2z, 2z+1 of the pinion's rotation, and the agreement of the lumped
 * models with the contact model; writes the TE series as CSV. Not a test:
 * long (a contact run takes some 18 000 steps per revolution at 40 rad/s).
 *
 *   te_errors [--models contact,lumped,calibrated] [--omega 40] [--torque 150]
 *             [--h 1e-5] [--ramp 0.01] [--settle 0.01] [--damping-s 0]
 *             [--revs 1] [--pitch-um 10] [--teeth 0,4,8,12,16] [--runout-um 20]
 *             [--phase-deg 30] [--contact seed|closure]
 *             [--damping-ratio 0 --damping-hz F] [--csv PREFIX]
 *
 * --csv PREFIX writes PREFIX_<model>_<case>.csv (time s, pinion angle rad,
 * TE um) for every run. --teeth lists the faulty pinion teeth (default
 * 0,4,8,12,16: windows of 3 mesh cycles that do not overlap). --contact
 * sets numerics.contact of the contact model (docs/explanation/contact.md "Contact
 * treatments"); --damping-ratio zeta at --damping-hz f gives both elastic
 * gears material damping (docs/explanation/elastic_body.md "Material damping"; not with
 * --damping-s). */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../common/te_run.h"

int main(int argc, char **argv)
{
    const char *models = "contact,lumped,calibrated", *teeth = "0,4,8,12,16";
    te_study_opts o = {TE_CONTACT, 150, 40, 1e-5, 0.01, 0.01, 1.0, 0, 10, 20, 30, {0}, 0, NULL, 0, NULL, 0, 0};
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!v) {
            fprintf(stderr, "%s: value missing\n", a);
            return 2;
        }
        i++;
        if (!strcmp(a, "--models"))
            models = v;
        else if (!strcmp(a, "--omega"))
            o.omega = atof(v);
        else if (!strcmp(a, "--torque"))
            o.torque = atof(v);
        else if (!strcmp(a, "--h"))
            o.h = atof(v);
        else if (!strcmp(a, "--ramp"))
            o.ramp = atof(v);
        else if (!strcmp(a, "--settle"))
            o.settle = atof(v);
        else if (!strcmp(a, "--revs"))
            o.revs = atof(v);
        else if (!strcmp(a, "--damping-s"))
            o.damping_s = atof(v);
        else if (!strcmp(a, "--pitch-um"))
            o.pitch_um = atof(v);
        else if (!strcmp(a, "--teeth"))
            teeth = v;
        else if (!strcmp(a, "--runout-um"))
            o.runout_um = atof(v);
        else if (!strcmp(a, "--phase-deg"))
            o.phase_deg = atof(v);
        else if (!strcmp(a, "--contact"))
            o.contact_scheme = v;
        else if (!strcmp(a, "--damping-ratio"))
            o.damping_ratio = atof(v);
        else if (!strcmp(a, "--damping-hz"))
            o.damping_hz = atof(v);
        else if (!strcmp(a, "--csv"))
            o.csv = v;
        else {
            fprintf(stderr, "unknown option %s\n", a);
            return 2;
        }
    }
    for (const char *c = teeth; *c && o.nf < TE_Z;) {
        char *end;
        long j = strtol(c, &end, 10);
        if (end == c || j < 0 || j >= TE_Z) {
            fprintf(stderr, "--teeth: tooth numbers 0..%d, comma-separated\n", TE_Z - 1);
            return 2;
        }
        o.faulty[o.nf++] = (int)j;
        c = *end == ',' ? end + 1 : end;
    }
    if (!(o.omega > 0 && o.torque > 0 && o.h > 0 && o.ramp > 0 && o.settle >= 0 && o.revs > 0) || o.nf == 0 ||
        o.damping_ratio < 0 || (o.damping_ratio > 0 && !(o.damping_hz > 0)) ||
        (o.damping_ratio > 0 && o.damping_s > 0)) {
        fprintf(stderr, "bad option value\n");
        return 2;
    }
    double f_mesh = o.omega * TE_Z / (2 * GS_PI);
    printf("20/30 pair (m 2.5, b 10 mm), %.0f N m on the pinion at %.1f rad/s (mesh frequency %.1f Hz), h %.1e s, "
           "ramp %.3f s, settle %.3f s, %.2f revolutions recorded, material damping %.2e s or %.3f at %.0f Hz "
           "(contact), contact treatment %s; pitch error %.2f um on pinion teeth %s, run-out %.2f um at %.1f deg\n",
           o.torque, o.omega, f_mesh, o.h, o.ramp, o.settle, o.revs, o.damping_s, o.damping_ratio, o.damping_hz,
           o.contact_scheme ? o.contact_scheme : "seed", o.pitch_um, teeth, o.runout_um, o.phase_deg);
    fflush(stdout);
    te_study_result res[3];
    int have[3] = {0, 0, 0};
    for (int mi = 0; mi < 3; mi++) {
        if (!strstr(models, te_model_names[mi]))
            continue;
        o.model = (te_model)mi;
        te_study_result *r = &res[mi];
        if (te_study(&o, r) != 0)
            return 1;
        have[mi] = 1;
        for (int q = 0; q < 3; q++) {
            printf("%-10s %-7s %6ld steps, mean TE %.4f um; orders of the first revolution (um)",
                   te_model_names[mi], te_case_names[q], r->steps[q], r->mean_te[q] * 1e6);
            for (int k = 0; k < TE_NORD; k++)
                printf(" %d: %.4f", te_orders[k], r->order[q][k] * 1e6);
            printf("; balance %.1e of %.1e J\n", r->worst[q], r->scale[q]);
        }
        if (r->f_mode > 0)
            printf("%-10s mesh mode %.0f Hz: mesh frequency / mode %.4f\n", te_model_names[mi], r->f_mode,
                   f_mesh / r->f_mode);
        printf("%-10s pitch error: mean TE shift over the 3 cycles of a faulty tooth %.4f um (standard error "
               "%.4f, median %.4f, %d windows:", te_model_names[mi], r->shift_mean * 1e6, r->shift_sem * 1e6,
               r->shift_median * 1e6, r->n_windows);
        for (int i = 0; i < r->n_windows; i++)
            printf(" %.3f", r->shift[i] * 1e6);
        printf("), over the record %.4f um (linear sharing %.4f); run-out: once-per-revolution TE %.4f um\n",
               r->record_shift * 1e6, -cos(20 * GS_PI / 180) * o.pitch_um * o.nf / TE_Z,
               r->runout_1x * 1e6);
        /* run-out sidebands against the phase modulation's A_z pi e / p_b
         * (docs/explanation/geometry.md "Run-out: the TE spectrum") */
        double pred = r->order[0][2] * GS_PI * o.runout_um / (GS_PI * 2.5e3 * cos(20 * GS_PI / 180));
        printf("%-10s run-out sidebands: orders 19 %.4f, 21 %.4f um (perfect gears %.4f, %.4f) against "
               "A_20 pi e / p_b = %.4f um\n", te_model_names[mi], r->order[2][1] * 1e6, r->order[2][3] * 1e6,
               r->order[0][1] * 1e6, r->order[0][3] * 1e6, pred * 1e6);
        fflush(stdout);
    }
    double kp = cos(20 * GS_PI / 180) * o.pitch_um * 1e-6;
    printf("closed forms (linear sharing): window shift %.4f um, mean over a revolution %.4f um per faulty "
           "tooth; run-out %.4f um\n", -kp / 3 * 1e6, -kp / TE_Z * 1e6, o.runout_um);
    if (have[TE_CONTACT])
        for (int mi = 1; mi < 3; mi++)
            if (have[mi])
                printf("%-10s against contact: window shift %+.2f%% (contact's standard error %.2f%%; against "
                       "its median %+.2f%%), run-out %+.2f%%\n", te_model_names[mi],
                       100 * (res[mi].shift_mean / res[0].shift_mean - 1),
                       100 * fabs(res[0].shift_sem / res[0].shift_mean),
                       100 * (res[mi].shift_median / res[0].shift_median - 1),
                       100 * (res[mi].runout_1x / res[0].runout_1x - 1));
    return 0;
}
