/* SPDX-License-Identifier: MIT
 * Fuzz target: scene parsing and validation (gs_scene_parse) on arbitrary
 * bytes. A valid scene must also survive being parsed again from its own
 * stored JSON (sc->json) — the text the daemon broadcasts to other ranks. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/scene.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size > (1u << 18))
        return -1;
    gs_scene *sc = NULL;
    gs_diag d;
    gs_err e = gs_scene_parse((const char *)data, size, &sc, &d);
    if (e == GS_OK) {
        if (!sc) {
            fprintf(stderr, "gs_scene_parse: GS_OK without a scene\n");
            abort();
        }
        if (sc->json) {
            gs_scene *again = NULL;
            if (gs_scene_parse(sc->json, strlen(sc->json), &again, &d) != GS_OK) {
                fprintf(stderr, "a valid scene's own JSON does not parse again: %s (%s)\n", d.message, d.field);
                abort();
            }
            gs_scene_free(&again);
        }
        gs_scene_free(&sc);
    } else if (sc) {
        fprintf(stderr, "gs_scene_parse: error %d left a scene behind\n", (int)e);
        abort();
    } else if (!d.message[0]) {
        fprintf(stderr, "gs_scene_parse: error %d without a message\n", (int)e);
        abort();
    }
    return 0;
}
