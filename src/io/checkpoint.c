/* SPDX-License-Identifier: MIT
 * Checkpoints: the engine's snapshot bytes (exact doubles, so a restored
 * run continues bit for bit) in an HDF5 file, written to a temporary name
 * and renamed so a crash never leaves a half-written checkpoint. */
#include <hdf5.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/record.h"
#include "io/h5attr.h"

gs_err gs_checkpoint_write(const char *path, const char *bytes, size_t len, const char *scene_json,
                           int64_t step, double time, gs_diag *d)
{
    char tmp[1100];
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    hid_t f = H5Fcreate(tmp, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    if (f < 0)
        return gs_diag_set(d, GS_EIO, "path", "cannot create the checkpoint '%s'", path);
    hsize_t n = len;
    hid_t sp = H5Screate_simple(1, &n, NULL);
    hid_t ds = H5Dcreate2(f, "snapshot", H5T_NATIVE_UINT8, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    herr_t st = ds < 0 ? -1 : H5Dwrite(ds, H5T_NATIVE_UINT8, H5S_ALL, H5S_ALL, H5P_DEFAULT, bytes);
    if (ds >= 0)
        H5Dclose(ds);
    H5Sclose(sp);
    if (gsi_h5_string_attr(f, "scene", scene_json) < 0 ||
        gsi_h5_scalar_attr(f, "step", H5T_NATIVE_INT64, &step) < 0 ||
        gsi_h5_scalar_attr(f, "time", H5T_NATIVE_DOUBLE, &time) < 0)
        st = -1;
    if (H5Fclose(f) < 0 || st < 0 || rename(tmp, path) != 0) {
        remove(tmp);
        return gs_diag_set(d, GS_EIO, "path", "cannot write the checkpoint '%s'", path);
    }
    return GS_OK;
}

gs_err gs_checkpoint_read(const char *path, char **bytes, size_t *len, gs_diag *d)
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
    hid_t sp = H5Dget_space(ds);
    hsize_t n = 0;
    H5Sget_simple_extent_dims(sp, &n, NULL);
    char *b = n > 0 && n < (1ull << 31) ? malloc(n) : NULL;
    gs_err err = GS_OK;
    if (!b || H5Dread(ds, H5T_NATIVE_UINT8, H5S_ALL, H5S_ALL, H5P_DEFAULT, b) < 0) {
        free(b);
        b = NULL;
        err = gs_diag_set(d, GS_EIO, "path", "cannot read the checkpoint '%s'", path);
    }
    H5Sclose(sp);
    H5Dclose(ds);
    H5Fclose(f);
    *bytes = b;
    *len = b ? (size_t)n : 0;
    return err;
}
