/* SPDX-License-Identifier: BSD-3-Clause */
/* The simulated camera: exposure, noise statistics against the model,
 * clipping, quantisation, determinism, invertibility of the whole chain
 * with the true response and exposure, response curves and lens geometry. */
#include <stdlib.h>
#include <string.h>

#include "setlight/vset.h"
#include "testing.h"

#define PI 3.14159265358979323846

static void fill_rgb(sl_image *img, double r, double g, double b)
{
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            float *p = sl_image_pixel(img, x, y);
            p[0] = (float)r;
            p[1] = (float)g;
            p[2] = (float)b;
        }
}

static void test_exposure(void)
{
    sl_vset_camera cam;
    sl_vset_camera_default(&cam, 5500);
    /* Sunny 16: an 18% grey card in 100 klx sun at 1/100 s, f/16, ISO 100
     * lands near 19% of raw saturation (ISO 12232 saturation speed). */
    sl_vset_exposure e = {0.01, 16, 100};
    double x = 0.18 * 100000 / PI * sl_vset_exposure_scale(&cam, &e);
    CHECK_NEAR(x, 0.187, 0.002);
    sl_vset_exposure e2 = {0.02, 16, 100}, e3 = {0.01, 16 * sqrt(2), 100}, e4 = {0.01, 16, 400};
    CHECK_NEAR(sl_vset_exposure_scale(&cam, &e2) / sl_vset_exposure_scale(&cam, &e), 2, 1e-12);
    CHECK_NEAR(sl_vset_exposure_scale(&cam, &e3) / sl_vset_exposure_scale(&cam, &e), 0.5, 1e-12);
    CHECK_NEAR(sl_vset_exposure_scale(&cam, &e4) / sl_vset_exposure_scale(&cam, &e), 4, 1e-12);
    /* A white of luminance L gives green = L on the sensor. */
    double g = cam.cam_from_rec709[1][0] + cam.cam_from_rec709[1][1] + cam.cam_from_rec709[1][2];
    CHECK_NEAR(g, 1, 1e-12);
    /* The camera's colour differs from the working space, but a white lit
     * at the white-balance colour comes out neutral. */
    double m[3][3], off = 0;
    sl_vset_camera_output_matrix(&cam, m);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            off = fmax(off, fabs(m[i][j] - (i == j)));
    CHECK(off > 0.05);
    double w[3];
    sl_vset_kelvin_rgb(5500, w);
    double o[3] = {0, 0, 0};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            o[i] += m[i][j] * w[j];
    CHECK_NEAR(o[0] / o[1], 1, 1e-9);
    CHECK_NEAR(o[2] / o[1], 1, 1e-9);
}

/* Mean and std of one channel of an image. */
static void moments(const sl_image *img, int c, double *mean, double *sd)
{
    double s = 0, s2 = 0;
    int n = img->width * img->height;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            double v = sl_image_pixel(img, x, y)[c];
            s += v;
            s2 += v * v;
        }
    *mean = s / n;
    *sd = sqrt(fmax(0, s2 / n - *mean * *mean) * n / (n - 1.0));
}

static void check_flat_noise(double iso, double target_x)
{
    sl_vset_camera cam;
    sl_error err;
    sl_vset_camera_default(&cam, 5500);
    sl_vset_exposure e = {0.01, 8, iso};
    double scale = sl_vset_exposure_scale(&cam, &e);
    sl_image rad;
    CHECK_OK(sl_image_alloc(&rad, 256, 256, 3, &err), &err);
    double L = target_x / scale;
    fill_rgb(&rad, L, L, L);
    sl_vset_shot shot;
    CHECK_OK(sl_vset_camera_shoot(&cam, &e, &rad, 42, &shot, &err), &err);
    double q = 1.0 / ((1 << cam.raw_bits) - 1);
    for (int c = 0; c < 3; c++) {
        double x = (cam.cam_from_rec709[c][0] + cam.cam_from_rec709[c][1] +
                    cam.cam_from_rec709[c][2]) * L * scale;
        double sd_model = sl_vset_sensor_noise_std(&cam, iso, x);
        sd_model = sqrt(sd_model * sd_model + q * q / 12);
        double mean, sd;
        moments(&shot.sensor, c, &mean, &sd);
        printf("  ISO %g X %.4g ch %d: std %.4g model %.4g (ratio %.4f), mean %.5g\n", iso, x,
               c, sd, sd_model, sd / sd_model, mean);
        CHECK_NEAR(sd / sd_model, 1, 0.05);
        CHECK_NEAR(mean, x, 4 * sd_model / 256 + q);
    }
    sl_vset_shot_free(&shot);
    sl_image_free(&rad);
}

static void test_noise(void)
{
    check_flat_noise(100, 0.2);
    check_flat_noise(1600, 0.05);
    check_flat_noise(6400, 0.005); /* a few electrons: Poisson by counting */
}

static bool invert3(const double m[3][3], double out[3][3])
{
    double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                 m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                 m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    if (det == 0)
        return false;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            int a = (j + 1) % 3, b = (j + 2) % 3, c = (i + 1) % 3, d = (i + 2) % 3;
            out[i][j] = (m[a][c] * m[b][d] - m[a][d] * m[b][c]) / det;
        }
    return true;
}

static void test_clipping_and_quantisation(void)
{
    sl_vset_camera cam;
    sl_error err;
    sl_vset_camera_default(&cam, 5500);
    sl_vset_exposure e = {0.01, 8, 100};
    double scale = sl_vset_exposure_scale(&cam, &e);
    const int w = 1000;
    sl_image rad;
    CHECK_OK(sl_image_alloc(&rad, w, 4, 3, &err), &err);
    /* Green-only ramp through raw saturation, X from 0.5 to 1.5. */
    double inv[3][3];
    CHECK(invert3(cam.cam_from_rec709, inv));
    for (int y = 0; y < 4; y++)
        for (int x = 0; x < w; x++) {
            double X = 0.5 + (double)x / w;
            float *p = sl_image_pixel(&rad, x, y);
            for (int c = 0; c < 3; c++)
                p[c] = (float)(inv[c][1] * X / scale);
        }
    sl_vset_shot shot;
    CHECK_OK(sl_vset_camera_shoot(&cam, &e, &rad, 7, &shot, &err), &err);
    int wrong = 0, levels_bad = 0;
    double q = (1 << 14) - 1;
    for (int y = 0; y < 4; y++)
        for (int x = 0; x < w; x++) {
            const float *p = sl_image_pixel(&rad, x, y);
            double X = (cam.cam_from_rec709[1][0] * p[0] + cam.cam_from_rec709[1][1] * p[1] +
                        cam.cam_from_rec709[1][2] * p[2]) * scale;
            double sd = sl_vset_sensor_noise_std(&cam, 100, X);
            float g = sl_image_pixel(&shot.sensor, x, y)[1];
            if (X > 1 + 6 * sd && g != 1.0f)
                wrong++;
            if (X < 1 - 6 * sd && g >= 1.0f)
                wrong++;
            for (int c = 0; c < 3; c++) {
                double v = sl_image_pixel(&shot.sensor, x, y)[c] * q;
                if (fabs(v - floor(v + 0.5)) > 1e-3)
                    levels_bad++;
                float l = sl_image_pixel(&shot.linear, x, y)[c];
                if (l < 0 || l > 1)
                    wrong++;
            }
        }
    CHECK(wrong == 0);
    CHECK(levels_bad == 0);
    sl_vset_shot_free(&shot);

    /* 12-bit raw: values on 4095 levels. */
    cam.raw_bits = 12;
    CHECK_OK(sl_vset_camera_shoot(&cam, &e, &rad, 7, &shot, &err), &err);
    levels_bad = 0;
    for (int x = 0; x < w; x++) {
        double v = sl_image_pixel(&shot.sensor, x, 0)[0] * 4095.0;
        if (fabs(v - floor(v + 0.5)) > 1e-3)
            levels_bad++;
    }
    CHECK(levels_bad == 0);
    /* 8-bit output: 256 levels. */
    sl_vset_quantize(&shot.encoded, 8);
    int distinct = 0, seen[256] = {0};
    for (int x = 0; x < w; x++) {
        double v = sl_image_pixel(&shot.encoded, x, 0)[1] * 255.0;
        CHECK_MSG(fabs(v - floor(v + 0.5)) < 1e-4, "8-bit level %g", v);
        int k = (int)floor(v + 0.5);
        if (!seen[k]++)
            distinct++;
    }
    CHECK(distinct > 10);
    sl_vset_shot_free(&shot);
    sl_image_free(&rad);
}

static void test_determinism(void)
{
    sl_vset_camera cam;
    sl_error err;
    sl_vset_camera_default(&cam, 3200);
    sl_vset_exposure e = {0.01, 4, 400};
    sl_image rad;
    CHECK_OK(sl_image_alloc(&rad, 200, 100, 3, &err), &err);
    fill_rgb(&rad, 20, 30, 10);
    sl_vset_shot a, b, c;
    sl_threads_set(1);
    CHECK_OK(sl_vset_camera_shoot(&cam, &e, &rad, 5, &a, &err), &err);
    sl_threads_set(2);
    CHECK_OK(sl_vset_camera_shoot(&cam, &e, &rad, 5, &b, &err), &err);
    CHECK_OK(sl_vset_camera_shoot(&cam, &e, &rad, 6, &c, &err), &err);
    sl_threads_set(0);
    size_t n = a.sensor.stride * (size_t)a.sensor.height;
    CHECK(memcmp(a.encoded.data, b.encoded.data, n * sizeof(float)) == 0);
    CHECK(memcmp(a.sensor.data, b.sensor.data, n * sizeof(float)) == 0);
    size_t differ = 0;
    for (size_t i = 0; i < n; i++)
        differ += a.sensor.data[i] != c.sensor.data[i];
    CHECK(differ > n * 9 / 10);
    sl_vset_shot_free(&a);
    sl_vset_shot_free(&b);
    sl_vset_shot_free(&c);
    sl_vset_exposure bad = {0, 4, 400};
    CHECK_RESULT(sl_vset_camera_shoot(&cam, &bad, &rad, 5, &a, &err), SL_ERR_USAGE, &err);
    CHECK(a.sensor.data == NULL);
    sl_image_free(&rad);
}

/* A bracket of 7 exposures 3 stops apart of a grey ramp from 1e-2 to 1e5
 * cd/m^2, inverted pixel by pixel with the true response, matrix and
 * exposure. The error is compared with the std the noise model predicts
 * (sensor noise, raw quantisation, and output quantisation through the
 * response's slope). */
static void check_invert(const char *response, int out_bits, bool per_pixel)
{
    sl_vset_camera cam;
    sl_error err;
    sl_vset_camera_default(&cam, 5500);
    CHECK_OK(sl_vset_response_preset(response, &cam.response, &err), &err);
    const int w = 700, h = 24;
    sl_image rad;
    CHECK_OK(sl_image_alloc(&rad, w, h, 3, &err), &err);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double L = pow(10, -2 + 7.0 * (x + 0.5) / w);
            float *p = sl_image_pixel(&rad, x, y);
            p[0] = p[1] = p[2] = (float)L;
        }
    double mout[3][3], minv[3][3], cinv[3][3];
    sl_vset_camera_output_matrix(&cam, mout);
    invert3(mout, minv);
    invert3(cam.cam_from_rec709, cinv);
    double qraw = 1.0 / ((1 << cam.raw_bits) - 1), qout = 1.0 / ((1 << out_bits) - 1);
    long used = 0, outliers = 0;
    double rel_sum = 0;
    for (int k = 0; k < 7; k++) {
        sl_vset_exposure e = {1.0 / 4000 * pow(8, k), 8, 100};
        double scale = sl_vset_exposure_scale(&cam, &e);
        sl_vset_shot shot;
        CHECK_OK(sl_vset_camera_shoot(&cam, &e, &rad, 100 + (uint64_t)k, &shot, &err), &err);
        sl_vset_quantize(&shot.encoded, out_bits);
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                const float *pe = sl_image_pixel(&shot.encoded, x, y);
                double L = sl_image_pixel(&rad, x, y)[0], lin[3], raw[3], ok = 1;
                /* Pixels are chosen by their noise-free value: choosing by
                 * the measured one would bias the mean near the limits. */
                for (int c = 0; c < 3; c++) {
                    lin[c] = sl_vset_response_invert(&cam.response, pe[c]);
                    double ideal = (mout[c][0] + mout[c][1] + mout[c][2]) * L * scale;
                    if (ideal < 0.03 || ideal > 0.85)
                        ok = 0;
                }
                double xr = L * scale;
                for (int c = 0; c < 3; c++) {
                    raw[c] = (cam.cam_from_rec709[c][0] + cam.cam_from_rec709[c][1] +
                              cam.cam_from_rec709[c][2]) * xr;
                    if (raw[c] * cam.wb[c] > 0.95)
                        ok = 0;
                }
                if (!ok)
                    continue;
                for (int i = 0; i < 3; i++) {
                    double est = 0, var = 0;
                    for (int j = 0; j < 3; j++) {
                        est += minv[i][j] * lin[j];
                        double sr = sl_vset_sensor_noise_std(&cam, e.iso, raw[j]);
                        var += cinv[i][j] * cinv[i][j] * (sr * sr + qraw * qraw / 12);
                        double slope = sl_vset_response_slope(&cam.response,
                                                              sl_vset_response_invert(&cam.response, pe[j]));
                        double sq = qout / slope;
                        var += minv[i][j] * minv[i][j] * sq * sq / 12;
                    }
                    est /= scale;
                    double sd = sqrt(var) / scale;
                    if (fabs(est - L) > 4 * sd)
                        outliers++;
                    rel_sum += (est - L) / L;
                    used++;
                }
            }
        sl_vset_shot_free(&shot);
    }
    double frac = (double)outliers / (double)used, mean_rel = rel_sum / (double)used;
    printf("  %s %d-bit: %ld samples, beyond 4 sigma %.2e, mean relative error %.2e\n", response,
           out_bits, used, frac, mean_rel);
    CHECK(used > 10000);
    if (per_pixel)
        CHECK(frac < 1e-3);
    CHECK(fabs(mean_rel) < 0.005);
    sl_image_free(&rad);
}

static void test_invertible(void)
{
    check_invert("canon", 16, true);
    check_invert("srgb", 16, true);
    check_invert("filmic", 16, true);
    check_invert("canon", 8, false);
}

static void test_responses(void)
{
    sl_vset_response r;
    sl_error err;
    CHECK_OK(sl_vset_response_preset("srgb", &r, &err), &err);
    CHECK_NEAR(sl_vset_response_apply(&r, 0.18), 0.4614, 0.001);
    for (double x = 0.001; x < 1; x *= 1.3)
        CHECK_NEAR(sl_vset_response_invert(&r, sl_vset_response_apply(&r, x)), x, 1e-9);
    CHECK_OK(sl_vset_response_preset("filmic", &r, &err), &err);
    CHECK_NEAR(sl_vset_response_apply(&r, 1), 1, 1e-12);
    CHECK(sl_vset_response_slope(&r, 0.01) < sl_vset_response_slope(&r, 0.1)); /* toe */
    CHECK(sl_vset_response_slope(&r, 0.95) < 0.5);          /* shoulder */
    CHECK_RESULT(sl_vset_response_preset("velvia", &r, &err), SL_ERR_USAGE, &err);

    /* Plain "I B" text: a gamma 2 curve. */
    const char *p = sl_test_path("gamma.txt");
    FILE *f = fopen(p, "w");
    for (int i = 0; i <= 100; i++)
        fprintf(f, "%g %g\n", i / 100.0, sqrt(i / 100.0));
    fclose(f);
    CHECK_OK(sl_vset_response_load(p, NULL, &r, &err), &err);
    CHECK_NEAR(sl_vset_response_apply(&r, 0.25), 0.5, 0.002);
    const char *bad = sl_test_path("bad.txt");
    f = fopen(bad, "w");
    fputs("0 0\n0.5 zebra\n", f);
    fclose(f);
    CHECK_RESULT(sl_vset_response_load(bad, NULL, &r, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, bad) != NULL);

    const char *dorf = sl_test_data("crf/dorfCurves.txt");
    if (!dorf)
        return;
    CHECK_OK(sl_vset_response_load(dorf, NULL, &r, &err), &err);
    CHECK(strcmp(r.name, "agfacolor-futura-100CDRed") == 0);
    CHECK_OK(sl_vset_response_load(dorf, "agfacolor-futura-100CDBlue", &r, &err), &err);
    CHECK(strcmp(r.name, "agfacolor-futura-100CDBlue") == 0);
    bool mono = true;
    for (int i = 1; i < SL_VSET_CRF_SAMPLES; i++)
        mono = mono && r.curve[i] >= r.curve[i - 1];
    CHECK(mono && r.curve[0] == 0 && r.curve[SL_VSET_CRF_SAMPLES - 1] == 1);
    CHECK(sl_vset_response_apply(&r, 0.18) > 0.3); /* film curves lift the mid-tones */
    CHECK_RESULT(sl_vset_response_load(dorf, "no-such-film", &r, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "no-such-film") != NULL);
}

static void test_lens_geometry(void)
{
    sl_vset_lens rl;
    sl_vset_lens_rectilinear(&rl, 100);
    const int w = 1200, h = 800;
    double p = 36.0 / w;
    sl_vset_view v = {30, 10, 5};
    double fwd[3] = {sin(30 * PI / 180) * cos(10 * PI / 180), sin(10 * PI / 180),
                     cos(30 * PI / 180) * cos(10 * PI / 180)};
    for (int k = 0; k < 16; k++) {
        double phi = k * 0.7, rpx = 20.0 * k;
        double x = w / 2.0 + rpx * cos(phi), y = h / 2.0 + rpx * sin(phi), d[3], x2, y2;
        CHECK(sl_vset_lens_to_dir(&rl, &v, w, h, x, y, d));
        double ang = acos(fmin(1, d[0] * fwd[0] + d[1] * fwd[1] + d[2] * fwd[2]));
        CHECK_NEAR(ang, atan(rpx * p / 100), 1e-9);
        CHECK(sl_vset_lens_from_dir(&rl, &v, w, h, d, &x2, &y2));
        CHECK_NEAR(x2, x, 1e-7);
        CHECK_NEAR(y2, y, 1e-7);
    }
    double d[3];
    /* Orientation at yaw 0: image right is -X, image up is +Y. */
    sl_vset_view z = {0, 0, 0};
    CHECK(sl_vset_lens_to_dir(&rl, &z, w, h, w - 1, h / 2.0, d));
    CHECK(d[0] < 0 && fabs(d[1]) < 1e-12);
    CHECK(sl_vset_lens_to_dir(&rl, &z, w, h, w / 2.0, 0, d));
    CHECK(d[1] > 0 && fabs(d[0]) < 1e-12);
    sl_vset_view east = {90, 0, 0};
    CHECK(sl_vset_lens_to_dir(&rl, &east, w, h, w / 2.0, h / 2.0, d));
    CHECK_NEAR(d[0], 1, 1e-12);
    CHECK_NEAR(sl_vset_lens_vignette(&rl, w, h, w / 2.0, h / 2.0), 1, 1e-12);
    CHECK(sl_vset_lens_vignette(&rl, w, h, 0, 0) < sl_vset_lens_vignette(&rl, w, h, w / 4.0, h / 4.0));
}

static void test_lens_image(void)
{
    sl_error err;
    sl_image env, img;
    CHECK_OK(sl_image_alloc(&env, 512, 256, 3, &err), &err);
    sl_image_fill(&env, 1.0f);
    sl_lens fe;
    sl_vset_fisheye_true(&fe, 300, 200);
    sl_vset_view v = {0, 0, 0};
    sl_view_pose pose = {0, 0, 0};
    CHECK_OK(sl_vset_view_image(&fe, &pose, &env, 2, &img, &err), &err);
    CHECK_NEAR(sl_image_pixel(&img, 150, 100)[1], sl_lens_vignette(&fe, 150.5, 100.5), 0.002);
    CHECK(sl_image_pixel(&img, 0, 0)[0] == 0); /* outside the image circle */
    sl_image_free(&img);
    /* One bright texel lands where the lens geometry says. */
    sl_image_fill(&env, 0.0f);
    int tx = 270, ty = 120;
    for (int c = 0; c < 3; c++)
        sl_image_pixel(&env, tx, ty)[c] = 1000.0f;
    double u = (tx + 0.5) / 512, vv = (ty + 0.5) / 256;
    double lon = PI * (1 - 2 * u), lat = PI * (0.5 - vv);
    double d[3] = {sin(lon) * cos(lat), sin(lat), cos(lon) * cos(lat)}, ex, ey;
    sl_vset_lens rl;
    sl_vset_lens_rectilinear(&rl, 50);
    CHECK(sl_vset_lens_from_dir(&rl, &v, 300, 200, d, &ex, &ey));
    sl_lens rect;
    sl_lens_nominal(&rect, SL_LENS_RECTILINEAR, 300, 200, 50, 36);
    CHECK_OK(sl_vset_view_image(&rect, &pose, &env, 4, &img, &err), &err);
    double sx = 0, sy = 0, sw = 0;
    for (int y = 0; y < 200; y++)
        for (int x = 0; x < 300; x++) {
            double q = sl_image_pixel(&img, x, y)[0];
            sx += q * (x + 0.5);
            sy += q * (y + 0.5);
            sw += q;
        }
    CHECK(sw > 0);
    CHECK_NEAR(sx / sw, ex, 1.0);
    CHECK_NEAR(sy / sw, ey, 1.0);
    sl_image_free(&img);
    sl_image_free(&env);
}

int main(void)
{
    RUN(test_exposure);
    RUN(test_noise);
    RUN(test_clipping_and_quantisation);
    RUN(test_determinism);
    RUN(test_invertible);
    RUN(test_responses);
    RUN(test_lens_geometry);
    RUN(test_lens_image);
    return sl_test_finish();
}
