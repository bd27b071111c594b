/* SPDX-License-Identifier: MIT
 * Quasi-static mesh stiffness (stiffness.c): the result written as HDF5 and
 * as JSON. */
#include <hdf5.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "contact/stiffness_hook.h"
#include "contact/stiffness_internal.h"
#include "gearsim/contact.h"
#include "gearsim/fe.h"
#include "gearsim/fe_static.h"
#include "gearsim/mesh.h"
#include "gearsim/models.h"
#include "gearsim/qp.h"
#include "gearsim/stiffness.h"
#include "io/h5attr.h"
#include "gearsim/util.h"

/* ------------------------------------------------------------------------ */
/* HDF5                                                                      */
/* ------------------------------------------------------------------------ */

static herr_t put_ds(hid_t g, const char *name, hid_t type, int rank, const hsize_t *dims,
                     const void *data)
{
    hid_t sp = H5Screate_simple(rank, dims, NULL);
    hid_t ds = H5Dcreate2(g, name, type, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    herr_t st = ds < 0 ? -1 : H5Dwrite(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data);
    if (ds >= 0)
        H5Dclose(ds);
    H5Sclose(sp);
    return st;
}

gs_err gs_stiffness_write_h5(const char *path, const gs_scene *sc, const gs_stiffness_result *r,
                             gs_diag *d)
{
    if (!path || !r || (r->positions > 0 && !r->pt))
        return gs_diag_set(d, GS_EINVAL, "out", "NULL path or empty result");
    int n = r->positions;
    size_t nn = n > 0 ? (size_t)n : 1;
    double *col = malloc(nn * 10 * sizeof *col);
    int *pairs = malloc(nn * sizeof *pairs);
    int *pt_tooth = malloc(nn * GS_STIFF_MAX_PAIRS * 2 * sizeof *pt_tooth);
    double *pf = malloc(nn * GS_STIFF_MAX_PAIRS * sizeof *pf);
    if (!col || !pairs || !pt_tooth || !pf) {
        free(col);
        free(pairs);
        free(pt_tooth);
        free(pf);
        return GS_ENOMEM;
    }
    for (int j = 0; j < n; j++) {
        const gs_stiffness_point *p = &r->pt[j];
        double v[10] = {p->roll, p->angle_rad * 180.0 / GS_PI, p->te_elastic_um, p->te_raw_um, p->te0_um,
                        p->k, p->te_half_um, p->k_tan, p->te_ref_um, p->te_loaded_um};
        for (int c = 0; c < 10; c++)
            col[(size_t)c * nn + (size_t)j] = v[c];
        pairs[j] = p->pairs;
        for (int q = 0; q < GS_STIFF_MAX_PAIRS; q++) {
            bool used = q < p->n_pair;
            pt_tooth[((size_t)j * GS_STIFF_MAX_PAIRS + (size_t)q) * 2] = used ? p->pair[q].tooth[0] : -1;
            pt_tooth[((size_t)j * GS_STIFF_MAX_PAIRS + (size_t)q) * 2 + 1] =
                used ? p->pair[q].tooth[1] : -1;
            pf[(size_t)j * GS_STIFF_MAX_PAIRS + (size_t)q] = used ? p->pair[q].force_n : 0.0;
        }
    }
    gs_err err = GS_EIO;
    hid_t f = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    hid_t g = f < 0 ? -1 : H5Gcreate2(f, "stiffness", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (g >= 0) {
        static const char *const names[10] = {"roll", "angle_deg", "te_elastic_um", "te_raw_um",
                                              "te0_um", "k", "te_half_um", "k_tan",
                                              "te_ref_um", "te_loaded_um"};
        hsize_t d1[1] = {(hsize_t)n}, d2[2] = {(hsize_t)n, GS_STIFF_MAX_PAIRS},
                d3[3] = {(hsize_t)n, GS_STIFF_MAX_PAIRS, 2};
        herr_t st = 0;
        for (int c = 0; c < 10; c++)
            st |= put_ds(g, names[c], H5T_NATIVE_DOUBLE, 1, d1, col + (size_t)c * nn);
        /* te_um: the former name of te_elastic_um, a soft link for one release */
        st |= H5Lcreate_soft("te_elastic_um", g, "te_um", H5P_DEFAULT, H5P_DEFAULT) < 0 ? -1 : 0;
        st |= put_ds(g, "pairs", H5T_NATIVE_INT, 1, d1, pairs);
        st |= put_ds(g, "pair_tooth", H5T_NATIVE_INT, 3, d3, pt_tooth);
        st |= put_ds(g, "pair_force_n", H5T_NATIVE_DOUBLE, 2, d2, pf);
        st |= gsi_h5_string_attr(g, "scene", sc && sc->json ? sc->json : "");
        st |= gsi_h5_string_attr(g, "mesh", r->mesh_name);
        st |= gsi_h5_scalar_attr(g, "driver", H5T_NATIVE_INT, &r->driver);
        st |= gsi_h5_scalar_attr(g, "teeth", H5T_NATIVE_INT, &r->teeth[0]);
        st |= gsi_h5_scalar_attr(g, "teeth_driven", H5T_NATIVE_INT, &r->teeth[1]);
        st |= gsi_h5_scalar_attr(g, "refine", H5T_NATIVE_INT, &r->refine[0]);
        const struct {
            const char *name;
            double v;
        } sc_attr[] = {{"torque_nm", r->torque_nm},         {"force_n", r->force_n},
                       {"face_width_mm", r->face_width_mm}, {"base_radius_m", r->base_radius_m},
                       {"contact_ratio", r->contact_ratio}, {"k_min", r->k_min},
                       {"k_mean", r->k_mean},               {"k_max", r->k_max},
                       {"te_elastic_min", r->te_min},       {"te_elastic_mean", r->te_mean},
                       {"te_elastic_max", r->te_max},       {"te_loaded_min", r->te_loaded_min},
                       {"te_loaded_mean", r->te_loaded_mean}, {"te_loaded_max", r->te_loaded_max},
                       /* the former names of te_elastic_min/mean/max, for one release */
                       {"te_min", r->te_min},               {"te_mean", r->te_mean},
                       {"te_max", r->te_max}};
        for (size_t c = 0; c < sizeof sc_attr / sizeof sc_attr[0]; c++)
            st |= gsi_h5_scalar_attr(g, sc_attr[c].name, H5T_NATIVE_DOUBLE, &sc_attr[c].v);
        if (r->slices > 0) {
            /* the slice analysis: load along the face per position */
            hsize_t dz[1] = {(hsize_t)r->slices}, dl[2] = {(hsize_t)r->positions, (hsize_t)r->slices};
            double *pk = malloc((size_t)r->positions * sizeof *pk);
            if (!pk)
                st = -1;
            for (int j = 0; pk && j < r->positions; j++)
                pk[j] = r->pt[j].peak_load_n_mm;
            st |= put_ds(g, "face_z_mm", H5T_NATIVE_DOUBLE, 1, dz, r->face_z_mm);
            st |= put_ds(g, "face_load_n_per_mm", H5T_NATIVE_DOUBLE, 2, dl, r->face_load);
            if (pk)
                st |= put_ds(g, "peak_load_n_per_mm", H5T_NATIVE_DOUBLE, 1, d1, pk);
            free(pk);
            st |= gsi_h5_scalar_attr(g, "slices", H5T_NATIVE_INT, &r->slices);
            st |= gsi_h5_scalar_attr(g, "k_hbeta", H5T_NATIVE_DOUBLE, &r->k_hbeta);
            st |= gsi_h5_scalar_attr(g, "coupling_mm", H5T_NATIVE_DOUBLE, &r->coupling_mm);
            st |= gsi_h5_scalar_attr(g, "overlap_ratio", H5T_NATIVE_DOUBLE, &r->overlap_ratio);
        }
        if (st >= 0)
            err = GS_OK;
        H5Gclose(g);
    }
    if (f >= 0 && H5Fclose(f) < 0)
        err = GS_EIO;
    free(col);
    free(pairs);
    free(pt_tooth);
    free(pf);
    if (err != GS_OK)
        return gs_diag_set(d, err, "out", "cannot write %s", path);
    return GS_OK;
}

/* JSON number, or null for NaN / infinity. */
static json_object *json_num(double v)
{
    return isfinite(v) ? json_object_new_double(v) : NULL;
}

/* {min, mean, max, peak_to_peak} of a TE over the positions. */
static json_object *json_te_range(double lo, double mean, double hi)
{
    json_object *t = json_object_new_object();
    json_object_object_add(t, "min", json_num(lo));
    json_object_object_add(t, "mean", json_num(mean));
    json_object_object_add(t, "max", json_num(hi));
    json_object_object_add(t, "peak_to_peak", json_num(hi - lo));
    return t;
}

json_object *gs_stiffness_json(const gs_stiffness_result *r, const gs_scene *s)
{
    json_object *o = json_object_new_object();
    json_object_object_add(o, "mesh", json_object_new_string(r->mesh_name));
    json_object_object_add(o, "driver", json_object_new_string(s->bodies[r->body[0]].name));
    json_object_object_add(o, "driven", json_object_new_string(s->bodies[r->body[1]].name));
    json_object *teeth = json_object_new_array();
    json_object_array_add(teeth, json_object_new_int(r->teeth[0]));
    json_object_array_add(teeth, json_object_new_int(r->teeth[1]));
    json_object_object_add(o, "teeth", teeth);
    json_object *ref = json_object_new_array();
    json_object_array_add(ref, json_object_new_int(r->refine[0]));
    json_object_array_add(ref, json_object_new_int(r->refine[1]));
    json_object_object_add(o, "refine", ref);
    json_object *nodes = json_object_new_array();
    json_object_array_add(nodes, json_object_new_int64(r->nodes[0]));
    json_object_array_add(nodes, json_object_new_int64(r->nodes[1]));
    json_object_object_add(o, "nodes", nodes);
    json_object_object_add(o, "positions", json_object_new_int(r->positions));
    json_object_object_add(o, "torque_nm", json_num(r->torque_nm));
    json_object_object_add(o, "force_n", json_num(r->force_n));
    json_object_object_add(o, "base_radius_mm", json_num(r->base_radius_m * 1e3));
    json_object_object_add(o, "face_width_mm", json_num(r->face_width_mm));
    json_object_object_add(o, "contact_ratio", json_num(r->contact_ratio));
    json_object_object_add(o, "units", json_object_new_string("k: N/(mm um) per mm face width; te: um along the line of action"));
    json_object *pts = json_object_new_array();
    for (int j = 0; j < r->positions; j++) {
        const gs_stiffness_point *p = &r->pt[j];
        json_object *q = json_object_new_object();
        json_object_object_add(q, "roll", json_num(p->roll));
        json_object_object_add(q, "angle_deg", json_num(p->angle_rad * 180.0 / 3.14159265358979323846));
        json_object_object_add(q, "k", json_num(p->k));
        /* te_loaded_um: the loaded static TE (the main output); te_elastic_um its
         * elastic part (they differ on modified flanks); te_um: the former name of
         * te_elastic_um, kept for one release (docs/reference/outputs.md). */
        json_object_object_add(q, "te_elastic_um", json_num(p->te_elastic_um));
        json_object_object_add(q, "te_um", json_num(p->te_elastic_um));
        json_object_object_add(q, "te_raw_um", json_num(p->te_raw_um));
        json_object_object_add(q, "te0_um", json_num(p->te0_um));
        json_object_object_add(q, "te_ref_um", json_num(p->te_ref_um));
        json_object_object_add(q, "te_loaded_um", json_num(p->te_loaded_um));
        json_object_object_add(q, "k_tan", json_num(p->k_tan));
        json_object_object_add(q, "pairs", json_object_new_int(p->pairs));
        json_object *fa = json_object_new_array();
        for (int k = 0; k < p->n_pair; k++) {
            json_object *pp = json_object_new_object();
            json_object *tt = json_object_new_array();
            json_object_array_add(tt, json_object_new_int(p->pair[k].tooth[0]));
            json_object_array_add(tt, json_object_new_int(p->pair[k].tooth[1]));
            json_object_object_add(pp, "teeth", tt);
            json_object_object_add(pp, "force_n", json_num(p->pair[k].force_n));
            json_object_array_add(fa, pp);
        }
        json_object_object_add(q, "pair_forces", fa);
        json_object_object_add(q, "converged", json_object_new_boolean(p->converged));
        json_object_object_add(q, "penetration_um", json_num(p->penetration_um));
        json_object_array_add(pts, q);
    }
    json_object_object_add(o, "points", pts);
    json_object *k = json_object_new_object();
    json_object_object_add(k, "min", json_num(r->k_min));
    json_object_object_add(k, "mean", json_num(r->k_mean));
    json_object_object_add(k, "max", json_num(r->k_max));
    json_object_object_add(k, "tangent_mean", json_num(r->k_tan_mean));
    json_object_object_add(o, "k", k);
    json_object_object_add(o, "te_elastic_um", json_te_range(r->te_min, r->te_mean, r->te_max));
    json_object_object_add(o, "te_um", json_te_range(r->te_min, r->te_mean, r->te_max)); /* alias, one release */
    json_object_object_add(o, "te_loaded_um",
                           json_te_range(r->te_loaded_min, r->te_loaded_mean, r->te_loaded_max));
    json_object_object_add(o, "modified", json_object_new_boolean(r->modified));
    json_object_object_add(o, "fraction_multi_pair", json_num(r->frac_multi));
    json_object_object_add(o, "seconds", json_num(r->seconds));
    json_object_object_add(o, "solves", json_object_new_int64(r->solves));
    json_object_object_add(o, "columns", json_object_new_int64(r->columns));
    json_object_object_add(o, "window_widened", json_object_new_int64(r->window_widened));
    json_object_object_add(o, "zone_fraction", json_num(r->zone_fraction));
    json_object_object_add(o, "zone_restarts", json_object_new_int64(r->zone_restarts));
    json_object *tm = json_object_new_object();
    json_object_object_add(tm, "cpu_s", json_num(r->cpu_seconds));
    json_object_object_add(tm, "mesh_s", json_num(r->cpu_mesh));
    json_object_object_add(tm, "factor_s", json_num(r->cpu_factor));
    json_object_object_add(tm, "columns_s", json_num(r->cpu_columns));
    json_object_object_add(tm, "solves_s", json_num(r->cpu_solves));
    json_object_object_add(tm, "contact_s", json_num(r->cpu_contact));
    json_object_object_add(o, "cpu", tm);
    if (r->slices > 0) {
        /* the slice analysis (docs/explanation/helical.md) */
        json_object *sl = json_object_new_object(), *sec = json_object_new_object();
        json_object_object_add(sl, "slices", json_object_new_int(r->slices));
        json_object_object_add(sl, "coupling_mm", json_num(r->coupling_mm));
        json_object_object_add(sl, "local_compliance_um_mm_per_n", json_num(r->local_compliance));
        json_object_object_add(sl, "overlap_ratio", json_num(r->overlap_ratio));
        json_object_object_add(sl, "k_hbeta", json_num(r->k_hbeta));
        json_object_object_add(sec, "k_min", json_num(r->section_k_min));
        json_object_object_add(sec, "k_max", json_num(r->section_k_max));
        json_object_object_add(sec, "te_loaded_peak_to_peak_um", json_num(r->section_te_pp));
        json_object_object_add(sl, "transverse_section", sec);
        json_object *zz = json_object_new_array(), *fl = json_object_new_array(), *pk = json_object_new_array();
        for (int i = 0; i < r->slices; i++)
            json_object_array_add(zz, json_num(r->face_z_mm[i]));
        for (int j = 0; j < r->positions; j++) {
            json_object *row = json_object_new_array();
            for (int i = 0; i < r->slices; i++)
                json_object_array_add(row, json_num(r->face_load[(size_t)j * r->slices + i]));
            json_object_array_add(fl, row);
            json_object_array_add(pk, json_num(r->pt[j].peak_load_n_mm));
        }
        json_object_object_add(sl, "face_z_mm", zz);
        json_object_object_add(sl, "face_load_n_per_mm", fl);
        json_object_object_add(sl, "peak_load_n_per_mm", pk);
        json_object_object_add(o, "slice_analysis", sl);
    }
    return o;
}
