/* SPDX-License-Identifier: MIT
 * Checkpoints: the engine's snapshot bytes (exact doubles, so a restored
 * run continues bit for bit) in an HDF5 file, written to a temporary name
 * and renamed so a crash never leaves a half-written checkpoint. */
#include <hdf5.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "gearsim/record.h"
#include "gearsim/util.h"
#include "io/h5attr.h"

static herr_t write_info(hid_t f, const gs_autosave_info *a)
{
    hid_t g = H5Gcreate2(f, "autosave", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    if (g < 0)
        return -1;
    herr_t st = 0;
    if (gsi_h5_string_attr(g, "parent_id", a->parent_id) < 0 ||
        gsi_h5_scalar_attr(g, "start_step", H5T_NATIVE_INT64, &a->start_step) < 0 ||
        gsi_h5_scalar_attr(g, "target_step", H5T_NATIVE_INT64, &a->target_step) < 0 ||
        gsi_h5_string_attr(g, "record", a->record) < 0 ||
        gsi_h5_scalar_attr(g, "record_rows", H5T_NATIVE_INT64, &a->record_rows) < 0)
        st = -1;
    if (st == 0 && a->n_field_bodies > 0 &&
        gsi_h5_fixed_ds(g, "field_frames", H5T_NATIVE_INT64, a->field_frames,
                        (hsize_t)a->n_field_bodies, 0) < 0)
        st = -1;
    if (H5Gclose(g) < 0)
        st = -1;
    return st;
}

static gs_err write_file(const char *path, const char *bytes, size_t len, const char *scene_json,
                         int64_t step, double time, const gs_autosave_info *info, gs_diag *d)
{
    /* A new file under an unguessable name (never a planted symlink), handed
     * to HDF5 through its descriptor, then renamed over the target: rename
     * replaces a symlink at the target instead of following it. */
    char tmp[1200], via_fd[64];
    int fd = gs_tmp_create_beside(path, tmp, sizeof tmp);
    if (fd >= 0 && fchmod(fd, 0644) != 0) { /* every output's mode (docs/RELIABILITY.md) */
        close(fd);
        remove(tmp);
        fd = -1;
    }
    if (fd < 0)
        return gs_diag_set(d, GS_EIO, "path", "cannot create the checkpoint '%s'", path);
    snprintf(via_fd, sizeof via_fd, "/proc/self/fd/%d", fd);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    hid_t f = H5Fcreate(via_fd, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    close(fd);
    if (f < 0) {
        remove(tmp);
        return gs_diag_set(d, GS_EIO, "path", "cannot create the checkpoint '%s'", path);
    }
    herr_t st = gsi_h5_fixed_ds(f, "snapshot", H5T_NATIVE_UINT8, bytes, len, 0);
    if (gsi_h5_string_attr(f, "scene", scene_json) < 0 ||
        gsi_h5_scalar_attr(f, "step", H5T_NATIVE_INT64, &step) < 0 ||
        gsi_h5_scalar_attr(f, "time", H5T_NATIVE_DOUBLE, &time) < 0)
        st = -1;
    if (st >= 0 && info && write_info(f, info) < 0)
        st = -1;
    if (H5Fclose(f) < 0 || st < 0 || rename(tmp, path) != 0) {
        remove(tmp);
        return gs_diag_set(d, GS_EIO, "path", "cannot write the checkpoint '%s'", path);
    }
    return GS_OK;
}

gs_err gs_checkpoint_write(const char *path, const char *bytes, size_t len, const char *scene_json,
                           int64_t step, double time, gs_diag *d)
{
    return write_file(path, bytes, len, scene_json, step, time, NULL, d);
}

gs_err gs_autosave_write(const char *path, const char *bytes, size_t len, const char *scene_json,
                         int64_t step, double time, const gs_autosave_info *info, gs_diag *d)
{
    return write_file(path, bytes, len, scene_json, step, time, info, d);
}

static int read_string_attr(hid_t loc, const char *name, char *out, size_t cap)
{
    out[0] = '\0';
    char *buf = gsi_h5_read_string_attr(loc, name, 1u << 20);
    int st = -1;
    if (buf) {
        snprintf(out, cap, "%s", buf);
        st = strlen(buf) < cap ? 0 : -1;
    }
    free(buf);
    return st;
}

gs_err gs_autosave_read_info(const char *path, gs_autosave_info *a, gs_diag *d)
{
    memset(a, 0, sizeof *a);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f < 0)
        return gs_diag_set(d, GS_EIO, "path", "'%s' is not an HDF5 file", path);
    hid_t g = H5Gopen2(f, "autosave", H5P_DEFAULT);
    if (g < 0) {
        H5Fclose(f);
        return gs_diag_set(d, GS_ENOTFOUND, "path", "'%s' is not an automatic checkpoint", path);
    }
    gs_err err = GS_OK;
    if (read_string_attr(g, "parent_id", a->parent_id, sizeof a->parent_id) < 0 ||
        gsi_h5_read_attr(g, "start_step", H5T_NATIVE_INT64, &a->start_step, 1) < 0 ||
        gsi_h5_read_attr(g, "target_step", H5T_NATIVE_INT64, &a->target_step, 1) < 0 ||
        read_string_attr(g, "record", a->record, sizeof a->record) < 0 ||
        gsi_h5_read_attr(g, "record_rows", H5T_NATIVE_INT64, &a->record_rows, 1) < 0)
        err = gs_diag_set(d, GS_EIO, "path", "the /autosave group of '%s' is incomplete", path);
    else if (a->start_step < 0 || a->target_step <= a->start_step || a->record_rows < 0 ||
             a->target_step > GS_CHECKPOINT_MAX_STEP)
        err = gs_diag_set(d, GS_ERANGE, "path", "the /autosave group of '%s' holds steps out of range (start %lld, "
                          "target %lld, record rows %lld)", path, (long long)a->start_step,
                          (long long)a->target_step, (long long)a->record_rows);
    if (err == GS_OK && H5Lexists(g, "field_frames", H5P_DEFAULT) > 0) {
        hid_t ds = H5Dopen2(g, "field_frames", H5P_DEFAULT);
        hid_t sp = ds >= 0 ? H5Dget_space(ds) : -1, t = ds >= 0 ? H5Dget_type(ds) : -1;
        hsize_t n = 0;
        if (sp < 0 || t < 0 || H5Tget_class(t) != H5T_INTEGER || H5Sget_simple_extent_ndims(sp) != 1 ||
            H5Sget_simple_extent_dims(sp, &n, NULL) != 1 || n > GS_AUTOSAVE_MAX_BODIES ||
            (n > 0 && H5Dread(ds, H5T_NATIVE_INT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, a->field_frames) < 0))
            err = gs_diag_set(d, GS_EIO, "path", "bad /autosave/field_frames in '%s'", path);
        else
            a->n_field_bodies = (int)n;
        for (int b = 0; err == GS_OK && b < a->n_field_bodies; b++)
            if (a->field_frames[b] < 0 || a->field_frames[b] > GS_CHECKPOINT_MAX_STEP)
                err = gs_diag_set(d, GS_ERANGE, "path", "/autosave/field_frames[%d] of '%s' is out of range", b, path);
        if (t >= 0)
            H5Tclose(t);
        if (sp >= 0)
            H5Sclose(sp);
        if (ds >= 0)
            H5Dclose(ds);
    }
    H5Gclose(g);
    H5Fclose(f);
    return err;
}

/* The snapshot dataset, checked before anything is allocated: one
 * dimension of bytes (an integer type of size 1), stored contiguously and
 * whole in the file (a few bytes of file cannot declare gigabytes), at most
 * max_bytes. */
static gs_err check_snapshot(hid_t ds, const char *path, size_t max_bytes, hsize_t *n, gs_diag *d)
{
    hid_t sp = H5Dget_space(ds), t = H5Dget_type(ds), pl = H5Dget_create_plist(ds);
    int nd = sp >= 0 ? H5Sget_simple_extent_ndims(sp) : -1;
    hsize_t dim = 0;
    gs_err err = GS_OK;
    if (nd != 1 || H5Sget_simple_extent_dims(sp, &dim, NULL) != 1)
        err = gs_diag_set(d, GS_EIO, "path", "the snapshot of '%s' is not one-dimensional", path);
    else if (t < 0 || H5Tget_class(t) != H5T_INTEGER || H5Tget_size(t) != 1)
        err = gs_diag_set(d, GS_EIO, "path", "the snapshot of '%s' is not a dataset of bytes", path);
    else if (dim == 0 || dim > (hsize_t)max_bytes)
        err = gs_diag_set(d, GS_ETOOBIG, "path", "the snapshot of '%s' declares %llu bytes (at most %zu)", path,
                          (unsigned long long)dim, max_bytes);
    else if (pl < 0 || H5Pget_layout(pl) != H5D_CONTIGUOUS || H5Dget_storage_size(ds) != dim)
        err = gs_diag_set(d, GS_EIO, "path", "the snapshot of '%s' is not stored whole (%llu of %llu bytes)", path,
                          (unsigned long long)H5Dget_storage_size(ds), (unsigned long long)dim);
    if (pl >= 0)
        H5Pclose(pl);
    if (t >= 0)
        H5Tclose(t);
    if (sp >= 0)
        H5Sclose(sp);
    *n = dim;
    return err;
}

gs_err gs_checkpoint_read(const char *path, size_t max_bytes, char **bytes, size_t *len, gs_diag *d)
{
    *bytes = NULL;
    *len = 0;
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    FILE *probe = fopen(path, "rb");
    if (!probe)
        return gs_diag_set(d, GS_ENOTFOUND, "path", "no checkpoint at '%s'", path);
    fclose(probe);
    hid_t f = H5Fopen(path, H5F_ACC_RDONLY, H5P_DEFAULT);
    if (f < 0)
        return gs_diag_set(d, GS_EIO, "path", "'%s' is not an HDF5 file", path);
    hid_t ds = H5Dopen2(f, "snapshot", H5P_DEFAULT);
    if (ds < 0) {
        H5Fclose(f);
        return gs_diag_set(d, GS_EIO, "path", "'%s' is not a gearsim checkpoint", path);
    }
    hsize_t n = 0;
    gs_err err = check_snapshot(ds, path, max_bytes, &n, d);
    char *b = NULL;
    if (err == GS_OK) {
        b = malloc((size_t)n);
        if (!b)
            err = gs_diag_set(d, GS_ENOMEM, "path", "no memory for the snapshot of '%s'", path);
        else if (H5Dread(ds, H5T_NATIVE_UINT8, H5S_ALL, H5S_ALL, H5P_DEFAULT, b) < 0)
            err = gs_diag_set(d, GS_EIO, "path", "cannot read the checkpoint '%s'", path);
    }
    if (err != GS_OK) {
        free(b);
        b = NULL;
    }
    H5Dclose(ds);
    H5Fclose(f);
    *bytes = b;
    *len = b ? (size_t)n : 0;
    return err;
}
