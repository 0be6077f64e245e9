/* SPDX-License-Identifier: BSD-3-Clause */
/* Chart sampling and the colour-matrix fit on synthetic chart photos: the
 * `chart` preset rendered under a uniform white dome (every patch's
 * radiance is exactly its albedo), seen through a known camera matrix,
 * white balance and exposure. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/vset.h"
#include "setlight/render.h"
#include "setlight/stitch.h"
#include "testing.h"

#define W 120

/* Patch centres of the preset: 6 x 4 at pitch 0.32 of a 2.0-wide view. */
static void preset_centers(int w, double c[24][2])
{
    for (int p = 0; p < 24; p++) {
        c[p][0] = w * (0.5 + (p % 6 - 2.5) * 0.16);
        c[p][1] = w * (0.34 + (p / 6 - 1.5) * 0.16);
    }
}

static void camera_matrix(double m[3][3])
{
    sl_vset_camera cam;
    sl_vset_camera_default(&cam, 3200);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            m[i][j] = cam.wb[i] * cam.cam_from_rec709[i][j];
}

static void invert3(const double m[3][3], double inv[3][3])
{
    double d = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
               m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
               m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            int a = (j + 1) % 3, b = (j + 2) % 3, c = (i + 1) % 3, e = (i + 2) % 3;
            inv[i][j] = (m[a][c] * m[b][e] - m[a][e] * m[b][c]) / d;
        }
}

/* Renders the chart under a white dome (radiance 1) and applies
 * exposure * cam: camera RGB. Deterministic small noise when noise > 0. */
static int chart_photo(sl_image *img, double exposure, const double cam[3][3], double noise)
{
    sl_error err;
    sl_scene s;
    sl_scene_init(&s);
    sl_image env;
    int ok = sl_image_alloc(&env, 8, 4, 3, &err) == SL_OK;
    for (int i = 0; ok && i < 8 * 4 * 3; i++)
        env.data[i] = 1.0f;
    ok = ok && sl_scene_preset(&s, "chart", W, &err) == SL_OK &&
         sl_scene_set_dome(&s, &env, 0, 1, "white", &err) == SL_OK;
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 1;
    o.strategy = SL_STRATEGY_COSINE; /* Lambert under a constant dome: exact per sample */
    o.pixel_centers = true;
    o.bounces = 0;
    ok = ok && sl_render(&s, &o, img, NULL, &err) == SL_OK;
    sl_scene_free(&s);
    sl_image_free(&env);
    if (!ok) {
        printf("render failed: %s\n", err.message);
        return 0;
    }
    uint64_t st = 12345;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            float *v = img->data + (size_t)y * img->stride + (size_t)x * img->channels;
            double l[3] = {v[0], v[1], v[2]};
            for (int c = 0; c < 3; c++) {
                double n = 0;
                if (noise > 0) {
                    st = st * 6364136223846793005ULL + 1442695040888963407ULL;
                    n = noise * (((double)(st >> 11) / 9007199254740992.0) * 2 - 1);
                }
                v[c] = (float)(exposure * (cam[c][0] * l[0] + cam[c][1] * l[1] +
                                           cam[c][2] * l[2]) * (1 + n));
            }
        }
    return 1;
}

static void test_rendered_chart_is_reference(void)
{
    sl_image img = {0};
    double id[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, c[24][2];
    CHECK(chart_photo(&img, 1.0, id, 0));
    preset_centers(W, c);
    sl_chart_patch p[24];
    sl_error err;
    CHECK_OK(sl_chart_sample(&img, c, 0, 0, p, &err), &err);
    double worst = 0;
    for (int i = 0; i < 24; i++) {
        CHECK(p[i].valid);
        for (int k = 0; k < 3; k++)
            worst = fmax(worst, fabs(p[i].rgb[k] / SL_COLORCHECKER_LINEAR[i][k] - 1));
    }
    printf("  rendered patches vs reference albedo: worst relative error %.2e, %d px/patch\n",
           worst, p[0].pixels);
    CHECK(worst < 1e-4);
    sl_image_free(&img);
}

static void test_corners(void)
{
    double c[24][2], corners[4][2], got[24][2];
    preset_centers(W, c);
    memcpy(corners[0], c[0], sizeof(corners[0]));
    memcpy(corners[1], c[5], sizeof(corners[0]));
    memcpy(corners[2], c[23], sizeof(corners[0]));
    memcpy(corners[3], c[18], sizeof(corners[0]));
    sl_error err;
    CHECK_OK(sl_chart_centers_from_corners(corners, got, &err), &err);
    double worst = 0;
    for (int i = 0; i < 24; i++)
        worst = fmax(worst, hypot(got[i][0] - c[i][0], got[i][1] - c[i][1]));
    CHECK(worst < 1e-9);
    /* A perspective quadrilateral: the centre of the grid is where the
     * diagonals of the corner patches cross (projective invariant). */
    double q[4][2] = {{10, 10}, {110, 20}, {100, 70}, {15, 60}};
    CHECK_OK(sl_chart_centers_from_corners(q, got, &err), &err);
    CHECK_NEAR(got[0][0], 10, 1e-9);
    CHECK_NEAR(got[23][1], 70, 1e-9);
    /* Bad corners: collinear, twisted (bow-tie). */
    double line[4][2] = {{0, 0}, {1, 1}, {2, 2}, {3, 3}};
    CHECK_RESULT(sl_chart_centers_from_corners(line, got, &err), SL_ERR_USAGE, &err);
    double bow[4][2] = {{0, 0}, {100, 0}, {0, 60}, {100, 60}};
    CHECK_RESULT(sl_chart_centers_from_corners(bow, got, &err), SL_ERR_USAGE, &err);
}

static void check_fit(double noise, bool white_preserving)
{
    double cam[3][3], truth[3][3], c[24][2];
    const double exposure = 0.37;
    camera_matrix(cam);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            cam[i][j] *= exposure;
    invert3(cam, truth);
    sl_image img = {0};
    CHECK(chart_photo(&img, 1.0, cam, noise));
    /* Glare on patch 2 and a clipped white patch. */
    const double clip = 0.3;
    float *g = img.data + (size_t)(int)(0.34 * W - 0.24 * W) * img.stride +
               (size_t)(int)(W * (0.5 - 1.5 * 0.16)) * img.channels;
    g[0] = g[1] = g[2] = 0.25f;
    preset_centers(W, c);
    sl_chart_patch p[24];
    sl_error err;
    CHECK_OK(sl_chart_sample(&img, c, 0, clip, p, &err), &err);
    CHECK(!p[18].valid && p[18].clipped > 0); /* white: 0.9 * 0.37 * wb > clip */
    int valid = 0;
    for (int i = 0; i < 24; i++)
        valid += p[i].valid;
    sl_ccm_options o;
    sl_ccm_options_init(&o);
    o.white_preserving = white_preserving;
    sl_ccm_fit fit;
    CHECK_OK(sl_ccm_fit_chart(p, SL_COLORCHECKER_LINEAR, &o, &fit, &err), &err);
    CHECK(fit.used == valid && !fit.used_patch[18]);
    double worst = 0, norm = 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            worst = fmax(worst, fabs(fit.m[i][j] - truth[i][j]));
            norm = fmax(norm, fabs(truth[i][j]));
        }
    double true_gain = cbrt(truth[0][0] * (truth[1][1] * truth[2][2] - truth[1][2] * truth[2][1]) -
                            truth[0][1] * (truth[1][0] * truth[2][2] - truth[1][2] * truth[2][0]) +
                            truth[0][2] * (truth[1][0] * truth[2][1] - truth[1][1] * truth[2][0]));
    printf("  noise %.3f%s: %d patches, dE2000 before mean %.2f max %.2f, after mean %.3f max "
           "%.3f, matrix error %.2e of max entry, gain %.5f (true %.5f), neutral patch %d\n",
           noise, white_preserving ? " white-preserving" : "", fit.used, fit.de_before_mean,
           fit.de_before_max, fit.de_after_mean, fit.de_after_max, worst / norm, fit.gain,
           true_gain, fit.neutral_patch + 1);
    CHECK(fit.de_before_mean > 3); /* the uncalibrated camera is visibly off */
    CHECK(fit.de_after_mean <= 1.0);
    CHECK(fit.de_after_max <= 3.0);
    CHECK(fabs(fit.gain / true_gain - 1) < 0.01);
    CHECK(worst / norm < 0.01);
    if (white_preserving) {
        int n = fit.neutral_patch;
        CHECK(n >= 19 && n < 24);
        for (int k = 0; k < 3; k++) {
            double v = fit.m[k][0] * p[n].rgb[0] + fit.m[k][1] * p[n].rgb[1] +
                       fit.m[k][2] * p[n].rgb[2];
            CHECK_NEAR(v, SL_COLORCHECKER_LINEAR[n][k], 1e-9);
        }
    }
    sl_image_free(&img);
}

static void test_fit_exact(void) { check_fit(0, false); }
static void test_fit_noisy(void) { check_fit(0.02, false); }
static void test_fit_white_preserving(void) { check_fit(0.02, true); }

/* A shadow across the chart: everything right of the middle of column 4
 * (0-based 3) gets a quarter of the light. Column 4's patches straddle the
 * edge (non-uniform, invalid); columns 5 and 6 are uniformly darker, which
 * no colour matrix explains: left out as outliers, and the fit on the lit
 * half is as good as on a whole chart. */
static void test_half_in_shadow(void)
{
    double cam[3][3], truth[3][3], c[24][2];
    camera_matrix(cam);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            cam[i][j] *= 0.37;
    invert3(cam, truth);
    sl_image img = {0};
    CHECK(chart_photo(&img, 1.0, cam, 0.01));
    preset_centers(W, c);
    double edge = c[3][0];
    for (int y = 0; y < img.height; y++)
        for (int x = 0; x < img.width; x++)
            if (x + 0.5 > edge)
                for (int k = 0; k < 3; k++)
                    img.data[(size_t)y * img.stride + (size_t)x * img.channels + k] *= 0.25f;
    sl_chart_patch p[24];
    sl_error err;
    CHECK_OK(sl_chart_sample(&img, c, 0, 0, p, &err), &err);
    sl_ccm_fit fit;
    CHECK_OK(sl_ccm_fit_chart(p, SL_COLORCHECKER_LINEAR, NULL, &fit, &err), &err);
    int straddle = 0, outliers_right = 0;
    for (int i = 0; i < 24; i++) {
        if (i % 6 == 3)
            straddle += !p[i].valid;
        if (i % 6 >= 4)
            outliers_right += fit.outlier[i];
    }
    double worst = 0, norm = 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            worst = fmax(worst, fabs(fit.m[i][j] - truth[i][j]));
            norm = fmax(norm, fabs(truth[i][j]));
        }
    printf("  half in shadow: %d of 4 edge patches invalid (spread %.2f), %d outliers (%d in "
           "the shadow), %d used; dE2000 after mean %.3f max %.3f, matrix error %.2e\n",
           straddle, p[3].spread, fit.outliers, outliers_right, fit.used, fit.de_after_mean,
           fit.de_after_max, worst / norm);
    CHECK(straddle == 4);
    CHECK(outliers_right == 8 && fit.outliers == 8);
    CHECK(fit.used == 12);
    CHECK(fit.de_after_mean <= 1.0 && fit.de_after_max <= 3.0);
    CHECK(worst / norm < 0.02);
    /* Still a ColorChecker: the lit half carries it. */
    sl_chart_judgement j;
    sl_chart_judge(p, &fit, SL_COLORCHECKER_LINEAR, &j);
    CHECK_MSG(j.plausible, "half in shadow refused: %s", j.text);
    /* With the outlier test off, the shadowed patches drag the fit. */
    sl_ccm_options o;
    sl_ccm_options_init(&o);
    o.outlier_ratio = 0;
    sl_ccm_fit raw;
    CHECK_OK(sl_ccm_fit_chart(p, SL_COLORCHECKER_LINEAR, &o, &raw, &err), &err);
    printf("  without the outlier test: %d used, dE2000 after mean %.3f max %.3f\n", raw.used,
           raw.de_after_mean, raw.de_after_max);
    CHECK(raw.used == 20 && raw.de_after_mean > 3);
    sl_image_free(&img);
}

static void test_too_few_patches(void)
{
    sl_chart_patch p[24];
    memset(p, 0, sizeof(p));
    for (int i = 0; i < 5; i++) {
        p[i].valid = true;
        p[i].pixels = 10;
        memcpy(p[i].rgb, SL_COLORCHECKER_LINEAR[i], sizeof(p[i].rgb));
    }
    sl_ccm_fit fit;
    sl_error err;
    CHECK_RESULT(sl_ccm_fit_chart(p, SL_COLORCHECKER_LINEAR, NULL, &fit, &err), SL_ERR_INPUT,
                 &err);
    CHECK(strstr(err.message, "5 usable") != NULL);
}

int main(void)
{
    RUN(test_rendered_chart_is_reference);
    RUN(test_corners);
    RUN(test_fit_exact);
    RUN(test_fit_noisy);
    RUN(test_fit_white_preserving);
    RUN(test_half_in_shadow);
    RUN(test_too_few_patches);
    return sl_test_finish();
}
