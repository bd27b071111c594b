/* SPDX-License-Identifier: MIT
 * Modal analysis of the linearised rigid/lumped train (gearsim/modal.h,
 * docs/explanation/modal.md). */
#include <json-c/json.h>
#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/modal.h"
#include "gearsim/util.h"

const char *gs_mode_kind_name(int kind)
{
    static const char *const names[] = {"rotational", "translational", "planet", "mixed"};
    return kind >= 0 && kind < 4 ? names[kind] : "unknown";
}

void gs_modal_free(gs_modal **pm)
{
    gs_modal *m = pm ? *pm : NULL;
    if (!m)
        return;
    free(m->dof_body), free(m->dof_comp), free(m->T), free(m->M), free(m->K);
    free(m->omega2), free(m->freq_hz), free(m->shape), free(m->body_shape);
    free(m->group), free(m->group_first), free(m->group_mult), free(m->group_kind);
    free(m->group_central), free(m->lever), free(m->G);
    free(m);
    *pm = NULL;
}

/* Coordinates of each body (x, y, rotation as needed by its joint). */
static int count_dofs(const gs_scene *s, int *first, int *ncomp)
{
    int n = 0;
    for (int i = 0; i < s->n_bodies; i++) {
        const gs_scene_body *b = &s->bodies[i];
        int c = 0;
        if (b->joint == GS_JOINT_FIXED_AXIS)
            c = 1;
        else if (b->joint == GS_JOINT_BEARING)
            c = 3;
        else if (b->joint == GS_JOINT_ON_CARRIER)
            c = b->pin_bearing ? 3 : 1;
        first[i] = n;
        ncomp[i] = c;
        n += c;
    }
    return n;
}

/* Row r of T (column-major 3nb x n). */
#define TT(m, r, j) ((m)->T[(size_t)(j) * (size_t)(3 * (m)->n_bodies) + (size_t)(r)])

/* Add k g g' to K, g = T' c (c over the 3 nb physical displacements). */
static void add_spring(gs_modal *m, const double *c, double k, double *g)
{
    int nb3 = 3 * m->n_bodies, n = m->n;
    for (int j = 0; j < n; j++) {
        double v = 0;
        for (int r = 0; r < nb3; r++)
            v += c[r] * TT(m, r, j);
        g[j] = v;
    }
    for (int j = 0; j < n; j++)
        for (int i = 0; i < n; i++)
            m->K[(size_t)j * n + i] += k * g[i] * g[j];
}

static gs_err mesh_row(const gs_scene *s, int mi, double *c, double *k, gs_diag *d)
{
    const gs_scene_mesh *sm = &s->meshes[mi];
    char f[96];
    if (sm->model != GS_MESH_LUMPED && sm->model != GS_MESH_KINEMATIC) {
        snprintf(f, sizeof f, "meshes[%d].model", mi);
        return gs_diag_set(d, GS_ERANGE, f,
                           "mesh '%s': the modal analysis needs a mean mesh stiffness (a lumped mesh with "
                           "constant or rectangular stiffness) or an exact ratio (kinematic)",
                           sm->name);
    }
    int A = sm->gear[0], B = sm->gear[1];
    const gs_gear_params *gA = &s->bodies[A].gear, *gB = &s->bodies[B].gear;
    double rA = gs_gear_base_radius(gA), rB = gs_gear_base_radius(gB);
    bool internal = gA->kind == GS_GEAR_INTERNAL || gB->kind == GS_GEAR_INTERNAL;
    int R = A, P = B; /* internal: ring, pinion */
    if (internal && gB->kind == GS_GEAR_INTERNAL)
        R = B, P = A;
    double rR = gs_gear_base_radius(&s->bodies[R].gear), rP = gs_gear_base_radius(&s->bodies[P].gear);
    double c0[2], c1[2];
    gs_scene_body_centre(s, internal ? R : A, c0);
    gs_scene_body_centre(s, internal ? P : B, c1);
    double u[2] = {c1[0] - c0[0], c1[1] - c0[1]};
    double a = hypot(u[0], u[1]);
    snprintf(f, sizeof f, "meshes[%d].gears", mi);
    if (!(a > 1e-9))
        return gs_diag_set(d, GS_EGEOMETRY, f, "mesh '%s': the two gears share one centre", sm->name);
    u[0] /= a, u[1] /= a;
    double up[2] = {-u[1], u[0]};
    double cw = (internal ? rR - rP : rA + rB) / a;
    if (!(cw > 0 && cw < 1))
        return gs_diag_set(d, GS_EGEOMETRY, f,
                           "mesh '%s': base radii and centre distance %.6g mm admit no line of action",
                           sm->name, a * 1e3);
    double alpha = acos(cw); /* operating pressure angle */
    double sa = sin(alpha), ca = cos(alpha);
    memset(c, 0, sizeof(double) * 3 * (size_t)s->n_bodies);
    if (internal) {
        double n[2] = {-sa * u[0] + ca * up[0], -sa * u[1] + ca * up[1]};
        c[3 * R] += n[0], c[3 * R + 1] += n[1], c[3 * R + 2] += rR;
        c[3 * P] -= n[0], c[3 * P + 1] -= n[1], c[3 * P + 2] -= rP;
    } else {
        double n[2] = {sa * u[0] + ca * up[0], sa * u[1] + ca * up[1]};
        c[3 * A] += n[0], c[3 * A + 1] += n[1], c[3 * A + 2] += rA;
        c[3 * B] -= n[0], c[3 * B + 1] -= n[1], c[3 * B + 2] += rB;
    }
    if (sm->model == GS_MESH_KINEMATIC) {
        *k = -1.0; /* a constraint, not a spring */
    } else if (sm->stiffness_type == GS_STIFF_CONSTANT) {
        *k = sm->k_single;
    } else if (sm->stiffness_type == GS_STIFF_RECTANGULAR) {
        double eps;
        gs_err e = gs_pair_contact_ratio(gA, gB, a, &eps, NULL, d);
        if (e != GS_OK) {
            snprintf(d->field, sizeof d->field, "%s", f);
            return e;
        }
        double e1 = eps - 1.0;
        e1 = e1 < 0 ? 0 : e1 > 1 ? 1 : e1;
        *k = sm->k_single * (1 - e1) + sm->k_double * e1; /* mean over one mesh cycle */
    } else {
        snprintf(f, sizeof f, "meshes[%d].stiffness", mi);
        return gs_diag_set(d, GS_ERANGE, f,
                           "mesh '%s': the modal analysis needs a constant or rectangular stiffness", sm->name);
    }
    return GS_OK;
}

static gs_err build(const gs_scene *s, gs_modal *m, gs_diag *d)
{
    int nb = s->n_bodies, nb3 = 3 * nb;
    int *first = gs_calloc((size_t)nb, sizeof(int)), *nc = gs_calloc((size_t)nb, sizeof(int));
    if (!first || !nc) {
        free(first), free(nc);
        return GS_ENOMEM;
    }
    int n = count_dofs(s, first, nc);
    m->n = n;
    m->n_bodies = nb;
    if (n == 0) {
        free(first), free(nc);
        return gs_diag_set(d, GS_ERANGE, "joints", "no body can move: every body is held");
    }
    size_t nn = (size_t)n * (size_t)n;
    m->dof_body = gs_calloc((size_t)n, sizeof(int));
    m->dof_comp = gs_calloc((size_t)n, sizeof(int));
    m->T = gs_calloc((size_t)nb3 * (size_t)n, sizeof(double));
    m->M = gs_calloc(nn, sizeof(double));
    m->K = gs_calloc(nn, sizeof(double));
    m->lever = gs_calloc((size_t)nb, sizeof(double));
    double *c = gs_calloc((size_t)nb3, sizeof(double)), *g = gs_calloc((size_t)n, sizeof(double));
    gs_err e = GS_ENOMEM;
    if (!m->dof_body || !m->dof_comp || !m->T || !m->M || !m->K || !m->lever || !c || !g)
        goto out;
    /* T: own coordinates first, then the carrier terms of rigid pins. */
    for (int i = 0; i < nb; i++) {
        for (int k = 0; k < nc[i]; k++) {
            int comp = nc[i] == 1 ? 2 : k;
            m->dof_body[first[i] + k] = i;
            m->dof_comp[first[i] + k] = comp;
            TT(m, 3 * i + comp, first[i] + k) = 1.0;
        }
        const gs_scene_body *b = &s->bodies[i];
        m->lever[i] = b->type == GS_BODY_GEAR ? gs_gear_base_radius(&b->gear) : 0.0;
    }
    for (int i = 0; i < nb; i++) {
        const gs_scene_body *b = &s->bodies[i];
        if (b->joint != GS_JOINT_ON_CARRIER)
            continue;
        int C = b->carrier;
        double cp[2], cc[2];
        gs_scene_body_centre(s, i, cp);
        gs_scene_body_centre(s, C, cc);
        double dx = cp[0] - cc[0], dy = cp[1] - cc[1];
        double r = hypot(dx, dy);
        if (r > m->lever[C])
            m->lever[C] = r;
        /* the pin: carrier translation plus its rotation times d */
        if (!b->pin_bearing) /* rigid pin: the centre is the pin, carrier translation plus rotation x d */
            for (int j = 0; j < n; j++) {
                TT(m, 3 * i, j) = TT(m, 3 * C, j) - dy * TT(m, 3 * C + 2, j);
                TT(m, 3 * i + 1, j) = TT(m, 3 * C + 1, j) + dx * TT(m, 3 * C + 2, j);
            }
        else /* planet bearing: isotropic spring between the pin and the planet's centre */
            for (int comp = 0; comp < 2; comp++) {
                memset(c, 0, sizeof(double) * (size_t)nb3);
                c[3 * i + comp] = 1.0;
                c[3 * C + comp] = -1.0;
                c[3 * C + 2] = comp == 0 ? dy : -dx; /* minus the pin's rotation term */
                add_spring(m, c, b->bearing_k, g);
            }
    }
    /* mass */
    for (int i = 0; i < nb; i++) {
        const gs_scene_body *b = &s->bodies[i];
        double w[3] = {b->mass, b->mass, b->inertia};
        for (int r = 0; r < 3; r++)
            for (int jc = 0; jc < n; jc++) {
                double tj = TT(m, 3 * i + r, jc);
                if (tj == 0)
                    continue;
                for (int ic = 0; ic < n; ic++)
                    m->M[(size_t)jc * n + ic] += w[r] * TT(m, 3 * i + r, ic) * tj;
            }
    }
    /* supports */
    for (int i = 0; i < nb; i++) {
        const gs_scene_body *b = &s->bodies[i];
        if (b->joint != GS_JOINT_BEARING)
            continue;
        for (int comp = 0; comp < 3; comp++) {
            double k = comp < 2 ? b->bearing_k : b->torsion_k;
            if (k <= 0)
                continue;
            memset(c, 0, sizeof(double) * (size_t)nb3);
            c[3 * i + comp] = 1.0;
            add_spring(m, c, k, g);
        }
    }
    /* meshes: springs, or constraint rows (kinematic) */
    m->n_con = 0;
    m->G = gs_calloc((size_t)(s->n_meshes ? s->n_meshes : 1) * (size_t)n, sizeof(double));
    if (!m->G) {
        e = GS_ENOMEM;
        goto out;
    }
    for (int mi = 0; mi < s->n_meshes; mi++) {
        double k = 0;
        e = mesh_row(s, mi, c, &k, d);
        if (e != GS_OK)
            goto out;
        if (k >= 0) {
            add_spring(m, c, k, g);
            continue;
        }
        for (int j = 0; j < n; j++) { /* row-major n_con x n */
            double v = 0;
            for (int r = 0; r < nb3; r++)
                v += c[r] * TT(m, r, j);
            m->G[(size_t)m->n_con * n + j] = v;
        }
        m->n_con++;
    }
    e = GS_OK;
out:
    free(first), free(nc), free(c), free(g);
    return e;
}

/* Null space of the constraint rows (n x r, column-major) by SVD; r = n
 * when there are none. */
static double *null_space(const gs_modal *m, int *r)
{
    int n = m->n, k = m->n_con;
    double *N;
    if (k == 0) {
        N = gs_calloc((size_t)n * n, sizeof(double));
        for (int i = 0; N && i < n; i++)
            N[(size_t)i * n + i] = 1.0;
        *r = n;
        return N;
    }
    double *A = malloc(sizeof(double) * (size_t)k * n), *sv = malloc(sizeof(double) * (size_t)(k < n ? k : n));
    double *Vt = malloc(sizeof(double) * (size_t)n * n), *sup = malloc(sizeof(double) * (size_t)(k < n ? k : n));
    N = NULL;
    if (A && sv && Vt && sup) {
        memcpy(A, m->G, sizeof(double) * (size_t)k * n);
        if (LAPACKE_dgesvd(LAPACK_ROW_MAJOR, 'N', 'A', k, n, A, n, sv, NULL, 1, Vt, n, sup) == 0) {
            int rank = 0;
            for (int i = 0; i < (k < n ? k : n); i++)
                rank += sv[i] > 1e-12 * sv[0];
            *r = n - rank;
            N = gs_calloc((size_t)n * (size_t)(*r > 0 ? *r : 1), sizeof(double));
            for (int c = 0; N && c < *r; c++) /* rows rank.. of V' are the null space */
                for (int i = 0; i < n; i++)
                    N[(size_t)c * n + i] = Vt[(size_t)(rank + c) * n + i];
        }
    }
    free(A), free(sv), free(Vt), free(sup);
    return N;
}

static gs_err solve(gs_modal *m, gs_diag *d)
{
    int n = m->n, nb3 = 3 * m->n_bodies, r = 0;
    double *N = null_space(m, &r);
    if (!N)
        return GS_ENOMEM;
    if (r == 0) {
        free(N);
        return gs_diag_set(d, GS_ERANGE, "meshes", "the kinematic meshes lock the whole train: nothing can vibrate");
    }
    m->n_modes = r;
    size_t nr = (size_t)n * (size_t)r, rr = (size_t)r * (size_t)r;
    double *Kr = calloc(rr, sizeof(double)), *Mr = calloc(rr, sizeof(double)), *tmp = calloc(nr, sizeof(double));
    m->shape = calloc(nr, sizeof(double));
    m->omega2 = calloc((size_t)r, sizeof(double));
    m->freq_hz = calloc((size_t)r, sizeof(double));
    m->body_shape = calloc((size_t)nb3 * (size_t)r, sizeof(double));
    if (!Kr || !Mr || !tmp || !m->shape || !m->omega2 || !m->freq_hz || !m->body_shape) {
        free(N), free(Kr), free(Mr), free(tmp);
        return GS_ENOMEM;
    }
    /* reduced matrices N' K N, N' M N */
    for (int pass = 0; pass < 2; pass++) {
        const double *A = pass ? m->M : m->K;
        double *R = pass ? Mr : Kr;
        for (int c = 0; c < r; c++)
            for (int i = 0; i < n; i++) {
                double v = 0;
                for (int j = 0; j < n; j++)
                    v += A[(size_t)j * n + i] * N[(size_t)c * n + j];
                tmp[(size_t)c * n + i] = v;
            }
        for (int c = 0; c < r; c++)
            for (int a = 0; a < r; a++) {
                double v = 0;
                for (int i = 0; i < n; i++)
                    v += N[(size_t)a * n + i] * tmp[(size_t)c * n + i];
                R[(size_t)c * r + a] = v;
            }
    }
    lapack_int info = LAPACKE_dsygv(LAPACK_COL_MAJOR, 1, 'V', 'U', r, Kr, r, Mr, r, m->omega2);
    if (info != 0) {
        free(N), free(Kr), free(Mr), free(tmp);
        return gs_diag_set(d, GS_ESINGULAR, "bodies",
                           "the generalised eigenproblem failed (dsygv info %d): a moving body without mass?",
                           (int)info);
    }
    for (int j = 0; j < r; j++) {
        for (int i = 0; i < n; i++) {
            double v = 0;
            for (int c = 0; c < r; c++)
                v += N[(size_t)c * n + i] * Kr[(size_t)j * r + c];
            m->shape[(size_t)j * n + i] = v;
        }
        m->freq_hz[j] = sqrt(m->omega2[j] > 0 ? m->omega2[j] : 0.0) / (2 * GS_PI);
        for (int q = 0; q < nb3; q++) {
            double v = 0;
            for (int i = 0; i < n; i++)
                v += TT(m, q, i) * m->shape[(size_t)j * n + i];
            m->body_shape[(size_t)j * nb3 + q] = v;
        }
    }
    free(N), free(Kr), free(Mr), free(tmp);
    return GS_OK;
}

static gs_err classify(const gs_scene *s, gs_modal *m)
{
    int n = m->n_modes, nb = m->n_bodies;
    m->group = calloc((size_t)n, sizeof(int));
    m->group_first = calloc((size_t)n, sizeof(int));
    m->group_mult = calloc((size_t)n, sizeof(int));
    m->group_kind = calloc((size_t)n, sizeof(int));
    m->group_central = calloc((size_t)n, sizeof(double));
    if (!m->group || !m->group_first || !m->group_mult || !m->group_kind || !m->group_central)
        return GS_ENOMEM;
    double wmax = 2 * GS_PI * m->freq_hz[n - 1];
    int G = 0;
    for (int j = 0; j < n; j++) {
        if (j == 0 || 2 * GS_PI * (m->freq_hz[j] - m->freq_hz[j - 1]) > GS_MODAL_GROUP_TOL * wmax) {
            m->group_first[G] = j;
            G++;
        }
        m->group[j] = G - 1;
        m->group_mult[G - 1]++;
    }
    m->n_groups = G;
    for (int gi = 0; gi < G; gi++) {
        double ct = 0, cr = 0, tot = 0;
        for (int j = m->group_first[gi]; j < m->group_first[gi] + m->group_mult[gi]; j++) {
            const double *bs = m->body_shape + (size_t)j * 3 * nb;
            for (int i = 0; i < nb; i++) {
                const gs_scene_body *b = &s->bodies[i];
                double t = b->mass * (bs[3 * i] * bs[3 * i] + bs[3 * i + 1] * bs[3 * i + 1]);
                double r = b->inertia * bs[3 * i + 2] * bs[3 * i + 2];
                tot += t + r;
                if (b->joint != GS_JOINT_ON_CARRIER)
                    ct += t, cr += r;
            }
        }
        const double tol = 1e-8;
        double central = tot > 0 ? (ct + cr) / tot : 0;
        m->group_central[gi] = central;
        int kind = GS_MODE_MIXED;
        if (central < tol)
            kind = GS_MODE_PLANET;
        else if (cr <= tol * (ct + cr))
            kind = GS_MODE_TRANSLATIONAL;
        else if (ct <= tol * (ct + cr))
            kind = GS_MODE_ROTATIONAL;
        m->group_kind[gi] = kind;
    }
    return GS_OK;
}

gs_err gs_modal_analyse(const gs_scene *s, gs_modal **out, gs_diag *d)
{
    *out = NULL;
    gs_modal *m = gs_calloc(1, sizeof *m);
    if (!m)
        return GS_ENOMEM;
    gs_err e = build(s, m, d);
    if (e == GS_OK)
        e = solve(m, d);
    if (e == GS_OK)
        e = classify(s, m);
    if (e != GS_OK) {
        if (e == GS_ENOMEM && !d->message[0])
            gs_diag_set(d, GS_ENOMEM, "bodies", "out of memory in the modal analysis");
        gs_modal_free(&m);
        return e;
    }
    *out = m;
    return GS_OK;
}

json_object *gs_modal_json(const gs_modal *m, const gs_scene *s)
{
    int n = m->n_modes, nb = m->n_bodies;
    json_object *o = json_object_new_object();
    json_object_object_add(o, "scene", json_object_new_string(s->name));
    json_object_object_add(o, "dof", json_object_new_int(m->n));
    json_object_object_add(o, "constraints", json_object_new_int(m->n - n));
    json_object *counts = json_object_new_object();
    int cnt[4] = {0, 0, 0, 0};
    for (int g = 0; g < m->n_groups; g++)
        cnt[m->group_kind[g]]++;
    for (int k = 0; k < 4; k++)
        json_object_object_add(counts, gs_mode_kind_name(k), json_object_new_int(cnt[k]));
    json_object_object_add(o, "groups_by_kind", counts);
    json_object *groups = json_object_new_array();
    for (int g = 0; g < m->n_groups; g++) {
        json_object *x = json_object_new_object();
        int j0 = m->group_first[g];
        double f = 0;
        for (int j = j0; j < j0 + m->group_mult[g]; j++)
            f += m->freq_hz[j];
        f /= m->group_mult[g];
        json_object_object_add(x, "frequency_hz", json_object_new_double(f));
        json_object_object_add(x, "kind", json_object_new_string(gs_mode_kind_name(m->group_kind[g])));
        json_object_object_add(x, "multiplicity", json_object_new_int(m->group_mult[g]));
        json_object_object_add(x, "central_energy", json_object_new_double(m->group_central[g]));
        json_object_object_add(x, "first_mode", json_object_new_int(j0));
        json_object_array_add(groups, x);
    }
    json_object_object_add(o, "groups", groups);
    json_object *modes = json_object_new_array();
    for (int j = 0; j < n; j++) {
        const double *bs = m->body_shape + (size_t)j * 3 * nb;
        /* scale: largest of |x|, |y|, |lever * theta| is 1, positive */
        double big = 0, sgn = 1;
        for (int i = 0; i < nb; i++)
            for (int r = 0; r < 3; r++) {
                double v = r < 2 ? bs[3 * i + r] : bs[3 * i + 2] * m->lever[i];
                if (fabs(v) > big * (1 + 1e-9))
                    big = fabs(v), sgn = v < 0 ? -1 : 1;
            }
        double sc = big > 0 ? sgn / big : 1;
        json_object *x = json_object_new_object();
        json_object_object_add(x, "index", json_object_new_int(j));
        json_object_object_add(x, "frequency_hz", json_object_new_double(m->freq_hz[j]));
        json_object_object_add(x, "group", json_object_new_int(m->group[j]));
        json_object_object_add(x, "kind", json_object_new_string(gs_mode_kind_name(m->group_kind[m->group[j]])));
        json_object *sh = json_object_new_array();
        for (int i = 0; i < nb; i++) {
            const gs_scene_body *b = &s->bodies[i];
            json_object *e = json_object_new_object();
            json_object_object_add(e, "body", json_object_new_string(b->name));
            double X = sc * bs[3 * i], Y = sc * bs[3 * i + 1], th = sc * bs[3 * i + 2];
            json_object_object_add(e, "x", json_object_new_double(X));
            json_object_object_add(e, "y", json_object_new_double(Y));
            json_object_object_add(e, "theta", json_object_new_double(th));
            json_object_object_add(e, "u", json_object_new_double(th * m->lever[i]));
            if (b->joint == GS_JOINT_ON_CARRIER) {
                double cp[2], cc[2];
                gs_scene_body_centre(s, i, cp);
                gs_scene_body_centre(s, b->carrier, cc);
                double psi = atan2(cp[1] - cc[1], cp[0] - cc[0]);
                json_object_object_add(e, "radial", json_object_new_double(X * cos(psi) + Y * sin(psi)));
                json_object_object_add(e, "tangential", json_object_new_double(-X * sin(psi) + Y * cos(psi)));
            }
            json_object_array_add(sh, e);
        }
        json_object_object_add(x, "shape", sh);
        json_object_array_add(modes, x);
    }
    json_object_object_add(o, "modes", modes);
    json_object *bodies = json_object_new_array();
    for (int i = 0; i < nb; i++) {
        double c2[2];
        gs_scene_body_centre(s, i, c2);
        json_object *e = json_object_new_object();
        json_object_object_add(e, "name", json_object_new_string(s->bodies[i].name));
        json_object *cc = json_object_new_array();
        json_object_array_add(cc, json_object_new_double(c2[0]));
        json_object_array_add(cc, json_object_new_double(c2[1]));
        json_object_object_add(e, "centre", cc);
        json_object_object_add(e, "radius", json_object_new_double(m->lever[i]));
        json_object_object_add(e, "on_carrier", json_object_new_boolean(s->bodies[i].joint == GS_JOINT_ON_CARRIER));
        json_object_array_add(bodies, e);
    }
    json_object_object_add(o, "bodies", bodies);
    return o;
}
