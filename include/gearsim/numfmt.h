/* SPDX-License-Identifier: MIT
 * gearsim: exact number text for JSON output (the telemetry events). */
#ifndef GEARSIM_NUMFMT_H
#define GEARSIM_NUMFMT_H

#include <stddef.h>

/* Room for any text gs_fmt_double writes, its NUL included. */
#define GS_FMT_DOUBLE_MAX 32

/* The shortest decimal text that reads back (strtod, Python's float, any
 * correctly rounding reader) as exactly x: at most 17 significant digits,
 * laid out as printf's %g would lay them out (an exponent below -4 or from
 * 17 up in e-notation, "e-05" style), and always a JSON float: an integral
 * value keeps ".0" (3.0, -0.0), as json-c writes doubles. A non-finite x
 * writes "null" (JSON has no NaN or infinity). Writes the NUL; returns the
 * length. buf holds at least GS_FMT_DOUBLE_MAX bytes. */
int gs_fmt_double(char *buf, double x);

#endif
