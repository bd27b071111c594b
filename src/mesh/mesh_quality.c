/* SPDX-License-Identifier: MIT
 * gearsim: element quality and topology checks of triangle meshes. */
#include <math.h>
#include <stdlib.h>

#include "gearsim/mesh.h"

void gs_mesh_quality_eval(const gs_mesh *m, gs_mesh_quality *q)
{
    q->n_tris = m->n_tris;
    q->n_bad = 0;
    q->area = 0.0;
    q->min_area = INFINITY;
    q->max_area = -INFINITY;
    q->min_angle_deg = 180.0;
    q->max_angle_deg = 0.0;
    q->max_aspect = 0.0;
    q->mean_aspect = 0.0;
    q->min_edge = INFINITY;
    q->max_edge = 0.0;
    for (gs_index t = 0; t < m->n_tris; t++) {
        const gs_index *v = m->tri + 3 * t;
        double x[3], y[3], e[3];
        for (int k = 0; k < 3; k++) {
            x[k] = m->xy[2 * v[k]];
            y[k] = m->xy[2 * v[k] + 1];
        }
        for (int k = 0; k < 3; k++) /* e[k] opposite vertex k */
            e[k] = hypot(x[(k + 2) % 3] - x[(k + 1) % 3], y[(k + 2) % 3] - y[(k + 1) % 3]);
        double A = 0.5 * ((x[1] - x[0]) * (y[2] - y[0]) - (y[1] - y[0]) * (x[2] - x[0]));
        double emax = fmax(e[0], fmax(e[1], e[2])), emin = fmin(e[0], fmin(e[1], e[2]));
        q->area += A;
        if (A < q->min_area)
            q->min_area = A;
        if (A > q->max_area)
            q->max_area = A;
        if (emin < q->min_edge)
            q->min_edge = emin;
        if (emax > q->max_edge)
            q->max_edge = emax;
        if (!(A > 1e-12 * emax * emax)) {
            q->n_bad++;
            continue;
        }
        for (int k = 0; k < 3; k++) {
            /* angle at vertex k from the law of cosines, clamped */
            double a = e[k], b = e[(k + 1) % 3], c = e[(k + 2) % 3];
            double cs = (b * b + c * c - a * a) / (2.0 * b * c);
            cs = cs > 1 ? 1 : cs < -1 ? -1 : cs;
            double ang = acos(cs) * 180.0 / GS_PI;
            if (ang < q->min_angle_deg)
                q->min_angle_deg = ang;
            if (ang > q->max_angle_deg)
                q->max_angle_deg = ang;
        }
        /* R / (2 r) = a b c s / (8 A^2), s the half perimeter */
        double s = 0.5 * (e[0] + e[1] + e[2]);
        double asp = e[0] * e[1] * e[2] * s / (8.0 * A * A);
        if (asp > q->max_aspect)
            q->max_aspect = asp;
        q->mean_aspect += asp;
    }
    gs_index good = m->n_tris - q->n_bad;
    if (good > 0)
        q->mean_aspect /= (double)good;
}

typedef struct {
    gs_index a, b;
} edge_t;

static int edge_cmp(const void *p, const void *q)
{
    const edge_t *x = p, *y = q;
    if (x->a != y->a)
        return x->a < y->a ? -1 : 1;
    if (x->b != y->b)
        return x->b < y->b ? -1 : 1;
    return 0;
}

static gs_index uf_find(gs_index *par, gs_index i)
{
    while (par[i] != i) {
        par[i] = par[par[i]];
        i = par[i];
    }
    return i;
}

gs_err gs_mesh_check_topology(const gs_mesh *m, gs_index *n_boundary_edges, int *n_loops)
{
    gs_index ne = 3 * m->n_tris;
    edge_t *E = malloc((size_t)(ne ? ne : 1) * sizeof *E);
    gs_index *deg = calloc((size_t)m->n_nodes + 1, sizeof *deg);
    gs_index *par = malloc(((size_t)m->n_nodes + 1) * sizeof *par);
    char *used = calloc((size_t)m->n_nodes + 1, 1);
    gs_err e = GS_ENOMEM;
    if (!E || !deg || !par || !used)
        goto out;
    e = GS_EINVAL;
    for (gs_index t = 0; t < m->n_tris; t++) {
        const gs_index *v = m->tri + 3 * t;
        for (int k = 0; k < 3; k++) {
            if (v[k] < 0 || v[k] >= m->n_nodes)
                goto out;
            used[v[k]] = 1;
        }
        if (v[0] == v[1] || v[1] == v[2] || v[0] == v[2])
            goto out;
        for (int k = 0; k < 3; k++) {
            gs_index a = v[k], b = v[(k + 1) % 3];
            E[3 * t + k].a = a < b ? a : b;
            E[3 * t + k].b = a < b ? b : a;
        }
    }
    if (m->mid)
        for (gs_index i = 0; i < 3 * m->n_tris; i++) {
            if (m->mid[i] < 0 || m->mid[i] >= m->n_nodes)
                goto out;
            used[m->mid[i]] = 1;
        }
    for (gs_index i = 0; i < m->n_nodes; i++) {
        if (!used[i])
            goto out;
        par[i] = i;
    }
    qsort(E, (size_t)ne, sizeof *E, edge_cmp);
    gs_index nb = 0;
    for (gs_index i = 0; i < ne;) {
        gs_index j = i;
        while (j < ne && E[j].a == E[i].a && E[j].b == E[i].b)
            j++;
        if (j - i > 2)
            goto out;
        if (j - i == 1) {
            nb++;
            deg[E[i].a]++;
            deg[E[i].b]++;
            gs_index ra = uf_find(par, E[i].a), rb = uf_find(par, E[i].b);
            if (ra != rb)
                par[ra] = rb;
        }
        i = j;
    }
    int loops = 0;
    for (gs_index i = 0; i < m->n_nodes; i++) {
        if (deg[i] != 0 && deg[i] != 2)
            goto out; /* a boundary that touches itself */
        if (deg[i] == 2 && uf_find(par, i) == i)
            loops++;
    }
    if (n_boundary_edges)
        *n_boundary_edges = nb;
    if (n_loops)
        *n_loops = loops;
    e = GS_OK;
out:
    free(E);
    free(deg);
    free(par);
    free(used);
    return e;
}
