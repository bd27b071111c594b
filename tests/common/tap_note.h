/* SPDX-License-Identifier: MIT
 * Included before <cmocka.h> into every C test (meson.build: cmocka_dep):
 * the tests' print_message() output becomes TAP comments, each line
 * prefixed with "# ", so that meson's TAP parser (the tests run with
 * CMOCKA_MESSAGE_OUTPUT=TAP) reads nothing but TAP. cmocka's own
 * declaration of print_message then declares this function again. */
#ifndef GEARSIM_TESTS_TAP_NOTE_H
#define GEARSIM_TESTS_TAP_NOTE_H

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

static void gs_tap_note(const char *const format, ...) __attribute__((format(printf, 1, 2), unused));

static void gs_tap_note(const char *const format, ...)
{
    static int mid_line; /* the last note ended without a newline */
    va_list ap;
    va_start(ap, format);
    int n = vsnprintf(NULL, 0, format, ap);
    va_end(ap);
    if (n < 0)
        return;
    char *buf = malloc((size_t)n + 1);
    if (!buf)
        return;
    va_start(ap, format);
    vsnprintf(buf, (size_t)n + 1, format, ap);
    va_end(ap);
    for (const char *p = buf; *p; p++) {
        if (!mid_line)
            fputs(*p == '\n' ? "#" : "# ", stdout);
        fputc(*p, stdout);
        mid_line = *p != '\n';
    }
    free(buf);
    fflush(stdout);
}

#define print_message gs_tap_note

#endif
