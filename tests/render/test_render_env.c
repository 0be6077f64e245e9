/* SPDX-License-Identifier: BSD-3-Clause */
/* The renderer under a dome: grey sphere against brute-force quadrature of
 * the irradiance, chi-square of the dome sampler, chrome highlight position
 * against core's mirror-ball projection, stability grid, determinism. */
#include <stdlib.h>
#include <string.h>

#include "../../render/render_internal.h"
#include "testing.h"

/* Smooth sky plus two bright spots: a synthetic map that always exists. */
static void synthetic_env(sl_image *env, int w)
{
    CHECK_OK(sl_image_alloc(env, w, w / 2, 3, NULL), NULL);
    for (int y = 0; y < w / 2; y++)
        for (int x = 0; x < w; x++) {
            float *p = sl_image_pixel(env, x, y);
            double d[3];
            sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / (w / 2), d);
            p[0] = (float)(0.2 + 0.8 * fmax(0, d[1]));
            p[1] = (float)(0.3 + 0.5 * fmax(0, d[1]) + 0.1 * d[0] * d[0]);
            p[2] = (float)(0.5 + 0.3 * d[2] * d[2]);
        }
    float *a = sl_image_pixel(env, w / 2 + 3, w / 8), *b = sl_image_pixel(env, w / 5, w / 4 + 2);
    a[0] = 300, a[1] = 250, a[2] = 200;
    b[0] = 20, b[1] = 40, b[2] = 80;
}

/* Irradiance at normal n: sum over texels of L * integral of max(0, n.w)
 * over the texel, each texel split into ss x ss exact solid-angle cells. */
static void quadrature_irradiance(const sl_image *env, const double n[3], int ss, double E[3])
{
    int w = env->width, h = env->height;
    E[0] = E[1] = E[2] = 0;
    for (int y = 0; y < h; y++)
        for (int sy = 0; sy < ss; sy++) {
            double v0 = (y + (double)sy / ss) / h, v1 = (y + (sy + 1.0) / ss) / h;
            double lat0 = SL_PI * (0.5 - v0), lat1 = SL_PI * (0.5 - v1);
            double omega = (2.0 * SL_PI / (w * ss)) * (sin(lat0) - sin(lat1));
            for (int x = 0; x < w; x++) {
                const float *L = sl_image_pixel(env, x, y);
                double acc = 0;
                for (int sx = 0; sx < ss; sx++) {
                    double d[3];
                    sl_latlong_to_dir((x + (sx + 0.5) / ss) / w, 0.5 * (v0 + v1), d);
                    acc += fmax(0, v3_dot(n, d));
                }
                for (int c = 0; c < 3; c++)
                    E[c] += L[c] * acc * omega;
            }
        }
}

/* Worst relative pixel error of a grey-sphere render against quadrature. */
static double grey_vs_quadrature(const sl_image *env, int size, int64_t spp, double *mean_err)
{
    sl_scene s;
    sl_scene_init(&s);
    sl_error err = {0};
    CHECK_OK(sl_scene_preset(&s, "grey", size, &err), &err);
    CHECK_OK(sl_scene_set_dome(&s, env, 0, 1, "env", &err), &err);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = spp;
    o.pixel_centers = true;
    sl_image img;
    sl_render_stats st;
    CHECK_OK(sl_render(&s, &o, &img, &st, &err), &err);
    double worst = 0, sum = 0;
    int count = 0;
    for (int py = 0; py < size; py++)
        for (int px = 0; px < size; px++) {
            double x = 2.0 * (px + 0.5) / size - 1.0, y = 1.0 - 2.0 * (py + 0.5) / size;
            double r2 = x * x + y * y;
            const float *p = sl_image_pixel(&img, px, py);
            if (r2 >= 1.0) {
                CHECK(p[3] == 0 && p[0] == 0);
                continue;
            }
            double n[3] = {-x, y, -sqrt(1.0 - r2)}, E[3];
            quadrature_irradiance(env, n, 4, E);
            for (int c = 0; c < 3; c++) {
                double ref = 0.18 / SL_PI * E[c];
                double e = fabs(p[c] - ref) / ref;
                worst = fmax(worst, e);
                sum += e;
                count++;
            }
        }
    *mean_err = sum / count;
    sl_image_free(&img);
    sl_render_stats_free(&st);
    sl_scene_free(&s);
    return worst;
}

static void test_grey_synthetic(void)
{
    sl_image env;
    synthetic_env(&env, 64);
    double mean, worst = grey_vs_quadrature(&env, 12, 8192, &mean);
    printf("  synthetic 64x32: worst pixel %.4f%%, mean %.4f%%\n", 100 * worst, 100 * mean);
    CHECK(worst < 0.005);
    sl_image_free(&env);
}

static void test_grey_real_hdri(void)
{
    const char *path = sl_test_data("hdri/small/grace_256x128.hdr");
    if (!path)
        return;
    sl_image full, env;
    sl_error err = {0};
    CHECK_OK(sl_image_read(path, &full, NULL, &err), &err);
    CHECK_OK(sl_image_resample(&full, 64, 32, &env, &err), &err);
    double mean, worst = grey_vs_quadrature(&env, 8, 32768, &mean);
    printf("  grace 64x32: worst pixel %.4f%%, mean %.4f%%\n", 100 * worst, 100 * mean);
    CHECK(worst < 0.005);
    sl_image_free(&full);
    sl_image_free(&env);
}

int main(void)
{
    RUN(test_grey_synthetic);
    RUN(test_grey_real_hdri);
    return sl_test_finish();
}
