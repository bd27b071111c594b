/* SPDX-License-Identifier: MIT
 * gearsim internal: HDF5 attributes and small datasets, shared by the
 * writers and readers of the library (record, checkpoint, meshes, stiffness
 * results). */
#ifndef GEARSIM_IO_H5ATTR_H
#define GEARSIM_IO_H5ATTR_H

#include <hdf5.h>

/* A scalar NUL-terminated string attribute `name` = value on loc.
 * Returns a negative value on failure. */
herr_t gsi_h5_string_attr(hid_t loc, const char *name, const char *value);

/* A scalar attribute of a native type (H5T_NATIVE_DOUBLE, _INT64, ...). */
herr_t gsi_h5_scalar_attr(hid_t loc, const char *name, hid_t type, const void *value);

/* A one-dimensional attribute of n values of a native type (n = 1 gives an
 * array of one, not a scalar). */
herr_t gsi_h5_array_attr(hid_t loc, const char *name, hid_t type, const void *value, hsize_t n);

/* Read the attribute `name` of loc, exactly n numbers (a scalar is one), as
 * type into value (room for n). Returns a negative value when it is
 * missing, unreadable, not numeric or of another size. */
herr_t gsi_h5_read_attr(hid_t loc, const char *name, hid_t type, void *value, hsize_t n);

/* A fixed-length string attribute of fewer than max bytes, malloc'd (the
 * caller frees it); NULL when missing, of another type or too long. */
char *gsi_h5_read_string_attr(hid_t loc, const char *name, size_t max);

/* A fixed-size dataset of rows (x cols, when cols > 0) values of type;
 * rows == 0 or data == NULL gives an empty one. 0 on success, -1 on failure. */
int gsi_h5_fixed_ds(hid_t g, const char *name, hid_t type, const void *data, hsize_t rows,
                    hsize_t cols);

#endif
