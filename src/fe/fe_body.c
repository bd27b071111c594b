/* SPDX-License-Identifier: MIT
 * An elastic body in the energy-momentum step (METHOD.md sections 2 and 4).
 *
 * The step matrix of the body, theta last, is
 *
 *     A = [ A_ee  a ]     A_ee = (2/h^2 + alpha_d/h) M + (1/2 + beta/h) K  (sparse)
 *         [ a^T   d ]     a = 2/h^2 s,  d = 2/h^2 I + c/h
 *
 * Only A_ee goes to CHOLMOD (its fill-reducing ordering is not disturbed by
 * the dense theta row). Theta is a border handled by its Schur complement:
 * y = A_ee^{-1} a and sigma = d - a^T y are computed once per (h, c), and
 *
 *     A^{-1} [r_e; r_t] = [x0 - t y; t],  x0 = A_ee^{-1} r_e,  t = (r_t - a^T x0)/sigma
 *
 * which is exactly the Cholesky factorisation with theta ordered last (its
 * last row is L^{-1} a, its last pivot sqrt(sigma)). One sparse solve per
 * step; a new brake coefficient changes sigma only.
 *
 * The right-hand side is not formed as b = 2/h M w - K q + F: with
 * dq = h w + delta, A (h w) cancels 2/h M w exactly and
 *
 *     A delta = F - K (q + (h/2 + beta) w) - alpha_d M w - c w_theta e_theta,
 *
 * the same scheme with the large rigid part taken out before the solve: the
 * round-off no longer scales with the spin speed (energy drift at 3000 rpm
 * went from ~1e-11 to ~1e-14 over 1e4 steps), and the right-hand side needs
 * K only. Then q += h w + delta, w += 2 delta / h.
 *
 * Rayleigh damping D = alpha_d M + beta K of the elastic unknowns (material
 * damping_m, damping_s) enters as the force -D dq / h = -D (w_n + w_{n+1})/2,
 * the midpoint velocity, constant over the step: it adds alpha_d/h M +
 * beta/h K to A_ee, - alpha_d M w to the right-hand side, and dissipates
 * exactly dq^T D dq / h per step, which is booked. The rigid rotation is
 * not damped (alpha_d M acts on u' only, not on the coupling s or I).
 *
 * Compliance: (A^{-1})_ij = G_ij + y_i y_j / sigma (elastic i, j),
 * -y_i / sigma (elastic i, theta), 1 / sigma (theta, theta), where
 * G = A_ee^{-1}. Columns of G are cached per node (x and y together) for the
 * current h; they serve both the compliance block and the back-substitution
 * dq += A^{-1} E f, which is then a few axpys instead of a solve.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cholmod.h>

#include "fe/fe_internal.h"
#include "gearsim/util.h"

#define CACHE_DEFAULT_BYTES ((size_t)256 << 20)
/* Factorisations kept for the step sizes visited (an adaptive step moves
 * between h / 2^k): the least recently used one is replaced. */
#define FACTOR_SLOTS 4
/* A solve with a factor of more entries than this (a few milliseconds of
 * work and more) runs beside a polling service (gs_run_polled): one solve
 * of the finest meshes takes seconds and cannot be divided. Smaller ones
 * run here (a thread per solve would cost more than the solve). */
#define POLLED_SOLVE_NNZ 2e6

/* The compliance columns cached for one h (see struct gs_fe_body). */
typedef struct col_cache {
    gs_index cap, len;
    double *cols;
    gs_index *slot_of, *node_of;
    uint64_t *stamp;
} col_cache;

typedef struct factor_slot {
    double h;          /* 0: empty */
    cholmod_factor *L; /* of A_ee for this h (and the body's damping) */
    double *y;         /* ne: A_ee^{-1} a for this h */
    uint64_t used;     /* set_step count when last made current */
    col_cache cache;   /* its columns while another slot is current */
} factor_slot;

struct gs_fe_body {
    const gs_fe_model *m;
    gs_index ne;
    cholmod_common cc;
    cholmod_sparse *A;
    cholmod_factor *L;  /* the current slot's factor */
    factor_slot slot[FACTOR_SLOTS];
    int cur;            /* the current slot, -1 before the first set_step */
    uint64_t n_set;
    cholmod_dense *rb, *rx, *ry, *re; /* one right-hand side: b, x, workspaces */
    cholmod_dense *bb, *bx, *by, *be; /* batches of unit vectors */

    double h, c;
    bool have_step, held, in_step;
    double *y; /* ne: A_ee^{-1} a (the current slot's) */
    double sigma;

    double *q, *w;      /* ne + 1 each, theta last */
    double *delta;      /* ne + 1: dq - h w in the current step */
    double *dq;         /* ne + 1: scratch for the step's increment (damping) */
    double rt;          /* theta row of the right-hand side being solved */
    double moment;
    double *fnod;       /* ne: nodal loads of the current step (work), valid if has_fnod */
    bool has_fnod;
    double *fi;         /* ne + 1: interface forces of the current step */
    gs_index *touched;  /* entries of fi set in this step */
    unsigned char *tmark; /* ne + 1: listed in touched */
    gs_index n_touched;
    size_t cap_touched;

    double energy0, work_in, work_iface, dissipated, damped;

    size_t cache_limit;
    gs_index cache_cap, cache_len;
    double *cols;      /* cache_cap slots of 2 * ne: G columns of x then y */
    gs_index *slot_of; /* n_free_nodes: slot, or -1 */
    gs_index *node_of; /* cache_cap: free node in the slot */
    uint64_t *stamp;   /* cache_cap: when the slot was last used (clock) */
    uint64_t clock;    /* counts uses of slots */
    uint64_t request;  /* clock at the start of the current request */

    /* The last compliance block (blk_n dofs, resolved indices blk_q) for
     * the current h and c: the next step's block shares most of its dofs
     * and copies their entries instead of gathering them from the columns
     * again (bit for bit the same values). blk_pos: position in blk_q of
     * each index of q, -1 when absent. */
    gs_index blk_n;
    gs_index *blk_q, *blk_pos;
    /* Computed at the end of a step from the new state, in the one pass
     * over the matrices that the energies need: -K (q + (h/2 + beta) w),
     * the next step's right-hand side without loads (valid for next_h),
     * and the energies. Invalid after any change of state, and not
     * computed when the step was ended with the energies deferred
     * (defer_energy, set by gs_fe_body_defer_energy): gs_fe_body_energy
     * then sums them from the state and begin_step forms the right-hand
     * side, the same values bit for bit. */
    double *next_r, next_h, next_T, next_V;
    bool next_valid, defer_energy;
    double *blk_C;
    size_t cap_blk_q, cap_blk_C;
    bool blk_valid;
    /* Scratch of a compliance or apply request: resolved indices of its
     * dofs, of the selected ones, and their positions in the last block. */
    gs_index *req_q, *req_sel, *req_old;
    size_t cap_req_q, cap_req_sel, cap_req_old;

    gs_fe_stats st;
};

/* ---- lifecycle ---------------------------------------------------------- */

void gs_fe_body_free(gs_fe_body **pb)
{
    if (!pb || !*pb)
        return;
    gs_fe_body *b = *pb;
    cholmod_l_free_dense(&b->rb, &b->cc);
    cholmod_l_free_dense(&b->rx, &b->cc);
    cholmod_l_free_dense(&b->ry, &b->cc);
    cholmod_l_free_dense(&b->re, &b->cc);
    cholmod_l_free_dense(&b->bb, &b->cc);
    cholmod_l_free_dense(&b->bx, &b->cc);
    cholmod_l_free_dense(&b->by, &b->cc);
    cholmod_l_free_dense(&b->be, &b->cc);
    for (int k = 0; k < FACTOR_SLOTS; k++) {
        cholmod_l_free_factor(&b->slot[k].L, &b->cc);
        free(b->slot[k].y);
        free(b->slot[k].cache.cols);
        free(b->slot[k].cache.slot_of);
        free(b->slot[k].cache.node_of);
        free(b->slot[k].cache.stamp);
    }
    cholmod_l_free_sparse(&b->A, &b->cc);
    cholmod_l_finish(&b->cc);
    free(b->q);
    free(b->w);
    free(b->delta);
    free(b->dq);
    free(b->fnod);
    free(b->fi);
    free(b->touched);
    free(b->tmark);
    free(b->cols);
    free(b->slot_of);
    free(b->node_of);
    free(b->stamp);
    free(b->blk_q);
    free(b->blk_pos);
    free(b->blk_C);
    free(b->req_q);
    free(b->req_sel);
    free(b->req_old);
    free(b->next_r);
    free(b);
    *pb = NULL;
}

gs_err gs_fe_body_new(const gs_fe_model *m, gs_fe_body **out)
{
    if (!out)
        return GS_EINVAL;
    *out = NULL;
    if (!m)
        return GS_EINVAL;
    gs_fe_body *b = gs_calloc(1, sizeof *b);
    if (!b)
        return GS_ENOMEM;
    gsi_cholmod_start(&b->cc); /* failures are returned as gs_err */
    b->m = m;
    b->ne = m->ne;
    size_t n1 = (size_t)m->ne + 1;
    b->q = gs_calloc(n1, sizeof *b->q);
    b->w = gs_calloc(n1, sizeof *b->w);
    b->delta = gs_calloc(n1, sizeof *b->delta);
    b->dq = gs_calloc(n1, sizeof *b->dq);
    b->fnod = gs_calloc(n1, sizeof *b->fnod);
    b->fi = gs_calloc(n1, sizeof *b->fi);
    b->tmark = gs_calloc(n1, sizeof *b->tmark);
    b->slot_of = gs_calloc((size_t)m->n_free_nodes + 1, sizeof *b->slot_of);
    b->rb = cholmod_l_zeros(n1 - 1 > 0 ? n1 - 1 : 1, 1, CHOLMOD_REAL, &b->cc);
    if (!b->q || !b->w || !b->delta || !b->dq || !b->fnod || !b->fi || !b->tmark || !b->slot_of || !b->rb) {
        gs_fe_body_free(&b);
        return GS_ENOMEM;
    }
    for (gs_index k = 0; k < m->n_free_nodes; k++)
        b->slot_of[k] = -1;
    b->cur = -1;
    b->cache_limit = CACHE_DEFAULT_BYTES;
    b->energy0 = 0;
    *out = b;
    return GS_OK;
}

/* ---- sparse solves ------------------------------------------------------ */

/* X = A_ee^{-1} B with the body's factor and workspace, for gs_run_polled:
 * it touches only the solver's arrays, which the poll hook never reads. */
typedef struct solve_job {
    gs_fe_body *b;
    cholmod_dense *rhs, **x, **y, **e;
} solve_job;

static int solve_run(void *arg)
{
    solve_job *j = arg;
    return cholmod_l_solve2(CHOLMOD_A, j->b->L, j->rhs, NULL, j->x, NULL, j->y, j->e, &j->b->cc);
}

static int solve_polled(gs_fe_body *b, cholmod_dense *rhs, cholmod_dense **x, cholmod_dense **y, cholmod_dense **e)
{
    solve_job j = {b, rhs, x, y, e};
    return b->st.factor_nnz > POLLED_SOLVE_NNZ ? gs_run_polled(solve_run, &j) : solve_run(&j);
}

/* x = A_ee^{-1} rb, result in b->rx->x. */
static gs_err solve_one(gs_fe_body *b)
{
    if (!solve_polled(b, b->rb, &b->rx, &b->ry, &b->re))
        return GS_ENOMEM;
    b->st.solves++;
    gs_poll(); /* a fine mesh's step is many solves: a service answers between them */
    return GS_OK;
}

static void block_forget(gs_fe_body *b);

static void cache_clear(gs_fe_body *b)
{
    block_forget(b);
    for (gs_index s = 0; s < b->cache_len; s++)
        b->slot_of[b->node_of[s]] = -1;
    b->cache_len = 0;
}

/* sigma = d - a^T y for the current h, c. */
static gs_err update_sigma(gs_fe_body *b)
{
    const gs_fe_model *m = b->m;
    double a = 2.0 / (b->h * b->h), ay = 0;
    for (gs_index i = 0; i < b->ne; i++)
        ay += m->s[i] * b->y[i];
    b->sigma = a * m->inertia_total + b->c / b->h - a * ay;
    return b->sigma > 0 && isfinite(b->sigma) ? GS_OK : GS_ESINGULAR;
}

/* The factor of slot sl of body b (its symbolic analysis once per body,
 * copied to the other slots), for gs_run_polled. */
typedef struct factor_job {
    gs_fe_body *b;
    factor_slot *sl;
    double alpha_m, kappa;
} factor_job;

static int factor_in_slot(void *arg)
{
    factor_job *j = arg;
    gs_fe_body *b = j->b;
    factor_slot *sl = j->sl;
    const gs_fe_model *m = b->m;
    /* A_ee = alpha_m M + kappa K (formed here too: a pass over every
     * entry, seconds for the finest meshes) */
    if (!b->A) {
        b->A = gsi_fe_cholmod_matrix(m, j->alpha_m, j->kappa, &b->cc);
        if (!b->A)
            return GS_ENOMEM;
    } else {
        double *Ax = b->A->x;
        for (gs_index p = 0; p < m->nnz; p++)
            Ax[p] = j->alpha_m * m->mx[p] + j->kappa * m->kx[p];
    }
    if (!sl->L) {
        int src = -1;
        for (int k = 0; k < FACTOR_SLOTS; k++)
            if (b->slot[k].L && src < 0)
                src = k;
        if (src >= 0) {
            sl->L = cholmod_l_copy_factor(b->slot[src].L, &b->cc);
        } else { /* ordering and symbolic analysis: once per body */
            sl->L = cholmod_l_analyze(b->A, &b->cc);
            b->st.factor_nnz = b->cc.lnz;
        }
        if (!sl->L)
            return GS_ENOMEM;
    }
    if (!cholmod_l_factorize(b->A, sl->L, &b->cc))
        return GS_ENOMEM;
    if (b->cc.status == CHOLMOD_NOT_POSDEF)
        return GS_ESINGULAR;
    return GS_OK;
}

/* Factorise A_ee for h into slot k (its factor keeps the ordering of the
 * first analysis: a copy of another slot's, or the analysis itself). */
static gs_err factorise(gs_fe_body *b, int k, double h)
{
    const gs_fe_model *m = b->m;
    factor_slot *sl = &b->slot[k];
    sl->h = 0;
    /* alpha for M: 2/h^2 of the scheme plus alpha_d/h of mass-proportional
     * damping (exactly 2/h^2 without it); the theta border keeps 2/h^2. */
    double alpha = 2.0 / (h * h), kappa = 0.5 + m->mat.damping_s / h;
    double alpha_m = m->mat.damping_m > 0 ? alpha + m->mat.damping_m / h : alpha;
    if (!sl->y) {
        sl->y = gs_calloc((size_t)b->ne + 1, sizeof *sl->y);
        if (!sl->y)
            return GS_ENOMEM;
    }
    if (b->ne == 0) {
        sl->h = h;
        return GS_OK;
    }
    /* One piece of work that cannot be divided: a service answers
     * meanwhile (gs_run_polled). */
    factor_job fj = {b, sl, alpha_m, kappa};
    gs_err fe = (gs_err)gs_run_polled(factor_in_slot, &fj);
    if (fe != GS_OK)
        return fe;
    b->st.factorizations++;
    b->L = sl->L;
    double *r = b->rb->x;
    for (gs_index i = 0; i < b->ne; i++)
        r[i] = alpha * m->s[i];
    GS_TRY(solve_one(b));
    memcpy(sl->y, b->rx->x, (size_t)b->ne * sizeof *sl->y);
    sl->h = h;
    return GS_OK;
}

/* Exchange the body's column cache with the one kept in slot sl. */
static void cache_swap(gs_fe_body *b, factor_slot *sl)
{
    col_cache *c = &sl->cache, t = *c;
    *c = (col_cache){b->cache_cap, b->cache_len, b->cols, b->slot_of, b->node_of, b->stamp};
    b->cache_cap = t.cap;
    b->cache_len = t.len;
    b->cols = t.cols;
    b->slot_of = t.slot_of;
    b->node_of = t.node_of;
    b->stamp = t.stamp;
}

/* Make slot k's column cache the body's (allocated empty the first time). */
static gs_err cache_select(gs_fe_body *b, int k)
{
    if (k == b->cur)
        return GS_OK;
    if (b->cur >= 0)
        cache_swap(b, &b->slot[b->cur]); /* park the current one in its slot */
    cache_swap(b, &b->slot[k]);
    b->cur = k;
    if (!b->slot_of) {
        gs_index n = b->m->n_free_nodes;
        b->slot_of = gs_calloc((size_t)n + 1, sizeof *b->slot_of);
        if (!b->slot_of)
            return GS_ENOMEM;
        for (gs_index i = 0; i < n; i++)
            b->slot_of[i] = -1;
    }
    return GS_OK;
}

/* Make the factorisation for h current, with its cached columns: from its
 * slot, or made in the empty or least recently used one. */
static gs_err use_factor(gs_fe_body *b, double h)
{
    int k = -1, lru = 0;
    for (int j = 0; j < FACTOR_SLOTS; j++) {
        if (b->slot[j].h == h && k < 0)
            k = j;
        if (b->slot[j].used < b->slot[lru].used)
            lru = j;
    }
    bool fresh = k < 0;
    if (fresh)
        k = lru;
    GS_TRY(cache_select(b, k));
    if (fresh) {
        cache_clear(b);
        gs_err e = factorise(b, k, h);
        if (e != GS_OK) {
            b->L = NULL;
            b->y = NULL;
            return e;
        }
    }
    factor_slot *sl = &b->slot[k];
    sl->used = ++b->n_set;
    b->L = sl->L;
    b->y = sl->y;
    return GS_OK;
}

gs_err gs_fe_body_set_step(gs_fe_body *b, double h, double brake_c)
{
    if (!b || !(isfinite(h) && h > 0) || !(isfinite(brake_c) && brake_c >= 0))
        return GS_EINVAL;
    if (b->in_step)
        return GS_ESTATE;
    if (!b->have_step || h != b->h) {
        b->have_step = false;
        GS_TRY(use_factor(b, h));
        b->h = h;
    }
    b->c = brake_c;
    block_forget(b);
    GS_TRY(update_sigma(b));
    b->have_step = true;
    return GS_OK;
}

double gsi_fe_body_time_bare_solve(gs_fe_body *b, int reps)
{
    if (!b || !b->L || reps < 1)
        return -1.0;
    double *r = b->rb->x;
    for (gs_index i = 0; i < b->ne; i++)
        r[i] = 1.0 / (double)(1 + i % 7);
    double t0 = gs_now();
    for (int k = 0; k < reps; k++)
        if (solve_one(b) != GS_OK)
            return -1.0;
    return (gs_now() - t0) / reps;
}

/* ---- state -------------------------------------------------------------- */

/* Kinetic energy of the state from w^T M w of the elastic block. */
static double kinetic_of(const gs_fe_body *b, double wmw)
{
    const gs_fe_model *m = b->m;
    double wt = b->w[b->ne], sw = 0;
    for (gs_index i = 0; i < b->ne; i++)
        sw += m->s[i] * b->w[i];
    return 0.5 * (wmw + 2.0 * wt * sw + m->inertia_total * wt * wt);
}

void gs_fe_body_energy(const gs_fe_body *b, double *kinetic, double *elastic)
{
    if (!b) {
        *kinetic = *elastic = 0;
        return;
    }
    if (b->next_valid) {
        *kinetic = b->next_T;
        *elastic = b->next_V;
        return;
    }
    double wmw, qkq; /* the pass's sums, in its order (gsi_fe_step_pass) */
    gsi_fe_quadform2(b->m, b->w, b->q, &wmw, &qkq);
    *kinetic = kinetic_of(b, wmw);
    *elastic = 0.5 * qkq;
}

double gs_fe_body_kinetic(const gs_fe_body *b)
{
    if (!b)
        return 0;
    return kinetic_of(b, gsi_fe_quadform(b->m, 1.0, 0.0, b->w));
}

double gs_fe_body_elastic(const gs_fe_body *b)
{
    return b ? 0.5 * gsi_fe_quadform(b->m, 0.0, 1.0, b->q) : 0.0;
}

double gs_fe_body_damped(const gs_fe_body *b)
{
    return b ? b->damped : 0.0;
}

double gs_fe_body_angular_momentum(const gs_fe_body *b)
{
    if (!b)
        return 0;
    double sw = 0;
    for (gs_index i = 0; i < b->ne; i++)
        sw += b->m->s[i] * b->w[i];
    return b->m->inertia_total * b->w[b->ne] + sw;
}

void gs_fe_body_spin(gs_fe_body *b, double dw)
{
    if (!b || b->held || b->in_step)
        return;
    b->w[b->ne] += dw;
    /* The next right-hand side does not use theta' (K acts on the elastic
     * unknowns); the kinetic energy does. */
    if (b->next_valid)
        b->next_T = gs_fe_body_kinetic(b);
}

void gs_fe_body_defer_energy(gs_fe_body *b, bool defer)
{
    if (b)
        b->defer_energy = defer;
}

double gs_fe_body_theta(const gs_fe_body *b)
{
    return b ? b->q[b->ne] : 0.0;
}

double gs_fe_body_omega(const gs_fe_body *b)
{
    return b ? b->w[b->ne] : 0.0;
}

const double *gs_fe_body_q(const gs_fe_body *b)
{
    return b ? b->q : NULL;
}

const double *gs_fe_body_w(const gs_fe_body *b)
{
    return b ? b->w : NULL;
}

void gs_fe_body_nodal(const gs_fe_body *b, double *u_nodes, double *v_nodes)
{
    if (!b)
        return;
    const gs_fe_model *m = b->m;
    for (gs_index i = 0; i < 2 * m->n_nodes; i++) {
        gs_index d = m->dof[i];
        if (u_nodes)
            u_nodes[i] = d >= 0 ? b->q[d] : 0.0;
        if (v_nodes)
            v_nodes[i] = d >= 0 ? b->w[d] : 0.0;
    }
}

static void reset_accounts(gs_fe_body *b)
{
    b->energy0 = gs_fe_body_kinetic(b) + gs_fe_body_elastic(b);
    b->work_in = b->work_iface = b->dissipated = b->damped = 0;
}

gs_err gs_fe_body_set_state(gs_fe_body *b, double theta, double omega, const double *u_nodes,
                            const double *v_nodes)
{
    if (!b || !isfinite(theta) || !isfinite(omega))
        return GS_EINVAL;
    if (b->in_step)
        return GS_ESTATE;
    const gs_fe_model *m = b->m;
    b->next_valid = false; /* before any early return: q may be half-written */
    for (gs_index k = 0; k < m->n_free_nodes; k++)
        for (int c = 0; c < 2; c++) {
            gs_index n = 2 * m->free_node[k] + c;
            double u = u_nodes ? u_nodes[n] : 0.0, v = v_nodes ? v_nodes[n] : 0.0;
            if (!isfinite(u) || !isfinite(v))
                return GS_EINVAL;
            b->q[2 * k + c] = u;
            b->w[2 * k + c] = v;
        }
    b->q[b->ne] = theta;
    b->w[b->ne] = b->held ? 0.0 : omega;
    block_forget(b);
    reset_accounts(b);
    return GS_OK;
}

gs_err gs_fe_body_hold_theta(gs_fe_body *b, bool held)
{
    if (!b)
        return GS_EINVAL;
    if (b->in_step)
        return GS_ESTATE;
    b->held = held;
    block_forget(b);
    b->next_valid = false;
    if (held && b->w[b->ne] != 0) {
        b->w[b->ne] = 0;
        reset_accounts(b);
    }
    return GS_OK;
}

/* ---- the step ----------------------------------------------------------- */

/* x = A^{-1} [rb; rt] with the bordered solve of the file comment; rb is
 * the elastic right-hand side already in b->rb. */
static gs_err bordered_solve(gs_fe_body *b, double *x)
{
    const gs_index ne = b->ne;
    const double *s = b->m->s;
    if (ne > 0)
        GS_TRY(solve_one(b));
    const double *x0 = ne > 0 ? b->rx->x : NULL;
    if (b->held) {
        if (ne > 0)
            memcpy(x, x0, (size_t)ne * sizeof *x);
        x[ne] = 0;
        return GS_OK;
    }
    double a = 2.0 / (b->h * b->h), ax = 0;
    for (gs_index i = 0; i < ne; i++)
        ax += s[i] * x0[i];
    double t = (b->rt - a * ax) / b->sigma;
    for (gs_index i = 0; i < ne; i++)
        x[i] = x0[i] - t * b->y[i];
    x[ne] = t;
    return GS_OK;
}

gs_err gs_fe_body_begin_step(gs_fe_body *b, double moment_nm, const double *f_nodes)
{
    if (!b || !isfinite(moment_nm))
        return GS_EINVAL;
    if (!b->have_step || b->in_step)
        return GS_ESTATE;
    const gs_fe_model *m = b->m;
    const gs_index ne = b->ne;
    const double h = b->h;
    double *r = b->rb->x;

    /* A dq = b with dq = h w + delta: A (h w) cancels the 2/h M w of b
     * analytically, leaving A delta = F - K (q + (h/2 + beta) w) - c w_theta e_theta.
     * Same scheme, but the solve only sees the small correction, so the
     * round-off does not scale with the rigid (or any) velocity. */
    b->has_fnod = f_nodes != NULL;
    for (gs_index k = 0; f_nodes && k < m->n_free_nodes; k++) /* fnod is read only if has_fnod */
        for (int c = 0; c < 2; c++) {
            double f = f_nodes[2 * m->free_node[k] + c];
            if (!isfinite(f))
                return GS_EINVAL;
            b->fnod[2 * k + c] = f;
        }
    if (!f_nodes && !(m->mat.damping_m > 0)) {
        /* -K x: computed by the last end_step from this state, else formed
         * here by its pass (the values of the branch below, bit for bit) */
        if (b->next_valid && b->next_h == h)
            memcpy(r, b->next_r, (size_t)ne * sizeof *r);
        else
            gsi_fe_rhs_pass(m, 0.5 * h + m->mat.damping_s, b->q, b->w, r);
    } else {
        for (gs_index i = 0; i < ne; i++) {
            r[i] = f_nodes ? b->fnod[i] : 0.0;
            b->delta[i] = b->q[i] + (0.5 * h + m->mat.damping_s) * b->w[i]; /* scratch */
        }
        if (m->mat.damping_m > 0) /* and - alpha_d M w */
            gsi_fe_symv2(m, -m->mat.damping_m, b->w, -1.0, b->delta, r);
        else
            gsi_fe_symv2(m, 0.0, b->delta, -1.0, b->delta, r);
    }
    double rt = moment_nm - b->c * b->w[ne];

    b->moment = moment_nm;

    b->rt = rt;
    GS_TRY(bordered_solve(b, b->delta));
    b->in_step = true;
    return GS_OK;
}

/* The increment of coordinate i in the current step. */
static double increment(const gs_fe_body *b, gs_index i)
{
    return b->h * b->w[i] + b->delta[i];
}

/* The new state (q += dq, w = 2 dq / h - w, written with dq = h w + delta).
 * With the energies wanted, they and the next right-hand side come in one
 * pass over the matrices (struct gs_fe_body, next_*). Without them, the
 * state alone (also without memory for next_r): begin_step forms -K x
 * just before the solve (gsi_fe_rhs_pass, the same bytes), so that K and
 * then the factor stream back to back, not K here with the other gears'
 * factors between (docs/performance/index.md). */
static void advance(gs_fe_body *b)
{
    const gs_fe_model *m = b->m;
    const gs_index ne = b->ne;
    const double h = b->h;
    b->next_valid = false;
    if (ne > 0 && !b->next_r && !b->defer_energy)
        b->next_r = gs_calloc((size_t)ne, sizeof *b->next_r);
    if (ne == 0 || !b->next_r || b->defer_energy) {
        for (gs_index i = 0; i <= ne; i++) {
            b->q[i] += h * b->w[i] + b->delta[i];
            b->w[i] += 2.0 * b->delta[i] / h;
        }
        return;
    }
    double wmw, qkq;
    /* x = q + (h/2 + beta) w, as begin_step forms it */
    gsi_fe_step_pass(m, h, 0.5 * h + m->mat.damping_s, b->delta, b->q, b->w, b->next_r, &wmw, &qkq);
    b->q[ne] += h * b->w[ne] + b->delta[ne];
    b->w[ne] += 2.0 * b->delta[ne] / h;
    b->next_T = kinetic_of(b, wmw);
    b->next_V = 0.5 * qkq;
    b->next_h = h;
    b->next_valid = true;
}

gs_err gs_fe_body_end_step(gs_fe_body *b)
{
    if (!b)
        return GS_EINVAL;
    if (!b->in_step)
        return GS_ESTATE;
    const gs_index ne = b->ne;
    const double h = b->h;
    const double dqt = increment(b, ne);
    double win = b->moment * dqt, wif = 0;
    if (b->has_fnod)
        for (gs_index i = 0; i < ne; i++)
            win += b->fnod[i] * increment(b, i);
    for (gs_index k = 0; k < b->n_touched; k++) {
        gs_index i = b->touched[k];
        wif += b->fi[i] * increment(b, i);
        b->fi[i] = 0;
        b->tmark[i] = 0;
    }
    b->n_touched = 0;
    double dis = b->c * dqt * dqt / h;
    if (b->m->mat.damping_s > 0 || b->m->mat.damping_m > 0) {
        for (gs_index i = 0; i < ne; i++)
            b->dq[i] = increment(b, i);
        double dd = gsi_fe_quadform(b->m, b->m->mat.damping_m / h, b->m->mat.damping_s / h, b->dq);
        dis += dd;
        b->damped += dd;
    }
    b->work_in += win;
    b->work_iface += wif;
    b->dissipated += dis;
    b->in_step = false;
    b->st.steps++;
    advance(b);
    return GS_OK;
}

void gs_fe_body_cancel_step(gs_fe_body *b)
{
    if (!b || !b->in_step)
        return;
    for (gs_index k = 0; k < b->n_touched; k++) {
        gs_index i = b->touched[k];
        b->fi[i] = 0;
        b->tmark[i] = 0;
    }
    b->n_touched = 0;
    b->in_step = false;
}

gs_err gs_fe_body_step(gs_fe_body *b, double moment_nm, const double *f_nodes)
{
    GS_TRY(gs_fe_body_begin_step(b, moment_nm, f_nodes));
    return gs_fe_body_end_step(b);
}

/* ---- condensation ------------------------------------------------------- */

/* Index in q of an interface dof, or -1 when it cannot move (fixed node,
 * theta of a held body). */
static gs_err resolve(const gs_fe_body *b, gs_index dof, gs_index *qi)
{
    if (dof == GS_FE_DOF_THETA) {
        *qi = b->held ? -1 : b->ne;
        return GS_OK;
    }
    if (dof < 0 || dof >= 2 * b->m->n_nodes)
        return GS_EINVAL;
    *qi = b->m->dof[dof];
    return GS_OK;
}

static gs_err resolve_all(const gs_fe_body *b, int n, const gs_index *dofs, gs_index *qi)
{
    for (int k = 0; k < n; k++)
        GS_TRY(resolve(b, dofs[k], &qi[k]));
    return GS_OK;
}

static gs_err cache_reserve(gs_fe_body *b, gs_index want)
{
    if (want <= b->cache_cap)
        return GS_OK;
    gs_index cap = b->cache_cap ? b->cache_cap : 8;
    while (cap < want)
        cap *= 2;
    size_t per = 2 * (size_t)b->ne;
    double *cols = realloc(b->cols, (size_t)cap * per * sizeof *cols);
    if (!cols)
        return GS_ENOMEM;
    b->cols = cols;
    gs_index *no = realloc(b->node_of, (size_t)cap * sizeof *no);
    if (!no)
        return GS_ENOMEM;
    b->node_of = no;
    uint64_t *stp = realloc(b->stamp, (size_t)cap * sizeof *stp);
    if (!stp)
        return GS_ENOMEM;
    b->stamp = stp;
    b->cache_cap = cap;
    return GS_OK;
}

/* The nodes the memory bound holds (at least one). */
static gs_index cache_bound(const gs_fe_body *b)
{
    size_t per_node = 2 * (size_t)b->ne * sizeof(double);
    gs_index bound = (gs_index)(b->cache_limit / (per_node ? per_node : 1));
    return bound < 1 ? 1 : bound;
}

/* A slot for a new node: a fresh one while under the memory bound, else the
 * least recently used slot not used by the current request, else a fresh
 * one beyond the bound. */
static gs_err cache_slot(gs_fe_body *b, gs_index *slot)
{
    if (b->cache_len >= cache_bound(b)) {
        gs_index best = -1;
        for (gs_index s = 0; s < b->cache_len; s++)
            if (b->stamp[s] <= b->request && (best < 0 || b->stamp[s] < b->stamp[best]))
                best = s;
        if (best >= 0) {
            b->slot_of[b->node_of[best]] = -1;
            *slot = best;
            return GS_OK;
        }
    }
    GS_TRY(cache_reserve(b, b->cache_len + 1));
    *slot = b->cache_len++;
    return GS_OK;
}

/* The first position in col_order of the fixed group (gs_fe_model
 * col_order) that holds free node `node`, and the group's size. */
static gs_index group_of(const gs_fe_body *b, gs_index node, int *size)
{
    const gs_fe_model *m = b->m;
    gs_index pos = m->col_pos[node], nb = m->n_col_boundary;
    gs_index start = pos < nb ? 0 : nb, end = pos < nb ? nb : m->n_free_nodes;
    gs_index g0 = pos - (pos - start) % GSI_FE_GROUP, left = end - g0;
    *size = left < GSI_FE_GROUP ? (int)left : GSI_FE_GROUP;
    return g0;
}

/* Solve for the G columns of the whole group starting at position g0 of
 * col_order and keep them: those of nodes[0..n) (members of that group,
 * asked for) in slots[0..n), and those of the group's other members not
 * cached yet in new slots (the contact moves on to them next). The
 * right-hand sides of a solve are always the same group in the same order,
 * whichever of its nodes are missing: a multi-column solve (BLAS blocks)
 * rounds each column according to the batch it is in, and a column must
 * not depend on the history of requests, or a restored body (empty cache)
 * would continue with other bits than the body it was saved from. */
static gs_err cache_fill(gs_fe_body *b, gs_index g0, int n, const gs_index *nodes, const gs_index *slots)
{
    const gs_index ne = b->ne;
    const gs_index *order = b->m->col_order;
    if (!b->bb || b->bb->ncol != (size_t)(2 * GSI_FE_GROUP)) {
        cholmod_l_free_dense(&b->bb, &b->cc);
        b->bb = cholmod_l_zeros((size_t)ne, 2 * GSI_FE_GROUP, CHOLMOD_REAL, &b->cc);
        if (!b->bb)
            return GS_ENOMEM;
    }
    int gn;
    group_of(b, order[g0], &gn);
    double *B = b->bb->x;
    b->bb->ncol = (size_t)(2 * gn);
    for (int k = 0; k < gn; k++) {
        B[2 * order[g0 + k] + (size_t)(2 * k) * ne] = 1.0;
        B[2 * order[g0 + k] + 1 + (size_t)(2 * k + 1) * ne] = 1.0;
    }
    int ok = solve_polled(b, b->bb, &b->bx, &b->by, &b->be);
    for (int k = 0; k < gn; k++) {
        B[2 * order[g0 + k] + (size_t)(2 * k) * ne] = 0.0;
        B[2 * order[g0 + k] + 1 + (size_t)(2 * k + 1) * ne] = 0.0;
    }
    b->bb->ncol = 2 * GSI_FE_GROUP;
    if (!ok)
        return GS_ENOMEM;
    b->st.solves += (uint64_t)(2 * gn);
    b->st.group_solves++;
    gs_poll();
    const double *X = b->bx->x;
    const gs_index *pos = b->m->col_pos;
    for (int k = 0; k < n; k++)
        memcpy(b->cols + (size_t)slots[k] * 2 * ne, X + (size_t)(2 * (pos[nodes[k]] - g0)) * ne,
               2 * (size_t)ne * sizeof *X);
    /* the rest of the group, in fresh slots while the bound allows (never
     * evicting for them) */
    for (int k = 0; k < gn && b->cache_len < cache_bound(b); k++) {
        gs_index node = order[g0 + k], s;
        if (b->slot_of[node] >= 0)
            continue;
        GS_TRY(cache_slot(b, &s));
        b->slot_of[node] = s;
        b->node_of[s] = node;
        b->stamp[s] = b->request; /* evictable like an old column: not asked for by this request */
        b->st.group_kept++;
        memcpy(b->cols + (size_t)s * 2 * ne, X + (size_t)(2 * k) * ne, 2 * (size_t)ne * sizeof *X);
    }
    return GS_OK;
}

/* Make sure every elastic dof in qi[0..n) has its node's columns cached.
 * Missing nodes are gathered while they stay in one group (cache_fill). */
static gs_err cache_ensure(gs_fe_body *b, int n, const gs_index *qi)
{
    b->request = b->clock;
    gs_index nodes[GSI_FE_GROUP], slots[GSI_FE_GROUP], g0 = -1;
    int nb = 0;
    for (int k = 0; k <= n; k++) {
        gs_index node = -1, s = -1, g = -1;
        if (k < n) {
            if (qi[k] < 0 || qi[k] >= b->ne)
                continue;
            node = qi[k] / 2;
            s = b->slot_of[node];
            if (s >= 0) {
                if (b->stamp[s] <= b->request)
                    b->st.cache_hits++;
                b->stamp[s] = ++b->clock;
                continue;
            }
            int gn;
            g = group_of(b, node, &gn);
        }
        if (nb > 0 && g != g0) { /* a new group (or the end): solve the pending one */
            gs_err e = cache_fill(b, g0, nb, nodes, slots);
            if (e != GS_OK) {
                cache_clear(b);
                return e;
            }
            nb = 0;
        }
        if (k == n)
            break;
        GS_TRY(cache_slot(b, &s));
        b->slot_of[node] = s;
        b->node_of[s] = node;
        b->stamp[s] = ++b->clock;
        b->st.cache_misses++;
        g0 = g;
        nodes[nb] = node;
        slots[nb] = s;
        nb++;
    }
    return GS_OK;
}

static const double *column(const gs_fe_body *b, gs_index qi)
{
    return b->cols + ((size_t)b->slot_of[qi / 2] * 2 + (size_t)(qi % 2)) * (size_t)b->ne;
}

gs_err gs_fe_body_increment(gs_fe_body *b, int n, const gs_index *dofs, double *dq_out)
{
    if (!b || n < 0 || (n > 0 && (!dofs || !dq_out)))
        return GS_EINVAL;
    if (!b->in_step)
        return GS_ESTATE;
    for (int k = 0; k < n; k++) {
        gs_index qi;
        GS_TRY(resolve(b, dofs[k], &qi));
        dq_out[k] = qi >= 0 ? increment(b, qi) : 0.0;
    }
    return GS_OK;
}

/* The columns of dofs (resolve_all), each of them cached; their indices
 * in the body's request scratch (valid until the next request). */
static gs_err cached_columns(gs_fe_body *b, int n, const gs_index *dofs, gs_index **out)
{
    gs_index *qi = gs_grow(b->req_q, &b->cap_req_q, (size_t)(n ? n : 1), sizeof *qi);
    if (!qi)
        return GS_ENOMEM;
    b->req_q = qi;
    GS_TRY(resolve_all(b, n, dofs, qi));
    GS_TRY(cache_ensure(b, n, qi));
    *out = qi;
    return GS_OK;
}

/* Entry (r, c) of A^{-1} before symmetrisation, from the cached column of
 * qc (col, NULL for theta) and the border (is = 1/sigma, 0 when held). */
static double raw_entry(const gs_fe_body *b, gs_index qr, gs_index qc, const double *col, double is)
{
    const gs_index ne = b->ne;
    if (qr < 0 || qc < 0)
        return 0;
    if (qr == ne && qc == ne)
        return is;
    if (qr == ne)
        return -b->y[qc] * is;
    if (qc == ne)
        return -b->y[qr] * is;
    return col[qr] + b->y[qr] * b->y[qc] * is;
}

/* Remember the block C of the dofs qi for the next request. */
static void block_keep(gs_fe_body *b, int n, const gs_index *qi, const double *C)
{
    b->blk_valid = false;
    if (!b->blk_pos) {
        b->blk_pos = gs_calloc((size_t)b->ne + 1, sizeof *b->blk_pos);
        if (!b->blk_pos)
            return;
        for (gs_index i = 0; i <= b->ne; i++)
            b->blk_pos[i] = -1;
    }
    for (gs_index k = 0; k < b->blk_n; k++)
        if (b->blk_q[k] >= 0)
            b->blk_pos[b->blk_q[k]] = -1;
    b->blk_n = 0;
    gs_index *q = gs_grow(b->blk_q, &b->cap_blk_q, (size_t)(n ? n : 1), sizeof *q);
    if (!q)
        return;
    b->blk_q = q;
    double *c = gs_grow(b->blk_C, &b->cap_blk_C, (size_t)n * (size_t)n + 1, sizeof *c);
    if (!c)
        return;
    b->blk_C = c;
    memcpy(b->blk_q, qi, (size_t)n * sizeof *qi);
    memcpy(b->blk_C, C, (size_t)n * (size_t)n * sizeof *C);
    b->blk_n = n;
    for (int k = 0; k < n; k++)
        if (qi[k] >= 0)
            b->blk_pos[qi[k]] = k;
    b->blk_valid = true;
}

static void block_forget(gs_fe_body *b)
{
    b->blk_valid = false;
}

/* The compliance block C (n x n, column-major) of the resolved indices
 * qi, from the last block where it has the entries, else from the cached
 * columns; kept as the last block. */
static gs_err block_of(gs_fe_body *b, int n, const gs_index *qi, double *C)
{
    const gs_index ne = b->ne;
    const double is = b->held ? 0.0 : 1.0 / b->sigma;
    /* Positions in the last block (-1: not there); an unchanged list of
     * dofs is one copy. */
    bool same = b->blk_valid && b->blk_n == n;
    for (int k = 0; same && k < n; k++)
        same = b->blk_q[k] == qi[k];
    if (same) {
        memcpy(C, b->blk_C, (size_t)n * (size_t)n * sizeof *C);
        b->st.block_reused += (uint64_t)n * (uint64_t)n;
        return GS_OK;
    }
    gs_index *old = NULL;
    if (b->blk_valid) {
        old = gs_grow(b->req_old, &b->cap_req_old, (size_t)(n ? n : 1), sizeof *old);
        if (old) {
            b->req_old = old;
            for (int k = 0; k < n; k++)
                old[k] = qi[k] >= 0 ? b->blk_pos[qi[k]] : -1;
        }
    }
    const gs_index np = b->blk_n;
    uint64_t reused = 0;
    /* Entries symmetrised as (a_ij + a_ji) / 2: G is symmetric only up to
     * the round-off of the solves, C is made exactly so. */
    for (int j = 0; j < n; j++) {
        gs_index qj = qi[j];
        const double *colj = (qj >= 0 && qj < ne) ? column(b, qj) : NULL;
        gs_index oj = old ? old[j] : -1;
        for (int i = j; i < n; i++) {
            gs_index oi = old ? old[i] : -1;
            double v;
            if (oi >= 0 && oj >= 0) {
                v = b->blk_C[oi + (size_t)oj * np];
                reused += i == j ? 1 : 2;
            } else {
                gs_index qk = qi[i];
                v = raw_entry(b, qk, qj, colj, is);
                if (i != j) {
                    const double *coli = (qk >= 0 && qk < ne) ? column(b, qk) : NULL;
                    v = 0.5 * (v + raw_entry(b, qj, qk, coli, is));
                }
            }
            C[i + (size_t)j * n] = C[j + (size_t)i * n] = v;
        }
    }
    b->st.block_reused += reused;
    block_keep(b, n, qi, C);
    return GS_OK;
}

gs_err gs_fe_body_compliance(gs_fe_body *b, int n, const gs_index *dofs, double *C)
{
    if (!b || n < 0 || (n > 0 && (!dofs || !C)))
        return GS_EINVAL;
    if (!b->have_step)
        return GS_ESTATE;
    gs_index *qi;
    GS_TRY(cached_columns(b, n, dofs, &qi));
    return block_of(b, n, qi, C);
}

gs_err gs_fe_body_compliance_sub(gs_fe_body *b, int n, const gs_index *dofs, int k, const int *sel,
                                 double *C)
{
    if (!b || n < 0 || k < 0 || k > n || (n > 0 && !dofs) || (k > 0 && (!sel || !C)))
        return GS_EINVAL;
    if (!b->have_step)
        return GS_ESTATE;
    for (int a = 0; a < k; a++)
        if (sel[a] < 0 || sel[a] >= n)
            return GS_EINVAL;
    gs_index *qi;
    GS_TRY(cached_columns(b, n, dofs, &qi));
    gs_index *qs = gs_grow(b->req_sel, &b->cap_req_sel, (size_t)(k ? k : 1), sizeof *qs);
    if (!qs)
        return GS_ENOMEM;
    b->req_sel = qs;
    for (int a = 0; a < k; a++)
        qs[a] = qi[sel[a]];
    return block_of(b, k, qs, C);
}

static gs_err touch(gs_fe_body *b, gs_index i, double f)
{
    if (!b->tmark[i]) {
        gs_index *t = gs_grow(b->touched, &b->cap_touched, (size_t)b->n_touched + 1, sizeof *t);
        if (!t)
            return GS_ENOMEM;
        b->touched = t;
        b->touched[b->n_touched++] = i;
        b->tmark[i] = 1;
    }
    b->fi[i] += f;
    return GS_OK;
}

/* d += sum_g f[g] col[g], added to each entry in the order of g: the same
 * values as ng axpys one after the other, in one pass over d (the apply's
 * groups of AXPY_GROUP columns, and its last group with the rigid term). */
#define AXPY_GROUP 4
static void axpy_group(double *d, gs_index ne, int ng, const double *f, const double *const *col)
{
    if (ng == AXPY_GROUP) { /* the common group, unrolled */
        const double *c0 = col[0], *c1 = col[1], *c2 = col[2], *c3 = col[3];
        for (gs_index r = 0; r < ne; r++) {
            double v = d[r];
            v += f[0] * c0[r];
            v += f[1] * c1[r];
            v += f[2] * c2[r];
            v += f[3] * c3[r];
            d[r] = v;
        }
        return;
    }
    for (gs_index r = 0; r < ne; r++) {
        double v = d[r];
        for (int g = 0; g < ng; g++)
            v += f[g] * col[g][r];
        d[r] = v;
    }
}

gs_err gs_fe_body_apply(gs_fe_body *b, int n, const gs_index *dofs, const double *f)
{
    if (!b || n < 0 || (n > 0 && (!dofs || !f)))
        return GS_EINVAL;
    if (!b->in_step)
        return GS_ESTATE;
    for (int k = 0; k < n; k++)
        if (!isfinite(f[k]))
            return GS_EINVAL;
    gs_index *qi;
    GS_TRY(cached_columns(b, n, dofs, &qi));
    gs_err e = GS_OK;
    const gs_index ne = b->ne;
    double tau = 0;
    const double *cols[AXPY_GROUP + 1] = {NULL};
    double fs[AXPY_GROUP + 1];
    int ng = 0;
    for (int k = 0; k < n && e == GS_OK; k++) {
        gs_index i = qi[k];
        if (i < 0 || f[k] == 0)
            continue;
        e = touch(b, i, f[k]);
        if (i == ne) {
            tau -= f[k];
            continue;
        }
        cols[ng] = column(b, i);
        fs[ng++] = f[k];
        if (ng == AXPY_GROUP) {
            axpy_group(b->delta, ne, ng, fs, cols);
            ng = 0;
        }
        tau += f[k] * b->y[i];
    }
    if (e != GS_OK) {
        axpy_group(b->delta, ne, ng, fs, cols);
        return e;
    }
    if (!b->held) {
        /* the rigid coordinate's term rides with the last columns' pass */
        tau /= b->sigma;
        cols[ng] = b->y;
        fs[ng++] = tau;
        b->delta[ne] -= tau;
    }
    axpy_group(b->delta, ne, ng, fs, cols);
    return GS_OK;
}

/* ---- diagnostics -------------------------------------------------------- */

void gs_fe_body_get_balance(const gs_fe_body *b, gs_fe_balance *out)
{
    if (!b || !out)
        return;
    out->kinetic = gs_fe_body_kinetic(b);
    out->elastic = gs_fe_body_elastic(b);
    out->energy0 = b->energy0;
    out->work_in = b->work_in;
    out->work_iface = b->work_iface;
    out->dissipated = b->dissipated;
    out->damped = b->damped;
    out->residual = out->kinetic + out->elastic - b->energy0 - b->work_in - b->work_iface +
                    b->dissipated;
}

void gs_fe_body_get_stats(const gs_fe_body *b, gs_fe_stats *out)
{
    if (!b || !out)
        return;
    *out = b->st;
    out->cached_nodes = b->cache_len;
    out->cache_bytes = (size_t)b->cache_cap * 2 * (size_t)b->ne * sizeof(double);
}

gs_err gs_fe_body_set_cache_limit(gs_fe_body *b, size_t max_bytes)
{
    if (!b)
        return GS_EINVAL;
    b->cache_limit = max_bytes;
    return GS_OK;
}
