/* SPDX-License-Identifier: MIT
 * Tests that drive the engine directly (one process, MPI_COMM_WORLD):
 * an engine with a scene loaded, and an advance of n steps, each asserted
 * (cmocka) with the engine's message printed on failure. Include after
 * <cmocka.h> and <mpi.h>. */
#ifndef GEARSIM_TESTS_ENGINE_LOAD_H
#define GEARSIM_TESTS_ENGINE_LOAD_H

#include <string.h>

#include "gearsim/engine.h"

static gs_engine *engine_loaded(const char *txt) __attribute__((unused));
static void advance(gs_engine *e, int64_t n) __attribute__((unused));

static gs_engine *engine_loaded(const char *txt)
{
    gs_engine *e = NULL;
    assert_int_equal(gs_engine_new(MPI_COMM_WORLD, &e), GS_OK);
    gs_diag d;
    gs_err err = gs_engine_run(e, GS_OP_LOAD, txt, strlen(txt), &d, NULL);
    if (err != GS_OK)
        print_error("load: %s: %s\n", d.field, d.message);
    assert_int_equal(err, GS_OK);
    return e;
}

static void advance(gs_engine *e, int64_t n)
{
    gs_diag d;
    int64_t done = 0;
    gs_err err = gs_engine_run(e, GS_OP_STEP, &n, sizeof n, &d, &done);
    if (err != GS_OK)
        print_error("step: %s: %s\n", d.field, d.message);
    assert_int_equal(err, GS_OK);
    assert_int_equal(done, n);
}

#endif
