/* SPDX-License-Identifier: MIT
 * Near-field (Hertz) series compliance of the dynamic contact rows
 * (docs/explanation/contact.md "Near-field compliance").
 *
 * The FE contact of a mesh cannot resolve the Hertzian zone (half-width
 * about 0.06 mm at 20 N m against an element of about 0.3 mm on the
 * default mesh), and is too stiff by the difference between the Hertzian
 * approach of the surface to a depth d and the FE's own approach over the
 * same depth. The quasi-static analysis measures that difference per loaded
 * tooth pair (src/contact/stiffness_load.c: c = delta_H(P) / P - L, the FE's
 * part L from the FE itself). Here that analysis is run once at load, at
 * the scene's moment, and its pairs' compliances are kept against where the
 * pair is along the path of contact (the load-weighted contact point,
 * measured along the normal of the centre line). The contact step puts each
 * tooth pair's compliance in series with the pair's rows.
 *
 * The analysis also takes the node-sampling part of each pair's rigid gap
 * off its rows (gsi_stiff_nf_offsets: the flanks touch where they do, not
 * where their nearest node does). That offset is a property of the rigid
 * geometry: it is sampled here finely over a mesh cycle at the rigid
 * kinematic positions and kept against the angle of gear 1's tooth of the
 * pair from the centre line, the angle the analysis holds while its driver
 * (gear 0) turns under the load. The contact step takes it off the rows'
 * gaps with its slope in their derivatives (gsi_nf_row_offset), so the
 * offset is part of the gap function the rows linearise. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "nearfield_dyn.h"
#include "stiffness_hook.h"
#include "gearsim/util.h"
#include "stiffness_internal.h"

/* Rigid positions per mesh cycle at which the gap offsets are sampled. */
#define NF_OFF_SAMPLES 1536

struct gsi_nf_table {
    int n;
    double *key, *cs, *ct, *load; /* sorted by key */
    double sign;                  /* sign of dg/dtheta_0 of the loaded flanks' rows */
    int z[2];
    /* Gap offsets: against the angle of gear 1's tooth from the centre line
     * (rad, sorted), per slave gear of the rows (m). */
    int n_off;
    double *okey, (*off)[2];
};

void gsi_nf_table_free(gsi_nf_table **t)
{
    if (!t || !*t)
        return;
    free((*t)->key), free((*t)->cs), free((*t)->ct), free((*t)->load);
    free((*t)->okey), free((*t)->off);
    free(*t);
    *t = NULL;
}

/* Key of point X: its distance from centre c0 along the unit normal of the
 * centre line c0 -> c1. */
static double path_key(const double X[2], const double c0[2], const double c1[2])
{
    double ex = c1[0] - c0[0], ey = c1[1] - c0[1], l = hypot(ex, ey);
    return ((X[0] - c0[0]) * -ey + (X[1] - c0[1]) * ex) / l;
}

/* Angle of tooth t of gear 1 (z teeth, at angle th1 about its centre c1)
 * from the centre line towards gear 0's centre c0, in [-pi, pi]; with its
 * derivative w.r.t. c0 (that w.r.t. c1 is its negative). */
static double tooth_key(double th1, int t, int z, const double c0[2], const double c1[2], double dk_dc0[2])
{
    double ex = c0[0] - c1[0], ey = c0[1] - c1[1], l2 = ex * ex + ey * ey;
    if (dk_dc0) {
        dk_dc0[0] = ey / l2;
        dk_dc0[1] = -ex / l2;
    }
    return remainder(th1 + 2.0 * GS_PI * t / z - atan2(ey, ex), 2.0 * GS_PI);
}

static int by_key(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* The gap offsets of the run's pairs at NF_OFF_SAMPLES rigid positions over
 * its mesh cycle, into t (sorted by key). */
static gs_err offsets_build(gs_stiffness_run *run, gsi_nf_table *t)
{
    const work *w = gsi_stiffness_run_work(run);
    size_t cap = (size_t)NF_OFF_SAMPLES * 2 * GS_STIFF_MAX_PAIRS;
    double *rec = malloc(3 * cap * sizeof *rec);
    if (!rec)
        return GS_ENOMEM;
    gs_err e = GS_OK;
    int n = 0;
    for (int j = 0; j < NF_OFF_SAMPLES && e == GS_OK; j++) {
        if ((e = gsi_stiffness_run_offsets(run, (double)j / NF_OFF_SAMPLES)) != GS_OK)
            break;
        for (int p = 0; p < w->n_go && (size_t)n < cap; p++) {
            double *r = rec + 3 * (size_t)n++;
            int sl = w->go[p].slave;
            r[0] = tooth_key(w->theta0[1], w->go[p].tooth[1], w->b[1].sb->gear.teeth, w->b[0].c, w->b[1].c,
                             NULL);
            r[1] = sl < 0 || sl == 0 ? w->go[p].off : 0.0;
            r[2] = sl < 0 || sl == 1 ? w->go[p].off : 0.0;
        }
    }
    if (e == GS_OK) {
        qsort(rec, (size_t)n, 3 * sizeof *rec, by_key);
        t->okey = malloc((size_t)n * sizeof *t->okey);
        t->off = malloc((size_t)n * sizeof *t->off);
        if (!t->okey || !t->off)
            e = GS_ENOMEM;
        for (int i = 0; i < n && e == GS_OK; i++) {
            t->okey[i] = rec[3 * i];
            t->off[i][0] = rec[3 * i + 1];
            t->off[i][1] = rec[3 * i + 2];
        }
        t->n_off = e == GS_OK ? n : 0;
    }
    free(rec);
    return e;
}

gs_err gsi_nf_table_build(const gs_scene *sc, int mesh_index, gsi_nf_table **out, gs_diag *d)
{
    *out = NULL;
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    o.nearfield = 2; /* auto: on quadratic meshes (the correction is measured on them) */
    o.tangent = 0;
    o.driver = 0;
    gs_stiffness_run *run = NULL;
    GS_TRY(gs_stiffness_begin(sc, mesh_index, &o, &run, d));
    gsi_nf_table *t = calloc(1, sizeof *t);
    size_t cap = (size_t)o.positions * GS_STIFF_MAX_PAIRS;
    double *rec = malloc(4 * cap * sizeof *rec);
    gs_err e = t && rec ? GS_OK : GS_ENOMEM;
    int n = 0;
    for (int j = 0; j < o.positions && e == GS_OK; j++) {
        if ((e = gs_stiffness_next(run, d)) != GS_OK)
            break;
        const work *w = gsi_stiffness_run_work(run);
        const gs_contact_row *rows;
        const double *x;
        int nr = gs_stiffness_run_rows(run, &rows, &x);
        const double *c0 = w->b[0].c, *c1 = w->b[1].c;
        for (int p = 0; p < w->n_pc && (size_t)n < cap; p++) {
            double lam = 0.0, kx = 0.0;
            for (int i = 0; i < nr; i++) {
                if (!(x[i] > 0.0) || w->teeth[i][0] != w->pc[p].tooth[0] || w->teeth[i][1] != w->pc[p].tooth[1])
                    continue;
                lam += x[i];
                kx += x[i] * path_key(rows[i].x[0], c0, c1);
                t->sign = rows[i].dg_dtheta[w->si[0]] > 0 ? 1.0 : -1.0;
            }
            if (!(lam > 1e-6 * w->ftot))
                continue;
            double *r = rec + 4 * (size_t)n++;
            r[0] = kx / lam;
            r[1] = w->pc[p].c;
            r[2] = gsi_stiff_nf_tangent(w, nr, p);
            r[3] = lam;
        }
        for (int k = 0; k < 2; k++)
            t->z[k] = w->b[k].sb->gear.teeth;
    }
    if (e == GS_OK && n < 2)
        e = gs_diag_set(d, GS_ERANGE, "nearfield",
                        "the quasi-static analysis found no near-field correction for this pair "
                        "(it needs quadratic elements, mesh.order 2)");
    if (e == GS_OK && !gsi_stiffness_nf_no_offsets)
        e = offsets_build(run, t);
    if (e == GS_OK) {
        qsort(rec, (size_t)n, 4 * sizeof *rec, by_key);
        t->n = n;
        t->key = malloc((size_t)n * sizeof *t->key);
        t->cs = malloc((size_t)n * sizeof *t->cs);
        t->ct = malloc((size_t)n * sizeof *t->ct);
        t->load = malloc((size_t)n * sizeof *t->load);
        if (!t->key || !t->cs || !t->ct || !t->load)
            e = GS_ENOMEM;
        for (int i = 0; i < n && e == GS_OK; i++) {
            t->key[i] = rec[4 * i];
            t->cs[i] = rec[4 * i + 1];
            t->ct[i] = rec[4 * i + 2];
            t->load[i] = rec[4 * i + 3];
        }
    }
    free(rec);
    gs_stiffness_run_free(&run);
    if (e != GS_OK) {
        gsi_nf_table_free(&t);
        return e;
    }
    *out = t;
    return GS_OK;
}

double gsi_nf_row_compliance(const gsi_nf_table *t, const gs_contact_row *r, const double c0[2],
                             const double c1[2])
{
    if (!t || t->n < 1 || !(r->dg_dtheta[0] * t->sign > 0.0))
        return 0.0;
    double k = path_key(r->x[0], c0, c1);
    if (k <= t->key[0])
        return t->cs[0];
    if (k >= t->key[t->n - 1])
        return t->cs[t->n - 1];
    int lo = gs_index_below(t->key, t->n, k), hi = lo + 1;
    double dk = t->key[hi] - t->key[lo], a = dk > 0.0 ? (k - t->key[lo]) / dk : 0.0;
    return (1.0 - a) * t->cs[lo] + a * t->cs[hi];
}

void gsi_nf_row_offset(const gsi_nf_table *t, const gs_mesh *m0, const gs_mesh *m1, const gs_contact_candidate *c,
                       const gs_contact_pose pose[2], gs_contact_row *r)
{
    if (!t || t->n_off < 2 || !(r->dg_dtheta[0] * t->sign > 0.0))
        return;
    int tooth1 = gsi_nf_pair(t, m0, m1, c) % t->z[1], sl = c->slave;
    double dk_dc0[2];
    double k = tooth_key(pose[1].theta, tooth1, t->z[1], pose[0].c, pose[1].c, dk_dc0);
    /* Linear between samples, the end values beyond (slope 0 there). */
    double off, slope = 0.0;
    if (k <= t->okey[0]) {
        off = t->off[0][sl];
    } else if (k >= t->okey[t->n_off - 1]) {
        off = t->off[t->n_off - 1][sl];
    } else {
        int lo = gs_index_below(t->okey, t->n_off, k), hi = lo + 1;
        double dk = t->okey[hi] - t->okey[lo];
        slope = dk > 0.0 ? (t->off[hi][sl] - t->off[lo][sl]) / dk : 0.0;
        off = t->off[lo][sl] + slope * (k - t->okey[lo]);
    }
    /* g - off(k): dk/dtheta_1 = 1, dk/dc_1 = -dk/dc_0. */
    r->gap.g -= off;
    r->dg_dtheta[1] -= slope;
    for (int i = 0; i < 2; i++) {
        r->dg_dc[0][i] -= slope * dk_dc0[i];
        r->dg_dc[1][i] += slope * dk_dc0[i];
    }
}

int gsi_nf_pair(const gsi_nf_table *t, const gs_mesh *m0, const gs_mesh *m1, const gs_contact_candidate *c)
{
    const gs_mesh *m[2] = {m0, m1};
    int tooth[2];
    gs_index mnode = c->window[c->n_window / 2];
    for (int k = 0; k < 2; k++)
        tooth[k] = c->slave == k ? c->slave_tooth : gsi_stiff_node_tooth(m[k], t->z[k], mnode);
    return tooth[0] * t->z[1] + tooth[1];
}

int gsi_nf_run_secant(const gs_stiffness_run *run, int *pair, double *c_sec)
{
    const work *w = gsi_stiffness_run_work(run);
    const gs_contact_row *rows;
    const double *x;
    int nr = w ? gs_stiffness_run_rows(run, &rows, &x) : 0, np = 0;
    for (int i = 0; i < nr; i++)
        pair[i] = -1;
    if (!w || !w->nf)
        return 0;
    for (int p = 0; p < w->n_pc; p++) {
        if (!(gsi_stiff_nf_tangent(w, nr, p) > 0.0)) /* the pairs the tangent corrects */
            continue;
        for (int i = 0; i < nr; i++)
            if (w->teeth[i][0] == w->pc[p].tooth[0] && w->teeth[i][1] == w->pc[p].tooth[1])
                pair[i] = np;
        c_sec[np++] = w->pc[p].c;
    }
    return np;
}

int gsi_nf_table_samples(const gsi_nf_table *t, const double **key, const double **c_sec,
                         const double **c_tan, const double **load)
{
    if (!t)
        return 0;
    *key = t->key;
    *c_sec = t->cs;
    *c_tan = t->ct;
    *load = t->load;
    return t->n;
}

int gsi_nf_table_offsets(const gsi_nf_table *t, const double **key, const double (**off)[2])
{
    if (!t)
        return 0;
    *key = t->okey;
    *off = (const double(*)[2])t->off;
    return t->n_off;
}
