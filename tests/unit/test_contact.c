/* SPDX-License-Identifier: MIT
 * Contact geometry (src/contact): Rvachev sign functions and the contact
 * search of a gear mesh (docs/explanation/contact.md).
 *
 * Gradient checks use central differences with step 1e-6 x the length scale
 * of the configuration: the truncation error is ~(1e-6)^2 relative (g is
 * smooth at the sampled points), the round-off ~1e-16 x |coordinates| / step,
 * at most ~1e-8 relative here, so 1e-7 (sign functions) and 1e-6 (the chain
 * through rotations of 30 mm radius gears, where coordinates are ~1e4 times
 * the step) leave a margin of 10 to 100 while any wrong term (a missing
 * blend-weight derivative, a sign) is O(1). Samples whose central
 * difference straddles a change of the nearest segment or of the blend
 * state are skipped, and counted. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/contact.h"
#include "gearsim/geometry.h"
#include "gearsim/mesh.h"
#include "gearsim/util.h"
#include "../common/gears.h"

#define DEG (GS_PI / 180.0)

/* Deterministic uniform numbers in [0, 1). */
static double rnd(uint64_t *s)
{
    *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(*s >> 11) / 9007199254740992.0;
}

/* ------------------------------------------------------------------------ */
/* Sign functions                                                           */
/* ------------------------------------------------------------------------ */

typedef struct {
    int kind; /* 0 line, 1 convex wedge, 2 concave wedge */
    double p[6];
} prim;

static double prim_eval(const prim *pr, const double x[2], const double *p, double grad[8])
{
    double g = 0, gr[8];
    gs_err e;
    if (pr->kind == 0)
        e = gs_gap_line(x, p, p + 2, &g, gr);
    else
        e = gs_gap_wedge(x, p, p + 2, p + 4, pr->kind == 1, &g, gr);
    assert_int_equal(e, GS_OK);
    if (grad)
        memcpy(grad, gr, sizeof gr);
    return g;
}

/* Max relative error of the analytic gradient of a primitive at x. */
static double prim_fd_error(const prim *pr, const double x0[2], double L)
{
    double gr[8], pts[8];
    pts[0] = x0[0];
    pts[1] = x0[1];
    memcpy(pts + 2, pr->p, sizeof pr->p);
    prim_eval(pr, x0, pr->p, gr);
    double h = 1e-6 * L, err = 0, norm = 1.0;
    for (int q = 0; q < 8; q++)
        norm = fmax(norm, fabs(gr[q]));
    int nq = pr->kind == 0 ? 6 : 8;
    for (int q = 0; q < nq; q++) {
        double v[2];
        for (int sgn = 0; sgn < 2; sgn++) {
            double pp[8];
            memcpy(pp, pts, sizeof pp);
            pp[q] += sgn ? -h : h;
            v[sgn] = prim_eval(pr, pp, pp + 2, NULL);
        }
        double fd = (v[0] - v[1]) / (2 * h);
        err = fmax(err, fabs(fd - gr[q]) / norm);
    }
    /* translation invariance: the gradients sum to zero */
    double sx = 0, sy = 0;
    for (int j = 0; j < 4; j++) {
        sx += gr[2 * j];
        sy += gr[2 * j + 1];
    }
    err = fmax(err, fmax(fabs(sx), fabs(sy)) / norm);
    return err;
}

static void primitive_gradients(void **state)
{
    (void)state;
    uint64_t s = 7;
    const double L = 1e-3, off[2] = {0.031, -0.022}; /* gear-like scale and position */
    double worst[3] = {0, 0, 0};
    int n = 0;
    for (int kind = 0; kind < 3; kind++) {
        for (int trial = 0; trial < 200; trial++) {
            prim pr = {.kind = kind};
            double ang = 2 * GS_PI * rnd(&s), turn = (10 + 150 * rnd(&s)) * DEG;
            if (kind == 2)
                turn = -turn;
            double l0 = L * (0.5 + rnd(&s)), l1 = L * (0.5 + rnd(&s));
            pr.p[2] = off[0];
            pr.p[3] = off[1];
            pr.p[0] = off[0] - l0 * cos(ang);
            pr.p[1] = off[1] - l0 * sin(ang);
            pr.p[4] = off[0] + l1 * cos(ang + turn);
            pr.p[5] = off[1] + l1 * sin(ang + turn);
            double x[2];
            do {
                x[0] = off[0] + L * (2 * rnd(&s) - 1);
                x[1] = off[1] + L * (2 * rnd(&s) - 1);
            } while (hypot(x[0] - off[0], x[1] - off[1]) < 0.05 * L);
            worst[kind] = fmax(worst[kind], prim_fd_error(&pr, x, L));
            n++;
        }
    }
    print_message("# sign gradients vs central FD (step 1e-6 L, %d samples): line %.1e, convex "
                  "wedge %.1e, concave wedge %.1e (max relative)\n",
                  n, worst[0], worst[1], worst[2]);
    for (int k = 0; k < 3; k++)
        assert_true(worst[k] < 1e-7);
}

/* Convex quadrant x <= 0, y >= 0 and concave (union y >= 0 or x >= 0)
 * corners at the origin, scaled by `scale`; material on the left. */
static void corner(int convex, double scale, double p[6])
{
    p[0] = -scale;
    p[1] = 0;
    p[2] = 0;
    p[3] = 0;
    p[4] = 0;
    p[5] = convex ? scale : -scale;
}

static bool corner_inside(int convex, const double x[2])
{
    return convex ? (x[0] < 0 && x[1] > 0) : (x[1] > 0 || x[0] > 0);
}

static void zero_set_and_sign(void **state)
{
    (void)state;
    uint64_t s = 11;
    double worst_zero = 0;
    int n_sign = 0;
    for (int convex = 0; convex < 2; convex++) {
        for (int si = 0; si < 3; si++) {
            double scale = si == 0 ? 1.0 : (si == 1 ? 1e-3 : 0.05);
            double p[6];
            corner(convex, scale, p);
            /* rotate and shift the corner so nothing is axis-aligned */
            double a = 0.7 + si, c = cos(a), sn = sin(a), sh[2] = {0.3 * scale, -1.7 * scale};
            for (int j = 0; j < 3; j++) {
                double X = p[2 * j], Y = p[2 * j + 1];
                p[2 * j] = c * X - sn * Y + sh[0];
                p[2 * j + 1] = sn * X + c * Y + sh[1];
            }
            double big = 2.0 * scale; /* largest coordinate magnitude */
            /* zero set: points on either segment */
            for (int seg = 0; seg < 2; seg++)
                for (int i = 0; i <= 20; i++) {
                    double t = i / 20.0, x[2];
                    x[0] = p[2 * seg] + t * (p[2 * seg + 2] - p[2 * seg]);
                    x[1] = p[2 * seg + 1] + t * (p[2 * seg + 3] - p[2 * seg + 1]);
                    double g, gr[8];
                    assert_int_equal(gs_gap_wedge(x, p, p + 2, p + 4, convex, &g, gr), GS_OK);
                    for (int q = 0; q < 8; q++)
                        assert_false(isnan(gr[q]));
                    worst_zero = fmax(worst_zero, fabs(g) / big);
                    gs_gap ge;
                    assert_int_equal(gs_gap_eval(x, p, 3, &ge), GS_OK);
                    worst_zero = fmax(worst_zero, fabs(ge.g) / big);
                    assert_int_equal(gs_gap_line(x, p + 2 * seg, p + 2 * seg + 2, &g, gr), GS_OK);
                    worst_zero = fmax(worst_zero, fabs(g) / big);
                }
            /* sign: random points in the corner's frame */
            for (int i = 0; i < 2000; i++) {
                double xl[2] = {scale * (1.8 * rnd(&s) - 0.9), scale * (1.8 * rnd(&s) - 0.9)};
                if (fabs(xl[0]) < 1e-6 * scale || fabs(xl[1]) < 1e-6 * scale)
                    continue;
                bool in = corner_inside(convex, xl);
                double x[2] = {c * xl[0] - sn * xl[1] + sh[0], sn * xl[0] + c * xl[1] + sh[1]};
                double g, gr[8];
                assert_int_equal(gs_gap_wedge(x, p, p + 2, p + 4, convex, &g, gr), GS_OK);
                assert_true(in ? g < 0 : g > 0);
                gs_gap ge;
                assert_int_equal(gs_gap_eval(x, p, 3, &ge), GS_OK);
                assert_true(in ? ge.g < 0 : ge.g > 0);
                assert_int_equal(ge.kind == GS_GAP_LINE || ge.kind == (convex ? GS_GAP_CONVEX
                                                                             : GS_GAP_CONCAVE),
                                 1);
                n_sign++;
            }
            /* the vertex itself: g = 0, bisector subgradient, no NaN */
            double g, gr[8];
            assert_int_equal(gs_gap_wedge(p + 2, p, p + 2, p + 4, convex, &g, gr), GS_OK);
            assert_true(g == 0.0);
            double bis[2] = {gr[0], gr[1]};
            /* along n1 + n2 */
            double n1[2] = {p[3] - p[1], -(p[2] - p[0])}, n2[2] = {p[5] - p[3], -(p[4] - p[2])};
            double nb[2] = {n1[0] + n2[0], n1[1] + n2[1]};
            assert_true(fabs(bis[0] * nb[1] - bis[1] * nb[0]) <=
                        1e-12 * hypot(bis[0], bis[1]) * hypot(nb[0], nb[1]));
            assert_true(bis[0] * nb[0] + bis[1] * nb[1] > 0);
        }
    }
    print_message("# zero set: max |g| / max|coordinate| on the segments = %.1e (bound 1e-15); "
                  "%d sign checks (convex and concave, 3 scales) all right\n",
                  worst_zero, n_sign);
    assert_true(worst_zero <= 1e-15);
}

/* Error checks of the sign functions. */
static void sign_errors(void **state)
{
    (void)state;
    double a[2] = {0, 0}, x[2] = {1, 1}, g, gr[8];
    assert_int_equal(gs_gap_line(x, a, a, &g, gr), GS_EGEOMETRY);
    double nanp[2] = {NAN, 0}, b[2] = {1, 0};
    assert_int_equal(gs_gap_line(nanp, a, b, &g, gr), GS_EGEOMETRY);
    assert_int_equal(gs_gap_line(NULL, a, b, &g, gr), GS_EINVAL);
    double pts[6] = {0, 0, 1, 0, 1, 0};
    gs_gap ge;
    assert_int_equal(gs_gap_eval(x, pts, 3, &ge), GS_EGEOMETRY);
    assert_int_equal(gs_gap_eval(x, pts, 1, &ge), GS_EINVAL);
}

/* A 6-node polyline with convex and concave vertices of several turns and
 * unequal segments; scale L, placed at gear-like coordinates. */
static void test_polyline(double L, double *pts)
{
    const double turn[4] = {25 * DEG, -40 * DEG, 8 * DEG, 70 * DEG};
    const double len[5] = {1.0, 0.7, 1.3, 0.9, 1.1};
    double ang = 0.4, x = 0.028, y = 0.011;
    pts[0] = x;
    pts[1] = y;
    for (int i = 0; i < 5; i++) {
        x += L * len[i] * cos(ang);
        y += L * len[i] * sin(ang);
        pts[2 * i + 2] = x;
        pts[2 * i + 3] = y;
        if (i < 4)
            ang += turn[i];
    }
}

typedef gs_err (*gap_fn)(const double x[2], const double *pts, int k, gs_gap *out);
typedef bool (*same_fn)(const gs_gap *a, const gs_gap *b);

/* Largest |central difference (step h) - analytic| of g0's gradient w.r.t.
 * the slave point x0 and each master node used (k <= 7 nodes); *skip is
 * set when a perturbed evaluation is in another state (same false). */
static double fd_gap_error(gap_fn f, same_fn same, const double x0[2], const double *pts, int k,
                           const gs_gap *g0, double h, bool *skip)
{
    double err = 0;
    *skip = false;
    for (int q = 0; q < 2 + 2 * g0->n_master && !*skip; q++) {
        double v[2];
        for (int sg = 0; sg < 2; sg++) {
            double x[2] = {x0[0], x0[1]}, p[14];
            memcpy(p, pts, (size_t)(2 * k) * sizeof *p);
            double dlt = sg ? -h : h;
            if (q < 2)
                x[q] += dlt;
            else
                p[2 * g0->master[(q - 2) / 2] + (q % 2)] += dlt;
            gs_gap g1;
            assert_int_equal(f(x, p, k, &g1), GS_OK);
            if (!same(g0, &g1))
                *skip = true;
            v[sg] = g1.g;
        }
        err = fmax(err, fabs((v[0] - v[1]) / (2 * h) - g0->grad[q]));
    }
    return err;
}

/* Same nearest segment and blend state. */
static bool same_blend(const gs_gap *a, const gs_gap *b)
{
    return b->segment == a->segment && b->n_master == a->n_master &&
           (b->blend > 0) == (a->blend > 0) && (b->blend < 1) == (a->blend < 1);
}

static void eval_gradients(void **state)
{
    (void)state;
    const double L = 1e-3;
    double pts[12];
    test_polyline(L, pts);
    uint64_t s = 3;
    double worst = 0, h = 1e-6 * L;
    int checked = 0, skipped = 0, blended = 0;
    for (int trial = 0; trial < 3000; trial++) {
        /* near the polyline: a point on it plus an offset up to 0.3 L */
        int i = (int)(5 * rnd(&s));
        double t = rnd(&s);
        double x0[2] = {pts[2 * i] + t * (pts[2 * i + 2] - pts[2 * i]) + 0.6 * L * (rnd(&s) - 0.5),
                        pts[2 * i + 1] + t * (pts[2 * i + 3] - pts[2 * i + 1]) +
                            0.6 * L * (rnd(&s) - 0.5)};
        gs_gap g0;
        assert_int_equal(gs_gap_eval(x0, pts, 6, &g0), GS_OK);
        double norm = 1.0;
        for (int q = 0; q < 8; q++)
            norm = fmax(norm, fabs(g0.grad[q]));
        /* the unknowns: slave x, y, then each master node used */
        bool skip;
        double err = fd_gap_error(gs_gap_eval, same_blend, x0, pts, 6, &g0, h, &skip) / norm;
        if (skip) {
            skipped++;
            continue;
        }
        checked++;
        if (g0.blend > 0 && g0.blend < 1)
            blended++;
        worst = fmax(worst, err);
    }
    print_message("# gap_eval gradients vs central FD (step 1e-6 L): %d points (%d in a blend "
                  "zone), %d skipped at a switch, max relative error %.1e\n",
                  checked, blended, skipped, worst);
    assert_true(worst < 1e-7);
    assert_true(checked > 2500 && blended > 200);
}

/* Sweep paths past each vertex at several offsets; |dg| per step is bounded
 * by the gradient bound (|dg/dx| <= 2 + sqrt 2 plus the blend term, < 4)
 * times the step: a jump at a switch of feature would exceed it. */
static void continuity(void **state)
{
    (void)state;
    const double L = 1e-3;
    double pts[12];
    test_polyline(L, pts);
    const double offs[] = {0.0, 0.05, -0.05, 0.12, -0.12, 0.16, -0.16};
    const int nstep = 20000;
    double worst_ratio = 0, worst_zero = 0;
    int switches = 0;
    for (unsigned io = 0; io < sizeof offs / sizeof offs[0]; io++) {
        double d = offs[io] * L;
        double prev = 0, prevx[2] = {0, 0};
        int prev_seg = -1;
        for (int j = 0; j <= nstep; j++) {
            /* arc-length position along the polyline, from 0.2 of segment 0
             * to 0.8 of segment 4; the offset normal turns smoothly through
             * each vertex over +-0.3 L of arc length */
            double lens[5], tot = 0;
            for (int i = 0; i < 5; i++) {
                lens[i] = hypot(pts[2 * i + 2] - pts[2 * i], pts[2 * i + 3] - pts[2 * i + 1]);
                tot += lens[i];
            }
            double sa = 0.2 * lens[0] + (tot - 0.2 * lens[0] - 0.2 * lens[4]) * j / nstep;
            int i = 0;
            double acc = 0;
            while (i < 4 && acc + lens[i] < sa) {
                acc += lens[i];
                i++;
            }
            double t = (sa - acc) / lens[i];
            double P[2] = {pts[2 * i] + t * (pts[2 * i + 2] - pts[2 * i]),
                           pts[2 * i + 1] + t * (pts[2 * i + 3] - pts[2 * i + 1])};
            double an[6];
            for (int k = 0; k < 5; k++)
                an[k] = atan2(-(pts[2 * k + 2] - pts[2 * k]), pts[2 * k + 3] - pts[2 * k + 1]);
            double a = an[i], eta = 0.3 * L;
            double to_end = lens[i] - (sa - acc), from_start = sa - acc;
            if (i < 4 && to_end < eta) {
                double w = 0.5 * (1 - to_end / eta);
                double da = atan2(sin(an[i + 1] - an[i]), cos(an[i + 1] - an[i]));
                a = an[i] + w * da;
            } else if (i > 0 && from_start < eta) {
                double w = 0.5 * (1 - from_start / eta);
                double da = atan2(sin(an[i - 1] - an[i]), cos(an[i - 1] - an[i]));
                a = an[i] + w * da;
            }
            double x[2] = {P[0] + d * cos(a), P[1] + d * sin(a)};
            gs_gap g;
            assert_int_equal(gs_gap_eval(x, pts, 6, &g), GS_OK);
            if (d == 0.0)
                worst_zero = fmax(worst_zero, fabs(g.g) / 0.04);
            if (j > 0) {
                double dx = hypot(x[0] - prevx[0], x[1] - prevx[1]);
                worst_ratio = fmax(worst_ratio, fabs(g.g - prev) / (dx + 1e-300));
                if (g.segment != prev_seg)
                    switches++;
            }
            prev = g.g;
            prevx[0] = x[0];
            prevx[1] = x[1];
            prev_seg = g.segment;
        }
    }
    print_message("# continuity: 7 offset paths (0, +-0.05, +-0.12, +-0.16 L; r1 >= 0.175 L here) past 4 vertices, %d "
                  "steps each, %d nearest-segment switches: max |dg|/|dx| = %.3f (bound 4); on the "
                  "zero set max |g| / max|coordinate| = %.1e\n",
                  nstep, switches, worst_ratio, worst_zero);
    assert_true(worst_ratio < 4.0);
    assert_true(switches >= 7 * 4);
    assert_true(worst_zero <= 1e-15);
}

/* ------------------------------------------------------------------------ */
/* Search on real gear pairs                                                */
/* ------------------------------------------------------------------------ */

/* ------------------------------------------------------------------------ */
/* Parabolic edges (order 2): gs_gap_eval_quad                              */
/* ------------------------------------------------------------------------ */

/* Three parabolic edges (7 nodes), corner spacing L:
 * case 0: on a circle of radius 20 L, counter-clockwise (convex body, the
 *         material inside), nodes at equal angles;
 * case 1: the same circle clockwise (concave: the material outside);
 * case 2: a true convex corner: edge 0 slightly bowed along +x up to the
 *         origin, edges 1 and 2 leaving it turned 70 degrees left;
 * case 3: the concave corner, turned 70 degrees right. */
static void quad_chain(int kase, double L, double p[14])
{
    if (kase < 2) {
        const double R = 20 * L, dphi = 0.5 * L / R;
        for (int j = 0; j < 7; j++) {
            double a = (kase == 0 ? 1.0 : -1.0) * (j - 3) * dphi - GS_PI / 2;
            p[2 * j] = R * cos(a);
            p[2 * j + 1] = R * sin(a) + R;
        }
        return;
    }
    double turn = (kase == 2 ? 70.0 : -70.0) * DEG;
    /* edge 0: (-L, 0) .. (0, 0), mid-side node bowed by 0.02 L outwards (-y) */
    p[0] = -L;
    p[1] = 0;
    p[2] = -0.5 * L;
    p[3] = -0.02 * L * (kase == 2 ? 1 : -1);
    p[4] = 0;
    p[5] = 0;
    double t[2] = {cos(turn), sin(turn)}, nrm[2] = {t[1], -t[0]};
    for (int j = 3; j < 7; j++) {
        double s = 0.5 * L * (j - 2), bow = (j % 2) ? 0.01 * L : 0.0;
        p[2 * j] = s * t[0] + bow * nrm[0];
        p[2 * j + 1] = s * t[1] + bow * nrm[1];
    }
}

/* Point and outward normal of edge e at xi (the test's own formulas). */
static void quad_point(const double *p, int e, double xi, double P[2], double n[2])
{
    const double *a = p + 4 * e, *m = a + 2, *b = a + 4;
    double N[3] = {(1 - xi) * (1 - 2 * xi), 4 * xi * (1 - xi), xi * (2 * xi - 1)};
    double dN[3] = {4 * xi - 3, 4 - 8 * xi, 4 * xi - 1};
    double t[2];
    for (int q = 0; q < 2; q++) {
        P[q] = N[0] * a[q] + N[1] * m[q] + N[2] * b[q];
        t[q] = dN[0] * a[q] + dN[1] * m[q] + dN[2] * b[q];
    }
    double tl = hypot(t[0], t[1]);
    n[0] = t[1] / tl;
    n[1] = -t[0] / tl;
}

/* Zero set, sign and magnitude: on the edges g = 0 to round-off; a point P
 * + t n at small offset t has g = t (the Euclidean distance, interior
 * points of smooth chains; on corner chains |g| <= |t| and the sign of t);
 * on the circle chains g is the distance to the circle to well below the
 * sagitta of the chords through corner and mid-side nodes (the polyline
 * gap's error), so the gap is measured to the parabolas. */
static void quad_zero_set_and_sign(void **state)
{
    (void)state;
    const double L = 1e-3;
    uint64_t s = 11;
    double worst_zero = 0, worst_t = 0, worst_circle = 0;
    int n_sign = 0;
    for (int kase = 0; kase < 4; kase++) {
        double p[14];
        quad_chain(kase, L, p);
        for (int trial = 0; trial < 2000; trial++) {
            int e = (int)(3 * rnd(&s));
            double xi = rnd(&s), P[2], n[2];
            quad_point(p, e, xi, P, n);
            gs_gap g;
            assert_int_equal(gs_gap_eval_quad(P, p, 7, &g), GS_OK);
            assert_int_equal(g.kind, GS_GAP_PARABOLA);
            assert_int_equal(g.n_master, 3);
            worst_zero = fmax(worst_zero, fabs(g.g) / L);
            double t = 0.05 * L * (2 * rnd(&s) - 1);
            if (fabs(t) < 1e-6 * L)
                continue;
            double x[2] = {P[0] + t * n[0], P[1] + t * n[1]};
            assert_int_equal(gs_gap_eval_quad(x, p, 7, &g), GS_OK);
            n_sign++;
            assert_true(g.g * t > 0);
            assert_true(fabs(g.g) <= fabs(t) * (1 + 1e-12));
            if (kase < 2 && xi > 0.1 && xi < 0.9)
                worst_t = fmax(worst_t, fabs(g.g - t) / L);
            if (kase < 2) {
                const double R = 20 * L;
                double gc = (kase == 0 ? 1 : -1) * (hypot(x[0], x[1] - R) - R);
                worst_circle = fmax(worst_circle, fabs(g.g - gc));
            }
        }
    }
    /* sagitta of a chord between corner and mid-side node: (L/2)^2 / (8 R) */
    const double sag = 0.25 * L * L / (8 * 20 * L);
    print_message("# quad gap: |g| on the edges <= %.1e L; g = t to %.1e L (interior, smooth "
                  "chains); %d signs; |g - circle distance| <= %.2e m = %.1e of the chord "
                  "sagitta %.2e m\n",
                  worst_zero, worst_t, n_sign, worst_circle, worst_circle / sag, sag);
    assert_true(worst_zero < 1e-13);
    assert_true(worst_t < 1e-12);
    assert_true(worst_circle < 0.02 * sag);
    assert_true(n_sign > 7000);
    /* errors */
    double p[14], x[2] = {0, 0};
    gs_gap g;
    quad_chain(0, L, p);
    assert_int_equal(gs_gap_eval_quad(x, p, 6, &g), GS_EINVAL);
    assert_int_equal(gs_gap_eval_quad(x, p, 1, &g), GS_EINVAL);
    assert_int_equal(gs_gap_eval_quad(NULL, p, 7, &g), GS_EINVAL);
    p[4] = p[2];
    p[5] = p[3];
    assert_int_equal(gs_gap_eval_quad(x, p, 7, &g), GS_EGEOMETRY);
    quad_chain(0, L, p);
    p[7] = NAN;
    assert_int_equal(gs_gap_eval_quad(x, p, 7, &g), GS_EGEOMETRY);
}

/* Gradients against central differences (step 1e-6 L) w.r.t. the slave
 * point and the three nodes of the edge used, at points up to 0.3 L off the
 * chains, joint vertices (the clamped projection) included; a sample whose
 * difference straddles a change of edge or of the clamped state is
 * skipped. */
/* Same edge, and both at a joint vertex or both not. */
static bool same_edge(const gs_gap *a, const gs_gap *b)
{
    bool va = a->xi == 0.0 || a->xi == 1.0, vb = b->xi == 0.0 || b->xi == 1.0;
    return b->segment == a->segment && va == vb;
}

static void quad_gradients(void **state)
{
    (void)state;
    const double L = 1e-3, h = 1e-6 * L;
    uint64_t s = 5;
    double worst = 0;
    int checked = 0, skipped = 0, at_vertex = 0;
    for (int kase = 0; kase < 4; kase++) {
        double pts[14];
        quad_chain(kase, L, pts);
        for (int trial = 0; trial < 1500; trial++) {
            int e = (int)(3 * rnd(&s));
            double P[2], n[2];
            quad_point(pts, e, rnd(&s), P, n);
            double x0[2] = {P[0] + 0.6 * L * (rnd(&s) - 0.5), P[1] + 0.6 * L * (rnd(&s) - 0.5)};
            gs_gap g0;
            assert_int_equal(gs_gap_eval_quad(x0, pts, 7, &g0), GS_OK);
            bool vtx0 = g0.xi == 0.0 || g0.xi == 1.0, skip;
            double err = fd_gap_error(gs_gap_eval_quad, same_edge, x0, pts, 7, &g0, h, &skip);
            if (skip) {
                skipped++;
                continue;
            }
            checked++;
            at_vertex += vtx0;
            worst = fmax(worst, err);
        }
    }
    print_message("# quad gap gradients vs central FD (step 1e-6 L): %d points (%d at a joint "
                  "vertex), %d skipped at a switch, max error %.1e (|grad| <= 1)\n",
                  checked, at_vertex, skipped, worst);
    assert_true(worst < 1e-7);
    assert_true(checked > 5000 && at_vertex > 50);
}

/* Continuity across the joints: |g| is the distance to the union of the
 * edges and g changes sign only on them, so g is 1-Lipschitz. Paths along
 * each chain at offsets -0.3 L .. 0.3 L, 20 000 steps each: |dg| <= |dx|
 * at every step (a jump at a change of edge, or a wrong sign at a joint
 * vertex, would break it), and the gradient turns by at most the joint's
 * turn angle per step across a smooth chain's ridge (C1 but for that). */
static void quad_continuity(void **state)
{
    (void)state;
    const double L = 1e-3;
    double worst_lip = 0, worst_turn_smooth = 0;
    int switches = 0;
    for (int kase = 0; kase < 4; kase++) {
        double p[14];
        quad_chain(kase, L, p);
        for (int io = 0; io < 9; io++) {
            double off = (io - 4) * 0.075 * L;
            const int steps = 20000;
            double gp = 0, xp[2] = {0, 0}, np[2] = {0, 0};
            int segp = -1;
            for (int k = 0; k <= steps; k++) {
                /* along the chain: edge e, xi in [0.05, 0.95] of the whole */
                double u = 3.0 * (0.05 + 0.9 * k / steps);
                int e = (int)u < 3 ? (int)u : 2;
                double P[2], n[2];
                quad_point(p, e, u - e, P, n);
                double x[2] = {P[0] + off * n[0], P[1] + off * n[1]};
                gs_gap g;
                assert_int_equal(gs_gap_eval_quad(x, p, 7, &g), GS_OK);
                if (k > 0) {
                    double dx = hypot(x[0] - xp[0], x[1] - xp[1]);
                    worst_lip = fmax(worst_lip, (fabs(g.g - gp) - 1e-15 * L) / dx);
                    if (g.segment != segp)
                        switches++;
                    if (kase < 2) {
                        double c = g.grad[0] * np[0] + g.grad[1] * np[1];
                        worst_turn_smooth = fmax(worst_turn_smooth, acos(fmin(1.0, c)));
                    }
                }
                gp = g.g;
                xp[0] = x[0];
                xp[1] = x[1];
                np[0] = g.grad[0];
                np[1] = g.grad[1];
                segp = g.segment;
            }
        }
    }
    print_message("# quad gap continuity: max |dg| / |dx| = %.9f along 36 paths (%d edge "
                  "switches); smooth chains: gradient turns <= %.1e rad per step\n",
                  worst_lip, switches, worst_turn_smooth);
    assert_true(worst_lip <= 1.0 + 1e-9);
    assert_true(switches >= 36);
    /* a step is 4.5e-4 of the chain (~0.07 mrad of the circle's turn); the
     * joints of parabolas through a circle turn by far less */
    assert_true(worst_turn_smooth < 2e-4);
}

static void scene_xy(const gs_mesh *m, const gs_contact_pose *ps, gs_index nd, double x[2])
{
    double X = m->xy[2 * nd] + (ps->u ? ps->u[2 * nd] : 0);
    double Y = m->xy[2 * nd + 1] + (ps->u ? ps->u[2 * nd + 1] : 0);
    x[0] = ps->c[0] + cos(ps->theta) * X - sin(ps->theta) * Y;
    x[1] = ps->c[1] + sin(ps->theta) * X + cos(ps->theta) * Y;
}

/* Whether node nd is a mid-side node of a quadratic mesh. */
static bool is_mid_node(const gs_mesh *m, gs_index nd)
{
    for (gs_index q = 0; m->mid && q < 3 * m->n_tris; q++)
        if (m->mid[q] == nd)
            return true;
    return false;
}

static double seg_dist(const double x[2], const double a[2], const double b[2])
{
    double d[2] = {b[0] - a[0], b[1] - a[1]}, w[2] = {x[0] - a[0], x[1] - a[1]};
    double t = (w[0] * d[0] + w[1] * d[1]) / (d[0] * d[0] + d[1] * d[1]);
    t = t < 0 ? 0 : (t > 1 ? 1 : t);
    return hypot(w[0] - t * d[0], w[1] - t * d[1]);
}

/* Brute force over the whole boundary loop of mesh mb: distance, and whether
 * x is inside the loop (ray casting). */
static double loop_distance(const gs_mesh *mb, const gs_contact_pose *pb, const double x[2],
                            bool *inside_loop)
{
    double best = INFINITY;
    bool in = false;
    for (gs_index j = 0; j < mb->n_boundary; j++) {
        double a[2], b[2];
        scene_xy(mb, pb, mb->boundary[j], a);
        scene_xy(mb, pb, mb->boundary[(j + 1) % mb->n_boundary], b);
        best = fmin(best, seg_dist(x, a, b));
        if ((a[1] > x[1]) != (b[1] > x[1])) {
            double xc = a[0] + (x[1] - a[1]) / (b[1] - a[1]) * (b[0] - a[0]);
            if (xc > x[0])
                in = !in;
        }
    }
    *inside_loop = in;
    return best;
}

typedef struct pair_case {
    const char *name;
    gs_gear_params g[2];
    double a;
    double gamma;   /* direction of the line of centres */
    int positions;
    int order;      /* element order of both meshes (0 = 1) */
} pair_case;

static gs_mesh *mesh_order(const gs_gear_params *p, int order)
{
    if (order < 2)
        return mesh_of(p, 0);
    gs_gear_mesh_opts o;
    gs_gear_mesh_opts_defaults(&o);
    o.order = 2;
    gs_mesh *m = NULL;
    assert_int_equal(gs_gear_mesh(p, &o, &m, NULL), GS_OK);
    return m;
}

static void run_pair(const pair_case *pc)
{
    gs_mesh *m[2] = {mesh_order(&pc->g[0], pc->order), mesh_order(&pc->g[1], pc->order)};
    /* order 2: the brute-force inside test below is of the polyline through
     * corner and mid-side nodes, the gap of the parabolic edges; they may
     * disagree within the chords' sagitta (~1 um here) */
    const double sign_tol = pc->order == 2 ? 1e-5 : 1e-9;
    gs_pair_info info;
    gs_diag d;
    assert_int_equal(gs_pair_analyse(&pc->g[0], &pc->g[1], pc->a, &info, &d), GS_OK);
    gs_contact_search *s = NULL;
    assert_int_equal(gs_contact_search_new(m[0], &pc->g[0], m[1], &pc->g[1], NULL, &s, &d), GS_OK);
    const double mod = pc->g[0].module_m, thr = 0.05 * mod;
    gs_contact_pose pose[2];
    memset(pose, 0, sizeof pose);
    /* gear 1 (wheel or ring) at the origin, gear 0 at distance a */
    pose[0].c[0] = pc->a * cos(pc->gamma);
    pose[0].c[1] = pc->a * sin(pc->gamma);
    gs_index flank_nodes = m[0]->flank_ptr[2 * m[0]->n_teeth] + m[1]->flank_ptr[2 * m[1]->n_teeth];
    gs_index cmin = 1 << 30, cmax = 0, brute_max = 0, tested_max = 0, total_brute = 0;
    int teeth_max[2] = {0, 0};
    double worst_tooth_off = 0, worst_beyond_lens = -INFINITY, worst_sign_dist = 0, tmax = 0;
    int sign_checks = 0;
    double times[64];
    for (int ip = 0; ip < pc->positions; ip++) {
        double pitch0 = 2 * GS_PI / pc->g[0].teeth;
        pose[0].theta = 0.37 + pitch0 * ip / pc->positions;
        pose[1].theta = gs_pair_mesh_phase(&pc->g[0], pose[0].c, pose[0].theta, &pc->g[1],
                                           pose[1].c, 0.0);
        const gs_contact_candidate *cand;
        gs_index n;
        gs_contact_stats st;
        double t0 = gs_now();
        assert_int_equal(gs_contact_search_run(s, pose, &cand, &n, &st), GS_OK);
        times[ip < 64 ? ip : 63] = gs_now() - t0;
        cmin = n < cmin ? n : cmin;
        cmax = n > cmax ? n : cmax;
        tested_max = st.nodes_tested > tested_max ? st.nodes_tested : tested_max;
        /* the candidate teeth are those around the pitch point */
        for (int A = 0; A < 2; A++) {
            teeth_max[A] = st.n_teeth[A] > teeth_max[A] ? st.n_teeth[A] : teeth_max[A];
            double pa = atan2(st.pitch_point[1] - pose[A].c[1], st.pitch_point[0] - pose[A].c[0]);
            double pitch = 2 * GS_PI / pc->g[A].teeth;
            /* the lens of the two tip circles: its corner I (intersection
             * of the circles) seen from A's centre, in pitches of A */
            double ex = pose[1 - A].c[0] - pose[A].c[0], ey = pose[1 - A].c[1] - pose[A].c[1];
            double dd = hypot(ex, ey), ra = gs_gear_tip_radius(&pc->g[A]);
            double rb = gs_gear_tip_radius(&pc->g[1 - A]);
            double xi = (ra * ra - rb * rb + dd * dd) / (2 * dd), yi = sqrt(ra * ra - xi * xi);
            double lens = fabs(atan2(yi, xi) - atan2(sin(pa - atan2(ey, ex)),
                                                     cos(pa - atan2(ey, ex)))) / pitch;
            for (int k = 0; k < st.n_teeth[A] && k < 16; k++) {
                double ta = pose[A].theta + pitch * st.teeth[A][k];
                double off = fabs(atan2(sin(ta - pa), cos(ta - pa))) / pitch;
                worst_tooth_off = fmax(worst_tooth_off, off);
                worst_beyond_lens = fmax(worst_beyond_lens, off - lens);
            }
        }
        /* brute force: every flank node within thr of the other boundary is a
         * candidate */
        gs_index brute = 0;
        for (int A = 0; A < 2; A++) {
            const gs_mesh *ma = m[A];
            for (gs_index q = 0; q < ma->flank_ptr[2 * ma->n_teeth]; q++) {
                gs_index nd = ma->flank_nodes[q];
                double x[2];
                bool in;
                scene_xy(ma, &pose[A], nd, x);
                double dist = loop_distance(m[1 - A], &pose[1 - A], x, &in);
                if (dist > thr)
                    continue;
                brute++;
                bool found = false;
                for (gs_index c = 0; c < n && !found; c++)
                    found = cand[c].slave == A && cand[c].slave_node == nd;
                if (!found)
                    print_message("# MISSING: gear %d node %lld at distance %.3e m\n", A,
                                  (long long)nd, dist);
                assert_true(found);
            }
        }
        total_brute += brute;
        brute_max = brute > brute_max ? brute : brute_max;
        /* every candidate: the gap has the sign of the brute-force inside test
         * (material inside the loop for an external gear, outside for a ring) */
        for (gs_index c = 0; c < n; c++) {
            const gs_contact_candidate *cc = &cand[c];
            double x[2];
            bool in;
            scene_xy(m[cc->slave], &pose[cc->slave], cc->slave_node, x);
            double dist = loop_distance(m[cc->master], &pose[cc->master], x, &in);
            bool material = pc->g[cc->master].kind == GS_GEAR_INTERNAL ? !in : in;
            gs_contact_row row;
            assert_int_equal(gs_contact_eval(s, pose, cc, &row), GS_OK);
            /* the search evaluates the gap beyond the band only (NAN within) */
            assert_true(isnan(cc->gap) ? cc->distance <= 0.1 * fmin(pc->g[0].module_m, pc->g[1].module_m) * (1 + 1e-12)
                                       : fabs(row.gap.g - cc->gap) <= 1e-15 + 1e-9 * fabs(cc->gap));
            if (pc->order == 2) {
                /* whole parabolic edges: corners at even window positions */
                assert_int_equal(row.gap.kind, GS_GAP_PARABOLA);
                for (int q = 0; q < cc->n_window; q++)
                    assert_int_equal(is_mid_node(m[cc->master], cc->window[q]), q % 2 == 1);
            }
            assert_true(fabs(cc->distance - dist) <= 1e-12);
            if (dist > sign_tol) {
                sign_checks++;
                assert_true(material ? row.gap.g < 0 : row.gap.g > 0);
            } else {
                worst_sign_dist = fmax(worst_sign_dist, fabs(row.gap.g));
            }
        }
        /* determinism */
        gs_contact_candidate *copy = malloc((size_t)n * sizeof *copy);
        memcpy(copy, cand, (size_t)n * sizeof *copy);
        gs_index n2;
        assert_int_equal(gs_contact_search_run(s, pose, &cand, &n2, NULL), GS_OK);
        assert_int_equal(n2, n);
        assert_int_equal(memcmp(copy, cand, (size_t)n * sizeof *copy), 0);
        free(copy);
    }
    /* median search time (the machine is shared: the maximum is noise) */
    int nt = pc->positions < 64 ? pc->positions : 64;
    for (int i = 1; i < nt; i++)
        for (int j = i; j > 0 && times[j - 1] > times[j]; j--) {
            double t = times[j];
            times[j] = times[j - 1];
            times[j - 1] = t;
        }
    tmax = times[nt / 2];
    print_message("# %s: a = %.4g mm, contact ratio %.3f (tips %.3f); %d mesh positions over "
                  "one pitch: candidate teeth <= %d + %d, farthest %.2f pitches from the pitch "
                  "point, %.2f beyond the corner of the tip circles' lens; nodes measured <= %lld of %lld flank nodes; candidates %lld..%lld; brute "
                  "force (flank nodes within 0.05 m) mean %lld, max %lld per position, all found; %d "
                  "gap signs checked (touching: |g| <= %.1e m); median search %.0f us\n",
                  pc->name, pc->a * 1e3, info.contact_ratio, info.contact_ratio_tips,
                  pc->positions, teeth_max[0], teeth_max[1], worst_tooth_off, worst_beyond_lens,
                  (long long)tested_max, (long long)flank_nodes, (long long)cmin,
                  (long long)cmax, (long long)(total_brute / pc->positions),
                  (long long)brute_max, sign_checks, worst_sign_dist, tmax * 1e6);
    /* small: a few teeth, a small share of the flank nodes */
    assert_true(cmax > 0 && cmax < flank_nodes / 4);
    assert_true(total_brute > 0);
    /* teeth near the pitch point: a tooth can touch only inside the lens
     * where the two tip circles overlap; its centre lies at most half a
     * pitch (its own width) plus the band beyond the lens corner */
    assert_true(worst_beyond_lens <= 0.75);
    gs_contact_search_free(&s);
    assert_null(s);
    gs_mesh_free(&m[0]);
    gs_mesh_free(&m[1]);
}

static void search_external(void **state)
{
    (void)state;
    pair_case pc = {.name = "external 20/30 m 2.5", .a = 62.5e-3, .gamma = 0.3, .positions = 12};
    pc.g[0] = gear(GS_GEAR_EXTERNAL, 20, 2.5e-3, 0);
    pc.g[1] = gear(GS_GEAR_EXTERNAL, 30, 2.5e-3, 0);
    run_pair(&pc);
}

static void search_external_quad(void **state)
{
    (void)state;
    pair_case pc = {.name = "external 20/30 m 2.5, order 2", .a = 62.5e-3, .gamma = 0.3,
                    .positions = 6, .order = 2};
    pc.g[0] = gear(GS_GEAR_EXTERNAL, 20, 2.5e-3, 0);
    pc.g[1] = gear(GS_GEAR_EXTERNAL, 30, 2.5e-3, 0);
    run_pair(&pc);
}

static void search_internal_quad(void **state)
{
    (void)state;
    pair_case pc = {.name = "internal 24 in 72 m 2.5, order 2", .a = 60e-3, .gamma = -1.1,
                    .positions = 6, .order = 2};
    pc.g[0] = gear(GS_GEAR_EXTERNAL, 24, 2.5e-3, 0);
    pc.g[1] = gear(GS_GEAR_INTERNAL, 72, 2.5e-3, 0);
    pc.g[1].addendum_coef = 0.8;
    run_pair(&pc);
}

static void search_internal(void **state)
{
    (void)state;
    pair_case pc = {.name = "internal 24 in 72 m 2.5", .a = 60e-3, .gamma = -1.1, .positions = 12};
    pc.g[0] = gear(GS_GEAR_EXTERNAL, 24, 2.5e-3, 0);
    pc.g[1] = gear(GS_GEAR_INTERNAL, 72, 2.5e-3, 0);
    pc.g[1].addendum_coef = 0.8;
    run_pair(&pc);
}

/* A high contact ratio pair (long addendum, 40/60): more teeth in mesh at
 * once; the tooth selection follows the lens of the tip circles, so no
 * contact ratio is assumed. */
static void search_high_ratio(void **state)
{
    (void)state;
    pair_case pc = {.name = "high ratio 40/60 m 2.5 h_a* 1.3", .a = 125e-3, .gamma = 2.0,
                    .positions = 8};
    pc.g[0] = gear(GS_GEAR_EXTERNAL, 40, 2.5e-3, 0);
    pc.g[1] = gear(GS_GEAR_EXTERNAL, 60, 2.5e-3, 0);
    for (int i = 0; i < 2; i++) {
        pc.g[i].addendum_coef = 1.3;
        pc.g[i].dedendum_coef = 1.55;
        pc.g[i].fillet_coef = 0.25;
    }
    run_pair(&pc);
}

/* The chained gradients of gs_contact_eval w.r.t. theta, c and du of every
 * node used, on candidates of the 20/30 pair with displacements. */
static void chained_gradients_order(int order)
{
    gs_gear_params g[2] = {gear(GS_GEAR_EXTERNAL, 20, 2.5e-3, 0),
                           gear(GS_GEAR_EXTERNAL, 30, 2.5e-3, 0)};
    gs_mesh *m[2] = {mesh_order(&g[0], order), mesh_order(&g[1], order)};
    gs_contact_search *s = NULL;
    assert_int_equal(gs_contact_search_new(m[0], &g[0], m[1], &g[1], NULL, &s, NULL), GS_OK);
    double *u[2];
    for (int b = 0; b < 2; b++) {
        u[b] = malloc((size_t)(2 * m[b]->n_nodes) * sizeof *u[b]);
        for (gs_index k = 0; k < 2 * m[b]->n_nodes; k++)
            u[b][k] = 2e-6 * sin(0.7 * (double)k + b);
    }
    gs_contact_pose pose[2];
    memset(pose, 0, sizeof pose);
    pose[0].c[0] = 0.01;
    pose[0].c[1] = -0.02;
    pose[1].c[0] = pose[0].c[0] + 62.5e-3 * cos(0.3);
    pose[1].c[1] = pose[0].c[1] + 62.5e-3 * sin(0.3);
    pose[0].theta = 0.2;
    pose[1].theta = gs_pair_mesh_phase(&g[0], pose[0].c, pose[0].theta, &g[1], pose[1].c, 0);
    pose[0].u = u[0];
    pose[1].u = u[1];
    const gs_contact_candidate *cand;
    gs_index n;
    assert_int_equal(gs_contact_search_run(s, pose, &cand, &n, NULL), GS_OK);
    assert_true(n > 0);
    gs_contact_candidate *cs = malloc((size_t)n * sizeof *cs);
    memcpy(cs, cand, (size_t)n * sizeof *cs);
    const double mod = 2.5e-3, hu = 1e-6 * mod;
    double worst = 0;
    int checked = 0, skipped = 0, wedges = 0;
    for (gs_index c = 0; c < n; c++) {
        gs_contact_row r0;
        assert_int_equal(gs_contact_eval(s, pose, &cs[c], &r0), GS_OK);
        /* unknowns: theta, c_x, c_y of each body; du of each node used */
        int nunk = 6 + 2 * r0.n_nodes;
        bool skip = false;
        double err = 0;
        for (int q = 0; q < nunk && !skip; q++) {
            double v[2], an, scale;
            for (int sg = 0; sg < 2; sg++) {
                gs_contact_pose p[2] = {pose[0], pose[1]};
                double dl = sg ? -1.0 : 1.0;
                gs_index nd = -1;
                int b = -1, comp = 0;
                if (q < 6) {
                    b = q / 3;
                    if (q % 3 == 0)
                        p[b].theta += dl * hu / 0.03;
                    else
                        p[b].c[q % 3 - 1] += dl * hu;
                } else {
                    int j = (q - 6) / 2;
                    b = r0.body[j];
                    nd = r0.node[j];
                    comp = (q - 6) % 2;
                    u[b][2 * nd + comp] += dl * hu;
                }
                gs_contact_row r1;
                assert_int_equal(gs_contact_eval(s, p, &cs[c], &r1), GS_OK);
                if (nd >= 0)
                    u[b][2 * nd + comp] -= dl * hu;
                if (r1.gap.segment != r0.gap.segment || r1.gap.n_master != r0.gap.n_master ||
                    (r1.gap.blend > 0) != (r0.gap.blend > 0) ||
                    (r1.gap.blend < 1) != (r0.gap.blend < 1) ||
                    (r1.gap.xi <= 0.0) != (r0.gap.xi <= 0.0) ||
                    (r1.gap.xi >= 1.0) != (r0.gap.xi >= 1.0))
                    skip = true;
                v[sg] = r1.gap.g;
            }
            if (q < 6) {
                int b = q / 3;
                an = q % 3 == 0 ? r0.dg_dtheta[b] : r0.dg_dc[b][q % 3 - 1];
                double h = q % 3 == 0 ? hu / 0.03 : hu;
                scale = q % 3 == 0 ? 0.05 : 1.0; /* dg/dtheta ~ radius */
                err = fmax(err, fabs((v[0] - v[1]) / (2 * h) - an) / scale);
            } else {
                int j = (q - 6) / 2;
                an = r0.dg_du[j][(q - 6) % 2];
                err = fmax(err, fabs((v[0] - v[1]) / (2 * hu) - an));
            }
        }
        /* duplicate nodes would be summed wrongly by a collector: none */
        for (int i = 0; i < r0.n_nodes; i++)
            for (int j = i + 1; j < r0.n_nodes; j++)
                assert_false(r0.body[i] == r0.body[j] && r0.node[i] == r0.node[j]);
        if (skip) {
            skipped++;
            continue;
        }
        checked++;
        wedges += r0.gap.kind != GS_GAP_LINE;
        worst = fmax(worst, err);
    }
    print_message("# chained gradients, order %d (theta, c, du) vs central FD (du step 1e-6 m, "
                  "theta step 1e-6 m / 30 mm): %d candidates (%d with a wedge or parabola), %d "
                  "skipped, max error %.1e (relative to 1, and to 50 mm for theta)\n",
                  order < 2 ? 1 : 2, checked, wedges, skipped, worst);
    assert_true(worst < 1e-6);
    assert_true(checked > 10);
    free(cs);
    free(u[0]);
    free(u[1]);
    gs_contact_search_free(&s);
    gs_mesh_free(&m[0]);
    gs_mesh_free(&m[1]);
}

static void chained_gradients(void **state)
{
    (void)state;
    chained_gradients_order(1);
}

static void chained_gradients_quad(void **state)
{
    (void)state;
    chained_gradients_order(2);
}

static void search_errors(void **state)
{
    (void)state;
    gs_gear_params g[2] = {gear(GS_GEAR_EXTERNAL, 20, 2.5e-3, 0),
                           gear(GS_GEAR_EXTERNAL, 30, 2.5e-3, 0)};
    gs_mesh *m[2] = {mesh_of(&g[0], 0), mesh_of(&g[1], 0)};
    gs_contact_search *s = NULL;
    gs_diag d;
    gs_contact_opts o;
    gs_contact_opts_defaults(&o);
    o.window = 4;
    assert_int_equal(gs_contact_search_new(m[0], &g[0], m[1], &g[1], &o, &s, &d), GS_ERANGE);
    assert_string_equal(d.field, "contact.window");
    assert_null(s);
    gs_mesh *rect = NULL;
    assert_int_equal(gs_mesh_rectangle(0.01, 0.002, 4, 2, &rect), GS_OK);
    assert_int_equal(gs_contact_search_new(rect, &g[0], m[1], &g[1], NULL, &s, &d), GS_EINVAL);
    assert_string_equal(d.field, "mesh");
    /* mesh of the wrong gear */
    assert_int_equal(gs_contact_search_new(m[1], &g[0], m[1], &g[1], NULL, &s, &d), GS_EINVAL);
    assert_int_equal(gs_contact_search_new(m[0], &g[0], m[1], &g[1], NULL, &s, &d), GS_OK);
    gs_contact_pose pose[2];
    memset(pose, 0, sizeof pose);
    const gs_contact_candidate *c;
    gs_index n;
    assert_int_equal(gs_contact_search_run(s, pose, &c, &n, NULL), GS_EINVAL); /* same centre */
    pose[1].c[0] = 0.0625;
    pose[0].theta = NAN;
    assert_int_equal(gs_contact_search_run(s, pose, &c, &n, NULL), GS_EINVAL);
    /* far apart: nothing */
    pose[0].theta = 0;
    pose[1].c[0] = 1.0;
    assert_int_equal(gs_contact_search_run(s, pose, &c, &n, NULL), GS_OK);
    assert_int_equal(n, 0);
    gs_contact_search_free(&s);
    gs_contact_search_free(&s); /* safe twice */
    gs_mesh_free(&rect);
    gs_mesh_free(&m[0]);
    gs_mesh_free(&m[1]);
}

/* One pass: the finer gear's flanks are slaves, corners of both. */
static void one_pass(void **state)
{
    (void)state;
    gs_gear_params g[2] = {gear(GS_GEAR_EXTERNAL, 20, 2.5e-3, 0),
                           gear(GS_GEAR_EXTERNAL, 30, 2.5e-3, 0)};
    gs_mesh *m[2] = {mesh_of(&g[0], 0), mesh_of(&g[1], 0)};
    gs_contact_opts o;
    gs_contact_opts_defaults(&o);
    gs_contact_search *s2 = NULL, *s1 = NULL;
    assert_int_equal(gs_contact_search_new(m[0], &g[0], m[1], &g[1], &o, &s2, NULL), GS_OK);
    o.passes = GS_CONTACT_ONE_PASS;
    assert_int_equal(gs_contact_search_new(m[0], &g[0], m[1], &g[1], &o, &s1, NULL), GS_OK);
    gs_contact_pose pose[2];
    memset(pose, 0, sizeof pose);
    pose[1].c[0] = 62.5e-3;
    pose[0].theta = 0.1;
    pose[1].theta = gs_pair_mesh_phase(&g[0], pose[0].c, pose[0].theta, &g[1], pose[1].c, 0);
    const gs_contact_candidate *c;
    gs_index n1, n2;
    assert_int_equal(gs_contact_search_run(s2, pose, &c, &n2, NULL), GS_OK);
    assert_int_equal(gs_contact_search_run(s1, pose, &c, &n1, NULL), GS_OK);
    int flank_slaves_1 = 0;
    for (gs_index k = 0; k < n1; k++) {
        const gs_mesh *ms = m[c[k].slave];
        gs_index nd = c[k].slave_node;
        bool corner = ms->node_tag[nd] == GS_NODE_TIP;
        for (int t = 0; t < 2 * ms->n_teeth && !corner; t++)
            corner = ms->flank_nodes[ms->flank_ptr[t + 1] - 1] == nd;
        if (!corner) {
            assert_int_equal(c[k].slave, 0); /* 20 teeth: the finer flank spacing */
            flank_slaves_1++;
        }
    }
    print_message("# one pass: %lld candidates (%d flank slaves, all on the pinion) against %lld "
                  "with two passes\n",
                  (long long)n1, flank_slaves_1, (long long)n2);
    assert_true(n1 < n2 && flank_slaves_1 > 0);
    gs_contact_search_free(&s1);
    gs_contact_search_free(&s2);
    gs_mesh_free(&m[0]);
    gs_mesh_free(&m[1]);
}

/* fan_corner of gs_contact_eval against brute force: for a flank slave
 * (not a tip corner, not a tip arc node) outside the master, the master's
 * nearest point over the whole boundary loop (order 2: the parabolic edges
 * sampled at 2000 points each, the nodes exactly) is one of its tip
 * corners (the last node of a flank table: that corner expected) or lies
 * on an edge of its tip land (either end expected).
 * Pairs within 1e-9 m of a tie between the corner and another point are
 * not judged. Both element orders, 24 positions over a pitch. */
static void corner_fan_order(int order)
{
    gs_gear_params g[2] = {gear(GS_GEAR_EXTERNAL, 20, 2.5e-3, 0),
                           gear(GS_GEAR_EXTERNAL, 30, 2.5e-3, 0)};
    gs_mesh *m[2] = {mesh_order(&g[0], order), mesh_order(&g[1], order)};
    gs_contact_search *s = NULL;
    assert_int_equal(gs_contact_search_new(m[0], &g[0], m[1], &g[1], NULL, &s, NULL), GS_OK);
    int fan = 0, agree = 0, ties = 0, total = 0;
    for (int pos = 0; pos < 24; pos++) {
        gs_contact_pose pose[2];
        memset(pose, 0, sizeof pose);
        pose[1].c[0] = 62.5e-3;
        pose[0].theta = 2 * GS_PI / 20 * pos / 24.0;
        pose[1].theta = gs_pair_mesh_phase(&g[0], pose[0].c, pose[0].theta, &g[1], pose[1].c, 0);
        const gs_contact_candidate *c;
        gs_index n;
        assert_int_equal(gs_contact_search_run(s, pose, &c, &n, NULL), GS_OK);
        for (gs_index k = 0; k < n; k++) {
            gs_contact_row r;
            assert_int_equal(gs_contact_eval(s, pose, &c[k], &r), GS_OK);
            const gs_mesh *mb = m[c[k].master];
            const gs_contact_pose *pb = &pose[c[k].master];
            double x[2];
            scene_xy(m[c[k].slave], &pose[c[k].slave], c[k].slave_node, x);
            /* nearest boundary point: nodes exactly, edges sampled */
            double best = INFINITY, bestnode = INFINITY;
            gs_index bn = -1, be0 = -1, be1 = -1;
            int step = order == 2 ? 2 : 1;
            for (gs_index j = 0; j < mb->n_boundary; j++) {
                double a[2];
                scene_xy(mb, pb, mb->boundary[j], a);
                double dn = hypot(x[0] - a[0], x[1] - a[1]);
                if (dn < bestnode) {
                    bestnode = dn;
                    bn = mb->boundary[j];
                }
            }
            for (gs_index j = 0; j < mb->n_boundary; j += step) {
                double p[3][2];
                for (int q = 0; q <= step; q++)
                    scene_xy(mb, pb, mb->boundary[(j + q) % mb->n_boundary], p[q]);
                double dj = INFINITY;
                if (order < 2)
                    dj = seg_dist(x, p[0], p[1]);
                for (int t = 1; order == 2 && t < 2000; t++) {
                    double xi = t / 2000.0, N0 = (1 - xi) * (1 - 2 * xi), N1 = 4 * xi * (1 - xi),
                           N2 = xi * (2 * xi - 1);
                    double P[2] = {N0 * p[0][0] + N1 * p[1][0] + N2 * p[2][0],
                                   N0 * p[0][1] + N1 * p[1][1] + N2 * p[2][1]};
                    dj = fmin(dj, hypot(x[0] - P[0], x[1] - P[1]));
                }
                if (dj < best) {
                    best = dj;
                    be0 = mb->boundary[j];
                    be1 = mb->boundary[(j + step) % mb->n_boundary];
                }
            }
            bool tipc = false, tip0 = false, tip1 = false, slave_tip = c[k].slave_where == 2;
            const gs_mesh *ms = m[c[k].slave];
            for (int f = 0; f < 2 * mb->n_teeth; f++) {
                gs_index tn = mb->flank_nodes[mb->flank_ptr[f + 1] - 1];
                tipc |= tn == bn;
                tip0 |= tn == be0;
                tip1 |= tn == be1;
            }
            for (int f = 0; f < 2 * ms->n_teeth; f++)
                slave_tip |= ms->flank_nodes[ms->flank_ptr[f + 1] - 1] == c[k].slave_node;
            tip0 |= mb->node_tag[be0] == GS_NODE_TIP;
            tip1 |= mb->node_tag[be1] == GS_NODE_TIP;
            total++;
            double diff = bestnode - best; /* > 0: some edge point is nearer than every node */
            if (diff > 1e-12 && diff < 1e-9) {
                ties++;
                continue;
            }
            /* (b) the corner's normal cone; (a) beside the tip land */
            bool at_corner = tipc && diff <= 1e-12, land = diff > 0 && tip0 && tip1;
            bool expect = !slave_tip && r.gap.g > 0 && (at_corner || land);
            fan += expect;
            bool ok = !expect ? r.fan_corner < 0
                              : (at_corner ? r.fan_corner == bn : r.fan_corner == be0 || r.fan_corner == be1);
            if (ok)
                agree++;
            else
                print_error("position %d candidate %lld: fan_corner %lld, brute force %s (node %lld, g %.3e)\n", pos,
                            (long long)k, (long long)r.fan_corner, expect ? "fan" : "none", (long long)bn, r.gap.g);
        }
    }
    print_message("# tip-corner fans, order %d: %d candidates over 24 positions, %d in a tip corner's fan or beside a tip land, %d agree "
                  "with brute force, %d ties not judged\n",
                  order, total, fan, agree, ties);
    assert_int_equal(agree, total - ties);
    assert_true(fan > 0);
    gs_contact_search_free(&s);
    gs_mesh_free(&m[0]);
    gs_mesh_free(&m[1]);
}

static void corner_fan(void **state)
{
    (void)state;
    corner_fan_order(1);
    corner_fan_order(2);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(primitive_gradients),
        cmocka_unit_test(zero_set_and_sign),
        cmocka_unit_test(sign_errors),
        cmocka_unit_test(eval_gradients),
        cmocka_unit_test(continuity),
        cmocka_unit_test(search_external),
        cmocka_unit_test(search_internal),
        cmocka_unit_test(search_high_ratio),
        cmocka_unit_test(chained_gradients),
        cmocka_unit_test(chained_gradients_quad),
        cmocka_unit_test(search_external_quad),
        cmocka_unit_test(search_internal_quad),
        cmocka_unit_test(quad_zero_set_and_sign),
        cmocka_unit_test(quad_gradients),
        cmocka_unit_test(quad_continuity),
        cmocka_unit_test(search_errors),
        cmocka_unit_test(one_pass),
        cmocka_unit_test(corner_fan),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
