/* SPDX-License-Identifier: MIT
 * Gear meshes (gear_mesh.c): the tooth sector template, its plan of counts
 * and shapes fixed at refine 0, and its four blocks (tooth, band under it,
 * the two space sides). */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/mesh.h"
#include "gearsim/util.h"
#include "mesh/gear_mesh_internal.h"
#include "mesh/mesh_internal.h"

/* ------------------------------------------------------------------------ */
/* The sector template                                                      */
/* ------------------------------------------------------------------------ */

void gsi_gmesh_sector_free(sector_t *s)
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

gs_err gsi_gmesh_make_plan(const gs_gear_geom *g, const gs_gear_mesh_opts *o, plan_t *pl, gs_diag *d)
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
    double lay_c = fabs(g->rf - pl->R0) * gsi_gmesh_grade_top(1.0 / nr0, o->grading);
    double lay_i = pl->fband * fabs(g->r_form - pl->R0) * gsi_gmesh_grade_top(1.0 / o->rim, o->grading);
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
        ids[i] = gsi_gmesh_node_add(nb, ax + fr[i] * (bx - ax), ay + fr[i] * (by - ay), GS_NODE_INTERIOR);
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
        ids[j] = gsi_gmesh_node_add(nb, R * cos(ps), sgn * R * sin(ps), GS_NODE_INTERIOR);
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
        (dst) = gsi_gmesh_node_add(&s->nd, (x), (y), (tag));              \
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
gs_err gsi_gmesh_build_sector(const gs_gear_geom *g, const plan_t *pl, const plan_t *pt, int nc_lo,
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
        fa[i] = gsi_gmesh_grade_both((double)i / na, pl->grading);
    /* fr: the radial line at the space centre, graded towards the root;
     * fi: the R/S interface, `nband` graded layers up to about the root
     * circle, then equal steps up the fillet's height to the form point. */
    for (int j = 0; j <= nr; j++)
        fi[j] = j <= pl->nband ? pl->fband * gsi_gmesh_grade_top((double)j / pl->nband, pl->grading)
                               : pl->fband + (1.0 - pl->fband) * (j - pl->nband) / (nr - pl->nband);

    /* Flanks: uniform in involute arc length (rb phi^2 / 2 = (R^2 - rb^2) / (2 rb)),
     * graded towards a thin tip. */
    double lf = (g->r_form * g->r_form - rb * rb), la = (g->ra * g->ra - rb * rb);
    for (int j = 0; j <= nf; j++) {
        double u = gsi_gmesh_grade_top((double)j / nf, pl->gtip);
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
        double ps = -g->psi_tip + 2.0 * g->psi_tip * gsi_gmesh_grade_both((double)i / ntip, pl->grading);
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
            fr[j] = gsi_gmesh_grade_top((double)j / c, pl->grading);
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
    if (gsi_gmesh_layered_block(&s->nd, &s->tr, nf, cT, chord, tip, fl_lo, fl_hi) ||
        gsi_gmesh_layered_block(&s->nd, &s->tr, nr, cR, rbot, chord, rl, rr) ||
        gsi_gmesh_layered_block(&s->nd, &s->tr, ns, cS, rr, sr_hi, sbot_hi, stop_hi) ||
        gsi_gmesh_layered_block(&s->nd, &s->tr, ns, cS2, rl, sr_lo, sbot_lo, stop_lo))
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
