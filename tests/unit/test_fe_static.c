/* SPDX-License-Identifier: MIT
 * Unit tests of the factored static solves (src/fe/fe_static.c): the half
 * columns y_j = L^{-1} P e_j and the back substitution against the full
 * solves of the same object (K^{-1} entries and K^{-1} f), on a clamped
 * strip big enough for many supernodes; fixed dofs; input errors. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/fe.h"
#include "gearsim/fe_static.h"
#include "gearsim/mesh.h"

/* Clamped strip 100 x 20 mm, 60 x 12 cells (793 nodes). */
static void strip(gs_mesh **mesh, gs_fe_model **m, gs_fe_static **s)
{
    assert_int_equal(gs_mesh_rectangle(0.1, 0.02, 60, 12, mesh), GS_OK);
    gs_material mat = gs_material_steel();
    assert_int_equal(gs_fe_model_new(*mesh, &mat, 0.01, 0.0, m), GS_OK);
    assert_int_equal(gs_fe_static_new(*m, s), GS_OK);
}

/* y_i . y_j equals (K^{-1})_ij from gs_fe_static_columns, for dofs spread
 * over the strip (near the clamp, in the middle, at the free end). */
static void half_columns_give_the_compliance(void **state)
{
    (void)state;
    gs_mesh *mesh;
    gs_fe_model *m;
    gs_fe_static *s;
    strip(&mesh, &m, &s);
    gs_index ne = gs_fe_static_size(s);
    assert_true(ne > 1500);
    enum { N = 8 };
    gs_index nodes[N] = {1, 67, 200, 400, 500, 600, 791, 792};
    gs_index dofs[2 * N];
    for (int i = 0; i < N; i++) {
        dofs[2 * i] = gs_fe_dof_node(nodes[i], 0);
        dofs[2 * i + 1] = gs_fe_dof_node(nodes[i], 1);
    }
    double C[4 * N * N];
    assert_int_equal(gs_fe_static_columns(s, 2 * N, dofs, 2 * N, dofs, C), GS_OK);
    double *y = calloc((size_t)2 * N * (size_t)ne, sizeof *y);
    assert_non_null(y);
    gs_index maxnz = 0;
    for (int j = 0; j < 2 * N; j++) {
        gs_index nz;
        const gs_index *idx;
        const double *val;
        assert_int_equal(gs_fe_static_half_column(s, dofs[j], &nz, &idx, &val), GS_OK);
        assert_true(nz > 0 && nz <= ne);
        for (gs_index q = 0; q < nz; q++) {
            assert_true(idx[q] >= 0 && idx[q] < ne);
            if (q > 0)
                assert_true(idx[q] > idx[q - 1]);
            y[(size_t)j * (size_t)ne + (size_t)idx[q]] = val[q];
        }
        if (nz > maxnz)
            maxnz = nz;
    }
    /* sparse: a half column touches a fraction of the factor's rows */
    assert_true(maxnz < ne / 2);
    double cmax = 0.0;
    for (int i = 0; i < 4 * N * N; i++)
        cmax = fmax(cmax, fabs(C[i]));
    assert_true(cmax > 0.0);
    for (int i = 0; i < 2 * N; i++)
        for (int j = 0; j < 2 * N; j++) {
            double d = 0.0;
            for (gs_index q = 0; q < ne; q++)
                d += y[(size_t)i * (size_t)ne + (size_t)q] * y[(size_t)j * (size_t)ne + (size_t)q];
            assert_true(fabs(d - C[(size_t)j * 2 * N + (size_t)i]) <= 1e-10 * cmax);
        }
    /* Back substitution of sum_j f_j y_j equals the full solve of f. */
    double *z = calloc((size_t)ne, sizeof *z);
    size_t nn = 2 * (size_t)mesh->n_nodes;
    double *f = calloc(nn, sizeof *f), *u0 = malloc(nn * sizeof *u0), *u1 = malloc(nn * sizeof *u1);
    assert_true(z && f && u0 && u1);
    for (int j = 0; j < 2 * N; j++) {
        double fj = 100.0 * sin(1.3 * j + 0.2);
        f[dofs[j]] += fj;
        for (gs_index q = 0; q < ne; q++)
            z[q] += fj * y[(size_t)j * (size_t)ne + (size_t)q];
    }
    gs_index *all = malloc(nn * sizeof *all);
    assert_non_null(all);
    for (size_t i = 0; i < nn; i++)
        all[i] = (gs_index)i;
    long s0 = gs_fe_static_solves(s);
    assert_int_equal(gs_fe_static_back(s, 1, z, (gs_index)nn, all, u1), GS_OK);
    assert_int_equal(gs_fe_static_solves(s), s0 + 1);
    assert_int_equal(gs_fe_static_solve(s, 1, f, u0), GS_OK);
    double umax = 0.0;
    for (size_t i = 0; i < nn; i++)
        umax = fmax(umax, fabs(u0[i]));
    assert_true(umax > 0.0);
    for (size_t i = 0; i < nn; i++)
        assert_true(fabs(u1[i] - u0[i]) <= 1e-10 * umax);
    /* the clamped nodes (x = 0) do not move */
    assert_true(u1[gs_fe_dof_node(0, 0)] == 0.0 && u1[gs_fe_dof_node(0, 1)] == 0.0);
    /* Partial back substitution at a few rows (one node at the far end, the
     * chosen dofs, a clamped node): the full one's entries, visiting part of
     * L only; all rows: all of L. */
    {
        gs_index rows[2 * N + 3];
        int nr = 0;
        for (int j = 0; j < 2 * N; j++)
            rows[nr++] = dofs[j];
        rows[nr++] = gs_fe_dof_node(mesh->n_nodes - 1, 0);
        rows[nr++] = gs_fe_dof_node(mesh->n_nodes - 1, 1);
        rows[nr++] = gs_fe_dof_node(0, 1);
        double ur[2 * N + 3], frac = -1.0;
        long s1 = gs_fe_static_solves(s);
        assert_int_equal(gs_fe_static_back_rows(s, z, nr, rows, ur, &frac), GS_OK);
        assert_int_equal(gs_fe_static_solves(s), s1 + 1);
        for (int i = 0; i < nr; i++)
            assert_true(fabs(ur[i] - u1[rows[i]]) <= 1e-12 * umax);
        assert_true(ur[nr - 1] == 0.0);
        assert_true(frac > 0.0 && frac < 1.0);
        double *ua = malloc(nn * sizeof *ua);
        assert_non_null(ua);
        assert_int_equal(gs_fe_static_back_rows(s, z, (gs_index)nn, all, ua, &frac), GS_OK);
        assert_true(fabs(frac - 1.0) < 1e-12);
        for (size_t i = 0; i < nn; i++)
            assert_true(fabs(ua[i] - u1[i]) <= 1e-12 * umax);
        free(ua);
        s0 += 2;
    }
    /* Batched: the back substitutions of the half columns are the columns
     * of K^{-1}, here at the chosen dofs. */
    double Cb[4 * N * N];
    assert_int_equal(gs_fe_static_back(s, 2 * N, y, 2 * N, dofs, Cb), GS_OK);
    assert_int_equal(gs_fe_static_solves(s), s0 + 2 + 2 * N); /* + the full solve */
    for (int i = 0; i < 4 * N * N; i++)
        assert_true(fabs(Cb[i] - C[i]) <= 1e-10 * cmax);
    free(all);
    free(z);
    free(f);
    free(u0);
    free(u1);
    free(y);
    gs_fe_static_free(&s);
    gs_fe_model_free(&m);
    gs_mesh_free(&mesh);
}

static void fixed_dofs_and_errors(void **state)
{
    (void)state;
    gs_mesh *mesh;
    gs_fe_model *m;
    gs_fe_static *s;
    strip(&mesh, &m, &s);
    gs_index nz = 7;
    const gs_index *idx;
    const double *val;
    /* node 0 is on the clamp: no half column */
    assert_int_equal(gs_fe_static_half_column(s, gs_fe_dof_node(0, 1), &nz, &idx, &val), GS_OK);
    assert_int_equal(nz, 0);
    assert_int_equal(gs_fe_static_half_column(s, -1, &nz, &idx, &val), GS_EINVAL);
    assert_int_equal(gs_fe_static_half_column(s, 2 * mesh->n_nodes, &nz, &idx, &val), GS_EINVAL);
    assert_int_equal(gs_fe_static_half_column(NULL, 0, &nz, &idx, &val), GS_EINVAL);
    assert_int_equal(gs_fe_static_half_column(s, 0, NULL, &idx, &val), GS_EINVAL);
    double z[4] = {0};
    gs_index bad = 2 * mesh->n_nodes;
    assert_int_equal(gs_fe_static_back(s, 1, NULL, 1, &bad, z), GS_EINVAL);
    assert_int_equal(gs_fe_static_back(NULL, 1, z, 1, &bad, z), GS_EINVAL);
    double *zz = calloc((size_t)gs_fe_static_size(s), sizeof *zz);
    assert_int_equal(gs_fe_static_back(s, 1, zz, 1, &bad, z), GS_EINVAL);
    assert_int_equal(gs_fe_static_back_rows(s, zz, 1, &bad, z, NULL), GS_EINVAL);
    assert_int_equal(gs_fe_static_back_rows(NULL, zz, 1, &bad, z, NULL), GS_EINVAL);
    assert_int_equal(gs_fe_static_back_rows(s, NULL, 1, &bad, z, NULL), GS_EINVAL);
    free(zz);
    assert_int_equal(gs_fe_static_size(NULL), 0);
    gs_fe_static_free(&s);
    gs_fe_model_free(&m);
    gs_mesh_free(&mesh);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(half_columns_give_the_compliance),
        cmocka_unit_test(fixed_dofs_and_errors),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
