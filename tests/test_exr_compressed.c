/* SPDX-License-Identifier: BSD-3-Clause */
/* sl_exr_write_compressed: chunks compressed in parallel and written in
 * order round-trip exactly for every compression, chunk-unaligned heights
 * and thread counts; a bad compression leaves no file. */
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "testing.h"

static void round_trip(int w, int h, int channels, sl_pixel_type type, sl_exr_compression comp,
                       int threads)
{
    sl_error err;
    sl_image img = {0}, back = {0};
    CHECK_OK(sl_image_alloc(&img, w, h, channels, &err), &err);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            for (int c = 0; c < channels; c++)
                sl_image_pixel(&img, x, y)[c] = (float)(exp2(8 * sin(0.37 * x + 0.11 * y * (c + 1))) * 0.1);
    char name[64];
    snprintf(name, sizeof name, "exrc_%d_%d_%d_%d_%d.exr", h, channels, (int)type, (int)comp, threads);
    const char *path = sl_test_path(name);
    sl_threads_set(threads);
    CHECK_OK(sl_exr_write_compressed(path, &img, NULL, type, comp, &err), &err);
    sl_threads_set(0);
    CHECK_OK(sl_exr_read(path, &back, NULL, &err), &err);
    double worst = 0;
    for (int y = 0; y < h && back.data; y++)
        for (int x = 0; x < w; x++)
            for (int c = 0; c < channels; c++) {
                float a = sl_image_pixel(&img, x, y)[c], b = sl_image_pixel(&back, x, y)[c];
                worst = fmax(worst, fabs(b / a - 1));
            }
    /* Float exact; half within its rounding (2^-11). */
    CHECK(worst <= (type == SL_PIXEL_FLOAT ? 0 : 4.9e-4));
    sl_image_free(&img);
    sl_image_free(&back);
}

static void test_round_trips(void)
{
    const sl_exr_compression comps[3] = {SL_EXR_ZIP, SL_EXR_PIZ, SL_EXR_NONE};
    for (int k = 0; k < 3; k++)
        for (int threads = 1; threads <= 3; threads += 2) {
            round_trip(53, 101, 3, SL_PIXEL_FLOAT, comps[k], threads);
            round_trip(40, 33, 1, SL_PIXEL_HALF, comps[k], threads);
        }
    round_trip(7, 1, 4, SL_PIXEL_FLOAT, SL_EXR_PIZ, 2);
}

static void test_bad_compression(void)
{
    sl_error err;
    sl_image img = {0};
    CHECK_OK(sl_image_alloc(&img, 4, 4, 3, &err), &err);
    const char *path = sl_test_path("exrc_bad.exr");
    CHECK_RESULT(sl_exr_write_compressed(path, &img, NULL, SL_PIXEL_FLOAT, (sl_exr_compression)9, &err),
                 SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, path) != NULL);
    CHECK(access(path, F_OK) != 0);
    sl_image_free(&img);
}

int main(void)
{
    RUN(test_round_trips);
    RUN(test_bad_compression);
    return sl_test_finish();
}
