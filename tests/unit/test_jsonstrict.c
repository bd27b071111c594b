/* SPDX-License-Identifier: MIT
 * The strict JSON check (src/scene/jsonstrict.c): every RFC 8259 violation
 * that json-c's tokener lets through is refused with a path and a reason;
 * valid texts pass, and json-c's own output of them passes again (round
 * trip), so the check never refuses what the daemon itself writes. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <json-c/json.h>

#include "scene/jsonstrict.h"

typedef struct bad_case {
    const char *text;
    size_t len;          /* 0: strlen(text) */
    const char *field;   /* expected path */
    const char *reason;  /* substring of the message */
} bad_case;

#define T(s) s, sizeof(s) - 1

static const bad_case bad[] = {
    {T("{\"v\":1,\"cmd\":\"status\",\"cmd\":\"shutdown\"}"), "cmd", "duplicate key 'cmd'"},
    {T("{\"a\":{\"x\":1,\"y\":2,\"x\":3}}"), "a.x", "duplicate key 'x'"},
    {T("{\"ab\":1,\"a\\u0062\":2}"), "ab", "duplicate key 'ab'"},
    {T("{\"k\":[1,{\"q\":1,\"q\":1}]}"), "k[1].q", "duplicate key 'q'"},
    {T("{\"id\":\"a\0b\"}"), "id", "NUL byte in a string"},
    {T("{\"id\":\"a\\u0000b\"}"), "id", "\\u0000"},
    {T("{\"id\":\"a\tb\"}"), "id", "raw control character 0x09"},
    {T("{\"id\":\"a\nb\"}"), "id", "raw control character 0x0A"},
    {T("{\"id\":\"\\ud800\"}"), "id", "lone high surrogate"},
    {T("{\"id\":\"\\ud800\\u0041\"}"), "id", "lone high surrogate"},
    {T("{\"id\":\"\\udc00\\ud800\"}"), "id", "lone low surrogate"},
    {T("{\"id\":\"\\x41\"}"), "id", "invalid escape"},
    {T("{\"id\":\"\\u12\"}"), "id", "four hex digits"},
    {T("{\"v\":1 /* c */}"), "v", "comments are not JSON"},
    {T("// c\n{}"), "", "comments are not JSON"},
    {T("{'v':1}"), "", "single quotes"},
    {T("{\"v\":'1'}"), "v", "single quotes"},
    {T("{\"v\":1,}"), "v", "trailing comma before '}'"},
    {T("{\"a\":[1,2,]}"), "a[2]", "trailing comma before ']'"},
    {T("{\"v\":01}"), "v", "leading zeros"},
    {T("{\"v\":-01.5}"), "v", "leading zeros"},
    {T("{\"v\":NaN}"), "v", "NaN and Infinity"},
    {T("{\"v\":-Infinity}"), "v", "NaN and Infinity"},
    {T("{\"v\":Infinity}"), "v", "NaN and Infinity"},
    {T("{\"v\":1e999}"), "v", "out of the range of a double"},
    {T("{\"v\":1.}"), "v", "decimal point"},
    {T("{\"v\":.5}"), "v", "unexpected character"},
    {T("{\"v\":1e}"), "v", "exponent"},
    {T("{\"v\":+1}"), "v", "unexpected character"},
    {T("{\"v\":1}x"), "", "trailing characters"},
    {T("{\"v\":1}{}"), "", "trailing characters"},
    {T("{\"v\":1}\0"), "", "trailing characters"},
    {T("{\"v\":tru}"), "v", "invalid literal"},
    {T("{\"v\":True}"), "v", "unexpected character"},
    {T("{\"v\" 1}"), "v", "':'"},
    {T("{v:1}"), "", "a key"},
    {T("{\"v\":1"), "v", "the text ends"},
    {T("[1 2]"), "[0]", "',' or ']'"},
    {T(""), "", "the text ends"},
    {T("\xef\xbb\xbf{}"), "", "unexpected character"},
    {T("{\"s\":\"\xc0\xaf\"}"), "s", "invalid UTF-8"},
    {T("{\"s\":\"\xed\xa0\x80\"}"), "s", "invalid UTF-8"},
};

static void refuses_each_violation(void **state)
{
    (void)state;
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        gs_diag d;
        gs_diag_clear(&d);
        gs_err e = gsi_json_strict(bad[i].text, bad[i].len, "", &d);
        if (e == GS_OK || strcmp(d.field, bad[i].field) != 0 || !strstr(d.message, bad[i].reason))
            print_error("case %zu: got %d field '%s' message '%s'\n", i, (int)e, d.field, d.message);
        assert_int_equal(e, strstr(bad[i].reason, "range") ? GS_ERANGE : GS_EPARSE);
        assert_string_equal(d.field, bad[i].field);
        assert_non_null(strstr(d.message, bad[i].reason));
        assert_non_null(strstr(d.message, "at byte"));
    }
}

static void prefix_names_the_path(void **state)
{
    (void)state;
    gs_diag d;
    const char *t = "{\"bodies\":[{\"name\":\"a\",\"name\":\"b\"}]}";
    assert_int_equal(gsi_json_strict(t, strlen(t), "args.scene", &d), GS_EPARSE);
    assert_string_equal(d.field, "args.scene.bodies[0].name");
}

/* An error under an empty key that comes before any other key: the path
 * is built before the key store exists (found by the fuzzers: pointer
 * arithmetic on the empty store). */
static void empty_first_key(void **state)
{
    (void)state;
    gs_diag d;
    const char *t[] = {"{\"\":\"lo:\"x", "{\"\":{\"a\":tru}}", "{\n \"\"e:1}"};
    for (size_t i = 0; i < sizeof t / sizeof t[0]; i++) {
        assert_int_equal(gsi_json_strict(t[i], strlen(t[i]), "args", &d), GS_EPARSE);
        assert_true(strncmp(d.field, "args", 4) == 0);
    }
}

static void depth_limit(void **state)
{
    (void)state;
    char buf[300];
    for (int depth = 63; depth <= 66; depth++) {
        int n = 0;
        for (int i = 0; i < depth; i++)
            buf[n++] = '[';
        for (int i = 0; i < depth; i++)
            buf[n++] = ']';
        gs_diag d;
        gs_err e = gsi_json_strict(buf, (size_t)n, "", &d);
        assert_int_equal(e, depth <= GSI_JSON_MAX_DEPTH ? GS_OK : GS_EPARSE);
    }
}

static const char *const good[] = {
    "{\"v\":1,\"id\":\"a\",\"cmd\":\"status\"}",
    "{\"v\":1.0,\"id\":\"x\",\"cmd\":\"hello\",\"args\":{}}",
    " \t\r\n{ \"a\" : [ 1 , -0 , 0.5 , -1.25e-3 , 1E+2 , 2e+30 ] } \n",
    "{\"s\":\"\\\"\\\\\\/\\b\\f\\n\\r\\t \\u00e9 \\ud83d\\ude00 \xc3\xa9 \xf0\x9f\x98\x80\"}",
    "{\"a\":{\"a\":{\"a\":1}},\"b\":{\"a\":2}}",
    "{\"x\":1,\"X\":2,\"x \":3}",
    "[]", "{}", "\"str\"", "0", "-0.0e0", "true", "false", "null",
    "[[[[{\"deep\":[null]}]]]]",
    "{\"big\":1.7976931348623157e308,\"tiny\":4.9e-324,\"under\":1e-999}",
};

static void accepts_valid_and_round_trips(void **state)
{
    (void)state;
    for (size_t i = 0; i < sizeof good / sizeof good[0]; i++) {
        gs_diag d;
        gs_diag_clear(&d);
        gs_err e = gsi_json_strict(good[i], strlen(good[i]), "", &d);
        if (e != GS_OK)
            print_error("good %zu refused: %s: %s\n", i, d.field, d.message);
        assert_int_equal(e, GS_OK);
        if (strcmp(good[i], "null") == 0)
            continue; /* json-c represents it as NULL */
        json_object *o = json_tokener_parse(good[i]);
        assert_non_null(o);
        const char *again = json_object_to_json_string_ext(o, JSON_C_TO_STRING_PLAIN);
        e = gsi_json_strict(again, strlen(again), "", &d);
        if (e != GS_OK)
            print_error("round trip %zu refused: %s: %s (%s)\n", i, d.field, d.message, again);
        json_object *o2 = json_tokener_parse(again);
        assert_non_null(o2);
        assert_true(json_object_equal(o, o2));
        json_object_put(o2);
        json_object_put(o);
    }
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(refuses_each_violation),
        cmocka_unit_test(prefix_names_the_path),
        cmocka_unit_test(empty_first_key),
        cmocka_unit_test(depth_limit),
        cmocka_unit_test(accepts_valid_and_round_trips),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
