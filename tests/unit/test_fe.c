/* SPDX-License-Identifier: MIT
 * Unit tests of the FE model (src/fe/fe_model.c): element matrices, mass
 * properties, the coupling vector, assembly against dense references, static
 * solve, stress recovery, input errors. Tolerances are round-off scaled by
 * the size of the quantities compared unless stated. */
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
#include "gearsim/mesh.h"
#include "../common/rect.h"

static const double T = 0.02; /* thickness, m */

static double max_abs(const double *a, gs_index n)
{
    double m = 0;
    for (gs_index i = 0; i < n; i++)
        m = fmax(m, fabs(a[i]));
    return m;
}

/* free_rectangle (tests/common/rect.h): no fixed node, the core inertia
 * keeps M positive. */

static void single_triangle_rigid_modes(void **state)
{
    (void)state;
    gs_mesh *mesh = free_rectangle(0.3, 0.2, 1, 1, 0);
    mesh->n_tris = 1; /* keep only the first triangle (nodes 0, 1, 3) */
    mesh->tri[2] = 3;
    /* node 2 would be in no element: make it the fourth corner of nothing */
    mesh->n_fixed = 1;
    mesh->fixed[0] = 2;
    gs_material mat = gs_material_steel();
    gs_fe_model *m = NULL;
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, 1.0, &m), GS_OK);
    gs_fe_model_info info;
    gs_fe_model_get_info(m, &info);
    assert_int_equal(info.n_elastic, 6);
    double K[49], M[49];
    assert_int_equal(gs_fe_model_dense(m, K, M), GS_OK);
    /* rigid modes: translations and the infinitesimal rotation (-y, x) */
    double modes[3][7] = {{0}};
    gs_index nodes[3] = {0, 1, 3};
    for (int a = 0; a < 3; a++) {
        gs_index d = gs_fe_model_dof(m, nodes[a], 0);
        modes[0][d] = 1;
        modes[1][d + 1] = 1;
        modes[2][d] = -mesh->xy[2 * nodes[a] + 1];
        modes[2][d + 1] = mesh->xy[2 * nodes[a]];
    }
    double kmax = max_abs(K, 49);
    for (int r = 0; r < 3; r++)
        for (int i = 0; i < 7; i++) {
            double f = 0;
            for (int j = 0; j < 7; j++)
                f += K[i + 7 * j] * modes[r][j];
            assert_true(fabs(f) < 1e-13 * kmax);
        }
    /* symmetric, 3 zero and 3 positive eigenvalues in the elastic block */
    double Ke[36], ev[6];
    for (int i = 0; i < 6; i++)
        for (int j = 0; j < 6; j++) {
            assert_true(fabs(K[i + 7 * j] - K[j + 7 * i]) <= 1e-15 * kmax);
            Ke[i + 6 * j] = K[i + 7 * j];
        }
    assert_int_equal(LAPACKE_dsyev(LAPACK_COL_MAJOR, 'N', 'U', 6, Ke, 6, ev), 0);
    for (int i = 0; i < 3; i++)
        assert_true(fabs(ev[i]) < 1e-12 * ev[5]);
    for (int i = 3; i < 6; i++)
        assert_true(ev[i] > 1e-3 * ev[5]);
    /* consistent mass: each direction sums to the element mass */
    double area = 0.5 * 0.3 * 0.2, sum = 0;
    for (int i = 0; i < 6; i += 2)
        for (int j = 0; j < 6; j += 2)
            sum += M[i + 7 * j];
    assert_true(fabs(sum - 7850.0 * T * area) < 1e-12 * sum);
    gs_fe_model_free(&m);
    assert_null(m);
    gs_mesh_free(&mesh);
}

static void patch_test_constant_strain(void **state)
{
    (void)state;
    const int nx = 5, ny = 4;
    gs_mesh *mesh = free_rectangle(0.5, 0.3, nx, ny, 0.25);
    gs_material mat = gs_material_steel();
    gs_fe_model *m = NULL;
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, 1.0, &m), GS_OK);
    gs_fe_model_info info;
    gs_fe_model_get_info(m, &info);
    gs_index n = info.n_elastic + 1;
    double *K = calloc((size_t)(n * n), sizeof *K);
    double *u = calloc((size_t)n, sizeof *u);
    double *un = calloc((size_t)(2 * mesh->n_nodes), sizeof *un);
    double *stress = calloc((size_t)(3 * mesh->n_tris), sizeof *stress);
    double *vme = calloc((size_t)mesh->n_tris, sizeof *vme);
    double *vmn = calloc((size_t)mesh->n_nodes, sizeof *vmn);
    assert_int_equal(gs_fe_model_dense(m, K, NULL), GS_OK);
    /* linear field: eps_xx = 1e-4, eps_yy = -2e-4, gamma_xy = 3e-4 */
    const double exx = 1e-4, eyy = -2e-4, gxy = 3e-4;
    for (gs_index k = 0; k < mesh->n_nodes; k++) {
        double x = mesh->xy[2 * k], y = mesh->xy[2 * k + 1];
        un[2 * k] = 1e-5 + exx * x + 0.5 * gxy * y;
        un[2 * k + 1] = -2e-5 + eyy * y + 0.5 * gxy * x;
        u[gs_fe_model_dof(m, k, 0)] = un[2 * k];
        u[gs_fe_model_dof(m, k, 1)] = un[2 * k + 1];
    }
    /* interior nodes are in equilibrium under a constant stress */
    double kmax = max_abs(K, n * n), umax = max_abs(u, n);
    for (int j = 1; j < ny; j++)
        for (int i = 1; i < nx; i++) {
            gs_index k = (gs_index)j * (nx + 1) + i;
            for (int c = 0; c < 2; c++) {
                gs_index r = gs_fe_model_dof(m, k, c);
                double f = 0;
                for (gs_index q = 0; q < n; q++)
                    f += K[r + q * n] * u[q];
                assert_true(fabs(f) < 1e-12 * kmax * umax);
            }
        }
    /* every element recovers the exact stress (plane stress) */
    double E = mat.youngs_pa, nu = mat.poisson, f = E / (1 - nu * nu);
    double sx = f * (exx + nu * eyy), sy = f * (eyy + nu * exx), txy = E / (2 * (1 + nu)) * gxy;
    double vm = sqrt(sx * sx + sy * sy - sx * sy + 3 * txy * txy);
    assert_int_equal(gs_fe_model_stress(m, un, stress, vme, vmn), GS_OK);
    for (gs_index e = 0; e < mesh->n_tris; e++) {
        assert_true(fabs(stress[3 * e] - sx) < 1e-9 * vm);
        assert_true(fabs(stress[3 * e + 1] - sy) < 1e-9 * vm);
        assert_true(fabs(stress[3 * e + 2] - txy) < 1e-9 * vm);
        assert_true(fabs(vme[e] - vm) < 1e-9 * vm);
    }
    for (gs_index k = 0; k < mesh->n_nodes; k++)
        assert_true(fabs(vmn[k] - vm) < 1e-9 * vm);
    free(K);
    free(u);
    free(un);
    free(stress);
    free(vme);
    free(vmn);
    gs_fe_model_free(&m);
    gs_mesh_free(&mesh);
}

static void plane_strain_stress(void **state)
{
    (void)state;
    gs_mesh *mesh = NULL;
    assert_int_equal(gs_mesh_rectangle(0.2, 0.1, 3, 2, &mesh), GS_OK);
    gs_material mat = gs_material_steel();
    mat.plane = GS_PLANE_STRAIN;
    gs_fe_model *m = NULL;
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, 0.0, &m), GS_OK);
    double *un = calloc((size_t)(2 * mesh->n_nodes), sizeof *un);
    double *st = calloc((size_t)(3 * mesh->n_tris), sizeof *st);
    double *vme = calloc((size_t)mesh->n_tris, sizeof *vme);
    const double eps = 1e-4; /* uniaxial strain along x */
    for (gs_index k = 0; k < mesh->n_nodes; k++)
        un[2 * k] = eps * mesh->xy[2 * k];
    assert_int_equal(gs_fe_model_stress(m, un, st, vme, NULL), GS_OK);
    double E = mat.youngs_pa, nu = mat.poisson, f = E / ((1 + nu) * (1 - 2 * nu));
    double sx = f * (1 - nu) * eps, sy = f * nu * eps, sz = nu * (sx + sy);
    double vm = sqrt(0.5 * ((sx - sy) * (sx - sy) + (sy - sz) * (sy - sz) + (sz - sx) * (sz - sx)));
    for (gs_index e = 0; e < mesh->n_tris; e++) {
        assert_true(fabs(st[3 * e] - sx) < 1e-9 * sx);
        assert_true(fabs(st[3 * e + 1] - sy) < 1e-9 * sx);
        assert_true(fabs(vme[e] - vm) < 1e-9 * sx);
    }
    free(un);
    free(st);
    free(vme);
    gs_fe_model_free(&m);
    gs_mesh_free(&mesh);
}

static void mass_properties_rectangle(void **state)
{
    (void)state;
    const double a = 0.4, bh = 0.1, rho = 7850.0;
    gs_mesh *mesh = free_rectangle(a, bh, 8, 3, 0.2);
    gs_material mat = gs_material_steel();
    gs_fe_model *m = NULL;
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, 2.5, &m), GS_OK);
    gs_fe_model_info info;
    gs_fe_model_get_info(m, &info);
    double mass = rho * T * a * bh;
    assert_true(fabs(info.area_m2 - a * bh) < 1e-14);
    assert_true(fabs(info.mass_kg - mass) < 1e-12 * mass);
    assert_true(fabs(info.centroid[0] - a / 2) < 1e-12);
    assert_true(fabs(info.centroid[1]) < 1e-12);
    /* integral rho (x^2 + y^2): exact for linear elements on a polygon */
    double Iexp = rho * T * (a * a * a * bh / 3 + a * bh * bh * bh / 12);
    assert_true(fabs(info.inertia_elastic - Iexp) < 1e-12 * Iexp);
    assert_true(fabs(info.inertia_total - Iexp - 2.5) < 1e-12 * Iexp);
    /* with no fixed node, s = M (J X) and s.(J X) = I_elastic */
    gs_index n = info.n_elastic + 1;
    double *M = calloc((size_t)(n * n), sizeof *M), *jx = calloc((size_t)n, sizeof *jx);
    double *s = calloc((size_t)n, sizeof *s);
    assert_int_equal(gs_fe_model_dense(m, NULL, M), GS_OK);
    gs_fe_model_coupling(m, s);
    for (gs_index k = 0; k < mesh->n_nodes; k++) {
        jx[gs_fe_model_dof(m, k, 0)] = -mesh->xy[2 * k + 1];
        jx[gs_fe_model_dof(m, k, 1)] = mesh->xy[2 * k];
    }
    double sj = 0, smax = max_abs(s, n - 1);
    for (gs_index i = 0; i < n - 1; i++) {
        double v = 0;
        for (gs_index j = 0; j < n - 1; j++)
            v += M[i + j * n] * jx[j];
        assert_true(fabs(v - s[i]) < 1e-12 * smax);
        assert_true(fabs(M[i + (n - 1) * n] - s[i]) == 0);
        sj += s[i] * jx[i];
    }
    assert_true(fabs(sj - Iexp) < 1e-12 * Iexp);
    assert_true(M[(n - 1) + (n - 1) * n] == info.inertia_total);
    free(M);
    free(jx);
    free(s);
    gs_fe_model_free(&m);
    gs_mesh_free(&mesh);
}

static void annulus_inertia(void **state)
{
    (void)state;
    const double ri = 0.03, ro = 0.05, rho = 7850.0;
    gs_mesh *mesh = NULL;
    assert_int_equal(gsi_fe_mesh_annulus(ri, ro, 4, 256, &mesh), GS_OK);
    gs_material mat = gs_material_steel();
    gs_fe_model *m = NULL;
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, 0.0, &m), GS_OK);
    gs_fe_model_info info;
    gs_fe_model_get_info(m, &info);
    assert_int_equal(info.n_free_nodes, 4 * 256);
    /* polygonal approximation of the circles: relative error ~ (2 pi / 256)^2 / 6 = 1e-4 */
    double Iann = 0.5 * GS_PI * rho * T * (pow(ro, 4) - pow(ri, 4));
    assert_true(fabs(info.inertia_elastic / Iann - 1) < 3e-4);
    assert_true(fabs(info.area_m2 / (GS_PI * (ro * ro - ri * ri)) - 1) < 3e-4);
    assert_true(fabs(info.centroid[0]) < 1e-12 && fabs(info.centroid[1]) < 1e-12);
    gs_fe_model_free(&m);
    gs_mesh_free(&mesh);
}

static void static_and_energy_match_dense(void **state)
{
    (void)state;
    gs_mesh *mesh = NULL;
    assert_int_equal(gs_mesh_rectangle(0.3, 0.05, 6, 2, &mesh), GS_OK);
    gs_material mat = gs_material_steel();
    gs_fe_model *m = NULL;
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, 0.0, &m), GS_OK);
    gs_fe_model_info info;
    gs_fe_model_get_info(m, &info);
    gs_index ne = info.n_elastic, n = ne + 1, nn = mesh->n_nodes;
    double *K = calloc((size_t)(n * n), sizeof *K), *Ke = calloc((size_t)(ne * ne), sizeof *Ke);
    double *f = calloc((size_t)(2 * nn), sizeof *f), *u = calloc((size_t)(2 * nn), sizeof *u);
    double *x = calloc((size_t)ne, sizeof *x);
    assert_int_equal(gs_fe_model_dense(m, K, NULL), GS_OK);
    for (gs_index j = 0; j < ne; j++)
        for (gs_index i = 0; i < ne; i++)
            Ke[i + j * ne] = K[i + j * n];
    for (gs_index k = 0; k < 2 * nn; k++)
        f[k] = sin(0.37 * k) * 1e3;
    for (gs_index k = 0; k < nn; k++)
        for (int c = 0; c < 2; c++) {
            gs_index d = gs_fe_model_dof(m, k, c);
            if (d >= 0)
                x[d] = f[2 * k + c];
        }
    assert_int_equal(gs_fe_model_static(m, f, u), GS_OK);
    assert_int_equal(LAPACKE_dposv(LAPACK_COL_MAJOR, 'U', (int)ne, 1, Ke, (int)ne, x, (int)ne), 0);
    double xmax = max_abs(x, ne), e = 0;
    for (gs_index k = 0; k < nn; k++)
        for (int c = 0; c < 2; c++) {
            gs_index d = gs_fe_model_dof(m, k, c);
            double ref = d >= 0 ? x[d] : 0.0;
            assert_true(fabs(u[2 * k + c] - ref) < 1e-9 * xmax);
            e += 0.5 * u[2 * k + c] * f[2 * k + c] * (d >= 0);
        }
    /* 1/2 u^T K u = 1/2 f.u at equilibrium */
    double ee = gs_fe_model_energy(m, u);
    assert_true(fabs(ee - e) < 1e-9 * fabs(e));
    free(K);
    free(Ke);
    free(f);
    free(u);
    free(x);
    gs_fe_model_free(&m);
    gs_mesh_free(&mesh);
}

static void input_errors(void **state)
{
    (void)state;
    gs_mesh *mesh = NULL;
    assert_int_equal(gs_mesh_rectangle(0.3, 0.05, 3, 2, &mesh), GS_OK);
    gs_material mat = gs_material_steel();
    gs_fe_model *m = (gs_fe_model *)&mat; /* must be reset to NULL on failure */
    assert_int_equal(gs_fe_model_new(NULL, &mat, T, 0, &m), GS_EINVAL);
    assert_null(m);
    assert_int_equal(gs_fe_model_new(mesh, NULL, T, 0, &m), GS_EINVAL);
    assert_int_equal(gs_fe_model_new(mesh, &mat, 0.0, 0, &m), GS_EINVAL);
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, -1.0, &m), GS_EINVAL);
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, 0, NULL), GS_EINVAL);
    gs_material bad = mat;
    bad.poisson = 0.5;
    assert_int_equal(gs_fe_model_new(mesh, &bad, T, 0, &m), GS_EINVAL);
    bad = mat;
    bad.youngs_pa = NAN;
    assert_int_equal(gs_fe_model_new(mesh, &bad, T, 0, &m), GS_EINVAL);
    /* clockwise element */
    gs_index t1 = mesh->tri[1];
    mesh->tri[1] = mesh->tri[2];
    mesh->tri[2] = t1;
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, 0, &m), GS_EGEOMETRY);
    mesh->tri[2] = mesh->tri[1];
    mesh->tri[1] = t1;
    /* node index out of range */
    gs_index t0 = mesh->tri[0];
    mesh->tri[0] = mesh->n_nodes;
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, 0, &m), GS_EINVAL);
    mesh->tri[0] = t0;
    /* nothing holds the rotation: no fixed node and no core inertia */
    gs_index nf = mesh->n_fixed;
    mesh->n_fixed = 0;
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, 0, &m), GS_ESINGULAR);
    mesh->n_fixed = nf;
    /* a free node in no element */
    mesh->n_tris -= 2; /* the last cell's triangles hold the corner node alone */
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, 0, &m), GS_EGEOMETRY);
    mesh->n_tris += 2;
    assert_null(m);
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, 0, &m), GS_OK);
    assert_int_equal(gs_fe_model_dof(m, -1, 0), -1);
    assert_int_equal(gs_fe_model_dof(m, 0, 0), -1); /* clamped */
    assert_int_equal(gs_fe_model_static(m, NULL, NULL), GS_EINVAL);
    gs_fe_model_free(&m);
    gs_fe_model_free(&m); /* safe on NULL */
    gs_fe_model_free(NULL);
    gs_mesh_free(&mesh);
}

static void static_needs_support(void **state)
{
    (void)state;
    gs_mesh *mesh = free_rectangle(0.3, 0.05, 3, 2, 0);
    gs_material mat = gs_material_steel();
    gs_fe_model *m = NULL;
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, 1.0, &m), GS_OK);
    double f[24] = {0}, u[24];
    assert_int_equal(gs_fe_model_static(m, f, u), GS_ESINGULAR);
    gs_fe_model_free(&m);
    gs_mesh_free(&mesh);
}

/* gsi_fe_step_pass (the end of an FE body's step in one pass) gives bit for
 * bit the values of the separate loops and kernels it replaces, reading the
 * rows by node pairs (gs_fe_model.pass_nb) or one by one; gsi_fe_rhs_pass
 * (its right-hand side alone, from the state it left) the same y. */
static void step_pass_matches_separate_loops(void **state)
{
    (void)state;
    gs_mesh *mesh = free_rectangle(0.3, 0.05, 10, 4, 0.2);
    gs_material mat = gs_material_steel();
    gs_fe_model *m = NULL;
    assert_int_equal(gs_fe_model_new(mesh, &mat, T, 1e-6, &m), GS_OK);
    const gs_index ne = m->ne;
    const double h = 1e-5, c = 0.5 * h + 3e-7;
    double *q0 = malloc((size_t)ne * sizeof *q0), *w0 = malloc((size_t)ne * sizeof *w0);
    double *dl = malloc((size_t)ne * sizeof *dl);
    double *q1 = malloc((size_t)ne * sizeof *q1), *w1 = malloc((size_t)ne * sizeof *w1);
    double *x1 = malloc((size_t)ne * sizeof *x1), *y1 = malloc((size_t)ne * sizeof *y1);
    double *q2 = malloc((size_t)ne * sizeof *q2), *w2 = malloc((size_t)ne * sizeof *w2);
    double *y2 = malloc((size_t)ne * sizeof *y2);
    for (gs_index i = 0; i < ne; i++) {
        q0[i] = 1e-6 * sin(0.71 * (double)i + 0.2) * (1.0 + (double)(i % 5));
        w0[i] = 1e-2 * cos(1.37 * (double)i) / (1.0 + (double)(i % 3));
        dl[i] = i % 7 ? 1e-9 * sin(2.1 * (double)i) : 0.0;
    }
    /* reference: the state update, x, y = -K x on a zero y, the energies */
    double qm1, qk1, qm2, qk2;
    for (gs_index i = 0; i < ne; i++) {
        q1[i] = q0[i] + (h * w0[i] + dl[i]);
        w1[i] = w0[i] + 2.0 * dl[i] / h;
        x1[i] = q1[i] + c * w1[i];
        y1[i] = 0.0;
    }
    gsi_fe_symv2(m, 0.0, x1, -1.0, x1, y1);
    gsi_fe_quadform2(m, w1, q1, &qm1, &qk1);
    memcpy(q2, q0, (size_t)ne * sizeof *q2);
    memcpy(w2, w0, (size_t)ne * sizeof *w2);
    for (gs_index i = 0; i < ne; i++)
        y2[i] = NAN; /* needs no initial value */
    gsi_fe_step_pass(m, h, c, dl, q2, w2, y2, &qm2, &qk2);
    assert_memory_equal(q1, q2, (size_t)ne * sizeof *q1);
    assert_memory_equal(w1, w2, (size_t)ne * sizeof *w1);
    assert_memory_equal(y1, y2, (size_t)ne * sizeof *y1);
    assert_memory_equal(&qm1, &qm2, sizeof qm1);
    assert_memory_equal(&qk1, &qk2, sizeof qk1);
    assert_true(qm1 > 0 && qk1 > 0);
    /* without the energies (qm, qk NULL): the same state and y */
    memcpy(q2, q0, (size_t)ne * sizeof *q2);
    memcpy(w2, w0, (size_t)ne * sizeof *w2);
    for (gs_index i = 0; i < ne; i++)
        y2[i] = NAN;
    gsi_fe_step_pass(m, h, c, dl, q2, w2, y2, NULL, NULL);
    assert_memory_equal(q1, q2, (size_t)ne * sizeof *q1);
    assert_memory_equal(w1, w2, (size_t)ne * sizeof *w1);
    assert_memory_equal(y1, y2, (size_t)ne * sizeof *y1);
    /* the right-hand side alone from the new state (gsi_fe_rhs_pass): the
     * same y, the state not written */
    for (gs_index i = 0; i < ne; i++)
        y2[i] = NAN;
    gsi_fe_rhs_pass(m, c, q1, w1, y2);
    assert_memory_equal(y1, y2, (size_t)ne * sizeof *y1);
    /* the same with the row indices one by one (no node pairs) */
    assert_non_null(m->pass_nb);
    int32_t *nb = m->pass_nb;
    m->pass_nb = NULL;
    memcpy(q2, q0, (size_t)ne * sizeof *q2);
    memcpy(w2, w0, (size_t)ne * sizeof *w2);
    gsi_fe_step_pass(m, h, c, dl, q2, w2, y2, &qm2, &qk2);
    double *y3 = malloc((size_t)ne * sizeof *y3);
    for (gs_index i = 0; i < ne; i++)
        y3[i] = NAN;
    gsi_fe_rhs_pass(m, c, q1, w1, y3);
    m->pass_nb = nb; /* back before any assertion can end the test */
    assert_memory_equal(y1, y2, (size_t)ne * sizeof *y1);
    assert_memory_equal(q1, q2, (size_t)ne * sizeof *q1);
    assert_memory_equal(&qm1, &qm2, sizeof qm1);
    assert_memory_equal(&qk1, &qk2, sizeof qk1);
    assert_memory_equal(y1, y3, (size_t)ne * sizeof *y1);
    free(y3);
    free(q0), free(w0), free(dl), free(q1), free(w1), free(x1), free(y1);
    free(q2), free(w2), free(y2);
    gs_fe_model_free(&m);
    gs_mesh_free(&mesh);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(single_triangle_rigid_modes),
        cmocka_unit_test(patch_test_constant_strain),
        cmocka_unit_test(plane_strain_stress),
        cmocka_unit_test(mass_properties_rectangle),
        cmocka_unit_test(annulus_inertia),
        cmocka_unit_test(static_and_energy_match_dense),
        cmocka_unit_test(input_errors),
        cmocka_unit_test(static_needs_support),
        cmocka_unit_test(step_pass_matches_separate_loops),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
