/* SPDX-License-Identifier: MIT
 * gearsim-modal: natural frequencies and mode shapes of a scene's
 * linearised rigid/lumped train (include/gearsim/modal.h, docs/MODAL.md).
 *
 *   gearsim-modal SCENE.json [--json]
 *
 * Without --json prints one line per group of equal frequencies (frequency,
 * kind, multiplicity); with --json the result object of the `modal` command
 * (proto/v1/results/modal.json). Exit status 0 on success, 1 on bad usage,
 * 2 on an error (message on stderr naming the field). Not an MPI program. */
#include <stdio.h>
#include <string.h>

#include <json-c/json.h>

#include "gearsim/modal.h"
#include "tool.h"

int main(int argc, char **argv)
{
    const char *path = NULL;
    int json = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--json"))
            json = 1;
        else if (argv[i][0] != '-' && !path)
            path = argv[i];
        else {
            fprintf(stderr, "usage: gearsim-modal SCENE.json [--json]\n");
            return 1;
        }
    }
    if (!path) {
        fprintf(stderr, "usage: gearsim-modal SCENE.json [--json]\n");
        return 1;
    }
    gs_scene *s = tool_load_scene("gearsim-modal", path);
    if (!s)
        return 2;
    gs_diag d;
    gs_diag_clear(&d);
    gs_modal *m = NULL;
    gs_err e = gs_modal_analyse(s, &m, &d);
    if (e != GS_OK) {
        fprintf(stderr, "gearsim-modal: %s: %s: %s (%s)\n", path, d.field, d.message, gs_errcode(e));
        gs_scene_free(&s);
        return 2;
    }
    if (json) {
        json_object *o = gs_modal_json(m, s);
        printf("%s\n", json_object_to_json_string_ext(o, JSON_C_TO_STRING_PLAIN));
        json_object_put(o);
    } else {
        printf("%s: %d coordinates, %d groups of modes\n", s->name, m->n, m->n_groups);
        printf("%14s  %-13s %s\n", "frequency Hz", "kind", "multiplicity");
        for (int g = 0; g < m->n_groups; g++)
            printf("%14.3f  %-13s %d\n", m->freq_hz[m->group_first[g]], gs_mode_kind_name(m->group_kind[g]),
                   m->group_mult[g]);
    }
    gs_modal_free(&m);
    gs_scene_free(&s);
    return 0;
}
