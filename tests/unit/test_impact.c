/* SPDX-License-Identifier: MIT
 * Unit tests of the impact module: the collinear impact of two discs in
 * closed form; the slender rod striking a rough floor in each of the five
 * slip processes, against the impulse relations written out independently
 * per process (areas of triangles and trapezoids under v_n(P_n)); Lemke
 * against gs_qp on frictionless multi-contact steps; LCPs that end on a ray;
 * argument checking. Tolerances: 1e-12 relative where both sides are a few
 * flops of closed form, 1e-9 where Lemke's tableau and the QP's
 * factorisation meet (their round-off is ~1e-14 kappa). */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/impact.h"

#define TEST_RNG_SEED 0x243f6a8885a308d3ull
#include "../common/rand.h"

static void near(double got, double want, double tol, const char *what)
{
    double err = fabs(got - want);
    if (!(err <= tol * fmax(1.0, fabs(want)))) {
        print_error("%s: got %.17g, want %.17g (error %.3g, tol %.3g)\n", what, got, want, err, tol);
        fail();
    }
}

/* ------------------------------------------------------------ discs */

/* Two discs on the x axis, disc 0 on the right moving left: the classical
 *   v0' = (m0 v0 + m1 v1 + e m1 (v1 - v0)) / (m0 + m1), and symmetric. */
static void collinear_discs(void **state)
{
    (void)state;
    const double es[] = {0.0, 0.3, 0.75, 1.0};
    const double mus[] = {0.0, 0.5};
    for (int law = 0; law < 3; law++)
        for (size_t ie = 0; ie < 4; ie++)
            for (size_t im = 0; im < 2; im++) {
                double m0 = 2.0, m1 = 5.0, v0 = -1.5, v1 = 0.8, e = es[ie];
                gs_impact_case c = {
                    .body = {{m0, 0.3, {1.0, 0.0}, {v0, 0.0}, 0.0, false},
                             {m1, 0.7, {-1.0, 0.0}, {v1, 0.0}, 0.0, false}},
                    .point = {0.0, 0.0}, .normal = {2.0, 0.0}, /* normalised by the solver */
                    .e = e, .mu = mus[im], .law = (gs_restitution)law};
                gs_impact_result r;
                assert_int_equal(gs_impact_solve(&c, &r, NULL), GS_OK);
                double w0 = (m0 * v0 + m1 * v1 + e * m1 * (v1 - v0)) / (m0 + m1);
                double w1 = (m0 * v0 + m1 * v1 + e * m0 * (v0 - v1)) / (m0 + m1);
                near(r.velocity[0][0], w0, 1e-13, "disc 0 velocity");
                near(r.velocity[1][0], w1, 1e-13, "disc 1 velocity");
                near(r.velocity[0][1], 0.0, 1e-13, "no transverse velocity");
                near(r.omega[0], 0.0, 1e-13, "no spin");
                near(r.impulse_t, 0.0, 1e-13, "no friction impulse");
                double mred = m0 * m1 / (m0 + m1), loss = 0.5 * mred * (v0 - v1) * (v0 - v1) * (1 - e * e);
                near(r.dissipation, loss, 1e-13, "dissipation");
                near(r.energy_before - r.energy_after, loss, 1e-13, "energy balance");
                assert_int_equal(r.process, mus[im] == 0.0 ? GS_IMPACT_FRICTIONLESS
                                                           : GS_IMPACT_STICK_COMPRESSION);
            }
}

/* ------------------------------------------------------------ rod */

/* A slender rod (mass m, length l, inertia m l^2 / 12) at angle th to the
 * floor, its lower end at the origin, the floor normal +y. In the floor's
 * (x, y) frame the inverse effective mass at the end is
 *   W_xx = (1 + 3 sin^2 th) / m, W_yy = (1 + 3 cos^2 th) / m, W_xy = -3 sin th cos th / m. */
typedef struct {
    double m, l, th, vx, vy; /* end point velocity (rod not spinning) */
    double e, mu;
} rod;

static gs_impact_case rod_case(const rod *R, gs_restitution law)
{
    double hx = 0.5 * R->l * cos(R->th), hy = 0.5 * R->l * sin(R->th);
    gs_impact_case c = {
        .body = {{R->m, R->m * R->l * R->l / 12.0, {hx, hy}, {R->vx, R->vy}, 0.0, false},
                 {0.0, 0.0, {0.0, 0.0}, {0.0, 0.0}, 0.0, true}},
        .point = {0.0, 0.0}, .normal = {0.0, 1.0}, .e = R->e, .mu = R->mu, .law = law};
    return c;
}

/* Expected final P_n and P_x of the rod, from the relations per process. */
typedef struct {
    gs_impact_process process;
    double pn, px;
} expect;

static expect rod_expect(const rod *R, gs_restitution law)
{
    const double m = R->m, s = sin(R->th), co = cos(R->th), e = R->e, mu = R->mu;
    const double Wxx = (1 + 3 * s * s) / m, Wyy = (1 + 3 * co * co) / m, Wxy = -3 * s * co / m;
    const double sg = R->vx > 0 ? 1.0 : -1.0; /* slip direction; friction along -sg */
    const double a1 = Wyy - sg * mu * Wxy;    /* dv_y/dP_n while slipping */
    const double b1 = Wxy - sg * mu * Wxx;    /* dv_x/dP_n while slipping */
    const double vy0 = R->vy, Pc1 = -vy0 / a1;
    double Ps = (b1 * sg < 0) ? -R->vx / b1 : INFINITY;
    /* sliding throughout: one straight line; every law gives (1 + e) Pc */
    if (!(Ps < (1 + e) * Pc1))
        return (expect){GS_IMPACT_SLIDING, (1 + e) * Pc1, -sg * mu * (1 + e) * Pc1};
    bool stick = fabs(Wxy) <= mu * Wxx;
    double a2 = stick ? Wyy - Wxy * Wxy / Wxx : Wyy + sg * mu * Wxy; /* after the slip stop */
    double kx2 = stick ? -Wxy / Wxx : sg * mu;                       /* dP_x/dP_n after it */
    double vyS = vy0 + a1 * Ps;                                      /* v_y at the slip stop */
    double Pc, Pf;
    gs_impact_process proc;
    if (Ps < Pc1) { /* slip stops in compression */
        proc = stick ? GS_IMPACT_STICK_COMPRESSION : GS_IMPACT_REVERSAL_COMPRESSION;
        Pc = Ps - vyS / a2;
        double Wc = 0.5 * Ps * (vy0 + vyS) + 0.5 * (Pc - Ps) * vyS; /* trapezoid + triangle */
        if (law == GS_RESTITUTION_NEWTON)
            Pf = Pc + e * (-vy0) / a2;
        else if (law == GS_RESTITUTION_POISSON)
            Pf = (1 + e) * Pc;
        else
            Pf = Pc + sqrt(-2 * e * e * Wc / a2); /* triangle of area e^2 |Wc| */
    } else { /* slip stops in restitution */
        proc = stick ? GS_IMPACT_STICK_RESTITUTION : GS_IMPACT_REVERSAL_RESTITUTION;
        Pc = Pc1;
        double Wc = -0.5 * a1 * Pc * Pc, W1 = 0.5 * a1 * (Ps - Pc) * (Ps - Pc);
        if (law == GS_RESTITUTION_NEWTON)
            Pf = Ps + (e * (-vy0) - vyS) / a2;
        else if (law == GS_RESTITUTION_POISSON)
            Pf = (1 + e) * Pc;
        else {
            double Rm = -e * e * Wc - W1; /* work left after the slip stop */
            Pf = Ps + (-vyS + sqrt(vyS * vyS + 2 * a2 * Rm)) / a2;
        }
    }
    (void)Pc;
    return (expect){proc, Pf, -sg * mu * Ps + kx2 * (Pf - Ps)};
}

static void rod_processes(void **state)
{
    (void)state;
    const double th = GS_PI / 4; /* stick iff mu >= 0.6 (3 s c <= mu (1 + 3 s^2)) */
    const struct {
        rod R;
        gs_impact_process want;
    } cases[] = {
        {{1.0, 1.0, th, 3.0, -1.0, 0.5, 0.3}, GS_IMPACT_SLIDING},
        {{1.0, 1.0, th, -0.5, -1.0, 0.5, 0.3}, GS_IMPACT_SLIDING}, /* slip never stops */
        {{1.0, 1.0, th, 0.5, -1.0, 0.5, 0.8}, GS_IMPACT_STICK_COMPRESSION},
        {{1.0, 1.0, th, 1.2, -1.0, 0.5, 0.8}, GS_IMPACT_STICK_RESTITUTION},
        {{1.0, 1.0, th, 0.4, -1.0, 0.5, 0.3}, GS_IMPACT_REVERSAL_COMPRESSION},
        {{1.0, 1.0, th, 1.0, -1.0, 0.5, 0.3}, GS_IMPACT_REVERSAL_RESTITUTION},
        {{2.0, 0.6, 0.3, 0.2, -2.0, 0.9, 1.2}, GS_IMPACT_STICK_COMPRESSION},
        {{0.5, 2.0, 1.2, 0.05, -0.3, 0.0, 0.1}, GS_IMPACT_REVERSAL_COMPRESSION},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++)
        for (int law = 0; law < 3; law++) {
            gs_impact_case c = rod_case(&cases[k].R, (gs_restitution)law);
            expect x = rod_expect(&cases[k].R, (gs_restitution)law);
            gs_impact_result r;
            assert_int_equal(gs_impact_solve(&c, &r, NULL), GS_OK);
            if (r.process != cases[k].want || x.process != cases[k].want) {
                print_error("case %zu law %s: process %s, independent %s, want %s\n", k,
                            gs_restitution_name((gs_restitution)law),
                            gs_impact_process_name(r.process), gs_impact_process_name(x.process),
                            gs_impact_process_name(cases[k].want));
                fail();
            }
            near(r.impulse_n, x.pn, 1e-12, "P_n");
            /* P_t is along t = (-n_y, n_x) = (-1, 0) */
            near(-r.impulse_t, x.px, 1e-12, "P_x");
            near(r.energy_before - r.energy_after, r.dissipation, 1e-12, "energy balance");
            assert_true(r.dissipation_t >= -1e-15);
            if (law == GS_RESTITUTION_NEWTON)
                near(r.v[1], -c.e * c.body[0].velocity[1], 1e-12, "Newton v_n");
            if (law == GS_RESTITUTION_POISSON)
                near(r.impulse_n, (1 + c.e) * r.impulse_n_compression, 1e-12, "Poisson P_n");
            if (law == GS_RESTITUTION_STRONGE)
                near(r.work_n_restitution, -c.e * c.e * r.work_n_compression, 1e-12,
                     "Stronge work ratio");
        }
}

/* At rest tangentially: sticks throughout when the cone allows, otherwise
 * slips from rest in the direction that W_tn drives. */
static void slip_from_rest(void **state)
{
    (void)state;
    rod R = {1.0, 1.0, GS_PI / 4, 0.0, -1.0, 0.5, 0.8};
    gs_impact_case c = rod_case(&R, GS_RESTITUTION_STRONGE);
    gs_impact_result r;
    assert_int_equal(gs_impact_solve(&c, &r, NULL), GS_OK);
    assert_int_equal(r.process, GS_IMPACT_STICK_COMPRESSION);
    near(r.v[0], 0.0, 1e-14, "stuck");
    near(r.dissipation_t, 0.0, 1e-14, "no friction work");
    c.mu = 0.3;
    assert_int_equal(gs_impact_solve(&c, &r, NULL), GS_OK);
    assert_int_equal(r.process, GS_IMPACT_SLIDING);
    assert_true(fabs(r.impulse_t) > 0.0);
    assert_true(r.v[0] * r.impulse_t < 0.0); /* friction opposes the slip it cannot prevent */
    near(fabs(r.impulse_t), 0.3 * r.impulse_n, 1e-13, "on the cone");
}

static void separating_and_errors(void **state)
{
    (void)state;
    rod R = {1.0, 1.0, 0.5, 1.0, 0.5, 0.5, 0.3};
    gs_impact_case c = rod_case(&R, GS_RESTITUTION_NEWTON);
    gs_impact_result r;
    assert_int_equal(gs_impact_solve(&c, &r, NULL), GS_OK);
    assert_int_equal(r.process, GS_IMPACT_NONE);
    assert_true(r.impulse_n == 0.0);
    gs_diag d;
    c.body[0].mass = -1.0;
    assert_int_equal(gs_impact_solve(&c, &r, &d), GS_ERANGE);
    assert_string_equal(d.field, "bodies[0].mass");
    c.body[0].mass = 1.0;
    c.e = 1.5;
    assert_int_equal(gs_impact_solve(&c, &r, &d), GS_ERANGE);
    assert_string_equal(d.field, "e");
    c.e = 0.5;
    c.normal[0] = c.normal[1] = 0.0;
    assert_int_equal(gs_impact_solve(&c, &r, &d), GS_ERANGE);
    assert_string_equal(d.field, "contact.normal");
    c.normal[1] = 1.0;
    c.body[1].fixed = false;
    c.body[0].fixed = true;
    c.body[1].mass = 1.0;
    c.body[1].inertia = 0.0;
    assert_int_equal(gs_impact_solve(&c, &r, &d), GS_ERANGE);
    assert_string_equal(d.field, "bodies[1].inertia");
    gs_impact_contact_problem p = {{1.0, 2.0, 1.0}, {0.0, -1.0}, 0.5, 0.1, GS_RESTITUTION_NEWTON};
    assert_int_equal(gs_impact_contact(&p, &r, &d), GS_ERANGE);
    assert_string_equal(d.field, "W");
    gs_restitution law;
    assert_true(gs_restitution_parse("poisson", &law) && law == GS_RESTITUTION_POISSON);
    assert_false(gs_restitution_parse("hooke", &law));
}

/* ------------------------------------------------------------ LCP */

static void lcp_small(void **state)
{
    (void)state;
    /* P-matrix, solution by hand: A = [2 1; 1 2], q = [-5 ; -1]: z = (2.5, 0), w = (0, 1.5). */
    double A[4] = {2, 1, 1, 2}, q[2] = {-5, -1}, z[2], w[2];
    gs_lcp_info info;
    assert_int_equal(gs_lcp_lemke(2, A, q, z, w, 0, &info), GS_OK);
    near(z[0], 2.5, 1e-14, "z0");
    near(z[1], 0.0, 1e-14, "z1");
    near(w[1], 1.5, 1e-14, "w1");
    assert_int_equal(info.status, GS_LCP_SOLVED);
    assert_false(info.multiple);
    /* q >= 0: z = 0 without pivoting */
    double q2[2] = {1, 0};
    assert_int_equal(gs_lcp_lemke(2, A, q2, z, w, 0, &info), GS_OK);
    assert_true(z[0] == 0.0 && z[1] == 0.0);
    assert_int_equal(info.n_degenerate, 1);
}

static void lcp_ray(void **state)
{
    (void)state;
    gs_lcp_info info;
    double z[3], w[3];
    /* w = -z - 1 >= 0 has no solution with z >= 0 */
    double A1[1] = {-1}, q1[1] = {-1};
    assert_int_equal(gs_lcp_lemke(1, A1, q1, z, w, 0, &info), GS_EINFEASIBLE);
    assert_int_equal(info.status, GS_LCP_RAY);
    /* a P-matrix: w1 = z1 - z2 - 1, w2 = z2 - 1, one solution */
    double A2[4] = {1, -1, 0, 1}, q2[2] = {-1, -1};
    gs_err e = gs_lcp_lemke(2, A2, q2, z, w, 0, &info);
    assert_int_equal(e, GS_OK);
    near(z[0], 2.0, 1e-14, "z0");
    near(z[1], 1.0, 1e-14, "z1");
    /* copositive-plus but infeasible: A = [0 1; -1 0] (skew), q = (-1, -1):
     * w1 = z2 - 1, w2 = -z1 - 1 < 0 always */
    double A3[4] = {0, 1, -1, 0}, q3[2] = {-1, -1};
    assert_int_equal(gs_lcp_lemke(2, A3, q3, z, w, 0, &info), GS_EINFEASIBLE);
    assert_int_equal(info.status, GS_LCP_RAY);
    double bad[1] = {NAN};
    assert_int_equal(gs_lcp_lemke(1, bad, q1, z, w, 0, &info), GS_EINVAL);
}

/* Random planar bodies above a floor (and on each other), frictionless:
 * the LCP and the QP must give the same velocities, and the same impulses
 * when the LCP reports a unique solution. */
static void lemke_vs_qp(void **state)
{
    (void)state;
    int n_multiple = 0, n_unique = 0, n_gain = 0;
    for (int trial = 0; trial < 200; trial++) {
        int nb = 1 + (int)(urand() * 3), nc = 1 + (int)(urand() * 6);
        gs_impact_body B[5];
        gs_impact_point C[8];
        B[0] = (gs_impact_body){0, 0, {0, 0}, {0, 0}, 0, true};
        for (int b = 1; b <= nb; b++)
            B[b] = (gs_impact_body){uniform(0.5, 3), uniform(0.05, 1), {uniform(-1, 1), uniform(0, 2)},
                                    {uniform(-1, 1), uniform(-2, 0.5)}, uniform(-2, 2), false};
        for (int k = 0; k < nc; k++) {
            /* b1 < b0 with normals near +y: always feasible (lift the higher bodies faster) */
            int b0 = 1 + (int)(urand() * nb), b1 = (int)(urand() * b0);
            double a = uniform(-0.6, 0.6);
            C[k] = (gs_impact_point){{b0, b1}, {uniform(-1.5, 1.5), uniform(-0.5, 1.5)},
                                     {sin(a), cos(a)}, uniform(0, 1), 0.0};
        }
        bool all_e0 = trial % 4 == 0;
        for (int k = 0; k < nc && all_e0; k++)
            C[k].e = 0.0;
        gs_impact_multi m = {nb + 1, B, nc, C, urand() < 0.5 ? 0.0 : 1e-3, {0.0, -9.81}};
        double buf[2][2 * 5 + 5 + 8 + 8];
        gs_impact_multi_result r[2];
        for (int i = 0; i < 2; i++)
            r[i] = (gs_impact_multi_result){buf[i], buf[i] + 10, buf[i] + 15, buf[i] + 23, {0}, 0, false, 0, 0};
        gs_diag d;
        gs_err e0 = gs_impact_multi_solve(&m, &r[0], &d);
        if (e0 != GS_OK) {
            print_error("trial %d: %s: %s\n", trial, d.field, d.message);
            for (int b = 1; b <= nb; b++)
                print_error("body %d m %g I %g c %g %g v %g %g w %g\n", b, B[b].mass, B[b].inertia,
                            B[b].centre[0], B[b].centre[1], B[b].velocity[0], B[b].velocity[1], B[b].omega);
            for (int k = 0; k < nc; k++)
                print_error("contact %d-%d p %g %g n %g %g e %g\n", C[k].body[0], C[k].body[1], C[k].point[0],
                            C[k].point[1], C[k].normal[0], C[k].normal[1], C[k].e);
        }
        assert_int_equal(e0, GS_OK);
        assert_int_equal(gs_impact_multi_solve_qp(&m, &r[1], &d), GS_OK);
        double vs = 1.0;
        for (int b = 0; b <= nb; b++)
            vs = fmax(vs, fabs(B[b].velocity[0]) + fabs(B[b].velocity[1]) + fabs(B[b].omega));
        for (int i = 0; i < 2 * (nb + 1); i++)
            near(r[0].velocity[i], r[1].velocity[i], 1e-9 * vs, "velocity LCP vs QP");
        for (int i = 0; i <= nb; i++)
            near(r[0].omega[i], r[1].omega[i], 1e-9 * vs, "omega LCP vs QP");
        if (r[0].several) {
            n_multiple++;
        } else {
            n_unique++;
            double ps = 0.0;
            for (int k = 0; k < nc; k++)
                ps = fmax(ps, fabs(r[0].impulse_n[k]));
            for (int k = 0; k < nc; k++)
                near(r[0].impulse_n[k], r[1].impulse_n[k], 1e-8 * fmax(ps, 1.0), "impulse LCP vs QP");
        }
        /* with e = 0 the step is the M-projection of v- onto {N v >= 0}: no energy gain
         * (with e > 0 Newton's law at several contacts may gain energy; counted) */
        if (m.h == 0.0 && all_e0)
            assert_true(r[0].energy_after <= r[0].energy_before * (1 + 1e-12) + 1e-15);
        if (m.h == 0.0 && r[0].energy_after > r[0].energy_before * (1 + 1e-12))
            n_gain++;
    }
    print_message("# Lemke vs QP: %d unique, %d with several impulse solutions (same velocities); "
                  "%d steps with e > 0 gained energy\n", n_unique, n_multiple, n_gain);
    assert_true(n_unique > 50);
}

/* A box with 4 floor contacts (rank 3 for one planar body): several impulse
 * solutions, reported; then one contact of a falling rod with friction
 * agrees with the single-impact solver under Newton's hypothesis when slip
 * does not change (Newton = velocity level LCP with e). */
static void multi_cases(void **state)
{
    (void)state;
    gs_impact_body B[2] = {{0, 0, {0, 0}, {0, 0}, 0, true},
                           {1.0, 1.0 / 6.0, {0.0, 0.5}, {0.0, -1.0}, 0.0, false}};
    gs_impact_point C[4] = {{{1, 0}, {-0.5, 0}, {0, 1}, 0.0, 0.0}, {{1, 0}, {0.5, 0}, {0, 1}, 0.0, 0.0},
                            {{1, 0}, {-0.25, 0}, {0, 1}, 0.0, 0.0}, {{1, 0}, {0.25, 0}, {0, 1}, 0.0, 0.0}};
    gs_impact_multi m = {2, B, 4, C, 0.0, {0, 0}};
    double buf[4 + 2 + 4 + 4];
    gs_impact_multi_result r = {buf, buf + 4, buf + 6, buf + 10, {0}, 0, false, 0, 0};
    assert_int_equal(gs_impact_multi_solve(&m, &r, NULL), GS_OK);
    assert_true(r.several);
    near(r.velocity[3], 0.0, 1e-12, "box stopped");
    near(r.omega[1], 0.0, 1e-12, "box not spinning");
    near(r.impulse_n[0] + r.impulse_n[1] + r.impulse_n[2] + r.impulse_n[3], 1.0, 1e-12, "total impulse");

    /* Rod with friction, one contact, sliding throughout */
    rod R = {1.0, 1.0, GS_PI / 4, 3.0, -1.0, 0.5, 0.3};
    gs_impact_case c = rod_case(&R, GS_RESTITUTION_NEWTON);
    gs_impact_result s;
    assert_int_equal(gs_impact_solve(&c, &s, NULL), GS_OK);
    gs_impact_body RB[2] = {c.body[0], c.body[1]};
    gs_impact_point RC = {{0, 1}, {0, 0}, {0, 1}, 0.5, 0.3};
    gs_impact_multi rm = {2, RB, 1, &RC, 0.0, {0, 0}};
    double b2[4 + 2 + 1 + 1];
    gs_impact_multi_result rr = {b2, b2 + 4, b2 + 6, b2 + 7, {0}, 0, false, 0, 0};
    assert_int_equal(gs_impact_multi_solve(&rm, &rr, NULL), GS_OK);
    near(rr.impulse_n[0], s.impulse_n, 1e-12, "LCP P_n = Routh (sliding)");
    near(rr.impulse_t[0], s.impulse_t, 1e-12, "LCP P_t = Routh (sliding)");
    gs_diag d;
    RC.body[1] = 7;
    assert_int_equal(gs_impact_multi_solve(&rm, &rr, &d), GS_ERANGE);
    assert_string_equal(d.field, "contacts[0].bodies");
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(collinear_discs),
        cmocka_unit_test(rod_processes),
        cmocka_unit_test(slip_from_rest),
        cmocka_unit_test(separating_and_errors),
        cmocka_unit_test(lcp_small),
        cmocka_unit_test(lcp_ray),
        cmocka_unit_test(lemke_vs_qp),
        cmocka_unit_test(multi_cases),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
