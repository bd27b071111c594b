/* SPDX-License-Identifier: MIT
 * gearsim: dense strictly convex quadratic programs (METHOD.md section 4).
 *
 *     minimise   1/2 x^T H x - c^T x
 *     subject to E x  = e      (n_eq rows: joints, kinematic meshes)
 *                G x >= g      (n_in rows: contact)
 *
 * H symmetric positive definite, tens to a few hundred unknowns. Solved by
 * the dual active-set method of Goldfarb and Idnani (Math. Programming 27,
 * 1983): Cholesky of H once, then Givens-rotation updates of the QR
 * factorisation of J = L^{-T} N_A as constraints enter and leave the active
 * set A. The method starts from the unconstrained minimum and only ever adds
 * violated constraints, so it needs no feasible starting point, and it may
 * start from a guessed active set (the previous time step's) instead.
 *
 * Multipliers follow the Lagrangian
 *     L = 1/2 x^T H x - c^T x - lambda_eq^T (E x - e) - lambda_in^T (G x - g),
 * so at the solution H x - c = E^T lambda_eq + G^T lambda_in, lambda_in >= 0,
 * and lambda_in are the contact forces (impulses) the step uses.
 *
 * Matrices are dense, row-major, with leading dimension n (row i of E starts
 * at E + i*n). None of the calls involve MPI: each rank may call them on its
 * own problems. A workspace is not thread-safe; use one per thread.
 * See docs/explanation/qp.md for the algorithm, its tolerances and its measured accuracy. */
#ifndef GEARSIM_QP_H
#define GEARSIM_QP_H

#include "gearsim/types.h"

/* Workspace: factors, active-set state and scratch for problems of up to
 * n_max unknowns, max_eq equalities and max_ineq inequalities. Reusable
 * across any number of solves; holds the last Hessian factor (see
 * gs_qp_set_hessian). */
typedef struct gs_qp gs_qp;

/* Tolerances. All are relative, so the solver is invariant to scaling a row,
 * the objective or x. Defaults from gs_qp_options_default(). */
typedef struct gs_qp_options {
    /* A row n_i^T x >= b_i counts as violated when its residual is below
     * -feas_tol * (|b_i| + |n_i| (|x| + |x0|)), x0 = H^{-1} c the
     * unconstrained minimiser (x is computed as x0 plus a correction, so its
     * round-off scales with both). The final x satisfies every row to that
     * tolerance. A row that is a combination sum_k r_k n_k of active rows is
     * judged with sum_k |r_k| (|b_k| + |n_k| (|x| + |x0|)) added to the
     * scale: consistent redundant equalities and duplicated contact rows
     * are degenerate, not infeasible. Default 1e-12. */
    double feas_tol;
    /* A row is linearly dependent on the active rows when its part outside
     * their span, in the metric of H^{-1} (|J2^T n_i|, see docs/explanation/qp.md), is
     * below dep_tol * (|L^{-1} n_i| + sum_k |r_k| |L^{-1} n_k|): its own size
     * plus that of the combination expressing it through the active rows.
     * Default 1e-11. */
    double dep_tol;
    /* H is rejected (GS_ESINGULAR) when LAPACK's reciprocal 1-norm condition
     * estimate is below this. Default 100 * DBL_EPSILON (2.2e-14). */
    double rcond_min;
    /* Cap on dual active-set steps per solve (adds plus drops); 0 means
     * 10 * (n + n_eq + n_in) + 100. Exceeding it gives GS_ENOCONV. */
    int max_iter;
} gs_qp_options;

/* One problem. The solver reads, never keeps, these arrays. */
typedef struct gs_qp_problem {
    int n;             /* unknowns, 1 <= n <= n_max */
    const double *H;   /* n*n, symmetric positive definite; only the lower
                        * triangle H[i*n+j], j <= i, is read. Ignored by
                        * gs_qp_solve_factored. */
    const double *c;   /* n: linear term (objective has -c^T x) */
    int n_eq;          /* 0 <= n_eq <= max_eq */
    const double *E;   /* n_eq*n, may be NULL when n_eq == 0 */
    const double *e;   /* n_eq */
    int n_in;          /* 0 <= n_in <= max_ineq */
    const double *G;   /* n_in*n, may be NULL when n_in == 0 */
    const double *g;   /* n_in */
} gs_qp_problem;

/* Solution. The caller owns and sizes the arrays; the solver fills them.
 * Output arrays may be NULL except x. On an error return only iterations,
 * conflict_eq and conflict_in are meaningful. */
typedef struct gs_qp_result {
    double *x;          /* [n] minimiser */
    double *lambda_eq;  /* [n_eq] or NULL: equality multipliers (any sign) */
    double *lambda_in;  /* [n_in] or NULL: inequality multipliers, >= 0,
                         * zero off the active set */
    int *active;        /* [min(n, n_in)] or NULL: indices of the active
                         * inequalities, in factorisation order; pass them
                         * back as the next solve's warm start */
    /* Scalars, always written: */
    double objective;   /* 1/2 x^T H x - c^T x */
    int n_active;       /* number of entries written to active */
    int iterations;     /* dual active-set steps (adds and drops) after the
                         * equalities and the warm start were installed */
    int n_warm_kept;    /* warm-start rows that stayed in the initial active set */
    int n_eq_dependent; /* equality rows skipped as dependent on earlier ones
                         * (consistent, lambda_eq = 0 for them) */
    int n_weak;         /* inequalities outside the active set with zero
                         * residual (to feas_tol), or dependent on the active
                         * rows and holding to round-off: the solution is
                         * degenerate, the multipliers may not be unique */
    int conflict_eq;    /* GS_EINFEASIBLE: the equality row found inconsistent, or -1 */
    int conflict_in;    /* GS_EINFEASIBLE: the inequality row that cannot be
                         * satisfied together with the active set, or -1 */
} gs_qp_result;

/* The default tolerances documented in gs_qp_options. */
void gs_qp_options_default(gs_qp_options *o);

/* Allocate a workspace for n_max >= 1 unknowns, max_eq >= 0 equalities and
 * max_ineq >= 0 inequalities. The caller owns *out and frees it with
 * gs_qp_free. Errors: GS_EINVAL (sizes), GS_ENOMEM. */
gs_err gs_qp_new(int n_max, int max_eq, int max_ineq, gs_qp **out);

/* Free the workspace; safe on NULL and on *q == NULL; sets *q = NULL. */
void gs_qp_free(gs_qp **q);

/* Replace the tolerances (copied). Errors: GS_EINVAL for negative or
 * non-finite values, or tolerances >= 1. */
gs_err gs_qp_set_options(gs_qp *q, const gs_qp_options *o);

/* Factor H (n*n, lower triangle read, row-major) once and keep the factor
 * for gs_qp_solve_factored. O(n^3). Errors: GS_EINVAL (n out of range,
 * NULL, non-finite entries), GS_ESINGULAR (H not numerically positive
 * definite: Cholesky fails or the condition estimate is below rcond_min).
 * On error the workspace holds no factor. */
gs_err gs_qp_set_hessian(gs_qp *q, int n, const double *H);

/* As gs_qp_set_hessian, but the caller gives the Cholesky factor L of
 * H = L L^T (n*n row-major, lower triangle read), e.g. cached while the
 * time step is constant. Errors: GS_EINVAL, GS_ESINGULAR (a diagonal entry
 * <= 0 or the condition estimate of H below rcond_min). */
gs_err gs_qp_set_cholesky(gs_qp *q, int n, const double *L);

/* Solve with the factor of the last successful gs_qp_set_hessian or
 * gs_qp_set_cholesky; p->H is ignored and p->n must equal that n.
 * warm_active (n_warm entries, may be NULL when n_warm == 0) lists inequality
 * indices guessed active, typically the previous solve's r->active: they are
 * installed as equalities first, and those whose multipliers come out
 * negative are released again, before the dual iterations start. A wrong
 * guess costs iterations, never accuracy. Duplicates and rows dependent on
 * the equalities are ignored. O(n^2) per step plus O(n (n_eq + n_in)) per
 * search for a violated row.
 * Errors: GS_EINVAL (sizes beyond the workspace, NULL arrays, non-finite
 * data, warm index out of range, no factor or a factor of another size),
 * GS_EINFEASIBLE (the constraints have no common point: r->conflict_eq or
 * r->conflict_in names the row that proved it), GS_ENOCONV (max_iter
 * reached, only on round-off cycling in extreme degeneracy). */
gs_err gs_qp_solve_factored(gs_qp *q, const gs_qp_problem *p, const int *warm_active,
                            int n_warm, gs_qp_result *r);

/* gs_qp_set_hessian(q, p->n, p->H) then gs_qp_solve_factored. Errors: those
 * of both. */
gs_err gs_qp_solve(gs_qp *q, const gs_qp_problem *p, const int *warm_active, int n_warm,
                   gs_qp_result *r);

#endif
