/* SPDX-License-Identifier: BSD-3-Clause */
/* The renderer's chrome sphere, photographed by its validation camera,
 * unwraps to the environment it was lit with: a perfect mirror (F = 1) under
 * a known dome, rendered by sl_render, unwrapped with sl_unwrap (orthographic,
 * the sphere filling the image width, reflectance 1), compared with the dome
 * box-filtered to the same lat-long. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ball_fixture.h"
#include "setlight/render.h"
#include "setlight/stitch.h"
#include "testing.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* Quantile q of the relative luminance error over the front hemisphere
 * (directions within 90 degrees of -Z, the side facing the camera). */
static double front_median_pct(const sl_image *out, const sl_image *truth, double q)
{
    int w = out->width, h = out->height, n = 0;
    double *rel = malloc(sizeof(double) * (size_t)w * h);
    if (!rel)
        return INFINITY;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / h, d);
            if (atan2(hypot(d[0], d[1]), -d[2]) > M_PI / 2)
                continue;
            const float *p = sl_image_pixel(out, x, y), *t = sl_image_pixel(truth, x, y);
            double lo = sl_luminance_px(p);
            double lt = sl_luminance_px(t);
            rel[n++] = fabs(lo - lt) / lt;
        }
    qsort(rel, (size_t)n, sizeof *rel, sl_cmp_double);
    double v = rel[(int)(q * (n - 1))];
    free(rel);
    return v;
}

static double front_median(const sl_image *out, const sl_image *truth)
{
    return front_median_pct(out, truth, 0.5);
}

static void test_renderer_chrome_unwraps_to_its_dome(void)
{
    enum { SIZE = 160, W = 128 };
    ball_fixture f;
    ball_fixture_init(&f, 8, 8);
    sl_image env = {0}, photo = {0}, out = {0}, truth = {0};
    sl_error err;
    sl_scene scene;
    sl_scene_init(&scene);
    sl_material mirror;
    double one[3] = {1, 1, 1}, zero[3] = {0, 0, 0};
    sl_material_conductor(&mirror, one, zero, 0.0);
    mirror.fresnel = SL_FRESNEL_ONE;
    int mat = -1;
    double centre[3] = {0, 0, 0};
    sl_render_options ro;
    sl_render_options_init(&ro);
    ro.spp = 16;
    ro.bounces = 0;
    if (ball_fixture_truth(&f, 512, 2, &env, &err) ||
        sl_scene_add_material(&scene, &mirror, &mat, &err) ||
        sl_scene_add_sphere(&scene, centre, 1.0, mat, &err) ||
        sl_scene_set_dome(&scene, &env, 0.0, 1.0, "procedural", &err)) {
        CHECK_MSG(false, "%s", err.message);
        goto done;
    }
    sl_camera_validation(&scene.camera, SIZE, SIZE, 2.0, 0.0, 0.0);
    CHECK_OK(sl_render(&scene, &ro, &photo, NULL, &err), &err);
    if (!photo.data)
        goto done;
    sl_unwrap_options o = {.circle = {.cx = SIZE / 2.0, .cy = SIZE / 2.0, .r = SIZE / 2.0},
                           .width = W};
    sl_reflectance_constant(&o.reflectance, 1, 1, 1);
    CHECK_OK(sl_unwrap(&photo, &o, &out, NULL, &err), &err);
    CHECK_OK(sl_image_resample(&env, W, W / 2, &truth, &err), &err);
    if (!out.data || !truth.data)
        goto done;
    double med = front_median(&out, &truth), p90 = front_median_pct(&out, &truth, 0.9);
    printf("  renderer chrome (%dx%d, 16 spp) -> %dx%d: front median rel err %.4f, 90th "
           "percentile %.4f\n",
           SIZE, SIZE, W, W / 2, med, p90);
    CHECK(med < 0.02);
    /* Negative control: the same photo unwrapped upside down. */
    sl_image_free(&out);
    o.geometry.roll_deg = 180;
    CHECK_OK(sl_unwrap(&photo, &o, &out, NULL, &err), &err);
    double wrong = out.data ? front_median(&out, &truth) : 0.0;
    printf("  camera wrongly rolled by 180 deg: front median rel err %.4f\n", wrong);
    CHECK(wrong > 0.1);
done:
    sl_scene_free(&scene);
    sl_image_free(&env);
    sl_image_free(&photo);
    sl_image_free(&out);
    sl_image_free(&truth);
}

int main(void)
{
    RUN(test_renderer_chrome_unwraps_to_its_dome);
    return sl_test_finish();
}
