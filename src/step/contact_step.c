/* SPDX-License-Identifier: MIT
 * The step with contact meshes (METHOD.md sections 3 and 4), rank 0.
 *
 * Every body offered its compliance block C over its interface unknowns
 * (coordinate, candidate node displacements), its free increment d0 and the
 * current displacements of those nodes (src/step/plan.c, records). Here:
 *
 *  1. every candidate of every contact mesh is evaluated at the current
 *     positions (Rvachev gap g and its gradient, src/contact); a candidate
 *     becomes a constraint row when it touches or penetrates (g <= 0), or,
 *     with `constrain: predicted`, when the free motion would take it there
 *     (g + grad g . d0 <= 0);
 *  2. the unknowns are the rigid coordinates and the displacements of the
 *     nodes that enter some row; each body's block of the Hessian is the
 *     inverse of the matching sub-block of its compliance (the compliance of
 *     a subset of unknowns is the sub-block of the compliance: exact static
 *     condensation of every other unknown of the body);
 *  3. the QP  min 1/2 (x - d0)^T H (x - d0)  subject to the kinematic rows
 *     E x = 0 and the linearised, homogeneous contact rows G x >= 0 is solved
 *     by Goldfarb-Idnani (src/qp); with implicit flank friction on some row,
 *     Coulomb's law joins it as the frictional LCP of src/step/contact_friction.c;
 *  4. the interface forces f = E^T mu + G^T lambda go back to the bodies
 *     (exactly zero for a body no row touches), the rigid increments are x.
 * The rows drop g(x_n): the reaction does no work (lambda^T G x = 0 by
 * complementarity), so frictionless contact conserves energy exactly.
 *
 * numerics.contact "closure" (docs/explanation/contact.md, "Contact treatments") keeps
 * the gap instead, G x >= -g(x_n), on every candidate the free motion (or,
 * after a solve, the solution) brings to g <= 0: penetration is closed in
 * the step, up to the linearisation. The reactions then do the work
 * lambda^T G x = -lambda^T g, booked per mesh as contact_work (never in the
 * residual). The rows are the seed's otherwise (the same gap functions,
 * tip corners included). "closure_energy" solves the same rows and also
 * reports the reactions' moments on each mesh's gears, along which
 * gs_step_contact_return gives the work back as a velocity update. */
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "contact/contact_mesh.h"
#include "contact/nearfield_dyn.h"
#include "contact_friction.h"
#include "gearsim/qp.h"
#include "gearsim/util.h"
#include "step_internal.h"

typedef struct row_ref {
    int mesh;
    gs_index cand;  /* the candidate of the mesh's last search */
    double g0;      /* closure: the row is G x >= -g0 (g0 = r.gap.g, or after
                     * a Newton update g(x_k) - G x_k at the iterate x_k) */
    bool fan;       /* watched only: left to a tip node's row (fan_corner); it
                     * becomes a row when the step's end finds it inside
                     * (closure_newton), never from its linearised gap */
    gs_contact_row r;
} row_ref;

/* Closure, Newton on the nonlinear gap: the rows are linearised again at
 * the step's end while the solution leaves some row or watched candidate
 * deeper than this inside (m), at most CLOSURE_NEWTON_MAX times a step. */
#define CLOSURE_NEWTON_TOL 1e-9
#define CLOSURE_NEWTON_MAX 4

typedef struct solver {
    double **u;          /* per body: full nodal displacement array (elastic gears in contact) */
    double **ue;         /* closure: the same at the step's end (plan nodes only) */
    row_ref *rows;
    int n_rows;
    size_t cap_rows;
    row_ref *end;        /* closure_newton: the rows and watched candidates at the step's end */
    size_t cap_end;
    double *q0;          /* closure_newton: the coordinates kept while the poses move */
    size_t cap_q0;
    row_ref *watch;      /* adaptive step: candidates without a row, checked after the solve */
    int n_watch;
    size_t cap_watch;
    int *unk;            /* per body, per plan dof: global unknown, -1 unused */
    size_t cap_unk;
    size_t *base;        /* per body: offset of its plan dofs in unk */
    size_t cap_base;
    int *sel;            /* scratch: selected dofs of one body */
    size_t cap_sel;
    double *ff, *ffm;    /* friction: generalised forces, total and per mesh */
    size_t cap_ff, cap_ffm;
    gsi_friction *fr;    /* friction: tangent rows, implicit solve (src/step/contact_friction.c) */
    double *mg, *mJ, *H0, *c0, *xp, *mf; /* force meshes: g, J, saved H block and c, last x, forces */
    size_t cap_m[6];
    double *H, *c, *E, *e, *G, *g, *x, *lam_eq, *lam_in, *S, *f;
    double *inc;         /* closure: the step's increments of every plan dof */
    size_t cap_inc;
    size_t cap[11];      /* capacities of the eleven arrays above, in that order of reserve() */
    gs_qp *qp;
    int qp_n, qp_eq, qp_in;
    /* Two-phase record: gsi_contact_select found the rows (and these
     * per-mesh contact figures: rows, penetration) for the solve that
     * follows. */
    bool rows_ready;
    double *mct;
    size_t cap_mct;
    /* "nearfield" (src/contact/nearfield_dyn.c): per row its tooth pair's
     * group (-1: none); per group its mesh, pair, unknown and compliance */
    int *grp;
    size_t cap_grp;
    int n_grp;
    struct nf_group {
        int mesh, pair, unk;
        double c;
    } *gr;
    size_t cap_gr;
} solver;

void gsi_contact_free(gs_system *sys)
{
    solver *s = sys->solver;
    if (!s)
        return;
    for (int i = 0; s->u && i < sys->n_bodies; i++)
        free(s->u[i]), free(s->ue[i]);
    free(s->u);
    free(s->ue);
    free(s->rows);
    free(s->end);
    free(s->q0);
    free(s->watch);
    free(s->unk);
    free(s->base);
    free(s->sel);
    free(s->ff);
    free(s->ffm);
    gsi_friction_free(&s->fr);
    free(s->mg), free(s->mJ), free(s->H0), free(s->c0), free(s->xp), free(s->mf);
    free(s->H), free(s->c), free(s->E), free(s->e), free(s->G), free(s->g);
    free(s->x), free(s->lam_eq), free(s->lam_in), free(s->S), free(s->f);
    free(s->inc);
    free(s->mct);
    free(s->grp);
    free(s->gr);
    gs_qp_free(&s->qp);
    free(s);
    sys->solver = NULL;
}

static solver *get_solver(gs_system *sys)
{
    if (sys->solver)
        return sys->solver;
    solver *s = gs_calloc(1, sizeof *s);
    if (!s)
        return NULL;
    s->u = gs_calloc((size_t)sys->n_bodies, sizeof(double *));
    s->ue = gs_calloc((size_t)sys->n_bodies, sizeof(double *));
    if (!s->u || !s->ue) {
        free(s->u);
        free(s->ue);
        free(s);
        return NULL;
    }
    sys->solver = s;
    return s;
}

/* Grow a scratch array of doubles to n (capacity in *cap). */
static bool grow(double **p, size_t *cap, size_t n)
{
    double *q = gs_grow(*p, cap, n, sizeof(double));
    if (!q)
        return false;
    *p = q;
    return true;
}

/* Dense arrays for N unknowns, ne equality rows and ni contact rows. */
static gs_err reserve(solver *s, int N, int ne, int ni, int maxdof)
{
    size_t n = (size_t)N, m = (size_t)(ne + ni) + 1;
    if (!grow(&s->H, &s->cap[0], n * n) || !grow(&s->c, &s->cap[1], n) || !grow(&s->x, &s->cap[2], n) ||
        !grow(&s->E, &s->cap[3], m * n) || !grow(&s->e, &s->cap[4], m) || !grow(&s->G, &s->cap[5], m * n) ||
        !grow(&s->g, &s->cap[6], m) || !grow(&s->lam_eq, &s->cap[7], m) || !grow(&s->lam_in, &s->cap[8], m) ||
        !grow(&s->f, &s->cap[9], n) || !grow(&s->S, &s->cap[10], (size_t)maxdof * (size_t)maxdof))
        return GS_ENOMEM;
    return GS_OK;
}

static gs_err add_row(row_ref **rows, int *n, size_t *cap, int mesh, gs_index cand, const gs_contact_row *r)
{
    row_ref *nr = gs_grow(*rows, cap, (size_t)*n + 1, sizeof *nr);
    if (!nr)
        return GS_ENOMEM;
    *rows = nr;
    nr[*n].mesh = mesh;
    nr[*n].cand = cand;
    nr[*n].g0 = r->gap.g;
    nr[*n].fan = false;
    nr[*n].r = *r;
    (*n)++;
    return GS_OK;
}

/* Plan dof of component comp of plan node k of body i. */
static int node_dof(const gs_system *sys, int i, int k, int comp)
{
    return (sys->bodies[i].coord >= 0 ? 1 : 0) + 2 * k + comp;
}

/* The change of row r's gap over the step, linearised: from the solution x
 * (N unknowns, unknown map unk) where the row's coordinates are unknowns,
 * else from the free increments d0 of the records (x NULL: all free). */
static double gap_change(const gs_system *sys, const solver *s, const gs_contact_row *r,
                         const gsi_contact_mesh *cm, const double *rec, const double *x)
{
    const gs_step_plan *p = &sys->plan;
    double dg = 0.0;
    for (int k = 0; k < 2; k++) {
        int b = cm->body[k], c = sys->bodies[b].coord;
        dg += gsi_centre_translation_dot(sys, b, r->dg_dc[k], x);
        if (c < 0)
            continue;
        int nd = p->n_dof[b];
        dg += r->dg_dtheta[k] * (x ? x[c] : rec[p->rec_off[b] + (size_t)nd * nd]);
    }
    for (int t = 0; t < r->n_nodes; t++) {
        int gk = r->body[t], b = cm->body[gk];
        if (!cm->elastic[gk])
            continue;
        int pk = gsi_plan_find(p, b, r->node[t]);
        if (pk < 0)
            continue;
        int nd = p->n_dof[b];
        const double *d0 = rec + p->rec_off[b] + (size_t)nd * nd;
        for (int comp = 0; comp < 2; comp++) {
            int a = node_dof(sys, b, pk, comp), u = x ? s->unk[s->base[b] + (size_t)a] : -1;
            dg += r->dg_du[t][comp] * (u >= 0 ? x[u] : d0[a]);
        }
    }
    return dg;
}

/* Candidate j of contact mesh cm at the poses: its row, with "nearfield"
 * the pair's gap offset taken off (gsi_nf_row_offset). */
static gs_err eval_row(const gsi_contact_mesh *cm, const gs_contact_pose pose[2], gs_index j, gs_contact_row *r)
{
    GS_TRY(gs_contact_eval(cm->search, pose, &cm->cand[j], r));
    if (cm->nf)
        gsi_nf_row_offset(cm->nf, cm->mesh[0], cm->mesh[1], &cm->cand[j], pose, r);
    return GS_OK;
}

/* True when node `node` of gear k (0 / 1) of contact mesh cm is a slave
 * candidate of this step (tip corners and tip arc nodes are slaves in both
 * search modes when near the other gear). A flank node outside the other
 * gear in the outer normal cone of its tip corner, or beside its tip land
 * (gs_contact_row.fan_corner), gets no row then (docs/explanation/contact.md "Tip
 * corners: no locking"): its gap's gradient there points from the corner
 * to the node, along the flank rather than across it, or radially through
 * the other gear's centre, and such a row holds the flank against the
 * rolling (locking); the contact of a sharp corner with a smooth flank has
 * the flank's normal, which the corner's own row against the flank edges
 * carries. */
static bool corner_is_slave(const gsi_contact_mesh *cm, int k, gs_index node)
{
    for (gs_index j = 0; j < cm->n_cand; j++)
        if (cm->cand[j].slave == k && cm->cand[j].slave_node == node)
            return true;
    return false;
}

/* Evaluate the candidates of contact mesh mi at the current positions and
 * keep those that become rows; returns the deepest penetration. With an
 * adaptive step that can still refine (or closure), the others are kept to
 * watch. */
static gs_err collect_rows(gs_system *sys, solver *s, int mi, const double *rec, double *pen)
{
    gsi_contact_mesh *cm = sys->meshes[mi].contact;
    bool closure = sys->contact_scheme != GS_CONTACT_SEED; /* closure, closure_energy */
    gs_contact_pose pose[2];
    for (int k = 0; k < 2; k++) {
        gs_system_body_pose(sys, cm->body[k], pose[k].c, &pose[k].theta);
        pose[k].u = cm->elastic[k] ? s->u[cm->body[k]] : NULL;
    }
    *pen = 0.0;
    for (gs_index j = 0; j < cm->n_cand; j++) {
        gs_contact_row r;
        GS_TRY(eval_row(cm, pose, j, &r));
        double g = r.gap.g;
        if (-g > *pen)
            *pen = -g;
        if (r.fan_corner >= 0 && corner_is_slave(cm, cm->cand[j].master, r.fan_corner)) {
            /* Outside the master at its tip corner or tip land: that node's
             * own row holds it. The closure still watches it: a flank node
             * can slip past the corner into the flank beside it within a
             * step (a corner's row does not stop the other gear's flank
             * vertex), and the gap at the step's end, not its linearisation
             * here (along the flank), makes it a row then (closure_newton). */
            if (closure) {
                GS_TRY(add_row(&s->watch, &s->n_watch, &s->cap_watch, mi, j, &r));
                s->watch[s->n_watch - 1].fan = true;
            }
            continue;
        }
        bool take = g <= 0.0;
        if (!take && (cm->predict || closure)) /* the free motion's change of g */
            take = g + gap_change(sys, s, &r, cm, rec, NULL) <= 0.0;
        if (take)
            GS_TRY(add_row(&s->rows, &s->n_rows, &s->cap_rows, mi, j, &r));
        else if (closure || sys->level < sys->adapt_levels)
            GS_TRY(add_row(&s->watch, &s->n_watch, &s->cap_watch, mi, j, &r));
    }
    return GS_OK;
}

/* The deepest penetration the solution x would make on a watched
 * candidate (one without a row, so nothing stops it this step). */
static double watched_penetration(const gs_system *sys, const solver *s, const double *rec, const double *x)
{
    double pen = 0.0;
    for (int j = 0; j < s->n_watch; j++) {
        if (s->watch[j].fan)
            continue;
        const gs_contact_row *r = &s->watch[j].r;
        double g = r->gap.g + gap_change(sys, s, r, sys->meshes[s->watch[j].mesh].contact, rec, x);
        pen = fmax(pen, -g);
    }
    return pen;
}

/* Closure: the step's increments of every plan dof (into s->inc, at the
 * bodies' base offsets) from the solution x: an unknown's is x itself, any
 * other dof a of body i moves by d0_a + C_a,sel H_sel (x_sel - d0_sel), the
 * response to the interface forces H_sel (x_sel - d0_sel) on its unknowns
 * (the same forces the body is given back). */
static gs_err plan_increments(const gs_system *sys, solver *s, const double *rec, int N, size_t total_dof)
{
    const gs_step_plan *p = &sys->plan;
    if (!grow(&s->inc, &s->cap_inc, total_dof + 1) || !grow(&s->f, &s->cap[9], (size_t)N))
        return GS_ENOMEM;
    for (int i = 0; i < sys->n_bodies; i++) {
        int nd = p->n_dof[i], k = 0;
        const double *C = rec + p->rec_off[i], *d0 = C + (size_t)nd * nd;
        const int *unk = s->unk + s->base[i];
        double *inc = s->inc + s->base[i];
        for (int a = 0; a < nd; a++)
            if (unk[a] >= 0)
                s->sel[k++] = a;
        /* forces on the selected dofs, in s->f[0 .. k) */
        for (int a = 0; a < k; a++) {
            double v = 0.0;
            for (int b = 0; b < k; b++)
                v += s->H[(size_t)unk[s->sel[a]] * N + unk[s->sel[b]]] * (s->x[unk[s->sel[b]]] - d0[s->sel[b]]);
            s->f[a] = v;
        }
        for (int a = 0; a < nd; a++) {
            if (unk[a] >= 0) {
                inc[a] = s->x[unk[a]];
                continue;
            }
            double v = d0[a];
            for (int b = 0; b < k; b++)
                v += C[(size_t)s->sel[b] * nd + a] * s->f[b];
            inc[a] = v;
        }
    }
    return GS_OK;
}

/* Closure: row r's linear part applied to the increments s->inc (with
 * carrier, the term of a planet's carrier coordinate too, from s->x, as the
 * row of step 4 has it). */
static double inc_dot(const gs_system *sys, const solver *s, const gs_contact_row *r, const gsi_contact_mesh *cm,
                      bool carrier)
{
    const gs_step_plan *p = &sys->plan;
    double g = 0.0;
    for (int k = 0; k < 2; k++) {
        int b = cm->body[k];
        if (sys->bodies[b].coord >= 0)
            g += r->dg_dtheta[k] * s->inc[s->base[b]];
        const gs_body_rt *br = &sys->bodies[b];
        g += gsi_centre_translation_dot(sys, b, r->dg_dc[k], s->x);
        if (carrier && br->carrier >= 0 && br->tcoord < 0) {
            int cc = sys->bodies[br->carrier].coord;
            if (cc >= 0) {
                double pc[2], th;
                gs_system_body_pose(sys, b, pc, &th);
                const double *cC = sys->bodies[br->carrier].centre;
                g += (r->dg_dc[k][0] * -(pc[1] - cC[1]) + r->dg_dc[k][1] * (pc[0] - cC[0])) * s->x[cc];
            }
        }
    }
    for (int t = 0; t < r->n_nodes; t++) {
        int gk = r->body[t], b = cm->body[gk];
        int pk = cm->elastic[gk] ? gsi_plan_find(p, b, r->node[t]) : -1;
        if (pk < 0)
            continue;
        for (int comp = 0; comp < 2; comp++)
            g += r->dg_du[t][comp] * s->inc[s->base[b] + (size_t)node_dof(sys, b, pk, comp)];
    }
    return g;
}

/* Closure: row r's gap at the step's end, linearised, from s->inc. */
static double closure_gap(const gs_system *sys, const solver *s, const gs_contact_row *r,
                          const gsi_contact_mesh *cm)
{
    return r->gap.g + inc_dot(sys, s, r, cm, false);
}

/* Closure, Newton on the nonlinear gap: the gaps of the rows and of the
 * watched candidates at the step's end of the solution x_k (s->x, s->inc;
 * positions from the rigid increments and the nodes' displacement
 * increments, not linearised). The rows' linearisation at the step's start
 * misses a curved gap by about kappa |dx_rel|^2 / 2 (the parabolic edges of
 * order 2: kappa v_s^2 h^2 / 2) and the rotation's arc by r dtheta^2 / 2.
 * When some row or watched candidate ends deeper than CLOSURE_NEWTON_TOL,
 * every row is linearised again at x_k,
 *   g(x_k) + G_k (x - x_k) >= 0,  i.e.  G_k x >= -(g(x_k) - G_k x_k),
 * the watched candidates that end inside become rows the same way, and the
 * step is solved again (*redo). The rows stay linear in the increment with
 * a constant term, like the closure's, so the reactions' work
 * lambda^T G x is booked the same way. */
static gs_err closure_newton(gs_system *sys, solver *s, bool *redo)
{
    const gs_step_plan *p = &sys->plan;
    int n = sys->n_coords;
    *redo = false;
    for (int i = 0; i < sys->n_bodies; i++) {
        if (p->n_nodes[i] == 0 || !s->u[i])
            continue;
        if (!s->ue[i]) {
            const gs_mesh *m = sys->bodies[i].ops->mesh(&sys->bodies[i]);
            s->ue[i] = gs_calloc(2 * (size_t)m->n_nodes, sizeof(double));
            if (!s->ue[i])
                return GS_ENOMEM;
        }
        for (int k = 0; k < p->n_nodes[i]; k++)
            for (int comp = 0; comp < 2; comp++) {
                size_t a = 2 * (size_t)p->nodes[i][k] + (size_t)comp;
                s->ue[i][a] = s->u[i][a] + s->inc[s->base[i] + (size_t)node_dof(sys, i, k, comp)];
            }
    }
    /* The poses at the step's end: the coordinates moved by x_k for the
     * pose only, restored bit for bit below. */
    double *q0 = gs_grow(s->q0, &s->cap_q0, (size_t)n + 1, sizeof(double));
    if (!q0)
        return GS_ENOMEM;
    s->q0 = q0;
    memcpy(q0, sys->q, (size_t)n * sizeof(double));
    for (int j = 0; j < n; j++)
        sys->q[j] += s->x[j];
    gs_err err = GS_OK;
    double deepest = 0.0;
    int n_end = s->n_rows + s->n_watch;
    row_ref *end = gs_grow(s->end, &s->cap_end, (size_t)n_end + 1, sizeof *end);
    if (!end)
        err = GS_ENOMEM;
    else
        s->end = end;
    for (int j = 0; j < n_end && err == GS_OK; j++) {
        const row_ref *w = j < s->n_rows ? &s->rows[j] : &s->watch[j - s->n_rows];
        gsi_contact_mesh *cm = sys->meshes[w->mesh].contact;
        gs_contact_pose pose[2];
        for (int k = 0; k < 2; k++) {
            gs_system_body_pose(sys, cm->body[k], pose[k].c, &pose[k].theta);
            pose[k].u = cm->elastic[k] ? s->ue[cm->body[k]] : NULL;
        }
        end[j] = *w;
        err = eval_row(cm, pose, w->cand, &end[j].r);
        if (err == GS_OK && (j < s->n_rows || end[j].r.gap.g < -CLOSURE_NEWTON_TOL))
            deepest = fmax(deepest, -end[j].r.gap.g);
    }
    memcpy(sys->q, q0, (size_t)n * sizeof(double));
    if (err == GS_OK && deepest > CLOSURE_NEWTON_TOL) {
        /* Linearise at x_k: the row's constant g(x_k) - G_k x_k. */
        int rows = s->n_rows, kept = 0;
        for (int j = 0; j < n_end && err == GS_OK; j++) {
            row_ref *e = &end[j];
            e->g0 = e->r.gap.g - inc_dot(sys, s, &e->r, sys->meshes[e->mesh].contact, true);
            if (j < rows) {
                s->rows[j] = *e;
            } else if (e->r.gap.g < -CLOSURE_NEWTON_TOL) {
                err = add_row(&s->rows, &s->n_rows, &s->cap_rows, e->mesh, e->cand, &e->r);
                if (err == GS_OK)
                    s->rows[s->n_rows - 1].g0 = e->g0;
            } else {
                s->watch[kept++] = s->watch[j - rows];
            }
        }
        s->n_watch = kept;
        *redo = err == GS_OK;
    }
    return err;
}

/* Closure: move the watched candidates the solution would take to g < 0
 * into the rows (the rows only grow, so the solves that follow end);
 * returns how many moved. */
static gs_err promote_watched(gs_system *sys, solver *s, int *moved)
{
    *moved = 0;
    int kept = 0;
    for (int j = 0; j < s->n_watch; j++) {
        const row_ref *w = &s->watch[j];
        if (!w->fan && closure_gap(sys, s, &w->r, sys->meshes[w->mesh].contact) < 0.0) {
            GS_TRY(add_row(&s->rows, &s->n_rows, &s->cap_rows, w->mesh, w->cand, &w->r));
            (*moved)++;
        } else {
            s->watch[kept++] = *w;
        }
    }
    s->n_watch = kept;
    return GS_OK;
}

/* Velocity of the material point at x of gear body b from its rigid motion
 * at the step's start (the planet's centre turns with its carrier). */
static void point_velocity(const gs_system *sys, int b, const double x[2], double v[2])
{
    double c[2], th;
    gs_system_body_pose(sys, b, c, &th);
    v[0] = v[1] = 0.0;
    int k = sys->bodies[b].coord;
    double w = k >= 0 ? sys->w[k] : 0.0;
    v[0] += -w * (x[1] - c[1]);
    v[1] += w * (x[0] - c[0]);
    const gs_body_rt *br = &sys->bodies[b];
    if (br->tcoord >= 0) { /* a translating centre (contact_centre.c) */
        v[0] += sys->w[br->tcoord];
        v[1] += sys->w[br->tcoord + 1];
    } else if (br->carrier >= 0) {
        int kc = sys->bodies[br->carrier].coord;
        double wc = kc >= 0 ? sys->w[kc] : 0.0;
        const double *cc = sys->bodies[br->carrier].centre;
        v[0] += -wc * (x[1] - cc[1]);
        v[1] += wc * (x[0] - cc[0]);
    }
}

/* Generalised forces (into fm, N unknowns) of a force F (scene frame) at x on
 * gear body b, at mesh node `node` (-1: none) of gear k of contact mesh cm:
 * the moment on its rotation and on its carrier's, and R^T F on the node's
 * displacement unknowns when the node is one. */
void gsi_contact_point_force(const gs_system *sys, const gsi_contact_mesh *cm, int k, gs_index node,
                             const double x[2], const double F[2], const int *unk, const size_t *base,
                             double *fm)
{
    int b = cm->body[k];
    double c[2], th;
    gs_system_body_pose(sys, b, c, &th);
    int kc = sys->bodies[b].coord;
    if (kc >= 0)
        fm[kc] += -(x[1] - c[1]) * F[0] + (x[0] - c[0]) * F[1];
    const gs_body_rt *br = &sys->bodies[b];
    if (br->tcoord >= 0) { /* a translating centre (contact_centre.c) */
        fm[br->tcoord] += F[0];
        fm[br->tcoord + 1] += F[1];
    } else if (br->carrier >= 0) {
        int cc = sys->bodies[br->carrier].coord;
        const double *cC = sys->bodies[br->carrier].centre;
        if (cc >= 0)
            fm[cc] += -(c[1] - cC[1]) * F[0] + (c[0] - cC[0]) * F[1];
    }
    int pk = cm->elastic[k] && node >= 0 ? gsi_plan_find(&sys->plan, b, node) : -1;
    if (pk < 0)
        return;
    int u0 = unk[base[b] + (size_t)node_dof(sys, b, pk, 0)], u1 = unk[base[b] + (size_t)node_dof(sys, b, pk, 1)];
    if (u0 < 0 || u1 < 0)
        return; /* not an unknown of this step: the friction of its row is skipped with it */
    double cs = cos(th), sn = sin(th);
    fm[u0] += cs * F[0] + sn * F[1];
    fm[u1] += -sn * F[0] + cs * F[1];
}

/* Coulomb friction on the flanks, explicit in the normal forces of the
 * frictionless solve of the same step: on every row with a positive normal
 * force F_n = lambda |dg/dx_s| of a mesh with mu > 0 and friction_scheme
 * "explicit", the force mu F_n along
 * the tangent, opposing the sliding velocity of the slave point relative to
 * the master (from the gears' rigid motion at the step's start), on the
 * slave node, and its reaction on the master nodes in the proportions of the
 * gap gradient. Rows that do not slide (|v_t| below 1e-9 m/s) carry none.
 * Per-mesh generalised forces go to s->ffm, their sum to s->ff. */
static gs_err friction_forces(gs_system *sys, solver *s, int N, const size_t *base, bool *any)
{
    int nm = sys->n_meshes;
    *any = false;
    for (int mi = 0; mi < nm; mi++) {
        const gsi_contact_mesh *cm = sys->meshes[mi].contact;
        *any |= sys->meshes[mi].ops->contact && cm->friction > 0 && cm->friction_explicit;
    }
    if (!*any)
        return GS_OK;
    if (!grow(&s->ffm, &s->cap_ffm, (size_t)nm * (size_t)N) || !grow(&s->ff, &s->cap_ff, (size_t)N))
        return GS_ENOMEM;
    memset(s->ffm, 0, (size_t)nm * (size_t)N * sizeof(double));
    memset(s->ff, 0, (size_t)N * sizeof(double));
    for (int r = 0; r < s->n_rows; r++) {
        int mi = s->rows[r].mesh;
        const gsi_contact_mesh *cm = sys->meshes[mi].contact;
        double lam = s->lam_in[r];
        if (cm->friction <= 0 || !cm->friction_explicit || !(lam > 0))
            continue;
        const gs_contact_row *cr = &s->rows[r].r;
        double gn = hypot(cr->gap.grad[0], cr->gap.grad[1]);
        if (!(gn > 0))
            continue;
        double nx = cr->gap.grad[0] / gn, ny = cr->gap.grad[1] / gn, tx = -ny, ty = nx;
        int ks = cr->body[0], km = 1 - ks;
        /* Sliding velocity of the slave point over the master surface, from
         * the gears' rigid motion (with the elastic velocities included this
         * explicit friction feeds the tooth vibrations instead of damping
         * them: see docs/explanation/contact.md). */
        double vs[2], vm[2], wsum = 0;
        point_velocity(sys, cm->body[ks], cr->x[0], vs);
        point_velocity(sys, cm->body[km], cr->x[0], vm);
        for (int t = 1; t < cr->n_nodes; t++)
            wsum += hypot(cr->gap.grad[2 * t], cr->gap.grad[2 * t + 1]);
        double vt = (vs[0] - vm[0]) * tx + (vs[1] - vm[1]) * ty;
        if (fabs(vt) < 1e-9)
            continue;
        double mag = cm->friction * lam * gn * (vt > 0 ? -1.0 : 1.0);
        double F[2] = {mag * tx, mag * ty};
        if (s->fr)
            s->fr->beta[r] = mag;
        double *fm = s->ffm + (size_t)mi * N;
        gsi_contact_point_force(sys, cm, ks, cr->node[0], cr->x[0], F, s->unk, base, fm);
        for (int t = 1; t < cr->n_nodes && wsum > 0; t++) {
            double wt = hypot(cr->gap.grad[2 * t], cr->gap.grad[2 * t + 1]) / wsum;
            double Fm[2] = {-wt * F[0], -wt * F[1]};
            gsi_contact_point_force(sys, cm, cr->body[t], cr->node[t], cr->x[t], Fm, s->unk, base, fm);
        }
    }
    for (int mi = 0; mi < nm; mi++)
        for (int j = 0; j < N; j++)
            s->ff[j] += s->ffm[(size_t)mi * N + j];
    return GS_OK;
}

/* "nearfield": the rows of a tooth pair share one spring of the pair's
 * near-field compliance c in series with the bodies (src/contact/nearfield_dyn.c),
 * an unknown s >= 0 of energy s^2 / (2 c) in the QP that enters each of
 * the pair's rows, G x + s >= -g0. At the solution s = c Lambda, Lambda the
 * pair's summed multipliers, so each row is g + G x + c Lambda >= 0,
 * complementary with its lambda: the compliant rows of the quasi-static
 * analysis. Groups the rows (s->grp), one unknown each from *N on. */
static gs_err nf_groups(gs_system *sys, solver *s, int *N)
{
    s->n_grp = 0;
    int *grp = gs_grow(s->grp, &s->cap_grp, (size_t)s->n_rows + 1, sizeof(int));
    if (!grp)
        return GS_ENOMEM;
    s->grp = grp;
    for (int r = 0; r < s->n_rows; r++) {
        int mi = s->rows[r].mesh;
        const gsi_contact_mesh *cm = sys->meshes[mi].contact;
        grp[r] = -1;
        if (!cm->nf)
            continue;
        double c[2][2], th;
        gs_system_body_pose(sys, cm->body[0], c[0], &th);
        gs_system_body_pose(sys, cm->body[1], c[1], &th);
        double cr = gsi_nf_row_compliance(cm->nf, &s->rows[r].r, c[0], c[1]);
        if (!(cr > 0.0))
            continue;
        int pair = gsi_nf_pair(cm->nf, cm->mesh[0], cm->mesh[1], &cm->cand[s->rows[r].cand]);
        int g = 0;
        while (g < s->n_grp && !(s->gr[g].mesh == mi && s->gr[g].pair == pair))
            g++;
        if (g == s->n_grp) {
            struct nf_group *ng = gs_grow(s->gr, &s->cap_gr, (size_t)g + 1, sizeof *ng);
            if (!ng)
                return GS_ENOMEM;
            s->gr = ng;
            /* the pair's compliance where its first row is */
            s->gr[g] = (struct nf_group){.mesh = mi, .pair = pair, .unk = (*N)++, .c = cr};
            s->n_grp++;
        }
        grp[r] = g;
    }
    return GS_OK;
}

/* One solve of the step's problem: the QP, or with implicit friction on
 * some row the frictional LCP (src/step/contact_friction.c). */
static gs_err qp_or_lcp(gs_system *sys, solver *s, gs_qp_problem *pr, gs_qp_result *res)
{
    if (s->fr && s->fr->n_fric > 0)
        GS_TRY(gsi_friction_solve(s->fr, pr, res));
    else
        GS_TRY(gs_qp_solve(s->qp, pr, NULL, 0, res));
    sys->last_iterations += res->iterations;
    return GS_OK;
}

/* True when some mesh has a force (lumped, compliant, impact) beside the
 * contact meshes. */
static bool has_force_meshes(const gs_system *sys)
{
    if (sys->n_joints > 0) /* the supports of translating centres (contact_centre.c) */
        return true;
    for (int i = 0; i < sys->n_meshes; i++)
        if (sys->meshes[i].ops->n_eq == 0 && !sys->meshes[i].ops->contact)
            return true;
    return false;
}

/* The QP of the step, with the forces of the meshes that have one
 * (lumped, compliant) when there are any: they act on the rigid
 * coordinates (unknowns 0..n-1), nonlinear in the increment, so the QP is
 * solved again for them linearised at its last solution, their Jacobian
 * (symmetrised) added to the rigid block of the Hessian, until two
 * solutions agree (sequential QP). At the fixed point they are the exact
 * discrete-gradient forces, so the energy identity holds as in the Newton
 * step; their dissipation goes to *diss and their forces to sol. */
static gs_err solve_step_qp(gs_system *sys, solver *s, gs_qp_problem *pr, gs_qp_result *res, double *sol,
                            double *diss)
{
    *diss = 0.0;
    if (!has_force_meshes(sys))
        return qp_or_lcp(sys, s, pr, res);
    int n = sys->n_coords, N = pr->n, nm = sys->n_meshes;
    size_t nn = (size_t)n * (size_t)n;
    if (!grow(&s->mg, &s->cap_m[0], (size_t)n) || !grow(&s->mJ, &s->cap_m[1], nn) ||
        !grow(&s->H0, &s->cap_m[2], nn) || !grow(&s->c0, &s->cap_m[3], (size_t)N) ||
        !grow(&s->xp, &s->cap_m[4], (size_t)N) || !grow(&s->mf, &s->cap_m[5], (size_t)nm))
        return GS_ENOMEM;
    for (int i = 0; i < n; i++)
        memcpy(s->H0 + (size_t)i * n, s->H + (size_t)i * N, (size_t)n * sizeof(double));
    memcpy(s->c0, s->c, (size_t)N * sizeof(double));
    /* Start: the step without the meshes' forces. */
    GS_TRY(qp_or_lcp(sys, s, pr, res));
    gs_err status = GS_ENOCONV;
    for (int it = 0; it < sys->max_newton; it++) {
        memcpy(s->xp, s->x, (size_t)N * sizeof(double));
        gsi_mesh_forces(sys, s->xp, s->mg, s->mJ, s->mf);
        for (int i = 0; i < n; i++) {
            double cj = 0.0;
            for (int j = 0; j < n; j++) {
                double Jij = 0.5 * (s->mJ[(size_t)i * n + j] + s->mJ[(size_t)j * n + i]);
                s->H[(size_t)i * N + j] = s->H0[(size_t)i * n + j] + Jij;
                cj += Jij * s->xp[j];
            }
            s->c[i] = s->c0[i] - s->mg[i] + cj;
        }
        GS_TRY(qp_or_lcp(sys, s, pr, res));
        double dx = 0.0, sc = 1e-300;
        for (int j = 0; j < N; j++) {
            dx = fmax(dx, fabs(s->x[j] - s->xp[j]));
            sc = fmax(sc, fabs(s->x[j]));
        }
        if (dx <= sys->newton_tol * sc) {
            status = GS_OK;
            break;
        }
    }
    /* Leave H and c as they were for a second solve (friction). */
    for (int i = 0; i < n; i++)
        memcpy(s->H + (size_t)i * N, s->H0 + (size_t)i * n, (size_t)n * sizeof(double));
    memcpy(s->c, s->c0, (size_t)N * sizeof(double));
    if (status != GS_OK)
        return status;
    /* The forces at the solution: booked, and part of the bodies' interface forces. */
    *diss = gsi_mesh_forces(sys, s->x, s->mg, s->mJ, s->mf);
    for (int i = 0; i < nm; i++)
        if (sys->meshes[i].ops->n_eq == 0 && !sys->meshes[i].ops->contact)
            sol[gs_sol_mesh_force(sys, i)] = s->mf[i];
    return GS_OK;
}

/* The solve, or with mask (gsi_contact_select) only its rows and
 * unknowns: the compliance entries the solve will read. */
static gs_err contact_solve(gs_system *sys, const double *rec, double *sol, int *mask)
{
    solver *s = get_solver(sys);
    if (!s)
        return GS_ENOMEM;
    bool ready = s->rows_ready && !mask;
    s->rows_ready = false;
    const gs_step_plan *p = &sys->plan;
    int n = sys->n_coords, nb = sys->n_bodies;
    /* 0. Records: sanity, and the nodes' current displacements. */
    size_t total_dof = 0;
    int maxdof = 1;
    for (int i = 0; i < nb; i++) {
        int nd = p->n_dof[i];
        total_dof += (size_t)nd;
        if (nd > maxdof)
            maxdof = nd;
        const double *r = rec + p->rec_off[i];
        if (!mask && nd > 0 && (!(r[0] > 0) || !isfinite(r[0])))
            return GS_ESINGULAR;
        if (p->n_nodes[i] == 0 || ready)
            continue;
        const gs_mesh *m = sys->bodies[i].ops->mesh(&sys->bodies[i]);
        if (!s->u[i]) {
            s->u[i] = gs_calloc(2 * (size_t)m->n_nodes, sizeof(double));
            if (!s->u[i])
                return GS_ENOMEM;
        }
        const double *u = r + (size_t)nd * nd + nd;
        for (int k = 0; k < p->n_nodes[i]; k++) {
            s->u[i][2 * p->nodes[i][k]] = u[2 * k];
            s->u[i][2 * p->nodes[i][k] + 1] = u[2 * k + 1];
        }
    }
    /* 1. Rows (found by the selection of this step when ready). */
    if (!grow(&s->mct, &s->cap_mct, 2 * (size_t)sys->n_meshes + 1))
        return GS_ENOMEM;
    if (!ready) {
        s->n_rows = 0;
        s->n_watch = 0;
    }
    for (int mi = 0; mi < sys->n_meshes; mi++) {
        if (!sys->meshes[mi].ops->contact)
            continue;
        double pen;
        int before = s->n_rows;
        if (!ready) {
            GS_TRY(collect_rows(sys, s, mi, rec, &pen));
            s->mct[2 * mi] = s->n_rows - before;
            s->mct[2 * mi + 1] = pen;
        }
        if (!sol)
            continue;
        double *ct = sol + gs_sol_mesh_contact(sys, mi);
        ct[1] = s->mct[2 * mi];
        ct[2] = s->mct[2 * mi + 1];
    }
    bool closure = sys->contact_scheme != GS_CONTACT_SEED; /* closure, closure_energy */
    int passes = 0, newton = 0;
again:;
    /* 2. Unknowns: coordinates, then the nodes that enter a row. */
    int *nu = gs_grow(s->unk, &s->cap_unk, total_dof + 1, sizeof(int));
    if (!nu)
        return GS_ENOMEM;
    s->unk = nu;
    size_t *base = gs_grow(s->base, &s->cap_base, (size_t)nb, sizeof(size_t));
    if (!base)
        return GS_ENOMEM;
    s->base = base;
    int *unk = s->unk;
    for (int i = 0, off = 0; i < nb; i++) {
        base[i] = (size_t)off;
        for (int k = 0; k < p->n_dof[i]; k++)
            unk[off + k] = -1;
        if (sys->bodies[i].coord >= 0)
            unk[off] = sys->bodies[i].coord;
        off += p->n_dof[i];
    }
    int N = n;
    for (int r = 0; r < s->n_rows; r++) {
        const gs_contact_row *cr = &s->rows[r].r;
        const gsi_contact_mesh *cm = sys->meshes[s->rows[r].mesh].contact;
        for (int t = 0; t < cr->n_nodes; t++) {
            int gk = cr->body[t], b = cm->body[gk];
            int pk = cm->elastic[gk] ? gsi_plan_find(p, b, cr->node[t]) : -1;
            if (pk < 0)
                continue;
            for (int comp = 0; comp < 2; comp++) {
                int *u = &unk[base[b] + (size_t)node_dof(sys, b, pk, comp)];
                if (*u < 0)
                    *u = N++;
            }
        }
    }
    if (mask) {
        /* The entries step 3 reads: the unknowns' (C[0] too, the record's
         * health); with closure every one (its increments read whole
         * columns, and promoted rows add unknowns). */
        for (size_t a = 0; a < total_dof; a++)
            mask[a] = closure || unk[a] >= 0;
        for (int i = 0; i < nb; i++)
            if (p->n_dof[i] > 0)
                mask[base[i]] = 1;
        s->rows_ready = true;
        return GS_OK;
    }
    int nbody = N; /* unknowns of the bodies; then the near-field springs' */
    if (closure)
        GS_TRY(nf_groups(sys, s, &N));
    int ne = sys->n_eq, ni = s->n_rows;
    GS_TRY(reserve(s, N, ne, ni, maxdof));
    gs_err err = GS_OK;
    /* 3. Hessian blocks: inverses of the compliance sub-blocks. */
    memset(s->H, 0, (size_t)N * N * sizeof(double));
    memset(s->c, 0, (size_t)N * sizeof(double));
    int *sel = gs_grow(s->sel, &s->cap_sel, (size_t)maxdof, sizeof(int));
    if (!sel)
        return GS_ENOMEM;
    s->sel = sel;
    for (int i = 0; i < nb && err == GS_OK; i++) {
        int nd = p->n_dof[i], k = 0;
        for (int a = 0; a < nd; a++)
            if (unk[base[i] + a] >= 0)
                sel[k++] = a;
        if (k == 0)
            continue;
        const double *C = rec + p->rec_off[i], *d0 = C + (size_t)nd * nd;
        for (int a = 0; a < k; a++)
            for (int b = 0; b < k; b++)
                s->S[a * k + b] = C[(size_t)sel[b] * nd + sel[a]];
        if (LAPACKE_dpotrf(LAPACK_ROW_MAJOR, 'L', k, s->S, k) != 0 ||
            LAPACKE_dpotri(LAPACK_ROW_MAJOR, 'L', k, s->S, k) != 0) {
            err = GS_ESINGULAR;
            break;
        }
        for (int a = 0; a < k; a++)
            for (int b = 0; b < k; b++) {
                double v = a >= b ? s->S[a * k + b] : s->S[b * k + a];
                s->H[(size_t)unk[base[i] + sel[a]] * N + unk[base[i] + sel[b]]] = v;
                s->c[unk[base[i] + sel[a]]] += v * d0[sel[b]];
            }
    }
    if (err != GS_OK)
        return err;
    gsi_centre_mass(sys, s->H, s->c, N); /* translating centres: free masses */
    for (int g = 0; closure && g < s->n_grp; g++) /* near-field springs: s^2 / (2 c) */
        s->H[(size_t)s->gr[g].unk * N + s->gr[g].unk] = 1.0 / s->gr[g].c;
    /* 4. Rows: kinematic equalities and linearised contacts. */
    memset(s->E, 0, (size_t)(ne ? ne : 1) * N * sizeof(double));
    for (int a = 0; a < ne; a++) {
        memcpy(s->E + (size_t)a * N, sys->eq_rows + (size_t)a * n, (size_t)n * sizeof(double));
        s->e[a] = 0.0;
    }
    memset(s->G, 0, (size_t)(ni ? ni : 1) * N * sizeof(double));
    for (int r = 0; r < ni; r++) {
        const gs_contact_row *cr = &s->rows[r].r;
        const gsi_contact_mesh *cm = sys->meshes[s->rows[r].mesh].contact;
        double *G = s->G + (size_t)r * N;
        /* seed: homogeneous, the gap g(x_n) is dropped on purpose; closure: kept */
        s->g[r] = closure ? -s->rows[r].g0 : 0.0;
        for (int k = 0; k < 2; k++) {
            int b = cm->body[k], c = sys->bodies[b].coord;
            if (c >= 0)
                G[c] += cr->dg_dtheta[k];
            /* A planet's centre turns with its carrier, dc = J (c - c_C) dtheta_C,
             * or a centre translates (contact_centre.c). */
            gsi_centre_row(sys, b, cr->dg_dc[k], G);
        }
        for (int t = 0; t < cr->n_nodes; t++) {
            int gk = cr->body[t], b = cm->body[gk];
            int pk = cm->elastic[gk] ? gsi_plan_find(p, b, cr->node[t]) : -1;
            if (pk < 0)
                continue;
            for (int comp = 0; comp < 2; comp++)
                G[unk[base[b] + (size_t)node_dof(sys, b, pk, comp)]] += cr->dg_du[t][comp];
        }
        if (closure && s->grp[r] >= 0)
            G[s->gr[s->grp[r]].unk] = 1.0;
    }
    /* 4b. Flank friction: per row its force (and, implicit, its tangent row). */
    if (s->fr || gsi_friction_any(sys, false)) {
        GS_TRY(gsi_friction_begin(&s->fr, N, ni));
        for (int r = 0; r < ni; r++)
            GS_TRY(gsi_friction_add(s->fr, sys, r, s->rows[r].mesh, &s->rows[r].r, unk, base));
    }
    /* 5. The QP. */
    if (!s->qp || N > s->qp_n || ne > s->qp_eq || ni > s->qp_in) {
        gs_qp_free(&s->qp);
        s->qp_n = N > s->qp_n ? N + 16 : s->qp_n;
        s->qp_eq = ne > s->qp_eq ? ne : s->qp_eq;
        s->qp_in = ni > s->qp_in ? ni + 32 : s->qp_in;
        GS_TRY(gs_qp_new(s->qp_n, s->qp_eq, s->qp_in, &s->qp));
    }
    gs_qp_problem pr = {.n = N, .H = s->H, .c = s->c, .n_eq = ne, .E = s->E, .e = s->e,
                        .n_in = ni, .G = s->G, .g = s->g};
    gs_qp_result res = {.x = s->x, .lambda_eq = s->lam_eq, .lambda_in = s->lam_in};
    double mdiss;
    sys->last_iterations = 0;
    GS_TRY(solve_step_qp(sys, s, &pr, &res, sol, &mdiss));
    /* 5b. Flank friction: forces from this solve's normal forces, then the
     * step solved again with them as loads. */
    bool fric = false;
    if (ni > 0) {
        GS_TRY(friction_forces(sys, s, N, base, &fric));
        if (fric) {
            for (int j = 0; j < N; j++)
                s->c[j] += s->ff[j];
            GS_TRY(solve_step_qp(sys, s, &pr, &res, sol, &mdiss));
        }
    }
    /* 5c. Closure: candidates without a row that the solution takes inside
     * get one, and the step is solved again (at most 8 times). */
    if (closure && ((s->n_watch > 0 && passes < 8) || newton < CLOSURE_NEWTON_MAX)) {
        GS_TRY(plan_increments(sys, s, rec, N, total_dof));
        int moved = 0;
        if (s->n_watch > 0 && passes < 8)
            GS_TRY(promote_watched(sys, s, &moved));
        if (moved > 0) {
            passes++;
            goto again;
        }
        /* 5c'. Newton on the nonlinear gap (closure_newton). */
        bool redo = false;
        if (newton < CLOSURE_NEWTON_MAX)
            GS_TRY(closure_newton(sys, s, &redo));
        if (redo) {
            newton++;
            goto again;
        }
    }
    /* 5d. Adaptive step: a solution that would push a watched node deeper
     * than the threshold is not taken; the step is taken again finer. */
    if (s->n_watch > 0 && sys->level < sys->adapt_levels &&
        watched_penetration(sys, s, rec, s->x) > sys->adapt_penetration)
        return GS_EREFINE;
    /* 6. Solution: rigid increments, contact figures, interface forces. */
    memcpy(sol, s->x, (size_t)n * sizeof(double));
    memset(s->f, 0, (size_t)N * sizeof(double));
    if (has_force_meshes(sys)) {
        /* The force meshes' forces on the coordinates reach the elastic
         * bodies with the rest of their interface forces. */
        sol[n] += mdiss;
        for (int j = 0; j < n; j++)
            s->f[j] -= s->mg[j];
    }
    if (s->fr && s->fr->n_fric > 0) {
        /* Implicit friction: the forces of the solution, with any explicit ones. */
        if (!fric) {
            if (!grow(&s->ffm, &s->cap_ffm, (size_t)sys->n_meshes * (size_t)N))
                return GS_ENOMEM;
            memset(s->ffm, 0, (size_t)sys->n_meshes * (size_t)N * sizeof(double));
        }
        gsi_friction_forces(s->fr, s->ffm);
        fric = true;
    }
    if (fric) {
        /* The friction forces' work over the step is what they dissipate:
         * booked exactly, so the balance holds whatever the force. */
        for (int mi = 0; mi < sys->n_meshes; mi++) {
            const double *fm = s->ffm + (size_t)mi * N;
            double w = 0;
            for (int j = 0; j < N; j++) {
                s->f[j] += fm[j];
                w += fm[j] * s->x[j];
            }
            sol[gs_sol_mesh_contact(sys, mi) + 3] = -w;
            sol[n] += -w;
        }
    }
    for (int a = 0; a < ne; a++)
        for (int j = 0; j < N; j++)
            s->f[j] += s->E[(size_t)a * N + j] * s->lam_eq[a];
    if (closure)
        for (int mi = 0; mi < sys->n_meshes; mi++)
            if (sys->meshes[mi].ops->contact)
                sol[gs_sol_mesh_contact(sys, mi) + 1] = 0.0;
    for (int r = 0; r < ni; r++) {
        if (closure) {
            /* rows per mesh (promoted ones too), and the reactions' work */
            double gx = 0.0; /* the bodies' part of the row (not its spring) */
            for (int j = 0; j < nbody; j++)
                gx += s->G[(size_t)r * N + j] * s->x[j];
            double *ct = sol + gs_sol_mesh_contact(sys, s->rows[r].mesh);
            ct[1] += 1.0;
            ct[4] += s->lam_in[r] * gx;
            /* closure_energy: the moments of the reactions on the mesh's two
             * gears, the direction of the velocity update that returns
             * ct[4] (gs_step_contact_return, src/step/step.c) */
            const gsi_contact_mesh *cm = sys->meshes[s->rows[r].mesh].contact;
            for (int k = 0; k < 2; k++) {
                int c = sys->bodies[cm->body[k]].coord;
                if (c >= 0)
                    ct[5 + k] += s->lam_in[r] * s->G[(size_t)r * N + c];
            }
        }
        if (s->lam_in[r] == 0.0)
            continue;
        for (int j = 0; j < N; j++)
            s->f[j] += s->G[(size_t)r * N + j] * s->lam_in[r];
        /* Normal force: lambda times the slave-point gradient's length. */
        const gs_contact_row *cr = &s->rows[r].r;
        int mi = s->rows[r].mesh;
        sol[gs_sol_mesh_contact(sys, mi)] += 1.0;
        sol[gs_sol_mesh_force(sys, mi)] += s->lam_in[r] * hypot(cr->gap.grad[0], cr->gap.grad[1]);
    }
    if (closure) { /* every step, also once a pair's springs have let go */
        /* The springs' energy at the step's end, 1/2 c Lambda^2 per pair:
         * part of the potential (ct[7]). The reactions' work on the bodies
         * booked above less the springs' change of energy is what the pair
         * lost or gained (contact_work), so the balance holds with it. */
        for (int g = 0; g < s->n_grp; g++) {
            double L = 0.0;
            for (int r = 0; r < ni; r++)
                if (s->grp[r] == g)
                    L += s->lam_in[r];
            sol[gs_sol_mesh_contact(sys, s->gr[g].mesh) + 7] += 0.5 * s->gr[g].c * L * L;
        }
        for (int mi = 0; mi < sys->n_meshes; mi++) {
            double *ct = sol + gs_sol_mesh_contact(sys, mi);
            if (sys->meshes[mi].ops->contact && ((const gsi_contact_mesh *)sys->meshes[mi].contact)->nf)
                ct[4] += ct[7] - sys->meshes[mi].nf_energy;
        }
    }
    for (int i = 0; i < nb; i++)
        for (int a = 0; a < p->n_dof[i]; a++) {
            int u = unk[base[i] + a];
            sol[p->sol_off[i] + a] = u >= 0 ? s->f[u] : 0.0;
        }
    return GS_OK;
}

double gs_step_contact_friction(const gs_system *sys, int i)
{
    const solver *s = sys ? sys->solver : NULL;
    if (!s || !s->fr || i < 0 || i >= s->n_rows || i >= s->fr->n_rows)
        return 0.0;
    return s->fr->beta[i];
}

gs_err gsi_contact_solve(gs_system *sys, const double *rec, double *sol)
{
    return contact_solve(sys, rec, sol, NULL);
}

gs_err gsi_contact_select(gs_system *sys, const double *rec, int *mask)
{
    return contact_solve(sys, rec, NULL, mask);
}

int gs_step_contact_rows(const gs_system *sys)
{
    const solver *s = sys ? sys->solver : NULL;
    return s ? s->n_rows : 0;
}

const gs_contact_row *gs_step_contact_row(const gs_system *sys, int i, int *mesh, double *lambda)
{
    const solver *s = sys ? sys->solver : NULL;
    if (!s || i < 0 || i >= s->n_rows)
        return NULL;
    if (mesh)
        *mesh = s->rows[i].mesh;
    if (lambda)
        *lambda = s->lam_in && (size_t)i < s->cap[8] ? s->lam_in[i] : 0.0;
    return &s->rows[i].r;
}
