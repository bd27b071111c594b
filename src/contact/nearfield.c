/* SPDX-License-Identifier: MIT
 * Near-field (Hertz) correction of the quasi-static contact compliance
 * (include/gearsim/stiffness.h, docs/explanation/stiffness.md "Near-field correction").
 *
 * Half-plane z > 0 under the Hertzian line load p(x) = p0 sqrt(1 - x^2/a^2),
 * P = pi a p0 / 2 per unit length. On the load's axis x = 0 (Johnson,
 * Contact Mechanics, 1985, eq. 4.75 / McEwen 1949):
 *     sigma_z = -p0 a / sqrt(a^2 + z^2),
 *     sigma_x = -(p0 / a) ((a^2 + 2 z^2) / sqrt(a^2 + z^2) - 2 z).
 * The approach of the surface point towards the point at depth d is
 *     delta = -int_0^d eps_z dz,  eps_z = (sigma_z - nu' sigma_x) / E'
 * with E' = E, nu' = nu (plane stress) or E' = E / (1 - nu^2),
 * nu' = nu / (1 - nu) (plane strain). The integrals are elementary:
 *     int_0^d a / sqrt(a^2 + z^2) dz = a asinh(d / a),
 *     int_0^d ((a^2 + 2 z^2) / sqrt(a^2 + z^2) - 2 z) dz = d sqrt(a^2 + d^2) - d^2,
 * so that
 *     delta = 2 P / (pi E') [asinh(d/a) - nu' (d/a) (sqrt(1 + (d/a)^2) - d/a)],
 * which for d >> a is Johnson's eq. 5.39 per body,
 *     2 P / (pi E') [ln(2 d / a) - nu' / 2]. */
#include <math.h>

#include "gearsim/stiffness.h"
#include "gearsim/util.h"

static void plane_constants(double E, double nu, gs_plane plane, double *Ep, double *nup)
{
    if (plane == GS_PLANE_STRAIN) {
        *Ep = E / (1.0 - nu * nu);
        *nup = nu / (1.0 - nu);
    } else {
        *Ep = E;
        *nup = nu;
    }
}

double gs_hertz_line_half_width(double load_per_m, double r_eff_m, double e_star_pa)
{
    if (!(load_per_m > 0.0) || !(r_eff_m > 0.0) || !(e_star_pa > 0.0))
        return NAN;
    return sqrt(4.0 * load_per_m * r_eff_m / (GS_PI * e_star_pa));
}

double gs_hertz_line_modulus(double E1, double nu1, double E2, double nu2, gs_plane plane)
{
    double Ep1, Ep2, n1, n2;
    plane_constants(E1, nu1, plane, &Ep1, &n1);
    plane_constants(E2, nu2, plane, &Ep2, &n2);
    return 1.0 / (1.0 / Ep1 + 1.0 / Ep2);
}

double gs_hertz_line_approach(double load_per_m, double a_m, double depth_m, double E, double nu,
                              gs_plane plane)
{
    if (!(load_per_m >= 0.0) || !(a_m > 0.0) || !(depth_m >= 0.0) || !(E > 0.0))
        return NAN;
    double Ep, nup;
    plane_constants(E, nu, plane, &Ep, &nup);
    double t = depth_m / a_m;
    /* t (sqrt(1 + t^2) - t) = t / (sqrt(1 + t^2) + t): no cancellation at large t. */
    double f = asinh(t) - nup * t / (sqrt(1.0 + t * t) + t);
    return 2.0 * load_per_m / (GS_PI * Ep) * f;
}

int gs_gap_vertex3(double s_l, double g_l, double g_m, double s_h, double g_h, double c_max, double *s_v,
                   double *g0)
{
    if (!(s_l < 0.0 && s_h > 0.0) || !s_v || !g0)
        return 0;
    /* g_l - g_m = B s_l + C s_l^2, g_h - g_m = B s_h + C s_h^2. */
    double dl = g_l - g_m, dh = g_h - g_m, det = s_l * s_h * (s_h - s_l);
    double B = (dl * s_h * s_h - dh * s_l * s_l) / det, C = (s_l * dh - s_h * dl) / det;
    if (!(C > 0.0 && C <= c_max))
        return 0;
    double sv = -B / (2.0 * C);
    if (!(sv >= s_l && sv <= s_h))
        return 0;
    *s_v = sv;
    *g0 = g_m - B * B / (4.0 * C);
    return 1;
}

/* A line contact next to a sharp corner (docs/explanation/stiffness.md "Tip-corner
 * contact"). Coordinate x along the common tangent from the corner into the
 * corner body's flank, rigid gap g(x) = (x - xv)^2 / (2 R). When the
 * Hertzian zone reaches the corner (xv < a) the contact is [0, c], complete
 * at the corner and incomplete at c; Johnson's eq. 2.25b,
 *     (1/pi) PV int_0^c p(s) / (x - s) ds = (E* / 2) g'(x),
 * with x = c (1 + t) / 2 and the arcsine Chebyshev integrals
 *     (1/pi) PV int w(t) / (tau - t) dt = 1,  (1/pi) PV int t w / (tau - t) dt = tau - 1,
 * w(t) = sqrt((1 - t) / (1 + t)), gives p = w(t) (A0 + A1 t) with
 * A1 = E* c / (4 R), A0 = E* (c - xv) / (2 R), and the load
 * P = pi E* c (3 c - 4 xv) / (16 R), so
 *     c = (2 xv + sqrt(4 xv^2 + 48 R P / (pi E*))) / 3.
 * At xv = a (A0 = A1) p is Hertz's semi-ellipse on [0, 2a]; for xv -> -inf
 * with g'(0) = beta = -xv / R fixed, c -> 4 P / (pi E* beta) (a flat face
 * at angle beta to the flank). */
typedef struct corner_law {
    double c;   /* contact length */
    double A0, A1, N; /* pressure coefficients (any common scale), N = A0 - A1 / 2 */
    double mt, mt2;   /* load-weighted mean of t and t^2 */
} corner_law;

static int corner_solve(double P, double R, double xv, double estar, corner_law *L)
{
    if (!(P > 0.0) || !(R > 0.0) || !(estar > 0.0) || !isfinite(xv))
        return 0;
    double c = (2.0 * xv + sqrt(4.0 * xv * xv + 48.0 * R * P / (GS_PI * estar))) / 3.0;
    /* Scale 4 R / E*: A1 = c, A0 = 2 (c - xv). */
    L->c = c;
    L->A1 = c;
    L->A0 = 2.0 * (c - xv);
    L->N = L->A0 - 0.5 * L->A1;
    /* Arcsine moments E[t^2] = 1/2, E[t^4] = 3/8, odd ones 0; weight
     * (1 - t) A0 + (t - t^2) A1. */
    L->mt = (-0.5 * L->A0 + 0.5 * L->A1) / L->N;
    L->mt2 = (0.5 * L->A0 - 0.375 * L->A1) / L->N;
    return 1;
}

double gs_corner_line_width(double load_per_m, double r_eff_m, double xv_m, double e_star_pa)
{
    corner_law L;
    if (!corner_solve(load_per_m, r_eff_m, xv_m, e_star_pa, &L))
        return NAN;
    double a = gs_hertz_line_half_width(load_per_m, r_eff_m, e_star_pa);
    return xv_m >= a ? 2.0 * a : L.c;
}

/* Logarithmic energy int int ln|x - y| dmu dmu of the load mu = p / P on
 * [0, c]: on [-1, 1] the potential of w (A0 + A1 t) / pi follows from
 * int ln|tau - t| T_n(t) dt / (pi sqrt(1 - t^2)) = -T_n(tau) / n (n >= 1),
 * -ln 2 (n = 0); then the arcsine moments; plus ln(c / 2) for the length. */
static double corner_log_energy(const corner_law *L)
{
    double A0 = L->A0, A1 = L->A1, ln2 = log(2.0);
    double f0 = -A0 * ln2 + A1 * (0.5 * ln2 - 0.25), f1 = A0 - A1, f2 = 0.5 * A1;
    double g0 = A0, g1 = A1 - A0, g2 = -A1;
    double e = f0 * g0 + 0.5 * (f0 * g2 + f2 * g0 + f1 * g1) + 0.375 * f2 * g2;
    return log(0.5 * L->c) + e / (L->N * L->N);
}

double gs_corner_line_approach(double load_per_m, double r_eff_m, double xv_m, double depth_m,
                               double E, double nu, gs_plane plane, double e_star_pa, double K)
{
    if (!(depth_m >= 0.0) || !(E > 0.0) || !(K > 0.0) || !(e_star_pa > 0.0))
        return NAN;
    double a = gs_hertz_line_half_width(load_per_m, r_eff_m, e_star_pa);
    if (isnan(a))
        return NAN;
    if (xv_m >= a)
        return gs_hertz_line_approach(load_per_m, a, depth_m, E, nu, plane);
    corner_law L;
    if (!corner_solve(load_per_m, r_eff_m, xv_m, e_star_pa, &L))
        return NAN;
    if (depth_m == 0.0)
        return 0.0;
    /* The Hertzian load of the same logarithmic energy (ln(a/2) - 1/4) has
     * the same load-weighted approach to a depth d >> c: its centre's
     * (gs_hertz_line_approach) less P / (2 pi E'). */
    double aeq = 2.0 * exp(corner_log_energy(&L) + 0.25);
    double Ep, nup;
    plane_constants(E, nu, plane, &Ep, &nup);
    double P = load_per_m;
    double u = gs_hertz_line_approach(P, aeq, depth_m, E, nu, plane) - P / (2.0 * GS_PI * Ep);
    /* A wedge apex beyond the load: its log coefficient instead of the
     * half-plane's between the load's scale and d. */
    if (depth_m > aeq)
        u += (K - 2.0 / GS_PI) * P * log(depth_m / aeq) / Ep;
    /* The rigid approach: u + g at any point of the contact, the load-weighted
     * g = E[(x - xv)^2] / (2 R) measured from the gap's vertex (xv >= 0) or
     * from the corner's gap (xv < 0); this body's share E* / E'. */
    double ex = 0.5 * L.c * (1.0 + L.mt), ex2 = 0.25 * L.c * L.c * (1.0 + 2.0 * L.mt + L.mt2);
    double g = ex2 - 2.0 * xv_m * ex + xv_m * xv_m - (xv_m < 0.0 ? xv_m * xv_m : 0.0);
    return u + e_star_pa / Ep * g / (2.0 * r_eff_m);
}

double gs_wedge_apex_factor(double half_angle, double psi)
{
    double al = half_angle;
    if (!(al > 0.0 && al <= 0.5 * GS_PI + 1e-12) || !(fabs(psi) <= al))
        return NAN;
    double sc = sin(al) * cos(al), c = cos(psi), s = sin(psi);
    double k = c * c / (al + sc);
    if (s != 0.0)
        k += s * s / (al - sc);
    return k;
}
