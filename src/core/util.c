/* SPDX-License-Identifier: MIT
 * Clocks, checked allocation and file reading. */
#include <errno.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdbool.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/random.h>
#include <time.h>
#include <unistd.h>

#include "gearsim/util.h"

double gs_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void (*poll_fn)(void *);
static void *poll_user;
static int poll_depth;
static pthread_t poll_thread;

void gs_poll_set(void (*fn)(void *user), void *user)
{
    poll_fn = fn;
    poll_user = user;
    poll_thread = pthread_self();
}

/* The hook is called only from the thread that set it, never from within
 * itself. */
static bool poll_here(void) { return poll_fn && !poll_depth && pthread_equal(pthread_self(), poll_thread); }

void gs_poll(void)
{
    if (!poll_here())
        return;
    poll_depth = 1;
    poll_fn(poll_user);
    poll_depth = 0;
}

typedef struct polled_job {
    int (*fn)(void *);
    void *arg;
    int result;
    atomic_int done;
} polled_job;

static void *polled_main(void *p)
{
    polled_job *j = p;
    j->result = j->fn(j->arg);
    atomic_store(&j->done, 1);
    return NULL;
}

int gs_run_polled(int (*fn)(void *arg), void *arg)
{
    if (!poll_here())
        return fn(arg);
    polled_job j = {fn, arg, 0, 0};
    pthread_attr_t at;
    pthread_t th;
    pthread_attr_init(&at);
    pthread_attr_setstacksize(&at, (size_t)16 << 20); /* orderings and factorisations recurse */
    int rc = pthread_create(&th, &at, polled_main, &j);
    pthread_attr_destroy(&at);
    if (rc != 0)
        return fn(arg); /* no thread: here, unpolled */
    while (!atomic_load(&j.done)) {
        gs_poll();
        struct timespec ts = {0, 1000000};
        nanosleep(&ts, NULL);
    }
    pthread_join(th, NULL);
    return j.result;
}

double gs_cpu_now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void *gs_grow(void *p, size_t *cap, size_t n, size_t size)
{
    if (n <= *cap && p)
        return p;
    size_t c = *cap > SIZE_MAX / 4 ? n : 2 * *cap;
    if (c < n)
        c = n;
    if (c < 16)
        c = 16;
    if (size == 0 || c > SIZE_MAX / size)
        return NULL;
    void *q = realloc(p, c * size);
    if (!q)
        return NULL;
    *cap = c;
    return q;
}

void *gs_calloc(size_t n, size_t size)
{
    if (n == 0 || size == 0)
        return calloc(1, 1);
    if (n > SIZE_MAX / size)
        return NULL;
    return calloc(n, size);
}

char *gs_strdup(const char *s)
{
    if (!s)
        return NULL;
    size_t n = strlen(s) + 1;
    char *p = malloc(n);
    if (p)
        memcpy(p, s, n);
    return p;
}

char *gs_read_file(const char *path, size_t max_bytes, size_t *len)
{
    *len = 0;
    FILE *f = fopen(path, "rb");
    if (!f)
        return NULL;
    char *buf = NULL;
    size_t cap = 0, n = 0;
    for (;;) {
        if (n + 4096 + 1 > cap) {
            size_t ncap = cap ? 2 * cap : 8192;
            char *nb = realloc(buf, ncap);
            if (!nb) {
                free(buf);
                fclose(f);
                return NULL;
            }
            buf = nb;
            cap = ncap;
        }
        size_t r = fread(buf + n, 1, cap - n - 1, f);
        n += r;
        if (n > max_bytes) {
            free(buf);
            fclose(f);
            return NULL;
        }
        if (r == 0)
            break;
    }
    fclose(f);
    buf[n] = '\0';
    *len = n;
    return buf;
}

static void random_hex(char *out, int nbytes)
{
    unsigned char b[32];
    if (nbytes > 32)
        nbytes = 32;
    if (getrandom(b, (size_t)nbytes, 0) != nbytes) {
        /* No kernel randomness: time and pid still differ per call; O_EXCL
         * keeps the creation safe, only less unguessable. */
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        unsigned long long x = (unsigned long long)ts.tv_nsec ^ ((unsigned long long)getpid() << 32) ^
                               (unsigned long long)ts.tv_sec * 2654435761ull;
        for (int i = 0; i < nbytes; i++, x = x * 6364136223846793005ull + 1442695040888963407ull)
            b[i] = (unsigned char)(x >> 56);
    }
    for (int i = 0; i < nbytes; i++)
        snprintf(out + 2 * i, 3, "%02x", b[i]);
}

int gs_tmp_create_beside(const char *target, char *tmp, size_t cap)
{
    const char *slash = strrchr(target, '/');
    int dl = slash ? (int)(slash - target + 1) : 0;
    const char *base = slash ? slash + 1 : target;
    for (int attempt = 0; attempt < 16; attempt++) {
        char rnd[33];
        random_hex(rnd, 16);
        int n = snprintf(tmp, cap, "%.*s.%.64s.%s.tmp", dl, target, base, rnd);
        if (n < 0 || (size_t)n >= cap) {
            errno = ENAMETOOLONG;
            return -1;
        }
        int fd = open(tmp, O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0600);
        if (fd >= 0 || errno != EEXIST)
            return fd;
    }
    errno = EEXIST;
    return -1;
}

int gs_index_below(const double *key, int n, double k)
{
    int lo = 0, hi = n - 1;
    if (k >= key[hi])
        return hi;
    while (hi - lo > 1) {
        int m = (lo + hi) / 2;
        if (key[m] <= k)
            lo = m;
        else
            hi = m;
    }
    return lo;
}
