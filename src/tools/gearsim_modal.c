/* SPDX-License-Identifier: MIT
 * gearsim-modal: natural frequencies and mode shapes of a scene's
 * linearised rigid/lumped train (include/gearsim/modal.h, docs/explanation/modal.md).
 *
 *   gearsim-modal SCENE.json [--json]
 *   gearsim-modal SCENE.json --fe [--mesh NAME] [--positions N] [--modes M] [--refine R]
 *                 [--order 1|2] [--torque T] [--no-nearfield|--plain] [--nearfield-secant] [--json]
 *
 * Without --json prints one line per group of equal frequencies (frequency,
 * kind, multiplicity); with --json the result object of the `modal` command
 * (proto/v1/results/modal.json). With --fe: the torsional mesh modes of the
 * mesh's elastic pair from the FE model's generalised eigenproblem at the
 * loaded static contact (include/gearsim/fe_modes.h), one line per roll
 * position and the mean, or (--json) gs_fe_modes_json's object.
 * --nearfield-secant: the pairs' secant near-field compliance instead of the
 * tangent (the linearisation of the dynamic contact with "nearfield").
 * Exit status 0 on success, 1 on an error (message on stderr naming the
 * field), 2 on bad usage. Not an MPI program. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <json-c/json.h>

#include "gearsim/fe_modes.h"
#include "gearsim/modal.h"
#include "tool.h"

#define USAGE                                                                                   \
    "usage: gearsim-modal SCENE.json [--json]\n"                                                   \
    "       gearsim-modal SCENE.json --fe [--mesh NAME] [--positions N] [--modes M] [--refine R]\n" \
    "                     [--order 1|2] [--torque T] [--no-nearfield|--plain] [--nearfield-secant] [--json]\n"

static int fe_modes(const char *path, gs_scene *s, const char *mesh, const gs_fe_modes_opts *o, int json)
{
    int mi = 0;
    if (mesh) {
        mi = -1;
        for (int i = 0; i < s->n_meshes; i++)
            if (!strcmp(s->meshes[i].name, mesh))
                mi = i;
        if (mi < 0) {
            fprintf(stderr, "gearsim-modal: %s: mesh: no mesh '%s'\n", path, mesh);
            return TOOL_FAIL;
        }
    }
    gs_diag d;
    gs_diag_clear(&d);
    gs_fe_modes_result r;
    gs_err e = gs_fe_modes_analyse(s, mi, o, &r, &d);
    if (e != GS_OK) {
        fprintf(stderr, "gearsim-modal: %s: %s: %s (%s)\n", path, d.field, d.message, gs_errcode(e));
        return TOOL_FAIL;
    }
    if (json) {
        json_object *j = gs_fe_modes_json(&r);
        printf("%s\n", json_object_to_json_string_ext(j, JSON_C_TO_STRING_PLAIN));
        json_object_put(j);
    } else {
        printf("%s: FE mesh modes, %ld + %ld nodes, %ld unknowns, torque %.4g N m\n", s->name,
               (long)r.nodes[0], (long)r.nodes[1], (long)r.unknowns, r.torque_nm);
        printf("%6s %5s %12s %9s %12s %12s  higher modes Hz (rotation share)\n", "roll", "rows", "mode Hz",
               "rotation", "lumped Hz", "k_tan N/m");
        for (int j = 0; j < r.positions; j++) {
            const gs_fe_modes_point *p = &r.pt[j];
            printf("%6.3f %5d %12.2f %9.4f %12.2f %12.5g ", p->roll, p->rows, p->hz[0], p->rotation[0],
                   p->lumped_hz, p->k_tan);
            for (int m = 1; m < r.modes; m++)
                printf(" %.1f (%.3f)", p->hz[m], p->rotation[m]);
            printf("\n");
        }
        printf("first mesh mode: mean %.2f Hz (min %.2f, max %.2f); lumped closed form with the mean "
               "tangent stiffness %.5g N/m: %.2f Hz; %.2f s\n",
               r.mean_hz, r.min_hz, r.max_hz, r.k_tan_mean, r.lumped_mean_hz, r.seconds);
    }
    gs_fe_modes_result_clear(&r);
    return 0;
}

int main(int argc, char **argv)
{
    const char *path = NULL, *mesh = NULL;
    int json = 0, fe = 0;
    gs_fe_modes_opts o;
    gs_fe_modes_opts_defaults(&o);
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *v = i + 1 < argc ? argv[i + 1] : NULL;
        if (!strcmp(a, "--json"))
            json = 1;
        else if (!strcmp(a, "--fe"))
            fe = 1;
        else if (!strcmp(a, "--mesh") && v)
            mesh = argv[++i];
        else if (!strcmp(a, "--positions") && v)
            o.positions = atoi(argv[++i]);
        else if (!strcmp(a, "--modes") && v)
            o.modes = atoi(argv[++i]);
        else if (!strcmp(a, "--refine") && v)
            o.refine = atoi(argv[++i]);
        else if (!strcmp(a, "--order") && v)
            o.order = atoi(argv[++i]);
        else if (!strcmp(a, "--torque") && v)
            o.torque_nm = atof(argv[++i]);
        else if (!strcmp(a, "--no-nearfield") || !strcmp(a, "--plain"))
            o.nearfield = 0;
        else if (!strcmp(a, "--nearfield-secant"))
            o.nearfield_secant = 1;
        else if (a[0] != '-' && !path)
            path = a;
        else {
            fprintf(stderr, USAGE);
            return TOOL_USAGE;
        }
    }
    if (!path) {
        fprintf(stderr, USAGE);
        return TOOL_USAGE;
    }
    gs_scene *s = tool_load_scene("gearsim-modal", path);
    if (!s)
        return TOOL_FAIL;
    if (fe) {
        int rc = fe_modes(path, s, mesh, &o, json);
        gs_scene_free(&s);
        return rc;
    }
    gs_diag d;
    gs_diag_clear(&d);
    gs_modal *m = NULL;
    gs_err e = gs_modal_analyse(s, &m, &d);
    if (e != GS_OK) {
        fprintf(stderr, "gearsim-modal: %s: %s: %s (%s)\n", path, d.field, d.message, gs_errcode(e));
        gs_scene_free(&s);
        return TOOL_FAIL;
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
