/* SPDX-License-Identifier: MIT
 * Strict JSON (RFC 8259) check by recursive descent. Object keys are
 * unescaped into one arena; when an object closes, its keys (the arena's
 * tail since the object opened) are sorted and compared to find
 * duplicates, then dropped, so the check costs O(n log n) for n keys. */
#include <errno.h>
#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "scene/jsonstrict.h"

typedef struct key_ref {
    size_t off, len; /* in the arena */
    size_t at;       /* byte offset of the key in the text */
} key_ref;

typedef struct frame {
    size_t key_off, key_len; /* member key (arena) when in an object */
    long index;              /* element index when in an array, else -1 */
} frame;

typedef struct parser {
    const unsigned char *s;
    size_t n, i;
    int depth;
    char *arena;
    size_t alen, acap;
    key_ref *keys;
    size_t nkeys, kcap;
    frame stack[GSI_JSON_MAX_DEPTH + 1];
    const char *prefix;
    gs_diag *d;
    bool oom;
} parser;

/* The JSON path of the value being parsed, for the diagnostic. */
static void build_path(parser *p, char *out, size_t cap)
{
    size_t k = (size_t)snprintf(out, cap, "%s", p->prefix ? p->prefix : "");
    for (int l = 1; l <= p->depth && k + 1 < cap; l++) {
        const frame *f = &p->stack[l];
        if (f->index >= 0)
            k += (size_t)snprintf(out + k, cap - k, "[%ld]", f->index);
        else if (f->key_len > 0 || f->key_off != (size_t)-1)
            k += (size_t)snprintf(out + k, cap - k, "%s%.*s", k ? "." : "",
                                  (int)(f->key_len > 64 ? 64 : f->key_len),
                                  f->key_off == (size_t)-1 || !p->arena ? "" : p->arena + f->key_off);
        if (k >= cap)
            k = cap - 1;
    }
}

static gs_err fail(parser *p, const char *fmt, const char *arg)
{
    char path[160], why[200];
    build_path(p, path, sizeof path);
    snprintf(why, sizeof why, fmt, arg ? arg : "");
    return gs_diag_set(p->d, GS_EPARSE, path, "not strict JSON (RFC 8259) at byte %zu: %s", p->i, why);
}

static void skip_ws(parser *p)
{
    while (p->i < p->n && (p->s[p->i] == ' ' || p->s[p->i] == '\t' || p->s[p->i] == '\n' || p->s[p->i] == '\r'))
        p->i++;
}

static bool arena_put(parser *p, const void *b, size_t n)
{
    if (p->alen + n > p->acap) {
        size_t cap = p->acap ? 2 * p->acap : 256;
        while (cap < p->alen + n)
            cap *= 2;
        char *a = realloc(p->arena, cap);
        if (!a) {
            p->oom = true;
            return false;
        }
        p->arena = a;
        p->acap = cap;
    }
    memcpy(p->arena + p->alen, b, n);
    p->alen += n;
    return true;
}

static int hexval(unsigned c)
{
    if (c >= '0' && c <= '9')
        return (int)(c - '0');
    if (c >= 'a' && c <= 'f')
        return (int)(c - 'a' + 10);
    if (c >= 'A' && c <= 'F')
        return (int)(c - 'A' + 10);
    return -1;
}

/* Four hex digits after "\u" at p->i; -1 when malformed. */
static long hex4(parser *p)
{
    if (p->i + 4 > p->n)
        return -1;
    long v = 0;
    for (int k = 0; k < 4; k++) {
        int h = hexval(p->s[p->i + (size_t)k]);
        if (h < 0)
            return -1;
        v = v << 4 | h;
    }
    p->i += 4;
    return v;
}

static void put_utf8(parser *p, unsigned long cp)
{
    unsigned char b[4];
    size_t n;
    if (cp < 0x80)
        b[0] = (unsigned char)cp, n = 1;
    else if (cp < 0x800)
        b[0] = (unsigned char)(0xC0 | cp >> 6), b[1] = (unsigned char)(0x80 | (cp & 0x3F)), n = 2;
    else if (cp < 0x10000)
        b[0] = (unsigned char)(0xE0 | cp >> 12), b[1] = (unsigned char)(0x80 | (cp >> 6 & 0x3F)),
        b[2] = (unsigned char)(0x80 | (cp & 0x3F)), n = 3;
    else
        b[0] = (unsigned char)(0xF0 | cp >> 18), b[1] = (unsigned char)(0x80 | (cp >> 12 & 0x3F)),
        b[2] = (unsigned char)(0x80 | (cp >> 6 & 0x3F)), b[3] = (unsigned char)(0x80 | (cp & 0x3F)), n = 4;
    arena_put(p, b, n);
}

/* One UTF-8 sequence at p->i (first byte >= 0x80); its length or 0. */
static size_t utf8_len(parser *p)
{
    unsigned c = p->s[p->i];
    size_t k;
    unsigned long min, cp;
    if ((c & 0xE0) == 0xC0)
        k = 1, min = 0x80, cp = c & 0x1F;
    else if ((c & 0xF0) == 0xE0)
        k = 2, min = 0x800, cp = c & 0x0F;
    else if ((c & 0xF8) == 0xF0)
        k = 3, min = 0x10000, cp = c & 0x07;
    else
        return 0;
    if (p->i + k >= p->n)
        return 0;
    for (size_t j = 1; j <= k; j++) {
        if ((p->s[p->i + j] & 0xC0) != 0x80)
            return 0;
        cp = cp << 6 | (p->s[p->i + j] & 0x3F);
    }
    if (cp < min || cp > 0x10FFFF || (cp >= 0xD800 && cp <= 0xDFFF))
        return 0;
    return k + 1;
}

/* A string at p->i (the opening quote). With `key`, its unescaped bytes
 * are appended to the arena. */
static gs_err string(parser *p, bool key)
{
    p->i++;
    for (;;) {
        if (p->i >= p->n)
            return fail(p, "unterminated string%s", NULL);
        unsigned c = p->s[p->i];
        if (c == '"') {
            p->i++;
            return GS_OK;
        }
        if (c < 0x20) {
            char hex[8];
            snprintf(hex, sizeof hex, "%02X", c);
            return fail(p, c == 0 ? "NUL byte in a string%s" : "raw control character 0x%s in a string "
                                                               "(escape it)", c == 0 ? NULL : hex);
        }
        if (c == '\\') {
            p->i++;
            if (p->i >= p->n)
                return fail(p, "unterminated string%s", NULL);
            unsigned e = p->s[p->i++];
            static const char simple[] = "\"\\/bfnrt", real[] = "\"\\/\b\f\n\r\t";
            const char *at = e ? strchr(simple, (int)e) : NULL;
            if (at) {
                if (key)
                    arena_put(p, &real[at - simple], 1);
                continue;
            }
            if (e != 'u') {
                p->i--;
                return fail(p, "invalid escape in a string%s", NULL);
            }
            long u = hex4(p);
            if (u < 0)
                return fail(p, "\\u needs four hex digits%s", NULL);
            if (u == 0)
                return fail(p, "\\u0000 (NUL) in a string is refused%s", NULL);
            unsigned long cp = (unsigned long)u;
            if (u >= 0xDC00 && u <= 0xDFFF)
                return fail(p, "lone low surrogate escape (\\uDC00-\\uDFFF without a high one before it)%s", NULL);
            if (u >= 0xD800 && u <= 0xDBFF) {
                long lo = -1;
                if (p->i + 1 < p->n && p->s[p->i] == '\\' && p->s[p->i + 1] == 'u') {
                    p->i += 2;
                    lo = hex4(p);
                }
                if (lo < 0xDC00 || lo > 0xDFFF)
                    return fail(p, "lone high surrogate escape (\\uD800-\\uDBFF must be followed by "
                                   "\\uDC00-\\uDFFF)%s", NULL);
                cp = 0x10000 + (((unsigned long)u - 0xD800) << 10) + ((unsigned long)lo - 0xDC00);
            }
            if (key)
                put_utf8(p, cp);
            continue;
        }
        if (c < 0x80) {
            if (key)
                arena_put(p, &p->s[p->i], 1);
            p->i++;
            continue;
        }
        size_t k = utf8_len(p);
        if (!k)
            return fail(p, "invalid UTF-8 in a string%s", NULL);
        if (key)
            arena_put(p, &p->s[p->i], k);
        p->i += k;
    }
}

static bool is_digit(parser *p, size_t i) { return i < p->n && p->s[i] >= '0' && p->s[i] <= '9'; }

static gs_err number(parser *p)
{
    size_t start = p->i;
    if (p->s[p->i] == '-')
        p->i++;
    if (!is_digit(p, p->i)) {
        if (p->i < p->n && (p->s[p->i] == 'I' || p->s[p->i] == 'N'))
            return fail(p, "NaN and Infinity are not JSON numbers%s", NULL);
        return fail(p, "a number needs a digit here%s", NULL);
    }
    if (p->s[p->i] == '0' && is_digit(p, p->i + 1))
        return fail(p, "leading zeros are not allowed in numbers%s", NULL);
    while (is_digit(p, p->i))
        p->i++;
    if (p->i < p->n && p->s[p->i] == '.') {
        p->i++;
        if (!is_digit(p, p->i))
            return fail(p, "a digit must follow the decimal point%s", NULL);
        while (is_digit(p, p->i))
            p->i++;
    }
    if (p->i < p->n && (p->s[p->i] == 'e' || p->s[p->i] == 'E')) {
        p->i++;
        if (p->i < p->n && (p->s[p->i] == '+' || p->s[p->i] == '-'))
            p->i++;
        if (!is_digit(p, p->i))
            return fail(p, "a digit must follow the exponent mark%s", NULL);
        while (is_digit(p, p->i))
            p->i++;
    }
    /* The value must fit a double (json-c would make it infinite). */
    size_t len = p->i - start;
    char small[128], *buf = len < sizeof small ? small : malloc(len + 1);
    if (!buf) {
        p->oom = true;
        return GS_ENOMEM;
    }
    memcpy(buf, p->s + start, len);
    buf[len] = '\0';
    errno = 0;
    double v = strtod(buf, NULL);
    bool over = errno == ERANGE && isinf(v);
    if (buf != small)
        free(buf);
    if (over) {
        size_t here = p->i;
        p->i = start;
        fail(p, "number out of the range of a double%s", NULL);
        p->i = here;
        return GS_ERANGE; /* a value out of range, like other range errors */
    }
    return GS_OK;
}

static gs_err literal(parser *p, const char *word)
{
    size_t n = strlen(word);
    if (p->i + n <= p->n && memcmp(p->s + p->i, word, n) == 0) {
        p->i += n;
        return GS_OK;
    }
    return fail(p, "invalid literal (expected '%s')", word);
}

static int cmp_key(const parser *p, const key_ref *a, const key_ref *b)
{
    size_t m = a->len < b->len ? a->len : b->len;
    int c = memcmp(p->arena + a->off, p->arena + b->off, m);
    return c ? c : (a->len > b->len) - (a->len < b->len);
}

/* Shell sort of keys[lo..hi) by their bytes (qsort has no context pointer). */
static void sort_keys(parser *p, size_t lo, size_t hi)
{
    size_t n = hi - lo, gap = 1;
    while (gap < n / 3)
        gap = 3 * gap + 1;
    for (; gap > 0; gap /= 3)
        for (size_t i = lo + gap; i < hi; i++) {
            key_ref t = p->keys[i];
            size_t j = i;
            while (j >= lo + gap && cmp_key(p, &p->keys[j - gap], &t) > 0) {
                p->keys[j] = p->keys[j - gap];
                j -= gap;
            }
            p->keys[j] = t;
        }
}

static gs_err value(parser *p);

static gs_err unexpected(parser *p, const char *what)
{
    if (p->i >= p->n)
        return fail(p, "the text ends where %s is expected", what);
    unsigned c = p->s[p->i];
    if (c == '/')
        return fail(p, "comments are not JSON%s", NULL);
    if (c == '\'')
        return fail(p, "single quotes are not JSON (strings use \")%s", NULL);
    if (c == 'N' || c == 'I')
        return fail(p, "NaN and Infinity are not JSON numbers%s", NULL);
    if (c == 0)
        return fail(p, "NUL byte where %s is expected", what);
    return fail(p, "unexpected character where %s is expected", what);
}

static gs_err object(parser *p)
{
    p->i++;
    size_t first = p->nkeys, arena0 = p->alen;
    frame *f = &p->stack[p->depth];
    f->index = -1;
    skip_ws(p);
    if (p->i < p->n && p->s[p->i] == '}') {
        p->i++;
        return GS_OK;
    }
    for (;;) {
        skip_ws(p);
        if (p->i >= p->n || p->s[p->i] != '"') {
            if (p->i < p->n && p->s[p->i] == '}' && p->nkeys > first)
                return fail(p, "trailing comma before '}'%s", NULL);
            return unexpected(p, "a key (a string in double quotes)");
        }
        size_t at = p->i, off = p->alen;
        f->key_off = (size_t)-1;
        f->key_len = 0;
        GS_TRY(string(p, true));
        if (p->oom)
            return GS_ENOMEM;
        f->key_off = off;
        f->key_len = p->alen - off;
        if (p->nkeys == p->kcap) {
            size_t cap = p->kcap ? 2 * p->kcap : 64;
            key_ref *k = realloc(p->keys, cap * sizeof *k);
            if (!k)
                return GS_ENOMEM;
            p->keys = k;
            p->kcap = cap;
        }
        p->keys[p->nkeys++] = (key_ref){off, p->alen - off, at};
        skip_ws(p);
        if (p->i >= p->n || p->s[p->i] != ':')
            return unexpected(p, "':'");
        p->i++;
        GS_TRY(value(p));
        skip_ws(p);
        if (p->i < p->n && p->s[p->i] == ',') {
            p->i++;
            continue;
        }
        if (p->i < p->n && p->s[p->i] == '}')
            break;
        return unexpected(p, "',' or '}'");
    }
    size_t end = p->i + 1;
    sort_keys(p, first, p->nkeys);
    for (size_t k = first + 1; k < p->nkeys; k++)
        if (cmp_key(p, &p->keys[k - 1], &p->keys[k]) == 0) {
            key_ref *a = &p->keys[k - 1], *b = &p->keys[k];
            p->i = a->at > b->at ? a->at : b->at;
            f->key_off = a->off;
            f->key_len = a->len;
            char name[80];
            snprintf(name, sizeof name, "%.*s", (int)(a->len > 64 ? 64 : a->len), p->arena + a->off);
            return fail(p, "duplicate key '%s' (each key may appear once)", name);
        }
    p->nkeys = first;
    p->alen = arena0;
    p->i = end;
    return GS_OK;
}

static gs_err array(parser *p)
{
    p->i++;
    frame *f = &p->stack[p->depth];
    f->index = 0;
    skip_ws(p);
    if (p->i < p->n && p->s[p->i] == ']') {
        p->i++;
        return GS_OK;
    }
    for (;;) {
        skip_ws(p);
        if (p->i < p->n && p->s[p->i] == ']' && f->index > 0)
            return fail(p, "trailing comma before ']'%s", NULL);
        GS_TRY(value(p));
        skip_ws(p);
        if (p->i < p->n && p->s[p->i] == ',') {
            p->i++;
            f->index++;
            continue;
        }
        if (p->i < p->n && p->s[p->i] == ']') {
            p->i++;
            return GS_OK;
        }
        return unexpected(p, "',' or ']'");
    }
}

static gs_err value(parser *p)
{
    skip_ws(p);
    if (p->i >= p->n)
        return unexpected(p, "a value");
    unsigned c = p->s[p->i];
    if (c == '{' || c == '[') {
        if (p->depth >= GSI_JSON_MAX_DEPTH)
            return fail(p, "nesting deeper than 64 arrays/objects%s", NULL);
        p->depth++;
        p->stack[p->depth] = (frame){(size_t)-1, 0, -1};
        gs_err e = c == '{' ? object(p) : array(p);
        if (e == GS_OK)
            p->depth--;
        return e;
    }
    if (c == '"')
        return string(p, false);
    if (c == '-' || (c >= '0' && c <= '9'))
        return number(p);
    if (c == 't')
        return literal(p, "true");
    if (c == 'f')
        return literal(p, "false");
    if (c == 'n')
        return literal(p, "null");
    return unexpected(p, "a value");
}

gs_err gsi_json_strict(const char *text, size_t len, const char *prefix, gs_diag *d)
{
    parser p = {.s = (const unsigned char *)text, .n = len, .prefix = prefix, .d = d};
    p.stack[0] = (frame){(size_t)-1, 0, -1};
    gs_err e = value(&p);
    if (e == GS_OK) {
        skip_ws(&p);
        if (p.i < p.n) {
            p.depth = 0;
            e = fail(&p, "trailing characters after the JSON value%s", NULL);
        }
    }
    if (p.oom)
        e = gs_diag_set(d, GS_ENOMEM, "", "out of memory while checking the JSON text");
    free(p.arena);
    free(p.keys);
    return e;
}
