/* SPDX-License-Identifier: MIT
 * gearsimd: the daemon. Rank 0 serves ZeroMQ (src/service); every other rank
 * executes the engine's operations as rank 0 broadcasts them (src/dist). */
#include <getopt.h>
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "gearsim/engine.h"
#include "gearsim/service.h"

static void usage(FILE *f)
{
    fprintf(f,
            "usage: gearsimd [--connection-file PATH] [--data-dir DIR] [--bind ADDR]\n"
            "                [--command-port N] [--telemetry-port N]\n"
            "Run under mpirun -n N. Binds loopback by default; the endpoints go to the\n"
            "connection file (default $XDG_RUNTIME_DIR/gearsim/gearsimd.json or\n"
            "/tmp/gearsim-$UID/gearsimd.json).\n");
}

int main(int argc, char **argv)
{
    int provided;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
    int rank;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    static char conn[4096];
    const char *xdg = getenv("XDG_RUNTIME_DIR");
    if (xdg && xdg[0])
        snprintf(conn, sizeof conn, "%s/gearsim/gearsimd.json", xdg);
    else
        snprintf(conn, sizeof conn, "/tmp/gearsim-%u/gearsimd.json", (unsigned)getuid());
    gs_service_config cfg = {.connection_file = conn, .data_dir = ".", .bind = "127.0.0.1"};
    static const struct option opts[] = {
        {"connection-file", required_argument, 0, 'c'}, {"data-dir", required_argument, 0, 'd'},
        {"bind", required_argument, 0, 'b'},            {"command-port", required_argument, 0, 'p'},
        {"telemetry-port", required_argument, 0, 't'},  {"help", no_argument, 0, 'h'},
        {0, 0, 0, 0}};
    int c, bad = 0;
    while ((c = getopt_long(argc, argv, "c:d:b:p:t:h", opts, NULL)) != -1) {
        switch (c) {
        case 'c': cfg.connection_file = optarg; break;
        case 'd': cfg.data_dir = optarg; break;
        case 'b': cfg.bind = optarg; break;
        case 'p': cfg.command_port = atoi(optarg); break;
        case 't': cfg.telemetry_port = atoi(optarg); break;
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
    gs_engine *eng;
    if (gs_engine_new(MPI_COMM_WORLD, &eng) != GS_OK)
        MPI_Abort(MPI_COMM_WORLD, 1);
    gs_err e = rank == 0 ? gs_service_run(eng, &cfg) : gs_engine_serve(eng);
    gs_engine_free(&eng);
    MPI_Finalize();
    return e == GS_OK ? 0 : 1;
}
