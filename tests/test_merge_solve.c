/* SPDX-License-Identifier: BSD-3-Clause */
/* The Debevec-Malik fit's own Cholesky (merge_cholesky_solve) against
 * OpenCV's solvers (cv::solve with DECOMP_CHOLESKY, LU, SVD) on the systems
 * the fit really builds (256 nodes; samples of a synthetic 7x3 JPEG
 * bracket, and of the real stack_room and memorial brackets when the shared
 * data is there): the same solution, the residual and the time of each,
 * printed (docs/merge.md quotes these lines). A matrix that is not positive
 * definite is refused. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../stitch/merge_private.h" /* merge_cholesky_solve, merge_fit_system_hook */
#include "merge_fixture.h"
#include "testing.h"

enum { MAX_SYSTEMS = 4, NODES = 256, REPEATS = 21 };

static double *captured_a[MAX_SYSTEMS], *captured_b[MAX_SYSTEMS];
static int captured, captured_n;

/* Keeps the first round's system of a fit (the others differ only in the
 * robust weights). */
static void capture(const double *a, const double *b, int n)
{
    if (captured >= MAX_SYSTEMS || captured_n)
        return;
    captured_a[captured] = malloc((size_t)n * n * sizeof(double));
    captured_b[captured] = malloc((size_t)n * sizeof(double));
    memcpy(captured_a[captured], a, (size_t)n * n * sizeof(double));
    memcpy(captured_b[captured], b, (size_t)n * sizeof(double));
    captured_n = n;
}

bool opencv_solve(double *a, double *b, int n, int method); /* opencv_solve_cxx.cpp */

static bool opencv_cholesky(double *a, double *b, int n)
{
    return opencv_solve(a, b, n, 0);
}

static bool opencv_lu(double *a, double *b, int n)
{
    return opencv_solve(a, b, n, 1);
}

static bool opencv_svd(double *a, double *b, int n)
{
    return opencv_solve(a, b, n, 2);
}

/* |a x - b| / |b| */
static double residual(const double *a, const double *b, const double *x, int n)
{
    double num = 0, den = 0;
    for (int i = 0; i < n; i++) {
        double s = -b[i];
        for (int k = 0; k < n; k++)
            s += a[i * n + k] * x[k];
        num += s * s;
        den += b[i] * b[i];
    }
    return sqrt(num / den);
}

/* Median time of `repeats` solves of the system, each on a fresh copy; the
 * solution in x. */
static double time_solver(bool (*solve)(double *, double *, int), const double *a0,
                          const double *b0, int n, double *x, int repeats, bool *ok)
{
    double *a = malloc((size_t)n * n * sizeof *a), t[REPEATS];
    for (int r = 0; r < repeats; r++) {
        memcpy(a, a0, (size_t)n * n * sizeof *a);
        memcpy(x, b0, (size_t)n * sizeof *x);
        double t0 = sl_seconds();
        *ok = solve(a, x, n);
        t[r] = sl_seconds() - t0;
    }
    free(a);
    qsort(t, (size_t)repeats, sizeof t[0], sl_cmp_double);
    return t[repeats / 2];
}

/* Fits the response of a bracket and compares the two solvers on the
 * first system it builds. */
static void compare_on(const char *label, const char *const *paths, int count,
                       const double *times)
{
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    opt.times = times;
    opt.response_mode = SL_RESPONSE_AUTO;
    sl_merge_result fit;
    sl_error err;
    captured_n = 0;
    int before = captured;
    merge_fit_system_hook = capture;
    sl_result r = sl_merge_response(paths, count, &opt, &fit, &err);
    merge_fit_system_hook = NULL;
    CHECK_OK(r, &err);
    if (!r)
        sl_merge_result_free(&fit);
    CHECK_MSG(captured_n == NODES, "%s: no %dx%d system captured", label, NODES, NODES);
    if (captured_n != NODES)
        return;
    captured++;
    int n = captured_n;
    const double *a = captured_a[before], *b = captured_b[before];
    /* the fit's own solver, then OpenCV's (SVD is slow: a few runs) */
    static const struct {
        const char *name;
        bool (*solve)(double *, double *, int);
        int repeats;
    } solvers[4] = {{"own Cholesky", merge_cholesky_solve, 21},
                    {"cv::solve DECOMP_CHOLESKY", opencv_cholesky, 21},
                    {"DECOMP_LU", opencv_lu, 5},
                    {"DECOMP_SVD", opencv_svd, 1}};
    double x[4][NODES], res[4], ms[4], diff[4];
    bool ok[4];
    char line[1024];
    int at = snprintf(line, sizeof line, "%s, %dx%d:", label, n, n);
    for (int k = 0; k < 4; k++) {
        ms[k] = 1e3 * time_solver(solvers[k].solve, a, b, n, x[k], solvers[k].repeats, &ok[k]);
        res[k] = residual(a, b, x[k], n);
        double d = 0, scale = 0;
        for (int i = 0; i < n; i++) {
            d = fmax(d, fabs(x[k][i] - x[0][i]));
            scale = fmax(scale, fabs(x[0][i]));
        }
        diff[k] = d / scale;
        at += snprintf(line + at, sizeof line - (size_t)at, " %s %.2f ms residual %.1e%s;",
                       solvers[k].name, ms[k], res[k], ok[k] ? "" : " (refused)");
    }
    printf("%s OpenCV's Cholesky solution within %.0e of the own\n", line, diff[1]);
    CHECK_MSG(ok[0] && ok[1], "%s: a Cholesky refused the system", label);
    /* Both are backward-stable Cholesky factorisations of a well-posed
     * system: the same solution, and residuals at double precision
     * (the reason it is kept is in docs/merge.md). */
    CHECK_MSG(res[0] < 1e-9 && res[1] < 1e-9, "%s: residuals %.2e, %.2e", label, res[0],
              res[1]);
    CHECK_MSG(diff[1] < 1e-9, "%s: solutions differ by %.2e", label, diff[1]);
}

static void test_synthetic(void)
{
    mf_bracket br = {.width = 256, .height = 128, .frames = 7, .stops = 3, .curve = MF_GAMMA,
                     .bits = 8, .ext = "jpg", .noise_gain = 2e-5, .noise_floor = 1e-6,
                     .seed = 3};
    mf_result truth;
    sl_error err;
    CHECK_OK(mf_make_bracket(sl_test_tmpdir(), "syn", &br, &truth, &err), &err);
    const char *paths[MF_MAX_FRAMES];
    for (int i = 0; i < truth.frames; i++)
        paths[i] = truth.paths[i];
    compare_on("synthetic 7x3 JPEG 256x128", paths, truth.frames, NULL);
    mf_result_free(&truth);
}

static void test_real(void)
{
    const char *room = sl_test_data("brackets/stack_room");
    if (room) {
        char p[7][4096];
        const char *paths[7];
        for (int i = 0; i < 7; i++) {
            snprintf(p[i], sizeof p[i], "%s/stack_room_exp_%d.jpg", room, i);
            paths[i] = p[i];
        }
        compare_on("stack_room 7 JPEGs 640x427", paths, 7, NULL);
    }
    const char *memorial = sl_test_data("brackets/memorial");
    if (memorial) {
        char p[16][4096];
        const char *paths[16];
        double times[16];
        for (int i = 0; i < 16; i++) {
            snprintf(p[i], sizeof p[i], "%s/memorial%04d.png", memorial, 61 + i);
            paths[i] = p[i];
            times[i] = 32.0 / (1 << i); /* 32 s .. 1/1024 s (SOURCES.md) */
        }
        compare_on("memorial 16 PNGs 512x768", paths, 16, times);
    }
}

static void test_refuses(void)
{
    double a[4] = {1, 2, 2, 1}, b[2] = {1, 1}; /* eigenvalues 3 and -1 */
    CHECK(!merge_cholesky_solve(a, b, 2));
    double c[4] = {4, 2, 2, 3}, d[2] = {2, 1}; /* x = (0.5, 0) */
    CHECK(merge_cholesky_solve(c, d, 2));
    CHECK_NEAR(d[0], 0.5, 1e-15);
    CHECK_NEAR(d[1], 0, 1e-15);
}

int main(void)
{
    RUN(test_refuses);
    RUN(test_synthetic);
    RUN(test_real);
    for (int i = 0; i < captured; i++) {
        free(captured_a[i]);
        free(captured_b[i]);
    }
    return sl_test_finish();
}
