/* SPDX-License-Identifier: MIT
 * HDF5 attributes and small datasets (src/io/h5attr.h). */
#include <stdlib.h>
#include <string.h>

#include "io/h5attr.h"

/* Create attribute `name` of type on loc over the dataspace sp, write value
 * and close the attribute and sp. */
static herr_t write_attr(hid_t loc, const char *name, hid_t type, hid_t sp, const void *value)
{
    if (sp < 0)
        return -1;
    hid_t a = H5Acreate2(loc, name, type, sp, H5P_DEFAULT, H5P_DEFAULT);
    herr_t st = a < 0 ? -1 : H5Awrite(a, type, value);
    if (a >= 0 && H5Aclose(a) < 0)
        st = -1;
    H5Sclose(sp);
    return st;
}

herr_t gsi_h5_string_attr(hid_t loc, const char *name, const char *value)
{
    hid_t t = H5Tcopy(H5T_C_S1);
    H5Tset_size(t, strlen(value) + 1);
    H5Tset_strpad(t, H5T_STR_NULLTERM);
    herr_t st = gsi_h5_scalar_attr(loc, name, t, value);
    H5Tclose(t);
    return st;
}

herr_t gsi_h5_scalar_attr(hid_t loc, const char *name, hid_t type, const void *value)
{
    return write_attr(loc, name, type, H5Screate(H5S_SCALAR), value);
}

herr_t gsi_h5_array_attr(hid_t loc, const char *name, hid_t type, const void *value, hsize_t n)
{
    return write_attr(loc, name, type, H5Screate_simple(1, &n, NULL), value);
}

herr_t gsi_h5_read_attr(hid_t loc, const char *name, hid_t type, void *value, hsize_t n)
{
    hid_t a = H5Aopen(loc, name, H5P_DEFAULT);
    if (a < 0)
        return -1;
    /* A file is input: the attribute must hold exactly n numbers (a longer
     * one would be written past value), of a numeric class. */
    hid_t sp = H5Aget_space(a), t = H5Aget_type(a);
    H5T_class_t c = t >= 0 ? H5Tget_class(t) : H5T_NO_CLASS;
    herr_t st = -1;
    if (sp >= 0 && H5Sget_simple_extent_npoints(sp) == (hssize_t)n && (c == H5T_INTEGER || c == H5T_FLOAT))
        st = H5Aread(a, type, value);
    if (t >= 0)
        H5Tclose(t);
    if (sp >= 0)
        H5Sclose(sp);
    H5Aclose(a);
    return st < 0 ? -1 : 0;
}

char *gsi_h5_read_string_attr(hid_t loc, const char *name, size_t max)
{
    hid_t a = H5Aopen(loc, name, H5P_DEFAULT);
    if (a < 0)
        return NULL;
    hid_t t = H5Aget_type(a);
    size_t n = t >= 0 ? H5Tget_size(t) : 0;
    char *buf = n > 0 && n < max ? calloc(n + 1, 1) : NULL;
    if (buf && (H5Tget_class(t) != H5T_STRING || H5Tis_variable_str(t) || H5Aread(a, t, buf) < 0)) {
        free(buf);
        buf = NULL;
    }
    if (t >= 0)
        H5Tclose(t);
    H5Aclose(a);
    return buf;
}

int gsi_h5_fixed_ds(hid_t g, const char *name, hid_t type, const void *data, hsize_t rows,
                    hsize_t cols)
{
    hsize_t dims[2] = {rows, cols};
    hid_t sp = H5Screate_simple(cols ? 2 : 1, dims, NULL);
    if (sp < 0)
        return -1;
    hid_t ds = H5Dcreate2(g, name, type, sp, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
    herr_t st = ds < 0 ? -1 : (rows && data ? H5Dwrite(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, data) : 0);
    if (ds >= 0 && H5Dclose(ds) < 0)
        st = -1;
    H5Sclose(sp);
    return st < 0 ? -1 : 0;
}
