/* SPDX-License-Identifier: BSD-3-Clause */
/* The virtual set's scoring (vset/vset_score.c) on images and rigs whose
 * answers are known: a lat-long twice the truth with a quarter of the band
 * 10% bright, a merged photo with clipped pixels, a rig with two lamps in
 * one light and one lamp it missed, the light a chart receives (the white
 * a chart-calibrated map is scored in). */
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/vset.h"
#include "testing.h"

#define W 64
#define H 32

/* A smooth truth: brighter up, never dark. */
static void make_truth(sl_image *t)
{
    sl_error err = {0};
    CHECK_OK(sl_image_alloc(t, W, H, 3, &err), &err);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float *p = sl_image_pixel(t, x, y);
            p[0] = p[1] = p[2] = (float)(1 + 0.5 * (H - y) / H + 0.1 * x / W);
        }
}

/* test = 2 truth; the band's texels in the first quarter of the width
 * (longitudes +180..+90: none faces +Z) 10% brighter. */
static void latlong_known(void)
{
    sl_image truth, test;
    sl_error err = {0};
    make_truth(&truth);
    CHECK_OK(sl_image_alloc(&test, W, H, 4, &err), &err);
    double band_sr = 0, quarter_power = 0, power = 0;
    for (int y = 0; y < H; y++) {
        double lat = 90 - 180 * (y + 0.5) / H, dw = sl_latlong_texel_solid_angle(y, W, H);
        for (int x = 0; x < W; x++) {
            const float *t = sl_image_pixel(&truth, x, y);
            float *p = sl_image_pixel(&test, x, y);
            bool bright = fabs(lat) <= 60 && x < W / 4;
            for (int c = 0; c < 3; c++)
                p[c] = 2 * t[c] * (bright ? 1.1f : 1.0f);
            p[3] = 1;
            band_sr += fabs(lat) <= 60 ? dw : 0;
            quarter_power += bright ? 0.1 * t[1] * dw : 0;
            power += t[1] * dw;
        }
    }
    sl_vset_image_score s;
    CHECK_OK(sl_vset_score_latlong(&test, NULL, &truth, 60, NULL, &s, &err), &err);
    CHECK_NEAR(s.scale, 2, 1e-6);
    CHECK_NEAR(s.median, 0, 1e-6);
    CHECK_NEAR(s.p95, 0.1, 1e-5);
    CHECK_NEAR(s.power, 1 + quarter_power / power, 1e-6);
    CHECK_NEAR(s.solid_angle_sr, band_sr, 1e-9);
    CHECK(s.pixels > 0);

    /* the half of the sphere around +Z holds none of the bright texels */
    const double toward[3] = {0, 0, 1};
    CHECK_OK(sl_vset_score_latlong(&test, NULL, &truth, 60, toward, &s, &err), &err);
    CHECK_NEAR(s.p95, 0, 1e-6);
    CHECK_NEAR(s.solid_angle_sr, band_sr / 2, 1e-9);

    /* unseen texels (alpha 0) are not compared */
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W / 4; x++)
            sl_image_pixel(&test, x, y)[3] = 0;
    CHECK_OK(sl_vset_score_latlong(&test, NULL, &truth, 60, NULL, &s, &err), &err);
    CHECK_NEAR(s.p95, 0, 1e-6);

    /* the test's RGB through a matrix first: a camera's space */
    const double half[3][3] = {{0.5, 0, 0}, {0, 0.5, 0}, {0, 0, 0.5}};
    CHECK_OK(sl_vset_score_latlong(&test, half, &truth, 60, NULL, &s, &err), &err);
    CHECK_NEAR(s.scale, 1, 1e-6);

    /* an image against a truth of another size is refused */
    sl_image small = {0};
    CHECK_OK(sl_image_alloc(&small, 16, 8, 3, &err), &err);
    CHECK_RESULT(sl_vset_score_image(&test, NULL, &small, NULL, &s, &err), SL_ERR_INPUT, &err);
    sl_image_free(&small);
    sl_image_free(&truth);
    sl_image_free(&test);
}

/* A merge four times the truth, its clipped pixels wrong, a black border. */
static void image_known(void)
{
    sl_image truth, test, clipped;
    sl_error err = {0};
    make_truth(&truth);
    CHECK_OK(sl_image_alloc(&test, W, H, 3, &err), &err);
    CHECK_OK(sl_image_alloc(&clipped, W, H, 3, &err), &err);
    int compared = 0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float *t = sl_image_pixel(&truth, x, y), *p = sl_image_pixel(&test, x, y);
            float *m = sl_image_pixel(&clipped, x, y);
            bool border = x < 2, clip = y < 4;
            for (int c = 0; c < 3; c++) {
                if (border)
                    t[c] = 0;
                p[c] = (clip ? 100 : 4) * t[c] + (border ? 0.5f : 0);
                m[c] = clip && c == 1 ? 1 : 0;
            }
            compared += !border && !clip;
        }
    sl_vset_image_score s;
    CHECK_OK(sl_vset_score_image(&test, NULL, &truth, &clipped, &s, &err), &err);
    CHECK(s.pixels == compared);
    CHECK_NEAR(s.scale, 4, 1e-6);
    CHECK_NEAR(s.p95, 0, 1e-6);
    CHECK_NEAR(s.power, 1, 1e-6);
    /* without the mask the clipped rows count: an eighth of the pixels 25 times off */
    CHECK_OK(sl_vset_score_image(&test, NULL, &truth, NULL, &s, &err), &err);
    CHECK_NEAR(s.scale, 4, 1e-6);
    CHECK_NEAR(s.p95, 24, 1e-4);
    sl_image_free(&truth);
    sl_image_free(&test);
    sl_image_free(&clipped);
}

static json_t *dir_json(double az_deg, double el_deg)
{
    double az = az_deg * M_PI / 180, el = el_deg * M_PI / 180;
    return json_pack("[f,f,f]", sin(az) * cos(el), sin(el), cos(az) * cos(el));
}

/* Lamps at azimuth 0 and 3 (one rig light at 1.5), 90 (a rig light at 91,
 * 20% bright), 180 (no rig light near): the rig made from a map twice the
 * truth. */
static void rig_known(void)
{
    sl_error err = {0};
    double az[4] = {0, 3, 90, 180}, y[4] = {10, 30, 5, 7};
    json_t *lamps = json_array();
    for (int i = 0; i < 4; i++)
        json_array_append_new(lamps, json_pack("{s:o, s:[f,f,f]}", "direction", dir_json(az[i], 0),
                                               "integral_rgb", y[i], y[i], y[i]));
    json_t *truth = json_pack("{s:o}", "lights", lamps);
    json_t *rig = json_pack("{s:i, s:[{s:o, s:[f,f,f]}, {s:o, s:[f,f,f]}, {s:o, s:[f,f,f]}]}",
                            "version", 2, "lights", "direction", dir_json(1.5, 0), "integral",
                            80.0, 80.0, 80.0, "direction", dir_json(91, 0), "integral", 12.0, 12.0,
                            12.0, "direction", dir_json(0, -60), "integral", 1.0, 1.0, 1.0);
    char tp[4096], rp[4096];
    snprintf(tp, sizeof tp, "%s", sl_test_path("lights.json"));
    snprintf(rp, sizeof rp, "%s", sl_test_path("rig.json"));
    CHECK_OK(sl_json_write_atomic(tp, truth, 0, &err), &err);
    CHECK_OK(sl_json_write_atomic(rp, rig, 0, &err), &err);
    json_decref(truth);
    json_decref(rig);
    sl_vset_rig_score s;
    CHECK_OK(sl_vset_score_rig(rp, tp, 2, NULL, 5, &s, &err), &err);
    CHECK(s.truth_lights == 4 && s.rig_lights == 3 && s.matched == 3);
    CHECK_NEAR(s.direction_worst_deg, 1.5, 1e-6);
    CHECK_NEAR(s.direction_mean_deg, (1.5 + 1.5 + 1) / 3, 1e-6);
    /* 80 / 2 against 10 + 30: 1; 12 / 2 against 5: 1.2 */
    CHECK_NEAR(s.power_worst, 1.2, 1e-9);
    CHECK_NEAR(s.power_median, 1.2, 1e-9); /* the upper of two */
    /* in a white that halves red and doubles blue, the grey lamps' luminance
     * is 0.2126 / 2 + 0.7152 + 0.0722 * 2 = 0.9659 of theirs */
    const double white[3] = {0.5, 1, 2};
    CHECK_OK(sl_vset_score_rig(rp, tp, 2, white, 5, &s, &err), &err);
    CHECK_NEAR(s.power_worst, 1.2 / 0.9659, 1e-9);
    CHECK_NEAR(s.power_median, 1.2 / 0.9659, 1e-9);
    /* a stricter match leaves the 1.5-degree pair out */
    CHECK_OK(sl_vset_score_rig(rp, tp, 2, NULL, 1.2, &s, &err), &err);
    CHECK(s.matched == 1);
    /* a file that is no rig names itself */
    CHECK_RESULT(sl_vset_score_rig(sl_test_path("nope.json"), tp, 1, NULL, 5, &s, &err),
                 SL_ERR_NOT_FOUND, &err);
    CHECK(strstr(err.message, "nope.json") != NULL);
}

/* A flat surface facing +Z under a set whose half in front (z > 0) has
 * radiance (1, 2, 3) and whose half behind is 100: the irradiance is
 * pi (1, 2, 3), the half behind adds nothing; turned to face -Z it is
 * pi 100. */
static void irradiance_known(void)
{
    sl_image ll;
    sl_error err = {0};
    CHECK_OK(sl_image_alloc(&ll, 512, 256, 3, &err), &err);
    for (int y = 0; y < ll.height; y++)
        for (int x = 0; x < ll.width; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / ll.width, (y + 0.5) / ll.height, d);
            float *p = sl_image_pixel(&ll, x, y);
            for (int c = 0; c < 3; c++)
                p[c] = d[2] > 0 ? (float)(c + 1) : 100.0f;
        }
    const double front[3] = {0, 0, 1}, back[3] = {0, 0, -1};
    double e[3];
    sl_vset_irradiance(&ll, front, e);
    for (int c = 0; c < 3; c++)
        CHECK_NEAR(e[c] / (M_PI * (c + 1)), 1, 1e-4);
    sl_vset_irradiance(&ll, back, e);
    for (int c = 0; c < 3; c++)
        CHECK_NEAR(e[c] / (M_PI * 100), 1, 1e-4);
    sl_image_free(&ll);
}

int main(void)
{
    RUN(latlong_known);
    RUN(image_known);
    RUN(rig_known);
    RUN(irradiance_known);
    return sl_test_finish();
}
