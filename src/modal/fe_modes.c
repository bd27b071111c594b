/* SPDX-License-Identifier: MIT
 * Torsional mesh modes of an elastic pair from the FE model's own
 * generalised eigenproblem (include/gearsim/fe_modes.h, docs/explanation/modal.md
 * "FE mesh modes"). */
#include <cholmod.h>
#include <json-c/json.h>
#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fe/fe_internal.h"
#include "contact/nearfield_dyn.h"
#include "gearsim/contact.h"
#include "gearsim/fe_modes.h"
#include "gearsim/geometry.h"
#include "gearsim/stiffness.h"
#include "gearsim/util.h"

void gs_fe_modes_opts_defaults(gs_fe_modes_opts *o)
{
    memset(o, 0, sizeof *o);
    o->positions = 12;
    o->modes = 4;
    o->refine = -1;
    o->lanczos = 60;
    o->nearfield = 2;
    o->nearfield_secant = 0;
}

void gs_fe_modes_result_clear(gs_fe_modes_result *r)
{
    if (!r)
        return;
    free(r->pt);
    memset(r, 0, sizeof *r);
}

/* One FE body: its model (with the core's inertia, as the time integration
 * builds it), the factor of K_e + c M_e and the border of theta. */
typedef struct mbody {
    gs_fe_model *m;
    gs_index ne, off;    /* elastic unknowns; offset of u in the global vector */
    double inertia;      /* whole inertia */
    double *s;           /* ne: angular coupling */
    double *z;           /* ne: (K_e + c M_e)^{-1} s */
    double schur;        /* c I - c^2 s.z */
    cholmod_factor *L;
} mbody;

typedef struct ctx {
    mbody b[2];
    gs_index n;          /* global unknowns: u0, theta0, u1, theta1 */
    double c;            /* shift */
    double rb[2];        /* base radii (the rolling of gs_fe_modes_conjugate_row) */
    cholmod_common cc;
    cholmod_dense *B;    /* scratch right-hand side (ne of the larger body) */
} ctx;

static void ctx_free(ctx *x)
{
    for (int k = 0; k < 2; k++) {
        if (x->b[k].L)
            cholmod_l_free_factor(&x->b[k].L, &x->cc);
        free(x->b[k].s);
        free(x->b[k].z);
        gs_fe_model_free(&x->b[k].m);
    }
    if (x->B)
        cholmod_l_free_dense(&x->B, &x->cc);
    cholmod_l_finish(&x->cc);
}

/* The rigid core of an external gear: the solid hub disc, or what a given
 * inertia leaves beyond the elastic part (as the time integration). */
static gs_err core_inertia(const gs_scene_body *sb, const gs_mesh *mesh, double *core, gs_diag *d)
{
    const gs_gear_params *g = &sb->gear;
    *core = 0.0;
    if (g->kind == GS_GEAR_EXTERNAL) {
        double rh = gs_gear_hub_radius(g);
        *core = 0.5 * GS_PI * sb->material.density * g->face_width_m * rh * rh * rh * rh;
    }
    if (!sb->inertia_given)
        return GS_OK;
    gs_fe_model *m;
    GS_TRY(gs_fe_model_new(mesh, &sb->material, g->face_width_m, 0.0, &m));
    gs_fe_model_info info;
    gs_fe_model_get_info(m, &info);
    gs_fe_model_free(&m);
    *core = sb->inertia - info.inertia_elastic;
    if (*core < 0)
        return gs_diag_set(d, GS_ERANGE, "bodies", "'%s': inertia below that of its elastic part", sb->name);
    return GS_OK;
}

/* y = (K_e + c M_e)^{-1} f on body k (ne values). */
static gs_err solve_e(ctx *x, int k, const double *f, double *y)
{
    mbody *b = &x->b[k];
    cholmod_dense B = *x->B;
    B.nrow = B.d = (size_t)b->ne;
    B.ncol = 1;
    memcpy(B.x, f, (size_t)b->ne * sizeof *f);
    cholmod_dense *X = cholmod_l_solve(CHOLMOD_A, b->L, &B, &x->cc);
    if (!X)
        return GS_ENOMEM;
    memcpy(y, X->x, (size_t)b->ne * sizeof *y);
    cholmod_l_free_dense(&X, &x->cc);
    return GS_OK;
}

/* y = A^{-1} f, A = K + c M of both bodies (theta bordered). */
static gs_err solve_A(ctx *x, const double *f, double *y)
{
    for (int k = 0; k < 2; k++) {
        mbody *b = &x->b[k];
        const double *fu = f + b->off;
        double *yu = y + b->off;
        GS_TRY(solve_e(x, k, fu, yu));
        double sy = 0.0;
        for (gs_index i = 0; i < b->ne; i++)
            sy += b->s[i] * yu[i];
        double t = (fu[b->ne] - x->c * sy) / b->schur;
        for (gs_index i = 0; i < b->ne; i++)
            yu[i] -= x->c * t * b->z[i];
        yu[b->ne] = t;
    }
    return GS_OK;
}

/* y = alpha M v + beta K v on both bodies. */
static void apply_MK(const ctx *x, double alpha, double beta, const double *v, double *y)
{
    for (int k = 0; k < 2; k++) {
        const mbody *b = &x->b[k];
        const double *u = v + b->off;
        double *yu = y + b->off;
        double th = u[b->ne], su = 0.0;
        memset(yu, 0, (size_t)(b->ne + 1) * sizeof *yu);
        gsi_fe_symv2(b->m, alpha, u, beta, u, yu);
        for (gs_index i = 0; i < b->ne; i++) {
            yu[i] += alpha * b->s[i] * th;
            su += b->s[i] * u[i];
        }
        yu[b->ne] = alpha * (su + b->inertia * th);
    }
}

static double dot(gs_index n, const double *a, const double *b)
{
    double s = 0.0;
    for (gs_index i = 0; i < n; i++)
        s += a[i] * b[i];
    return s;
}

static gs_err body_init(ctx *x, int k, const gs_scene_body *sb, const gs_mesh *mesh, gs_diag *d)
{
    mbody *b = &x->b[k];
    double core;
    GS_TRY(core_inertia(sb, mesh, &core, d));
    gs_err e = gs_fe_model_new(mesh, &sb->material, sb->gear.face_width_m, core, &b->m);
    if (e != GS_OK)
        return gs_diag_set(d, e, "bodies", "finite element model of '%s' failed", sb->name);
    gs_fe_model_info info;
    gs_fe_model_get_info(b->m, &info);
    b->ne = info.n_elastic;
    b->inertia = info.inertia_total;
    b->s = malloc((size_t)b->ne * sizeof *b->s);
    b->z = malloc((size_t)b->ne * sizeof *b->z);
    if (!b->s || !b->z)
        return GS_ENOMEM;
    gs_fe_model_coupling(b->m, b->s);
    return GS_OK;
}

static gs_err body_factor(ctx *x, int k)
{
    mbody *b = &x->b[k];
    cholmod_sparse *A = gsi_fe_cholmod_matrix(b->m, x->c, 1.0, &x->cc);
    if (!A)
        return GS_ENOMEM;
    b->L = cholmod_l_analyze(A, &x->cc);
    int ok = b->L && cholmod_l_factorize(A, b->L, &x->cc) && x->cc.status != CHOLMOD_NOT_POSDEF;
    cholmod_l_free_sparse(&A, &x->cc);
    if (!ok)
        return GS_ESINGULAR;
    GS_TRY(solve_e(x, k, b->s, b->z));
    b->schur = x->c * b->inertia - x->c * x->c * dot(b->ne, b->s, b->z);
    return b->schur > 0.0 ? GS_OK : GS_ESINGULAR;
}

double gs_fe_modes_conjugate_row(double a[2], const double rb[2])
{
    double sigma = a[0] * a[1] > 0.0 ? -1.0 : 1.0;
    double scale = fabs(a[0]) / rb[0] + fabs(a[1]) / rb[1];
    if (!(scale > 0.0))
        return 0.0;
    double eps = a[0] / rb[0] + sigma * a[1] / rb[1];
    a[0] -= 0.5 * eps * rb[0];
    a[1] -= 0.5 * sigma * eps * rb[1];
    return fabs(eps) / scale;
}

/* The constraint rows G (nr x n, row-major) of the active contact rows, each
 * conjugate to the rolling; *dep the largest departure corrected. */
static int build_G(const ctx *x, const gs_contact_row *rows, const double *force, int nr, double fmin, double *G,
                   int *which, double *dep)
{
    int m = 0;
    *dep = 0.0;
    for (int i = 0; i < nr; i++) {
        if (!(force[i] > fmin))
            continue;
        which[m] = i;
        double *g = G + (size_t)m * (size_t)x->n;
        memset(g, 0, (size_t)x->n * sizeof *g);
        const gs_contact_row *r = &rows[i];
        double a[2] = {r->dg_dtheta[0], r->dg_dtheta[1]};
        *dep = fmax(*dep, gs_fe_modes_conjugate_row(a, x->rb));
        for (int k = 0; k < 2; k++)
            g[x->b[k].off + x->b[k].ne] += a[k];
        for (int t = 0; t < r->n_nodes; t++) {
            const mbody *b = &x->b[r->body[t]];
            for (int comp = 0; comp < 2; comp++) {
                gs_index q = gs_fe_model_dof(b->m, r->node[t], comp);
                if (q >= 0)
                    g[b->off + q] += r->dg_du[t][comp];
            }
        }
        m++;
    }
    return m;
}

/* Pseudo-inverse of the symmetric m x m matrix S in place (eigenvalues below
 * 1e-12 of the largest dropped: nearly parallel rows of one contact). */
static gs_err pinv_sym(int m, double *S)
{
    double *ev = malloc((size_t)m * sizeof *ev), *V = malloc((size_t)m * (size_t)m * sizeof *V);
    if (!ev || !V) {
        free(ev), free(V);
        return GS_ENOMEM;
    }
    memcpy(V, S, (size_t)m * (size_t)m * sizeof *V);
    if (LAPACKE_dsyev(LAPACK_COL_MAJOR, 'V', 'U', m, V, m, ev) != 0) {
        free(ev), free(V);
        return GS_ESINGULAR;
    }
    double top = fabs(ev[m - 1]);
    memset(S, 0, (size_t)m * (size_t)m * sizeof *S);
    for (int l = 0; l < m; l++) {
        if (!(ev[l] > 1e-12 * top))
            continue;
        for (int i = 0; i < m; i++)
            for (int j = 0; j < m; j++)
                S[i + j * m] += V[i + l * m] * V[j + l * m] / ev[l];
    }
    free(ev), free(V);
    return GS_OK;
}

/* Lanczos on T = P A^{-1} M (P: onto G q = 0 along A^{-1} G'), self-adjoint
 * in the M inner product; eigenvalues mu = 1 / (w^2 + c). Fills the lowest
 * `want` modes above 0 Hz of one position. */
static gs_err position_modes(ctx *x, const double *G, int m, const double *Cm, int steps, int want,
                             gs_fe_modes_point *pt)
{
    gs_index n = x->n;
    size_t nz = (size_t)n;
    gs_err e = GS_ENOMEM;
    double *Z = malloc(nz * (size_t)(m ? m : 1) * sizeof *Z);      /* A^{-1} G' */
    double *S = malloc((size_t)(m ? m * m : 1) * sizeof *S);
    double *Q = malloc(nz * (size_t)(steps + 1) * sizeof *Q);      /* Lanczos vectors */
    double *MQ = malloc(nz * (size_t)(steps + 1) * sizeof *MQ);    /* M times them */
    double *w = malloc(nz * sizeof *w), *y = malloc(nz * sizeof *y), *r = malloc(nz * sizeof *r);
    double *al = malloc((size_t)steps * sizeof *al), *be = malloc((size_t)steps * sizeof *be);
    double *Y = malloc((size_t)steps * (size_t)steps * sizeof *Y), *dd = malloc((size_t)steps * sizeof *dd);
    double *ee = malloc((size_t)steps * sizeof *ee), *gy = malloc((size_t)(m ? m : 1) * sizeof *gy);
    double *lam = malloc((size_t)(m ? m : 1) * sizeof *lam);
    if (!Z || !S || !Q || !MQ || !w || !y || !r || !al || !be || !Y || !dd || !ee || !gy || !lam)
        goto out;
    for (int i = 0; i < m; i++)
        if ((e = solve_A(x, G + (size_t)i * nz, Z + (size_t)i * nz)) != GS_OK)
            goto out;
    for (int i = 0; i < m; i++)
        for (int j = 0; j < m; j++)
            S[i + j * m] = dot(n, G + (size_t)i * nz, Z + (size_t)j * nz);
    for (int i = 0; i < m; i++) /* symmetric to round-off: take the mean */
        for (int j = 0; j < i; j++)
            S[i + j * m] = S[j + i * m] = 0.5 * (S[i + j * m] + S[j + i * m]);
    /* Compliant rows, G q + C lambda = 0: the Schur complement G A^-1 G' + C
     * (Woodbury: the inverse of A + G' C^-1 G on the rows' span). */
    if (Cm)
        for (size_t i = 0; i < (size_t)m * (size_t)m; i++)
            S[i] += Cm[i];
    if (m > 0 && (e = pinv_sym(m, S)) != GS_OK)
        goto out;
/* w = T v from Mv = M v */
#define APPLY_T(Mv, out_)                                                        \
    do {                                                                         \
        if ((e = solve_A(x, (Mv), (out_))) != GS_OK)                             \
            goto out;                                                            \
        for (int i_ = 0; i_ < m; i_++)                                           \
            gy[i_] = dot(n, G + (size_t)i_ * nz, (out_));                        \
        for (int i_ = 0; i_ < m; i_++) {                                         \
            double l_ = 0.0;                                                     \
            for (int j_ = 0; j_ < m; j_++)                                       \
                l_ += S[i_ + j_ * m] * gy[j_];                                   \
            lam[i_] = l_;                                                        \
        }                                                                        \
        for (int i_ = 0; i_ < m; i_++)                                           \
            for (gs_index q_ = 0; q_ < n; q_++)                                  \
                (out_)[q_] -= Z[(size_t)i_ * nz + (size_t)q_] * lam[i_];         \
    } while (0)
    /* Start: T applied to a fixed vector with every unknown moving. */
    for (gs_index i = 0; i < n; i++)
        y[i] = 1.0 + 0.5 * sin(0.7 * (double)i);
    apply_MK(x, 1.0, 0.0, y, r);
    APPLY_T(r, w);
    apply_MK(x, 1.0, 0.0, w, r);
    double nrm = sqrt(dot(n, w, r));
    for (gs_index i = 0; i < n; i++) {
        Q[i] = w[i] / nrm;
        MQ[i] = r[i] / nrm;
    }
    int k = 0;
    for (; k < steps; k++) {
        double *q = Q + (size_t)k * nz, *mq = MQ + (size_t)k * nz;
        APPLY_T(mq, w);
        al[k] = dot(n, w, mq);
        /* Full reorthogonalisation, twice, in the M inner product. */
        for (int pass = 0; pass < 2; pass++)
            for (int j = 0; j <= k; j++) {
                double h = dot(n, w, MQ + (size_t)j * nz);
                const double *qj = Q + (size_t)j * nz;
                for (gs_index i = 0; i < n; i++)
                    w[i] -= h * qj[i];
            }
        apply_MK(x, 1.0, 0.0, w, r);
        be[k] = sqrt(fmax(dot(n, w, r), 0.0));
        if (k + 1 == steps || be[k] <= 1e-14 * fabs(al[0]))
            break;
        for (gs_index i = 0; i < n; i++) {
            q[nz + (size_t)i] = w[i] / be[k];
            mq[nz + (size_t)i] = r[i] / be[k];
        }
    }
    int ns = k + 1;
    memcpy(dd, al, (size_t)ns * sizeof *dd);
    memcpy(ee, be, (size_t)ns * sizeof *ee);
    if (LAPACKE_dstev(LAPACK_COL_MAJOR, 'V', ns, dd, ee, Y, ns) != 0) {
        e = GS_ESINGULAR;
        goto out;
    }
    /* Largest mu first = lowest w; skip the rigid rotation (w ~ 0). */
    int got = 0;
    for (int l = ns - 1; l >= 0 && got < want; l--) {
        double w2 = 1.0 / dd[l] - x->c;
        if (!(dd[l] > 0.0) || w2 < 1e-8 * x->c) /* the rigid rotation, 0 Hz to round-off (rows conjugate) */
            continue;
        /* Ritz vector y = Q Y[:, l]; its residual on the constrained space
         * and its rotation share. */
        memset(y, 0, nz * sizeof *y);
        for (int j = 0; j < ns; j++) {
            double cj = Y[j + l * ns];
            const double *qj = Q + (size_t)j * nz;
            for (gs_index i = 0; i < n; i++)
                y[i] += cj * qj[i];
        }
        apply_MK(x, 1.0, 0.0, y, r);
        double kin = dot(n, y, r), rot = 0.0;
        for (int b = 0; b < 2; b++) {
            double th = y[x->b[b].off + x->b[b].ne];
            rot += x->b[b].inertia * th * th;
        }
        apply_MK(x, -w2, 1.0, y, w); /* K y - w^2 M y */
        /* Remove the reactions G' lambda (least squares). */
        double rn = 0.0;
        if (m > 0) {
            double *GG = malloc((size_t)m * (size_t)m * sizeof *GG);
            if (!GG) {
                e = GS_ENOMEM;
                goto out;
            }
            for (int i = 0; i < m; i++) {
                gy[i] = dot(n, G + (size_t)i * nz, w);
                for (int j = 0; j < m; j++)
                    GG[i + j * m] = dot(n, G + (size_t)i * nz, G + (size_t)j * nz);
            }
            e = pinv_sym(m, GG);
            for (int i = 0; i < m && e == GS_OK; i++) {
                double l2 = 0.0;
                for (int j = 0; j < m; j++)
                    l2 += GG[i + j * m] * gy[j];
                const double *gi = G + (size_t)i * nz;
                for (gs_index q = 0; q < n; q++)
                    w[q] -= l2 * gi[q];
            }
            free(GG);
            if (e != GS_OK)
                goto out;
        }
        rn = sqrt(dot(n, w, w)) / (w2 * sqrt(dot(n, r, r)));
        pt->hz[got] = sqrt(w2) / (2.0 * GS_PI);
        pt->rotation[got] = rot / kin;
        pt->residual[got] = rn;
        got++;
    }
#undef APPLY_T
    for (; got < want; got++)
        pt->hz[got] = pt->rotation[got] = pt->residual[got] = NAN;
    e = GS_OK;
out:
    free(Z), free(S), free(Q), free(MQ), free(w), free(y), free(r), free(al), free(be);
    free(Y), free(dd), free(ee), free(gy), free(lam);
    return e;
}

gs_err gs_fe_modes_analyse(const gs_scene *sc, int mesh_index, const gs_fe_modes_opts *opt,
                           gs_fe_modes_result *out, gs_diag *d)
{
    if (!sc || !out)
        return gs_diag_set(d, GS_EINVAL, "", "NULL scene or result");
    memset(out, 0, sizeof *out);
    gs_fe_modes_opts o;
    if (opt)
        o = *opt;
    else
        gs_fe_modes_opts_defaults(&o);
    if (o.modes < 1 || o.modes > GS_FE_MODES_MAX)
        return gs_diag_set(d, GS_ERANGE, "modes", "modes must be 1..%d", GS_FE_MODES_MAX);
    if (o.lanczos < 2 * o.modes + 4 || o.lanczos > 1000)
        return gs_diag_set(d, GS_ERANGE, "lanczos", "Lanczos steps must be %d..1000", 2 * o.modes + 4);
    double t0 = gs_now();
    gs_stiffness_opts so;
    gs_stiffness_opts_defaults(&so);
    so.nearfield = o.nearfield;
    so.positions = o.positions;
    so.refine = o.refine;
    so.order = o.order;
    so.torque_nm = o.torque_nm;
    so.phase = o.phase;
    so.driver = 0;
    /* The tangent stiffness of each position (central difference at T). */
    gs_stiffness_result tan;
    so.tangent = 1;
    so.tangent_step = 0.1;
    GS_TRY(gs_stiffness_analyse(sc, mesh_index, &so, &tan, d));
    so.tangent = 0;
    gs_stiffness_run *run = NULL;
    ctx x;
    memset(&x, 0, sizeof x);
    gsi_cholmod_start(&x.cc);
    double *G = NULL;
    gs_err e = gs_stiffness_begin(sc, mesh_index, &so, &run, d);
    if (e != GS_OK)
        goto done;
    const gs_scene_mesh *sm = &sc->meshes[mesh_index];
    for (int k = 0; k < 2 && e == GS_OK; k++) {
        const gs_mesh *mk = gs_stiffness_run_mesh(run, k);
        e = body_init(&x, k, &sc->bodies[sm->gear[k]], mk, d);
        out->nodes[k] = mk->n_nodes;
        out->inertia[k] = x.b[k].inertia;
        out->base_radius[k] = gs_gear_base_radius(&sc->bodies[sm->gear[k]].gear);
        x.rb[k] = out->base_radius[k];
    }
    if (e != GS_OK)
        goto done;
    x.b[0].off = 0;
    x.b[1].off = x.b[0].ne + 1;
    x.n = x.b[0].ne + x.b[1].ne + 2;
    out->unknowns = x.n;
    out->torque_nm = tan.torque_nm;
    out->positions = o.positions;
    out->modes = o.modes;
    double lever = out->base_radius[0] * out->base_radius[0] / out->inertia[0] +
                   out->base_radius[1] * out->base_radius[1] / out->inertia[1];
    /* Shift: the lumped estimate with the mean secant stiffness. */
    x.c = tan.k_mean * tan.face_width_mm * 1e6 * lever;
    x.B = cholmod_l_zeros((size_t)(x.b[0].ne > x.b[1].ne ? x.b[0].ne : x.b[1].ne), 1, CHOLMOD_REAL, &x.cc);
    out->pt = gs_calloc((size_t)o.positions, sizeof *out->pt);
    if (!x.B || !out->pt) {
        e = GS_ENOMEM;
        goto done;
    }
    for (int k = 0; k < 2 && e == GS_OK; k++)
        e = body_factor(&x, k);
    if (e != GS_OK) {
        gs_diag_set(d, e, "meshes", "factorisation of K + c M failed");
        goto done;
    }
    out->min_hz = INFINITY;
    out->max_hz = -INFINITY;
    for (int j = 0; j < o.positions; j++) {
        if ((e = gs_stiffness_next(run, d)) != GS_OK)
            goto done;
        const gs_contact_row *rows;
        const double *force;
        int nr = gs_stiffness_run_rows(run, &rows, &force);
        double *g2 = realloc(G, (size_t)(nr ? nr : 1) * (size_t)x.n * sizeof *G);
        if (!g2) {
            e = GS_ENOMEM;
            goto done;
        }
        G = g2;
        gs_fe_modes_point *pt = &out->pt[j];
        pt->roll = tan.pt[j].roll;
        int *which = NULL, *pair = NULL;
        double *Cm = NULL, ct[GS_STIFF_MAX_PAIRS];
        which = malloc((size_t)(nr ? nr : 1) * sizeof *which);
        pair = malloc((size_t)(nr ? nr : 1) * sizeof *pair);
        if (!which || !pair) {
            free(which), free(pair);
            e = GS_ENOMEM;
            goto done;
        }
        pt->rows = build_G(&x, rows, force, nr, 1e-9 * tan.force_n, G, which, &pt->lever_departure);
        int m = pt->rows;
        int npairs = o.nearfield_secant ? gsi_nf_run_secant(run, pair, ct) : gs_stiffness_run_nearfield(run, pair, ct);
        if (npairs > 0 && m > 0) {
            Cm = calloc((size_t)m * (size_t)m, sizeof *Cm);
            if (!Cm) {
                free(which), free(pair);
                e = GS_ENOMEM;
                goto done;
            }
            for (int a = 0; a < m; a++)
                for (int b = 0; b < m; b++) {
                    int pa = pair[which[a]], pb = pair[which[b]];
                    if (pa >= 0 && pa == pb)
                        Cm[a + b * m] = ct[pa];
                }
        }
        e = position_modes(&x, G, m, Cm, o.lanczos, o.modes, pt);
        free(which), free(pair), free(Cm);
        if (e != GS_OK) {
            gs_diag_set(d, e, "meshes", "eigenproblem at roll %.3f failed", pt->roll);
            goto done;
        }
        pt->k_tan = tan.pt[j].k_tan * tan.face_width_mm * 1e6;
        pt->lumped_hz = sqrt(pt->k_tan * lever) / (2.0 * GS_PI);
        out->mean_hz += pt->hz[0] / o.positions;
        out->min_hz = fmin(out->min_hz, pt->hz[0]);
        out->max_hz = fmax(out->max_hz, pt->hz[0]);
        out->k_tan_mean += pt->k_tan / o.positions;
    }
    out->lumped_mean_hz = sqrt(out->k_tan_mean * lever) / (2.0 * GS_PI);
    out->seconds = gs_now() - t0;
done:
    gs_stiffness_run_free(&run);
    gs_stiffness_result_clear(&tan);
    ctx_free(&x);
    free(G);
    if (e != GS_OK) {
        if (d && !d->message[0])
            gs_diag_set(d, e, "meshes", "FE mesh modes failed: %s", gs_strerror(e));
        gs_fe_modes_result_clear(out);
    }
    return e;
}

static json_object *num(double v)
{
    return isfinite(v) ? json_object_new_double(v) : NULL;
}

json_object *gs_fe_modes_json(const gs_fe_modes_result *r)
{
    json_object *o = json_object_new_object();
    json_object_object_add(o, "positions", json_object_new_int(r->positions));
    json_object_object_add(o, "modes", json_object_new_int(r->modes));
    json_object *a = json_object_new_array();
    json_object *in = json_object_new_array();
    json_object *rb = json_object_new_array();
    for (int k = 0; k < 2; k++) {
        json_object_array_add(a, json_object_new_int64(r->nodes[k]));
        json_object_array_add(in, num(r->inertia[k]));
        json_object_array_add(rb, num(r->base_radius[k] * 1e3));
    }
    json_object_object_add(o, "nodes", a);
    json_object_object_add(o, "unknowns", json_object_new_int64(r->unknowns));
    json_object_object_add(o, "inertia", in);
    json_object_object_add(o, "base_radius_mm", rb);
    json_object_object_add(o, "torque_nm", num(r->torque_nm));
    json_object_object_add(o, "mean_hz", num(r->mean_hz));
    json_object_object_add(o, "min_hz", num(r->min_hz));
    json_object_object_add(o, "max_hz", num(r->max_hz));
    json_object_object_add(o, "k_tan_mean", num(r->k_tan_mean));
    json_object_object_add(o, "lumped_mean_hz", num(r->lumped_mean_hz));
    json_object_object_add(o, "seconds", num(r->seconds));
    json_object *pts = json_object_new_array();
    for (int j = 0; j < r->positions; j++) {
        const gs_fe_modes_point *p = &r->pt[j];
        json_object *q = json_object_new_object();
        json_object_object_add(q, "roll", num(p->roll));
        json_object_object_add(q, "rows", json_object_new_int(p->rows));
        json_object *hz = json_object_new_array(), *rot = json_object_new_array(), *res = json_object_new_array();
        for (int m = 0; m < r->modes; m++) {
            json_object_array_add(hz, num(p->hz[m]));
            json_object_array_add(rot, num(p->rotation[m]));
            json_object_array_add(res, num(p->residual[m]));
        }
        json_object_object_add(q, "hz", hz);
        json_object_object_add(q, "rotation", rot);
        json_object_object_add(q, "residual", res);
        json_object_object_add(q, "k_tan", num(p->k_tan));
        json_object_object_add(q, "lumped_hz", num(p->lumped_hz));
        json_object_object_add(q, "lever_departure", num(p->lever_departure));
        json_object_array_add(pts, q);
    }
    json_object_object_add(o, "points", pts);
    return o;
}
