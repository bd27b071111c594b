/* SPDX-License-Identifier: MIT
 * gearsim: basic numeric types and constants shared by every module. */
#ifndef GEARSIM_TYPES_H
#define GEARSIM_TYPES_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "gearsim/error.h"

/* Sizes of meshes and linear systems. */
typedef int64_t gs_index;

#define GS_PI 3.14159265358979323846
#define GS_RPM_PER_RAD_S (60.0 / (2.0 * GS_PI))

#endif
