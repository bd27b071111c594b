/* SPDX-License-Identifier: MIT
 * The daemon's files (docs/RELIABILITY.md, "File rules"): the locks that
 * keep a second daemon off a data directory and a connection file, the
 * connection file itself, and client-named paths opened beneath the data
 * directory: every directory component with O_NOFOLLOW from an O_DIRECTORY
 * descriptor, the file's type checked with fstatat before any open (a FIFO
 * or device is never opened), the opened descriptor checked again (regular,
 * one link), and the daemon's own files (lock, connection file, the record
 * being written, the running advance's autosave) never written through. */
#ifndef GSI_FILES_H
#define GSI_FILES_H

#include <stdbool.h>
#include <stddef.h>
#include <sys/stat.h>

#include "service/service_internal.h"

#define GSI_LOCK_NAME ".gearsimd.lock"

/* A path beneath the data directory: its directory, opened without
 * following links, the last component's name, and (when opened) the file. */
typedef struct gsi_beneath {
    int dirfd, fd;
    char leaf[256];
} gsi_beneath;

/* Rank 0, before the service starts: flock DATA_DIR/.gearsimd.lock and
 * CONNECTION_FILE.lock (the connection file's directory is made 0700, or
 * must be ours and not writable by others). 0, or -1 with a sentence. The
 * locks are held until the process exits. */
int gs_service_lock(const gs_service_config *cfg, char *err, size_t cap);

/* Write the connection file: a new temporary file (above), then rename. */
int gsi_write_connection_text(const char *path, const char *txt, char *err, size_t cap);

/* Open `rel` for reading: a regular file of one link, no symlink anywhere.
 * Errors name `field`. On success b->fd is open (blocking) and st filled. */
gs_err gsi_open_read(gs_service *s, const char *rel, const char *field, gsi_beneath *b, struct stat *st,
                     gs_diag *d);
/* Check `rel` as a write target: no symlink in it; if it exists it is a
 * regular file that is none of the daemon's own files (and, with create, has
 * one link). With create the file is created (not truncated) and b->fd
 * opened, for a writer that opens it by name afterwards. */
gs_err gsi_check_write(gs_service *s, const char *rel, const char *field, bool create, gsi_beneath *b,
                       gs_diag *d);
/* After a by-name open: the name still refers to b->fd's file. */
gs_err gsi_confirm_same(gsi_beneath *b, const char *rel, const char *field, gs_diag *d);
void gsi_beneath_close(gsi_beneath *b);
/* "/proc/self/fd/N": a name for an open descriptor, for by-name APIs. */
void gsi_fd_path(int fd, char *out, size_t cap);

#endif
