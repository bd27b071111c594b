/* SPDX-License-Identifier: MIT
 * Error strings generated from the GS_ERRORS table. */
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "gearsim/error.h"

static const char *const codes[] = {
#define GS_ERR_CODE(e, code, msg) [e] = code,
    GS_ERRORS(GS_ERR_CODE)
#undef GS_ERR_CODE
};

static const char *const messages[] = {
#define GS_ERR_MSG(e, code, msg) [e] = msg,
    GS_ERRORS(GS_ERR_MSG)
#undef GS_ERR_MSG
};

const char *gs_strerror(gs_err e)
{
    if ((int)e < 0 || e >= GS_ERR_COUNT)
        return "unknown error";
    return messages[e];
}

const char *gs_errcode(gs_err e)
{
    if ((int)e < 0 || e >= GS_ERR_COUNT)
        return "internal";
    return codes[e];
}

gs_err gs_diag_set(gs_diag *d, gs_err e, const char *field, const char *fmt, ...)
{
    if (d == NULL)
        return e;
    snprintf(d->field, sizeof d->field, "%s", field ? field : "");
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(d->message, sizeof d->message, fmt, ap);
    va_end(ap);
    return e;
}

void gs_diag_clear(gs_diag *d)
{
    if (d) {
        d->field[0] = '\0';
        d->message[0] = '\0';
    }
}
