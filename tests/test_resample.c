/* SPDX-License-Identifier: BSD-3-Clause */
/* Area-weighted shrinking keeps the mean exactly; enlarging is bilinear. */
#include "testing.h"

#include <math.h>
#include <stdint.h>
#include <string.h>

static uint64_t rng_state = 12345;

static double rng_uniform(void) { return sl_test_uniform(&rng_state); }

static double image_mean(const sl_image *img, int c)
{
    double s = 0.0;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++)
            s += sl_image_pixel(img, x, y)[c];
    return s / ((double)img->width * img->height);
}

/* HDR-like content: mostly dim noise with a few very bright pixels. */
static void fill_hdr_noise(sl_image *img)
{
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++)
            for (int c = 0; c < img->channels; c++) {
                double r = rng_uniform();
                sl_image_pixel(img, x, y)[c] = (float)(r < 0.001 ? 5000.0 * r * 1000 : r);
            }
}

static void check_energy(int sw, int sh, int dw, int dh)
{
    sl_error err;
    sl_image src, dst;
    CHECK_OK(sl_image_alloc(&src, sw, sh, 3, &err), &err);
    fill_hdr_noise(&src);
    CHECK_OK(sl_image_resample(&src, dw, dh, &dst, &err), &err);
    CHECK(dst.width == dw && dst.height == dh && dst.channels == 3);
    double worst = 0.0;
    for (int c = 0; c < 3; c++) {
        double a = image_mean(&src, c), b = image_mean(&dst, c);
        worst = fmax(worst, fabs(b / a - 1.0));
    }
    printf("  %dx%d -> %dx%d: relative mean error %.3g\n", sw, sh, dw, dh, worst);
    CHECK(worst < 1e-6);
    sl_image_free(&src);
    sl_image_free(&dst);
}

static void test_energy(void)
{
    check_energy(64, 64, 32, 32);    /* 2 */
    check_energy(99, 60, 33, 20);    /* 3 */
    check_energy(1000, 50, 333, 17); /* 1000 -> 333, 50 -> 17 */
    check_energy(7, 700, 3, 300);    /* 7 -> 3 */
    check_energy(500, 9, 1, 1);      /* everything into one pixel */
    check_energy(1000, 20, 333, 20); /* shrink x only */
}

static void test_mixed(void)
{
    sl_error err;
    sl_image src, dst;
    CHECK_OK(sl_image_alloc(&src, 300, 10, 1, &err), &err);
    /* f(x, y) = x (in source pixel-centre units): area shrink in x is exact for
     * a linear function, bilinear enlarge in y of a y-constant is exact. */
    for (int y = 0; y < 10; y++)
        for (int x = 0; x < 300; x++)
            sl_image_pixel(&src, x, y)[0] = (float)(x + 0.5);
    CHECK_OK(sl_image_resample(&src, 100, 37, &dst, &err), &err);
    double worst = 0.0;
    for (int y = 0; y < 37; y++)
        for (int x = 0; x < 100; x++)
            worst = fmax(worst, fabs(sl_image_pixel(&dst, x, y)[0] - (3 * x + 1.5)));
    printf("  300x10 -> 100x37 of a ramp: max error %.3g\n", worst);
    CHECK(worst < 1e-4);
    sl_image_free(&dst);
    sl_image_free(&src);
}

static void test_constant(void)
{
    sl_error err;
    sl_image src, dst;
    int sizes[][2] = {{17, 5}, {333, 100}, {1000, 1}, {1, 1000}, {2048, 3}};
    CHECK_OK(sl_image_alloc(&src, 1000, 300, 4, &err), &err);
    sl_image_fill(&src, 0.3f);
    for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; i++) {
        CHECK_OK(sl_image_resample(&src, sizes[i][0], sizes[i][1], &dst, &err), &err);
        double worst = 0.0;
        for (int y = 0; y < dst.height; y++)
            for (int x = 0; x < dst.width * 4; x++)
                worst = fmax(worst, fabs(sl_image_pixel(&dst, 0, y)[x] - 0.3f));
        CHECK(worst < 1e-7);
        sl_image_free(&dst);
    }
    sl_image_free(&src);
}

static void test_enlarge_then_shrink(void)
{
    sl_error err;
    sl_image src, big, back;
    CHECK_OK(sl_image_alloc(&src, 64, 48, 1, &err), &err);
    for (int y = 0; y < 48; y++)
        for (int x = 0; x < 64; x++)
            sl_image_pixel(&src, x, y)[0] = (float)(2.0 + sin(x * 0.15) * cos(y * 0.2));
    CHECK_OK(sl_image_resample(&src, 256, 192, &big, &err), &err);
    /* Enlarging is bilinear with pixel centres aligned: the centre of source
     * texel (x, y) falls between big texels 4x+1 and 4x+2. */
    float c = 0.5f * (sl_image_pixel(&big, 4 * 10 + 1, 4 * 10 + 1)[0] +
                      sl_image_pixel(&big, 4 * 10 + 2, 4 * 10 + 2)[0]);
    CHECK_NEAR(c, sl_image_pixel(&src, 10, 10)[0], 0.01);
    CHECK_OK(sl_image_resample(&big, 64, 48, &back, &err), &err);
    double worst = 0.0, sum = 0.0;
    for (int y = 1; y < 47; y++)
        for (int x = 1; x < 63; x++) {
            double e = fabs(sl_image_pixel(&back, x, y)[0] - sl_image_pixel(&src, x, y)[0]);
            worst = fmax(worst, e);
            sum += e;
        }
    printf("  64x48 -> 256x192 -> 64x48 (interior): max error %.3g mean %.3g\n", worst,
           sum / (62 * 46));
    /* What is left is the blur of the linear tent (variance 1/6 texel^2 per
     * axis) on a wave with |f''| up to 0.0625: about 0.005 at the peaks. */
    CHECK(worst < 0.012);
    CHECK(sum / (62 * 46) < 0.005);
    sl_image_free(&src);
    sl_image_free(&big);
    sl_image_free(&back);
}

static void test_threads(void)
{
    sl_error err;
    sl_image src, a, b;
    CHECK_OK(sl_image_alloc(&src, 301, 203, 3, &err), &err);
    fill_hdr_noise(&src);
    CHECK_OK(sl_image_resample(&src, 97, 400, &a, &err), &err);
    int saved = sl_threads_get();
    sl_threads_set(1);
    CHECK_OK(sl_image_resample(&src, 97, 400, &b, &err), &err);
    sl_threads_set(saved);
    CHECK(a.data && b.data && memcmp(a.data, b.data, sizeof(float) * 97 * 400 * 3) == 0);
    sl_image_free(&a);
    sl_image_free(&b);
    sl_image_free(&src);
}

static void test_bad_input(void)
{
    sl_error err;
    sl_image src, dst;
    CHECK_OK(sl_image_alloc(&src, 4, 4, 1, &err), &err);
    CHECK_RESULT(sl_image_resample(&src, 0, 4, &dst, &err), SL_ERR_USAGE, &err);
    CHECK(dst.data == NULL);
    CHECK(strstr(err.message, "0x4") != NULL);
    sl_image empty = {0};
    CHECK_RESULT(sl_image_resample(&empty, 2, 2, &dst, &err), SL_ERR_INPUT, &err);
    sl_image_free(&src);
}

int main(void)
{
    RUN(test_energy);
    RUN(test_mixed);
    RUN(test_constant);
    RUN(test_enlarge_then_shrink);
    RUN(test_threads);
    RUN(test_bad_input);
    return sl_test_finish();
}
