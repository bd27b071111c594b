/* SPDX-License-Identifier: MIT
 * gearsim: small helpers used across modules (clocks, checked allocation). */
#ifndef GEARSIM_UTIL_H
#define GEARSIM_UTIL_H

#include <stddef.h>

/* Monotonic wall clock in seconds. */
double gs_now(void);
/* CPU seconds of the process (all threads): the comparable cost figure on a
 * shared machine, where wall clocks are inflated by the load. */
double gs_cpu_now(void);
/* calloc that returns NULL for n*size overflow instead of wrapping. */
void *gs_calloc(size_t n, size_t size);
/* Grow an array to hold at least n elements of `size` bytes: returns p when
 * its capacity *cap (in elements) suffices, else a larger block (at least
 * twice the old capacity) with *cap updated; NULL when allocation fails
 * (p is then still valid and still the caller's). */
void *gs_grow(void *p, size_t *cap, size_t n, size_t size);
/* strdup into a fresh allocation; NULL on failure or NULL input. */
char *gs_strdup(const char *s);
/* Read a whole file into a NUL-terminated buffer (owned by the caller).
 * Returns NULL and sets *len = 0 on failure. max_bytes bounds the size. */
char *gs_read_file(const char *path, size_t max_bytes, size_t *len);
/* Create a new file beside `target` (same directory) under an unguessable
 * name, .BASE.<32 hex>.tmp, with O_CREAT|O_EXCL|O_NOFOLLOW, mode 0600: a
 * planted symlink or file of that name is never followed or reused. Returns
 * the descriptor (the name in tmp), or -1 with errno. */
int gs_tmp_create_beside(const char *target, char *tmp, size_t cap);
/* The poll hook: long computations (meshing, assembly, set-up of
 * factorisations, compliance columns, rank 0's waits on the other ranks)
 * call gs_poll() between pieces of work of a few milliseconds, and gs_poll
 * calls fn(user), so a service answers its clients meanwhile. fn must not
 * start other computation; a call from within fn returns at once. NULL: no
 * hook (the default). */
void gs_poll_set(void (*fn)(void *user), void *user);
void gs_poll(void);
/* Run fn(arg) and return its result. With a poll hook set and called from
 * the thread that set it, fn runs on a worker thread while this one calls
 * the hook every millisecond or so: for one piece of work that cannot be
 * divided (a sparse factorisation, building a body) but touches nothing the
 * hook reads. Otherwise fn runs here. */
int gs_run_polled(int (*fn)(void *arg), void *arg);
/* Index of the last of the n ascending keys at or below k: 0 below the
 * first, n - 1 at or above the last (the segment of a piecewise-linear
 * table holding k, the end segments continued outwards). n >= 1. */
int gs_index_below(const double *key, int n, double k);

#endif
