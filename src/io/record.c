/* SPDX-License-Identifier: MIT
 * HDF5 time-series record of a run (layout in include/gearsim/record.h). */
#include <hdf5.h>
#include <json-c/json.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "gearsim/mesh_io.h"
#include "gearsim/record.h"
#include "io/h5attr.h"
#include "gearsim/util.h"

enum { DS_TIME, DS_STEP, DS_ENERGY, DS_ANGLE, DS_OMEGA, DS_FORCE, DS_DEFL, DS_N };

/* Field datasets of one elastic body, in /fields/<name>/. */
enum { FD_TIME, FD_STEP, FD_THETA, FD_DISP, FD_VM, FD_POS, FD_N };

typedef struct rec_body {
    char name[208];
    gs_index n_nodes, n_tris;
    int npe;             /* nodes per element: 3, or 6 (quadratic, dataset triangles6) */
    double centre[2];
    double *xy;          /* copy of the body-frame nodes (2 n) */
    double *scratch;     /* 3 n: one frame of displacement / position / NaN */
    hid_t ds[FD_N];
    int64_t frames;      /* complete frames written */
    int64_t flushed;     /* frames as of the last flush (listed in the XDMF) */
    double *times;       /* time of every frame written */
    size_t tcap;
} rec_body;

struct gs_record {
    char path[1024];
    hid_t file;
    hid_t ds[DS_N];
    int cols[DS_N];
    int64_t rows;       /* rows on disk */
    int nbuf, cap;      /* buffered rows */
    double *buf[DS_N];
    /* Field snapshots (gs_record_add_meshes); nb == 0: none, no XDMF. */
    int nb;
    rec_body *bodies;
    bool fields_dirty;  /* frames written since the last flush */
    char xmf[1040];
};

static const char *const ds_names[DS_N] = {"time", "step", "energy", "angle", "omega",
                                           "mesh_force", "mesh_deflection"};

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
    return gs_record_open_as(path, path, sys, out, d);
}

gs_err gs_record_open_as(const char *path, const char *create_as, const gs_system *sys, gs_record **out,
                         gs_diag *d)
{
    *out = NULL;
    gs_record *r = gs_calloc(1, sizeof *r);
    if (!r)
        return GS_ENOMEM;
    snprintf(r->path, sizeof r->path, "%s", path);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    r->file = H5Fcreate(create_as, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    if (r->file < 0) {
        free(r);
        return gs_diag_set(d, GS_EIO, "path", "cannot create the record file '%s'", path);
    }
    gsi_h5_string_attr(r->file, "scene", sys->scene->json);
    if (sys->scene->fidelity_choice) /* `fidelity: {targets}`: the rung chosen and why */
        gsi_h5_string_attr(r->file, "fidelity_choice", sys->scene->fidelity_choice);
    gsi_h5_string_attr(r->file, "gearsim_version", "0.1.0");
    gsi_h5_scalar_attr(r->file, "time_step", H5T_NATIVE_DOUBLE, &sys->h);
    hid_t g = H5Gcreate2(r->file, "telemetry", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    int cols[DS_N] = {1, 1, 7, sys->n_bodies, sys->n_bodies, sys->n_meshes, sys->n_meshes};
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
        gsi_h5_string_attr(r->ds[DS_ENERGY], "columns",
                        "[\"kinetic\",\"potential\",\"total\",\"work_in\",\"dissipated\",\"balance_residual\","
                        "\"contact_work\"]");
        char *bn = names_json(sys, false), *mn = names_json(sys, true);
        gsi_h5_string_attr(g, "bodies", bn ? bn : "[]");
        gsi_h5_string_attr(g, "meshes", mn ? mn : "[]");
        gsi_h5_string_attr(r->ds[DS_ANGLE], "bodies", bn ? bn : "[]");
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
    double ev[7] = {e.kinetic, e.potential, e.total, e.work_in, e.dissipated, e.balance_residual, e.contact_work};
    memcpy(&r->buf[DS_ENERGY][7 * k], ev, sizeof ev);
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

static int write_xmf(gs_record *r);

gs_err gs_record_flush(gs_record *r)
{
    if (!r || (r->nbuf == 0 && !r->fields_dirty))
        return GS_OK;
    gs_err err = GS_OK;
    for (int i = 0; i < DS_N && r->nbuf > 0; i++) {
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
        return GS_EIO;
    if (r->fields_dirty) {
        /* The XDMF lists only what the flush above made durable. */
        for (int b = 0; b < r->nb; b++)
            r->bodies[b].flushed = r->bodies[b].frames;
        if (write_xmf(r))
            return GS_EIO;
        r->fields_dirty = false;
    }
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
    for (int b = 0; b < r->nb; b++) {
        rec_body *rb = &r->bodies[b];
        for (int k = 0; k < FD_N; k++)
            if (rb->ds[k] >= 0 && H5Dclose(rb->ds[k]) < 0)
                err = GS_EIO;
        free(rb->xy);
        free(rb->scratch);
        free(rb->times);
    }
    free(r->bodies);
    if (r->file >= 0 && H5Fclose(r->file) < 0)
        err = GS_EIO;
    free(r);
    *pr = NULL;
    return err;
}

const char *gs_record_path(const gs_record *r) { return r->path; }
int64_t gs_record_rows(const gs_record *r) { return r->rows + r->nbuf; }

/* ------------------------------------------------------------------------ */
/* Field snapshots of elastic bodies                                        */
/* ------------------------------------------------------------------------ */

int gs_record_n_meshes(const gs_record *r) { return r ? r->nb : 0; }

int64_t gs_record_field_frames(const gs_record *r, int body)
{
    return r && body >= 0 && body < r->nb ? r->bodies[body].frames : 0;
}

/* Group names are also written unescaped into the XDMF file and into
 * "file:/path" references there, hence the extra restrictions. */
static bool valid_body_name(const char *s)
{
    if (!s || !*s || !strcmp(s, ".") || strlen(s) > 200)
        return false;
    for (const char *c = s; *c; c++)
        if (strchr("/:<>&\"'", *c) || (unsigned char)*c < 32)
            return false;
    return true;
}

/* An extendable (0, n[, c]) dataset of `rank` (1..3), chunked by frame:
 * several frames per chunk only while a chunk stays under 64 KiB. */
static hid_t frame_ds(hid_t g, const char *name, hid_t type, int rank, hsize_t n, hsize_t c)
{
    hsize_t dims[3] = {0, n, c}, maxd[3] = {H5S_UNLIMITED, n, c}, chunk[3] = {256, n, c};
    if (rank > 1) {
        hsize_t frame_bytes = 8 * n * (rank == 3 ? c : 1);
        hsize_t per = frame_bytes ? 65536 / frame_bytes : 256;
        chunk[0] = per < 1 ? 1 : per > 256 ? 256 : per;
        if (n == 0)
            chunk[1] = 1;
    }
    hid_t sp = H5Screate_simple(rank, dims, maxd);
    hid_t pl = H5Pcreate(H5P_DATASET_CREATE);
    hid_t ds = -1;
    if (sp >= 0 && pl >= 0 && H5Pset_chunk(pl, rank, chunk) >= 0)
        ds = H5Dcreate2(g, name, type, sp, H5P_DEFAULT, pl, H5P_DEFAULT);
    if (pl >= 0)
        H5Pclose(pl);
    if (sp >= 0)
        H5Sclose(sp);
    return ds;
}

static char *body_names_json(const gs_record_mesh *bodies, int n)
{
    json_object *arr = json_object_new_array();
    if (!arr)
        return NULL;
    for (int i = 0; i < n; i++)
        json_object_array_add(arr, json_object_new_string(bodies[i].name));
    char *s = gs_strdup(json_object_to_json_string_ext(arr, JSON_C_TO_STRING_PLAIN));
    json_object_put(arr);
    return s;
}

static int write_body(hid_t gb, hid_t gf, const gs_record_mesh *e, int index, rec_body *rb)
{
    const gs_mesh *m = e->mesh;
    hsize_t nn = (hsize_t)m->n_nodes;
    int st = 0;
    hid_t g = H5Gcreate2(gb, e->name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (g < 0)
        return -1;
    st |= gsi_h5_scalar_attr(g, "index", H5T_NATIVE_INT, &index) < 0;
    st |= gsi_h5_array_attr(g, "centre_m", H5T_NATIVE_DOUBLE, e->centre, 2) < 0;
    st |= gsi_h5_fixed_ds(g, "nodes", H5T_NATIVE_DOUBLE, m->xy, nn, 2);
    st |= gsi_h5_fixed_ds(g, "triangles", H5T_NATIVE_INT64, m->tri, (hsize_t)m->n_tris, 3);
    if (m->mid) { /* quadratic: the Triangle_6 connectivity for the XDMF */
        gs_index *t6 = gs_mesh_triangle6(m);
        st |= t6 ? gsi_h5_fixed_ds(g, "triangles6", H5T_NATIVE_INT64, t6, (hsize_t)m->n_tris, 6) : -1;
        free(t6);
    }
    st |= gsi_h5_fixed_ds(g, "fixed", H5T_NATIVE_INT64, m->fixed, (hsize_t)(m->fixed ? m->n_fixed : 0), 0);
    if (m->node_tag) {
        st |= gsi_h5_fixed_ds(g, "node_tag", H5T_NATIVE_SCHAR, m->node_tag, nn, 0);
    } else {
        signed char *z = gs_calloc((size_t)nn + 1, 1);
        st |= z ? gsi_h5_fixed_ds(g, "node_tag", H5T_NATIVE_SCHAR, z, nn, 0) : -1;
        free(z);
    }
    if (H5Gclose(g) < 0)
        st = -1;
    if (st)
        return -1;

    g = H5Gcreate2(gf, e->name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (g < 0)
        return -1;
    rb->ds[FD_TIME] = frame_ds(g, "time", H5T_NATIVE_DOUBLE, 1, 0, 0);
    rb->ds[FD_STEP] = frame_ds(g, "step", H5T_NATIVE_INT64, 1, 0, 0);
    rb->ds[FD_THETA] = frame_ds(g, "theta", H5T_NATIVE_DOUBLE, 1, 0, 0);
    rb->ds[FD_DISP] = frame_ds(g, "displacement", H5T_NATIVE_DOUBLE, 3, nn, 3);
    rb->ds[FD_VM] = frame_ds(g, "von_mises", H5T_NATIVE_DOUBLE, 2, nn, 0);
    rb->ds[FD_POS] = frame_ds(g, "position", H5T_NATIVE_DOUBLE, 3, nn, 2);
    for (int k = 0; k < FD_N; k++)
        if (rb->ds[k] < 0)
            st = -1;
    if (!st) {
        st |= gsi_h5_string_attr(rb->ds[FD_DISP], "frame", "body") < 0;
        st |= gsi_h5_string_attr(rb->ds[FD_DISP], "units", "m") < 0;
        st |= gsi_h5_string_attr(rb->ds[FD_VM], "units", "Pa") < 0;
        st |= gsi_h5_string_attr(rb->ds[FD_POS], "frame", "scene") < 0;
        st |= gsi_h5_string_attr(rb->ds[FD_POS], "units", "m") < 0;
        st |= gsi_h5_string_attr(rb->ds[FD_THETA], "units", "rad") < 0;
        st |= gsi_h5_string_attr(rb->ds[FD_TIME], "units", "s") < 0;
    }
    if (H5Gclose(g) < 0)
        st = -1;
    return st ? -1 : 0;
}

gs_err gs_record_add_meshes(gs_record *r, const gs_record_mesh *bodies, int n, gs_diag *d)
{
    if (!r || r->file < 0)
        return gs_diag_set(d, GS_EINVAL, "record", "no open record");
    if (r->nb > 0)
        return gs_diag_set(d, GS_ESTATE, "bodies", "the elastic bodies of %s are already declared",
                           r->path);
    if (!bodies || n < 1)
        return gs_diag_set(d, GS_EINVAL, "bodies", "no elastic body given");
    for (int i = 0; i < n; i++) {
        char f[64];
        snprintf(f, sizeof f, "bodies[%d].name", i);
        if (!valid_body_name(bodies[i].name))
            return gs_diag_set(d, GS_EINVAL, f, "a body name must be 1-200 characters, not \".\", "
                                                "without / : < > & or quotes");
        for (int j = 0; j < i; j++)
            if (!strcmp(bodies[i].name, bodies[j].name))
                return gs_diag_set(d, GS_EINVAL, f, "name '%s' used twice", bodies[i].name);
        const gs_mesh *m = bodies[i].mesh;
        snprintf(f, sizeof f, "bodies[%d].mesh", i);
        if (!m || m->n_nodes < 1 || !m->xy || m->n_tris < 0 || (m->n_tris > 0 && !m->tri))
            return gs_diag_set(d, GS_EINVAL, f, "no usable mesh for '%s'", bodies[i].name);
    }
    if (gs_mesh_io_xmf_path(r->path, r->xmf, sizeof r->xmf) != GS_OK)
        return gs_diag_set(d, GS_EINVAL, "path", "record path too long for its XDMF file");

    rec_body *rb = gs_calloc((size_t)n, sizeof *rb);
    if (!rb)
        return GS_ENOMEM;
    for (int i = 0; i < n; i++) {
        const gs_mesh *m = bodies[i].mesh;
        snprintf(rb[i].name, sizeof rb[i].name, "%s", bodies[i].name);
        rb[i].n_nodes = m->n_nodes;
        rb[i].n_tris = m->n_tris;
        rb[i].npe = m->mid ? 6 : 3;
        rb[i].centre[0] = bodies[i].centre[0];
        rb[i].centre[1] = bodies[i].centre[1];
        for (int k = 0; k < FD_N; k++)
            rb[i].ds[k] = -1;
        rb[i].xy = gs_calloc(2 * (size_t)m->n_nodes, sizeof(double));
        rb[i].scratch = gs_calloc(3 * (size_t)m->n_nodes, sizeof(double));
        if (rb[i].xy)
            memcpy(rb[i].xy, m->xy, 2 * (size_t)m->n_nodes * sizeof(double));
    }
    /* From here the record owns rb (freed by gs_record_close). */
    r->bodies = rb;
    r->nb = n;
    for (int i = 0; i < n; i++)
        if (!rb[i].xy || !rb[i].scratch)
            return GS_ENOMEM;

    int st = 0;
    char *names = body_names_json(bodies, n);
    if (!names)
        return GS_ENOMEM;
    hid_t gb = H5Gcreate2(r->file, "bodies", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    hid_t gf = gb < 0 ? -1 : H5Gcreate2(r->file, "fields", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (gb < 0 || gf < 0)
        st = -1;
    else {
        st |= gsi_h5_string_attr(gb, "names", names) < 0;
        st |= gsi_h5_string_attr(gf, "names", names) < 0;
        for (int i = 0; i < n && !st; i++)
            st |= write_body(gb, gf, &bodies[i], i, &rb[i]);
    }
    free(names);
    if (gf >= 0 && H5Gclose(gf) < 0)
        st = -1;
    if (gb >= 0 && H5Gclose(gb) < 0)
        st = -1;
    if (!st && H5Fflush(r->file, H5F_SCOPE_GLOBAL) < 0)
        st = -1;
    if (!st && write_xmf(r))
        return gs_diag_set(d, GS_EIO, "path", "cannot write the XDMF file '%s'", r->xmf);
    if (st)
        return gs_diag_set(d, GS_EIO, "path", "cannot write the meshes into '%s'", r->path);
    return GS_OK;
}

/* Extend ds to k + 1 frames and write frame k (dims n x c after the frame
 * axis, `rank` 1..3) from buf. 0 on success. */
static int put_frame(hid_t ds, hid_t type, int rank, hsize_t k, hsize_t n, hsize_t c,
                     const void *buf)
{
    hsize_t nd[3] = {k + 1, n, c}, start[3] = {k, 0, 0}, count[3] = {1, n, c};
    if (H5Dset_extent(ds, nd) < 0)
        return -1;
    if (rank > 1 && n == 0)
        return 0;
    hid_t fs = H5Dget_space(ds);
    if (fs < 0)
        return -1;
    hid_t ms = H5Screate_simple(rank, count, NULL);
    int st = ms >= 0 && H5Sselect_hyperslab(fs, H5S_SELECT_SET, start, NULL, count, NULL) >= 0 &&
                     H5Dwrite(ds, type, ms, fs, H5P_DEFAULT, buf) >= 0
                 ? 0
                 : -1;
    if (ms >= 0)
        H5Sclose(ms);
    H5Sclose(fs);
    return st;
}

gs_err gs_record_field_frame(gs_record *r, int body, int64_t step, double time, double theta,
                             const double *u, const double *vm)
{
    if (!r || r->nb == 0)
        return GS_ESTATE;
    if (body < 0 || body >= r->nb || !u)
        return GS_EINVAL;
    rec_body *rb = &r->bodies[body];
    double *nt = gs_grow(rb->times, &rb->tcap, (size_t)rb->frames + 1, sizeof *nt);
    if (!nt)
        return GS_ENOMEM;
    rb->times = nt;
    hsize_t k = (hsize_t)rb->frames, n = (hsize_t)rb->n_nodes;
    double *w = rb->scratch;
    int st = 0;
    /* displacement, 3 components (z = 0) */
    for (gs_index i = 0; i < rb->n_nodes; i++) {
        w[3 * i] = u[2 * i];
        w[3 * i + 1] = u[2 * i + 1];
        w[3 * i + 2] = 0.0;
    }
    st |= put_frame(rb->ds[FD_DISP], H5T_NATIVE_DOUBLE, 3, k, n, 3, w);
    /* position = centre + R(theta) (X + u) */
    double c = cos(theta), s = sin(theta);
    for (gs_index i = 0; i < rb->n_nodes && !st; i++) {
        double x = rb->xy[2 * i] + u[2 * i], y = rb->xy[2 * i + 1] + u[2 * i + 1];
        w[2 * i] = rb->centre[0] + (c * x - s * y);
        w[2 * i + 1] = rb->centre[1] + (s * x + c * y);
    }
    if (!st)
        st |= put_frame(rb->ds[FD_POS], H5T_NATIVE_DOUBLE, 3, k, n, 2, w);
    if (!st && !vm) {
        for (gs_index i = 0; i < rb->n_nodes; i++)
            w[i] = NAN;
    }
    if (!st)
        st |= put_frame(rb->ds[FD_VM], H5T_NATIVE_DOUBLE, 2, k, n, 0, vm ? vm : w);
    /* The scalars last, time very last: its length counts complete frames. */
    if (!st)
        st |= put_frame(rb->ds[FD_STEP], H5T_NATIVE_INT64, 1, k, 0, 0, &step);
    if (!st)
        st |= put_frame(rb->ds[FD_THETA], H5T_NATIVE_DOUBLE, 1, k, 0, 0, &theta);
    if (!st)
        st |= put_frame(rb->ds[FD_TIME], H5T_NATIVE_DOUBLE, 1, k, 0, 0, &time);
    if (st)
        return GS_EIO;
    rb->times[rb->frames++] = time;
    r->fields_dirty = true;
    return GS_OK;
}

/* ---- XDMF ---------------------------------------------------------------- */

typedef struct tframe {
    double t;
    int64_t k;
} tframe;

static int cmp_tframe(const void *a, const void *b)
{
    const tframe *x = a, *y = b;
    if (x->t != y->t)
        return x->t < y->t ? -1 : 1;
    return x->k < y->k ? -1 : x->k > y->k;
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Text with XML's five special characters escaped. */
static void xml_text(FILE *f, const char *s)
{
    for (; *s; s++) {
        switch (*s) {
        case '<': fputs("&lt;", f); break;
        case '>': fputs("&gt;", f); break;
        case '&': fputs("&amp;", f); break;
        case '"': fputs("&quot;", f); break;
        case '\'': fputs("&apos;", f); break;
        default: fputc(*s, f);
        }
    }
}

/* Frame k of /fields/<body>/<ds> (T frames of n nodes, c columns, or one
 * value per node when c == 0), in XDMF 3's own hyperslab form: the HDF path
 * followed by |start:stride:count:dimensions of the dataset. This is what
 * ParaView's default .xmf reader (Xdmf3 Reader S/T) reads; it ignores the
 * XDMF 2 form (ItemType="HyperSlab" with two child items) and crashes on it
 * in a Geometry (ParaView 5.11, deploy/check-paraview.sh). */
static void xmf_slab(FILE *f, const char *h5, const char *body, const char *ds, int64_t k,
                     int64_t T, gs_index n, int c)
{
    const char *ind = "            ";
    if (c > 0)
        fprintf(f, "%s<DataItem Dimensions=\"1 %lld %d\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">",
                ind, (long long)n, c);
    else
        fprintf(f, "%s<DataItem Dimensions=\"1 %lld\" NumberType=\"Float\" Precision=\"8\" Format=\"HDF\">",
                ind, (long long)n);
    xml_text(f, h5);
    fprintf(f, ":/fields/%s/%s", body, ds);
    if (c > 0)
        fprintf(f, "|%lld 0 0:1 1 1:1 %lld %d:%lld %lld %d", (long long)k, (long long)n, c, (long long)T,
                (long long)n, c);
    else
        fprintf(f, "|%lld 0:1 1:1 %lld:%lld %lld", (long long)k, (long long)n, (long long)T, (long long)n);
    fprintf(f, "</DataItem>\n");
}

static void xmf_grid(FILE *f, const char *h5, const rec_body *rb, int64_t k)
{
    const char *nm = rb->name;
    long long n = (long long)rb->n_nodes, m = (long long)rb->n_tris, T = (long long)rb->flushed;
    fprintf(f, "        <Grid Name=\"%s\" GridType=\"Uniform\">\n", nm);
    bool q = rb->npe == 6;
    fprintf(f, "          <Topology TopologyType=\"%s\" NumberOfElements=\"%lld\">\n",
            q ? "Triangle_6" : "Triangle", m);
    fprintf(f, "            <DataItem Dimensions=\"%lld %d\" NumberType=\"Int\" Precision=\"8\" "
               "Format=\"HDF\">", m, rb->npe);
    xml_text(f, h5);
    fprintf(f, ":/bodies/%s/%s</DataItem>\n          </Topology>\n", nm, q ? "triangles6" : "triangles");
    fprintf(f, "          <Geometry GeometryType=\"XY\">\n");
    xmf_slab(f, h5, nm, "position", k, T, rb->n_nodes, 2);
    fprintf(f, "          </Geometry>\n");
    fprintf(f, "          <Attribute Name=\"displacement\" AttributeType=\"Vector\" Center=\"Node\">\n");
    xmf_slab(f, h5, nm, "displacement", k, T, rb->n_nodes, 3);
    fprintf(f, "          </Attribute>\n");
    fprintf(f, "          <Attribute Name=\"von_mises\" AttributeType=\"Scalar\" Center=\"Node\">\n");
    xmf_slab(f, h5, nm, "von_mises", k, T, rb->n_nodes, 0);
    fprintf(f, "          </Attribute>\n");
    fprintf(f, "          <Attribute Name=\"node_tag\" AttributeType=\"Scalar\" Center=\"Node\">\n");
    fprintf(f, "            <DataItem Dimensions=\"%lld\" NumberType=\"Char\" Precision=\"1\" "
               "Format=\"HDF\">", n);
    xml_text(f, h5);
    fprintf(f, ":/bodies/%s/node_tag</DataItem>\n          </Attribute>\n        </Grid>\n", nm);
}

/* Rewrite the XDMF file for the flushed frames: write <xmf>.tmp, rename it
 * over <xmf>. 0 on success. */
static int write_xmf(gs_record *r)
{
    if (r->nb == 0)
        return 0;
    const char *slash = strrchr(r->path, '/');
    const char *h5 = slash ? slash + 1 : r->path;
    /* Distinct frame times, ascending, and each body's frames sorted by time. */
    int64_t total = 0;
    for (int b = 0; b < r->nb; b++)
        total += r->bodies[b].flushed;
    double *times = gs_calloc((size_t)total + 1, sizeof *times);
    tframe **sorted = gs_calloc((size_t)r->nb, sizeof *sorted);
    int64_t *pos = gs_calloc((size_t)r->nb, sizeof *pos), *cur = gs_calloc((size_t)r->nb, sizeof *cur);
    int st = times && sorted && pos && cur ? 0 : -1;
    int64_t nt = 0;
    for (int b = 0; b < r->nb && !st; b++) {
        const rec_body *rb = &r->bodies[b];
        sorted[b] = gs_calloc((size_t)rb->flushed + 1, sizeof **sorted);
        if (!sorted[b]) {
            st = -1;
            break;
        }
        for (int64_t k = 0; k < rb->flushed; k++) {
            sorted[b][k] = (tframe){rb->times[k], k};
            times[nt++] = rb->times[k];
        }
        qsort(sorted[b], (size_t)rb->flushed, sizeof **sorted, cmp_tframe);
        cur[b] = -1;
    }
    if (!st) {
        qsort(times, (size_t)nt, sizeof *times, cmp_double);
        int64_t u = 0;
        for (int64_t i = 0; i < nt; i++)
            if (u == 0 || times[i] != times[u - 1])
                times[u++] = times[i];
        nt = u;
    }
    char tmp[1200];
    int fd = st ? -1 : gs_tmp_create_beside(r->xmf, tmp, sizeof tmp);
    struct stat rs; /* the XDMF file is as readable as its record */
    if (fd >= 0 && stat(r->path, &rs) == 0 && fchmod(fd, rs.st_mode & 0666) != 0) {
        /* keeps 0600 */
    }
    FILE *f = fd < 0 ? NULL : fdopen(fd, "w");
    if (fd >= 0 && !f) {
        close(fd);
        remove(tmp);
    }
    if (f) {
        fprintf(f, "<?xml version=\"1.0\" ?>\n<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n");
        fprintf(f, "<Xdmf Version=\"3.0\">\n  <Domain>\n");
        fprintf(f, "    <Grid Name=\"fields\" GridType=\"Collection\" CollectionType=\"Temporal\">\n");
        for (int64_t i = 0; i < nt; i++) {
            fprintf(f, "      <Grid Name=\"frame_%lld\" GridType=\"Collection\" "
                       "CollectionType=\"Spatial\">\n", (long long)i);
            fprintf(f, "        <Time Value=\"%.17g\" />\n", times[i]);
            for (int b = 0; b < r->nb; b++) {
                /* the body's latest frame at or before this time */
                while (pos[b] < r->bodies[b].flushed && sorted[b][pos[b]].t <= times[i])
                    cur[b] = sorted[b][pos[b]++].k;
                if (cur[b] >= 0)
                    xmf_grid(f, h5, &r->bodies[b], cur[b]);
            }
            fprintf(f, "      </Grid>\n");
        }
        fprintf(f, "    </Grid>\n  </Domain>\n</Xdmf>\n");
        if (ferror(f))
            st = -1;
        if (fclose(f) != 0)
            st = -1;
        if (!st && rename(tmp, r->xmf) != 0)
            st = -1;
        if (st)
            remove(tmp);
    } else {
        st = -1;
    }
    for (int b = 0; sorted && b < r->nb; b++)
        free(sorted[b]);
    free(sorted);
    free(times);
    free(pos);
    free(cur);
    return st;
}

/* ---- reopen after a resume ----------------------------------------------- */

/* Cut an extendable dataset to `keep` entries along its first axis; the
 * current length goes to *had. 0 on success. */
static int cut_ds(hid_t ds, hsize_t keep, hsize_t *had)
{
    hid_t sp = H5Dget_space(ds);
    hsize_t dims[3] = {0, 0, 0};
    int rank = sp >= 0 ? H5Sget_simple_extent_ndims(sp) : -1;
    if (rank >= 1 && rank <= 3)
        H5Sget_simple_extent_dims(sp, dims, NULL);
    if (sp >= 0)
        H5Sclose(sp);
    if (rank < 1 || rank > 3)
        return -1;
    if (had)
        *had = dims[0];
    if (dims[0] < keep)
        return -1;
    dims[0] = keep;
    return H5Dset_extent(ds, dims) < 0 ? -1 : 0;
}

static int reopen_body(gs_record *r, rec_body *rb, const char *name, int64_t keep)
{
    snprintf(rb->name, sizeof rb->name, "%s", name);
    for (int k = 0; k < FD_N; k++)
        rb->ds[k] = -1;
    char p[512];
    snprintf(p, sizeof p, "/bodies/%s", name);
    hid_t g = H5Gopen2(r->file, p, H5P_DEFAULT);
    if (g < 0)
        return -1;
    int st = 0;
    if (gsi_h5_read_attr(g, "centre_m", H5T_NATIVE_DOUBLE, rb->centre, 2) < 0)
        st = -1;
    hid_t dn = H5Dopen2(g, "nodes", H5P_DEFAULT), dt = H5Dopen2(g, "triangles", H5P_DEFAULT);
    hsize_t nd[2] = {0, 0}, td[2] = {0, 0};
    if (dn < 0 || dt < 0)
        st = -1;
    if (!st) {
        hid_t sp = H5Dget_space(dn);
        H5Sget_simple_extent_dims(sp, nd, NULL);
        H5Sclose(sp);
        sp = H5Dget_space(dt);
        H5Sget_simple_extent_dims(sp, td, NULL);
        H5Sclose(sp);
        rb->n_nodes = (gs_index)nd[0];
        rb->n_tris = (gs_index)td[0];
        rb->npe = H5Lexists(g, "triangles6", H5P_DEFAULT) > 0 ? 6 : 3;
        rb->xy = gs_calloc(2 * (size_t)nd[0] + 1, sizeof(double));
        rb->scratch = gs_calloc(3 * (size_t)nd[0] + 1, sizeof(double));
        if (!rb->xy || !rb->scratch || nd[1] != 2 ||
            (nd[0] > 0 && H5Dread(dn, H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL, H5P_DEFAULT, rb->xy) < 0))
            st = -1;
    }
    if (dn >= 0)
        H5Dclose(dn);
    if (dt >= 0)
        H5Dclose(dt);
    H5Gclose(g);
    if (st)
        return -1;
    static const char *const fd_names[FD_N] = {"time", "step", "theta", "displacement", "von_mises", "position"};
    snprintf(p, sizeof p, "/fields/%s", name);
    g = H5Gopen2(r->file, p, H5P_DEFAULT);
    if (g < 0)
        return -1;
    for (int k = 0; k < FD_N && !st; k++) {
        rb->ds[k] = H5Dopen2(g, fd_names[k], H5P_DEFAULT);
        if (rb->ds[k] < 0 || cut_ds(rb->ds[k], (hsize_t)keep, NULL) < 0)
            st = -1;
    }
    H5Gclose(g);
    if (st)
        return -1;
    rb->tcap = keep > 0 ? (size_t)keep : 64;
    rb->times = gs_calloc(rb->tcap, sizeof *rb->times);
    if (!rb->times || (keep > 0 && H5Dread(rb->ds[FD_TIME], H5T_NATIVE_DOUBLE, H5S_ALL, H5S_ALL,
                                           H5P_DEFAULT, rb->times) < 0))
        return -1;
    rb->frames = rb->flushed = keep;
    return 0;
}

gs_err gs_record_reopen(const char *path, const gs_system *sys, int64_t rows,
                        const int64_t *field_frames, int n_frames, gs_record **out, gs_diag *d)
{
    return gs_record_reopen_as(path, path, sys, rows, field_frames, n_frames, out, d);
}

gs_err gs_record_reopen_as(const char *path, const char *open_as, const gs_system *sys, int64_t rows,
                           const int64_t *field_frames, int n_frames, gs_record **out, gs_diag *d)
{
    *out = NULL;
    gs_record *r = gs_calloc(1, sizeof *r);
    if (!r)
        return GS_ENOMEM;
    snprintf(r->path, sizeof r->path, "%s", path);
    for (int i = 0; i < DS_N; i++)
        r->ds[i] = -1;
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    r->file = H5Fopen(open_as, H5F_ACC_RDWR, H5P_DEFAULT);
    if (r->file < 0) {
        free(r);
        return gs_diag_set(d, GS_EIO, "path", "cannot reopen the record file '%s'", path);
    }
    int cols[DS_N] = {1, 1, 7, sys->n_bodies, sys->n_bodies, sys->n_meshes, sys->n_meshes};
    const char *bad = NULL;
    hid_t g = H5Gopen2(r->file, "telemetry", H5P_DEFAULT);
    if (g < 0)
        bad = "it has no /telemetry";
    for (int i = 0; i < DS_N && !bad; i++) {
        r->cols[i] = cols[i];
        if (cols[i] == 0)
            continue;
        r->ds[i] = H5Dopen2(g, ds_names[i], H5P_DEFAULT);
        hsize_t dims[2] = {0, 1};
        hid_t sp = r->ds[i] >= 0 ? H5Dget_space(r->ds[i]) : -1;
        if (sp >= 0) {
            if (H5Sget_simple_extent_ndims(sp) != ds_rank(i))
                dims[1] = 0;
            H5Sget_simple_extent_dims(sp, dims, NULL);
            H5Sclose(sp);
        }
        if (r->ds[i] < 0 || (ds_rank(i) == 2 && dims[1] != (hsize_t)cols[i]))
            bad = "its telemetry datasets do not match the scene";
        else if (dims[0] < (hsize_t)rows)
            bad = "it has fewer telemetry rows than the checkpoint says were flushed";
    }
    if (g >= 0)
        H5Gclose(g);
    for (int i = 0; i < DS_N && !bad; i++)
        if (r->ds[i] >= 0 && cut_ds(r->ds[i], (hsize_t)rows, NULL) < 0)
            bad = "its telemetry could not be cut back to the checkpoint";
    r->rows = rows;
    if (!bad && H5Lexists(r->file, "fields", H5P_DEFAULT) > 0) {
        hid_t gf = H5Gopen2(r->file, "fields", H5P_DEFAULT);
        char *names = gf >= 0 ? gsi_h5_read_string_attr(gf, "names", 64u << 20) : NULL;
        if (gf >= 0)
            H5Gclose(gf);
        json_object *arr = names ? json_tokener_parse(names) : NULL;
        free(names);
        int n = arr && json_object_get_type(arr) == json_type_array ? (int)json_object_array_length(arr) : -1;
        if (n < 1 || n != n_frames) {
            bad = "its field snapshots do not match the checkpoint";
        } else if (gs_mesh_io_xmf_path(r->path, r->xmf, sizeof r->xmf) != GS_OK ||
                   !(r->bodies = gs_calloc((size_t)n, sizeof *r->bodies))) {
            bad = "out of memory";
        } else {
            r->nb = n;
            for (int b = 0; b < n; b++)
                for (int k = 0; k < FD_N; k++)
                    r->bodies[b].ds[k] = -1;
            for (int b = 0; b < n && !bad; b++) {
                const char *nm = json_object_get_string(json_object_array_get_idx(arr, (size_t)b));
                if (!nm || !valid_body_name(nm) || field_frames[b] < 0 ||
                    reopen_body(r, &r->bodies[b], nm, field_frames[b]) < 0)
                    bad = "its field snapshots could not be cut back to the checkpoint";
            }
        }
        json_object_put(arr);
    } else if (!bad && n_frames > 0) {
        bad = "it has no field snapshots but the checkpoint counts some";
    }
    if (!bad && (H5Fflush(r->file, H5F_SCOPE_GLOBAL) < 0 || write_xmf(r)))
        bad = "it cannot be written";
    if (bad) {
        gs_record_close(&r);
        return gs_diag_set(d, GS_EIO, "path", "cannot continue the record '%s': %s", path, bad);
    }
    *out = r;
    return GS_OK;
}
