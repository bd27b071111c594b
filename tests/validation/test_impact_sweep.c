/* SPDX-License-Identifier: MIT
 * Random sweep of single frictional impacts (40000 cases, about half approaching: two free bodies
 * or a body on the ground; random mass, inertia, geometry, velocities,
 * e in [0, 1], mu in [0, 1.5]) checking the statements of METHOD.md
 * section 6:
 *  - without friction, or without change of slip (sliding throughout), the
 *    three hypotheses give the same impulses (tolerance 1e-11 relative:
 *    they are the same closed form evaluated along different routes);
 *  - Stronge's hypothesis never creates energy and both its dissipation
 *    components are non-negative (tolerance 1e-12 of the initial energy);
 *  - the energy balance KE_before - KE_after = D_n + D_t holds for every law
 *    (1e-11 of the initial energy);
 *  - Newton's hypothesis creates energy in some cases where slip stops and
 *    changes (counted, examples printed; the test fails if none is found).
 * Runs in well under a second. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "gearsim/impact.h"

#define TEST_RNG_SEED 0x13198a2e03707344ull
#include "../common/rand.h"

static double logu(double a, double b)
{
    return exp(uniform(log(a), log(b)));
}

static gs_impact_case random_case(void)
{
    gs_impact_case c;
    memset(&c, 0, sizeof c);
    for (int i = 0; i < 2; i++) {
        gs_impact_body *b = &c.body[i];
        b->mass = logu(0.1, 10);
        double rg = logu(0.05, 1.0); /* radius of gyration */
        b->inertia = b->mass * rg * rg;
        b->centre[0] = uniform(-1, 1);
        b->centre[1] = (i == 0 ? 1 : -1) * uniform(0.05, 1);
        b->velocity[0] = uniform(-2, 2);
        b->velocity[1] = uniform(-2, 2);
        b->omega = uniform(-3, 3);
    }
    if (urand() < 0.4) { /* ground at rest (a moving fixed body would do work) */
        c.body[1].fixed = true;
        c.body[1].velocity[0] = c.body[1].velocity[1] = c.body[1].omega = 0.0;
    }
    double a = uniform(-0.4, 0.4);
    c.normal[0] = sin(a);
    c.normal[1] = cos(a);
    c.e = urand() < 0.1 ? (urand() < 0.5 ? 0.0 : 1.0) : urand();
    c.mu = urand() < 0.15 ? 0.0 : uniform(0, 1.5);
    return c;
}

static const char *pname(gs_impact_process p)
{
    return gs_impact_process_name(p);
}

static void sweep(void **state)
{
    (void)state;
    const int N = 40000;
    int n_impacts = 0, n_same = 0, n_gain_newton = 0, n_gain_poisson = 0, n_printed = 0;
    int count[7][3] = {{0}};
    for (int it = 0; it < N; it++) {
        gs_impact_case c = random_case();
        gs_impact_result r[3];
        for (int law = 0; law < 3; law++) {
            c.law = (gs_restitution)law;
            gs_diag d;
            gs_err e = gs_impact_solve(&c, &r[law], &d);
            if (e != GS_OK) {
                print_error("case %d: %s: %s\n", it, d.field, d.message);
                fail();
            }
            count[r[law].process][law]++;
        }
        if (r[0].process == GS_IMPACT_NONE)
            continue;
        n_impacts++;
        const double E0 = r[0].energy_before;
        for (int law = 0; law < 3; law++) {
            double bal = r[law].energy_before - r[law].energy_after - r[law].dissipation;
            if (!(fabs(bal) <= 1e-11 * E0)) {
                print_error("case %d law %d: energy balance off by %.3g (E0 %.6g)\n", it, law, bal, E0);
                fail();
            }
            if (!(r[law].dissipation_t >= -1e-12 * E0)) {
                print_error("case %d law %d: negative tangential dissipation %.3g\n", it, law,
                            r[law].dissipation_t);
                fail();
            }
        }
        const gs_impact_result *s = &r[GS_RESTITUTION_STRONGE];
        if (!(s->energy_after <= E0 * (1 + 1e-12)) || !(s->dissipation_n >= -1e-12 * E0)) {
            print_error("case %d: Stronge created energy: E %.17g -> %.17g, D_n %.3g, D_t %.3g\n", it,
                        E0, s->energy_after, s->dissipation_n, s->dissipation_t);
            fail();
        }
        bool no_change = c.mu == 0.0;
        for (int law = 0; law < 3; law++)
            no_change = no_change || r[law].process == GS_IMPACT_SLIDING;
        if (no_change) {
            /* sliding under one law means the slip outlasts (1 + e) P_c, the
             * common end of all three: every law then slides throughout */
            n_same++;
            for (int law = 1; law < 3; law++) {
                double sc = fmax(r[0].impulse_n, 1e-300);
                if (r[law].process != r[0].process ||
                    !(fabs(r[law].impulse_n - r[0].impulse_n) <= 1e-11 * sc) ||
                    !(fabs(r[law].impulse_t - r[0].impulse_t) <= 1e-11 * sc)) {
                    print_error("case %d: %s/%s disagree: P_n %.17g vs %.17g, P_t %.17g vs %.17g\n", it,
                                pname(r[0].process), pname(r[law].process), r[0].impulse_n,
                                r[law].impulse_n, r[0].impulse_t, r[law].impulse_t);
                    fail();
                }
            }
        }
        const gs_impact_result *nw = &r[GS_RESTITUTION_NEWTON], *po = &r[GS_RESTITUTION_POISSON];
        if (nw->energy_after > E0 * (1 + 1e-9)) {
            n_gain_newton++;
            if (n_printed++ < 5)
                print_message("# Newton gains energy (case %d, %s): m %.4g I %.4g%s, e %.3f, mu %.3f, "
                              "v0 (t, n) = (%.4f, %.4f), W = [%.4f %.4f %.4f]: KE %.6f -> %.6f "
                              "(D_n %.6f, D_t %.6f); Stronge KE -> %.6f (%s)\n",
                              it, pname(nw->process), c.body[0].mass, c.body[0].inertia,
                              c.body[1].fixed ? " on ground" : "", c.e, c.mu, nw->v0[0], nw->v0[1],
                              nw->W[0], nw->W[1], nw->W[2], E0, nw->energy_after, nw->dissipation_n,
                              nw->dissipation_t, s->energy_after, pname(s->process));
            if (nw->process == GS_IMPACT_SLIDING || nw->process == GS_IMPACT_FRICTIONLESS) {
                print_error("case %d: Newton gained energy without a change of slip\n", it);
                fail();
            }
        }
        if (po->energy_after > E0 * (1 + 1e-9))
            n_gain_poisson++;
    }
    print_message("# %d cases, %d impacts; %d without friction or change of slip (all laws agree)\n", N,
                  n_impacts, n_same);
    print_message("# %-22s %8s %8s %8s\n", "process", "newton", "poisson", "stronge");
    for (int p = 0; p < 7; p++)
        print_message("# %-22s %8d %8d %8d\n", pname((gs_impact_process)p), count[p][0], count[p][1],
                      count[p][2]);
    print_message("# energy created: Newton %d cases, Poisson %d cases, Stronge 0\n", n_gain_newton,
                  n_gain_poisson);
    assert_true(n_impacts >= 10000);
    assert_true(n_same > 500);
    assert_true(n_gain_newton > 0);
}

int main(void)
{
    const struct CMUnitTest tests[] = {cmocka_unit_test(sweep)};
    return cmocka_run_group_tests(tests, NULL, NULL);
}
