/* SPDX-License-Identifier: MIT
 * The FE model of a body's elastic part (METHOD.md section 1): linear or
 * quadratic triangles (element operations in fe_element.c), consistent mass, the angular coupling vector s, the inertias,
 * elimination of the fixed (core interface) nodes, assembly into one
 * compressed-column pattern shared by K and M; static solve and stress
 * recovery. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include <cholmod.h>

#include "fe/fe_internal.h"
#include "gearsim/util.h"

/* ---- element kernels ---------------------------------------------------- */

/* Constitutive matrix (row-major 3x3) for (eps_xx, eps_yy, gamma_xy). */
static void material_matrix(const gs_material *mat, double D[9])
{
    double E = mat->youngs_pa, nu = mat->poisson;
    memset(D, 0, 9 * sizeof *D);
    if (mat->plane == GS_PLANE_STRAIN) {
        double f = E / ((1.0 + nu) * (1.0 - 2.0 * nu));
        D[0] = D[4] = f * (1.0 - nu);
        D[1] = D[3] = f * nu;
        D[8] = f * (1.0 - 2.0 * nu) / 2.0;
    } else {
        double f = E / (1.0 - nu * nu);
        D[0] = D[4] = f;
        D[1] = D[3] = f * nu;
        D[8] = f * (1.0 - nu) / 2.0;
    }
}

/* ---- pattern ------------------------------------------------------------ */

static int cmp_index(const void *a, const void *b)
{
    gs_index x = *(const gs_index *)a, y = *(const gs_index *)b;
    return (x > y) - (x < y);
}

/* For every free node k, the sorted distinct free neighbours j <= k (itself
 * included, last): nbp[k] .. nbp[k+1] in nb. */
static gs_err node_graph(gs_fe_model *m, gs_index **nbp_out, gs_index **nb_out)
{
    gs_index nf = m->n_free_nodes;
    gs_index *cnt = gs_calloc((size_t)nf + 1, sizeof *cnt);
    if (!cnt)
        return GS_ENOMEM;
    const int nn = m->nn;
    for (gs_index e = 0; e < m->n_tris; e++)
        for (int i = 0; i < nn; i++)
            for (int j = 0; j < nn; j++) {
                gs_index fa = m->dof[2 * m->en[nn * e + i]], fb = m->dof[2 * m->en[nn * e + j]];
                if (fa >= 0 && fb >= 0 && fa <= fb && (fa < fb || i == j))
                    cnt[fb / 2 + 1]++;
            }
    for (gs_index k = 0; k < nf; k++)
        cnt[k + 1] += cnt[k];
    gs_index *raw = gs_calloc((size_t)cnt[nf], sizeof *raw);
    gs_index *pos = gs_calloc((size_t)nf + 1, sizeof *pos);
    if (!raw || !pos) {
        free(cnt);
        free(raw);
        free(pos);
        return GS_ENOMEM;
    }
    memcpy(pos, cnt, (size_t)nf * sizeof *pos);
    for (gs_index e = 0; e < m->n_tris; e++)
        for (int i = 0; i < nn; i++)
            for (int j = 0; j < nn; j++) {
                gs_index fa = m->dof[2 * m->en[nn * e + i]], fb = m->dof[2 * m->en[nn * e + j]];
                if (fa >= 0 && fb >= 0 && fa <= fb && (fa < fb || i == j))
                    raw[pos[fb / 2]++] = fa / 2;
            }
    /* sort, drop duplicates, compact in place */
    gs_index w = 0;
    for (gs_index k = 0; k < nf; k++) {
        gs_index a = cnt[k], z = cnt[k + 1];
        qsort(raw + a, (size_t)(z - a), sizeof *raw, cmp_index);
        cnt[k] = w;
        for (gs_index p = a; p < z; p++)
            if (p == a || raw[p] != raw[p - 1])
                raw[w++] = raw[p];
    }
    cnt[nf] = w;
    free(pos);
    for (gs_index k = 0; k < nf; k++)
        if (cnt[k + 1] == cnt[k]) { /* a free node in no element has no mass */
            free(cnt);
            free(raw);
            return GS_EGEOMETRY;
        }
    *nbp_out = cnt;
    *nb_out = raw;
    return GS_OK;
}

static gs_index find_neighbour(const gs_index *nb, gs_index lo, gs_index hi, gs_index key)
{
    while (lo < hi) {
        gs_index mid = lo + (hi - lo) / 2;
        if (nb[mid] < key)
            lo = mid + 1;
        else
            hi = mid;
    }
    return lo;
}

/* ---- model -------------------------------------------------------------- */

static gs_err check_inputs(const gs_mesh *mesh, const gs_material *mat, double t, double core)
{
    if (!mesh || !mat || !mesh->xy || (mesh->n_tris > 0 && !mesh->tri) ||
        (mesh->n_fixed > 0 && !mesh->fixed))
        return GS_EINVAL;
    if (mesh->n_nodes < 1 || mesh->n_tris < 1 || mesh->n_fixed < 0)
        return GS_EINVAL;
    if (!(isfinite(mat->youngs_pa) && mat->youngs_pa > 0) ||
        !(isfinite(mat->density) && mat->density > 0) ||
        !(mat->poisson > -1.0 && mat->poisson < 0.5) ||
        (mat->plane != GS_PLANE_STRESS && mat->plane != GS_PLANE_STRAIN) ||
        !(isfinite(mat->damping_s) && mat->damping_s >= 0) ||
        !(isfinite(mat->damping_m) && mat->damping_m >= 0))
        return GS_EINVAL;
    if (!(isfinite(t) && t > 0) || !(isfinite(core) && core >= 0))
        return GS_EINVAL;
    for (gs_index i = 0; i < 2 * mesh->n_nodes; i++)
        if (!isfinite(mesh->xy[i]))
            return GS_EINVAL;
    for (gs_index i = 0; i < 3 * mesh->n_tris; i++)
        if (mesh->tri[i] < 0 || mesh->tri[i] >= mesh->n_nodes ||
            (mesh->mid && (mesh->mid[i] < 0 || mesh->mid[i] >= mesh->n_nodes)))
            return GS_EINVAL;
    for (gs_index i = 0; i < mesh->n_fixed; i++)
        if (mesh->fixed[i] < 0 || mesh->fixed[i] >= mesh->n_nodes)
            return GS_EINVAL;
    return GS_OK;
}

void gs_fe_model_free(gs_fe_model **pm)
{
    if (!pm || !*pm)
        return;
    gs_fe_model *m = *pm;
    free(m->xy);
    free(m->en);
    free(m->dof);
    free(m->free_node);
    free(m->col_order);
    free(m->col_pos);
    free(m->colp);
    free(m->rowi);
    free(m->kx);
    free(m->mx);
    free(m->pass_nb);
    free(m->s);
    free(m);
    *pm = NULL;
}

/* gs_fe_model.col_order, col_pos and n_col_boundary (see there). */
static gs_err column_order(gs_fe_model *m, const gs_mesh *mesh)
{
    gs_index nf = m->n_free_nodes, n = 0;
    m->col_order = gs_calloc((size_t)nf + 1, sizeof *m->col_order);
    m->col_pos = gs_calloc((size_t)nf + 1, sizeof *m->col_pos);
    if (!m->col_order || !m->col_pos)
        return GS_ENOMEM;
    for (gs_index k = 0; k < nf; k++)
        m->col_pos[k] = -1;
    for (gs_index i = 0; mesh->boundary && i < mesh->n_boundary; i++) {
        gs_index node = mesh->boundary[i];
        if (node < 0 || node >= m->n_nodes || m->dof[2 * node] < 0)
            continue;
        gs_index k = m->dof[2 * node] / 2;
        if (m->col_pos[k] < 0) {
            m->col_pos[k] = n;
            m->col_order[n++] = k;
        }
    }
    m->n_col_boundary = n;
    for (gs_index k = 0; k < nf; k++)
        if (m->col_pos[k] < 0) {
            m->col_pos[k] = n;
            m->col_order[n++] = k;
        }
    return GS_OK;
}

/* gs_fe_model.pass_nb from the pattern: left NULL when a node's two
 * columns are not in the layout pass_node reads (they always are, from
 * assemble) or a node index does not fit in 32 bits. */
static gs_err pass_nodes(gs_fe_model *m)
{
    const gs_index *cp = m->colp, *ri = m->rowi;
    if (m->ne % 2 || m->n_free_nodes > INT32_MAX)
        return GS_OK;
    int32_t *nb = gsi_huge_calloc((size_t)m->nnz / 4 + 1, sizeof *nb); /* (nnz - 3 nodes) / 4 */
    if (!nb)
        return GS_ENOMEM;
    gs_index o = 0;
    for (gs_index j = 0; j < m->ne; j += 2) {
        gs_index a = cp[j], len = cp[j + 1] - 1 - a;
        bool ok = len % 2 == 0 && cp[j + 2] - cp[j + 1] == len + 2 && ri[cp[j + 2] - 2] == j;
        for (gs_index t = 0; ok && t < len; t += 2) {
            ok = ri[a + t] % 2 == 0 && ri[a + t + 1] == ri[a + t] + 1 && ri[a + t] < j &&
                 ri[cp[j + 1] + t] == ri[a + t] && ri[cp[j + 1] + t + 1] == ri[a + t + 1];
            nb[o++] = (int32_t)(ri[a + t] / 2);
        }
        if (!ok) {
            free(nb);
            return GS_OK;
        }
    }
    m->pass_nb = nb;
    return GS_OK;
}

static gs_err assemble(gs_fe_model *m)
{
    gs_index *nbp = NULL, *nb = NULL;
    GS_TRY(node_graph(m, &nbp, &nb));
    gs_index nf = m->n_free_nodes, ne = m->ne;
    gs_err err = GS_ENOMEM;
    m->colp = gs_calloc((size_t)ne + 1, sizeof *m->colp);
    if (!m->colp)
        goto out;
    for (gs_index k = 0; k < nf; k++) {
        gs_index len = nbp[k + 1] - nbp[k];
        m->colp[2 * k + 1] = m->colp[2 * k] + 2 * len - 1;
        m->colp[2 * k + 2] = m->colp[2 * k + 1] + 2 * len;
    }
    m->nnz = m->colp[ne];
    m->rowi = gsi_huge_calloc((size_t)m->nnz, sizeof *m->rowi);
    m->kx = gsi_huge_calloc((size_t)m->nnz, sizeof *m->kx);
    m->mx = gsi_huge_calloc((size_t)m->nnz, sizeof *m->mx);
    m->s = gs_calloc((size_t)ne, sizeof *m->s);
    if (!m->rowi || !m->kx || !m->mx || !m->s)
        goto out;
    for (gs_index k = 0; k < nf; k++)
        for (gs_index p = nbp[k]; p < nbp[k + 1]; p++) {
            gs_index j = nb[p], o = 2 * (p - nbp[k]);
            m->rowi[m->colp[2 * k] + o] = 2 * j;
            if (j != k)
                m->rowi[m->colp[2 * k] + o + 1] = 2 * j + 1;
            m->rowi[m->colp[2 * k + 1] + o] = 2 * j;
            m->rowi[m->colp[2 * k + 1] + o + 1] = 2 * j + 1;
        }

    const double rho = m->mat.density, t = m->thickness;
    const int nn = m->nn;
    double sx = 0, sy = 0;
    for (gs_index e = 0; e < m->n_tris; e++) {
        const gs_index *tn = m->en + nn * e;
        double ke[144], me[36], X[6], Y[6];
        gsi_fe_props pr;
        for (int i = 0; i < nn; i++) {
            X[i] = m->xy[2 * tn[i]];
            Y[i] = m->xy[2 * tn[i] + 1];
            for (int j = 0; j < i; j++)
                if (tn[i] == tn[j]) {
                    err = GS_EGEOMETRY;
                    goto out;
                }
        }
        err = m->el->matrices(X, Y, m->Dmat, t, rho, ke, me, &pr);
        if (err != GS_OK)
            goto out;
        m->area += pr.area;
        sx += pr.mx;
        sy += pr.my;
        m->inertia_elastic += pr.polar;
        for (int i = 0; i < nn; i++) {
            gs_index fi = m->dof[2 * tn[i]];
            if (fi < 0)
                continue;
            m->s[fi] += pr.s[2 * i];
            m->s[fi + 1] += pr.s[2 * i + 1];
        }

        for (int i = 0; i < nn; i++)
            for (int j = 0; j < nn; j++) {
                gs_index fa = m->dof[2 * tn[i]], fb = m->dof[2 * tn[j]];
                if (fa < 0 || fb < 0 || fa > fb || (fa == fb && i != j))
                    continue;
                gs_index kb = fb / 2;
                gs_index p = find_neighbour(nb, nbp[kb], nbp[kb + 1], fa / 2) - nbp[kb];
                double mij = me[nn * i + j];
                for (int cj = 0; cj < 2; cj++)
                    for (int ci = 0; ci < 2; ci++) {
                        if (fa == fb && ci > cj)
                            continue;
                        gs_index q = m->colp[fb + cj] + 2 * p + ci;
                        m->kx[q] += ke[(2 * i + ci) * 2 * nn + 2 * j + cj];
                        if (ci == cj)
                            m->mx[q] += mij;
                    }
            }
    }
    m->mass = rho * t * m->area;
    m->centroid[0] = sx / m->mass;
    m->centroid[1] = sy / m->mass;
    m->inertia_total = m->inertia_elastic + m->inertia_core;
    err = pass_nodes(m);
out:
    free(nbp);
    free(nb);
    return err;
}

gs_err gs_fe_model_new(const gs_mesh *mesh, const gs_material *mat, double thickness_m,
                       double core_inertia, gs_fe_model **out)
{
    if (!out)
        return GS_EINVAL;
    *out = NULL;
    GS_TRY(check_inputs(mesh, mat, thickness_m, core_inertia));
    if (mesh->n_fixed == 0 && core_inertia == 0)
        return GS_ESINGULAR; /* u could carry the whole rigid rotation */
    gs_fe_model *m = gs_calloc(1, sizeof *m);
    if (!m)
        return GS_ENOMEM;
    m->n_nodes = mesh->n_nodes;
    m->n_tris = mesh->n_tris;
    m->mat = *mat;
    m->thickness = thickness_m;
    m->inertia_core = core_inertia;
    material_matrix(mat, m->Dmat);
    m->xy = gs_calloc((size_t)(2 * m->n_nodes), sizeof *m->xy);
    m->el = gsi_fe_element_of(mesh);
    m->nn = m->el->nn;
    m->en = gs_calloc((size_t)(m->nn * m->n_tris), sizeof *m->en);
    m->dof = gs_calloc((size_t)(2 * m->n_nodes), sizeof *m->dof);
    m->free_node = gs_calloc((size_t)m->n_nodes, sizeof *m->free_node);
    if (!m->xy || !m->en || !m->dof || !m->free_node) {
        gs_fe_model_free(&m);
        return GS_ENOMEM;
    }
    memcpy(m->xy, mesh->xy, (size_t)(2 * m->n_nodes) * sizeof *m->xy);
    for (gs_index e = 0; e < m->n_tris; e++)
        for (int i = 0; i < 3; i++) {
            m->en[m->nn * e + i] = mesh->tri[3 * e + i];
            if (m->nn == 6)
                m->en[m->nn * e + 3 + i] = mesh->mid[3 * e + i];
        }
    for (gs_index i = 0; i < mesh->n_fixed; i++)
        m->dof[2 * mesh->fixed[i]] = -1;
    for (gs_index i = 0; i < m->n_nodes; i++) {
        if (m->dof[2 * i] < 0) {
            m->dof[2 * i + 1] = -1;
            continue;
        }
        m->free_node[m->n_free_nodes] = i;
        m->dof[2 * i] = 2 * m->n_free_nodes;
        m->dof[2 * i + 1] = 2 * m->n_free_nodes + 1;
        m->n_free_nodes++;
    }
    m->ne = 2 * m->n_free_nodes;
    gs_err e = column_order(m, mesh);
    if (e == GS_OK)
        e = assemble(m);
    if (e != GS_OK) {
        gs_fe_model_free(&m);
        return e;
    }
    *out = m;
    return GS_OK;
}

void gs_fe_model_get_info(const gs_fe_model *m, gs_fe_model_info *info)
{
    if (!m || !info)
        return;
    info->n_nodes = m->n_nodes;
    info->n_tris = m->n_tris;
    info->n_free_nodes = m->n_free_nodes;
    info->n_elastic = m->ne;
    info->nnz = m->nnz;
    info->area_m2 = m->area;
    info->mass_kg = m->mass;
    info->centroid[0] = m->centroid[0];
    info->centroid[1] = m->centroid[1];
    info->inertia_elastic = m->inertia_elastic;
    info->inertia_core = m->inertia_core;
    info->inertia_total = m->inertia_total;
}

gs_index gs_fe_model_dof(const gs_fe_model *m, gs_index node, int comp)
{
    if (!m || node < 0 || node >= m->n_nodes)
        return -1;
    return m->dof[2 * node + (comp != 0)];
}

void gs_fe_model_coupling(const gs_fe_model *m, double *s_out)
{
    if (m && s_out)
        memcpy(s_out, m->s, (size_t)m->ne * sizeof *s_out);
}

/* y += beta * K x only: the step's right-hand side, which reads one value
 * array instead of two. */
static void symv_k(const gs_fe_model *m, double beta, const double *x, double *y)
{
    const gs_index *cp = m->colp, *ri = m->rowi;
    const double *kx = m->kx;
    for (gs_index j = 0; j < m->ne; j++) {
        double bx = beta * x[j], acc = 0;
        gs_index end = cp[j + 1] - 1; /* diagonal last */
        for (gs_index p = cp[j]; p < end; p++) {
            gs_index i = ri[p];
            y[i] += kx[p] * bx;
            acc += kx[p] * x[i];
        }
        y[j] += beta * acc + kx[end] * bx;
    }
}

void gsi_fe_symv2(const gs_fe_model *m, double alpha, const double *xm, double beta,
                  const double *xk, double *y)
{
    if (alpha == 0) {
        symv_k(m, beta, xk, y);
        return;
    }
    const gs_index *cp = m->colp, *ri = m->rowi;
    const double *kx = m->kx, *mx = m->mx;
    for (gs_index j = 0; j < m->ne; j++) {
        double am = alpha * xm[j], bk = beta * xk[j], acc = 0;
        gs_index end = cp[j + 1] - 1; /* diagonal last */
        for (gs_index p = cp[j]; p < end; p++) {
            gs_index i = ri[p];
            y[i] += mx[p] * am + kx[p] * bk;
            acc += alpha * mx[p] * xm[i] + beta * kx[p] * xk[i];
        }
        y[j] += acc + mx[end] * am + kx[end] * bk;
    }
}

double gsi_fe_quadform(const gs_fe_model *m, double alpha, double beta, const double *x)
{
    const gs_index *cp = m->colp, *ri = m->rowi;
    double off = 0, diag = 0;
    for (gs_index j = 0; j < m->ne; j++) {
        gs_index end = cp[j + 1] - 1;
        double acc = 0;
        for (gs_index p = cp[j]; p < end; p++)
            acc += (alpha * m->mx[p] + beta * m->kx[p]) * x[ri[p]];
        off += acc * x[j];
        diag += (alpha * m->mx[end] + beta * m->kx[end]) * x[j] * x[j];
    }
    return diag + 2.0 * off;
}

void gsi_fe_quadform2(const gs_fe_model *m, const double *xm, const double *xk, double *qm, double *qk)
{
    const gs_index *cp = m->colp, *ri = m->rowi;
    const double *mx = m->mx, *kx = m->kx;
    double offm = 0, diagm = 0, offk = 0, diagk = 0;
    for (gs_index j = 0; j < m->ne; j++) {
        gs_index end = cp[j + 1] - 1;
        double am = 0, ak = 0;
        for (gs_index p = cp[j]; p < end; p++) {
            am += mx[p] * xm[ri[p]];
            ak += kx[p] * xk[ri[p]];
        }
        offm += am * xm[j];
        diagm += mx[end] * xm[j] * xm[j];
        offk += ak * xk[j];
        diagk += kx[end] * xk[j] * xk[j];
    }
    *qm = diagm + 2.0 * offm;
    *qk = diagk + 2.0 * offk;
}

/* The sums of gsi_fe_step_pass, kept in this order. */
typedef struct pass_sums {
    double offm, diagm, offk, diagk;
} pass_sums;

/* A column's end: its off-diagonal sums am (M) and ak (K) and its diagonal
 * entries md, kd against its own w_j, q_j. */
static inline void pass_close(pass_sums *restrict s, double am, double ak, double md, double kd, double wj, double qj)
{
    s->offm += am * wj;
    s->diagm += md * wj * wj;
    s->offk += ak * qj;
    s->diagk += kd * qj * qj;
}

/* The entry j of q, w at the start of column j. */
static inline void pass_entry(gs_index j, double h, const double *restrict delta, double *restrict q,
                              double *restrict w)
{
    q[j] += h * w[j] + delta[j];
    w[j] += 2.0 * delta[j] / h;
}

/* x_i = q_i + c w_i of the updated entries (formed where it is read, not
 * stored: the same value each time). */
#define PASS_X(i) (q[i] + c * w[i])

/* Column j alone (entry j already updated); the energy sums only when en
 * (a constant at each call: the compiler drops the M stream without). */
static inline __attribute__((always_inline)) void pass_column(const gs_fe_model *m, gs_index j,
                                                              const double *restrict q, const double *restrict w,
                                                              double c, double *restrict y,
                                                              pass_sums *restrict s, const bool en)
{
    const gs_index *restrict ri = m->rowi;
    const double *restrict mx = m->mx, *restrict kx = m->kx;
    gs_index end = m->colp[j + 1] - 1;
    double bx = -1.0 * PASS_X(j), acc = 0, am = 0, ak = 0;
    for (gs_index p = m->colp[j]; p < end; p++) {
        gs_index i = ri[p];
        double k = kx[p];
        y[i] += k * bx;
        acc += k * PASS_X(i);
        if (en) {
            am += mx[p] * w[i];
            ak += k * q[i];
        }
    }
    y[j] = 0.0 + (-1.0 * acc + kx[end] * bx);
    if (!en)
        return;
    pass_close(s, am, ak, mx[end], kx[end], w[j], q[j]);
}

/* Row i of the two columns of a node (pass_node): column j's entry ka and
 * column j + 1's kb. */
static inline __attribute__((always_inline)) void pass_row(gs_index i, double ka, double kb, double ma, double mb,
                                                           const double *restrict q, const double *restrict w,
                                                           double c, double *restrict y,
                                                           double bx0, double bx1, double *restrict acc,
                                                           const bool en)
{
    double xi = PASS_X(i);
    y[i] = (y[i] + ka * bx0) + kb * bx1;
    acc[0] += ka * xi;
    acc[1] += kb * xi;
    if (en) {
        double wi = w[i], qi = q[i];
        acc[2] += ma * wi;
        acc[3] += ka * qi;
        acc[4] += mb * wi;
        acc[5] += kb * qi;
    }
}

/* The two columns of free node k, j = 2k and j + 1, together: assemble()
 * lays out column j + 1 as the rows of column j (the node pairs above the
 * node) followed by row j, then its diagonal. Every sum and every entry of
 * y receives the same terms in the same order as column j then column
 * j + 1 one after the other (each y[i] gets column j's term first; y[j],
 * born at the end of column j, then column j + 1's), so the result is the
 * same bit for bit; the two columns' independent sums run interleaved, and
 * each row index and vector entry is read once for both. Without en, y
 * alone (the same entries: the energy sums never enter y). The rows come
 * in pairs 2l, 2l + 1 (the nodes l above the node): nb (the model's
 * pass_nb for this node) gives one 32-bit node index per pair instead of
 * two row indices, a quarter of the index stream. */
static inline __attribute__((always_inline)) void pass_node(const gs_fe_model *m, gs_index j, const int32_t *nb,
                                                            const double *restrict q, const double *restrict w,
                                                            double c, double *restrict y,
                                                            pass_sums *restrict s, const bool en)
{
    const double *restrict mx = m->mx, *restrict kx = m->kx;
    const gs_index a = m->colp[j], ea = m->colp[j + 1] - 1, b = m->colp[j + 1], eb = m->colp[j + 2] - 1;
    const gs_index len = ea - a;
    const double *restrict k0 = kx + a, *restrict k1 = kx + b, *restrict m0 = mx + a, *restrict m1 = mx + b;
    double bx0 = -1.0 * PASS_X(j), bx1 = -1.0 * PASS_X(j + 1);
    double acc[6] = {0, 0, 0, 0, 0, 0}; /* acc0, acc1, am0, ak0, am1, ak1 */
    for (gs_index t = 0; t < len; t += 2) {
        gs_index i = 2 * (gs_index)nb[t / 2];
        pass_row(i, k0[t], k1[t], en ? m0[t] : 0, en ? m1[t] : 0, q, w, c, y, bx0, bx1, acc, en);
        pass_row(i + 1, k0[t + 1], k1[t + 1], en ? m0[t + 1] : 0, en ? m1[t + 1] : 0, q, w, c, y, bx0, bx1, acc,
                 en);
    }
    y[j] = 0.0 + (-1.0 * acc[0] + kx[ea] * bx0);
    if (en) {
        pass_close(s, acc[2], acc[3], mx[ea], kx[ea], w[j], q[j]);
    }
    gs_index p = eb - 1; /* column j + 1, row j */
    y[j] += kx[p] * bx1;
    acc[1] += kx[p] * PASS_X(j);
    y[j + 1] = 0.0 + (-1.0 * acc[1] + kx[eb] * bx1);
    if (!en)
        return;
    acc[4] += mx[p] * w[j];
    acc[5] += kx[p] * q[j];
    pass_close(s, acc[4], acc[5], mx[eb], kx[eb], w[j + 1], q[j + 1]);
}

/* Nodes ahead of the pass whose K (and M) entries it asks the cache for:
 * K is streamed once a step, after the two solves have pushed it out, and
 * the hardware's own prefetch leaves the pass waiting on memory. In paired
 * rounds of the pair's step (docs/performance/index.md) 16 nodes
 * ahead took 2-4 % off the step against none (4 about the same, 64 less). */
enum { PASS_AHEAD = 16 };

/* Prefetch x[from, to) line by line (a hint: no value changes). */
static inline void pass_prefetch(const double *x, gs_index from, gs_index to)
{
    for (const char *p = (const char *)(x + from), *e = (const char *)(x + to); p < e; p += 64)
        __builtin_prefetch(p, 0, 3);
}

/* The pass with (en) or without the energy sums: by nodes along pass_nb,
 * or (a pattern not in node pairs) column by column. */
static inline __attribute__((always_inline)) void step_pass(const gs_fe_model *m, double h, double c,
                                                            const double *delta, double *q, double *w, double *y,
                                                            pass_sums *s, const bool en, const bool upd)
{
    const gs_index *cp = m->colp;
    if (!m->pass_nb) {
        for (gs_index j = 0; j < m->ne; j++) {
            if (upd)
                pass_entry(j, h, delta, q, w);
            pass_column(m, j, q, w, c, y, s, en);
        }
        return;
    }
    const int32_t *nb = m->pass_nb;
    for (gs_index j = 0; j + 1 < m->ne; j += 2) {
        const gs_index ja = j + 2 * PASS_AHEAD;
        if (ja + 2 <= m->ne) {
            pass_prefetch(m->kx, cp[ja], cp[ja + 2]);
            if (en)
                pass_prefetch(m->mx, cp[ja], cp[ja + 2]);
        }
        if (upd) {
            pass_entry(j, h, delta, q, w);
            pass_entry(j + 1, h, delta, q, w);
        }
        pass_node(m, j, nb, q, w, c, y, s, en);
        nb += (cp[j + 1] - 1 - cp[j]) / 2;
    }
}

#undef PASS_X

void gsi_fe_step_pass(const gs_fe_model *m, double h, double c, const double *delta, double *q,
                      double *w, double *y, double *qm, double *qk)
{
    pass_sums s = {0, 0, 0, 0};
    if (!qm || !qk) { /* no energies: K alone, the M stream not read */
        step_pass(m, h, c, delta, q, w, y, &s, false, true);
        return;
    }
    step_pass(m, h, c, delta, q, w, y, &s, true, true);
    *qm = s.diagm + 2.0 * s.offm;
    *qk = s.diagk + 2.0 * s.offk;
}

void gsi_fe_rhs_pass(const gs_fe_model *m, double c, const double *q, const double *w, double *y)
{
    pass_sums s = {0, 0, 0, 0};
    /* without upd the pass writes neither q nor w */
    step_pass(m, 0.0, c, NULL, (double *)q, (double *)w, y, &s, false, false);
}

gs_err gs_fe_model_dense(const gs_fe_model *m, double *K, double *M)
{
    if (!m)
        return GS_EINVAL;
    if (m->ne + 1 > 20000)
        return GS_ETOOBIG;
    gs_index n = m->ne + 1;
    if (K)
        memset(K, 0, (size_t)(n * n) * sizeof *K);
    if (M)
        memset(M, 0, (size_t)(n * n) * sizeof *M);
    for (gs_index j = 0; j < m->ne; j++)
        for (gs_index p = m->colp[j]; p < m->colp[j + 1]; p++) {
            gs_index i = m->rowi[p];
            if (K)
                K[i + j * n] = K[j + i * n] = m->kx[p];
            if (M)
                M[i + j * n] = M[j + i * n] = m->mx[p];
        }
    if (M) {
        for (gs_index i = 0; i < m->ne; i++)
            M[i + m->ne * n] = M[m->ne + i * n] = m->s[i];
        M[m->ne + m->ne * n] = m->inertia_total;
    }
    return GS_OK;
}

double gs_fe_model_energy(const gs_fe_model *m, const double *u_nodes)
{
    if (!m || !u_nodes)
        return 0;
    double *u = gs_calloc((size_t)m->ne, sizeof *u);
    double e = 0;
    if (u) {
        for (gs_index k = 0; k < m->n_free_nodes; k++) {
            u[2 * k] = u_nodes[2 * m->free_node[k]];
            u[2 * k + 1] = u_nodes[2 * m->free_node[k] + 1];
        }
        e = gsi_fe_quadform(m, 0.0, 1.0, u);
    }
    free(u);
    return 0.5 * e;
}

/* A CHOLMOD view of alpha M + beta K, allocated in common c. */
static cholmod_sparse *combined_matrix(const gs_fe_model *m, double alpha, double beta,
                                       cholmod_common *c)
{
    cholmod_sparse *A = cholmod_l_allocate_sparse((size_t)m->ne, (size_t)m->ne, (size_t)m->nnz,
                                                  1, 1, 1, CHOLMOD_REAL, c);
    if (!A)
        return NULL;
    SuiteSparse_long *Ap = A->p, *Ai = A->i;
    double *Ax = A->x;
    for (gs_index j = 0; j <= m->ne; j++)
        Ap[j] = m->colp[j];
    for (gs_index p = 0; p < m->nnz; p++) {
        Ai[p] = m->rowi[p];
        Ax[p] = alpha * m->mx[p] + beta * m->kx[p];
    }
    return A;
}

cholmod_sparse *gsi_fe_cholmod_matrix(const gs_fe_model *m, double alpha, double beta,
                                      cholmod_common *c)
{
    return combined_matrix(m, alpha, beta, c);
}

gs_err gs_fe_model_static(const gs_fe_model *m, const double *f_nodes, double *u_nodes)
{
    if (!m || !f_nodes || !u_nodes)
        return GS_EINVAL;
    memset(u_nodes, 0, (size_t)(2 * m->n_nodes) * sizeof *u_nodes);
    if (m->ne == 0)
        return GS_OK;
    cholmod_common c;
    gsi_cholmod_start(&c);
    gs_err err = GS_ENOMEM;
    cholmod_factor *L = NULL;
    cholmod_dense *B = NULL, *X = NULL;
    cholmod_sparse *K = combined_matrix(m, 0.0, 1.0, &c);
    if (!K)
        goto out;
    L = cholmod_l_analyze(K, &c);
    if (!L)
        goto out;
    if (!cholmod_l_factorize(K, L, &c) || c.status == CHOLMOD_NOT_POSDEF) {
        err = c.status == CHOLMOD_NOT_POSDEF ? GS_ESINGULAR : GS_ENOMEM;
        goto out;
    }
    /* A K that is singular in exact arithmetic (rigid motions not held) often
     * factorises with round-off pivots; the diagonal estimate of the
     * reciprocal condition number is then ~1e-16. */
    if (cholmod_l_rcond(L, &c) < 1e-13) {
        err = GS_ESINGULAR;
        goto out;
    }
    B = cholmod_l_zeros((size_t)m->ne, 1, CHOLMOD_REAL, &c);
    if (!B)
        goto out;
    double *bx = B->x;
    for (gs_index k = 0; k < m->n_free_nodes; k++) {
        bx[2 * k] = f_nodes[2 * m->free_node[k]];
        bx[2 * k + 1] = f_nodes[2 * m->free_node[k] + 1];
    }
    X = cholmod_l_solve(CHOLMOD_A, L, B, &c);
    if (!X)
        goto out;
    const double *xx = X->x;
    for (gs_index k = 0; k < m->n_free_nodes; k++) {
        u_nodes[2 * m->free_node[k]] = xx[2 * k];
        u_nodes[2 * m->free_node[k] + 1] = xx[2 * k + 1];
    }
    err = GS_OK;
out:
    cholmod_l_free_dense(&X, &c);
    cholmod_l_free_dense(&B, &c);
    cholmod_l_free_factor(&L, &c);
    cholmod_l_free_sparse(&K, &c);
    cholmod_l_finish(&c);
    return err;
}

/* Von Mises stress; plane strain includes sigma_zz = nu (sigma_xx + sigma_yy). */
static double von_mises(const double sg[3], bool strain, double nu)
{
    double sz = strain ? nu * (sg[0] + sg[1]) : 0.0;
    return sqrt(0.5 * ((sg[0] - sg[1]) * (sg[0] - sg[1]) + (sg[1] - sz) * (sg[1] - sz) +
                       (sz - sg[0]) * (sz - sg[0])) +
                3.0 * sg[2] * sg[2]);
}

gs_err gs_fe_model_stress(const gs_fe_model *m, const double *u_nodes, double *stress,
                          double *vm_elem, double *vm_node)
{
    if (!m || !u_nodes)
        return GS_EINVAL;
    double *wsum = NULL;
    if (vm_node) {
        wsum = gs_calloc((size_t)m->n_nodes, sizeof *wsum);
        if (!wsum)
            return GS_ENOMEM;
        memset(vm_node, 0, (size_t)m->n_nodes * sizeof *vm_node);
    }
    const double nu = m->mat.poisson;
    const int nn = m->nn;
    for (gs_index e = 0; e < m->n_tris; e++) {
        const gs_index *tn = m->en + nn * e;
        double X[6], Y[6], ue[12], sn[18], sg[3], area;
        for (int i = 0; i < nn; i++) {
            bool fixed = m->dof[2 * tn[i]] < 0;
            X[i] = m->xy[2 * tn[i]];
            Y[i] = m->xy[2 * tn[i] + 1];
            ue[2 * i] = fixed ? 0.0 : u_nodes[2 * tn[i]];
            ue[2 * i + 1] = fixed ? 0.0 : u_nodes[2 * tn[i] + 1];
        }
        m->el->stress(X, Y, m->Dmat, ue, sn, sg, &area);
        if (stress)
            memcpy(stress + 3 * e, sg, sizeof sg);
        if (vm_elem)
            vm_elem[e] = von_mises(sg, m->mat.plane == GS_PLANE_STRAIN, nu);
        if (vm_node)
            for (int i = 0; i < nn; i++) {
                vm_node[tn[i]] += area * von_mises(sn + 3 * i, m->mat.plane == GS_PLANE_STRAIN, nu);
                wsum[tn[i]] += area;
            }
    }
    if (vm_node)
        for (gs_index i = 0; i < m->n_nodes; i++)
            vm_node[i] = wsum[i] > 0 ? vm_node[i] / wsum[i] : 0.0;
    free(wsum);
    return GS_OK;
}
