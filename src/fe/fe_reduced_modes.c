/* SPDX-License-Identifier: MIT
 * A reduced elastic body (fe_reduced.c, docs/explanation/elastic_body.md "Reduced elastic body"):
 * its modes up to f_max, dense LAPACK (dsygvd) up to DENSE_MAX unknowns,
 * else Lanczos with shift-invert on the factor of K, restarted deflated
 * against the modes found. */
#include <cholmod.h>
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fe/fe_internal.h"
#include "fe/fe_reduced_internal.h"
#include "gearsim/util.h"

/* ---- modes -------------------------------------------------------------- */

static gs_err add_mode(gs_fe_reduced *b, int *cap, const double *u, double lam)
{
    if (b->N >= MODES_MAX)
        return GS_ETOOBIG;
    if (b->N >= *cap) {
        int nc = *cap ? 2 * *cap : 64;
        double *P = realloc(b->Phi, (size_t)nc * (size_t)b->n * sizeof *P);
        if (!P)
            return GS_ENOMEM;
        b->Phi = P;
        double *o = realloc(b->om2, (size_t)nc * sizeof *o);
        if (!o)
            return GS_ENOMEM;
        b->om2 = o;
        *cap = nc;
    }
    double *p = b->Phi + (size_t)b->N * (size_t)b->n;
    if (u) {
        memcpy(p, u, (size_t)b->ne * sizeof *p);
        p[b->ne] = gsi_fe_red_theta_of(b, u);
    } else { /* the rigid rotation */
        memset(p, 0, (size_t)b->ne * sizeof *p);
        p[b->ne] = 1.0 / sqrt(b->Itot);
    }
    b->om2[b->N++] = lam;
    return GS_OK;
}

static gs_err modes_dense(gs_fe_reduced *b, int *cap, double lmax)
{
    gs_index ne = b->ne, n = b->n;
    double *Kd = gs_calloc((size_t)(n * n), sizeof *Kd), *Md = gs_calloc((size_t)(n * n), sizeof *Md);
    double *Ke = gs_calloc((size_t)(ne * ne), sizeof *Ke), *Me = gs_calloc((size_t)(ne * ne), sizeof *Me);
    double *wv = gs_calloc((size_t)ne, sizeof *wv);
    gs_err e = (!Kd || !Md || !Ke || !Me || !wv) ? GS_ENOMEM : gs_fe_model_dense(b->m, Kd, Md);
    if (e == GS_OK) {
        for (gs_index j = 0; j < ne; j++)
            for (gs_index i = 0; i < ne; i++) {
                Ke[i + j * ne] = Kd[i + j * n];
                Me[i + j * ne] = Md[i + j * n] - (b->held ? 0.0 : b->m->s[i] * b->m->s[j] / b->Itot);
            }
        if (LAPACKE_dsygvd(LAPACK_COL_MAJOR, 1, 'V', 'L', (lapack_int)ne, Ke, (lapack_int)ne, Me,
                           (lapack_int)ne, wv) != 0)
            e = GS_ESINGULAR;
    }
    for (gs_index j = 0; e == GS_OK && j < ne && wv[j] <= lmax; j++)
        e = add_mode(b, cap, Ke + j * ne, wv[j]);
    free(Kd), free(Md), free(Ke), free(Me), free(wv);
    return e;
}

/* One Lanczos run on K^{-1} Mbar, orthogonal to the modes b->Phi[first..N)
 * (elastic parts) in Mbar; adds the converged Ritz pairs with lambda <= lmax.
 * *added: how many. */
static gs_err lanczos_run(gs_fe_reduced *b, int *cap, int first, double lmax, unsigned seed, int *added)
{
    gs_index ne = b->ne, n = b->n;
    int nlock = b->N - first;
    *added = 0;
    int mmax = (int)(ne < LANCZOS_MAX ? ne : LANCZOS_MAX);
    int m = 0, cv = 0;
    double *V = NULL, *MV = NULL, *al = NULL, *be = NULL;
    double *MX = gs_calloc((size_t)ne * (size_t)(nlock > 0 ? nlock : 1), sizeof *MX);
    double *w = gs_calloc((size_t)ne, sizeof *w), *mw = gs_calloc((size_t)ne, sizeof *mw);
    gs_err e = (!MX || !w || !mw) ? GS_ENOMEM : GS_OK;
    for (int k = 0; e == GS_OK && k < nlock; k++)
        gsi_fe_red_mbar(b, b->Phi + (size_t)(first + k) * (size_t)n, MX + (size_t)k * (size_t)ne);
    /* start vector: pseudo-random */
    uint64_t st = 0x9E3779B97F4A7C15ULL * (seed + 1);
    for (gs_index i = 0; i < ne; i++) {
        st ^= st << 13, st ^= st >> 7, st ^= st << 17;
        w[i] = (double)(st >> 11) / 9007199254740992.0 - 0.5;
    }
    double thmin = 1.0 / lmax;
    double *S = NULL, *dd = NULL, *ee = NULL;
    int done = 0;
    while (e == GS_OK && !done) {
        /* orthogonalise w against the locked modes and V (twice), in Mbar */
        for (int pass = 0; pass < 2; pass++) {
            for (int k = 0; k < nlock; k++) {
                double cf = gsi_fe_red_dotn(ne, MX + (size_t)k * (size_t)ne, w);
                const double *x = b->Phi + (size_t)(first + k) * (size_t)n;
                for (gs_index i = 0; i < ne; i++)
                    w[i] -= cf * x[i];
            }
            for (int k = 0; k < m; k++) {
                double cf = gsi_fe_red_dotn(ne, MV + (size_t)k * (size_t)ne, w);
                const double *x = V + (size_t)k * (size_t)ne;
                for (gs_index i = 0; i < ne; i++)
                    w[i] -= cf * x[i];
            }
        }
        gsi_fe_red_mbar(b, w, mw);
        double bn = sqrt(fabs(gsi_fe_red_dotn(ne, w, mw)));
        if (m > 0)
            be[m - 1] = bn;
        if (m > 0 && (m % 20 == 0 || bn < 1e-12 * fabs(al[m - 1]) || m == mmax)) {
            /* Ritz values of T_m: converged ones with theta >= thmin margin */
            memcpy(dd, al, (size_t)m * sizeof *dd);
            memcpy(ee, be, (size_t)m * sizeof *ee);
            if (LAPACKE_dstev(LAPACK_COL_MAJOR, 'V', (lapack_int)m, dd, ee, S, (lapack_int)m) != 0) {
                e = GS_ENOCONV;
                break;
            }
            bool all = true;
            cv = 0;
            for (int i = m - 1; i >= 0; i--) {
                if (dd[i] < 0.7 * thmin)
                    break;
                double res = fabs(bn * S[(size_t)i * (size_t)m + (size_t)(m - 1)]);
                if (res > 1e-10 * dd[i]) {
                    all = false;
                    break;
                }
                if (dd[i] >= thmin)
                    cv++;
            }
            if (all || bn < 1e-12 * fabs(al[m - 1]) || m == mmax)
                done = 1;
            if (done)
                break;
        }
        if (m == mmax)
            break;
        /* new Lanczos vector */
        if (m % 64 == 0) {
            size_t nc = (size_t)m + 64;
            double *t;
            if (!(t = realloc(V, nc * (size_t)ne * sizeof *t)) || !((V = t), 1) ||
                !(t = realloc(MV, nc * (size_t)ne * sizeof *t)) || !((MV = t), 1) ||
                !(t = realloc(al, nc * sizeof *t)) || !((al = t), 1) || !(t = realloc(be, nc * sizeof *t)) ||
                !((be = t), 1) || !(t = realloc(dd, nc * sizeof *t)) || !((dd = t), 1) ||
                !(t = realloc(ee, nc * sizeof *t)) || !((ee = t), 1) ||
                !(t = realloc(S, nc * nc * sizeof *t)) || !((S = t), 1)) {
                e = GS_ENOMEM;
                break;
            }
        }
        if (!(bn > 0)) {
            e = GS_ENOCONV;
            break;
        }
        double *v = V + (size_t)m * (size_t)ne, *mv = MV + (size_t)m * (size_t)ne;
        for (gs_index i = 0; i < ne; i++) {
            v[i] = w[i] / bn;
            mv[i] = mw[i] / bn;
        }
        e = gsi_fe_red_ksolve(b, 1, mv, w);
        if (e != GS_OK)
            break;
        double a = gsi_fe_red_dotn(ne, mv, w);
        al[m] = a;
        for (gs_index i = 0; i < ne; i++)
            w[i] -= a * v[i] + (m > 0 ? bn * V[(size_t)(m - 1) * (size_t)ne + (size_t)i] : 0.0);
        m++;
    }
    /* Ritz vectors of the converged pairs below f_max */
    for (int i = m - 1; e == GS_OK && i >= 0 && i >= m - cv; i--) {
        memset(w, 0, (size_t)ne * sizeof *w);
        const double *y = S + (size_t)i * (size_t)m;
        for (int k = 0; k < m; k++) {
            const double *x = V + (size_t)k * (size_t)ne;
            for (gs_index j = 0; j < ne; j++)
                w[j] += y[k] * x[j];
        }
        gsi_fe_red_mbar(b, w, mw);
        double nn = sqrt(gsi_fe_red_dotn(ne, w, mw));
        for (gs_index j = 0; j < ne; j++)
            w[j] /= nn;
        e = add_mode(b, cap, w, 1.0 / dd[i]);
        if (e == GS_OK)
            (*added)++;
    }
    free(V), free(MV), free(al), free(be), free(dd), free(ee), free(S), free(MX), free(w), free(mw);
    return e;
}

/* Sort the elastic modes [first, N) by frequency (insertion: few). */
static void sort_modes(gs_fe_reduced *b, int first)
{
    double *t = b->scratch;
    for (int i = first + 1; i < b->N; i++) {
        double lam = b->om2[i];
        memcpy(t, b->Phi + (size_t)i * (size_t)b->n, (size_t)b->n * sizeof *t);
        int j = i - 1;
        while (j >= first && b->om2[j] > lam) {
            b->om2[j + 1] = b->om2[j];
            memcpy(b->Phi + (size_t)(j + 1) * (size_t)b->n, b->Phi + (size_t)j * (size_t)b->n,
                   (size_t)b->n * sizeof *t);
            j--;
        }
        b->om2[j + 1] = lam;
        memcpy(b->Phi + (size_t)(j + 1) * (size_t)b->n, t, (size_t)b->n * sizeof *t);
    }
}

gs_err gsi_fe_red_compute_modes(gs_fe_reduced *b, int solver)
{
    int cap = 0;
    double w = 2.0 * GS_PI * b->fmax, lmax = isfinite(w) ? w * w : INFINITY;
    if (!b->held)
        GS_TRY(add_mode(b, &cap, NULL, 0.0));
    int first = b->N;
    if (solver == 1 || (solver == 0 && b->ne <= DENSE_MAX)) {
        GS_TRY(modes_dense(b, &cap, lmax));
    } else {
        if (!isfinite(lmax))
            return GS_ETOOBIG;
        for (unsigned run = 0; run < RESTARTS_MAX; run++) {
            int added = 0;
            GS_TRY(lanczos_run(b, &cap, first, lmax, run, &added));
            if (run < 4)
                b->lz_added[run] = added;
            b->lz_runs = (int)run + 1;
            if (added == 0)
                break;
        }
        sort_modes(b, first);
    }
    return GS_OK;
}
