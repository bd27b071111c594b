/* SPDX-License-Identifier: MIT
 * gearsim: the one error enum and the diagnostics that carry a field name.
 *
 * Every fallible function returns a gs_err. Codes are generated together with
 * their stable wire strings (the protocol's error.code) and messages, so a code
 * can never lack either. A gs_diag, when given, receives the offending field
 * (a JSON path such as "bodies[2].teeth") and a human sentence. */
#ifndef GEARSIM_ERROR_H
#define GEARSIM_ERROR_H

#include <stddef.h>
#include <stdint.h>

/* X(enum, wire code, message) */
#define GS_ERRORS(X)                                                                  \
    X(GS_OK, "ok", "success")                                                         \
    X(GS_ENOMEM, "no_memory", "out of memory")                                        \
    X(GS_EINVAL, "invalid_argument", "invalid argument")                              \
    X(GS_EPARSE, "bad_json", "malformed JSON")                                        \
    X(GS_ESCHEMA, "invalid_field", "a field is missing, unknown or of the wrong type") \
    X(GS_ERANGE, "out_of_range", "a value is out of its allowed range")               \
    X(GS_EGEOMETRY, "impossible_geometry", "the geometry cannot be built")            \
    X(GS_ESTATE, "wrong_state", "the command is not allowed in the current state")    \
    X(GS_EUNKNOWN, "unknown_command", "unknown command")                              \
    X(GS_EVERSION, "unsupported_version", "unsupported protocol version")             \
    X(GS_ETOOBIG, "too_large", "the message or request exceeds a limit")              \
    X(GS_EIO, "io_error", "input/output error")                                       \
    X(GS_ENOTFOUND, "not_found", "not found")                                         \
    X(GS_ESINGULAR, "singular", "a matrix is singular or not positive definite")      \
    X(GS_ENOCONV, "no_convergence", "an iteration did not converge")                  \
    X(GS_EINFEASIBLE, "infeasible", "the constraints cannot be satisfied")            \
    X(GS_EMPI, "mpi_error", "an MPI operation failed")                                \
    X(GS_EBUSY, "busy", "the service is busy")                                        \
    X(GS_EREFINE, "refine", "the step is to be taken again with a smaller time step") \
    X(GS_EINTERNAL, "internal", "internal error")                                    \
    X(GS_ERANKLOST, "rank_lost", "a rank of the daemon died")

typedef enum {
#define GS_ERR_ENUM(e, code, msg) e,
    GS_ERRORS(GS_ERR_ENUM)
#undef GS_ERR_ENUM
        GS_ERR_COUNT
} gs_err;

/* Human message of a code ("unknown error" for values out of range). */
const char *gs_strerror(gs_err e);
/* Stable machine-readable string used on the wire as error.code. */
const char *gs_errcode(gs_err e);

/* Where an error came from, for a client: field path and sentence. */
typedef struct gs_diag {
    char field[160];
    char message[320];
} gs_diag;

/* Fill d (if not NULL) and return e. printf-style message. */
gs_err gs_diag_set(gs_diag *d, gs_err e, const char *field, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
void gs_diag_clear(gs_diag *d);

/* Propagate an error code from a call, keeping the first one. */
#define GS_TRY(expr)                     \
    do {                                 \
        gs_err gs_try_e_ = (expr);       \
        if (gs_try_e_ != GS_OK)          \
            return gs_try_e_;            \
    } while (0)

#endif
