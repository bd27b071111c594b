/* SPDX-License-Identifier: MIT
 * Every error code has a distinct wire string and a message. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <string.h>

#include "gearsim/error.h"

static void every_code_has_strings(void **state)
{
    (void)state;
    for (int i = 0; i < GS_ERR_COUNT; i++) {
        assert_non_null(gs_strerror((gs_err)i));
        assert_true(strlen(gs_strerror((gs_err)i)) > 0);
        assert_true(strlen(gs_errcode((gs_err)i)) > 0);
        for (int j = 0; j < i; j++)
            assert_string_not_equal(gs_errcode((gs_err)i), gs_errcode((gs_err)j));
    }
    assert_string_equal(gs_strerror((gs_err)999), "unknown error");
}

static void diag_names_field(void **state)
{
    (void)state;
    gs_diag d;
    gs_err e = gs_diag_set(&d, GS_ERANGE, "bodies[1].teeth", "must be at least %d", 6);
    assert_int_equal(e, GS_ERANGE);
    assert_string_equal(d.field, "bodies[1].teeth");
    assert_string_equal(d.message, "must be at least 6");
    assert_int_equal(gs_diag_set(NULL, GS_EIO, "x", "y"), GS_EIO);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(every_code_has_strings),
        cmocka_unit_test(diag_names_field),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
