/* SPDX-License-Identifier: MIT
 * Unit tests of the reduced elastic body (src/fe/fe_reduced.c, docs/explanation/elastic_body.md
 * "Reduced elastic body") on small annulus meshes:
 *
 *   all_modes_*      every mode kept (dense eigensolver): the reduced body
 *                    reproduces gs_fe_body step by step (free increments,
 *                    compliance, nodal displacements, theta, energies) over
 *                    300 steps with nodal loads, a moment, interface forces
 *                    and a brake; undamped and damped, free and held. The
 *                    two are different algorithms (a sparse step solve
 *                    against a modal sum), so this fails if any modal term
 *                    or the brake's rank-one update is wrong.
 *   all_modes_rayleigh  the same with mass-proportional damping (damping_m):
 *                    diagonal in a held body's modes, with a rank-one
 *                    coupling through the rotation in a free body's.
 *   truncated_balance  few modes kept: the energy balance (kinetic +
 *                    elastic - work + dissipation) holds to round-off,
 *                    damped (stiffness- and mass-proportional) and
 *                    undamped, with a set_state whose residual
 *                    part is not zero (it fails if the residual's potential
 *                    or dissipation is dropped).
 *   truncated_static   under a constant load with damping the reduced body
 *                    comes to rest at K^{-1} f (modal + residual = exact
 *                    statics; it fails without the residual flexibility).
 *   lanczos_dense    the Lanczos eigensolver (deflated restarts) finds the
 *                    dense solver's modes below f_max, the double ones of
 *                    the annulus's cyclic symmetry included.
 *   save_load        a snapshot restores the state bit for bit.
 *   state_round_trip  the state read back (theta, omega, nodal u, v) and
 *                    set again reads back the same and steps on alike; a
 *                    velocity outside the kept modes keeps its projection;
 *                    switching held/free after creation is refused.
 * Comparisons are relative to the largest value compared. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fe/fe_internal.h"
#include "gearsim/fe.h"

typedef struct fixture {
    gs_mesh *mesh;
    gs_fe_model *model;
    gs_index nn;
} fixture;

/* Rayleigh alpha (damping_m) of the next make(): 0 unless a test sets it. */
static double make_alpha;

static void make(fixture *f, double beta)
{
    memset(f, 0, sizeof *f);
    assert_int_equal(gsi_fe_mesh_annulus(0.02, 0.04, 3, 14, &f->mesh), GS_OK);
    gs_material mat = gs_material_steel();
    mat.damping_s = beta;
    mat.damping_m = make_alpha;
    assert_int_equal(gs_fe_model_new(f->mesh, &mat, 0.01, 1e-4, &f->model), GS_OK);
    f->nn = f->mesh->n_nodes;
}

static void unmake(fixture *f)
{
    gs_fe_model_free(&f->model);
    gs_mesh_free(&f->mesh);
}

static double maxabs(const double *x, gs_index n)
{
    double m = 0;
    for (gs_index i = 0; i < n; i++)
        m = fmax(m, fabs(x[i]));
    return m;
}

static void wavy(gs_index nn, double *u, double *v)
{
    for (gs_index k = 0; k < 2 * nn; k++) {
        u[k] = 1e-6 * sin(0.9 * (double)k + 0.2);
        v[k] = 1e-3 * cos(1.3 * (double)k);
    }
}

/* Nodal loads of step s: a travelling pair of forces on outer nodes. */
static void loads(const fixture *f, int s, double *fn)
{
    memset(fn, 0, (size_t)(2 * f->nn) * sizeof *fn);
    gs_index a = f->nn - 1 - (gs_index)((s / 40) % 10), c = f->nn - 5;
    fn[2 * a] = 30.0 * sin(0.07 * s);
    fn[2 * a + 1] = -50.0;
    fn[2 * c + 1] = 20.0 * cos(0.05 * s);
}

static void run_compare(bool held, double beta, double brake)
{
    fixture f;
    make(&f, beta);
    gs_fe_body *full = NULL;
    gs_fe_reduced *red = NULL;
    assert_int_equal(gs_fe_body_new(f.model, &full), GS_OK);
    gs_fe_reduced_opts o = {INFINITY, held, 0, NULL, 0, false};
    assert_int_equal(gs_fe_reduced_new(f.model, &o, &red), GS_OK);
    gs_fe_reduced_info info;
    gs_fe_reduced_get_info(red, &info);
    gs_fe_model_info mi;
    gs_fe_model_get_info(f.model, &mi);
    assert_int_equal(info.elastic_modes, mi.n_elastic);
    gs_index nn = f.nn;
    double *u = calloc((size_t)(2 * nn), sizeof *u), *v = calloc((size_t)(2 * nn), sizeof *v);
    double *u1 = calloc((size_t)(2 * nn), sizeof *u1), *u2 = calloc((size_t)(2 * nn), sizeof *u2);
    double *fn = calloc((size_t)(2 * nn), sizeof *fn);
    wavy(nn, u, v);
    assert_int_equal(gs_fe_body_set_state(full, 0.1, 3.0, u, v), GS_OK);
    assert_int_equal(gs_fe_body_hold_theta(full, held), GS_OK);
    assert_int_equal(gs_fe_reduced_set_state(red, 0.1, 3.0, u, v), GS_OK);
    double h = 2e-6;
    assert_int_equal(gs_fe_body_set_step(full, h, brake), GS_OK);
    assert_int_equal(gs_fe_reduced_set_step(red, h, brake), GS_OK);
    /* interface dofs: theta and the two components of three outer nodes */
    gs_index dofs[7] = {GS_FE_DOF_THETA, gs_fe_dof_node(nn - 2, 0), gs_fe_dof_node(nn - 2, 1),
                        gs_fe_dof_node(nn - 7, 0), gs_fe_dof_node(nn - 7, 1), gs_fe_dof_node(0, 0),
                        gs_fe_dof_node(0, 1)};
    double d1[7], d2[7], C1[49], C2[49], fi[7];
    double eu = 0, ei = 0, ec = 0, et = 0, su = 0, si = 0, sc = 0, se = 0;
    for (int s = 0; s < 300; s++) {
        loads(&f, s, fn);
        double M = 2.0 + sin(0.03 * s);
        assert_int_equal(gs_fe_body_begin_step(full, M, fn), GS_OK);
        assert_int_equal(gs_fe_reduced_begin_step(red, M, fn), GS_OK);
        assert_int_equal(gs_fe_body_increment(full, 7, dofs, d1), GS_OK);
        assert_int_equal(gs_fe_reduced_increment(red, 7, dofs, d2), GS_OK);
        for (int k = 0; k < 7; k++) {
            ei = fmax(ei, fabs(d1[k] - d2[k]));
            si = fmax(si, fabs(d1[k]));
        }
        if (s % 10 == 0) {
            assert_int_equal(gs_fe_body_compliance(full, 7, dofs, C1), GS_OK);
            assert_int_equal(gs_fe_reduced_compliance(red, 7, dofs, C2), GS_OK);
            for (int k = 0; k < 49; k++) {
                ec = fmax(ec, fabs(C1[k] - C2[k]));
                sc = fmax(sc, fabs(C1[k]));
            }
        }
        for (int k = 0; k < 7; k++)
            fi[k] = (k + 1) * 10.0 * cos(0.1 * s + k);
        assert_int_equal(gs_fe_body_apply(full, 7, dofs, fi), GS_OK);
        assert_int_equal(gs_fe_reduced_apply(red, 7, dofs, fi), GS_OK);
        assert_int_equal(gs_fe_body_increment(full, 7, dofs, d1), GS_OK);
        assert_int_equal(gs_fe_reduced_increment(red, 7, dofs, d2), GS_OK);
        for (int k = 0; k < 7; k++) {
            ei = fmax(ei, fabs(d1[k] - d2[k]));
            si = fmax(si, fabs(d1[k]));
        }
        assert_int_equal(gs_fe_body_end_step(full), GS_OK);
        assert_int_equal(gs_fe_reduced_end_step(red), GS_OK);
        gs_fe_body_nodal(full, u1, NULL);
        assert_int_equal(gs_fe_reduced_nodal(red, u2, NULL), GS_OK);
        for (gs_index k = 0; k < 2 * nn; k++) {
            eu = fmax(eu, fabs(u1[k] - u2[k]));
            su = fmax(su, fabs(u1[k]));
        }
        double dn[2];
        assert_int_equal(gs_fe_reduced_node_displacement(red, nn - 2, dn), GS_OK);
        eu = fmax(eu, fabs(dn[0] - u1[2 * (nn - 2)]) + fabs(dn[1] - u1[2 * (nn - 2) + 1]));
        if (!held) {
            et = fmax(et, fabs(gs_fe_body_theta(full) - gs_fe_reduced_theta(red)));
            et = fmax(et, 1e-3 * fabs(gs_fe_body_angular_momentum(full) - gs_fe_reduced_angular_momentum(red)));
        }
        double T1, V1, T2, V2;
        gs_fe_body_energy(full, &T1, &V1);
        gs_fe_reduced_energy(red, &T2, &V2);
        se = fmax(se, T1 + V1);
        et = fmax(et, fabs(T1 - T2) + fabs(V1 - V2));
        if (s == 150) { /* a spin increment, as closure_energy's velocity update */
            gs_fe_body_spin(full, 0.5);
            gs_fe_reduced_spin(red, 0.5);
        }
    }
    gs_fe_balance b1, b2;
    gs_fe_body_get_balance(full, &b1);
    gs_fe_reduced_get_balance(red, &b2);
    print_message("held %d beta %g brake %g: increments %.2e, compliance %.2e, nodal u %.2e, energy/theta %.2e "
                  "(relative), damped %.6e / %.6e, brake %.6e / %.6e\n",
                  held, beta, brake, ei / si, ec / sc, eu / su, et / fmax(se, 1.0), b1.damped, b2.damped,
                  b1.dissipated - b1.damped, b2.dissipated - b2.damped);
    assert_true(ei <= 1e-10 * si);
    assert_true(ec <= 1e-10 * sc);
    assert_true(eu <= 1e-10 * su);
    assert_true(et <= 1e-10 * fmax(se, 1.0));
    assert_true(fabs(b1.damped - b2.damped) <= 1e-9 * fmax(b1.damped, 1e-300) + 1e-18);
    assert_true(fabs(b1.dissipated - b2.dissipated) <= 1e-9 * fmax(b1.dissipated, 1e-300) + 1e-18);
    if (beta > 0 || make_alpha > 0)
        assert_true(b2.damped > 0);
    if (brake > 0 && !held)
        assert_true(b2.dissipated - b2.damped > 0);
    free(u), free(v), free(u1), free(u2), free(fn);
    gs_fe_reduced_free(&red);
    gs_fe_body_free(&full);
    unmake(&f);
}

static void all_modes_free(void **state)
{
    (void)state;
    run_compare(false, 0.0, 0.0);
}

static void all_modes_free_damped_brake(void **state)
{
    (void)state;
    run_compare(false, 2e-7, 0.05);
}

static void all_modes_held(void **state)
{
    (void)state;
    run_compare(true, 0.0, 0.0);
}

static void all_modes_held_damped(void **state)
{
    (void)state;
    run_compare(true, 2e-7, 0.0);
}

/* Mass-proportional damping (alpha M on u'): diagonal in a held body's
 * modes, diagonal plus the rank-one coupling through the rotation in a free
 * body's; every mode kept, the reduced body is the full one. */
static void all_modes_rayleigh(void **state)
{
    (void)state;
    make_alpha = 3000.0;
    run_compare(false, 0.0, 0.0);
    run_compare(false, 2e-7, 0.05);
    run_compare(true, 2e-7, 0.0);
    make_alpha = 0.0;
}

/* Truncated: energy balance at round-off. */
static void run_balance(double beta, double brake, bool held, bool stat)
{
    fixture f;
    make(&f, beta);
    gs_fe_reduced *red = NULL;
    gs_fe_reduced_opts o = {60e3, held, 0, NULL, 0, stat};
    assert_int_equal(gs_fe_reduced_new(f.model, &o, &red), GS_OK);
    gs_fe_reduced_info info;
    gs_fe_reduced_get_info(red, &info);
    gs_fe_model_info mi;
    gs_fe_model_get_info(f.model, &mi);
    assert_true(info.elastic_modes > 0 && info.elastic_modes < mi.n_elastic / 4);
    gs_index nn = f.nn;
    double *u = calloc((size_t)(2 * nn), sizeof *u), *v = calloc((size_t)(2 * nn), sizeof *v);
    double *fn = calloc((size_t)(2 * nn), sizeof *fn);
    wavy(nn, u, v);
    assert_int_equal(gs_fe_reduced_set_state(red, 0.1, 3.0, u, v), GS_OK);
    assert_int_equal(gs_fe_reduced_set_step(red, 5e-6, brake), GS_OK);
    gs_index dofs[3] = {GS_FE_DOF_THETA, gs_fe_dof_node(nn - 3, 0), gs_fe_dof_node(nn - 3, 1)};
    double worst = 0, scale = 0;
    for (int s = 0; s < 400; s++) {
        loads(&f, s, fn);
        if (s == 200)
            assert_int_equal(gs_fe_reduced_set_step(red, 2.5e-6, brake), GS_OK);
        assert_int_equal(gs_fe_reduced_begin_step(red, 1.0 + sin(0.02 * s), fn), GS_OK);
        double fi[3] = {0.3, 40.0 * sin(0.05 * s), -25.0};
        assert_int_equal(gs_fe_reduced_apply(red, 3, dofs, fi), GS_OK);
        assert_int_equal(gs_fe_reduced_end_step(red), GS_OK);
        gs_fe_balance b;
        gs_fe_reduced_get_balance(red, &b);
        scale = fmax(scale, fmax(fabs(b.kinetic) + fabs(b.elastic), fabs(b.work_in) + fabs(b.work_iface)));
        scale = fmax(scale, fabs(b.dissipated)); /* every term of the balance */
        worst = fmax(worst, fabs(b.residual));
    }
    gs_fe_balance b;
    gs_fe_reduced_get_balance(red, &b);
    gs_fe_reduced_get_info(red, &info);
    print_message("f_max 60 kHz (%d elastic modes of %ld), beta %g, brake %g, held %d, %s residual: balance %.2e "
                  "of %.3e J (damped %.3e J, residual loss %.3e J, residual support %ld rows)\n",
                  info.elastic_modes, (long)mi.n_elastic, beta, brake, held, stat ? "static" : "midpoint", worst,
                  scale, b.damped, info.residual_loss, (long)info.residual_support);
    assert_true(worst <= 1e-12 * scale);
    /* the static rule loses energy (booked), the midpoint rule none */
    if (stat)
        assert_true(info.residual_loss > 0);
    else
        assert_true(info.residual_loss == 0.0);
    if (beta > 0 || make_alpha > 0)
        assert_true(b.damped > 1e-6 * scale);
    free(u), free(v), free(fn);
    gs_fe_reduced_free(&red);
    unmake(&f);
}

static void truncated_balance(void **state)
{
    (void)state;
    for (int stat = 0; stat < 2; stat++) {
        run_balance(0.0, 0.0, false, stat);
        run_balance(3e-7, 0.05, false, stat);
        run_balance(3e-7, 0.0, true, stat);
        make_alpha = 3000.0; /* mass-proportional damping too */
        run_balance(0.0, 0.0, false, stat);
        run_balance(3e-7, 0.05, false, stat);
        run_balance(0.0, 0.0, true, stat);
        make_alpha = 0.0;
    }
}

/* No mode kept (held, f_max far below the first mode): the body is its
 * residual alone. Undamped under a constant load the static rule puts it at
 * K^{-1} f from the first step on; the midpoint rule alternates between
 * 2 K^{-1} f and 0 (the full scheme's highest modes do the same). */
static void residual_rules(void **state)
{
    (void)state;
    fixture f;
    make(&f, 0.0);
    gs_index nn = f.nn;
    double *fn = calloc((size_t)(2 * nn), sizeof *fn), *us = calloc((size_t)(2 * nn), sizeof *us);
    double *u = calloc((size_t)(2 * nn), sizeof *u);
    fn[2 * (nn - 1)] = 100.0;
    fn[2 * (nn - 6) + 1] = 200.0;
    assert_int_equal(gs_fe_model_static(f.model, fn, us), GS_OK);
    double um = maxabs(us, 2 * nn);
    for (int stat = 0; stat < 2; stat++) {
        gs_fe_reduced *red = NULL;
        gs_fe_reduced_opts o = {1.0, true, 0, NULL, 0, stat};
        assert_int_equal(gs_fe_reduced_new(f.model, &o, &red), GS_OK);
        gs_fe_reduced_info info;
        gs_fe_reduced_get_info(red, &info);
        assert_int_equal(info.modes, 0);
        assert_int_equal(gs_fe_reduced_set_step(red, 1e-5, 0.0), GS_OK);
        for (int s = 1; s <= 4; s++) {
            assert_int_equal(gs_fe_reduced_step(red, 0.0, fn), GS_OK);
            assert_int_equal(gs_fe_reduced_nodal(red, u, NULL), GS_OK);
            double want = stat ? 1.0 : (s % 2 ? 2.0 : 0.0), e = 0;
            for (gs_index k = 0; k < 2 * nn; k++)
                e = fmax(e, fabs(u[k] - want * us[k]));
            print_message("%s rule, step %d: |u - %g K^-1 f| = %.2e of %.2e m\n", stat ? "static" : "midpoint", s,
                          want, e, um);
            assert_true(e <= 1e-9 * um);
        }
        gs_fe_balance b;
        gs_fe_reduced_get_balance(red, &b);
        assert_true(fabs(b.residual) <= 1e-12 * fabs(b.work_in));
        gs_fe_reduced_free(&red);
    }
    free(fn), free(us), free(u);
    unmake(&f);
}

/* Constant load, damped, held: the rest state is K^{-1} f. */
static void truncated_static(void **state)
{
    (void)state;
    fixture f;
    make(&f, 2e-5);
    gs_fe_reduced *red = NULL;
    gs_fe_reduced_opts o = {60e3, true, 0, NULL, 0, false};
    assert_int_equal(gs_fe_reduced_new(f.model, &o, &red), GS_OK);
    gs_index nn = f.nn;
    double *fn = calloc((size_t)(2 * nn), sizeof *fn), *us = calloc((size_t)(2 * nn), sizeof *us);
    double *u = calloc((size_t)(2 * nn), sizeof *u);
    fn[2 * (nn - 1)] = 100.0;
    fn[2 * (nn - 1) + 1] = -300.0;
    fn[2 * (nn - 6) + 1] = 200.0;
    assert_int_equal(gs_fe_model_static(f.model, fn, us), GS_OK);
    assert_int_equal(gs_fe_reduced_set_step(red, 1e-5, 0.0), GS_OK);
    for (int s = 0; s < 4000; s++)
        assert_int_equal(gs_fe_reduced_step(red, 0.0, fn), GS_OK);
    assert_int_equal(gs_fe_reduced_nodal(red, u, NULL), GS_OK);
    double e = 0;
    for (gs_index k = 0; k < 2 * nn; k++)
        e = fmax(e, fabs(u[k] - us[k]));
    /* the modal part alone is far from it: the residual flexibility matters */
    double *um = calloc((size_t)(2 * nn), sizeof *um);
    gs_fe_reduced_info info;
    gs_fe_reduced_get_info(red, &info);
    double T, V, Vs = gs_fe_model_energy(f.model, us);
    gs_fe_reduced_energy(red, &T, &V);
    print_message("static limit: |u - K^-1 f| %.2e of %.2e m; elastic energy %.10e / %.10e J; "
                  "%d modes, residual support %ld rows\n",
                  e, maxabs(us, 2 * nn), V, Vs, info.modes, (long)info.residual_support);
    assert_true(e <= 1e-9 * maxabs(us, 2 * nn));
    assert_true(fabs(V - Vs) <= 1e-8 * Vs);
    free(fn), free(us), free(u), free(um);
    gs_fe_reduced_free(&red);
    unmake(&f);
}

static void save_load(void **state)
{
    (void)state;
    fixture f;
    make(&f, 3e-7);
    gs_fe_reduced *red = NULL;
    gs_fe_reduced_opts o = {60e3, false, 0, NULL, 0, false};
    assert_int_equal(gs_fe_reduced_new(f.model, &o, &red), GS_OK);
    gs_index nn = f.nn;
    double *fn = calloc((size_t)(2 * nn), sizeof *fn);
    assert_int_equal(gs_fe_reduced_set_step(red, 5e-6, 0.02), GS_OK);
    for (int s = 0; s < 50; s++) {
        loads(&f, s, fn);
        assert_int_equal(gs_fe_reduced_step(red, 1.0, fn), GS_OK);
    }
    size_t ns = gs_fe_reduced_state_size(red);
    double *x = calloc(ns, sizeof *x), *y = calloc(ns, sizeof *y);
    gs_fe_reduced_save(red, x);
    for (int pass = 0; pass < 2; pass++) {
        for (int s = 50; s < 80; s++) {
            loads(&f, s, fn);
            assert_int_equal(gs_fe_reduced_step(red, 1.0, fn), GS_OK);
        }
        if (pass == 0) {
            gs_fe_reduced_save(red, y);
            assert_int_equal(gs_fe_reduced_load(red, x), GS_OK);
        }
    }
    gs_fe_reduced_save(red, x);
    assert_memory_equal(x, y, ns * sizeof *x);
    /* a load on a node that is not a candidate is refused */
    gs_fe_reduced *r2 = NULL;
    gs_index cand[1] = {nn - 1};
    gs_fe_reduced_opts o2 = {60e3, false, 1, cand, 0, false};
    assert_int_equal(gs_fe_reduced_new(f.model, &o2, &r2), GS_OK);
    assert_int_equal(gs_fe_reduced_set_step(r2, 5e-6, 0.0), GS_OK);
    memset(fn, 0, (size_t)(2 * nn) * sizeof *fn);
    fn[2 * (nn - 2)] = 1.0;
    assert_int_equal(gs_fe_reduced_begin_step(r2, 0.0, fn), GS_EINVAL);
    gs_index dof = gs_fe_dof_node(nn - 2, 0);
    double C;
    assert_int_equal(gs_fe_reduced_compliance(r2, 1, &dof, &C), GS_EINVAL);
    gs_fe_reduced_free(&r2);
    free(fn), free(x), free(y);
    gs_fe_reduced_free(&red);
    unmake(&f);
}

/* What the body carries round-trips: the state read back (theta, omega,
 * nodal u and v) of a truncated body with residual forces and a decaying
 * residual displacement, given to a second body by set_state, reads back
 * the same and steps on as the first (the residual as a displacement
 * instead of forces: the same field, decaying at the same rate). A
 * velocity outside the kept modes is dropped (massless): what is kept is
 * the M-orthogonal projection, whose kinetic energy is below the full
 * body's and which a second set_state keeps whole. */
static void state_round_trip(void **state)
{
    (void)state;
    fixture f;
    make(&f, 3e-7);
    gs_index nn = f.nn;
    size_t n2 = (size_t)(2 * nn);
    gs_fe_reduced *a = NULL, *b = NULL;
    gs_fe_reduced_opts o = {60e3, false, 0, NULL, 0, false};
    assert_int_equal(gs_fe_reduced_new(f.model, &o, &a), GS_OK);
    assert_int_equal(gs_fe_reduced_new(f.model, &o, &b), GS_OK);
    double *u = calloc(n2, sizeof *u), *v = calloc(n2, sizeof *v), *u2 = calloc(n2, sizeof *u2),
           *v2 = calloc(n2, sizeof *v2), *fn = calloc(n2, sizeof *fn);
    wavy(nn, u, v);
    assert_int_equal(gs_fe_reduced_set_state(a, 0.1, 3.0, u, v), GS_OK);
    assert_int_equal(gs_fe_reduced_set_step(a, 5e-6, 0.02), GS_OK);
    assert_int_equal(gs_fe_reduced_set_step(b, 5e-6, 0.02), GS_OK);
    for (int s = 0; s < 30; s++) {
        loads(&f, s, fn);
        assert_int_equal(gs_fe_reduced_step(a, 1.0, fn), GS_OK);
    }
    gs_fe_reduced_info info;
    gs_fe_reduced_get_info(a, &info);
    assert_true(info.residual_support > 0);
    double th = gs_fe_reduced_theta(a), om = gs_fe_reduced_omega(a), T1, V1, T2, V2;
    assert_int_equal(gs_fe_reduced_nodal(a, u, v), GS_OK);
    gs_fe_reduced_energy(a, &T1, &V1);
    assert_int_equal(gs_fe_reduced_set_state(b, th, om, u, v), GS_OK);
    assert_int_equal(gs_fe_reduced_nodal(b, u2, v2), GS_OK);
    gs_fe_reduced_energy(b, &T2, &V2);
    double eu = 0, ev = 0;
    for (size_t k = 0; k < n2; k++) {
        eu = fmax(eu, fabs(u2[k] - u[k]));
        ev = fmax(ev, fabs(v2[k] - v[k]));
    }
    double et = fabs(gs_fe_reduced_theta(b) - th), eo = fabs(gs_fe_reduced_omega(b) - om);
    print_message("read back: u %.2e of %.2e m, v %.2e of %.2e m/s, theta %.2e, omega %.2e; T %.2e, V %.2e "
                  "(relative)\n", eu, maxabs(u, 2 * nn), ev, maxabs(v, 2 * nn), et, eo, fabs(T2 - T1) / T1,
                  fabs(V2 - V1) / V1);
    assert_true(eu <= 1e-10 * maxabs(u, 2 * nn) && ev <= 1e-10 * maxabs(v, 2 * nn));
    assert_true(et <= 1e-10 * fabs(th) && eo <= 1e-10 * fabs(om));
    /* the residual's energy two ways: 1/2 Y^T G_res Y (the first body's, its
     * forces) and 1/2 z^T K z (the second's, a displacement): equal to the
     * accuracy of the modes G_res = G_ir - sum phi phi^T / w^2 rests on
     * (measured 1.6e-10 of V, the residual more than half of it) */
    assert_true(fabs(T2 - T1) <= 1e-10 * T1 && fabs(V2 - V1) <= 1e-9 * V1);
    /* both step on alike */
    for (int s = 30; s < 60; s++) {
        loads(&f, s, fn);
        assert_int_equal(gs_fe_reduced_step(a, 1.0, fn), GS_OK);
        assert_int_equal(gs_fe_reduced_step(b, 1.0, fn), GS_OK);
    }
    assert_int_equal(gs_fe_reduced_nodal(a, u, v), GS_OK);
    assert_int_equal(gs_fe_reduced_nodal(b, u2, v2), GS_OK);
    eu = ev = 0;
    for (size_t k = 0; k < n2; k++) {
        eu = fmax(eu, fabs(u2[k] - u[k]));
        ev = fmax(ev, fabs(v2[k] - v[k]));
    }
    print_message("30 steps on: u %.2e of %.2e m, v %.2e of %.2e m/s apart\n", eu, maxabs(u, 2 * nn), ev,
                  maxabs(v, 2 * nn));
    assert_true(eu <= 1e-9 * maxabs(u, 2 * nn) && ev <= 1e-9 * maxabs(v, 2 * nn));
    /* a velocity field outside the kept modes: its projection is kept */
    gs_fe_body *full = NULL;
    assert_int_equal(gs_fe_body_new(f.model, &full), GS_OK);
    wavy(nn, u, v);
    memset(u, 0, n2 * sizeof *u);
    double Tf, Vf, Tr, Vr, Tr2;
    assert_int_equal(gs_fe_body_set_state(full, 0.0, 3.0, u, v), GS_OK);
    gs_fe_body_energy(full, &Tf, &Vf);
    assert_int_equal(gs_fe_reduced_set_state(a, 0.0, 3.0, u, v), GS_OK);
    gs_fe_reduced_energy(a, &Tr, &Vr);
    assert_int_equal(gs_fe_reduced_nodal(a, NULL, v2), GS_OK);
    assert_int_equal(gs_fe_reduced_set_state(b, 0.0, gs_fe_reduced_omega(a), u, v2), GS_OK);
    gs_fe_reduced_energy(b, &Tr2, &Vr);
    print_message("kinetic energy of a wavy velocity: full %.6e J, reduced (kept modes) %.6e J, once more %.6e J\n",
                  Tf, Tr, Tr2);
    assert_true(Tr < Tf && Tr > 0);
    assert_true(fabs(Tr2 - Tr) <= 1e-10 * Tr);
    gs_fe_body_free(&full);
    /* held or free is the basis's: switching is refused, the state untouched */
    size_t ns = gs_fe_reduced_state_size(a);
    double *x = calloc(ns, sizeof *x), *y = calloc(ns, sizeof *y);
    gs_fe_reduced_save(a, x);
    assert_int_equal(gs_fe_reduced_hold_theta(a, false), GS_OK);
    assert_int_equal(gs_fe_reduced_hold_theta(a, true), GS_EINVAL);
    gs_fe_reduced_save(a, y);
    assert_memory_equal(x, y, ns * sizeof *x);
    gs_fe_reduced *c = NULL;
    gs_fe_reduced_opts oh = {60e3, true, 0, NULL, 0, false};
    assert_int_equal(gs_fe_reduced_new(f.model, &oh, &c), GS_OK);
    assert_int_equal(gs_fe_reduced_hold_theta(c, true), GS_OK);
    assert_int_equal(gs_fe_reduced_hold_theta(c, false), GS_EINVAL);
    gs_fe_reduced_free(&c);
    free(x), free(y);
    free(u), free(v), free(u2), free(v2), free(fn);
    gs_fe_reduced_free(&a);
    gs_fe_reduced_free(&b);
    unmake(&f);
}

static void lanczos_dense(void **state)
{
    (void)state;
    gs_mesh *mesh = NULL;
    gs_fe_model *model = NULL;
    assert_int_equal(gsi_fe_mesh_annulus(0.02, 0.04, 4, 40, &mesh), GS_OK);
    gs_material mat = gs_material_steel();
    assert_int_equal(gs_fe_model_new(mesh, &mat, 0.01, 1e-4, &model), GS_OK);
    for (int held = 0; held < 2; held++) {
        gs_fe_reduced *a = NULL, *b = NULL;
        gs_fe_reduced_opts oa = {90e3, held, 0, NULL, 1, false}, ob = {90e3, held, 0, NULL, 2, false};
        assert_int_equal(gs_fe_reduced_new(model, &oa, &a), GS_OK);
        assert_int_equal(gs_fe_reduced_new(model, &ob, &b), GS_OK);
        gs_fe_reduced_info ia, ib;
        gs_fe_reduced_get_info(a, &ia);
        gs_fe_reduced_get_info(b, &ib);
        print_message("held %d: dense %d modes (highest %.1f Hz), Lanczos %d (highest %.1f Hz)\n", held, ia.modes,
                      ia.f_top_hz, ib.modes, ib.f_top_hz);
        assert_true(ia.elastic_modes >= 10);
        assert_int_equal(ia.modes, ib.modes);
        assert_true(fabs(ia.f_top_hz - ib.f_top_hz) <= 1e-8 * ia.f_top_hz);
        /* the same compliance at a few dofs (the same subspace) */
        gs_index nn = mesh->n_nodes;
        gs_index dofs[5] = {GS_FE_DOF_THETA, gs_fe_dof_node(nn - 1, 0), gs_fe_dof_node(nn - 1, 1),
                            gs_fe_dof_node(nn - 21, 0), gs_fe_dof_node(nn - 21, 1)};
        double Ca[25], Cb[25], e = 0, sc = 0;
        assert_int_equal(gs_fe_reduced_set_step(a, 5e-6, 0), GS_OK);
        assert_int_equal(gs_fe_reduced_set_step(b, 5e-6, 0), GS_OK);
        assert_int_equal(gs_fe_reduced_compliance(a, 5, dofs, Ca), GS_OK);
        assert_int_equal(gs_fe_reduced_compliance(b, 5, dofs, Cb), GS_OK);
        for (int k = 0; k < 25; k++) {
            e = fmax(e, fabs(Ca[k] - Cb[k]));
            sc = fmax(sc, fabs(Ca[k]));
        }
        assert_true(e <= 1e-8 * sc);
        gs_fe_reduced_free(&a);
        gs_fe_reduced_free(&b);
    }
    gs_fe_model_free(&model);
    gs_mesh_free(&mesh);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(all_modes_free),     cmocka_unit_test(all_modes_free_damped_brake),
        cmocka_unit_test(all_modes_held),     cmocka_unit_test(all_modes_held_damped),
        cmocka_unit_test(all_modes_rayleigh),
        cmocka_unit_test(truncated_balance),  cmocka_unit_test(truncated_static), cmocka_unit_test(residual_rules),
        cmocka_unit_test(save_load),          cmocka_unit_test(lanczos_dense),
        cmocka_unit_test(state_round_trip),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
