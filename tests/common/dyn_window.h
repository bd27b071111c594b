/* SPDX-License-Identifier: MIT
 * Figures of a dynamic run over a steady window, shared by
 * tests/bench/lowspeed_te.c and tests/bench/dyn_convergence_run.c
 * (docs/validation/lowspeed.md).
 *
 * Every step: dw_energy() keeps the worst energy balance residual and the
 * energy scale over the whole run; inside the window dw_sample() records,
 * for one mesh, the kinematic TE a . q - s_ref, the mesh phase c . q
 * (cycles), its force and deepest penetration, the elastic (strain) energy
 * of the system and the angles of two bodies (the speed ratio).
 * dw_finish() reduces the samples over the whole mesh cycles from the
 * window's first sample: mean TE and rms about the mean, peak and mean
 * force, largest penetration, largest strain energy against its mean, the
 * mean speed ratio. */
#ifndef GEARSIM_TESTS_DYN_WINDOW_H
#define GEARSIM_TESTS_DYN_WINDOW_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/step.h"

typedef struct dw_sample_t {
    double t, te, phase, force, pen, strain, th_in, th_out;
} dw_sample_t;

typedef struct dyn_window {
    dw_sample_t *s;
    long n, cap;
    double worst, scale; /* largest |balance residual| over the run, energy scale (J) */
    double contact_work; /* last booked contact work (J) */
    double elastic;      /* last elastic energy of the system (J) */
} dyn_window;

typedef struct dyn_figures {
    int cycles;          /* whole mesh cycles used */
    long used;           /* samples in them */
    double seconds;      /* time they span, s */
    double mesh_hz;      /* cycles / seconds */
    double te_mean, te_rms, te_pp; /* kinematic TE: mean, rms about the mean, peak to peak (m) */
    double f_peak, f_mean;         /* |force| of the mesh: largest, mean (N) */
    double pen_max;                /* deepest penetration (m) */
    double strain_max, strain_mean; /* elastic energy of the system (J) */
    double ratio;                  /* mean speed ratio in / out over the cycles */
    double balance_rel;            /* worst |balance residual| / scale over the run */
} dyn_figures;

static inline void dw_free(dyn_window *w)
{
    free(w->s);
    memset(w, 0, sizeof *w);
}

/* Energy bookkeeping after every step (the whole run). */
static inline void dw_energy(dyn_window *w, gs_system *s)
{
    gs_energy en;
    gs_system_energy(s, &en);
    w->worst = fmax(w->worst, fabs(en.balance_residual));
    w->scale = fmax(w->scale, fmax(fabs(en.total), fmax(en.work_in, en.dissipated)));
    if (w->scale < 1e-300)
        w->scale = 1e-300;
    w->contact_work = en.contact_work;
    w->elastic = en.elastic;
}

/* One sample of mesh `mi` (after dw_energy of the same step); in/out the
 * bodies of the speed ratio (-1: not recorded). 0, or -1 out of memory. */
static inline int dw_sample(dyn_window *w, gs_system *s, int mi, int in, int out)
{
    if (w->n == w->cap) {
        long cap = w->cap ? 2 * w->cap : 8192;
        dw_sample_t *p = realloc(w->s, sizeof *p * (size_t)cap);
        if (!p)
            return -1;
        w->s = p, w->cap = cap;
    }
    const gs_gmesh_rt *m = &s->meshes[mi];
    double te = -m->s_ref, ph = 0;
    for (int k = 0; k < s->n_coords; k++) {
        te += m->a[k] * s->q[k];
        ph += m->c[k] * s->q[k];
    }
    dw_sample_t *x = &w->s[w->n++];
    x->t = s->time, x->te = te, x->phase = ph, x->force = fabs(m->force), x->pen = m->penetration;
    x->strain = w->elastic;
    x->th_in = in >= 0 ? gs_system_angle(s, in) : 0;
    x->th_out = out >= 0 ? gs_system_angle(s, out) : 0;
    return 0;
}

/* Reduce over the whole mesh cycles from the first sample. 0, or -1 when
 * the window holds no whole cycle. */
static inline int dw_finish(const dyn_window *w, dyn_figures *f)
{
    memset(f, 0, sizeof *f);
    f->balance_rel = w->worst / w->scale;
    if (w->n < 2)
        return -1;
    const dw_sample_t *s = w->s;
    double sgn = s[w->n - 1].phase >= s[0].phase ? 1 : -1;
    int cycles = (int)floor(sgn * (s[w->n - 1].phase - s[0].phase));
    if (cycles < 1)
        return -1;
    double sx = 0, fs = 0, es = 0, lo = INFINITY, hi = -INFINITY;
    long used = 0;
    for (long i = 0; i < w->n && sgn * (s[i].phase - s[0].phase) < cycles; i++) {
        sx += s[i].te;
        fs += s[i].force;
        es += s[i].strain;
        f->f_peak = fmax(f->f_peak, s[i].force);
        f->pen_max = fmax(f->pen_max, s[i].pen);
        f->strain_max = fmax(f->strain_max, s[i].strain);
        lo = fmin(lo, s[i].te), hi = fmax(hi, s[i].te);
        used++;
    }
    double mean = sx / (double)used, sxx = 0;
    for (long i = 0; i < used; i++)
        sxx += (s[i].te - mean) * (s[i].te - mean);
    const dw_sample_t *e = &s[used - 1];
    f->cycles = cycles, f->used = used;
    f->seconds = e->t - s[0].t;
    f->mesh_hz = f->seconds > 0 ? cycles / f->seconds : 0;
    f->te_mean = mean, f->te_rms = sqrt(sxx / (double)used), f->te_pp = hi - lo;
    f->f_mean = fs / (double)used, f->strain_mean = es / (double)used;
    double dout = e->th_out - s[0].th_out;
    f->ratio = dout != 0 ? fabs((e->th_in - s[0].th_in) / dout) : 0;
    return 0;
}

#endif
