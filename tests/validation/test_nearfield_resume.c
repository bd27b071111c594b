/* SPDX-License-Identifier: MIT
 * Checkpoints of a run with the near-field springs (`"nearfield": true`,
 * docs/explanation/contact.md "Near-field compliance") through the engine
 * path the service uses: contact_drive (default quadratic mesh,
 * closure_energy) run N steps, checkpointed to an HDF5 file
 * (gs_engine_snapshot, gs_checkpoint_write) and restored in a new engine
 * (gs_checkpoint_read, GS_OP_RESTORE), then M steps; a second engine runs
 * N + M steps without interruption.
 *
 *  1. the springs hold energy at the checkpoint (the teeth are loaded);
 *     right after the restore the energy balance is at round-off, as it is
 *     in the run that took the checkpoint (the springs' energy is part of
 *     the potential: without it the balance is off by that energy);
 *  2. the resumed run's snapshot (coordinates, speeds, system energies,
 *     every mesh's figures and springs' energy, the bodies' states) and its
 *     energy figures equal the uninterrupted run's bit for bit, and its
 *     balance stays at round-off;
 *  3. a checkpoint whose springs' energy is damaged is refused with a
 *     message naming it: negative, or on a mesh without "nearfield". */
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
#include "gearsim/engine.h"
#include "gearsim/record.h"
#include "gearsim/scene.h"
#include "gearsim/step.h"
#include "scene_build.h"

#define N1 400 /* the backlash closes at about 1.25 ms (h 1e-5 s): loaded at 4 ms */
#define N2 100

static char *scene_text(int nf)
{
    json_object *root = vt_scene("contact_drive");
    vt_contact_scheme(root, "closure_energy");
    json_object *m = json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
    json_object_object_add(m, "nearfield", json_object_new_boolean(nf));
    char *txt = strdup(json_object_to_json_string(root));
    json_object_put(root);
    return txt;
}

/* |balance residual| over the energy scale, and the springs' energy. */
static double balance(gs_engine *e, double *nf_energy)
{
    gs_system *s = gs_engine_system(e);
    gs_energy en;
    gs_system_energy(s, &en);
    if (nf_energy)
        *nf_energy = s->meshes[0].nf_energy;
    return fabs(en.balance_residual) / fmax(en.total, fmax(en.work_in, en.dissipated));
}

typedef struct {
    char *bytes;
    size_t len;
    gs_energy en;
} end_state;

static void take(gs_engine *e, end_state *o)
{
    assert_int_equal(gs_engine_snapshot(e, &o->bytes, &o->len), GS_OK);
    gs_system_energy(gs_engine_system(e), &o->en);
}

static void same(const char *what, const end_state *a, const end_state *b)
{
    size_t diff = a->len == b->len ? 0 : 1;
    for (size_t k = 0; k < a->len && k < b->len; k++)
        diff += a->bytes[k] != b->bytes[k];
    print_message("%s: snapshot of %zu bytes, %zu bytes differ; total energy %.17g and %.17g J\n", what, a->len,
                  diff, a->en.total, b->en.total);
    assert_int_equal(diff, 0);
    assert_memory_equal(&a->en, &b->en, sizeof a->en);
}

/* A copy of the snapshot with the springs' energy of mesh 0 set to v. */
static char *with_nf_energy(const char *b, size_t len, double v)
{
    gs_snapshot_view sv;
    gs_diag d;
    assert_int_equal(gs_engine_snapshot_check(b, len, &sv, &d), GS_OK);
    char *o = malloc(len);
    assert_non_null(o);
    memcpy(o, b, len);
    memcpy(o + (sv.meshes - b) + 8 * sizeof(double), &v, sizeof v);
    return o;
}

static gs_err restore(gs_engine **e, const char *b, size_t len, gs_diag *d)
{
    assert_int_equal(gs_engine_new(MPI_COMM_WORLD, e), GS_OK);
    return gs_engine_run(*e, GS_OP_RESTORE, b, len, d, NULL);
}

static void resume_nearfield(void **state)
{
    (void)state;
    char *txt = scene_text(1);
    /* N1 steps, the checkpoint in a file */
    gs_engine *a = engine_loaded(txt);
    advance(a, N1);
    double enf_a, bal_a = balance(a, &enf_a);
    char *bytes = NULL;
    size_t len = 0;
    assert_int_equal(gs_engine_snapshot(a, &bytes, &len), GS_OK);
    gs_system *sa = gs_engine_system(a);
    gs_diag d;
    char path[] = "/tmp/gs_nearfield_resume_XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0 && close(fd) == 0);
    assert_int_equal(gs_checkpoint_write(path, bytes, len, sa->scene->json, sa->step, sa->time, &d), GS_OK);
    gs_engine_free(&a);

    /* 3. damaged springs' energy: refused, the message names it */
    char *neg = with_nf_energy(bytes, len, -1e-3);
    gs_snapshot_view sv;
    assert_int_equal(gs_engine_snapshot_check(neg, len, &sv, &d), GS_ERANGE);
    print_message("negative: %s\n", d.message);
    assert_non_null(strstr(d.message, "near-field spring energy"));
    free(neg);
    char *plain = scene_text(0);
    gs_engine *p = engine_loaded(plain);
    free(plain);
    advance(p, 10);
    char *pb = NULL;
    size_t pl = 0;
    assert_int_equal(gs_engine_snapshot(p, &pb, &pl), GS_OK);
    gs_engine_free(&p);
    gs_engine *r = NULL;
    assert_int_equal(restore(&r, pb, pl, &d), GS_OK); /* as written: restored */
    gs_engine_free(&r);
    char *odd = with_nf_energy(pb, pl, 1e-4);
    assert_int_equal(restore(&r, odd, pl, &d), GS_EIO);
    print_message("no nearfield: %s\n", d.message);
    assert_non_null(strstr(d.message, "near-field spring energy"));
    assert_null(gs_engine_system(r));
    gs_engine_free(&r);
    free(odd);
    free(pb);
    free(bytes);

    /* 1. restored from the file: the springs' energy and the balance */
    gs_engine *b = NULL;
    assert_int_equal(gs_checkpoint_read(path, (size_t)1 << 30, &bytes, &len, &d), GS_OK);
    gs_err err = restore(&b, bytes, len, &d);
    if (err != GS_OK)
        print_error("restore: %s: %s\n", d.field, d.message);
    assert_int_equal(err, GS_OK);
    free(bytes);
    double enf_b, bal_b = balance(b, &enf_b);
    print_message("at the checkpoint (step %d): springs' energy %.6e J, balance %.1e; restored: %.6e J, "
                  "balance %.1e\n", N1, enf_a, bal_a, enf_b, bal_b);
    assert_true(enf_a > 1e-6); /* the springs are loaded (3.2e-6 J) */
    assert_true(bal_a < 1e-12);
    assert_memory_equal(&enf_b, &enf_a, sizeof enf_a);
    assert_true(bal_b < 1e-12);

    /* 2. on to N1 + N2: the uninterrupted run's state, bit for bit */
    advance(b, N2);
    double bal_end = balance(b, NULL);
    end_state res, ref;
    take(b, &res);
    gs_engine_free(&b);
    gs_engine *c = engine_loaded(txt);
    advance(c, N1 + N2);
    take(c, &ref);
    gs_engine_free(&c);
    print_message("resumed, step %d: balance %.1e\n", N1 + N2, bal_end);
    same("restored in a new engine", &res, &ref);
    assert_true(bal_end < 1e-12);

    remove(path);
    free(ref.bytes), free(res.bytes);
    free(txt);
}

int main(int argc, char **argv)
{
    int provided;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(resume_nearfield),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    MPI_Finalize();
    return rc;
}
