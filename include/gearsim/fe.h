/* SPDX-License-Identifier: MIT
 * gearsim: linear finite elements of an elastic body in its material frame
 * (METHOD.md sections 1, 2 and 4). Owned by the fe module; the material
 * struct is the contract with the scene module. */
#ifndef GEARSIM_FE_H
#define GEARSIM_FE_H

#include "gearsim/mesh.h"
#include "gearsim/types.h"

typedef enum { GS_PLANE_STRESS = 0, GS_PLANE_STRAIN = 1 } gs_plane;

typedef struct gs_material {
    double youngs_pa;   /* E, default 210e9 (steel) */
    double poisson;     /* nu, default 0.3 */
    double density;     /* rho kg/m^3, default 7850 */
    gs_plane plane;     /* default plane stress with the face width as thickness */
} gs_material;

static inline gs_material gs_material_steel(void)
{
    gs_material m = {210e9, 0.3, 7850.0, GS_PLANE_STRESS};
    return m;
}

#endif
