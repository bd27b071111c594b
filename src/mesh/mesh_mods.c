/* SPDX-License-Identifier: MIT
 * gearsim: a gear's profile modifications and tooth errors applied to its FE
 * mesh (include/gearsim/mesh.h, gs_gear_mods_apply_mesh; the modifications
 * themselves are geometry, src/geometry/modification.c). */
#include <math.h>

#include "gearsim/mesh.h"
#include "gearsim/modification.h"
#include "gearsim/util.h"

gs_err gs_gear_mods_apply_mesh(const gs_gear_geom *g, const gs_gear_mods *m, gs_mesh *mesh,
                               gs_diag *d)
{
    if (!gs_gear_mods_any(m))
        return GS_OK;
    const int z = g->z;
    const double pitch = 2.0 * GS_PI / z, half = GS_PI / z;
    double *xy = mesh->xy;
    /* 1. Profile: flank nodes to the modified flank at their radius. The
     * node's side follows from its polar angle relative to its tooth. */
    if (gs_gear_mods_has_profile(m) && mesh->node_tag) {
        for (gs_index i = 0; i < mesh->n_nodes; i++) {
            if (mesh->node_tag[i] != GS_NODE_FLANK)
                continue;
            double x = xy[2 * i], y = xy[2 * i + 1], R = hypot(x, y);
            double th = atan2(y, x);
            double k = nearbyint(th / pitch);
            double a = th - k * pitch;
            int side = a > 0.0 ? GS_FLANK_CCW : GS_FLANK_CW;
            double f = gs_gear_flank_offset(g, m, side, R);
            if (f == 0.0)
                continue;
            double psi = gs_gear_involute_psi(g, R) + f / g->rb;
            double t = k * pitch + (side == GS_FLANK_CCW ? psi : -psi);
            xy[2 * i] = R * cos(t);
            xy[2 * i + 1] = R * sin(t);
        }
    }
    /* 2. Pitch errors: tooth k turned by e_k / r, fully from half way
     * between root and pitch circle outwards, fading to the root circle. */
    if (m->n_pitch == z) {
        double r = g->r, rr = g->rf;
        double span = 0.5 * fabs(r - rr);
        for (gs_index i = 0; i < mesh->n_nodes; i++) {
            double x = xy[2 * i], y = xy[2 * i + 1], rad = hypot(x, y);
            double th = atan2(y, x);
            long k = lround(th / pitch);
            double a = remainder(th - 2.0 * GS_PI * (double)k / z, 2.0 * GS_PI);
            int kk = (int)(((k % z) + z) % z);
            double e = m->pitch_m[kk];
            if (e == 0.0 || fabs(a) > half)
                continue;
            double w = (g->internal ? rr - rad : rad - rr) / span;
            w = w < 0 ? 0 : (w > 1 ? 1 : w);
            double t = e / r * w, ct = cos(t), st = sin(t);
            xy[2 * i] = ct * x - st * y;
            xy[2 * i + 1] = st * x + ct * y;
        }
    }
    /* 3. Run-out: the toothed body offset from the axis. */
    if (m->runout_m != 0.0) {
        double ex = m->runout_m * cos(m->runout_phase), ey = m->runout_m * sin(m->runout_phase);
        for (gs_index i = 0; i < mesh->n_nodes; i++) {
            xy[2 * i] += ex;
            xy[2 * i + 1] += ey;
        }
    }
    /* No element may have turned over. */
    for (gs_index t = 0; t < mesh->n_tris; t++) {
        const double *p0 = xy + 2 * mesh->tri[3 * t], *p1 = xy + 2 * mesh->tri[3 * t + 1],
                     *p2 = xy + 2 * mesh->tri[3 * t + 2];
        double ar = (p1[0] - p0[0]) * (p2[1] - p0[1]) - (p1[1] - p0[1]) * (p2[0] - p0[0]);
        double l2 = fmax(fmax(hypot(p1[0] - p0[0], p1[1] - p0[1]), hypot(p2[0] - p1[0], p2[1] - p1[1])),
                         hypot(p0[0] - p2[0], p0[1] - p2[1]));
        if (!(ar > 1e-12 * l2 * l2))
            return gs_diag_set(d, GS_EGEOMETRY, "modification",
                               "the modifications turn element %lld over: the mesh is too coarse "
                               "or fine for offsets this large; reduce them or change the mesh",
                               (long long)t);
    }
    return GS_OK;
}
