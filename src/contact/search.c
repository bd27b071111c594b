/* SPDX-License-Identifier: MIT
 * Contact search of one gear mesh (METHOD.md section 5) and the scene-frame
 * gap of a candidate with its chain rule (section 3). Conventions and the
 * contract are in gearsim/contact.h; the reasoning in docs/explanation/contact.md.
 *
 * Outline of a search, for each gear A as slave against gear B:
 *
 *  1. Zone. A point of A can touch B only inside B's toothed zone: within
 *     B's tip circle (external B) or outside it (ring), widened by the band.
 *     Seen from A's centre, the part of A's tooth annulus in that zone is an
 *     angular interval around the direction of B's centre (or away from it,
 *     for a ring); its half-width follows from the law of cosines,
 *     cos(beta) >= or <= (rho^2 + d^2 - R^2) / (2 rho d), extremal over the
 *     annulus radii rho. The candidate teeth are those whose centre lies in
 *     the interval widened by half a pitch: the teeth around the pitch point,
 *     as many as the geometry allows to touch (any contact ratio).
 *  2. Slaves. On each candidate tooth: flank 0 (root to tip), the tip arc,
 *     flank 1 (tip to root). A node outside B's zone is skipped at once.
 *  3. Distance. The node is taken to B's body frame; its polar angle locates
 *     it on B's boundary loop (stored in order of polar angle) by bisection;
 *     a short walk along the loop finds the nearest boundary segment (with
 *     B's displacements). Within the band (or inside B by at most the depth
 *     limit) the node becomes a candidate with the window of B's boundary
 *     nodes centred on its nearest node, reordered so B's material is on the
 *     left. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/contact.h"
#include "gearsim/util.h"

#define WALK_HALF 3 /* boundary segments examined on each side of the bisected one */

typedef struct gear_data {
    const gs_mesh *m;
    gs_gear_params p;
    int internal, z;
    double mod, ra, rf;
    double rho_lo, rho_hi;   /* radial extent of the teeth (tip and root circles) */
    double flank_spacing;    /* mean reference distance of consecutive flank nodes */
    gs_index nb;
    double *ang;             /* nb: unwrapped polar angle of boundary node j (reference) */
    gs_index *bpos;          /* n_nodes: position on the boundary loop, or -1 */
    int order;               /* element order of the mesh (1, 2) */
    gs_index cpar;           /* order 2: parity of the corner positions on the loop */
    unsigned char *tipc;     /* n_nodes: 1 for a tip corner (the last node of a flank) */
} gear_data;

struct gs_contact_search {
    gear_data g[2];
    gs_contact_opts o;
    double band, depth;
    gs_contact_candidate *cand;
    gs_index n;
    size_t cap;
};

static gs_err tip_corner_distance(const gear_data *gb, const double *pts, const gs_contact_candidate *cand,
                                  const double x[2], gs_gap *gap);

void gs_contact_opts_defaults(gs_contact_opts *o)
{
    o->band_m = 0.0;
    o->depth_m = 0.0;
    o->window = 5;
    o->passes = GS_CONTACT_TWO_PASS;
}

static double wrap_pi(double a)
{
    a = fmod(a, 2.0 * GS_PI);
    if (a > GS_PI)
        a -= 2.0 * GS_PI;
    else if (a <= -GS_PI)
        a += 2.0 * GS_PI;
    return a;
}

static gs_err gear_prepare(gear_data *gd, const gs_mesh *m, const gs_gear_params *p, int idx,
                           gs_diag *d)
{
    const char *which = idx ? "gear 1" : "gear 0";
    if (!m->flank_ptr || !m->flank_nodes || !m->boundary || m->n_boundary < 3 ||
        m->n_teeth != p->teeth || !m->node_tag)
        return gs_diag_set(d, GS_EINVAL, "mesh",
                           "%s: not a gear mesh of these parameters (flank tables, boundary "
                           "loop and %d teeth expected)", which, p->teeth);
    gs_gear_geom geom;
    gs_err e = gs_gear_geometry(p, &geom, d);
    if (e != GS_OK) {
        if (d)
            strcpy(d->field, "gears");
        return e;
    }
    gd->m = m;
    gd->p = *p;
    gd->internal = geom.internal;
    gd->z = geom.z;
    gd->mod = geom.m;
    gd->ra = geom.ra;
    gd->rf = geom.rf;
    gd->rho_lo = fmin(geom.ra, geom.rf);
    gd->rho_hi = fmax(geom.ra, geom.rf);
    gd->nb = m->n_boundary;
    gd->ang = malloc((size_t)gd->nb * sizeof *gd->ang);
    gd->bpos = malloc((size_t)m->n_nodes * sizeof *gd->bpos);
    if (!gd->ang || !gd->bpos)
        return GS_ENOMEM;
    for (gs_index i = 0; i < m->n_nodes; i++)
        gd->bpos[i] = -1;
    double prev = 0.0;
    for (gs_index j = 0; j < gd->nb; j++) {
        gs_index nd = m->boundary[j];
        if (nd < 0 || nd >= m->n_nodes)
            return gs_diag_set(d, GS_EINVAL, "mesh", "%s: boundary node out of range", which);
        gd->bpos[nd] = j;
        double a = atan2(m->xy[2 * nd + 1], m->xy[2 * nd]);
        gd->ang[j] = j ? gd->ang[j - 1] + wrap_pi(a - prev) : a;
        prev = a;
    }
    gd->order = gs_mesh_order(m);
    if (gd->order == 2) {
        /* the loop alternates corner and mid-side nodes (mesh.h) */
        char *is_mid = gs_calloc((size_t)m->n_nodes, 1);
        if (!is_mid)
            return GS_ENOMEM;
        for (gs_index q = 0; q < 3 * m->n_tris; q++)
            if (m->mid[q] >= 0 && m->mid[q] < m->n_nodes)
                is_mid[m->mid[q]] = 1;
        gd->cpar = is_mid[m->boundary[0]] ? 1 : 0;
        bool alt = gd->nb % 2 == 0;
        for (gs_index j = 0; j < gd->nb && alt; j++)
            alt = (is_mid[m->boundary[j]] != 0) == ((j % 2) != gd->cpar);
        free(is_mid);
        if (!alt)
            return gs_diag_set(d, GS_EINVAL, "mesh",
                               "%s: order-2 boundary loop does not alternate corner and "
                               "mid-side nodes", which);
    }
    /* tip corners: the tip end of every flank table (root to tip) */
    gd->tipc = gs_calloc((size_t)m->n_nodes, 1);
    if (!gd->tipc)
        return GS_ENOMEM;
    for (int f = 0; f < 2 * m->n_teeth; f++)
        if (m->flank_ptr[f + 1] > m->flank_ptr[f]) {
            gs_index nd = m->flank_nodes[m->flank_ptr[f + 1] - 1];
            if (nd >= 0 && nd < m->n_nodes)
                gd->tipc[nd] = 1;
        }
    /* flank spacing from flank 0 of tooth 0 */
    gs_index f0 = m->flank_ptr[0], f1 = m->flank_ptr[1];
    double len = 0.0;
    for (gs_index q = f0; q + 1 < f1; q++) {
        const double *a = m->xy + 2 * m->flank_nodes[q], *b = m->xy + 2 * m->flank_nodes[q + 1];
        len += hypot(b[0] - a[0], b[1] - a[1]);
    }
    gd->flank_spacing = f1 - f0 > 1 ? len / (double)(f1 - f0 - 1) : 0.0;
    return GS_OK;
}

gs_err gs_contact_search_new(const gs_mesh *m0, const gs_gear_params *g0, const gs_mesh *m1,
                             const gs_gear_params *g1, const gs_contact_opts *o,
                             gs_contact_search **out, gs_diag *d)
{
    if (!out)
        return GS_EINVAL;
    *out = NULL;
    if (!m0 || !g0 || !m1 || !g1)
        return gs_diag_set(d, GS_EINVAL, "gears", "two meshes and two gears are required");
    gs_contact_opts def;
    if (!o) {
        gs_contact_opts_defaults(&def);
        o = &def;
    }
    if (o->window < 3 || o->window > GS_CONTACT_WINDOW_MAX || o->window % 2 == 0)
        return gs_diag_set(d, GS_ERANGE, "contact.window",
                           "master window: an odd number of nodes from 3 to %d (got %d)",
                           GS_CONTACT_WINDOW_MAX, o->window);
    if (!(o->band_m >= 0.0) || !isfinite(o->band_m))
        return gs_diag_set(d, GS_ERANGE, "contact.band", "band must be >= 0 and finite");
    if (!(o->depth_m >= 0.0) || !isfinite(o->depth_m))
        return gs_diag_set(d, GS_ERANGE, "contact.depth", "depth must be >= 0 and finite");
    if (o->passes != GS_CONTACT_TWO_PASS && o->passes != GS_CONTACT_ONE_PASS)
        return gs_diag_set(d, GS_ERANGE, "contact.passes", "passes: one or two");
    if (g0->kind == GS_GEAR_INTERNAL && g1->kind == GS_GEAR_INTERNAL)
        return gs_diag_set(d, GS_EINVAL, "gears", "two internal gears cannot mesh");
    gs_contact_search *s = gs_calloc(1, sizeof *s);
    if (!s)
        return GS_ENOMEM;
    gs_err e = gear_prepare(&s->g[0], m0, g0, 0, d);
    if (e == GS_OK)
        e = gear_prepare(&s->g[1], m1, g1, 1, d);
    if (e != GS_OK) {
        gs_contact_search_free(&s);
        return e;
    }
    s->o = *o;
    double mm = fmin(s->g[0].mod, s->g[1].mod);
    s->band = o->band_m > 0.0 ? o->band_m : 0.1 * mm;
    s->depth = o->depth_m > 0.0 ? o->depth_m : 0.5 * mm;
    *out = s;
    return GS_OK;
}

void gs_contact_search_free(gs_contact_search **s)
{
    if (!s || !*s)
        return;
    for (int i = 0; i < 2; i++) {
        free((*s)->g[i].ang);
        free((*s)->g[i].bpos);
        free((*s)->g[i].tipc);
    }
    free((*s)->cand);
    free(*s);
    *s = NULL;
}

/* Body-frame position X + u of node nd. */
static void body_pos(const gear_data *gd, const gs_contact_pose *ps, gs_index nd, double y[2])
{
    y[0] = gd->m->xy[2 * nd];
    y[1] = gd->m->xy[2 * nd + 1];
    if (ps->u) {
        y[0] += ps->u[2 * nd];
        y[1] += ps->u[2 * nd + 1];
    }
}

/* Scene position of node nd, with c, sn the cosine and sine of ps->theta
 * (taken once per pose by the callers that place many nodes). */
static void scene_pos_cs(const gear_data *gd, const gs_contact_pose *ps, double c, double sn, gs_index nd,
                         double x[2])
{
    double y[2];
    body_pos(gd, ps, nd, y);
    x[0] = ps->c[0] + c * y[0] - sn * y[1];
    x[1] = ps->c[1] + sn * y[0] + c * y[1];
}

static void scene_pos(const gear_data *gd, const gs_contact_pose *ps, gs_index nd, double x[2])
{
    scene_pos_cs(gd, ps, cos(ps->theta), sin(ps->theta), nd, x);
}

static double seg_d2(const double y[2], const double a[2], const double b[2])
{
    double d[2] = {b[0] - a[0], b[1] - a[1]}, w[2] = {y[0] - a[0], y[1] - a[1]};
    double dd = d[0] * d[0] + d[1] * d[1];
    double t = dd > 0.0 ? (w[0] * d[0] + w[1] * d[1]) / dd : 0.0;
    t = t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t);
    double e0 = w[0] - t * d[0], e1 = w[1] - t * d[1];
    return e0 * e0 + e1 * e1;
}

static gs_index wrapi(gs_index j, gs_index n)
{
    if (j >= 0 && j < n) /* nearly always: no division */
        return j;
    j %= n;
    return j < 0 ? j + n : j;
}

/* Distance^2 from y (B's body frame) to boundary segment j -> j+1. */
static double bseg_d2(const gear_data *gb, const gs_contact_pose *pb, const double y[2],
                      gs_index j)
{
    double a[2], b[2];
    body_pos(gb, pb, gb->m->boundary[wrapi(j, gb->nb)], a);
    body_pos(gb, pb, gb->m->boundary[wrapi(j + 1, gb->nb)], b);
    return seg_d2(y, a, b);
}

/* Nearest boundary segment of B to y (B's body frame): bisection on the
 * polar angle, then a descent along the loop. Returns its start position. */
static gs_index nearest_segment(const gear_data *gb, const gs_contact_pose *pb, const double y[2],
                                double *d2_out)
{
    const gs_index nb = gb->nb;
    double phi = atan2(y[1], y[0]);
    double a0 = gb->ang[0];
    phi = a0 + fmod(fmod(phi - a0, 2.0 * GS_PI) + 2.0 * GS_PI, 2.0 * GS_PI);
    gs_index lo = 0, hi = nb; /* ang[lo] <= phi < ang[hi], ang[nb] := a0 + 2 pi */
    while (hi - lo > 1) {
        gs_index mid = lo + (hi - lo) / 2;
        if (gb->ang[mid] <= phi)
            lo = mid;
        else
            hi = mid;
    }
    gs_index best = lo;
    double bd = INFINITY;
    for (gs_index j = lo - WALK_HALF; j <= lo + WALK_HALF; j++) {
        double d2 = bseg_d2(gb, pb, y, j);
        if (d2 < bd) {
            bd = d2;
            best = j;
        }
    }
    for (int dir = -1; dir <= 1; dir += 2) {
        for (gs_index steps = 0; steps < nb; steps++) {
            double d2 = bseg_d2(gb, pb, y, best + dir);
            if (!(d2 < bd))
                break;
            bd = d2;
            best += dir;
        }
    }
    *d2_out = bd;
    return wrapi(best, nb);
}

static gs_err push(gs_contact_search *s, const gs_contact_candidate *c)
{
    gs_contact_candidate *p = gs_grow(s->cand, &s->cap, (size_t)s->n + 1, sizeof *p);
    if (!p)
        return GS_ENOMEM;
    s->cand = p;
    s->cand[s->n++] = *c;
    return GS_OK;
}

/* The master window of slave candidate c around boundary position j0 of B,
 * material on the left, and its body-frame positions. */
static void make_window(const gear_data *gb, const gs_contact_pose *pb, gs_index j0, int k,
                        gs_contact_candidate *c, double *pts)
{
    int half = (k - 1) / 2;
    c->n_window = k;
    for (int q = 0; q < k; q++) {
        gs_index off = gb->internal ? half - q : q - half;
        c->window[q] = gb->m->boundary[wrapi(j0 + off, gb->nb)];
        body_pos(gb, pb, c->window[q], pts + 2 * q);
    }
}

/* Order 2: the window of E = (k - 1) / 2 whole parabolic edges around the
 * edge that holds boundary segment j -> j+1 of B (that edge central; E even:
 * the extra edge on the side of the edge's end nearer to y), material on
 * the left, corners at even positions. */
static void make_window_quad(const gear_data *gb, const gs_contact_pose *pb, gs_index j,
                             const double y[2], int k, gs_contact_candidate *c, double *pts)
{
    const int E = (k - 1) / 2;
    gs_index c0 = (j % 2 == gb->cpar) ? j : j - 1; /* first corner of the edge */
    gs_index start;
    if (E % 2)
        start = c0 - 2 * ((E - 1) / 2);
    else {
        double a[2], b[2];
        body_pos(gb, pb, gb->m->boundary[wrapi(c0, gb->nb)], a);
        body_pos(gb, pb, gb->m->boundary[wrapi(c0 + 2, gb->nb)], b);
        bool near_a = hypot(y[0] - a[0], y[1] - a[1]) <= hypot(y[0] - b[0], y[1] - b[1]);
        start = near_a ? c0 - E : c0 - E + 2;
    }
    c->n_window = k;
    for (int q = 0; q < k; q++) {
        gs_index off = gb->internal ? start + (k - 1 - q) : start + q;
        c->window[q] = gb->m->boundary[wrapi(off, gb->nb)];
        body_pos(gb, pb, c->window[q], pts + 2 * q);
    }
}

typedef struct pass_ctx {
    gs_contact_search *s;
    int ia, ib;
    const gs_contact_pose *pose;
    double cB[2], zoneR2;
    bool zone_inside; /* B external: |x - cB| <= R; ring: >= R */
    bool flanks;      /* flank interior nodes are slaves in this pass */
    double ca, sa, cb, sb; /* cosine and sine of A's and B's rotations */
    gs_index tested;
} pass_ctx;

static gs_err try_node(pass_ctx *pc, gs_index nd, int tooth, int where, bool corner)
{
    gs_contact_search *s = pc->s;
    const gear_data *ga = &s->g[pc->ia], *gb = &s->g[pc->ib];
    if (!corner && !pc->flanks)
        return GS_OK;
    double x[2];
    scene_pos_cs(ga, &pc->pose[pc->ia], pc->ca, pc->sa, nd, x);
    double dx = x[0] - pc->cB[0], dy = x[1] - pc->cB[1], r2 = dx * dx + dy * dy;
    if (pc->zone_inside ? r2 > pc->zoneR2 : r2 < pc->zoneR2)
        return GS_OK;
    pc->tested++;
    const gs_contact_pose *pb = &pc->pose[pc->ib];
    double cb = pc->cb, sb = pc->sb;
    double y[2] = {cb * dx + sb * dy, -sb * dx + cb * dy};
    double d2;
    gs_index j = nearest_segment(gb, pb, y, &d2);
    double dist = sqrt(d2);
    if (dist > fmax(s->band, s->depth))
        return GS_OK;
    gs_contact_candidate c;
    memset(&c, 0, sizeof c);
    double pts[2 * GS_CONTACT_WINDOW_MAX];
    /* Within the band the node is a candidate whatever its gap: the gap is
     * evaluated only for the depth test beyond it (the rows evaluate their
     * own, with the displacements; most of a search's cost was this). */
    bool need_gap = dist > s->band;
    gs_gap gap = {.g = NAN};
    if (gb->order == 2) {
        make_window_quad(gb, pb, j, y, s->o.window, &c, pts);
        if (need_gap)
            GS_TRY(gs_gap_eval_quad(y, pts, c.n_window, &gap));
    } else {
        double a[2], b[2];
        body_pos(gb, pb, gb->m->boundary[j], a);
        body_pos(gb, pb, gb->m->boundary[wrapi(j + 1, gb->nb)], b);
        gs_index j0 = hypot(y[0] - a[0], y[1] - a[1]) <= hypot(y[0] - b[0], y[1] - b[1])
                          ? j
                          : wrapi(j + 1, gb->nb);
        make_window(gb, pb, j0, s->o.window, &c, pts);
        if (need_gap) {
            GS_TRY(gs_gap_eval(y, pts, c.n_window, &gap));
            GS_TRY(tip_corner_distance(gb, pts, &c, y, &gap));
        }
    }
    if (need_gap && !(gap.g < 0.0 && dist <= s->depth))
        return GS_OK;
    c.slave = pc->ia;
    c.master = pc->ib;
    c.slave_node = nd;
    c.slave_tooth = tooth;
    c.slave_where = where;
    c.distance = dist;
    c.gap = gap.g;
    return push(s, &c);
}

/* Half-width (rad) of the angular interval of A's tooth annulus inside B's
 * zone, around the direction of B's centre (or away from it for a ring B);
 * negative when the annulus misses the zone. */
static double zone_half_width(const gear_data *ga, const gear_data *gb, double d, double R,
                              double band)
{
    double lo = ga->rho_lo - band, hi = ga->rho_hi + band;
    if (lo < 1e-9 * hi)
        lo = 1e-9 * hi;
    double kap_lo = (lo * lo + d * d - R * R) / (2.0 * lo * d);
    double kap_hi = (hi * hi + d * d - R * R) / (2.0 * hi * d);
    if (!gb->internal) {
        /* cos(beta) >= kappa; kappa(rho) has one minimum, at sqrt(d^2 - R^2) */
        double rs = sqrt(fmax(d * d - R * R, 0.0));
        rs = rs < lo ? lo : (rs > hi ? hi : rs);
        double kap = (rs * rs + d * d - R * R) / (2.0 * rs * d);
        if (kap > 1.0)
            return -1.0;
        return acos(kap < -1.0 ? -1.0 : kap);
    }
    /* ring: cos(beta) <= kappa; the largest kappa is at an end */
    double kap = fmax(kap_lo, kap_hi);
    if (kap < -1.0)
        return -1.0;
    return GS_PI - acos(kap > 1.0 ? 1.0 : kap);
}

static gs_err run_pass(gs_contact_search *s, const gs_contact_pose pose[2], int ia,
                       gs_contact_stats *st, gs_index *tested)
{
    const gear_data *ga = &s->g[ia], *gb = &s->g[1 - ia];
    pass_ctx pc = {.s = s, .ia = ia, .ib = 1 - ia, .pose = pose};
    pc.ca = cos(pose[ia].theta);
    pc.sa = sin(pose[ia].theta);
    pc.cb = cos(pose[1 - ia].theta);
    pc.sb = sin(pose[1 - ia].theta);
    pc.cB[0] = pose[1 - ia].c[0];
    pc.cB[1] = pose[1 - ia].c[1];
    double ex = pc.cB[0] - pose[ia].c[0], ey = pc.cB[1] - pose[ia].c[1], d = hypot(ex, ey);
    double R = gb->internal ? gb->ra - s->band : gb->ra + s->band;
    pc.zone_inside = !gb->internal;
    pc.zoneR2 = R > 0.0 ? R * R : 0.0;
    if (s->o.passes == GS_CONTACT_TWO_PASS)
        pc.flanks = true;
    else {
        double h0 = s->g[0].flank_spacing, h1 = s->g[1].flank_spacing;
        pc.flanks = ia == 0 ? h0 <= h1 : h1 < h0;
    }
    double half = zone_half_width(ga, gb, d, R, s->band);
    st->n_teeth[ia] = 0;
    if (half < 0.0)
        return GS_OK;
    const int z = ga->z;
    const double pitch = 2.0 * GS_PI / z;
    double phic = atan2(ey, ex) + (gb->internal ? GS_PI : 0.0);
    double reach = half + 0.5 * pitch + s->band / fmax(ga->rho_lo, 1e-12);
    long tc = lround((phic - pose[ia].theta) / pitch);
    long nmax = (long)ceil(reach / pitch) + 1;
    long olo = -nmax, ohi = nmax;
    if (ohi - olo + 1 > z) { /* every tooth once */
        olo = -(z - 1) / 2;
        ohi = z / 2;
    }
    const gs_mesh *m = ga->m;
    for (long o = olo; o <= ohi; o++) {
        int t = (int)(((tc + o) % z + z) % z);
        double at = pose[ia].theta + pitch * (double)t;
        if (fabs(wrap_pi(at - phic)) > reach)
            continue;
        if (st->n_teeth[ia] < 16)
            st->teeth[ia][st->n_teeth[ia]] = t;
        st->n_teeth[ia]++;
        gs_index f0b = m->flank_ptr[2 * t], f0e = m->flank_ptr[2 * t + 1];
        gs_index f1b = m->flank_ptr[2 * t + 1], f1e = m->flank_ptr[2 * t + 2];
        for (gs_index q = f0b; q < f0e; q++)
            GS_TRY(try_node(&pc, m->flank_nodes[q], t, 0, q == f0e - 1));
        if (f0e > f0b && f1e > f1b) {
            gs_index p0 = ga->bpos[m->flank_nodes[f0e - 1]];
            gs_index p1 = ga->bpos[m->flank_nodes[f1e - 1]];
            if (p0 >= 0 && p1 >= 0) {
                gs_index step = p1 > p0 ? 1 : -1;
                for (gs_index j = p0 + step; j != p1; j += step) {
                    gs_index nd = m->boundary[j];
                    if (m->node_tag[nd] == GS_NODE_TIP)
                        GS_TRY(try_node(&pc, nd, t, 2, true));
                }
            }
        }
        for (gs_index q = f1e - 1; q >= f1b; q--)
            GS_TRY(try_node(&pc, m->flank_nodes[q], t, 1, q == f1e - 1));
    }
    *tested += pc.tested;
    return GS_OK;
}

static bool pose_ok(const gs_contact_pose *p)
{
    return isfinite(p->c[0]) && isfinite(p->c[1]) && isfinite(p->theta);
}

gs_err gs_contact_search_run(gs_contact_search *s, const gs_contact_pose pose[2],
                             const gs_contact_candidate **cand, gs_index *n,
                             gs_contact_stats *stats)
{
    if (!s || !pose || !cand || !n)
        return GS_EINVAL;
    *cand = NULL;
    *n = 0;
    if (!pose_ok(&pose[0]) || !pose_ok(&pose[1]))
        return GS_EINVAL;
    double ex = pose[1].c[0] - pose[0].c[0], ey = pose[1].c[1] - pose[0].c[1];
    double d = hypot(ex, ey);
    if (!(d > 0.0))
        return GS_EINVAL;
    gs_contact_stats st;
    memset(&st, 0, sizeof st);
    /* pitch point on the working pitch circles (radii in the ratio of the
     * tooth counts) */
    const double z0 = s->g[0].z, z1 = s->g[1].z;
    if (s->g[1].internal) {
        double f = z1 / (z1 - z0);
        st.pitch_point[0] = pose[1].c[0] - f * ex;
        st.pitch_point[1] = pose[1].c[1] - f * ey;
    } else if (s->g[0].internal) {
        double f = z0 / (z0 - z1);
        st.pitch_point[0] = pose[0].c[0] + f * ex;
        st.pitch_point[1] = pose[0].c[1] + f * ey;
    } else {
        double f = z0 / (z0 + z1);
        st.pitch_point[0] = pose[0].c[0] + f * ex;
        st.pitch_point[1] = pose[0].c[1] + f * ey;
    }
    s->n = 0;
    gs_index tested = 0;
    for (int ia = 0; ia < 2; ia++)
        GS_TRY(run_pass(s, pose, ia, &st, &tested));
    st.nodes_tested = tested;
    st.n_candidates = s->n;
    if (stats)
        *stats = st;
    *cand = s->cand;
    *n = s->n;
    return GS_OK;
}

/* Order 1 at a master tip corner V (window position v), the slave outside
 * the master: the Euclidean distance to the two segments at V instead of
 * the blended
 * R-function wedge, whose gradient off the zero set turns towards the
 * corner's bisector (a predicted row of a flank node beside the flank then
 * pushes along neither flank nor tip: locking, docs/explanation/contact.md "Tip
 * corners"). Used where gs_gap_eval blends V's wedge or projects beyond V
 * on a segment ending at V; elsewhere the gap is untouched. The distance
 * is that of gs_gap_eval_quad on the two segments as straight parabolic
 * edges (mid-side nodes at the midpoints), its gradient on a midpoint
 * shared half and half by the segment's ends; the row keeps the two nodes
 * of the nearer segment (n_master 2). */
static gs_err tip_corner_distance(const gear_data *gb, const double *pts, const gs_contact_candidate *cand,
                                  const double x[2], gs_gap *gap)
{
    const int k = cand->n_window;
    int v = -1;
    if (gap->kind == GS_GAP_CONVEX && gap->n_master == 3)
        v = gap->master[1];
    else if (gap->kind == GS_GAP_LINE) {
        int i = gap->segment;
        const double *a = pts + 2 * i, *b = pts + 2 * i + 2;
        double d[2] = {b[0] - a[0], b[1] - a[1]};
        double tau = ((x[0] - a[0]) * d[0] + (x[1] - a[1]) * d[1]) / (d[0] * d[0] + d[1] * d[1]);
        v = tau >= 1.0 ? i + 1 : (tau <= 0.0 ? i : -1);
    }
    /* outside the master only: inside, the wedge's rows (the seed's, which
     * makes rows at g <= 0 alone) stay as they were; on the zero set both
     * are zero with the segment's normal as gradient */
    if (v < 1 || v > k - 2 || !gb->tipc[cand->window[v]] || !(gap->g > 0.0))
        return GS_OK;
    double q[10];
    for (int c = 0; c < 2; c++) {
        q[c] = pts[2 * (v - 1) + c];
        q[4 + c] = pts[2 * v + c];
        q[8 + c] = pts[2 * (v + 1) + c];
        q[2 + c] = 0.5 * (q[c] + q[4 + c]);
        q[6 + c] = 0.5 * (q[4 + c] + q[8 + c]);
    }
    gs_gap qg;
    GS_TRY(gs_gap_eval_quad(x, q, 5, &qg));
    const int e = qg.segment; /* segment v - 1 + e of the window */
    double ga[2], gb2[2];
    for (int c = 0; c < 2; c++) {
        ga[c] = qg.grad[2 + c] + 0.5 * qg.grad[4 + c];
        gb2[c] = qg.grad[6 + c] + 0.5 * qg.grad[4 + c];
    }
    memset(gap, 0, sizeof *gap);
    gap->g = qg.g;
    gap->kind = GS_GAP_CORNER;
    gap->segment = v - 1 + e;
    gap->xi = qg.xi;
    gap->n_master = 2;
    gap->master[0] = v - 1 + e;
    gap->master[1] = v + e;
    gap->master[2] = -1;
    gap->grad[0] = qg.grad[0];
    gap->grad[1] = qg.grad[1];
    gap->grad[2] = ga[0];
    gap->grad[3] = ga[1];
    gap->grad[4] = gb2[0];
    gap->grad[5] = gb2[1];
    return GS_OK;
}

/* For a flank slave (not a tip corner): a master tip node whose own row
 * covers this one, or -1. (a) The slave is outside the master beside an
 * edge of its tip land (both ends tip nodes): the end nearer the
 * projection. (b) The master tip corner V (a window node) whose outer
 * normal cone holds the slave point x: V convex, x - V at an obtuse-or-right angle to both
 * boundary pieces leaving V (x projects onto V from either side), so V is
 * the master's nearest point and x lies outside it. Tangents at V: the
 * segments at order 1, the end tangents of the two parabolic edges at
 * order 2. Returns V's mesh node, or -1. */
static bool tip_node(const gear_data *gb, gs_index nd)
{
    return gb->tipc[nd] || gb->m->node_tag[nd] == GS_NODE_TIP;
}

static gs_index corner_fan(const gear_data *gb, const double *pts, const gs_contact_candidate *cand,
                           const double x[2], const gs_gap *gap)
{
    const int k = cand->n_window, st = gb->order == 2 ? 2 : 1;
    /* outside the master beside its tip land: the nearer end of that edge */
    if (gap->g > 0.0 && gap->n_master >= 2) {
        gs_index a = cand->window[gap->master[0]], b = cand->window[gap->master[gap->n_master - 1]];
        if (tip_node(gb, a) && tip_node(gb, b))
            return gap->xi < 0.5 ? a : b;
    }
    for (int q = st; q + st < k; q += st) {
        if (!gb->tipc[cand->window[q]])
            continue;
        const double *V = pts + 2 * q;
        double tin[2], tout[2];
        for (int c = 0; c < 2; c++) {
            if (st == 1) {
                tin[c] = V[c] - pts[2 * (q - 1) + c];
                tout[c] = pts[2 * (q + 1) + c] - V[c];
            } else { /* P'(1) of edge (q-2, q-1, q), P'(0) of edge (q, q+1, q+2) */
                tin[c] = pts[2 * (q - 2) + c] - 4.0 * pts[2 * (q - 1) + c] + 3.0 * V[c];
                tout[c] = -3.0 * V[c] + 4.0 * pts[2 * (q + 1) + c] - pts[2 * (q + 2) + c];
            }
        }
        double d[2] = {x[0] - V[0], x[1] - V[1]};
        if (tin[0] * tout[1] - tin[1] * tout[0] > 0.0 && d[0] * tin[0] + d[1] * tin[1] > 0.0 &&
            d[0] * tout[0] + d[1] * tout[1] < 0.0)
            return cand->window[q];
    }
    return -1;
}

gs_err gs_contact_eval(const gs_contact_search *s, const gs_contact_pose pose[2],
                       const gs_contact_candidate *cand, gs_contact_row *row)
{
    if (!s || !pose || !cand || !row)
        return GS_EINVAL;
    if (cand->slave < 0 || cand->slave > 1 || cand->master != 1 - cand->slave ||
        cand->n_window < 2 || cand->n_window > GS_CONTACT_WINDOW_MAX)
        return GS_EINVAL;
    const gear_data *ga = &s->g[cand->slave], *gb = &s->g[cand->master];
    if (cand->slave_node < 0 || cand->slave_node >= ga->m->n_nodes)
        return GS_EINVAL;
    double pts[2 * GS_CONTACT_WINDOW_MAX], x[2];
    const double cm = cos(pose[cand->master].theta), sm = sin(pose[cand->master].theta);
    for (int q = 0; q < cand->n_window; q++) {
        if (cand->window[q] < 0 || cand->window[q] >= gb->m->n_nodes)
            return GS_EINVAL;
        scene_pos_cs(gb, &pose[cand->master], cm, sm, cand->window[q], pts + 2 * q);
    }
    scene_pos(ga, &pose[cand->slave], cand->slave_node, x);
    memset(row, 0, sizeof *row);
    if (gb->order == 2)
        GS_TRY(gs_gap_eval_quad(x, pts, cand->n_window, &row->gap));
    else {
        GS_TRY(gs_gap_eval(x, pts, cand->n_window, &row->gap));
        GS_TRY(tip_corner_distance(gb, pts, cand, x, &row->gap));
    }
    row->fan_corner = s->g[cand->slave].tipc[cand->slave_node] || cand->slave_where == 2
                          ? -1
                          : corner_fan(gb, pts, cand, x, &row->gap);
    row->n_nodes = 1 + row->gap.n_master;
    for (int q = 0; q < row->n_nodes; q++) {
        int b = q ? cand->master : cand->slave;
        row->body[q] = b;
        if (q == 0) {
            row->node[q] = cand->slave_node;
            row->x[q][0] = x[0];
            row->x[q][1] = x[1];
        } else {
            int w = row->gap.master[q - 1];
            row->node[q] = cand->window[w];
            row->x[q][0] = pts[2 * w];
            row->x[q][1] = pts[2 * w + 1];
        }
        const double *dg = row->gap.grad + 2 * q;
        double xc[2] = {row->x[q][0] - pose[b].c[0], row->x[q][1] - pose[b].c[1]};
        gs_gap_chain(dg, pose[b].theta, xc, &row->dg_dtheta[b], row->dg_du[q]);
        row->dg_dc[b][0] += dg[0];
        row->dg_dc[b][1] += dg[1];
    }
    return GS_OK;
}
