/* SPDX-License-Identifier: MIT
 * A checkpoint of a scene that gave accuracy targets (`"fidelity":
 * {"targets": ...}`) keeps the choice the targets made (gs_scene.
 * fidelity_choice, reported by replies, status and the record) along with
 * the concrete setting: the engine snapshot carries it after the loads, a
 * restore (from the bytes and through the HDF5 file) gives it back, and a
 * damaged choice is refused with a message naming it, as the rest of the
 * snapshot is. A scene without targets writes the snapshot it always did. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
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

/* The builtin scene `name`, with "fidelity": fid inserted when fid. */
static char *scene_text(const char *name, const char *fid)
{
    const char *base = gs_scene_builtin(name);
    assert_non_null(base);
    size_t n = strlen(base) + (fid ? strlen(fid) : 0) + 32;
    char *txt = malloc(n);
    assert_non_null(txt);
    const char *br = strchr(base, '{');
    if (fid)
        snprintf(txt, n, "%.*s\"fidelity\": %s, %s", (int)(br - base) + 1, base, fid, br + 1);
    else
        snprintf(txt, n, "%s", base);
    return txt;
}

/* The scene loaded and 20 steps taken. */
static gs_engine *loaded(const char *txt)
{
    gs_engine *e = engine_loaded(txt);
    advance(e, 20);
    return e;
}

/* The engine's snapshot, checked, into *b, *len and *v. */
static void snapshot(gs_engine *e, char **b, size_t *len, gs_snapshot_view *v)
{
    gs_diag d;
    assert_int_equal(gs_engine_snapshot(e, b, len), GS_OK);
    assert_int_equal(gs_engine_snapshot_check(*b, *len, v, &d), GS_OK);
}

static gs_err restore(gs_engine *e, const char *b, size_t len, gs_diag *d)
{
    return gs_engine_run(e, GS_OP_RESTORE, b, len, d, NULL);
}

/* The snapshot's bytes up to the end of its loads, then `tail` of tl bytes. */
static char *with_tail(const char *b, size_t len, const char *tail, size_t tl, size_t *out_len)
{
    gs_snapshot_view v;
    gs_diag d;
    assert_int_equal(gs_engine_snapshot_check(b, len, &v, &d), GS_OK);
    size_t keep = (size_t)(v.loads - b) + strlen(v.loads) + 1;
    char *o = malloc(keep + tl + 1);
    assert_non_null(o);
    memcpy(o, b, keep);
    memcpy(o + keep, tail, tl);
    *out_len = keep + tl;
    return o;
}

static void choice_survives_restore(void **state)
{
    (void)state;
    char *txt = scene_text("pair", "{\"targets\": {\"speed\": 0.001}}");
    gs_engine *a = loaded(txt);
    free(txt);
    const char *want = gs_engine_system(a)->scene->fidelity_choice;
    assert_non_null(want);
    assert_non_null(strstr(want, "\"why\""));
    char *b;
    size_t len;
    gs_snapshot_view v;
    gs_diag d;
    snapshot(a, &b, &len, &v);
    assert_non_null(v.choice);
    assert_string_equal(v.choice, want);

    /* restored from the bytes: the same choice, the same step */
    gs_engine *r = NULL;
    assert_int_equal(gs_engine_new(MPI_COMM_WORLD, &r), GS_OK);
    gs_err e = restore(r, b, len, &d);
    if (e != GS_OK)
        print_error("restore: %s\n", d.message);
    assert_int_equal(e, GS_OK);
    assert_int_equal(gs_engine_system(r)->step, 20);
    assert_non_null(gs_engine_system(r)->scene->fidelity_choice);
    assert_string_equal(gs_engine_system(r)->scene->fidelity_choice, want);
    gs_engine_free(&r);

    /* through the checkpoint file */
    char path[] = "/tmp/gs_test_checkpoint_XXXXXX";
    int fd = mkstemp(path);
    assert_true(fd >= 0);
    close(fd);
    assert_int_equal(gs_checkpoint_write(path, b, len, gs_engine_system(a)->scene->json, 20,
                                         gs_engine_system(a)->time, &d), GS_OK);
    char *fb;
    size_t fl;
    assert_int_equal(gs_checkpoint_read(path, 1u << 26, &fb, &fl, &d), GS_OK);
    remove(path);
    assert_int_equal(gs_engine_new(MPI_COMM_WORLD, &r), GS_OK);
    assert_int_equal(restore(r, fb, fl, &d), GS_OK);
    assert_non_null(gs_engine_system(r)->scene->fidelity_choice);
    assert_string_equal(gs_engine_system(r)->scene->fidelity_choice, want);
    /* and a snapshot of the restored engine is the original's, byte for byte */
    char *b2;
    size_t l2;
    assert_int_equal(gs_engine_snapshot(r, &b2, &l2), GS_OK);
    assert_int_equal(l2, len);
    assert_memory_equal(b2, b, len);
    free(b2);
    free(fb);
    gs_engine_free(&r);
    free(b);
    gs_engine_free(&a);
}

static void no_targets_no_choice(void **state)
{
    (void)state;
    char *txt = scene_text("pair", NULL);
    gs_engine *a = loaded(txt);
    free(txt);
    assert_null(gs_engine_system(a)->scene->fidelity_choice);
    char *b;
    size_t len;
    gs_snapshot_view v;
    gs_diag d;
    snapshot(a, &b, &len, &v);
    assert_null(v.choice);
    /* the loads end the snapshot, as before choices were kept */
    assert_true(v.loads + strlen(v.loads) + 1 == b + len);
    gs_engine *r = NULL;
    assert_int_equal(gs_engine_new(MPI_COMM_WORLD, &r), GS_OK);
    assert_int_equal(restore(r, b, len, &d), GS_OK);
    assert_null(gs_engine_system(r)->scene->fidelity_choice);

    /* a (well-formed) choice added to a scene not set from targets: refused */
    static const char ok[] = "{\"choice\":{\"level\":\"kinematic\"},\"why\":\"x\"}";
    size_t bl;
    char *bad = with_tail(b, len, ok, sizeof ok, &bl);
    assert_int_equal(gs_engine_snapshot_check(bad, bl, &v, &d), GS_OK);
    assert_int_equal(restore(r, bad, bl, &d), GS_EIO);
    assert_non_null(strstr(d.message, "not set from targets"));
    free(bad);
    gs_engine_free(&r);
    free(b);
    gs_engine_free(&a);
}

static void damaged_choice_refused(void **state)
{
    (void)state;
    char *txt = scene_text("pair", "{\"targets\": {\"speed\": 0.001}}");
    gs_engine *a = loaded(txt);
    free(txt);
    char *b;
    size_t len;
    assert_int_equal(gs_engine_snapshot(a, &b, &len), GS_OK);
    struct {
        const char *tail;
        size_t n; /* bytes of tail, its NUL included or not */
        const char *says;
    } cases[] = {
        {"not json", 9, "not a JSON object"},
        {"[1, 2]", 7, "not a JSON object"},
        {"{\"choice\": {\"level\": \"ltca\"}} trailing", 39, "not a JSON object"},
        {"{\"why\": \"x\"}", 13, "names no level"},
        {"{\"choice\": {\"level\": 3}, \"why\": \"x\"}", 37, "names no level"},
        {"{\"choice\": {\"level\": \"ltca\"}}", 30, "gives no reason"},
        {"{\"choice\": {\"level\": \"ltca\"}, \"why\": 1}", 40, "gives no reason"},
        {"", 1, "fidelity choice has 0 bytes"},
        {"{\"choice\": {\"level\": \"ltca\"}, \"why\": \"x\"}", 41, "bytes after its end"}, /* no NUL */
        {"{\"choice\": {\"level\": \"ltca\"}, \"why\": \"x\"}\0{}", 44, "bytes after its end"},
    };
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        size_t bl;
        char *bad = with_tail(b, len, cases[k].tail, cases[k].n, &bl);
        gs_snapshot_view v;
        gs_diag d;
        gs_diag_clear(&d);
        gs_err e = gs_engine_snapshot_check(bad, bl, &v, &d);
        if (e != GS_EIO || !strstr(d.message, cases[k].says))
            print_error("case %zu: %d %s\n", k, e, d.message);
        assert_int_equal(e, GS_EIO);
        assert_non_null(strstr(d.message, cases[k].says));
        gs_engine *r = NULL;
        assert_int_equal(gs_engine_new(MPI_COMM_WORLD, &r), GS_OK);
        assert_int_equal(restore(r, bad, bl, &d), GS_EIO);
        assert_null(gs_engine_system(r));
        gs_engine_free(&r);
        free(bad);
    }
    free(b);
    gs_engine_free(&a);
}

int main(int argc, char **argv)
{
    int provided;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(choice_survives_restore),
        cmocka_unit_test(no_targets_no_choice),
        cmocka_unit_test(damaged_choice_refused),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    MPI_Finalize();
    return rc;
}
