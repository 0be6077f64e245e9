/* SPDX-License-Identifier: BSD-3-Clause */
/* The blend's float row loop against the double loop it replaced
 * (docs/stitch.md, "Speed"): `setlight stitch --focal-mm 8 --sensor-mm
 * 36,24 --float` of the views twice, once with every texel's samples
 * through the double loop (stitch_blend_reference), and the differences of
 * the two lat-longs' RGB: the largest absolute and relative (to the larger
 * of the two, texels above 1e-3 of the median) and how many texels differ
 * by more than 1e-6, 1e-4 and 1e-2 relative; A likewise. With --compare,
 * the same numbers (and the relative RMS difference, the texels beyond
 * half's rounding 2^-11 and the power ratio) of two lat-longs given.
 *   ./build/bench/bench_stitch_blend_diff OUT_DIR VIEW...
 *   ./build/bench/bench_stitch_blend_diff --compare A.exr B.exr */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/stitch.h"
#include "../stitch/stitch_blend_private.h"

static int stitch_once(const char *const *views, int count, const char *out, bool reference)
{
    sl_stitch_run_options o;
    sl_stitch_run_options_init(&o);
    o.view_paths = views;
    o.view_count = count;
    o.out_path = out;
    o.stitch.focal_mm = 8;
    o.stitch.sensor_mm[0] = 36;
    o.stitch.sensor_mm[1] = 24;
    o.stitch.pixel_type = SL_PIXEL_FLOAT;
    stitch_blend_reference = reference;
    sl_stitch_run_result res;
    sl_error err;
    if (sl_stitch_run(&o, &res, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    printf("%-6s blend %.2f CPU s, %lld hot texels\n", reference ? "double" : "float",
           res.stitch.cpu[SL_STITCH_BLEND], (long long)res.stitch.coverage.hot_texels);
    sl_stitch_run_result_free(&res);
    return 0;
}

/* a against b (the reference): their RGB and A differences. */
static int compare(const char *a_path, const char *b_path)
{
    sl_image a = {0}, b = {0};
    sl_error err;
    if (sl_exr_read(a_path, &a, NULL, &err) || sl_exr_read(b_path, &b, NULL, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    if (a.width != b.width || a.height != b.height || a.channels < 4 || b.channels < 4) {
        fprintf(stderr, "%s and %s: not two RGBA images of one size\n", a_path, b_path);
        return 1;
    }
    size_t n = (size_t)a.width * a.height;
    float *lum = malloc(n * sizeof(float));
    for (size_t i = 0; i < n; i++)
        lum[i] = b.data[i * 4 + 1];
    double median = stitch_median(lum, n), floor_v = 1e-3 * median;
    free(lum);
    double max_abs = 0, max_rel = 0, max_a = 0, sum_d2 = 0, sum_b2 = 0, power[2] = {0, 0};
    long long over[4] = {0, 0, 0, 0}, bytes_same = 0;
    const double limits[4] = {1e-6, 1e-4, 0x1p-11, 1e-2};
    for (size_t i = 0; i < n; i++) {
        double worst = 0;
        for (int c = 0; c < 3; c++) {
            double x = a.data[i * 4 + c], y = b.data[i * 4 + c], d = fabs(x - y);
            double big = fmax(fabs(x), fabs(y));
            max_abs = fmax(max_abs, d);
            if (big > floor_v)
                worst = fmax(worst, d / big);
            sum_d2 += d * d;
            sum_b2 += y * y;
            power[0] += x;
            power[1] += y;
        }
        max_rel = fmax(max_rel, worst);
        for (int k = 0; k < 4; k++)
            over[k] += worst > limits[k];
        max_a = fmax(max_a, fabs(a.data[i * 4 + 3] - b.data[i * 4 + 3]));
        bytes_same += !memcmp(a.data + i * 4, b.data + i * 4, 4 * sizeof(float));
    }
    printf("%dx%d: RGB max |a - b| %.3g (median G %.3g), max relative %.3g, relative RMS "
           "difference %.3g; texels over 1e-6 relative: %lld, 1e-4: %lld, 2^-11: %lld, 1e-2: "
           "%lld; sum of RGB a / b %.7f; A max %.3g; %lld of %zu texels the same bytes\n",
           a.width, a.height, max_abs, median, max_rel, sqrt(sum_d2 / sum_b2), over[0], over[1],
           over[2], over[3], power[0] / power[1], max_a, bytes_same, n);
    sl_image_free(&a);
    sl_image_free(&b);
    return 0;
}

int main(int argc, char **argv)
{
    if (argc == 4 && !strcmp(argv[1], "--compare"))
        return compare(argv[2], argv[3]);
    if (argc < 3) {
        fprintf(stderr, "usage: bench_stitch_blend_diff OUT_DIR VIEW... | --compare A.exr B.exr\n");
        return 2;
    }
    char a_path[4096], b_path[4096];
    snprintf(a_path, sizeof a_path, "%s/blend_float.exr", argv[1]);
    snprintf(b_path, sizeof b_path, "%s/blend_double.exr", argv[1]);
    const char *const *views = (const char *const *)argv + 2;
    if (stitch_once(views, argc - 2, a_path, false) || stitch_once(views, argc - 2, b_path, true))
        return 1;
    return compare(a_path, b_path);
}
