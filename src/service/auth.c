/* SPDX-License-Identifier: MIT
 * CURVE keys, allow-list and the ZAP handler thread (auth.h). The handler
 * answers every ZAP request: 200 for a CURVE client whose public key is on
 * the allow-list, 400 for anything else, so an unknown client's connection
 * is dropped before a single message of it reaches the service. */
#include <dirent.h>
#include <errno.h>
#include <pthread.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <zmq.h>

#include "service/auth.h"

#define KEY_Z85 40
#define KEY_BYTES 32
#define MAX_ALLOWED 4096

static struct {
    bool enabled;
    char server_public[KEY_Z85 + 1];
    char server_secret[KEY_Z85 + 1];
    uint8_t allowed[MAX_ALLOWED][KEY_BYTES];
    int n_allowed;
    bool local_client;      /* keys made at start for loopback clients */
    char client_public[KEY_Z85 + 1];
    char client_secret[KEY_Z85 + 1];
    void *zap;
    pthread_t thread;
    bool running;
    unsigned long refused;
} A;

static const char z85_chars[] =
    "0123456789abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ.-:+=^!/*?&<>()[]{}@%$#";

static bool is_z85_key(const char *s, size_t n)
{
    if (n != KEY_Z85)
        return false;
    for (size_t i = 0; i < n; i++)
        if (!s[i] || !strchr(z85_chars, s[i]))
            return false;
    return true;
}

static char *trim(char *s)
{
    while (*s == ' ' || *s == '\t')
        s++;
    size_t n = strlen(s);
    while (n && strchr(" \t\r\n", s[n - 1]))
        s[--n] = '\0';
    return s;
}

/* Read `public-key = ...` and `secret-key = ...` (or a bare key line, taken
 * as public) from a key file. Each output may be NULL. Returns the number of
 * public keys seen (each passed to on_public), or -1 on a malformed file. */
static int read_key_file(const char *path, char *secret, void (*on_public)(const char *z85, void *u), void *u,
                         char *err, size_t cap)
{
    FILE *f = fopen(path, "r");
    if (!f) {
        snprintf(err, cap, "cannot read key file '%s': %s", path, strerror(errno));
        return -1;
    }
    char line[512];
    int n_pub = 0, lineno = 0;
    if (secret)
        secret[0] = '\0';
    while (fgets(line, sizeof line, f)) {
        lineno++;
        char *l = trim(line);
        if (!l[0] || l[0] == '#')
            continue;
        char *eq = strchr(l, '=');
        const char *key = "public-key", *val = l;
        if (eq && eq != l && !is_z85_key(l, strlen(l))) {
            *eq = '\0';
            key = trim(l);
            val = trim(eq + 1);
        }
        if (!is_z85_key(val, strlen(val))) {
            snprintf(err, cap, "%s:%d: not a 40-character Z85 key", path, lineno);
            fclose(f);
            return -1;
        }
        if (strcmp(key, "public-key") == 0) {
            n_pub++;
            if (on_public)
                on_public(val, u);
        } else if (strcmp(key, "secret-key") == 0) {
            if (secret)
                snprintf(secret, KEY_Z85 + 1, "%s", val);
        } else {
            snprintf(err, cap, "%s:%d: unknown key '%.32s' (public-key or secret-key)", path, lineno, key);
            fclose(f);
            return -1;
        }
    }
    fclose(f);
    return n_pub;
}

static void add_allowed(const char *z85, void *u)
{
    (void)u;
    if (A.n_allowed < MAX_ALLOWED && zmq_z85_decode(A.allowed[A.n_allowed], z85))
        A.n_allowed++;
}

static bool ends_with(const char *s, const char *suffix)
{
    size_t n = strlen(s), k = strlen(suffix);
    return n >= k && strcmp(s + n - k, suffix) == 0;
}

int gs_service_set_curve(const char *server_key_file, const char *allow_path, char *err, size_t cap)
{
    if (!server_key_file || !allow_path) {
        snprintf(err, cap, "CURVE needs both a server key file and an allow-list of client keys");
        return -1;
    }
    char secret[KEY_Z85 + 1], pub_seen[KEY_Z85 + 1] = "";
    if (read_key_file(server_key_file, secret, NULL, NULL, err, cap) < 0)
        return -1;
    if (!secret[0]) {
        snprintf(err, cap, "'%s' holds no secret-key line (give the server's .key file, not its .pub)",
                 server_key_file);
        return -1;
    }
    if (zmq_curve_public(pub_seen, secret) != 0) {
        snprintf(err, cap, "'%s': the secret key is not valid", server_key_file);
        return -1;
    }
    A.n_allowed = 0;
    struct stat st;
    if (stat(allow_path, &st) != 0) {
        snprintf(err, cap, "cannot read the allow-list '%s': %s", allow_path, strerror(errno));
        return -1;
    }
    if (S_ISDIR(st.st_mode)) {
        DIR *dir = opendir(allow_path);
        if (!dir) {
            snprintf(err, cap, "cannot list '%s': %s", allow_path, strerror(errno));
            return -1;
        }
        struct dirent *de;
        int rc = 0;
        while (rc == 0 && (de = readdir(dir))) {
            if (de->d_name[0] == '.' || !ends_with(de->d_name, ".pub"))
                continue;
            char p[4096];
            snprintf(p, sizeof p, "%s/%s", allow_path, de->d_name);
            if (read_key_file(p, NULL, add_allowed, NULL, err, cap) < 0)
                rc = -1;
        }
        closedir(dir);
        if (rc)
            return -1;
    } else if (read_key_file(allow_path, NULL, add_allowed, NULL, err, cap) < 0) {
        return -1;
    }
    if (A.n_allowed == 0) {
        snprintf(err, cap, "the allow-list '%s' holds no client public key (*.pub files of `gearctl keys`)",
                 allow_path);
        return -1;
    }
    snprintf(A.server_secret, sizeof A.server_secret, "%s", secret);
    snprintf(A.server_public, sizeof A.server_public, "%s", pub_seen);
    A.enabled = true;
    return 0;
}

int gs_service_set_curve_local(char *err, size_t cap)
{
    char cpub[KEY_Z85 + 1], csec[KEY_Z85 + 1];
    if (!zmq_has("curve") || zmq_curve_keypair(A.server_public, A.server_secret) != 0 ||
        zmq_curve_keypair(cpub, csec) != 0) {
        snprintf(err, cap, "cannot make the loopback CURVE keys (libzmq without CURVE?); "
                           "--insecure-loopback runs without them");
        return -1;
    }
    A.n_allowed = 0;
    add_allowed(cpub, NULL);
    if (A.n_allowed != 1) {
        snprintf(err, cap, "cannot decode the loopback client key");
        return -1;
    }
    snprintf(A.client_public, sizeof A.client_public, "%s", cpub);
    snprintf(A.client_secret, sizeof A.client_secret, "%s", csec);
    A.local_client = true;
    A.enabled = true;
    return 0;
}

bool gsi_curve_local_client(const char **pub, const char **secret)
{
    if (!A.local_client)
        return false;
    *pub = A.client_public;
    *secret = A.client_secret;
    return true;
}

bool gs_bind_is_loopback(const char *bind)
{
    if (!bind || !bind[0])
        return true; /* the default, 127.0.0.1 */
    if (strcmp(bind, "localhost") == 0 || strcmp(bind, "lo") == 0 || strcmp(bind, "::1") == 0 ||
        strcmp(bind, "[::1]") == 0)
        return true;
    /* 127.a.b.c, digits and dots only */
    if (strncmp(bind, "127.", 4) != 0)
        return false;
    int dots = 0;
    for (const char *p = bind + 4; *p; p++) {
        if (*p == '.')
            dots++;
        else if (*p < '0' || *p > '9')
            return false;
    }
    return dots == 2;
}

bool gsi_curve_enabled(void) { return A.enabled; }
const char *gsi_curve_server_public(void) { return A.server_public; }
int gsi_curve_allowed_count(void) { return A.n_allowed; }

int gsi_curve_apply(void *sock)
{
    int one = 1;
    if (zmq_setsockopt(sock, ZMQ_CURVE_SERVER, &one, sizeof one) != 0 ||
        zmq_setsockopt(sock, ZMQ_CURVE_SECRETKEY, A.server_secret, KEY_Z85) != 0 ||
        zmq_setsockopt(sock, ZMQ_ZAP_DOMAIN, "gearsim", 7) != 0)
        return -1;
    return 0;
}

static bool key_allowed(const uint8_t *key)
{
    for (int i = 0; i < A.n_allowed; i++)
        if (memcmp(A.allowed[i], key, KEY_BYTES) == 0)
            return true;
    return false;
}

/* One ZAP request (RFC 27): version, request id, domain, address, identity,
 * mechanism, credentials...; one reply: version, request id, status code,
 * status text, user id, metadata. */
static void *zap_thread(void *arg)
{
    (void)arg;
    for (;;) {
        zmq_msg_t part[8];
        int n = 0;
        bool more = true, term = false;
        while (more) {
            zmq_msg_t m;
            zmq_msg_init(&m);
            if (zmq_msg_recv(&m, A.zap, 0) < 0) {
                zmq_msg_close(&m);
                if (errno == ETERM)
                    term = true;
                break;
            }
            more = zmq_msg_more(&m);
            if (n < 8)
                part[n++] = m;
            else
                zmq_msg_close(&m);
        }
        if (term || more) {
            for (int i = 0; i < n; i++)
                zmq_msg_close(&part[i]);
            if (term)
                break;
            continue;
        }
        bool ok = false;
        if (n >= 7 && zmq_msg_size(&part[0]) == 3 && memcmp(zmq_msg_data(&part[0]), "1.0", 3) == 0 &&
            zmq_msg_size(&part[5]) == 5 && memcmp(zmq_msg_data(&part[5]), "CURVE", 5) == 0 &&
            zmq_msg_size(&part[6]) == KEY_BYTES)
            ok = key_allowed(zmq_msg_data(&part[6]));
        if (!ok) {
            A.refused++;
            if (A.refused <= 10 || A.refused % 1000 == 0) {
                char addr[64] = "?";
                if (n >= 4) {
                    size_t k = zmq_msg_size(&part[3]) < sizeof addr - 1 ? zmq_msg_size(&part[3]) : sizeof addr - 1;
                    memcpy(addr, zmq_msg_data(&part[3]), k);
                    addr[k] = '\0';
                }
                fprintf(stderr, "gearsimd: refused a client from %s (key not on the allow-list; %lu refused)\n",
                        addr, A.refused);
            }
        }
        if (n >= 2) {
            zmq_send(A.zap, "1.0", 3, ZMQ_SNDMORE);
            zmq_send(A.zap, zmq_msg_data(&part[1]), zmq_msg_size(&part[1]), ZMQ_SNDMORE);
            zmq_send(A.zap, ok ? "200" : "400", 3, ZMQ_SNDMORE);
            const char *text = ok ? "OK" : "client key not allowed";
            zmq_send(A.zap, text, strlen(text), ZMQ_SNDMORE);
            zmq_send(A.zap, "", 0, ZMQ_SNDMORE);
            zmq_send(A.zap, "", 0, 0);
        }
        for (int i = 0; i < n; i++)
            zmq_msg_close(&part[i]);
    }
    zmq_close(A.zap);
    A.zap = NULL;
    return NULL;
}

int gsi_curve_start(void *zctx)
{
    A.zap = zmq_socket(zctx, ZMQ_REP);
    if (!A.zap)
        return -1;
    int linger = 0;
    zmq_setsockopt(A.zap, ZMQ_LINGER, &linger, sizeof linger);
    if (zmq_bind(A.zap, "inproc://zeromq.zap.01") != 0) {
        zmq_close(A.zap);
        A.zap = NULL;
        return -1;
    }
    if (pthread_create(&A.thread, NULL, zap_thread, NULL) != 0) {
        zmq_close(A.zap);
        A.zap = NULL;
        return -1;
    }
    A.running = true;
    return 0;
}

void gsi_curve_stop(void *zctx)
{
    if (!A.running)
        return;
    zmq_ctx_shutdown(zctx);
    pthread_join(A.thread, NULL);
    A.running = false;
}
