/* SPDX-License-Identifier: MIT
 * Near-field (Hertz) correction of the quasi-static contact compliance
 * (include/gearsim/stiffness.h, docs/STIFFNESS.md "Near-field correction").
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

int gs_gap_vertex3(double s_l, double g_l, double g_m, double s_h, double g_h, double *s_v,
                   double *g0)
{
    if (!(s_l < 0.0 && s_h > 0.0) || !s_v || !g0)
        return 0;
    /* g_l - g_m = B s_l + C s_l^2, g_h - g_m = B s_h + C s_h^2. */
    double dl = g_l - g_m, dh = g_h - g_m, det = s_l * s_h * (s_h - s_l);
    double B = (dl * s_h * s_h - dh * s_l * s_l) / det, C = (s_l * dh - s_h * dl) / det;
    if (!(C > 0.0))
        return 0;
    double sv = -B / (2.0 * C);
    if (!(sv >= s_l && sv <= s_h))
        return 0;
    *s_v = sv;
    *g0 = g_m - B * B / (4.0 * C);
    return 1;
}
