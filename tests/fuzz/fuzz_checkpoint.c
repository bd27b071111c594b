/* SPDX-License-Identifier: MIT
 * Fuzz target: the checkpoint reader as the service uses it — `restore`
 * of a file in the data directory, or --resume of <data dir>/autosave.h5 —
 * on a one-rank engine. An input describes an HDF5 file, built with the
 * HDF5 library so that what is fuzzed is gearsim's reading of it (the
 * shape, type, declared size and layout of the snapshot dataset, the
 * /autosave attributes and field frames) and the snapshot's bytes:
 *
 *   byte 0   bits 0-1 snapshot rank (0: one dimension, 1: two, 2: scalar,
 *            3: no snapshot); bits 2-4 its type (u8, i8, i32, double, u16,
 *            u8 again); bit 5 the declared length is bytes 1-4 (else the
 *            payload's) and nothing is written; bit 6 an /autosave group
 *            and --resume instead of restore; bit 7 chunked layout
 *   bytes 1-4    a declared length (uint32, little end first)
 *   bytes 5-28   start_step, target_step, record_rows (int64)
 *   byte 29      field_frames count (its values: record_rows + i)
 *   the rest     the snapshot's bytes
 *
 * After a restore that succeeds the run takes one step and answers
 * `state` and `status`. Every reply must be a JSON object with v, id and
 * ok, and contain no NaN or Infinity; anything else aborts (a finding).
 * The scene limit is 16 MiB so that a seed's scene meshes in milliseconds. */
#include <dirent.h>
#include <hdf5.h>
#include <math.h>
#include <mpi.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "gearsim/engine.h"
#include "gearsim/util.h"
#include "service/options.h"
#include "service/service_internal.h"
#include "fuzz_common.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    fuzz_setup(argc, argv, "fuzz_checkpoint", "fuzzck");
    gs_service_set_max_scene_mb(16);
    H5Eset_auto2(H5E_DEFAULT, NULL, NULL);
    return 0;
}

static int64_t get64(const uint8_t *p)
{
    uint64_t v = 0;
    for (int i = 7; i >= 0; i--)
        v = v << 8 | p[i];
    return (int64_t)v;
}

/* The file the input describes at path; false when HDF5 cannot make it
 * (the input is then skipped). */
static bool build_file(const char *path, const uint8_t *data, size_t size)
{
    unsigned flags = data[0];
    uint32_t declared = (uint32_t)data[1] | (uint32_t)data[2] << 8 | (uint32_t)data[3] << 16 | (uint32_t)data[4] << 24;
    int64_t start = get64(data + 5), target = get64(data + 13), rows = get64(data + 21);
    int n_frames = data[29] % 80;
    const uint8_t *pay = data + 30;
    size_t plen = size - 30;
    const hid_t types[] = {H5T_NATIVE_UINT8, H5T_NATIVE_INT8, H5T_NATIVE_INT32,
                           H5T_NATIVE_DOUBLE, H5T_NATIVE_UINT16, H5T_NATIVE_UINT8};
    hid_t type = types[(flags >> 2 & 7) % 6];
    size_t tsize = H5Tget_size(type);
    hid_t f = H5Fcreate(path, H5F_ACC_TRUNC, H5P_DEFAULT, H5P_DEFAULT);
    if (f < 0)
        return false;
    bool ok = true;
    int rank = flags & 3;
    if (rank != 3) {
        hsize_t len = flags & 32 ? declared : (hsize_t)(plen / tsize);
        hsize_t dims[2] = {len, 2};
        int nd = rank == 0 ? 1 : rank == 1 ? 2 : 0;
        if (nd == 2)
            dims[0] = len / 2;
        hid_t sp = nd ? H5Screate_simple(nd, dims, NULL) : H5Screate(H5S_SCALAR);
        hid_t pl = H5Pcreate(H5P_DATASET_CREATE);
        if (flags & 128) {
            hsize_t chunk[2] = {64, 2};
            H5Pset_chunk(pl, nd ? nd : 1, chunk);
        }
        hid_t ds = sp >= 0 ? H5Dcreate2(f, "snapshot", type, sp, H5P_DEFAULT, pl, H5P_DEFAULT) : -1;
        hsize_t elems = nd == 0 ? 1 : nd == 1 ? dims[0] : dims[0] * 2;
        if (ds >= 0 && !(flags & 32) && elems > 0 && elems * tsize <= plen) {
            void *buf = malloc(elems * tsize);
            memcpy(buf, pay, elems * tsize);
            H5Dwrite(ds, type, H5S_ALL, H5S_ALL, H5P_DEFAULT, buf);
            free(buf);
        }
        ok = ds >= 0;
        if (ds >= 0)
            H5Dclose(ds);
        H5Pclose(pl);
        if (sp >= 0)
            H5Sclose(sp);
    }
    if (ok && (flags & 64)) {
        hid_t g = H5Gcreate2(f, "autosave", H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
        hid_t sc = H5Screate(H5S_SCALAR), st = H5Tcopy(H5T_C_S1);
        H5Tset_size(st, 8);
        const char *names[] = {"start_step", "target_step", "record_rows"};
        int64_t vals[] = {start, target, rows};
        for (int i = 0; i < 3; i++) {
            hid_t a = H5Acreate2(g, names[i], H5T_NATIVE_INT64, sc, H5P_DEFAULT, H5P_DEFAULT);
            H5Awrite(a, H5T_NATIVE_INT64, &vals[i]);
            H5Aclose(a);
        }
        const char *snames[] = {"parent_id", "record"};
        const char *svals[] = {"fuzz\0\0\0\0", "\0\0\0\0\0\0\0\0"};
        for (int i = 0; i < 2; i++) {
            hid_t a = H5Acreate2(g, snames[i], st, sc, H5P_DEFAULT, H5P_DEFAULT);
            H5Awrite(a, st, svals[i]);
            H5Aclose(a);
        }
        if (n_frames > 0) {
            hsize_t n = (hsize_t)n_frames;
            int64_t fr[80];
            for (int i = 0; i < n_frames; i++)
                fr[i] = rows + i;
            hid_t fs = H5Screate_simple(1, &n, NULL);
            hid_t ds = H5Dcreate2(g, "field_frames", H5T_NATIVE_INT64, fs, H5P_DEFAULT, H5P_DEFAULT, H5P_DEFAULT);
            H5Dwrite(ds, H5T_NATIVE_INT64, H5S_ALL, H5S_ALL, H5P_DEFAULT, fr);
            H5Dclose(ds);
            H5Sclose(fs);
        }
        H5Tclose(st);
        H5Sclose(sc);
        H5Gclose(g);
    }
    H5Fclose(f);
    return ok || rank == 3;
}

/* Does o hold a non-finite number anywhere (json-c reads NaN and Infinity)? */
static bool has_nonfinite(json_object *o)
{
    switch (json_object_get_type(o)) {
    case json_type_double:
        return !isfinite(json_object_get_double(o));
    case json_type_object: {
        json_object_object_foreach(o, k, v) {
            (void)k;
            if (has_nonfinite(v))
                return true;
        }
        return false;
    }
    case json_type_array:
        for (size_t i = 0; i < json_object_array_length(o); i++)
            if (has_nonfinite(json_object_array_get_idx(o, i)))
                return true;
        return false;
    default:
        return false;
    }
}

static void check_reply(const char *what, const char *reply)
{
    json_object *r = reply ? json_tokener_parse(reply) : NULL;
    json_object *ok;
    if (!r || json_object_get_type(r) != json_type_object || !json_object_object_get_ex(r, "ok", &ok) ||
        json_object_get_type(ok) != json_type_boolean || !json_object_object_get_ex(r, "v", NULL) ||
        (!json_object_get_boolean(ok) && !json_object_object_get_ex(r, "error", NULL))) {
        fprintf(stderr, "malformed reply to %s: %.300s\n", what, reply ? reply : "(none)");
        abort();
    }
    /* Not JSON, whatever json-c accepts: the writer must never emit them. */
    if (has_nonfinite(r)) {
        fprintf(stderr, "a non-JSON number in the reply to %s: %.300s\n", what, reply);
        abort();
    }
    json_object_put(r);
}

static char *ask(gs_service *s, const char *req)
{
    static const unsigned char who[] = {0, 'f', 'u', 'z', 'z'};
    char *reply = gsi_handle_request_text(s, who, sizeof who, req, strlen(req), false);
    check_reply(req, reply);
    return reply;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size < 30 || size > (1u << 20))
        return -1;
    gs_service *s = gs_calloc(1, sizeof *s);
    if (!s || gsi_service_init(s, eng, &cfg) != GS_OK)
        abort();
    bool resume = data[0] & 64;
    char path[sizeof data_dir + 32];
    snprintf(path, sizeof path, "%s/%s", data_dir, resume ? GSI_AUTOSAVE_NAME : "c.h5");
    if (build_file(path, data, size)) {
        bool loaded = false;
        if (resume) {
            gs_diag d;
            gs_diag_clear(&d);
            gs_err e = gsi_resume(s, &d);
            if (e != GS_OK && !d.message[0]) {
                fprintf(stderr, "--resume: error %d without a message\n", (int)e);
                abort();
            }
            loaded = e == GS_OK;
        } else {
            char *r = ask(s, "{\"v\":1,\"id\":\"r\",\"cmd\":\"restore\",\"args\":{\"path\":\"c.h5\"}}");
            loaded = strstr(r, "\"ok\":true") != NULL;
            free(r);
        }
        if (loaded && gs_engine_system(eng)) {
            int64_t one = 1, done = 0;
            gs_diag d;
            gs_diag_clear(&d);
            gs_engine_run(eng, GS_OP_STEP, &one, sizeof one, &d, &done);
            free(ask(s, "{\"v\":1,\"id\":\"s\",\"cmd\":\"state\"}"));
            free(ask(s, "{\"v\":1,\"id\":\"t\",\"cmd\":\"status\"}"));
        }
    }
    fuzz_teardown(s);
    return 0;
}
