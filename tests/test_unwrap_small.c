/* SPDX-License-Identifier: BSD-3-Clause */
/* The unwrap at small sizes against a plain bicubic remap (each texel
 * centre mapped into the photo, one Keys cubic lookup, as cv2.remap with
 * INTER_CUBIC): an ideal orthographic ball filling its frame, 256, 512 and
 * 1024 px across, unwrapped to N x N/2, scored against the environment's
 * texel means within 110 degrees of the direction back at the camera. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "ball_fixture.h"
#include "setlight/stitch.h"
#include "testing.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* A uniform value in [0, 1) for a noise lattice point of octave k. */
static double hash01(uint32_t x, uint32_t y, uint32_t k)
{
    uint64_t state = (uint64_t)x << 42 ^ (uint64_t)y << 21 ^ k;
    return sl_test_uniform(&state);
}

/* A 1024 x 512 lat-long with detail at every scale down to the texel (value
 * noise, octaves of equal amplitude, as real HDRIs have: edges and texture
 * at the texel), log-normal, and a small bright lamp. */
static sl_result detailed_env(sl_image *env, sl_error *err)
{
    const int w = 1024, h = 512;
    sl_result r = sl_image_alloc(env, w, h, 3, err);
    if (r)
        return r;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float *p = sl_image_pixel(env, x, y);
            for (int k = 0; k < 3; k++) {
                double s = 0.0;
                for (int o = 0; o < 8; o++) {
                    /* Bilinear value noise with cells of 2^o texels (wrapping
                     * in longitude). */
                    int cell = 1 << o, nx = w / cell;
                    double fx = (x + 0.5) / cell - 0.5, fy = (y + 0.5) / cell - 0.5;
                    double x0 = floor(fx), y0 = floor(fy), tx = fx - x0, ty = fy - y0;
                    uint32_t ix0 = (uint32_t)(((int)x0 % nx + nx) % nx), ix1 = (ix0 + 1) % (uint32_t)nx;
                    uint32_t iy0 = (uint32_t)(y0 + 1), iy1 = iy0 + 1, kk = (uint32_t)(o + 8 * (k > 0));
                    double v = (1 - ty) * ((1 - tx) * hash01(ix0, iy0, kk) + tx * hash01(ix1, iy0, kk)) +
                               ty * ((1 - tx) * hash01(ix0, iy1, kk) + tx * hash01(ix1, iy1, kk));
                    s += v - 0.5;
                }
                p[k] = (float)(exp(1.2 * s) * (k == 2 ? 1.1 : (k == 0 ? 0.9 : 1.0)));
            }
            if (abs(x - 300) <= 1 && abs(y - 180) <= 1)
                p[0] = p[1] = p[2] = 500.0f;
        }
    return SL_OK;
}

/* Keys' cubic convolution kernel, a = -0.75 (OpenCV's INTER_CUBIC). */
static double keys(double t)
{
    const double a = -0.75;
    t = fabs(t);
    if (t < 1.0)
        return ((a + 2.0) * t - (a + 3.0)) * t * t + 1.0;
    if (t < 2.0)
        return ((a * t - 5.0 * a) * t + 8.0 * a) * t - 4.0 * a;
    return 0.0;
}

/* One bicubic lookup at photo point (x, y), pixel centres at i + 0.5,
 * edge pixels repeated (BORDER_REPLICATE). */
static void bicubic_lookup(const sl_image *img, double x, double y, float *out)
{
    double fx = x - 0.5, fy = y - 0.5, x0 = floor(fx), y0 = floor(fy);
    double wx[4], wy[4], rgb[3] = {0, 0, 0};
    for (int i = 0; i < 4; i++) {
        wx[i] = keys(fx - (x0 - 1 + i));
        wy[i] = keys(fy - (y0 - 1 + i));
    }
    for (int j = 0; j < 4; j++) {
        int yi = (int)y0 - 1 + j;
        yi = yi < 0 ? 0 : (yi >= img->height ? img->height - 1 : yi);
        for (int i = 0; i < 4; i++) {
            int xi = (int)x0 - 1 + i;
            xi = xi < 0 ? 0 : (xi >= img->width ? img->width - 1 : xi);
            const float *p = sl_image_pixel(img, xi, yi);
            for (int k = 0; k < 3; k++)
                rgb[k] += wx[i] * wy[j] * p[k];
        }
    }
    for (int k = 0; k < 3; k++)
        out[k] = (float)rgb[k];
}

/* Median relative luminance error of est against truth within max_deg of
 * the direction back at the camera (-axis, axis the camera's view). */
static double median_error(const sl_image *est, const sl_image *truth, const double axis[3],
                           double max_deg)
{
    int w = est->width, h = est->height, n = 0;
    double *rel = malloc(sizeof(double) * (size_t)w * (size_t)h);
    if (!rel)
        return NAN;
    double c = cos(max_deg * M_PI / 180.0);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / h, d);
            if (-(d[0] * axis[0] + d[1] * axis[1] + d[2] * axis[2]) < c)
                continue;
            double lt = sl_luminance_px(sl_image_pixel(truth, x, y));
            rel[n++] = fabs(sl_luminance_px(sl_image_pixel(est, x, y)) - lt) / lt;
        }
    double m = sl_test_median(rel, (size_t)n);
    free(rel);
    return m;
}

/* The lat-long's own texels averaged k x k (solid-angle weighted) to the
 * output's size: the point values of its bilinear surface at the output's
 * texel centres when k is 1 or 2, not the surface's texel means. */
static sl_result area_down(const sl_image *env, int k, sl_image *out, sl_error *err)
{
    sl_result r = sl_image_alloc(out, env->width / k, env->height / k, 3, err);
    for (int y = 0; !r && y < out->height; y++)
        for (int x = 0; x < out->width; x++) {
            double acc[3] = {0, 0, 0}, ws = 0.0;
            for (int j = 0; j < k; j++) {
                int ey = y * k + j;
                double wt = sl_latlong_texel_solid_angle(ey, env->width, env->height);
                for (int i = 0; i < k; i++) {
                    const float *p = sl_image_pixel(env, x * k + i, ey);
                    for (int c = 0; c < 3; c++)
                        acc[c] += wt * p[c];
                    ws += wt;
                }
            }
            float *p = sl_image_pixel(out, x, y);
            for (int c = 0; c < 3; c++)
                p[c] = (float)(acc[c] / ws);
        }
    return r;
}

static void test_small_balls(void)
{
    static const int sizes[] = {256, 512, 1024};
    sl_image env = {0};
    sl_error err;
    if (detailed_env(&env, &err)) {
        CHECK_MSG(false, "%s", err.message);
        return;
    }
    for (size_t s = 0; s < sizeof sizes / sizeof *sizes; s++) {
        int n = sizes[s];
        ball_fixture f;
        ball_fixture_init(&f, n, n);
        f.balls[0].r = 0.5 * n;
        f.clutter = false;
        f.ss = 2;
        f.env = &env;
        f.azimuth_deg = 180;
        sl_image photo = {0}, out = {0}, truth = {0}, remap = {0}, texels = {0};
        sl_unwrap_options o = {.geometry = {.camera = SL_BALL_ORTHOGRAPHIC,
                                            .azimuth_deg = f.azimuth_deg},
                               .width = n,
                               .no_confidence = true};
        ball_fixture_circle(&f, 0, &o.circle);
        o.reflectance = f.reflectance;
        sl_ball_view v;
        /* Truth sub-samples: 2 per environment texel along each axis. */
        int sub = 2 * env.width / n;
        if (sl_ball_view_init(&v, n, n, &o.circle, &o.geometry, &err) ||
            ball_fixture_render(&f, &photo, &err) || sl_unwrap(&photo, &o, &out, NULL, &err) ||
            ball_fixture_truth(&f, n, sub, &truth, &err) ||
            area_down(&env, env.width / n, &texels, &err) ||
            sl_image_alloc(&remap, n, n / 2, 3, &err)) {
            CHECK_MSG(false, "%s", err.message);
            goto next;
        }
        for (int y = 0; y < n / 2; y++)
            for (int x = 0; x < n; x++) {
                double d[3], px, py, ci;
                sl_latlong_to_dir((x + 0.5) / n, (y + 0.5) / (n / 2), d);
                sl_ball_view_dir_to_pixel(&v, d, &px, &py, &ci);
                bicubic_lookup(&photo, px, py, sl_image_pixel(&remap, x, y));
            }
        double axis[3];
        for (int k = 0; k < 3; k++)
            axis[k] = v.cam_to_world[k][2];
        double es = median_error(&out, &truth, axis, 110.0);
        double eb = median_error(&remap, &truth, axis, 110.0);
        double ps = median_error(&out, &texels, axis, 110.0);
        double pb = median_error(&remap, &texels, axis, 110.0);
        printf("  %d px ball -> %dx%d, median rel. error within 110 deg: against the texel means "
               "setlight %.5f, bicubic remap %.5f (ratio %.3f); against the lat-long's texels "
               "averaged %dx%d %.5f, %.5f (%.3f)\n",
               n, n, n / 2, es, eb, es / eb, env.width / n, env.width / n, ps, pb, ps / pb);
        CHECK_MSG(es <= 0.9 * eb, "%d px: setlight %.5f > 0.9 x bicubic remap %.5f", n, es, eb);
    next:
        sl_image_free(&photo);
        sl_image_free(&out);
        sl_image_free(&truth);
        sl_image_free(&remap);
        sl_image_free(&texels);
    }
    sl_image_free(&env);
}

int main(void)
{
    RUN(test_small_balls);
    return sl_test_finish();
}
