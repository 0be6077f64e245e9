/* SPDX-License-Identifier: BSD-3-Clause */
/* Probe photographs of the virtual set: the chrome ball's highlight of a
 * one-bright-texel environment lands where mirror-reflection geometry puts
 * it; the grey ball and the chart sit where their truth says, with the
 * radiance a uniform environment gives; bad probes are refused. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/vset.h"
#include "setlight/render.h"
#include "setlight/stitch.h"
#include "testing.h"

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

/* The point of a mirror sphere (centre c, radius rad) that reflects
 * direction d into a pinhole at the origin: bisection on the normal's angle
 * in the plane of the camera, the centre and d. */
static void mirror_point(const double c[3], double rad, const double d[3], double p[3])
{
    double dist = sqrt(dot3(c, c)), a[3], b[3];
    for (int k = 0; k < 3; k++)
        a[k] = -c[k] / dist;
    double da = dot3(d, a);
    for (int k = 0; k < 3; k++)
        b[k] = d[k] - da * a[k];
    double nb = sqrt(dot3(b, b));
    for (int k = 0; k < 3; k++)
        b[k] /= nb;
    double target = atan2(dot3(d, b), da), lo = 0, hi = 0.5 * M_PI;
    for (int it = 0; it < 100; it++) {
        double phi = 0.5 * (lo + hi), n[3], v[3], refl[3];
        for (int k = 0; k < 3; k++) {
            n[k] = cos(phi) * a[k] + sin(phi) * b[k];
            p[k] = c[k] + rad * n[k];
        }
        double pl = sqrt(dot3(p, p));
        for (int k = 0; k < 3; k++)
            v[k] = p[k] / pl;
        double vn = dot3(v, n);
        for (int k = 0; k < 3; k++)
            refl[k] = v[k] - 2 * vn * n[k];
        if (atan2(dot3(refl, b), dot3(refl, a)) < target)
            lo = phi;
        else
            hi = phi;
    }
}

static void test_chrome_highlight(void)
{
    /* Camera looks along -Z (yaw 180): image right is +X, up +Y. */
    static const double fwd[3] = {0, 0, -1}, right[3] = {1, 0, 0}, up[3] = {0, 1, 0};
    /* Coarse texels, so each highlight spans a few pixels and its centroid
     * is not quantised to one pixel. */
    const int W = 64, H = 32;
    static const int texels[][2] = {{37, 12}, {25, 20}, {50, 10}, {32, 5}};
    for (int t = 0; t < 4; t++) {
        sl_image env;
        sl_error err;
        CHECK_OK(sl_image_alloc(&env, W, H, 3, &err), &err);
        memset(env.data, 0, sizeof(float) * W * H * 3);
        int tx = texels[t][0], ty = texels[t][1];
        float *px = sl_image_pixel(&env, tx, ty);
        px[0] = px[1] = px[2] = 1000;
        double d[3];
        sl_latlong_to_dir((tx + 0.5) / W, (ty + 0.5) / H, d);

        sl_vset_probe p;
        sl_vset_probe_default(&p, SL_VSET_PROBE_CHROME, 160, 120);
        p.distance_m = 1.0;
        p.spp = 32;
        sl_vset_probe_geometry g;
        sl_image img;
        CHECK_OK(sl_vset_probe_render(&p, &env, &img, &g, &err), &err);
        double c[3] = {0, 0, -1.0}, pt[3];
        mirror_point(c, 0.05, d, pt);
        double z = dot3(pt, fwd);
        double ex = 80 + g.focal_px * dot3(pt, right) / z;
        double ey = 60 - g.focal_px * dot3(pt, up) / z;
        double sx = 0, sy = 0, s = 0, peak = 0;
        int peak_x = -1, peak_y = -1;
        for (int y = 0; y < img.height; y++)
            for (int x = 0; x < img.width; x++) {
                double l = sl_luminance_px(sl_image_pixel(&img, x, y));
                sx += l * (x + 0.5);
                sy += l * (y + 0.5);
                s += l;
                if (l > peak) {
                    peak = l;
                    peak_x = x;
                    peak_y = y;
                }
            }
        CHECK(s > 0);
        double gx = sx / s, gy = sy / s;
        printf("texel (%d, %d): highlight centroid (%.3f, %.3f), mirror geometry (%.3f, %.3f), "
               "%.3f px apart\n",
               tx, ty, gx, gy, ex, ey, hypot(gx - ex, gy - ey));
        CHECK_MSG(hypot(gx - ex, gy - ey) < 0.2, "texel (%d, %d): %.3f px off", tx, ty,
                  hypot(gx - ex, gy - ey));
        CHECK(fabs(peak_x + 0.5 - ex) <= 1.5 && fabs(peak_y + 0.5 - ey) <= 1.5);
        /* On the ball, inside its truth circle. */
        CHECK(hypot(ex - g.cx, ey - g.cy) < g.r);
        sl_image_free(&img);
        sl_image_free(&env);
    }
}

static sl_result uniform_env(sl_image *env, sl_error *err)
{
    sl_result r = sl_image_alloc(env, 64, 32, 3, err);
    if (!r)
        for (int i = 0; i < 64 * 32 * 3; i++)
            env->data[i] = 1.0f;
    return r;
}

/* Under a uniform environment of radiance 1, a Lambert surface of albedo a
 * has radiance a: the background reads exactly 1 outside the ball's truth
 * circle, the ball 0.18 on average inside it (each pixel far below 1), and
 * the chart's patches their albedos round the truth centres (vignetting
 * divided out; the chart is noise-free). */
static void test_truth_geometry(void)
{
    sl_image env;
    sl_error err;
    CHECK_OK(uniform_env(&env, &err), &err);
    sl_vset_probe p;
    sl_vset_probe_default(&p, SL_VSET_PROBE_GREY, 192, 128);
    p.spp = 4;
    sl_vset_probe_geometry g;
    sl_image img;
    CHECK_OK(sl_vset_probe_render(&p, &env, &img, &g, &err), &err);
    CHECK_NEAR(g.focal_px, 200.0 * 192 / 36, 1e-9);
    CHECK_NEAR(g.r, g.focal_px * tan(asin(0.05 / 2.0)), 1e-9);
    CHECK_NEAR(g.ball_angle_deg, asin(0.025) * 180 / M_PI, 1e-9);
    int inside = 0, outside = 0, bad = 0;
    double mean = 0;
    for (int y = 0; y < img.height; y++)
        for (int x = 0; x < img.width; x++) {
            double rr = hypot(x + 0.5 - g.cx, y + 0.5 - g.cy);
            double v = sl_vset_lens_vignette(&p.lens, 192, 128, x + 0.5, y + 0.5);
            double l = sl_luminance_px(sl_image_pixel(&img, x, y)) / v;
            if (rr < g.r - 1) {
                inside++;
                mean += l;
                bad += l > 0.6;
            } else if (rr > g.r + 1) {
                outside++;
                bad += fabs(l - 1) > 1e-3;
            }
        }
    mean /= inside;
    printf("grey ball: r %.2f px, %d pixels inside (mean %.4f), %d outside, %d off\n", g.r,
           inside, mean, outside, bad);
    CHECK(inside > 1000 && outside > 10000 && bad == 0);
    CHECK_NEAR(mean, 0.18, 0.18 * 0.02);
    sl_image_free(&img);

    sl_vset_probe_default(&p, SL_VSET_PROBE_CHART, 240, 160);
    p.spp = 4;
    CHECK_OK(sl_vset_probe_render(&p, &env, &img, &g, &err), &err);
    double worst = 0;
    for (int i = 0; i < 24; i++) {
        int x0 = (int)g.patch_centers[i][0], y0 = (int)g.patch_centers[i][1];
        double acc[3] = {0, 0, 0};
        for (int y = y0 - 3; y <= y0 + 3; y++)
            for (int x = x0 - 3; x <= x0 + 3; x++) {
                double v = sl_vset_lens_vignette(&p.lens, 240, 160, x + 0.5, y + 0.5);
                const float *px = sl_image_pixel(&img, x, y);
                for (int k = 0; k < 3; k++)
                    acc[k] += px[k] / v / 49;
            }
        for (int k = 0; k < 3; k++) {
            double e = fabs(acc[k] / SL_COLORCHECKER_LINEAR[i][k] - 1);
            worst = e > worst ? e : worst;
        }
    }
    printf("chart: 7x7 pixels round the patch centres read their albedo to %.2f%%\n",
           100 * worst);
    CHECK(worst < 1e-4);
    /* Corners are patches 1, 6, 24, 19; patch 1 top left, 6 top right. */
    CHECK(g.corners[0][0] < g.corners[1][0] && g.corners[0][1] < g.corners[3][1]);
    CHECK_NEAR(g.corners[2][0], g.patch_centers[23][0], 1e-12);
    double c[24][2];
    CHECK_OK(sl_chart_centers_from_corners((const double(*)[2])g.corners, c, &err), &err);
    double off = 0;
    for (int i = 0; i < 24; i++)
        off = fmax(off, hypot(c[i][0] - g.patch_centers[i][0], c[i][1] - g.patch_centers[i][1]));
    CHECK(off < 1e-6);
    /* The frame surrounds the patches. */
    CHECK(g.outline[0][0] < g.patch_centers[0][0] && g.outline[2][1] > g.patch_centers[23][1]);
    sl_image_free(&img);
    sl_image_free(&env);
}

static void test_bad_probes(void)
{
    sl_image env, img;
    sl_error err;
    CHECK_OK(uniform_env(&env, &err), &err);
    sl_vset_probe p;
    sl_vset_probe_default(&p, SL_VSET_PROBE_GREY, 64, 48);
    p.size_m = 3;
    CHECK_RESULT(sl_vset_probe_render(&p, &env, &img, NULL, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "grey") != NULL && img.data == NULL);
    sl_vset_probe_default(&p, SL_VSET_PROBE_CHROME, 64, 48);
    p.lens.focal_mm = 0; /* no lens */
    CHECK_RESULT(sl_vset_probe_render(&p, &env, &img, NULL, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "rectilinear") != NULL);
    sl_vset_probe_default(&p, SL_VSET_PROBE_CHART, 8, 48);
    CHECK_RESULT(sl_vset_probe_render(&p, &env, &img, NULL, &err), SL_ERR_USAGE, &err);
    sl_image_free(&env);
}

int main(void)
{
    RUN(test_chrome_highlight);
    RUN(test_truth_geometry);
    RUN(test_bad_probes);
    return sl_test_finish();
}
