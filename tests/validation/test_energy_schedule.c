/* SPDX-License-Identifier: MIT
 * The engine's energy schedule (gs_engine_set_energy_schedule,
 * docs/performance/index.md): elastic gears skip their kinetic and strain
 * energies at the end of steps whose energies nothing reads, and sum them
 * from the state when they are read. Two engines step the same scene, one
 * with the energies every step, one on the schedule, in chunks of uneven
 * length; the scene publishes every 7 steps. Required: at every published
 * step (read by the step hook, as the daemon's telemetry does) and at every
 * chunk end, gs_system_energy gives the same bytes on both (kinetic,
 * potential, elastic, total, work in, dissipated, contact work, balance
 * residual), the snapshots (rigid state, mesh forces, every body's q and w)
 * are the same bytes, and the scheduled engine really deferred (its elastic
 * bodies report NaN on the steps in between, the other engine never).
 * Scenes: contact_drive (seed and closure_energy, which books against the
 * energies every step and so never defers), planetary_contact and
 * contact_impact: 135 steps of the pair and of contact_impact, 74 of the
 * others; GEARSIM_LONG=1: 2970, 698 of planetary_contact, 405 with
 * closure_energy. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <json-c/json.h>

#include "gearsim/engine.h"
#include "gearsim/step.h"
#include "gearsim/util.h"
#include "scene_build.h"

enum { EVERY = 7, MAXREC = 4096 };

typedef struct run {
    gs_energy at[MAXREC]; /* energies at the published steps */
    int n_at;
    int64_t deferred;     /* steps after which an elastic body's energy was NaN */
} run;

static bool hook(gs_engine *e, void *user)
{
    run *r = user;
    gs_system *s = gs_engine_system(e);
    bool nan = false;
    for (int i = 0; i < s->n_bodies; i++)
        nan |= s->bodies[i].ops->state_size && isnan(s->bodies[i].T);
    if (s->step % EVERY == 0) {
        assert_false(nan); /* due: computed */
        if (r->n_at < MAXREC)
            gs_system_energy(s, &r->at[r->n_at++]);
    } else if (nan) {
        r->deferred++;
    }
    return true;
}

static gs_engine *load(const char *builtin, const char *scheme, bool sched, run *r)
{
    json_object *root = vt_scene(builtin);
    if (scheme) {
        json_object *num = json_object_object_get(root, "numerics");
        json_object_object_add(num, "contact", json_object_new_string(scheme));
    }
    json_object *out = json_object_new_object();
    json_object_object_add(out, "telemetry_every", json_object_new_int(EVERY));
    json_object_object_add(root, "outputs", out);
    const char *txt = json_object_to_json_string(root);
    gs_engine *e = NULL;
    assert_int_equal(gs_engine_new(MPI_COMM_SELF, &e), GS_OK);
    gs_diag d;
    assert_int_equal(gs_engine_run(e, GS_OP_LOAD, txt, strlen(txt), &d, NULL), GS_OK);
    json_object_put(root);
    gs_engine_set_hook(e, hook, r);
    gs_engine_set_energy_schedule(e, sched);
    return e;
}

static void same_energy(gs_engine *a, gs_engine *b)
{
    gs_energy ea, eb;
    gs_system_energy(gs_engine_system(a), &ea);
    gs_system_energy(gs_engine_system(b), &eb);
    assert_true(isfinite(eb.total) && isfinite(eb.balance_residual));
    assert_memory_equal(&ea, &eb, sizeof ea);
}

static void compare(const char *builtin, const char *scheme, int chunks, bool defers)
{
    static const int64_t len[] = {23, 1, 50, 8, 14, 2, 37};
    run *ra = calloc(1, sizeof *ra), *rb = calloc(1, sizeof *rb);
    assert_true(ra && rb);
    gs_engine *a = load(builtin, scheme, false, ra), *b = load(builtin, scheme, true, rb);
    same_energy(a, b);
    gs_diag d;
    for (int c = 0; c < chunks; c++) {
        int64_t n = len[c % 7], da = 0, db = 0;
        assert_int_equal(gs_engine_run(a, GS_OP_STEP, &n, sizeof n, &d, &da), GS_OK);
        assert_int_equal(gs_engine_run(b, GS_OP_STEP, &n, sizeof n, &d, &db), GS_OK);
        assert_true(da == n && db == n);
        same_energy(a, b);
    }
    assert_int_equal(ra->n_at, rb->n_at);
    assert_true(ra->n_at > 0);
    assert_memory_equal(ra->at, rb->at, (size_t)ra->n_at * sizeof ra->at[0]);
    char *sa = NULL, *sb = NULL;
    size_t la = 0, lb = 0;
    assert_int_equal(gs_engine_snapshot(a, &sa, &la), GS_OK);
    assert_int_equal(gs_engine_snapshot(b, &sb, &lb), GS_OK);
    assert_int_equal(la, lb);
    assert_memory_equal(sa, sb, la);
    assert_int_equal(ra->deferred, 0);
    if (defers)
        assert_true(rb->deferred > 0);
    else
        assert_int_equal(rb->deferred, 0);
    printf("# %s %s: %d published steps equal, %lld steps deferred\n", builtin, scheme ? scheme : "seed",
           rb->n_at, (long long)rb->deferred);
    free(sa), free(sb);
    gs_engine_free(&a);
    gs_engine_free(&b);
    free(ra), free(rb);
}

static int scale(int k)
{
    const char *l = getenv("GEARSIM_LONG");
    return l && l[0] == '1' ? k : 1;
}

static void pair_seed(void **st) { (void)st; compare("contact_drive", "seed", 7 * scale(22), true); }
static void pair_closure_energy(void **st) { (void)st; compare("contact_drive", "closure_energy", 3 * scale(7), false); }
static void planetary(void **st) { (void)st; compare("planetary_contact", "seed", 3 * scale(12), true); }
static void impact(void **st) { (void)st; compare("contact_impact", "seed", 7 * scale(22), true); }

int main(int argc, char **argv)
{
    int provided;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(pair_seed),
        cmocka_unit_test(pair_closure_energy),
        cmocka_unit_test(planetary),
        cmocka_unit_test(impact),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    MPI_Finalize();
    return rc;
}
