/* SPDX-License-Identifier: MIT
 * Shared by the command line tools: loading the scene file named on the
 * command line. */
#ifndef GEARSIM_TOOLS_TOOL_H
#define GEARSIM_TOOLS_TOOL_H

#include <stdio.h>

#include "gearsim/scene.h"

/* Exit statuses of every tool, as gearsimd's and gearctl's: 0 success,
 * TOOL_FAIL an error (message on stderr), TOOL_USAGE bad usage. */
enum { TOOL_FAIL = 1, TOOL_USAGE = 2 };

/* The scene in the file at path; NULL after printing
 * "TOOL: PATH: FIELD: MESSAGE (CODE)" on stderr. The caller frees it. */
static inline gs_scene *tool_load_scene(const char *tool, const char *path)
{
    gs_diag d;
    gs_diag_clear(&d);
    gs_scene *s = NULL;
    gs_err e = gs_scene_load_file(path, &s, &d);
    if (e != GS_OK) {
        fprintf(stderr, "%s: %s: %s: %s (%s)\n", tool, path, d.field, d.message, gs_errcode(e));
        return NULL;
    }
    return s;
}

#endif
