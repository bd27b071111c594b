/* SPDX-License-Identifier: MIT
 * Checkpoints of reduced elastic bodies through the engine path the service
 * uses (the checkpoint and restore commands, automatic checkpoints and
 * --resume): contact_drive with both gears reduced (bodies[i].reduction) at
 * h 1e-5 s, run N steps in one engine, checkpointed (gs_engine_snapshot,
 * gs_checkpoint_write), the engine freed; a new engine reads the file
 * (gs_checkpoint_read, GS_OP_RESTORE: new reduced bodies, no residual
 * column computed, a fresh step constant) and runs M steps. A third engine
 * runs N + M steps without interruption. The resumed run's engine snapshot
 * (coordinates, velocities, system energies, mesh forces, every body's
 * state) and the bodies' kinetic and elastic energies equal the
 * uninterrupted run's bit for bit; so do the first engine's after it goes
 * on from its checkpoint (taking a checkpoint changes nothing).
 *
 *   static_rule    the recommended setting: static residual, f_max 30 kHz,
 *                  2 % damping at 9.2 kHz; the checkpoint falls after the
 *                  backlash has closed (contact, residual forces present);
 *   midpoint_tip   the midpoint rule with mass-proportional damping on
 *                  the wheel and a tip load on it (a residual displacement from the
 *                  initial state, decaying), checkpointed during the
 *                  first impacts.
 * A few CPU seconds (the modes of the two gears, twice per engine). */
#define _POSIX_C_SOURCE 200809L
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <json-c/json.h>
#include <math.h>
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "../common/engine_load.h"
#include "../common/json_child.h"
#include "../common/reduced_scene.h"
#include "gearsim/engine.h"
#include "gearsim/fe.h"
#include "gearsim/models.h"
#include "gearsim/record.h"
#include "gearsim/scene.h"
#include "gearsim/step.h"

static char *scene_text(const char *rule, double damping_m, double tip_load)
{
    json_object *root = reduced_drive_scene(3e4, rule, damping_m > 0 ? "damping_m" : NULL, damping_m);
    assert_non_null(root);
    if (tip_load != 0)
        json_object_object_add(tj_child(tj_child(root, "initial"), "wheel"), "tip_load",
                               json_object_new_double(tip_load));
    char *txt = strdup(json_object_to_json_string(root));
    json_object_put(root);
    return txt;
}

typedef struct {
    char *bytes;
    size_t len;
    double T[4], V[4], force, rloss[4];
    gs_index cols[4];
    int64_t step;
} end_state;

static void take(gs_engine *e, end_state *o)
{
    assert_int_equal(gs_engine_snapshot(e, &o->bytes, &o->len), GS_OK);
    gs_system *s = gs_engine_system(e);
    assert_true(s->n_bodies <= 4);
    for (int i = 0; i < s->n_bodies; i++) {
        o->T[i] = s->bodies[i].T;
        o->V[i] = s->bodies[i].V;
        /* the body's own figures (gs_elastic_reduced_info) */
        gs_fe_reduced_info ri;
        assert_true(gs_elastic_reduced_info(&s->bodies[i], &ri));
        o->rloss[i] = ri.residual_loss;
        o->cols[i] = ri.cached_nodes;
        assert_true(ri.cached_nodes > 0 && ri.column_cpu_s > 0);
    }
    o->force = s->meshes[0].force;
    o->step = s->step;
}

static void same(const char *what, const end_state *a, const end_state *b, int nb)
{
    size_t diff = a->len == b->len ? 0 : 1;
    for (size_t k = 0; k < a->len && k < b->len; k++)
        diff += a->bytes[k] != b->bytes[k];
    print_message("%s: snapshot of %zu bytes, %zu bytes differ; mesh force %.9g N and %.9g N\n", what, a->len,
                  diff, a->force, b->force);
    assert_int_equal(a->step, b->step);
    assert_int_equal(diff, 0);
    assert_memory_equal(a->T, b->T, (size_t)nb * sizeof(double));
    assert_memory_equal(a->V, b->V, (size_t)nb * sizeof(double));
    assert_memory_equal(&a->force, &b->force, sizeof(double));
    assert_memory_equal(a->rloss, b->rloss, (size_t)nb * sizeof(double));
}

static void resume_case(const char *rule, double damping_m, double tip_load, int64_t n1, int64_t n2)
{
    char *txt = scene_text(rule, damping_m, tip_load);
    char path[] = "/tmp/gs_reduced_resume_XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    close(fd);

    /* the uninterrupted run */
    gs_engine *c = engine_loaded(txt);
    advance(c, n1 + n2);
    end_state ref;
    take(c, &ref);
    gs_system *sc = gs_engine_system(c);
    int nb = sc->n_bodies;
    assert_true(fabs(ref.force) > 0); /* the teeth are in contact at the end */
    for (int i = 0; i < nb; i++) /* the static rule books a loss, the midpoint rule none */
        assert_true(strcmp(rule, "static") == 0 ? ref.rloss[i] > 0 : ref.rloss[i] == 0.0);
    gs_engine_free(&c);

    /* N steps, checkpoint to a file, then M more in the same engine */
    gs_engine *a = engine_loaded(txt);
    advance(a, n1);
    char *bytes = NULL;
    size_t len = 0;
    assert_int_equal(gs_engine_snapshot(a, &bytes, &len), GS_OK);
    gs_system *sa = gs_engine_system(a);
    gs_diag d;
    assert_int_equal(gs_checkpoint_write(path, bytes, len, sa->scene->json, sa->step, sa->time, &d), GS_OK);
    free(bytes);
    advance(a, n2);
    end_state cont;
    take(a, &cont);
    gs_engine_free(&a);
    same("checkpointed, then on in the same engine", &cont, &ref, nb);

    /* a new engine restores the file and runs M steps */
    gs_engine *b = NULL;
    assert_int_equal(gs_engine_new(MPI_COMM_WORLD, &b), GS_OK);
    assert_int_equal(gs_checkpoint_read(path, (size_t)1 << 30, &bytes, &len, &d), GS_OK);
    gs_err err = gs_engine_run(b, GS_OP_RESTORE, bytes, len, &d, NULL);
    if (err != GS_OK)
        print_error("restore: %s: %s\n", d.field, d.message);
    assert_int_equal(err, GS_OK);
    free(bytes);
    assert_int_equal(gs_engine_system(b)->step, n1);
    advance(b, n2);
    end_state res;
    take(b, &res);
    gs_engine_free(&b);
    same("restored in a new engine", &res, &ref, nb);

    remove(path);
    free(ref.bytes), free(cont.bytes), free(res.bytes);
    free(txt);
}

static void static_rule(void **state)
{
    (void)state;
    /* the backlash closes at 1.25 ms: the checkpoint at 1.6 ms */
    resume_case("static", 0, 0, 160, 60);
}

static void midpoint_tip(void **state)
{
    (void)state;
    resume_case("midpoint", 200.0, 50.0, 200, 60);
}

int main(int argc, char **argv)
{
    int provided;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(static_rule),
        cmocka_unit_test(midpoint_tip),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    MPI_Finalize();
    return rc;
}
