/* SPDX-License-Identifier: MIT
 * The midpoint (energy-momentum) step of METHOD.md section 2 on the rigid
 * coordinates: each body gives its condensed compliance C and free
 * increment d0, d = d0 + C f (src/models), the meshes give equality rows and
 * discrete-gradient forces, and rank 0 solves
 *
 *     dq - d0 + C (g(dq) - G^T lambda) = 0,     G dq = 0
 *
 * (the compliance form: a body that nothing touches keeps its free
 * increment bit for bit, and its interface force (dq - d0)/C is exactly 0)
 * by Newton's method on the small KKT system (LAPACK, dense). The discrete
 * gradient makes the energy identity exact for the converged increment, so
 * the balance residual is the Newton residual times dq: round-off. */
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/step.h"
#include "gearsim/util.h"
#include "contact/contact_mesh.h"
#include "step_internal.h"

/* Bodies that give their record in two phases (models.h): the free part
 * first, then only the compliance entries the solve reads. */
static bool two_phase(const gs_system *sys, const gs_body_rt *b)
{
    /* Without contact meshes the solve reads every entry (the coordinates'):
     * the whole records in one exchange. */
    return sys->n_contact > 0 && b->ops->interface_free && b->ops->compliance;
}

/* Records of the bodies this rank owns (every body when `all`); the
 * others' blocks are zero so that a sum over ranks assembles them. A
 * two-phase body writes its free part only (gs_step_compliance follows). */
static void records(gs_system *sys, double *rec, bool all)
{
    /* Zero every block but those an elastic body of this rank overwrites
     * (compliance, free increment, node displacements): megabytes per
     * step for a planetary train in contact. */
    const gs_step_plan *p = &sys->plan;
    size_t end = 0;
    for (int i = 0; i < sys->n_bodies; i++) {
        const gs_body_rt *b = &sys->bodies[i];
        size_t nd = (size_t)p->n_dof[i], len = nd * nd + nd + 2 * (size_t)p->n_nodes[i];
        if (!((all || b->owner == sys->rank) && b->ops->state_size && nd > 0))
            memset(rec + p->rec_off[i], 0, len * sizeof(double));
        end = p->rec_off[i] + len;
    }
    if (p->rec_size > end)
        memset(rec + end, 0, (p->rec_size - end) * sizeof(double));
    /* Body order one substep, the reverse the next: the factor an elastic
     * body solved last is solved first again, with only the contact and the
     * end-of-step passes between, while it is still in cache (two gears'
     * factors on one rank are about twice the share of L3 that one keeps;
     * in body order every step, each was evicted before its next solve;
     * docs/performance/index.md). The bodies are independent here,
     * so the records are the same bit for bit. */
    const bool back = sys->substeps & 1;
    gs_model_view v;
    gs_system_view(sys, &v);
    for (int k = 0; k < sys->n_bodies; k++) {
        int i = back ? sys->n_bodies - 1 - k : k;
        gs_body_rt *b = &sys->bodies[i];
        if (!all && b->owner != sys->rank)
            continue;
        /* Bodies with their own state (elastic) are timed for the balance of
         * ranks; a rigid body's interface is a few flops, and two clock reads
         * per rigid body were a sixth of the lumped planetary's step
         * (tests/bench/bench_lumped.c). */
        if (!b->ops->state_size) {
            b->ops->interface(&v, b, sys->h_sub, rec + sys->plan.rec_off[i]);
            continue;
        }
        double t0 = gs_now();
        if (two_phase(sys, b))
            b->ops->interface_free(&v, b, sys->h_sub, rec + sys->plan.rec_off[i]);
        else
            b->ops->interface(&v, b, sys->h_sub, rec + sys->plan.rec_off[i]);
        b->work_s += gs_now() - t0;
    }
}

/* The part of body i's record that travels in phase one: offset in its
 * record and length (the free part of a two-phase body, else all). */
static void free_part(const gs_system *sys, int i, size_t *off, size_t *len)
{
    const gs_step_plan *p = &sys->plan;
    size_t nd = (size_t)p->n_dof[i], c = nd * nd;
    *off = two_phase(sys, &sys->bodies[i]) ? c : 0;
    *len = c + nd + 2 * (size_t)p->n_nodes[i] - *off;
}

size_t gs_step_free_size(const gs_system *sys)
{
    size_t n = 0;
    for (int i = 0; i < sys->n_bodies; i++) {
        size_t off, len;
        free_part(sys, i, &off, &len);
        n += len;
    }
    return n ? n : 1;
}

void gs_step_free_pack(const gs_system *sys, double *rec, double *buf, bool unpack)
{
    for (int i = 0; i < sys->n_bodies; i++) {
        size_t off, len;
        free_part(sys, i, &off, &len);
        double *r = rec + sys->plan.rec_off[i] + off;
        if (unpack)
            memcpy(r, buf, len * sizeof(double));
        else
            memcpy(buf, r, len * sizeof(double));
        buf += len;
    }
}

bool gs_step_two_phase(const gs_system *sys)
{
    for (int i = 0; i < sys->n_bodies; i++)
        if (two_phase(sys, &sys->bodies[i]) && sys->plan.n_dof[i] > 0)
            return true;
    return false;
}

int *gs_step_mask(gs_system *sys)
{
    int *m = gs_grow(sys->rec_mask, &sys->cap_mask, gs_step_mask_size(sys), sizeof(int));
    if (m)
        sys->rec_mask = m;
    return m;
}

size_t gs_step_mask_size(const gs_system *sys)
{
    size_t n = 0;
    for (int i = 0; i < sys->n_bodies; i++)
        n += (size_t)sys->plan.n_dof[i];
    return n + 1;
}

gs_err gs_step_select(gs_system *sys, const double *rec, int *mask)
{
    const gs_step_plan *p = &sys->plan;
    size_t total = gs_step_mask_size(sys) - 1;
    for (int i = 0; i < sys->n_bodies; i++) {
        size_t nd = (size_t)p->n_dof[i];
        /* A two-phase body that could not begin its step says so in d0[0]. */
        if (nd > 0 && two_phase(sys, &sys->bodies[i]) && !isfinite(rec[p->rec_off[i] + nd * nd]))
            return GS_ESINGULAR;
    }
    if (sys->n_contact > 0)
        return gsi_contact_select(sys, rec, mask);
    for (size_t a = 0; a < total; a++)
        mask[a] = 1;
    return GS_OK;
}

size_t gs_step_compliance_size(const gs_system *sys, const int *mask)
{
    size_t n = 0;
    for (int i = 0; i < sys->n_bodies; i++) {
        size_t k = 0;
        for (int a = 0; a < sys->plan.n_dof[i]; a++)
            k += mask[a] != 0;
        if (two_phase(sys, &sys->bodies[i]))
            n += k * k;
        mask += sys->plan.n_dof[i];
    }
    return n ? n : 1;
}

/* The selected dofs of body i (mask at its plan dofs) into sel; their count. */
static int selected(const gs_system *sys, int i, const int *mask, int *sel)
{
    int k = 0;
    for (int a = 0; a < sys->plan.n_dof[i]; a++)
        if (mask[a])
            sel[k++] = a;
    return k;
}

static gs_err compliance(gs_system *sys, const int *mask, double *buf, double *rec, bool all)
{
    const gs_step_plan *p = &sys->plan;
    int maxdof = 1;
    for (int i = 0; i < sys->n_bodies; i++)
        maxdof = p->n_dof[i] > maxdof ? p->n_dof[i] : maxdof;
    int *sel = gs_grow(sys->rec_sel, &sys->cap_sel, (size_t)maxdof, sizeof(int));
    if (!sel)
        return GS_ENOMEM;
    sys->rec_sel = sel;
    gs_model_view v;
    gs_system_view(sys, &v);
    for (int i = 0; i < sys->n_bodies; i++) {
        gs_body_rt *b = &sys->bodies[i];
        int nd = p->n_dof[i];
        int k = selected(sys, i, mask, sel);
        mask += nd;
        if (!two_phase(sys, b))
            continue;
        size_t kk = (size_t)k * (size_t)k;
        if (rec) { /* rank 0: into the record's C block */
            double *C = rec + p->rec_off[i];
            for (int c = 0; c < k; c++)
                for (int r = 0; r < k; r++)
                    C[(size_t)sel[c] * nd + sel[r]] = buf[r + (size_t)c * k];
        } else if (all || b->owner == sys->rank) {
            double t0 = gs_now();
            b->ops->compliance(&v, b, k, sel, buf);
            b->work_s += gs_now() - t0;
        } else {
            memset(buf, 0, kk * sizeof(double));
        }
        buf += kk;
    }
    return GS_OK;
}

gs_err gs_step_compliance(gs_system *sys, const int *mask, double *buf)
{
    return compliance(sys, mask, buf, NULL, false);
}

gs_err gs_step_compliance_unpack(gs_system *sys, const int *mask, const double *buf, double *rec)
{
    return compliance(sys, mask, (double *)buf, rec, false);
}

void gs_step_records(gs_system *sys, double *rec)
{
    records(sys, rec, false);
}

/* fmax(a, b) inline (the library call was a twentieth of the lumped
 * planetary's step, tests/bench/bench_lumped.c): b when a is NaN, a when b
 * is, else the larger. */
static inline double max2(double a, double b)
{
    return b > a || a != a ? b : a;
}

static double maxabs(const double *x, int n)
{
    double m = 0;
    for (int i = 0; i < n; i++)
        m = max2(m, fabs(x[i]));
    return m;
}

double gsi_mesh_forces(const gs_system *sys, const double *dq, double *g, double *J, double *force)
{
    int n = sys->n_coords;
    memset(g, 0, (size_t)n * sizeof(double));
    memset(J, 0, (size_t)n * n * sizeof(double));
    double diss = 0;
    gs_model_view v;
    gs_system_view(sys, &v);
    for (int i = 0; i < sys->n_meshes; i++) {
        const gs_gmesh_rt *me = &sys->meshes[i];
        if (!me->ops->force)
            continue;
        double dd, f;
        me->ops->force(&v, me, sys->q, dq, sys->h_sub, g, J, &dd, &f);
        diss += dd;
        force[i] = f;
    }
    for (int i = 0; i < sys->n_joints; i++) {
        double dd;
        sys->joints[i].ops->force(&v, &sys->joints[i], sys->q, dq, sys->h_sub, g, J, &dd);
        diss += dd;
    }
    return diss;
}

/* Residual F = -(dq - d0 + C (g(dq) - G^T lambda); G dq) and the mesh
 * Jacobian J at (dq, lambda); returns max |F| over the momentum rows and its
 * scale. Mesh dissipation and forces go to out[n], out[n+1+i]. */
static double residual(gs_system *sys, const double *C, const double *d0, const double *dq,
                       const double *lambda, double *g, double *J, double *F, double *out,
                       double *scale)
{
    int n = sys->n_coords, m = sys->n_eq;
    out[n] = gsi_mesh_forces(sys, dq, g, J, out + n + 1);
    double sc = 1e-300;
    for (int i = 0; i < n; i++) {
        double gl = 0;
        for (int a = 0; a < m; a++)
            gl += sys->eq_rows[(size_t)a * n + i] * lambda[a];
        F[i] = -(dq[i] - d0[i] + C[i] * (g[i] - gl));
        sc = max2(sc, max2(fabs(dq[i]), max2(fabs(d0[i]), fabs(C[i] * g[i]))));
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

/* Dense LU with partial pivoting of the small row-major k x k system A x = b
 * (b overwritten by x): the KKT systems of rigid trains are a few unknowns,
 * where LAPACKE's layout transposition and checks cost more than the
 * elimination (tests/bench/bench_lumped.c). Returns nonzero when singular. */
#define SMALL_SOLVE 24
static int small_solve(int k, double *A, double *b)
{
    for (int c = 0; c < k; c++) {
        int p = c;
        double big = fabs(A[c * k + c]);
        for (int r = c + 1; r < k; r++)
            if (fabs(A[r * k + c]) > big)
                big = fabs(A[r * k + c]), p = r;
        if (!(big > 0.0))
            return 1;
        if (p != c) {
            for (int j = c; j < k; j++) {
                double t = A[c * k + j];
                A[c * k + j] = A[p * k + j];
                A[p * k + j] = t;
            }
            double t = b[c];
            b[c] = b[p];
            b[p] = t;
        }
        double inv = 1.0 / A[c * k + c];
        for (int r = c + 1; r < k; r++) {
            double f = A[r * k + c] * inv;
            if (f == 0.0)
                continue;
            for (int j = c + 1; j < k; j++)
                A[r * k + j] -= f * A[c * k + j];
            b[r] -= f * b[c];
        }
    }
    for (int r = k - 1; r >= 0; r--) {
        double v = b[r];
        for (int j = r + 1; j < k; j++)
            v -= A[r * k + j] * b[j];
        b[r] = v / A[r * k + r];
    }
    return 0;
}

static gs_err newton_solve(gs_system *sys, const double *rec, double *out)
{
    int n = sys->n_coords, m = sys->n_eq, k = n + m;
    double *C = sys->work;            /* n: the bodies' compliances */
    double *d0 = C + n;               /* n: their free increments */
    double *dq = d0 + n;              /* n */
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
        C[i] = d0[i] = 0.0;
    for (int i = 0; i < sys->n_bodies; i++) {
        int c = sys->bodies[i].coord;
        if (c < 0)
            continue;
        /* A body that could not form its step reports a non-finite C. */
        const double *r = rec + sys->plan.rec_off[i];
        if (!(r[0] > 0) || !isfinite(r[0]) || !isfinite(r[1]))
            return GS_ESINGULAR;
        C[c] = r[0];
        d0[c] = r[1];
    }
    /* Translating centres (bearing joints): a free mass, 1/C = 2 m / h^2,
     * free increment h v; their supports act through the joints' forces. */
    for (int i = 0; i < sys->n_bodies; i++) {
        int tc = sys->bodies[i].tcoord;
        if (tc < 0)
            continue;
        double h = sys->h_sub, mass = sys->bodies[i].mass;
        for (int k = 0; k < 2; k++) {
            C[tc + k] = h * h / (2.0 * mass);
            d0[tc + k] = h * sys->w[tc + k];
        }
    }
    /* Start from the free motion of each body: deterministic, no hidden state. */
    for (int i = 0; i < n; i++)
        dq[i] = d0[i];
    for (int i = 0; i < m; i++)
        lambda[i] = 0.0;
    bool nonlinear = false;
    for (int i = 0; i < sys->n_meshes; i++)
        nonlinear |= sys->meshes[i].ops->n_eq == 0;
    double scale;
    double fres = residual(sys, C, d0, dq, lambda, g, J, F, out, &scale);
    int it;
    gs_err status = GS_ENOCONV;
    bool small_step = false;
    for (it = 0; it < sys->max_newton; it++) {
        /* Converged: a linear problem after its one solve, or a residual at
         * the tolerance, or a Newton update that no longer changes dq. */
        if (it > 0 && (!nonlinear || fres <= sys->newton_tol * scale || small_step)) {
            status = GS_OK;
            break;
        }
        memset(K, 0, (size_t)k * k * sizeof(double));
        for (int i = 0; i < n; i++) {
            K[i * k + i] = 1.0;
            for (int j = 0; j < n; j++)
                K[i * k + j] += C[i] * J[i * n + j];
            for (int a = 0; a < m; a++) {
                double v = sys->eq_rows[(size_t)a * n + i];
                K[i * k + n + a] = -C[i] * v;
                K[(n + a) * k + i] = v;
            }
        }
        if (k <= SMALL_SOLVE ? small_solve(k, K, F) != 0 : LAPACKE_dgesv(LAPACK_ROW_MAJOR, k, 1, K, k, piv, F, 1) != 0)
            return GS_ESINGULAR;
        /* Backtracking on the residual: the discrete gradient is only
         * piecewise smooth (backlash, stiffness transitions). */
        double t = 1.0, ft = 0, st = 0;
        for (int ls = 0; ls < 30; ls++) {
            for (int i = 0; i < k; i++)
                trial[i] = (i < n ? dq[i] : lambda[i - n]) + t * F[i];
            ft = residual(sys, C, d0, trial, trial + n, g, J, Ft, out, &st);
            if (ft < fres || ft <= sys->newton_tol * st || !nonlinear)
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
    /* Interface forces f = (d - d0) / C: exactly zero for a body nothing
     * touches, and the body lands exactly on d. */
    for (int i = 0; i < sys->n_bodies; i++) {
        int c = sys->bodies[i].coord;
        if (c >= 0)
            out[sys->plan.sol_off[i]] = (dq[c] - d0[c]) / C[c];
    }
    return GS_OK;
}

gs_err gs_step_solve(gs_system *sys, const double *rec, double *sol)
{
    memset(sol, 0, sys->plan.sol_size * sizeof(double));
    if (sys->n_contact > 0)
        return gsi_contact_solve(sys, rec, sol);
    return newton_solve(sys, rec, sol);
}

/* Finish the bodies' own steps (this rank's, or all when `all`). */
static gs_err finish(gs_system *sys, const double *sol, bool all)
{
    gs_err err = GS_OK;
    gs_model_view v;
    gs_system_view(sys, &v);
    for (int i = 0; i < sys->n_bodies; i++) {
        gs_body_rt *b = &sys->bodies[i];
        if ((!all && b->owner != sys->rank) || !b->ops->finish)
            continue;
        double t0 = gs_now();
        gs_err e = b->ops->finish(&v, b, sol + sys->plan.sol_off[i]);
        b->work_s += gs_now() - t0;
        if (err == GS_OK)
            err = e;
    }
    return err;
}

static gs_err apply(gs_system *sys, const double *sol, bool all)
{
    gs_err err = finish(sys, sol, all);
    int n = sys->n_coords;
    double h = sys->h_sub, tm = sys->time + 0.5 * h;
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
    gs_model_view v;
    gs_system_view(sys, &v);
    for (int i = 0; i < sys->n_meshes; i++) {
        gs_gmesh_rt *me = &sys->meshes[i];
        if (me->ops->after_step)
            sys->dissipated += me->ops->after_step(&v, me);
        me->deflection = gs_gmesh_s(&v, me, sys->q) - me->s_ref;
        me->force = sol[gs_sol_mesh_force(sys, i)];
        const double *ct = sol + gs_sol_mesh_contact(sys, i);
        me->n_active = (int)ct[0];
        me->n_rows = (int)ct[1];
        me->penetration = ct[2];
        me->friction_loss += ct[3];
        me->contact_work += ct[4]; /* gap closure (numerics.contact); 0 with the seed's rows */
        if (me->ops->contact)
            me->nf_energy = ct[7]; /* near-field springs (src/step/contact_step.c) */
    }
    /* The sum over the meshes, formed the same way after a restore. */
    sys->contact_work = 0.0;
    for (int i = 0; i < sys->n_meshes; i++)
        sys->contact_work += sys->meshes[i].contact_work;
    /* Stop with the limit named rather than go on with garbage. */
    if (err == GS_OK)
        err = gs_system_check(sys, &sys->diag);
    return err;
}

/* numerics.contact "closure_energy": the closure's rows close the gap, so
 * their reactions do the work W = lambda^T G x in the step (the contact
 * nodes' inelastic share at a contact onset, docs/explanation/contact.md). It is given
 * back, exactly, as a velocity update of the mesh's two gears (Laursen and
 * Love's velocity update, here restricted to the rigid rotations): an
 * impulse P along the reactions' moments v_k = sum_r lambda_r G_r,theta_k
 * (equal and opposite along the contact normals, so no net force on the
 * pair) changes theta'_k by P v_k / I_k, keeping every elastic velocity
 * relative to its gear's frame and every position. With L_k the angular
 * momenta after the step, the kinetic energy changes by
 * a P^2 + b P, a = sum v_k^2 / (2 I_k), b = sum v_k L_k / I_k
 * (T is quadratic in the speeds with a constant mass matrix: exact), and
 * a P^2 + b P + W = 0 is solved for P, the root of smaller size (the
 * least change of the motion; the larger root reverses the approach of
 * the two gears, a rigid bounce that skips the elastic impact). W is all
 * the mesh's contact_work still booked, this step's reactions' work
 * included. When no root exists (W > 0, energy to take out, and too
 * little relative motion along the moments to take it, as in steady
 * rolling) the P that takes the most, and the rest is taken from the
 * pair's rotation as a whole (speeds scaled alike); what even that cannot
 * take waits for the next steps. The updates' energy is booked in
 * contact_work too, so contact_work is what is still owed (round-off, or
 * such a rest) and the balance holds as before. */
/* closure_energy: change the speeds of the rotations coord[k] (bodies
 * body[k], inertias Ik[k], angular momenta L[k], updated) by P d[k], P the
 * root of smaller size of a P^2 + b P + W = 0 (the kinetic energy change
 * -W: a = sum Ik d^2 / 2, b = sum d L), or, without a root, the P that
 * takes the most; returns the kinetic energy change. */
static double spin_pair(gs_system *sys, const int body[2], const int coord[2], const double Ik[2], double L[2],
                        const double d[2], double W)
{
    double a = 0.0, b = 0.0, P = 0.0, dT = 0.0;
    for (int k = 0; k < 2; k++) {
        a += 0.5 * Ik[k] * d[k] * d[k];
        b += d[k] * L[k];
    }
    if (!(a > 0.0) || W == 0.0)
        return 0.0;
    double disc = b * b - 4.0 * a * W;
    if (disc >= 0.0) /* without cancellation */
        P = -2.0 * W / (b + copysign(sqrt(disc), b));
    else
        P = -b / (2.0 * a);
    for (int k = 0; k < 2; k++) {
        if (d[k] == 0.0 || P == 0.0)
            continue;
        gs_body_rt *bd = &sys->bodies[body[k]];
        double dw = P * d[k];
        double dTk = dw * L[k] + 0.5 * Ik[k] * dw * dw;
        dT += dTk;
        sys->w[coord[k]] += dw;
        L[k] += Ik[k] * dw;
        if (bd->ops->state_size) {
            if (bd->ops->spin)
                bd->ops->spin(bd, dw);
            bd->T += dTk;
            bd->L = L[k];
        }
    }
    return dT;
}

/* True when coordinate c enters a kinematic (equality) row. */
static bool in_eq_row(const gs_system *sys, int c)
{
    for (int a = 0; a < sys->n_eq; a++)
        if (sys->eq_rows[(size_t)a * sys->n_coords + c] != 0.0)
            return true;
    return false;
}

double gs_step_contact_return(gs_system *sys, const double *sol)
{
    if (sys->contact_scheme != GS_CONTACT_CLOSURE_ENERGY)
        return 0.0;
    double rest = 0.0;
    for (int i = 0; i < sys->n_meshes; i++) {
        gs_gmesh_rt *me = &sys->meshes[i];
        if (!me->ops->contact || me->contact_work == 0.0)
            continue;
        const double *ct = sol + gs_sol_mesh_contact(sys, i);
        const gsi_contact_mesh *cm = me->contact;
        int body[2] = {cm->body[0], cm->body[1]}, coord[2];
        double L[2] = {0, 0}, Ik[2] = {0, 0}, d[2] = {0, 0}, r[2] = {0, 0};
        for (int k = 0; k < 2; k++) {
            gs_body_rt *bd = &sys->bodies[body[k]];
            coord[k] = bd->coord;
            if (coord[k] < 0 || !(bd->inertia_eff > 0) || in_eq_row(sys, coord[k]))
                continue; /* held, or tied by a kinematic row the update would break */
            Ik[k] = bd->inertia_eff;
            L[k] = bd->ops->state_size ? bd->L : Ik[k] * sys->w[coord[k]];
            d[k] = ct[5 + k] / Ik[k];
        }
        /* What is still booked (this step's work and any rest of earlier
         * steps), along the reactions' moments. */
        me->contact_work += spin_pair(sys, body, coord, Ik, L, d, me->contact_work);
        /* A rest to take out (energy the rows made by pushing a penetration
         * out, with too little relative motion along the moments to take
         * it, as in steady rolling or at a release): from the pair's
         * rotation as a whole, d proportional to the speeds. */
        if (me->contact_work > 0.0) {
            for (int k = 0; k < 2; k++)
                r[k] = Ik[k] > 0 ? L[k] / Ik[k] : 0.0;
            me->contact_work += spin_pair(sys, body, coord, Ik, L, r, me->contact_work);
        }
        rest += me->contact_work;
    }
    sys->contact_work = 0.0;
    for (int i = 0; i < sys->n_meshes; i++)
        sys->contact_work += sys->meshes[i].contact_work;
    return rest;
}

/* The adaptive step (METHOD.md section 3: "reducing h adaptively when
 * penetration appears"). The contact solve watches the candidates without
 * a row: when its solution would push one deeper than
 * numerics.adaptive.penetration_um, it answers GS_EREFINE instead, and the
 * substep is taken again at half the size (gs_step_refine; the rest of the
 * step is a whole number of the halves). A step of h taken without a
 * refinement lets the next one try a level coarser. Every rank sees the
 * same answer (broadcast with the solution), so every rank makes the same
 * choice. Time is kept as whole ticks of h / 2^levels: no drift, and
 * t = step h exactly at step ends. */
static void set_level(gs_system *sys, int level)
{
    sys->level = level;
    sys->h_sub = sys->h / (double)((int64_t)1 << level);
}

void gs_step_refine(gs_system *sys)
{
    set_level(sys, sys->level + 1);
    sys->refined = true;
    sys->refinements++;
}

bool gs_step_advance(gs_system *sys)
{
    int L = sys->adapt_levels;
    sys->substeps++;
    if (L == 0) {
        sys->step++;
        sys->time = (double)sys->step * sys->h;
        return true;
    }
    int64_t full = (int64_t)1 << L;
    sys->sub_ticks += (int64_t)1 << (L - sys->level);
    bool done = sys->sub_ticks >= full;
    if (done) {
        if (!sys->refined && sys->level > 0)
            set_level(sys, sys->level - 1);
        sys->refined = false;
        sys->step++;
        sys->sub_ticks = 0;
        sys->time = (double)sys->step * sys->h;
    } else {
        sys->time = ((double)sys->step + (double)sys->sub_ticks / (double)full) * sys->h;
    }
    return done;
}

gs_err gs_step_apply(gs_system *sys, const double *sol)
{
    return apply(sys, sol, false);
}

static gs_err serial_substep(gs_system *sys)
{
    GS_TRY(gs_step_prepare(sys));
    size_t need = sys->plan.rec_size + sys->plan.sol_size;
    if (need > sys->buf_cap) {
        double *nb = realloc(sys->buf, need * sizeof(double));
        if (!nb)
            return GS_ENOMEM;
        sys->buf = nb;
        sys->buf_cap = need;
    }
    double *rec = sys->buf, *sol = rec + sys->plan.rec_size;
    /* In one process this rank plays every owner. */
    records(sys, rec, true);
    gs_err e = GS_OK;
    if (gs_step_two_phase(sys)) {
        int *mask = gs_step_mask(sys);
        e = mask ? gs_step_select(sys, rec, mask) : GS_ENOMEM;
        double *cb = NULL;
        if (e == GS_OK) {
            cb = gs_grow(sys->rec_cbuf, &sys->cap_cbuf, gs_step_compliance_size(sys, mask), sizeof(double));
            if (cb)
                sys->rec_cbuf = cb;
            e = cb ? compliance(sys, mask, cb, NULL, true) : GS_ENOMEM;
        }
        if (e == GS_OK)
            e = compliance(sys, mask, cb, rec, true);
    }
    if (e == GS_OK)
        e = gs_step_solve(sys, rec, sol);
    if (e != GS_OK)
        return e;
    e = apply(sys, sol, true);
    gs_system_book_damping(sys);
    if (e == GS_OK)
        gs_step_contact_return(sys, sol);
    return e;
}

gs_err gs_step_whole(gs_system *sys, gs_err (*substep)(void *ctx), void *ctx)
{
    for (;;) {
        gs_err e = substep(ctx);
        if (e == GS_EREFINE) {
            gs_step_refine(sys);
            continue;
        }
        if (e != GS_OK)
            return e;
        if (gs_step_advance(sys))
            return GS_OK;
    }
}

static gs_err serial_substep_cb(void *sys)
{
    return serial_substep(sys);
}

gs_err gs_step_serial(gs_system *sys)
{
    return gs_step_whole(sys, serial_substep_cb, sys);
}
