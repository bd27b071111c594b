/* SPDX-License-Identifier: MIT
 * Shared by the unit tests: gear parameters from the defaults and their
 * mesh. Include after cmocka.h. */
#ifndef GEARSIM_TESTS_GEARS_H
#define GEARSIM_TESTS_GEARS_H

#include <string.h>

#include "gearsim/geometry.h"
#include "gearsim/mesh.h"

/* The default gear with z teeth of module m (metres) and profile shift x. */
static inline gs_gear_params gear(gs_gear_kind kind, int z, double m, double x)
{
    gs_gear_params p;
    memset(&p, 0, sizeof p);
    gs_gear_params_defaults(&p);
    p.kind = kind;
    p.teeth = z;
    p.module_m = m;
    p.profile_shift = x;
    return p;
}

/* The default linear mesh (order 1, its default counts) of p at the given
 * refinement; fails the test with the diagnostic on error. The unit tests
 * of the mesher's layout and of the contact search on straight edges use
 * it; the quadratic default mesh is tested in test_fe_quad.c. */
static inline gs_mesh *mesh_of(const gs_gear_params *p, int refine)
{
    gs_gear_mesh_opts o;
    gs_gear_mesh_opts_for_order(&o, 1);
    o.refine = refine;
    gs_mesh *m = NULL;
    gs_diag d;
    gs_diag_clear(&d);
    gs_err e = gs_gear_mesh(p, &o, &m, &d);
    if (e != GS_OK)
        print_error("gs_gear_mesh: %s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    return m;
}

#endif
