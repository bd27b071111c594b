/* SPDX-License-Identifier: MIT
 * An annulus mesh (a gear-like rim on a rigid hub) for the fe tests and the
 * benchmark, until the gear mesher provides toothed bodies. */
#include <math.h>
#include <stdlib.h>

#include "fe/fe_internal.h"
#include "gearsim/util.h"

gs_err gsi_fe_mesh_annulus(double r_in, double r_out, int n_r, int n_t, gs_mesh **out)
{
    if (!out)
        return GS_EINVAL;
    *out = NULL;
    if (!(r_in > 0) || !(r_out > r_in) || !isfinite(r_out) || n_r < 1 || n_t < 3)
        return GS_EINVAL;
    gs_mesh *m = gs_calloc(1, sizeof *m);
    if (!m)
        return GS_ENOMEM;
    m->n_nodes = (gs_index)(n_r + 1) * n_t;
    m->n_tris = 2 * (gs_index)n_r * n_t;
    m->n_fixed = n_t;
    m->xy = gs_calloc((size_t)(2 * m->n_nodes), sizeof *m->xy);
    m->tri = gs_calloc((size_t)(3 * m->n_tris), sizeof *m->tri);
    m->fixed = gs_calloc((size_t)m->n_fixed, sizeof *m->fixed);
    if (!m->xy || !m->tri || !m->fixed) {
        gs_mesh_free(&m);
        return GS_ENOMEM;
    }
    for (int j = 0; j <= n_r; j++) {
        double r = r_in + (r_out - r_in) * j / n_r;
        for (int i = 0; i < n_t; i++) {
            double a = 2.0 * GS_PI * i / n_t;
            gs_index k = (gs_index)j * n_t + i;
            m->xy[2 * k] = r * cos(a);
            m->xy[2 * k + 1] = r * sin(a);
        }
    }
    gs_index t = 0;
    for (int j = 0; j < n_r; j++)
        for (int i = 0; i < n_t; i++) {
            /* a, b on radius j; d, c on radius j + 1; angle grows a -> b and
             * d -> c, so (a, d, c, b) runs counter-clockwise */
            gs_index a = (gs_index)j * n_t + i, b = (gs_index)j * n_t + (i + 1) % n_t;
            gs_index d = a + n_t, c = b + n_t;
            gs_index e[6];
            if ((i + j) % 2 == 0) {
                gs_index f[6] = {a, d, c, a, c, b};
                for (int q = 0; q < 6; q++)
                    e[q] = f[q];
            } else {
                gs_index f[6] = {a, d, b, d, c, b};
                for (int q = 0; q < 6; q++)
                    e[q] = f[q];
            }
            for (int q = 0; q < 6; q++)
                m->tri[3 * t + q] = e[q];
            t += 2;
        }
    for (int i = 0; i < n_t; i++)
        m->fixed[i] = i;
    *out = m;
    return GS_OK;
}

gs_err gsi_fe_mesh_annulus_order(double r_in, double r_out, int n_r, int n_t, int order,
                                 gs_mesh **out)
{
    if (order != 1 && order != 2)
        return GS_EINVAL;
    GS_TRY(gsi_fe_mesh_annulus(r_in, r_out, n_r, n_t, out));
    if (order == 1)
        return GS_OK;
    gs_mesh *m = *out;
    gs_index n0 = m->n_nodes;
    gs_err e = gs_mesh_make_quadratic(m);
    if (e != GS_OK) {
        gs_mesh_free(out);
        return e;
    }
    /* boundary mid-side nodes: the middle of an edge with both ends on one
     * circle goes onto that circle (same angle) */
    for (gs_index t = 0; t < m->n_tris; t++)
        for (int i = 0; i < 3; i++) {
            gs_index k = m->mid[3 * t + i];
            if (k < n0)
                continue;
            const double *p = m->xy + 2 * m->tri[3 * t + i], *q = m->xy + 2 * m->tri[3 * t + (i + 1) % 3];
            double rp = hypot(p[0], p[1]), rq = hypot(q[0], q[1]);
            for (int c = 0; c < 2; c++) {
                double R = c ? r_out : r_in;
                if (fabs(rp - R) < 1e-12 * R && fabs(rq - R) < 1e-12 * R) {
                    double x = m->xy[2 * k], y = m->xy[2 * k + 1], r = hypot(x, y);
                    m->xy[2 * k] = x * R / r;
                    m->xy[2 * k + 1] = y * R / r;
                }
            }
        }
    return GS_OK;
}
