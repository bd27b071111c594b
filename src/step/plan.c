/* SPDX-License-Identifier: MIT
 * The step plan: what every rank must agree on before the records are
 * exchanged (step.h, gs_step_plan). The contact search of every contact
 * mesh runs here on every rank, from the rigid state only (METHOD.md
 * section 5: deterministic, so every rank finds the same candidates and no
 * candidate list has to travel); the nodes it names become interface
 * unknowns of their elastic bodies. */
#include <stdlib.h>
#include <string.h>

#include "contact/contact_mesh.h"
#include "step_internal.h"
#include "gearsim/util.h"

void gsi_plan_free(gs_step_plan *p, int n_bodies)
{
    for (int i = 0; p->nodes && i < n_bodies; i++)
        free(p->nodes[i]);
    for (int i = 0; p->seen && i < n_bodies; i++)
        free(p->seen[i]);
    free(p->nodes);
    free(p->seen);
    p->nodes = NULL;
    p->seen = NULL;
    free(p->n_nodes);
    free(p->cap_nodes);
    free(p->n_dof);
    free(p->rec_off);
    free(p->sol_off);
    p->n_nodes = p->n_dof = NULL;
    p->cap_nodes = NULL;
    p->rec_off = p->sol_off = NULL;
}

gs_err gsi_plan_new(gs_system *sys)
{
    gs_step_plan *p = &sys->plan;
    size_t nb = (size_t)(sys->n_bodies ? sys->n_bodies : 1);
    p->n_nodes = gs_calloc(nb, sizeof(int));
    p->cap_nodes = gs_calloc(nb, sizeof(size_t));
    p->n_dof = gs_calloc(nb, sizeof(int));
    p->nodes = gs_calloc(nb, sizeof(gs_index *));
    p->rec_off = gs_calloc(nb, sizeof(size_t));
    p->sol_off = gs_calloc(nb, sizeof(size_t));
    p->seen = gs_calloc(nb, sizeof(uint32_t *));
    if (!p->n_nodes || !p->cap_nodes || !p->n_dof || !p->nodes || !p->rec_off || !p->sol_off || !p->seen)
        return GS_ENOMEM;
    return GS_OK;
}

static gs_err add_node(gs_step_plan *p, int body, gs_index node)
{
    /* A node already listed in this pass: nothing to add (every window
     * names its master nodes again). */
    uint32_t *seen = p->seen[body];
    if (seen) {
        if (seen[node] == p->pass)
            return GS_OK;
        seen[node] = p->pass;
    }
    gs_index *nn = gs_grow(p->nodes[body], &p->cap_nodes[body], (size_t)p->n_nodes[body] + 1,
                           sizeof(gs_index));
    if (!nn)
        return GS_ENOMEM;
    p->nodes[body] = nn;
    p->nodes[body][p->n_nodes[body]++] = node;
    return GS_OK;
}

static int cmp_index(const void *a, const void *b)
{
    gs_index x = *(const gs_index *)a, y = *(const gs_index *)b;
    return (x > y) - (x < y);
}

/* Ascending order of n distinct nodes: insertion sort, close to linear on
 * the lists the search makes (tooth after tooth, nodes mostly in order). */
static void sort_unique(gs_index *v, int n)
{
    for (int j = 1; j < n; j++) {
        gs_index x = v[j];
        int k = j;
        while (k > 0 && v[k - 1] > x) {
            v[k] = v[k - 1];
            k--;
        }
        v[k] = x;
    }
}

int gsi_plan_find(const gs_step_plan *p, int body, gs_index node)
{
    const gs_index *v = p->nodes[body];
    int lo = 0, hi = p->n_nodes[body] - 1;
    while (lo <= hi) {
        int mid = (lo + hi) / 2;
        if (v[mid] == node)
            return mid;
        if (v[mid] < node)
            lo = mid + 1;
        else
            hi = mid - 1;
    }
    return -1;
}

/* Candidates of one contact mesh from the rigid state; their nodes on
 * elastic gears (not on the fixed core) join the plan. */
static gs_err search(gs_system *sys, gs_gmesh_rt *m)
{
    gsi_contact_mesh *cm = m->contact;
    gs_contact_pose pose[2];
    for (int k = 0; k < 2; k++) {
        gs_system_body_pose(sys, cm->body[k], pose[k].c, &pose[k].theta);
        pose[k].u = NULL;
    }
    GS_TRY(gs_contact_search_run(cm->search, pose, &cm->cand, &cm->n_cand, NULL));
    for (gs_index j = 0; j < cm->n_cand; j++) {
        const gs_contact_candidate *c = &cm->cand[j];
        if (cm->elastic[c->slave])
            GS_TRY(add_node(&sys->plan, cm->body[c->slave], c->slave_node));
        if (cm->elastic[c->master])
            for (int w = 0; w < c->n_window; w++)
                GS_TRY(add_node(&sys->plan, cm->body[c->master], c->window[w]));
    }
    return GS_OK;
}

gs_err gs_step_prepare(gs_system *sys)
{
    gs_step_plan *p = &sys->plan;
    for (int i = 0; i < sys->n_bodies; i++)
        p->n_nodes[i] = 0;
    bool wrapped = ++p->pass == 0;
    for (int i = 0; i < sys->n_bodies; i++) {
        /* Marks for the nodes of bodies with a mesh (made once, after the
         * bodies are built; all cleared when the pass count wraps). */
        const gs_body_rt *b = &sys->bodies[i];
        const gs_mesh *m = b->ops && b->ops->mesh ? b->ops->mesh(b) : NULL;
        if (!m)
            continue;
        if (!p->seen[i]) {
            p->seen[i] = gs_calloc((size_t)m->n_nodes + 1, sizeof(uint32_t));
            if (!p->seen[i])
                return GS_ENOMEM;
        } else if (wrapped) {
            memset(p->seen[i], 0, ((size_t)m->n_nodes + 1) * sizeof(uint32_t));
        }
    }
    if (wrapped)
        p->pass = 1;
    for (int i = 0; i < sys->n_meshes; i++)
        if (sys->meshes[i].ops->contact)
            GS_TRY(search(sys, &sys->meshes[i]));
    /* Solution: dq, dissipation, mesh forces, contact figures, then forces. */
    size_t roff = 0, soff = (size_t)(sys->n_coords + 1 + (1 + GS_SOL_CONTACT) * sys->n_meshes);
    for (int i = 0; i < sys->n_bodies; i++) {
        int n = p->n_nodes[i];
        if (n > 1) {
            /* Sorted and unique, so that every rank lays the record out alike
             * and the solve can look nodes up by bisection. */
            if (p->seen[i])
                sort_unique(p->nodes[i], n);
            else
                qsort(p->nodes[i], (size_t)n, sizeof(gs_index), cmp_index);
            int k = 1;
            for (int j = 1; j < n; j++)
                if (p->nodes[i][j] != p->nodes[i][k - 1])
                    p->nodes[i][k++] = p->nodes[i][j];
            p->n_nodes[i] = n = k;
        }
        int nd = (sys->bodies[i].coord >= 0 ? 1 : 0) + 2 * n;
        p->n_dof[i] = nd;
        p->rec_off[i] = roff;
        p->sol_off[i] = soff;
        roff += (size_t)nd * (size_t)nd + (size_t)nd + 2 * (size_t)n;
        soff += (size_t)nd;
    }
    p->rec_size = roff ? roff : 1;
    p->sol_size = soff;
    return GS_OK;
}
