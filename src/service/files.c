/* SPDX-License-Identifier: MIT
 * The daemon's files (files.h): locks, the connection file, and every
 * client-named path opened beneath the data directory without following a
 * symbolic link, with the opened descriptor checked before any use. */

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "gearsim/util.h"
#include "service/files.h"
#include "service/options.h"

/* Held for the life of the process: closing them would drop the locks. */
static int lock_fd[2] = {-1, -1};
static struct stat lock_st[2];

/* Make (0700) or check the directory of the connection file: it must be a
 * directory of ours that nobody else can write to. */
static int check_conn_dir(const char *path, char *err, size_t cap)
{
    char dir[PATH_MAX];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (!slash)
        snprintf(dir, sizeof dir, ".");
    else if (slash == dir)
        dir[1] = '\0';
    else
        *slash = '\0';
    if (mkdir(dir, 0700) != 0 && errno != EEXIST) {
        snprintf(err, cap, "cannot create the directory '%s' of the connection file: %s", dir, strerror(errno));
        return -1;
    }
    struct stat st;
    if (lstat(dir, &st) != 0 || !S_ISDIR(st.st_mode)) {
        snprintf(err, cap, "the directory of the connection file, '%s', is not a directory", dir);
        return -1;
    }
    if (st.st_uid != geteuid() || (st.st_mode & 022)) {
        snprintf(err, cap, "the directory of the connection file, '%s', must belong to this user and must not be "
                           "writable by others (it holds the client keys; use a 0700 directory)", dir);
        return -1;
    }
    return 0;
}

static int take_lock(int k, int dirfd, const char *name, const char *shown, char *err, size_t cap)
{
    int fd = openat(dirfd, name, O_RDWR | O_CREAT | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC, 0600);
    struct stat st;
    if (fd < 0 || fstat(fd, &st) != 0 || !S_ISREG(st.st_mode)) {
        snprintf(err, cap, "cannot open the lock file '%s': %s", shown,
                 fd < 0 ? strerror(errno) : "not a regular file");
        if (fd >= 0)
            close(fd);
        return -1;
    }
    if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
        char pid[32] = "";
        ssize_t n = pread(fd, pid, sizeof pid - 1, 0);
        pid[n > 0 ? n : 0] = '\0';
        pid[strcspn(pid, "\n")] = '\0';
        snprintf(err, cap, "another gearsimd%s%s%s holds '%s'; refusing to start (one daemon per data directory "
                           "and per connection file)", pid[0] ? " (pid " : "", pid, pid[0] ? ")" : "", shown);
        close(fd);
        return -1;
    }
    char txt[32];
    int n = snprintf(txt, sizeof txt, "%d\n", (int)getpid());
    if (ftruncate(fd, 0) != 0 || pwrite(fd, txt, (size_t)n, 0) != n) {
        /* the lock holds without the pid; only the message is poorer */
    }
    lock_fd[k] = fd;
    lock_st[k] = st;
    return 0;
}

int gs_service_lock(const gs_service_config *cfg, char *err, size_t cap)
{
    const char *dd = cfg->data_dir ? cfg->data_dir : ".";
    int dfd = open(dd, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd < 0) {
        snprintf(err, cap, "data directory '%s': %s", dd, strerror(errno));
        return -1;
    }
    char shown[PATH_MAX + 32];
    snprintf(shown, sizeof shown, "%s/%s", dd, GSI_LOCK_NAME);
    int rc = take_lock(0, dfd, GSI_LOCK_NAME, shown, err, cap);
    close(dfd);
    if (rc != 0 || !cfg->connection_file)
        return rc;
    if (check_conn_dir(cfg->connection_file, err, cap) != 0)
        return -1;
    snprintf(shown, sizeof shown, "%s.lock", cfg->connection_file);
    struct stat a;
    /* The same file when the connection file's lock is the data dir's. */
    if (lstat(shown, &a) == 0 && a.st_dev == lock_st[0].st_dev && a.st_ino == lock_st[0].st_ino)
        return 0;
    return take_lock(1, AT_FDCWD, shown, shown, err, cap);
}

int gsi_write_connection_text(const char *path, const char *txt, char *err, size_t cap)
{
    char tmp[PATH_MAX + 96];
    int fd = gs_tmp_create_beside(path, tmp, sizeof tmp);
    if (fd < 0) {
        snprintf(err, cap, "cannot create a temporary file beside '%s': %s", path, strerror(errno));
        return -1;
    }
    size_t n = strlen(txt);
    int bad = fchmod(fd, 0600) != 0 || write(fd, txt, n) != (ssize_t)n || write(fd, "\n", 1) != 1;
    if (close(fd) != 0)
        bad = 1;
    if (!bad && rename(tmp, path) != 0)
        bad = 1;
    if (bad) {
        snprintf(err, cap, "cannot write the connection file '%s': %s", path, strerror(errno));
        unlink(tmp);
        return -1;
    }
    return 0;
}

/* ---- paths beneath the data directory ----------------------------------- */

void gsi_beneath_close(gsi_beneath *b)
{
    if (b->fd >= 0)
        close(b->fd);
    if (b->dirfd >= 0)
        close(b->dirfd);
    b->fd = b->dirfd = -1;
}

/* Walk rel's directories from the data directory, each opened with
 * O_NOFOLLOW; leaves b->dirfd on the last one and b->leaf its name. */
static gs_err walk(const char *data_dir, const char *rel, gsi_beneath *b, const char *field, gs_diag *d)
{
    b->fd = b->dirfd = -1;
    int fd = open(data_dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (fd < 0)
        return gs_diag_set(d, GS_EIO, field, "the data directory cannot be opened: %s", strerror(errno));
    const char *p = rel;
    for (;;) {
        while (*p == '/')
            p++;
        const char *q = strchr(p, '/');
        size_t n = q ? (size_t)(q - p) : strlen(p);
        const char *rest = p + n;
        while (*rest == '/')
            rest++;
        if (n >= sizeof b->leaf) {
            close(fd);
            return gs_diag_set(d, GS_ERANGE, field, "a component of '%s' is too long", rel);
        }
        if (!*rest) { /* the last component */
            memcpy(b->leaf, p, n);
            b->leaf[n] = '\0';
            if (!n || strcmp(b->leaf, ".") == 0) {
                close(fd);
                return gs_diag_set(d, GS_ERANGE, field, "'%s' names a directory, not a file", rel);
            }
            b->dirfd = fd;
            return GS_OK;
        }
        char comp[256];
        memcpy(comp, p, n);
        comp[n] = '\0';
        int nfd = openat(fd, comp, O_RDONLY | O_DIRECTORY | O_NOFOLLOW | O_CLOEXEC);
        int en = errno;
        close(fd);
        if (nfd < 0) {
            if (en == ENOENT)
                return gs_diag_set(d, GS_ENOTFOUND, field, "the directory '%s' in '%s' does not exist", comp, rel);
            return gs_diag_set(d, GS_ERANGE, field, "'%s' in '%s' is not a directory (symbolic links are refused)",
                               comp, rel);
        }
        fd = nfd;
        p = rest;
    }
}

static bool same_file(const struct stat *a, const struct stat *b)
{
    return a->st_dev == b->st_dev && a->st_ino == b->st_ino;
}

/* Names the daemon's own file that `st` is, or NULL. */
static const char *protected_file(gs_service *s, const struct stat *st)
{
    struct stat o;
    if (lock_fd[0] >= 0 && same_file(st, &lock_st[0]))
        return "the daemon's lock file";
    if (lock_fd[1] >= 0 && same_file(st, &lock_st[1]))
        return "the daemon's lock file";
    if (s->cfg && s->cfg->connection_file && stat(s->cfg->connection_file, &o) == 0 && same_file(st, &o))
        return "the daemon's connection file";
    if (s->record && stat(gs_record_path(s->record), &o) == 0 && same_file(st, &o))
        return "the record being written";
    char p[PATH_MAX + 16];
    snprintf(p, sizeof p, "%s/%s", s->data_dir, GSI_AUTOSAVE_NAME);
    if (s->adv.active && s->adv.next_autosave > 0 && stat(p, &o) == 0 && same_file(st, &o))
        return "the running advance's automatic checkpoint";
    return NULL;
}

static gs_err refuse_kind(const struct stat *st, const char *rel, const char *field, gs_diag *d)
{
    if (S_ISREG(st->st_mode))
        return GS_OK;
    const char *kind = S_ISDIR(st->st_mode) ? "a directory" : S_ISFIFO(st->st_mode) ? "a FIFO"
                     : S_ISLNK(st->st_mode) ? "a symbolic link" : S_ISSOCK(st->st_mode) ? "a socket"
                     : S_ISCHR(st->st_mode) || S_ISBLK(st->st_mode) ? "a device" : "not a regular file";
    return gs_diag_set(d, GS_ERANGE, field, "'%s' is %s; only regular files are used", rel, kind);
}

gs_err gsi_open_read(gs_service *s, const char *rel, const char *field, gsi_beneath *b, struct stat *st,
                     gs_diag *d)
{
    GS_TRY(walk(s->data_dir, rel, b, field, d));
    struct stat pre;
    /* Before any open: a FIFO or device is refused without blocking on it. */
    if (fstatat(b->dirfd, b->leaf, &pre, AT_SYMLINK_NOFOLLOW) != 0) {
        gsi_beneath_close(b);
        return gs_diag_set(d, GS_ENOTFOUND, field, "no file '%s' in the data directory", rel);
    }
    gs_err e = refuse_kind(&pre, rel, field, d);
    if (e == GS_OK) {
        /* O_NONBLOCK: a FIFO swapped in since the check still does not block. */
        b->fd = openat(b->dirfd, b->leaf, O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
        if (b->fd < 0)
            e = errno == ELOOP ? gs_diag_set(d, GS_ERANGE, field, "'%s' is a symbolic link; refused", rel)
                               : gs_diag_set(d, GS_ENOTFOUND, field, "cannot open '%s': %s", rel, strerror(errno));
    }
    if (e == GS_OK && fstat(b->fd, st) != 0)
        e = gs_diag_set(d, GS_EIO, field, "cannot inspect '%s'", rel);
    if (e == GS_OK)
        e = refuse_kind(st, rel, field, d);
    if (e == GS_OK && st->st_nlink > 1)
        e = gs_diag_set(d, GS_ERANGE, field, "'%s' has %lu hard links; files with more than one name are refused",
                        rel, (unsigned long)st->st_nlink);
    if (e == GS_OK && fcntl(b->fd, F_SETFL, fcntl(b->fd, F_GETFL) & ~O_NONBLOCK) != 0)
        e = gs_diag_set(d, GS_EIO, field, "cannot use '%s'", rel);
    if (e != GS_OK)
        gsi_beneath_close(b);
    return e;
}

gs_err gsi_check_write(gs_service *s, const char *rel, const char *field, bool create, gsi_beneath *b,
                       gs_diag *d)
{
    GS_TRY(walk(s->data_dir, rel, b, field, d));
    struct stat st;
    gs_err e = GS_OK;
    if (fstatat(b->dirfd, b->leaf, &st, AT_SYMLINK_NOFOLLOW) == 0) {
        const char *own = protected_file(s, &st);
        if (own)
            e = gs_diag_set(d, GS_ERANGE, field, "'%s' is %s; choose another name", rel, own);
        else
            e = refuse_kind(&st, rel, field, d);
        if (e == GS_OK && create && st.st_nlink > 1)
            e = gs_diag_set(d, GS_ERANGE, field, "'%s' has %lu hard links; writing it would change another name",
                            rel, (unsigned long)st.st_nlink);
    }
    if (e == GS_OK && create) {
        b->fd = openat(b->dirfd, b->leaf, O_WRONLY | O_CREAT | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC, 0644);
        struct stat now;
        if (b->fd < 0)
            e = gs_diag_set(d, GS_EIO, field, "cannot create '%s': %s", rel,
                            errno == ELOOP ? "it is a symbolic link" : strerror(errno));
        else if (fstat(b->fd, &now) != 0 || !S_ISREG(now.st_mode) || now.st_nlink != 1)
            e = gs_diag_set(d, GS_ERANGE, field, "'%s' changed into something other than a file of one name", rel);
    }
    if (e != GS_OK)
        gsi_beneath_close(b);
    return e;
}

gs_err gsi_confirm_same(gsi_beneath *b, const char *rel, const char *field, gs_diag *d)
{
    struct stat a, n;
    if (b->fd < 0 || fstat(b->fd, &a) != 0 || fstatat(b->dirfd, b->leaf, &n, AT_SYMLINK_NOFOLLOW) != 0 ||
        !same_file(&a, &n))
        return gs_diag_set(d, GS_EIO, field, "'%s' was replaced while it was being opened; refused", rel);
    return GS_OK;
}

void gsi_fd_path(int fd, char *out, size_t cap)
{
    snprintf(out, cap, "/proc/self/fd/%d", fd);
}
