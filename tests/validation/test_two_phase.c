/* SPDX-License-Identifier: MIT
 * The two-phase step record (step.h, docs/performance/index.md)
 * against the whole record it replaces: on elastic gears in contact, each
 * substep is formed both ways from the same state — every body's whole
 * record (interface(): the full compliance block over its plan dofs), and
 * the free parts, the selection, then only the selected sub-blocks — and
 * the two solutions must agree bit for bit, as must the compliance entries
 * the selection names. The selection must also be what makes the saving:
 * with the seed's rows, a small part of the whole blocks (checked below a
 * quarter of their entries); with closure, whole blocks (its increments
 * read whole columns). Scenes: contact_drive (seed and closure) and
 * planetary_contact, from a state with teeth in mesh. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <json-c/json.h>

#include "gearsim/models.h"
#include "gearsim/step.h"
#include "gearsim/util.h"
#include "scene_build.h"

static gs_system *build(const char *builtin, const char *scheme)
{
    json_object *root = vt_scene(builtin);
    if (scheme) {
        json_object *num = json_object_object_get(root, "numerics");
        json_object_object_add(num, "contact", json_object_new_string(scheme));
    }
    return vt_system(root);
}

/* Warm up, then `steps` substeps formed both ways; returns the fraction of
 * the whole blocks' entries the selections named (over all the substeps). */
static double compare(const char *builtin, const char *scheme, int warm, int steps)
{
    gs_system *sys = build(builtin, scheme);
    for (int k = 0; k < warm; k++)
        assert_int_equal(gs_step_serial(sys), GS_OK);
    double sel_entries = 0, all_entries = 0;
    int with_rows = 0;
    for (int k = 0; k < steps; k++) {
        assert_int_equal(gs_step_prepare(sys), GS_OK);
        const gs_step_plan *p = &sys->plan;
        size_t rn = p->rec_size, sn = p->sol_size;
        double *rec1 = calloc(rn, sizeof(double)), *rec2 = calloc(rn, sizeof(double));
        double *sol1 = calloc(sn, sizeof(double)), *sol2 = calloc(sn, sizeof(double));
        assert_true(rec1 && rec2 && sol1 && sol2);
        /* the whole records, as before the two phases */
        gs_model_view v;
        gs_system_view(sys, &v);
        for (int i = 0; i < sys->n_bodies; i++)
            sys->bodies[i].ops->interface(&v, &sys->bodies[i], sys->h_sub, rec1 + p->rec_off[i]);
        assert_int_equal(gs_step_solve(sys, rec1, sol1), GS_OK);
        /* the two phases (the bodies' steps begun again from the same state) */
        assert_true(gs_step_two_phase(sys));
        gs_step_records(sys, rec2);
        int *mask = gs_step_mask(sys);
        assert_non_null(mask);
        assert_int_equal(gs_step_select(sys, rec2, mask), GS_OK);
        size_t cn = gs_step_compliance_size(sys, mask);
        double *cb = calloc(cn, sizeof(double));
        assert_non_null(cb);
        assert_int_equal(gs_step_compliance(sys, mask, cb), GS_OK);
        assert_int_equal(gs_step_compliance_unpack(sys, mask, cb, rec2), GS_OK);
        assert_int_equal(gs_step_solve(sys, rec2, sol2), GS_OK);
        assert_memory_equal(sol1, sol2, sn * sizeof(double));
        const int *mk = mask;
        for (int i = 0; i < sys->n_bodies; i++) {
            int nd = p->n_dof[i];
            const double *C1 = rec1 + p->rec_off[i], *C2 = rec2 + p->rec_off[i];
            /* free increments and node displacements: equal */
            assert_memory_equal(C1 + (size_t)nd * nd, C2 + (size_t)nd * nd,
                                ((size_t)nd + 2 * (size_t)p->n_nodes[i]) * sizeof(double));
            int kk = 0;
            for (int a = 0; a < nd; a++) {
                kk += mk[a] != 0;
                for (int b = 0; b < nd; b++)
                    if (mk[a] && mk[b])
                        assert_memory_equal(&C1[(size_t)b * nd + a], &C2[(size_t)b * nd + a], sizeof(double));
            }
            if (p->n_nodes[i] > 0) {
                sel_entries += (double)kk * kk;
                all_entries += (double)nd * nd;
            }
            mk += nd;
        }
        for (int m = 0; m < sys->n_meshes; m++)
            with_rows += sol2[gs_sol_mesh_contact(sys, m) + 1] > 0;
        assert_int_equal(gs_step_apply(sys, sol2), GS_OK);
        gs_step_advance(sys);
        free(cb);
        free(rec1), free(rec2), free(sol1), free(sol2);
    }
    assert_true(with_rows > 0); /* the comparison saw contact rows */
    gs_system_free(&sys);
    double frac = sel_entries / all_entries;
    printf("# %s (%s): %d substeps with teeth in mesh, selected entries %.4f of the whole blocks\n", builtin,
           scheme ? scheme : "seed", steps, frac);
    return frac;
}

static void pair_seed(void **state)
{
    (void)state;
    assert_true(compare("contact_drive", "seed", 300, 40) < 0.25);
}

static void pair_closure(void **state)
{
    (void)state;
    assert_true(compare("contact_drive", "closure", 300, 20) == 1.0);
}

static void planetary(void **state)
{
    (void)state;
    assert_true(compare("planetary_contact", "seed", 500, 15) < 0.25);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(pair_seed),
        cmocka_unit_test(pair_closure),
        cmocka_unit_test(planetary),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
