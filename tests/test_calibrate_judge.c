/* SPDX-License-Identifier: BSD-3-Clause */
/* Is it a ColorChecker? sl_chart_judge on patch sets that break one law of
 * the chart each, on synthetic photos of things that are not a chart (a
 * white brick wall, coloured squares, the chart's colours in another
 * order) and of charts that are (through a camera matrix, tiny,
 * overexposed); the overlay picture; negative samples clamped. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "chart_fixture.h"
#include "setlight/render.h"
#include "setlight/stitch.h"
#include "testing.h"

/* A camera with crosstalk (rows: its R, G, B from Rec.709), like a raw
 * sensor before its colour matrix. */
static const double camera[3][3] = {{0.70, 0.25, 0.05}, {0.10, 0.80, 0.10}, {0.02, 0.18, 0.80}};

/* The 24 patches as that camera sees them under light 0.6. */
static void camera_patches(sl_chart_patch p[24])
{
    memset(p, 0, sizeof(sl_chart_patch) * 24);
    for (int k = 0; k < 24; k++) {
        sl_mat3_apply(camera, SL_COLORCHECKER_LINEAR[k], p[k].rgb);
        for (int c = 0; c < 3; c++)
            p[k].rgb[c] *= 0.6;
        p[k].pixels = 100;
        p[k].valid = true;
        p[k].radius = 5;
        p[k].center[0] = 20 + 40 * (k % 6);
        p[k].center[1] = 20 + 40 * (k / 6);
    }
}

/* outlier_test off: every valid patch in the fit, so that the neutral
 * row's own laws are what is tested (with it on, a neutral off by the
 * factors below is also left out as lit differently). */
static void judge_with(const sl_chart_patch p[24], bool outlier_test, sl_chart_judgement *j)
{
    sl_ccm_options o;
    sl_ccm_options_init(&o);
    if (!outlier_test)
        o.outlier_ratio = 0;
    sl_ccm_fit fit;
    sl_error err;
    CHECK_OK(sl_ccm_fit_chart(p, SL_COLORCHECKER_LINEAR, &o, &fit, &err), &err);
    sl_chart_judge(p, &fit, SL_COLORCHECKER_LINEAR, j);
}

static void judge(const sl_chart_patch p[24], sl_chart_judgement *j) { judge_with(p, true, j); }

/* Each law of the chart broken alone is named alone. */
static void test_laws(void)
{
    sl_chart_patch p[24], q[24];
    sl_chart_judgement j;
    camera_patches(p);
    judge(p, &j);
    printf("  camera: plausible %d, slope %.3f, chroma %.2f vs %.3f, turns %d, condition %.2f, "
           "dE limit %.2f\n", j.plausible, j.neutral_slope, j.colour_chroma, j.neutral_chroma,
           j.hue_turns, j.condition, j.de_limit);
    CHECK(j.plausible && j.reasons == 0 && j.text[0] == '\0');
    CHECK_NEAR(j.neutral_slope, 1.0, 1e-3);
    CHECK(j.hue_turns == 1);
    CHECK_NEAR(j.de_limit, 13.1, 0.1);

    /* Neutral 6.5 and neutral 5 swapped: the row does not darken step by step. */
    memcpy(q, p, sizeof(q));
    memcpy(q[20].rgb, p[21].rgb, sizeof(q[20].rgb));
    memcpy(q[21].rgb, p[20].rgb, sizeof(q[21].rgb));
    judge_with(q, false, &j);
    printf("  neutrals swapped: %s\n", j.text);
    CHECK(j.reasons & SL_CHART_NEUTRALS);
    CHECK(strstr(j.text, "step by step") && j.order_breaks == 1);

    /* Veiling flare of half the white level: ordered, but a third of the
     * chart's contrast. */
    memcpy(q, p, sizeof(q));
    for (int k = 0; k < 24; k++)
        for (int c = 0; c < 3; c++)
            q[k].rgb[c] += 0.5 * p[18].rgb[c];
    judge_with(q, false, &j);
    printf("  flare: slope %.2f: %s\n", j.neutral_slope, j.text);
    CHECK(j.reasons & SL_CHART_NEUTRALS && strstr(j.text, "contrast"));
    CHECK(j.neutral_slope < 0.5);
    judge(q, &j);
    printf("  flare, outlier test on: %s\n", j.text);
    CHECK(j.reasons & SL_CHART_NEUTRALS);

    /* Blue and red swapped: the hues go round the other way. */
    memcpy(q, p, sizeof(q));
    memcpy(q[12].rgb, p[14].rgb, sizeof(q[12].rgb));
    memcpy(q[14].rgb, p[12].rgb, sizeof(q[14].rgb));
    sl_ccm_fit fit;
    sl_error err;
    CHECK_OK(sl_ccm_fit_chart(q, SL_COLORCHECKER_LINEAR, NULL, &fit, &err), &err);
    sl_chart_judge(q, &fit, SL_COLORCHECKER_LINEAR, &j);
    printf("  blue <-> red: turns %d: %s\n", j.hue_turns, j.text);
    CHECK(j.reasons & SL_CHART_COLOURS && strstr(j.text, "hue order"));

    /* Colour patches washed out to the neutrals' saturation. */
    memcpy(q, p, sizeof(q));
    for (int k = 0; k < 18; k++) {
        double m = (p[k].rgb[0] + p[k].rgb[1] + p[k].rgb[2]) / 3;
        for (int c = 0; c < 3; c++)
            q[k].rgb[c] = m * p[18].rgb[c] / p[18].rgb[1] * (1 + 0.02 * (c - 1) * (k % 3));
    }
    judge(q, &j);
    printf("  washed out: %s\n", j.text);
    CHECK(j.reasons & SL_CHART_COLOURS && strstr(j.text, "colourful"));

    /* Too few patches in one light. */
    memcpy(q, p, sizeof(q));
    for (int k = 0; k < 24; k++)
        q[k].valid = k % 6 < 1 || k >= 18 || k == 12 || k == 14 || k == 16;
    judge(q, &j);
    printf("  %d used: %s\n", j.used, j.text);
    CHECK(j.reasons == SL_CHART_FEW_PATCHES);

    /* A matrix that swaps colours or is ill-conditioned is no camera's. */
    sl_ccm_fit bad;
    CHECK_OK(sl_ccm_fit_chart(p, SL_COLORCHECKER_LINEAR, NULL, &bad, &err), &err);
    for (int c = 0; c < 3; c++) {
        double t = bad.m[c][0];
        bad.m[c][0] = bad.m[c][2];
        bad.m[c][2] = t;
    }
    sl_chart_judge(p, &bad, SL_COLORCHECKER_LINEAR, &j);
    CHECK(j.reasons & SL_CHART_MATRIX && strstr(j.text, "determinant"));
    CHECK_OK(sl_ccm_fit_chart(p, SL_COLORCHECKER_LINEAR, NULL, &bad, &err), &err);
    for (int c = 0; c < 3; c++)
        bad.m[c][1] += 0.999 * bad.m[c][0];
    for (int c = 0; c < 3; c++)
        bad.m[c][0] *= 1.0 / 200;
    sl_chart_judge(p, &bad, SL_COLORCHECKER_LINEAR, &j);
    printf("  condition %.0f: %s\n", j.condition, j.text);
    CHECK(j.reasons & SL_CHART_MATRIX && j.condition > SL_CHART_MAX_CONDITION);
}

/* Photo -> sampled where the fixture's grid is -> fit (false when none
 * fits) -> judgement. */
static bool judge_photo(const chart_fixture *f, sl_chart_judgement *j, sl_chart_patch p[24],
                        sl_ccm_fit *fit)
{
    sl_image img = {0};
    sl_error err;
    double centers[24][2];
    for (int k = 0; k < 24; k++)
        chart_fixture_center(f, k, centers[k]);
    CHECK_OK(chart_fixture_render(f, &img, &err), &err);
    CHECK_OK(sl_chart_sample(&img, (const double(*)[2])centers, 0, 0.999, p, &err), &err);
    bool fitted = sl_ccm_fit_chart(p, SL_COLORCHECKER_LINEAR, NULL, fit, &err) == SL_OK;
    if (fitted)
        sl_chart_judge(p, fit, SL_COLORCHECKER_LINEAR, j);
    sl_image_free(&img);
    return fitted;
}

/* Things that are not a ColorChecker, sampled where a chart would be (as a
 * detector that took them for one would): refused, each for its reasons. */
static void test_not_a_chart(void)
{
    static const char *const kinds[] = {"chartwall", "chartsquares", "chartshuffled"};
    for (int kind = 0; kind < 3; kind++) {
        chart_fixture f;
        CHECK(chart_fixture_kind(&f, kinds[kind]));
        /* Over the squares: the grid's top left on the first one. */
        if (kind == 1)
            f.center[0] = 0.18 * f.width + 2.5 * f.pitch, f.center[1] = 0.22 * f.height + 1.5 * f.pitch;
        sl_chart_patch p[24];
        sl_ccm_fit fit;
        sl_chart_judgement j;
        bool fitted = judge_photo(&f, &j, p, &fit);
        printf("  %s: %s\n", kinds[kind], fitted ? j.text : "no matrix fits");
        CHECK_MSG(!fitted || !j.plausible, "%s taken for a chart", kinds[kind]);
        if (fitted)
            CHECK(strlen(j.text) > 20);
    }
}

/* Real charts in the fixture's photos pass: exact, through the camera, with
 * the light's colour, tiny (6 px pitch), turned, overexposed (clipped
 * patches left out). */
static void test_charts_pass(void)
{
    for (int kind = 0; kind < 4; kind++) {
        chart_fixture f;
        chart_fixture_init(&f);
        f.chart = true;
        if (kind == 1)
            f.pitch = 6;
        if (kind == 2)
            f.angle_deg = 12;
        if (kind == 3)
            f.exposure *= 2;
        sl_chart_patch p[24];
        sl_ccm_fit fit;
        sl_chart_judgement j;
        CHECK(judge_photo(&f, &j, p, &fit));
        printf("  chart %d: %d used, slope %.2f, condition %.2f, dE %.3f: %s\n", kind, fit.used,
               j.neutral_slope, j.condition, fit.de_after_mean, j.plausible ? "plausible" : j.text);
        CHECK_MSG(j.plausible, "chart %d refused: %s", kind, j.text);
    }
}

/* The overlay: at least 256 px wide, each used patch's disc outlined in
 * green round its centre, an excluded one in red. */
static void test_overlay(void)
{
    chart_fixture f;
    chart_fixture_init(&f);
    f.chart = true;
    f.exposure *= 2; /* white clips */
    sl_image img = {0};
    sl_error err;
    CHECK_OK(chart_fixture_render(&f, &img, &err), &err);
    double c[24][2];
    for (int p = 0; p < 24; p++)
        chart_fixture_center(&f, p, c[p]);
    sl_chart_patch p[24];
    sl_ccm_fit fit;
    CHECK_OK(sl_chart_sample(&img, c, 0, 0.999, p, &err), &err);
    CHECK_OK(sl_ccm_fit_chart(p, SL_COLORCHECKER_LINEAR, NULL, &fit, &err), &err);
    CHECK(!p[18].valid && fit.used_patch[21]);
    sl_image ov;
    CHECK_OK(sl_chart_overlay(&img, p, &fit, 512, &ov, &err), &err);
    CHECK(ov.width == 512 && ov.height > 200);
    /* The crop starts two pitches (8 radii) left of and above patch 1. */
    double s = 512.0 / (c[5][0] - c[0][0] + 16 * p[0].radius);
    double x0 = c[0][0] - 8 * p[0].radius, y0 = c[0][1] - 8 * p[0].radius;
    const int probe[2] = {21, 18};
    for (int k = 0; k < 2; k++) {
        int q = probe[k];
        /* The ring's right-hand point. */
        int x = (int)((c[q][0] - x0 + p[q].radius) * s), y = (int)((c[q][1] - y0) * s);
        const float *v = sl_image_pixel(&ov, x, y);
        printf("  overlay: patch %d ring at (%d, %d) = %.2f %.2f %.2f\n", q + 1, x, y, v[0], v[1], v[2]);
        if (k == 0)
            CHECK(v[1] > 0.9f && v[0] < 0.2f);
        else
            CHECK(v[0] > 0.9f && v[1] < 0.2f);
    }
    sl_image_free(&ov);
    sl_image_free(&img);
}

/* A camera that saturated at 1.0: the overexposed chart's float file holds
 * the level in many pixels; a render with noise holds its top in one. */
static void test_pinned_maximum(void)
{
    chart_fixture f;
    CHECK(chart_fixture_kind(&f, "chartclipped"));
    sl_image img = {0};
    sl_error err;
    CHECK_OK(chart_fixture_render(&f, &img, &err), &err);
    double level[3];
    int64_t n = sl_pinned_maximum(&img, level);
    printf("  overexposed chart: %lld pixels pinned at %g %g %g\n", (long long)n, level[0],
           level[1], level[2]);
    CHECK(level[0] == 1 && level[1] == 1 && level[2] == 1 && n > 1000);
    uint64_t state = 3;
    for (int i = 0; i < img.width * img.height * 3; i++)
        img.data[i] = (float)(0.5 + 0.1 * sl_test_uniform(&state));
    CHECK(sl_pinned_maximum(&img, level) == 0 && level[0] == 0 && level[1] == 0 && level[2] == 0);
    sl_image_free(&img);
}

static void test_clamp_negative(void)
{
    sl_image img = {0};
    sl_error err;
    CHECK_OK(sl_image_alloc(&img, 2, 1, 4, &err), &err);
    const float v[8] = {1, -0.5f, 2, -7, 0.5f, 0, -1, 1};
    memcpy(img.data, v, sizeof(v));
    double fraction;
    CHECK(sl_calibrate_clamp_negative(&img, &fraction) == 2);
    CHECK_NEAR(fraction, 1.5 / 5.0, 1e-12);
    CHECK(img.data[1] == 0 && img.data[6] == 0 && img.data[3] == -7); /* alpha untouched */
    sl_image_free(&img);
}

int main(void)
{
    RUN(test_laws);
    RUN(test_not_a_chart);
    RUN(test_charts_pass);
    RUN(test_overlay);
    RUN(test_pinned_maximum);
    RUN(test_clamp_negative);
    return sl_test_finish();
}
