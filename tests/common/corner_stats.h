/* SPDX-License-Identifier: MIT
 * Contact-locking statistics of a two-gear contact mesh (issue 15, "No
 * contact locking"; docs/explanation/contact.md "Tip corners"), shared by
 * tests/bench/corner_stats.c and tests/validation/test_contact_corner.c.
 *
 * After every step, each contact row of the mesh (cs_init's `mesh`) that
 * carries force (lambda > 0, gs_step_contact_row) is compared with the
 * lines of action (the two common internal tangents of the base circles at
 * the current centres; the two common external ones when a gear is
 * internal): the angle between the row's slave normal dg/dx and the nearer
 * line, and its lever arm |dg/dtheta_k| / (|dg/dx| r_b,k) on each gear (1 on
 * the line of action). A step with a loaded row more than `off_deg` off both
 * lines is an "off" step; consecutive off steps form an episode. Over the
 * window t >= t_from: the mesh force (max, mean, steps above force_factor x
 * the mean), the strain energy (max, mean), and per episode its length, its
 * largest force and strain energy and the row that was off (slave gear and
 * node, its radius against the tip radius, the master nodes). */
#ifndef GEARSIM_TESTS_CORNER_STATS_H
#define GEARSIM_TESTS_CORNER_STATS_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/contact.h"
#include "gearsim/geometry.h"
#include "gearsim/step.h"

#define CS_MAX_EPISODES 64

typedef struct cs_episode {
    double t0;          /* time of the first off step, s */
    int steps;          /* consecutive off steps */
    double f_max;       /* largest mesh force in the episode, N */
    double se_max;      /* largest strain energy in the episode, J */
    double angle;       /* the off row's angle to the line of action at f_max, deg */
    double lever;       /* its smaller lever arm ratio */
    double f_row;       /* its normal force, N */
    int slave_gear;     /* gear (0 / 1 of the mesh) of the slave */
    long slave_node;
    double slave_r_um;  /* tip radius minus the slave's radius, um (0 at a tip corner) */
    long master[3];
    int n_master;
    double master_r_um; /* tip radius of the master minus its outermost node's radius, um */
    int kind;           /* the off row's gap kind (gs_gap_kind), blend weight, gap (m), */
    double blend, g, xi; /* projection parameter (order 2) */
} cs_episode;

typedef struct cs_stats {
    double off_deg, force_factor, t_from; /* settings */
    int mesh;               /* the contact mesh watched */
    long steps, n_win;      /* steps run, steps in the window */
    double f_max, f_mean, t_fmax;
    double se_max, se_mean, t_semax;
    long n_off;             /* off steps in the window */
    long n_force;           /* steps in the window with force > force_factor x mean */
    long n_off_rows;        /* loaded off rows summed over the window's steps */
    double off_angle_max;   /* largest angle of a loaded row, deg */
    int n_ep;               /* episodes (the first CS_MAX_EPISODES kept) */
    long n_ep_total;
    int longest;            /* steps of the longest episode */
    cs_episode ep[CS_MAX_EPISODES];
    /* internal */
    double *f_hist;
    size_t cap;
    bool in_ep;
    double rb[2], ra[2];
    int body[2];
    bool internal;          /* one gear of the mesh is internal (a ring) */
    FILE *csv;
} cs_stats;

static inline void cs_init(cs_stats *c, const gs_system *s, int mesh, double t_from, double off_deg,
                           double force_factor, FILE *csv)
{
    memset(c, 0, sizeof *c);
    c->mesh = mesh;
    c->t_from = t_from;
    c->off_deg = off_deg;
    c->force_factor = force_factor;
    c->csv = csv;
    for (int k = 0; k < 2; k++) {
        int b = s->scene->meshes[mesh].gear[k];
        gs_gear_geom g;
        gs_gear_geometry(&s->scene->bodies[b].gear, &g, NULL);
        if (s->scene->bodies[b].gear.kind == GS_GEAR_INTERNAL)
            c->internal = true;
        c->body[k] = b;
        c->rb[k] = g.rb;
        c->ra[k] = g.ra;
    }
    if (csv)
        fprintf(csv, "t_s,force_N,strain_J,loaded_rows,off_rows,max_angle_deg,off_force_N,te_m,kinetic_J,"
                     "rigid_kinetic_J,dissipated_J,work_in_J,omega0_rad_s,omega1_rad_s\n");
}

/* Angle (deg) of unit normal n to the nearer line of action, and the lever
 * ratios of the row. */
static inline double cs_row_angle(const cs_stats *c, const gs_system *s, const gs_contact_row *r, double *lever)
{
    double c0[2], c1[2], th;
    gs_system_body_pose(s, c->body[0], c0, &th);
    gs_system_body_pose(s, c->body[1], c1, &th);
    double e[2] = {c1[0] - c0[0], c1[1] - c0[1]}, a = hypot(e[0], e[1]);
    e[0] /= a;
    e[1] /= a;
    double p[2] = {-e[1], e[0]};
    /* internal tangents of the base circles; the external ones (ring) */
    double ca = (c->internal ? fabs(c->rb[0] - c->rb[1]) : c->rb[0] + c->rb[1]) / a, sa = sqrt(fmax(0.0, 1.0 - ca * ca));
    double gn = hypot(r->gap.grad[0], r->gap.grad[1]);
    double n[2] = {r->gap.grad[0] / gn, r->gap.grad[1] / gn};
    double best = 180.0;
    for (int sg = -1; sg <= 1; sg += 2) {
        /* the line of action makes the working pressure angle with the
         * common tangent of the pitch circles */
        double l[2] = {ca * p[0] + sg * sa * e[0], ca * p[1] + sg * sa * e[1]};
        double d = fabs(n[0] * l[0] + n[1] * l[1]);
        best = fmin(best, acos(fmin(1.0, d)) * 180.0 / GS_PI);
    }
    *lever = INFINITY;
    for (int k = 0; k < 2; k++)
        *lever = fmin(*lever, fabs(r->dg_dtheta[k]) / (gn * c->rb[k]));
    return best;
}

/* After each step. */
static inline void cs_step(cs_stats *c, const gs_system *s)
{
    gs_energy e;
    gs_system_energy(s, &e);
    double t = s->time, F = fabs(s->meshes[c->mesh].force);
    c->steps++;
    int loaded = 0, off = 0;
    double amax = 0.0, foff = 0.0;
    const gs_contact_row *worst = NULL;
    double w_ang = 0, w_lev = 0, w_f = 0;
    int nr = gs_step_contact_rows(s);
    for (int i = 0; i < nr; i++) {
        int mesh;
        double lam;
        const gs_contact_row *r = gs_step_contact_row(s, i, &mesh, &lam);
        if (!r || mesh != c->mesh || !(lam > 0))
            continue;
        loaded++;
        double lev, ang = cs_row_angle(c, s, r, &lev);
        double fr = lam * hypot(r->gap.grad[0], r->gap.grad[1]);
        amax = fmax(amax, ang);
        if (ang > c->off_deg) {
            off++;
            foff += fr;
            if (!worst || fr > w_f) {
                worst = r;
                w_ang = ang;
                w_lev = lev;
                w_f = fr;
            }
        }
    }
    if (c->csv) {
        /* kinematic TE a . q - s_ref; the kinetic energy of the rigid
         * rotations at their current speeds (the rest of e.kinetic is that of
         * the elastic deformation and its coupling) */
        const gs_gmesh_rt *m = &s->meshes[c->mesh];
        double te = -m->s_ref, tr = 0.0;
        for (int k = 0; k < s->n_coords; k++)
            te += m->a[k] * s->q[k];
        for (int b = 0; b < s->n_bodies; b++)
            if (s->bodies[b].coord >= 0)
                tr += 0.5 * s->bodies[b].inertia_eff * s->w[s->bodies[b].coord] * s->w[s->bodies[b].coord];
        double om[2];
        for (int k = 0; k < 2; k++) {
            int kc = s->bodies[c->body[k]].coord;
            om[k] = kc >= 0 ? s->w[kc] : 0.0;
        }
        fprintf(c->csv, "%.8g,%.6g,%.6g,%d,%d,%.3f,%.6g,%.6e,%.8e,%.8e,%.8e,%.8e,%.9g,%.9g\n", t, F, e.elastic, loaded,
                off, amax, foff, te, e.kinetic, tr, e.dissipated, e.work_in, om[0], om[1]);
    }
    if (t < c->t_from) {
        c->in_ep = false;
        return;
    }
    if (!c->f_hist || (size_t)c->n_win >= c->cap) {
        size_t nc = c->cap ? 2 * c->cap : 4096;
        double *p = realloc(c->f_hist, nc * sizeof *p);
        if (!p)
            abort();
        c->f_hist = p;
        c->cap = nc;
    }
    c->f_hist[c->n_win++] = F;
    c->f_mean += F;
    c->se_mean += e.elastic;
    if (F > c->f_max) {
        c->f_max = F;
        c->t_fmax = t;
    }
    if (e.elastic > c->se_max) {
        c->se_max = e.elastic;
        c->t_semax = t;
    }
    c->off_angle_max = fmax(c->off_angle_max, amax);
    c->n_off_rows += off;
    if (!off) {
        c->in_ep = false;
        return;
    }
    c->n_off++;
    if (!c->in_ep) {
        c->in_ep = true;
        c->n_ep_total++;
        if (c->n_ep < CS_MAX_EPISODES) {
            cs_episode *p = &c->ep[c->n_ep++];
            memset(p, 0, sizeof *p);
            p->t0 = t;
        }
    }
    if (c->n_ep_total > CS_MAX_EPISODES)
        return;
    cs_episode *p = &c->ep[c->n_ep - 1];
    p->steps++;
    if (p->steps > c->longest)
        c->longest = p->steps;
    p->se_max = fmax(p->se_max, e.elastic);
    if (F >= p->f_max) {
        p->f_max = F;
        p->angle = w_ang;
        p->lever = w_lev;
        p->f_row = w_f;
        int ks = worst->body[0], km = 1 - ks;
        double cs_[2], cm_[2], th;
        gs_system_body_pose(s, c->body[ks], cs_, &th);
        gs_system_body_pose(s, c->body[km], cm_, &th);
        p->slave_gear = ks;
        p->slave_node = (long)worst->node[0];
        p->slave_r_um = fabs(c->ra[ks] - hypot(worst->x[0][0] - cs_[0], worst->x[0][1] - cs_[1])) * 1e6;
        p->n_master = worst->n_nodes - 1;
        double rmax = 0; /* the master node nearest its tip radius */
        for (int j = 1; j < worst->n_nodes && j < 4; j++) {
            p->master[j - 1] = (long)worst->node[j];
            double r = hypot(worst->x[j][0] - cm_[0], worst->x[j][1] - cm_[1]);
            if (j == 1 || fabs(c->ra[km] - r) < fabs(c->ra[km] - rmax))
                rmax = r;
        }
        p->master_r_um = fabs(c->ra[km] - rmax) * 1e6;
        p->kind = (int)worst->gap.kind;
        p->blend = worst->gap.blend;
        p->g = worst->gap.g;
        p->xi = worst->gap.xi;
    }
}

/* At the end: the means and the steps above force_factor x the mean. */
static inline void cs_finish(cs_stats *c)
{
    if (c->n_win > 0) {
        c->f_mean /= (double)c->n_win;
        c->se_mean /= (double)c->n_win;
    }
    for (long i = 0; i < c->n_win; i++)
        c->n_force += c->f_hist[i] > c->force_factor * c->f_mean;
    free(c->f_hist);
    c->f_hist = NULL;
}

/* The report: one summary line, then up to `n_print` episodes, largest force first. */
static inline void cs_print(const cs_stats *c, FILE *out, const char *label, double se_static, int n_print)
{
    fprintf(out,
            "%s: %ld steps, window from %.0f ms (%ld steps): force max %.0f N at %.2f ms, mean %.1f N (x%.2f); "
            "strain energy max %.3f mJ at %.2f ms, mean %.3f mJ, static %.3f mJ (x%.1f); steps with force > %.1f x "
            "mean: %ld; steps with a loaded row > %.0f deg off the line of action: %ld (%ld rows, largest angle "
            "%.1f deg) in %ld episodes, longest %d steps\n",
            label, c->steps, c->t_from * 1e3, c->n_win, c->f_max, c->t_fmax * 1e3, c->f_mean,
            c->f_mean > 0 ? c->f_max / c->f_mean : 0.0, c->se_max * 1e3, c->t_semax * 1e3, c->se_mean * 1e3,
            se_static * 1e3, se_static > 0 ? c->se_max / se_static : 0.0, c->force_factor, c->n_force, c->off_deg,
            c->n_off, c->n_off_rows, c->off_angle_max, c->n_ep_total, c->longest);
    int idx[CS_MAX_EPISODES];
    for (int i = 0; i < c->n_ep; i++)
        idx[i] = i;
    for (int i = 0; i < c->n_ep; i++) /* largest force first (insertion sort) */
        for (int j = i; j > 0 && c->ep[idx[j]].f_max > c->ep[idx[j - 1]].f_max; j--) {
            int tmp = idx[j];
            idx[j] = idx[j - 1];
            idx[j - 1] = tmp;
        }
    for (int i = 0; i < c->n_ep && i < n_print; i++) {
        const cs_episode *p = &c->ep[idx[i]];
        fprintf(out,
                "  episode at %.2f ms, %d steps: force max %.0f N, strain energy max %.3f mJ; row %.1f deg off, "
                "lever %.2f, %.0f N: slave gear %d node %ld (%.1f um from its tip radius) against gear %d nodes",
                p->t0 * 1e3, p->steps, p->f_max, p->se_max * 1e3, p->angle, p->lever, p->f_row, p->slave_gear,
                p->slave_node, p->slave_r_um, 1 - p->slave_gear);
        for (int j = 0; j < p->n_master; j++)
            fprintf(out, " %ld", p->master[j]);
        fprintf(out, " (the nearest to its tip radius %.1f um from it); gap kind %d, blend %.2f, xi %.3f, g %.3g um\n",
                p->master_r_um, p->kind, p->blend, p->xi, p->g * 1e6);
    }
}

#endif
