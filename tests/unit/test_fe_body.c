/* SPDX-License-Identifier: MIT
 * Unit tests of the body in the step (src/fe/fe_body.c): factorisation per
 * time step, the free-motion step and the condensation interface against a
 * dense inverse of the step matrix, the per-node compliance cache, a held
 * theta, state errors. Small annulus meshes, so dense LAPACK references are
 * cheap. Comparisons are relative to the largest entry compared: 1e-10, as
 * the brief asks (the dense and sparse paths agree to ~1e-14 here; cond(A)
 * is ~1e4 at these sizes and steps). */
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

typedef struct fixture {
    gs_mesh *mesh;
    gs_fe_model *model;
    gs_fe_body *body;
    gs_index ne, n;
} fixture;

static int setup(void **state)
{
    fixture *f = calloc(1, sizeof *f);
    if (!f || gsi_fe_mesh_annulus(0.02, 0.04, 3, 14, &f->mesh) != GS_OK)
        return -1;
    gs_material mat = gs_material_steel();
    if (gs_fe_model_new(f->mesh, &mat, 0.01, 1e-4, &f->model) != GS_OK)
        return -1;
    if (gs_fe_body_new(f->model, &f->body) != GS_OK)
        return -1;
    gs_fe_model_info info;
    gs_fe_model_get_info(f->model, &info);
    f->ne = info.n_elastic;
    f->n = f->ne + 1;
    *state = f;
    return 0;
}

static int teardown(void **state)
{
    fixture *f = *state;
    gs_fe_body_free(&f->body);
    gs_fe_model_free(&f->model);
    gs_mesh_free(&f->mesh);
    free(f);
    return 0;
}

/* A non-trivial state: small displacements and velocities on every node. */
static void set_wavy_state(fixture *f, double theta, double omega)
{
    gs_index nn = f->mesh->n_nodes;
    double *u = calloc((size_t)(2 * nn), sizeof *u), *v = calloc((size_t)(2 * nn), sizeof *v);
    for (gs_index k = 0; k < 2 * nn; k++) {
        u[k] = 1e-6 * sin(0.9 * k + 0.2);
        v[k] = 1e-3 * cos(1.3 * k);
    }
    assert_int_equal(gs_fe_body_set_state(f->body, theta, omega, u, v), GS_OK);
    free(u);
    free(v);
}

/* Dense A (n x n, column-major) of METHOD.md section 2, brake on theta; if
 * held, theta's row and column are replaced by the identity. */
static double *dense_step_matrix(fixture *f, double h, double c, bool held)
{
    gs_index n = f->n;
    double *K = calloc((size_t)(n * n), sizeof *K), *M = calloc((size_t)(n * n), sizeof *M);
    assert_int_equal(gs_fe_model_dense(f->model, K, M), GS_OK);
    for (gs_index i = 0; i < n * n; i++)
        K[i] = 2.0 / (h * h) * M[i] + 0.5 * K[i];
    K[n * n - 1] += c / h;
    if (held) {
        for (gs_index i = 0; i < n; i++)
            K[i + (n - 1) * n] = K[(n - 1) + i * n] = 0;
        K[n * n - 1] = 1;
    }
    free(M);
    return K;
}

static double *dense_inverse(const double *A, gs_index n)
{
    double *Ai = malloc((size_t)(n * n) * sizeof *Ai);
    memcpy(Ai, A, (size_t)(n * n) * sizeof *Ai);
    assert_int_equal(LAPACKE_dpotrf(LAPACK_COL_MAJOR, 'U', (int)n, Ai, (int)n), 0);
    assert_int_equal(LAPACKE_dpotri(LAPACK_COL_MAJOR, 'U', (int)n, Ai, (int)n), 0);
    for (gs_index j = 0; j < n; j++)
        for (gs_index i = j + 1; i < n; i++)
            Ai[i + j * n] = Ai[j + i * n];
    return Ai;
}

/* b = 2/h M w - K q + F (dense). */
static double *dense_rhs(fixture *f, double h, double moment, const double *fnod_q)
{
    gs_index n = f->n;
    double *K = calloc((size_t)(n * n), sizeof *K), *M = calloc((size_t)(n * n), sizeof *M);
    double *b = calloc((size_t)n, sizeof *b);
    assert_int_equal(gs_fe_model_dense(f->model, K, M), GS_OK);
    const double *q = gs_fe_body_q(f->body), *w = gs_fe_body_w(f->body);
    for (gs_index i = 0; i < n; i++) {
        double v = fnod_q ? fnod_q[i] : 0.0;
        for (gs_index j = 0; j < n; j++)
            v += 2.0 / h * M[i + j * n] * w[j] - K[i + j * n] * q[j];
        b[i] = v;
    }
    b[n - 1] += moment;
    free(K);
    free(M);
    return b;
}

/* Index in q of an interface dof for the dense reference (-1: immovable). */
static gs_index qindex(fixture *f, gs_index dof, bool held)
{
    if (dof == GS_FE_DOF_THETA)
        return held ? -1 : f->ne;
    return gs_fe_model_dof(f->model, dof / 2, (int)(dof % 2));
}

static void state_errors(void **state)
{
    fixture *f = *state;
    gs_fe_body *b = f->body;
    gs_index d = GS_FE_DOF_THETA;
    double x = 0;
    assert_int_equal(gs_fe_body_begin_step(b, 0, NULL), GS_ESTATE);
    assert_int_equal(gs_fe_body_end_step(b), GS_ESTATE);
    assert_int_equal(gs_fe_body_compliance(b, 1, &d, &x), GS_ESTATE);
    assert_int_equal(gs_fe_body_set_step(b, 0.0, 0), GS_EINVAL);
    assert_int_equal(gs_fe_body_set_step(b, 1e-5, -1), GS_EINVAL);
    assert_int_equal(gs_fe_body_set_step(b, NAN, 0), GS_EINVAL);
    assert_int_equal(gs_fe_body_set_step(b, 1e-5, 0), GS_OK);
    assert_int_equal(gs_fe_body_increment(b, 1, &d, &x), GS_ESTATE);
    assert_int_equal(gs_fe_body_apply(b, 1, &d, &x), GS_ESTATE);
    assert_int_equal(gs_fe_body_begin_step(b, NAN, NULL), GS_EINVAL);
    assert_int_equal(gs_fe_body_begin_step(b, 0, NULL), GS_OK);
    assert_int_equal(gs_fe_body_begin_step(b, 0, NULL), GS_ESTATE);
    assert_int_equal(gs_fe_body_set_step(b, 2e-5, 0), GS_ESTATE);
    assert_int_equal(gs_fe_body_set_state(b, 0, 0, NULL, NULL), GS_ESTATE);
    gs_index bad = 2 * f->mesh->n_nodes;
    assert_int_equal(gs_fe_body_increment(b, 1, &bad, &x), GS_EINVAL);
    bad = -7;
    assert_int_equal(gs_fe_body_apply(b, 1, &bad, &x), GS_EINVAL);
    assert_int_equal(gs_fe_body_end_step(b), GS_OK);
    gs_fe_body *nb = (gs_fe_body *)f; /* reset to NULL on failure */
    assert_int_equal(gs_fe_body_new(NULL, &nb), GS_EINVAL);
    assert_null(nb);
    gs_fe_body_free(&nb);
    gs_fe_body_free(NULL);
}

/* The compliance a body gives for a set of dofs does not depend on what it
 * was asked before (the column cache's batches): a body restored from a
 * checkpoint starts with an empty cache and must continue bit for bit like
 * the body it was saved from. One body is asked node by node first, a fresh
 * one for all the nodes at once; the blocks must be identical. */
static void compliance_independent_of_history(void **state)
{
    fixture *f = *state;
    gs_fe_body *fresh;
    assert_int_equal(gs_fe_body_new(f->model, &fresh), GS_OK);
    assert_int_equal(gs_fe_body_set_step(f->body, 1e-6, 0), GS_OK);
    assert_int_equal(gs_fe_body_set_step(fresh, 1e-6, 0), GS_OK);
    enum { NN = 12, N = 2 * NN };
    gs_index d[N];
    for (int k = 0; k < NN; k++) {
        gs_index node = f->mesh->n_nodes - 1 - 3 * k; /* outer rings, spread */
        d[2 * k] = gs_fe_dof_node(node, 0);
        d[2 * k + 1] = gs_fe_dof_node(node, 1);
    }
    double one[4], Ca[N * N], Cb[N * N];
    for (int k = 0; k < NN; k++)
        assert_int_equal(gs_fe_body_compliance(f->body, 2, d + 2 * k, one), GS_OK);
    assert_int_equal(gs_fe_body_compliance(f->body, N, d, Ca), GS_OK);
    assert_int_equal(gs_fe_body_compliance(fresh, N, d, Cb), GS_OK);
    int differ = 0;
    for (int i = 0; i < N * N; i++)
        differ += memcmp(&Ca[i], &Cb[i], sizeof Ca[i]) != 0;
    assert_int_equal(differ, 0);
    gs_fe_body_free(&fresh);
}

static void refactor_only_on_new_h(void **state)
{
    fixture *f = *state;
    gs_fe_stats st;
    gs_index dofs[3] = {GS_FE_DOF_THETA, gs_fe_dof_node(20, 0), gs_fe_dof_node(20, 1)};
    double C1[9], C2[9];
    assert_int_equal(gs_fe_body_set_step(f->body, 1e-5, 0), GS_OK);
    assert_int_equal(gs_fe_body_set_step(f->body, 1e-5, 0), GS_OK);
    gs_fe_body_get_stats(f->body, &st);
    assert_int_equal(st.factorizations, 1);
    assert_int_equal(gs_fe_body_compliance(f->body, 3, dofs, C1), GS_OK);
    /* a new brake coefficient: no factorisation, cache kept, theta entry changes */
    assert_int_equal(gs_fe_body_set_step(f->body, 1e-5, 50.0), GS_OK);
    assert_int_equal(gs_fe_body_compliance(f->body, 3, dofs, C2), GS_OK);
    gs_fe_body_get_stats(f->body, &st);
    assert_int_equal(st.factorizations, 1);
    assert_int_equal(st.cache_misses, 1);
    assert_int_equal(st.cache_hits, 1);
    assert_true(C2[0] < C1[0]);
    /* a new h: refactorised, cache emptied */
    assert_int_equal(gs_fe_body_set_step(f->body, 2e-5, 50.0), GS_OK);
    gs_fe_body_get_stats(f->body, &st);
    assert_int_equal(st.factorizations, 2);
    assert_int_equal(st.cached_nodes, 0);
    assert_true(st.factor_nnz > 0);
    for (int k = 0; k < 5; k++)
        assert_int_equal(gs_fe_body_step(f->body, 1.0, NULL), GS_OK);
    gs_fe_body_get_stats(f->body, &st);
    assert_int_equal(st.factorizations, 2);
    assert_int_equal(st.steps, 5);
}

/* Free step, compliance, increment and apply against the dense inverse. */
static void check_condensation(fixture *f, double h, double c, bool held)
{
    gs_fe_body *b = f->body;
    gs_index n = f->n, nn = f->mesh->n_nodes;
    assert_int_equal(gs_fe_body_hold_theta(b, held), GS_OK);
    assert_int_equal(gs_fe_body_set_step(b, h, c), GS_OK);
    set_wavy_state(f, 0.3, 12.0);
    double *A = dense_step_matrix(f, h, c, held), *Ai = dense_inverse(A, n);

    /* interface: theta, both components of three rim nodes, one fixed node,
     * one y component alone, and a repeated dof */
    const gs_index nodes[3] = {nn - 1, nn - 5, 2 * 14 + 3};
    gs_index dofs[10];
    int nd = 0;
    dofs[nd++] = GS_FE_DOF_THETA;
    for (int k = 0; k < 3; k++) {
        dofs[nd++] = gs_fe_dof_node(nodes[k], 0);
        dofs[nd++] = gs_fe_dof_node(nodes[k], 1);
    }
    dofs[nd++] = gs_fe_dof_node(3, 0); /* on the hub: fixed */
    dofs[nd++] = gs_fe_dof_node(17, 1);
    dofs[nd++] = gs_fe_dof_node(nodes[0], 0);

    double C[100], cmax = 0, err = 0;
    assert_int_equal(gs_fe_body_compliance(b, nd, dofs, C), GS_OK);
    for (int j = 0; j < nd; j++)
        for (int i = 0; i < nd; i++) {
            gs_index qi = qindex(f, dofs[i], held), qj = qindex(f, dofs[j], held);
            double ref = (qi < 0 || qj < 0) ? 0.0 : Ai[qi + qj * n];
            cmax = fmax(cmax, fabs(ref));
            err = fmax(err, fabs(C[i + j * nd] - ref));
            assert_true(C[i + j * nd] == C[j + i * nd]);
        }
    print_message("# h %.0e c %g held %d: compliance max |C - dense| / max |C| = %.2e\n", h, c,
                  held, err / cmax);
    assert_true(err <= 1e-10 * cmax);

    /* free motion and the condensed back-substitution */
    double *fq = calloc((size_t)n, sizeof *fq), *fn = calloc((size_t)(2 * nn), sizeof *fn);
    for (gs_index k = 0; k < 2 * nn; k++)
        fn[k] = 10.0 * cos(0.7 * k);
    for (gs_index k = 0; k < nn; k++)
        for (int cc = 0; cc < 2; cc++) {
            gs_index d = gs_fe_model_dof(f->model, k, cc);
            if (d >= 0)
                fq[d] = fn[2 * k + cc];
        }
    const double moment = 3.0;
    double *rhs = dense_rhs(f, h, held ? 0.0 : moment, fq);
    if (held)
        rhs[n - 1] = 0;
    double fi[10];
    for (int k = 0; k < nd; k++)
        fi[k] = 100.0 * (k + 1) * (k % 2 ? -1 : 1);
    for (int k = 0; k < nd; k++) {
        gs_index qk = qindex(f, dofs[k], held);
        if (qk >= 0)
            rhs[qk] += fi[k];
    }
    double *dq_free = calloc((size_t)n, sizeof *dq_free), *dq_ref = calloc((size_t)n, sizeof *dq_ref);
    double *b_free = dense_rhs(f, h, held ? 0.0 : moment, fq);
    if (held)
        b_free[n - 1] = 0;
    for (gs_index i = 0; i < n; i++)
        for (gs_index j = 0; j < n; j++) {
            dq_free[i] += Ai[i + j * n] * b_free[j];
            dq_ref[i] += Ai[i + j * n] * rhs[j];
        }
    double *q0 = malloc((size_t)n * sizeof *q0);
    memcpy(q0, gs_fe_body_q(b), (size_t)n * sizeof *q0);

    double inc[10], dmax = 0;
    assert_int_equal(gs_fe_body_begin_step(b, moment, fn), GS_OK);
    assert_int_equal(gs_fe_body_increment(b, nd, dofs, inc), GS_OK);
    for (gs_index i = 0; i < n; i++)
        dmax = fmax(dmax, fabs(dq_free[i]));
    for (int k = 0; k < nd; k++) {
        gs_index qk = qindex(f, dofs[k], held);
        double ref = qk >= 0 ? dq_free[qk] : 0.0;
        assert_true(fabs(inc[k] - ref) <= 1e-10 * dmax);
    }
    /* apply in two parts: forces add up */
    assert_int_equal(gs_fe_body_apply(b, 4, dofs, fi), GS_OK);
    assert_int_equal(gs_fe_body_apply(b, nd - 4, dofs + 4, fi + 4), GS_OK);
    assert_int_equal(gs_fe_body_end_step(b), GS_OK);
    const double *q1 = gs_fe_body_q(b);
    double emax = 0, rmax = 0, wif = 0;
    for (gs_index i = 0; i < n; i++) {
        emax = fmax(emax, fabs(q1[i] - q0[i] - dq_ref[i]));
        rmax = fmax(rmax, fabs(dq_ref[i]));
    }
    for (int k = 0; k < nd; k++) {
        gs_index qk = qindex(f, dofs[k], held);
        if (qk >= 0)
            wif += fi[k] * dq_ref[qk];
    }
    print_message("# h %.0e c %g held %d: condensed step max |dq - dense| / max |dq| = %.2e\n", h,
                  c, held, emax / rmax);
    assert_true(emax <= 1e-10 * rmax);
    gs_fe_balance bal;
    gs_fe_body_get_balance(b, &bal);
    assert_true(fabs(bal.work_iface - wif) <= 1e-10 * fabs(wif));
    double escale = fmax(bal.energy0, fabs(bal.work_in) + fabs(bal.work_iface));
    print_message("# one step with moment, nodal loads, interface forces, brake: balance residual "
                  "%.2e of %.3e J\n",
                  bal.residual, escale);
    assert_true(fabs(bal.residual) <= 1e-12 * escale);
    if (held)
        assert_true(q1[n - 1] == q0[n - 1]);
    free(A);
    free(Ai);
    free(fq);
    free(fn);
    free(rhs);
    free(b_free);
    free(dq_free);
    free(dq_ref);
    free(q0);
}

static void condensation_matches_dense(void **state)
{
    fixture *f = *state;
    check_condensation(f, 1e-5, 0.0, false);
    check_condensation(f, 1e-6, 20.0, false);
    check_condensation(f, 1e-4, 5.0, false);
    check_condensation(f, 1e-5, 0.0, true);
}

static void cache_reuse_and_eviction(void **state)
{
    fixture *f = *state;
    gs_fe_body *b = f->body;
    gs_fe_stats st0, st;
    assert_int_equal(gs_fe_body_set_step(b, 1e-5, 0), GS_OK);
    gs_index d1[4] = {gs_fe_dof_node(40, 0), gs_fe_dof_node(41, 1), gs_fe_dof_node(40, 1),
                      GS_FE_DOF_THETA};
    double C[16], Cr[16];
    assert_int_equal(gs_fe_body_compliance(b, 4, d1, C), GS_OK);
    gs_fe_body_get_stats(b, &st0);
    /* nodes 40 and 41 share a group: one group solve, which keeps the
     * group's other members too */
    assert_int_equal(st0.cache_misses, 2);
    assert_int_equal(st0.group_solves, 1);
    assert_true(st0.group_kept >= 1);
    assert_int_equal(st0.cached_nodes, (gs_index)(st0.cache_misses + st0.group_kept));
    /* the same teeth again: no solve, same numbers */
    assert_int_equal(gs_fe_body_compliance(b, 4, d1, Cr), GS_OK);
    gs_fe_body_get_stats(b, &st);
    assert_int_equal(st.solves, st0.solves);
    assert_int_equal(st.cache_hits, st0.cache_hits + 2);
    assert_memory_equal(C, Cr, sizeof C);
    /* apply on cached nodes costs no solve either */
    assert_int_equal(gs_fe_body_begin_step(b, 0, NULL), GS_OK);
    gs_fe_body_get_stats(b, &st0);
    double fz[4] = {1, 2, 3, 4};
    assert_int_equal(gs_fe_body_apply(b, 4, d1, fz), GS_OK);
    assert_int_equal(gs_fe_body_end_step(b), GS_OK);
    gs_fe_body_get_stats(b, &st);
    assert_int_equal(st.solves, st0.solves);
    /* a bound of two nodes, on a fresh body (no group member is kept
     * beyond the bound): a third node evicts the least recently used (40
     * here: 41 was used after it in this request) */
    gs_fe_body *fresh = NULL;
    assert_int_equal(gs_fe_body_new(f->model, &fresh), GS_OK);
    b = fresh;
    gs_fe_body_set_cache_limit(b, 2 * 2 * (size_t)f->ne * sizeof(double));
    assert_int_equal(gs_fe_body_set_step(b, 1e-5, 0), GS_OK);
    assert_int_equal(gs_fe_body_compliance(b, 4, d1, C), GS_OK);
    gs_fe_body_get_stats(b, &st);
    assert_int_equal(st.cached_nodes, 2);
    assert_int_equal(st.group_kept, 0);
    gs_index d2[2] = {gs_fe_dof_node(41, 0), gs_fe_dof_node(50, 0)};
    double C4[4];
    gs_fe_body_get_stats(b, &st0);
    assert_int_equal(gs_fe_body_compliance(b, 2, d2, C4), GS_OK);
    gs_fe_body_get_stats(b, &st);
    assert_int_equal(st.cached_nodes, 2);
    assert_int_equal(st.cache_misses, st0.cache_misses + 1);
    assert_int_equal(st.cache_hits, st0.cache_hits + 1);
    /* node 40 comes back (evicting 41, now the oldest): recomputed, same numbers */
    gs_index d4[4] = {gs_fe_dof_node(40, 0), gs_fe_dof_node(50, 0), gs_fe_dof_node(40, 1),
                      GS_FE_DOF_THETA};
    gs_fe_body_get_stats(b, &st0);
    assert_int_equal(gs_fe_body_compliance(b, 4, d4, Cr), GS_OK);
    gs_fe_body_get_stats(b, &st);
    assert_int_equal(st.cache_misses, st0.cache_misses + 1);
    assert_int_equal(st.cache_hits, st0.cache_hits + 1);
    const int same[3] = {0, 2, 15}; /* (40x,40x), (40y,40x), (theta,theta) in both */
    for (int k = 0; k < 3; k++)
        assert_true(fabs(Cr[same[k]] - C[same[k]]) <= 1e-14 * fabs(C[same[k]]));
    /* a request larger than the bound still succeeds */
    gs_index d3[6] = {gs_fe_dof_node(42, 0), gs_fe_dof_node(43, 0), gs_fe_dof_node(44, 0),
                      gs_fe_dof_node(45, 0), gs_fe_dof_node(46, 0), gs_fe_dof_node(47, 0)};
    double C36[36];
    assert_int_equal(gs_fe_body_compliance(b, 6, d3, C36), GS_OK);
    gs_fe_body_get_stats(b, &st);
    assert_int_equal(st.cached_nodes, 6);
    gs_fe_body_free(&fresh);
}

/* The mesh's boundary loop orders the column groups (gs_fe_model
 * col_order): a request for one boundary node solves for its group of
 * loop neighbours and keeps their columns, so the next requests along the
 * loop cost no solve, and a kept column is bit for bit the one a fresh
 * body computes when asked for that node alone (it depends on the group,
 * not on the history). The annulus gets its outer circle as the loop. */
static void column_groups_follow_boundary(void **state)
{
    fixture *f = *state;
    gs_mesh *mesh = f->mesh;
    gs_index nb = 0;
    mesh->boundary = calloc((size_t)mesh->n_nodes, sizeof *mesh->boundary);
    assert_non_null(mesh->boundary);
    for (gs_index i = 0; i < mesh->n_nodes; i++)
        if (hypot(mesh->xy[2 * i], mesh->xy[2 * i + 1]) > 0.04 - 1e-9)
            mesh->boundary[nb++] = i;
    /* in order of decreasing index: not the free-node order */
    for (gs_index i = 0; i < nb / 2; i++) {
        gs_index t = mesh->boundary[i];
        mesh->boundary[i] = mesh->boundary[nb - 1 - i];
        mesh->boundary[nb - 1 - i] = t;
    }
    mesh->n_boundary = nb;
    assert_true(nb >= 10);
    gs_material mat = gs_material_steel();
    gs_fe_model *m = NULL;
    assert_int_equal(gs_fe_model_new(mesh, &mat, 0.01, 1e-4, &m), GS_OK);
    assert_int_equal(m->n_col_boundary, nb);
    for (gs_index i = 0; i < nb; i++)
        assert_int_equal(m->col_order[i], m->dof[2 * mesh->boundary[i]] / 2);
    for (gs_index k = 0; k < m->n_free_nodes; k++)
        assert_int_equal(m->col_order[m->col_pos[k]], k);
    gs_fe_body *b = NULL, *alone = NULL;
    assert_int_equal(gs_fe_body_new(m, &b), GS_OK);
    assert_int_equal(gs_fe_body_new(m, &alone), GS_OK);
    assert_int_equal(gs_fe_body_set_step(b, 1e-5, 0), GS_OK);
    assert_int_equal(gs_fe_body_set_step(alone, 1e-5, 0), GS_OK);
    gs_index first = mesh->boundary[0], next = mesh->boundary[1], far = mesh->boundary[GSI_FE_GROUP];
    gs_index d1[2] = {gs_fe_dof_node(first, 0), gs_fe_dof_node(first, 1)};
    double C[4], Cn[4], Ca[4];
    gs_fe_stats st0, st;
    assert_int_equal(gs_fe_body_compliance(b, 2, d1, C), GS_OK);
    gs_fe_body_get_stats(b, &st0);
    assert_int_equal(st0.group_solves, 1);
    assert_int_equal(st0.group_kept, GSI_FE_GROUP - 1);
    /* the loop neighbour: kept, no solve, the same bits as asked alone */
    gs_index d2[2] = {gs_fe_dof_node(next, 0), gs_fe_dof_node(next, 1)};
    assert_int_equal(gs_fe_body_compliance(b, 2, d2, Cn), GS_OK);
    gs_fe_body_get_stats(b, &st);
    assert_int_equal(st.solves, st0.solves);
    assert_int_equal(st.group_solves, 1);
    assert_int_equal(gs_fe_body_compliance(alone, 2, d2, Ca), GS_OK);
    assert_memory_equal(Cn, Ca, sizeof Cn);
    /* the first node of the next group: a new group solve */
    gs_index d3[2] = {gs_fe_dof_node(far, 0), gs_fe_dof_node(far, 1)};
    assert_int_equal(gs_fe_body_compliance(b, 2, d3, Cn), GS_OK);
    gs_fe_body_get_stats(b, &st);
    assert_int_equal(st.group_solves, 2);
    gs_fe_body_free(&alone);
    gs_fe_body_free(&b);
    gs_fe_model_free(&m);
}

/* Consecutive requests that share dofs (the contact plan of successive
 * steps) copy the shared entries of the previous block: the block, in
 * another order and with new, repeated and immovable dofs, must equal bit
 * for bit the block computed from the same cached columns. The grouped
 * back-substitution (four columns per pass) must give the same state bit
 * for bit as one column at a time, on a body with the same columns (the
 * columns themselves depend on which nodes were solved for together). */
/* A sub-block (two-phase step record) holds the whole block's entries bit
 * for bit, whatever block the body kept before (none, another selection,
 * the whole list), and the cache fills the columns of the whole list. */
static void compliance_sub_is_exact(void **state)
{
    fixture *f = *state;
    gs_fe_body *b = f->body;
    set_wavy_state(f, 0.1, 30.0);
    gs_index d[9] = {GS_FE_DOF_THETA, gs_fe_dof_node(40, 0), gs_fe_dof_node(40, 1), gs_fe_dof_node(41, 0),
                     gs_fe_dof_node(41, 1), gs_fe_dof_node(50, 0), gs_fe_dof_node(50, 1), gs_fe_dof_node(0, 0),
                     gs_fe_dof_node(52, 1)};
    int s1[4] = {0, 2, 5, 8}, s2[5] = {0, 1, 2, 6, 8}, bad[1] = {9};
    double C[81], S[25];
    gs_fe_stats st;
    assert_int_equal(gs_fe_body_set_step(b, 1e-5, 0.5), GS_OK);
    assert_int_equal(gs_fe_body_compliance_sub(b, 9, d, 4, s1, S), GS_OK);
    gs_fe_body_get_stats(b, &st);
    assert_int_equal(st.cache_misses, 4); /* nodes 40, 41, 50, 52: 41 unselected too */
    assert_int_equal(gs_fe_body_set_step(b, 1e-5, 0.5), GS_OK); /* forget the kept block */
    assert_int_equal(gs_fe_body_compliance(b, 9, d, C), GS_OK);
    for (int round = 0; round < 3; round++) {
        /* after the whole block, after s1, after s2 (the kept block differs) */
        const int *sel = round == 1 ? s2 : s1;
        int k = round == 1 ? 5 : 4;
        assert_int_equal(gs_fe_body_compliance_sub(b, 9, d, k, sel, S), GS_OK);
        for (int j = 0; j < k; j++)
            for (int i = 0; i < k; i++)
                assert_memory_equal(&S[i + j * k], &C[sel[i] + sel[j] * 9], sizeof(double));
    }
    assert_true(S[0] > 0);
    assert_int_equal(gs_fe_body_compliance_sub(b, 9, d, 1, bad, S), GS_EINVAL);
    assert_int_equal(gs_fe_body_compliance_sub(b, 9, d, 10, s1, S), GS_EINVAL);
}

static void block_reuse_is_exact(void **state)
{
    fixture *f = *state;
    gs_fe_body *b = f->body, *twin = NULL;
    set_wavy_state(f, 0.1, 30.0);
    gs_index d1[7] = {GS_FE_DOF_THETA, gs_fe_dof_node(40, 0), gs_fe_dof_node(40, 1), gs_fe_dof_node(41, 0),
                      gs_fe_dof_node(41, 1), gs_fe_dof_node(50, 0), gs_fe_dof_node(50, 1)};
    /* d2: 41 and 50 kept (in another order), 40 gone, 52 new, 41x twice, a
     * fixed node (0, on the inner circle) */
    gs_index d2[8] = {gs_fe_dof_node(50, 1), GS_FE_DOF_THETA, gs_fe_dof_node(41, 0), gs_fe_dof_node(52, 0),
                      gs_fe_dof_node(41, 1), gs_fe_dof_node(0, 0), gs_fe_dof_node(41, 0), gs_fe_dof_node(50, 0)};
    double C1[49], C2[64], R2[64];
    gs_fe_stats st0, st;
    assert_int_equal(gs_fe_body_new(f->model, &twin), GS_OK);
    double *u = calloc((size_t)(4 * f->mesh->n_nodes), sizeof *u);
    assert_non_null(u);
    gs_fe_body_nodal(b, u, u + 2 * f->mesh->n_nodes);
    assert_int_equal(gs_fe_body_set_state(twin, gs_fe_body_theta(b), gs_fe_body_omega(b), u,
                                          u + 2 * f->mesh->n_nodes), GS_OK);
    gs_fe_body *bb[2] = {b, twin};
    for (int k = 0; k < 2; k++) {
        assert_int_equal(gs_fe_body_set_step(bb[k], 1e-5, 0.5), GS_OK);
        assert_int_equal(gs_fe_body_compliance(bb[k], 7, d1, C1), GS_OK);
        gs_fe_body_get_stats(bb[k], &st0);
        assert_int_equal(gs_fe_body_compliance(bb[k], 8, d2, C2), GS_OK);
        gs_fe_body_get_stats(bb[k], &st);
        assert_true(st.block_reused > st0.block_reused); /* the shared entries were copied */
    }
    /* set_step forgets the kept block (columns stay): computed afresh */
    assert_int_equal(gs_fe_body_set_step(b, 1e-5, 0.5), GS_OK);
    gs_fe_body_get_stats(b, &st0);
    assert_int_equal(gs_fe_body_compliance(b, 8, d2, R2), GS_OK);
    gs_fe_body_get_stats(b, &st);
    assert_int_equal(st.block_reused, st0.block_reused);
    assert_memory_equal(C2, R2, sizeof C2);
    /* the same list again: one copy, same bits */
    assert_int_equal(gs_fe_body_compliance(b, 8, d2, C2), GS_OK);
    assert_memory_equal(C2, R2, sizeof C2);
    /* a step with forces on nine node dofs (two full groups of four, one
     * more), all in one call on b, one call per dof on the twin; theta held
     * in both, so that no border correction (summed per call) differs */
    gs_index d3[10] = {GS_FE_DOF_THETA, gs_fe_dof_node(40, 0), gs_fe_dof_node(40, 1), gs_fe_dof_node(41, 0),
                       gs_fe_dof_node(41, 1), gs_fe_dof_node(50, 0), gs_fe_dof_node(50, 1), gs_fe_dof_node(52, 0),
                       gs_fe_dof_node(52, 1), gs_fe_dof_node(53, 0)};
    double fz[10] = {0.3, 1, -2, 3, 0, 5, -6, 7, 8, -9};
    for (int k = 0; k < 2; k++) {
        assert_int_equal(gs_fe_body_hold_theta(bb[k], true), GS_OK);
        assert_int_equal(gs_fe_body_begin_step(bb[k], 0.7, NULL), GS_OK);
    }
    assert_int_equal(gs_fe_body_apply(b, 10, d3, fz), GS_OK);
    double c53;
    assert_int_equal(gs_fe_body_compliance(twin, 1, &d3[9], &c53), GS_OK); /* node 53 solved alone in both */
    for (int j = 0; j < 10; j++)
        assert_int_equal(gs_fe_body_apply(twin, 1, &d3[j], &fz[j]), GS_OK);
    for (int k = 0; k < 2; k++)
        assert_int_equal(gs_fe_body_end_step(bb[k]), GS_OK);
    double dq = 0;
    for (gs_index i = 0; i < f->n; i++)
        dq = fmax(dq, fabs(gs_fe_body_q(b)[i] - gs_fe_body_q(twin)[i]));
    print_message("# grouped vs one-by-one back-substitution: max |q - q_twin| = %.3g\n", dq);
    assert_true(dq == 0);
    /* a new brake changes the theta entries: the kept block is not used */
    assert_int_equal(gs_fe_body_hold_theta(b, false), GS_OK);
    assert_int_equal(gs_fe_body_set_step(b, 1e-5, 2.0), GS_OK);
    gs_fe_body_get_stats(b, &st0);
    assert_int_equal(gs_fe_body_compliance(b, 8, d2, C2), GS_OK);
    gs_fe_body_get_stats(b, &st);
    assert_int_equal(st.block_reused, st0.block_reused);
    assert_true(C2[1 + 8] != R2[1 + 8]); /* (theta, theta) */
    /* the energies in one pass equal the two separate ones */
    double T, V;
    gs_fe_body_energy(b, &T, &V);
    assert_true(T == gs_fe_body_kinetic(b) && V == gs_fe_body_elastic(b));
    free(u);
    gs_fe_body_free(&twin);
}

static void nodal_roundtrip_and_hold(void **state)
{
    fixture *f = *state;
    gs_fe_body *b = f->body;
    gs_index nn = f->mesh->n_nodes;
    double *u = calloc((size_t)(2 * nn), sizeof *u), *u2 = calloc((size_t)(2 * nn), sizeof *u2);
    for (gs_index k = 0; k < 2 * nn; k++)
        u[k] = 1e-6 * (k + 1);
    assert_int_equal(gs_fe_body_set_state(b, 1.0, 5.0, u, NULL), GS_OK);
    gs_fe_body_nodal(b, u2, NULL);
    for (gs_index k = 0; k < nn; k++)
        for (int c = 0; c < 2; c++) {
            bool fixed = gs_fe_model_dof(f->model, k, c) < 0;
            assert_true(u2[2 * k + c] == (fixed ? 0.0 : u[2 * k + c]));
        }
    assert_true(gs_fe_body_theta(b) == 1.0 && gs_fe_body_omega(b) == 5.0);
    assert_true(fabs(gs_fe_body_elastic(b) - gs_fe_model_energy(f->model, u)) <=
                1e-14 * gs_fe_body_elastic(b));
    /* holding theta stops it and moments do no work */
    assert_int_equal(gs_fe_body_hold_theta(b, true), GS_OK);
    assert_true(gs_fe_body_omega(b) == 0.0);
    assert_int_equal(gs_fe_body_set_step(b, 1e-5, 0), GS_OK);
    for (int k = 0; k < 10; k++)
        assert_int_equal(gs_fe_body_step(b, 100.0, NULL), GS_OK);
    assert_true(gs_fe_body_theta(b) == 1.0);
    gs_fe_balance bal;
    gs_fe_body_get_balance(b, &bal);
    assert_true(bal.work_in == 0.0);
    assert_true(fabs(bal.residual) <= 1e-12 * bal.energy0);
    free(u);
    free(u2);
}

/* gs_fe_body_spin: a rigid spin increment dw changes theta' by dw, keeps
 * the elastic velocities and positions, and changes the kinetic energy by
 * exactly dw L + I dw^2 / 2 (L the angular momentum before, I the total
 * inertia), also when taken right after a step (the cached next energy). */
static void spin_increment(void **state)
{
    fixture *f = *state;
    gs_fe_body *b = f->body;
    set_wavy_state(f, 0.3, 40.0);
    assert_int_equal(gs_fe_body_set_step(b, 1e-5, 0), GS_OK);
    assert_int_equal(gs_fe_body_step(b, 0.5, NULL), GS_OK);
    gs_fe_model_info info;
    gs_fe_model_get_info(f->model, &info);
    const double dws[3] = {0.7, -3.0, 1e-3};
    for (int k = 0; k < 3; k++) {
        double T0, V0, T1, V1, dw = dws[k];
        gs_fe_body_energy(b, &T0, &V0);
        double L = gs_fe_body_angular_momentum(b), om = gs_fe_body_omega(b), th = gs_fe_body_theta(b);
        double *w0 = malloc((size_t)f->n * sizeof *w0);
        memcpy(w0, gs_fe_body_w(b), (size_t)f->n * sizeof *w0);
        gs_fe_body_spin(b, dw);
        gs_fe_body_energy(b, &T1, &V1);
        double want = dw * L + 0.5 * info.inertia_total * dw * dw;
        print_message("spin %g rad/s: dT %.12e J, dw L + I dw^2/2 %.12e J\n", dw, T1 - T0, want);
        assert_true(fabs((T1 - T0) - want) <= 1e-12 * T0);
        assert_true(fabs(T1 - gs_fe_body_kinetic(b)) <= 1e-14 * T1);
        assert_true(V1 == V0 && gs_fe_body_theta(b) == th);
        assert_true(gs_fe_body_omega(b) == om + dw);
        assert_memory_equal(gs_fe_body_w(b), w0, (size_t)f->ne * sizeof *w0);
        free(w0);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test_setup_teardown(state_errors, setup, teardown),
        cmocka_unit_test_setup_teardown(refactor_only_on_new_h, setup, teardown),
        cmocka_unit_test_setup_teardown(column_groups_follow_boundary, setup, teardown),
        cmocka_unit_test_setup_teardown(condensation_matches_dense, setup, teardown),
        cmocka_unit_test_setup_teardown(cache_reuse_and_eviction, setup, teardown),
        cmocka_unit_test_setup_teardown(block_reuse_is_exact, setup, teardown),
        cmocka_unit_test_setup_teardown(compliance_sub_is_exact, setup, teardown),
        cmocka_unit_test_setup_teardown(compliance_independent_of_history, setup, teardown),
        cmocka_unit_test_setup_teardown(nodal_roundtrip_and_hold, setup, teardown),
        cmocka_unit_test_setup_teardown(spin_increment, setup, teardown),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
