/* SPDX-License-Identifier: MIT
 * gs_fmt_double: every text reads back (strtod) as the identical double,
 * has no digit more than needed, and is a JSON float. */
#include <setjmp.h>
#include <stdarg.h>
#include <stddef.h>
#include <stdint.h>
#include <cmocka.h>
#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "gearsim/numfmt.h"

static uint64_t rng = 0x9e3779b97f4a7c15ull;
static uint64_t next(void)
{
    rng ^= rng << 13, rng ^= rng >> 7, rng ^= rng << 17;
    return rng;
}

static double from_bits(uint64_t b)
{
    double x;
    memcpy(&x, &b, sizeof x);
    return x;
}

static uint64_t bits(double x)
{
    uint64_t b;
    memcpy(&b, &x, sizeof b);
    return b;
}

/* Significant digits of a formatted text. */
static int sig_digits(const char *t)
{
    int n = 0, lead = 1, z = 0;
    for (; *t && *t != 'e'; t++) {
        if (*t < '0' || *t > '9')
            continue;
        if (lead && *t == '0')
            continue;
        lead = 0;
        n++;
        z = *t == '0' ? z + 1 : 0;
    }
    return n - z;
}

static long n_checked, n_short_checked;

/* x's text: reads back bit for bit, JSON float form, and (when `shortest`)
 * no correctly rounded text with one digit fewer reads back as x. */
static void check(double x, int shortest)
{
    char buf[GS_FMT_DOUBLE_MAX + 8];
    memset(buf, 'Z', sizeof buf);
    int len = gs_fmt_double(buf, x);
    assert_true(len > 0 && len < GS_FMT_DOUBLE_MAX);
    assert_int_equal((int)strlen(buf), len);
    if (!isfinite(x)) {
        assert_string_equal(buf, "null");
        return;
    }
    char *end;
    double y = strtod(buf, &end);
    if (*end || bits(y) != bits(x))
        fail_msg("%.17g (bits %016llx) wrote '%s', read back %.17g", x, (unsigned long long)bits(x), buf, y);
    assert_true(strchr(buf, '.') || strchr(buf, 'e'));
    n_checked++;
    if (shortest && x != 0.0) {
        int n = sig_digits(buf);
        assert_true(n >= 1 && n <= 17);
        if (n > 1) {
            char t[40];
            snprintf(t, sizeof t, "%.*e", n - 2, x);
            if (strtod(t, NULL) == x)
                fail_msg("%.17g wrote '%s' (%d digits) but '%s' reads back too", x, buf, n, t);
        }
        n_short_checked++;
    }
}

static void edge_values(void **state)
{
    (void)state;
    const double v[] = {0.0, -0.0, 1.0, -1.0, 2.0, 3.0, 0.1, 0.2, 0.3, 1.0 / 3.0, 2.0 / 3.0, 1e-5, 1e-4,
                        9.9999999999999995e-5, 1e16, 1e17, 1e21, 1e22, 1e23, 123456789012345678.0,
                        5e-324, -5e-324, DBL_MIN, DBL_MAX, -DBL_MAX, DBL_EPSILON, 1.0 + DBL_EPSILON,
                        1.0 - DBL_EPSILON / 2, 9007199254740993.0, 4.35, 0.30000000000000004, M_PI,
                        2.2250738585072009e-308, 1.7976931348623157e308, 4.9406564584124654e-324,
                        100.0, 1e100, 1e-100, 299792458.0, 6.02214076e23, 1.602176634e-19};
    for (size_t i = 0; i < sizeof v / sizeof v[0]; i++) {
        check(v[i], 1);
        check(-v[i], 1);
    }
    char b[GS_FMT_DOUBLE_MAX];
    gs_fmt_double(b, 0.0), assert_string_equal(b, "0.0");
    gs_fmt_double(b, -0.0), assert_string_equal(b, "-0.0");
    gs_fmt_double(b, 3.0), assert_string_equal(b, "3.0");
    gs_fmt_double(b, 0.1), assert_string_equal(b, "0.1");
    gs_fmt_double(b, 1e-5), assert_string_equal(b, "1e-05");
    gs_fmt_double(b, 1e-4), assert_string_equal(b, "0.0001");
    gs_fmt_double(b, 1e17), assert_string_equal(b, "1e+17");
    gs_fmt_double(b, 1e16), assert_string_equal(b, "10000000000000000.0");
    gs_fmt_double(b, -1.5e-300), assert_string_equal(b, "-1.5e-300");
    gs_fmt_double(b, 5e-324), assert_string_equal(b, "5e-324");
    gs_fmt_double(b, NAN), assert_string_equal(b, "null");
    gs_fmt_double(b, -INFINITY), assert_string_equal(b, "null");
}

/* Every power of two and of ten and their neighbours one ulp away. */
static void powers_and_neighbours(void **state)
{
    (void)state;
    for (int e = -1074; e <= 1023; e++) {
        double x = ldexp(1.0, e);
        check(x, 1), check(nextafter(x, 0.0), 1), check(nextafter(x, INFINITY), 1);
    }
    /* The integer powers of two below 2^53 (their own fast path): the
     * integer's digits and ".0", as printf writes the integer. */
    for (int e = 0; e < 53; e++) {
        char b[GS_FMT_DOUBLE_MAX], t[40];
        double x = ldexp(1.0, e);
        snprintf(t, sizeof t, "%.0f.0", x);
        gs_fmt_double(b, x), assert_string_equal(b, t);
        snprintf(t, sizeof t, "-%.0f.0", x);
        gs_fmt_double(b, -x), assert_string_equal(b, t);
    }
    for (int e = -323; e <= 308; e++) {
        char t[16];
        snprintf(t, sizeof t, "1e%d", e);
        double x = strtod(t, NULL);
        check(x, 1), check(nextafter(x, 0.0), 1), check(nextafter(x, INFINITY), 1);
    }
}

/* Random bit patterns (every exponent, subnormals, NaN and infinities). */
static void random_bits(void **state)
{
    (void)state;
    for (long i = 0; i < 1000000; i++)
        check(from_bits(next()), i % 16 == 0);
}

/* Random values in the ranges telemetry carries, and short decimals. */
static void random_values(void **state)
{
    (void)state;
    for (long i = 0; i < 1000000; i++) {
        double m = (double)(next() >> 11) * 0x1p-53;
        int e = (int)(next() % 41) - 25;
        check(m * pow(10.0, e) * ((next() & 1) ? -1 : 1), i % 16 == 0);
        double d = (double)(next() % 100000) * pow(10.0, (int)(next() % 21) - 12);
        check(d, i % 16 == 0);
    }
    for (int i = -100000; i <= 100000; i++)
        check((double)i, 1), check(i * 0.001, 1);
    print_message("# %ld texts read back bit for bit, %ld checked shortest\n", n_checked, n_short_checked);
}

int main(void)
{
    const struct CMUnitTest tests[] = {
        cmocka_unit_test(edge_values),
        cmocka_unit_test(powers_and_neighbours),
        cmocka_unit_test(random_bits),
        cmocka_unit_test(random_values),
    };
    return cmocka_run_group_tests(tests, NULL, NULL);
}
