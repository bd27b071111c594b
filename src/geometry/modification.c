/* SPDX-License-Identifier: MIT
 * gearsim: profile modifications (tip and root relief, measured deviation
 * tables) and tooth errors (pitch errors, run-out) of a spur gear
 * (include/gearsim/modification.h, docs/explanation/geometry.md); their application to
 * a gear's FE mesh is src/mesh/mesh_mods.c. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/modification.h"
#include "gearsim/util.h"

gs_gear_mods *gs_gear_mods_new(void)
{
    return gs_calloc(1, sizeof(gs_gear_mods));
}

void gs_gear_mods_free(gs_gear_mods **m)
{
    if (!m || !*m)
        return;
    free((*m)->pitch_m);
    free(*m);
    *m = NULL;
}

gs_err gs_gear_mods_copy(const gs_gear_mods *src, gs_gear_mods **dst)
{
    *dst = NULL;
    if (!src)
        return GS_OK;
    gs_gear_mods *c = gs_gear_mods_new();
    if (!c)
        return GS_ENOMEM;
    *c = *src;
    c->pitch_m = NULL;
    if (src->n_pitch > 0) {
        c->pitch_m = malloc((size_t)src->n_pitch * sizeof *c->pitch_m);
        if (!c->pitch_m) {
            free(c);
            return GS_ENOMEM;
        }
        memcpy(c->pitch_m, src->pitch_m, (size_t)src->n_pitch * sizeof *c->pitch_m);
    }
    *dst = c;
    return GS_OK;
}

static int flank_has(const gs_flank_mod *f)
{
    return f->tip.amount_m != 0.0 || f->root.amount_m != 0.0 || f->n_dev > 0;
}

int gs_gear_mods_has_profile(const gs_gear_mods *m)
{
    return m && (flank_has(&m->flank[0]) || flank_has(&m->flank[1]));
}

int gs_gear_mods_any(const gs_gear_mods *m)
{
    if (!m)
        return 0;
    if (gs_gear_mods_has_profile(m) || m->runout_m != 0.0)
        return 1;
    for (int k = 0; k < m->n_pitch; k++)
        if (m->pitch_m[k] != 0.0)
            return 1;
    return 0;
}

double gs_gear_roll_length(const gs_gear_geom *g, double R)
{
    double u = R * R - g->rb * g->rb;
    return u > 0 ? sqrt(u) : 0.0;
}

double gs_gear_roll_radius(const gs_gear_geom *g, double L)
{
    return sqrt(g->rb * g->rb + L * L);
}

/* Relief removed at roll length L: the relief grows from its start L_s to
 * its end L_e (tip or form point), either way round. */
static double relief_at(const gs_relief *r, double L, double Ls, double Le)
{
    if (r->amount_m == 0.0 || Le == Ls)
        return 0.0;
    double u = (L - Ls) / (Le - Ls);
    if (!(u > 0.0))
        return 0.0;
    if (u > 1.0)
        u = 1.0;
    return r->amount_m * (r->parabolic ? u * u : u);
}

static double table_at(const gs_flank_mod *f, double xi)
{
    int n = f->n_dev;
    if (n <= 0)
        return 0.0;
    if (xi <= f->dev_roll[0])
        return f->dev_m[0];
    if (xi >= f->dev_roll[n - 1])
        return f->dev_m[n - 1];
    int lo = 0, hi = n - 1;
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (f->dev_roll[mid] <= xi)
            lo = mid;
        else
            hi = mid;
    }
    double t = (xi - f->dev_roll[lo]) / (f->dev_roll[hi] - f->dev_roll[lo]);
    return f->dev_m[lo] + t * (f->dev_m[hi] - f->dev_m[lo]);
}

double gs_gear_flank_offset(const gs_gear_geom *g, const gs_gear_mods *m, int side, double R)
{
    if (!m)
        return 0.0;
    const gs_flank_mod *f = &m->flank[side ? 1 : 0];
    if (!flank_has(f))
        return 0.0;
    double L = gs_gear_roll_length(g, R);
    double La = gs_gear_roll_length(g, g->ra), Lf = gs_gear_roll_length(g, g->r_form);
    double off = 0.0;
    if (f->tip.amount_m != 0.0)
        off -= relief_at(&f->tip, L, gs_gear_roll_length(g, f->tip.start_radius_m), La);
    if (f->root.amount_m != 0.0)
        off -= relief_at(&f->root, L, gs_gear_roll_length(g, f->root.start_radius_m), Lf);
    if (f->n_dev > 0)
        off += table_at(f, L / g->rb);
    return off;
}

double gs_gear_modified_psi(const gs_gear_geom *g, const gs_gear_mods *m, int side, double R)
{
    double psi = gs_gear_involute_psi(g, R);
    if (!m)
        return psi;
    double f = gs_gear_flank_offset(g, m, side, R);
    return f == 0.0 ? psi : psi + f / g->rb;
}

static gs_err check_relief(const gs_gear_geom *g, const gs_relief *r, int tip, const char *prefix,
                           const char *side, gs_diag *d)
{
    char field[160];
    snprintf(field, sizeof field, "%s%s.%s_relief", prefix, side, tip ? "tip" : "root");
    if (r->amount_m == 0.0)
        return GS_OK;
    if (!(r->amount_m > 0.0) || !(r->amount_m <= 0.5 * g->m) || !isfinite(r->amount_m))
        return gs_diag_set(d, GS_ERANGE, field,
                           "relief amount %g um out of range (0 to half a module, %g um)",
                           r->amount_m * 1e6, 0.5 * g->m * 1e6);
    double lo = fmin(g->r_form, g->ra), hi = fmax(g->r_form, g->ra);
    double R = r->start_radius_m;
    if (!isfinite(R) || !(R > lo) || !(R < hi))
        return gs_diag_set(d, GS_ERANGE, field,
                           "relief must start on the involute flank: start diameter %.6g mm "
                           "outside the form diameter %.6g mm to tip diameter %.6g mm",
                           2e3 * R, 2e3 * g->r_form, 2e3 * g->ra);
    return GS_OK;
}

gs_err gs_gear_mods_check(const gs_gear_geom *g, const gs_gear_mods *m, const char *prefix,
                          const char *prefix_body, gs_diag *d)
{
    if (!m)
        return GS_OK;
    static const char *const side[2] = {".cw", ".ccw"};
    for (int s = 0; s < 2; s++) {
        const gs_flank_mod *f = &m->flank[s];
        GS_TRY(check_relief(g, &f->tip, 1, prefix, side[s], d));
        GS_TRY(check_relief(g, &f->root, 0, prefix, side[s], d));
        char field[160];
        snprintf(field, sizeof field, "%s%s.deviation", prefix, side[s]);
        if (f->n_dev < 0 || f->n_dev > GS_MOD_TABLE_MAX)
            return gs_diag_set(d, GS_ERANGE, field, "1 to %d points", GS_MOD_TABLE_MAX);
        for (int i = 0; i < f->n_dev; i++) {
            if (!isfinite(f->dev_roll[i]) || !isfinite(f->dev_m[i]) ||
                fabs(f->dev_m[i]) > 0.5 * g->m)
                return gs_diag_set(d, GS_ERANGE, field,
                                   "point %d: finite roll angle and deviation within half a "
                                   "module expected", i);
            if (i > 0 && !(f->dev_roll[i] > f->dev_roll[i - 1]))
                return gs_diag_set(d, GS_ERANGE, field,
                                   "roll angles must increase (point %d)", i);
        }
        /* The relieved flank must stay a flank: the tooth no thinner than
         * zero at its tip (a ring's tooth alike). */
        double psi_tip = gs_gear_modified_psi(g, m, s, g->ra);
        if (gs_gear_modified_psi(g, m, 1 - s, g->ra) + psi_tip <= 0.0) {
            snprintf(field, sizeof field, "%s%s", prefix, side[s]);
            return gs_diag_set(d, GS_EGEOMETRY, field, "the modifications leave no tooth tip");
        }
    }
    char field[160];
    if (m->n_pitch != 0) {
        snprintf(field, sizeof field, "%s.pitch_errors_um", prefix_body);
        if (m->n_pitch != g->z)
            return gs_diag_set(d, GS_ERANGE, field, "one value per tooth: %d expected, got %d",
                               g->z, m->n_pitch);
        for (int k = 0; k < m->n_pitch; k++)
            if (!isfinite(m->pitch_m[k]) || fabs(m->pitch_m[k]) > 0.1 * g->m)
                return gs_diag_set(d, GS_ERANGE, field,
                                   "tooth %d: %g um beyond a tenth of the module (%g um)", k,
                                   m->pitch_m[k] * 1e6, 0.1 * g->m * 1e6);
    }
    snprintf(field, sizeof field, "%s.runout", prefix_body);
    if (!isfinite(m->runout_m) || m->runout_m < 0.0 || m->runout_m > 0.1 * g->m ||
        !isfinite(m->runout_phase))
        return gs_diag_set(d, GS_ERANGE, field,
                           "eccentricity 0 to a tenth of the module (%g um), finite phase",
                           0.1 * g->m * 1e6);
    return GS_OK;
}
