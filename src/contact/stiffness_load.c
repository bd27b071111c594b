/* SPDX-License-Identifier: MIT
 * Quasi-static mesh stiffness (stiffness.c): one load case. The contact rows
 * at the current position, their near-field correction (corner contacts and
 * the flanks' own gap), the contact window and the QP solve iterated until
 * the driver's rotation settles, and the load shared out over the tooth
 * pairs. */
#include <hdf5.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "contact/stiffness_hook.h"
#include "contact/stiffness_internal.h"
#include "gearsim/contact.h"
#include "gearsim/fe.h"
#include "gearsim/fe_static.h"
#include "gearsim/mesh.h"
#include "gearsim/models.h"
#include "gearsim/qp.h"
#include "gearsim/stiffness.h"
#include "io/h5attr.h"
#include "gearsim/util.h"

void gsi_stiff_work_free(work *w)
{
    for (int k = 0; k < 2; k++) {
        gsi_stiff_sbody_free(&w->b[k]);
        free(w->rd[k]);
    }
    gs_contact_search_free(&w->search);
    free(w->row);
    free(w->cand);
    free(w->teeth);
    free(w->gsl);
    free(w->kept);
    free(w->H);
    free(w->cvec);
    free(w->x);
    free(w->lam_in);
    free(w->Gm);
    free(w->gz);
    free(w->gbar);
    free(w->a);
    free(w->fq);
    free(w->uq);
    gs_qp_free(&w->qp);
}

static gs_err work_reserve(work *w, int n)
{
    if (n <= w->cap)
        return GS_OK;
    int c = n > 2 * w->cap ? n : 2 * w->cap;
    size_t cn = (size_t)c;
    GROW(w->row, cn);
    GROW(w->cand, cn);
    GROW(w->H, cn * cn);
    GROW(w->Gm, cn * cn);
    GROW(w->cvec, cn);
    GROW(w->x, cn);
    GROW(w->lam_in, cn);
    GROW(w->gz, cn);
    GROW(w->gbar, cn);
    GROW(w->a, cn);
    GROW(w->teeth, cn);
    GROW(w->gsl, 8 * cn);
    for (int k = 0; k < 2; k++)
        GROW(w->rd[k], cn);
    w->cap = c;
    return GS_OK;
}

static void set_poses(const work *w, double delta, gs_contact_pose pose[2])
{
    for (int k = 0; k < 2; k++) {
        int s = w->si[k];
        pose[s].c[0] = w->b[k].c[0];
        pose[s].c[1] = w->b[k].c[1];
        pose[s].theta = w->theta0[k] + (k == 0 ? delta : 0.0);
        pose[s].u = w->b[k].u;
    }
}

/* Tooth pair (driver tooth, driven tooth) of a candidate. */
static void cand_teeth(const work *w, const gs_contact_candidate *c, int tooth[2])
{
    gs_index mnode = c->window[c->n_window / 2];
    for (int k = 0; k < 2; k++) {
        const sbody *b = &w->b[k];
        tooth[k] = c->slave == w->si[k] ? c->slave_tooth
                                        : gsi_stiff_node_tooth(b->mesh, b->sb->gear.teeth, mnode);
    }
}

/* The near-field entry of tooth pair t (gsi_stiff_nf_offsets; one per pair), or NULL. */
static const struct gap_off *gap_off_find(const work *w, const int t[2])
{
    for (int p = 0; p < w->n_go; p++)
        if (w->go[p].tooth[0] == t[0] && w->go[p].tooth[1] == t[1])
            return &w->go[p];
    return NULL;
}

/* The gap offset of the rows of tooth pair t whose slave is search gear
 * slave (gsi_stiff_nf_offsets; 0 when none). */
static double gap_offset(const work *w, const int t[2], int slave)
{
    const struct gap_off *go = gsi_stiffness_nf_no_offsets ? NULL : gap_off_find(w, t);
    return go && (go->slave < 0 || go->slave == slave) ? go->off : 0.0;
}

/* Make the displacement zones cover what the last search read: the teeth
 * it visited on each gear and their neighbours (the master segments near a
 * slave node), and every node of its candidates. A zone that grows after
 * displacements were computed in this roll position leaves wrong (zero)
 * displacements behind at the new nodes: w->restart is set and the
 * position is solved again from the start (GS_EINTERNAL here). */
int gsi_stiffness_zone_late = 0; /* src/contact/stiffness_hook.h */
int gsi_stiffness_nf_no_offsets = 0; /* src/contact/stiffness_hook.h */

gs_err gsi_stiff_zone_cover(work *w, const gs_contact_stats *st, const gs_contact_candidate *cand,
                            gs_index nc)
{
    for (int k = 0; k < 2; k++) {
        sbody *b = &w->b[k];
        if (!b->zone_on || b->zall || (gsi_stiffness_zone_late && !(b->dirty && w->n_prev == 1)))
            continue;
        int s = w->si[k], grew = 0, z = b->sb->gear.teeth;
        if (st->n_teeth[s] > 16)
            for (int t = 0; t < z; t++)
                grew |= gsi_stiff_zone_add(b, t);
        else
            for (int i = 0; i < st->n_teeth[s]; i++)
                grew |= gsi_stiff_zone_add(b, st->teeth[s][i]);
        for (gs_index j = 0; j < nc; j++) {
            const gs_contact_candidate *c = &cand[j];
            if (c->slave == s && !b->zt[b->btooth[b->bpos[c->slave_node]]])
                grew |= gsi_stiff_zone_add(b, b->btooth[b->bpos[c->slave_node]]);
            if (c->master == s)
                for (int q = 0; q < c->n_window; q++)
                    if (!b->zt[b->btooth[b->bpos[c->window[q]]]])
                        grew |= gsi_stiff_zone_add(b, b->btooth[b->bpos[c->window[q]]]);
        }
        if (grew) {
            gsi_stiff_zone_rebuild(b);
            if (b->dirty)
                w->restart = 1;
        }
    }
    return w->restart ? GS_EINTERNAL : GS_OK;
}

/* Search and evaluate at the current state; keep the rows the driver's
 * rotation in the torque direction closes (a_i s < 0) and any row already
 * penetrated, of those only the rows whose gap is below win (the contact
 * window; INFINITY: all). Returns their number in *nr and the smallest gap
 * in *gmin. */
gs_err gsi_stiff_collect(work *w, double delta, double win, int *nr, double *gmin)
{
    gs_contact_pose pose[2];
    set_poses(w, delta, pose);
    const gs_contact_candidate *cand;
    gs_index nc;
    gs_contact_stats st;
    GS_TRY(gs_contact_search_run(w->search, pose, &cand, &nc, &st));
    GS_TRY(gsi_stiff_zone_cover(w, &st, cand, nc));
    GS_TRY(work_reserve(w, (int)nc + 1));
    if (nc + 1 > w->capk) {
        GROW(w->kept, (size_t)nc + 1);
        w->capk = nc + 1;
    }
    w->call = cand;
    w->ncall = nc;
    int n = 0;
    double lo = INFINITY;
    double tiny = 1e-6 * w->rb;
    for (gs_index j = 0; j < nc; j++) {
        gs_contact_row r;
        w->kept[j] = 0;
        GS_TRY(gs_contact_eval(w->search, pose, &cand[j], &r));
        int tp[2];
        bool have_tp = w->n_go > 0; /* near-field gap offsets: only they need the pair here */
        if (have_tp) {
            cand_teeth(w, &cand[j], tp);
            r.gap.g -= gap_offset(w, tp, cand[j].slave);
        }
        double a = r.dg_dtheta[w->si[0]];
        if (!(a * w->sgn < -tiny || r.gap.g < 0.0))
            continue;
        if (!(r.gap.g < win)) {
            w->win_dropped++;
            continue;
        }
        if (r.gap.g < lo)
            lo = r.gap.g;
        w->kept[j] = 1;
        w->row[n] = r;
        w->cand[n] = &cand[j];
        if (!have_tp)
            cand_teeth(w, &cand[j], tp);
        w->teeth[n][0] = tp[0];
        w->teeth[n][1] = tp[1];
        n++;
    }
    *nr = n;
    *gmin = lo;
    return GS_OK;
}

/* Per row: the body-k nodes and their dg/du. */
static int row_nodes(const work *w, const gs_contact_row *r, int k, gs_index *node, double (*g)[2])
{
    int n = 0;
    for (int t = 0; t < r->n_nodes; t++)
        if (r->body[t] == w->si[k]) {
            node[n] = r->node[t];
            g[n][0] = r->dg_du[t][0];
            g[n][1] = r->dg_du[t][1];
            n++;
        }
    return n;
}

/* Near-field correction of the compliance of row i: c of its tooth pair
 * from the previous linearisation (0 when none). */
static double nf_compliance(const work *w, int i)
{
    const int *t = w->teeth[i];
    for (int p = 0; p < w->n_pc; p++)
        if (w->pc[p].tooth[0] == t[0] && w->pc[p].tooth[1] == t[1])
            return w->pc[p].c;
    return 0.0;
}

/* Shape functions of the element of body b containing the reference point
 * q (corner barycentrics; 6-node elements with their mid-side nodes taken
 * at the edge midpoints, true away from curved boundary edges). Returns the
 * number of nodes (3 or 6) in node/N, 0 when q is in no element. */
static int locate(const gs_mesh *m, const double q[2], gs_index node[6], double N[6])
{
    for (gs_index e = 0; e < m->n_tris; e++) {
        const gs_index *t = m->tri + 3 * e;
        const double *p0 = m->xy + 2 * t[0], *p1 = m->xy + 2 * t[1], *p2 = m->xy + 2 * t[2];
        double det = (p1[0] - p0[0]) * (p2[1] - p0[1]) - (p2[0] - p0[0]) * (p1[1] - p0[1]);
        double l1 = ((q[0] - p0[0]) * (p2[1] - p0[1]) - (p2[0] - p0[0]) * (q[1] - p0[1])) / det;
        double l2 = ((p1[0] - p0[0]) * (q[1] - p0[1]) - (q[0] - p0[0]) * (p1[1] - p0[1])) / det;
        double l0 = 1.0 - l1 - l2, tol = -1e-10;
        if (l0 < tol || l1 < tol || l2 < tol)
            continue;
        double L[3] = {l0, l1, l2};
        for (int i = 0; i < 3; i++)
            node[i] = t[i];
        if (!m->mid) {
            for (int i = 0; i < 3; i++)
                N[i] = L[i];
            return 3;
        }
        for (int i = 0; i < 3; i++) {
            N[i] = L[i] * (2.0 * L[i] - 1.0);
            node[3 + i] = m->mid[3 * e + i];
            N[3 + i] = 4.0 * L[i] * L[(i + 1) % 3];
        }
        return 6;
    }
    return 0;
}

/* Near-field approach of body k from its surface to depth d under the line
 * load Pm (N/m) of a pair of effective radius reff: the Hertzian law at the
 * contact centre; next to a tip corner of body kc (kc >= 0), the flanks'
 * touching point xv from the corner, gs_corner_line_approach (the corner
 * body a wedge of factor kw where the load reaches the corner). */
static double nf_body_approach(const work *w, double reff, int kc, double xv, double kw, int k,
                               double Pm, double depth)
{
    const gs_material *mk = &w->b[k].sb->material;
    if (kc < 0) {
        double a = gs_hertz_line_half_width(Pm, reff, w->nf_estar);
        return gs_hertz_line_approach(Pm, a, depth, mk->youngs_pa, mk->poisson, mk->plane);
    }
    return gs_corner_line_approach(Pm, reff, xv, depth, mk->youngs_pa, mk->poisson, mk->plane,
                                   w->nf_estar, k == kc ? kw : 2.0 / GS_PI);
}

/* Near-field approach (both bodies, surface to their depths) of pair p under
 * the normal load lam (N), divided by lam. */
static double nf_hertz(const work *w, int p, double lam)
{
    double Pm = lam / w->nf_bw, s = 0.0;
    for (int k = 0; k < 2; k++)
        s += nf_body_approach(w, w->pc[p].reff, w->pc[p].kc, w->pc[p].xv, w->pc[p].kw, k, Pm,
                              w->pc[p].depth[k]);
    return s / lam;
}

/* Unit normal of the involute of body k through the point X (scene frame):
 * the line through X tangent to the base circle; of its two directions
 * (either flank) the one nearest +-nref. */
static void involute_normal(const work *w, int k, const double X[2], const double nref[2], double n[2])
{
    const gs_gear_params *gp = &w->b[k].sb->gear;
    double ex = X[0] - w->b[k].c[0], ey = X[1] - w->b[k].c[1], r = hypot(ex, ey);
    double rb = gs_gear_base_radius(gp), sb = fmin(rb / r, 1.0), cb = sqrt(1.0 - sb * sb);
    ex /= r;
    ey /= r;
    double best = -1.0;
    for (int sg = -1; sg <= 1; sg += 2) {
        double m[2] = {cb * ex - sg * sb * ey, cb * ey + sg * sb * ex};
        double dp = fabs(m[0] * nref[0] + m[1] * nref[1]);
        if (dp > best) {
            best = dp;
            n[0] = m[0];
            n[1] = m[1];
        }
    }
}

/* Normal load of every stored pair in the current solution; c from it. */
static void nearfield_refresh(work *w, int nr)
{
    for (int p = 0; p < w->n_pc; p++) {
        double lam = 0.0;
        for (int i = 0; i < nr; i++) {
            if (w->x[i] <= 0.0)
                continue;
            const int *t = w->teeth[i];
            if (t[0] == w->pc[p].tooth[0] && t[1] == w->pc[p].tooth[1])
                lam += w->x[i];
        }
        if (w->pc[p].skip || !(lam > 1e-6 * w->ftot))
            w->pc[p].c = 0.0;
        else
            w->pc[p].c = fmax(nf_hertz(w, p, lam) - w->pc[p].L, 0.0);
    }
}

/* Tangent near-field compliance of pair p at the loads of the current
 * solution (nr rows): d(delta_H)/dP less the FE's surface-to-Q part L, by a
 * central difference of 0.1 % in the load; 0 where the secant correction is
 * none (gs_stiffness_run_nearfield). The tangent, not delta_H / P: a small
 * motion about the loaded contact keeps the contact zone (the incremental
 * stiffness of a Hertzian contact is that of a flat punch of its width). */
double gsi_stiff_nf_tangent(const work *w, int nr, int p)
{
    if (p < 0 || p >= w->n_pc || w->pc[p].skip || !(w->pc[p].c > 0.0))
        return 0.0;
    double lam = 0.0;
    for (int i = 0; i < nr; i++)
        if (w->x[i] > 0.0 && w->teeth[i][0] == w->pc[p].tooth[0] && w->teeth[i][1] == w->pc[p].tooth[1])
            lam += w->x[i];
    if (!(lam > 1e-6 * w->ftot))
        return 0.0;
    double e = 1e-3, hi = (1.0 + e) * lam, lo = (1.0 - e) * lam;
    double dd = (hi * nf_hertz(w, p, hi) - lo * nf_hertz(w, p, lo)) / (hi - lo);
    return fmax(dd - w->pc[p].L, 0.0);
}

/* Relative curvature 1/R_1 + 1/R_2 (*curv, 1/m) of the flanks at the
 * contact point X (scene frame): involute radii sqrt(r^2 - r_b^2), concave
 * for an internal gear; each body's signed curvature in kb (may be NULL).
 * Returns a mask of the bodies (bit k) for which X is within GS_NF_CORNER
 * module of the tip circle: a tip-corner contact, not a Hertzian line
 * contact (0: a flank contact). */
static int pair_curvature(const work *w, const double X[2], double *curv, double kb[2])
{
    int corner = 0;
    *curv = 0.0;
    for (int k = 0; k < 2; k++) {
        const gs_gear_params *gp = &w->b[k].sb->gear;
        double rr = hypot(X[0] - w->b[k].c[0], X[1] - w->b[k].c[1]);
        double rt = gs_gear_tip_radius(gp), eps = GS_NF_CORNER * gp->module_m;
        if (gp->kind == GS_GEAR_INTERNAL ? rr < rt + eps : rr > rt - eps)
            corner |= 1 << k;
        double rb = gs_gear_base_radius(gp);
        double Rk = fmax(sqrt(fmax(rr * rr - rb * rb, 0.0)), 0.05 * gp->module_m);
        double ck = (gp->kind == GS_GEAR_INTERNAL ? -1.0 : 1.0) / Rk;
        *curv += ck;
        if (kb)
            kb[k] = ck;
    }
    return corner;
}

/* The exact rigid gap (*g, m) of a tip corner, the slave node of row r
 * (candidate cd; rigid bodies, u = 0), against the involute flank of the
 * master body kf: its involute's base angle phi0 from the master window's
 * nodes on the involute (r_form <= r <= r_tip; the boundary nodes lie on
 * the exact outline), F(X) = theta_X - s inv(alpha_X) (constant, phi0, on
 * an involute unwound in the sense s = +-1, the sense for which the nodes
 * agree), and the distance of the corner P from it along P's normal line to
 * the base circle, s r_b (phi0 - F(P)), signed by the master's outward
 * normal (the row's gap gradient). Returns 0 (no *g) when fewer than two
 * window nodes are on the involute, they do not agree, or the foot of P
 * is off the involute (a corner on the fillet). */
static int corner_exact_gap(const work *w, int kf, const gs_contact_row *r,
                            const gs_contact_candidate *cd, double *g)
{
    const sbody *b = &w->b[kf];
    const gs_gear_params *gp = &b->sb->gear;
    double rb = gs_gear_base_radius(gp), ra = gs_gear_tip_radius(gp), rf = w->nf_rform[kf];
    double rlo = fmin(rf, ra), rhi = fmax(rf, ra);
    double th = w->theta0[kf] + (kf == 0 ? w->nf_dc : 0.0), cs = cos(th), sn = sin(th);
    double best = INFINITY, phi0 = 0.0;
    int sbest = 0;
    for (int sg = -1; sg <= 1; sg += 2) {
        double f0 = 0.0, lo = INFINITY, hi = -INFINITY;
        int n = 0;
        for (int j = 0; j < cd->n_window; j++) {
            const double *X = b->mesh->xy + 2 * cd->window[j];
            double rr = hypot(X[0], X[1]);
            if (!(rr >= rlo * (1.0 + 1e-9) && rr <= rhi * (1.0 - 1e-9) && rr > rb))
                continue;
            double ang = atan2(sn * X[0] + cs * X[1], cs * X[0] - sn * X[1]);
            double F = ang - sg * gs_involute(acos(rb / rr));
            if (n == 0)
                f0 = F;
            double dF = remainder(F - f0, 2.0 * GS_PI);
            lo = fmin(lo, dF);
            hi = fmax(hi, dF);
            n++;
        }
        if (n >= 2 && hi - lo < best) {
            best = hi - lo;
            sbest = sg;
            phi0 = f0 + 0.5 * (hi + lo);
        }
    }
    if (!(best * rb < 1e-8))
        return 0;
    const double *P = r->x[0];
    double px = P[0] - b->c[0], py = P[1] - b->c[1], rp = hypot(px, py);
    if (!(rp > rb))
        return 0;
    double al = acos(rb / rp), thp = atan2(py, px);
    double dF = remainder(thp - sbest * gs_involute(al) - phi0, 2.0 * GS_PI);
    double phT = thp + sbest * al;
    double T[2] = {rb * cos(phT), rb * sin(phT)};
    double u[2] = {px - T[0], py - T[1]}, lt = hypot(u[0], u[1]);
    double foot = lt + sbest * rb * dF; /* |Y'T|: the involute's point on P's normal line */
    double rfoot = hypot(rb, foot);
    if (!(rfoot >= rlo && rfoot <= rhi + 1e-3 * gp->module_m))
        return 0;
    double dn = -sbest * rb * dF;
    double gn = hypot(r->gap.grad[0], r->gap.grad[1]);
    if (!(gn > 0.0))
        return 0;
    double side = (u[0] * r->gap.grad[0] + u[1] * r->gap.grad[1]) / (lt * gn);
    *g = side >= 0.0 ? dn : -dn;
    return 1;
}

/* Where a pair flagged as a tip-corner contact (the corner P of body kc is
 * its nearest node) touches, for conjugate involutes of two external gears:
 * the line of action (the common internal tangent of the base circles
 * nearest the corner's involute normal) crosses the corner's involute at
 * roll length rho_v = rho_tip + s r_b (phi(T_v) - phi(T_tip)) (T the
 * tangent points of the involute's normals at the crossing and at P, s its
 * unwinding sense). Returns 1 with the crossing in X (scene frame) when it
 * is inside the corner's flank (rho_v < rho_tip) and on both involutes
 * (above both form radii): a flank contact next to the corner, whose rows
 * sample it with no node beyond the corner; 0 when the crossing is beyond
 * the tip: a true corner contact. */
static int corner_loa(const work *w, int kc, const double P[2], const double nref[2], double X[2],
                      double *xv)
{
    const sbody *bc = &w->b[kc], *bf = &w->b[1 - kc];
    if (bc->sb->gear.kind == GS_GEAR_INTERNAL || bf->sb->gear.kind == GS_GEAR_INTERNAL)
        return 0;
    double rbc = gs_gear_base_radius(&bc->sb->gear), rbf = gs_gear_base_radius(&bf->sb->gear);
    double px = P[0] - bc->c[0], py = P[1] - bc->c[1], rp = hypot(px, py);
    if (!(rp > rbc))
        return 0;
    /* The corner's involute normal: of the two tangents from P, the one
     * nearest the flank body's involute normal at P. */
    double nf_[2], nc_[2];
    involute_normal(w, 1 - kc, P, nref, nf_);
    involute_normal(w, kc, P, nf_, nc_);
    /* Tangent point of the corner's normal line on base circle kc. */
    double tpar = px * nc_[0] + py * nc_[1];
    double T[2] = {px - tpar * nc_[0], py - tpar * nc_[1]};
    double rho_tip = sqrt(rp * rp - rbc * rbc);
    double sg = (T[0] * py - T[1] * px) < 0.0 ? 1.0 : -1.0; /* -sign(e_T x (P - T)) */
    /* The line of action: unit normal m, m.X = h, tangent to both base
     * circles with the circles on opposite sides. */
    double D[2] = {bf->c[0] - bc->c[0], bf->c[1] - bc->c[1]}, a = hypot(D[0], D[1]);
    double cg = (rbc + rbf) / a;
    if (!(cg < 1.0))
        return 0;
    double sgm = sqrt(1.0 - cg * cg), Dh[2] = {D[0] / a, D[1] / a}, Dp[2] = {-Dh[1], Dh[0]};
    double m[2] = {0.0, 0.0}, best = INFINITY;
    for (int i = 0; i < 4; i++) {
        double c1 = (i & 1) ? -cg : cg, s1 = (i & 2) ? -sgm : sgm;
        double mm[2] = {c1 * Dh[0] + s1 * Dp[0], c1 * Dh[1] + s1 * Dp[1]};
        double q = fabs(mm[0] * nc_[0] + mm[1] * nc_[1]);
        if (q < best) {
            best = q;
            m[0] = mm[0];
            m[1] = mm[1];
        }
    }
    /* Circle kc at the origin here: m.C_c - h = sc rbc, m.D = -sc (rbc + rbf). */
    double sc = -(m[0] * D[0] + m[1] * D[1]) / (rbc + rbf);
    double Tv[2] = {-sc * rbc * m[0], -sc * rbc * m[1]}; /* foot from the centre */
    double dphi = remainder(atan2(Tv[1], Tv[0]) - atan2(T[1], T[0]), 2.0 * GS_PI);
    double rho_v = rho_tip + sg * rbc * dphi;
    /* Along the common tangent: the involute's arc between the roll lengths. */
    *xv = (rho_tip * rho_tip - rho_v * rho_v) / (2.0 * rbc);
    if (!(rho_v < rho_tip) || !(rho_v > 0.0))
        return 0;
    double e[2] = {Tv[0] / rbc, Tv[1] / rbc};
    double Xl[2] = {Tv[0] + rho_v * sg * e[1], Tv[1] - rho_v * sg * e[0]};
    double rcv = hypot(Xl[0], Xl[1]);
    X[0] = bc->c[0] + Xl[0];
    X[1] = bc->c[1] + Xl[1];
    double rfv = hypot(X[0] - bf->c[0], X[1] - bf->c[1]);
    double raf = gs_gear_tip_radius(&bf->sb->gear);
    return rcv >= w->nf_rform[kc] && rfv >= w->nf_rform[1 - kc] && rfv <= raf;
}

/* Near-field correction, rigid bodies at the kinematic position turned by
 * nf_dc (conjugate flanks with backlash: where every pair touches; else
 * delta 0), u = 0: per tooth pair the part of its rows' gap that comes from sampling
 * the flanks at nodes. The rows of one pass sample the gap between the two
 * flanks at the slave nodes along the common tangent (coordinate s); near a
 * line contact it is smooth and convex, g(s) = g0 + (s - s0)^2 / (2 R) to
 * leading order, and the nearest node sits up to h^2 / (8 R) above the
 * minimum g0 (h the node spacing). Per pass the parabola through the row of
 * smallest gap and its neighbours on either side (within GS_NF_FIT module)
 * gives g0 at its vertex (when the vertex lies between them), taken from
 * the pass whose master flank has the larger involute radius (the flatter
 * one, whose parabolic edges depart least from it: near a form point the
 * other pass sees the edges' bulge). The offset min_i g_i - g0 is taken off every row of
 * the pair (gsi_stiff_collect): the pair first touches where its flanks do, not
 * where its nearest node does, and the Hertz law (nearfield_measure) gives
 * the approach about that contact. Tip-corner contacts, and pairs without
 * a vertex, keep 0. */
static gs_err nf_offsets_at(work *w)
{
    w->n_go = 0;
    int nr;
    double gmin;
    GS_TRY(gsi_stiff_collect(w, w->nf_dc, INFINITY, &nr, &gmin));
    for (int i = 0; i < nr; i++) {
        const int *t = w->teeth[i];
        if (gap_off_find(w, t) || w->n_go == (int)(sizeof w->go / sizeof w->go[0]))
            continue;
        /* The pair's row of smallest gap: its contact point and tangent. */
        int im = -1;
        for (int j = 0; j < nr; j++)
            if (w->teeth[j][0] == t[0] && w->teeth[j][1] == t[1] &&
                (im < 0 || w->row[j].gap.g < w->row[im].gap.g))
                im = j;
        const gs_contact_row *rm = &w->row[im];
        double curv, nn = hypot(rm->gap.grad[0], rm->gap.grad[1]);
        bool corner = pair_curvature(w, rm->x[0], &curv, NULL) != 0;
        double off = 0.0, g0best = 0.0, win = GS_NF_FIT * w->b[0].sb->gear.module_m;
        double rho_best = 0.0, xv[2] = {0.0, 0.0};
        int ng0 = 0;
        for (int pass = 0; pass < 2 && !corner && nn > 0.0; pass++) {
            double tg[2] = {-rm->gap.grad[1] / nn, rm->gap.grad[0] / nn};
            int jm = -1, jl = -1, jh = -1;
            double sl = -INFINITY, sh = INFINITY;
            for (int j = 0; j < nr; j++)
                if (w->teeth[j][0] == t[0] && w->teeth[j][1] == t[1] &&
                    (w->cand[j]->slave == w->si[pass]) &&
                    (jm < 0 || w->row[j].gap.g < w->row[jm].gap.g))
                    jm = j;
            if (jm < 0)
                continue;
            const double *xm = w->row[jm].x[0];
            for (int j = 0; j < nr; j++) {
                if (j == jm || w->teeth[j][0] != t[0] || w->teeth[j][1] != t[1] ||
                    w->cand[j]->slave != w->si[pass])
                    continue;
                double sj = (w->row[j].x[0][0] - xm[0]) * tg[0] + (w->row[j].x[0][1] - xm[1]) * tg[1];
                if (sj < 0.0 && sj > sl && sj >= -win) {
                    sl = sj;
                    jl = j;
                }
                if (sj > 0.0 && sj < sh && sj <= win) {
                    sh = sj;
                    jh = j;
                }
            }
            if (jl < 0 || jh < 0)
                continue;
            double gm = w->row[jm].gap.g, sv, g0;
            if (!gs_gap_vertex3(sl, w->row[jl].gap.g, gm, sh, w->row[jh].gap.g, GS_NF_FIT_CURV * 0.5 * curv,
                                &sv, &g0))
                continue;
            /* The pass whose master flank is the flatter (larger involute
             * radius: its parabolic edges follow it more closely) wins. */
            const gs_gear_params *gpm = &w->b[1 - pass].sb->gear;
            double rr = hypot(xm[0] - w->b[1 - pass].c[0], xm[1] - w->b[1 - pass].c[1]);
            double rbm = gs_gear_base_radius(gpm);
            double rho = sqrt(fmax(rr * rr - rbm * rbm, 0.0));
            if (ng0 == 0 || rho > rho_best) {
                rho_best = rho;
                g0best = g0;
                xv[0] = xm[0] + sv * tg[0];
                xv[1] = xm[1] + sv * tg[1];
            }
            ng0 = 1;
        }
        int oslave = -1, flank = 0, okc = -1;
        double oxv = 0.0;
        int cmask = corner ? pair_curvature(w, rm->x[0], &(double){0.0}, NULL) : 0;
        if ((cmask == 1 || cmask == 2) && w->nf_conj) {
            /* A tip corner of body kc: its row (the corner node as slave). */
            int kc = cmask == 1 ? 0 : 1, ic = -1;
            double rtc = gs_gear_tip_radius(&w->b[kc].sb->gear);
            for (int j = 0; j < nr; j++) {
                if (w->teeth[j][0] != t[0] || w->teeth[j][1] != t[1] ||
                    w->cand[j]->slave != w->si[kc])
                    continue;
                double rr = hypot(w->row[j].x[0][0] - w->b[kc].c[0], w->row[j].x[0][1] - w->b[kc].c[1]);
                if (fabs(rr - rtc) < 1e-3 * w->b[kc].sb->gear.module_m &&
                    (ic < 0 || w->row[j].gap.g < w->row[ic].gap.g))
                    ic = j;
            }
            double gex, gn = ic >= 0 ? hypot(w->row[ic].gap.grad[0], w->row[ic].gap.grad[1]) : 0.0;
            double nref[2] = {gn > 0.0 ? w->row[ic].gap.grad[0] / gn : 0.0,
                              gn > 0.0 ? w->row[ic].gap.grad[1] / gn : 0.0};
            double xvc = NAN;
            int inside = gn > 0.0 && corner_loa(w, kc, w->row[ic].x[0], nref, xv, &xvc);
            if (isfinite(xvc) && (inside || xvc < 0.0)) {
                okc = kc;
                oxv = xvc;
            }
            if (inside) {
                /* Conjugate flanks touching next to the corner: a flank
                 * contact at xv, g0 = 0 (as below). */
                flank = 1;
                ng0 = 1;
            } else if (okc >= 0 && corner_exact_gap(w, 1 - kc, &w->row[ic], w->cand[ic], &gex)) {
                /* A true corner contact: the rows of the corner node take
                 * its exact gap (the master's parabolic edges near its form
                 * point may sit ~1 um off the involute at the default
                 * density). */
                off = w->row[ic].gap.g - gex;
                oslave = w->si[kc];
            }
        }
        if (ng0 > 0)
            off = rm->gap.g - (w->nf_conj ? 0.0 : g0best);
        w->go[w->n_go].tooth[0] = t[0];
        w->go[w->n_go].tooth[1] = t[1];
        w->go[w->n_go].off = off;
        w->go[w->n_go].slave = oslave;
        w->go[w->n_go].flank = flank;
        w->go[w->n_go].kc = okc;
        w->go[w->n_go].xv = oxv;
        w->go[w->n_go].has_x = ng0 > 0;
        w->go[w->n_go].ref = rm->gap.g - off;
        if (ng0 > 0) {
            /* Driver's body frame at the rows' angle. */
            double th = w->theta0[0] + w->nf_dc, cs = cos(th), sn = sin(th);
            double dx = xv[0] - w->b[0].c[0], dy = xv[1] - w->b[0].c[1];
            w->go[w->n_go].xb[0] = cs * dx + sn * dy;
            w->go[w->n_go].xb[1] = -sn * dx + cs * dy;
        }
        w->n_go++;
    }
    return GS_OK;
}

/* Modified flanks (relief, deviations) of a pair whose perfect gears are
 * conjugate involutes: the rows sample the modified flanks at the same
 * nodes as the perfect ones, moved along the normal by the modification,
 * whose curvature is a small fraction of the involute's (a linear relief
 * of C over L adds about (C / L) r_b^2 / rho^3 to 1 / rho: 1-2 %). So the
 * nodes' sampling error of the perfect flanks (the conjugate rule: every
 * pair touches at the kinematic angle turned through nf_dc, the tip
 * corners' exact gaps) is taken for the modified ones too, and the pair's
 * flank gap (the reference of its rows' rigid gaps) is the modified rows'
 * smallest gap less that offset: the relief at the contact. The vertex fit
 * on the modified rows, which it replaces, put single pairs up to 6 %
 * off the unmodified pair's TE in the limit of a vanishing relief
 * (tests/validation/test_stiffness.c nearfield_modified_limit). */
gs_err gsi_stiff_nf_offsets(work *w)
{
    if (!w->nf_refconj)
        return nf_offsets_at(w);
    double *keep[2];
    for (int k = 0; k < 2; k++) {
        keep[k] = w->b[k].mesh->xy;
        if (w->b[k].xy_ref)
            w->b[k].mesh->xy = w->b[k].xy_ref;
    }
    w->nf_conj = 1;
    gs_err e = nf_offsets_at(w);
    w->nf_conj = 0;
    for (int k = 0; k < 2; k++)
        w->b[k].mesh->xy = keep[k];
    if (e != GS_OK)
        return e;
    int nr, ngo = w->n_go;
    double gmin;
    w->n_go = 0; /* the modified rows' own gaps, no offset taken off */
    e = gsi_stiff_collect(w, w->nf_dc, INFINITY, &nr, &gmin);
    w->n_go = ngo;
    if (e != GS_OK)
        return e;
    for (int p = 0; p < w->n_go; p++) {
        double gp = INFINITY;
        for (int i = 0; i < nr; i++)
            if (w->teeth[i][0] == w->go[p].tooth[0] && w->teeth[i][1] == w->go[p].tooth[1])
                gp = fmin(gp, w->row[i].gap.g);
        if (isfinite(gp))
            w->go[p].ref = gp - w->go[p].off;
    }
    return GS_OK;
}

/* At the converged plain FE solution (rows w->row, forces w->x,
 * displacements in the bodies): the near-field data of every loaded tooth
 * pair. Per pair and body k the FE approach of the contact point
 * (load-weighted over the pair's rows) is to be replaced by the approach of
 * the point Q_k at depth d below it (FE, by reciprocity: one static solve
 * with a unit load at Q_k) plus the Hertzian approach between the surface
 * and depth d (gs_hertz_line_approach, with the half-width of the pair's
 * load and the involute curvature radii at the contact point). Stored: the
 * FE's surface-to-Q approach per unit load L (frozen: it is a property of
 * the mesh under the FE's own load distribution), the depths and the
 * effective radius; nearfield_refresh then sets c = Hertz(lam)/lam - L. */
static gs_err nearfield_measure(work *w, int nr, double delta)
{
    struct {
        int tooth[2];
        double lam, x[2], n[2];
    } g[GS_STIFF_MAX_PAIRS];
    int ng = 0;
    for (int i = 0; i < nr; i++) {
        double l = w->x[i];
        if (l <= 0.0)
            continue;
        const int *t = w->teeth[i];
        int p = 0;
        while (p < ng && (g[p].tooth[0] != t[0] || g[p].tooth[1] != t[1]))
            p++;
        if (p == ng) {
            if (ng == GS_STIFF_MAX_PAIRS)
                continue;
            memset(&g[p], 0, sizeof g[p]);
            g[p].tooth[0] = t[0];
            g[p].tooth[1] = t[1];
            ng++;
        }
        const gs_contact_row *r = &w->row[i];
        /* dg/dx_slave is the master's outward normal: the driver's outward
         * normal is +that when the driven gear is the master. */
        double sd = w->cand[i]->slave == w->si[0] ? -1.0 : 1.0;
        g[p].lam += l;
        g[p].x[0] += l * r->x[0][0];
        g[p].x[1] += l * r->x[0][1];
        g[p].n[0] += l * sd * r->gap.grad[0];
        g[p].n[1] += l * sd * r->gap.grad[1];
    }
    int np = 0;
    for (int p = 0; p < ng; p++) {
        double lam = g[p].lam, X[2] = {g[p].x[0] / lam, g[p].x[1] / lam};
        double nn = hypot(g[p].n[0], g[p].n[1]);
        if (!(lam > 1e-6 * w->ftot) || !(nn > 0.0))
            continue;
        /* The flanks' contact point (gsi_stiff_nf_offsets) when known, else the rows'
         * load centre. */
        const struct gap_off *go = gap_off_find(w, g[p].tooth);
        bool has_x = go && go->has_x;
        if (has_x) {
            double th = w->theta0[0] + delta, cs = cos(th), sn = sin(th);
            X[0] = w->b[0].c[0] + cs * go->xb[0] - sn * go->xb[1];
            X[1] = w->b[0].c[1] + sn * go->xb[0] + cs * go->xb[1];
        }
        double nD[2] = {g[p].n[0] / nn, g[p].n[1] / nn};
        double curv, kb[2];
        int corner = pair_curvature(w, X, &curv, kb);
        if (go && go->flank)
            corner = 0;
        /* Next to a tip corner of body kc (gsi_stiff_nf_offsets found where the
         * flanks touch, xv from the corner): both bodies get
         * gs_corner_line_approach with both flanks' curvature, the corner
         * body a wedge of half-angle (pi/2 + alpha_tip)/2 loaded normal to
         * its flank face. */
        int kc = -1, only = -1;
        double xvc = 0.0, kw = 0.0;
        if (go && go->kc >= 0) {
            kc = go->kc;
            xvc = go->xv;
            corner = 0;
            const gs_gear_params *gc = &w->b[kc].sb->gear;
            double at = acos(fmin(gs_gear_base_radius(gc) / gs_gear_tip_radius(gc), 1.0));
            double al = 0.25 * GS_PI + 0.5 * at;
            kw = gs_wedge_apex_factor(al, 0.5 * GS_PI - al);
        } else if ((corner == 1 || corner == 2) && kb[corner == 1 ? 1 : 0] > 0.0) {
            /* Otherwise (modified flanks, a ring) the flank body alone gets
             * the half-plane law with its own flank curvature; a concave
             * flank, a ring's, under a corner keeps the plain FE. */
            only = corner == 1 ? 1 : 0;
            curv = kb[only];
            corner = 0;
        }
        if (corner) {
            memset(&w->pc[np], 0, sizeof w->pc[np]);
            w->pc[np].tooth[0] = g[p].tooth[0];
            w->pc[np].tooth[1] = g[p].tooth[1];
            w->pc[np].skip = 1;
            w->pc[np].kc = -1;
            np++;
            continue;
        }
        double Pm = lam / w->nf_bw, reff = 1.0 / fmax(curv, 1e-9);
        double c = 0.0, L = 0.0, dep[2] = {0.0, 0.0};
        bool skip = false;
        for (int k = 0; k < 2 && !skip; k++) {
            if (only >= 0 && k != only)
                continue;
            sbody *b = &w->b[k];
            const gs_mesh *m = b->mesh;
            double nk[2] = {k == 0 ? nD[0] : -nD[0], k == 0 ? nD[1] : -nD[1]};
            double th = w->theta0[k] + (k == 0 ? delta : 0.0), cs = cos(th), sn = sin(th);
            double eb[2] = {-(cs * nk[0] + sn * nk[1]), -(-sn * nk[0] + cs * nk[1])};
            gs_index node[6];
            double N[6];
            int nq = 0;
            double depth = w->nf_depth;
            /* Q in the body; near a tip the normal may leave the tooth
             * before depth d: a smaller depth then, else no correction. */
            for (int tries = 0; tries < 4 && nq == 0; tries++, depth *= 0.75) {
                double Q[2] = {X[0] - depth * nk[0] - b->c[0], X[1] - depth * nk[1] - b->c[1]};
                double qb[2] = {cs * Q[0] + sn * Q[1], -sn * Q[0] + cs * Q[1]};
                nq = locate(m, qb, node, N);
            }
            depth /= 0.75;
            if (nq == 0) {
                skip = true;
                break;
            }
            size_t len = (size_t)(2 * m->n_nodes);
            memset(w->fq, 0, len * sizeof *w->fq);
            for (int t = 0; t < nq; t++) {
                w->fq[2 * node[t]] += N[t] * eb[0];
                w->fq[2 * node[t] + 1] += N[t] * eb[1];
            }
            GS_TRY(gs_fe_static_solve(b->fs, 1, w->fq, w->uq));
            /* FE approach at Q (reciprocity) and at the surface, all rows' loads. */
            double aq = 0.0, as = 0.0;
            for (int i = 0; i < nr; i++) {
                double l = w->x[i];
                if (l <= 0.0)
                    continue;
                gs_index nd[4];
                double gg[4][2];
                int mm = row_nodes(w, &w->row[i], k, nd, gg);
                double bq = 0.0, bs = 0.0;
                for (int t = 0; t < mm; t++) {
                    bq += gg[t][0] * w->uq[2 * nd[t]] + gg[t][1] * w->uq[2 * nd[t] + 1];
                    bs += gg[t][0] * b->u[2 * nd[t]] + gg[t][1] * b->u[2 * nd[t] + 1];
                }
                aq += l * bq;
                const int *t = w->teeth[i];
                if (t[0] == g[p].tooth[0] && t[1] == g[p].tooth[1])
                    as += l * bs;
            }
            as /= lam;
            /* The FE carries the pair's load on its slave nodes, up to half
             * a node spacing from the flanks' contact point; Q's
             * displacement under the load there instead (by reciprocity,
             * the unit solve's field at the contact point, just inside the
             * surface) less the one under the nodal loads. */
            double dself = 0.0;
            if (has_x) {
                double xc[2] = {X[0] - b->c[0], X[1] - b->c[1]};
                double xbk[2] = {cs * xc[0] + sn * xc[1], -sn * xc[0] + cs * xc[1]};
                double Qb[2] = {xbk[0] + depth * eb[0], xbk[1] + depth * eb[1]};
                double pin[2] = {xbk[0] + 1e-2 * (Qb[0] - xbk[0]), xbk[1] + 1e-2 * (Qb[1] - xbk[1])};
                gs_index nx[6];
                double Nx[6];
                int nxn = locate(m, pin, nx, Nx);
                if (nxn > 0) {
                    double ux = 0.0, own = 0.0;
                    for (int t = 0; t < nxn; t++)
                        ux += Nx[t] * (eb[0] * w->uq[2 * nx[t]] + eb[1] * w->uq[2 * nx[t] + 1]);
                    for (int i = 0; i < nr; i++) {
                        const int *ti = w->teeth[i];
                        if (w->x[i] <= 0.0 || ti[0] != g[p].tooth[0] || ti[1] != g[p].tooth[1])
                            continue;
                        gs_index nd[4];
                        double gg[4][2];
                        int mm = row_nodes(w, &w->row[i], k, nd, gg);
                        for (int t = 0; t < mm; t++)
                            own += w->x[i] * (gg[t][0] * w->uq[2 * nd[t]] + gg[t][1] * w->uq[2 * nd[t] + 1]);
                    }
                    dself = lam * ux - own;
                }
            }
            double dh = nf_body_approach(w, reff, kc, xvc, kw, k, Pm, depth);
            c += (dh - (as - aq - dself)) / lam;
            L += (as - aq - dself) / lam;
            dep[k] = depth;
        }
        /* The Hertz law is the approach at the contact centre; a loaded row
         * at distance x from it starts x^2 / (2 R) apart (its rigid gap
         * above the pair's, offset taken off) and moves that much less:
         * the FE's centre approach is the rows' plus their load-weighted
         * rigid gap (a^2 / (8 R) once the mesh resolves the pressure). */
        if (!skip && has_x) {
            double gs = 0.0;
            for (int i = 0; i < nr; i++) {
                const int *ti = w->teeth[i];
                if (w->x[i] <= 0.0 || ti[0] != g[p].tooth[0] || ti[1] != g[p].tooth[1])
                    continue;
                const gs_contact_row *r = &w->row[i];
                double du = 0.0;
                for (int t = 0; t < r->n_nodes; t++) {
                    const sbody *b = &w->b[r->body[t] == w->si[0] ? 0 : 1];
                    du += r->dg_du[t][0] * b->u[2 * r->node[t]] + r->dg_du[t][1] * b->u[2 * r->node[t] + 1];
                }
                gs += w->x[i] * (r->gap.g - du - r->dg_dtheta[w->si[0]] * (delta - w->nf_dc) - go->ref);
            }
            c -= gs / (lam * lam);
            L += gs / (lam * lam);
        }
        /* The FE's point load is stiffer than the Hertzian one while the
         * mesh does not resolve a; never add a negative compliance (W must
         * stay positive definite). */
        c = skip ? 0.0 : fmax(c, 0.0);
        w->pc[np].tooth[0] = g[p].tooth[0];
        w->pc[np].tooth[1] = g[p].tooth[1];
        w->pc[np].c = c;
        w->pc[np].L = L;
        w->pc[np].depth[0] = dep[0];
        w->pc[np].depth[1] = dep[1];
        w->pc[np].reff = reff;
        w->pc[np].kc = kc;
        w->pc[np].xv = xvc;
        w->pc[np].kw = kw;
        w->pc[np].skip = skip;
        np++;
    }
    w->n_pc = np;
    return GS_OK;
}

/* One load case from the current state (delta in *delta, displacements in
 * the bodies): iterate linearisations. Fills lambda in w->x, the rows in
 * w->row (nr), and the outcome. */
/* The contact window (docs/explanation/stiffness.md "Contact window"): the first
 * linearisation takes the rows whose gap is below the TE of a soft mesh
 * (GS_WIN_K, a quarter of a usual steel spur mesh stiffness) under the load,
 * the next ones those below GS_WIN_FACTOR times the current elastic TE; the
 * window is widened fourfold whenever a row left out is found penetrated at
 * a settled solution. */
#define GS_WIN_K 5e9      /* N/m^2: 5 N/(mm um) */
#define GS_WIN_FACTOR 2.0

/* 1 when a candidate of the last search left out of the rows by the window
 * is penetrated at the current state (delta, u): the window missed it. */
static gs_err window_missed(work *w, double delta, int *missed)
{
    gs_contact_pose pose[2];
    set_poses(w, delta, pose);
    *missed = 0;
    for (gs_index j = 0; j < w->ncall && !*missed; j++) {
        if (w->kept[j])
            continue;
        gs_contact_row r;
        GS_TRY(gs_contact_eval(w->search, pose, &w->call[j], &r));
        *missed = r.gap.g < 0.0;
    }
    return GS_OK;
}

gs_err gsi_stiff_solve_load(work *w, double T, int max_iter, double delta0, double *delta, int *nr_out,
                            int *iters, int *converged, double *pen, gs_diag *d)
{
    int nr = 0;
    *converged = 0;
    w->n_prev = 0;
    w->n_pc = 0;
    w->ftot = fabs(T) / w->rb;
    int phase = w->nf ? 0 : 1; /* 0: plain FE; 1: with the near-field correction */
    if (w->nf)
        max_iter *= 4; /* the fixed point on the pair loads converges linearly */
    double bw = fmin(w->b[0].sb->gear.face_width_m, w->b[1].sb->gear.face_width_m);
    double wscale = 1.0;
    double win = w->win_on ? w->ftot / (bw * GS_WIN_K) : INFINITY;
    for (int it = 0; it < max_iter; it++) {
        double gmin;
        GS_TRY(gsi_stiff_collect(w, *delta, win, &nr, &gmin));
        if (nr == 0)
            return gs_diag_set(d, GS_EINFEASIBLE, "meshes",
                               "no contact row can carry the torque at this position");
        /* Columns of every node in a row. */
        for (int k = 0; k < 2; k++) {
            gs_index nodes[4 * 512];
            int nn = 0;
            for (int i = 0; i < nr; i++) {
                gs_index nd[4];
                double gg[4][2];
                int m = row_nodes(w, &w->row[i], k, nd, gg);
                for (int t = 0; t < m; t++) {
                    if (nn == (int)(sizeof nodes / sizeof nodes[0])) {
                        GS_TRY(gsi_stiff_sbody_need(&w->b[k], nn, nodes));
                        nn = 0;
                    }
                    nodes[nn++] = nd[t];
                }
            }
            GS_TRY(gsi_stiff_sbody_need(&w->b[k], nn, nodes));
        }
        /* W = sum_k B_k C_k B_k^T from the cached compliance among the
         * rows' dofs: row i of body k is sum_t g_it . u(node_it). */
        size_t n = (size_t)nr;
        memset(w->H, 0, n * n * sizeof *w->H);
        for (int k = 0; k < 2; k++) {
            sbody *b = &w->b[k];
            rowdofs *rd = w->rd[k];
            for (int i = 0; i < nr; i++) {
                gs_index nd[4];
                double gg[4][2];
                rd[i].m = row_nodes(w, &w->row[i], k, nd, gg);
                for (int t = 0; t < rd[i].m; t++)
                    for (int c = 0; c < 2; c++) {
                        rd[i].slot[2 * t + c] = b->slot[2 * b->bpos[nd[t]] + c];
                        rd[i].g[2 * t + c] = gg[t][c];
                    }
            }
            int ns = 0;
            for (int i = 0; i < nr; i++)
                for (int p = 0; p < 2 * rd[i].m; p++)
                    w->gsl[ns++] = rd[i].slot[p];
            gsi_stiff_sbody_gram(b, ns, w->gsl);
            size_t cap = (size_t)b->capd;
            for (int i = 0; i < nr; i++)
                for (int j = 0; j <= i; j++) {
                    double sum = 0.0;
                    for (int p = 0; p < 2 * rd[i].m; p++) {
                        const double *Gp = b->G + (size_t)rd[i].slot[p] * cap;
                        double sp = 0.0;
                        for (int q = 0; q < 2 * rd[j].m; q++)
                            sp += Gp[rd[j].slot[q]] * rd[j].g[q];
                        sum += rd[i].g[p] * sp;
                    }
                    w->H[(size_t)i * n + (size_t)j] += sum;
                }
        }
        if (w->nf && w->n_pc > 0) {
            /* The pair's extra compliance on its rows' block (rank one). */
            for (int i = 0; i < nr; i++) {
                double ci = nf_compliance(w, i);
                if (ci == 0.0)
                    continue;
                const int *ti = w->teeth[i];
                for (int j = 0; j <= i; j++) {
                    const int *tj = w->teeth[j];
                    if (ti[0] == tj[0] && ti[1] == tj[1])
                        w->H[(size_t)i * n + (size_t)j] += ci;
                }
            }
        }
        double dmax = 0.0;
        for (int i = 0; i < nr; i++)
            dmax = fmax(dmax, w->H[(size_t)i * n + (size_t)i]);
        for (int i = 0; i < nr; i++) {
            w->H[(size_t)i * n + (size_t)i] += 1e-9 * dmax;
            for (int j = 0; j < i; j++)
                w->H[(size_t)j * n + (size_t)i] = w->H[(size_t)i * n + (size_t)j];
        }
        /* Linear term and constraint data. */
        for (int i = 0; i < nr; i++) {
            const gs_contact_row *r = &w->row[i];
            double a = r->dg_dtheta[w->si[0]];
            double bu = 0.0;
            for (int t = 0; t < r->n_nodes; t++) {
                const sbody *b = &w->b[r->body[t] == w->si[0] ? 0 : 1];
                bu += r->dg_du[t][0] * b->u[2 * r->node[t]] + r->dg_du[t][1] * b->u[2 * r->node[t] + 1];
            }
            w->a[i] = a;
            w->gbar[i] = r->gap.g - a * *delta - bu;
            w->cvec[i] = -w->gbar[i];
            w->gz[i] = 0.0;
        }
        memset(w->Gm, 0, n * n * sizeof *w->Gm);
        for (int i = 0; i < nr; i++)
            w->Gm[(size_t)i * n + (size_t)i] = 1.0;
        if (!w->qp || w->qp_n < nr) {
            gs_qp_free(&w->qp);
            GS_TRY(gs_qp_new(w->cap, 1, w->cap, &w->qp));
            w->qp_n = w->cap;
        }
        double e = -T, lam_eq = 0.0;
        gs_qp_problem p = {.n = nr, .H = w->H, .c = w->cvec, .n_eq = 1, .E = w->a, .e = &e,
                           .n_in = nr, .G = w->Gm, .g = w->gz};
        gs_qp_result res;
        memset(&res, 0, sizeof res);
        res.x = w->x;
        res.lambda_eq = &lam_eq;
        res.lambda_in = w->lam_in;
        gs_err qe = gs_qp_solve(w->qp, &p, NULL, 0, &res);
        if (qe != GS_OK)
            return gs_diag_set(d, qe, "meshes", "static contact QP failed (%d rows): %s", nr,
                               gs_strerror(qe));
        double dnew = -lam_eq;
        /* Displacements: u_k = C_k B_k^T lambda. */
        for (int k = 0; k < 2; k++) {
            sbody *b = &w->b[k];
            memset(b->fd, 0, (size_t)b->nd * sizeof *b->fd);
            for (int j = 0; j < nr; j++) {
                double l = w->x[j];
                if (l <= 0.0)
                    continue;
                for (int q = 0; q < 2 * w->rd[k][j].m; q++)
                    b->fd[w->rd[k][j].slot[q]] += l * w->rd[k][j].g[q];
            }
            GS_TRY(gsi_stiff_sbody_displace(b));
        }
        /* Settled when delta changed by less than 1e-7 of the elastic
         * rotation twice in a row. The active set is not a criterion: the
         * two passes give two nearly parallel rows per flank contact, whose
         * split of the load is degenerate (the QP may flip between them)
         * while delta, the gaps and the force per tooth pair do not move. */
        if (phase == 1 && w->n_pc > 0)
            nearfield_refresh(w, nr);
        double scale = fabs(dnew - delta0) + 1e-9 / w->rb;
        bool small = fabs(dnew - *delta) <= 1e-7 * scale;
        *delta = dnew;
        *iters = it + 1;
        *nr_out = nr;
        if (w->win_on)
            win = wscale * fmax(GS_WIN_FACTOR * fabs(dnew - delta0) * w->rb,
                                1e-3 * w->ftot / (bw * GS_WIN_K));
        if (small && it > 0 && w->n_prev == 1 && w->win_on) {
            int missed;
            GS_TRY(window_missed(w, dnew, &missed));
            if (missed) {
                wscale *= 4.0;
                win *= 4.0;
                w->win_widened++;
                w->n_prev = 0;
                continue;
            }
        }
        if (small && it > 0 && w->n_prev == 1) {
            if (phase == 0) {
                /* Plain FE settled: measure the near field, then iterate
                 * with the correction. */
                GS_TRY(nearfield_measure(w, nr, dnew));
                phase = 1;
                w->n_prev = 0;
                continue;
            }
            *converged = 1;
            break;
        }
        w->n_prev = small ? 1 : 0;
    }
    /* Penetration left at the final deformed position: the solution's rows
     * re-evaluated there (the candidates stay valid: no search since). */
    gs_contact_pose pose[2];
    set_poses(w, *delta, pose);
    double lo = 0.0;
    for (int i = 0; i < *nr_out; i++) {
        gs_contact_row r;
        GS_TRY(gs_contact_eval(w->search, pose, w->cand[i], &r));
        r.gap.g -= gap_offset(w, w->teeth[i], w->cand[i]->slave);
        if (r.gap.g < lo)
            lo = r.gap.g;
    }
    *pen = -lo;
    return GS_OK;
}

static int cmp_pair(const void *pa, const void *pb)
{
    const gs_stiffness_pair *a = pa, *b = pb;
    return (a->force_n < b->force_n) - (a->force_n > b->force_n);
}

/* Tooth pairs of the solution in w->x / w->row (nr rows). */
void gsi_stiff_pairs_of(const work *w, int nr, double F, gs_stiffness_point *pt)
{
    gs_stiffness_pair acc[64];
    int na = 0;
    for (int i = 0; i < nr; i++) {
        double l = w->x[i];
        if (l <= 0.0)
            continue;
        const int *tooth = w->teeth[i];
        double f = -l * w->a[i] * w->sgn / w->rb;
        int j = 0;
        while (j < na && (acc[j].tooth[0] != tooth[0] || acc[j].tooth[1] != tooth[1]))
            j++;
        if (j == na) {
            if (na == 64)
                continue;
            acc[na].tooth[0] = tooth[0];
            acc[na].tooth[1] = tooth[1];
            acc[na].force_n = 0.0;
            na++;
        }
        acc[j].force_n += f;
    }
    qsort(acc, (size_t)na, sizeof acc[0], cmp_pair);
    pt->pairs = 0;
    for (int j = 0; j < na; j++)
        if (acc[j].force_n >= 0.01 * F)
            pt->pairs++;
    while (na > 0 && acc[na - 1].force_n < 1e-6 * F)
        na--; /* round-off shares */
    pt->n_pair = na < GS_STIFF_MAX_PAIRS ? na : GS_STIFF_MAX_PAIRS;
    for (int j = 0; j < pt->n_pair; j++)
        pt->pair[j] = acc[j];
}
