/* SPDX-License-Identifier: MIT
 * Profile modifications and tooth errors (include/gearsim/modification.h,
 * docs/explanation/geometry.md, docs/explanation/stiffness.md "Profile modifications and the Harris
 * map"). Checks (each can fail):
 *  - geometry: every flank node of a gear with tip and root relief (linear
 *    and parabolic, different on the two flanks) lies on the modified
 *    profile psi(R) - C(R)/rb to 1e-12 m (1e-9 mm), C computed here from
 *    the relief's closed form; nodes below the stated start diameter are
 *    bit-identical to the unmodified mesh, nodes above it are relieved;
 *    the relief given as a roll length starts at the radius of that roll
 *    length; the tip corner is relieved by the full amount;
 *  - unmodified gears are bit-identical to the plain mesher (gs_gear_mesh),
 *    and an empty / zero modification gives a byte-identical stiffness run;
 *  - pitch error table and run-out move the nodes as stated;
 *  - bad input names its field;
 *  - the textbook result on the 20/30 steel pair (module 2.5, face 10 mm)
 *    at the design load 200 N/mm: a linear long tip relief on both gears
 *    sized for that load (C = 2 x the unmodified peak-to-peak TE: with two
 *    pairs the relief raises the double-zone TE by C/2 on average) gives a
 *    peak-to-peak loaded static TE below half the unmodified one, and over
 *    the loads 100..300 N/mm (the Harris map) its minimum lies at the design
 *    load or next to it;
 *  - the compliant mesh with relief: each pair's force-approach law is the
 *    unrelieved one moved by the two flanks' relief at the contact point
 *    (1e-12 at the stations), no force inside the clearance, the
 *    quasi-static TE p-p at 20 N m falls below 0.7 of the unrelieved one,
 *    and a driven run keeps the energy balance at round-off;
 *  - the FE contact model (contact_drive: 30/20, 20 N m on the wheel,
 *    30-50 ms): a tip relief sized as above lowers the peak dynamic mesh
 *    force by at least 5 % at the same mean force, both runs with the
 *    energy balance at round-off (1e-11 of the energy scale);
 *  - the calibrated lumped mesh of the relieved pair: its mean dynamic TE
 *    at the steady load within 3 % of the FE loaded static TE (te_loaded,
 *    the relief's geometric TE included), the balance at round-off;
 *  - run-out of 20 um on the pinion (with backlash): over one pinion
 *    revolution the loaded static TE has a once-per-revolution term of
 *    amplitude e within 2 % and sidebands at orders z -+ 1 at least ten
 *    times those of the perfect pair; long mode (GEARSIM_LONG=1): the
 *    dynamic TE of the FE contact model over one pinion revolution has the
 *    once-per-revolution order within 10 % of e (printed with orders
 *    19-21);
 *  - mesh models refuse what they cannot represent, naming the field:
 *    relief on a plain lumped mesh, pitch errors, a one-flank modification
 *    or added material on a compliant one;
 *  - pitch errors and run-out in the lumped (rectangular) and calibrated
 *    lumped meshes (rigid 20/30 pair, 150 N m, 10 rad/s, one pinion
 *    revolution): the mean TE shift of one pinion tooth +10 um and the
 *    once-per-revolution TE of a 20 um run-out within 5 % of the
 *    quasi-static FE contact analysis over one revolution, the energy
 *    balance within 1e-10 of the energy through the pair; the
 *    planetary_runout train with lumped meshes carries the sun's run-out
 *    in its three sun-planet meshes (carrier frame) with the balance at
 *    round-off. *
 * The dynamic runs (drive_scene, ring_relief, runout_dynamic) pin linear
 * triangles (vt_scene_linear): their figures were measured on them and
 * the quadratic default costs about 12 times as much per step. On the
 * linear pair the analysis' near-field default (auto) is the plain FE; what
 * feeds a dynamic or calibrated comparison sets nearfield 0 explicitly. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/mesh.h"
#include "gearsim/models.h"
#include "gearsim/modification.h"
#include "gearsim/scene.h"
#include "gearsim/stiffness.h"
#include "models/compliant_mesh.h"
#include "compliant_static.h"
#include "scene_build.h"

/* The 20/30 pair of docs/explanation/stiffness.md; `mod0`, `mod1` are JSON members
 * added to the pinion and the wheel (may be ""). Linear triangles
 * (mesh.order 1): the figures below were measured on them, and on the
 * quadratic default at refine 1 the Harris map's analysis left a position
 * unconverged (gs_stiffness max_iter 12) besides taking minutes. */
static gs_scene *pair_scene(const char *mod0, const char *mod1, gs_err *err, gs_diag *d)
{
    char txt[8192];
    snprintf(txt, sizeof txt,
             "{\"name\": \"pair\", \"bodies\": ["
             "{\"name\": \"pinion\", \"teeth\": 20, \"module_mm\": 2.5, \"face_width_mm\": 10, "
             "\"model\": \"elastic\", \"mesh\": {\"order\": 1}%s%s},"
             "{\"name\": \"wheel\", \"teeth\": 30, \"module_mm\": 2.5, \"face_width_mm\": 10, "
             "\"model\": \"elastic\", \"mesh\": {\"order\": 1}%s%s}],"
             "\"joints\": [{\"body\": \"pinion\", \"type\": \"fixed_axis\", \"centre_mm\": [0, 0]},"
             "{\"body\": \"wheel\", \"type\": \"fixed_axis\", \"centre_mm\": [62.5, 0]}],"
             "\"meshes\": [{\"name\": \"pw\", \"gears\": [\"pinion\", \"wheel\"], \"model\": \"contact\"}],"
             "\"initial\": {\"wheel\": {\"angle\": 0.10471975511965977}}}",
             mod0[0] ? ", " : "", mod0, mod1[0] ? ", " : "", mod1);
    gs_scene *sc = NULL;
    gs_diag_clear(d);
    *err = gs_scene_parse(txt, strlen(txt), &sc, d);
    return sc;
}

static gs_scene *pair_ok(const char *mod0, const char *mod1)
{
    gs_err e;
    gs_diag d;
    gs_scene *sc = pair_scene(mod0, mod1, &e, &d);
    if (e != GS_OK)
        print_error("scene: %s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    return sc;
}

/* Relief removed at roll length L, from the definition (independent of
 * modification.c's code path). */
static double relief(double amount, double L, double Ls, double Le, int parabolic)
{
    double u = (L - Ls) / (Le - Ls);
    if (u <= 0)
        return 0;
    if (u > 1)
        u = 1;
    return amount * (parabolic ? u * u : u);
}

static void flank_nodes_on_profile(void **state)
{
    (void)state;
    /* Pinion: cw flank linear tip relief 20 um from diameter 53.5 mm and
     * parabolic root relief 8 um over 1.5 mm of roll from the form point;
     * ccw flank parabolic tip relief 12 um over 2 mm of roll. */
    gs_scene *sc = pair_ok(
        "\"modification\": {\"cw\": {\"tip_relief\": {\"amount_um\": 20, \"start_diameter_mm\": 53.5}, "
        "\"root_relief\": {\"amount_um\": 8, \"length_mm\": 1.5, \"shape\": \"parabolic\"}}, "
        "\"ccw\": {\"tip_relief\": {\"amount_um\": 12, \"length_mm\": 2.0, \"shape\": \"parabolic\"}}}",
        "");
    const gs_scene_body *b = &sc->bodies[0];
    gs_gear_geom g;
    gs_diag d;
    assert_int_equal(gs_gear_geometry(&b->gear, &g, &d), GS_OK);
    gs_mesh *m0 = NULL, *m1 = NULL;
    assert_int_equal(gs_scene_gear_mesh_perfect(b, 1, &m0, &d), GS_OK);
    assert_int_equal(gs_scene_gear_mesh_refined(b, 1, &m1, &d), GS_OK);
    assert_int_equal(m0->n_nodes, m1->n_nodes);
    double rb = g.rb;
    double La = sqrt(g.ra * g.ra - rb * rb), Lf = sqrt(g.r_form * g.r_form - rb * rb);
    /* Starts: cw tip at 53.5/2 mm; cw root at Lf + 1.5 mm; ccw tip at La - 2 mm. */
    double Ls_cw_tip = sqrt(0.02675 * 0.02675 - rb * rb), Ls_cw_root = Lf + 1.5e-3,
           Ls_ccw_tip = La - 2.0e-3;
    assert_true(fabs(b->mods->flank[GS_FLANK_CW].tip.start_radius_m - 0.02675) < 1e-15);
    assert_true(fabs(sqrt(pow(b->mods->flank[GS_FLANK_CCW].tip.start_radius_m, 2) - rb * rb) -
                     Ls_ccw_tip) < 1e-15);
    double worst = 0, worst_tipcorner = 0;
    int relieved[2] = {0, 0}, below_same = 0, below_moved = 0, n = 0;
    double pitch = 2 * GS_PI / g.z;
    for (gs_index i = 0; i < m1->n_nodes; i++) {
        if (m1->node_tag[i] != GS_NODE_FLANK) {
            /* everything else untouched */
            assert_true(m1->xy[2 * i] == m0->xy[2 * i] && m1->xy[2 * i + 1] == m0->xy[2 * i + 1]);
            continue;
        }
        n++;
        double x = m1->xy[2 * i], y = m1->xy[2 * i + 1], R = hypot(x, y);
        double x0 = m0->xy[2 * i], y0 = m0->xy[2 * i + 1];
        double th = atan2(y, x), k = nearbyint(th / pitch), a = th - k * pitch;
        int ccw = a > 0;
        double L = sqrt(R * R - rb * rb), C;
        if (ccw)
            C = relief(12e-6, L, Ls_ccw_tip, La, 1);
        else
            C = relief(20e-6, L, Ls_cw_tip, La, 0) + relief(8e-6, L, Ls_cw_root, Lf, 1);
        /* the involute half angle at R, from METHOD.md's polar equation */
        double phi = acos(rb / R);
        double psi = g.s_pitch / (2 * g.r) + (tan(g.alpha) - g.alpha) - (tan(phi) - phi);
        double err = R * fabs(fabs(a) - (psi - C / rb));
        worst = fmax(worst, err);
        if (C > 0) {
            relieved[ccw]++;
            if (fabs(R - g.ra) < 1e-12 * g.ra)
                worst_tipcorner = fmax(worst_tipcorner, fabs(rb * (psi - fabs(a)) - (ccw ? 12e-6 : 20e-6)));
        } else {
            if (x == x0 && y == y0)
                below_same++;
            else
                below_moved++;
        }
        /* radius kept */
        assert_true(fabs(R - hypot(x0, y0)) < 1e-15 * g.ra);
    }
    print_message("%d flank nodes: worst distance from the modified profile %.3e m; relieved cw %d, "
                  "ccw %d; unrelieved bit-identical %d, moved %d; tip corner relief error %.2e m\n",
                  n, worst, relieved[0], relieved[1], below_same, below_moved, worst_tipcorner);
    assert_true(worst < 1e-12);
    assert_true(worst_tipcorner < 1e-12);
    assert_true(relieved[0] > 0 && relieved[1] > 0 && below_same > 0);
    assert_int_equal(below_moved, 0);
    /* The relief starts at the stated diameter: zero at it, positive just above. */
    double R0 = 0.02675;
    assert_true(gs_gear_flank_offset(&g, b->mods, GS_FLANK_CW, R0) == 0.0);
    assert_true(gs_gear_flank_offset(&g, b->mods, GS_FLANK_CW, R0 * (1 + 1e-9)) < 0.0);
    assert_true(gs_gear_flank_offset(&g, b->mods, GS_FLANK_CW, R0 * (1 - 1e-9)) == 0.0);
    gs_mesh_free(&m0);
    gs_mesh_free(&m1);
    gs_scene_free(&sc);
}

/* The near-field correction's default (auto) keeps the plain FE on
 * modified flanks, where it is not validated (docs/explanation/stiffness.md): a relieved
 * quadratic pair by default is the plain FE bit for bit, and forcing the
 * correction on changes it. */
static void nearfield_auto_plain_on_modified(void **state)
{
    (void)state;
    gs_scene *sc = pair_ok("\"modification\": {\"tip_relief\": {\"amount_um\": 9.6, \"length_mm\": 4.466}}",
                           "\"modification\": {\"tip_relief\": {\"amount_um\": 9.6, \"length_mm\": 4.466}}");
    gs_diag d;
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    assert_int_equal(o.nearfield, 2);
    o.order = 2;
    o.positions = 2;
    o.tangent = 0;
    gs_stiffness_result r[3];
    for (int v = 0; v < 3; v++) {
        o.nearfield = (2 + v) % 3; /* auto, off, on */
        assert_int_equal(gs_stiffness_analyse(sc, 0, &o, &r[v], &d), GS_OK);
        assert_int_equal(r[v].modified, 1);
    }
    for (int j = 0; j < o.positions; j++) {
        assert_memory_equal(&r[0].pt[j].te_elastic_um, &r[1].pt[j].te_elastic_um, sizeof(double));
        assert_true(r[2].pt[j].te_elastic_um != r[1].pt[j].te_elastic_um);
    }
    print_message("relieved order-2 pair: auto = plain bit for bit (TE %.4f um), forced on %.4f um\n",
                  r[0].pt[0].te_elastic_um, r[2].pt[0].te_elastic_um);
    for (int v = 0; v < 3; v++)
        gs_stiffness_result_clear(&r[v]);
    gs_scene_free(&sc);
}

static void unmodified_bit_identical(void **state)
{
    (void)state;
    gs_scene *s0 = pair_ok("", "");
    gs_scene *s1 = pair_ok("\"modification\": {}", "\"modification\": {\"tip_relief\": {\"amount_um\": 0, "
                                                   "\"length_mm\": 2}}, \"pitch_errors_um\": [" 
                                                   "0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0]");
    gs_diag d;
    for (int k = 0; k < 2; k++) {
        gs_mesh *a = NULL, *b = NULL;
        gs_gear_mesh_opts o;
        gs_gear_mesh_opts_for_order(&o, 1); /* the pair's linear mesh */
        assert_int_equal(gs_gear_mesh(&s0->bodies[k].gear, &o, &a, &d), GS_OK);
        assert_int_equal(gs_scene_gear_mesh(&s1->bodies[k], &b, &d), GS_OK);
        assert_int_equal(a->n_nodes, b->n_nodes);
        assert_int_equal(memcmp(a->xy, b->xy, 2 * (size_t)a->n_nodes * sizeof(double)), 0);
        gs_mesh_free(&a);
        gs_mesh_free(&b);
    }
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    o.positions = 6;
    o.tangent = 0;
    gs_stiffness_result r0, r1;
    assert_int_equal(gs_stiffness_analyse(s0, 0, &o, &r0, &d), GS_OK);
    assert_int_equal(gs_stiffness_analyse(s1, 0, &o, &r1, &d), GS_OK);
    assert_int_equal(r1.modified, 0);
    for (int j = 0; j < o.positions; j++) {
        assert_int_equal(memcmp(&r0.pt[j].te_raw_um, &r1.pt[j].te_raw_um, sizeof(double)), 0);
        assert_int_equal(memcmp(&r0.pt[j].te0_um, &r1.pt[j].te0_um, sizeof(double)), 0);
        assert_true(r0.pt[j].te_loaded_um == r0.pt[j].te_elastic_um);
    }
    print_message("unmodified: meshes and a 6-position stiffness run byte-identical (TE p-p %.4f um)\n",
                  r0.te_max - r0.te_min);
    gs_stiffness_result_clear(&r0);
    gs_stiffness_result_clear(&r1);
    gs_scene_free(&s0);
    gs_scene_free(&s1);
}

static void pitch_and_runout(void **state)
{
    (void)state;
    char pe[1024] = "\"pitch_errors_um\": [";
    for (int k = 0; k < 20; k++) {
        char v[32];
        snprintf(v, sizeof v, "%s%g", k ? "," : "", k == 3 ? 15.0 : k == 11 ? -7.5 : 0.0);
        strcat(pe, v);
    }
    strcat(pe, "], \"runout\": {\"eccentricity_um\": 25, \"phase_deg\": 30}");
    gs_scene *sc = pair_ok(pe, "");
    gs_diag d;
    gs_mesh *m0 = NULL, *m1 = NULL;
    assert_int_equal(gs_scene_gear_mesh_perfect(&sc->bodies[0], -1, &m0, &d), GS_OK);
    assert_int_equal(gs_scene_gear_mesh(&sc->bodies[0], &m1, &d), GS_OK);
    const gs_gear_params *g = &sc->bodies[0].gear;
    double r = gs_gear_pitch_radius(g), rf = gs_gear_root_radius(g);
    double ex = 25e-6 * cos(GS_PI / 6), ey = 25e-6 * sin(GS_PI / 6), worst = 0;
    for (int t = 0; t < m0->n_teeth; t++)
        for (gs_index q = m0->flank_ptr[2 * t]; q < m0->flank_ptr[2 * t + 2]; q++) {
            gs_index n = m0->flank_nodes[q];
            double x0 = m0->xy[2 * n], y0 = m0->xy[2 * n + 1];
            if (hypot(x0, y0) < 0.5 * (r + rf))
                continue;
            double e = t == 3 ? 15e-6 : t == 11 ? -7.5e-6 : 0.0, a = e / r;
            double xe = cos(a) * x0 - sin(a) * y0 + ex, ye = sin(a) * x0 + cos(a) * y0 + ey;
            worst = fmax(worst, hypot(m1->xy[2 * n] - xe, m1->xy[2 * n + 1] - ye));
        }
    print_message("pitch errors (tooth 3 +15 um, tooth 11 -7.5 um) and run-out 25 um at 30 deg: "
                  "flank nodes off by at most %.2e m\n", worst);
    assert_true(worst < 1e-15);
    gs_mesh_free(&m0);
    gs_mesh_free(&m1);
    gs_scene_free(&sc);
}

static void bad_input(void **state)
{
    (void)state;
    struct {
        const char *mod, *field;
    } cases[] = {
        {"\"modification\": {\"tip_relief\": {\"amount_um\": 10, \"start_diameter_mm\": 60}}",
         "bodies[0].modification.cw.tip_relief"},
        {"\"modification\": {\"tip_relief\": {\"amount_um\": -1, \"length_mm\": 1}}",
         "bodies[0].modification.tip_relief.amount_um"},
        {"\"modification\": {\"tip_relief\": {\"amount_um\": 10}}", "bodies[0].modification.tip_relief"},
        {"\"modification\": {\"tip_relief\": {\"amount_um\": 10, \"length_mm\": 1, \"shape\": \"cubic\"}}",
         "bodies[0].modification.tip_relief.shape"},
        {"\"modification\": {\"deviation\": {\"roll_deg\": [10, 5], \"um\": [1, 2]}}",
         "bodies[0].modification.cw.deviation"},
        {"\"modification\": {\"crowning\": 3}", "bodies[0].modification.crowning"},
        {"\"pitch_errors_um\": [1, 2, 3]", "bodies[0].pitch_errors_um"},
        {"\"runout\": {\"eccentricity_um\": 1000}", "bodies[0].runout"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        gs_err e;
        gs_diag d;
        gs_scene *sc = pair_scene(cases[i].mod, "", &e, &d);
        print_message("%s -> %s: %s\n", cases[i].mod, d.field, d.message);
        assert_int_not_equal(e, GS_OK);
        assert_null(sc);
        assert_string_equal(d.field, cases[i].field);
    }
}

static double pp_at(const gs_scene *sc, double w_n_per_mm, double *mean)
{
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    o.positions = 24;
    o.refine = 1;
    o.tangent = 0;
    double rb = gs_gear_base_radius(&sc->bodies[0].gear);
    o.torque_nm = w_n_per_mm * 10.0 * rb;
    gs_stiffness_result r;
    gs_diag d;
    gs_err e = gs_stiffness_analyse(sc, 0, &o, &r, &d);
    if (e != GS_OK)
        print_error("stiffness: %s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    for (int j = 0; j < r.positions; j++)
        assert_true(r.pt[j].converged);
    double pp = r.te_loaded_max - r.te_loaded_min;
    if (mean)
        *mean = r.te_loaded_mean;
    gs_stiffness_result_clear(&r);
    return pp;
}

static void harris_map(void **state)
{
    (void)state;
    gs_scene *s0 = pair_ok("", "");
    double design = 200.0;
    double pp0 = pp_at(s0, design, NULL);
    /* Long linear relief from the highest point of single contact,
     * (eps - 1) p_b of roll from the tip, on both gears. */
    gs_pair_info info;
    gs_diag d;
    assert_int_equal(gs_pair_analyse(&s0->bodies[0].gear, &s0->bodies[1].gear, 0.0625, &info, &d), GS_OK);
    double len_mm = (info.contact_ratio - 1.0) * info.base_pitch * 1e3;
    double C = 2.0 * pp0;
    char mod[512];
    snprintf(mod, sizeof mod,
             "\"modification\": {\"tip_relief\": {\"amount_um\": %.6f, \"length_mm\": %.6f}}", C, len_mm);
    gs_scene *s1 = pair_ok(mod, mod);
    static const double loads[] = {100, 150, 200, 250, 300};
    double pp[5], best = INFINITY;
    int ib = -1;
    for (int i = 0; i < 5; i++) {
        pp[i] = pp_at(s1, loads[i], NULL);
        if (pp[i] < best) {
            best = pp[i];
            ib = i;
        }
    }
    double pp0_150 = pp_at(s0, 150, NULL), pp0_250 = pp_at(s0, 250, NULL);
    print_message("20/30 pair, 200 N/mm: p-p static TE without relief %.4f um; with linear tip relief "
                  "%.3f um over %.3f mm of roll on both gears %.4f um (ratio %.3f)\n",
                  pp0, C, len_mm, pp[2], pp[2] / pp0);
    print_message("Harris map (relief %.3f um): ", C);
    for (int i = 0; i < 5; i++)
        print_message("%g N/mm: %.4f  ", loads[i], pp[i]);
    print_message("\nwithout relief: 150 N/mm %.4f, 200 N/mm %.4f, 250 N/mm %.4f um\n", pp0_150, pp0,
                  pp0_250);
    assert_true(pp[2] < 0.5 * pp0);
    assert_true(ib >= 1 && ib <= 3);
    /* Without relief p-p grows with the load (no minimum inside). */
    assert_true(pp0_150 < pp0 && pp0 < pp0_250);
    gs_scene_free(&s0);
    gs_scene_free(&s1);
}

/* The builtin contact_drive scene (30/20, moment on the wheel) with a long
 * linear tip relief of amount c_um on both gears (0: none) and the mesh
 * model `model`. */
static json_object *drive_scene(double c_um, const char *model)
{
    json_object *root = vt_contact_scheme(vt_scene_linear("contact_drive"), "seed");
    json_object *bodies = json_object_object_get(root, "bodies");
    for (size_t i = 0; i < json_object_array_length(bodies); i++) {
        json_object *b = json_object_array_get_idx(bodies, i);
        if (strcmp(model, "contact") != 0)
            json_object_object_add(b, "model", json_object_new_string("rigid"));
        if (!(c_um > 0))
            continue;
        json_object *mo = json_object_new_object(), *tr = json_object_new_object();
        json_object_object_add(tr, "amount_um", json_object_new_double(c_um));
        json_object_object_add(tr, "length_mm", json_object_new_double(4.466));
        json_object_object_add(mo, "tip_relief", tr);
        json_object_object_add(b, "modification", mo);
    }
    json_object *m = json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
    json_object_object_add(m, "model", json_object_new_string(model));
    if (!strcmp(model, "lumped")) {
        json_object *st = json_object_new_object();
        json_object_object_add(st, "type", json_object_new_string("calibrated"));
        json_object_object_add(m, "stiffness", st);
        json_object_object_add(m, "backlash_mm", json_object_new_double(0.0));
    }
    return root;
}

static gs_scene *parse_tree(json_object *root)
{
    const char *txt = json_object_to_json_string(root);
    gs_scene *sc = NULL;
    gs_diag d;
    gs_err e = gs_scene_parse(txt, strlen(txt), &sc, &d);
    if (e != GS_OK)
        print_error("scene: %s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    return sc;
}


/* The compliant mesh with relief: every pair's law is the unrelieved law
 * moved by the two flanks' relief at its contact point; the quasi-static TE
 * peak-to-peak falls; a driven run keeps the energy balance at round-off. */
static void compliant_relief(void **state)
{
    (void)state;
    gs_system *s0 = vt_system(drive_scene(0, "compliant"));
    gs_system *s1 = vt_system(drive_scene(4.0, "compliant"));
    const gs_gmesh_rt *m0 = &s0->meshes[0], *m1 = &s1->meshes[0];
    gsi_compliant_info info;
    assert_true(gsi_compliant_info_get(m0, &info));
    /* the pinion of the model is the external gear listed first: the wheel */
    gs_gear_geom g[2];
    gs_diag d;
    assert_int_equal(gs_gear_geometry(&s1->scene->bodies[0].gear, &g[0], &d), GS_OK);
    assert_int_equal(gs_gear_geometry(&s1->scene->bodies[1].gear, &g[1], &d), GS_OK);
    double worst = 0;
    double tw = info.transition * info.base_pitch, v0 = -0.5 * tw;
    double dv = (info.path_length + tw) / (info.stations - 1);
    for (int k = 0; k < info.stations; k++) {
        double v = v0 + k * dv;
        gsi_compliant_point pt;
        gsi_compliant_point_at(m1, v, &pt);
        double C = -(gs_gear_flank_offset(&g[0], s1->scene->bodies[0].mods, 0, hypot(g[0].rb, pt.rho[0])) +
                     gs_gear_flank_offset(&g[1], s1->scene->bodies[1].mods, 0, hypot(g[1].rb, pt.rho[1])));
        for (int i = 1; i <= 4; i++) {
            double dl = 5e-6 * i;
            double f1 = gsi_compliant_pair_force(m1, v, dl + C), f0 = gsi_compliant_pair_force(m0, v, dl);
            worst = fmax(worst, fabs(f1 - f0) / f0);
        }
        /* inside the clearance: no force */
        if (C > 1e-9)
            assert_true(gsi_compliant_pair_force(m1, v, 0.5 * C) == 0.0);
    }
    print_message("compliant relief: pair law = unrelieved law moved by the relief, worst %.2e (relative, "
                  "at the %d stations)\n", worst, info.stations);
    assert_true(worst < 1e-12);
    /* static TE over a cycle at the scene's load (20 N m on the wheel) */
    double W = 20.0 / g[0].rb, pp[2];
    for (int q = 0; q < 2; q++) {
        double lo = INFINITY, hi = -INFINITY;
        for (int j = 0; j < 48; j++) {
            double te = vt_compliant_static(q ? m1 : m0, j / 48.0, W);
            lo = fmin(lo, te);
            hi = fmax(hi, te);
        }
        pp[q] = hi - lo;
    }
    print_message("compliant mesh, 20 N m: quasi-static TE p-p %.4f um without relief, %.4f um with 4 um\n",
                  pp[0] * 1e6, pp[1] * 1e6);
    assert_true(pp[1] < 0.7 * pp[0]);
    /* energy balance over a driven run with relief */
    double worst_b = 0, scale = 0;
    gs_energy e;
    for (int i = 0; i < 3000; i++)
        vt_step_balance(s1, &e, &worst_b, &scale);
    print_message("compliant with relief, 30 ms driven: balance residual %.2e of %.2e J\n", worst_b, scale);
    assert_true(worst_b < 1e-11 * scale);
    gs_system_free(&s0);
    gs_system_free(&s1);
}

/* Peak dynamic mesh force at tooth entry in the FE contact model with and
 * without relief, the energy balance at round-off in both. */
static void contact_dynamic_relief(void **state)
{
    (void)state;
    /* relief sized for the load as in harris_map: 2 x the unmodified p-p */
    gs_scene *sc = parse_tree(drive_scene(0, "contact"));
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    o.nearfield = 0; /* sized on the FE contact model it runs in, which has no near-field part */
    o.positions = 24;
    o.tangent = 0;
    gs_stiffness_result r;
    gs_diag d;
    assert_int_equal(gs_stiffness_analyse(sc, 0, &o, &r, &d), GS_OK);
    double C = 2.0 * (r.te_loaded_max - r.te_loaded_min);
    gs_stiffness_result_clear(&r);
    gs_scene_free(&sc);
    double peak[2], mean[2], res[2], sc_e[2];
    for (int q = 0; q < 2; q++) {
        gs_system *s = vt_system(drive_scene(q ? C : 0.0, "contact"));
        double worst = 0, scale = 0, sum = 0, mx = 0;
        int n = 0;
        gs_energy e;
        for (int i = 0; i < 5000; i++) {
            vt_step_balance(s, &e, &worst, &scale);
            if (i >= 3000) {
                double f = s->meshes[0].force;
                sum += f;
                mx = fmax(mx, f);
                n++;
            }
        }
        peak[q] = mx;
        mean[q] = sum / n;
        res[q] = worst;
        sc_e[q] = scale;
        gs_system_free(&s);
    }
    print_message("FE contact, 30/20 pair at 20 N m, 30-50 ms: mesh force peak %.1f N (mean %.1f N, peak "
                  "over mean %.1f N) without relief; with %.3f um long linear tip relief on both gears: peak "
                  "%.1f N (mean %.1f N, over mean %.1f N); balance residuals %.2e / %.2e of %.2e J\n",
                  peak[0], mean[0], peak[0] - mean[0], C, peak[1], mean[1], peak[1] - mean[1], res[0], res[1],
                  sc_e[0]);
    assert_true(peak[1] < 0.95 * peak[0]);
    assert_true(fabs(mean[1] / mean[0] - 1) < 0.01);
    assert_true(res[0] < 1e-11 * sc_e[0] && res[1] < 1e-11 * sc_e[1]);
}

/* The calibrated lumped mesh with relief: calibrated by the FE analysis of
 * the relieved pair, its mean dynamic TE at the steady load (contact_drive,
 * 20 N m, 30-60 ms) stands at the FE loaded static TE with the relief's
 * geometric part (te_loaded), and the energy balance holds. */
static void calibrated_relief(void **state)
{
    (void)state;
    const double C = 4.0;
    gs_scene *sc = parse_tree(drive_scene(C, "contact"));
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    o.nearfield = 0; /* as the calibration (src/models/meshes.c) */
    o.positions = 24;
    o.tangent = 1;
    o.tangent_step = 0.05;
    o.torque_nm = 20.0;
    gs_stiffness_result r;
    gs_diag d;
    assert_int_equal(gs_stiffness_analyse(sc, 0, &o, &r, &d), GS_OK);
    assert_int_equal(r.modified, 1);
    double te_loaded = r.te_loaded_mean * 1e-6, te_plain = r.te_mean * 1e-6;
    gs_stiffness_result_clear(&r);
    gs_scene_free(&sc);
    gs_system *s = vt_system(drive_scene(C, "lumped"));
    double worst = 0, scale = 0, defl = 0;
    int n = 0;
    gs_energy e;
    for (int i = 0; i < 6000; i++) {
        vt_step_balance(s, &e, &worst, &scale);
        if (i >= 3000) {
            defl += s->meshes[0].deflection;
            n++;
        }
    }
    defl /= n;
    print_message("calibrated lumped with %.1f um relief: mean dynamic TE %.4e m; FE loaded static TE %.4e m "
                  "(%+.2f%%; te from the relieved closing %.4e m); balance %.2e of %.2e J\n",
                  C, defl, te_loaded, 100 * (defl / te_loaded - 1), te_plain, worst, scale);
    assert_true(fabs(defl / te_loaded - 1) < 0.03);
    assert_true(worst < 1e-11 * scale);
    gs_system_free(&s);
}

/* Amplitude of harmonic k of x (n samples over one period). */
static double harmonic(const double *x, int n, int k)
{
    double re = 0, im = 0;
    for (int i = 0; i < n; i++) {
        re += x[i] * cos(2 * GS_PI * k * i / n);
        im -= x[i] * sin(2 * GS_PI * k * i / n);
    }
    return 2 * hypot(re, im) / n;
}

/* Run-out of the pinion: the loaded static TE over one pinion revolution
 * (20 mesh cycles, 8 positions each) carries the once-per-revolution term
 * of amplitude e (the centre offset projected on the line of action) and
 * sidebands of the mesh harmonic at z -+ 1 orders. */
static void runout_spectrum(void **state)
{
    (void)state;
    const char *thin = "\"thinning_mm\": 0.05";
    char mod[256];
    snprintf(mod, sizeof mod, "%s, \"runout\": {\"eccentricity_um\": 20, \"phase_deg\": 30}", thin);
    gs_scene *s[2] = {pair_ok(thin, thin), pair_ok(mod, thin)};
    double h[2][4];
    static const int orders[4] = {1, 19, 20, 21};
    for (int q = 0; q < 2; q++) {
        gs_stiffness_opts o;
        gs_stiffness_opts_defaults(&o);
        o.positions = 160;
        o.cycles = 20;
        o.tangent = 0;
        gs_stiffness_result r;
        gs_diag d;
        assert_int_equal(gs_stiffness_analyse(s[q], 0, &o, &r, &d), GS_OK);
        assert_int_equal(r.modified, q);
        double te[160];
        for (int j = 0; j < 160; j++)
            te[j] = r.pt[j].te_loaded_um;
        for (int k = 0; k < 4; k++)
            h[q][k] = harmonic(te, 160, orders[k]);
        gs_stiffness_result_clear(&r);
        gs_scene_free(&s[q]);
    }
    double pb = GS_PI * 2.5 * cos(20 * GS_PI / 180); /* mm */
    print_message("loaded static TE over one pinion revolution (um): without run-out order 1 %.2e, 19 %.2e, "
                  "20 %.4f, 21 %.2e; with 20 um run-out order 1 %.4f (e = 20), 19 %.4f, 20 %.4f, 21 %.4f (phase "
                  "modulation alone: %.4f each)\n",
                  h[0][0], h[0][1], h[0][2], h[0][3], h[1][0], h[1][1], h[1][2], h[1][3],
                  h[1][2] * GS_PI * 20e-3 / pb);
    assert_true(fabs(h[1][0] / 20.0 - 1) < 0.02);
    assert_true(h[1][1] > 10 * h[0][1] && h[1][3] > 10 * h[0][3]);
    assert_true(h[0][0] < 0.01);
}

/* The example scenes parse, carry what their descriptions say, and the
 * planetary train with sun run-out builds and steps with the balance held. */
static void example_scenes(void **state)
{
    (void)state;
    const char *root = getenv("GEARSIM_SOURCE_ROOT");
    if (!root) {
        print_message("GEARSIM_SOURCE_ROOT not set: example scenes not checked\n");
        return;
    }
    char path[1024];
    gs_diag d;
    gs_scene *sc = NULL;
    snprintf(path, sizeof path, "%s/deploy/scenes/pair_relief.json", root);
    assert_int_equal(gs_scene_load_file(path, &sc, &d), GS_OK);
    for (int k = 0; k < 2; k++) {
        const gs_gear_mods *m = sc->bodies[k].mods;
        assert_non_null(m);
        assert_true(fabs(m->flank[0].tip.amount_m - 10.3e-6) < 1e-15);
        assert_int_equal(memcmp(&m->flank[0], &m->flank[1], sizeof m->flank[0]), 0);
    }
    /* What its description says, on the default mesh (24 positions, the
     * scene's design load of 200 N/mm, plain FE: the default on modified
     * flanks): the relief is twice the peak-to-peak static TE of the same
     * pair unrelieved (stiffness_pair.json; 5.166 um, C 10.3 um; the 9.6 um
     * sized on linear triangles was 7 % short), and it takes that
     * peak-to-peak down to 1.317 um (0.255 of it; 9.6 um left 1.401 um; 0.787
     * and 0.736 um at refine 1 and 2, where the unrelieved pair has 5.170
     * and 5.109 um). */
    gs_stiffness_opts so;
    gs_stiffness_opts_defaults(&so);
    so.tangent = 0;
    so.nearfield = 0;
    gs_stiffness_result rr, ru;
    assert_int_equal(gs_stiffness_analyse(sc, 0, &so, &rr, &d), GS_OK);
    double amount = sc->bodies[0].mods->flank[0].tip.amount_m * 1e6;
    gs_scene_free(&sc);
    snprintf(path, sizeof path, "%s/deploy/scenes/stiffness_pair.json", root);
    assert_int_equal(gs_scene_load_file(path, &sc, &d), GS_OK);
    assert_null(sc->bodies[0].mods);
    assert_int_equal(gs_stiffness_analyse(sc, 0, &so, &ru, &d), GS_OK);
    gs_scene_free(&sc);
    double pp_u = ru.te_loaded_max - ru.te_loaded_min, pp_r = rr.te_loaded_max - rr.te_loaded_min;
    print_message("pair_relief: relief %.2f um against 2 x the unrelieved p-p %.4f um (%+.2f%%); p-p with it %.4f um "
                  "(%.3f of the unrelieved)\n", amount, pp_u, 100 * (amount / (2 * pp_u) - 1), pp_r, pp_r / pp_u);
    assert_true(fabs(rr.force_n / ru.force_n - 1) < 1e-12);
    assert_true(fabs(rr.force_n / rr.face_width_mm - 200.0) < 1e-9); /* the design load */
    assert_true(fabs(amount / (2 * pp_u) - 1) < 0.01);
    assert_true(pp_r < 0.3 * pp_u);
    gs_stiffness_result_clear(&rr);
    gs_stiffness_result_clear(&ru);
    snprintf(path, sizeof path, "%s/deploy/scenes/planetary_runout.json", root);
    assert_int_equal(gs_scene_load_file(path, &sc, &d), GS_OK);
    int sun = gs_scene_find_body(sc, "sun");
    assert_non_null(sc->bodies[sun].mods);
    assert_true(fabs(sc->bodies[sun].mods->runout_m - 20e-6) < 1e-15);
    gs_system *s = NULL;
    gs_err err = gs_system_new(sc, 0, 1, &s, &d); /* takes the scene */
    sc = NULL;
    if (err != GS_OK)
        print_error("%s: %s\n", d.field, d.message);
    assert_int_equal(err, GS_OK);
    double worst = 0, scale = 0;
    gs_energy e;
    for (int i = 0; i < 50; i++)
        vt_step_balance(s, &e, &worst, &scale);
    print_message("planetary_runout: 50 steps, balance %.2e of %.2e J\n", worst, scale);
    assert_true(worst <= 1e-11 * fmax(scale, 1e-3));
    gs_system_free(&s);
}

/* A ring (internal gear, its tip the smaller radius): parabolic tip relief
 * over 1.5 mm of roll from its tip, the nodes on psi(R) - C(R)/rb with the
 * ring's involute (psi = s/2r - inv(alpha) + inv(phi)). */
static void ring_relief(void **state)
{
    (void)state;
    json_object *root = vt_contact_scheme(vt_scene_linear("planetary_contact"), "seed");
    json_object *bodies = json_object_object_get(root, "bodies");
    json_object *ring = NULL;
    for (size_t i = 0; i < json_object_array_length(bodies); i++) {
        json_object *b = json_object_array_get_idx(bodies, i);
        if (!strcmp(json_object_get_string(json_object_object_get(b, "name")), "ring"))
            ring = b;
    }
    assert_non_null(ring);
    json_object *mo = json_tokener_parse(
        "{\"tip_relief\": {\"amount_um\": 15, \"length_mm\": 1.5, \"shape\": \"parabolic\"}}");
    json_object_object_add(ring, "modification", mo);
    gs_scene *sc = parse_tree(root);
    json_object_put(root);
    const gs_scene_body *b = &sc->bodies[gs_scene_find_body(sc, "ring")];
    gs_gear_geom g;
    gs_diag d;
    assert_int_equal(gs_gear_geometry(&b->gear, &g, &d), GS_OK);
    gs_mesh *m0 = NULL, *m1 = NULL;
    assert_int_equal(gs_scene_gear_mesh_perfect(b, -1, &m0, &d), GS_OK);
    assert_int_equal(gs_scene_gear_mesh(b, &m1, &d), GS_OK);
    double rb = g.rb, La = sqrt(g.ra * g.ra - rb * rb), Ls = La + 1.5e-3;
    double pitch = 2 * GS_PI / g.z, worst = 0;
    int relieved = 0, same = 0;
    for (gs_index i = 0; i < m1->n_nodes; i++) {
        if (m1->node_tag[i] != GS_NODE_FLANK)
            continue;
        double x = m1->xy[2 * i], y = m1->xy[2 * i + 1], R = hypot(x, y);
        double th = atan2(y, x), a = th - nearbyint(th / pitch) * pitch;
        double L = sqrt(R * R - rb * rb), C = relief(15e-6, L, Ls, La, 1);
        double phi = acos(rb / R);
        double psi = g.s_pitch / (2 * g.r) - (tan(g.alpha) - g.alpha) + (tan(phi) - phi);
        worst = fmax(worst, R * fabs(fabs(a) - (psi - C / rb)));
        if (C > 0)
            relieved++;
        else
            same += x == m0->xy[2 * i] && y == m0->xy[2 * i + 1];
    }
    print_message("ring z%d, parabolic tip relief 15 um over 1.5 mm: %d flank nodes relieved, %d untouched, "
                  "worst distance from the modified profile %.2e m\n", g.z, relieved, same, worst);
    assert_true(worst < 1e-12);
    assert_true(relieved > 0 && same > 0);
    gs_mesh_free(&m0);
    gs_mesh_free(&m1);
    gs_scene_free(&sc);
}

/* Long mode (GEARSIM_LONG=1): the dynamic TE of the FE contact model
 * (contact_drive, 20 um run-out on the 20-tooth pinion, which is driven
 * at about 44 rad/s) over one pinion revolution in the steady state, by
 * order of the pinion's rotation (samples weighted by the angle they span):
 * the once-per-revolution order and the sidebands 19 and 21 about the mesh
 * order 20, printed with the perfect pair's. */
static void runout_dynamic(void **state)
{
    (void)state;
    for (int q = 0; q < 2; q++) {
        json_object *root = vt_contact_scheme(vt_scene_linear("contact_drive"), "seed");
        json_object *bodies = json_object_object_get(root, "bodies");
        if (q)
            json_object_object_add(json_object_array_get_idx(bodies, 1), "runout",
                                   json_tokener_parse("{\"eccentricity_um\": 20, \"phase_deg\": 0}"));
        gs_system *s = vt_system(root);
        int p = gs_scene_find_body(s->scene, "pinion");
        double worst = 0, scale = 0;
        gs_energy e;
        for (int i = 0; i < 5000; i++)
            vt_step_balance(s, &e, &worst, &scale);
        double th0 = gs_system_angle(s, p), prev = th0;
        double re[4] = {0}, im[4] = {0}, mean = 0;
        static const int ord[4] = {1, 19, 20, 21};
        int n = 0;
        while (fabs(prev - th0) < 2 * GS_PI && n < 40000) {
            vt_step_balance(s, &e, &worst, &scale);
            double th = gs_system_angle(s, p), dth = fabs(th - prev), x = s->meshes[0].deflection;
            double u = fabs(0.5 * (th + prev) - th0);
            mean += x * dth;
            for (int k = 0; k < 4; k++) {
                re[k] += x * cos(ord[k] * u) * dth;
                im[k] -= x * sin(ord[k] * u) * dth;
            }
            prev = th;
            n++;
        }
        print_message("FE contact, %s: one pinion revolution in %d steps, mean DTE %.4f um; orders 1 %.4f, 19 "
                      "%.4f, 20 %.4f, 21 %.4f um; balance %.2e of %.2e J\n",
                      q ? "20 um run-out on the pinion" : "perfect gears", n, mean / (2 * GS_PI) * 1e6,
                      hypot(re[0], im[0]) / GS_PI * 1e6, hypot(re[1], im[1]) / GS_PI * 1e6,
                      hypot(re[2], im[2]) / GS_PI * 1e6, hypot(re[3], im[3]) / GS_PI * 1e6, worst, scale);
        assert_true(worst < 1e-11 * scale);
        if (q)
            assert_true(fabs(hypot(re[0], im[0]) / GS_PI / 20e-6 - 1) < 0.1);
        gs_system_free(&s);
    }
}

/* Mesh models refuse what they cannot represent, naming the field. */
static void models_refuse(void **state)
{
    (void)state;
    struct {
        const char *model, *stiffness, *add, *field;
    } cases[] = {
        {"lumped", NULL, "{\"modification\": {\"tip_relief\": {\"amount_um\": 5, \"length_mm\": 2}}}",
         "bodies[0].modification"},
        {"compliant", NULL, "{\"pitch_errors_um\": [0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,0,1]}",
         "bodies[0].pitch_errors_um"},
        {"compliant", NULL, "{\"modification\": {\"ccw\": {\"tip_relief\": {\"amount_um\": 5, \"length_mm\": 2}}}}",
         "bodies[0].modification"},
        {"compliant", NULL, "{\"modification\": {\"deviation\": {\"roll_deg\": [0, 60], \"um\": [3, 3]}}}",
         "bodies[0].modification"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        json_object *root = drive_scene(0, cases[i].model);
        json_object *b = json_object_array_get_idx(json_object_object_get(root, "bodies"), 0);
        json_object *add = json_tokener_parse(cases[i].add);
        json_object_object_foreach(add, k, v) json_object_object_add(b, k, json_object_get(v));
        json_object_put(add);
        json_object *m = json_object_array_get_idx(json_object_object_get(root, "meshes"), 0);
        if (!cases[i].stiffness)
            json_object_object_del(m, "stiffness");
        gs_scene *sc = parse_tree(root);
        json_object_put(root);
        gs_system *s = NULL;
        gs_diag d;
        gs_err e = gs_system_new(sc, 0, 1, &s, &d);
        print_message("%s mesh with %s -> %s: %s\n", cases[i].model, cases[i].add, d.field, d.message);
        assert_int_not_equal(e, GS_OK);
        assert_string_equal(d.field, cases[i].field);
        gs_system_free(&s);
    }
}

/* The 20/30 pair on rigid teeth with a lumped mesh (`stiffness` JSON, "" for
 * the default rectangular wave) at low speed: the pinion driven by T, the
 * wheel braked to hold omega0 on the pinion from the start. */
static gs_scene *lumped_pair(const char *mod0, const char *stiffness, double T, double omega0)
{
    char txt[8192];
    double c = 2.25 * T / omega0; /* wheel brake: 1.5 T at omega0 / 1.5 */
    snprintf(txt, sizeof txt,
             "{\"name\": \"pair\", \"bodies\": ["
             "{\"name\": \"pinion\", \"teeth\": 20, \"module_mm\": 2.5, \"face_width_mm\": 10, "
             "\"thinning_mm\": 0.05, \"model\": \"rigid\"%s%s},"
             "{\"name\": \"wheel\", \"teeth\": 30, \"module_mm\": 2.5, \"face_width_mm\": 10, "
             "\"thinning_mm\": 0.05, \"model\": \"rigid\"}],"
             "\"joints\": [{\"body\": \"pinion\", \"type\": \"fixed_axis\", \"centre_mm\": [0, 0]},"
             "{\"body\": \"wheel\", \"type\": \"fixed_axis\", \"centre_mm\": [62.5, 0]}],"
             "\"meshes\": [{\"name\": \"pw\", \"gears\": [\"pinion\", \"wheel\"], \"model\": \"lumped\"%s%s}],"
             "\"loads\": [{\"body\": \"pinion\", \"type\": \"constant\", \"moment\": %.17g},"
             "{\"body\": \"wheel\", \"type\": \"brake\", \"coefficient\": %.17g}],"
             "\"numerics\": {\"time_step\": 2e-5},"
             "\"initial\": {\"pinion\": {\"omega\": %.17g}, \"wheel\": {\"angle\": 0.10471975511965977, "
             "\"omega\": %.17g}}}",
             mod0[0] ? ", " : "", mod0, stiffness[0] ? ", \"stiffness\": " : "", stiffness, T, c, omega0,
             -omega0 * 20.0 / 30.0);
    gs_err e;
    gs_diag d;
    gs_scene *sc = NULL;
    e = gs_scene_parse(txt, strlen(txt), &sc, &d);
    if (e != GS_OK)
        print_error("scene: %s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    return sc;
}

/* One pinion revolution of a lumped run after a settling time: the mean
 * kinematic TE (a . q - s_ref, the tooth errors excluded) and its
 * once-per-revolution term (re, im) in the pinion angle; the worst balance
 * residual and the energy scale. */
static void lumped_revolution(gs_scene *sc, double *mean, double h1[2], double *worst, double *scale)
{
    gs_system *s = NULL;
    gs_diag d;
    gs_err e = gs_system_new(sc, 0, 1, &s, &d); /* takes the scene */
    if (e != GS_OK)
        print_error("system: %s: %s\n", d.field, d.message);
    assert_int_equal(e, GS_OK);
    gs_energy en;
    *worst = 0, *scale = 0;
    const gs_gmesh_rt *m = &s->meshes[0];
    int cp = s->bodies[0].coord, n = s->n_coords;
    for (int i = 0; i < 2500; i++) /* 50 ms: the start's mesh-mode transient dies out */
        vt_step_balance(s, &en, worst, scale);
    double th0 = s->q[cp], sum = 0, re = 0, im = 0, th_prev = th0;
    while (s->q[cp] - th0 < 2 * GS_PI) {
        vt_step_balance(s, &en, worst, scale);
        double te = -m->s_ref, th = s->q[cp], dth = th - th_prev;
        for (int i = 0; i < n; i++)
            te += m->a[i] * s->q[i];
        sum += te * dth;
        re += te * cos(th) * dth;
        im += te * sin(th) * dth;
        th_prev = th;
    }
    double span = th_prev - th0;
    *mean = sum / span;
    h1[0] = 2 * re / span, h1[1] = 2 * im / span;
    gs_system_free(&s);
}

/* Pitch errors and run-out in the lumped and calibrated lumped meshes
 * against the quasi-static FE contact analysis of the same pair over one
 * pinion revolution (20 mesh cycles): one pinion tooth +10 um gives a mean
 * TE shift, a 20 um pinion run-out a once-per-revolution TE term; the
 * lumped runs (pinion at 10 rad/s: mesh frequency 32 Hz, far below the mesh
 * mode) agree within 5 %, with the energy balance at round-off. */
static void lumped_tooth_errors(void **state)
{
    (void)state;
    const double T = 150.0, omega0 = 10.0; /* 6400 N along the line of action */
    const char *thin = "\"thinning_mm\": 0.05";
    char pitch[512] = "\"pitch_errors_um\": [", run[128];
    for (int k = 0; k < 20; k++)
        strcat(pitch, k == 3 ? ",10" : k ? ",0" : "0");
    strcat(pitch, "]");
    snprintf(run, sizeof run, "\"runout\": {\"eccentricity_um\": 20, \"phase_deg\": 30}");
    /* FE: the loaded static TE over one pinion revolution (um) */
    const char *cases[3] = {"", pitch, run};
    double fe_mean[3], fe_h1[3][2];
    for (int q = 0; q < 3; q++) {
        char mod[640];
        snprintf(mod, sizeof mod, "%s%s%s", thin, cases[q][0] ? ", " : "", cases[q]);
        gs_scene *sc = pair_ok(mod, thin);
        gs_stiffness_opts o;
        gs_stiffness_opts_defaults(&o);
        o.nearfield = 0; /* the lumped meshes stand in for the plain FE model */
        o.positions = 160;
        o.cycles = 20;
        o.tangent = 0;
        o.torque_nm = T;
        gs_stiffness_result r;
        gs_diag d;
        assert_int_equal(gs_stiffness_analyse(sc, 0, &o, &r, &d), GS_OK);
        double te[160], sum = 0, re = 0, im = 0;
        for (int j = 0; j < 160; j++) {
            te[j] = r.pt[j].te_loaded_um * 1e-6;
            double th = r.pt[j].angle_rad;
            sum += te[j];
            re += te[j] * cos(th);
            im += te[j] * sin(th);
        }
        fe_mean[q] = sum / 160;
        fe_h1[q][0] = 2 * re / 160, fe_h1[q][1] = 2 * im / 160;
        gs_stiffness_result_clear(&r);
        gs_scene_free(&sc);
    }
    double fe_pitch = fe_mean[1] - fe_mean[0];
    double fe_run = hypot(fe_h1[2][0] - fe_h1[0][0], fe_h1[2][1] - fe_h1[0][1]);
    print_message("FE contact, one pinion revolution at %.0f N m: mean TE shift of pinion tooth 3 +10 um "
                  "%.4f um; once-per-revolution TE of 20 um run-out %.4f um\n", T, fe_pitch * 1e6, fe_run * 1e6);
    const char *stiff[2] = {"", "{\"type\": \"calibrated\"}"};
    const char *names[2] = {"lumped (rectangular)", "calibrated lumped"};
    for (int k = 0; k < 2; k++) {
        double mean[3], h1[3][2], worst[3], scale[3];
        for (int q = 0; q < 3; q++)
            lumped_revolution(lumped_pair(cases[q], stiff[k], T, omega0), &mean[q], h1[q], &worst[q], &scale[q]);
        double lp = mean[1] - mean[0], lr = hypot(h1[2][0] - h1[0][0], h1[2][1] - h1[0][1]);
        print_message("%s at %.0f rad/s: mean TE shift %.4f um (FE %.4f, %+.2f%%); run-out term %.4f um "
                      "(FE %.4f, %+.2f%%); balance residuals %.1e %.1e %.1e of %.1e J\n",
                      names[k], omega0, lp * 1e6, fe_pitch * 1e6, 100 * (lp / fe_pitch - 1), lr * 1e6,
                      fe_run * 1e6, 100 * (lr / fe_run - 1), worst[0], worst[1], worst[2], scale[0]);
        assert_true(fabs(lp / fe_pitch - 1) < 0.05);
        assert_true(fabs(lr / fe_run - 1) < 0.05);
        /* scale: the work through the pair over the run (about 1 kJ in
         * 36000 steps); the run-out's speed ripple decorrelates the work and
         * brake sums' round-off, which then reaches a few 1e-11 of it */
        for (int q = 0; q < 3; q++)
            assert_true(worst[q] < 1e-10 * scale[q]);
    }
}

/* The planetary_runout train (source tree root) on rigid teeth with lumped
 * meshes: the rectangular wave (calibration NULL) or calibrated from the FE
 * model with that law on linear triangles (for the calibration's speed). */
static json_object *runout_train_lumped(const char *root, const char *calibration)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/deploy/scenes/planetary_runout.json", root);
    json_object *tree = json_object_from_file(path);
    assert_non_null(tree);
    if (calibration)
        vt_pin_linear(tree);
    json_object *bodies = json_object_object_get(tree, "bodies");
    for (size_t i = 0; i < json_object_array_length(bodies); i++) {
        json_object *b = json_object_array_get_idx(bodies, i), *t;
        if (json_object_object_get_ex(b, "teeth", &t))
            json_object_object_add(b, "model", json_object_new_string("rigid"));
    }
    json_object *meshes = json_object_object_get(tree, "meshes");
    for (size_t i = 0; i < json_object_array_length(meshes); i++) {
        json_object *m = json_object_array_get_idx(meshes, i);
        json_object_object_add(m, "model", json_object_new_string("lumped"));
        if (calibration) {
            json_object *st = json_object_new_object();
            json_object_object_add(st, "type", json_object_new_string("calibrated"));
            json_object_object_add(st, "calibration", json_object_new_string(calibration));
            json_object_object_add(m, "stiffness", st);
        }
    }
    return tree;
}

/* The planetary_runout train on rigid teeth with lumped meshes: the sun's
 * run-out enters the three sun-planet meshes (angles in the carrier's
 * frame) and no other; a driven run keeps the energy balance. */
static void lumped_planetary_runout(void **state)
{
    (void)state;
    const char *root = getenv("GEARSIM_SOURCE_ROOT");
    if (!root) {
        print_message("GEARSIM_SOURCE_ROOT not set: planetary run-out not checked\n");
        return;
    }
    gs_system *s = vt_system(runout_train_lumped(root, NULL));
    int with = 0;
    for (int i = 0; i < s->n_meshes; i++) {
        const char *g0 = s->scene->bodies[s->scene->meshes[i].gear[0]].name;
        int sun = !strcmp(g0, "sun");
        assert_int_equal(s->meshes[i].n_err, sun);
        if (sun) {
            assert_true(s->meshes[i].err[0].carrier >= 0);
            assert_true(fabs(s->meshes[i].err[0].runout - 20e-6) < 1e-15);
        }
        with += sun;
    }
    assert_int_equal(with, 3);
    double worst = 0, scale = 0;
    gs_energy e;
    for (int i = 0; i < 4000; i++)
        vt_step_balance(s, &e, &worst, &scale);
    print_message("planetary_runout with lumped meshes: 3 sun-planet meshes carry the run-out; 40 ms driven, "
                  "balance %.2e of %.2e J\n", worst, scale);
    assert_true(worst < 1e-11 * scale);
    gs_system_free(&s);
}

/* The same train with lumped meshes calibrated from the FE model (tangent
 * and secant laws; linear triangles for the calibration's speed). Every
 * mesh starts from rest with the sun's run-out already loading the
 * sun-planet springs: with the table's first node at the start, the exact
 * phase quotient of the piecewise-linear table jumped between two slopes
 * as the step's phase increment changed sign, and Newton stalled at step 0
 * (relative residual 6e-4, tangent; step 1, secant). The table's entries
 * now sit at interval middles (src/models/meshes.c, calibrate). */
static void calibrated_planetary_runout(void **state)
{
    (void)state;
    const char *root = getenv("GEARSIM_SOURCE_ROOT");
    if (!root) {
        print_message("GEARSIM_SOURCE_ROOT not set: calibrated planetary run-out not checked\n");
        return;
    }
    static const char *const laws[] = {"tangent", "secant"};
    for (int l = 0; l < 2; l++) {
        gs_system *s = vt_system(runout_train_lumped(root, laws[l]));
        double worst = 0, scale = 0, iters = 0;
        gs_energy e;
        for (int i = 0; i < 2000; i++) {
            vt_step_balance(s, &e, &worst, &scale);
            iters += s->last_iterations / 2000.0;
        }
        print_message("planetary_runout, calibrated (%s) lumped meshes: 20 ms from rest, balance %.2e of %.2e J, "
                      "%.2f Newton iterations per step\n", laws[l], worst, scale, iters);
        assert_true(worst < 1e-11 * scale);
        gs_system_free(&s);
    }
}

#define SHORT_TESTS                                                                                  \
    cmocka_unit_test(flank_nodes_on_profile), cmocka_unit_test(ring_relief),                           \
        cmocka_unit_test(unmodified_bit_identical), cmocka_unit_test(nearfield_auto_plain_on_modified), cmocka_unit_test(pitch_and_runout),                \
        cmocka_unit_test(bad_input), cmocka_unit_test(harris_map), cmocka_unit_test(compliant_relief), \
        cmocka_unit_test(contact_dynamic_relief), cmocka_unit_test(calibrated_relief),                 \
        cmocka_unit_test(runout_spectrum), cmocka_unit_test(example_scenes),                           \
        cmocka_unit_test(models_refuse), cmocka_unit_test(lumped_tooth_errors),                         \
        cmocka_unit_test(lumped_planetary_runout), cmocka_unit_test(calibrated_planetary_runout)

int main(void)
{
    if (getenv("GEARSIM_TEST_FILTER"))
        cmocka_set_test_filter(getenv("GEARSIM_TEST_FILTER"));
    const struct CMUnitTest tests[] = {SHORT_TESTS};
    /* the long mode (GEARSIM_LONG=1) adds the dynamic run-out spectrum */
    const struct CMUnitTest long_tests[] = {SHORT_TESTS, cmocka_unit_test(runout_dynamic)};
    if (getenv("GEARSIM_LONG"))
        return cmocka_run_group_tests(long_tests, NULL, NULL);
    return cmocka_run_group_tests(tests, NULL, NULL);
}
