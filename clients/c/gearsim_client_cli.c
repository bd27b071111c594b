/* SPDX-License-Identifier: MIT
 * gearsim-client-c: load a scene, advance to --until T, and print one line per
 * telemetry event: simulated time, total energy and the rpm of every body.
 *
 *   gearsim-client-c [--connection-file PATH] SCENE.json|builtin:NAME --until T
 *
 * Exit status 0 when the run completes, 1 with the error message on stderr. */
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim_client.h"

#define TIMEOUT_MS 10000
#define LOAD_TIMEOUT_MS 120000
#define EVENT_SILENCE_MS 30000

static void usage(void)
{
    fprintf(stderr, "usage: gearsim-client-c [--connection-file PATH] [--no-events] SCENE.json|builtin:NAME "
                    "--until T\n  --no-events: no subscriber; completion is learned from status\n");
}

static int die(const gsc_error *e)
{
    int n = (int)strlen(e->message);
    while (n > 0 && (e->message[n - 1] == '\n' || e->message[n - 1] == ' '))
        n--; /* json_util_get_last_err() ends with a newline */
    fprintf(stderr, "gearsim-client-c: error: %.*s [%s%s%s]\n", n, e->message, e->code,
            e->field[0] ? ", field " : "", e->field);
    return 1;
}

static double num(json_object *o, const char *key)
{
    json_object *v;
    return json_object_object_get_ex(o, key, &v) ? json_object_get_double(v) : 0.0;
}

static const char *str(json_object *o, const char *key)
{
    json_object *v;
    return json_object_object_get_ex(o, key, &v) ? json_object_get_string(v) : "";
}

static void print_telemetry(json_object *ev)
{
    json_object *energy = NULL, *bodies = NULL;
    json_object_object_get_ex(ev, "energy", &energy);
    json_object_object_get_ex(ev, "bodies", &bodies);
    printf("t=%.10g E=%.10g", num(ev, "time"), energy ? num(energy, "total") : 0.0);
    size_t n = bodies ? json_object_array_length(bodies) : 0;
    for (size_t i = 0; i < n; i++) {
        json_object *b = json_object_array_get_idx(bodies, i);
        printf(" %s=%.10g", str(b, "name"), num(b, "rpm"));
    }
    putchar('\n');
    fflush(stdout);
}

static int load(gsc_client *c, const char *spec, gsc_error *err)
{
    json_object *args = json_object_new_object();
    if (strncmp(spec, "builtin:", 8) == 0) {
        json_object_object_add(args, "builtin", json_object_new_string(spec + 8));
    } else {
        json_object *scene = json_object_from_file(spec);
        if (!scene) {
            snprintf(err->code, sizeof err->code, "io_error");
            snprintf(err->message, sizeof err->message, "cannot read scene %s: %s", spec,
                     json_util_get_last_err());
            err->field[0] = '\0';
            json_object_put(args);
            return -1;
        }
        json_object_object_add(args, "scene", scene);
    }
    int r = gsc_request(c, "load", args, LOAD_TIMEOUT_MS, 0, NULL, err);
    if (r != 0 && strcmp(err->code, "wrong_state") == 0) {
        /* A scene is loaded and idle: replace it. */
        json_object *st = NULL;
        gsc_error e2;
        if (gsc_request(c, "status", NULL, TIMEOUT_MS, 2, &st, &e2) == 0 &&
            strcmp(str(st, "state"), "loaded") == 0 &&
            gsc_request(c, "unload", NULL, TIMEOUT_MS, 2, NULL, &e2) == 0)
            r = gsc_request(c, "load", args, LOAD_TIMEOUT_MS, 0, NULL, err);
        json_object_put(st);
    }
    json_object_put(args);
    return r;
}

static void on_event(json_object *ev, void *user)
{
    (void)user;
    if (strcmp(str(ev, "type"), "telemetry") == 0)
        print_telemetry(ev);
}

int main(int argc, char **argv)
{
    const char *conn = NULL, *scene = NULL;
    double until = -1;
    bool events = true;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--connection-file") == 0 && i + 1 < argc)
            conn = argv[++i];
        else if (strcmp(argv[i], "--no-events") == 0)
            events = false;
        else if (strcmp(argv[i], "--until") == 0 && i + 1 < argc)
            until = strtod(argv[++i], NULL);
        else if (strcmp(argv[i], "-h") == 0 || strcmp(argv[i], "--help") == 0) {
            usage();
            return 0;
        } else if (argv[i][0] != '-' && !scene)
            scene = argv[i];
        else {
            usage();
            return 2;
        }
    }
    if (!scene || !(until > 0)) {
        usage();
        return 2;
    }
    gsc_error err;
    gsc_client *c = NULL;
    if (gsc_client_new(conn, &c, &err) != 0)
        return die(&err);
    int rc = 1;
    json_object *st = NULL, *args = NULL;
    if ((events && gsc_subscribe(c, "", TIMEOUT_MS, &err) != 0) || load(c, scene, &err) != 0 ||
        gsc_request(c, "status", NULL, TIMEOUT_MS, 2, &st, &err) != 0)
        goto out;
    double start = num(st, "time");
    if (!(until > start)) {
        fprintf(stderr, "gearsim-client-c: error: --until %g is not after the current time %g\n", until,
                start);
        goto out;
    }
    args = json_object_new_object();
    json_object_object_add(args, "time", json_object_new_double(until - start));
    if (gsc_request(c, "advance", args, TIMEOUT_MS, 2, NULL, &err) != 0)
        goto out;
    char parent[64];
    snprintf(parent, sizeof parent, "%s", gsc_last_id(c));
    json_object *ev = NULL;
    if (gsc_wait_done(c, parent, -1, on_event, NULL, &ev, &err) != 0)
        goto out;
    json_object *e;
    if (json_object_object_get_ex(ev, "error", &e)) {
        fprintf(stderr, "gearsim-client-c: error: run failed: %s [%s]\n", str(e, "message"), str(e, "code"));
    } else {
        fprintf(stderr, "done: %d steps, t=%g s%s\n", (int)num(ev, "steps"), num(ev, "time"),
                gsc_event_gaps(c) ? " (some events were dropped)" : "");
        rc = 0;
    }
    json_object_put(ev);
out:
    if (rc != 0 && err.code[0] && err.message[0])
        die(&err);
    json_object_put(st);
    json_object_put(args);
    gsc_client_free(&c);
    return rc;
}
