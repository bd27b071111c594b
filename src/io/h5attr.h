/* SPDX-License-Identifier: MIT
 * gearsim internal: HDF5 attributes, shared by the writers of the library
 * (record, checkpoint, meshes, stiffness results). */
#ifndef GEARSIM_IO_H5ATTR_H
#define GEARSIM_IO_H5ATTR_H

#include <hdf5.h>

/* A scalar NUL-terminated string attribute `name` = value on loc.
 * Returns a negative value on failure. */
herr_t gsi_h5_string_attr(hid_t loc, const char *name, const char *value);

/* A scalar attribute of a native type (H5T_NATIVE_DOUBLE, _INT64, ...). */
herr_t gsi_h5_scalar_attr(hid_t loc, const char *name, hid_t type, const void *value);

#endif
