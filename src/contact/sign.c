/* SPDX-License-Identifier: MIT
 * Localised Rvachev sign (gap) functions of a slave point against a short
 * master polyline (METHOD.md section 3; conventions in gearsim/contact.h,
 * the blending rule and its continuity argument in docs/CONTACT.md).
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
