/* SPDX-License-Identifier: MIT
 * gearsim: the service on rank 0 — ZeroMQ command (ROUTER) and telemetry
 * (PUB) sockets, the command table, advance in chunks, jobs, recording
 * (docs/reference/protocol.md). Other ranks run gs_engine_serve(). */
#ifndef GEARSIM_SERVICE_H
#define GEARSIM_SERVICE_H

#include "gearsim/engine.h"

typedef struct gs_service_config {
    const char *connection_file;  /* where to write the endpoints */
    const char *data_dir;         /* root of every path in commands */
    const char *bind;             /* address, default 127.0.0.1 */
    int command_port, telemetry_port;  /* 0: any free port */
} gs_service_config;

/* Run the service until shutdown (command or SIGTERM/SIGINT); rank 0 only.
 * Ends by broadcasting GS_OP_SHUTDOWN so the other ranks return too. */
gs_err gs_service_run(gs_engine *eng, const gs_service_config *cfg);

#endif
