/* SPDX-License-Identifier: MIT
 * Gear meshes (gear_mesh.c): growable node and triangle lists, graded
 * distributions on [0, 1], and blocks filled row by row (rows placed by
 * transfinite interpolation of the block's sides, joined by a zipper). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/mesh.h"
#include "gearsim/util.h"
#include "mesh/gear_mesh_internal.h"
#include "mesh/mesh_internal.h"

/* ------------------------------------------------------------------------ */
/* Growable node and triangle lists                                         */
/* ------------------------------------------------------------------------ */

gs_index gsi_gmesh_node_add(nodes_t *nb, double x, double y, int tag)
{
    if (nb->n == nb->cap) {
        gs_index nc = nb->cap ? 2 * nb->cap : 256;
        double *xy = realloc(nb->xy, (size_t)nc * 2 * sizeof *xy);
        if (!xy)
            return -1;
        nb->xy = xy;
        signed char *tg = realloc(nb->tag, (size_t)nc);
        if (!tg)
            return -1;
        nb->tag = tg;
        nb->cap = nc;
    }
    nb->xy[2 * nb->n] = x;
    nb->xy[2 * nb->n + 1] = y;
    nb->tag[nb->n] = (signed char)tag;
    return nb->n++;
}

int gsi_gmesh_tri_add(tris_t *tb, gs_index a, gs_index b, gs_index c)
{
    gs_index *t = gs_grow(tb->t, &tb->cap, (size_t)tb->n + 1, 3 * sizeof *t);
    if (!t)
        return -1;
    tb->t = t;
    tb->t[3 * tb->n] = a;
    tb->t[3 * tb->n + 1] = b;
    tb->t[3 * tb->n + 2] = c;
    tb->n++;
    return 0;
}

static double tri_area(const double *xy, gs_index a, gs_index b, gs_index c)
{
    double ax = xy[2 * a], ay = xy[2 * a + 1];
    return 0.5 * ((xy[2 * b] - ax) * (xy[2 * c + 1] - ay) - (xy[2 * b + 1] - ay) * (xy[2 * c] - ax));
}

/* 4 sqrt(3) A / (sum of squared edges): 1 equilateral, <= 0 inverted. */
double gsi_gmesh_tri_shape(const double *xy, gs_index a, gs_index b, gs_index c)
{
    double A = tri_area(xy, a, b, c);
    double s = 0.0;
    gs_index v[3] = {a, b, c};
    for (int k = 0; k < 3; k++) {
        gs_index p = v[k], q = v[(k + 1) % 3];
        double dx = xy[2 * q] - xy[2 * p], dy = xy[2 * q + 1] - xy[2 * p + 1];
        s += dx * dx + dy * dy;
    }
    return s > 0 ? 4.0 * sqrt(3.0) * A / s : -1.0;
}

/* ------------------------------------------------------------------------ */
/* Distributions on [0, 1] (nested: u = i/n and u = 2i/2n give one point)  */
/* ------------------------------------------------------------------------ */

/* Smallest steps at both ends; largest / smallest = g. */
double gsi_gmesh_grade_both(double u, double g)
{
    if (g <= 1.0 + 1e-12)
        return u;
    double dl = acosh(sqrt(g));
    return 0.5 * (1.0 + tanh(dl * (2.0 * u - 1.0)) / tanh(dl));
}

/* Smallest steps at u = 1; largest / smallest = g. */
double gsi_gmesh_grade_top(double u, double g)
{
    if (g <= 1.0 + 1e-12)
        return u;
    double dl = acosh(sqrt(g));
    return tanh(dl * u) / tanh(dl);
}

/* ------------------------------------------------------------------------ */
/* Blocks                                                                   */
/* ------------------------------------------------------------------------ */

static void chord_params(const nodes_t *nb, const gs_index *ids, int n, double *t)
{
    t[0] = 0.0;
    for (int i = 1; i <= n; i++) {
        double dx = nb->xy[2 * ids[i]] - nb->xy[2 * ids[i - 1]];
        double dy = nb->xy[2 * ids[i] + 1] - nb->xy[2 * ids[i - 1] + 1];
        t[i] = t[i - 1] + hypot(dx, dy);
    }
    for (int i = 1; i <= n; i++)
        t[i] /= t[n];
}

/* Point of a polyline (node ids, chord-length parameters t) at parameter u. */
static void poly_eval(const nodes_t *nb, const gs_index *ids, const double *t, int n, double u,
                      double P[2])
{
    int k = 0;
    while (k < n - 1 && t[k + 1] < u)
        k++;
    double den = t[k + 1] - t[k];
    double w = den > 0 ? (u - t[k]) / den : 0.0;
    w = w < 0 ? 0 : w > 1 ? 1 : w;
    for (int c = 0; c < 2; c++)
        P[c] = (1 - w) * nb->xy[2 * ids[k] + c] + w * nb->xy[2 * ids[k + 1] + c];
}

/* Parameter of the polyline's node at fractional index u * n. */
static double frac_param(const double *t, int n, double u)
{
    double x = u * n;
    int k = (int)floor(x);
    if (k >= n)
        return 1.0;
    if (k < 0)
        return 0.0;
    return t[k] + (x - k) * (t[k + 1] - t[k]);
}

/* A four-sided patch meshed row by row. Row j (0..nrow) runs from the left
 * side node lef[j] to the right side node rig[j] with cnt[j] elements; row
 * 0 is `bot`, row nrow is `top`. Nodes of the rows in between are placed
 * by transfinite interpolation of the four sides (Coons patch), their
 * spacing blended from the bottom's and the top's; consecutive rows are
 * joined by a gsi_gmesh_zipper (two rows of different counts is what lets a block
 * change its resolution: a tooth narrowing to its tip, a fillet finer than
 * the rim below it). */
int gsi_gmesh_layered_block(nodes_t *nb, tris_t *tb, int nrow, const int *cnt, const gs_index *bot,
                            const gs_index *top, const gs_index *lef, const gs_index *rig)
{
    const int nb0 = cnt[0], nt = cnt[nrow];
    int maxc = 0;
    for (int j = 0; j <= nrow; j++)
        maxc = cnt[j] > maxc ? cnt[j] : maxc;
    double *xb = malloc((size_t)(nb0 + 1) * sizeof *xb), *xt = malloc((size_t)(nt + 1) * sizeof *xt);
    double *yl = malloc((size_t)(nrow + 1) * sizeof *yl), *yr = malloc((size_t)(nrow + 1) * sizeof *yr);
    double *xa = malloc((size_t)(maxc + 1) * sizeof *xa), *xn = malloc((size_t)(maxc + 1) * sizeof *xn);
    gs_index *ra = malloc((size_t)(maxc + 1) * sizeof *ra), *rn = malloc((size_t)(maxc + 1) * sizeof *rn);
    int rc = -1;
    if (!xb || !xt || !yl || !yr || !xa || !xn || !ra || !rn)
        goto out;
    chord_params(nb, bot, nb0, xb);
    chord_params(nb, top, nt, xt);
    chord_params(nb, lef, nrow, yl);
    chord_params(nb, rig, nrow, yr);
    double p00[2] = {nb->xy[2 * bot[0]], nb->xy[2 * bot[0] + 1]};
    double p10[2] = {nb->xy[2 * bot[nb0]], nb->xy[2 * bot[nb0] + 1]};
    double p01[2] = {nb->xy[2 * top[0]], nb->xy[2 * top[0] + 1]};
    double p11[2] = {nb->xy[2 * top[nt]], nb->xy[2 * top[nt] + 1]};
    /* Orientation of the patch: signed area of its boundary polygon. */
    double A = 0.0;
    {
        double px = p00[0], py = p00[1];
#define ACC(id)                                                              \
    do {                                                                     \
        double qx = nb->xy[2 * (id)], qy = nb->xy[2 * (id) + 1];             \
        A += px * qy - qx * py;                                              \
        px = qx;                                                             \
        py = qy;                                                             \
    } while (0)
        for (int i = 1; i <= nb0; i++)
            ACC(bot[i]);
        for (int j = 1; j <= nrow; j++)
            ACC(rig[j]);
        for (int i = nt - 1; i >= 0; i--)
            ACC(top[i]);
        for (int j = nrow - 1; j >= 0; j--)
            ACC(lef[j]);
#undef ACC
    }
    const int ccw = A > 0;
    for (int i = 0; i <= nb0; i++) {
        ra[i] = bot[i];
        xa[i] = xb[i];
    }
    for (int j = 1; j <= nrow; j++) {
        const int n = cnt[j];
        if (j == nrow) {
            for (int i = 0; i <= n; i++) {
                rn[i] = top[i];
                xn[i] = xt[i];
            }
        } else {
            double e0 = 0.5 * (yl[j] + yr[j]);
            rn[0] = lef[j];
            rn[n] = rig[j];
            xn[0] = 0.0;
            xn[n] = 1.0;
            for (int i = 1; i < n; i++) {
                double u = (double)i / n;
                double xi = (1 - e0) * frac_param(xb, nb0, u) + e0 * frac_param(xt, nt, u);
                double eta = (1 - xi) * yl[j] + xi * yr[j];
                double B[2], T[2], P[2];
                poly_eval(nb, bot, xb, nb0, xi, B);
                poly_eval(nb, top, xt, nt, xi, T);
                for (int c = 0; c < 2; c++) {
                    double L = nb->xy[2 * lef[j] + c], R = nb->xy[2 * rig[j] + c];
                    P[c] = (1 - eta) * B[c] + eta * T[c] + (1 - xi) * L + xi * R -
                           ((1 - xi) * (1 - eta) * p00[c] + xi * (1 - eta) * p10[c] +
                            (1 - xi) * eta * p01[c] + xi * eta * p11[c]);
                }
                rn[i] = gsi_gmesh_node_add(nb, P[0], P[1], GS_NODE_INTERIOR);
                if (rn[i] < 0)
                    goto out;
                xn[i] = xi;
            }
        }
        /* gsi_gmesh_zipper rows (ra, xa, cnt[j-1]) and (rn, xn, n) by parameter */
        int i = 0, k = 0, na_ = cnt[j - 1];
        while (i < na_ || k < n) {
            int adv_lo = i == na_ ? 0 : k == n ? 1 : xa[i] + xa[i + 1] < xn[k] + xn[k + 1];
            int r;
            if (adv_lo) {
                r = ccw ? gsi_gmesh_tri_add(tb, ra[i], ra[i + 1], rn[k]) : gsi_gmesh_tri_add(tb, ra[i + 1], ra[i], rn[k]);
                i++;
            } else {
                r = ccw ? gsi_gmesh_tri_add(tb, rn[k + 1], rn[k], ra[i]) : gsi_gmesh_tri_add(tb, rn[k], rn[k + 1], ra[i]);
                k++;
            }
            if (r)
                goto out;
        }
        for (int q = 0; q <= n; q++) {
            ra[q] = rn[q];
            xa[q] = xn[q];
        }
    }
    rc = 0;
out:
    free(xb);
    free(xt);
    free(yl);
    free(yr);
    free(xa);
    free(xn);
    free(ra);
    free(rn);
    return rc;
}
