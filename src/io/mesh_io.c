/* SPDX-License-Identifier: MIT
 * gearsim: gear meshes to HDF5 + XDMF and back (include/gearsim/mesh_io.h
 * documents the layout). */
#include <hdf5.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/mesh_io.h"
#include "io/h5attr.h"
#include "gearsim/util.h"

gs_err gs_mesh_io_xmf_path(const char *h5_path, char *buf, size_t len)
{
    const char *slash = strrchr(h5_path, '/');
    const char *dot = strrchr(h5_path, '.');
    size_t stem = (dot && (!slash || dot > slash + 1)) ? (size_t)(dot - h5_path) : strlen(h5_path);
    if (stem + 5 > len)
        return GS_EINVAL;
    memcpy(buf, h5_path, stem);
    memcpy(buf + stem, ".xmf", 5);
    return GS_OK;
}

/* ------------------------------------------------------------------------ */
/* Small HDF5 helpers: 0 on success                                         */
/* ------------------------------------------------------------------------ */

static int valid_name(const char *s)
{
    if (!s || !*s || strchr(s, '/') || !strcmp(s, ".") || strlen(s) > 200)
        return 0;
    /* XML-safe, so the XDMF file needs no escaping */
    for (const char *c = s; *c; c++)
        if (*c == '<' || *c == '>' || *c == '&' || *c == '"' || *c == '\'' || (unsigned char)*c < 32)
            return 0;
    return 1;
}

static int write_gear(hid_t root, const gs_mesh_io_gear *e, int index)
{
    const gs_mesh *m = e->mesh;
    hid_t g = H5Gcreate2(root, e->name, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (g < 0)
        return -1;
    int r = 0;
    r |= gsi_h5_scalar_attr(g, "index", H5T_NATIVE_INT, &index) < 0;
    r |= gsi_h5_array_attr(g, "centre_m", H5T_NATIVE_DOUBLE, e->centre, 2) < 0;
    r |= gsi_h5_scalar_attr(g, "rotation_rad", H5T_NATIVE_DOUBLE, &e->rotation) < 0;
    if (e->params) {
        const gs_gear_params *p = e->params;
        gs_gear_geom geo;
        int have = gs_gear_geometry(p, &geo, NULL) == GS_OK;
        r |= gsi_h5_string_attr(g, "kind", p->kind == GS_GEAR_INTERNAL ? "internal" : "external") < 0;
        r |= gsi_h5_scalar_attr(g, "teeth", H5T_NATIVE_INT, &p->teeth) < 0;
        const struct {
            const char *n;
            double v;
        } a[] = {
            {"module_m", p->module_m},
            {"pressure_angle_rad", p->pressure_angle},
            {"addendum", p->addendum_coef},
            {"dedendum", p->dedendum_coef},
            {"fillet", p->fillet_coef},
            {"profile_shift", p->profile_shift},
            {"thinning_m", p->thinning_m},
            {"face_width_m", p->face_width_m},
            {"hub_radius_m", gs_gear_hub_radius(p)},
            {"pitch_radius_m", gs_gear_pitch_radius(p)},
            {"base_radius_m", gs_gear_base_radius(p)},
            {"tip_radius_m", gs_gear_tip_radius(p)},
            {"root_radius_m", gs_gear_root_radius(p)},
            {"form_radius_m", have ? geo.r_form : NAN},
        };
        for (size_t k = 0; k < sizeof a / sizeof a[0]; k++)
            r |= gsi_h5_scalar_attr(g, a[k].n, H5T_NATIVE_DOUBLE, &a[k].v) < 0;
    }
    double *placed = malloc((size_t)(2 * m->n_nodes + 1) * sizeof *placed);
    if (!placed) {
        H5Gclose(g);
        return -1;
    }
    double c = cos(e->rotation), s = sin(e->rotation);
    for (gs_index i = 0; i < m->n_nodes; i++) {
        double x = m->xy[2 * i], y = m->xy[2 * i + 1];
        placed[2 * i] = e->centre[0] + c * x - s * y;
        placed[2 * i + 1] = e->centre[1] + s * x + c * y;
    }
    r |= gsi_h5_fixed_ds(g, "nodes", H5T_NATIVE_DOUBLE, m->xy, (hsize_t)m->n_nodes, 2);
    r |= gsi_h5_fixed_ds(g, "nodes_placed", H5T_NATIVE_DOUBLE, placed, (hsize_t)m->n_nodes, 2);
    free(placed);
    r |= gsi_h5_fixed_ds(g, "triangles", H5T_NATIVE_INT64, m->tri, (hsize_t)m->n_tris, 3);
    if (m->mid) { /* quadratic: Triangle_6 connectivity (corners, mid-side nodes) */
        gs_index *t6 = gs_mesh_triangle6(m);
        r |= t6 ? gsi_h5_fixed_ds(g, "triangles6", H5T_NATIVE_INT64, t6, (hsize_t)m->n_tris, 6) : -1;
        free(t6);
    }
    r |= gsi_h5_fixed_ds(g, "fixed", H5T_NATIVE_INT64, m->fixed, (hsize_t)m->n_fixed, 0);
    if (m->node_tag) {
        r |= gsi_h5_fixed_ds(g, "node_tag", H5T_NATIVE_SCHAR, m->node_tag, (hsize_t)m->n_nodes, 0);
    } else {
        signed char *z = calloc((size_t)m->n_nodes + 1, 1);
        r |= z ? gsi_h5_fixed_ds(g, "node_tag", H5T_NATIVE_SCHAR, z, (hsize_t)m->n_nodes, 0) : -1;
        free(z);
    }
    r |= gsi_h5_fixed_ds(g, "boundary", H5T_NATIVE_INT64, m->boundary, (hsize_t)(m->boundary ? m->n_boundary : 0), 0);
    if (m->flank_ptr && m->n_teeth > 0) {
        r |= gsi_h5_fixed_ds(g, "flank_ptr", H5T_NATIVE_INT64, m->flank_ptr, (hsize_t)(2 * m->n_teeth + 1), 0);
        r |= gsi_h5_fixed_ds(g, "flank_nodes", H5T_NATIVE_INT64, m->flank_nodes,
                  (hsize_t)m->flank_ptr[2 * m->n_teeth], 0);
    } else {
        gs_index zero = 0;
        r |= gsi_h5_fixed_ds(g, "flank_ptr", H5T_NATIVE_INT64, &zero, 1, 0);
        r |= gsi_h5_fixed_ds(g, "flank_nodes", H5T_NATIVE_INT64, NULL, 0, 0);
    }
    H5Gclose(g);
    return r ? -1 : 0;
}

static int write_xmf(const char *xmf_path, const char *h5_path, const gs_mesh_io_gear *gears, int n)
{
    const char *slash = strrchr(h5_path, '/');
    const char *h5base = slash ? slash + 1 : h5_path;
    FILE *f = fopen(xmf_path, "w");
    if (!f)
        return -1;
    fprintf(f, "<?xml version=\"1.0\" ?>\n<!DOCTYPE Xdmf SYSTEM \"Xdmf.dtd\" []>\n");
    fprintf(f, "<Xdmf Version=\"3.0\">\n  <Domain>\n");
    fprintf(f, "    <Grid Name=\"gears\" GridType=\"Collection\" CollectionType=\"Spatial\">\n");
    for (int i = 0; i < n; i++) {
        const gs_mesh *m = gears[i].mesh;
        const char *nm = gears[i].name;
        fprintf(f, "      <Grid Name=\"%s\" GridType=\"Uniform\">\n", nm);
        bool q = m->mid != NULL;
        fprintf(f, "        <Topology TopologyType=\"%s\" NumberOfElements=\"%lld\">\n",
                q ? "Triangle_6" : "Triangle", (long long)m->n_tris);
        fprintf(f,
                "          <DataItem Dimensions=\"%lld %d\" NumberType=\"Int\" Precision=\"8\" "
                "Format=\"HDF\">%s:/gears/%s/%s</DataItem>\n",
                (long long)m->n_tris, q ? 6 : 3, h5base, nm, q ? "triangles6" : "triangles");
        fprintf(f, "        </Topology>\n        <Geometry GeometryType=\"XY\">\n");
        fprintf(f,
                "          <DataItem Dimensions=\"%lld 2\" NumberType=\"Float\" Precision=\"8\" "
                "Format=\"HDF\">%s:/gears/%s/nodes_placed</DataItem>\n",
                (long long)m->n_nodes, h5base, nm);
        fprintf(f, "        </Geometry>\n");
        fprintf(f, "        <Attribute Name=\"node_tag\" AttributeType=\"Scalar\" Center=\"Node\">\n");
        fprintf(f,
                "          <DataItem Dimensions=\"%lld\" NumberType=\"Char\" Precision=\"1\" "
                "Format=\"HDF\">%s:/gears/%s/node_tag</DataItem>\n",
                (long long)m->n_nodes, h5base, nm);
        fprintf(f, "        </Attribute>\n      </Grid>\n");
    }
    fprintf(f, "    </Grid>\n  </Domain>\n</Xdmf>\n");
    return fclose(f) == 0 ? 0 : -1;
}

gs_err gs_mesh_io_write(const char *h5_path, const char *xmf_path, const gs_mesh_io_gear *gears,
                        int n, gs_diag *d)
{
    if (!h5_path || !*h5_path)
        return gs_diag_set(d, GS_EINVAL, "path", "no output path");
    for (int i = 0; i < n; i++) {
        char f[64];
        snprintf(f, sizeof f, "gears[%d].name", i);
        if (!valid_name(gears[i].name))
            return gs_diag_set(d, GS_EINVAL, f, "a mesh name must be 1-200 characters without "
                                                "'/', quotes or <>&");
        if (!gears[i].mesh)
            return gs_diag_set(d, GS_EINVAL, f, "no mesh for '%s'", gears[i].name);
        for (int j = 0; j < i; j++)
            if (!strcmp(gears[i].name, gears[j].name))
                return gs_diag_set(d, GS_EINVAL, f, "name '%s' used twice", gears[i].name);
    }
    char xbuf[4096];
    if (!xmf_path) {
        if (gs_mesh_io_xmf_path(h5_path, xbuf, sizeof xbuf) != GS_OK)
            return gs_diag_set(d, GS_EINVAL, "path", "output path too long");
        xmf_path = xbuf;
    }
    /* HDF5 prints its error stack by default; we report through gs_diag. */
    H5E_auto2_t efn;
    void *edata;
    H5Eget_auto2(H5E_DEFAULT, &efn, &edata);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    gs_err e = GS_OK;
    hid_t file = H5Fcreate(h5_path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    if (file < 0) {
        e = gs_diag_set(d, GS_EIO, "path", "cannot create %s", h5_path);
        goto out;
    }
    int r = 0;
    const int version = 1;
    r |= gsi_h5_string_attr(file, "format", "gearsim-mesh") < 0;
    r |= gsi_h5_scalar_attr(file, "version", H5T_NATIVE_INT, &version) < 0;
    hid_t root = H5Gcreate2(file, "gears", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (root < 0)
        r = -1;
    else {
        size_t len = 1;
        for (int i = 0; i < n; i++)
            len += strlen(gears[i].name) + 1;
        char *names = calloc(len, 1);
        if (!names)
            r = -1;
        else {
            for (int i = 0; i < n; i++) {
                strcat(names, gears[i].name);
                if (i + 1 < n)
                    strcat(names, "\n");
            }
            r |= gsi_h5_string_attr(root, "names", names) < 0;
            free(names);
        }
        r |= gsi_h5_scalar_attr(root, "count", H5T_NATIVE_INT, &n) < 0;
        for (int i = 0; i < n && !r; i++)
            r |= write_gear(root, &gears[i], i);
        H5Gclose(root);
    }
    if (H5Fclose(file) < 0)
        r = -1;
    if (r) {
        e = gs_diag_set(d, GS_EIO, "path", "writing %s failed", h5_path);
        goto out;
    }
    if (write_xmf(xmf_path, h5_path, gears, n))
        e = gs_diag_set(d, GS_EIO, "path", "cannot write %s", xmf_path);
out:
    H5Eset_auto2(H5E_DEFAULT, efn, edata);
    return e;
}

/* ------------------------------------------------------------------------ */
/* Reading                                                                  */
/* ------------------------------------------------------------------------ */

/* Read a whole 1-D or 2-D dataset into a fresh array of `type`; *rows
 * receives the first dimension. NULL on failure. */
static void *read_all(hid_t g, const char *name, hid_t type, size_t elsize, hsize_t *rows)
{
    hid_t ds = H5Dopen2(g, name, H5P_DEFAULT);
    if (ds < 0)
        return NULL;
    hid_t sp = H5Dget_space(ds);
    hsize_t dims[2] = {0, 1};
    int rank = H5Sget_simple_extent_dims(sp, dims, NULL);
    H5Sclose(sp);
    size_t count = (size_t)dims[0] * (rank == 2 ? (size_t)dims[1] : 1);
    void *buf = calloc(count ? count : 1, elsize);
    if (buf && count && H5Dread(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf) < 0) {
        free(buf);
        buf = NULL;
    }
    H5Dclose(ds);
    *rows = dims[0];
    return buf;
}

gs_err gs_mesh_io_read(const char *h5_path, const char *name, gs_mesh **out, double centre[2],
                       double *rotation, gs_diag *d)
{
    *out = NULL;
    H5E_auto2_t efn;
    void *edata;
    H5Eget_auto2(H5E_DEFAULT, &efn, &edata);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    gs_err e = GS_OK;
    gs_mesh *m = NULL;
    hid_t g = -1, file = H5Fopen(h5_path, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (file < 0) {
        e = gs_diag_set(d, GS_EIO, "path", "cannot open %s", h5_path);
        goto out;
    }
    char path[256];
    snprintf(path, sizeof path, "/gears/%s", name);
    if (!valid_name(name) || H5Lexists(file, "gears", H5P_DEFAULT) <= 0 ||
        H5Lexists(file, path, H5P_DEFAULT) <= 0) {
        e = gs_diag_set(d, GS_ENOTFOUND, "name", "no mesh '%s' in %s", name, h5_path);
        goto out;
    }
    g = H5Gopen2(file, path, H5P_DEFAULT);
    m = gs_calloc(1, sizeof *m);
    if (g < 0 || !m) {
        e = gs_diag_set(d, GS_EIO, "path", "cannot read %s", path);
        goto out;
    }
    hsize_t rows;
    m->xy = read_all(g, "nodes", H5T_NATIVE_DOUBLE, sizeof(double), &rows);
    m->n_nodes = (gs_index)rows;
    m->tri = read_all(g, "triangles", H5T_NATIVE_INT64, sizeof(gs_index), &rows);
    m->n_tris = (gs_index)rows;
    if (H5Lexists(g, "triangles6", H5P_DEFAULT) > 0) { /* quadratic mesh */
        hsize_t r6;
        gs_index *t6 = read_all(g, "triangles6", H5T_NATIVE_INT64, sizeof(gs_index), &r6);
        m->mid = t6 && (gs_index)r6 == m->n_tris ? gs_calloc((size_t)(3 * r6) + 1, sizeof *m->mid) : NULL;
        if (m->mid)
            for (gs_index k = 0; k < m->n_tris; k++)
                for (int i = 0; i < 3; i++)
                    m->mid[3 * k + i] = t6[6 * k + 3 + i];
        free(t6);
        if (!m->mid) {
            e = gs_diag_set(d, GS_EIO, "path", "bad quadratic connectivity in %s", path);
            goto out;
        }
    }
    m->fixed = read_all(g, "fixed", H5T_NATIVE_INT64, sizeof(gs_index), &rows);
    m->n_fixed = (gs_index)rows;
    m->node_tag = read_all(g, "node_tag", H5T_NATIVE_SCHAR, 1, &rows);
    m->boundary = read_all(g, "boundary", H5T_NATIVE_INT64, sizeof(gs_index), &rows);
    m->n_boundary = (gs_index)rows;
    m->flank_ptr = read_all(g, "flank_ptr", H5T_NATIVE_INT64, sizeof(gs_index), &rows);
    m->n_teeth = rows >= 3 ? (int)((rows - 1) / 2) : 0;
    m->flank_nodes = read_all(g, "flank_nodes", H5T_NATIVE_INT64, sizeof(gs_index), &rows);
    if (!m->xy || !m->tri || !m->fixed || !m->node_tag || !m->boundary || !m->flank_ptr ||
        !m->flank_nodes) {
        e = gs_diag_set(d, GS_EIO, "path", "incomplete mesh %s in %s", path, h5_path);
        goto out;
    }
    if (m->boundary && m->n_boundary == 0) {
        free(m->boundary);
        m->boundary = NULL;
    }
    for (int k = 0; k < 2; k++) {
        const char *an = k ? "rotation_rad" : "centre_m";
        double v[2] = {0, 0};
        if (gsi_h5_read_attr(g, an, H5T_NATIVE_DOUBLE, v, k ? 1 : 2) < 0) {
            e = gs_diag_set(d, GS_EIO, "path", "no %s for %s", an, path);
            goto out;
        }
        if (k == 0 && centre) {
            centre[0] = v[0];
            centre[1] = v[1];
        }
        if (k == 1 && rotation)
            *rotation = v[0];
    }
    *out = m;
    m = NULL;
out:
    gs_mesh_free(&m);
    if (g >= 0)
        H5Gclose(g);
    if (file >= 0)
        H5Fclose(file);
    H5Eset_auto2(H5E_DEFAULT, efn, edata);
    return e;
}
