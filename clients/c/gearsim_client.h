/* SPDX-License-Identifier: MIT
 * gearsim_client: a small C client of gearsimd (docs/reference/protocol.md).
 *
 * One gsc_client holds a DEALER socket for commands and, after
 * gsc_subscribe(), a SUB socket for events. Requests carry ids unique to the
 * client; a request that times out is resent with the same id, so the daemon
 * answers from its reply cache and never executes it twice. JSON values are
 * json-c objects; ownership is stated per function. Not thread-safe: one
 * client per thread. No MPI: this library is not collective. */
#ifndef GEARSIM_CLIENT_H
#define GEARSIM_CLIENT_H

#include <stddef.h>

#include <json-c/json.h>

typedef struct gsc_client gsc_client;

/* An error: the daemon's error object, or a client-side failure with code
 * "timeout", "io_error", "bad_json" or "no_memory". */
typedef struct gsc_error {
    char code[64];
    char message[512];
    char field[256];
} gsc_error;

/* The default connection file: $XDG_RUNTIME_DIR/gearsim/gearsimd.json, else
 * /tmp/gearsim-<uid>/gearsimd.json. Writes into buf and returns it. */
const char *gsc_default_connection_file(char *buf, size_t n);

/* Read the connection file (NULL: the default) and connect the command
 * socket. On success *out is a new client (free with gsc_client_free) and 0
 * is returned; on failure -1, err filled (if not NULL), *out = NULL. */
int gsc_client_new(const char *connection_file, gsc_client **out, gsc_error *err);

/* Close the sockets and free the client; safe on NULL; sets *c = NULL. */
void gsc_client_free(gsc_client **c);

/* The daemon's session id, from the connection file (owned by the client). */
const char *gsc_client_session(const gsc_client *c);

/* Send {v: 1, id, cmd, args} and wait for its reply: up to timeout_ms per
 * attempt, resending the same frame `retries` times. args is borrowed (may be
 * NULL). On an ok reply returns 0 and, if result is not NULL, stores a new
 * reference to the result (caller calls json_object_put). On an error reply
 * or a timeout returns -1 with err filled. The request's id is then
 * available from gsc_last_id(). */
int gsc_request(gsc_client *c, const char *cmd, json_object *args, int timeout_ms, int retries,
                json_object **result, gsc_error *err);

/* The id of the last request sent (owned by the client). */
const char *gsc_last_id(const gsc_client *c);

/* Connect the SUB socket with a topic prefix ("" = every event) and wait up
 * to timeout_ms for the first heartbeat (the ZeroMQ slow joiner would lose
 * events sent before the subscription is live). 0 on success, -1 on failure.
 * From a daemon that batches telemetry (`telemetry_batch` in its connection
 * file) the telemetry travels many events per message, on the topic
 * `batch`; gsc_next_event hands them out one by one, in order, either way. */
int gsc_subscribe(gsc_client *c, const char *topic, int timeout_ms, gsc_error *err);

/* Wait up to timeout_ms for the next event. Returns 1 and a new reference in
 * *event (caller calls json_object_put), 0 on timeout, -1 if not subscribed.
 * Malformed messages are skipped. */
int gsc_next_event(gsc_client *c, int timeout_ms, json_object **event);

/* Wait for the end of the long request parent_id (advance, stiffness): its
 * `done` event when subscribed, and in any case every GSC_DONE_POLL_MS the
 * `finished` list of `status`, so a lost event (or no subscriber) never
 * hangs. Other events go to on_event (may be NULL; borrowed). Returns 0 and
 * a new reference to the done payload in *done (caller json_object_put),
 * -1 after timeout_ms (< 0: no limit) with err filled. */
#define GSC_DONE_POLL_MS 2000
int gsc_wait_done(gsc_client *c, const char *parent_id, int timeout_ms,
                  void (*on_event)(json_object *ev, void *user), void *user, json_object **done,
                  gsc_error *err);

/* Events missed so far (gaps in seq), counted when subscribed to "". */
long gsc_event_gaps(const gsc_client *c);

#endif
