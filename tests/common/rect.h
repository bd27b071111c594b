/* SPDX-License-Identifier: MIT
 * Shared by the unit tests: a rectangle mesh without fixed nodes whose
 * interior nodes are moved by a fixed pseudo-random pattern (patch tests).
 * Include after cmocka.h. */
#ifndef GEARSIM_TESTS_RECT_H
#define GEARSIM_TESTS_RECT_H

#include <math.h>

#include "gearsim/mesh.h"

/* gs_mesh_rectangle(lx, ly, nx, ny) with no fixed node, interior nodes moved
 * by up to `distort` of a cell. */
static inline gs_mesh *free_rectangle(double lx, double ly, int nx, int ny, double distort)
{
    gs_mesh *m = NULL;
    assert_int_equal(gs_mesh_rectangle(lx, ly, nx, ny, &m), GS_OK);
    m->n_fixed = 0;
    for (int j = 1; j < ny; j++)
        for (int i = 1; i < nx; i++) {
            gs_index k = (gs_index)j * (nx + 1) + i;
            m->xy[2 * k] += distort * lx / nx * sin(1.7 * k + 0.3);
            m->xy[2 * k + 1] += distort * ly / ny * cos(2.3 * k + 0.1);
        }
    return m;
}

#endif
