/* SPDX-License-Identifier: MIT
 * gearsim-mesh: mesh every gear of a scene and write the meshes to HDF5 with
 * an XDMF file beside (include/gearsim/mesh_io.h), so a user can look at the
 * gears before running anything (gearctl mesh draws them).
 *
 *   gearsim-mesh SCENE.json -o OUT.h5 [--refine N] [--xmf OUT.xmf] [--quiet]
 *
 * Each gear is placed at its joint (fixed axis: its centre; on a carrier:
 * carrier centre + radius at the angle; held: the origin) and turned so its
 * teeth sit in mesh with its neighbours: the first gear of each chain of
 * meshes keeps its scene angle, every other one takes the mesh phase nearest
 * to its own scene angle (gs_pair_mesh_phase). Prints one line per gear
 * (nodes, triangles, element quality) and any geometry warnings to stdout.
 * Exit status 0 on success, 1 on an error (message on stderr naming the
 * field), 2 on bad usage. Not an MPI program. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/geometry.h"
#include "gearsim/mesh.h"
#include "gearsim/models.h"
#include "gearsim/mesh_io.h"
#include "gearsim/scene.h"
#include "tool.h"

static void usage(FILE *f)
{
    fprintf(f, "usage: gearsim-mesh SCENE.json -o OUT.h5 [--refine N] [--xmf OUT.xmf] [--quiet]\n");
}

int main(int argc, char **argv)
{
    const char *scene_path = NULL, *out = NULL, *xmf = NULL;
    int refine = 0, quiet = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "-o") && i + 1 < argc)
            out = argv[++i];
        else if (!strcmp(argv[i], "--xmf") && i + 1 < argc)
            xmf = argv[++i];
        else if (!strcmp(argv[i], "--refine") && i + 1 < argc) {
            char *end;
            long v = strtol(argv[++i], &end, 10);
            if (*end || v < 0 || v > 8) {
                fprintf(stderr, "gearsim-mesh: --refine must be 0..8\n");
                return TOOL_USAGE;
            }
            refine = (int)v;
        } else if (!strcmp(argv[i], "--quiet"))
            quiet = 1;
        else if (!strcmp(argv[i], "-h") || !strcmp(argv[i], "--help")) {
            usage(stdout);
            return 0;
        } else if (argv[i][0] != '-' && !scene_path)
            scene_path = argv[i];
        else {
            usage(stderr);
            return TOOL_USAGE;
        }
    }
    if (!scene_path || !out) {
        usage(stderr);
        return TOOL_USAGE;
    }
    gs_scene *s = tool_load_scene("gearsim-mesh", scene_path);
    if (!s)
        return TOOL_FAIL;
    gs_diag d;
    gs_err e;
    int n = s->n_bodies, ng = 0, rc = 0;
    gs_mesh **meshes = calloc((size_t)n, sizeof *meshes);
    gs_mesh_io_gear *ent = calloc((size_t)n, sizeof *ent);
    double *rot = calloc((size_t)n, sizeof *rot);
    double(*ctr)[2] = calloc((size_t)n, sizeof *ctr);
    int *placed = calloc((size_t)n, sizeof *placed), *queue = calloc((size_t)n, sizeof *queue);
    if (!meshes || !ent || !rot || !ctr || !placed || !queue) {
        fprintf(stderr, "gearsim-mesh: out of memory\n");
        rc = TOOL_FAIL;
        goto done;
    }
    for (int i = 0; i < n; i++) {
        gs_scene_body_centre(s, i, ctr[i]);
        rot[i] = s->bodies[i].angle0;
    }
    /* Mesh phases: breadth first along the scene's meshes. */
    for (int root = 0; root < n; root++) {
        if (placed[root] || s->bodies[root].type != GS_BODY_GEAR)
            continue;
        int head = 0, tail = 0;
        queue[tail++] = root;
        placed[root] = 1;
        while (head < tail) {
            int a = queue[head++];
            for (int k = 0; k < s->n_meshes; k++) {
                int g0 = s->meshes[k].gear[0], g1 = s->meshes[k].gear[1];
                int b = g0 == a ? g1 : g1 == a ? g0 : -1;
                if (b < 0 || placed[b] || s->bodies[b].type != GS_BODY_GEAR)
                    continue;
                rot[b] = gs_pair_mesh_phase(&s->bodies[a].gear, ctr[a], rot[a], &s->bodies[b].gear,
                                            ctr[b], s->bodies[b].angle0);
                placed[b] = 1;
                queue[tail++] = b;
            }
        }
    }
    for (int i = 0; i < n; i++) {
        const gs_scene_body *b = &s->bodies[i];
        if (b->type != GS_BODY_GEAR)
            continue;
        gs_diag_clear(&d);
        e = gs_scene_gear_mesh_refined(b, refine, &meshes[i], &d);
        if (e != GS_OK) {
            fprintf(stderr, "gearsim-mesh: bodies[%d] (%s): %s: %s (%s)\n", i, b->name, d.field,
                    d.message, gs_errcode(e));
            rc = TOOL_FAIL;
            goto done;
        }
        char warn[1024];
        int nw = 0;
        gs_gear_check(&b->gear, NULL, warn, sizeof warn, &nw);
        gs_mesh_quality q;
        gs_mesh_quality_eval(meshes[i], &q);
        if (!quiet) {
            printf("%-16s %s z=%-4d m=%.4g mm  nodes %lld  triangles %lld  min angle %.1f deg  "
                   "max aspect %.2f\n",
                   b->name, b->gear.kind == GS_GEAR_INTERNAL ? "internal" : "external",
                   b->gear.teeth, b->gear.module_m * 1e3, (long long)meshes[i]->n_nodes,
                   (long long)meshes[i]->n_tris, q.min_angle_deg, q.max_aspect);
            if (nw > 0)
                printf("%s", warn);
        }
        ent[ng].name = b->name;
        ent[ng].mesh = meshes[i];
        ent[ng].params = &b->gear;
        ent[ng].centre[0] = ctr[i][0];
        ent[ng].centre[1] = ctr[i][1];
        ent[ng].rotation = rot[i];
        ng++;
    }
    if (ng == 0) {
        fprintf(stderr, "gearsim-mesh: %s has no gear\n", scene_path);
        rc = TOOL_FAIL;
        goto done;
    }
    gs_diag_clear(&d);
    e = gs_mesh_io_write(out, xmf, ent, ng, &d);
    if (e != GS_OK) {
        fprintf(stderr, "gearsim-mesh: %s: %s (%s)\n", d.field, d.message, gs_errcode(e));
        rc = TOOL_FAIL;
        goto done;
    }
    if (!quiet) {
        char xb[4096];
        if (!xmf && gs_mesh_io_xmf_path(out, xb, sizeof xb) == GS_OK)
            xmf = xb;
        printf("wrote %s and %s (%d gears)\n", out, xmf ? xmf : "", ng);
    }
done:
    if (meshes)
        for (int i = 0; i < n; i++)
            gs_mesh_free(&meshes[i]);
    free(meshes);
    free(ent);
    free(rot);
    free(ctr);
    free(placed);
    free(queue);
    gs_scene_free(&s);
    return rc;
}
