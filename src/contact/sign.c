/* SPDX-License-Identifier: MIT
 * Localised Rvachev sign (gap) functions of a slave point against a short
 * master polyline (METHOD.md section 3; conventions in gearsim/contact.h,
 * the blending rule and its continuity argument in docs/explanation/contact.md).
 *
 * Line gap of a -> b, d = b - a, L = |d|, w = x - a:
 *     g = cross(w, d) / L = w . n,   n = (d_y, -d_x) / L,
 * and with tau = w . d / L^2 (projection parameter)
 *     dg/dx = n,  dg/db = dg/dd = -tau n,  dg/da = -(1 - tau) n.
 * (dg/dd = (J w - g d / L) / L with J the +90 degree rotation; writing
 * w = tau d + g n gives J w = -tau L n + g d / L.)
 *
 * Wedge: W = g1 + g2 + sigma r, r = hypot(g1, g2), sigma = +1 convex,
 * -1 concave; dW/dg_i = 1 + sigma g_i / r. */
#include <math.h>
#include <string.h>

#include "gearsim/contact.h"

#define INV_SQRT2 0.70710678118654752440

static bool finite2(const double p[2])
{
    return isfinite(p[0]) && isfinite(p[1]);
}

static double cross2(const double u[2], const double v[2])
{
    return u[0] * v[1] - u[1] * v[0];
}

/* Line gap without argument checks; grad layout x, a, b (6 values). */
static gs_err line_gap(const double x[2], const double a[2], const double b[2], double *g,
                       double grad6[6])
{
    if (!finite2(x) || !finite2(a) || !finite2(b))
        return GS_EGEOMETRY;
    double d[2] = {b[0] - a[0], b[1] - a[1]};
    double L = hypot(d[0], d[1]);
    if (!(L > 0.0))
        return GS_EGEOMETRY;
    double n[2] = {d[1] / L, -d[0] / L};
    double w[2] = {x[0] - a[0], x[1] - a[1]};
    double tau = (w[0] * d[0] + w[1] * d[1]) / (L * L);
    /* cross(w, d) / L: exactly 0 at w = d (x at b), so the vertex of a wedge
     * gets the documented bisector subgradient */
    *g = (w[0] * d[1] - w[1] * d[0]) / L;
    grad6[0] = n[0];
    grad6[1] = n[1];
    grad6[2] = -(1.0 - tau) * n[0];
    grad6[3] = -(1.0 - tau) * n[1];
    grad6[4] = -tau * n[0];
    grad6[5] = -tau * n[1];
    return GS_OK;
}

gs_err gs_gap_line(const double x[2], const double a[2], const double b[2], double *g,
                   double grad[8])
{
    if (!x || !a || !b || !g || !grad)
        return GS_EINVAL;
    double gr[6];
    GS_TRY(line_gap(x, a, b, g, gr));
    memcpy(grad, gr, sizeof gr);
    grad[6] = grad[7] = 0.0;
    return GS_OK;
}

/* dW/dg1, dW/dg2 of the R-function, with the bisector subgradient at r = 0. */
static void rfun(double g1, double g2, double sigma, double *W, double *w1, double *w2)
{
    double r = hypot(g1, g2);
    *W = g1 + g2 + sigma * r;
    double c1 = INV_SQRT2, c2 = INV_SQRT2;
    if (r > 0.0) {
        c1 = g1 / r;
        c2 = g2 / r;
    }
    *w1 = 1.0 + sigma * c1;
    *w2 = 1.0 + sigma * c2;
}

gs_err gs_gap_wedge(const double x[2], const double a[2], const double b[2], const double c[2],
                    bool convex, double *g, double grad[8])
{
    if (!x || !a || !b || !c || !g || !grad)
        return GS_EINVAL;
    double g1, g2, d1[6], d2[6];
    GS_TRY(line_gap(x, a, b, &g1, d1));
    GS_TRY(line_gap(x, b, c, &g2, d2));
    double w1, w2;
    rfun(g1, g2, convex ? 1.0 : -1.0, g, &w1, &w2);
    for (int q = 0; q < 2; q++) {
        grad[0 + q] = w1 * d1[0 + q] + w2 * d2[0 + q];
        grad[2 + q] = w1 * d1[2 + q];
        grad[4 + q] = w1 * d1[4 + q] + w2 * d2[2 + q];
        grad[6 + q] = w2 * d2[4 + q];
    }
    return GS_OK;
}

/* Distance^2 from x to the closed segment p -> q (the end point itself when
 * the projection falls beyond it, so ties at a shared vertex are exact). */
static double seg_dist2(const double x[2], const double p[2], const double q[2])
{
    double d[2] = {q[0] - p[0], q[1] - p[1]};
    double w[2] = {x[0] - p[0], x[1] - p[1]};
    double t = (w[0] * d[0] + w[1] * d[1]) / (d[0] * d[0] + d[1] * d[1]);
    double e[2];
    if (t <= 0.0) {
        e[0] = w[0];
        e[1] = w[1];
    } else if (t >= 1.0) {
        e[0] = x[0] - q[0];
        e[1] = x[1] - q[1];
    } else {
        e[0] = w[0] - t * d[0];
        e[1] = w[1] - t * d[1];
    }
    return e[0] * e[0] + e[1] * e[1];
}

/* Blend weight of the wedge at vertex v (stencil p_{v-1}, p_v, p_{v+1}) and
 * its gradient w.r.t. x and the three stencil nodes (grad layout as grad[8]).
 * Returns phi; dphi is left zero when phi is 0 or 1 (S' = 0 there). */
static double blend_weight(const double x[2], const double *pm, const double *pv,
                           const double *pp, double dphi[8])
{
    memset(dphi, 0, 8 * sizeof *dphi);
    double e0[2] = {pv[0] - pm[0], pv[1] - pm[1]};
    double e1[2] = {pp[0] - pv[0], pp[1] - pv[1]};
    double L0 = hypot(e0[0], e0[1]), L1 = hypot(e1[0], e1[1]);
    /* m_L = min(L0, L1), r1 = m_L / 4, r2 = m_L / 2: t = 4 rho / m_L - 1 */
    bool first = L0 <= L1;
    double mL = first ? L0 : L1;
    double r[2] = {x[0] - pv[0], x[1] - pv[1]};
    double rho = hypot(r[0], r[1]);
    double t = 4.0 * rho / mL - 1.0;
    if (t <= 0.0)
        return 1.0;
    if (t >= 1.0)
        return 0.0;
    double phi = 1.0 - t * t * (3.0 - 2.0 * t);
    double dS = -6.0 * t * (1.0 - t);
    /* dt/drho = 4 / mL (rho > 0 here since t > 0), dt/dmL = -4 rho / mL^2 */
    double a = dS * 4.0 / mL, bm = -dS * 4.0 * rho / (mL * mL);
    double ur[2] = {r[0] / rho, r[1] / rho};
    for (int q = 0; q < 2; q++) {
        dphi[0 + q] += a * ur[q];
        dphi[4 + q] -= a * ur[q];
    }
    if (first) { /* mL = |pv - pm| */
        for (int q = 0; q < 2; q++) {
            dphi[4 + q] += bm * e0[q] / L0;
            dphi[2 + q] -= bm * e0[q] / L0;
        }
    } else { /* mL = |pp - pv| */
        for (int q = 0; q < 2; q++) {
            dphi[6 + q] += bm * e1[q] / L1;
            dphi[4 + q] -= bm * e1[q] / L1;
        }
    }
    return phi;
}

gs_err gs_gap_eval(const double x[2], const double *pts, int k, gs_gap *out)
{
    if (!x || !pts || !out || k < 2)
        return GS_EINVAL;
    memset(out, 0, sizeof *out);
    if (!finite2(x))
        return GS_EGEOMETRY;
    for (int j = 0; j < k; j++)
        if (!finite2(pts + 2 * j))
            return GS_EGEOMETRY;
    int best = -1;
    double bd = INFINITY;
    for (int i = 0; i + 1 < k; i++) {
        const double *p = pts + 2 * i, *q = pts + 2 * i + 2;
        if (p[0] == q[0] && p[1] == q[1])
            return GS_EGEOMETRY;
        double d2 = seg_dist2(x, p, q);
        if (d2 < bd) {
            bd = d2;
            best = i;
        }
    }
    const int i = best;
    double gL, dL[6];
    GS_TRY(line_gap(x, pts + 2 * i, pts + 2 * i + 2, &gL, dL));
    out->segment = i;
    out->kind = GS_GAP_LINE;
    out->g = gL;
    out->n_master = 2;
    out->master[0] = i;
    out->master[1] = i + 1;
    out->master[2] = -1;
    memcpy(out->grad, dL, sizeof dL);

    /* The ends of segment i that are interior vertices; at most one has
     * phi > 0 (rho_a + rho_b >= L_i >= r2_a + r2_b). */
    for (int v = i; v <= i + 1; v++) {
        if (v < 1 || v > k - 2)
            continue;
        const double *pm = pts + 2 * (v - 1), *pv = pts + 2 * v, *pp = pts + 2 * (v + 1);
        double dphi[8];
        double phi = blend_weight(x, pm, pv, pp, dphi);
        if (phi <= 0.0)
            continue;
        double e0[2] = {pv[0] - pm[0], pv[1] - pm[1]};
        double e1[2] = {pp[0] - pv[0], pp[1] - pv[1]};
        bool convex = cross2(e0, e1) > 0.0;
        double W, dW[8];
        GS_TRY(gs_gap_wedge(x, pm, pv, pp, convex, &W, dW));
        /* the line's nodes in the stencil v-1, v, v+1: i = v-1 -> slots 0,1;
         * i = v -> slots 1,2 */
        double dLs[8] = {dL[0], dL[1], 0, 0, 0, 0, 0, 0};
        int s0 = (i == v - 1) ? 0 : 1;
        for (int q = 0; q < 4; q++)
            dLs[2 + 2 * s0 + q] = dL[2 + q];
        out->g = phi * W + (1.0 - phi) * gL;
        for (int q = 0; q < 8; q++)
            out->grad[q] = phi * dW[q] + (1.0 - phi) * dLs[q] + (W - gL) * dphi[q];
        out->kind = convex ? GS_GAP_CONVEX : GS_GAP_CONCAVE;
        out->blend = phi;
        out->n_master = 3;
        out->master[0] = v - 1;
        out->master[1] = v;
        out->master[2] = v + 1;
        break;
    }
    return GS_OK;
}

void gs_gap_chain(const double dg_dx[2], double theta, const double x_minus_c[2],
                  double *dg_dtheta, double dg_du[2])
{
    double c = cos(theta), s = sin(theta);
    /* J (x - c) = (-(y), x) */
    *dg_dtheta += dg_dx[0] * -x_minus_c[1] + dg_dx[1] * x_minus_c[0];
    /* R^T g: R = [[c, -s], [s, c]] */
    dg_du[0] = c * dg_dx[0] + s * dg_dx[1];
    dg_du[1] = -s * dg_dx[0] + c * dg_dx[1];
}

/* ------------------------------------------------------------------------ */
/* Parabolic edges (order-2 boundaries; gs_gap_eval_quad)                   */
/* ------------------------------------------------------------------------ */

/* Edge a (xi = 0), m (xi = 1/2), b (xi = 1): P(xi) = sum_i N_i(xi) p_i in
 * Lagrange form (exactly a, m, b at xi = 0, 1/2, 1, so a joint vertex is the
 * same point seen from either edge), P' = 4(xi - 3/4) a + (4 - 8 xi) m +
 * (4 xi - 1) b, P'' = c2 = 4(a - 2m + b). */
typedef struct qedge {
    double a[2], m[2], b[2], c2[2];
} qedge;

static void qedge_set(qedge *q, const double a[2], const double m[2], const double b[2])
{
    for (int t = 0; t < 2; t++) {
        q->a[t] = a[t];
        q->m[t] = m[t];
        q->b[t] = b[t];
        q->c2[t] = 4.0 * (a[t] - 2.0 * m[t] + b[t]);
    }
}

static void shape3(double xi, double N[3])
{
    N[0] = (1.0 - xi) * (1.0 - 2.0 * xi);
    N[1] = 4.0 * xi * (1.0 - xi);
    N[2] = xi * (2.0 * xi - 1.0);
}

static void qedge_at(const qedge *q, double xi, double P[2], double dP[2])
{
    double N[3], dN[3] = {4.0 * xi - 3.0, 4.0 - 8.0 * xi, 4.0 * xi - 1.0};
    shape3(xi, N);
    for (int t = 0; t < 2; t++) {
        P[t] = N[0] * q->a[t] + N[1] * q->m[t] + N[2] * q->b[t];
        dP[t] = dN[0] * q->a[t] + dN[1] * q->m[t] + dN[2] * q->b[t];
    }
}

/* f(xi) = |P - x|^2 / 2 and its first two derivatives. */
static void qedge_f(const qedge *q, const double x[2], double xi, double *f, double *f1,
                    double *f2)
{
    double P[2], dP[2];
    qedge_at(q, xi, P, dP);
    double d[2] = {P[0] - x[0], P[1] - x[1]};
    *f = 0.5 * (d[0] * d[0] + d[1] * d[1]);
    *f1 = d[0] * dP[0] + d[1] * dP[1];
    *f2 = dP[0] * dP[0] + dP[1] * dP[1] + d[0] * q->c2[0] + d[1] * q->c2[1];
}

/* A root of f' in [lo, hi] with f'(lo) < 0 < f'(hi): Newton, kept in the
 * bracket (bisection when a step leaves it or does not shrink it enough). */
static double qedge_root(const qedge *q, const double x[2], double lo, double hi)
{
    double xi = 0.5 * (lo + hi);
    for (int it = 0; it < 60; it++) {
        double f, f1, f2;
        qedge_f(q, x, xi, &f, &f1, &f2);
        if (f1 == 0.0)
            return xi;
        if (f1 < 0.0)
            lo = xi;
        else
            hi = xi;
        double nx = f2 > 0.0 ? xi - f1 / f2 : 0.5 * (lo + hi);
        if (!(nx > lo && nx < hi) || fabs(nx - xi) > 0.5 * (hi - lo))
            nx = 0.5 * (lo + hi);
        if (fabs(nx - xi) <= 4e-16 * (1.0 + fabs(xi)) || hi - lo <= 4e-16 * (1.0 + fabs(xi)))
            return nx;
        xi = nx;
    }
    return xi;
}

#define QEDGE_SAMPLES 8

/* The global minimiser of f on [lo, hi]: the ends and every local minimum
 * (a sign change - to + of f' between samples); returns xi and f there. */
static double qedge_project(const qedge *q, const double x[2], double lo, double hi,
                            double *fmin)
{
    double best = lo, f, f1, f2;
    qedge_f(q, x, lo, &f, &f1, &f2);
    double bf = f;
    double prev_xi = lo, prev_f1 = f1;
    for (int s = 1; s <= QEDGE_SAMPLES; s++) {
        double xi = s == QEDGE_SAMPLES ? hi : lo + (hi - lo) * (double)s / QEDGE_SAMPLES;
        double g, g1, g2;
        qedge_f(q, x, xi, &g, &g1, &g2);
        if (prev_f1 < 0.0 && g1 > 0.0) {
            double r = qedge_root(q, x, prev_xi, xi), h, h1, h2;
            qedge_f(q, x, r, &h, &h1, &h2);
            if (h < bf) {
                bf = h;
                best = r;
            }
        } else if (g1 == 0.0 && g2 > 0.0 && g < bf) {
            bf = g;
            best = xi;
        }
        if (s == QEDGE_SAMPLES && g < bf) {
            bf = g;
            best = xi;
        }
        prev_xi = xi;
        prev_f1 = g1;
    }
    *fmin = bf;
    return best;
}

/* Outward unit normal (material on the left) of tangent t. */
static bool unit_normal(const double t[2], double n[2])
{
    double L = hypot(t[0], t[1]);
    if (!(L > 0.0))
        return false;
    n[0] = t[1] / L;
    n[1] = -t[0] / L;
    return true;
}

gs_err gs_gap_eval_quad(const double x[2], const double *pts, int k, gs_gap *out)
{
    if (!x || !pts || !out || k < 3 || k % 2 == 0)
        return GS_EINVAL;
    memset(out, 0, sizeof *out);
    if (!finite2(x))
        return GS_EGEOMETRY;
    for (int j = 0; j < k; j++) {
        if (!finite2(pts + 2 * j))
            return GS_EGEOMETRY;
        if (j > 0 && pts[2 * j] == pts[2 * j - 2] && pts[2 * j + 1] == pts[2 * j - 1])
            return GS_EGEOMETRY;
    }
    const int E = (k - 1) / 2;
    int be = -1;
    double bxi = 0.0, bf = INFINITY;
    for (int e = 0; e < E; e++) {
        qedge q;
        qedge_set(&q, pts + 4 * e, pts + 4 * e + 2, pts + 4 * e + 4);
        double lo = e == 0 ? -1.0 : 0.0, hi = e == E - 1 ? 2.0 : 1.0, f;
        double xi = qedge_project(&q, x, lo, hi, &f);
        if (f < bf) {
            bf = f;
            be = e;
            bxi = xi;
        }
    }
    if (be < 0)
        return GS_EGEOMETRY;
    qedge q;
    qedge_set(&q, pts + 4 * be, pts + 4 * be + 2, pts + 4 * be + 4);
    double P[2], dP[2], n[2];
    qedge_at(&q, bxi, P, dP);
    if (!unit_normal(dP, n))
        return GS_EGEOMETRY;
    double d[2] = {x[0] - P[0], x[1] - P[1]};
    double nu[2] = {n[0], n[1]};
    /* a joint vertex: the end xi = 1 of edge be < E - 1 (a tie at the shared
     * corner goes to the lower edge, so xi = 0 of an edge be > 0 is the
     * vertex only when the lower edge did not reach it first) */
    int joint = -1;
    if (bxi == 1.0 && be < E - 1)
        joint = be + 1;
    else if (bxi == 0.0 && be > 0)
        joint = be;
    double g;
    if (joint >= 0) {
        qedge qa, qb;
        qedge_set(&qa, pts + 4 * (joint - 1), pts + 4 * (joint - 1) + 2, pts + 4 * joint);
        qedge_set(&qb, pts + 4 * joint, pts + 4 * joint + 2, pts + 4 * joint + 4);
        double Pa[2], ta[2], Pb[2], tb[2], na[2], nb[2];
        qedge_at(&qa, 1.0, Pa, ta);
        qedge_at(&qb, 0.0, Pb, tb);
        if (!unit_normal(ta, na) || !unit_normal(tb, nb))
            return GS_EGEOMETRY;
        double nm[2] = {na[0] + nb[0], na[1] + nb[1]};
        double r = hypot(d[0], d[1]);
        if (r > 0.0) {
            double sd = d[0] * nm[0] + d[1] * nm[1];
            double s = sd > 0.0 ? 1.0 : (sd < 0.0 ? -1.0 : (cross2(ta, tb) > 0.0 ? 1.0 : -1.0));
            nu[0] = s * d[0] / r;
            nu[1] = s * d[1] / r;
            g = s * r;
        } else {
            double L = hypot(nm[0], nm[1]);
            nu[0] = L > 0.0 ? nm[0] / L : na[0];
            nu[1] = L > 0.0 ? nm[1] / L : na[1];
            g = 0.0;
        }
    } else {
        g = d[0] * n[0] + d[1] * n[1];
    }
    double N[3];
    shape3(bxi, N);
    out->g = g;
    out->kind = GS_GAP_PARABOLA;
    out->segment = be;
    out->xi = bxi;
    out->blend = 0.0;
    out->n_master = 3;
    out->grad[0] = nu[0];
    out->grad[1] = nu[1];
    for (int j = 0; j < 3; j++) {
        out->master[j] = 2 * be + j;
        out->grad[2 + 2 * j] = -N[j] * nu[0];
        out->grad[3 + 2 * j] = -N[j] * nu[1];
    }
    return GS_OK;
}
