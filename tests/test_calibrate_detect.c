/* SPDX-License-Identifier: BSD-3-Clause */
/* ColorChecker detection: on a rendered chart (known centres), on an image
 * without a chart, and on every real chart photo in the shared data. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/render.h"
#include "setlight/stitch.h"
#include "testing.h"

/* Under LeakSanitizer: OpenCV 4.6's mcc leaves buffers from its own
 * allocator when a chart is found (frames without symbols past
 * cv::fastMalloc); setlight's code never allocates through it. */
const char *__lsan_default_suppressions(void);
const char *__lsan_default_suppressions(void) { return "leak:cv::fastMalloc\n"; }

/* The chart preset on a mid-grey background, under a white dome. */
static int render_chart(sl_image *img, int w)
{
    sl_error err;
    sl_scene s;
    sl_scene_init(&s);
    sl_image env = {0};
    int ok = sl_image_alloc(&env, 8, 4, 3, &err) == SL_OK;
    for (int i = 0; ok && i < 8 * 4 * 3; i++)
        env.data[i] = 1.0f;
    ok = ok && sl_scene_preset(&s, "chart", w, &err) == SL_OK &&
         sl_scene_set_dome(&s, &env, 0, 1, "white", &err) == SL_OK;
    if (ok) {
        /* Room around the frame, as in a photo. */
        s.camera.ortho_width = 3.0;
        s.camera.height = (int)(w * 0.8);
    }
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 1;
    o.strategy = SL_STRATEGY_COSINE;
    o.pixel_centers = true;
    ok = ok && sl_render(&s, &o, img, NULL, &err) == SL_OK;
    sl_scene_free(&s);
    sl_image_free(&env);
    if (!ok)
        printf("render failed: %s\n", err.message);
    return ok;
}

static void test_detect_rendered(void)
{
    const int w = 480;
    sl_image img = {0};
    if (!render_chart(&img, w))
        return;
    /* Background: grey 0.3 where no shape was hit. */
    for (int y = 0; y < img.height; y++)
        for (int x = 0; x < img.width; x++) {
            float *p = img.data + (size_t)y * img.stride + (size_t)x * 4;
            if (p[3] < 0.5f)
                p[0] = p[1] = p[2] = 0.3f;
        }
    sl_chart_detection d;
    sl_error err;
    CHECK_OK(sl_chart_detect(&img, 0, "rendered", &d, &err), &err);
    double px = w / 3.0, pitch = 0.32 * px, worst = 0; /* pixels per world unit */
    for (int p = 0; p < 24; p++) {
        double tx = img.width * 0.5 + (p % 6 - 2.5) * pitch;
        double ty = img.height * 0.5 + (p / 6 - 1.5) * pitch;
        worst = fmax(worst, hypot(d.centers[p][0] - tx, d.centers[p][1] - ty));
    }
    printf("  rendered chart: worst centre error %.2f px (patch half-size %.1f px), trial fit dE %.3f\n",
           worst, 0.13 * px, d.fit_de_mean);
    CHECK(worst < 0.25 * 0.13 * px);
    sl_image_free(&img);
}

static void test_no_chart(void)
{
    sl_image img = {0};
    sl_error err;
    CHECK_OK(sl_image_alloc(&img, 200, 150, 3, &err), &err);
    for (int i = 0; i < 200 * 150 * 3; i++)
        img.data[i] = 0.18f + 0.05f * (float)((i / 3) % 7);
    sl_chart_detection d;
    CHECK_RESULT(sl_chart_detect(&img, 0, "plain.exr", &d, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "plain.exr") && strstr(err.message, "no chart found"));
    sl_image_free(&img);
}

static const char *const photos[] = {
    "colorchecker/arcu/color_checker_1.jpg",      "colorchecker/arcu/color_checker_2.jpg",
    "colorchecker/arcu/color_checker_3.jpg",      "colorchecker/arcu/color_checker_4.jpg",
    "colorchecker/arcu/color_checker_5.jpg",      "colorchecker/arcu/color_checker_6.jpg",
    "colorchecker/arcu/color_checker_7.jpg",      "colorchecker/arcu/color_checker_mini_1.jpg",
    "colorchecker/arcu/color_checker_mini_2.jpg", "colorchecker/arcu/color_checker_mini_3.jpg",
    "colorchecker/arcu/color_checker_mini_4.jpg", "colorchecker/classic_and_sg/input.jpg",
    "colorchecker/mindvision/CWF_colorchecker.jpg", "colorchecker/mindvision/TL84_colorchecker.jpg",
    "colorchecker/mindvision/d65_colorchecker.jpg", "colorchecker/mindvision/exposure30.jpg",
};

static void test_real_photos(void)
{
    int n = (int)(sizeof(photos) / sizeof(photos[0]));
    if (sl_test_sanitized())
        n = 2; /* mcc under sanitizers is slow: the first two photos */
    for (int i = 0; i < n; i++) {
        const char *path = sl_test_data(photos[i]);
        if (!path)
            return;
        sl_image img = {0};
        sl_error err;
        CHECK_OK(sl_image_read(path, &img, NULL, &err), &err);
        if (!img.data)
            continue;
        for (int y = 0; y < img.height; y++)
            for (int x = 0; x < img.width * img.channels; x++) {
                float *v = img.data + (size_t)y * img.stride + x;
                *v = sl_srgb_to_linear(*v);
            }
        sl_chart_detection d;
        sl_result r = sl_chart_detect(&img, 0.999, photos[i], &d, &err);
        CHECK_MSG(r == SL_OK, "%s: %s", photos[i], err.message);
        if (r) {
            sl_image_free(&img);
            continue;
        }
        sl_chart_patch p[24];
        sl_ccm_fit fit;
        CHECK_OK(sl_chart_sample(&img, d.centers, 0, 0.999, p, &err), &err);
        CHECK_OK(sl_ccm_fit_chart(p, SL_COLORCHECKER_LINEAR, NULL, &fit, &err), &err);
        /* Inside the true patches: each sampled disc is nearly uniform, and
         * the neutral row runs from white down to black. */
        /* Spread as a fraction of the white patch, so that JPEG noise on
         * the black patch does not count as being off the patch. */
        double spread = 0;
        int worst = 0;
        bool ordered = true;
        for (int k = 0; k < 24; k++) {
            double s = p[k].spread * (p[k].rgb[0] + p[k].rgb[1] + p[k].rgb[2]) /
                       (p[18].rgb[0] + p[18].rgb[1] + p[18].rgb[2]);
            if (s > spread)
                spread = s, worst = k;
        }
        for (int k = 18; k < 23; k++)
            ordered = ordered && sl_luminance(p[k].rgb) > sl_luminance(p[k + 1].rgb);
        printf("  %-44s %4dx%-4d cost %6.2f  max spread %.3f (patch %2d) neutrals %s  "
               "dE2000 vs X-Rite: before %.2f (max %.2f) after CCM %.2f (max %.2f), %d used, %d outliers\n",
               photos[i], img.width, img.height, d.cost, spread, worst + 1, ordered ? "ordered" : "NOT ordered",
               fit.de_before_mean, fit.de_before_max, fit.de_after_mean, fit.de_after_max, fit.used,
               fit.outliers);
        /* The phone photos are charts; the mindvision JPEGs are not
         * sRGB renderings and need their own colour space (refused here). */
        sl_chart_judgement j;
        sl_chart_judge(p, &fit, SL_COLORCHECKER_LINEAR, &j);
        printf("    judged %s%s\n", j.plausible ? "a ColorChecker" : "not usable: ", j.text);
        if (strstr(photos[i], "arcu/") || strstr(photos[i], "classic_and_sg/"))
            CHECK_MSG(j.plausible, "%s refused: %s", photos[i], j.text);
        CHECK_MSG(ordered, "%s: neutral row not ordered", photos[i]);
        CHECK_MSG(spread < 0.05, "%s: patch spread %.3f", photos[i], spread);
        sl_image_free(&img);
    }
}

int main(void)
{
    RUN(test_detect_rendered);
    RUN(test_no_chart);
    RUN(test_real_photos);
    return sl_test_finish();
}
