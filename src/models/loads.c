/* SPDX-License-Identifier: MIT
 * The loads on a body at a time: constant, ramped and tabulated moments and
 * the speed-proportional brake of the scene's loads (gearsim/models.h,
 * gs_model_loads). */
#include "gearsim/models.h"

static double load_moment(const gs_scene_load *l, double t)
{
    switch (l->type) {
    case GS_LOAD_CONSTANT:
        return l->moment;
    case GS_LOAD_RAMP:
        return t >= l->ramp_time ? l->moment : l->moment * t / l->ramp_time;
    case GS_LOAD_TABLE: {
        int n = l->n_table;
        if (t <= l->times[0])
            return l->moments[0];
        if (t >= l->times[n - 1])
            return l->moments[n - 1];
        int lo = 0, hi = n - 1;
        while (hi - lo > 1) {
            int mid = (lo + hi) / 2;
            if (l->times[mid] <= t)
                lo = mid;
            else
                hi = mid;
        }
        double u = (t - l->times[lo]) / (l->times[hi] - l->times[lo]);
        return l->moments[lo] + u * (l->moments[hi] - l->moments[lo]);
    }
    case GS_LOAD_BRAKE:
        return 0.0;
    }
    return 0.0;
}

void gs_model_loads(const gs_scene_load *loads, int n, int body, double t, double *moment, double *brake)
{
    double M = 0, c = 0;
    for (int i = 0; i < n; i++) {
        const gs_scene_load *l = &loads[i];
        if (l->body != body)
            continue;
        if (l->type == GS_LOAD_BRAKE)
            c += l->coefficient;
        else
            M += load_moment(l, t);
    }
    *moment = M;
    *brake = c;
}
