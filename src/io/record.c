/* SPDX-License-Identifier: MIT
 * HDF5 time-series record of a run (layout in include/gearsim/record.h). */
#include <hdf5.h>
#include <json-c/json.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/record.h"
#include "gearsim/util.h"

enum { DS_TIME, DS_STEP, DS_ENERGY, DS_ANGLE, DS_OMEGA, DS_FORCE, DS_DEFL, DS_N };

struct gs_record {
    char path[1024];
    hid_t file;
    hid_t ds[DS_N];
    int cols[DS_N];
    int64_t rows;       /* rows on disk */
    int nbuf, cap;      /* buffered rows */
    double *buf[DS_N];
};

static const char *const ds_names[DS_N] = {"time", "step", "energy", "angle", "omega",
                                           "mesh_force", "mesh_deflection"};

static herr_t put_string_attr(hid_t loc, const char *name, const char *value)
{
    hid_t t = H5Tcopy(H5T_C_S1);
    H5Tset_size(t, strlen(value) + 1);
    hid_t sp = H5Screate(H5S_SCALAR);
    hid_t a = H5Acreate2(loc, name, t, sp, H5P_DEFAULT, H5P_DEFAULT);
    herr_t st = a < 0 ? -1 : H5Awrite(a, t, value);
    if (a >= 0)
        H5Aclose(a);
    H5Sclose(sp);
    H5Tclose(t);
    return st;
}

static char *names_json(const gs_system *sys, bool meshes)
{
    json_object *arr = json_object_new_array();
    int n = meshes ? sys->n_meshes : sys->n_bodies;
    for (int i = 0; i < n; i++)
        json_object_array_add(arr, json_object_new_string(meshes ? sys->scene->meshes[i].name
                                                                  : sys->scene->bodies[i].name));
    char *s = gs_strdup(json_object_to_json_string_ext(arr, JSON_C_TO_STRING_PLAIN));
    json_object_put(arr);
    return s;
}

/* Time and step are vectors; every other series is rows x columns, even
 * with one body or one mesh, so readers index them the same way always. */
static int ds_rank(int i)
{
    return i == DS_TIME || i == DS_STEP ? 1 : 2;
}

static hid_t make_ds(hid_t g, const char *name, int cols, bool integer, int rank)
{
    hsize_t dims[2] = {0, (hsize_t)cols}, maxd[2] = {H5S_UNLIMITED, (hsize_t)cols};
    hsize_t chunk[2] = {256, (hsize_t)(cols > 0 ? cols : 1)};
    hid_t sp = H5Screate_simple(rank, dims, maxd);
    hid_t pl = H5Pcreate(H5P_DATASET_CREATE);
    H5Pset_chunk(pl, rank, chunk);
    hid_t ds = H5Dcreate2(g, name, integer ? H5T_NATIVE_INT64 : H5T_NATIVE_DOUBLE, sp, H5P_DEFAULT,
                          pl, H5P_DEFAULT);
    H5Pclose(pl);
    H5Sclose(sp);
    return ds;
}

gs_err gs_record_open(const char *path, const gs_system *sys, gs_record **out, gs_diag *d)
{
    *out = NULL;
    gs_record *r = gs_calloc(1, sizeof *r);
    if (!r)
        return GS_ENOMEM;
    snprintf(r->path, sizeof r->path, "%s", path);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    r->file = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    if (r->file < 0) {
        free(r);
        return gs_diag_set(d, GS_EIO, "path", "cannot create the record file '%s'", path);
    }
    put_string_attr(r->file, "scene", sys->scene->json);
    put_string_attr(r->file, "gearsim_version", "0.1.0");
    hid_t sp = H5Screate(H5S_SCALAR);
    hid_t a = H5Acreate2(r->file, "time_step", H5T_NATIVE_DOUBLE, sp, H5P_DEFAULT, H5P_DEFAULT);
    H5Awrite(a, H5T_NATIVE_DOUBLE, &sys->h);
    H5Aclose(a);
    H5Sclose(sp);
    hid_t g = H5Gcreate2(r->file, "telemetry", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    int cols[DS_N] = {1, 1, 6, sys->n_bodies, sys->n_bodies, sys->n_meshes, sys->n_meshes};
    bool ok = g >= 0;
    for (int i = 0; i < DS_N && ok; i++) {
        r->cols[i] = cols[i];
        if (cols[i] == 0) {
            r->ds[i] = -1;
            continue;
        }
        r->ds[i] = make_ds(g, ds_names[i], cols[i], i == DS_STEP, ds_rank(i));
        ok = r->ds[i] >= 0;
    }
    if (ok) {
        put_string_attr(r->ds[DS_ENERGY], "columns",
                        "[\"kinetic\",\"potential\",\"total\",\"work_in\",\"dissipated\",\"balance_residual\"]");
        char *bn = names_json(sys, false), *mn = names_json(sys, true);
        put_string_attr(g, "bodies", bn ? bn : "[]");
        put_string_attr(g, "meshes", mn ? mn : "[]");
        put_string_attr(r->ds[DS_ANGLE], "bodies", bn ? bn : "[]");
        free(bn);
        free(mn);
    }
    if (g >= 0)
        H5Gclose(g);
    if (!ok) {
        gs_record_close(&r);
        return gs_diag_set(d, GS_EIO, "path", "cannot write the record file '%s'", path);
    }
    H5Fflush(r->file, H5F_SCOPE_GLOBAL);
    *out = r;
    return GS_OK;
}

gs_err gs_record_sample(gs_record *r, const gs_system *sys)
{
    if (r->nbuf == r->cap) {
        int nc = r->cap ? 2 * r->cap : 256;
        for (int i = 0; i < DS_N; i++) {
            double *nb = realloc(r->buf[i], (size_t)nc * (size_t)(r->cols[i] ? r->cols[i] : 1) * sizeof(double));
            if (!nb)
                return GS_ENOMEM;
            r->buf[i] = nb;
        }
        r->cap = nc;
    }
    int k = r->nbuf++;
    gs_energy e;
    gs_system_energy(sys, &e);
    r->buf[DS_TIME][k] = sys->time;
    int64_t st = sys->step;
    memcpy(&r->buf[DS_STEP][k], &st, sizeof st);
    double ev[6] = {e.kinetic, e.potential, e.total, e.work_in, e.dissipated, e.balance_residual};
    memcpy(&r->buf[DS_ENERGY][6 * k], ev, sizeof ev);
    for (int b = 0; b < sys->n_bodies; b++) {
        r->buf[DS_ANGLE][k * sys->n_bodies + b] = gs_system_angle(sys, b);
        r->buf[DS_OMEGA][k * sys->n_bodies + b] = gs_system_omega(sys, b);
    }
    for (int m = 0; m < sys->n_meshes; m++) {
        r->buf[DS_FORCE][k * sys->n_meshes + m] = sys->meshes[m].force;
        r->buf[DS_DEFL][k * sys->n_meshes + m] = sys->meshes[m].deflection;
    }
    return GS_OK;
}

gs_err gs_record_flush(gs_record *r)
{
    if (!r || r->nbuf == 0)
        return GS_OK;
    gs_err err = GS_OK;
    for (int i = 0; i < DS_N; i++) {
        if (r->ds[i] < 0)
            continue;
        int rank = ds_rank(i);
        hsize_t nd[2] = {(hsize_t)(r->rows + r->nbuf), (hsize_t)r->cols[i]};
        hsize_t start[2] = {(hsize_t)r->rows, 0}, count[2] = {(hsize_t)r->nbuf, (hsize_t)r->cols[i]};
        if (H5Dset_extent(r->ds[i], nd) < 0) {
            err = GS_EIO;
            continue;
        }
        hid_t fs = H5Dget_space(r->ds[i]);
        H5Sselect_hyperslab(fs, H5S_SELECT_SET, start, NULL, count, NULL);
        hid_t ms = H5Screate_simple(rank, count, NULL);
        if (H5Dwrite(r->ds[i], i == DS_STEP ? H5T_NATIVE_INT64 : H5T_NATIVE_DOUBLE, ms, fs,
                     H5P_DEFAULT, r->buf[i]) < 0)
            err = GS_EIO;
        H5Sclose(ms);
        H5Sclose(fs);
    }
    r->rows += r->nbuf;
    r->nbuf = 0;
    if (H5Fflush(r->file, H5F_SCOPE_GLOBAL) < 0)
        err = GS_EIO;
    return err;
}

gs_err gs_record_close(gs_record **pr)
{
    if (!pr || !*pr)
        return GS_OK;
    gs_record *r = *pr;
    gs_err err = r->file >= 0 ? gs_record_flush(r) : GS_OK;
    for (int i = 0; i < DS_N; i++) {
        if (r->ds[i] > 0)
            H5Dclose(r->ds[i]);
        free(r->buf[i]);
    }
    if (r->file >= 0 && H5Fclose(r->file) < 0)
        err = GS_EIO;
    free(r);
    *pr = NULL;
    return err;
}

const char *gs_record_path(const gs_record *r) { return r->path; }
int64_t gs_record_rows(const gs_record *r) { return r->rows + r->nbuf; }
