/* SPDX-License-Identifier: MIT
 * gearsimd: the daemon. Rank 0 serves ZeroMQ (src/service); every other rank
 * executes the engine's operations as rank 0 broadcasts them (src/engine). */
#include <ctype.h>
#include <errno.h>
#include <getopt.h>
#include <mpi.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "gearsim/engine.h"
#include "gearsim/service.h"
#include "service/auth.h"
#include "service/options.h"

static void usage(FILE *f)
{
    fprintf(f,
            "usage: gearsimd [--config FILE] [--connection-file PATH] [--data-dir DIR]\n"
            "                [--bind ADDR] [--command-port N] [--telemetry-port N]\n"
            "                [--curve-server-key FILE --curve-allow DIR_OR_FILE]\n"
            "                [--resume] [--max-scene-mb N] [--max-record-mb N] [--max-clients N]\n"
            "                [--insecure-loopback]\n"
            "Run under mpirun -n N. Binds loopback by default; the endpoints go to the\n"
            "connection file (default $XDG_RUNTIME_DIR/gearsim/gearsimd.json or\n"
            "/tmp/gearsim-$UID/gearsimd.json, where the clients look by default).\n"
            "--data-dir (default: the working directory) is created when missing; an\n"
            "unusable one stops every rank with status 2. Any other --bind needs CURVE: the\n"
            "server's secret key file and the client public keys allowed (files of\n"
            "`gearctl keys`). --config reads `key = value` lines whose keys are the\n"
            "long options without '--' (deploy/gearsimd.conf); flags given on the\n"
            "command line win over the file. --resume continues the advance saved in\n"
            "DATA_DIR/autosave.h5 (scene outputs.checkpoint_every); --max-scene-mb refuses\n"
            "scenes whose estimated memory exceeds N MiB (default 4096); --max-record-mb\n"
            "stops a recording (error event, the run goes on) past N MiB (default 65536);\n"
            "--max-clients answers a new client 'too_large' while N others are active\n"
            "(a request in the last 60 s; default 256). On loopback the daemon makes a\n"
            "CURVE key pair for itself and one for its clients at every start and\n"
            "writes both into the 0600 connection file: only who can read that file\n"
            "can talk to it; --insecure-loopback turns this off (any local user could\n"
            "then send commands). A lock in DATA_DIR/.gearsimd.lock and beside the\n"
            "connection file keeps a second daemon off both. SIGTERM (to mpirun or to\n"
            "every rank) stops cleanly: the running advance ends with a cancelled\n"
            "`done`, the record is flushed, the connection file removed.\n"
            "Exit status of each rank: 0 after `shutdown` or SIGTERM, 1 on a failure\n"
            "while serving, 2 for bad options or keys, 3 when another daemon holds a\n"
            "lock (mpirun itself exits 1 after forwarding a signal).\n");
}

typedef struct daemon_opts {
    gs_service_config cfg;
    const char *curve_key, *curve_allow;
    bool resume;
    bool insecure_loopback;
    int64_t max_scene_mb;
    int64_t max_record_mb;
    int64_t max_clients;
} daemon_opts;

/* A whole decimal number in [lo, hi]; 0, or -1 when it is not. */
static int parse_int(const char *v, long long lo, long long hi, long long *out)
{
    char *end;
    errno = 0;
    long long x = strtoll(v, &end, 10);
    if (errno || end == v || *end || x < lo || x > hi)
        return -1;
    *out = x;
    return 0;
}

static int set_port(const char *v, int *out)
{
    long long p;
    if (parse_int(v, 0, 65535, &p) != 0)
        return -1;
    *out = (int)p;
    return 0;
}

/* A count from 1 to hi. */
static int parse_count(const char *v, long long hi, int64_t *out)
{
    long long x;
    if (parse_int(v, 1, hi, &x) != 0)
        return -1;
    *out = x;
    return 0;
}

/* true/yes/1 or false/no/0; 0, or -1 for anything else. */
static int parse_bool(const char *v, bool *out)
{
    if (!strcmp(v, "true") || !strcmp(v, "yes") || !strcmp(v, "1"))
        *out = true;
    else if (!strcmp(v, "false") || !strcmp(v, "no") || !strcmp(v, "0"))
        *out = false;
    else
        return -1;
    return 0;
}

/* One option by its long name; 0, or -1 when the name or value is bad. */
static int set_option(daemon_opts *o, const char *name, const char *v)
{
    if (!strcmp(name, "connection-file"))
        o->cfg.connection_file = v;
    else if (!strcmp(name, "data-dir"))
        o->cfg.data_dir = v;
    else if (!strcmp(name, "bind"))
        o->cfg.bind = v;
    else if (!strcmp(name, "command-port"))
        return set_port(v, &o->cfg.command_port);
    else if (!strcmp(name, "telemetry-port"))
        return set_port(v, &o->cfg.telemetry_port);
    else if (!strcmp(name, "curve-server-key"))
        o->curve_key = v;
    else if (!strcmp(name, "curve-allow"))
        o->curve_allow = v;
    else if (!strcmp(name, "resume"))
        return parse_bool(v, &o->resume);
    else if (!strcmp(name, "insecure-loopback"))
        return parse_bool(v, &o->insecure_loopback);
    else if (!strcmp(name, "max-scene-mb")) {
        return parse_count(v, 1ll << 40, &o->max_scene_mb);
    } else if (!strcmp(name, "max-record-mb")) {
        return parse_count(v, 1ll << 40, &o->max_record_mb);
    } else if (!strcmp(name, "max-clients")) {
        return parse_count(v, GSI_MAX_CLIENTS_CAP, &o->max_clients);
    } else
        return -1;
    return 0;
}

/* `key = value` lines; '#' starts a comment line; values may be quoted with
 * double quotes. The strings are kept for the life of the process. */
static int read_config(daemon_opts *o, const char *path, int rank)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        if (rank == 0)
            fprintf(stderr, "gearsimd: cannot read the configuration file '%s': %s\n", path, strerror(errno));
        return -1;
    }
    char line[4096];
    int lineno = 0, bad = 0;
    while (fgets(line, sizeof line, f)) {
        lineno++;
        char *l = line, *end;
        while (isspace((unsigned char)*l))
            l++;
        if (!*l || *l == '#')
            continue;
        char *eq = strchr(l, '=');
        if (!eq) {
            bad = 1;
            if (rank == 0)
                fprintf(stderr, "gearsimd: %s:%d: expected 'key = value'\n", path, lineno);
            continue;
        }
        *eq = '\0';
        char *v = eq + 1;
        for (end = eq; end > l && isspace((unsigned char)end[-1]); end--)
            end[-1] = '\0';
        while (isspace((unsigned char)*v))
            v++;
        for (end = v + strlen(v); end > v && isspace((unsigned char)end[-1]); end--)
            end[-1] = '\0';
        size_t n = strlen(v);
        if (n >= 2 && v[0] == '"' && v[n - 1] == '"') {
            v[n - 1] = '\0';
            v++;
        }
        char *copy = strdup(v);
        if (!copy || set_option(o, l, copy) != 0) {
            bad = 1;
            if (rank == 0)
                fprintf(stderr, "gearsimd: %s:%d: unknown key or bad value '%s = %s'\n", path, lineno, l, v);
            free(copy);
        }
    }
    fclose(f);
    return bad ? -1 : 0;
}

/* mkdir -p: every missing component of dir is created (mode 0755 less the
 * umask). 0, or -1 with errno set. */
static int make_dirs(const char *dir)
{
    char p[4096];
    if (snprintf(p, sizeof p, "%s", dir) >= (int)sizeof p) {
        errno = ENAMETOOLONG;
        return -1;
    }
    for (char *q = p + 1;; q++) {
        if (*q == '/' || *q == '\0') {
            char keep = *q;
            *q = '\0';
            if (mkdir(p, 0755) != 0 && errno != EEXIST)
                return -1;
            *q = keep;
            if (!keep)
                break;
        }
    }
    return 0;
}

/* The data directory, created when missing, must be a writable directory.
 * Rank 0 creates it first (on a shared file system the others then find it),
 * then every rank checks it (and creates it on a node-local file system).
 * 0 on every rank when all are fine, else -1 on every rank, with the reason
 * printed by each rank that failed. */
static int prepare_data_dir(const char *dir, int rank)
{
    int ok = 1;
    if (!dir[0]) {
        if (rank == 0)
            fprintf(stderr, "gearsimd: --data-dir: empty path\n");
        return -1;
    }
    for (int pass = 0; pass < 2; pass++) {
        if ((pass == 0) == (rank == 0)) {
            struct stat st;
            const char *why = NULL;
            if (make_dirs(dir) != 0)
                why = strerror(errno);
            else if (stat(dir, &st) != 0)
                why = strerror(errno);
            else if (!S_ISDIR(st.st_mode))
                why = "not a directory";
            else if (access(dir, W_OK | X_OK) != 0)
                why = "not writable";
            if (why) {
                fprintf(stderr, "gearsimd: --data-dir '%s' cannot be used (rank %d): %s\n", dir, rank, why);
                ok = 0;
            }
        }
        if (pass == 0)
            MPI_Bcast(&ok, 1, MPI_INT, 0, MPI_COMM_WORLD);
        if (!ok)
            return -1; /* rank 0 failed: nobody goes on */
    }
    MPI_Allreduce(MPI_IN_PLACE, &ok, 1, MPI_INT, MPI_MIN, MPI_COMM_WORLD);
    return ok ? 0 : -1;
}

int main(int argc, char **argv)
{
    /* A write past RLIMIT_FSIZE fails with EFBIG instead of killing the
     * daemon; the record reports it and stops (disk full is handled the
     * same way). Ignored dispositions survive the execv below. */
    signal(SIGXFSZ, SIG_IGN);
    /* One BLAS thread per rank unless the operator chose otherwise: ranks
     * are the parallelism, and a fixed thread count keeps the summation
     * order, and so the numbers, independent of how many ranks share a
     * machine. OpenBLAS reads the variable when it is loaded, before main,
     * so set it and start again (once; on failure just go on). */
    if (!getenv("OPENBLAS_NUM_THREADS")) {
        setenv("OPENBLAS_NUM_THREADS", "1", 1);
        setenv("OMP_NUM_THREADS", "1", 0);
        execv("/proc/self/exe", argv);
    }
    int provided;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
    int rank;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    /* Every rank catches SIGTERM/SIGINT (mpirun forwards them to all): rank 0
     * stops the service cleanly and then tells the others, which must not
     * die first. */
    gs_service_catch_signals();
    static char conn[4096];
    const char *xdg = getenv("XDG_RUNTIME_DIR");
    if (xdg && xdg[0])
        snprintf(conn, sizeof conn, "%s/gearsim/gearsimd.json", xdg);
    else
        snprintf(conn, sizeof conn, "/tmp/gearsim-%u/gearsimd.json", (unsigned)getuid());
    daemon_opts o = {.cfg = {.connection_file = conn, .data_dir = ".", .bind = "127.0.0.1"},
                     .max_scene_mb = GSI_DEFAULT_MAX_SCENE_MB,
                     .max_record_mb = GSI_DEFAULT_MAX_RECORD_MB,
                     .max_clients = GSI_DEFAULT_MAX_CLIENTS};
    static const struct option opts[] = {
        {"connection-file", required_argument, 0, 'c'}, {"data-dir", required_argument, 0, 'd'},
        {"bind", required_argument, 0, 'b'},            {"command-port", required_argument, 0, 'p'},
        {"telemetry-port", required_argument, 0, 't'},  {"help", no_argument, 0, 'h'},
        {"config", required_argument, 0, 'f'},          {"curve-server-key", required_argument, 0, 'k'},
        {"curve-allow", required_argument, 0, 'a'},     {"resume", no_argument, 0, 'r'},
        {"max-scene-mb", required_argument, 0, 'm'},    {"max-record-mb", required_argument, 0, 'R'},
        {"max-clients", required_argument, 0, 'C'},     {"insecure-loopback", no_argument, 0, 'I'},
        {0, 0, 0, 0}};
    int c, bad = 0;
    /* The configuration file first, so that command-line flags win. */
    for (int i = 1; i < argc; i++) {
        const char *path = NULL;
        if (!strcmp(argv[i], "--config") && i + 1 < argc)
            path = argv[i + 1];
        else if (!strncmp(argv[i], "--config=", 9))
            path = argv[i] + 9;
        if (path && read_config(&o, path, rank) != 0)
            bad = 1;
    }
    while ((c = getopt_long(argc, argv, "c:d:b:p:t:h", opts, NULL)) != -1) {
        int idx = -1;
        for (int i = 0; opts[i].name; i++)
            if (opts[i].val == c)
                idx = i;
        switch (c) {
        case 'f': break;
        case 'r': o.resume = true; break;
        case 'I': o.insecure_loopback = true; break;
        case 'c': case 'd': case 'b': case 'p': case 't': case 'k': case 'a': case 'm': case 'R': case 'C':
            if (set_option(&o, opts[idx].name, optarg) != 0) {
                if (rank == 0)
                    fprintf(stderr, "gearsimd: bad value '%s' for --%s\n", optarg, opts[idx].name);
                bad = 1;
            }
            break;
        case 'h':
            if (rank == 0)
                usage(stdout);
            MPI_Finalize();
            return 0;
        default: bad = 1;
        }
    }
    if (bad || optind < argc) {
        if (rank == 0)
            usage(stderr);
        MPI_Finalize();
        return 2;
    }
    /* The data directory first: the lock lives in it. */
    if (prepare_data_dir(o.cfg.data_dir, rank) != 0) {
        MPI_Finalize();
        return 2;
    }
    /* Rank 0 sets up CURVE (the operator's keys, or keys made now for a
     * loopback bind) and takes the locks, one daemon per data directory
     * and per connection file; every rank learns the outcome and exits with
     * the same status: 2 for bad keys, 3 when another daemon holds a lock. */
    int status = 0;
    if (rank == 0) {
        char err[1024];
        if (o.curve_key || o.curve_allow)
            status = gs_service_set_curve(o.curve_key, o.curve_allow, err, sizeof err) != 0 ? 2 : 0;
        else if (!o.insecure_loopback && gs_bind_is_loopback(o.cfg.bind))
            status = gs_service_set_curve_local(err, sizeof err) != 0 ? 2 : 0;
        if (status == 0)
            status = gs_service_lock(&o.cfg, err, sizeof err) != 0 ? 3 : 0;
        if (status)
            fprintf(stderr, "gearsimd: %s\n", err);
    }
    MPI_Bcast(&status, 1, MPI_INT, 0, MPI_COMM_WORLD);
    if (status) {
        MPI_Finalize();
        return status;
    }
    gs_service_set_resume(o.resume);
    gs_service_set_max_scene_mb(o.max_scene_mb);
    gs_service_set_max_record_mb(o.max_record_mb);
    gs_service_set_max_clients(o.max_clients);
    /* Rank 0 watches the ranks on its host (a dead rank is reported to
     * clients, docs/RELIABILITY.md): their process ids and host names. */
    int size;
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    struct {
        int pid;
        char host[60];
    } me = {(int)getpid(), ""}, *all = rank == 0 ? calloc((size_t)size, sizeof me) : NULL;
    gethostname(me.host, sizeof me.host - 1);
    MPI_Gather(&me, (int)sizeof me, MPI_BYTE, all, (int)sizeof me, MPI_BYTE, 0, MPI_COMM_WORLD);
    if (rank == 0 && all) {
        int *pids = calloc((size_t)size, sizeof *pids);
        for (int r = 1; pids && r < size; r++)
            pids[r] = strcmp(all[r].host, me.host) == 0 ? all[r].pid : 0;
        if (pids)
            gs_service_set_rank_pids(pids, size);
        free(pids);
    }
    free(all);
    gs_engine *eng;
    if (gs_engine_new(MPI_COMM_WORLD, &eng) != GS_OK)
        MPI_Abort(MPI_COMM_WORLD, 1);
    gs_err e = rank == 0 ? gs_service_run(eng, &o.cfg) : gs_engine_serve(eng);
    /* Every rank exits with rank 0's status: a start-up error of the service
     * (bind, connection file) fails the whole job, not rank 0 alone. */
    status = e == GS_OK ? 0 : 1;
    MPI_Bcast(&status, 1, MPI_INT, 0, MPI_COMM_WORLD);
    gs_engine_free(&eng);
    MPI_Finalize();
    return status;
}
