/* SPDX-License-Identifier: MIT
 * ZeroMQ CURVE authentication of the service's sockets: the server key, an
 * allow-list of client public keys and a ZAP handler on its own thread (so a
 * long MPI operation on the main thread never stalls new connections).
 * Key files are Z85 text written by `gearctl keys` (docs/reference/protocol.md):
 *
 *   NAME.key (mode 0600)   public-key = <40 Z85 chars>
 *                          secret-key = <40 Z85 chars>
 *   NAME.pub               public-key = <40 Z85 chars>
 *
 * Blank lines and lines starting with '#' are ignored; a line holding only
 * 40 Z85 characters is a public key too. */
#ifndef GSI_AUTH_H
#define GSI_AUTH_H

#include <stdbool.h>
#include <stddef.h>

/* Read the server's secret key file and the allow-list (a key file or a
 * directory of *.pub / *.key files). Call before gs_service_run, once.
 * Returns 0, or -1 with a sentence in err. */
int gs_service_set_curve(const char *server_key_file, const char *allow_path, char *err, size_t cap);
/* Loopback default: make a server key pair and one client key pair now,
 * allow only that client key; both go into the 0600 connection file so
 * that only who can read it can talk to the daemon. 0, or -1 with err. */
int gs_service_set_curve_local(char *err, size_t cap);
/* True for addresses that only this machine can reach (127.x.y.z, ::1,
 * localhost, lo): those may be bound without CURVE. */
bool gs_bind_is_loopback(const char *bind);

/* Used by the service loop (service.c). */
bool gsi_curve_enabled(void);
const char *gsi_curve_server_public(void); /* Z85, 40 chars */
int gsi_curve_allowed_count(void);
/* The client key pair made by gs_service_set_curve_local (Z85); false
 * when the keys were given by the operator (or CURVE is off). */
bool gsi_curve_local_client(const char **pub, const char **secret);
/* Make sock a CURVE server (before bind). */
int gsi_curve_apply(void *sock);
/* Bind the ZAP endpoint in zctx and start the handler thread (before any
 * socket binds). */
int gsi_curve_start(void *zctx);
/* After the service sockets are closed: shut zctx down, join the thread.
 * The caller still calls zmq_ctx_term. */
void gsi_curve_stop(void *zctx);

#endif
