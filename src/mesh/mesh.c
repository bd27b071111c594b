/* SPDX-License-Identifier: MIT
 * Mesh lifecycle and simple meshes used to verify the FE model. */
#include <stdlib.h>

#include "gearsim/mesh.h"
#include "gearsim/util.h"

void gs_mesh_free(gs_mesh **pm)
{
    if (!pm || !*pm)
        return;
    gs_mesh *m = *pm;
    free(m->xy);
    free(m->tri);
    free(m->fixed);
    free(m->flank_ptr);
    free(m->flank_nodes);
    free(m->node_tag);
    free(m->boundary);
    free(m->mid);
    free(m);
    *pm = NULL;
}

gs_err gs_mesh_rectangle(double lx, double ly, int nx, int ny, gs_mesh **out)
{
    *out = NULL;
    if (!(lx > 0) || !(ly > 0) || nx < 1 || ny < 1)
        return GS_EINVAL;
    gs_mesh *m = gs_calloc(1, sizeof *m);
    if (!m)
        return GS_ENOMEM;
    m->n_nodes = (gs_index)(nx + 1) * (ny + 1);
    m->n_tris = 2 * (gs_index)nx * ny;
    m->n_fixed = ny + 1;
    m->xy = gs_calloc((size_t)(2 * m->n_nodes), sizeof(double));
    m->tri = gs_calloc((size_t)(3 * m->n_tris), sizeof(gs_index));
    m->fixed = gs_calloc((size_t)m->n_fixed, sizeof(gs_index));
    if (!m->xy || !m->tri || !m->fixed) {
        gs_mesh_free(&m);
        return GS_ENOMEM;
    }
    for (int j = 0; j <= ny; j++)
        for (int i = 0; i <= nx; i++) {
            gs_index k = (gs_index)j * (nx + 1) + i;
            m->xy[2 * k] = lx * i / nx;
            m->xy[2 * k + 1] = -0.5 * ly + ly * j / ny;
        }
    gs_index t = 0;
    for (int j = 0; j < ny; j++)
        for (int i = 0; i < nx; i++) {
            gs_index a = (gs_index)j * (nx + 1) + i, b = a + 1, c = a + nx + 1, d = c + 1;
            if ((i + j) % 2 == 0) {
                gs_index e[6] = {a, b, d, a, d, c};
                for (int q = 0; q < 6; q++)
                    m->tri[3 * t + q] = e[q];
            } else {
                gs_index e[6] = {a, b, c, b, d, c};
                for (int q = 0; q < 6; q++)
                    m->tri[3 * t + q] = e[q];
            }
            t += 2;
        }
    for (int j = 0; j <= ny; j++)
        m->fixed[j] = (gs_index)j * (nx + 1);
    *out = m;
    return GS_OK;
}
