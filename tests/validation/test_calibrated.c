/* SPDX-License-Identifier: MIT
 * The lumped mesh model calibrated from the FE model (`stiffness:
 * {type: "calibrated"}`): its stiffness over the mesh cycle comes from the
 * quasi-static FE contact analysis of the same pair (docs/explanation/stiffness.md):
 * by default the tangent stiffness dF/dTE at the load with the offset that
 * puts the spring's equilibrium under the load at the FE static TE
 * (`calibration: "tangent"`), the secant F / TE on request ("secant").
 * On the moment-induced 30/20 pair (contact_drive) the calibrated lumped run
 * (rigid gears) is compared with the FE contact run (elastic gears):
 *  - both reach the closed-form steady speed M0 (z2/z1) / c (1%);
 *  - the mean line-of-action deflection of the lumped run (its dynamic
 *    transmission error at this load) agrees with the FE quasi-static
 *    transmission error at the same load within 10%;
 *  - the balance residual of the lumped run stays at round-off through the
 *    tabulated stiffness (discrete gradient);
 *  - the mean dynamic TE of the two runs, the same quantity (line-of-action
 *    deflection less the FE backlash closing and contact penetration),
 *    agree within 10%;
 *  - the FE run (numerics.contact "closure_energy", 5 % material damping at
 *    the FE mesh mode) is linear: no step with the teeth apart; its
 *    cycle-mean frequency of the mesh velocity within 3% of its own
 *    eigenproblem's mean mode;
 *  - the first torsional mesh mode against that cycle-mean frequency: the
 *    modal calibration (k_t scaled per position to the FE pair's own
 *    eigenproblem, delta_0 keeping the static TE) within 3% in closed form
 *    (issue 8) and 5% in its own run (its free response's cycle mean,
 *    within 3% of its table's per-position modes), keeping the mean TE
 *    within 1% of the static TE at the table's own positions; the
 *    tangent calibration below it (the web's compliance in the static
 *    stiffness) by less than 15%; the spectral peaks printed;
 *  - the secant calibration, run alongside, is printed for comparison;
 * and the wall-time ratio of the two runs is printed, not asserted: speed is
 * the benchmarks' business (bench_tradeoff, docs/performance/index.md).
 * On the default quadratic mesh; linear triangles (mesh.order 1) under
 * GEARSIM_LONG=1. */
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

#include "gearsim/stiffness.h"
#include "gearsim/step.h"
#include "gearsim/util.h"
#include "scene_build.h"

typedef struct run_out {
    double speed, defl, pen, residual, scale, wall, iters; /* iters: mean per step */
    double *dte, *vel; /* per step of the tail: line-of-action deflection and its rate a . w */
    double *phase;     /* and the mesh phase c . q (cycles) */
    /* contact meshes, over the tail: share of the steps with no loaded row
     * (the teeth apart), smallest and mean |force| along the line of action */
    double apart, fmin, fmean;
} run_out;

static run_out run(gs_system *s, int n, int tail)
{
    int p = gs_scene_find_body(s->scene, "pinion");
    double th = 0, defl = 0, pen = 0, worst = 0, scale = 0;
    run_out r = {0};
    r.dte = calloc((size_t)tail, sizeof(double));
    r.vel = calloc((size_t)tail, sizeof(double));
    r.phase = calloc((size_t)tail, sizeof(double));
    assert_non_null(r.phase);
    assert_non_null(r.dte);
    assert_non_null(r.vel);
    gs_energy e;
    double t0 = gs_now();
    for (int i = 0; i < n; i++) {
        if (i == n - tail)
            th = gs_system_angle(s, p);
        assert_int_equal(gs_step_serial(s), GS_OK);
        r.iters += (double)s->last_iterations / n;
        gs_system_energy(s, &e);
        worst = fmax(worst, fabs(e.balance_residual));
        scale = fmax(scale, fmax(e.total, fmax(e.work_in, e.dissipated)));
        if (i >= n - tail) {
            const gs_gmesh_rt *m = &s->meshes[0];
            defl += m->deflection;
            pen += m->penetration;
            double v = 0, ph = 0;
            for (int j = 0; j < s->n_coords; j++) {
                v += m->a[j] * s->w[j];
                ph += m->c[j] * s->q[j];
            }
            r.phase[i - (n - tail)] = ph;
            r.dte[i - (n - tail)] = m->deflection;
            r.vel[i - (n - tail)] = v;
            if (m->ops->contact)
                r.apart += (m->n_active == 0) / (double)tail;
            r.fmin = i == n - tail ? fabs(m->force) : fmin(r.fmin, fabs(m->force));
            r.fmean += fabs(m->force) / tail;
        }
    }
    r.wall = gs_now() - t0;
    r.speed = -(gs_system_angle(s, p) - th) / (tail * s->h);
    r.defl = defl / tail;
    r.pen = pen / tail;
    r.residual = worst;
    r.scale = scale;
    return r;
}

/* Dominant frequency of x (n samples, step h) in [f0, f1]: Hann-windowed DFT
 * on a 20 Hz grid, power smoothed over +-300 Hz (the response of a
 * parametrically excited, damped mode is a comb of mesh harmonics under a
 * resonance envelope, not one line), quadratic fit at the maximum. */
static double dominant_frequency(const double *x, int n, double h, double f0, double f1)
{
    const double df = 20.0;
    const int half = 15;
    int nf = (int)((f1 - f0) / df) + 1;
    double *P = calloc((size_t)nf, sizeof(double)), *S = calloc((size_t)nf, sizeof(double));
    assert_non_null(P);
    assert_non_null(S);
    double mean = 0;
    for (int i = 0; i < n; i++)
        mean += x[i] / n;
    for (int k = 0; k < nf; k++) {
        double w = 2 * M_PI * (f0 + k * df) * h, c = 0, s = 0;
        for (int i = 0; i < n; i++) {
            double v = (x[i] - mean) * (0.5 - 0.5 * cos(2 * M_PI * i / (n - 1)));
            c += v * cos(w * i);
            s += v * sin(w * i);
        }
        P[k] = c * c + s * s;
    }
    int best = half + 1;
    for (int k = 0; k < nf; k++) {
        int cnt = 0;
        for (int j = k - half; j <= k + half; j++)
            if (j >= 0 && j < nf) {
                S[k] += P[j];
                cnt++;
            }
        S[k] /= cnt;
    }
    for (int k = 1; k < nf - 1; k++)
        if (S[k] > S[best])
            best = k;
    double a = S[best - 1], b = S[best], c = S[best + 1], den = a - 2 * b + c;
    double f = f0 + df * (best + (den != 0 ? 0.5 * (a - c) / den : 0));
    free(P);
    free(S);
    return f;
}

/* Root mean square of x about its mean. */
static double rms(const double *x, int n)
{
    double m = 0, v = 0;
    for (int i = 0; i < n; i++)
        m += x[i] / n;
    for (int i = 0; i < n; i++)
        v += (x[i] - m) * (x[i] - m) / n;
    return sqrt(v);
}

/* The midpoint rule turns a mode omega into (2/h) atan(omega h / 2): undo it. */
static double unwarp(double f, double h)
{
    return tan(M_PI * f * h) / (M_PI * h);
}

/* Cycle-mean frequency of the mode a parametrically excited run follows:
 * x (n samples, step h) band-passed to [f0, f1] (the exact DFT on the
 * window's own grid k / (n h), inverted over the band), its zero
 * crossings counted: (crossings - 1) / (2 x the time between the first
 * and the last), the midpoint rule's warp undone; over whole mesh cycles
 * (whole_cycles). The mode's frequency
 * changes over the mesh cycle with the number of loaded tooth pairs (FE
 * eigenproblem: 7.8 kHz single, 9.7 kHz double contact); the count of
 * crossings averages it over time, at steady speed the mean over the
 * cycle's positions that the eigenproblem quotes. The spectral peak
 * instead falls on the lobe the response spends most time in (the double
 * contact's), not on that mean. */
static double crossing_frequency(const double *x, int n, double h, double f0, double f1)
{
    double *y = calloc((size_t)n, sizeof(double)), *ct = malloc((size_t)n * sizeof(double)),
           *st = malloc((size_t)n * sizeof(double));
    assert_non_null(y);
    assert_non_null(ct);
    assert_non_null(st);
    for (int i = 0; i < n; i++) {
        ct[i] = cos(2 * M_PI * i / n);
        st[i] = sin(2 * M_PI * i / n);
    }
    int k0 = (int)ceil(f0 * n * h), k1 = (int)floor(f1 * n * h);
    for (int k = k0; k <= k1 && 2 * k < n; k++) {
        double c = 0, s = 0;
        for (int i = 0; i < n; i++) {
            int j = (int)(((long)k * i) % n);
            c += x[i] * ct[j];
            s += x[i] * st[j];
        }
        for (int i = 0; i < n; i++) {
            int j = (int)(((long)k * i) % n);
            y[i] += 2.0 / n * (c * ct[j] + s * st[j]);
        }
    }
    int crossings = 0;
    double first = 0, last = 0;
    for (int i = 0; i + 1 < n; i++)
        if ((y[i] < 0) != (y[i + 1] < 0)) {
            double tz = (i + y[i] / (y[i] - y[i + 1])) * h;
            if (crossings++ == 0)
                first = tz;
            last = tz;
        }
    free(y);
    free(ct);
    free(st);
    assert_true(crossings > 2);
    return unwarp((crossings - 1) / (2 * (last - first)), h);
}

/* Cycle-mean frequency of the mesh mode a lumped run follows, from its
 * free response: the run goes on from where it stands in segments of
 * `every` steps; each segment is stepped twice from the same state, as is
 * and with the mesh velocity a . w raised by dv at its start, and the
 * difference of the two mesh velocities is the free response of the
 * (time-varying) linearised pair started there: the forced response to the
 * stiffness table, the same in both, cancels. Its zero crossings in the
 * segment give the frequency there ((crossings - 1) / (2 x the time from
 * the first to the last), the midpoint rule's warp undone); the mean over
 * the segments of `cycles` whole mesh cycles is the time mean over the
 * cycle, the quantity the FE run's crossing_frequency and the
 * eigenproblem's per-position mean quote. The spectral peak of the lumped
 * run is not that: the table's roughness shapes the comb of mesh
 * harmonics under a lobe that spans the per-position modes (8.0-10.4 kHz
 * on linear triangles, where the peak of the modal run fell 4.1 % above
 * its closed form). The segment's lowest and highest figures in lo, hi;
 * the largest difference of the unkicked repeat from the run in *repeat
 * (0: the restart reproduces the run). */
static double kicked_frequency(gs_system *s, int every, double cycles, double dv, double *lo, double *hi,
                               double *repeat)
{
    const gs_gmesh_rt *m = &s->meshes[0];
    int n = s->n_coords;
    double *q0 = malloc((size_t)n * sizeof(double)), *w0 = malloc((size_t)n * sizeof(double));
    double *ya = malloc((size_t)every * sizeof(double)), *yb = malloc((size_t)every * sizeof(double));
    assert_non_null(q0);
    assert_non_null(w0);
    assert_non_null(ya);
    assert_non_null(yb);
    double aa = 0, ph0 = 0;
    for (int j = 0; j < n; j++) {
        aa += m->a[j] * m->a[j];
        ph0 += m->c[j] * s->q[j];
    }
    double sum = 0, ph = ph0;
    int segs = 0;
    *lo = 1e300;
    *hi = 0;
    *repeat = 0;
    while (fabs(ph - ph0) < cycles) {
        memcpy(q0, s->q, (size_t)n * sizeof(double));
        memcpy(w0, s->w, (size_t)n * sizeof(double));
        double t0 = s->time;
        int64_t k0 = s->step;
        for (int pass = 0; pass < 3; pass++) { /* as is, kicked, as is again */
            if (pass > 0) {
                memcpy(s->q, q0, (size_t)n * sizeof(double));
                memcpy(s->w, w0, (size_t)n * sizeof(double));
                s->time = t0;
                s->step = k0;
            }
            if (pass == 1)
                for (int j = 0; j < n; j++)
                    s->w[j] += dv * m->a[j] / aa;
            for (int i = 0; i < every; i++) {
                assert_int_equal(gs_step_serial(s), GS_OK);
                double v = 0;
                for (int j = 0; j < n; j++)
                    v += m->a[j] * s->w[j];
                if (pass == 0)
                    ya[i] = v;
                else if (pass == 1)
                    yb[i] = v - ya[i];
                else
                    *repeat = fmax(*repeat, fabs(v - ya[i]));
            }
        }
        /* the free response's crossings (the kick at t = 0: a . w jumps by dv) */
        int crossings = 0;
        double first = 0, last = 0;
        for (int i = 0; i + 1 < every; i++)
            if ((yb[i] < 0) != (yb[i + 1] < 0)) {
                double tz = (i + yb[i] / (yb[i] - yb[i + 1])) * s->h;
                if (crossings++ == 0)
                    first = tz;
                last = tz;
            }
        assert_true(crossings > 2);
        double f = unwarp((crossings - 1) / (2 * (last - first)), s->h);
        sum += f;
        segs++;
        *lo = fmin(*lo, f);
        *hi = fmax(*hi, f);
        ph = 0;
        for (int j = 0; j < n; j++)
            ph += m->c[j] * s->q[j];
    }
    free(q0);
    free(w0);
    free(ya);
    free(yb);
    return sum / segs;
}

/* The samples from the first of the tail that span whole mesh cycles (the
 * cycle mean must weigh single and double contact by their shares of a
 * cycle: 4.24 cycles in the 30 ms window would move it by 0.5 %). */
static int whole_cycles(const run_out *r, int tail)
{
    double cycles = floor(fabs(r->phase[tail - 1] - r->phase[0]));
    assert_true(cycles >= 1);
    int i = 0;
    while (i < tail && fabs(r->phase[i] - r->phase[0]) < cycles)
        i++;
    return i;
}

/* The lumped, calibrated pair: the same scene at fidelity "lumped", the
 * mesh's stiffness from the FE analysis, no backlash (the FE transmission
 * error is measured from the contact-just-closing position); calibration
 * "tangent", "secant" or NULL (the default). */
/* Element order of the elastic gears (and of the calibration): 1 pins
 * linear triangles, 2 is the default mesh. */
static int g_order = 2;

/* The FE reference run's material damping: ratio FE_ZETA at the FE pair's
 * cycle-mean mesh mode (gearsim-modal --fe, docs/explanation/modal.md: 9075.2 Hz on the
 * default mesh, 9236.3 Hz on linear triangles, 20 N m). */
#define FE_ZETA 0.05
#define FE_MODE_HZ_O2 9075.2
#define FE_MODE_HZ_O1 9236.3
/* Bars on the mesh mode: the FE run's cycle-mean frequency against its own
 * eigenproblem (the modal calibration's per-position FE modes) and the
 * modal calibration's closed form against the FE run (issue 8: 3 %), the
 * modal calibration's own run against the FE run (issue 15: 5 %). */
#define MODE_FE_EIGEN_BAR 0.03
#define MODE_CLOSED_BAR 0.03
#define MODE_RUN_BAR 0.05
/* Band of the cycle-mean frequency estimate (Hz): the mesh mode's range
 * over the cycle (7.5-10 kHz) with margin, the mesh harmonics of the
 * flank geometry below it. */
#define CROSS_F0 5000.0
#define CROSS_F1 13000.0

static json_object *drive_scene(void)
{
    json_object *root = g_order == 1 ? vt_scene_linear("contact_drive") : vt_scene("contact_drive");
    /* The FE run with the energy-exact closure (docs/explanation/contact.md): the seed's
     * scheme drops the gap, and its micrometre penetrations and tooth
     * impacts pull the run's spectral peak below the FE pair's own mesh
     * mode (7.9 kHz against 9.3 kHz on the default mesh). */
    json_object_object_add(json_object_object_get(root, "numerics"), "contact",
                           json_object_new_string("closure_energy"));
    /* Material damping on both gears, FE_ZETA at the FE pair's mesh mode
     * (the lumped meshes' default 5 % of theirs): the reference run's
     * vibration about the loaded state then decays as the lumped runs' does.
     * Undamped or damped, no step of the window has the teeth apart (a row
     * loaded at every step; asserted below). */
    json_object *bs = json_object_object_get(root, "bodies");
    for (size_t i = 0; i < json_object_array_length(bs); i++) {
        json_object *mat = json_object_new_object();
        json_object_object_add(mat, "damping_ratio", json_object_new_double(FE_ZETA));
        json_object_object_add(mat, "damping_hz", json_object_new_double(g_order == 1 ? FE_MODE_HZ_O1 : FE_MODE_HZ_O2));
        json_object_object_add(json_object_array_get_idx(bs, i), "material", mat);
    }
    return root;
}

static gs_system *lumped_calibrated(const char *calibration)
{
    json_object *root = drive_scene();
    json_object_object_add(root, "fidelity", json_object_new_string("lumped"));
    json_object *tree = NULL;
    json_object_deep_copy(root, &tree, NULL);
    json_object_put(root);
    json_object *bs = json_object_object_get(tree, "bodies");
    for (size_t i = 0; i < json_object_array_length(bs); i++)
        json_object_object_add(json_object_array_get_idx(bs, i), "model", json_object_new_string("rigid"));
    json_object_object_del(tree, "fidelity");
    for (size_t i = 0; i < json_object_array_length(bs); i++)
        json_object_object_del(json_object_array_get_idx(bs, i), "material"); /* rigid: no material damping */
    json_object *m = json_object_array_get_idx(json_object_object_get(tree, "meshes"), 0);
    json_object_object_add(m, "model", json_object_new_string("lumped"));
    json_object *st = json_object_new_object();
    json_object_object_add(st, "type", json_object_new_string("calibrated"));
    json_object_object_add(st, "positions", json_object_new_int(24));
    if (calibration)
        json_object_object_add(st, "calibration", json_object_new_string(calibration));
    json_object_object_add(m, "stiffness", st);
    return vt_system(tree);
}

/* Mean of the calibrated table (k or delta_0), min and max. */
static double table_stats(const double *t, int n, double *lo, double *hi)
{
    double mean = 0;
    *lo = 1e300;
    *hi = -1e300;
    for (int j = 0; j < n; j++) {
        *lo = fmin(*lo, t[j]);
        *hi = fmax(*hi, t[j]);
        mean += t[j] / n;
    }
    return mean;
}

static void calibrated_run(void)
{
    const int n = 6000, tail = 3000;
    print_message("element order %d\n", g_order);
    gs_system *lum = lumped_calibrated(NULL); /* the default: tangent */
    gs_system *sec = lumped_calibrated("secant");
    gs_system *mod = lumped_calibrated("modal");
    const gs_gmesh_rt *gmod = &mod->meshes[0];
    const gs_gmesh_rt *gm = &lum->meshes[0], *gsec = &sec->meshes[0];
    double kmin, kmax, dmin, dmax, smin, smax;
    assert_non_null(gm->d0_table);
    assert_null(gsec->d0_table);
    double kmean = table_stats(gm->k_table, gm->n_table, &kmin, &kmax);
    double d0mean = table_stats(gm->d0_table, gm->n_table, &dmin, &dmax);
    double ksec = table_stats(gsec->k_table, gsec->n_table, &smin, &smax);
    double mmin, mmax, mdmin, mdmax;
    double kmod = table_stats(gmod->k_table, gmod->n_table, &mmin, &mmax);
    double d0mod = table_stats(gmod->d0_table, gmod->n_table, &mdmin, &mdmax);
    print_message("calibrated modal stiffness: min/mean/max %.4g / %.4g / %.4g N/m (tangent x %.4f in the mean); "
                  "offset delta_0 min/mean/max %.4g / %.4g / %.4g m\n", mmin, kmod, mmax, kmod / kmean, mdmin, d0mod,
                  mdmax);
    print_message("calibrated tangent stiffness: %d positions, min/mean/max %.4g / %.4g / %.4g N/m; offset "
                  "delta_0 min/mean/max %.4g / %.4g / %.4g m\n", gm->n_table, kmin, kmean, kmax, dmin, d0mean, dmax);
    print_message("calibrated secant stiffness: min/mean/max %.4g / %.4g / %.4g N/m\n", smin, ksec, smax);
    assert_int_equal(gm->n_table, 24);
    assert_true(kmax > kmin); /* it follows the single/double-tooth cycle */
    assert_true(dmin >= 0.0);
    assert_true(kmean > ksec); /* two-pair positions: the second pair is taken up under load */

    /* The FE quasi-static transmission error at the steady load: the brake
     * moment c w2 on the driven gear, i.e. M0 on the driver; k_tan the
     * stiffness small oscillations about the loaded state see. At the
     * calibration's own positions, the middles of 24 equal intervals of the
     * cycle (phase 1/48, src/models/meshes.c): the mean over 24 positions
     * carries a sampling error of the rough TE curve (the chords of the
     * discretised flanks), and the grid from phase 0 differs from the
     * table's by 1.1 % on linear triangles (3.785 against 3.744 um), 0.5 %
     * on the default mesh: measured against that grid, the modal run's
     * mean TE missed its 1 % bar on linear triangles (-1.34 %). */
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    o.nearfield = 0; /* the dynamic FE run has no near-field correction */
    o.positions = 24;
    o.phase = 0.5 / o.positions; /* as the calibration */
    o.tangent = 1;
    o.tangent_step = 0.05; /* as the calibration */
    o.torque_nm = 20.0;
    gs_stiffness_result sr;
    gs_diag d;
    gs_system *fe = vt_system(drive_scene());
    assert_int_equal(gs_stiffness_analyse(fe->scene, 0, &o, &sr, &d), GS_OK);
    double te = sr.te_mean * 1e-6, ktan = 0, force = sr.force_n;
    for (int j = 0; j < sr.positions; j++)
        ktan += sr.pt[j].k_tan * sr.face_width_mm * 1e6 / sr.positions;
    gs_stiffness_result_clear(&sr);
    /* The tangent table is that analysis: delta_0 + F / k_t is the static TE
     * at each of its positions (to round-off). */
    double te_table = 0;
    for (int j = 0; j < gm->n_table; j++)
        te_table += (gm->d0_table[j] + force / gm->k_table[j]) / gm->n_table;
    print_message("static TE at 20 N m over the table's 24 positions: analysis %.6e m, tangent table %.6e m\n", te,
                  te_table);
    assert_true(fabs(te_table / te - 1) < 1e-9);
    /* The cycle means under refinement in the roll, 192 positions (no
     * tangent): the static TE (the 24-position table's sampling error,
     * printed and held below 1 %: measured -0.66 % on linear triangles,
     * +0.71 % on the default mesh), and te0, the rigid closing of the flanks
     * (half the backlash from the 0.05 mm thinning, plus the chord sag of
     * the discretised flanks): the offset the FE run's line-of-action
     * deflection carries, in the time mean over the cycle (its 24-position
     * mean is 0.036 um, 1 % of the DTE, off on linear triangles). */
    o.positions = 192;
    o.phase = 0.0;
    o.tangent = 0;
    assert_int_equal(gs_stiffness_analyse(fe->scene, 0, &o, &sr, &d), GS_OK);
    double te_cycle = sr.te_mean * 1e-6, te0 = 0;
    for (int j = 0; j < sr.positions; j++)
        te0 += sr.pt[j].te0_um * 1e-6 / sr.positions;
    gs_stiffness_result_clear(&sr);
    print_message("static TE cycle mean (192 positions) %.6e m: the 24-position table %+.2f%% from it; te0 cycle mean "
                  "%.6e m\n", te_cycle, 100 * (te / te_cycle - 1), te0);
    assert_true(fabs(te / te_cycle - 1) < 0.01);

    run_out a = run(lum, n, tail);
    run_out c = run(sec, n, tail);
    run_out md = run(mod, n, tail);
    run_out b = run(fe, n, tail);
    double expect = 20.0 * (20.0 / 30.0) / 0.3;
    print_message("lumped calibrated: speed %.5f rad/s (%.2e), mean deflection %.4e m, balance %.2e of %.2e J, "
                  "wall %.4f s, %.2f iterations per step (secant calibration: %.4f s, %.2f)\n", a.speed,
                  a.speed / expect - 1, a.defl, a.residual, a.scale, a.wall, a.iters, c.wall, c.iters);
    print_message("FE contact:        speed %.5f rad/s (%.2e), FE quasi-static TE at 20 N m %.4e m, wall %.3f s\n",
                  b.speed, b.speed / expect - 1, te, b.wall);
    print_message("mean dynamic TE of the calibrated lumped run vs FE static TE: %+.2f%% (secant calibration "
                  "%+.2f%%)\n", 100 * (fabs(a.defl) / te - 1), 100 * (fabs(c.defl) / te - 1));
    assert_true(fabs(a.speed / expect - 1) < 1e-2);
    assert_true(fabs(c.speed / expect - 1) < 1e-2);
    assert_true(c.residual < 1e-11 * c.scale);
    assert_true(fabs(b.speed / expect - 1) < 1e-2);
    assert_true(a.residual < 1e-11 * a.scale);
    assert_true(fabs(fabs(a.defl) / te - 1) < 0.10);
    /* the modal calibration keeps the static TE under the load */
    print_message("modal calibration: mean dynamic TE %.4e m, %+.2f%% against the FE static TE; balance %.2e of "
                  "%.2e J\n", md.defl, 100 * (fabs(md.defl) / te - 1), md.residual, md.scale);
    assert_true(fabs(fabs(md.defl) / te - 1) < 0.01);
    assert_true(md.residual < 1e-11 * md.scale);

    /* (1) Mean dynamic transmission error, the same quantity from both runs:
     * s - s_ref = rb1 theta1 + rb2 theta2 from the exact-ratio placement
     * (backlash centred), less the rigid flank closing te0 for the FE gears
     * (the lumped mesh has no backlash), less the FE contact's penetration:
     * the step drops the gap of a row (METHOD.md section 3), so a tooth pair
     * that closes with some approach speed stays overlapped by ~|v| h and
     * the gears sit that much closer than their elastic deflection says
     * (raw mean deflection 55.84 / 55.21 / 54.86 um at h 2e-5 / 1e-5 /
     * 5e-6, less the mean deepest penetration 54.21 / 54.05 / 54.04 um:
     * only the corrected figure is converged in h). */
    double dte_lum = a.defl, dte_fe_raw = b.defl - te0, dte_fe = b.defl - te0 - b.pen;
    print_message("mean DTE: lumped calibrated %.4e m; FE contact %.4e m (mean deflection %.4e less te0 %.4e less "
                  "mean penetration %.4e); without the penetration %.4e m\n",
                  dte_lum, dte_fe, b.defl, te0, b.pen, dte_fe_raw);
    print_message("mean DTE lumped vs FE: %+.2f%% (bar 10%%; %+.2f%% against the uncorrected FE figure; secant "
                  "calibration %.4e m, %+.2f%%)\n", 100 * (dte_lum / dte_fe - 1), 100 * (dte_lum / dte_fe_raw - 1),
                  c.defl, 100 * (c.defl / dte_fe - 1));
    assert_true(fabs(dte_lum / dte_fe - 1) < 0.10);
    print_message("DTE rms about the mean (printed only): lumped calibrated %.3e m, secant calibration %.3e m, FE "
                  "contact %.3e m\n", rms(a.dte, tail), rms(c.dte, tail), rms(b.dte, tail));

    /* (2) First torsional mesh mode. Lumped: omega^2 = k_mean (rb1^2/I1 +
     * rb2^2/I2) with the calibrated (tangent) k_mean and the rigid inertias;
     * also the lumped run's own dominant frequency by the FE run's estimator.
     * FE: the cycle-mean frequency of the FE run's mesh-velocity signal
     * a . w (the rate of the DTE, which weights the mode above the low mesh
     * harmonics of the flank geometry; crossing_frequency), and, printed,
     * the dominant frequency (spectral peak) of it and of its DTE over the
     * same steady window, the midpoint rule's frequency warp undone. */
    double inv_l = 0, inv_f = 0;
    for (int i = 0; i < lum->n_bodies; i++) {
        int c = lum->bodies[i].coord;
        inv_l += gm->a[c] * gm->a[c] / lum->bodies[i].inertia_eff;
        c = fe->bodies[i].coord;
        inv_f += fe->meshes[0].a[c] * fe->meshes[0].a[c] / fe->bodies[i].inertia_eff;
    }
    double f_lum = sqrt(kmean * inv_l) / (2 * M_PI), f_tan = sqrt(ktan * inv_f) / (2 * M_PI);
    double f_sec = sqrt(ksec * inv_l) / (2 * M_PI), f_mod = sqrt(kmod * inv_l) / (2 * M_PI);
    double f_mod_peak = unwarp(dominant_frequency(md.vel, tail, mod->h, 4000, 14000), mod->h);
    double fd_fe = dominant_frequency(b.vel, tail, fe->h, 4000, 14000);
    double fd_fe_dte = dominant_frequency(b.dte, tail, fe->h, 4000, 14000);
    double f_fe_peak = unwarp(fd_fe, fe->h), f_fe_dte = unwarp(fd_fe_dte, fe->h);
    double f_lum_run = unwarp(dominant_frequency(a.vel, tail, lum->h, 4000, 14000), lum->h);
    /* The cycle-mean mode the runs follow (crossing_frequency): the FE run,
     * the modal calibration's run, the tangent one's. */
    double f_fe = crossing_frequency(b.vel, whole_cycles(&b, tail), fe->h, CROSS_F0, CROSS_F1);
    double f_mod_run = crossing_frequency(md.vel, whole_cycles(&md, tail), mod->h, CROSS_F0, CROSS_F1); /* printed */
    double f_lum_cross = crossing_frequency(a.vel, whole_cycles(&a, tail), lum->h, CROSS_F0, CROSS_F1);
    /* The FE eigenproblem's cycle mean at the same load: the modal table
     * holds k_t (f_FE / f_2)^2 per position, so sqrt(k_mod (rb1^2/I1 +
     * rb2^2/I2)) / 2 pi is f_FE there (to the difference of the two
     * analyses' tangent steps, 5 % and 10 %, and of the rigid and FE
     * inertias). */
    double f_eig = 0, f_eig_lo = 1e300, f_eig_hi = 0;
    for (int j = 0; j < gmod->n_table; j++) {
        double fj = sqrt(gmod->k_table[j] * inv_l) / (2 * M_PI);
        f_eig += fj / gmod->n_table;
        f_eig_lo = fmin(f_eig_lo, fj);
        f_eig_hi = fmax(f_eig_hi, fj);
    }
    print_message("mesh mode: lumped closed form %.0f Hz (tangent k_mean %.4g N/m; lumped run %.0f Hz spectral "
                  "peak, %.0f Hz cycle mean; secant closed form %.0f Hz); closed form with the FE tangent stiffness "
                  "%.4g N/m and the FE inertias %.0f Hz\n", f_lum, kmean, f_lum_run, f_lum_cross, f_sec, ktan, f_tan);
    print_message("FE run (damping %.0f%% at %.1f Hz): teeth apart at %.4f of the steps, |force| min / mean %.1f / "
                  "%.1f N; spectral peak %.0f Hz from the mesh velocity (%.0f Hz as stepped), %.0f Hz from the DTE "
                  "(printed only: the lobe of the double contact); cycle mean %.0f Hz; FE eigenproblem %.0f Hz "
                  "(%.0f-%.0f over %d positions): %+.2f%% (bar %.0f%%)\n", 100 * FE_ZETA,
                  g_order == 1 ? FE_MODE_HZ_O1 : FE_MODE_HZ_O2, b.apart, b.fmin, b.fmean, f_fe_peak, fd_fe, f_fe_dte,
                  f_fe, f_eig, f_eig_lo, f_eig_hi, gmod->n_table, 100 * (f_fe / f_eig - 1), 100 * MODE_FE_EIGEN_BAR);
    print_message("mesh mode, modal calibration: closed form %.0f Hz %+.2f%% against the FE run's cycle mean (bar "
                  "%.0f%%); its run's spectral peak %.0f Hz (printed), %+.2f%% against its closed form, %+.2f%% "
                  "against the FE run's cycle mean, %+.2f%% against the FE run's peak; its "
                  "run's crossing figure %.0f Hz (%+.2f%%, printed); tangent closed form %+.2f%%, its run's peak "
                  "%+.2f%%, crossing figure %.0f Hz\n", f_mod, 100 * (f_mod / f_fe - 1), 100 * MODE_CLOSED_BAR,
                  f_mod_peak, 100 * (f_mod_peak / f_mod - 1), 100 * (f_mod_peak / f_fe - 1),
                  100 * (f_mod_peak / f_fe_peak - 1), f_mod_run, 100 * (f_mod_run / f_fe - 1), 100 * (f_lum / f_fe - 1),
                  100 * (f_lum_run / f_fe - 1), f_lum_cross);
    /* The lumped runs' own cycle-mean mode from their free response
     * (kicked_frequency: 50-step segments over 4 mesh cycles, kick 1e-4 m/s
     * on a mesh velocity swinging some 3e-2 m/s), against the time mean of
     * their tables' per-position closed forms. */
    double kl_lo, kl_hi, kl_rep, km_lo, km_hi, km_rep, f_tab_tan = 0;
    for (int j = 0; j < gm->n_table; j++)
        f_tab_tan += sqrt(gm->k_table[j] * inv_l) / (2 * M_PI) / gm->n_table;
    double f_mod_kick = kicked_frequency(mod, 50, 4.0, 1e-4, &km_lo, &km_hi, &km_rep);
    double f_lum_kick = kicked_frequency(lum, 50, 4.0, 1e-4, &kl_lo, &kl_hi, &kl_rep);
    print_message("free response of the lumped runs, cycle mean (segment range): modal %.0f Hz (%.0f-%.0f), %+.2f%% "
                  "against its table's per-position mean %.0f Hz (bar 3%%), %+.2f%% against the FE run's cycle mean "
                  "(bar %.0f%%); tangent %.0f Hz (%.0f-%.0f), %+.2f%% against its table's %.0f Hz; unkicked repeat "
                  "differs by %.1e / %.1e m/s\n", f_mod_kick, km_lo, km_hi, 100 * (f_mod_kick / f_eig - 1), f_eig,
                  100 * (f_mod_kick / f_fe - 1), 100 * MODE_RUN_BAR, f_lum_kick, kl_lo, kl_hi,
                  100 * (f_lum_kick / f_tab_tan - 1), f_tab_tan, km_rep, kl_rep);
    /* The FE reference run is linear: no step of the window with the teeth
     * apart, the force far from zero. */
    assert_true(b.apart == 0.0);
    assert_true(b.fmin > 0.5 * b.fmean);
    /* Its two spectral estimates agree, and its cycle-mean frequency is its
     * own eigenproblem's (the run follows the FE pair's mesh mode). */
    assert_true(fabs(f_fe_peak / f_fe_dte - 1) < 0.02);
    assert_true(fabs(f_fe / f_eig - 1) < MODE_FE_EIGEN_BAR);
    /* Issue 8's check, met by the modal calibration: the lumped mesh mode in
     * closed form (the mean stiffness) within 3 % of the FE run's cycle mean,
     * the modal calibration's own run within 5 % of it. Each run's figure
     * is the estimator that recovers that run's own linearisation: the FE
     * run rings after every tooth pair's entry at the mode of the contact
     * state it is in (7.8 kHz single, 9.7 kHz double contact: two lobes in
     * its spectrum, the peak on the double contact's, 9561 Hz undamped,
     * 9771 Hz at 5 %), so its crossings give the cycle mean and its peak does
     * not (that was the -4.7 % / -5.9 % measured before: not a rattle, the
     * undamped run has no step with the teeth apart either); the lumped
     * runs' cycle mean comes from their free response (kicked_frequency),
     * which the forced response to the table does not reach: -0.36 % /
     * -0.32 % from the modal table's per-position mean (default mesh /
     * linear triangles), the tangent run -0.45 % / -0.36 % from its table's.
     * Their spectral peak, asserted before (within 3 % of the closed form),
     * is printed only: their comb of mesh harmonics is some 400 times weaker
     * in power than the FE run's, and where it peaks under the lobe of the
     * per-position modes depends on the table's roughness (-1.28 % on the
     * default mesh, +4.12 % on linear triangles, the tangent run's +8.9 %
     * there); their crossings in the band are pulled down by the forced
     * mesh harmonics below it (8085 Hz; printed). The FE run's ringing is
     * excited by the contact events at tooth entry, a step-size effect:
     * its power falls 2.3-3 times per halving of h, and at h 2.5e-6 the
     * cycle mean is no longer resolved (docs/explanation/stiffness.md, "A non-rattling
     * FE reference run"); the bars hold at h 2e-5 to 5e-6 (FE against its
     * eigenproblem) and at the test's 1e-5 (the closed form). */
    assert_true(fabs(f_mod / f_fe - 1) < MODE_CLOSED_BAR);
    assert_true(km_rep == 0.0 && kl_rep == 0.0); /* the restarted segments reproduce the runs */
    assert_true(fabs(f_mod_kick / f_eig - 1) < 0.03);
    assert_true(fabs(f_lum_kick / f_tab_tan - 1) < 0.03);
    assert_true(fabs(f_mod_kick / f_fe - 1) < MODE_RUN_BAR);
    /* The tangent (static, hub-to-hub) calibration lies below: the web's
     * torsional compliance is in k_t, while in the vibration most of the
     * inertia sits on the contact's side of it (docs/explanation/stiffness.md). Measured
     * -6 to -10%; the bar keeps the sign and the size. */
    assert_true(f_lum < f_fe && f_lum > 0.85 * f_fe);

    /* (3) Speed-up, same process: printed; asserted only far below the
     * measured ratio (timings on a shared machine are noisy). */
    print_message("wall time FE contact %.3f s / lumped calibrated %.4f s for %d steps: speed-up %.0fx (secant "
                  "calibration %.4f s)\n", b.wall, a.wall, n, b.wall / a.wall, c.wall);
    free(a.dte);
    free(a.vel);
    free(b.dte);
    free(b.vel);
    free(c.dte);
    free(c.vel);
    free(md.dte);
    free(md.vel);
    free(a.phase);
    free(b.phase);
    free(c.phase);
    free(md.phase);
    gs_system_free(&mod);
    gs_system_free(&sec);
    gs_system_free(&lum);
    gs_system_free(&fe);
}

/* Linear triangles (vt_scene_linear), GEARSIM_LONG=1 only: the mesh the
 * first bars were set on. */
static void calibrated_against_fe(void **state)
{
    (void)state;
    g_order = 1;
    calibrated_run();
    g_order = 2;
}

/* The default quadratic mesh (about 80 CPU seconds: the FE run's 6000
 * steps and the modal calibration's 24 eigenproblems). */
static void calibrated_against_fe_default(void **state)
{
    (void)state;
    g_order = 2;
    calibrated_run();
}

/* One group, one TAP plan (two groups printed two plans, which meson
 * counts as an error even with every subtest passed); the linear case only
 * in it under GEARSIM_LONG=1 (cmocka's skip prints "not ok # SKIP", which
 * meson counts as a failure). */
int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(calibrated_against_fe_default),
        cmocka_unit_test(calibrated_against_fe),
    };
    const char *lg = getenv("GEARSIM_LONG");
    size_t n = lg && strcmp(lg, "1") == 0 ? 2 : 1;
    return _cmocka_run_group_tests("tests", tests, n, NULL, NULL);
}
