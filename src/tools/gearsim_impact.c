/* SPDX-License-Identifier: MIT
 * gearsim-impact: the impact calculator (include/gearsim/impact.h,
 * docs/explanation/impact.md).
 *
 *   gearsim-impact CASE.json
 *
 * A case with "contact" is one frictional impact of two bodies (Routh's
 * method); "hypothesis" is "newton", "poisson", "stronge" or "all" (one
 * result per hypothesis). A case with "contacts" is one velocity-level step
 * with several contacts (Lemke; frictionless also checked as a QP). Prints
 * one JSON object on stdout (keys in docs/explanation/impact.md). Exit status
 * 0 on success, 1 on an error (message on stderr naming the field), 2 on bad
 * usage. Not an MPI program. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <json-c/json.h>

#include "gearsim/impact.h"
#include "scene/jsonv.h"
#include "tool.h"

static json_object *vec2(const double v[2])
{
    json_object *a = json_object_new_array();
    json_object_array_add(a, json_object_new_double(v[0]));
    json_object_array_add(a, json_object_new_double(v[1]));
    return a;
}

static void put(json_object *o, const char *k, double v)
{
    json_object_object_add(o, k, json_object_new_double(v));
}

/* Input ranges (SI units): wide enough for any gear or machine part, narrow
 * enough that every product the solvers form (W, energies, impulses) stays
 * a finite double, so no result prints Infinity or NaN. */
#define IMP_MASS_MIN 1e-9
#define IMP_MASS_MAX 1e9
#define IMP_INERTIA_MIN 1e-15
#define IMP_INERTIA_MAX 1e9
#define IMP_LENGTH_MAX 1e3    /* centres, contact points (m) */
#define IMP_SPEED_MAX 1e4     /* velocities (m/s), gravity (m/s^2) */
#define IMP_OMEGA_MAX 1e6     /* rad/s */
#define IMP_MU_MAX 1e3
#define IMP_STEP_MAX 1e3      /* s */

/* A required-or-defaulted [x, y] of finite numbers of magnitude <= max. */
static gs_err get_vec2(json_object *o, const char *key, const char *path, bool required,
                       double max, double out[2], gs_diag *d)
{
    char p[256];
    gsi_path(p, sizeof p, path, key);
    json_object *a;
    GS_TRY(gsi_json_array(o, key, path, required, &a, d));
    if (!a)
        return GS_OK;
    if (json_object_array_length(a) != 2)
        return gs_diag_set(d, GS_ESCHEMA, p, "'%s' must be an array of two numbers", key);
    for (int i = 0; i < 2; i++)
        if (!gsi_json_as_double(json_object_array_get_idx(a, i), &out[i]))
            return gs_diag_set(d, GS_ESCHEMA, p, "'%s' must be an array of two finite numbers", key);
    for (int i = 0; i < 2; i++)
        if (fabs(out[i]) > max)
            return gs_diag_set(d, GS_ERANGE, p, "'%s' = [%g, %g]: each component must be within +-%g "
                               "(SI units; scale the case)", key, out[0], out[1], max);
    return GS_OK;
}

static gs_err get_body(json_object *o, const char *path, gs_impact_body *b, gs_diag *d)
{
    static const char *const keys[] = {"name", "mass", "inertia", "centre", "velocity", "omega",
                                       "fixed", NULL};
    if (!json_object_is_type(o, json_type_object))
        return gs_diag_set(d, GS_ESCHEMA, path, "a body must be an object");
    GS_TRY(gsi_json_only(o, path, keys, d));
    memset(b, 0, sizeof *b);
    GS_TRY(gsi_json_bool(o, "fixed", path, false, &b->fixed, d));
    GS_TRY(gsi_json_positive(o, "mass", path, IMP_MASS_MAX, !b->fixed, 0.0, &b->mass, d));
    GS_TRY(gsi_json_positive(o, "inertia", path, IMP_INERTIA_MAX, !b->fixed, 0.0, &b->inertia, d));
    char p[256];
    if (!b->fixed && b->mass < IMP_MASS_MIN) {
        gsi_path(p, sizeof p, path, "mass");
        return gs_diag_set(d, GS_ERANGE, p, "'mass' = %g is below %g kg (scale the case)", b->mass, IMP_MASS_MIN);
    }
    if (!b->fixed && b->inertia < IMP_INERTIA_MIN) {
        gsi_path(p, sizeof p, path, "inertia");
        return gs_diag_set(d, GS_ERANGE, p, "'inertia' = %g is below %g kg m^2 (scale the case)", b->inertia,
                           IMP_INERTIA_MIN);
    }
    GS_TRY(get_vec2(o, "centre", path, !b->fixed, IMP_LENGTH_MAX, b->centre, d));
    GS_TRY(get_vec2(o, "velocity", path, false, IMP_SPEED_MAX, b->velocity, d));
    GS_TRY(gsi_json_number(o, "omega", path, -IMP_OMEGA_MAX, IMP_OMEGA_MAX, false, 0.0, &b->omega, d));
    return GS_OK;
}

static json_object *bodies_json(int n, const double *v, const double *w)
{
    json_object *a = json_object_new_array();
    for (int i = 0; i < n; i++) {
        json_object *b = json_object_new_object();
        json_object_object_add(b, "velocity", vec2(v + 2 * i));
        put(b, "omega", w[i]);
        json_object_array_add(a, b);
    }
    return a;
}

static json_object *single_json(const gs_impact_result *r, gs_restitution law)
{
    json_object *o = json_object_new_object();
    json_object_object_add(o, "hypothesis", json_object_new_string(gs_restitution_name(law)));
    json_object_object_add(o, "process", json_object_new_string(gs_impact_process_name(r->process)));
    json_object *im = json_object_new_object();
    put(im, "normal", r->impulse_n);
    put(im, "tangential", r->impulse_t);
    put(im, "normal_compression", r->impulse_n_compression);
    if (r->impulse_n_slip_stop >= 0.0)
        put(im, "normal_slip_stop", r->impulse_n_slip_stop);
    else
        json_object_object_add(im, "normal_slip_stop", NULL);
    json_object_object_add(o, "impulse", im);
    json_object *cv = json_object_new_object();
    json_object_object_add(cv, "before", vec2(r->v0));
    json_object_object_add(cv, "after", vec2(r->v));
    json_object_object_add(o, "contact_velocity", cv);
    double v[4] = {r->velocity[0][0], r->velocity[0][1], r->velocity[1][0], r->velocity[1][1]};
    json_object_object_add(o, "bodies", bodies_json(2, v, r->omega));
    json_object *wk = json_object_new_object();
    put(wk, "normal_compression", r->work_n_compression);
    put(wk, "normal_restitution", r->work_n_restitution);
    json_object_object_add(o, "work", wk);
    json_object *ds = json_object_new_object();
    put(ds, "normal", r->dissipation_n);
    put(ds, "tangential", r->dissipation_t);
    put(ds, "total", r->dissipation);
    json_object_object_add(o, "dissipation", ds);
    json_object *en = json_object_new_object();
    put(en, "before", r->energy_before);
    put(en, "after", r->energy_after);
    json_object_object_add(o, "energy", en);
    json_object *fr = json_object_new_object();
    json_object_object_add(fr, "tangent", vec2(r->tangent));
    json_object_object_add(fr, "normal", vec2(r->normal));
    json_object *W = json_object_new_array();
    for (int i = 0; i < 3; i++)
        json_object_array_add(W, json_object_new_double(r->W[i]));
    json_object_object_add(fr, "W_tt_tn_nn", W);
    json_object_object_add(o, "frame", fr);
    return o;
}

static gs_err run_single(json_object *root, gs_impact_body *bodies, int nb, json_object **out,
                         gs_diag *d)
{
    if (nb != 2)
        return gs_diag_set(d, GS_ESCHEMA, "bodies", "a case with 'contact' needs exactly 2 bodies");
    gs_impact_case c;
    memset(&c, 0, sizeof c);
    c.body[0] = bodies[0];
    c.body[1] = bodies[1];
    json_object *ct;
    static const char *const ckeys[] = {"point", "normal", NULL};
    GS_TRY(gsi_json_object(root, "contact", "", true, &ct, d));
    GS_TRY(gsi_json_only(ct, "contact", ckeys, d));
    GS_TRY(get_vec2(ct, "point", "contact", true, IMP_LENGTH_MAX, c.point, d));
    GS_TRY(get_vec2(ct, "normal", "contact", true, IMP_LENGTH_MAX, c.normal, d));
    GS_TRY(gsi_json_number(root, "e", "", 0.0, 1.0, true, 0.0, &c.e, d));
    GS_TRY(gsi_json_number(root, "mu", "", 0.0, IMP_MU_MAX, false, 0.0, &c.mu, d));
    char hyp[32];
    GS_TRY(gsi_json_string(root, "hypothesis", "", false, "stronge", hyp, sizeof hyp, d));
    bool all = strcmp(hyp, "all") == 0;
    if (!all && !gs_restitution_parse(hyp, &c.law))
        return gs_diag_set(d, GS_ERANGE, "hypothesis",
                           "'hypothesis' = '%s' is not newton, poisson, stronge or all", hyp);
    json_object *o = NULL, *arr = all ? json_object_new_array() : NULL;
    for (int k = 0; k < 3; k++) {
        if (all)
            c.law = (gs_restitution)k;
        gs_impact_result r;
        gs_err e = gs_impact_solve(&c, &r, d);
        if (e != GS_OK) {
            json_object_put(arr);
            return e;
        }
        o = single_json(&r, c.law);
        if (!all)
            break;
        json_object_array_add(arr, o);
    }
    if (all) {
        o = json_object_new_object();
        json_object_object_add(o, "results", arr);
    }
    json_object_object_add(o, "mode", json_object_new_string("single"));
    *out = o;
    return GS_OK;
}

static gs_err run_multi(json_object *root, gs_impact_body *bodies, int nb, json_object *cts,
                        json_object **out, gs_diag *d)
{
    gs_impact_multi m = {nb, bodies, 0, NULL, 0.0, {0.0, 0.0}};
    double e_def, mu_def;
    GS_TRY(gsi_json_number(root, "e", "", 0.0, 1.0, false, 0.0, &e_def, d));
    GS_TRY(gsi_json_number(root, "mu", "", 0.0, IMP_MU_MAX, false, 0.0, &mu_def, d));
    GS_TRY(gsi_json_number(root, "time_step", "", 0.0, IMP_STEP_MAX, false, 0.0, &m.h, d));
    GS_TRY(get_vec2(root, "gravity", "", false, IMP_SPEED_MAX, m.gravity, d));
    int nc = (int)json_object_array_length(cts);
    if (nc < 1 || nc > 200)
        return gs_diag_set(d, GS_ERANGE, "contacts", "between 1 and 200 contacts are allowed");
    gs_impact_point *pts = calloc((size_t)nc, sizeof *pts);
    double *buf = calloc((size_t)(3 * nb + 2 * nc) * 2, sizeof *buf);
    gs_err err = pts && buf ? GS_OK : GS_ENOMEM;
    static const char *const keys[] = {"bodies", "point", "normal", "e", "mu", NULL};
    for (int k = 0; k < nc && err == GS_OK; k++) {
        char p[64];
        snprintf(p, sizeof p, "contacts[%d]", k);
        json_object *c = json_object_array_get_idx(cts, k), *bi;
        if (!json_object_is_type(c, json_type_object)) {
            err = gs_diag_set(d, GS_ESCHEMA, p, "a contact must be an object");
            break;
        }
        if ((err = gsi_json_only(c, p, keys, d)) != GS_OK ||
            (err = gsi_json_array(c, "bodies", p, true, &bi, d)) != GS_OK ||
            (err = get_vec2(c, "point", p, true, IMP_LENGTH_MAX, pts[k].point, d)) != GS_OK ||
            (err = get_vec2(c, "normal", p, true, IMP_LENGTH_MAX, pts[k].normal, d)) != GS_OK ||
            (err = gsi_json_number(c, "e", p, 0.0, 1.0, false, e_def, &pts[k].e, d)) != GS_OK ||
            (err = gsi_json_number(c, "mu", p, 0.0, IMP_MU_MAX, false, mu_def, &pts[k].mu, d)) != GS_OK)
            break;
        char pb[96];
        snprintf(pb, sizeof pb, "%s.bodies", p);
        if (json_object_array_length(bi) != 2 ||
            !json_object_is_type(json_object_array_get_idx(bi, 0), json_type_int) ||
            !json_object_is_type(json_object_array_get_idx(bi, 1), json_type_int)) {
            err = gs_diag_set(d, GS_ESCHEMA, pb, "'bodies' must be two body indices");
            break;
        }
        pts[k].body[0] = json_object_get_int(json_object_array_get_idx(bi, 0));
        pts[k].body[1] = json_object_get_int(json_object_array_get_idx(bi, 1));
    }
    if (err == GS_OK) {
        m.n_contact = nc;
        m.contacts = pts;
        gs_impact_multi_result r = {buf, buf + 2 * nb, buf + 3 * nb, buf + 3 * nb + nc, {0}, 0, false, 0, 0};
        err = gs_impact_multi_solve(&m, &r, d);
        if (err == GS_OK) {
            json_object *o = json_object_new_object();
            json_object_object_add(o, "mode", json_object_new_string("multi"));
            json_object *l = json_object_new_object();
            json_object_object_add(l, "status", json_object_new_string(gs_lcp_status_name(r.lcp.status)));
            json_object_object_add(l, "size", json_object_new_int(r.lcp_size));
            json_object_object_add(l, "pivots", json_object_new_int(r.lcp.pivots));
            put(l, "residual", r.lcp.residual);
            json_object_object_add(l, "degenerate", json_object_new_int(r.lcp.n_degenerate));
            json_object_object_add(l, "multiple", json_object_new_boolean(r.lcp.multiple));
            json_object_object_add(o, "several_solutions", json_object_new_boolean(r.several));
            json_object_object_add(o, "lcp", l);
            json_object *ca = json_object_new_array();
            for (int k = 0; k < nc; k++) {
                json_object *ci = json_object_new_object();
                put(ci, "normal", r.impulse_n[k]);
                put(ci, "tangential", r.impulse_t[k]);
                json_object_array_add(ca, ci);
            }
            json_object_object_add(o, "contacts", ca);
            json_object_object_add(o, "bodies", bodies_json(nb, r.velocity, r.omega));
            json_object *en = json_object_new_object();
            put(en, "before", r.energy_before);
            put(en, "after", r.energy_after);
            json_object_object_add(o, "energy", en);
            bool frictionless = true;
            for (int k = 0; k < nc; k++)
                frictionless = frictionless && pts[k].mu == 0.0;
            if (frictionless) { /* the same step as a QP: the impulses must agree */
                gs_impact_multi_result q = {buf + 3 * nb + 2 * nc, buf + 5 * nb + 2 * nc,
                                            buf + 6 * nb + 2 * nc, buf + 6 * nb + 3 * nc,
                                            {0}, 0, false, 0, 0};
                gs_diag dq;
                gs_err eq = gs_impact_multi_solve_qp(&m, &q, &dq);
                json_object *qc = json_object_new_object();
                json_object_object_add(qc, "status", json_object_new_string(gs_errcode(eq)));
                if (eq == GS_OK) {
                    double dv = 0.0;
                    for (int i = 0; i < 2 * nb; i++)
                        dv = fmax(dv, fabs(q.velocity[i] - r.velocity[i]));
                    for (int i = 0; i < nb; i++)
                        dv = fmax(dv, fabs(q.omega[i] - r.omega[i]));
                    put(qc, "max_velocity_difference", dv);
                }
                json_object_object_add(o, "qp_check", qc);
            }
            *out = o;
        }
    }
    free(pts);
    free(buf);
    return err;
}

/* The first non-finite number in a result (a path into it), or false. */
static bool non_finite(json_object *o, char *where, size_t cap)
{
    switch (json_object_get_type(o)) {
    case json_type_double:
        return !isfinite(json_object_get_double(o)) && (snprintf(where, cap, "%s", ""), true);
    case json_type_array:
        for (size_t i = 0; i < json_object_array_length(o); i++)
            if (non_finite(json_object_array_get_idx(o, i), where, cap))
                return true;
        return false;
    case json_type_object: {
        json_object_object_foreach(o, k, v) if (non_finite(v, where, cap)) {
            char tail[160];
            snprintf(tail, sizeof tail, "%s", where);
            int n = snprintf(where, cap, "%.60s", k);
            if (tail[0] && n > 0 && (size_t)n + 1 < cap)
                snprintf(where + n, cap - (size_t)n, ".%.90s", tail);
            return true;
        }
        return false;
    }
    default:
        return false;
    }
}

int main(int argc, char **argv)
{
    if (argc != 2 || argv[1][0] == '-') {
        fprintf(stderr, "usage: gearsim-impact CASE.json\n");
        return TOOL_USAGE;
    }
    gs_diag d;
    gs_diag_clear(&d);
    json_object *root = json_object_from_file(argv[1]);
    if (!root) {
        fprintf(stderr, "gearsim-impact: error: %s: cannot read or parse JSON\n", argv[1]);
        return TOOL_FAIL;
    }
    gs_err err = GS_OK;
    json_object *out = NULL, *ba, *cts = NULL, *ct = NULL;
    gs_impact_body *bodies = NULL;
    int nb = 0;
    static const char *const keys[] = {"bodies", "contact", "contacts", "e", "mu", "hypothesis",
                                       "time_step", "gravity", "name", "comment", NULL};
    if (!json_object_is_type(root, json_type_object))
        err = gs_diag_set(&d, GS_ESCHEMA, "", "the case must be a JSON object");
    if (err == GS_OK)
        err = gsi_json_only(root, "", keys, &d);
    if (err == GS_OK)
        err = gsi_json_array(root, "bodies", "", true, &ba, &d);
    if (err == GS_OK) {
        nb = (int)json_object_array_length(ba);
        if (nb < 1 || nb > 100)
            err = gs_diag_set(&d, GS_ERANGE, "bodies", "between 1 and 100 bodies are allowed");
    }
    if (err == GS_OK && !(bodies = calloc((size_t)nb, sizeof *bodies)))
        err = GS_ENOMEM;
    for (int i = 0; i < nb && err == GS_OK; i++) {
        char p[32];
        snprintf(p, sizeof p, "bodies[%d]", i);
        err = get_body(json_object_array_get_idx(ba, i), p, &bodies[i], &d);
    }
    if (err == GS_OK)
        err = gsi_json_array(root, "contacts", "", false, &cts, &d);
    if (err == GS_OK)
        err = gsi_json_object(root, "contact", "", false, &ct, &d);
    if (err == GS_OK && !cts == !ct)
        err = gs_diag_set(&d, GS_ESCHEMA, "contact", "give exactly one of 'contact' and 'contacts'");
    if (err == GS_OK)
        err = cts ? run_multi(root, bodies, nb, cts, &out, &d) : run_single(root, bodies, nb, &out, &d);
    char where[160];
    if (err == GS_OK && non_finite(out, where, sizeof where))
        err = gs_diag_set(&d, GS_ERANGE, "bodies", "the result ('%s') is not finite for these inputs: "
                          "masses, inertias, lengths and speeds too far apart; scale the case", where);
    /* The solvers name their own quantities (W, the contact mass matrix;
     * the relative velocity); the user gave bodies. */
    if (err != GS_OK && (!strcmp(d.field, "W") || !strcmp(d.field, "velocity"))) {
        char m[sizeof d.message];
        snprintf(m, sizeof m, "%s", d.message);
        snprintf(d.message, sizeof d.message, "the bodies' masses, inertias, centres and velocities with this "
                 "contact give no usable impact (%.200s)", m);
        snprintf(d.field, sizeof d.field, "bodies");
    }
    if (err == GS_OK) {
        printf("%s\n", json_object_to_json_string_ext(out, JSON_C_TO_STRING_PRETTY));
    } else {
        fprintf(stderr, "gearsim-impact: error: %s%s%s [%s]\n", d.field, d.field[0] ? ": " : "",
                d.message[0] ? d.message : gs_strerror(err), gs_errcode(err));
    }
    json_object_put(out);
    json_object_put(root);
    free(bodies);
    return err == GS_OK ? 0 : TOOL_FAIL;
}
