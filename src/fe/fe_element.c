/* SPDX-License-Identifier: MIT
 * Element implementations behind gsi_fe_element (fe_internal.h): the linear
 * constant-strain triangle (closed forms) and the 6-node isoparametric
 * quadratic triangle (12-point Dunavant rule of degree 6: exact for the
 * consistent mass and the inertia of a curved element, whose Jacobian is
 * quadratic; docs/explanation/elastic_body.md "Quadratic elements"). */
#include <math.h>
#include <string.h>

#include "fe/fe_internal.h"
#include "mesh/mesh_internal.h"

/* ---- linear triangle ---------------------------------------------------- */

/* Shape function derivatives: dN_i/dx = b[i] / (2A), dN_i/dy = c[i] / (2A).
 * Returns 2A (positive when counter-clockwise). */
static double cst_geometry(const double *x, const double *y, double b[3], double c[3])
{
    for (int i = 0; i < 3; i++) {
        int j = (i + 1) % 3, k = (i + 2) % 3;
        b[i] = y[j] - y[k];
        c[i] = x[k] - x[j];
    }
    return (x[1] - x[0]) * (y[2] - y[0]) - (x[2] - x[0]) * (y[1] - y[0]);
}

/* Strain-displacement matrix B (3 x 2n, row-major) from shape function
 * derivatives dNx, dNy of n nodes. */
static void strain_matrix(int n, const double *dNx, const double *dNy, double *B)
{
    memset(B, 0, (size_t)(6 * n) * sizeof *B);
    for (int i = 0; i < n; i++) {
        B[0 * 2 * n + 2 * i] = dNx[i];
        B[1 * 2 * n + 2 * i + 1] = dNy[i];
        B[2 * 2 * n + 2 * i] = dNy[i];
        B[2 * 2 * n + 2 * i + 1] = dNx[i];
    }
}

/* ke += w B^T D B (2n x 2n row-major). */
static void add_btdb(int n, const double *B, const double D[9], double w, double *ke)
{
    int nd = 2 * n;
    double DB[3 * 12];
    for (int r = 0; r < 3; r++)
        for (int k = 0; k < nd; k++)
            DB[r * nd + k] = D[r * 3] * B[k] + D[r * 3 + 1] * B[nd + k] + D[r * 3 + 2] * B[2 * nd + k];
    for (int i = 0; i < nd; i++)
        for (int j = 0; j < nd; j++)
            ke[i * nd + j] += w * (B[i] * DB[j] + B[nd + i] * DB[nd + j] + B[2 * nd + i] * DB[2 * nd + j]);
}

static void stress_of(const double D[9], const double *B, int n, const double *ue, double sg[3])
{
    double eps[3] = {0, 0, 0};
    for (int r = 0; r < 3; r++)
        for (int k = 0; k < 2 * n; k++)
            eps[r] += B[r * 2 * n + k] * ue[k];
    for (int r = 0; r < 3; r++)
        sg[r] = D[3 * r] * eps[0] + D[3 * r + 1] * eps[1] + D[3 * r + 2] * eps[2];
}

/* Squared longest corner-to-corner edge (the scale of the degeneracy test). */
static double longest_edge2(const double *x, const double *y)
{
    double w2 = 0;
    for (int i = 0; i < 3; i++) {
        double ex = x[(i + 1) % 3] - x[i], ey = y[(i + 1) % 3] - y[i];
        if (ex * ex + ey * ey > w2)
            w2 = ex * ex + ey * ey;
    }
    return w2;
}

static gs_err cst_matrices(const double *x, const double *y, const double D[9], double t,
                           double rho, double *ke, double *me, gsi_fe_props *pr)
{
    double b[3], c[3], B[18], dNx[3], dNy[3];
    double twoA = cst_geometry(x, y, b, c);
    double w2 = longest_edge2(x, y);
    if (!(twoA > 1e-12 * w2))
        return GS_EGEOMETRY;
    for (int i = 0; i < 3; i++) {
        dNx[i] = b[i] / twoA;
        dNy[i] = c[i] / twoA;
    }
    double A = 0.5 * twoA;
    strain_matrix(3, dNx, dNy, B);
    memset(ke, 0, 36 * sizeof *ke);
    add_btdb(3, B, D, t * A, ke);
    double mfac = rho * t * A / 12.0; /* consistent mass: mfac (1 + delta_ij) */
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            me[3 * i + j] = i == j ? 2.0 * mfac : mfac;
    /* mass properties from the nodal interpolation, exact for linear X */
    double Xs = x[0] + x[1] + x[2], Ys = y[0] + y[1] + y[2];
    pr->area = A;
    pr->mx = rho * t * A * Xs / 3.0;
    pr->my = rho * t * A * Ys / 3.0;
    pr->polar = mfac * (x[0] * x[0] + x[1] * x[1] + x[2] * x[2] + y[0] * y[0] + y[1] * y[1] +
                        y[2] * y[2] + Xs * Xs + Ys * Ys);
    for (int i = 0; i < 3; i++) { /* s_i = sum_j m_ij J X_j, J X = (-Y, X) */
        pr->s[2 * i] = mfac * (-y[i] - Ys);
        pr->s[2 * i + 1] = mfac * (x[i] + Xs);
    }
    return GS_OK;
}

static void cst_stress(const double *x, const double *y, const double D[9], const double *ue,
                       double *sn, double *sc, double *area)
{
    double b[3], c[3], B[18], dNx[3], dNy[3];
    double twoA = cst_geometry(x, y, b, c);
    for (int i = 0; i < 3; i++) {
        dNx[i] = b[i] / twoA;
        dNy[i] = c[i] / twoA;
    }
    strain_matrix(3, dNx, dNy, B);
    stress_of(D, B, 3, ue, sc);
    for (int i = 0; i < 3; i++)
        memcpy(sn + 3 * i, sc, 3 * sizeof *sc);
    *area = 0.5 * twoA;
}

const gsi_fe_element gsi_fe_tri3 = {"tri3", 3, cst_matrices, cst_stress};

/* ---- quadratic triangle ------------------------------------------------- */

/* Node order and shape functions: gsi_t6_shape (mesh/mesh_internal.h). */

/* Dunavant's 12-point rule, degree 6; weights sum to 1 (times the area). */
static const double q12[12][3] = {
    {0.249286745170910, 0.249286745170910, 0.116786275726379},
    {0.249286745170910, 0.501426509658179, 0.116786275726379},
    {0.501426509658179, 0.249286745170910, 0.116786275726379},
    {0.063089014491502, 0.063089014491502, 0.050844906370207},
    {0.063089014491502, 0.873821971016996, 0.050844906370207},
    {0.873821971016996, 0.063089014491502, 0.050844906370207},
    {0.310352451033784, 0.636502499121399, 0.082851075618374},
    {0.636502499121399, 0.053145049844817, 0.082851075618374},
    {0.053145049844817, 0.310352451033784, 0.082851075618374},
    {0.636502499121399, 0.310352451033784, 0.082851075618374},
    {0.310352451033784, 0.053145049844817, 0.082851075618374},
    {0.053145049844817, 0.636502499121399, 0.082851075618374},
};

static gs_err t6_matrices(const double *x, const double *y, const double D[9], double t,
                          double rho, double *ke, double *me, gsi_fe_props *pr)
{
    double N[6], dNx[6], dNy[6], B[36];
    double det0 = gsi_t6_jacobian(x, y, 1.0 / 3, 1.0 / 3, N, dNx, dNy);
    double w2 = longest_edge2(x, y);
    if (!(det0 > 1e-12 * w2))
        return GS_EGEOMETRY;
    memset(ke, 0, 144 * sizeof *ke);
    memset(me, 0, 36 * sizeof *me);
    memset(pr, 0, sizeof *pr);
    for (int q = 0; q < 12; q++) {
        double det = gsi_t6_jacobian(x, y, q12[q][0], q12[q][1], N, dNx, dNy);
        if (!(det > 1e-3 * det0))
            return GS_EGEOMETRY;
        double w = 0.5 * q12[q][2] * det; /* area element */
        strain_matrix(6, dNx, dNy, B);
        add_btdb(6, B, D, t * w, ke);
        double X = 0, Y = 0;
        for (int i = 0; i < 6; i++) {
            X += N[i] * x[i];
            Y += N[i] * y[i];
        }
        for (int i = 0; i < 6; i++)
            for (int j = 0; j < 6; j++)
                me[6 * i + j] += rho * t * w * N[i] * N[j];
        pr->area += w;
    }
    /* mass properties through the consistent mass: X = sum N_j X_j exactly
     * (isoparametric), so these are the exact integrals over the element */
    for (int i = 0; i < 6; i++)
        for (int j = 0; j < 6; j++) {
            pr->mx += me[6 * i + j] * x[j];
            pr->my += me[6 * i + j] * y[j];
            pr->polar += me[6 * i + j] * (x[i] * x[j] + y[i] * y[j]);
            pr->s[2 * i] += me[6 * i + j] * -y[j];
            pr->s[2 * i + 1] += me[6 * i + j] * x[j];
        }
    return GS_OK;
}

static void t6_stress(const double *x, const double *y, const double D[9], const double *ue,
                      double *sn, double *sc, double *area)
{
    static const double nodes[6][2] = {{1, 0}, {0, 1}, {0, 0}, {0.5, 0.5}, {0, 0.5}, {0.5, 0}};
    double N[6], dNx[6], dNy[6], B[36];
    for (int i = 0; i < 6; i++) {
        gsi_t6_jacobian(x, y, nodes[i][0], nodes[i][1], N, dNx, dNy);
        strain_matrix(6, dNx, dNy, B);
        stress_of(D, B, 6, ue, sn + 3 * i);
    }
    gsi_t6_jacobian(x, y, 1.0 / 3, 1.0 / 3, N, dNx, dNy);
    strain_matrix(6, dNx, dNy, B);
    stress_of(D, B, 6, ue, sc);
    double A = 0;
    for (int q = 0; q < 12; q++)
        A += 0.5 * q12[q][2] * gsi_t6_jacobian(x, y, q12[q][0], q12[q][1], N, dNx, dNy);
    *area = A;
}

const gsi_fe_element gsi_fe_tri6 = {"tri6", 6, t6_matrices, t6_stress};

const gsi_fe_element *gsi_fe_element_of(const gs_mesh *m)
{
    return gs_mesh_order(m) == 2 ? &gsi_fe_tri6 : &gsi_fe_tri3;
}
