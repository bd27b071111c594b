/* SPDX-License-Identifier: MIT
 * gearsim: static solves of an elastic body with its stiffness factored once
 * (the quasi-static mesh stiffness of docs/explanation/stiffness.md; METHOD.md section 1).
 *
 * gs_fe_model_static() factorises K on every call; this object keeps the
 * sparse Cholesky factor of the elastic block K (fixed nodes held, no theta)
 * so that many right-hand sides and compliance columns cost one pair of
 * triangular solves each. Dofs are named as in fe.h: gs_fe_dof_node(node,
 * comp) in mesh numbering; fixed nodes are immovable (zero rows and columns).
 *
 * The model must outlive the object. Not thread-safe (one object per thread);
 * not collective. */
#ifndef GEARSIM_FE_STATIC_H
#define GEARSIM_FE_STATIC_H

#include "gearsim/fe.h"

typedef struct gs_fe_static gs_fe_static;

/* Factor K of model m once. Errors: GS_EINVAL (NULL), GS_ESINGULAR (K not
 * positive definite: too few fixed nodes), GS_ENOMEM. */
gs_err gs_fe_static_new(const gs_fe_model *m, gs_fe_static **out);

/* Free; safe on NULL; sets *s = NULL. */
void gs_fe_static_free(gs_fe_static **s);

/* nrhs static solutions K u = f at once: f_nodes and u_nodes hold nrhs
 * consecutive blocks of 2 * n_nodes values (x, y per mesh node, body frame).
 * Forces on fixed nodes are ignored, their displacements set to zero.
 * Errors: GS_EINVAL, GS_ENOMEM. */
gs_err gs_fe_static_solve(gs_fe_static *s, int nrhs, const double *f_nodes, double *u_nodes);

/* Columns of the static compliance K^{-1}: for each of the n dofs in `cols`
 * (gs_fe_dof_node numbering) the response at the n_rows dofs `rows`, written
 * to out[j * n_rows + i] = (K^{-1})[rows[i], cols[j]] (column-major). A
 * fixed node's dof gives zero rows / columns. The columns are solved in
 * batches (one multi-right-hand-side solve each).
 * Errors: GS_EINVAL (NULL, a dof out of range), GS_ENOMEM. */
gs_err gs_fe_static_columns(gs_fe_static *s, int n, const gs_index *cols, gs_index n_rows,
                            const gs_index *rows, double *out);

/* Half columns of the compliance, for the few-columns-of-a-large-body case
 * (the quasi-static contact of docs/explanation/stiffness.md). With K = P^T L L^T P
 * (the sparse Cholesky factor, fill-reducing permutation P), the half
 * column of dof j is y_j = L^{-1} P e_j, sparse (the elimination-tree
 * ancestors of j's pivot: a few per cent of L's rows, where a solve touches
 * all of L), and (K^{-1})_{ij} = y_i . y_j. gs_fe_static_size is the
 * length of these vectors (free dofs); half_column returns y_j's pattern
 * (factor positions, ascending) and values in *idx, *val (nnz of them;
 * owned by s, valid until the next call; nnz = 0 for a fixed node's dof).
 * gs_fe_static_back completes nrhs solves from their forward halves: for
 * each dense z_j (nrhs consecutive blocks of gs_fe_static_size entries,
 * e.g. y_d, giving the column K^{-1} e_d, or sum_d f_d y_d, giving
 * K^{-1} f) u_j = P^T L^{-T} z_j, written at the n_rows dofs `rows`
 * (gs_fe_dof_node numbering; fixed: 0) to out[j * n_rows + i]; counted as
 * nrhs solves. Errors: GS_EINVAL (NULL, a dof out of range), GS_ENOMEM. */
gs_index gs_fe_static_size(const gs_fe_static *s);
gs_err gs_fe_static_half_column(gs_fe_static *s, gs_index dof, gs_index *nnz,
                                const gs_index **idx, const double **val);
gs_err gs_fe_static_back(gs_fe_static *s, int nrhs, const double *z, gs_index n_rows,
                         const gs_index *rows, double *out);

/* gs_fe_static_back for one right-hand side z when only the entries at the
 * n_rows dofs `rows` are wanted: the back substitution visits only the
 * supernodes those entries depend on (the rows' pivots and their
 * elimination-tree ancestors), where gs_fe_static_back passes over all of
 * L. The entries are gs_fe_static_back's to round-off (another summation
 * order), written to out[i]; *frac (may be NULL) receives the fraction of
 * L's entries visited. Counted as one solve. Errors: GS_EINVAL. */
gs_err gs_fe_static_back_rows(gs_fe_static *s, const double *z, gs_index n_rows,
                              const gs_index *rows, double *out, double *frac);

/* Right-hand sides solved so far (one per column and per solved load case). */
long gs_fe_static_solves(const gs_fe_static *s);

#endif
