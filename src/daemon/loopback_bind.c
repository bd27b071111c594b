/* SPDX-License-Identifier: MIT
 * gearsim-loopback.so: preloaded into mpirun (and so into the ranks it
 * forks) on a single machine, it turns every bind() to the wildcard address
 * (0.0.0.0 or ::) into a bind to loopback (127.0.0.1 or ::1). Open MPI 4.1's
 * runtime (ORTE out-of-band TCP) binds its listeners to the wildcard whatever
 * oob_tcp_if_include says, and so listens, unauthenticated, on every
 * interface; no MCA parameter changes that. Explicit addresses pass
 * unchanged. Use it only when the whole job runs on this machine
 * (deploy/gearsimd.service, tests, deploy/demo.sh); a job across nodes needs
 * the runtime reachable from the other nodes (docs/RELIABILITY.md). */
#define _GNU_SOURCE
#include <dlfcn.h>
#include <errno.h>
#include <netinet/in.h>
#include <string.h>
#include <sys/socket.h>

typedef int (*bind_fn)(int, const struct sockaddr *, socklen_t);

int bind(int fd, const struct sockaddr *addr, socklen_t len)
{
    static bind_fn real;
    if (!real)
        real = (bind_fn)dlsym(RTLD_NEXT, "bind");
    if (!real) {
        errno = ENOSYS;
        return -1;
    }
    if (addr && addr->sa_family == AF_INET && len >= (socklen_t)sizeof(struct sockaddr_in)) {
        struct sockaddr_in in;
        memcpy(&in, addr, sizeof in);
        if (in.sin_addr.s_addr == htonl(INADDR_ANY)) {
            in.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
            return real(fd, (const struct sockaddr *)&in, sizeof in);
        }
    } else if (addr && addr->sa_family == AF_INET6 && len >= (socklen_t)sizeof(struct sockaddr_in6)) {
        struct sockaddr_in6 in6;
        memcpy(&in6, addr, sizeof in6);
        if (memcmp(&in6.sin6_addr, &in6addr_any, sizeof in6addr_any) == 0) {
            in6.sin6_addr = in6addr_loopback;
            return real(fd, (const struct sockaddr *)&in6, sizeof in6);
        }
    }
    return real(fd, addr, len);
}
