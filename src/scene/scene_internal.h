/* SPDX-License-Identifier: MIT
 * Internal: the scene parser's limits and the helpers its files share: the
 * top level, numerics, initial state and outputs, and the checks across
 * bodies and meshes (scene.c), bodies and joints (scene_bodies.c), meshes
 * and loads (scene_meshes.c), the train shorthand and the fidelity switch
 * (scene_train.c). */
#ifndef GSI_SCENE_INTERNAL_H
#define GSI_SCENE_INTERNAL_H

#include <stdbool.h>

#include <json-c/json.h>

#include "gearsim/scene.h"

#define MAX_BODIES 64
#define MAX_MESHES 256
#define MAX_LOADS 256
#define MAX_TABLE 100000
#define DEG (GS_PI / 180.0)

gs_err gsi_scene_apply_fidelity(json_object *root, json_object **out, bool *copy, gs_diag *d);
/* `fidelity: {targets}` (scene_targets.c): the rung chosen from the
 * trade-off table set on a copy of root (*out, *copy as for
 * gsi_scene_apply_fidelity), the choice and its reasons as JSON text in
 * *choice (owned by the caller); *choice NULL and root untouched when
 * `fidelity` is not an object. */
gs_err gsi_scene_fidelity_targets(json_object *root, json_object **out, bool *copy, char **choice, gs_diag *d);
gs_err gsi_scene_enum_field(json_object *o, const char *key, const char *path, const char *def,
                            const char *const *names, int n, int *out, gs_diag *d);
gs_err gsi_scene_expand_train(json_object *c, gs_diag *d);
gs_err gsi_scene_parse_body(json_object *o, const char *path, gs_scene_body *b, gs_diag *d);
gs_err gsi_scene_parse_gear_mesh(gs_scene *s, json_object *o, const char *path, gs_scene_mesh *m,
                                 gs_diag *d);
gs_err gsi_scene_parse_joint(gs_scene *s, json_object *o, const char *path, bool *seen, gs_diag *d);
gs_err gsi_scene_prefix_diag(gs_err e, gs_diag *d, const char *path);

#endif
