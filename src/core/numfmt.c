/* SPDX-License-Identifier: MIT
 * Shortest round-trip decimal text of a double (include/gearsim/numfmt.h).
 *
 * Fast path: x is scaled to 17 digits by a power of ten in 80-bit long
 * double arithmetic (64-bit significand) and the integers in the interval of
 * reals that read back as x (half an ulp either side) are the candidates:
 * the one with the most trailing zeros is the shortest text. Every test
 * carries a bound on the arithmetic's error: a candidate certainly inside is
 * taken, one certainly outside is passed over, and an undecided one (within
 * the error of an end, where ties to even decide), a significand at a power
 * of two (its interval is lopsided), a subnormal or an exponent beyond
 * 10^+-37 go to the slow path: printf's correctly rounded %.*e at 1..17 digits, each
 * read back by strtod. Either way the text reads back as x. */
#include "gearsim/numfmt.h"

#include <float.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* 10^0 .. 10^27 are exact in the 64-bit significand (5^27 < 2^64). */
static const long double pow10x[28] = {
    1e0L,  1e1L,  1e2L,  1e3L,  1e4L,  1e5L,  1e6L,  1e7L,  1e8L,  1e9L,  1e10L, 1e11L, 1e12L, 1e13L,
    1e14L, 1e15L, 1e16L, 1e17L, 1e18L, 1e19L, 1e20L, 1e21L, 1e22L, 1e23L, 1e24L, 1e25L, 1e26L, 1e27L};

/* v * 10^p with at most two roundings (|p| <= 54), or 0 out of range. */
static long double scale10(long double v, int p)
{
    if (p >= 0) {
        if (p > 54)
            return 0.0L;
        return p > 27 ? v * pow10x[27] * pow10x[p - 27] : v * pow10x[p];
    }
    p = -p;
    if (p > 54)
        return 0.0L;
    return p > 27 ? v / pow10x[27] / pow10x[p - 27] : v / pow10x[p];
}

/* Lay out digits d[0..n) (no trailing zeros, d[0] != '0') with decimal
 * exponent k (x = d.ddd * 10^k) as %g would, keeping a float's ".0". */
static int layout(char *buf, int neg, const char *d, int n, int k)
{
    char *p = buf;
    if (neg)
        *p++ = '-';
    if (k < -4 || k >= 17) {
        *p++ = d[0];
        if (n > 1) {
            *p++ = '.';
            memcpy(p, d + 1, (size_t)(n - 1));
            p += n - 1;
        }
        *p++ = 'e';
        *p++ = k < 0 ? '-' : '+';
        int e = k < 0 ? -k : k;
        if (e >= 100)
            *p++ = (char)('0' + e / 100);
        *p++ = (char)('0' + e / 10 % 10);
        *p++ = (char)('0' + e % 10);
    } else if (k >= 0) {
        for (int i = 0; i <= k; i++)
            *p++ = i < n ? d[i] : '0';
        *p++ = '.';
        if (n > k + 1) {
            memcpy(p, d + k + 1, (size_t)(n - k - 1));
            p += n - k - 1;
        } else {
            *p++ = '0';
        }
    } else {
        *p++ = '0';
        *p++ = '.';
        for (int i = 0; i < -k - 1; i++)
            *p++ = '0';
        memcpy(p, d, (size_t)n);
        p += n;
    }
    *p = '\0';
    return (int)(p - buf);
}

/* The exact slow path: the fewest digits whose correctly rounded text
 * strtod reads back as x. */
static int slow(char *buf, double x)
{
    char t[40];
    int n = 17;
    for (int i = 1; i <= 17; i++) {
        snprintf(t, sizeof t, "%.*e", i - 1, x);
        if (strtod(t, NULL) == x) {
            n = i;
            break;
        }
    }
    snprintf(t, sizeof t, "%.*e", n - 1, x);
    /* t: [-]d[.ddd]e[+-]XX */
    const char *s = t;
    int neg = *s == '-';
    s += neg;
    char d[20];
    int nd = 0;
    for (; *s && *s != 'e'; s++)
        if (*s != '.')
            d[nd++] = *s;
    int k = atoi(s + 1);
    while (nd > 1 && d[nd - 1] == '0')
        nd--;
    return layout(buf, neg, d, nd, k);
}

/* The integer c (17 or 18 digits: c = 1e17 when S rounded up) times
 * 10^(k-16). */
static int layout_int(char *buf, int neg, uint64_t c, int k)
{
    char r[24], d[24];
    int nd = 0;
    for (; c; c /= 10)
        r[nd++] = (char)('0' + c % 10);
    for (int i = 0; i < nd; i++)
        d[i] = r[nd - 1 - i];
    int kk = k + (nd - 17);
    while (nd > 1 && d[nd - 1] == '0')
        nd--;
    return layout(buf, neg, d, nd, kk);
}

int gs_fmt_double(char *buf, double x)
{
    if (!isfinite(x)) {
        memcpy(buf, "null", 5);
        return 4;
    }
    int neg = signbit(x) != 0;
    double a = fabs(x);
    if (a == 0.0) {
        memcpy(buf, neg ? "-0.0" : "0.0", neg ? 5 : 4);
        return neg ? 4 : 3;
    }
    uint64_t ab;
    memcpy(&ab, &a, sizeof ab);
    int e2 = (int)(ab >> 52) - 1022; /* a = f 2^e2, f in [0.5, 1) */
    if ((ab & 0xfffffffffffffull) == 0 && a >= 1.0 && a < 0x1p53) {
        /* An integer power of two (a planet's load share of 1, say): its
         * ulp is at most 1, so no text with fewer digits than its own
         * integer digits reads back as it; those digits are the shortest,
         * as the slow path finds them. */
        char r[20], d[20];
        int nd = 0;
        for (uint64_t c = (uint64_t)a; c; c /= 10)
            r[nd++] = (char)('0' + c % 10);
        for (int i = 0; i < nd; i++)
            d[i] = r[nd - 1 - i];
        int kk = nd - 1;
        while (nd > 1 && d[nd - 1] == '0')
            nd--;
        return layout(buf, neg, d, nd, kk);
    }
    if ((ab & 0xfffffffffffffull) == 0 || a < DBL_MIN)
        return slow(buf, x); /* lopsided interval; subnormal */
    /* Decimal exponent k (10^k <= a < 10^(k+1)) and a scaled to 17 digits,
     * S = a 10^(16-k) in [1e16, 1e17), with H, half an ulp of a, alike: the
     * reals that read back as a are S +- H (open) in units of the 17th
     * digit. At most three roundings of 2^-64 each: err bounds them. */
    int k = ((e2 - 1) * 78913) >> 18; /* about (e2 - 1) log10(2), floored */
    if (k > 37 || k < -37)
        return slow(buf, x);
    /* Half an ulp, 2^(e2-54), written as a double's bits (|k| <= 37 keeps
     * it a normal double): exact, and no libm call. */
    uint64_t hb = (uint64_t)(e2 - 54 + 1023) << 52;
    double hd;
    memcpy(&hd, &hb, sizeof hd);
    long double half = hd;
    long double S = scale10((long double)a, 16 - k), H = scale10(half, 16 - k);
    if (S >= 1e17L)
        k++, S /= 10.0L, H /= 10.0L;
    else if (S < 1e16L)
        k--, S *= 10.0L, H *= 10.0L;
    if (S < 1e16L || S >= 1e17L)
        return slow(buf, x);
    const long double err = (S + H) * (2.0L * LDBL_EPSILON);
    /* The nearest integer: 17 digits, |c - S| <= 1/2 < H - err always
     * (H > 1e16 2^-54 > 0.555). A multiple of 10^t in the interval has t
     * fewer digits: the most trailing zeros wins, the nearer on a tie; a
     * multiple of 10 within err of the interval's ends goes the slow way. */
    uint64_t best = (uint64_t)(S + 0.5L); /* exact sum: S's ulp is 2^-7 */
    long double bestd = fabsl((long double)best - S);
    int besttz = 0;
    for (uint64_t c = best; c % 10 == 0 && besttz < 18; c /= 10)
        besttz++;
    uint64_t m = ((uint64_t)(S - H - err) + 9) / 10 * 10;
    uint64_t top = (uint64_t)(S + H + err);
    for (; m <= top; m += 10) {
        long double dist = fabsl((long double)m - S);
        if (dist + err >= H) {
            if (dist - err <= H)
                return slow(buf, x); /* at an end: ties to even decide */
            continue;
        }
        int tz = 0;
        for (uint64_t c = m; c % 10 == 0 && tz < 18; c /= 10)
            tz++;
        if (tz > besttz || (tz == besttz && dist < bestd))
            best = m, bestd = dist, besttz = tz;
    }
    return layout_int(buf, neg, best, k);
}
