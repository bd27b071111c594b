/* SPDX-License-Identifier: MIT
 * The owner map of bodies over ranks (src/step/system.c assign_owners):
 * rank 0 alone selects the contact rows and solves the QP, so it must hold
 * the lightest share of the elastic gears (docs/performance/index.md); the map is the
 * same on every rank and on every build of the same
 * scene (the engine, checkpoints and the daemon's ranks rely on it); no
 * rank is left without a gear while another holds two.
 *
 * The share is counted here independently of the map's own weights: the
 * unknowns (2 per node) of each gear's mesh as gs_scene_gear_mesh builds
 * it, the size the free-motion solve scales with. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <string.h>

#include "gearsim/mesh.h"
#include "gearsim/models.h"
#include "gearsim/scene.h"
#include "gearsim/step.h"

enum { MAXB = 16, MAXR = 8 };

/* The owners of a builtin scene's bodies at `nranks`, as built on rank
 * `rank`; returns the body count. Built on a rank past the last so that no
 * gear is factorised (the map does not depend on the building rank: that is
 * checked below). */
static int owners_of(const char *name, int rank, int nranks, int owner[MAXB], long unknowns[MAXB])
{
    const char *txt = gs_scene_builtin(name);
    assert_non_null(txt);
    gs_scene *sc = NULL;
    gs_diag d;
    assert_int_equal(gs_scene_parse(txt, strlen(txt), &sc, &d), GS_OK);
    gs_system *sys = NULL;
    assert_int_equal(gs_system_new(sc, rank, nranks, &sys, &d), GS_OK);
    int n = sys->n_bodies;
    assert_true(n <= MAXB);
    for (int i = 0; i < n; i++) {
        owner[i] = sys->bodies[i].owner;
        unknowns[i] = 0;
        if (sys->scene->bodies[i].model == GS_MODEL_ELASTIC) {
            gs_mesh *m = NULL;
            assert_int_equal(gs_scene_gear_mesh(&sys->scene->bodies[i], &m, &d), GS_OK);
            unknowns[i] = 2L * (long)m->n_nodes;
            gs_mesh_free(&m);
        }
    }
    gs_system_free(&sys);
    return n;
}

static int body_index(const char *scene, const char *body)
{
    gs_scene *sc = NULL;
    gs_diag d;
    const char *txt = gs_scene_builtin(scene);
    assert_int_equal(gs_scene_parse(txt, strlen(txt), &sc, &d), GS_OK);
    int k = -1;
    for (int i = 0; i < sc->n_bodies; i++)
        if (strcmp(sc->bodies[i].name, body) == 0)
            k = i;
    gs_scene_free(&sc);
    assert_true(k >= 0);
    return k;
}

/* The pair at 2 ranks: the pinion (20 teeth, fewer unknowns) with the
 * serial work on rank 0, the wheel alone on rank 1. */
static void pair_two_ranks(void **st)
{
    (void)st;
    int owner[MAXB];
    long unk[MAXB];
    owners_of("contact_drive", 2, 2, owner, unk);
    int p = body_index("contact_drive", "pinion"), w = body_index("contact_drive", "wheel");
    assert_true(unk[p] < unk[w]);
    assert_int_equal(owner[p], 0);
    assert_int_equal(owner[w], 1);
}

/* For both contact scenes at 1 to 4 ranks: rank 0's unknowns are the
 * fewest of any rank; every rank owns a gear when there are at least as
 * many gears as ranks; the map is the same built on any rank and built
 * twice. */
static void lightest_on_rank_zero(void **st)
{
    (void)st;
    const char *scenes[] = {"contact_drive", "planetary_contact"};
    for (int k = 0; k < 2; k++)
        for (int nr = 1; nr <= 4; nr++) {
            int owner[MAXB], again[MAXB];
            long unk[MAXB], sum[MAXR] = {0};
            int gears[MAXR] = {0}, ng = 0;
            int n = owners_of(scenes[k], nr, nr, owner, unk);
            for (int i = 0; i < n; i++) {
                assert_true(owner[i] >= 0 && owner[i] < nr);
                sum[owner[i]] += unk[i];
                if (unk[i] > 0) {
                    gears[owner[i]]++;
                    ng++;
                }
            }
            for (int r = 1; r < nr; r++) {
                print_message("%s, %d ranks: rank 0 %ld unknowns, rank %d %ld\n", scenes[k], nr, sum[0], r, sum[r]);
                assert_true(sum[0] <= sum[r]);
                if (ng >= nr)
                    assert_true(gears[r] > 0);
            }
            if (ng >= nr)
                assert_true(gears[0] > 0);
            owners_of(scenes[k], nr, nr, again, unk);
            assert_memory_equal(owner, again, (size_t)n * sizeof *owner);
            if (k == 0) /* built on a rank that factorises its gear */
                for (int rank = 0; rank < nr; rank++) {
                    owners_of(scenes[k], rank, nr, again, unk);
                    assert_memory_equal(owner, again, (size_t)n * sizeof *owner);
                }
        }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(pair_two_ranks),
        cmocka_unit_test(lightest_on_rank_zero),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
