/* SPDX-License-Identifier: MIT
 * Fuzz target: the service's request handling without sockets — envelope
 * parsing and validation, the reply cache, dispatch and every command's
 * argument validation (src/service), on a one-rank engine. An input is up
 * to 8 requests, one per line, run in order on a fresh service (so that
 * `load` then `set_load`, `advance`, `checkpoint`... are reachable). Every
 * request must get exactly one reply that is a JSON object with v, id and
 * ok; anything else aborts (a finding). Requests for `stiffness` are
 * skipped: that command runs a seconds-long FE analysis once its arguments
 * are valid, which would stall the fuzzer. */
#include <dirent.h>
#include <mpi.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "gearsim/engine.h"
#include "gearsim/util.h"
#include "service/service_internal.h"
#include "fuzz_common.h"

int LLVMFuzzerInitialize(int *argc, char ***argv);
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

static int verbose; /* GEARSIM_FUZZ_VERBOSE=1: print the replies */

int LLVMFuzzerInitialize(int *argc, char ***argv)
{
    fuzz_setup(argc, argv, "fuzz_request", "fuzz");
    verbose = getenv("GEARSIM_FUZZ_VERBOSE") != NULL;
    return 0;
}

static void check_reply(const char *req, size_t n, const char *reply)
{
    if (!reply) {
        fprintf(stderr, "no reply to %.*s\n", (int)(n > 200 ? 200 : n), req);
        abort();
    }
    json_object *r = json_tokener_parse(reply);
    json_object *ok;
    if (!r || json_object_get_type(r) != json_type_object || !json_object_object_get_ex(r, "ok", &ok) ||
        json_object_get_type(ok) != json_type_boolean || !json_object_object_get_ex(r, "id", NULL) ||
        !json_object_object_get_ex(r, "v", NULL) ||
        (!json_object_get_boolean(ok) && !json_object_object_get_ex(r, "error", NULL))) {
        fprintf(stderr, "malformed reply %.300s\n", reply);
        abort();
    }
    json_object_put(r);
}

/* Is this request the `stiffness` command (however it is spelled in JSON)? */
static bool is_stiffness(const char *req, size_t n)
{
    json_tokener *tok = json_tokener_new();
    json_object *o = tok ? json_tokener_parse_ex(tok, req, (int)n) : NULL;
    json_object *c;
    bool yes = o && json_object_object_get_ex(o, "cmd", &c) && json_object_get_type(c) == json_type_string &&
               strcmp(json_object_get_string(c), "stiffness") == 0;
    json_object_put(o);
    json_tokener_free(tok);
    return yes;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    if (size > (1u << 16))
        return -1;
    gs_service *s = gs_calloc(1, sizeof *s);
    if (!s || gsi_service_init(s, eng, &cfg) != GS_OK)
        abort();
    static const unsigned char who[] = {0, 'f', 'u', 'z', 'z'};
    const char *p = (const char *)data, *end = p + size;
    for (int k = 0; k < 8 && p < end; k++) {
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        size_t n = nl ? (size_t)(nl - p) : (size_t)(end - p);
        /* a private copy, exactly n bytes, so ASan sees any over-read */
        char *req = malloc(n ? n : 1);
        memcpy(req, p, n);
        if (is_stiffness(req, n)) {
            free(req);
            p += n + 1;
            continue;
        }
        char *reply = gsi_handle_request_text(s, who, sizeof who, req, n, false);
        check_reply(req, n, reply);
        if (verbose)
            printf("%.200s\n", reply);
        free(reply);
        free(req);
        p += n + 1;
        if (s->shutdown)
            break;
    }
    fuzz_teardown(s);
    return 0;
}
