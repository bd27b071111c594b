/* SPDX-License-Identifier: MIT
 * Daemon options of the service that gs_service_config does not carry
 * (set by src/daemon/main.c before gs_service_run). */
#ifndef GSI_OPTIONS_H
#define GSI_OPTIONS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "gearsim/service.h"

/* --resume: at start, continue the advance saved in <data dir>/autosave.h5. */
void gs_service_set_resume(bool on);
/* --max-scene-mb: largest estimated memory of a loaded scene (MiB, >= 1). */
void gs_service_set_max_scene_mb(int64_t mb);

/* --max-record-mb: a recording stops (error event) past this size (MiB). */
void gs_service_set_max_record_mb(int64_t mb);

/* --max-clients: clients (command connections, by ZeroMQ routing id) that
 * may be active at once; one counts from its first request until it has
 * been silent for GSI_CLIENT_IDLE_S seconds. */
void gs_service_set_max_clients(int64_t n);

/* Every rank, right after MPI_Init: SIGTERM and SIGINT ask rank 0's
 * service loop to stop (cancelled `done`, record flushed, connection file
 * removed); the other ranks then end on its GS_OP_SHUTDOWN. */
void gs_service_catch_signals(void);

/* Rank 0 before the service: lock the data directory and the connection
 * file (service/files.h). */
int gs_service_lock(const gs_service_config *cfg, char *err, size_t cap);

/* Every rank's process id (main.c gathers them; 0 for a rank on another
 * host): rank 0 watches those on its host (src/service/watchdog.c). */
void gs_service_set_rank_pids(const int *pids, int n);
void gsi_watchdog_start(const char *conn_path, const char *conn_text);
void gsi_watchdog_stop(void);
/* The cause when a rank died, else NULL. */
const char *gsi_watchdog_lost(void);
/* Look at the watched ranks now (a few /proc reads); the cause when one
 * is gone, else NULL. */
const char *gsi_watchdog_check(void);

int64_t gsi_opt_max_clients(void);
int64_t gsi_opt_max_scene_mb(void);
int64_t gsi_opt_max_record_mb(void);

#define GSI_DEFAULT_MAX_SCENE_MB 4096
#define GSI_DEFAULT_MAX_RECORD_MB 65536
#define GSI_DEFAULT_MAX_CLIENTS 256
#define GSI_MAX_CLIENTS_CAP 65536
#define GSI_CLIENT_IDLE_S 60.0
#define GSI_AUTOSAVE_NAME "autosave.h5"

#endif
