/* SPDX-License-Identifier: MIT
 * gearsim: conforming linear-triangle meshes of the elastic part of a gear
 * (docs/GEOMETRY.md, "Meshes").
 *
 * One tooth sector (from the middle of one space to the middle of the next)
 * is meshed once, in the frame of tooth 0, as four blocks, each filled row
 * by row (rows placed by transfinite interpolation of the block's sides,
 * consecutive rows joined by a zipper, so a row may have more or fewer
 * elements than the next):
 *
 *   T   the tooth above the chord joining its two form points: `flank`
 *       rows along the flanks, `across` elements at the chord, fewer
 *       towards a narrower tip;
 *   R   under T, down to the band circle R0 (`rim` graded layers below the
 *       root circle plus layers for the fillet's height);
 *   S+- the two space sides, meshed sideways: rows from R0 up to the
 *       fillet and root arc, from the R/S interface to the space centre
 *       line (`rim` layers).
 *
 * The sector is then copied round the gear (nodes on the sector sides and
 * their order shared), and the region between the band circle and the hub
 * (or, for a ring, the outer rim) is filled with concentric rings whose
 * node count may halve from one ring to the next, each pair of rings joined
 * by a zipper. Sizes: uniform in arc length along a flank; across a tooth
 * and down the band graded so the smallest elements sit at the flanks and
 * the root (where teeth touch and bend); the rings grow geometrically away
 * from the teeth. Poor elements are then smoothed (interior nodes only).
 * Refinement multiplies every count by
 * 2^refine with all boundary nodes of the coarser mesh kept (nested).
 * Local refinement (fine_teeth) builds some sectors from finer plans, graded
 * one level per tooth, the coarser of two neighbours taking the finer one's
 * count on their shared side, and splits the rings' intervals under them. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/mesh.h"
#include "gearsim/util.h"
#include "mesh/mesh_internal.h"

/* ------------------------------------------------------------------------ */
/* Growable node and triangle lists                                         */
/* ------------------------------------------------------------------------ */

typedef struct {
    double *xy;
    signed char *tag;
    gs_index n, cap;
} nodes_t;

typedef struct {
    gs_index *t;
    gs_index n;
    size_t cap;
} tris_t;

static gs_index node_add(nodes_t *nb, double x, double y, int tag)
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

static int tri_add(tris_t *tb, gs_index a, gs_index b, gs_index c)
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
static double tri_shape(const double *xy, gs_index a, gs_index b, gs_index c)
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
static double grade_both(double u, double g)
{
    if (g <= 1.0 + 1e-12)
        return u;
    double dl = acosh(sqrt(g));
    return 0.5 * (1.0 + tanh(dl * (2.0 * u - 1.0)) / tanh(dl));
}

/* Smallest steps at u = 1; largest / smallest = g. */
static double grade_top(double u, double g)
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
 * joined by a zipper (two rows of different counts is what lets a block
 * change its resolution: a tooth narrowing to its tip, a fillet finer than
 * the rim below it). */
static int layered_block(nodes_t *nb, tris_t *tb, int nrow, const int *cnt, const gs_index *bot,
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
                rn[i] = node_add(nb, P[0], P[1], GS_NODE_INTERIOR);
                if (rn[i] < 0)
                    goto out;
                xn[i] = xi;
            }
        }
        /* zipper rows (ra, xa, cnt[j-1]) and (rn, xn, n) by parameter */
        int i = 0, k = 0, na_ = cnt[j - 1];
        while (i < na_ || k < n) {
            int adv_lo = i == na_ ? 0 : k == n ? 1 : xa[i] + xa[i + 1] < xn[k] + xn[k + 1];
            int r;
            if (adv_lo) {
                r = ccw ? tri_add(tb, ra[i], ra[i + 1], rn[k]) : tri_add(tb, ra[i + 1], ra[i], rn[k]);
                i++;
            } else {
                r = ccw ? tri_add(tb, rn[k + 1], rn[k], ra[i]) : tri_add(tb, rn[k], rn[k + 1], ra[i]);
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

/* ------------------------------------------------------------------------ */
/* The sector template                                                      */
/* ------------------------------------------------------------------------ */

typedef struct {
    nodes_t nd;
    tris_t tr;
    int nleft, nright;      /* nodes on each sector side (rim + 1 at the sector's refinement,
                             * or at its fine neighbour's: local refinement) */
    gs_index *left, *right; /* sector sides from R0 to the space centre */
    int nbot;
    gs_index *bottom;       /* R0 arc from -pi/z to +pi/z */
    int nflank;
    gs_index *flank_cw, *flank_ccw; /* form point -> tip corner */
    int nbnd;
    gs_index *bnd;          /* profile from S- to S+, both included */
} sector_t;

static void sector_free(sector_t *s)
{
    free(s->nd.xy);
    free(s->nd.tag);
    free(s->tr.t);
    free(s->left);
    free(s->right);
    free(s->bottom);
    free(s->flank_cw);
    free(s->flank_ccw);
    free(s->bnd);
}

/* Counts and shapes fixed at refine 0 (so that refinement is nested). */
typedef struct {
    int nf, na, nr, ns;           /* at the requested refinement; nr = all layers of R, S */
    int nband;                    /* layers of nr in the band below the root circle */
    double fband;                 /* fraction of the R/S interface taken by the band */
    int ntip;                     /* elements on the tip arc */
    double gtip;                  /* flank steps shrink towards a thin tip by this ratio */
    int nrb;                      /* elements on the band circle under R (under each S: ns) */
    double grading;
    double R0;                    /* band circle */
    double psiB;                  /* angle of the R/S block corner on R0 */
    double lfil;                  /* fillet length */
    double tfil[1025], sfil[1025];/* fillet parameter vs arc length fraction */
    double fR[1025], fpsi[1025];  /* fillet samples: radius and polar angle */
} plan_t;

static double fillet_t_at(const plan_t *pl, double frac)
{
    /* invert the monotone table sfil(tfil) */
    int lo = 0, hi = 1024;
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (pl->sfil[mid] <= frac)
            lo = mid;
        else
            hi = mid;
    }
    double den = pl->sfil[hi] - pl->sfil[lo];
    double w = den > 0 ? (frac - pl->sfil[lo]) / den : 0.0;
    return pl->tfil[lo] + w * (pl->tfil[hi] - pl->tfil[lo]);
}

/* Smallest polar angle of the fillet between radius R and the form point
 * (the fillet part "above" R, seen from the rim). */
static double fillet_envelope(const plan_t *pl, const gs_gear_geom *g, double R)
{
    double env = g->psi_form;
    for (int i = 0; i <= 1024; i++) {
        int above = g->internal ? pl->fR[i] <= R : pl->fR[i] >= R;
        if (above && pl->fpsi[i] < env)
            env = pl->fpsi[i];
    }
    return env;
}

static gs_err make_plan(const gs_gear_geom *g, const gs_gear_mesh_opts *o, plan_t *pl, gs_diag *d)
{
    const int L = 1 << o->refine;
    double m = g->m;
    /* Fillet arc-length table (dense polyline; the nodes themselves are
     * evaluated exactly on the curve). */
    double P[2], T[2], Q[2];
    gs_gear_fillet_point(g, 0.0, Q, T);
    pl->tfil[0] = 0.0;
    pl->sfil[0] = 0.0;
    for (int i = 1; i <= 1024; i++) {
        pl->tfil[i] = i / 1024.0;
        gs_gear_fillet_point(g, pl->tfil[i], P, T);
        pl->sfil[i] = pl->sfil[i - 1] + hypot(P[0] - Q[0], P[1] - Q[1]);
        Q[0] = P[0];
        Q[1] = P[1];
    }
    pl->lfil = pl->sfil[1024];
    for (int i = 0; i <= 1024; i++) {
        gs_gear_fillet_point(g, pl->tfil[i], P, T);
        pl->fR[i] = hypot(P[0], P[1]);
        pl->fpsi[i] = atan2(P[1], P[0]);
    }
    for (int i = 1; i <= 1024; i++)
        pl->sfil[i] /= pl->lfil;
    double rb = g->rb;
    double lflank = fabs(g->ra * g->ra - g->r_form * g->r_form) / (2.0 * rb);
    /* Reference element size at the surface: the flank's share, but not
     * below half the tooth height's (an undercut can leave a short involute). */
    double h = fmax(lflank, 0.5 * fabs(g->ra - g->rf)) / o->flank;
    /* Fillet and root arc are meshed as one curve, uniformly in arc length
     * (nodes exactly on whichever piece they fall); the root arc alone is
     * often a sliver (0.06 m for the standard rack). */
    double lroot = g->rf * (g->half_pitch - g->psi_root);
    int ns0 = (int)lround((pl->lfil + lroot) / h);
    pl->nf = o->flank * L;
    pl->na = o->across * L;
    /* R and S reach from the band circle up to the form radius: the band
     * gets `rim` layers, the height of the fillet as many more as fit at
     * the flank's element size. */
    int nx0 = (int)lround(fabs(g->r_form - g->rf) / h);
    pl->nband = o->rim * L;
    pl->nr = (o->rim + nx0) * L;
    pl->ns = (ns0 < 2 ? 2 : ns0) * L;
    pl->grading = o->grading;
    /* Band under the teeth: about a module and a quarter deep, or the whole
     * rim when what would be left is thin. */
    double rim = g->internal ? g->hub - g->rf : g->rf - g->hub;
    double tb = fmin(rim, 1.25 * m);
    if (rim - tb < 0.75 * tb)
        tb = rim;
    pl->R0 = tb == rim ? g->hub : g->internal ? g->rf + tb : g->rf - tb;
    /* Corner B of the under-tooth block on R0: the line B-F bisects the
     * angle between the tooth's base chord and the fillet at the form point
     * F, so the three blocks meeting at F share its straight angle. */
    double F[2], tf[2];
    gs_gear_fillet_point(g, 0.0, F, tf);
    double u[2] = {0.0, -1.0}; /* from F+ towards F- */
    double dx = u[0] + tf[0], dy = u[1] + tf[1], dn = hypot(dx, dy);
    dx /= dn;
    dy /= dn;
    /* |F + l d| = R0, l > 0 */
    double bq = F[0] * dx + F[1] * dy, cq = F[0] * F[0] + F[1] * F[1] - pl->R0 * pl->R0;
    double disc = bq * bq - cq;
    double psiB;
    if (disc > 0) {
        double l = g->internal ? -bq + sqrt(disc) : -bq - sqrt(disc);
        if (l <= 0)
            l = -bq + sqrt(disc);
        psiB = atan2(F[1] + l * dy, F[0] + l * dx);
    } else {
        psiB = 0.5 * g->psi_form;
    }
    double lo = 0.15 * g->half_pitch, hi = 0.8 * g->half_pitch;
    if (psiB < lo)
        psiB = lo;
    if (psiB > hi)
        psiB = hi;
    /* B must lie on the tooth side of every fillet point (an undercut fillet
     * dips towards the tooth centre). */
    double env = fillet_envelope(pl, g, pl->R0);
    if (psiB > 0.9 * env)
        psiB = 0.9 * env;
    if (psiB < 0.02 * g->half_pitch)
        return gs_diag_set(d, GS_EGEOMETRY, "mesh",
                           "cannot place the under-tooth block: the fillet cuts too deep into "
                           "the tooth");
    pl->psiB = psiB;
    /* Counts fixed at refine 0, then scaled, so refinement is nested. */
    int na0 = o->across, nr0 = o->rim + nx0;
    double wtip = 2.0 * g->ra * sin(g->psi_tip), wch = 2.0 * g->r_form * sin(g->psi_form);
    int ntip0 = (int)lround(na0 * wtip / wch);
    pl->ntip = (ntip0 < 1 ? 1 : ntip0 > na0 ? na0 : ntip0) * L;
    /* A tip thinner than the flank step would leave needle-like elements at
     * the top: shrink the flank steps towards the tip (ratio up to 4). */
    pl->gtip = h / fmax(wtip, 1e-12 * h);
    pl->gtip = pl->gtip < 1 ? 1 : pl->gtip > 4 ? 4 : pl->gtip;
    pl->fband = 1.0;
    if (pl->nr > pl->nband) {
        double fb = fabs(g->rf - pl->R0) / fabs(g->r_form - pl->R0);
        pl->fband = fb < 0.2 ? 0.2 : fb > 0.9 ? 0.9 : fb;
    }
    /* Band circle spacing: the deepest layer's thickness, so the elements
     * there are about square and the rings below start smoothly. */
    double lay_c = fabs(g->rf - pl->R0) * grade_top(1.0 / nr0, o->grading);
    double lay_i = pl->fband * fabs(g->r_form - pl->R0) * grade_top(1.0 / o->rim, o->grading);
    double hR0 = 0.5 * (lay_c + lay_i);
    int nrb0 = (int)lround(2.0 * psiB * pl->R0 / hR0);
    nrb0 = nrb0 < (na0 + 3) / 4 ? (na0 + 3) / 4 : nrb0 > 4 * na0 ? 4 * na0 : nrb0;
    pl->nrb = (nrb0 < 1 ? 1 : nrb0) * L;
    return GS_OK;
}

/* Ids of a side of nodes created along a straight segment A->B with
 * distribution fr[0..n] (fr[0] = 0, fr[n] = 1); ends given. */
static int line_nodes(nodes_t *nb, gs_index a, gs_index b, int n, const double *fr, gs_index *ids)
{
    ids[0] = a;
    ids[n] = b;
    double ax = nb->xy[2 * a], ay = nb->xy[2 * a + 1], bx = nb->xy[2 * b], by = nb->xy[2 * b + 1];
    for (int i = 1; i < n; i++) {
        ids[i] = node_add(nb, ax + fr[i] * (bx - ax), ay + fr[i] * (by - ay), GS_NODE_INTERIOR);
        if (ids[i] < 0)
            return -1;
    }
    return 0;
}

/* Nodes of the interface between R and S (and of R's other side, mirrored
 * by `sgn` = -1), from B on the band circle to the form point F: a
 * quadratic Bezier curve that arrives at F along the bisector of the angle
 * between the tooth's base chord and the fillet (so the blocks T, R and S
 * share the straight angle at F fairly), then pulled towards the tooth
 * centre wherever an undercut fillet dips below it. */
static int interface_side(nodes_t *nb, const gs_gear_geom *g, const plan_t *pl, gs_index a,
                          gs_index b, double sgn, const double *fr, gs_index *ids)
{
    ids[0] = a;
    ids[pl->nr] = b;
    double B[2] = {nb->xy[2 * a], sgn * nb->xy[2 * a + 1]};
    double F[2] = {nb->xy[2 * b], sgn * nb->xy[2 * b + 1]};
    double Q[2], tf[2];
    gs_gear_fillet_point(g, 0.0, Q, tf);
    double dx = tf[0], dy = tf[1] - 1.0, dn = hypot(dx, dy);
    dx /= dn;
    dy /= dn;
    double lam = 0.4 * hypot(F[0] - B[0], F[1] - B[1]);
    if (dy < 0 && lam * -dy > 0.6 * F[1]) /* keep the two sides apart */
        lam = 0.6 * F[1] / -dy;
    double C[2] = {F[0] + lam * dx, F[1] + lam * dy};
    for (int j = 1; j < pl->nr; j++) {
        double u = fr[j], w0 = (1 - u) * (1 - u), w1 = 2 * u * (1 - u), w2 = u * u;
        double x = w0 * B[0] + w1 * C[0] + w2 * F[0], y = w0 * B[1] + w1 * C[1] + w2 * F[1];
        double R = hypot(x, y), ps = atan2(y, x);
        double lim = 0.9 * fillet_envelope(pl, g, R);
        if (ps > lim)
            ps = lim;
        ids[j] = node_add(nb, R * cos(ps), sgn * R * sin(ps), GS_NODE_INTERIOR);
        if (ids[j] < 0)
            return -1;
    }
    return 0;
}

#define NEW_ARR(p, n)                                           \
    do {                                                        \
        (p) = gs_calloc((size_t)(n), sizeof *(p));              \
        if (!(p))                                               \
            goto nomem;                                         \
    } while (0)

#define ADD(dst, x, y, tag)                                     \
    do {                                                        \
        (dst) = node_add(&s->nd, (x), (y), (tag));              \
        if ((dst) < 0)                                          \
            goto nomem;                                         \
    } while (0)

/* Row counts of a block going from n0 (row 0) to n1 (row nrow): geometric
 * in between, so that each row changes by about the same factor. */
static void ramp_counts(int nrow, int n0, int n1, int *cnt)
{
    for (int j = 0; j <= nrow; j++) {
        double v = n0 * pow((double)n1 / n0, (double)j / nrow);
        cnt[j] = (int)lround(v);
        if (cnt[j] < 1)
            cnt[j] = 1;
    }
    cnt[0] = n0;
    cnt[nrow] = n1;
}

/* Row counts of an S block (meshed sideways, from the R/S interface, nr
 * elements, to the sector side, nside elements): each row about as many
 * elements as its length asks for, at most halving or doubling from one row
 * to the next. */
static void side_counts(const nodes_t *nd, const gs_index *top, const gs_index *bot, int ns, int nr,
                        int nc, int nside, int *cS)
{
    double l0 = hypot(nd->xy[2 * top[0]] - nd->xy[2 * bot[0]],
                      nd->xy[2 * top[0] + 1] - nd->xy[2 * bot[0] + 1]);
    int lo = nc < nside ? nc : nside, hi = nr > nside ? nr : nside;
    for (int k = 0; k <= ns; k++) {
        double lk = hypot(nd->xy[2 * top[k]] - nd->xy[2 * bot[k]],
                          nd->xy[2 * top[k] + 1] - nd->xy[2 * bot[k] + 1]);
        int c = (int)lround(nr * lk / l0);
        if (nside > nc) /* a finer side: blend towards its density */
            c = (int)lround(c * pow((double)nside / nc, (double)k / ns));
        cS[k] = c < lo ? lo : c > hi ? hi : c;
    }
    cS[0] = nr;
    cS[ns] = nside;
    for (int k = 1; k < ns; k++)
        if (cS[k] < (cS[k - 1] + 1) / 2)
            cS[k] = (cS[k - 1] + 1) / 2;
    for (int k = ns - 1; k >= 1; k--) {
        if (cS[k] > 2 * cS[k + 1])
            cS[k] = 2 * cS[k + 1];
        if (nside > nc && cS[k] < (cS[k + 1] + 1) / 2)
            cS[k] = (cS[k + 1] + 1) / 2;
    }
}

/* One tooth sector at the plan's refinement; its sides (the space centre
 * lines) get nc_lo and nc_hi elements: pl->nband, or a finer neighbour's
 * count (a transition sector next to locally refined teeth). */
static gs_err build_sector(const gs_gear_geom *g, const plan_t *pl, const plan_t *pt, int nc_lo,
                           int nc_hi, sector_t *s)
{
    const int nf = pt->nf, na = pt->na, nr = pl->nr, ns = pl->ns;
    const int ntip = pt->ntip, nrb = pl->nrb, nsb = pl->ns, nc = pl->nband;
    const int ncm = nc_lo > nc_hi ? nc_lo : nc_hi;
    const double hp = g->half_pitch, R0 = pl->R0, rb = g->rb;
    gs_index *fl_lo = NULL, *fl_hi = NULL, *tip = NULL, *chord = NULL, *rbot = NULL;
    gs_index *rl = NULL, *rr = NULL, *stop_hi = NULL, *stop_lo = NULL, *sbot_hi = NULL,
             *sbot_lo = NULL, *sr_hi = NULL, *sr_lo = NULL;
    double *fa = NULL, *fr = NULL, *fi = NULL;
    int *cT = NULL, *cR = NULL, *cS = NULL, *cS2 = NULL;
    NEW_ARR(fl_lo, nf + 1);
    NEW_ARR(fl_hi, nf + 1);
    NEW_ARR(tip, ntip + 1);
    NEW_ARR(chord, na + 1);
    NEW_ARR(rbot, nrb + 1);
    NEW_ARR(rl, nr + 1);
    NEW_ARR(rr, nr + 1);
    NEW_ARR(stop_hi, ns + 1);
    NEW_ARR(stop_lo, ns + 1);
    NEW_ARR(sbot_hi, nsb + 1);
    NEW_ARR(sbot_lo, nsb + 1);
    NEW_ARR(sr_hi, nc_hi + 1);
    NEW_ARR(sr_lo, nc_lo + 1);
    NEW_ARR(fa, na + 1);
    NEW_ARR(fr, (nr > ncm ? nr : ncm) + 1);
    NEW_ARR(fi, nr + 1);
    NEW_ARR(cT, nf + 1);
    NEW_ARR(cR, nr + 1);
    NEW_ARR(cS, ns + 1);
    NEW_ARR(cS2, ns + 1);
    for (int i = 0; i <= na; i++)
        fa[i] = grade_both((double)i / na, pl->grading);
    /* fr: the radial line at the space centre, graded towards the root;
     * fi: the R/S interface, `nband` graded layers up to about the root
     * circle, then equal steps up the fillet's height to the form point. */
    for (int j = 0; j <= nr; j++)
        fi[j] = j <= pl->nband ? pl->fband * grade_top((double)j / pl->nband, pl->grading)
                               : pl->fband + (1.0 - pl->fband) * (j - pl->nband) / (nr - pl->nband);

    /* Flanks: uniform in involute arc length (rb phi^2 / 2 = (R^2 - rb^2) / (2 rb)),
     * graded towards a thin tip. */
    double lf = (g->r_form * g->r_form - rb * rb), la = (g->ra * g->ra - rb * rb);
    for (int j = 0; j <= nf; j++) {
        double u = grade_top((double)j / nf, pl->gtip);
        double R = j == 0 ? g->r_form : j == nf ? g->ra : sqrt(rb * rb + lf + (la - lf) * u);
        double P[2], T[2];
        gs_gear_flank_point(g, R, P, T);
        ADD(fl_hi[j], P[0], P[1], GS_NODE_FLANK);
        ADD(fl_lo[j], P[0], -P[1], GS_NODE_FLANK);
    }
    /* Tip arc C- -> C+ (graded like the across lines) and the chord F- -> F+. */
    tip[0] = fl_lo[nf];
    tip[ntip] = fl_hi[nf];
    for (int i = 1; i < ntip; i++) {
        double ps = -g->psi_tip + 2.0 * g->psi_tip * grade_both((double)i / ntip, pl->grading);
        ADD(tip[i], g->ra * cos(ps), g->ra * sin(ps), GS_NODE_TIP);
    }
    chord[0] = fl_lo[0];
    chord[na] = fl_hi[0];
    if (line_nodes(&s->nd, chord[0], chord[na], na, fa, chord))
        goto nomem;
    /* Band circle: equal angles under the tooth and under each space side. */
    for (int i = 0; i <= nrb; i++) {
        double ps = -pl->psiB + 2.0 * pl->psiB * i / nrb;
        ADD(rbot[i], R0 * cos(ps), R0 * sin(ps), GS_NODE_INTERIOR);
    }
    sbot_hi[0] = rbot[nrb];
    sbot_lo[0] = rbot[0];
    for (int k = 1; k <= nsb; k++) {
        double ps = k == nsb ? hp : pl->psiB + (hp - pl->psiB) * k / nsb;
        ADD(sbot_hi[k], R0 * cos(ps), R0 * sin(ps), GS_NODE_INTERIOR);
        ADD(sbot_lo[k], R0 * cos(ps), -R0 * sin(ps), GS_NODE_INTERIOR);
    }
    if (interface_side(&s->nd, g, pl, rbot[0], chord[0], -1.0, fi, rl) ||
        interface_side(&s->nd, g, pl, rbot[nrb], chord[na], 1.0, fi, rr))
        goto nomem;
    /* Space sides: fillet then root arc, one curve at equal arc length
     * steps (each node exactly on the piece it falls on). */
    double lroot = g->rf * (hp - g->psi_root), ltot = pl->lfil + lroot;
    stop_hi[0] = fl_hi[0];
    stop_lo[0] = fl_lo[0];
    for (int k = 1; k <= ns; k++) {
        double P[2], T[2];
        int tag;
        double sk = ltot * k / ns;
        if (k < ns && sk < pl->lfil) {
            gs_gear_fillet_point(g, fillet_t_at(pl, sk / pl->lfil), P, T);
            tag = GS_NODE_FILLET;
        } else {
            double ps = k == ns ? hp : g->psi_root + (sk - pl->lfil) / g->rf;
            P[0] = g->rf * cos(ps);
            P[1] = g->rf * sin(ps);
            tag = sk == pl->lfil ? GS_NODE_FILLET : GS_NODE_ROOT;
        }
        ADD(stop_hi[k], P[0], P[1], tag);
        ADD(stop_lo[k], P[0], -P[1], tag);
    }
    /* The sector sides are shared with the neighbours: the lower one is the
     * exact mirror image of the upper one at its count (nested gradings, so
     * the same node of a coarse and a fine side has the same position). */
    for (int side = 1; side >= 0; side--) { /* the upper side first (node order) */
        int c = side ? nc_hi : nc_lo;
        gs_index *ids = side ? sr_hi : sr_lo;
        for (int j = 0; j <= c; j++)
            fr[j] = grade_top((double)j / c, pl->grading);
        if (line_nodes(&s->nd, side ? sbot_hi[nsb] : sbot_lo[nsb], side ? stop_hi[ns] : stop_lo[ns],
                       c, fr, ids))
            goto nomem;
        double ax = s->nd.xy[2 * sbot_hi[nsb]], ay = s->nd.xy[2 * sbot_hi[nsb] + 1];
        double bx = s->nd.xy[2 * stop_hi[ns]], by = s->nd.xy[2 * stop_hi[ns] + 1];
        for (int j = 1; j < c; j++) {
            s->nd.xy[2 * ids[j]] = ax + fr[j] * (bx - ax);
            s->nd.xy[2 * ids[j] + 1] = (side ? 1.0 : -1.0) * (ay + fr[j] * (by - ay));
        }
    }
    /* Row counts: the tooth narrows to its tip, keep elements about as wide
     * as at its base; R and S go from the band circle's spacing to their
     * top's. */
    {
        double w0 = hypot(s->nd.xy[2 * fl_hi[0]] - s->nd.xy[2 * fl_lo[0]],
                          s->nd.xy[2 * fl_hi[0] + 1] - s->nd.xy[2 * fl_lo[0] + 1]);
        for (int j = 0; j <= nf; j++) {
            double w = hypot(s->nd.xy[2 * fl_hi[j]] - s->nd.xy[2 * fl_lo[j]],
                             s->nd.xy[2 * fl_hi[j] + 1] - s->nd.xy[2 * fl_lo[j] + 1]);
            int c = (int)lround(na * w / w0);
            cT[j] = c < ntip ? ntip : c > na ? na : c;
        }
        cT[0] = na;
        cT[nf] = ntip;
        for (int j = nf - 1; j >= 1; j--) /* no row more than twice the next */
            if (cT[j] > 2 * cT[j + 1])
                cT[j] = 2 * cT[j + 1];
    }
    ramp_counts(nr, nrb, na, cR);
    /* S is meshed "sideways": its rows run from the band circle up to the
     * fillet and root, from the R/S interface (nr elements) to the space
     * centre line (`rim` layers, or a fine neighbour's), each with about as
     * many elements as its length asks for. So a tall fillet beside a thin
     * band needs no thin layers near the root. */
    side_counts(&s->nd, stop_hi, sbot_hi, ns, nr, nc, nc_hi, cS);
    side_counts(&s->nd, stop_hi, sbot_hi, ns, nr, nc, nc_lo, cS2); /* mirror images */
    if (layered_block(&s->nd, &s->tr, nf, cT, chord, tip, fl_lo, fl_hi) ||
        layered_block(&s->nd, &s->tr, nr, cR, rbot, chord, rl, rr) ||
        layered_block(&s->nd, &s->tr, ns, cS, rr, sr_hi, sbot_hi, stop_hi) ||
        layered_block(&s->nd, &s->tr, ns, cS2, rl, sr_lo, sbot_lo, stop_lo))
        goto nomem;
    /* Lists for assembly. */
    s->nleft = nc_lo + 1;
    s->nright = nc_hi + 1;
    NEW_ARR(s->left, nc_lo + 1);
    NEW_ARR(s->right, nc_hi + 1);
    memcpy(s->left, sr_lo, (size_t)(nc_lo + 1) * sizeof *sr_lo);
    memcpy(s->right, sr_hi, (size_t)(nc_hi + 1) * sizeof *sr_hi);
    s->nbot = 2 * nsb + nrb + 1;
    NEW_ARR(s->bottom, s->nbot);
    {
        int k = 0;
        for (int i = nsb; i >= 1; i--)
            s->bottom[k++] = sbot_lo[i];
        for (int i = 0; i <= nrb; i++)
            s->bottom[k++] = rbot[i];
        for (int i = 1; i <= nsb; i++)
            s->bottom[k++] = sbot_hi[i];
    }
    s->nflank = nf + 1;
    NEW_ARR(s->flank_cw, nf + 1);
    NEW_ARR(s->flank_ccw, nf + 1);
    memcpy(s->flank_cw, fl_lo, (size_t)(nf + 1) * sizeof *fl_lo);
    memcpy(s->flank_ccw, fl_hi, (size_t)(nf + 1) * sizeof *fl_hi);
    s->nbnd = 2 * ns + 2 * nf + ntip + 1;
    NEW_ARR(s->bnd, s->nbnd);
    {
        int k = 0;
        for (int i = ns; i >= 1; i--)
            s->bnd[k++] = stop_lo[i];
        for (int j = 0; j < nf; j++)
            s->bnd[k++] = fl_lo[j];
        for (int i = 0; i < ntip; i++)
            s->bnd[k++] = tip[i];
        for (int j = nf; j >= 0; j--)
            s->bnd[k++] = fl_hi[j];
        for (int i = 1; i <= ns; i++)
            s->bnd[k++] = stop_hi[i];
    }
    gs_err e = GS_OK;
    if (0) {
    nomem:
        e = GS_ENOMEM;
    }
    free(fl_lo);
    free(fl_hi);
    free(tip);
    free(chord);
    free(rbot);
    free(rl);
    free(rr);
    free(stop_hi);
    free(stop_lo);
    free(sbot_hi);
    free(sbot_lo);
    free(sr_hi);
    free(sr_lo);
    free(fa);
    free(fr);
    free(fi);
    free(cT);
    free(cR);
    free(cS);
    free(cS2);
    return e;
}

/* ------------------------------------------------------------------------ */
/* Rings between the band and the hub                                       */
/* ------------------------------------------------------------------------ */

typedef struct {
    int n;
    double *R;     /* radii, R[0] = R0 ... R[n-1] = hub */
    gs_index *N;   /* node counts at refine 0 */
} rings_t;

/* Rings at refine 0: element size grows by 1.3 per ring away from the
 * teeth; the count may at most halve from one ring to the next. */
static int plan_rings(const gs_gear_geom *g, double R0, gs_index N0, double h0, rings_t *rp)
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
static int zipper(nodes_t *nb, tris_t *tb, const gs_index *A, gs_index na, const gs_index *B,
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
            r = a_outer ? tri_add(tb, ia, ia1, jb) : tri_add(tb, ia1, ia, jb);
            i++;
        } else {
            r = a_outer ? tri_add(tb, jb1, jb, ia) : tri_add(tb, jb, jb1, ia);
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
static int smooth_poor(nodes_t *nb, const tris_t *tb, int iters, double thresh)
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
                double sh = tri_shape(nb->xy, T[0], T[1], T[2]);
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
                    double sh = tri_shape(nb->xy, T[0], T[1], T[2]);
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

/* ------------------------------------------------------------------------ */
/* Assembly                                                                 */
/* ------------------------------------------------------------------------ */

/* The default element order and, per order, the default counts: the only
 * place they are written (the scene takes its defaults from here). Order 2
 * chosen by measurement against the CalculiX reference within 40 000
 * unknowns for the 20/30 pair (docs/validation/calculix.md). */
#define GS_MESH_DEFAULT_ORDER 2
static const gs_gear_mesh_opts default_counts[2] = {
    {.flank = 8, .across = 4, .rim = 3, .refine = 0, .grading = 2.0, .order = 1},
    {.flank = 8, .across = 4, .rim = 2, .refine = 0, .grading = 3.0, .order = 2},
};

void gs_gear_mesh_opts_for_order(gs_gear_mesh_opts *o, int order)
{
    if (order != 1 && order != 2)
        order = GS_MESH_DEFAULT_ORDER;
    *o = default_counts[order - 1];
}

void gs_gear_mesh_opts_defaults(gs_gear_mesh_opts *o)
{
    gs_gear_mesh_opts_for_order(o, GS_MESH_DEFAULT_ORDER);
}

/* Chosen by measurement against the CalculiX reference (docs/validation/calculix.md
 * "Local refinement and the fine setting"). */
void gs_gear_mesh_opts_fine(gs_gear_mesh_opts *o)
{
    *o = (gs_gear_mesh_opts){.flank = 8, .across = 4, .rim = 1, .refine = 0, .grading = 3.0,
                             .order = 2, .fine_teeth = 3, .fine_refine = 3, .fine_centre = 0};
}

static gs_err check_opts(const gs_gear_mesh_opts *o, gs_diag *d)
{
    if (o->flank < 1 || o->flank > 1000)
        return gs_diag_set(d, GS_ERANGE, "mesh.flank", "elements along a flank: 1 to 1000 (got %d)",
                           o->flank);
    if (o->across < 1 || o->across > 1000)
        return gs_diag_set(d, GS_ERANGE, "mesh.across",
                           "elements across a tooth: 1 to 1000 (got %d)", o->across);
    if (o->rim < 1 || o->rim > 1000)
        return gs_diag_set(d, GS_ERANGE, "mesh.rim", "element layers in the rim: 1 to 1000 (got %d)",
                           o->rim);
    if (o->refine < 0 || o->refine > 8)
        return gs_diag_set(d, GS_ERANGE, "refine", "refinement level: 0 to 8 (got %d)", o->refine);
    if (!(o->grading >= 1.0 && o->grading <= 8.0))
        return gs_diag_set(d, GS_ERANGE, "mesh.grading", "grading: 1 to 8 (got %g)", o->grading);
    if (o->order != 1 && o->order != 2)
        return gs_diag_set(d, GS_ERANGE, "mesh.order", "element order: 1 or 2 (got %d)", o->order);
    if (o->fine_teeth < 0 || o->fine_teeth > 5000)
        return gs_diag_set(d, GS_ERANGE, "mesh.fine_teeth",
                           "locally refined teeth: 0 (none) to the number of teeth (got %d)",
                           o->fine_teeth);
    if (o->fine_teeth > 0 && (o->fine_refine < 1 || o->fine_refine > 4))
        return gs_diag_set(d, GS_ERANGE, "mesh.fine_refine",
                           "refinement of the fine teeth: 1 to 4 levels (got %d)", o->fine_refine);
    if (o->fine_teeth == 0 && o->fine_refine != 0)
        return gs_diag_set(d, GS_ERANGE, "mesh.fine_refine",
                           "fine_refine %d without fine_teeth: say how many teeth to refine",
                           o->fine_refine);
    if (o->refine + o->fine_refine > 8)
        return gs_diag_set(d, GS_ERANGE, "mesh.fine_refine",
                           "refine + fine_refine must not exceed 8 (got %d + %d)", o->refine,
                           o->fine_refine);
    return GS_OK;
}

gs_err gs_gear_mesh(const gs_gear_params *p, const gs_gear_mesh_opts *o, gs_mesh **out,
                    gs_diag *d)
{
    *out = NULL;
    gs_gear_mesh_opts def;
    if (!o) {
        gs_gear_mesh_opts_defaults(&def);
        o = &def;
    }
    GS_TRY(check_opts(o, d));
    gs_gear_geom g, g_true;
    GS_TRY(gs_gear_geometry(p, &g, d));
    g_true = g;
    /* Mesh the gear at a reference module of 10 mm and scale the result:
     * every size is a multiple of the module, so meshes of any module are
     * then exactly the same shape (round-off included, which the smoothing's
     * accept/reject comparisons would otherwise amplify). */
    const double mref = 0.01, scale = g.m / mref;
    {
        gs_gear_params pu = *p;
        pu.module_m = mref;
        pu.thinning_m = p->thinning_m / scale;
        pu.hub_radius_m = p->hub_radius_m > 0 ? p->hub_radius_m / scale : 0.0;
        pu.face_width_m = 0.01;
        gs_gear_geom gu;
        if (gs_gear_geometry(&pu, &gu, NULL) != GS_OK)
            return gs_diag_set(d, GS_EINTERNAL, "module_mm",
                               "the gear scaled to the reference module is not valid");
        g = gu;
    }
    plan_t *pl = malloc(sizeof *pl);
    if (!pl)
        return GS_ENOMEM;
    gs_err e = make_plan(&g, o, pl, d);
    if (e != GS_OK) {
        free(pl);
        return e;
    }
    /* Local refinement: the teeth of the `fine_teeth` sectors centred on
     * `fine_centre` (the T blocks, whose flanks carry the contact) are
     * meshed from a plan `fine_refine` levels finer, their bodies (rim band,
     * fillets) one level less; the sectors beside them step down one more
     * level per tooth to the base (graded), and of two neighbouring sectors
     * the coarser takes the finer one's node count on their shared side (a
     * 2:1 transition inside the coarser sector). */
    const int z = g.z;
    const int nfine = o->fine_teeth > z ? z : o->fine_teeth;
    const int nlev = nfine > 0 ? o->fine_refine + 1 : 1;

    const int c0 = nfine > 0 ? ((o->fine_centre - (nfine - 1) / 2) % z + z) % z : 0;
    plan_t *plv[5] = {pl, NULL, NULL, NULL, NULL};
    for (int lv = 1; lv < nlev; lv++) {
        gs_gear_mesh_opts of = *o;
        of.refine = o->refine + lv;
        plv[lv] = malloc(sizeof *plv[lv]);
        e = plv[lv] ? make_plan(&g, &of, plv[lv], d) : GS_ENOMEM;
        if (e != GS_OK) {
            for (int q = 0; q <= lv; q++)
                free(plv[q]);
            return e;
        }
    }
    int *lev = malloc((size_t)z * sizeof *lev);
    if (!lev) {
        for (int q = 0; q < nlev; q++)
            free(plv[q]);
        return GS_ENOMEM;
    }
    for (int k = 0; k < z; k++) {
        int off = ((k - c0) % z + z) % z, dist = 0;
        if (off >= nfine)
            dist = off - (nfine - 1) < z - off ? off - (nfine - 1) : z - off;
        /* body level (rim band, fillets, sector sides); the fine teeth's
         * own tooth (the T block, whose flanks carry the contact) one
         * level above their body: lev + 100 marks them */
        lev[k] = nlev - 2 - dist > 0 ? nlev - 2 - dist : 0;
        if (dist == 0)
            lev[k] += 100;
    }
    /* Size guard before allocating: triangles per sector ~ 2 (na nf + (na +
     * 2 ns) nr), plus the rings (bounded by a few times the band's). */
    {
        double tot = 0.0;
        for (int k = 0; k < z; k++) {
            const plan_t *pk = plv[lev[k] % 100 + lev[k] / 100];
            tot += 2.0 * ((double)pk->na * pk->nf + (double)(pk->na + 2 * pk->ns) * pk->nr) * 4.0;
        }
        if (tot > (double)(1 << 26)) {
            for (int q = 0; q < nlev; q++)
                free(plv[q]);
            free(lev);
            return gs_diag_set(d, GS_ETOOBIG, nlev > 1 ? "mesh.fine_refine" : "refine",
                               "the mesh would have about %.3g triangles (limit %d)", tot, 1 << 26);
        }
    }
    /* Sector variants: 4 per level, bit 0 / bit 1 set when the left / right
     * neighbour is one level finer. */
    sector_t sec[40];
    memset(sec, 0, sizeof sec);
    signed char *where[40] = {NULL}; /* -1 left side, +1 right side, 0 other */
    int *side_pos[40] = {NULL};      /* position on that side */
    nodes_t nd = {0};
    tris_t tr = {0};
    rings_t rp = {0};
    gs_mesh *m = NULL;
    gs_index *map = NULL, *first_left = NULL, *prev_right = NULL, *ring0 = NULL, *ringA = NULL,
             *ringB = NULL;
    int *var = NULL;
    gs_index n0 = 0;
    e = GS_ENOMEM;
    var = malloc((size_t)z * sizeof *var);
    if (!var)
        goto fail;
    {
        gs_index nl_max = 0, f_tot = 0, b_tot = 0;
        int side_max = 0;
        n0 = 0;
        for (int k = 0; k < z; k++) {
            int lk = lev[k] % 100, up = lev[k] / 100;
            int fl = lev[(k + z - 1) % z] % 100 > lk, fh = lev[(k + 1) % z] % 100 > lk;
            int v = 4 * lk + fl + 2 * fh + 20 * up;
            var[k] = v;
            sector_t *sv = &sec[v];
            if (!sv->nd.n) {
                const plan_t *pv = plv[lk];
                int nclo = fl ? plv[lk + 1]->nband : pv->nband;
                int nchi = fh ? plv[lk + 1]->nband : pv->nband;
                e = build_sector(&g, pv, plv[lk + up], nclo, nchi, sv);
                if (e != GS_OK)
                    goto fail;
                e = GS_ENOMEM;
                where[v] = calloc((size_t)sv->nd.n, 1);
                side_pos[v] = calloc((size_t)sv->nd.n, sizeof *side_pos[0]);
                if (!where[v] || !side_pos[v])
                    goto fail;
                for (int j = 0; j < sv->nleft; j++) {
                    where[v][sv->left[j]] = -1;
                    side_pos[v][sv->left[j]] = j;
                }
                for (int j = 0; j < sv->nright; j++) {
                    where[v][sv->right[j]] = 1;
                    side_pos[v][sv->right[j]] = j;
                }
            }
            nl_max = sv->nd.n > nl_max ? sv->nd.n : nl_max;
            side_max = sv->nleft > side_max ? sv->nleft : side_max;
            side_max = sv->nright > side_max ? sv->nright : side_max;
            f_tot += 2 * sv->nflank;
            b_tot += sv->nbnd - 1;
            n0 += sv->nbot - 1;
        }
        map = malloc((size_t)nl_max * sizeof *map);
        first_left = malloc((size_t)side_max * sizeof *first_left);
        prev_right = malloc((size_t)side_max * sizeof *prev_right);
        m = gs_calloc(1, sizeof *m);
        if (!map || !first_left || !prev_right || !m)
            goto fail;
        m->n_teeth = z;
        m->flank_ptr = malloc((size_t)(2 * z + 1) * sizeof *m->flank_ptr);
        m->flank_nodes = malloc((size_t)f_tot * sizeof *m->flank_nodes);
        m->n_boundary = b_tot;
        m->boundary = malloc((size_t)m->n_boundary * sizeof *m->boundary);
        ring0 = malloc((size_t)n0 * sizeof *ring0);
        if (!m->flank_ptr || !m->flank_nodes || !m->boundary || !ring0)
            goto fail;
    }
    {
        gs_index fpos = 0, bpos = 0, rpos = 0;
        m->flank_ptr[0] = 0;
        for (int k = 0; k < z; k++) {
            const sector_t *sv = &sec[var[k]];
            const signed char *wh = where[var[k]];
            const int *sp = side_pos[var[k]];
            const gs_index nl = sv->nd.n;
            double ang = 2.0 * GS_PI * k / z, c = cos(ang), sn = sin(ang);
            for (gs_index l = 0; l < nl; l++) {
                if (wh[l] == -1 && k > 0) {
                    map[l] = prev_right[sp[l]];
                    continue;
                }
                if (wh[l] == 1 && k == z - 1) {
                    map[l] = first_left[sp[l]];
                    continue;
                }
                double x = sv->nd.xy[2 * l], y = sv->nd.xy[2 * l + 1];
                map[l] = node_add(&nd, c * x - sn * y, sn * x + c * y, sv->nd.tag[l]);
                if (map[l] < 0)
                    goto fail;
            }
            if (k == 0)
                for (int j = 0; j < sv->nleft; j++)
                    first_left[j] = map[sv->left[j]];
            for (int j = 0; j < sv->nright; j++)
                prev_right[j] = map[sv->right[j]];
            for (gs_index t = 0; t < sv->tr.n; t++)
                if (tri_add(&tr, map[sv->tr.t[3 * t]], map[sv->tr.t[3 * t + 1]],
                            map[sv->tr.t[3 * t + 2]]))
                    goto fail;
            /* s = 0 is the clockwise flank for an external gear, the
             * counter-clockwise one for a ring (viewer inside the ring). */
            const gs_index *f0 = g.internal ? sv->flank_ccw : sv->flank_cw;
            const gs_index *f1 = g.internal ? sv->flank_cw : sv->flank_ccw;
            for (int q = 0; q < sv->nflank; q++)
                m->flank_nodes[fpos + q] = map[f0[q]];
            m->flank_ptr[2 * k + 1] = fpos += sv->nflank;
            for (int q = 0; q < sv->nflank; q++)
                m->flank_nodes[fpos + q] = map[f1[q]];
            m->flank_ptr[2 * k + 2] = fpos += sv->nflank;
            for (int q = 0; q + 1 < sv->nbnd; q++)
                m->boundary[bpos++] = map[sv->bnd[q]];
            for (int q = 0; q + 1 < sv->nbot; q++)
                ring0[rpos++] = map[sv->bottom[q]];
        }
    }
    /* Rings from the band circle to the hub / outer rim. */
    {
        const int L = 1 << o->refine;
        gs_index n0_base = (gs_index)z * (2 * pl->ns + pl->nrb) / L;
        /* the band circle's spacing is about its layer's thickness */
        double h0 = 2.0 * GS_PI * pl->R0 / (double)n0_base;
        if (plan_rings(&g, pl->R0, n0_base, h0, &rp))
            goto fail;
        /* Under locally refined teeth the rings start finer and halve
         * their extra density ring by ring down to the base's. */
        gs_index nA = n0;
        ringA = ring0;
        ring0 = NULL;
        int sub_all = 0;
        for (int k = 0; k + 1 < rp.n; k++) {
            for (int sub = 1; sub <= L; sub++) {
                double R = rp.R[k] + (rp.R[k + 1] - rp.R[k]) * sub / L;
                gs_index nb0 = (sub == L ? rp.N[k + 1] : rp.N[k]) * L;
                sub_all++;
                gs_index nB = 0;
                for (int pass = 0; pass < 2; pass++) {
                    gs_index cnt = 0;
                    for (gs_index q = 0; q < nb0; q++) {
                        double a = -GS_PI / z + 2.0 * GS_PI * q / nb0;
                        double am = a + GS_PI / nb0;
                        long tk = lround(am * z / (2.0 * GS_PI));
                        int lk = lev[(int)((tk % z + z) % z)] % 100 - sub_all;
                        int f = lk > 0 ? 1 << lk : 1;
                        for (int i = 0; i < f; i++, cnt++) {
                            if (!pass)
                                continue;
                            double ai = a + 2.0 * GS_PI * i / ((double)nb0 * f);
                            int last = k + 2 == rp.n && sub == L;
                            ringB[cnt] = node_add(&nd, R * cos(ai), R * sin(ai),
                                                  last ? GS_NODE_CORE : GS_NODE_INTERIOR);
                            if (ringB[cnt] < 0)
                                goto fail;
                        }
                    }
                    if (!pass) {
                        nB = cnt;
                        ringB = malloc((size_t)nB * sizeof *ringB);
                        if (!ringB)
                            goto fail;
                    }
                }
                if (zipper(&nd, &tr, ringA, nA, ringB, nB, !g.internal))
                    goto fail;
                free(ringA);
                ringA = ringB;
                ringB = NULL;
                nA = nB;
            }
        }
        /* ringA is the core interface. */
        m->n_fixed = nA;
        m->fixed = ringA;
        ringA = NULL;
        for (gs_index q = 0; q < m->n_fixed; q++)
            nd.tag[m->fixed[q]] = GS_NODE_CORE;
    }
    if (smooth_poor(&nd, &tr, 40, 0.6))
        goto fail;
    for (gs_index i = 0; i < 2 * nd.n; i++)
        nd.xy[i] *= scale;
    m->n_nodes = nd.n;
    m->xy = nd.xy;
    m->node_tag = nd.tag;
    m->n_tris = tr.n;
    m->tri = tr.t;
    nd.xy = NULL;
    nd.tag = NULL;
    tr.t = NULL;
    /* Every triangle must have come out counter-clockwise and not flat. */
    {
        gs_mesh_quality q;
        gs_mesh_quality_eval(m, &q);
        int loops = 0;
        gs_err te = gs_mesh_check_topology(m, NULL, &loops);
        if (te == GS_ENOMEM)
            goto fail;
        if (te != GS_OK || loops != 2)
            q.n_bad = q.n_bad > 0 ? q.n_bad : 1;
        if (q.n_bad > 0) {
            e = gs_diag_set(d, GS_EGEOMETRY, "mesh",
                            "%lld of %lld elements came out inverted or flat (%d teeth, module "
                            "%g mm, shift %g): try other mesh counts",
                            (long long)q.n_bad, (long long)q.n_tris, z, scale * mref * 1e3,
                            p->profile_shift);
            goto fail;
        }
    }
    /* Quadratic elements: mid-side nodes, on the exact outline at the true
     * module (after scaling, so they are exact to round-off). */
    if (o->order == 2) {
        e = gsi_mesh_quadratic(m, &g_true);
        if (e == GS_EGEOMETRY)
            e = gs_diag_set(d, GS_EGEOMETRY, "mesh.order",
                            "a curved quadratic element came out with a non-positive Jacobian "
                            "(%d teeth): try other mesh counts", z);
        if (e != GS_OK)
            goto fail;
    }
    e = GS_OK;
    *out = m;
    m = NULL;
fail:
    gs_mesh_free(&m);
    for (int v = 0; v < 40; v++) {
        sector_free(&sec[v]);
        free(where[v]);
        free(side_pos[v]);
    }
    free(nd.xy);
    free(nd.tag);
    free(tr.t);
    free(rp.R);
    free(rp.N);
    free(map);
    free(var);
    free(first_left);
    free(prev_right);
    free(ring0);
    free(ringA);
    free(ringB);
    for (int q = 0; q < nlev; q++)
        free(plv[q]);
    free(lev);
    return e;
}
