/* SPDX-License-Identifier: MIT
 * Dynamic validation of the elastic body in the energy-momentum step
 * (METHOD.md sections 2 and 8), on a gear-like rim: a steel annulus
 * r = 30..50 mm, 20 mm face width, clamped on a rigid hub (inner circle).
 *
 *  1. Free spin at 3000 rpm with an elastic disturbance: total energy
 *     conserved to 1e-12 relative over 1e4 steps for h = 1e-8 .. 1e-4 s
 *     (the scheme is unconditionally stable; only round-off remains); the
 *     same disturbance without spin (all energy elastic) to 2e-12;
 *     angular momentum I theta' + s.u' constant to round-off; the mean speed
 *     follows exactly from it: theta_N - theta_0 = (t L - s.(u_N - u_0)) / I.
 *  2. Modal check: lowest in-plane frequencies of the body with theta FREE
 *     (the rigid-coupled system: K v = w^2 M v with M the full mass matrix
 *     including s and I; its zero mode is the rigid rotation), from LAPACK
 *     dsygv; each excited alone in a time-stepped run (spinning), period
 *     measured from zero crossings over 20 periods, within 1% of 2 pi / w
 *     (and within 1e-4 of the midpoint rule's own period
 *     2 pi / ((2/h) atan(w h / 2)), which is what the scheme must produce).
 *  2b. Material damping D = beta K: a mode decays at zeta = beta w / 2;
 *      Rayleigh D = alpha M + beta K (theta held): zeta = alpha/(2w) + beta w/2.
 *  3. Energy balance with a driving moment (constant + ripple) and a speed
 *     brake: E_n - E_0 - W_in + D stays at round-off (1e-12 of the largest
 *     of E, W_in, D) at every step, and the speed settles at M0 / c.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fe/fe_internal.h"
#include "gearsim/fe.h"

static const double R_IN = 0.03, R_OUT = 0.05, FACE = 0.02;

typedef struct ring {
    gs_mesh *mesh;
    gs_fe_model *model;
    gs_fe_body *body;
    gs_index ne, nn;
    double inertia;
} ring;

/* Element order of the rings built below (the invariants are checked for
 * both orders). */
static int g_order = 1;

static void ring_new_damped(ring *r, int n_r, int n_t, double damping_s)
{
    memset(r, 0, sizeof *r);
    assert_int_equal(gsi_fe_mesh_annulus_order(R_IN, R_OUT, n_r, n_t, g_order, &r->mesh), GS_OK);
    gs_material mat = gs_material_steel();
    mat.damping_s = damping_s;
    /* the hub: a solid steel disc of radius R_IN */
    double core = 0.5 * GS_PI * mat.density * FACE * pow(R_IN, 4);
    assert_int_equal(gs_fe_model_new(r->mesh, &mat, FACE, core, &r->model), GS_OK);
    assert_int_equal(gs_fe_body_new(r->model, &r->body), GS_OK);
    gs_fe_model_info info;
    gs_fe_model_get_info(r->model, &info);
    r->ne = info.n_elastic;
    r->nn = r->mesh->n_nodes;
    r->inertia = info.inertia_total;
}

static void ring_new(ring *r, int n_r, int n_t)
{
    ring_new_damped(r, n_r, n_t, 0.0);
}

static void ring_free(ring *r)
{
    gs_fe_body_free(&r->body);
    gs_fe_model_free(&r->model);
    gs_mesh_free(&r->mesh);
}

/* Initial disturbance: the static deflection under radial rim loads
 * F cos(2 phi) + tangential F/2 sin(3 phi), and a tangential velocity field
 * growing with the radius (it carries angular momentum through s). */
static void disturb(ring *r, double theta, double omega, double F, double v0)
{
    double *f = calloc((size_t)(2 * r->nn), sizeof *f), *u = calloc((size_t)(2 * r->nn), sizeof *u);
    double *v = calloc((size_t)(2 * r->nn), sizeof *v);
    for (gs_index k = 0; k < r->nn; k++) {
        double x = r->mesh->xy[2 * k], y = r->mesh->xy[2 * k + 1], rr = hypot(x, y);
        double ph = atan2(y, x), c = x / rr, s = y / rr;
        if (rr > R_OUT * (1 - 1e-9)) {
            double fr = F * cos(2 * ph), ft = 0.5 * F * sin(3 * ph);
            f[2 * k] = fr * c - ft * s;
            f[2 * k + 1] = fr * s + ft * c;
        }
        double vt = v0 * (rr - R_IN) / (R_OUT - R_IN) * (1 + 0.3 * cos(ph));
        v[2 * k] = -vt * s;
        v[2 * k + 1] = vt * c;
    }
    assert_int_equal(gs_fe_model_static(r->model, f, u), GS_OK);
    assert_int_equal(gs_fe_body_set_state(r->body, theta, omega, u, v), GS_OK);
    free(f);
    free(u);
    free(v);
}

static double energy(const gs_fe_body *b)
{
    return gs_fe_body_kinetic(b) + gs_fe_body_elastic(b);
}

static double s_dot(const ring *r, const double *x)
{
    double *s = malloc((size_t)r->ne * sizeof *s), acc = 0;
    gs_fe_model_coupling(r->model, s);
    for (gs_index i = 0; i < r->ne; i++)
        acc += s[i] * x[i];
    free(s);
    return acc;
}

/* ---- 1. free spin ------------------------------------------------------- */

static void free_spin_run(int n_r, int n_t)
{
    ring r;
    ring_new(&r, n_r, n_t);
    const double omega0 = 3000.0 / GS_RPM_PER_RAD_S;
    const double hs[5] = {1e-8, 1e-7, 1e-6, 1e-5, 1e-4};
    const int nsteps = 10000;
    double *u0 = malloc((size_t)r.ne * sizeof *u0), *du = malloc((size_t)r.ne * sizeof *du);
    print_message("# free spin 3000 rpm, annulus of order %d, %d elastic dofs, %d steps per h\n",
                  g_order, (int)r.ne, nsteps);
    print_message("# %8s %12s %12s %14s %14s %14s %14s\n", "h (s)", "E0 (J)", "E_el0 (J)",
                  "max|dE|/E0", "max|dE_el|/E_el", "max|dL|/L0", "mean speed id.");
    for (int k = 0; k < 5; k++) {
        double h = hs[k];
        assert_int_equal(gs_fe_body_set_step(r.body, h, 0.0), GS_OK);
        disturb(&r, 0.0, omega0, 2e4, 0.5);
        double E0 = energy(r.body), L0 = gs_fe_body_angular_momentum(r.body);
        double Eel0 = gs_fe_body_elastic(r.body), th0 = gs_fe_body_theta(r.body);
        memcpy(u0, gs_fe_body_q(r.body), (size_t)r.ne * sizeof *u0);
        double dE = 0, dL = 0;
        for (int n = 0; n < nsteps; n++) {
            assert_int_equal(gs_fe_body_step(r.body, 0.0, NULL), GS_OK);
            dE = fmax(dE, fabs(energy(r.body) - E0));
            dL = fmax(dL, fabs(gs_fe_body_angular_momentum(r.body) - L0));
        }
        /* the elastic-only run: same disturbance, no spin, no rigid velocity */
        const double *q = gs_fe_body_q(r.body);
        for (gs_index i = 0; i < r.ne; i++)
            du[i] = q[i] - u0[i];
        double dth = gs_fe_body_theta(r.body) - th0;
        double pred = (nsteps * h * L0 - s_dot(&r, du)) / r.inertia;
        double idrel = fabs(dth - pred) / fabs(dth);
        gs_fe_balance bal;
        gs_fe_body_get_balance(r.body, &bal);

        disturb(&r, 0.0, 0.0, 2e4, 0.0);
        double Ee0 = energy(r.body), dEe = 0;
        for (int n = 0; n < nsteps; n++) {
            assert_int_equal(gs_fe_body_step(r.body, 0.0, NULL), GS_OK);
            dEe = fmax(dEe, fabs(energy(r.body) - Ee0));
        }
        print_message("# %8.0e %12.5e %12.5e %14.2e %14.2e %14.2e %14.2e\n", h, E0, Eel0, dE / E0,
                      dEe / Ee0, dL / fabs(L0), idrel);
        assert_true(dE <= 1e-12 * E0);
        /* all energy elastic: at h = 1e-4 every elastic period is shorter
         * than h (omega h >= 20) and the rounding of the state update is a
         * bounded random walk of ~1e-12; measured 8e-13 at 1e4 steps */
        assert_true(dEe <= 2e-12 * Ee0);
        assert_true(dL <= 1e-12 * fabs(L0));
        assert_true(idrel <= 1e-11);
        assert_true(fabs(bal.residual) <= 1e-12 * E0);
    }
    gs_fe_stats st;
    gs_fe_body_get_stats(r.body, &st);
    assert_int_equal(st.factorizations, 5);
    free(u0);
    free(du);
    ring_free(&r);
}

static void free_spin_conserves(void **state)
{
    (void)state;
    g_order = 1;
    free_spin_run(4, 48);
}

/* The same invariants with curved quadratic elements (mid-side nodes on the
 * circles), about the same number of unknowns. */
static void free_spin_conserves_quadratic(void **state)
{
    (void)state;
    g_order = 2;
    free_spin_run(2, 24);
    g_order = 1;
}

/* ---- 2. modes ----------------------------------------------------------- */

/* Generalised eigenproblem K v = lambda M v (dense, n x n), ascending;
 * vectors (M-normalised) overwrite K. */
static void eig(gs_index n, double *K, double *M, double *lambda)
{
    assert_int_equal(
        LAPACKE_dsygv(LAPACK_COL_MAJOR, 1, 'V', 'U', (int)n, K, (int)n, M, (int)n, lambda), 0);
}

/* Time-step the mode alone (spinning at omega_spin) and measure its period
 * from the zero crossings of the node dof with the largest modal amplitude. */
static double measured_period(ring *r, const double *v, double h, int nsteps, double omega_spin)
{
    gs_index n = r->ne + 1, best = 0;
    for (gs_index i = 0; i < r->ne; i++)
        if (fabs(v[i]) > fabs(v[best]))
            best = i;
    double eps = 1e-5 / fabs(v[best]); /* 10 um at the largest dof */
    double *un = calloc((size_t)(2 * r->nn), sizeof *un);
    for (gs_index k = 0; k < r->nn; k++)
        for (int c = 0; c < 2; c++) {
            gs_index d = gs_fe_model_dof(r->model, k, c);
            if (d >= 0)
                un[2 * k + c] = eps * v[d];
        }
    assert_int_equal(gs_fe_body_set_step(r->body, h, 0.0), GS_OK);
    assert_int_equal(gs_fe_body_set_state(r->body, eps * v[n - 1], omega_spin, un, NULL), GS_OK);
    double prev = gs_fe_body_q(r->body)[best], first = -1, last = -1;
    int crossings = 0;
    for (int s = 1; s <= nsteps; s++) {
        assert_int_equal(gs_fe_body_step(r->body, 0.0, NULL), GS_OK);
        double cur = gs_fe_body_q(r->body)[best];
        if ((prev < 0) != (cur < 0)) {
            double t = h * (s - 1 + prev / (prev - cur));
            if (first < 0)
                first = t;
            else
                crossings++;
            last = t;
        }
        prev = cur;
    }
    free(un);
    assert_true(crossings >= 2);
    return 2.0 * (last - first) / crossings;
}

static void modal_run(int n_r, int n_t)
{
    ring r;
    ring_new(&r, n_r, n_t);
    gs_index n = r.ne + 1, ne = r.ne;
    double *K = calloc((size_t)(n * n), sizeof *K), *M = calloc((size_t)(n * n), sizeof *M);
    double *Kh = calloc((size_t)(ne * ne), sizeof *Kh), *Mh = calloc((size_t)(ne * ne), sizeof *Mh);
    double *lam = calloc((size_t)n, sizeof *lam), *lamh = calloc((size_t)ne, sizeof *lamh);
    assert_int_equal(gs_fe_model_dense(r.model, K, M), GS_OK);
    for (gs_index j = 0; j < ne; j++)
        for (gs_index i = 0; i < ne; i++) {
            Kh[i + j * ne] = K[i + j * n];
            Mh[i + j * ne] = M[i + j * n];
        }
    eig(n, K, M, lam);    /* theta free: K now holds the vectors */
    eig(ne, Kh, Mh, lamh); /* theta held, for comparison */
    assert_true(fabs(lam[0]) < 1e-9 * lam[1]); /* the rigid rotation */

    /* modes to check: the two lowest elastic ones and the one with the
     * largest theta participation (the torsional mode of the rim) */
    gs_index pick[3] = {1, 3, 1};
    double tmax = 0;
    for (gs_index k = 1; k < n; k++) {
        double vt = fabs(K[(n - 1) + k * n]);
        if (vt > tmax) {
            tmax = vt;
            pick[2] = k;
        }
    }
    /* a degenerate pair (n = 1 and n = 2 shapes of a ring) counts once */
    while (pick[1] < n - 1 && fabs(lam[pick[1]] / lam[pick[0]] - 1) < 1e-6)
        pick[1]++;
    print_message("# annulus of order %d, %d elastic dofs; lowest omega (rad/s), theta free | "
                  "theta held:\n", g_order, (int)ne);
    for (int k = 1; k <= 6; k++)
        print_message("#   %2d  %12.2f | %12.2f\n", k, sqrt(lam[k]), sqrt(lamh[k - 1]));
    print_message("# %4s %12s %10s %12s %12s %10s %10s\n", "mode", "omega", "theta part",
                  "T eig (s)", "T meas (s)", "err", "err vs h");
    for (int p = 0; p < 3; p++) {
        gs_index k = pick[p];
        double w = sqrt(lam[k]), T = 2 * GS_PI / w;
        double h = T / 200.0;
        double Th = 2 * GS_PI / ((2.0 / h) * atan(w * h / 2.0));
        double Tm = measured_period(&r, K + k * n, h, 200 * 20, 100.0);
        print_message("# %4d %12.2f %10.3e %12.5e %12.5e %+9.2e %+9.2e\n", (int)k, w,
                      K[(n - 1) + k * n], T, Tm, Tm / T - 1, Tm / Th - 1);
        assert_true(fabs(Tm / T - 1) < 0.01);
        assert_true(fabs(Tm / Th - 1) < 1e-4);
    }
    /* the torsional mode feels the rigid coupling: with theta free the hub
     * turns against the rim, so it is stiffer than the lowest theta-held mode
     * (the held torsional mode) */
    print_message("# torsional mode: %.2f rad/s with theta free, %.2f rad/s with theta held\n",
                  sqrt(lam[pick[2]]), sqrt(lamh[0]));
    assert_true(tmax > 1e-3);
    assert_true(sqrt(lam[pick[2]]) > 1.5 * sqrt(lamh[0]));
    free(K);
    free(M);
    free(Kh);
    free(Mh);
    free(lam);
    free(lamh);
    ring_free(&r);
}

static void modal_periods(void **state)
{
    (void)state;
    g_order = 1;
    modal_run(3, 36);
}

static void modal_periods_quadratic(void **state)
{
    (void)state;
    g_order = 2;
    modal_run(2, 18);
    g_order = 1;
}

/* ---- 2b. material damping ----------------------------------------------- */

/* nsteps free steps of a damped body: E / E0 at the end, the worst balance
 * residual over E0 in *worst; all of the dissipation must be damping (no
 * brake). */
static double free_decay(gs_fe_body *body, int nsteps, double *worst)
{
    double E0 = energy(body);
    *worst = 0;
    for (int s = 0; s < nsteps; s++) {
        assert_int_equal(gs_fe_body_step(body, 0.0, NULL), GS_OK);
        gs_fe_balance bal;
        gs_fe_body_get_balance(body, &bal);
        *worst = fmax(*worst, fabs(bal.residual) / E0);
        assert_true(bal.damped == bal.dissipated);
    }
    return energy(body) / E0;
}

/* Stiffness-proportional damping D = beta K keeps the undamped modes and
 * damps mode k at the ratio zeta_k = beta w_k / 2 (proportional damping,
 * closed form). The lowest elastic mode, started alone with beta chosen for
 * zeta = 2%, loses energy as exp(-2 zeta w t): measured after 10 damped
 * periods (an integer number of steps, h = T/200, so the phase matches to
 * one step) within 1% (one step of phase moves the energy of a 2%-damped
 * oscillation by ~ zeta * 2 pi / 200 ~ 6e-4; the midpoint rule's own error
 * in the decay rate is (w h)^2/12 ~ 1e-4). The energy lost equals the
 * booked dissipation to round-off. */
static void damped_mode_decay(void **state)
{
    (void)state;
    ring r0;
    ring_new(&r0, 3, 36);
    gs_index n = r0.ne + 1;
    double *K = calloc((size_t)(n * n), sizeof *K), *M = calloc((size_t)(n * n), sizeof *M);
    double *lam = calloc((size_t)n, sizeof *lam);
    assert_int_equal(gs_fe_model_dense(r0.model, K, M), GS_OK);
    eig(n, K, M, lam);
    ring_free(&r0);
    const double zeta = 0.02, w = sqrt(lam[1]), beta = 2 * zeta / w;
    const double *v = K + 1 * n;
    ring r;
    ring_new_damped(&r, 3, 36, beta);
    double Td = 2 * GS_PI / (w * sqrt(1 - zeta * zeta)), h = Td / 200.0;
    int nsteps = 200 * 10;
    double *un = calloc((size_t)(2 * r.nn), sizeof *un);
    for (gs_index k = 0; k < r.nn; k++)
        for (int c = 0; c < 2; c++) {
            gs_index d = gs_fe_model_dof(r.model, k, c);
            if (d >= 0)
                un[2 * k + c] = 1e-3 * v[d];
        }
    assert_int_equal(gs_fe_body_set_step(r.body, h, 0.0), GS_OK);
    assert_int_equal(gs_fe_body_set_state(r.body, 1e-3 * v[n - 1], 0.0, un, NULL), GS_OK);
    double worst, ratio = free_decay(r.body, nsteps, &worst), expect = exp(-2 * zeta * w * nsteps * h);
    print_message("# damping beta %.3e s (zeta %.2f at w %.1f rad/s): E/E0 after 10 periods %.6f, "
                  "closed form %.6f (%+.2e); balance %.2e of E0\n",
                  beta, zeta, w, ratio, expect, ratio / expect - 1, worst);
    assert_true(fabs(ratio / expect - 1) < 0.01);
    assert_true(worst < 1e-12);
    free(un);
    free(K);
    free(M);
    free(lam);
    ring_free(&r);
}

/* Rayleigh damping D = alpha M + beta K (material damping_m, damping_s) on
 * a body with theta held: D is then proportional to the body's M and K, the
 * undamped modes stay, and mode k is damped at zeta_k = alpha / (2 w_k) +
 * beta w_k / 2 (closed form). The lowest mode, with zeta = 2% at it split
 * evenly between the two terms, loses energy as exp(-2 zeta w t) after 10
 * damped periods (h = T/200; within 1%, as above), and a higher mode (the
 * fourth) decays at its own zeta_k; the energy lost equals the booked
 * dissipation to round-off at every step. */
static void rayleigh_mode_decay(void **state)
{
    (void)state;
    ring r0;
    ring_new(&r0, 3, 36);
    gs_index n = r0.ne + 1, ne = r0.ne;
    double *K = calloc((size_t)(n * n), sizeof *K), *M = calloc((size_t)(n * n), sizeof *M);
    double *Ke = calloc((size_t)(ne * ne), sizeof *Ke), *Me = calloc((size_t)(ne * ne), sizeof *Me);
    double *lam = calloc((size_t)ne, sizeof *lam);
    assert_int_equal(gs_fe_model_dense(r0.model, K, M), GS_OK);
    for (gs_index j = 0; j < ne; j++)
        for (gs_index i = 0; i < ne; i++) {
            Ke[i + j * ne] = K[i + j * n];
            Me[i + j * ne] = M[i + j * n];
        }
    eig(ne, Ke, Me, lam);
    ring_free(&r0);
    const double zeta = 0.02, w0 = sqrt(lam[0]);
    const double alpha = zeta * w0, beta = zeta / w0; /* each gives zeta/2 at w0 */
    const int modes[2] = {0, 3};
    for (int mk = 0; mk < 2; mk++) {
        const double w = sqrt(lam[modes[mk]]), zk = alpha / (2 * w) + beta * w / 2;
        const double *v = Ke + (size_t)modes[mk] * ne;
        ring r;
        memset(&r, 0, sizeof r);
        assert_int_equal(gsi_fe_mesh_annulus(R_IN, R_OUT, 3, 36, &r.mesh), GS_OK);
        gs_material mat = gs_material_steel();
        mat.damping_s = beta;
        mat.damping_m = alpha;
        assert_int_equal(gs_fe_model_new(r.mesh, &mat, FACE, 1e-3, &r.model), GS_OK);
        assert_int_equal(gs_fe_body_new(r.model, &r.body), GS_OK);
        assert_int_equal(gs_fe_body_hold_theta(r.body, true), GS_OK);
        gs_index nn = r.mesh->n_nodes;
        double Td = 2 * GS_PI / (w * sqrt(1 - zk * zk)), h = Td / 200.0;
        int nsteps = 200 * 10;
        double *un = calloc((size_t)(2 * nn), sizeof *un);
        for (gs_index k = 0; k < nn; k++)
            for (int c = 0; c < 2; c++) {
                gs_index d = gs_fe_model_dof(r.model, k, c);
                if (d >= 0)
                    un[2 * k + c] = 1e-3 * v[d];
            }
        assert_int_equal(gs_fe_body_set_step(r.body, h, 0.0), GS_OK);
        assert_int_equal(gs_fe_body_set_state(r.body, 0.0, 0.0, un, NULL), GS_OK);
        double worst, ratio = free_decay(r.body, nsteps, &worst), expect = exp(-2 * zk * w * nsteps * h);
        print_message("# Rayleigh alpha %.3e 1/s, beta %.3e s: mode %d (w %.1f rad/s, zeta %.4f): E/E0 after "
                      "10 periods %.6f, closed form %.6f (%+.2e); balance %.2e of E0\n",
                      alpha, beta, modes[mk] + 1, w, zk, ratio, expect, ratio / expect - 1, worst);
        assert_true(fabs(ratio / expect - 1) < 0.01);
        assert_true(worst < 1e-12);
        free(un);
        ring_free(&r);
    }
    free(K);
    free(M);
    free(Ke);
    free(Me);
    free(lam);
}

/* ---- 3. balance with moment and brake ----------------------------------- */

static void balance_with_moment_and_brake(void **state)
{
    (void)state;
    ring r;
    ring_new(&r, 4, 48);
    const double M0 = 50.0, c = 0.5, h = 1e-5; /* steady speed M0 / c = 100 rad/s */
    const int nsteps = 10000;                  /* 0.1 s: ~30 time constants I / c */
    assert_int_equal(gs_fe_body_set_step(r.body, h, c), GS_OK);
    disturb(&r, 0.0, 0.0, 2e4, 0.5);
    double worst = 0, scale = 0, wsum = 0;
    int nw = 0;
    for (int n = 0; n < nsteps; n++) {
        double tm = (n + 0.5) * h;
        double moment = M0 * (1.0 + 0.5 * sin(2 * GS_PI * 200.0 * tm) * (tm < 0.05));
        assert_int_equal(gs_fe_body_step(r.body, moment, NULL), GS_OK);
        gs_fe_balance bal;
        gs_fe_body_get_balance(r.body, &bal);
        double sc = fmax(bal.kinetic + bal.elastic, fmax(fabs(bal.work_in), bal.dissipated));
        scale = fmax(scale, sc);
        worst = fmax(worst, fabs(bal.residual) / sc);
        if (n >= nsteps - 2000) {
            wsum += gs_fe_body_omega(r.body);
            nw++;
        }
    }
    gs_fe_balance bal;
    gs_fe_body_get_balance(r.body, &bal);
    double mean = wsum / nw;
    print_message("# moment %g N m (+50%% ripple for 50 ms), brake %g N m s, h %g s, %d steps\n",
                  M0, c, h, nsteps);
    print_message("# final E %.6e J, W_in %.6e J, D %.6e J, residual %.2e J\n",
                  bal.kinetic + bal.elastic, bal.work_in, bal.dissipated, bal.residual);
    print_message("# max |residual| / max(E, W_in, D) over all steps: %.2e (scale %.3e J)\n", worst,
                  scale);
    print_message("# mean speed over the last 20 ms %.9f rad/s, M0/c = %.9f\n", mean, M0 / c);
    assert_true(worst <= 1e-12);
    assert_true(fabs(mean / (M0 / c) - 1) < 1e-4);
    ring_free(&r);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(free_spin_conserves),
        cmocka_unit_test(free_spin_conserves_quadratic),
        cmocka_unit_test(modal_periods),
        cmocka_unit_test(modal_periods_quadratic),
        cmocka_unit_test(damped_mode_decay),
        cmocka_unit_test(rayleigh_mode_decay),
        cmocka_unit_test(balance_with_moment_and_brake),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
