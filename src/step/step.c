/* SPDX-License-Identifier: MIT
 * The midpoint (energy-momentum) step of METHOD.md section 2 on the rigid
 * coordinates: each body gives H d - rhs = f (src/models), the meshes give
 * equality rows and discrete-gradient forces, and rank 0 solves
 *
 *     H dq - rhs + g(dq) = G^T lambda,     G dq = 0
 *
 * by Newton's method on the small KKT system (LAPACK, dense). The discrete
 * gradient makes the energy identity exact for the converged increment, so
 * the balance residual is the Newton residual times dq: round-off. */
#include <lapacke.h>
#include <math.h>
#include <string.h>

#include "gearsim/step.h"

void gs_step_records(const gs_system *sys, double *rec)
{
    for (int i = 0; i < sys->n_bodies; i++) {
        const gs_body_rt *b = &sys->bodies[i];
        rec[2 * i] = rec[2 * i + 1] = 0.0;
        if (b->coord < 0 || b->owner != sys->rank)
            continue;
        b->ops->interface(sys, b, sys->h, &rec[2 * i], &rec[2 * i + 1]);
    }
}

int gs_step_solution_size(const gs_system *sys)
{
    return sys->n_coords + 1 + sys->n_meshes;
}

static double maxabs(const double *x, int n)
{
    double m = 0;
    for (int i = 0; i < n; i++)
        m = fmax(m, fabs(x[i]));
    return m;
}

/* Residual F = -(H dq - rhs + g(dq) - G^T lambda; G dq) and the mesh
 * Jacobian J at (dq, lambda); returns max |F| over the momentum rows and its
 * scale. Mesh dissipation and forces go to out[n], out[n+1+i]. */
static double residual(gs_system *sys, const double *H, const double *rhs, const double *dq,
                       const double *lambda, double *g, double *J, double *F, double *out,
                       double *scale)
{
    int n = sys->n_coords, m = sys->n_eq;
    memset(g, 0, (size_t)n * sizeof(double));
    memset(J, 0, (size_t)n * n * sizeof(double));
    double diss = 0;
    for (int i = 0; i < sys->n_meshes; i++) {
        gs_gmesh_rt *me = &sys->meshes[i];
        double dd, f;
        me->ops->force(sys, me, sys->q, dq, sys->h, g, J, &dd, &f);
        diss += dd;
        out[n + 1 + i] = f;
    }
    out[n] = diss;
    double sc = 1e-300;
    for (int i = 0; i < n; i++) {
        double gl = 0;
        for (int a = 0; a < m; a++)
            gl += sys->eq_rows[(size_t)a * n + i] * lambda[a];
        F[i] = -(H[i] * dq[i] - rhs[i] + g[i] - gl);
        sc = fmax(sc, fmax(fabs(H[i] * dq[i]), fmax(fabs(rhs[i]), fabs(g[i]))));
    }
    for (int a = 0; a < m; a++) {
        double v = 0;
        for (int i = 0; i < n; i++)
            v += sys->eq_rows[(size_t)a * n + i] * dq[i];
        F[n + a] = -v;
    }
    *scale = sc;
    return maxabs(F, n);
}

gs_err gs_step_solve(gs_system *sys, const double *rec, double *out)
{
    int n = sys->n_coords, m = sys->n_eq, k = n + m;
    double *H = sys->work;            /* n: diagonal of the bodies' H */
    double *rhs = H + n;              /* n */
    double *dq = rhs + n;             /* n */
    double *g = dq + n;               /* n */
    double *F = g + n;                /* k: Newton right-hand side */
    double *J = F + k;                /* n*n: mesh Jacobian */
    double *K = J + n * n;            /* k*k: KKT matrix */
    double *trial = K + k * k;        /* k: trial dq and lambda */
    double *Ft = trial + k;           /* k */
    lapack_int *piv = (lapack_int *)(Ft + k);
    double lambda[512];
    if (m > 512)
        return GS_ETOOBIG;
    for (int i = 0; i < n; i++)
        H[i] = rhs[i] = 0.0;
    for (int i = 0; i < sys->n_bodies; i++) {
        int c = sys->bodies[i].coord;
        if (c < 0)
            continue;
        H[c] += rec[2 * i];
        rhs[c] += rec[2 * i + 1];
    }
    /* Start from the free motion of each body: deterministic, no hidden state. */
    for (int i = 0; i < n; i++)
        dq[i] = rhs[i] / H[i];
    for (int i = 0; i < m; i++)
        lambda[i] = 0.0;
    bool nonlinear = false;
    for (int i = 0; i < sys->n_meshes; i++)
        nonlinear |= sys->meshes[i].ops->n_eq == 0;
    double scale;
    double fres = residual(sys, H, rhs, dq, lambda, g, J, F, out, &scale);
    int it;
    gs_err status = GS_ENOCONV;
    bool small_step = false;
    for (it = 0; it < sys->scene->max_newton; it++) {
        /* Converged: a linear problem after its one solve, or a residual at
         * the tolerance, or a Newton update that no longer changes dq. */
        if (it > 0 && (!nonlinear || fres <= sys->scene->newton_tol * scale || small_step)) {
            status = GS_OK;
            break;
        }
        memset(K, 0, (size_t)k * k * sizeof(double));
        for (int i = 0; i < n; i++) {
            K[i * k + i] = H[i];
            for (int j = 0; j < n; j++)
                K[i * k + j] += J[i * n + j];
            for (int a = 0; a < m; a++) {
                double v = sys->eq_rows[(size_t)a * n + i];
                K[i * k + n + a] = -v;
                K[(n + a) * k + i] = v;
            }
        }
        if (LAPACKE_dgesv(LAPACK_ROW_MAJOR, k, 1, K, k, piv, F, 1) != 0)
            return GS_ESINGULAR;
        /* Backtracking on the residual: the discrete gradient is only
         * piecewise smooth (backlash, stiffness transitions). */
        double t = 1.0, ft = 0, st = 0;
        for (int ls = 0; ls < 30; ls++) {
            for (int i = 0; i < k; i++)
                trial[i] = (i < n ? dq[i] : lambda[i - n]) + t * F[i];
            ft = residual(sys, H, rhs, trial, trial + n, g, J, Ft, out, &st);
            if (ft < fres || ft <= sys->scene->newton_tol * st || !nonlinear)
                break;
            t *= 0.5;
        }
        small_step = t * maxabs(F, n) <= 1e-15 * maxabs(trial, n);
        memcpy(dq, trial, (size_t)n * sizeof(double));
        memcpy(lambda, trial + n, (size_t)m * sizeof(double));
        memcpy(F, Ft, (size_t)k * sizeof(double));
        fres = ft;
        scale = st;
    }
    sys->last_iterations = it;
    sys->last_residual = fres / scale;
    if (status != GS_OK)
        return status;
    memcpy(out, dq, (size_t)n * sizeof(double));
    for (int i = 0, a = 0; i < sys->n_meshes; i++)
        if (sys->meshes[i].ops->n_eq == 1)
            out[n + 1 + i] = lambda[a++];
    return GS_OK;
}

void gs_step_apply(gs_system *sys, const double *sol)
{
    int n = sys->n_coords;
    double h = sys->h, tm = sys->time + 0.5 * h;
    for (int i = 0; i < sys->n_bodies; i++) {
        int c = sys->bodies[i].coord;
        if (c < 0)
            continue;
        double M, cb, d = sol[c];
        gs_system_body_load(sys, i, tm, &M, &cb);
        sys->work_in += M * d;
        sys->dissipated += cb * d * d / h;
    }
    sys->dissipated += sol[n];
    for (int i = 0; i < n; i++) {
        sys->w[i] = 2.0 * sol[i] / h - sys->w[i];
        sys->q[i] += sol[i];
    }
    for (int i = 0; i < sys->n_meshes; i++) {
        gs_gmesh_rt *me = &sys->meshes[i];
        double s = 0;
        for (int j = 0; j < n; j++)
            s += me->a[j] * sys->q[j];
        me->deflection = s - me->s_ref;
        me->force = sol[n + 1 + i];
    }
    sys->step++;
    sys->time += h;
}

gs_err gs_step_serial(gs_system *sys)
{
    double rec[2 * 64];
    double sol[64 + 1 + 256];
    if (sys->n_bodies > 64 || gs_step_solution_size(sys) > (int)(sizeof sol / sizeof sol[0]))
        return GS_ETOOBIG;
    /* In one process this rank plays every owner. */
    for (int i = 0; i < sys->n_bodies; i++) {
        const gs_body_rt *b = &sys->bodies[i];
        rec[2 * i] = rec[2 * i + 1] = 0.0;
        if (b->coord >= 0)
            b->ops->interface(sys, b, sys->h, &rec[2 * i], &rec[2 * i + 1]);
    }
    GS_TRY(gs_step_solve(sys, rec, sol));
    gs_step_apply(sys, sol);
    return GS_OK;
}
