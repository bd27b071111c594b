/* SPDX-License-Identifier: MIT
 * Validation of frictionless contact in the energy-momentum step
 * (METHOD.md sections 2, 3, 4): an elastic strip hits a rigid wall end-on.
 *
 * The strip: L x H = 100 x 10 mm, 10 mm thick, plane stress, E = 210 GPa,
 * rho = 7850 kg/m^3, meshed by gs_mesh_rectangle (nx x ny cells) with its
 * clamp removed (fixed = NULL, n_fixed = 0), so it is a free body. It moves
 * at v0 = 1 m/s in +x; its end x = L (nodes i = nx) meets the wall at
 * x_w = L + gap0.
 *
 * Poisson's ratio nu = 0 for the assertions. With nu = 0 the plane-stress
 * strip carries u_x(x, t), u_y = 0 as an exact solution of 2D elasticity
 * (sigma_yy = tau_xy = 0 identically), so the continuum answer is the 1D bar
 * one: contact lasts exactly 2L/c with c = sqrt(E/rho), the strip leaves at
 * exactly -v0 without vibration. What remains is the error of the
 * discretisation (mesh, h, contact rule), which is what the test measures.
 * With nu = 0.3 the slender strip's long waves still travel at the bar speed
 * sqrt(E/rho) (its free lateral faces let it contract); the plane-stress
 * dilatational ("plate") speed sqrt(E/(rho (1 - nu^2))), 4.8 % faster,
 * belongs to a plate wide compared with the wavelength. The nu = 0.3 run is
 * reported and checked to be nearer the bar speed, with the lateral-inertia
 * dispersion of the front as the cause of its larger deviation.
 *
 * Theta is held (gs_fe_body_hold_theta). Without a clamp the elastic
 * unknowns u of the nodes can carry a rigid rotation of the strip exactly
 * (linear triangles reproduce u = theta J X), so theta and u would share
 * that motion: the full mass matrix would be singular if the core had no
 * inertia (gs_fe_model_new rejects that), and with a core inertia the rigid
 * rotation would be split between theta and u in a way that has nothing to
 * do with a strip. Holding theta leaves the consistent mass matrix of the
 * elastic unknowns alone, which is definite; the strip keeps all its rigid
 * motions (translations and rotation) in u. The core inertia given to the
 * model is unused while theta is held; we pass the strip's own polar inertia
 * about the origin, because the body still forms the Schur pivot
 * sigma = 2/h^2 I - a^T A_ee^{-1} a >= 2/h^2 I_core, which a tiny I_core
 * would leave at round-off level (set_step checks sigma > 0 even when held).
 *
 * Contact (METHOD.md section 3, homogeneous): for every candidate end node
 * j the row -du_x,j >= 0 on its increment (the wall normal is -x), the gap
 * term dropped. Candidate rules, both measured:
 *   TOUCHING   gap_j(q_n) <= 0 (in contact or penetrated; the seed's rule);
 *   PREDICTED  also the nodes whose free-motion increment would close the
 *              gap within the step: gap_j - dfree_j <= 0.
 *
 * The QP (section 4), dual form: with C = rows/columns of A^{-1} at the
 * candidates' x dofs (gs_fe_body_compliance; the Delassus matrix W = G A^{-1}
 * G^T with G = -I on those dofs) and dfree their free increments, the
 * reactions lambda >= 0 (force -lambda on the x dof) solve
 *     min 1/2 lambda^T C lambda - dfree^T lambda   s.t.  lambda >= 0,
 * whose KKT conditions are exactly the contact law: C lambda - dfree = -du
 * >= 0 (the node does not advance), lambda >= 0, complementarity. gs_qp:
 * H = C, c = dfree, G = I, g = 0. C is a principal submatrix of A^{-1},
 * A = 2/h^2 M + 1/2 K with M (consistent mass, theta held) definite and K
 * semidefinite, over distinct dofs: symmetric positive definite, which is
 * the strict convexity gs_qp requires; gs_qp checks it (rcond estimate) and
 * the test asserts GS_OK and reports the worst rcond of C seen. The primal
 * form min 1/2 (d - dfree)^T C^{-1} (d - dfree) s.t. -d >= 0, whose
 * multipliers are the same lambda, is solved alongside on one run as a
 * cross-check (C^{-1} by LAPACK).
 *
 * Energy is measured with the elastic energy summed over the elements from
 * their strains (strain_energy below). The body's gs_fe_body_elastic is the
 * assembled u^T K u; for this free strip u is dominated by the rigid and
 * long-wave motion and that form loses ~eps |K| |u|^2 (2e-10 of E0 on
 * 100x10, 1.4e-9 on 200x20) while the step itself holds E to ~1e-12. The
 * body's balance (work_iface, residual) is checked as well, with that bound.
 *
 * Tests (tolerances and reasons at the asserts; figures in
 * docs/explanation/contact_strip.md):
 *  1. nu = 0, nx = 100 x ny = 10, 1000 steps per 2L/c: contact duration
 *     (first to last step with a reaction) within 2 % of 2L/c; rebound
 *     velocity (momentum / mass after separation) -v0 within 2 %; energy
 *     (kinetic + elastic) within 1e-11 of E0 at every step, work_iface below
 *     1e-14 E0, body balance residual below 1e-8 E0; primal and dual QP give
 *     the same reactions to 1e-8. Mesh refinement (nx = 25 .. 200) with the
 *     finest at least as good as the coarsest; Courant 1/sqrt(2); nu = 0.3
 *     nearer 2L/c_bar than 2L/c_dil.
 *  2. Penetration against h: 30 .. 30000 steps per 2L/c (three decades),
 *     both candidate rules: max penetration <= (max approach speed) h,
 *     approach speeds (chatter of the end nodes) <= 5 v0, order in h over
 *     the last decade 1 +- 0.25, duration and rebound within 2 % for
 *     N >= 1000, energy as in 1 at every h.
 */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <lapacke.h>
#include <math.h>
#include <stdbool.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "gearsim/fe.h"
#include "gearsim/mesh.h"
#include "gearsim/qp.h"

static const double LEN = 0.1, HGT = 0.01, THK = 0.01;
static const double YOUNG = 210e9, RHO = 7850.0, V0 = 1.0;

typedef enum { RULE_TOUCHING = 0, RULE_PREDICTED = 1 } cand_rule;

static const char *rule_name(cand_rule r)
{
    return r == RULE_TOUCHING ? "touching" : "predicted";
}

typedef struct strip_cfg {
    int nx, ny;
    double nu;
    int per;        /* time steps per 2L/c_bar */
    cand_rule rule;
    bool cross;     /* also solve the primal QP and compare */
} strip_cfg;

typedef struct strip_out {
    double h, T_ref;        /* step, 2L/c_bar */
    int first, last;        /* first and last step with a reaction (0-based) */
    int n_steps;            /* steps run */
    int n_contact_steps;    /* steps with a reaction */
    int n_reopen;           /* contact -> free -> contact transitions */
    double duration;        /* (last - first + 1) h */
    double v_after;         /* momentum / mass after the last contact */
    double p_drift;         /* |P_end - P_sep| / |P_sep| in free flight after */
    double dE_max;          /* max_n |E_n - E_0| / E_0, E from the element strains */
    double dE_lib;          /* the same with gs_fe_body_elastic (assembled u^T K u) */
    double w_iface;         /* |work_iface| / E0 at the end */
    double resid;           /* |balance residual| / E0 at the end */
    double resid_max;       /* its maximum over the steps */
    double e_vib;           /* 1 - (1/2 m v_after^2) / E0 */
    double pen_max;         /* max over steps and end nodes of -gap (m), >= 0 */
    double vapp_max;        /* max mean approach speed dq/h over the steps in which a
                             * free end node ended up penetrated (m/s) */
    int pen_step;           /* step of the max penetration */
    double standoff_max;    /* max gap (> 0) of a node carrying a reaction (m) */
    double primal_dev;      /* max |lambda_primal - lambda_dual| / max lambda */
    double rcond_min;       /* smallest reciprocal condition estimate of C */
    long qp_iter;           /* dual active-set steps, all solves */
    int max_cand;           /* most candidates in a step */
    double seconds;
} strip_out;

static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Reciprocal 1-norm condition estimate of the SPD matrix C (m x m). */
static double rcond_spd(int m, const double *C)
{
    double *F = malloc((size_t)(m * m) * sizeof *F), anorm = 0, rc = 0;
    memcpy(F, C, (size_t)(m * m) * sizeof *F);
    for (int j = 0; j < m; j++) {
        double s = 0;
        for (int i = 0; i < m; i++)
            s += fabs(C[i + j * m]);
        anorm = fmax(anorm, s);
    }
    assert_int_equal(LAPACKE_dpotrf(LAPACK_COL_MAJOR, 'L', m, F, m), 0);
    assert_int_equal(LAPACKE_dpocon(LAPACK_COL_MAJOR, 'L', m, F, m, anorm, &rc), 0);
    free(F);
    return rc;
}

/* Primal cross-check: min 1/2 (d - dfree)^T C^{-1} (d - dfree), -d >= 0.
 * Returns max |lambda_p - lambda| (lambda_p the multipliers of -d >= 0). */
static double primal_check(gs_qp *qp, int m, const double *C, const double *dfree,
                           const double *lambda)
{
    double *Hi = malloc((size_t)(m * m) * sizeof *Hi), *c = malloc((size_t)m * sizeof *c);
    double *G = calloc((size_t)(m * m), sizeof *G), *g = calloc((size_t)m, sizeof *g);
    double *x = malloc((size_t)m * sizeof *x), *lp = malloc((size_t)m * sizeof *lp);
    memcpy(Hi, C, (size_t)(m * m) * sizeof *Hi);
    assert_int_equal(LAPACKE_dpotrf(LAPACK_COL_MAJOR, 'L', m, Hi, m), 0);
    assert_int_equal(LAPACKE_dpotri(LAPACK_COL_MAJOR, 'L', m, Hi, m), 0);
    for (int j = 0; j < m; j++) /* symmetrise the lower triangle */
        for (int i = 0; i < j; i++)
            Hi[i + j * m] = Hi[j + i * m];
    for (int i = 0; i < m; i++) {
        c[i] = 0;
        for (int j = 0; j < m; j++)
            c[i] += Hi[i + j * m] * dfree[j];
        G[i * m + i] = -1.0;
    }
    gs_qp_problem p = {m, Hi, c, 0, NULL, NULL, m, G, g};
    gs_qp_result r = {x, NULL, lp, NULL, 0, 0, 0, 0, 0, 0, -1, -1};
    assert_int_equal(gs_qp_solve(qp, &p, NULL, 0, &r), GS_OK);
    double dev = 0;
    for (int i = 0; i < m; i++)
        dev = fmax(dev, fabs(lp[i] - lambda[i]));
    free(Hi);
    free(c);
    free(G);
    free(g);
    free(x);
    free(lp);
    return dev;
}

/* Elastic energy summed over the elements from their strains, with the
 * nodal differences formed first: u^T K u of the assembled matrix loses
 * ~eps (L/dx)^2 relative when u is dominated by a smooth (or rigid) field,
 * the element form ~eps L/dx. */
static double strain_energy(const gs_mesh *mesh, double nu, const double *u)
{
    const double d = YOUNG / (1 - nu * nu);
    double e = 0;
    for (gs_index t = 0; t < mesh->n_tris; t++) {
        const gs_index *v = mesh->tri + 3 * t;
        double x[3], y[3];
        for (int k = 0; k < 3; k++) {
            x[k] = mesh->xy[2 * v[k]];
            y[k] = mesh->xy[2 * v[k] + 1];
        }
        double A2 = (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
        double b1 = y[2] - y[0], b2 = y[0] - y[1], c1 = x[0] - x[2], c2 = x[1] - x[0];
        double du1 = u[2 * v[1]] - u[2 * v[0]], du2 = u[2 * v[2]] - u[2 * v[0]];
        double dv1 = u[2 * v[1] + 1] - u[2 * v[0] + 1], dv2 = u[2 * v[2] + 1] - u[2 * v[0] + 1];
        double exx = (b1 * du1 + b2 * du2) / A2, eyy = (c1 * dv1 + c2 * dv2) / A2;
        double gxy = (c1 * du1 + c2 * du2 + b1 * dv1 + b2 * dv2) / A2;
        e += 0.5 * THK * 0.5 * A2 * d *
             (exx * exx + 2 * nu * exx * eyy + eyy * eyy + 0.5 * (1 - nu) * gxy * gxy);
    }
    return e;
}

static void run_strip(const strip_cfg *cf, strip_out *o)
{
    memset(o, 0, sizeof *o);
    double t0 = now_s();
    gs_mesh *mesh;
    assert_int_equal(gs_mesh_rectangle(LEN, HGT, cf->nx, cf->ny, &mesh), GS_OK);
    free(mesh->fixed); /* a free strip: no clamp */
    mesh->fixed = NULL;
    mesh->n_fixed = 0;
    gs_material mat = {YOUNG, cf->nu, RHO, GS_PLANE_STRESS, 0.0, 0.0};
    double i_strip = RHO * THK * LEN * HGT * (LEN * LEN / 3 + HGT * HGT / 12);
    gs_fe_model *model;
    gs_fe_body *body;
    assert_int_equal(gs_fe_model_new(mesh, &mat, THK, i_strip, &model), GS_OK);
    assert_int_equal(gs_fe_body_new(model, &body), GS_OK);
    assert_int_equal(gs_fe_body_hold_theta(body, true), GS_OK);

    const gs_index nn = mesh->n_nodes;
    gs_fe_model_info info;
    gs_fe_model_get_info(model, &info);
    const gs_index ne = info.n_elastic;
    /* lumped (row-sum) masses of the consistent mass matrix, per x dof of q:
     * the momentum 1^T M w = sum m_k w_x,k */
    double *mx = calloc((size_t)ne, sizeof *mx);
    for (gs_index t = 0; t < mesh->n_tris; t++) {
        const gs_index *v = mesh->tri + 3 * t;
        const double *a = mesh->xy + 2 * v[0], *b = mesh->xy + 2 * v[1], *c = mesh->xy + 2 * v[2];
        double area = 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]));
        for (int k = 0; k < 3; k++)
            mx[gs_fe_model_dof(model, v[k], 0)] += RHO * THK * area / 3.0;
    }
    double mass = 0;
    for (gs_index i = 0; i < ne; i++)
        mass += mx[i];
    assert_true(fabs(mass / info.mass_kg - 1) < 1e-12);

    const double cbar = sqrt(YOUNG / RHO);
    o->T_ref = 2 * LEN / cbar;
    o->h = o->T_ref / cf->per;
    const double h = o->h;
    /* the end reaches the wall in the middle of step 2: first-contact
     * penetration (TOUCHING rule) is v0 h / 2 at every h, so the rate is not
     * blurred by the phase of the touch within a step */
    const double gap0 = 2.5 * V0 * h, xw = LEN + gap0;
    const int n_total = 3 + (int)ceil(1.6 * cf->per) + 10;

    double *vel = calloc((size_t)(2 * nn), sizeof *vel), *un = calloc((size_t)(2 * nn), sizeof *un);
    for (gs_index k = 0; k < nn; k++)
        vel[2 * k] = V0;
    assert_int_equal(gs_fe_body_set_step(body, h, 0.0), GS_OK);
    assert_int_equal(gs_fe_body_set_state(body, 0.0, 0.0, NULL, vel), GS_OK);
    const double E0 = gs_fe_body_kinetic(body) + gs_fe_body_elastic(body);
    assert_true(fabs(E0 / (0.5 * mass * V0 * V0) - 1) < 1e-12);

    const int nend = cf->ny + 1;
    gs_index *end_node = malloc((size_t)nend * sizeof *end_node);
    gs_index *end_q = malloc((size_t)nend * sizeof *end_q);
    for (int j = 0; j < nend; j++) {
        end_node[j] = (gs_index)j * (cf->nx + 1) + cf->nx;
        end_q[j] = gs_fe_model_dof(model, end_node[j], 0);
        assert_true(end_q[j] >= 0);
    }
    gs_index *dofs = malloc((size_t)nend * sizeof *dofs);
    int *cand = malloc((size_t)nend * sizeof *cand); /* end index j of each candidate */
    double *gap = malloc((size_t)nend * sizeof *gap), *dfall = malloc((size_t)nend * sizeof *dfall);
    double *C = malloc((size_t)(nend * nend) * sizeof *C), *dfree = malloc((size_t)nend * sizeof *dfree);
    double *G = calloc((size_t)(nend * nend), sizeof *G), *g = calloc((size_t)nend, sizeof *g);
    double *lam = malloc((size_t)nend * sizeof *lam), *mu = malloc((size_t)nend * sizeof *mu);
    double *f = malloc((size_t)nend * sizeof *f);
    int *active = malloc((size_t)nend * sizeof *active), *warm = malloc((size_t)nend * sizeof *warm);
    /* per end node: was it a candidate without reaction in the last step */
    signed char *was_free_cand = calloc((size_t)nend, 1);
    gs_index *end_dofs_all = malloc((size_t)nend * sizeof *end_dofs_all);
    for (int j = 0; j < nend; j++)
        end_dofs_all[j] = gs_fe_dof_node(end_node[j], 0);
    gs_qp *qp, *qp2;
    assert_int_equal(gs_qp_new(nend, 0, nend, &qp), GS_OK);
    assert_int_equal(gs_qp_new(nend, 0, nend, &qp2), GS_OK);

    o->first = o->last = -1;
    o->rcond_min = 1.0;
    double p_sep = 0;
    bool prev_contact = false;
    for (int n = 0; n < n_total; n++) {
        assert_int_equal(gs_fe_body_begin_step(body, 0.0, NULL), GS_OK);
        const double *q = gs_fe_body_q(body);
        assert_int_equal(gs_fe_body_increment(body, nend, end_dofs_all, dfall), GS_OK);
        int m = 0;
        for (int j = 0; j < nend; j++) {
            gap[j] = xw - (LEN + q[end_q[j]]);
            bool c = gap[j] <= 0 || (cf->rule == RULE_PREDICTED && gap[j] - dfall[j] <= 0);
            if (c) {
                cand[m] = j;
                dofs[m] = end_dofs_all[j];
                dfree[m] = dfall[j];
                m++;
            }
        }
        bool contact = false;
        if (m > 0) {
            o->max_cand = m > o->max_cand ? m : o->max_cand;
            assert_int_equal(gs_fe_body_compliance(body, m, dofs, C), GS_OK);
            o->rcond_min = fmin(o->rcond_min, rcond_spd(m, C));
            memset(G, 0, (size_t)(m * m) * sizeof *G);
            for (int i = 0; i < m; i++) {
                G[i * m + i] = 1.0;
                g[i] = 0.0;
            }
            int nw = 0;
            for (int i = 0; i < m; i++)
                if (was_free_cand[cand[i]])
                    warm[nw++] = i;
            /* C is symmetric: column-major = row-major */
            gs_qp_problem p = {m, C, dfree, 0, NULL, NULL, m, G, g};
            gs_qp_result r = {lam, NULL, mu, active, 0, 0, 0, 0, 0, 0, -1, -1};
            assert_int_equal(gs_qp_solve(qp, &p, warm, nw, &r), GS_OK);
            o->qp_iter += r.iterations;
            bool in_act[64] = {false};
            assert_true(m <= 64);
            for (int k = 0; k < r.n_active; k++)
                in_act[active[k]] = true;
            memset(was_free_cand, 0, (size_t)nend);
            double lmax = 0;
            for (int i = 0; i < m; i++) {
                if (in_act[i] || !(lam[i] > 0))
                    lam[i] = 0; /* row lambda_i >= 0 tight: no reaction */
                was_free_cand[cand[i]] = lam[i] == 0;
                if (lam[i] > 0) {
                    contact = true;
                    o->standoff_max = fmax(o->standoff_max, gap[cand[i]]);
                }
                lmax = fmax(lmax, lam[i]);
                f[i] = -lam[i]; /* the wall pushes in -x */
            }
            if (cf->cross && lmax > 0)
                o->primal_dev = fmax(o->primal_dev, primal_check(qp2, m, C, dfree, lam) / lmax);
            assert_int_equal(gs_fe_body_apply(body, m, dofs, f), GS_OK);
        } else {
            memset(was_free_cand, 0, (size_t)nend);
        }
        assert_int_equal(gs_fe_body_end_step(body), GS_OK);
        q = gs_fe_body_q(body);
        for (int j = 0; j < nend; j++) {
            double pen = (LEN + q[end_q[j]]) - xw;
            if (pen > 0 && gap[j] > 0) /* a free node crossed the wall */
                o->vapp_max = fmax(o->vapp_max, (gap[j] + pen) / h);
            if (pen > o->pen_max) {
                o->pen_max = pen;
                o->pen_step = n;
            }
        }
        double E = gs_fe_body_kinetic(body) + gs_fe_body_elastic(body);
        o->dE_lib = fmax(o->dE_lib, fabs(E - E0) / E0);
        gs_fe_body_nodal(body, un, NULL);
        double Es = gs_fe_body_kinetic(body) + strain_energy(mesh, cf->nu, un);
        o->dE_max = fmax(o->dE_max, fabs(Es - E0) / E0);
        gs_fe_balance bb;
        gs_fe_body_get_balance(body, &bb);
        o->resid_max = fmax(o->resid_max, fabs(bb.residual) / E0);
        const double *w = gs_fe_body_w(body);
        double P = 0;
        for (gs_index i = 0; i < ne; i++)
            P += mx[i] * w[i];
        if (contact) {
            if (o->first < 0)
                o->first = n;
            else if (!prev_contact)
                o->n_reopen++;
            o->last = n;
            o->n_contact_steps++;
        } else if (o->last == n - 1 && o->last >= 0) {
            p_sep = P; /* first free step after a contact */
        }
        prev_contact = contact;
        if (n == n_total - 1) {
            o->v_after = P / mass;
            o->p_drift = fabs(P - p_sep) / fabs(p_sep);
        }
    }
    o->n_steps = n_total;
    o->duration = (o->last - o->first + 1) * h;
    o->e_vib = 1 - 0.5 * mass * o->v_after * o->v_after / E0;
    gs_fe_balance bal;
    gs_fe_body_get_balance(body, &bal);
    o->w_iface = fabs(bal.work_iface) / E0;
    o->resid = fabs(bal.residual) / E0;
    o->seconds = now_s() - t0;

    gs_qp_free(&qp);
    gs_qp_free(&qp2);
    free(mx);
    free(vel);
    free(un);
    free(end_node);
    free(end_q);
    free(dofs);
    free(cand);
    free(gap);
    free(dfall);
    free(C);
    free(dfree);
    free(G);
    free(g);
    free(lam);
    free(mu);
    free(f);
    free(active);
    free(warm);
    free(was_free_cand);
    free(end_dofs_all);
    gs_fe_body_free(&body);
    gs_fe_model_free(&model);
    gs_mesh_free(&mesh);
}

static void print_row(const char *tag, const strip_cfg *cf, const strip_out *o)
{
    print_message("# %-9s %4dx%-3d %4.2f %6d %5.2f %6d %9.5f %+9.2e %9.6f %8.1e %8.1e %8.1e %8.1e "
                  "%4d %7.2f\n",
                  tag, cf->nx, cf->ny, cf->nu, cf->per, 2.0 * cf->nx / cf->per, o->n_contact_steps,
                  o->duration / o->T_ref, o->duration / o->T_ref - 1, -o->v_after / V0, o->e_vib,
                  o->dE_max, o->w_iface, o->resid_max, o->n_reopen, o->seconds);
}

static void print_head(void)
{
    print_message("# %-9s %8s %4s %6s %5s %6s %9s %9s %9s %8s %8s %8s %8s %4s %7s\n", "rule",
                  "mesh", "nu", "N", "cfl", "active", "Tc/(2L/c)", "err", "-v/v0", "E_vib/E0",
                  "dE/E0", "W_if/E0", "resid/E0", "reop", "time s");
}

/* Every run: the strip has left (enough free flight after the last contact
 * to see it), momentum is constant in that free flight, energy exact. */
static void check_common(const strip_cfg *cf, const strip_out *o)
{
    assert_true(o->first >= 0);
    assert_true(o->n_steps - 1 - o->last >= cf->per / 4);
    /* free flight conserves momentum exactly (1^T K = 0): round-off only */
    assert_true(o->p_drift < 1e-12);
    /* homogeneous constraints: the reaction does no work (complementarity
     * holds to the QP's feas_tol 1e-12 relative), the midpoint step
     * conserves E exactly otherwise; 1e-10 leaves a factor 100 for the
     * round-off of ~1e4 state updates */
    assert_true(o->dE_max < 1e-11);
    assert_true(o->w_iface < 1e-14);
    /* the body's own balance: exact in its terms, but its elastic energy is
     * the assembled u^T K u, whose round-off for this free strip is
     * ~eps |K| |u|^2 with u dominated by the smooth (rigid and long-wave)
     * motion; measured up to 2.7e-10 (100x10) and 1.3e-9 (200x20) */
    assert_true(o->resid_max < 1e-8);
}

/* ---- 1. duration, rebound, energy; mesh trend; nu ------------------------ */

static void impact_duration_rebound_energy(void **state)
{
    (void)state;
    strip_out o;
    strip_cfg cf = {100, 10, 0.0, 1000, RULE_TOUCHING, true};
    run_strip(&cf, &o);
    print_message("# strip %g x %g mm, t %g mm, E %g GPa, rho %g, v0 %g m/s; c_bar %.2f m/s, "
                  "2L/c %.4e s\n",
                  LEN * 1e3, HGT * 1e3, THK * 1e3, YOUNG * 1e-9, RHO, V0, sqrt(YOUNG / RHO),
                  o.T_ref);
    print_message("# main run: first contact step %d, last %d, h %.3e s; max candidates %d, "
                  "QP iterations %ld, min rcond(C) %.2e\n",
                  o.first, o.last, o.h, o.max_cand, o.qp_iter, o.rcond_min);
    print_message("# energy: max|E-E0|/E0 %.2e, |W_iface|/E0 %.2e, |residual|/E0 %.2e; "
                  "momentum drift after separation %.2e\n",
                  o.dE_max, o.w_iface, o.resid, o.p_drift);
    print_message("# primal (H = C^-1) vs dual (H = C) multipliers: max dev %.2e of max lambda\n",
                  o.primal_dev);
    print_head();
    print_row("touching", &cf, &o);
    check_common(&cf, &o);
    /* 2L/c within 2 %: the criterion of the brief; the timing resolution
     * is h = 0.1 % of 2L/c here, the rest is the mesh's dispersion */
    assert_true(fabs(o.duration / o.T_ref - 1) < 0.02);
    /* rebound: energy is exact, so |v_after| = v0 sqrt(1 - E_vib/E0);
     * 2 % allows E_vib up to 4 % of E0 left in vibration */
    assert_true(fabs(-o.v_after / V0 - 1) < 0.02);
    assert_true(o.e_vib >= -1e-10); /* it cannot gain energy */
    /* both QP forms give the same reactions; C^{-1} costs cond(C) eps */
    assert_true(o.primal_dev < 1e-8);

    print_message("# mesh refinement (nu = 0, touching rule, 1000 steps per 2L/c):\n");
    print_head();
    const int nxs[4] = {25, 50, 100, 200};
    double err[4], vb[4];
    for (int k = 0; k < 4; k++) {
        strip_cfg c2 = {nxs[k], nxs[k] / 10 < 2 ? 2 : nxs[k] / 10, 0.0, 1000, RULE_TOUCHING, false};
        strip_out o2;
        run_strip(&c2, &o2);
        print_row("touching", &c2, &o2);
        check_common(&c2, &o2);
        err[k] = o2.duration / o2.T_ref - 1;
        vb[k] = -o2.v_after / V0 - 1;
    }
    /* the finest mesh is at least as good as the coarsest */
    assert_true(fabs(err[3]) <= fabs(err[0]) + 1e-3);
    assert_true(fabs(vb[3]) <= fabs(vb[0]) + 1e-3);

    print_message("# Courant number c h / dx = 1/sqrt(2) (N = 283 for 100x10), where the leading "
                  "dispersion of the consistent mass and of the midpoint rule cancel:\n");
    print_head();
    strip_cfg c4 = {100, 10, 0.0, 283, RULE_TOUCHING, false};
    strip_out o4;
    run_strip(&c4, &o4);
    print_row("touching", &c4, &o4);
    check_common(&c4, &o4);
    c4.rule = RULE_PREDICTED;
    run_strip(&c4, &o4);
    print_row("predicted", &c4, &o4);
    check_common(&c4, &o4);

    print_message("# Poisson: nu = 0.3 (bar speed sqrt(E/rho) vs plane-stress dilatational "
                  "sqrt(E/(rho(1-nu^2))), ratio %.4f):\n",
                  1 / sqrt(1 - 0.09));
    print_head();
    strip_cfg c3 = {100, 10, 0.3, 1000, RULE_TOUCHING, false};
    strip_out o3;
    run_strip(&c3, &o3);
    print_row("touching", &c3, &o3);
    check_common(&c3, &o3);
    double Td = o3.T_ref * sqrt(1 - 0.09);
    print_message("# nu = 0.3: Tc / (2L/c_bar) - 1 = %+.4f, Tc / (2L/c_dil) - 1 = %+.4f\n",
                  o3.duration / o3.T_ref - 1, o3.duration / Td - 1);
    assert_true(fabs(o3.duration / o3.T_ref - 1) < fabs(o3.duration / Td - 1));
}

/* ---- 2. penetration against h, both rules -------------------------------- */

static void penetration_vs_step(void **state)
{
    (void)state;
    const int pers[7] = {30, 100, 300, 1000, 3000, 10000, 30000};
    for (int rr = 0; rr < 2; rr++) {
        cand_rule rule = (cand_rule)rr;
        double lh[7], lp[7], ls[7];
        static double pen_touch[7];
        double rc_min = 1, it_max = 0;
        print_message("# rule %s: penetration and early stop against h (nu = 0, 100x10)\n",
                      rule_name(rule));
        print_message("# %6s %9s %10s %8s %8s %8s %10s %8s %8s %9s %8s %5s %8s %8s %6s\n", "N",
                      "h (s)", "pen max(m)", "/v0h", "@t/T", "vapp/v0", "stop max", "/v0h",
                      "rate", "Tc err", "-v/v0", "reop", "dE/E", "resid/E", "time");
        for (int k = 0; k < 7; k++) {
            strip_cfg cf = {100, 10, 0.0, pers[k], rule, false};
            strip_out o;
            run_strip(&cf, &o);
            lh[k] = log(o.h);
            lp[k] = log(fmax(o.pen_max, 1e-300));
            ls[k] = log(fmax(o.standoff_max, 1e-300));
            double rate = k > 0 ? (rule == RULE_TOUCHING ? (lp[k] - lp[k - 1]) / (lh[k] - lh[k - 1])
                                                         : (ls[k] - ls[k - 1]) / (lh[k] - lh[k - 1]))
                                : NAN;
            print_message("# %6d %9.3e %10.3e %8.4f %8.4f %8.4f %10.3e %8.4f %8.3f %+9.2e %8.6f %5d "
                          "%8.1e %8.1e %6.2f\n",
                          pers[k], o.h, o.pen_max, o.pen_max / (V0 * o.h),
                          o.pen_max > 0 ? (o.pen_step - o.first) * o.h / o.T_ref : NAN,
                          o.vapp_max / V0, o.standoff_max,
                          o.standoff_max / (V0 * o.h), rate, o.duration / o.T_ref - 1,
                          -o.v_after / V0, o.n_reopen, o.dE_max, o.resid_max, o.seconds);
            rc_min = fmin(rc_min, o.rcond_min);
            it_max = fmax(it_max, (double)o.qp_iter / o.n_contact_steps);
            check_common(&cf, &o);
            /* structural: a constrained node never advances, so penetration
             * is made only by free nodes, each by its own increment */
            assert_true(o.pen_max <= o.vapp_max * o.h * (1 + 1e-9));
            /* chatter speeds of the end nodes, measured up to 3.3 v0 */
            assert_true(o.vapp_max <= 5 * V0);
            assert_true(o.standoff_max <= 5 * V0 * o.h);
            if (rule == RULE_TOUCHING) {
                /* the end reaches the wall mid-step: v0 h / 2 at least */
                assert_true(o.pen_max >= 0.5 * V0 * o.h * (1 - 1e-9));
                assert_true(o.standoff_max == 0); /* never stops early */
                pen_touch[k] = o.pen_max;
            } else {
                /* far less than the touching rule (only pushed by the
                 * neighbours' reactions through the negative off-diagonal
                 * compliance); measured at most 0.22 of it */
                assert_true(o.pen_max <= 0.5 * pen_touch[k]);
                assert_true(o.standoff_max > 0);
            }
            if (pers[k] >= 1000) {
                assert_true(fabs(o.duration / o.T_ref - 1) < 0.02);
                assert_true(fabs(-o.v_after / V0 - 1) < 0.02);
            }
        }
        /* order in h over the last decade (3000 -> 30000 steps per 2L/c),
         * where the chatter of the end nodes, not the first touch, sets the
         * approach speed; and least squares over all three decades */
        const double *ly = rule == RULE_TOUCHING ? lp : ls;
        double r_dec = (ly[6] - ly[4]) / (lh[6] - lh[4]);
        double sx = 0, sy = 0, sxx = 0, sxy = 0;
        for (int k = 0; k < 7; k++) {
            sx += lh[k];
            sy += ly[k];
            sxx += lh[k] * lh[k];
            sxy += lh[k] * ly[k];
        }
        double slope = (7 * sxy - sx * sy) / (7 * sxx - sx * sx);
        double r_pen = (lp[6] - lp[4]) / (lh[6] - lh[4]);
        print_message("# rule %s: order in h, last decade: max penetration %.3f, early stop %s%.3f; "
                      "least squares over 3 decades (%s) %.3f\n",
                      rule_name(rule), r_pen, rule == RULE_TOUCHING ? "(none) " : "",
                      rule == RULE_TOUCHING ? 0.0 : r_dec,
                      rule == RULE_TOUCHING ? "penetration" : "early stop", slope);
        print_message("# rule %s: smallest rcond(C) over all h %.2e; QP iterations per contact "
                      "step at most %.2f (warm start from the previous step)\n",
                      rule_name(rule), rc_min, it_max);
        /* order 1: the pen/(v0 h) ratio wanders with the chatter phase by
         * a factor ~1.3 between neighbouring h, so +-0.25 over a decade */
        assert_true(fabs(r_dec - 1) < 0.25);
        assert_true(fabs(r_pen - 1) < 0.25);
        assert_true(slope > 0.6 && slope < 1.25);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(impact_duration_rebound_energy),
        cmocka_unit_test(penetration_vs_step),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
