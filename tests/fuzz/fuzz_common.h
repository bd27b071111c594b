/* SPDX-License-Identifier: MIT
 * What the service-level fuzz targets share: a one-rank engine and a
 * private data directory, emptied between inputs and removed at exit.
 * Each target is its own program, so the state here is static. */
#ifndef GEARSIM_FUZZ_COMMON_H
#define GEARSIM_FUZZ_COMMON_H

#include <dirent.h>
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "gearsim/engine.h"
#include "service/options.h"
#include "service/service_internal.h"

static gs_engine *eng;
static char data_dir[64];
static gs_service_config cfg;

static void clean_data_dir(void)
{
    DIR *d = opendir(data_dir);
    if (!d)
        return;
    struct dirent *de;
    char p[sizeof data_dir + 300];
    while ((de = readdir(d)))
        if (strcmp(de->d_name, ".") && strcmp(de->d_name, "..")) {
            snprintf(p, sizeof p, "%s/%s", data_dir, de->d_name);
            unlink(p);
        }
    closedir(d);
}

static void at_exit(void)
{
    clean_data_dir();
    rmdir(data_dir);
}

/* MPI, the engine and /tmp/gearsim-<tag>-XXXXXX as the data directory;
 * aborts (naming the target) when any of them cannot be had. */
static void fuzz_setup(int *argc, char ***argv, const char *target, const char *tag)
{
    int provided;
    MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
    snprintf(data_dir, sizeof data_dir, "/tmp/gearsim-%s-XXXXXX", tag);
    if (gs_engine_new(MPI_COMM_WORLD, &eng) != GS_OK || !mkdtemp(data_dir)) {
        fprintf(stderr, "%s: cannot set up the engine or the data directory\n", target);
        abort();
    }
    atexit(at_exit);
    cfg.data_dir = data_dir;
    cfg.connection_file = NULL;
}

/* After an input: finish what the service left running, close its record,
 * unload the scene, free the service and empty the data directory. */
static void fuzz_teardown(gs_service *s)
{
    if (s->adv.active)
        gsi_finish_advance(s, true, GS_OK, NULL);
    gs_record_close(&s->record);
    if (gs_engine_system(eng)) {
        gs_diag d;
        gs_engine_run(eng, GS_OP_UNLOAD, NULL, 0, &d, NULL);
    }
    gsi_service_release(s);
    free(s);
    clean_data_dir();
}

#endif
