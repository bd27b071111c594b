/* SPDX-License-Identifier: MIT
 * Quadratic (6-node) triangles from a linear mesh: one node per edge, shared
 * by the two elements of an interior edge; on a gear's boundary the node is
 * placed on the exact curve the edge follows (involute at equal involute arc
 * length, fillet at equal arc length, tip/root/core circles at the middle
 * angle), through the geometry module's curve functions, so any later
 * change of a curve (profile modifications move GS_NODE_FLANK nodes) moves
 * the mid-side nodes with the corners (docs/explanation/elastic_body.md "Quadratic elements"). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "mesh/mesh_internal.h"
#include "gearsim/util.h"

typedef struct {
    gs_index a, b; /* a < b */
    gs_index id;   /* edge number in element order (3 e + i) */
} qedge;

static int qedge_cmp(const void *pa, const void *pb)
{
    const qedge *x = pa, *y = pb;
    if (x->a != y->a)
        return (x->a > y->a) - (x->a < y->a);
    if (x->b != y->b)
        return (x->b > y->b) - (x->b < y->b);
    return (x->id > y->id) - (x->id < y->id);
}

/* Node on edge (a, b) of a sorted edge table, or -1. */
static gs_index edge_lookup(const qedge *E, gs_index ne, const gs_index *mid_of, gs_index a,
                            gs_index b)
{
    qedge key = {a < b ? a : b, a < b ? b : a, -1};
    gs_index lo = 0, hi = ne;
    while (lo < hi) {
        gs_index md = lo + (hi - lo) / 2;
        if (qedge_cmp(&E[md], &key) < 0)
            lo = md + 1;
        else
            hi = md;
    }
    if (lo < ne && E[lo].a == key.a && E[lo].b == key.b)
        return mid_of[E[lo].id];
    return -1;
}

/* ---- gear boundary curves ---------------------------------------------- */

/* Frame of the tooth nearest to polar angle `ang`: its centre angle. */
static double tooth_centre(const gs_gear_geom *g, double ang)
{
    double pitch = 2.0 * GS_PI / g->z;
    return pitch * round(ang / pitch);
}

static void rot(double c, const double in[2], double out[2])
{
    double cs = cos(c), sn = sin(c);
    double x = cs * in[0] - sn * in[1], y = sn * in[0] + cs * in[1];
    out[0] = x;
    out[1] = y;
}

/* Fillet parameter of a point of the counter-clockwise fillet of tooth 0
 * (nearest point: sampled, then golden-section refined). Returns the
 * distance of the point from the curve in *dist. */
static double fillet_param(const gs_gear_geom *g, const double P[2], double *dist)
{
    double best = 0, bd = INFINITY, Q[2], T[2];
    const int ns = 256;
    for (int i = 0; i <= ns; i++) {
        gs_gear_fillet_point(g, (double)i / ns, Q, T);
        double d = hypot(Q[0] - P[0], Q[1] - P[1]);
        if (d < bd) {
            bd = d;
            best = (double)i / ns;
        }
    }
    double lo = fmax(0.0, best - 1.0 / ns), hi = fmin(1.0, best + 1.0 / ns);
    const double gr = 0.5 * (sqrt(5.0) - 1.0);
    for (int it = 0; it < 80 && hi - lo > 1e-15; it++) {
        double t1 = hi - gr * (hi - lo), t2 = lo + gr * (hi - lo);
        gs_gear_fillet_point(g, t1, Q, T);
        double d1 = hypot(Q[0] - P[0], Q[1] - P[1]);
        gs_gear_fillet_point(g, t2, Q, T);
        double d2 = hypot(Q[0] - P[0], Q[1] - P[1]);
        if (d1 < d2)
            hi = t2;
        else
            lo = t1;
    }
    double t = 0.5 * (lo + hi);
    gs_gear_fillet_point(g, t, Q, T);
    *dist = hypot(Q[0] - P[0], Q[1] - P[1]);
    return t;
}

/* Arc length of the fillet between parameters t0 < t1 (Gauss-Legendre on
 * |dP/dt| through the unit tangent and finite differences of position is
 * avoided: a fine polyline is accurate to far below the node tolerance). */
static double fillet_length(const gs_gear_geom *g, double t0, double t1)
{
    const int n = 64;
    double L = 0, P[2], Q[2], T[2];
    gs_gear_fillet_point(g, t0, Q, T);
    for (int i = 1; i <= n; i++) {
        gs_gear_fillet_point(g, t0 + (t1 - t0) * i / n, P, T);
        L += hypot(P[0] - Q[0], P[1] - Q[1]);
        Q[0] = P[0];
        Q[1] = P[1];
    }
    return L;
}

/* Parameter at arc length s from t0 towards t1: false position with the
 * Illinois modification on the fraction md of [t0, t1] (the length is
 * smooth in md: a few evaluations, where bisection took 60), to 1e-15 of
 * the interval. */
static double fillet_at_length(const gs_gear_geom *g, double t0, double t1, double s)
{
    double lo = 0, hi = 1, flo = -s, fhi = fillet_length(g, fmin(t0, t1), fmax(t0, t1)) - s;
    if (!(flo < 0.0) || !(fhi > 0.0))
        return flo >= 0.0 ? t0 : t1;
    int side = 0;
    double md = 0.5;
    for (int it = 0; it < 100 && hi - lo > 1e-15; it++) {
        md = (lo * fhi - hi * flo) / (fhi - flo);
        if (!(md > lo && md < hi))
            md = 0.5 * (lo + hi);
        double tm = t0 + (t1 - t0) * md;
        double f = (tm > t0 ? fillet_length(g, t0, tm) : fillet_length(g, tm, t0)) - s;
        if (f == 0.0)
            break;
        if (f < 0.0) {
            lo = md;
            flo = f;
            if (side == -1)
                fhi *= 0.5;
            side = -1;
        } else {
            hi = md;
            fhi = f;
            if (side == 1)
                flo *= 0.5;
            side = 1;
        }
    }
    return t0 + (t1 - t0) * md;
}

/* Middle of a boundary edge on the gear's exact outline (or on the core
 * circle). Falls back to the chord's middle where no curve is recognised. */
static void gear_mid(const gs_gear_geom *g, const double A[2], const double B[2], int ta, int tb,
                     double out[2], int *tag)
{
    double ra = hypot(A[0], A[1]), rbb = hypot(B[0], B[1]);
    out[0] = 0.5 * (A[0] + B[0]);
    out[1] = 0.5 * (A[1] + B[1]);
    *tag = ta == tb ? ta : GS_NODE_OTHER;
    double aa = atan2(A[1], A[0]), ab = atan2(B[1], B[0]);
    double da = remainder(ab - aa, 2.0 * GS_PI);
    /* circles: tip, root, core (hub or outer rim) */
    if (fabs(ra - rbb) <= 1e-9 * ra) {
        double R = 0.5 * (ra + rbb), am = aa + 0.5 * da;
        out[0] = R * cos(am);
        out[1] = R * sin(am);
        if (ta == GS_NODE_CORE || tb == GS_NODE_CORE)
            *tag = GS_NODE_CORE;
        else if (fabs(R - g->ra) <= 1e-9 * R)
            *tag = GS_NODE_TIP;
        else if (fabs(R - g->rf) <= 1e-9 * R)
            *tag = GS_NODE_ROOT;
        return;
    }
    /* tooth frame of the edge's middle, mirrored onto the counter-clockwise
     * half */
    double c = tooth_centre(g, aa + 0.5 * da);
    double a[2], b[2];
    rot(-c, A, a);
    rot(-c, B, b);
    double sg = (a[1] + b[1]) >= 0 ? 1.0 : -1.0;
    a[1] *= sg;
    b[1] *= sg;
    double m[2], T[2];
    if (ta == GS_NODE_FLANK && tb == GS_NODE_FLANK) {
        /* equal involute arc length: (R^2 - rb^2) / (2 rb) */
        double R = sqrt(0.5 * (ra * ra + rbb * rbb));
        gs_gear_flank_point(g, R, m, T);
        *tag = GS_NODE_FLANK;
    } else if ((ta == GS_NODE_FILLET || ta == GS_NODE_FLANK || ta == GS_NODE_ROOT) &&
               (tb == GS_NODE_FILLET || tb == GS_NODE_FLANK || tb == GS_NODE_ROOT) &&
               (ta == GS_NODE_FILLET || tb == GS_NODE_FILLET)) {
        /* fillet, possibly running into the form point (flank tag) or onto
         * the root arc (root tag): measured along the joined curve */
        const double *pf = a, *po = b;
        int to = tb;
        if (ta != GS_NODE_FILLET) {
            pf = b;
            po = a;
            to = ta;
        }
        double df, d2 = 0;
        double tf = fillet_param(g, pf, &df);
        if (df > 1e-7 * g->m)
            return;
        if (to == GS_NODE_ROOT) {
            double lf = fillet_length(g, tf, 1.0);
            double lr = g->rf * fabs(atan2(po[1], po[0]) - g->psi_root);
            double h = 0.5 * (lf + lr);
            if (h <= lf) {
                gs_gear_fillet_point(g, fillet_at_length(g, tf, 1.0, h), m, T);
                *tag = GS_NODE_FILLET;
            } else {
                double ps = g->psi_root + (h - lf) / g->rf *
                                              (atan2(po[1], po[0]) >= g->psi_root ? 1.0 : -1.0);
                m[0] = g->rf * cos(ps);
                m[1] = g->rf * sin(ps);
                *tag = GS_NODE_ROOT;
            }
        } else {
            double to_t = fillet_param(g, po, &d2);
            if (d2 > 1e-7 * g->m)
                return;
            double lo = fmin(tf, to_t), hi = fmax(tf, to_t);
            gs_gear_fillet_point(g, fillet_at_length(g, lo, hi, 0.5 * fillet_length(g, lo, hi)),
                                 m, T);
            *tag = GS_NODE_FILLET;
        }
    } else {
        return;
    }
    m[1] *= sg;
    rot(c, m, out);
}

/* ---- promotion ---------------------------------------------------------- */

void gsi_t6_shape(double l1, double l2, double N[6], double d1[6], double d2[6])
{
    double l3 = 1.0 - l1 - l2;
    if (N) {
        N[0] = l1 * (2 * l1 - 1);
        N[1] = l2 * (2 * l2 - 1);
        N[2] = l3 * (2 * l3 - 1);
        N[3] = 4 * l1 * l2;
        N[4] = 4 * l2 * l3;
        N[5] = 4 * l3 * l1;
    }
    double a[6] = {4 * l1 - 1, 0, -(4 * l3 - 1), 4 * l2, -4 * l2, 4 * (l3 - l1)};
    double b[6] = {0, 4 * l2 - 1, -(4 * l3 - 1), 4 * l1, 4 * (l3 - l2), -4 * l1};
    if (d1)
        memcpy(d1, a, sizeof a);
    if (d2)
        memcpy(d2, b, sizeof b);
}

double gsi_t6_jacobian(const double *x, const double *y, double l1, double l2, double N[6],
                       double dNx[6], double dNy[6])
{
    double d1[6], d2[6];
    gsi_t6_shape(l1, l2, N, d1, d2);
    double xa = 0, xb = 0, ya = 0, yb = 0;
    for (int i = 0; i < 6; i++) {
        xa += d1[i] * x[i];
        xb += d2[i] * x[i];
        ya += d1[i] * y[i];
        yb += d2[i] * y[i];
    }
    double det = xa * yb - xb * ya;
    if (dNx && dNy)
        for (int i = 0; i < 6; i++) {
            dNx[i] = (yb * d1[i] - ya * d2[i]) / det;
            dNy[i] = (-xb * d1[i] + xa * d2[i]) / det;
        }
    return det;
}

gs_err gsi_mesh_quadratic(gs_mesh *m, const gs_gear_geom *g)
{
    if (!m || m->mid || m->n_tris < 1 || !m->tri)
        return GS_EINVAL;
    gs_index ne = 3 * m->n_tris;
    qedge *E = malloc((size_t)ne * sizeof *E);
    gs_index *mid = malloc((size_t)ne * sizeof *mid);
    gs_err err = GS_ENOMEM;
    double *xy = NULL;
    signed char *tag = NULL;
    gs_index *bnd = NULL, *fn = NULL, *fp = NULL, *fx = NULL;
    char *isfix = calloc((size_t)m->n_nodes + 1, 1);
    if (!E || !mid || !isfix)
        goto out;
    for (gs_index i = 0; i < m->n_fixed; i++)
        isfix[m->fixed[i]] = 1;
    for (gs_index t = 0; t < m->n_tris; t++)
        for (int i = 0; i < 3; i++) {
            gs_index a = m->tri[3 * t + i], b = m->tri[3 * t + (i + 1) % 3];
            E[3 * t + i].a = a < b ? a : b;
            E[3 * t + i].b = a < b ? b : a;
            E[3 * t + i].id = 3 * t + i;
        }
    qsort(E, (size_t)ne, sizeof *E, qedge_cmp);
    gs_index nu = 0;
    for (gs_index i = 0; i < ne; i++)
        if (i == 0 || E[i].a != E[i - 1].a || E[i].b != E[i - 1].b)
            nu++;
    gs_index n0 = m->n_nodes, n1 = n0 + nu, nfx = m->n_fixed;
    xy = malloc((size_t)(2 * n1) * sizeof *xy);
    /* a mid-side node between two fixed nodes is fixed (core circle, clamp) */
    fx = malloc((size_t)(m->n_fixed + nu + 1) * sizeof *fx);
    if (!fx)
        goto out;
    if (m->n_fixed > 0)
        memcpy(fx, m->fixed, (size_t)m->n_fixed * sizeof *fx);
    if (m->node_tag)
        tag = malloc((size_t)n1);
    if (!xy || (m->node_tag && !tag))
        goto out;
    memcpy(xy, m->xy, (size_t)(2 * n0) * sizeof *xy);
    if (tag)
        memcpy(tag, m->node_tag, (size_t)n0);
    gs_index k = n0;
    for (gs_index i = 0; i < ne;) {
        gs_index j = i;
        while (j < ne && E[j].a == E[i].a && E[j].b == E[i].b)
            j++;
        const double *A = m->xy + 2 * E[i].a, *B = m->xy + 2 * E[i].b;
        double P[2] = {0.5 * (A[0] + B[0]), 0.5 * (A[1] + B[1])};
        int tg = GS_NODE_INTERIOR;
        if (j - i == 1) { /* boundary edge */
            int ta = m->node_tag ? m->node_tag[E[i].a] : GS_NODE_OTHER;
            int tb = m->node_tag ? m->node_tag[E[i].b] : GS_NODE_OTHER;
            tg = ta == tb ? ta : GS_NODE_OTHER;
            if (g)
                gear_mid(g, A, B, ta, tb, P, &tg);
        }
        xy[2 * k] = P[0];
        xy[2 * k + 1] = P[1];
        if (tag)
            tag[k] = (signed char)tg;
        for (gs_index q = i; q < j; q++)
            mid[E[q].id] = k;
        if (isfix[E[i].a] && isfix[E[i].b])
            fx[nfx++] = k;
        k++;
        i = j;
    }
    /* every element must stay valid with its curved edges */
    for (gs_index t = 0; t < m->n_tris; t++) {
        double x[6], y[6];
        for (int i = 0; i < 3; i++) {
            x[i] = xy[2 * m->tri[3 * t + i]];
            y[i] = xy[2 * m->tri[3 * t + i] + 1];
            x[3 + i] = xy[2 * mid[3 * t + i]];
            y[3 + i] = xy[2 * mid[3 * t + i] + 1];
        }
        static const double pts[7][2] = {{1, 0}, {0, 1}, {0, 0}, {0.5, 0.5},
                                         {0, 0.5}, {0.5, 0}, {1.0 / 3, 1.0 / 3}};
        double d0 = gsi_t6_jacobian(x, y, 1.0 / 3, 1.0 / 3, NULL, NULL, NULL);
        for (int q = 0; q < 7; q++)
            if (!(gsi_t6_jacobian(x, y, pts[q][0], pts[q][1], NULL, NULL, NULL) > 1e-3 * d0)) {
                err = GS_EGEOMETRY;
                goto out;
            }
    }
    /* boundary loop and flank tables with the mid-side nodes inserted */
    if (m->boundary && m->n_boundary > 0) {
        bnd = malloc((size_t)(2 * m->n_boundary) * sizeof *bnd);
        if (!bnd)
            goto out;
        for (gs_index i = 0; i < m->n_boundary; i++) {
            gs_index a = m->boundary[i], b = m->boundary[(i + 1) % m->n_boundary];
            bnd[2 * i] = a;
            bnd[2 * i + 1] = edge_lookup(E, ne, mid, a, b);
            if (bnd[2 * i + 1] < 0) {
                err = GS_EGEOMETRY;
                goto out;
            }
        }
    }
    if (m->flank_ptr && m->n_teeth > 0) {
        gs_index nf = 2 * (gs_index)m->n_teeth;
        fp = malloc((size_t)(nf + 1) * sizeof *fp);
        fn = malloc((size_t)(2 * m->flank_ptr[nf] + 1) * sizeof *fn);
        if (!fp || !fn)
            goto out;
        fp[0] = 0;
        for (gs_index f = 0; f < nf; f++) {
            gs_index w = fp[f];
            for (gs_index p = m->flank_ptr[f]; p < m->flank_ptr[f + 1]; p++) {
                if (p > m->flank_ptr[f]) {
                    gs_index md = edge_lookup(E, ne, mid, m->flank_nodes[p - 1], m->flank_nodes[p]);
                    if (md < 0) {
                        err = GS_EGEOMETRY;
                        goto out;
                    }
                    fn[w++] = md;
                }
                fn[w++] = m->flank_nodes[p];
            }
            fp[f + 1] = w;
        }
    }
    free(m->xy);
    m->xy = xy;
    xy = NULL;
    if (tag) {
        free(m->node_tag);
        m->node_tag = tag;
        tag = NULL;
    }
    if (bnd) {
        free(m->boundary);
        m->boundary = bnd;
        m->n_boundary *= 2;
        bnd = NULL;
    }
    if (fp) {
        free(m->flank_ptr);
        free(m->flank_nodes);
        m->flank_ptr = fp;
        m->flank_nodes = fn;
        fp = fn = NULL;
    }
    free(m->fixed);
    m->fixed = fx;
    m->n_fixed = nfx;
    fx = NULL;
    m->n_nodes = n1;
    m->mid = mid;
    mid = NULL;
    err = GS_OK;
out:
    free(E);
    free(mid);
    free(xy);
    free(tag);
    free(bnd);
    free(fp);
    free(fn);
    free(fx);
    free(isfix);
    return err;
}

gs_err gs_mesh_make_quadratic(gs_mesh *m)
{
    return gsi_mesh_quadratic(m, NULL);
}

gs_index *gs_mesh_triangle6(const gs_mesh *m)
{
    if (!m || !m->mid || m->n_tris < 1)
        return NULL;
    gs_index *t6 = malloc((size_t)(6 * m->n_tris) * sizeof *t6);
    if (!t6)
        return NULL;
    for (gs_index e = 0; e < m->n_tris; e++)
        for (int i = 0; i < 3; i++) {
            t6[6 * e + i] = m->tri[3 * e + i];
            t6[6 * e + 3 + i] = m->mid[3 * e + i];
        }
    return t6;
}
