/* SPDX-License-Identifier: MIT
 * gearsim fe module, library-internal: the reduced elastic body's data and
 * the helpers its files share (docs/explanation/elastic_body.md "Reduced elastic body"): the
 * body's lifecycle, energies, state, fields and snapshots (fe_reduced.c),
 * its modes (fe_reduced_modes.c) and its step (fe_reduced_step.c). */
#ifndef GEARSIM_FE_REDUCED_INTERNAL_H
#define GEARSIM_FE_REDUCED_INTERNAL_H

#include <cholmod.h>
#include <stdbool.h>

#include "fe/fe_internal.h"

#define DENSE_MAX 1600
#define MODES_MAX 4000

/* Lanczos vectors of one run (memory 2 ne of them); restarts go on */
#define LANCZOS_MAX 600
#define RESTARTS_MAX 40

/* candidate nodes whose residual columns one solve computes */
#define BATCH_NODES 8

struct gs_fe_reduced {
    const gs_fe_model *m;
    gs_index ne, n;       /* elastic unknowns; n = ne + 1 */
    bool held;
    double fmax;
    double Itot;          /* inertia_total */
    double beta;
    double alpha;         /* mass-proportional damping (material damping_m) */

    /* modes */
    int N;                /* kept modes (rigid one included for a free body) */
    double *Phi;          /* n x N column-major (theta last in each) */
    double *om2;          /* N: w_i^2 */
    double *PR;           /* nr x N, row-major: Phi at the rows */

    /* rows */
    gs_index nr;          /* 1 + 2 ncand */
    gs_index ncand;
    gs_index *cand_of;    /* n_nodes: candidate index or -1 */
    gs_index *rowq;       /* nr: index in x, or -1 (fixed node, held theta) */
    double **col;         /* ncand: 2 nr values (G_res columns x, y at the rows), or NULL */
    double *tcol;         /* nr: G_res column of theta */
    gs_index ncols;

    cholmod_common cc;
    cholmod_sparse *K;
    cholmod_factor *L;
    /* the residual columns' solve: right-hand sides, solution and CHOLMOD's
     * workspace, kept between groups (tens of MB that were allocated and
     * zeroed by the kernel once per group) */
    cholmod_dense *cB, *cX, *cY, *cE;
    double *cf;           /* 2 BATCH_NODES columns of length n: the unit forces */

    /* step */
    double h, c, d, r, kc;
    double gamma, dr;       /* residual rule: gamma 1/2 midpoint, 1 static; dr = gamma + beta/h */
    bool have_step, in_step;
    double *inv_a;        /* N */
    /* alpha M on u' in the modes: alpha (E + t t^T), E = 1 on the elastic
     * modes, t_i = sqrt(I) theta_i (free body; 0 held); the step's modal
     * matrix diag(a) + (alpha/h)(E + t t^T) is inverted by Sherman-Morrison:
     * H = diag(inv_a) - kap w w^T, w_i = t_i inv_a_i (kap 0: diagonal) */
    double *tt, *ww;      /* N */
    double kap;

    /* state */
    double *qm, *vm;      /* N */
    double *Y;            /* nr */
    gs_index *ysup;       /* rows with Y != 0 */
    gs_index nys;
    unsigned char *yin;   /* nr: in ysup */
    double az;            /* amplitude of z0 */
    double *z0, *z0R, e0; /* n; at the rows; z0^T K z0 */

    /* the begun step */
    double *dqm;          /* N: modal increment for the forces so far */
    double *Fa, *Fi, *Rf; /* nr: applied, interface forces; (F - Y)/d */
    gs_index *fl;         /* rows in Rf's support */
    gs_index nfl;
    unsigned char *fin;   /* nr */
    double moment;

    /* the last compliance block: raw G_res entries over rows blk_r (the
     * next step's block shares most rows and copies them: the columns are
     * far apart in memory) */
    gs_index *blk_r, *blk_pos; /* blk_n rows; nr: position or -1 */
    double *blk_G;
    double *blk_M;        /* the modal sums of the same entries, valid for h == blk_h */
    size_t blk_cap;       /* entries allocated in blk_G, blk_M, blk_r */
    double *sp_G, *sp_M;  /* the spare block buffers (swapped with blk_*: no allocation per step) */
    gs_index *sp_r;
    size_t sp_cap;
    double blk_h;
    gs_index blk_n, blk_rows;
    /* the last block as returned (C) and its selected rows in order (-1:
     * immovable): a step whose rows, h and brake are the same copies C
     * whole (the plan changes every few steps only) */
    double *blk_C, *sp_C;
    gs_index *blk_rr, *sp_rr;
    double blk_dr, blk_kc;
    bool blk_C_ok;

    double energy0, work_in, work_iface, dissipated, damped;
    double residual_loss;   /* the static rule's loss (in damped and dissipated) */
    double col_cpu;       /* CPU seconds spent computing residual columns */
    int lz_runs, lz_added[4]; /* Lanczos runs; modes the first ones added (the log) */
    uint64_t steps;
    double *scratch;      /* n */
};

/* Mode i carries elastic displacement u (not the free body's rigid rotation). */
static inline bool gsi_fe_red_is_elastic(const gs_fe_reduced *b, int i)
{
    return b->held || i > 0;
}

/* G_res entry (row r, column c); column c's node must be present. */
static inline double gsi_fe_red_gres(const gs_fe_reduced *b, gs_index r, gs_index c)
{
    if (c == 0)
        return b->tcol[r];
    gs_index k = (c - 1) >> 1;
    return b->col[k][(size_t)((c - 1) & 1) * (size_t)b->nr + (size_t)r];
}

double gsi_fe_red_dotn(gs_index n, const double *a, const double *b);
double gsi_fe_red_theta_of(const gs_fe_reduced *b, const double *u);
double gsi_fe_red_ygy(const gs_fe_reduced *b, const double *Yv, const gs_index *sup, gs_index ns);
gs_err gsi_fe_red_compute_modes(gs_fe_reduced *b, int solver);
gs_err gsi_fe_red_ensure_row(gs_fe_reduced *b, gs_index r);
gs_err gsi_fe_red_ksolve(gs_fe_reduced *b, int ncol, const double *f, double *x);
void gsi_fe_red_mbar(const gs_fe_reduced *b, const double *x, double *y);

#endif
