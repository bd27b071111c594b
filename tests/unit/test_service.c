/* SPDX-License-Identifier: MIT
 * The service core without sockets (gsi_handle_request_text): the reply
 * cache's bounds (per client, in all, by bytes), its lifetime, and that a
 * routing id reused after its client expired never gets the earlier
 * client's cached replies. Times are moved back by editing the stored
 * timestamps, so nothing waits. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <math.h>
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "gearsim/util.h"
#include "service/options.h"
#include "service/service_internal.h"

static gs_engine *eng;
static char data_dir[] = "/tmp/gearsim-svc-XXXXXX";
static gs_service_config cfg;

static char *ask(gs_service *s, const char *who, const char *req)
{
    char *r = gsi_handle_request_text(s, (const unsigned char *)who, strlen(who), req, strlen(req), false);
    assert_non_null(r);
    return r;
}

static gs_service *new_service(void)
{
    gs_service *s = calloc(1, sizeof *s);
    assert_non_null(s);
    assert_int_equal(gsi_service_init(s, eng, &cfg), GS_OK);
    return s;
}

static void free_service(gs_service *s)
{
    gsi_service_release(s);
    free(s);
}

/* Entries and bytes the cache holds for client `who`. */
static int client_entries(gs_service *s, const char *who, size_t *bytes)
{
    char prefix[64];
    size_t k = 0;
    for (size_t i = 0; i < strlen(who); i++)
        k += (size_t)snprintf(prefix + k, sizeof prefix - k, "%02x", (unsigned char)who[i]);
    snprintf(prefix + k, sizeof prefix - k, "/");
    int n = 0;
    *bytes = 0;
    for (int i = 0; i < GSI_CACHE; i++)
        if (s->cache[i].reply && strncmp(s->cache[i].key, prefix, strlen(prefix)) == 0)
            n++, *bytes += s->cache[i].bytes;
    return n;
}

static void retry_answered_from_cache(void **state)
{
    (void)state;
    gs_service *s = new_service();
    char *a = ask(s, "A", "{\"v\":1,\"id\":\"r1\",\"cmd\":\"status\"}");
    char *b = ask(s, "A", "{\"v\":1,\"id\":\"r1\",\"cmd\":\"hello\"}");
    assert_string_equal(a, b); /* the stored status reply, hello not run */
    char *c = ask(s, "B", "{\"v\":1,\"id\":\"r1\",\"cmd\":\"hello\"}");
    assert_non_null(strstr(c, "\"protocol\"")); /* another client: its own reply */
    free(a), free(b), free(c);
    free_service(s);
}

static void reused_routing_id_gets_nothing_cached(void **state)
{
    (void)state;
    gs_service *s = new_service();
    char *a = ask(s, "A", "{\"v\":1,\"id\":\"r1\",\"cmd\":\"status\"}");
    assert_non_null(strstr(a, "\"timing\""));
    /* Client A expires (silent longer than GSI_CLIENT_IDLE_S) but its reply
     * is still within the cache lifetime. */
    assert_int_equal(s->n_clients, 1);
    s->clients[0].last -= GSI_CLIENT_IDLE_S + 1;
    char *b = ask(s, "A", "{\"v\":1,\"id\":\"r1\",\"cmd\":\"hello\"}");
    assert_non_null(strstr(b, "\"protocol\"")); /* hello ran: a new client */
    assert_null(strstr(b, "\"timing\"")); /* not the status reply */
    free(a), free(b);
    free_service(s);
}

static void entries_expire(void **state)
{
    (void)state;
    gs_service *s = new_service();
    char *a = ask(s, "A", "{\"v\":1,\"id\":\"x\",\"cmd\":\"status\"}");
    for (int i = 0; i < GSI_CACHE; i++)
        if (s->cache[i].reply)
            s->cache[i].t -= GSI_CACHE_LIFETIME_S + 1;
    char *b = ask(s, "A", "{\"v\":1,\"id\":\"x\",\"cmd\":\"hello\"}");
    assert_non_null(strstr(b, "\"protocol\""));
    free(a), free(b);
    free_service(s);
}

static void per_client_bound(void **state)
{
    (void)state;
    gs_service *s = new_service();
    char req[128], *last = NULL;
    for (int i = 0; i < 300; i++) {
        snprintf(req, sizeof req, "{\"v\":1,\"id\":\"c%d\",\"cmd\":\"hello\"}", i);
        free(last);
        last = ask(s, "C", req);
    }
    size_t bytes;
    int n = client_entries(s, "C", &bytes);
    assert_int_equal(n, GSI_CACHE_CLIENT_ENTRIES);
    assert_true(bytes <= GSI_CACHE_CLIENT_BYTES);
    char *again = ask(s, "C", "{\"v\":1,\"id\":\"c299\",\"cmd\":\"status\"}");
    assert_string_equal(again, last); /* the newest are kept */
    char *first = ask(s, "C", "{\"v\":1,\"id\":\"c0\",\"cmd\":\"status\"}");
    assert_non_null(strstr(first, "\"timing\"")); /* the oldest were dropped: status runs */
    free(again), free(first), free(last);
    free_service(s);
}

static void byte_bounds_with_fetch_chunks(void **state)
{
    (void)state;
    char path[sizeof data_dir + 16];
    snprintf(path, sizeof path, "%s/blob.bin", data_dir);
    FILE *f = fopen(path, "wb");
    assert_non_null(f);
    for (int i = 0; i < (1 << 20); i++)
        fputc(i * 7 & 255, f);
    fclose(f);
    gs_service *s = new_service();
    const char *req = "{\"v\":1,\"id\":\"f\",\"cmd\":\"fetch\",\"args\":{\"path\":\"blob.bin\"}}";
    char who[16];
    for (int c = 0; c < 40; c++) {
        snprintf(who, sizeof who, "F%d", c);
        for (int k = 0; k < 4; k++) {
            char r2[128];
            snprintf(r2, sizeof r2, "{\"v\":1,\"id\":\"f%d\",\"cmd\":\"fetch\",\"args\":{\"path\":\"blob.bin\"}}", k);
            char *rep = ask(s, who, k ? r2 : req);
            assert_non_null(strstr(rep, "\"ok\":true"));
            free(rep);
            size_t b;
            client_entries(s, who, &b);
            assert_true(b <= GSI_CACHE_CLIENT_BYTES);
            assert_true(s->cache_bytes <= GSI_CACHE_BYTES);
        }
    }
    size_t sum = 0;
    for (int i = 0; i < GSI_CACHE; i++)
        sum += s->cache[i].reply ? s->cache[i].bytes : 0;
    assert_int_equal(sum, s->cache_bytes);
    assert_true(sum > GSI_CACHE_BYTES / 2); /* it does cache */
    free_service(s);
    unlink(path);
}

/* No reply carries a non-JSON number: a state holding NaN and Infinity
 * (as a run that diverged would) is answered with nulls, and
 * gsi_state_finite names the first bad value and the step. */
static void no_nonfinite_in_replies(void **state)
{
    (void)state;
    gs_service *s = new_service();
    char *r = ask(s, "a", "{\"v\":1,\"id\":\"l\",\"cmd\":\"load\",\"args\":{\"builtin\":\"pair\"}}");
    assert_non_null(strstr(r, "\"ok\":true"));
    free(r);
    gs_system *sys = gs_engine_system(eng);
    char msg[320];
    assert_true(gsi_state_finite(s, true, msg, sizeof msg));
    sys->step = 12;
    sys->w[0] = NAN;
    sys->q[1] = INFINITY;
    sys->work_in = -INFINITY;
    assert_false(gsi_state_finite(s, false, msg, sizeof msg));
    assert_non_null(strstr(msg, "a speed (#0)"));
    assert_non_null(strstr(msg, "step 12"));
    r = ask(s, "a", "{\"v\":1,\"id\":\"s\",\"cmd\":\"state\"}");
    assert_non_null(strstr(r, "\"ok\":true"));
    assert_null(strstr(r, "NaN"));
    assert_null(strstr(r, "nan"));
    assert_null(strstr(r, "Infinity"));
    assert_null(strstr(r, "inf"));
    assert_non_null(strstr(r, "null"));
    free(r);
    json_object *o = json_tokener_parse("{\"a\":[1.5,{\"b\":2.5}],\"c\":3.5}");
    json_object_array_put_idx(json_object_object_get(o, "a"), 0, json_object_new_double(NAN));
    json_object_object_add(json_object_array_get_idx(json_object_object_get(o, "a"), 1), "b",
                           json_object_new_double(-INFINITY));
    assert_int_equal(gsi_json_scrub(o), 2);
    assert_string_equal(json_object_to_json_string_ext(o, JSON_C_TO_STRING_PLAIN), "{\"a\":[null,{\"b\":null}],\"c\":3.5}");
    json_object_put(o);
    gs_diag d;
    gs_engine_run(eng, GS_OP_UNLOAD, NULL, 0, &d, NULL);
    free_service(s);
}

int main(int argc, char **argv)
{
    int provided;
    MPI_Init_thread(&argc, &argv, MPI_THREAD_FUNNELED, &provided);
    if (gs_engine_new(MPI_COMM_WORLD, &eng) != GS_OK || !mkdtemp(data_dir)) {
        fprintf(stderr, "test_service: cannot set up the engine or the data directory\n");
        return 1;
    }
    cfg.data_dir = data_dir;
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(retry_answered_from_cache),
        cmocka_unit_test(reused_routing_id_gets_nothing_cached),
        cmocka_unit_test(entries_expire),
        cmocka_unit_test(per_client_bound),
        cmocka_unit_test(byte_bounds_with_fetch_chunks),
        cmocka_unit_test(no_nonfinite_in_replies),
    };
    int rc = cmocka_run_group_tests(tests, NULL, NULL);
    rmdir(data_dir);
    gs_diag d;
    gs_engine_run(eng, GS_OP_SHUTDOWN, NULL, 0, &d, NULL);
    MPI_Finalize();
    return rc;
}
