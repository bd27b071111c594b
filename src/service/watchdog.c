/* SPDX-License-Identifier: MIT
 * Rank death (docs/RELIABILITY.md, "When a rank dies"): rank 0 knows the
 * process ids of the ranks on its own host (gathered at start) and a
 * thread looks at them every 100 ms, and every request looks once more
 * before it is answered (a client is never told the work is healthy after
 * the death could be seen). When one is gone (or a zombie) it
 * writes the cause into the connection file (`stopped`, so clients waiting
 * on a reply or an event learn it even while rank 0 is blocked in a
 * collective with the dead rank) and flags it for the service loop, which
 * publishes an error event and the done events of the running work, then
 * aborts the job (Open MPI would abort it anyway, a few seconds later).
 * Ranks on other hosts are not watched: there, clients learn it when
 * Open MPI's abort ends rank 0 and its process id disappears. */
#include <json-c/json.h>
#include <pthread.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "service/files.h"
#include "service/options.h"

static int *wd_pids;  /* per rank; 0: not on this host (or rank 0) */
static int wd_n;
static pthread_t wd_thread;
static bool wd_running;
static atomic_int wd_stop;
static atomic_int wd_lost; /* rank + 1 of the dead rank, 0 none */
static char wd_msg[300];
static char *wd_conn_path, *wd_conn_text;

void gs_service_set_rank_pids(const int *pids, int n)
{
    free(wd_pids);
    wd_pids = malloc((size_t)(n > 0 ? n : 1) * sizeof *wd_pids);
    if (!wd_pids) {
        wd_n = 0;
        return;
    }
    memcpy(wd_pids, pids, (size_t)n * sizeof *wd_pids);
    wd_n = n;
}

/* Gone or a zombie (a SIGKILLed rank stays one until its launcher reaps it). */
static bool pid_gone(int pid)
{
    char p[64], buf[512];
    snprintf(p, sizeof p, "/proc/%d/stat", pid);
    FILE *f = fopen(p, "r");
    if (!f)
        return true;
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = '\0';
    const char *rp = strrchr(buf, ')');
    return !rp || rp[1] != ' ' || rp[2] == 'Z' || rp[2] == 'X' || rp[2] == 'x';
}

static void mark_stopped(void)
{
    if (!wd_conn_path || !wd_conn_text)
        return;
    json_object *o = json_tokener_parse(wd_conn_text);
    if (!o)
        return;
    json_object_object_add(o, "stopped", json_object_new_string(wd_msg));
    char err[512];
    gsi_write_connection_text(wd_conn_path, json_object_to_json_string_ext(o, JSON_C_TO_STRING_PRETTY), err,
                              sizeof err);
    json_object_put(o);
}

/* Look at every watched rank once; the first to see one gone writes the
 * cause and flags it (the thread and a request's check may race: one
 * claim, and the other waits for the flag). True when a rank is gone. */
static atomic_int wd_claim;
static bool scan(void)
{
    if (atomic_load(&wd_lost))
        return true;
    for (int r = 1; r < wd_n; r++)
        if (wd_pids[r] > 0 && pid_gone(wd_pids[r])) {
            if (atomic_exchange(&wd_claim, 1) == 0) {
                snprintf(wd_msg, sizeof wd_msg, "rank %d of the daemon (pid %d) died; the MPI job is aborted "
                         "and the daemon stopped (an unfinished advance with checkpoint_every continues with "
                         "gearsimd --resume)", r, wd_pids[r]);
                fprintf(stderr, "gearsimd: %s\n", wd_msg);
                mark_stopped();
                atomic_store(&wd_lost, r + 1);
            }
            while (!atomic_load(&wd_lost)) {
                struct timespec ts = {0, 1000000};
                nanosleep(&ts, NULL);
            }
            return true;
        }
    return false;
}

static void *watch(void *arg)
{
    (void)arg;
    while (!atomic_load(&wd_stop)) {
        if (scan())
            return NULL;
        struct timespec ts = {0, 100000000};
        nanosleep(&ts, NULL);
    }
    return NULL;
}

void gsi_watchdog_start(const char *conn_path, const char *conn_text)
{
    bool any = false;
    for (int r = 1; r < wd_n; r++)
        any |= wd_pids[r] > 0;
    if (!any || wd_running)
        return;
    free(wd_conn_path);
    free(wd_conn_text);
    wd_conn_path = conn_path ? strdup(conn_path) : NULL;
    wd_conn_text = conn_text ? strdup(conn_text) : NULL;
    atomic_store(&wd_stop, 0);
    wd_running = pthread_create(&wd_thread, NULL, watch, NULL) == 0;
}

void gsi_watchdog_stop(void)
{
    if (!wd_running)
        return;
    atomic_store(&wd_stop, 1);
    pthread_join(wd_thread, NULL);
    wd_running = false;
}

const char *gsi_watchdog_lost(void) { return atomic_load(&wd_lost) ? wd_msg : NULL; }

const char *gsi_watchdog_check(void) { return wd_running && scan() ? wd_msg : NULL; }
