/* SPDX-License-Identifier: MIT
 * A run of n steps read over its second half (the steady state after the
 * ramp), shared by tests/validation/test_ltca.c and
 * tests/bench/bench_tradeoff.c: every step, the worst energy balance
 * residual and the energy scale (total, work in, dissipated) over the whole
 * run; over the second half, the first mesh's deflection (its sum and sum
 * of squares: the mean TE and the DTE rms about it; the transmission
 * error sh_te, the same for every mesh model), its force (sum and
 * largest magnitude) and the angle of one body at the half's start. */
#ifndef GEARSIM_TESTS_STEADY_HALF_H
#define GEARSIM_TESTS_STEADY_HALF_H

#include <math.h>
#include <stdbool.h>

#include "gearsim/step.h"

typedef struct steady_half {
    int n, half;          /* steps in all, in the second half */
    int body;             /* the body whose angle th0 is kept (-1: none) */
    double worst, scale;  /* largest |balance residual|, energy scale (J) */
    double d1, d2;        /* sum of the deflection, of its square (m, m^2) */
    double fsum, fpeak;   /* sum of the force, largest |force| (N) */
    double th0;           /* angle of `body` at the half's start (rad) */
} steady_half;

static inline steady_half sh_start(int n, int body)
{
    steady_half r = {0};
    r.n = n;
    r.half = n / 2;
    r.body = body;
    return r;
}

static inline bool sh_in_half(const steady_half *r, int i)
{
    return i >= r->n - r->half;
}

/* The transmission error of the first mesh, m: the kinematic a . q -
 * s_ref of the rigid coordinates (the hubs of elastic gears), what a
 * contact mesh reports as its deflection. A lumped or ltca mesh adds the
 * gears' tooth errors (pitch tables, run-out) to its deflection as the
 * displacement E(q) (docs/explanation/geometry.md "Tooth errors in the
 * lumped meshes"): taken out here, so that every rung's TE is the same
 * quantity (without tooth errors E is 0 and the deflection is returned
 * as it is). */
static inline double sh_te(const gs_system *sys)
{
    const gs_gmesh_rt *m = &sys->meshes[0];
    return m->n_err ? m->deflection - gs_gmesh_error(m, sys->q) : m->deflection;
}

/* Step i of the run: one step and its figures; false when the step failed. */
static inline bool sh_step(steady_half *r, gs_system *sys, int i)
{
    if (i == r->n - r->half && r->body >= 0)
        r->th0 = gs_system_angle(sys, r->body);
    if (gs_step_serial(sys) != GS_OK)
        return false;
    gs_energy e;
    gs_system_energy(sys, &e);
    r->worst = fmax(r->worst, fabs(e.balance_residual));
    r->scale = fmax(r->scale, fmax(e.total, fmax(e.work_in, e.dissipated)));
    if (sh_in_half(r, i)) {
        double x = sh_te(sys), f = sys->meshes[0].force;
        r->d1 += x;
        r->d2 += x * x;
        r->fsum += f;
        r->fpeak = fmax(r->fpeak, fabs(f));
    }
    return true;
}

/* Mean deflection over the half and the rms about it. */
static inline double sh_mean(const steady_half *r)
{
    return r->d1 / r->half;
}

static inline double sh_rms(const steady_half *r)
{
    double m = sh_mean(r);
    return sqrt(fmax(r->d2 / r->half - m * m, 0.0));
}

#endif
