/* SPDX-License-Identifier: MIT
 * Shared by tests/bench/te_errors.c and tests/validation/test_tooth_errors.c:
 * the dynamic transmission error of the 20/30 pair (module 2.5, face 10 mm,
 * thinning 0.05 mm) with tooth errors on the pinion, in the `contact`
 * (elastic gears), rectangular `lumped` and calibrated `lumped` (rigid gears)
 * mesh models, run the same way (docs/explanation/geometry.md "Tooth errors: dynamic
 * comparison"): the pinion driven by a moment ramped up over `ramp` seconds
 * from rest, the wheel braked so that the pinion turns at omega at the full
 * moment; the kinematic TE a . q - s_ref (the tooth errors' own displacement
 * excluded) recorded per step against the pinion angle. */
#ifndef GEARSIM_TESTS_TE_RUN_H
#define GEARSIM_TESTS_TE_RUN_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/scene.h"
#include "gearsim/step.h"

typedef enum { TE_CONTACT, TE_LUMPED, TE_CALIBRATED } te_model;

static const char *const te_model_names[3] = {"contact", "lumped", "calibrated"};

typedef struct {
    te_model model;
    double torque;      /* N m on the pinion */
    double omega;       /* pinion speed at the full moment, rad/s */
    double h;           /* time step, s */
    double ramp;        /* ramp time of the moment, s */
    double damping_s;   /* contact: material damping beta (s) of both gears, 0 none */
    const char *errors; /* JSON members added to the pinion ("" none) */
    double angle0;      /* initial pinion angle, rad (whole pitches keep the mesh) */
    const char *contact_scheme; /* contact: numerics.contact, "seed" or "closure" (NULL: "seed") */
    double damping_ratio, damping_hz; /* contact: material damping zeta at f of both gears (0: none;
                                       * not with damping_s) */
} te_setup;

/* One run: samples from the first step whose pinion angle is at least
 * rec_from (rad, absolute) until the pinion has turned `span` rad more. */
typedef struct {
    int n, cap;
    double *th, *te, *t; /* pinion angle (rad), kinematic TE (m), time (s) */
    double worst, scale; /* largest |balance residual| and the energy scale (J) */
    long steps;          /* steps taken in all */
    double f_mode;       /* lumped meshes: the torsional mesh mode of the rigid pair with the
                          * mesh's mean stiffness, sqrt(k (rb1^2/I1 + rb2^2/I2)) / 2 pi, Hz */
} te_record;

static inline void te_record_free(te_record *r)
{
    free(r->th);
    free(r->te);
    free(r->t);
    memset(r, 0, sizeof *r);
}

/* The scene text of a setup (buf of size len). */
/* Linear triangles (mesh.order 1) for the contact model's gears and the
 * calibration: the bars were measured on them, and the ~60 000 contact
 * steps of the tests would take about 12 times as long on the quadratic
 * default. */
static inline void te_scene_text(const te_setup *su, char *buf, size_t len)
{
    int contact = su->model == TE_CONTACT;
    char mat[160] = "", num[64] = "";
    if (contact && su->damping_s > 0)
        snprintf(mat, sizeof mat, ", \"material\": {\"damping_s\": %.17g}", su->damping_s);
    else if (contact && su->damping_ratio > 0)
        snprintf(mat, sizeof mat, ", \"material\": {\"damping_ratio\": %.17g, \"damping_hz\": %.17g}",
                 su->damping_ratio, su->damping_hz);
    if (contact) /* NULL: the seed's scheme, which the tooth-error bars were measured with */
        snprintf(num, sizeof num, ", \"contact\": \"%s\"", su->contact_scheme ? su->contact_scheme : "seed");
    const char *stiff = su->model == TE_CALIBRATED ? ", \"stiffness\": {\"type\": \"calibrated\"}" : "";
    double c = 2.25 * su->torque / su->omega; /* wheel brake: 1.5 T at 2 omega / 3 */
    snprintf(buf, len,
             "{\"name\": \"te pair\", \"bodies\": ["
             "{\"name\": \"pinion\", \"teeth\": 20, \"module_mm\": 2.5, \"face_width_mm\": 10, "
             "\"thinning_mm\": 0.05, \"model\": \"%s\", \"mesh\": {\"order\": 1}%s%s%s},"
             "{\"name\": \"wheel\", \"teeth\": 30, \"module_mm\": 2.5, \"face_width_mm\": 10, "
             "\"thinning_mm\": 0.05, \"model\": \"%s\", \"mesh\": {\"order\": 1}%s}],"
             "\"joints\": [{\"body\": \"pinion\", \"type\": \"fixed_axis\", \"centre_mm\": [0, 0]},"
             "{\"body\": \"wheel\", \"type\": \"fixed_axis\", \"centre_mm\": [62.5, 0]}],"
             "\"meshes\": [{\"name\": \"pw\", \"gears\": [\"pinion\", \"wheel\"], \"model\": \"%s\"%s}],"
             "\"loads\": [{\"body\": \"pinion\", \"type\": \"ramp\", \"moment\": %.17g, \"ramp_time\": %.17g},"
             "{\"body\": \"wheel\", \"type\": \"brake\", \"coefficient\": %.17g}],"
             "\"numerics\": {\"time_step\": %.17g%s},"
             "\"initial\": {\"pinion\": {\"angle\": %.17g}, \"wheel\": {\"angle\": 0.10471975511965977}}}",
             contact ? "elastic" : "rigid", mat, su->errors[0] ? ", " : "", su->errors,
             contact ? "elastic" : "rigid", mat, contact ? "contact" : "lumped", stiff, su->torque, su->ramp, c,
             su->h, num, su->angle0);
}

/* Build and run a setup; 0 on success, else prints the diagnostic and
 * returns -1. max_steps bounds the run. */
static inline int te_run(const te_setup *su, double rec_from, double span, long max_steps, te_record *r)
{
    char txt[8192];
    te_scene_text(su, txt, sizeof txt);
    memset(r, 0, sizeof *r);
    gs_scene *sc = NULL;
    gs_diag d;
    if (gs_scene_parse(txt, strlen(txt), &sc, &d) != GS_OK) {
        fprintf(stderr, "scene: %s: %s\n", d.field, d.message);
        return -1;
    }
    gs_system *s = NULL;
    if (gs_system_new(sc, 0, 1, &s, &d) != GS_OK) { /* takes the scene */
        fprintf(stderr, "system: %s: %s\n", d.field, d.message);
        return -1;
    }
    const gs_gmesh_rt *m = &s->meshes[0];
    int cp = s->bodies[gs_scene_find_body(s->scene, "pinion")].coord, nc = s->n_coords;
    double th_end = INFINITY;
    if (m->k_single > 0) {
        double eps = m->contact_ratio, inv = 0;
        double k = eps >= 2 ? m->k_double : m->k_single * (2 - eps) + m->k_double * (eps - 1);
        for (int i = 0; i < s->n_bodies; i++)
            if (s->bodies[i].coord >= 0)
                inv += m->a[s->bodies[i].coord] * m->a[s->bodies[i].coord] / s->bodies[i].inertia_eff;
        r->f_mode = sqrt(k * inv) / (2 * GS_PI);
    }
    gs_energy en;
    int rc = 0;
    for (long i = 0; i < max_steps; i++) {
        if (gs_step_serial(s) != GS_OK) {
            fprintf(stderr, "step %ld: %s: %s\n", i, s->diag.field, s->diag.message);
            rc = -1;
            break;
        }
        r->steps++;
        gs_system_energy(s, &en);
        r->worst = fmax(r->worst, fabs(en.balance_residual));
        r->scale = fmax(r->scale, fmax(en.total, fmax(en.work_in, en.dissipated)));
        double th = s->q[cp];
        if (th < rec_from)
            continue;
        if (!isfinite(th_end))
            th_end = th + span;
        if (r->n == r->cap) {
            r->cap = r->cap ? 2 * r->cap : 4096;
            r->th = realloc(r->th, sizeof(double) * (size_t)r->cap);
            r->te = realloc(r->te, sizeof(double) * (size_t)r->cap);
            r->t = realloc(r->t, sizeof(double) * (size_t)r->cap);
        }
        double te = -m->s_ref;
        for (int k = 0; k < nc; k++)
            te += m->a[k] * s->q[k];
        r->th[r->n] = th, r->te[r->n] = te, r->t[r->n] = s->time;
        r->n++;
        if (th >= th_end)
            break;
    }
    if (rc == 0 && !(r->n > 1 && r->th[r->n - 1] >= th_end)) {
        fprintf(stderr, "run stopped after %ld steps before the recorded span was covered\n", r->steps);
        rc = -1;
    }
    gs_system_free(&s);
    return rc;
}

/* Angle-weighted mean of the TE over the samples with lo <= th < hi (each
 * sample weighted by the angle its step spans). */
static inline double te_mean(const te_record *r, double lo, double hi)
{
    double sum = 0, w = 0;
    for (int i = 1; i < r->n; i++) {
        double tm = 0.5 * (r->th[i] + r->th[i - 1]);
        if (tm < lo || tm >= hi)
            continue;
        double dth = r->th[i] - r->th[i - 1];
        sum += 0.5 * (r->te[i] + r->te[i - 1]) * dth;
        w += dth;
    }
    return w > 0 ? sum / w : NAN;
}

/* Pitch errors on the pinion teeth faulty[0 .. nf): tooth j stands on the
 * line of centres (the wheel lies along +x, beta = 0) at pinion angle
 * v = -2 pi j / z (mod 2 pi) and is in contact within eps / 2 < 1.5 mesh
 * cycles of it; its window is those 3 cycles. For every window lying in
 * both records, the TE of `err` averaged over the window minus that of
 * `ref` over the same angles: their mean, standard error and median; the
 * count is returned (at most max). */
static inline int te_window_shifts(const te_record *err, const te_record *ref, const int *faulty, int nf, int z,
                                   double *shift, int max, double *mean, double *sem, double *median)
{
    double lo = fmax(err->th[0], ref->th[0]), hi = fmin(err->th[err->n - 1], ref->th[ref->n - 1]);
    double p = 2 * GS_PI / z;
    int n = 0;
    for (int f = 0; f < nf; f++) {
        double vc = -faulty[f] * p;
        vc += 2 * GS_PI * ceil((lo + 1.5 * p - vc) / (2 * GS_PI));
        for (; vc + 1.5 * p <= hi && n < max; vc += 2 * GS_PI)
            shift[n++] = te_mean(err, vc - 1.5 * p, vc + 1.5 * p) - te_mean(ref, vc - 1.5 * p, vc + 1.5 * p);
    }
    double s = 0, s2 = 0;
    for (int i = 0; i < n; i++)
        s += shift[i];
    *mean = n ? s / n : NAN;
    for (int i = 0; i < n; i++)
        s2 += (shift[i] - *mean) * (shift[i] - *mean);
    *sem = n > 1 ? sqrt(s2 / (n - 1) / n) : NAN;
    /* median: insertion sort of a copy */
    double tmp[256];
    int m = n < 256 ? n : 256;
    for (int i = 0; i < m; i++) {
        double v = shift[i];
        int k = i;
        for (; k > 0 && tmp[k - 1] > v; k--)
            tmp[k] = tmp[k - 1];
        tmp[k] = v;
    }
    *median = m ? (m % 2 ? tmp[m / 2] : 0.5 * (tmp[m / 2 - 1] + tmp[m / 2])) : NAN;
    return n;
}

/* Complex amplitude (re, im) of order k of the pinion's rotation over the
 * revolution [th0, th0 + 2 pi): TE ~ re cos(k th) + im sin(k th). */
static inline void te_order(const te_record *r, double th0, int k, double *re, double *im)
{
    double a = 0, b = 0;
    for (int i = 1; i < r->n; i++) {
        double tm = 0.5 * (r->th[i] + r->th[i - 1]);
        if (tm < th0 || tm >= th0 + 2 * GS_PI)
            continue;
        double dth = r->th[i] - r->th[i - 1], x = 0.5 * (r->te[i] + r->te[i - 1]);
        a += x * cos(k * tm) * dth;
        b += x * sin(k * tm) * dth;
    }
    *re = a / GS_PI, *im = b / GS_PI;
}

/* A study: each of the three cases (perfect gears, pitch errors of
 * pitch_um on the pinion teeth faulty[0 .. nf), run-out runout_um at
 * phase_deg on the pinion) run in one mesh model from the ramp-up over
 * `revs` pinion revolutions recorded after the settling time. */
typedef struct {
    te_model model;
    double torque, omega, h, ramp, settle, revs, damping_s;
    double pitch_um, runout_um, phase_deg;
    int faulty[32], nf;
    const char *csv; /* write PREFIX_<model>_<case>.csv when set */
    int no_pitch;    /* leave out the pitch-error case */
    const char *contact_scheme;       /* contact: numerics.contact (NULL: "seed") */
    double damping_ratio, damping_hz; /* contact: material damping zeta at f (0: none) */
} te_study_opts;

#define TE_Z 20
#define TE_NORD 7
static const int te_orders[TE_NORD] = {1, TE_Z - 1, TE_Z, TE_Z + 1, 2 * TE_Z - 1, 2 * TE_Z, 2 * TE_Z + 1};
static const char *const te_case_names[3] = {"perfect", "pitch", "runout"};

typedef struct {
    long steps[3];
    double mean_te[3];          /* over the record, m */
    double order[3][TE_NORD];   /* amplitudes of te_orders over the first recorded revolution, m */
    double worst[3], scale[3];  /* balance residual and energy scale, J */
    double f_mode;              /* lumped: mesh mode, Hz (0 for contact) */
    double shift[256];          /* pitch: the window shifts, m */
    int n_windows;
    double shift_mean, shift_sem, shift_median; /* m */
    double record_shift;        /* pitch: mean TE shift over the whole record, m */
    double runout_1x;           /* run-out: once-per-revolution TE, perfect run's removed, m */
} te_study_result;

static inline int te_study(const te_study_opts *o, te_study_result *res)
{
    memset(res, 0, sizeof *res);
    char pitch[1024] = "\"pitch_errors_um\": [", run[160];
    for (int k = 0; k < TE_Z; k++) {
        int is = 0;
        for (int f = 0; f < o->nf; f++)
            is |= o->faulty[f] == k;
        char v[40];
        snprintf(v, sizeof v, "%s%.17g", k ? "," : "", is ? o->pitch_um : 0.0);
        strcat(pitch, v);
    }
    strcat(pitch, "]");
    snprintf(run, sizeof run, "\"runout\": {\"eccentricity_um\": %.17g, \"phase_deg\": %.17g}", o->runout_um,
             o->phase_deg);
    const char *cases[3] = {"", pitch, run};
    double th_rec = 0.5 * o->omega * o->ramp + o->omega * o->settle, span = 2 * GS_PI * o->revs;
    te_record r[3];
    double re1[3], im1[3];
    memset(r, 0, sizeof r);
    for (int q = 0; q < 3; q++) {
        if (q == 1 && o->no_pitch)
            continue;
        te_setup su = {o->model, o->torque, o->omega, o->h,       o->ramp,          o->damping_s,
                       cases[q], 0.0,      o->contact_scheme, o->damping_ratio, o->damping_hz};
        long max_steps = (long)(2.0 * (o->ramp + o->settle + span / o->omega) / o->h) + 1000;
        if (te_run(&su, th_rec, span, max_steps, &r[q]) != 0) {
            for (int k = 0; k <= q; k++)
                te_record_free(&r[k]);
            return -1;
        }
        double th0 = r[q].th[0];
        res->steps[q] = r[q].steps;
        res->mean_te[q] = te_mean(&r[q], th0, th0 + span);
        res->worst[q] = r[q].worst, res->scale[q] = r[q].scale;
        if (r[q].f_mode > 0)
            res->f_mode = r[q].f_mode;
        for (int k = 0; k < TE_NORD; k++) {
            double a, b;
            te_order(&r[q], th0, te_orders[k], &a, &b);
            res->order[q][k] = hypot(a, b);
            if (k == 0)
                re1[q] = a, im1[q] = b;
        }
        if (o->csv) {
            char path[1024];
            snprintf(path, sizeof path, "%s_%s_%s.csv", o->csv, te_model_names[o->model], te_case_names[q]);
            FILE *f = fopen(path, "w");
            if (f) {
                fprintf(f, "t_s,pinion_angle_rad,te_um\n");
                for (int i = 0; i < r[q].n; i++)
                    fprintf(f, "%.9g,%.12g,%.9g\n", r[q].t[i], r[q].th[i], r[q].te[i] * 1e6);
                fclose(f);
            } else {
                perror(path);
            }
        }
    }
    double th0 = r[0].th[0];
    if (!o->no_pitch) {
        res->n_windows = te_window_shifts(&r[1], &r[0], o->faulty, o->nf, TE_Z, res->shift, 256,
                                          &res->shift_mean, &res->shift_sem, &res->shift_median);
        res->record_shift = te_mean(&r[1], th0, th0 + span) - te_mean(&r[0], th0, th0 + span);
    }
    res->runout_1x = hypot(re1[2] - re1[0], im1[2] - im1[0]);
    for (int q = 0; q < 3; q++)
        te_record_free(&r[q]);
    return 0;
}

#endif
