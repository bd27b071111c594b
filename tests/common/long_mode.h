/* SPDX-License-Identifier: MIT
 * The suite's long mode (GEARSIM_LONG=1, the benchmark machine's runs) for
 * cmocka tests with a default group and a long one. Include after cmocka.h. */
#ifndef GEARSIM_TEST_LONG_MODE_H
#define GEARSIM_TEST_LONG_MODE_H

#include <stdlib.h>
#include <string.h>

static inline int run_groups_long(const struct CMUnitTest *tests, size_t n, const struct CMUnitTest *long_tests,
                                  size_t n_long)
{
    const char *lg = getenv("GEARSIM_LONG");
    int rc = _cmocka_run_group_tests("tests", tests, n, NULL, NULL);
    if (lg && strcmp(lg, "1") == 0)
        rc |= _cmocka_run_group_tests("long_tests", long_tests, n_long, NULL, NULL);
    return rc;
}

/* The default group, then the long one in long mode. */
#define RUN_GROUPS_LONG(tests, long_tests)                                                                        \
    run_groups_long(tests, sizeof(tests) / sizeof((tests)[0]), long_tests, sizeof(long_tests) / sizeof((long_tests)[0]))

#endif
