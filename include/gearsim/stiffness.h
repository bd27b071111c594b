/* SPDX-License-Identifier: MIT
 * gearsim: quasi-static mesh stiffness and static transmission error of a
 * gear pair with elastic FE bodies and frictionless contact
 * (docs/explanation/stiffness.md; METHOD.md sections 1, 3, 5 and 7 rung 3).
 *
 * The pair of a scene mesh is rolled slowly through one mesh cycle (no
 * inertia). At each of N roll positions the driver (gear 0 of the mesh unless
 * chosen otherwise) carries the moment T about its axis, the other gear's hub
 * is held; both gears are elastic FE bodies (plane stress or strain and
 * material from the scene, cores fixed) and the driver's rigid rotation delta
 * beyond its kinematic (mesh phase) position is an unknown. The static
 * contact problem keeps the gap (g0 + G (delta, u) >= 0) and is solved in the
 * contact forces by a QP on the static Delassus matrix; the linearisation is
 * repeated at the deformed position until delta settles (the split of the
 * load between nearly parallel rows of one contact is degenerate and is not
 * used as a criterion).
 *
 * Sign of the transmission error: s = sign(T), r_b1 the driver's base radius;
 *   te_raw = r_b1 s delta         from the kinematic position (um)
 *   te0    = r_b1 s delta0        the no-load position where the first gap
 *                                 closes (rigid bodies; backlash, thinning and
 *                                 the chords of the flank polylines)
 *   te     = te_raw - te0         > 0: the driver runs ahead of the
 *                                 unloaded kinematic position (the driven
 *                                 gear lags), along the line of action.
 * Mesh stiffness per mm of face width: k = F / te / b with F = |T| / r_b1 and
 * b the smaller face width (mm); the tangent stiffness needs no offset at
 * all: by default the chord k_tan = (F - F/2) / (te_raw(T) - te_raw(T/2)) / b,
 * with tangent_step h > 0 the central difference
 * k_tan = 2 h F / (te_raw(T (1 + h)) - te_raw(T (1 - h))) / b, dF/d(te) at F.
 *
 * Not collective; allocates; the scene is only read. */
#ifndef GEARSIM_STIFFNESS_H
#define GEARSIM_STIFFNESS_H

#include "gearsim/scene.h"
#include "gearsim/types.h"

/* Tooth pairs kept per position (more are summed into pairs but not listed). */
#define GS_STIFF_MAX_PAIRS 6

typedef struct gs_stiffness_opts {
    int positions;     /* roll positions over one mesh cycle (one driver pitch), >= 1;
                        * default 24 */
    double torque_nm;  /* moment on the driver, signed (+ counter-clockwise); 0 selects
                        * the default: the scene's constant / ramp load on the driver
                        * (table: its largest moment), else a line load of
                        * 200 N/mm along the line of action, T = 200 b r_b1 */
    int driver;        /* gear of the mesh (0 or 1) that carries T; default 0 */
    int refine;        /* -1 (default): the scene's mesh density; else refinement level
                        * for both gears (0..6) */
    double phase;      /* start of the roll in driver pitches beyond the driver's scene
                        * angle (default 0); the roll advances in the torque direction */
    int tangent;       /* 1 (default): also solve at a second load (two with
                        * tangent_step) for k_tan */
    double tangent_step; /* 0 (default): k_tan is the chord from T/2 to T (te_half);
                        * h in (0, 0.5]: the central difference over T (1 -+ h), the
                        * tangent at T (te_half NaN) */
    int max_iter;      /* linearisations per load case (default 12) */
    int cycles;        /* mesh cycles (driver pitches) the positions span (default 1; more to
                        * see tooth errors and run-out, which are not periodic in one pitch) */
    int order;         /* 0 (default): the scene's element order (mesh.order); else 1 or 2
                        * for both gears */
    int nearfield;     /* 2 (default, auto): near-field (Hertz) correction of the contact
                        * compliance (docs/explanation/stiffness.md "Near-field correction") when both
                        * gears have quadratic elements and neither has flank modifications
                        * or pitch errors, else the plain FE; 1: the
                        * correction on any mesh; 0: the plain FE contact (what the dynamic
                        * FE model has) */
    double nearfield_depth_mm; /* depth d below the contact where the FE field is taken,
                        * mm (at most one module); 0 (default): 0.2 module */
    int fine;          /* 0 (default): the scene's mesh; 1: both gears on the `fine` setting
                        * (gs_gear_mesh_opts_fine: teeth in contact locally refined, cycles + 2
                        * of them rounded up to odd; replaces the scene's mesh density, refine
                        * and order) */
    int all_rows;      /* 0 (default): the contact QP takes the rows within a window of the
                        * contact, checked at the solution (docs/explanation/stiffness.md "Contact
                        * window"); 1: every closing row of the search (the reference) */
    int all_dofs;      /* 0 (default): the displacements for the contact search only at the
                        * teeth it reads, by partial back substitutions (docs/explanation/stiffness.md
                        * "Displacement zone"); 1: at every boundary dof (the reference) */
    int slices;        /* slice analysis (helical gears, lead modifications or a misalignment:
                        * docs/explanation/helical.md): slices of the face, 0 (default): 320 */
    double coupling_mm; /* slice analysis: coupling length lambda along the face (the decay
                        * length of a point load's deflection), mm; 0 (default): 1.1 m_n
                        * (fitted to a 3D tooth: tests/reference/helical_coupling) */
} gs_stiffness_opts;

void gs_stiffness_opts_defaults(gs_stiffness_opts *o);

typedef struct gs_stiffness_pair {
    int tooth[2];      /* tooth of the driver, of the driven gear */
    double force_n;    /* its share of the torque / r_b1, N along the line of action */
} gs_stiffness_pair;

typedef struct gs_stiffness_point {
    double roll;          /* position in the mesh cycle, [0, 1) */
    double angle_rad;     /* driver's kinematic rotation from the first position, rad
                           * (in the torque direction) */
    double delta_rad;     /* driver's loaded rotation beyond its kinematic angle (signed) */
    double te_elastic_um; /* te_raw - te0 (header): the elastic part of the TE, output as
                           * te_elastic_um (and, for one release, te_um) */
    double te_raw_um;
    double te0_um;
    double te_ref_um;     /* r_b1 s delta_ref: the no-load closing of the perfect gears (the
                           * same meshes without modifications and tooth errors); te0 when
                           * neither gear is modified */
    double te_loaded_um;  /* te_raw - te_ref: the loaded static TE (the analysis' main output,
                           * te_loaded_um in JSON and HDF5) including the geometric
                           * TE of the modifications (the Harris map's quantity); te when
                           * neither gear is modified */
    double k;             /* F / te / b, N/(mm um) */
    double te_half_um;    /* te_raw at T/2 (NaN without the tangent option or with
                           * tangent_step) */
    double k_tan;         /* F/2 / (te_raw - te_half) / b, or the central difference
                           * with tangent_step (NaN without the tangent option) */
    int pairs;            /* tooth pairs carrying at least 1 % of F */
    int n_pair;           /* entries of pair[], by decreasing force */
    gs_stiffness_pair pair[GS_STIFF_MAX_PAIRS];
    int rows;             /* contact rows in the last QP */
    int active;           /* rows with a positive force */
    int iterations;       /* linearisations at T */
    int converged;        /* 1 when delta settled (two changes below 1e-7 of the
                           * elastic rotation) at T (and T/2) */
    double penetration_um; /* deepest gap < 0 re-evaluated at the final deformed position */
    double peak_load_n_mm; /* slice analysis: the largest load per unit face width on one
                           * contact line (N/mm; 0 in the planar analysis) */
} gs_stiffness_point;

typedef struct gs_stiffness_result {
    char mesh_name[GS_NAME_MAX];
    int mesh_index;
    int driver;           /* gear of the mesh that carries the torque */
    int body[2];          /* scene body indices: driver, driven */
    int teeth[2];         /* tooth counts: driver, driven */
    int refine[2];        /* refinement used for each */
    gs_index nodes[2];    /* FE nodes of each */
    int positions;
    gs_stiffness_point *pt; /* positions entries (owned; gs_stiffness_result_clear) */
    double torque_nm;     /* T actually used (signed) */
    double force_n;       /* F = |T| / r_b1 */
    double base_radius_m; /* r_b1 */
    double face_width_mm; /* b */
    double contact_ratio; /* of the involute flanks (gs_pair_contact_ratio) */
    double k_min, k_mean, k_max;     /* of k over the positions */
    double k_tan_mean;               /* NaN without the tangent option */
    double te_min, te_mean, te_max;  /* of te_elastic_um */
    double te_loaded_min, te_loaded_mean, te_loaded_max; /* of te_loaded_um */
    int modified;         /* 1 when a gear carries modifications or tooth errors */
    double frac_multi;    /* fraction of positions with 2 or more pairs in contact */
    long solves;          /* right-hand sides solved (both bodies) */
    double seconds;       /* wall time of the analysis */
    /* The cost split, CPU seconds of the process (both bodies): meshing and
     * FE models, factorisations of K, compliance among the contact dofs
     * (half columns and their Gram entries, computed when a contact row
     * first needs a node and cached across positions), the back
     * substitutions for the displacements (one per body and linearisation),
     * and the rest (contact search, gaps, QPs, near field) = cpu_seconds
     * minus the four. columns: contact dofs whose compliance was computed. */
    double cpu_seconds, cpu_mesh, cpu_factor, cpu_columns, cpu_solves, cpu_contact;
    long columns;
    long window_widened;  /* contact window widened (a row left out found penetrated at a
                           * settled solution), over all positions and load cases */
    double zone_fraction; /* displacement zone: the mean fraction of L's entries a
                           * back substitution for the displacements visited (1: all) */
    long zone_restarts;   /* positions solved again because a zone grew mid-position */
    /* Slice analysis (0 / NULL in the planar analysis; docs/explanation/helical.md): the
     * points above are the helical pair's; the section_* figures the planar analysis
     * of its transverse section (the spur pair of the same transverse geometry and
     * face width) at the same positions. */
    int slices;           /* slices of the face (0: planar analysis) */
    double coupling_mm;   /* coupling length lambda used */
    double local_compliance; /* the pair compliance's local part (no spread along the
                           * face), um mm / N */
    double overlap_ratio; /* eps_beta */
    double k_hbeta;       /* face load factor: the largest cycle-mean load per unit face
                           * width over F / b */
    double section_k_min, section_k_max, section_te_pp; /* te_pp: loaded static TE, um */
    double *face_z_mm;    /* slices: slice centres from the face centre, mm */
    double *face_load;    /* positions x slices: load per unit face width summed over the
                           * contact lines, N/mm */
} gs_stiffness_result;

/* Analyse mesh mesh_index of scene sc (o may be NULL: defaults). out is
 * overwritten (call gs_stiffness_result_clear on it afterwards; it need not
 * be initialised). Gears on carriers are placed at the carrier's scene angle.
 * Errors (d names the field): GS_EINVAL (NULL), GS_ERANGE ("meshes" index,
 * "positions", "driver", "refine", "torque": zero T or no load given and no
 * default possible), the errors of meshing, of the FE model (GS_ESINGULAR),
 * of the contact search and of the QP (GS_EINFEASIBLE when no contact row can
 * carry the torque), GS_ENOMEM. */
gs_err gs_stiffness_analyse(const gs_scene *sc, int mesh_index, const gs_stiffness_opts *o,
                            gs_stiffness_result *out, gs_diag *d);

/* The same analysis one roll position at a time, for callers that must stay
 * responsive (the service's chunked `stiffness`): begin validates, meshes
 * and factorises (errors as gs_stiffness_analyse) and keeps pointers into
 * sc, which must stay unchanged until end or free; next solves the next
 * position; end (once done == positions) fills out and frees the run; free
 * abandons it. gs_stiffness_analyse is begin, next until done, end. */
typedef struct gs_stiffness_run gs_stiffness_run;
gs_err gs_stiffness_begin(const gs_scene *sc, int mesh_index, const gs_stiffness_opts *o,
                          gs_stiffness_run **run, gs_diag *d);
gs_err gs_stiffness_next(gs_stiffness_run *run, gs_diag *d);
int gs_stiffness_run_done(const gs_stiffness_run *run);
int gs_stiffness_run_positions(const gs_stiffness_run *run);
gs_err gs_stiffness_end(gs_stiffness_run **run, gs_stiffness_result *out, gs_diag *d);
void gs_stiffness_run_free(gs_stiffness_run **run);
/* The contact rows of the last load case solved by gs_stiffness_next (with
 * the tangent option that is a second load: run with tangent 0 to get the
 * rows at T), for the FE mesh modes (include/gearsim/fe_modes.h): *rows the
 * rows (gear indices in them are the mesh's gears 0 and 1), *force their
 * forces (N, >= 0; > 0: active) at the deformed position; returns their
 * number (0 before the first position). Valid until the next call on run. */
struct gs_contact_row;
int gs_stiffness_run_rows(const gs_stiffness_run *run, const struct gs_contact_row **rows,
                          const double **force);
/* The near-field correction at the last position (gs_stiffness_opts.nearfield
 * on): per row of gs_stiffness_run_rows its tooth pair's index into c_tan
 * (-1: a row without correction), and per such pair the tangent series
 * compliance c_t = d(delta_H)/dP - L (m/N) at its load, which adds c_t
 * (sum of the pair's row forces) to every row of the pair: the small-motion
 * compliance about the loaded contact. pair holds the rows' number,
 * c_tan GS_STIFF_MAX_PAIRS. Returns the number of pairs (0: none, or the
 * correction off). */
int gs_stiffness_run_nearfield(const gs_stiffness_run *run, int *pair, double *c_tan);
/* The FE mesh of the driver (k = 0) or the driven gear (k = 1). */
const gs_mesh *gs_stiffness_run_mesh(const gs_stiffness_run *run, int k);

/* Free the arrays of a result and zero it; safe on a zeroed result. */
void gs_stiffness_result_clear(gs_stiffness_result *r);

/* Write the result to an HDF5 file (created or truncated): group /stiffness
 * with datasets roll, angle_deg, te_elastic_um, te_raw_um, te0_um, k,
 * te_half_um, k_tan, te_ref_um, te_loaded_um (doubles, one per position; te_um
 * a soft link to te_elastic_um, its former name, for one release), pairs
 * (int), pair_tooth (positions x
 * GS_STIFF_MAX_PAIRS x 2 ints, -1 when unused), pair_force_n (positions x
 * GS_STIFF_MAX_PAIRS); attributes scene (the scene JSON, sc may be NULL),
 * mesh, driver, torque_nm, force_n, face_width_mm, base_radius_m,
 * contact_ratio, k_min, k_mean, k_max, te_loaded_min/mean/max (the loaded
 * static TE), te_elastic_min/mean/max (and their former names te_min,
 * te_mean, te_max, for one release).
 * Errors: GS_EINVAL, GS_EIO (d names "out"). */
gs_err gs_stiffness_write_h5(const char *path, const gs_scene *sc, const gs_stiffness_result *r,
                             gs_diag *d);

/* The result as a JSON object (owned by the caller, json_object_put): the
 * document `gearsim-stiffness --json` prints and the service's `stiffness`
 * command returns (docs/explanation/stiffness.md). s is the analysed scene. */
struct json_object;
struct json_object *gs_stiffness_json(const gs_stiffness_result *r, const gs_scene *s);

/* Near-field correction (docs/explanation/stiffness.md "Near-field correction"): the
 * Hertzian line contact of two cylinders, per unit length.
 *
 * gs_hertz_line_modulus: the contact modulus E* of two bodies, 1/E* =
 * 1/E'_1 + 1/E'_2 with E' = E (plane stress) or E / (1 - nu^2) (plane strain).
 * gs_hertz_line_half_width: a = sqrt(4 P R / (pi E*)) for the line load P
 * (N/m), the effective radius R (1/R = 1/R_1 + 1/R_2, m). NaN for
 * non-positive arguments.
 * gs_hertz_line_approach: the approach of the surface point on the load's
 * axis towards the point at depth d of one half-plane (E, nu, plane) under
 * the Hertzian pressure of half-width a and resultant P per unit length:
 *     2 P / (pi E') [asinh(d/a) - nu' (d/a) (sqrt(1 + (d/a)^2) - d/a)],
 * nu' = nu (plane stress) or nu / (1 - nu) (plane strain); for d >> a
 * Johnson's (Contact Mechanics, eq. 5.39) 2 P / (pi E') (ln(2 d / a) - nu'/2).
 * Metres and pascals; NaN for invalid arguments. */
double gs_hertz_line_modulus(double E1, double nu1, double E2, double nu2, gs_plane plane);
double gs_hertz_line_half_width(double load_per_m, double r_eff_m, double e_star_pa);
double gs_hertz_line_approach(double load_per_m, double a_m, double depth_m, double E, double nu,
                              gs_plane plane);

/* The smallest gap between two smooth flanks from three samples of it
 * along their common tangent (the contact rows of the nodes nearest the
 * contact and their neighbours, docs/explanation/stiffness.md "Near-field correction"):
 * the parabola g(s) = g_m + B s + C s^2 through (s_l, g_l), (0, g_m),
 * (s_h, g_h), s_l < 0 < s_h; its vertex s_v = -B / (2 C) in *s_v and
 * g_0 = g_m - B^2 / (4 C) in *g0. Returns 1 when the parabola is convex
 * and at most c_max curved (0 < C <= c_max; INFINITY: no bound) and
 * s_l <= s_v <= s_h, else 0 (outputs untouched). */
int gs_gap_vertex3(double s_l, double g_l, double g_m, double s_h, double g_h, double c_max, double *s_v,
                   double *g0);

/* Near-field law of a line contact next to a sharp tip corner
 * (docs/explanation/stiffness.md "Tip-corner contact"): x along the common tangent from
 * the corner into the corner body's flank, rigid gap (x - xv)^2 / (2 R)
 * (xv > 0: the flanks' touching point inside the flank; xv < 0: beyond the
 * corner, whose flank face then leaves the other flank at -xv / R).
 *
 * gs_corner_line_width: the contact length, 2 a (Hertz) when xv >= a, else
 * c = (2 xv + sqrt(4 xv^2 + 48 R P / (pi E*))) / 3 on [0, c], the pressure
 * singular at the corner. NaN for invalid arguments.
 * gs_corner_line_approach: one body's rigid approach (surface to depth d,
 * the gap's vertex for xv >= 0, the corner's gap for xv < 0 as reference)
 * under the line load P: gs_hertz_line_approach when xv >= a, else the
 * load-weighted approach of the Hertzian load of equal logarithmic energy,
 * plus (K - 2/pi) P ln(d / a_eq) / E' (K: gs_wedge_apex_factor of the
 * corner body, 2/pi for the flank's half-plane), plus this body's share
 * E* / E' of the load-weighted rigid gap. Continuous at xv = a.
 * gs_wedge_apex_factor: K = cos^2 psi / (al + sin al cos al) + sin^2 psi /
 * (al - sin al cos al), the coefficient in the approach P K ln(d / r) / E'
 * along the line of a force at the apex of a wedge of half-angle al, at psi
 * from its bisector (Michell's radial stress field); 2 / pi for the
 * half-plane. NaN unless 0 < al <= pi / 2 and |psi| <= al. */
double gs_corner_line_width(double load_per_m, double r_eff_m, double xv_m, double e_star_pa);
double gs_corner_line_approach(double load_per_m, double r_eff_m, double xv_m, double depth_m,
                               double E, double nu, gs_plane plane, double e_star_pa, double K);
double gs_wedge_apex_factor(double half_angle, double psi);

#endif
