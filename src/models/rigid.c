/* SPDX-License-Identifier: MIT
 * Rigid body model: one rotation coordinate in joint coordinates
 * (METHOD.md section 1), moments and an implicit brake (section 2). */
#include "gearsim/models.h"

static gs_err rigid_init(const gs_model_view *sys, gs_body_rt *b, gs_diag *d)
{
    (void)sys;
    (void)d;
    b->model = NULL;
    return GS_OK;
}

static void rigid_destroy(gs_body_rt *b)
{
    (void)b;
}

/* d = d0 + C f with 1/C = 2/h^2 I + c/h and d0 = C (2/h I w + M(t + h/2)):
 * the midpoint momentum equation with the brake -c d/h taken implicitly. */
static void rigid_interface(const gs_model_view *sys, gs_body_rt *b, double h, double *rec)
{
    if (b->coord < 0)
        return;
    double *C = &rec[0], *d0 = &rec[1];
    double M, c;
    gs_model_body_load(sys, b->index, sys->time + 0.5 * h, &M, &c);
    double I = b->inertia_eff;
    double H = 2.0 / (h * h) * I + c / h;
    *C = 1.0 / H;
    *d0 = (2.0 / h * I * sys->w[b->coord] + M) / H;
}

static void rigid_energy(const gs_model_view *sys, const gs_body_rt *b, double *T, double *V)
{
    double w = sys->w[b->coord];
    *T = 0.5 * b->inertia_eff * w * w;
    *V = 0.0;
}

const gs_body_ops gsi_body_rigid = {
    .name = "rigid",
    .init = rigid_init,
    .destroy = rigid_destroy,
    .interface = rigid_interface,
    .energy = rigid_energy,
};
