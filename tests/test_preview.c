/* SPDX-License-Identifier: BSD-3-Clause */
/* Previews: colour channels only, the median-to-mid-grey exposure, a given
 * exposure, the OCIO display views, and the 8-bit file. */
#include <stdlib.h>
#include <string.h>

#include "testing.h"

/* 1.055 * 0.18^(1/2.4) - 0.055: mid grey through the sRGB curve. */
#define SRGB_MID_GREY 0.46135612950044164

static void test_preview_grey_with_confidence(void)
{
    sl_error err;
    sl_image img, pic;
    /* A constant grey of 3.7 with a confidence ramp in the fourth channel. */
    CHECK_OK(sl_image_alloc(&img, 30, 20, 4, &err), &err);
    for (int y = 0; y < 20; y++)
        for (int x = 0; x < 30; x++) {
            float *p = sl_image_pixel(&img, x, y);
            p[0] = p[1] = p[2] = 3.7f;
            p[3] = x / 29.0f;
        }
    sl_preview_options opt = {.auto_exposure = true};
    sl_preview_result res;
    CHECK_OK(sl_preview_image(&img, &opt, &pic, &res, &err), &err);
    CHECK(pic.channels == 3);
    CHECK_NEAR(res.median_luminance, 3.7, 1e-6);
    CHECK_NEAR(res.exposure_stops, log2(0.18 / 3.7), 1e-6);
    CHECK(strcmp(res.view, "sRGB/Standard") == 0);
    double worst = 0;
    for (int y = 0; y < 20; y++)
        for (int x = 0; x < 30; x++)
            for (int c = 0; c < 3; c++)
                worst = fmax(worst, fabs(sl_image_pixel(&pic, x, y)[c] - SRGB_MID_GREY));
    CHECK(worst < 1e-5);
    sl_image_free(&pic);

    /* Given exposure: 3.7 * 2^-4 = 0.23125 through the sRGB curve; Raw is linear. */
    opt.auto_exposure = false;
    opt.exposure_stops = -4;
    CHECK_OK(sl_preview_image(&img, &opt, &pic, &res, &err), &err);
    CHECK_NEAR(sl_image_pixel(&pic, 7, 3)[1], sl_linear_to_srgb(0.23125f), 2e-5);
    CHECK(res.exposure_stops == -4 && res.median_luminance == 0);
    sl_image_free(&pic);
    opt.view = "raw";
    CHECK_OK(sl_preview_image(&img, &opt, &pic, &res, &err), &err);
    CHECK_NEAR(sl_image_pixel(&pic, 7, 3)[1], 0.23125, 1e-6);
    CHECK(strcmp(res.view, "sRGB/Raw") == 0);
    sl_image_free(&pic);
    opt.exposure_stops = 0; /* 3.7 clamps to 1 */
    CHECK_OK(sl_preview_image(&img, &opt, &pic, &res, &err), &err);
    CHECK(sl_image_pixel(&pic, 0, 0)[0] == 1.0f);
    sl_image_free(&pic);
    opt.view = "Filmic";
    CHECK_RESULT(sl_preview_image(&img, &opt, &pic, &res, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "Filmic") && strstr(err.message, "Standard, Raw"));
    CHECK(pic.data == NULL);

    /* The file: 8-bit RGB, no alpha. */
    opt = (sl_preview_options){.auto_exposure = true};
    const char *path = sl_test_path("grey.png");
    CHECK_OK(sl_preview_write(path, &img, NULL, &opt, &res, &err), &err);
    sl_image back;
    sl_meta meta;
    CHECK_OK(sl_image_read(path, &back, &meta, &err), &err);
    CHECK(back.channels == 3 && meta.bits_per_sample == 8);
    CHECK_NEAR(sl_image_pixel(&back, 29, 19)[0], 118 / 255.0, 1e-6); /* round(0.46136 * 255) */
    sl_image_free(&back);
    sl_meta_free(&meta);
    sl_image_free(&img);
}

static int compare_floats(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

static void test_preview_median(void)
{
    sl_error err;
    sl_image img, pic;
    /* Luminances 1..101 in a shuffled order among 60 black texels (left out)
     * and one grey texel (1-channel image): the median is 51. */
    int order[161];
    for (int i = 0; i < 161; i++)
        order[i] = i;
    uint64_t state = 7;
    sl_test_shuffle(order, 161, &state);
    CHECK_OK(sl_image_alloc(&img, 23, 7, 1, &err), &err);
    for (int i = 0; i < 161; i++)
        sl_image_pixel(&img, i % 23, i / 23)[0] = order[i] < 101 ? (float)(order[i] + 1) : 0.0f;
    sl_preview_options opt = {.auto_exposure = true};
    sl_preview_result res;
    CHECK_OK(sl_preview_image(&img, &opt, &pic, &res, &err), &err);
    CHECK_NEAR(res.median_luminance, 51.0, 1e-4);
    CHECK(pic.channels == 3);
    /* The texel of 51 shows mid grey, black stays black. */
    for (int i = 0; i < 161; i++) {
        const float *p = sl_image_pixel(&pic, i % 23, i / 23);
        if (order[i] == 50)
            CHECK_NEAR(p[0], SRGB_MID_GREY, 1e-5);
        if (order[i] >= 101)
            CHECK(p[0] == 0.0f && p[1] == 0.0f && p[2] == 0.0f);
    }
    sl_image_free(&pic);
    sl_image_free(&img);

    /* Sorted, reversed, few distinct values, one or two texels: against a sort. */
    static const int sizes[] = {1, 2, 3, 1000, 1001};
    for (int kind = 0; kind < 4; kind++)
        for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
            int n = sizes[s];
            float *sorted = malloc((size_t)n * sizeof *sorted);
            CHECK_OK(sl_image_alloc(&img, n, 1, 1, &err), &err);
            for (int i = 0; i < n; i++) {
                float v = kind == 0   ? (float)(i + 1)
                          : kind == 1 ? (float)(n - i)
                          : kind == 2 ? (float)(1 + sl_test_rand(&state) % 3)
                                      : (float)(1e-6 + 1e9 * sl_test_uniform(&state));
                sl_image_pixel(&img, i, 0)[0] = v;
                sorted[i] = 0.2126f * v + 0.7152f * v + 0.0722f * v;
            }
            qsort(sorted, (size_t)n, sizeof *sorted, compare_floats);
            CHECK_OK(sl_preview_image(&img, &opt, &pic, &res, &err), &err);
            CHECK_MSG(res.median_luminance == sorted[n / 2], "kind %d n %d: median %g, sort %g",
                      kind, n, res.median_luminance, sorted[n / 2]);
            sl_image_free(&pic);
            sl_image_free(&img);
            free(sorted);
        }

    /* All black: no exposure, a black picture. */
    CHECK_OK(sl_image_alloc(&img, 23, 7, 1, &err), &err);
    sl_image_fill(&img, 0.0f);
    CHECK_OK(sl_preview_image(&img, &opt, &pic, &res, &err), &err);
    CHECK(res.exposure_stops == 0 && res.median_luminance == 0);
    sl_image_free(&pic);
    sl_image_free(&img);
}

static void test_preview_colorspace(void)
{
    /* An ACEScg image is shown as the same colour: its grey stays grey. */
    sl_error err;
    sl_image img, pic;
    CHECK_OK(sl_image_alloc(&img, 4, 4, 3, &err), &err);
    sl_image_fill(&img, 0.5f);
    sl_preview_options opt = {.colorspace = "acescg", .auto_exposure = true};
    sl_preview_result res;
    CHECK_OK(sl_preview_image(&img, &opt, &pic, &res, &err), &err);
    CHECK_NEAR(res.median_luminance, 0.5, 1e-4);
    for (int c = 0; c < 3; c++)
        CHECK_NEAR(sl_image_pixel(&pic, 1, 1)[c], SRGB_MID_GREY, 1e-4);
    sl_image_free(&pic);
    sl_image_free(&img);
}

int main(void)
{
    RUN(test_preview_grey_with_confidence);
    RUN(test_preview_median);
    RUN(test_preview_colorspace);
    return sl_test_finish();
}
