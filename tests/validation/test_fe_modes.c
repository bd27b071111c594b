/* SPDX-License-Identifier: MIT
 * Torsional mesh modes of the elastic pair from the FE model's generalised
 * eigenproblem (include/gearsim/fe_modes.h, docs/explanation/modal.md "FE mesh modes"),
 * on contact_drive (30/20 teeth, module 2.5 mm, 20 N m). Checks (each can
 * fail):
 *  - against an independent dense solve of the same problem on a coarse mesh
 *    (flank 2, across 1, rim 1; about 2450 unknowns): K and M of both bodies
 *    from gs_fe_model_dense, the contact rows of the quasi-static analysis
 *    (gs_stiffness_run_rows) eliminated by a QR null space, LAPACK dsygv:
 *    the lowest two modes above 0 Hz agree to 1e-7 at three roll positions;
 *  - the scaling law w ~ 1 / sqrt(rho): four times the density on both gears
 *    halves every frequency (the static contact does not depend on rho) to
 *    1e-8;
 *  - on the linear mesh (refine 0): the first mode is a rigid-rotation mode (share of
 *    kinetic energy in I theta^2 / 2 above 0.9), its residual on the
 *    constrained space below 1e-8, and it lies within [1.00, 1.15] times
 *    the closed form of two inertias on a spring, w^2 = k_t (rb1^2/I1 +
 *    rb2^2/I2), with the tangent stiffness of the same position (measured
 *    +5 % to +10 %: most of a gear's inertia sits in its rim and teeth, on
 *    the contact's side of the web's torsion that the static stiffness
 *    includes);
 *  - the same on the default quadratic mesh (order 2) at four positions,
 *    roll 0.75 included, where the rows held closed lock the rolling unless
 *    they are made conjugate to it (a spurious 144 Hz mode before,
 *    gs_fe_modes_conjugate_row), and the rolling is then a 0 Hz mode;
 *  - gs_fe_modes_conjugate_row on made-up lever arms of an external and an
 *    internal pair: the rolling leaves the row at zero, both lever arms get
 *    the mean relative departure. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <json-c/json.h>
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/contact.h"
#include "gearsim/fe.h"
#include "gearsim/fe_modes.h"
#include "gearsim/geometry.h"
#include "gearsim/stiffness.h"
#include "scene_build.h"

static gs_scene *scene(int coarse, double density, int order)
{
    /* linear triangles (mesh.order 1): the figures of docs/explanation/modal.md were
     * measured on them and the dense comparison needs a small problem;
     * order 2: the default mesh */
    json_object *root = order == 1 ? vt_scene_linear("contact_drive") : vt_scene("contact_drive");
    json_object *bodies = json_object_object_get(root, "bodies");
    for (size_t i = 0; i < json_object_array_length(bodies); i++) {
        json_object *b = json_object_array_get_idx(bodies, i);
        if (coarse) {
            json_object *m = json_object_new_object();
            json_object_object_add(m, "flank", json_object_new_int(2));
            json_object_object_add(m, "across", json_object_new_int(1));
            json_object_object_add(m, "rim", json_object_new_int(1));
            json_object_object_add(m, "grading", json_object_new_int(1));
            json_object_object_add(m, "order", json_object_new_int(1));
            json_object_object_add(b, "mesh", m);
        }
        json_object *mat = json_object_new_object();
        json_object_object_add(mat, "density", json_object_new_double(density));
        json_object_object_add(b, "material", mat);
    }
    return vt_scene_parse(root);
}

static gs_fe_modes_result analyse(const gs_scene *sc, int positions)
{
    gs_fe_modes_opts o;
    gs_fe_modes_opts_defaults(&o);
    o.nearfield = 0; /* the FE model's own modes (the dense check solves the same problem) */
    o.positions = positions;
    o.modes = 2;
    gs_fe_modes_result r;
    gs_diag d;
    gs_diag_clear(&d);
    gs_err e = gs_fe_modes_analyse(sc, 0, &o, &r, &d);
    if (e != GS_OK)
        print_error("fe modes: %s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    return r;
}

/* The dense generalised eigenproblem of one position, solved on the null
 * space of the active rows; the lowest two frequencies above 0 Hz. */
static void dense_modes(const gs_scene *sc, gs_stiffness_run *run, double hz[2])
{
    gs_fe_model *m[2];
    gs_index ne[2], off[2];
    double rb[2];
    for (int k = 0; k < 2; k++) {
        const gs_scene_body *sb = &sc->bodies[sc->meshes[0].gear[k]];
        rb[k] = gs_gear_base_radius(&sb->gear);
        double rh = gs_gear_hub_radius(&sb->gear);
        double core = 0.5 * GS_PI * sb->material.density * sb->gear.face_width_m * rh * rh * rh * rh;
        assert_int_equal(gs_fe_model_new(gs_stiffness_run_mesh(run, k), &sb->material, sb->gear.face_width_m,
                                         core, &m[k]),
                         GS_OK);
        gs_fe_model_info info;
        gs_fe_model_get_info(m[k], &info);
        ne[k] = info.n_elastic;
    }
    off[0] = 0;
    off[1] = ne[0] + 1;
    int n = (int)(ne[0] + ne[1] + 2);
    double *K = calloc((size_t)n * n, sizeof *K), *M = calloc((size_t)n * n, sizeof *M);
    assert_non_null(K);
    assert_non_null(M);
    for (int k = 0; k < 2; k++) {
        int nk = (int)ne[k] + 1;
        double *Kb = malloc((size_t)nk * nk * sizeof *Kb), *Mb = malloc((size_t)nk * nk * sizeof *Mb);
        assert_int_equal(gs_fe_model_dense(m[k], Kb, Mb), GS_OK);
        for (int j = 0; j < nk; j++)
            for (int i = 0; i < nk; i++) {
                K[(size_t)(off[k] + j) * n + (size_t)(off[k] + i)] = Kb[(size_t)j * nk + i];
                M[(size_t)(off[k] + j) * n + (size_t)(off[k] + i)] = Mb[(size_t)j * nk + i];
            }
        free(Kb), free(Mb);
    }
    /* The rows carrying force, as columns of G' (n x nr). */
    const gs_contact_row *rows;
    const double *force;
    int nr = gs_stiffness_run_rows(run, &rows, &force);
    double *Gt = calloc((size_t)n * (size_t)(nr + 1), sizeof *Gt);
    int a = 0;
    for (int i = 0; i < nr; i++) {
        if (!(force[i] > 1e-9 * 568.0))
            continue;
        double *g = Gt + (size_t)a * n;
        double lever[2] = {rows[i].dg_dtheta[0], rows[i].dg_dtheta[1]};
        gs_fe_modes_conjugate_row(lever, rb);
        for (int k = 0; k < 2; k++)
            g[off[k] + ne[k]] += lever[k];
        for (int t = 0; t < rows[i].n_nodes; t++)
            for (int c = 0; c < 2; c++) {
                gs_index q = gs_fe_model_dof(m[rows[i].body[t]], rows[i].node[t], c);
                if (q >= 0)
                    g[off[rows[i].body[t]] + q] += rows[i].dg_du[t][c];
            }
        a++;
    }
    assert_true(a >= 1);
    /* Q' K Q and Q' M Q with Q from the QR factorisation of G'; the trailing
     * n - a block is the problem on the null space. */
    double *tau = malloc((size_t)a * sizeof *tau);
    assert_int_equal(LAPACKE_dgeqrf(LAPACK_COL_MAJOR, n, a, Gt, n, tau), 0);
    double *mats[2] = {K, M};
    for (int s = 0; s < 2; s++) {
        assert_int_equal(LAPACKE_dormqr(LAPACK_COL_MAJOR, 'L', 'T', n, n, a, Gt, n, tau, mats[s], n), 0);
        assert_int_equal(LAPACKE_dormqr(LAPACK_COL_MAJOR, 'R', 'N', n, n, a, Gt, n, tau, mats[s], n), 0);
    }
    int r = n - a;
    double *w = malloc((size_t)r * sizeof *w);
    /* In place: the trailing block starts at (a, a), leading dimension n. */
    assert_int_equal(LAPACKE_dsygv(LAPACK_COL_MAJOR, 1, 'N', 'U', r, K + (size_t)a * n + a, n,
                                   M + (size_t)a * n + a, n, w),
                     0);
    int got = 0;
    for (int i = 0; i < r && got < 2; i++)
        if (w[i] > 1e6) /* above 160 Hz: not the rigid rotation */
            hz[got++] = sqrt(w[i]) / (2.0 * GS_PI);
    assert_int_equal(got, 2);
    free(w), free(tau), free(Gt), free(K), free(M);
    gs_fe_model_free(&m[0]);
    gs_fe_model_free(&m[1]);
}

static void test_dense(void **state)
{
    (void)state;
    gs_scene *sc = scene(1, 7850.0, 1);
    gs_fe_modes_result r = analyse(sc, 3);
    gs_stiffness_opts so;
    gs_stiffness_opts_defaults(&so);
    so.nearfield = 0; /* as gs_fe_modes: the FE model's contact rows */
    so.positions = 3;
    so.tangent = 0;
    gs_stiffness_run *run;
    gs_diag d;
    assert_int_equal(gs_stiffness_begin(sc, 0, &so, &run, &d), GS_OK);
    for (int j = 0; j < 3; j++) {
        assert_int_equal(gs_stiffness_next(run, &d), GS_OK);
        double hz[2];
        dense_modes(sc, run, hz);
        for (int k = 0; k < 2; k++) {
            double rel = fabs(r.pt[j].hz[k] / hz[k] - 1.0);
            printf("# roll %.3f mode %d: Lanczos %.6f Hz, dense %.6f Hz, rel %.1e, residual %.1e\n", r.pt[j].roll,
                   k + 1, r.pt[j].hz[k], hz[k], rel, r.pt[j].residual[k]);
            assert_true(rel < 1e-7);
        }
    }
    gs_stiffness_run_free(&run);
    gs_fe_modes_result_clear(&r);
    gs_scene_free(&sc);
}

static void test_density_scaling(void **state)
{
    (void)state;
    gs_scene *a = scene(1, 7850.0, 1), *b = scene(1, 4 * 7850.0, 1);
    gs_fe_modes_result ra = analyse(a, 2), rb = analyse(b, 2);
    for (int j = 0; j < 2; j++)
        for (int k = 0; k < 2; k++) {
            double rel = fabs(rb.pt[j].hz[k] * 2.0 / ra.pt[j].hz[k] - 1.0);
            printf("# roll %.3f mode %d: %.6f Hz, 4 rho %.6f Hz, ratio - 1/2 rel %.1e\n", ra.pt[j].roll, k + 1,
                   ra.pt[j].hz[k], rb.pt[j].hz[k], rel);
            assert_true(rel < 1e-8);
        }
    gs_fe_modes_result_clear(&ra);
    gs_fe_modes_result_clear(&rb);
    gs_scene_free(&a);
    gs_scene_free(&b);
}

static void closed_form(int order)
{
    gs_scene *sc = scene(0, 7850.0, order);
    gs_fe_modes_result r = analyse(sc, 4);
    printf("# order %d: %ld unknowns\n", order, (long)r.unknowns);
    for (int j = 0; j < r.positions; j++) {
        const gs_fe_modes_point *p = &r.pt[j];
        double ratio = p->hz[0] / p->lumped_hz;
        printf("# roll %.3f: FE %.1f Hz (rotation %.4f, residual %.1e, %d rows, lever departure %.2e), closed form "
               "%.1f Hz, ratio %.4f\n",
               p->roll, p->hz[0], p->rotation[0], p->residual[0], p->rows, p->lever_departure, p->lumped_hz, ratio);
        assert_true(p->rotation[0] > 0.9);
        assert_true(p->residual[0] < 1e-8);
        assert_true(ratio >= 1.0 && ratio <= 1.15);
        assert_true(p->rotation[1] < 0.1); /* the next one is a body mode */
    }
    printf("# mean %.1f Hz, closed form with the mean tangent stiffness %.1f Hz\n", r.mean_hz, r.lumped_mean_hz);
    gs_fe_modes_result_clear(&r);
    gs_scene_free(&sc);
}

static void test_closed_form(void **state)
{
    (void)state;
    closed_form(1);
}

static void test_closed_form_order2(void **state)
{
    (void)state;
    closed_form(2);
}

static void test_conjugate_row(void **state)
{
    (void)state;
    const double rb[2] = {0.035, 0.0235};
    /* external: both lever arms of one sign, rolling (1/rb0, -1/rb1) */
    double a[2] = {-rb[0] * 1.01, -rb[1] * 0.99};
    double dep = gs_fe_modes_conjugate_row(a, rb);
    assert_true(fabs(dep - 0.01) < 1e-12);
    assert_true(fabs(a[0] / rb[0] - a[1] / rb[1]) < 1e-15);
    assert_true(fabs(a[0] + rb[0]) < 1e-15 && fabs(a[1] + rb[1]) < 1e-15);
    /* internal: opposite signs, rolling (1/rb0, 1/rb1) */
    double b[2] = {-rb[0] * 1.02, rb[1] * 1.00};
    dep = gs_fe_modes_conjugate_row(b, rb);
    assert_true(fabs(dep - 0.02 / 2.02) < 1e-12);
    assert_true(fabs(b[0] / rb[0] + b[1] / rb[1]) < 1e-15);
    assert_true(fabs(b[0] + 1.01 * rb[0]) < 1e-15 && fabs(b[1] - 1.01 * rb[1]) < 1e-15);
    /* already conjugate: unchanged */
    double c[2] = {-rb[0], -rb[1]};
    assert_true(gs_fe_modes_conjugate_row(c, rb) == 0.0);
    assert_true(c[0] == -rb[0] && c[1] == -rb[1]);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(test_dense),
        cmocka_unit_test(test_density_scaling),
        cmocka_unit_test(test_closed_form),
        cmocka_unit_test(test_closed_form_order2),
        cmocka_unit_test(test_conjugate_row),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
