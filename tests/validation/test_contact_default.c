/* SPDX-License-Identifier: MIT
 * The default contact treatment on the shipped scenes (docs/explanation/contact_treatments.md,
 * "Contact treatments"): every builtin scene with contact meshes, loaded as
 * shipped (no numerics.contact: the default "closure_energy", on the
 * scene's own mesh, order 2, and time step), penetrates at most 1 % of the
 * static deflection of its meshes at their running load. The static
 * deflection is independent of the dynamic run: the quasi-static analysis
 * of the same mesh (gs_stiffness_analyse, plain FE contact as the dynamic
 * model has it, mean TE over 4 roll positions) at the mesh's steady force:
 *  - contact_drive: the scene's 20 N m on the wheel (the analysis' default);
 *  - planetary_contact, planetary_runout: every mesh carries the sun's
 *    moment over three sun base radii along its line of action (the
 *    train's closed form; sun and planets have the same base radius);
 *  - pair_relief, stiffness_pair: no loads and at rest, so no contact is
 *    made; the bar is taken at the analysis' default 200 N/mm;
 *  - contact_impact (the seed's experiment 7.1, no load): at most 0.001 um
 *    at each of 25 impacts, every impact printed.
 * The scene list is checked against gs_scene_builtin_names, so a new
 * shipped contact scene without a case here fails.
 * Cheap by default (contact_drive 30 ms, through the 20 ms ramp to full
 * load; the planetary trains 8 ms; the unloaded pairs 2 ms; 25 impacts);
 * GEARSIM_LONG=1 runs contact_drive 200 ms and the trains 60 ms. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <json-c/json.h>

#include "gearsim/geometry.h"
#include "gearsim/stiffness.h"
#include "gearsim/step.h"
#include "scene_build.h"

static bool long_mode(void)
{
    return getenv("GEARSIM_LONG") != NULL;
}

/* Static deflection (m) of mesh mi of scene sc at driver moment torque
 * (0: the analysis' default load); tried with both signs of the moment
 * when the first finds no flank to carry it. */
static double static_deflection(const gs_scene *sc, int mi, double torque)
{
    gs_stiffness_opts o;
    gs_stiffness_opts_defaults(&o);
    o.positions = 4;
    o.tangent = 0;
    o.nearfield = 0;
    o.torque_nm = torque;
    gs_stiffness_result r;
    gs_diag d;
    gs_err e = gs_stiffness_analyse(sc, mi, &o, &r, &d);
    if (e == GS_EINFEASIBLE && torque != 0.0) {
        o.torque_nm = -torque;
        e = gs_stiffness_analyse(sc, mi, &o, &r, &d);
    }
    if (e != GS_OK)
        print_error("stiffness of mesh %d: %s: %s\n", mi, d.field, d.message);
    assert_int_equal(e, GS_OK);
    double te = r.te_mean * 1e-6;
    print_message("  static deflection of mesh %s: %.4f um (F %.1f N, %d positions)\n", r.mesh_name, r.te_mean,
                  r.force_n, r.positions);
    gs_stiffness_result_clear(&r);
    assert_true(te > 0.0);
    return te;
}

/* Run the builtin scene as shipped for t_end simulated seconds; returns
 * the deepest penetration of each contact mesh over the run in pen[]. */
static void run_shipped(const char *name, double t_end, double *pen, gs_system **keep)
{
    gs_system *s = vt_system(vt_scene(name));
    assert_int_equal(s->scene->contact_scheme, GS_CONTACT_CLOSURE_ENERGY);
    assert_true(s->n_meshes <= 64);
    int n = (int)lround(t_end / s->h);
    gs_energy e;
    double worst = 0, scale = 0;
    for (int m = 0; m < s->n_meshes; m++)
        pen[m] = 0;
    for (int i = 0; i < n; i++) {
        vt_step_balance(s, &e, &worst, &scale);
        for (int m = 0; m < s->n_meshes; m++)
            pen[m] = fmax(pen[m], s->meshes[m].penetration);
    }
    print_message("%s as shipped, %.0f ms at h %.1e: balance %.2e of %.2e J\n", name, t_end * 1e3, s->h, worst,
                  scale);
    assert_true(worst <= 1e-9 * fmax(scale, 1e-3));
    *keep = s;
}

/* The bar of one scene: each contact mesh's penetration at most 1 % of
 * its static deflection at force_n along its line of action (0: the
 * analysis' default load). */
static void check_scene(const char *name, double t_end, double force_n)
{
    double pen[64];
    gs_system *s;
    run_shipped(name, t_end, pen, &s);
    const gs_scene *sc = s->scene;
    double defl = 0;
    for (int m = 0; m < sc->n_meshes; m++) {
        if (sc->meshes[m].model != GS_MESH_CONTACT)
            continue;
        /* the planetary meshes all have the same pair geometry: one analysis
         * per kind (external sun-planet, internal planet-ring) */
        bool same = m > 0 && sc->meshes[m - 1].model == GS_MESH_CONTACT &&
                    sc->bodies[sc->meshes[m].gear[1]].gear.kind == sc->bodies[sc->meshes[m - 1].gear[1]].gear.kind &&
                    sc->bodies[sc->meshes[m].gear[0]].gear.teeth == sc->bodies[sc->meshes[m - 1].gear[0]].gear.teeth &&
                    sc->bodies[sc->meshes[m].gear[1]].gear.teeth == sc->bodies[sc->meshes[m - 1].gear[1]].gear.teeth;
        if (!same) {
            double torque = 0;
            if (force_n > 0) {
                torque = force_n * gs_gear_base_radius(&sc->bodies[sc->meshes[m].gear[0]].gear);
            }
            defl = static_deflection(sc, m, torque);
        }
        print_message("| %s | %s | %.5f | %.4f | %.3f %% |\n", name, sc->meshes[m].name, pen[m] * 1e6, defl * 1e6,
                      100 * pen[m] / defl);
        assert_true(pen[m] <= 0.01 * defl);
    }
    gs_system_free(&s);
}

static void contact_drive(void **st)
{
    (void)st;
    check_scene("contact_drive", long_mode() ? 0.2 : 0.03, 0);
}

/* The sun's 20 N m over three sun base radii, along every mesh's line of
 * action. */
static double planetary_force(const char *name)
{
    gs_scene *sc = vt_scene_parse(vt_scene(name));
    int sun = gs_scene_find_body(sc, "sun");
    assert_true(sun >= 0);
    double rb = gs_gear_base_radius(&sc->bodies[sun].gear);
    double moment = 0;
    for (int i = 0; i < sc->n_loads; i++)
        if (sc->loads[i].body == sun)
            moment = fmax(moment, fabs(sc->loads[i].moment));
    gs_scene_free(&sc);
    assert_true(moment > 0);
    return moment / (3 * rb);
}

static void planetary_contact(void **st)
{
    (void)st;
    check_scene("planetary_contact", long_mode() ? 0.06 : 0.008, planetary_force("planetary_contact"));
}

static void planetary_runout(void **st)
{
    (void)st;
    check_scene("planetary_runout", long_mode() ? 0.06 : 0.008, planetary_force("planetary_runout"));
}

static void unloaded_pairs(void **st)
{
    (void)st;
    check_scene("pair_relief", 0.002, 0);
    check_scene("stiffness_pair", 0.002, 0);
}

/* Seed 7.1 as shipped (default treatment, default mesh, h 1e-6 s): at
 * most 0.001 um at each of 25 impacts (a new contact after a step
 * without any), E itself conserved. */
static void impacts(void **st)
{
    (void)st;
    gs_system *s = vt_system(vt_scene("contact_impact"));
    assert_int_equal(s->scene->contact_scheme, GS_CONTACT_CLOSURE_ENERGY);
    gs_energy e0, e;
    gs_system_energy(s, &e0);
    double pen[25] = {0}, drift = 0;
    int impacts = 0, steps = 0, start[25] = {0};
    bool touching = false;
    while (steps < 30000) {
        assert_int_equal(gs_step_serial(s), GS_OK);
        steps++;
        gs_system_energy(s, &e);
        drift = fmax(drift, fabs(e.total - e0.total) / e0.total);
        const gs_gmesh_rt *m = &s->meshes[0];
        bool now = m->n_active > 0;
        if (now && !touching) {
            if (impacts == 25)
                break;
            start[impacts++] = steps;
        }
        if (impacts > 0)
            pen[impacts - 1] = fmax(pen[impacts - 1], m->penetration);
        touching = now;
    }
    print_message("contact_impact as shipped: %d impacts in %d steps, max |E - E0|/E0 %.2e\n", impacts, steps, drift);
    print_message("| impact | first step | deepest penetration (um) |\n|---|---|---|\n");
    double worst = 0;
    for (int i = 0; i < impacts; i++) {
        print_message("| %d | %d | %.5f |\n", i + 1, start[i], pen[i] * 1e6);
        worst = fmax(worst, pen[i]);
    }
    print_message("deepest over all impacts: %.5f um\n", worst * 1e6);
    assert_int_equal(impacts, 25);
    assert_true(drift < 1e-10);
    for (int i = 0; i < impacts; i++)
        assert_true(pen[i] <= 0.001e-6);
    gs_system_free(&s);
}

/* Every builtin scene with a contact mesh has its case above. */
static void all_covered(void **st)
{
    (void)st;
    const char *cases[] = {"contact_drive", "contact_impact", "pair_relief", "stiffness_pair",
                           "planetary_contact", "planetary_runout", NULL};
    for (const char *const *n = gs_scene_builtin_names(); *n; n++) {
        gs_scene *sc = vt_scene_parse(vt_scene(*n));
        bool contact = false;
        for (int m = 0; m < sc->n_meshes; m++)
            contact |= sc->meshes[m].model == GS_MESH_CONTACT;
        bool listed = false;
        for (int k = 0; cases[k]; k++)
            listed |= !strcmp(cases[k], *n);
        if (contact != listed)
            print_error("builtin %s: contact meshes %d, checked here %d\n", *n, contact, listed);
        assert_true(contact == listed);
        /* the treatment of a scene without contact meshes is the seed's (it
         * has no contact rows) */
        assert_int_equal(sc->contact_scheme, contact ? GS_CONTACT_CLOSURE_ENERGY : GS_CONTACT_SEED);
        gs_scene_free(&sc);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(all_covered),   cmocka_unit_test(unloaded_pairs),     cmocka_unit_test(impacts),
        cmocka_unit_test(contact_drive), cmocka_unit_test(planetary_contact), cmocka_unit_test(planetary_runout),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
