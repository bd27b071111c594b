/* SPDX-License-Identifier: MIT
 * Gear meshes (gear_mesh.c): the concentric rings between the band circle
 * and the hub (or a ring's outer rim), joined by zippers, and the smoothing
 * of poor elements (interior nodes only). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/mesh.h"
#include "gearsim/util.h"
#include "mesh/gear_mesh_internal.h"
#include "mesh/mesh_internal.h"

/* ------------------------------------------------------------------------ */
/* Rings between the band and the hub                                       */
/* ------------------------------------------------------------------------ */

/* Rings at refine 0: element size grows by 1.3 per ring away from the
 * teeth; the count may at most halve from one ring to the next. */
int gsi_gmesh_plan_rings(const gs_gear_geom *g, double R0, gs_index N0, double h0, rings_t *rp)
{
    const double grow = 1.3;
    int cap = 64;
    rp->R = malloc((size_t)cap * sizeof *rp->R);
    rp->N = malloc((size_t)cap * sizeof *rp->N);
    if (!rp->R || !rp->N)
        return -1;
    double dir = g->internal ? 1.0 : -1.0, hub = g->hub;
    rp->n = 1;
    rp->R[0] = R0;
    rp->N[0] = N0;
    if (fabs(hub - R0) <= 1e-12 * hub)
        return 0;
    double R = R0, h = h0;
    gs_index N = N0;
    for (;;) {
        double hn = h * grow;
        double Rn = R + dir * hn;
        int last = g->internal ? Rn >= hub - 0.5 * hn : Rn <= hub + 0.5 * hn;
        if (last)
            Rn = hub;
        gs_index want = (gs_index)llround(2.0 * GS_PI * Rn / hn);
        gs_index lo = (N + 1) / 2;
        if (want < 12)
            want = 12;
        if (want < lo)
            want = lo;
        if (want > N)
            want = N;
        if (rp->n == cap) {
            cap *= 2;
            double *nR = realloc(rp->R, (size_t)cap * sizeof *nR);
            if (!nR)
                return -1;
            rp->R = nR;
            gs_index *nN = realloc(rp->N, (size_t)cap * sizeof *nN);
            if (!nN)
                return -1;
            rp->N = nN;
        }
        rp->R[rp->n] = Rn;
        rp->N[rp->n] = want;
        rp->n++;
        if (last)
            break;
        R = Rn;
        h = hn;
        N = want;
    }
    return 0;
}

/* Angles of a closed loop of nodes, unwrapped to increase from `from`
 * (which is within pi of the first node's angle); out has n + 1 entries,
 * the last one closing the loop (first + 2 pi). */
static void loop_angles(const nodes_t *nb, const gs_index *L, gs_index n, double from, double *out)
{
    double prev = atan2(nb->xy[2 * L[0] + 1], nb->xy[2 * L[0]]);
    double d0 = prev - from;
    out[0] = from + d0 - 2 * GS_PI * floor(d0 / (2 * GS_PI) + 0.5);
    for (gs_index k = 1; k < n; k++) {
        double a = atan2(nb->xy[2 * L[k] + 1], nb->xy[2 * L[k]]);
        double da = a - prev;
        da -= 2 * GS_PI * floor(da / (2 * GS_PI));
        out[k] = out[k - 1] + da;
        prev = a;
    }
    out[n] = out[0] + 2 * GS_PI;
}

/* Triangulate the band between two closed loops of nodes on concentric
 * circles, each in increasing angle: walk both, always advancing on the
 * loop whose next edge midpoint comes first in angle. Counter-clockwise
 * triangles; `a_outer` says which loop has the larger radius. */
int gsi_gmesh_zipper(nodes_t *nb, tris_t *tb, const gs_index *A, gs_index na, const gs_index *B,
                     gs_index nbn, int a_outer)
{
    double *aa = malloc((size_t)(na + 1) * sizeof *aa), *ab = malloc((size_t)(nbn + 1) * sizeof *ab);
    gs_index *Br = malloc((size_t)nbn * sizeof *Br);
    int rc = -1;
    if (!aa || !ab || !Br)
        goto out;
    double a0 = atan2(nb->xy[2 * A[0] + 1], nb->xy[2 * A[0]]);
    loop_angles(nb, A, na, a0, aa);
    /* Start B at its node nearest in angle to A[0]. */
    gs_index j0 = 0;
    double best = 1e300;
    for (gs_index j = 0; j < nbn; j++) {
        double t = atan2(nb->xy[2 * B[j] + 1], nb->xy[2 * B[j]]) - a0;
        t -= 2 * GS_PI * floor(t / (2 * GS_PI) + 0.5);
        if (fabs(t) < best) {
            best = fabs(t);
            j0 = j;
        }
    }
    for (gs_index j = 0; j < nbn; j++)
        Br[j] = B[(j0 + j) % nbn];
    loop_angles(nb, Br, nbn, a0, ab);
    gs_index i = 0, j = 0;
    while (i < na || j < nbn) {
        gs_index ia = A[i % na], ia1 = A[(i + 1) % na];
        gs_index jb = Br[j % nbn], jb1 = Br[(j + 1) % nbn];
        int adv_a = i == na ? 0 : j == nbn ? 1 : aa[i] + aa[i + 1] < ab[j] + ab[j + 1];
        int r;
        if (adv_a) {
            r = a_outer ? gsi_gmesh_tri_add(tb, ia, ia1, jb) : gsi_gmesh_tri_add(tb, ia1, ia, jb);
            i++;
        } else {
            r = a_outer ? gsi_gmesh_tri_add(tb, jb1, jb, ia) : gsi_gmesh_tri_add(tb, jb, jb1, ia);
            j++;
        }
        if (r)
            goto out;
    }
    rc = 0;
out:
    free(aa);
    free(ab);
    free(Br);
    return rc;
}

/* ------------------------------------------------------------------------ */
/* Smoothing of poor elements                                               */
/* ------------------------------------------------------------------------ */

/* Smart Laplacian smoothing: an interior node touching an element of shape
 * below `thresh` moves towards the mean of its neighbours, by the largest of
 * the steps 1, 1/2, 1/4 that raises its worst incident shape. Boundary
 * nodes never move (they lie on the exact curves), nodes of good elements
 * neither (that keeps the grading). */
int gsi_gmesh_smooth_poor(nodes_t *nb, const tris_t *tb, int iters, double thresh)
{
    gs_index n = nb->n;
    gs_index *cnt = calloc((size_t)n + 1, sizeof *cnt);
    gs_index *adj = malloc((size_t)(3 * tb->n + 1) * sizeof *adj);
    if (!cnt || !adj) {
        free(cnt);
        free(adj);
        return -1;
    }
    /* node -> incident triangles (CSR) */
    for (gs_index t = 0; t < tb->n; t++)
        for (int k = 0; k < 3; k++)
            cnt[tb->t[3 * t + k] + 1]++;
    for (gs_index i = 0; i < n; i++)
        cnt[i + 1] += cnt[i];
    gs_index *pos = malloc((size_t)n * sizeof *pos);
    if (!pos) {
        free(cnt);
        free(adj);
        return -1;
    }
    memcpy(pos, cnt, (size_t)n * sizeof *pos);
    for (gs_index t = 0; t < tb->n; t++)
        for (int k = 0; k < 3; k++)
            adj[pos[tb->t[3 * t + k]]++] = t;
    free(pos);
    for (int it = 0; it < iters; it++) {
        gs_index moved = 0;
        for (gs_index v = 0; v < n; v++) {
            if (nb->tag[v] != GS_NODE_INTERIOR)
                continue;
            double worst = 1e300, cx = 0.0, cy = 0.0;
            gs_index deg = 0;
            for (gs_index q = cnt[v]; q < cnt[v + 1]; q++) {
                const gs_index *T = tb->t + 3 * adj[q];
                double sh = gsi_gmesh_tri_shape(nb->xy, T[0], T[1], T[2]);
                if (sh < worst)
                    worst = sh;
                for (int k = 0; k < 3; k++)
                    if (T[k] != v) {
                        cx += nb->xy[2 * T[k]];
                        cy += nb->xy[2 * T[k] + 1];
                        deg++;
                    }
            }
            if (worst >= thresh || deg == 0)
                continue;
            cx /= (double)deg;
            cy /= (double)deg;
            double x0 = nb->xy[2 * v], y0 = nb->xy[2 * v + 1];
            for (double w = 1.0; w > 0.2; w *= 0.5) {
                nb->xy[2 * v] = x0 + w * (cx - x0);
                nb->xy[2 * v + 1] = y0 + w * (cy - y0);
                double nw = 1e300;
                for (gs_index q = cnt[v]; q < cnt[v + 1]; q++) {
                    const gs_index *T = tb->t + 3 * adj[q];
                    double sh = gsi_gmesh_tri_shape(nb->xy, T[0], T[1], T[2]);
                    if (sh < nw)
                        nw = sh;
                }
                if (nw > worst) {
                    moved++;
                    goto next;
                }
            }
            nb->xy[2 * v] = x0;
            nb->xy[2 * v + 1] = y0;
        next:;
        }
        if (!moved)
            break;
    }
    free(cnt);
    free(adj);
    return 0;
}
