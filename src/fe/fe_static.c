/* SPDX-License-Identifier: MIT
 * Static solves with K factored once (include/gearsim/fe_static.h). */
#include <cblas.h>
#include <cholmod.h>
#include <stdlib.h>
#ifdef _OPENMP
#include <omp.h>
#endif
#include <string.h>
#include <sys/mman.h>

#include "fe/fe_internal.h"
#include "gearsim/fe_static.h"

/* Right-hand sides per CHOLMOD solve: bounds the dense workspace to
 * BATCH * ne doubles. */
#define BATCH 64

struct gs_fe_static {
    const gs_fe_model *m;
    cholmod_common c;
    cholmod_factor *L;
    long solves;
    /* Half columns (gs_fe_static_half_column): */
    SuiteSparse_long *iperm; /* ne: factor position of free dof q */
    SuiteSparse_long *sup;   /* ne: supernode of factor column k */
    double *x;               /* ne: dense work, zero between calls */
    double *xb;              /* ne: gs_fe_static_back_rows' solution (factor order) */
    double *xg;              /* ne: its gathered entries below a supernode's diagonal block */
    unsigned char *smark;    /* nsuper: gs_fe_static_back_rows' supernodes */
    unsigned char *mark;     /* nsuper: supernode queued */
    SuiteSparse_long *heap;  /* nsuper: pending supernodes (min-heap) */
    gs_index *hidx;          /* ne: pattern of the last half column */
    double *hval;            /* ne: its values */
    cholmod_dense *bw, *bx, *by, *be; /* gs_fe_static_back: reused solution and workspace */
};

void gs_fe_static_free(gs_fe_static **ps)
{
    if (!ps || !*ps)
        return;
    gs_fe_static *s = *ps;
    if (s->L)
        cholmod_l_free_factor(&s->L, &s->c);
    free(s->iperm);
    free(s->sup);
    free(s->x);
    free(s->xb);
    free(s->xg);
    free(s->smark);
    free(s->mark);
    free(s->heap);
    free(s->hidx);
    free(s->hval);
    cholmod_l_free_dense(&s->bw, &s->c);
    cholmod_l_free_dense(&s->bx, &s->c);
    cholmod_l_free_dense(&s->by, &s->c);
    cholmod_l_free_dense(&s->be, &s->c);
    cholmod_l_finish(&s->c);
    free(s);
    *ps = NULL;
}

/* CHOLMOD's large arrays (the factor's values above all, read by every
 * back substitution and half column) on transparent huge pages where the
 * kernel offers them on request (madvise): 2 MB pages instead of 4 kB, far
 * fewer TLB misses and page faults. Blocks come from aligned_alloc, so
 * free and realloc stay the C library's. */
#define GS_HUGE_PAGE ((size_t)2 << 20)

static void *huge_malloc(size_t n)
{
    if (n < GS_HUGE_PAGE)
        return malloc(n);
    size_t len = (n + GS_HUGE_PAGE - 1) / GS_HUGE_PAGE * GS_HUGE_PAGE;
    void *p = aligned_alloc(GS_HUGE_PAGE, len);
#ifdef MADV_HUGEPAGE
    if (p)
        (void)madvise(p, len, MADV_HUGEPAGE);
#endif
    return p;
}

void *gsi_huge_calloc(size_t n, size_t size)
{
    if (size != 0 && n > (size_t)-1 / size)
        return NULL;
    if (n * size < GS_HUGE_PAGE)
        return calloc(n, size);
    void *p = huge_malloc(n * size);
    if (p)
        memset(p, 0, n * size);
    return p;
}

void gsi_cholmod_start(cholmod_common *c)
{
    /* Before CHOLMOD's first allocation; blocks allocated before would be
     * freed by free all the same. */
    SuiteSparse_config.malloc_func = huge_malloc;
    SuiteSparse_config.calloc_func = gsi_huge_calloc;
#ifdef _OPENMP
    /* No active parallel level: every OpenMP region of the libraries runs
     * with a team of one (the calling thread). */
    omp_set_max_active_levels(0);
#endif
    cholmod_l_start(c);
    c->print = 0;
}

gs_err gs_fe_static_new(const gs_fe_model *m, gs_fe_static **out)
{
    if (!m || !out)
        return GS_EINVAL;
    *out = NULL;
    gs_fe_static *s = calloc(1, sizeof *s);
    if (!s)
        return GS_ENOMEM;
    s->m = m;
    gsi_cholmod_start(&s->c);
    /* Supernodal LL' always (also for small K): the half columns walk its
     * supernodes. */
    s->c.supernodal = CHOLMOD_SUPERNODAL;
    if (m->ne == 0) {
        *out = s;
        return GS_OK;
    }
    gs_err err = GS_ENOMEM;
    cholmod_sparse *K = gsi_fe_cholmod_matrix(m, 0.0, 1.0, &s->c);
    if (!K)
        goto fail;
    s->L = cholmod_l_analyze(K, &s->c);
    if (!s->L) {
        cholmod_l_free_sparse(&K, &s->c);
        goto fail;
    }
    int ok = cholmod_l_factorize(K, s->L, &s->c);
    cholmod_l_free_sparse(&K, &s->c);
    if (!ok || s->c.status == CHOLMOD_NOT_POSDEF) {
        err = s->c.status == CHOLMOD_NOT_POSDEF ? GS_ESINGULAR : GS_ENOMEM;
        goto fail;
    }
    /* As gs_fe_model_static: round-off pivots of a K singular in exact
     * arithmetic show as a reciprocal condition estimate near 1e-16. */
    if (cholmod_l_rcond(s->L, &s->c) < 1e-13) {
        err = GS_ESINGULAR;
        goto fail;
    }
    if (!s->L->is_super || !s->L->is_ll) {
        err = GS_EINTERNAL;
        goto fail;
    }
    {
        size_t ne = (size_t)m->ne, ns = s->L->nsuper;
        s->iperm = malloc(ne * sizeof *s->iperm);
        s->sup = malloc(ne * sizeof *s->sup);
        s->x = calloc(ne, sizeof *s->x);
        s->xb = malloc(ne * sizeof *s->xb);
        s->xg = malloc(ne * sizeof *s->xg);
        s->smark = calloc(ns, 1);
        s->mark = calloc(ns, 1);
        s->heap = malloc(ns * sizeof *s->heap);
        s->hidx = malloc(ne * sizeof *s->hidx);
        s->hval = malloc(ne * sizeof *s->hval);
        if (!s->iperm || !s->sup || !s->x || !s->xb || !s->xg || !s->smark || !s->mark || !s->heap || !s->hidx || !s->hval)
            goto fail;
        const SuiteSparse_long *perm = s->L->Perm, *super = s->L->super;
        for (size_t k = 0; k < ne; k++)
            s->iperm[perm[k]] = (SuiteSparse_long)k;
        for (size_t q = 0; q < ns; q++)
            for (SuiteSparse_long k = super[q]; k < super[q + 1]; k++)
                s->sup[k] = (SuiteSparse_long)q;
    }
    *out = s;
    return GS_OK;
fail:
    gs_fe_static_free(&s);
    return err;
}

long gs_fe_static_solves(const gs_fe_static *s)
{
    return s ? s->solves : 0;
}

/* Solve K X = B for k right-hand sides held in B (ne x k). */
static cholmod_dense *solve_dense(gs_fe_static *s, cholmod_dense *B)
{
    cholmod_dense *X = cholmod_l_solve(CHOLMOD_A, s->L, B, &s->c);
    if (X)
        s->solves += (long)B->ncol;
    return X;
}

gs_err gs_fe_static_solve(gs_fe_static *s, int nrhs, const double *f_nodes, double *u_nodes)
{
    if (!s || nrhs < 0 || (nrhs > 0 && (!f_nodes || !u_nodes)))
        return GS_EINVAL;
    const gs_fe_model *m = s->m;
    size_t nn = 2 * (size_t)m->n_nodes;
    memset(u_nodes, 0, (size_t)nrhs * nn * sizeof *u_nodes);
    if (m->ne == 0 || nrhs == 0)
        return GS_OK;
    for (int j0 = 0; j0 < nrhs; j0 += BATCH) {
        int k = nrhs - j0 < BATCH ? nrhs - j0 : BATCH;
        cholmod_dense *B = cholmod_l_zeros((size_t)m->ne, (size_t)k, CHOLMOD_REAL, &s->c);
        if (!B)
            return GS_ENOMEM;
        double *bx = B->x;
        for (int j = 0; j < k; j++) {
            const double *f = f_nodes + (size_t)(j0 + j) * nn;
            double *b = bx + (size_t)j * (size_t)m->ne;
            for (gs_index q = 0; q < m->n_free_nodes; q++) {
                b[2 * q] = f[2 * m->free_node[q]];
                b[2 * q + 1] = f[2 * m->free_node[q] + 1];
            }
        }
        cholmod_dense *X = solve_dense(s, B);
        cholmod_l_free_dense(&B, &s->c);
        if (!X)
            return GS_ENOMEM;
        const double *xx = X->x;
        for (int j = 0; j < k; j++) {
            const double *x = xx + (size_t)j * (size_t)m->ne;
            double *u = u_nodes + (size_t)(j0 + j) * nn;
            for (gs_index q = 0; q < m->n_free_nodes; q++) {
                u[2 * m->free_node[q]] = x[2 * q];
                u[2 * m->free_node[q] + 1] = x[2 * q + 1];
            }
        }
        cholmod_l_free_dense(&X, &s->c);
    }
    return GS_OK;
}

/* All n dofs of d in the model's range 0 .. 2 n_nodes - 1. */
static bool dofs_ok(const gs_fe_model *m, gs_index n, const gs_index *d)
{
    for (gs_index i = 0; i < n; i++)
        if (d[i] < 0 || d[i] >= 2 * m->n_nodes)
            return false;
    return true;
}

gs_err gs_fe_static_columns(gs_fe_static *s, int n, const gs_index *cols, gs_index n_rows,
                            const gs_index *rows, double *out)
{
    if (!s || n < 0 || n_rows < 0 || (n > 0 && (!cols || !out)) || (n_rows > 0 && !rows))
        return GS_EINVAL;
    const gs_fe_model *m = s->m;
    if (!dofs_ok(m, n, cols) || !dofs_ok(m, n_rows, rows))
        return GS_EINVAL;
    memset(out, 0, (size_t)n * (size_t)n_rows * sizeof *out);
    if (m->ne == 0 || n == 0 || n_rows == 0)
        return GS_OK;
    /* Only the columns of free dofs need a solve. */
    int *job = malloc((size_t)n * sizeof *job);
    if (!job)
        return GS_ENOMEM;
    int nj = 0;
    for (int j = 0; j < n; j++)
        if (m->dof[cols[j]] >= 0)
            job[nj++] = j;
    gs_err err = GS_OK;
    for (int j0 = 0; j0 < nj; j0 += BATCH) {
        int k = nj - j0 < BATCH ? nj - j0 : BATCH;
        cholmod_dense *B = cholmod_l_zeros((size_t)m->ne, (size_t)k, CHOLMOD_REAL, &s->c);
        if (!B) {
            err = GS_ENOMEM;
            break;
        }
        double *bx = B->x;
        for (int j = 0; j < k; j++)
            bx[(size_t)j * (size_t)m->ne + (size_t)m->dof[cols[job[j0 + j]]]] = 1.0;
        cholmod_dense *X = solve_dense(s, B);
        cholmod_l_free_dense(&B, &s->c);
        if (!X) {
            err = GS_ENOMEM;
            break;
        }
        const double *xx = X->x;
        for (int j = 0; j < k; j++) {
            const double *x = xx + (size_t)j * (size_t)m->ne;
            double *o = out + (size_t)job[j0 + j] * (size_t)n_rows;
            for (gs_index i = 0; i < n_rows; i++) {
                gs_index q = m->dof[rows[i]];
                o[i] = q >= 0 ? x[q] : 0.0;
            }
        }
        cholmod_l_free_dense(&X, &s->c);
    }
    free(job);
    return err;
}

gs_index gs_fe_static_size(const gs_fe_static *s)
{
    return s ? s->m->ne : 0;
}

static void heap_push(SuiteSparse_long *h, size_t *n, SuiteSparse_long v)
{
    size_t i = (*n)++;
    while (i > 0 && h[(i - 1) / 2] > v) {
        h[i] = h[(i - 1) / 2];
        i = (i - 1) / 2;
    }
    h[i] = v;
}

static SuiteSparse_long heap_pop(SuiteSparse_long *h, size_t *n)
{
    SuiteSparse_long top = h[0], v = h[--(*n)];
    size_t i = 0;
    for (;;) {
        size_t c = 2 * i + 1;
        if (c >= *n)
            break;
        if (c + 1 < *n && h[c + 1] < h[c])
            c++;
        if (h[c] >= v)
            break;
        h[i] = h[c];
        i = c;
    }
    if (*n > 0)
        h[i] = v;
    return top;
}

gs_err gs_fe_static_half_column(gs_fe_static *s, gs_index dof, gs_index *nnz,
                                const gs_index **idx, const double **val)
{
    if (!s || !nnz || !idx || !val)
        return GS_EINVAL;
    const gs_fe_model *m = s->m;
    if (dof < 0 || dof >= 2 * m->n_nodes)
        return GS_EINVAL;
    *nnz = 0;
    *idx = s->hidx;
    *val = s->hval;
    if (m->ne == 0 || m->dof[dof] < 0)
        return GS_OK;
    /* Forward substitution L y = P e_dof over the supernodes it reaches (the
     * ancestors of the unit's column), in increasing order. */
    const cholmod_factor *L = s->L;
    const SuiteSparse_long *super = L->super, *pi = L->pi, *px = L->px, *Ls = L->s;
    const double *Lx = L->x;
    double *x = s->x;
    SuiteSparse_long k0 = s->iperm[m->dof[dof]];
    x[k0] = 1.0;
    size_t nh = 0;
    heap_push(s->heap, &nh, s->sup[k0]);
    s->mark[s->sup[k0]] = 1;
    gs_index n = 0;
    while (nh > 0) {
        SuiteSparse_long q = heap_pop(s->heap, &nh);
        s->mark[q] = 0;
        SuiteSparse_long nc = super[q + 1] - super[q], nr = pi[q + 1] - pi[q], nb = nr - nc;
        const SuiteSparse_long *rows = Ls + pi[q];
        const double *lq = Lx + px[q];
        /* x_1 = L_11^{-1} x_1 in the diagonal block, then x_2 -= L_21 x_1
         * below it (one dgemv into g, scattered), as CHOLMOD's supernodal
         * solve */
        double *x1 = x + super[q];
        for (SuiteSparse_long c = 0; c < nc; c++) {
            double xj = x1[c] / lq[c + c * nr];
            x1[c] = xj;
            if (xj != 0.0)
                for (SuiteSparse_long r = c + 1; r < nc; r++)
                    x1[r] -= lq[r + c * nr] * xj;
        }
        if (nb > 0) {
            double *g = s->xg;
            cblas_dgemv(CblasColMajor, CblasNoTrans, (blasint)nb, (blasint)nc, 1.0, lq + nc,
                        (blasint)nr, x1, 1, 0.0, g, 1);
            for (SuiteSparse_long r = 0; r < nb; r++)
                x[rows[nc + r]] -= g[r];
        }
        for (SuiteSparse_long c = 0; c < nc; c++) {
            s->hidx[n] = (gs_index)(super[q] + c);
            s->hval[n++] = x1[c];
            x1[c] = 0.0;
        }
        for (SuiteSparse_long r = nc; r < nr; r++) {
            SuiteSparse_long t = s->sup[rows[r]];
            if (!s->mark[t]) {
                s->mark[t] = 1;
                heap_push(s->heap, &nh, t);
            }
        }
    }
    *nnz = n;
    return GS_OK;
}

gs_err gs_fe_static_back(gs_fe_static *s, int nrhs, const double *z, gs_index n_rows,
                         const gs_index *rows, double *out)
{
    if (!s || nrhs < 0 || n_rows < 0 || (nrhs > 0 && (!z || !out)) || (n_rows > 0 && !rows))
        return GS_EINVAL;
    const gs_fe_model *m = s->m;
    if (!dofs_ok(m, n_rows, rows))
        return GS_EINVAL;
    memset(out, 0, (size_t)nrhs * (size_t)n_rows * sizeof *out);
    if (m->ne == 0 || nrhs == 0 || n_rows == 0)
        return GS_OK;
    size_t ne = (size_t)m->ne;
    cholmod_dense Z = {.nrow = ne, .ncol = (size_t)nrhs, .nzmax = ne * (size_t)nrhs, .d = ne,
                       .x = (void *)z, .xtype = CHOLMOD_REAL, .dtype = CHOLMOD_DOUBLE};
    /* solve2 keeps the solution and workspace between calls. */
    if (!cholmod_l_solve2(CHOLMOD_Lt, s->L, &Z, NULL, &s->bw, NULL, &s->by, &s->be, &s->c) ||
        !cholmod_l_solve2(CHOLMOD_Pt, s->L, s->bw, NULL, &s->bx, NULL, &s->by, &s->be, &s->c))
        return GS_ENOMEM;
    s->solves += nrhs;
    for (int j = 0; j < nrhs; j++) {
        const double *x = (const double *)s->bx->x + (size_t)j * s->bx->d;
        double *o = out + (size_t)j * (size_t)n_rows;
        for (gs_index i = 0; i < n_rows; i++) {
            gs_index q = m->dof[rows[i]];
            o[i] = q >= 0 ? x[q] : 0.0;
        }
    }
    return GS_OK;
}

gs_err gs_fe_static_back_rows(gs_fe_static *s, const double *z, gs_index n_rows,
                              const gs_index *rows, double *out, double *frac)
{
    if (!s || n_rows < 0 || (n_rows > 0 && (!z || !out || !rows)))
        return GS_EINVAL;
    const gs_fe_model *m = s->m;
    if (!dofs_ok(m, n_rows, rows))
        return GS_EINVAL;
    if (frac)
        *frac = 0.0;
    for (gs_index i = 0; i < n_rows; i++)
        out[i] = 0.0;
    if (m->ne == 0 || n_rows == 0)
        return GS_OK;
    const cholmod_factor *L = s->L;
    const SuiteSparse_long *super = L->super, *pi = L->pi, *px = L->px, *Ls = L->s;
    const double *Lx = L->x;
    SuiteSparse_long ns = (SuiteSparse_long)L->nsuper;
    unsigned char *mk = s->smark;
    /* The supernodes the rows' entries depend on: each row's supernode and
     * its ancestors (the parent of a supernode is the supernode of its first
     * row below the diagonal block); a walk stops at a marked one. */
    SuiteSparse_long lo = ns;
    for (gs_index i = 0; i < n_rows; i++) {
        gs_index q = m->dof[rows[i]];
        if (q < 0)
            continue;
        SuiteSparse_long t = s->sup[s->iperm[q]];
        if (t < lo)
            lo = t;
        while (!mk[t]) {
            mk[t] = 1;
            SuiteSparse_long nc = super[t + 1] - super[t], nr = pi[t + 1] - pi[t];
            if (nr == nc)
                break;
            t = s->sup[Ls[pi[t] + nc]];
        }
    }
    /* L^T x = z over them, the last supernode first; the entries a column
     * reads belong to marked supernodes (its ancestors), solved before. */
    double *x = s->xb, *g = s->xg, used = 0.0;
    for (SuiteSparse_long t = ns - 1; t >= lo; t--) {
        if (!mk[t])
            continue;
        mk[t] = 0;
        SuiteSparse_long k1 = super[t], nc = super[t + 1] - k1, nr = pi[t + 1] - pi[t];
        SuiteSparse_long nb = nr - nc;
        const SuiteSparse_long *ri = Ls + pi[t];
        const double *lq = Lx + px[t];
        double *xs = x + k1;
        for (SuiteSparse_long c = 0; c < nc; c++)
            xs[c] = z[k1 + c];
        /* x_1 = L_11^{-T} (z_1 - L_21^T x_2), x_2 the entries below the
         * diagonal block (gathered), as CHOLMOD's supernodal solve. */
        if (nb > 0) {
            for (SuiteSparse_long r = 0; r < nb; r++)
                g[r] = x[ri[nc + r]];
            cblas_dgemv(CblasColMajor, CblasTrans, (blasint)nb, (blasint)nc, -1.0, lq + nc,
                        (blasint)nr, g, 1, 1.0, xs, 1);
        }
        for (SuiteSparse_long c = nc - 1; c >= 0; c--) {
            const double *lc = lq + c * nr;
            double sum = xs[c];
            for (SuiteSparse_long r = c + 1; r < nc; r++)
                sum -= lc[r] * xs[r];
            xs[c] = sum / lc[c];
        }
        used += (double)(nr * nc);
    }
    for (gs_index i = 0; i < n_rows; i++) {
        gs_index q = m->dof[rows[i]];
        if (q >= 0)
            out[i] = x[s->iperm[q]];
    }
    s->solves++;
    if (frac)
        *frac = used / (double)L->xsize;
    return GS_OK;
}
