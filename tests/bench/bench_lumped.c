/* SPDX-License-Identifier: MIT
 * Benchmark of the rigid lumped planetary step alone (no service): steps per
 * second on one rank for the builtin `planetary` (sun, three planets on a
 * carrier, held ring, six lumped meshes: 5 coordinates) and
 * `planetary_floating` (sun on a bearing joint: 7 coordinates), against two
 * references timed in the same run:
 *  - hand: a tight hand-written loop of the same arithmetic (below; the
 *    train with lumped meshes on fixed axes only, so `planetary`), started
 *    from the same state; its trajectory is compared with the library's;
 *  - dgesv: one LAPACKE dgesv of the step's k x k system.
 * Prints a table with the ratios step / hand and step / dgesv; not a test.
 * Times are process CPU seconds (the machine is shared: wall time counts
 * other jobs' slices), the best of 9 interleaved batches of step and hand
 * loop. Run with OPENBLAS_NUM_THREADS=1:
 *     meson test -C build --benchmark --suite bench lumped
 *     build/tests/bench/bench_lumped [steps] */
#include <lapacke.h>
#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/step.h"
#include "gearsim/util.h"

static gs_system *build(const char *name)
{
    const char *txt = gs_scene_builtin(name);
    gs_scene *sc;
    gs_diag d;
    if (gs_scene_parse(txt, strlen(txt), &sc, &d) != GS_OK) {
        fprintf(stderr, "%s: %s\n", d.field, d.message);
        exit(1);
    }
    gs_system *s;
    if (gs_system_new(sc, 0, 1, &s, &d) != GS_OK) {
        fprintf(stderr, "%s: %s\n", d.field, d.message);
        exit(1);
    }
    return s;
}

static double time_solve(int k, int reps)
{
    double *A = malloc(sizeof(double) * (size_t)k * k), *A0 = malloc(sizeof(double) * (size_t)k * k);
    double b[64];
    lapack_int piv[64];
    for (int i = 0; i < k; i++)
        for (int j = 0; j < k; j++)
            A0[i * k + j] = (i == j ? 2.0 : 0.0) + 1.0 / (1.0 + i + j);
    double best = 1e30;
    for (int batch = 0; batch < 3; batch++) {
        double t0 = gs_cpu_now();
        for (int r = 0; r < reps; r++) {
            memcpy(A, A0, sizeof(double) * (size_t)k * k);
            for (int i = 0; i < k; i++)
                b[i] = 1.0;
            LAPACKE_dgesv(LAPACK_ROW_MAJOR, k, 1, A, k, piv, b, 1);
        }
        double t = (gs_cpu_now() - t0) / reps;
        best = t < best ? t : best;
    }
    free(A), free(A0);
    return best;
}

/* The reference: a tight hand-written loop of the same arithmetic for a
 * rigid train whose meshes are all lumped rectangular-wave springs on fixed
 * axes (the builtin `planetary`): the rigid bodies' condensed compliance and
 * free increment (ramp and constant moments, implicit brake), the lumped
 * meshes' discrete-gradient force and Jacobian, the Newton iteration with
 * its backtracking on the residual and an inline LU of the k x k system,
 * the state update and the energy booking. Everything the library does
 * through its tables (plan, records, operations, diagnostics) is flattened
 * here into fixed arrays, so the ratio step / hand loop is the cost of the
 * library's generality. Its trajectory is checked against the library's. */
#define HN 8  /* coordinates */
#define HM 8  /* meshes */
typedef struct hand {
    int n, nm;
    double q[HN], w[HN], inertia[HN], M0[HN], ramp[HN], brake[HN];
    int ramped[HN];
    double a[HM][HN], c[HM][HN], s_ref[HM], ks[HM], kd[HM], e1[HM], tr[HM], hb[HM], damp[HM];
    double h, tol, work_in, dissipated, force[HM], defl[HM];
    int max_newton;
    long long step;
} hand;

static int hand_init(const gs_system *s, hand *H)
{
    memset(H, 0, sizeof *H);
    H->n = s->n_coords;
    H->nm = s->n_meshes;
    if (H->n > HN || H->nm > HM || s->n_eq || s->adapt_levels || s->smooth_contact)
        return 1;
    for (int i = 0; i < s->n_bodies; i++) {
        const gs_body_rt *b = &s->bodies[i];
        if (b->tcoord >= 0 || b->ops->state_size)
            return 1;
        if (b->coord < 0)
            continue;
        H->inertia[b->coord] = b->inertia_eff;
        for (int l = 0; l < s->scene->n_loads; l++) {
            const gs_scene_load *ld = &s->scene->loads[l];
            if (ld->body != i)
                continue;
            if (ld->type == GS_LOAD_BRAKE) {
                H->brake[b->coord] += ld->coefficient;
            } else if (ld->type == GS_LOAD_RAMP || ld->type == GS_LOAD_CONSTANT) {
                if (H->M0[b->coord] != 0)
                    return 1;
                H->M0[b->coord] = ld->moment;
                H->ramped[b->coord] = ld->type == GS_LOAD_RAMP;
                H->ramp[b->coord] = ld->ramp_time;
            } else {
                return 1;
            }
        }
    }
    for (int k = 0; k < H->nm; k++) {
        const gs_gmesh_rt *m = &s->meshes[k];
        if (strcmp(m->ops->name, "lumped") || m->k_table || m->n_tr || m->n_err || m->contact ||
            m->overlap_ratio > 0)
            return 1;
        memcpy(H->a[k], m->a, sizeof(double) * (size_t)H->n);
        memcpy(H->c[k], m->c, sizeof(double) * (size_t)H->n);
        H->s_ref[k] = m->s_ref;
        H->ks[k] = m->k_single;
        H->kd[k] = m->k_double;
        H->e1[k] = m->contact_ratio - 1.0;
        H->tr[k] = m->transition;
        H->hb[k] = m->half_backlash;
        H->damp[k] = m->damping;
    }
    memcpy(H->q, s->q, sizeof(double) * (size_t)H->n);
    memcpy(H->w, s->w, sizeof(double) * (size_t)H->n);
    H->h = s->h;
    H->step = s->step;
    H->tol = s->newton_tol;
    H->max_newton = s->max_newton;
    H->work_in = s->work_in;
    H->dissipated = s->dissipated;
    return 0;
}

static inline double hk(const hand *H, int k, double phi, double *dk)
{
    double e1 = H->e1[k], dlt = H->tr[k], ks = H->ks[k], kd = H->kd[k];
    *dk = 0.0;
    if (kd == ks || e1 <= 0.0)
        return ks;
    if (e1 >= 1.0)
        return kd;
    double f = phi - floor(phi), w, dw = 0.0;
    if (f < 0.5 * dlt)
        w = 0.5 + f / dlt, dw = 1.0 / dlt;
    else if (f < e1 - 0.5 * dlt)
        w = 1.0;
    else if (f < e1 + 0.5 * dlt)
        w = 0.5 - (f - e1) / dlt, dw = -1.0 / dlt;
    else if (f < 1.0 - 0.5 * dlt)
        w = 0.0;
    else
        w = 0.5 + (f - 1.0) / dlt, dw = 1.0 / dlt;
    *dk = (kd - ks) * dw;
    return ks + (kd - ks) * w;
}

static inline double hmax(double a, double b)
{
    return b > a || a != a ? b : a;
}

static inline double hdead(double x, double hb)
{
    return x > hb ? x - hb : (x < -hb ? x + hb : 0.0);
}

/* Residual and Jacobian at dq; returns max |F|, its scale in *sc, the
 * meshes' dissipation in *diss. */
static double hand_res(hand *H, const double *C, const double *d0, const double *dq, double *F, double *J,
                       double *sc, double *diss)
{
    int n = H->n;
    double g[HN] = {0};
    memset(J, 0, sizeof(double) * (size_t)n * n);
    *diss = 0;
    for (int k = 0; k < H->nm; k++) {
        const double *a = H->a[k], *c = H->c[k];
        double s0 = -H->s_ref[k], ds = 0, p0 = 0, dp = 0;
        for (int i = 0; i < n; i++) {
            s0 += a[i] * H->q[i];
            ds += a[i] * dq[i];
            p0 += c[i] * H->q[i];
            dp += c[i] * dq[i];
        }
        double s1 = s0 + ds, hb = H->hb[k], f0 = hdead(s0, hb), f1 = hdead(s1, hb), dk0, dk1;
        double k0 = hk(H, k, p0, &dk0), k1 = hk(H, k, p0 + dp, &dk1), kbar = 0.5 * (k0 + k1), dfs;
        bool same = (s0 > hb && s1 > hb) || (s0 < -hb && s1 < -hb);
        if (same)
            dfs = 0.5 * (f0 + f1);
        else if (ds != 0.0)
            dfs = (f1 * f1 - f0 * f0) / (2.0 * ds);
        else
            dfs = f0;
        double gs = kbar * dfs, Q = 0.25 * (f0 * f0 + f1 * f1), gp, jpp;
        if (dp != 0.0) {
            gp = Q * (k1 - k0) / dp;
            jpp = Q * (dk1 * dp - (k1 - k0)) / (dp * dp);
        } else {
            gp = Q * dk0;
            jpp = 0.0;
        }
        double cd = fabs(s0 + 0.5 * ds) > hb ? H->damp[k] : 0.0, fd = cd * ds / H->h;
        for (int i = 0; i < n; i++)
            g[i] += a[i] * (gs + fd) + c[i] * gp;
        double jss = (f0 != 0.0 || f1 != 0.0 ? 0.5 * kbar : 0.0) + cd / H->h;
        double jsp = 0.5 * dk1 * dfs;
        double jps = dp != 0.0 ? 0.5 * f1 * (f1 != 0.0 ? 1.0 : 0.0) * (k1 - k0) / dp : 0.5 * f1 * dk0;
        for (int i = 0; i < n; i++) {
            if (a[i] == 0.0 && c[i] == 0.0)
                continue;
            for (int j = 0; j < n; j++)
                J[i * n + j] += a[i] * (jss * a[j] + jsp * c[j]) + c[i] * (jps * a[j] + jpp * c[j]);
        }
        *diss += fd * ds;
        H->force[k] = gs + fd;
    }
    double s = 1e-300, mx = 0;
    for (int i = 0; i < n; i++) {
        F[i] = -(dq[i] - d0[i] + C[i] * g[i]);
        s = hmax(s, hmax(fabs(dq[i]), hmax(fabs(d0[i]), fabs(C[i] * g[i]))));
        mx = hmax(mx, fabs(F[i]));
    }
    *sc = s;
    return mx;
}

static int hand_step(hand *H)
{
    int n = H->n;
    double C[HN], d0[HN], dq[HN], F[HN], Ft[HN], J[HN * HN], K[HN * HN], trial[HN], Mh[HN];
    double h = H->h, tm = (double)H->step * h + 0.5 * h;
    for (int i = 0; i < n; i++) {
        double M = H->ramped[i] && tm < H->ramp[i] ? H->M0[i] * tm / H->ramp[i] : H->M0[i];
        double Hh = 2.0 / (h * h) * H->inertia[i] + H->brake[i] / h;
        C[i] = 1.0 / Hh;
        d0[i] = (2.0 / h * H->inertia[i] * H->w[i] + M) / Hh;
        dq[i] = d0[i];
        Mh[i] = M;
    }
    double sc, st = 0, diss, dt = 0;
    double fres = hand_res(H, C, d0, dq, F, J, &sc, &diss);
    int it;
    bool small = false, ok = false;
    for (it = 0; it < H->max_newton; it++) {
        if (it > 0 && (fres <= H->tol * sc || small)) {
            ok = true;
            break;
        }
        for (int i = 0; i < n; i++)
            for (int j = 0; j < n; j++)
                K[i * n + j] = (i == j ? 1.0 : 0.0) + C[i] * J[i * n + j];
        /* inline LU, partial pivoting */
        for (int c = 0; c < n; c++) {
            int p = c;
            double big = fabs(K[c * n + c]);
            for (int r = c + 1; r < n; r++)
                if (fabs(K[r * n + c]) > big)
                    big = fabs(K[r * n + c]), p = r;
            if (!(big > 0.0))
                return 1;
            if (p != c) {
                for (int j = c; j < n; j++) {
                    double t = K[c * n + j];
                    K[c * n + j] = K[p * n + j];
                    K[p * n + j] = t;
                }
                double t = F[c];
                F[c] = F[p];
                F[p] = t;
            }
            double inv = 1.0 / K[c * n + c];
            for (int r = c + 1; r < n; r++) {
                double f = K[r * n + c] * inv;
                for (int j = c + 1; j < n; j++)
                    K[r * n + j] -= f * K[c * n + j];
                F[r] -= f * F[c];
            }
        }
        for (int r = n - 1; r >= 0; r--) {
            double v = F[r];
            for (int j = r + 1; j < n; j++)
                v -= K[r * n + j] * F[j];
            F[r] = v / K[r * n + r];
        }
        double t = 1.0, ft = 0, mf = 0, mt = 0;
        for (int ls = 0; ls < 30; ls++) {
            for (int i = 0; i < n; i++)
                trial[i] = dq[i] + t * F[i];
            ft = hand_res(H, C, d0, trial, Ft, J, &st, &dt);
            if (ft < fres || ft <= H->tol * st)
                break;
            t *= 0.5;
        }
        for (int i = 0; i < n; i++)
            mf = hmax(mf, fabs(F[i])), mt = hmax(mt, fabs(trial[i]));
        small = t * mf <= 1e-15 * mt;
        memcpy(dq, trial, sizeof(double) * (size_t)n);
        memcpy(F, Ft, sizeof(double) * (size_t)n);
        fres = ft;
        sc = st;
        diss = dt;
    }
    if (!ok)
        return 1;
    for (int i = 0; i < n; i++) {
        H->work_in += Mh[i] * dq[i];
        H->dissipated += H->brake[i] * dq[i] * dq[i] / h;
    }
    H->dissipated += diss;
    for (int i = 0; i < n; i++) {
        H->w[i] = 2.0 * dq[i] / h - H->w[i];
        H->q[i] += dq[i];
    }
    for (int k = 0; k < H->nm; k++) {
        double s = -H->s_ref[k];
        for (int i = 0; i < n; i++)
            s += H->a[k][i] * H->q[i];
        H->defl[k] = s;
    }
    H->step++;
    return 0;
}

#define BATCHES 9

int main(int argc, char **argv)
{
    int steps = argc > 1 ? atoi(argv[1]) : 20000;
    const char *env = getenv("OPENBLAS_NUM_THREADS");
    double la[3] = {0, 0, 0};
    FILE *lf = fopen("/proc/loadavg", "r");
    if (lf) {
        if (fscanf(lf, "%lf %lf %lf", &la[0], &la[1], &la[2]) != 3)
            la[0] = -1;
        fclose(lf);
    }
    printf("# rigid lumped planetary step alone, one rank, CPU time, best of %d interleaved batches of %d steps "
           "(OPENBLAS_NUM_THREADS=%s, load average %.2f)\n", BATCHES, steps, env ? env : "unset", la[0]);
    printf("%-20s %6s %12s %10s %10s %10s %10s %10s %12s %10s\n", "scene", "coords", "steps/s", "us/step",
           "iter/step", "hand us", "step/hand", "hand dev", "dgesv us", "step/solve");
    const char *names[] = {"planetary", "planetary_floating"};
    int only = getenv("BENCH_ONLY") ? atoi(getenv("BENCH_ONLY")) : -1;
    for (int k = 0; k < 2; k++) {
        if (only >= 0 && k != only)
            continue;
        gs_system *s = build(names[k]);
        for (int i = 0; i < 3000; i++) /* past the ramp's start */
            gs_step_serial(s);
        /* The hand loop from the same state: the same trajectory (largest
         * difference of the angles over 2000 steps, relative to their
         * largest increment over them). */
        hand H;
        bool have_hand = hand_init(s, &H) == 0;
        double dev = NAN;
        if (have_hand) {
            double q0[HN], qmax = 0, dmax = 0;
            memcpy(q0, s->q, sizeof(double) * (size_t)H.n);
            for (int i = 0; i < 2000; i++) {
                if (gs_step_serial(s) != GS_OK || hand_step(&H) != 0) {
                    fprintf(stderr, "%s: step failed\n", names[k]);
                    return 1;
                }
                for (int c = 0; c < H.n; c++) {
                    qmax = fmax(qmax, fabs(s->q[c] - q0[c]));
                    dmax = fmax(dmax, fabs(s->q[c] - H.q[c]));
                }
            }
            dev = dmax / qmax;
        }
        double best = 1e30, hbest = 1e30, iters = 0;
        for (int batch = 0; batch < BATCHES; batch++) {
            long it = 0;
            double t0 = gs_cpu_now();
            for (int i = 0; i < steps; i++) {
                if (gs_step_serial(s) != GS_OK) {
                    fprintf(stderr, "%s: step failed\n", names[k]);
                    return 1;
                }
                it += s->last_iterations;
            }
            double t = (gs_cpu_now() - t0) / steps;
            best = t < best ? t : best;
            iters = (double)it / steps;
            if (!have_hand)
                continue;
            t0 = gs_cpu_now();
            for (int i = 0; i < steps; i++)
                if (hand_step(&H) != 0) {
                    fprintf(stderr, "%s: hand step failed\n", names[k]);
                    return 1;
                }
            t = (gs_cpu_now() - t0) / steps;
            hbest = t < hbest ? t : hbest;
        }
        double ts = time_solve(s->n_coords + s->n_eq, getenv("BENCH_NOSOLVE") ? 10 : 200000);
        if (have_hand)
            printf("%-20s %6d %12.0f %10.3f %10.2f %10.3f %10.2f %10.1e %12.3f %10.1f\n", names[k], s->n_coords,
                   1.0 / best, best * 1e6, iters, hbest * 1e6, best / hbest, dev, ts * 1e6, best / ts);
        else
            printf("%-20s %6d %12.0f %10.3f %10.2f %10s %10s %10s %12.3f %10.1f\n", names[k], s->n_coords,
                   1.0 / best, best * 1e6, iters, "-", "-", "-", ts * 1e6, best / ts);
        gs_system_free(&s);
    }
    return 0;
}
