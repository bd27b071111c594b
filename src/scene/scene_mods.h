/* SPDX-License-Identifier: MIT
 * Internal: a gear body's `modification`, `pitch_errors_um` and `runout`
 * (and the older single `pitch_error`) into b->mods. */
#ifndef GSI_SCENE_MODS_H
#define GSI_SCENE_MODS_H

#include <json-c/json.h>

#include "gearsim/scene.h"

/* After the gear's own fields are parsed and validated. Leaves b->mods NULL
 * when the body has none of these fields. */
gs_err gsi_scene_parse_mods(json_object *o, const char *path, gs_scene_body *b, gs_diag *d);

#endif
