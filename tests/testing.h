/* SPDX-License-Identifier: BSD-3-Clause */
/* A small test harness: CHECK macros that count and report, one temp folder
 * per test program, and the shared-data path with a clean skip when absent.
 * Each test program ends with `return sl_test_finish();`, which prints
 * "N passed, N failed" and returns the exit status. */
#ifndef SETLIGHT_TESTING_H
#define SETLIGHT_TESTING_H

#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

#include "setlight/core.h"

extern int sl_test_passed;
extern int sl_test_failed;
extern int sl_test_skipped;

void sl_test_fail(const char *file, int line, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));

#define CHECK(cond)                                                                        \
    do {                                                                                   \
        if (cond)                                                                          \
            sl_test_passed++;                                                              \
        else                                                                               \
            sl_test_fail(__FILE__, __LINE__, "CHECK(%s)", #cond);                          \
    } while (0)

#define CHECK_MSG(cond, ...)                                                               \
    do {                                                                                   \
        if (cond)                                                                          \
            sl_test_passed++;                                                              \
        else                                                                               \
            sl_test_fail(__FILE__, __LINE__, __VA_ARGS__);                                 \
    } while (0)

/* |a - b| <= tol, and neither is NaN. */
#define CHECK_NEAR(a, b, tol)                                                              \
    do {                                                                                   \
        double _a = (double)(a), _b = (double)(b), _t = (double)(tol);                     \
        if (fabs(_a - _b) <= _t)                                                           \
            sl_test_passed++;                                                              \
        else                                                                               \
            sl_test_fail(__FILE__, __LINE__, "CHECK_NEAR(%s, %s, %s): %.10g vs %.10g (diff %.3g)", \
                         #a, #b, #tol, _a, _b, fabs(_a - _b));                             \
    } while (0)

/* result == expected; prints the error message on failure. */
#define CHECK_RESULT(expr, expected, errp)                                                 \
    do {                                                                                   \
        sl_result _r = (expr);                                                             \
        if (_r == (expected))                                                              \
            sl_test_passed++;                                                              \
        else                                                                               \
            sl_test_fail(__FILE__, __LINE__, "%s returned %s, expected %s: %s", #expr,    \
                         sl_result_name(_r), sl_result_name(expected),                     \
                         sl_test_errmsg(errp));                                            \
    } while (0)

#define CHECK_OK(expr, errp) CHECK_RESULT(expr, SL_OK, errp)

const char *sl_test_errmsg(const sl_error *err);

/* Runs a test function and prints its name. */
#define RUN(fn)                                                                            \
    do {                                                                                   \
        int _f = sl_test_failed;                                                           \
        fn();                                                                              \
        printf("%s %s\n", sl_test_failed == _f ? "ok  " : "FAIL", #fn);                    \
        fflush(stdout);                                                                    \
    } while (0)

/* A fresh folder for this test program (removed and remade at first call). */
const char *sl_test_tmpdir(void);
/* tmpdir + "/" + name, in a static rotating buffer. */
const char *sl_test_path(const char *name);
/* Path under ../shared/data, or NULL (and a "skip" line) when absent. */
const char *sl_test_data(const char *relative);
void sl_test_skip(const char *what);
/* Built with AddressSanitizer or run with SETLIGHT_SANITIZED set (not "0"):
 * tests then use smaller sizes (same assertions) or skip what is too slow. */
bool sl_test_sanitized(void);
bool sl_test_file_exists(const char *path);
/* Number of entries in a folder other than . and .. (-1 if it cannot be read). */
int sl_test_count_files(const char *dir);
/* The whole file, NUL-terminated (for text), malloc'd; size may be NULL.
 * NULL when it cannot be read. */
char *sl_test_read_file(const char *path, size_t *size);
/* Whether two sl_meta hold the same (every field and attribute, in order);
 * prints both, labelled by `name`, when not (native readers vs OIIO). */
bool sl_test_same_meta(const char *name, const sl_meta *native, const sl_meta *oiio);
/* Pearson chi-square p-value of observed counts against expected counts
 * (same total), pooling neighbouring bins until each pooled bin expects at
 * least 5; *dof gets the degrees of freedom. A count in a bin that expects
 * nothing is an outright failure (p = 0). */
double sl_test_chi2(const double *obs, const double *expct, int n, int *dof);
/* splitmix64 (core.h) on a caller's state: the same numbers on every platform. */
uint64_t sl_test_rand(uint64_t *state);
/* Uniform in [0, 1) with 53 bits. */
double sl_test_uniform(uint64_t *state);
/* Fisher-Yates shuffle of n ints. */
void sl_test_shuffle(int *a, int n, uint64_t *state);
/* The median of v[0 .. n-1] (the upper one for even n), sorting v in place; NaN when n is 0. */
double sl_test_median(double *v, size_t n);
int sl_test_finish(void);

/* The end of a make_fixture kind: unless r already failed, img written to
 * OUT as an sRGB 8-bit photo (jpeg) or a float Rec.709 EXR; img and meta
 * freed; a failure printed as "make_fixture: ...". Returns the exit code. */
int sl_test_fixture_write(const char *out, sl_image *img, sl_meta *meta, bool jpeg, sl_result r,
                          sl_error *err);

#endif
