/* SPDX-License-Identifier: MIT
 * gearsim: conforming linear-triangle meshes of the elastic part of a gear
 * (docs/explanation/geometry.md, "Meshes").
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
#include "mesh/gear_mesh_internal.h"
#include "mesh/mesh_internal.h"

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
    gs_err e = gsi_gmesh_make_plan(&g, o, pl, d);
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
        e = plv[lv] ? gsi_gmesh_make_plan(&g, &of, plv[lv], d) : GS_ENOMEM;
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
                e = gsi_gmesh_build_sector(&g, pv, plv[lk + up], nclo, nchi, sv);
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
                map[l] = gsi_gmesh_node_add(&nd, c * x - sn * y, sn * x + c * y, sv->nd.tag[l]);
                if (map[l] < 0)
                    goto fail;
            }
            if (k == 0)
                for (int j = 0; j < sv->nleft; j++)
                    first_left[j] = map[sv->left[j]];
            for (int j = 0; j < sv->nright; j++)
                prev_right[j] = map[sv->right[j]];
            for (gs_index t = 0; t < sv->tr.n; t++)
                if (gsi_gmesh_tri_add(&tr, map[sv->tr.t[3 * t]], map[sv->tr.t[3 * t + 1]],
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
        if (gsi_gmesh_plan_rings(&g, pl->R0, n0_base, h0, &rp))
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
                            ringB[cnt] = gsi_gmesh_node_add(&nd, R * cos(ai), R * sin(ai),
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
                if (gsi_gmesh_zipper(&nd, &tr, ringA, nA, ringB, nB, !g.internal))
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
    if (gsi_gmesh_smooth_poor(&nd, &tr, 40, 0.6))
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
        gsi_gmesh_sector_free(&sec[v]);
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
