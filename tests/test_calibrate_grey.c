/* SPDX-License-Identifier: BSD-3-Clause */
/* Grey sphere calibration on the virtual set: the `stage` lat-long, scaled
 * by a known exposure and channel gains, is the uncalibrated HDRI; the
 * "photo" is an 18% grey sphere rendered under the true map, placed in a
 * larger frame at a known circle. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/vset.h"
#include "setlight/render.h"
#include "setlight/stitch.h"
#include "testing.h"

static int render_photo(const sl_image *env, int n, int64_t spp, sl_image *out)
{
    sl_error err;
    sl_scene s;
    sl_scene_init(&s);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = spp;
    o.seed = 777; /* not the fit's seed: independent noise */
    int ok = sl_scene_preset(&s, "grey", n, &err) == SL_OK &&
             sl_scene_set_dome(&s, env, 0, 1, "truth", &err) == SL_OK &&
             sl_render(&s, &o, out, NULL, &err) == SL_OK;
    if (!ok)
        printf("photo render failed: %s\n", err.message);
    sl_scene_free(&s);
    return ok;
}

static void test_stage(void)
{
    bool san = sl_test_sanitized();
    /* The error measured includes the render noise of both spheres. */
    int n = san ? 32 : 64;
    int64_t spp = san ? 256 : 512;
    sl_error err;
    sl_vset_desc desc;
    sl_vset_scene vs = {0};
    CHECK_OK(sl_vset_preset("stage", &desc, &err), &err);
    CHECK_OK(sl_vset_scene_make(&desc, 128, &vs, &err), &err);
    if (!vs.latlong.data)
        return;
    /* The "photo": the sphere centred at (70, 60), radius n/2, in a frame. */
    sl_image sphere = {0}, photo = {0};
    if (!render_photo(&vs.latlong, n, 2 * spp, &sphere))
        return;
    CHECK_OK(sl_image_alloc(&photo, 160, 120, 3, &err), &err);
    int ox = 70 - n / 2, oy = 60 - n / 2;
    for (int y = 0; y < n; y++)
        for (int x = 0; x < n; x++)
            memcpy(photo.data + (size_t)(y + oy) * photo.stride + (size_t)(x + ox) * 3,
                   sphere.data + (size_t)y * sphere.stride + (size_t)x * 4, 3 * sizeof(float));
    /* The uncalibrated HDRI. */
    const double truth_gain[3] = {2.0 / 1.3, 2.0 / 1.0, 2.0 / 0.8};
    sl_image hdri = {0};
    CHECK_OK(sl_image_alloc(&hdri, vs.latlong.width, vs.latlong.height, 3, &err), &err);
    for (int y = 0; y < hdri.height; y++)
        for (int x = 0; x < hdri.width; x++)
            for (int c = 0; c < 3; c++)
                hdri.data[(size_t)y * hdri.stride + (size_t)x * 3 + c] =
                    (float)(vs.latlong.data[(size_t)y * vs.latlong.stride + (size_t)x * 3 + c] /
                            truth_gain[c]);
    sl_grey_options o;
    sl_grey_options_init(&o);
    o.circle[0] = 70, o.circle[1] = 60, o.circle[2] = n / 2.0;
    o.spp = spp;
    sl_grey_fit fit;
    CHECK_OK(sl_grey_sphere_fit(&hdri, &photo, &o, &fit, &err), &err);
    double true_scale = sl_luminance(truth_gain);
    printf("  stage %dpx %lld spp: gain %.4f %.4f %.4f (true %.4f %.4f %.4f), scale %.4f (true "
           "%.4f, %+.2f%%), rel RMSE before %.4f after %.4f, p95 %.4f, %lld px, %lld rejected\n",
           n, (long long)spp, fit.gain[0], fit.gain[1], fit.gain[2], truth_gain[0], truth_gain[1],
           truth_gain[2], fit.scale, true_scale, 100 * (fit.scale / true_scale - 1),
           fit.rel_rmse_before, fit.rel_rmse_after, fit.error_p95, (long long)fit.pixels,
           (long long)fit.rejected);
    CHECK(fabs(fit.scale / true_scale - 1) < 0.01);
    for (int c = 0; c < 3; c++)
        CHECK(fabs(fit.gain[c] / truth_gain[c] - 1) < 0.01);
    CHECK(fit.rel_rmse_after < 0.02);
    CHECK(fit.rel_rmse_before > 0.05); /* the balance was visibly off */
    sl_grey_fit_free(&fit);
    /* The sphere found by unwrap's ball detector instead of given. */
    sl_ball_circle bc;
    CHECK_OK(sl_ball_detect(&photo, "grey.exr", &bc, &err), &err);
    printf("  detected circle %.2f %.2f %.2f (true 70 60 %.1f)\n", bc.cx, bc.cy, bc.r, n / 2.0);
    CHECK(hypot(bc.cx - 70, bc.cy - 60) < 1 && fabs(bc.r - n / 2.0) < 1);
    /* A circle on the black surround: no sphere there. */
    o.circle[0] = 140, o.circle[1] = 100, o.circle[2] = 15;
    CHECK_RESULT(sl_grey_sphere_fit(&hdri, &photo, &o, &fit, &err), SL_ERR_INPUT, &err);
    CHECK(fit.render.data == NULL && fit.photo.data == NULL);
    /* A circle too small to measure. */
    o.circle[2] = 3;
    CHECK_RESULT(sl_grey_sphere_fit(&hdri, &photo, &o, &fit, &err), SL_ERR_USAGE, &err);
    sl_image_free(&hdri);
    sl_image_free(&photo);
    sl_image_free(&sphere);
    sl_vset_scene_free(&vs);
}

/* An 18% grey ball photographed by a pinhole on its axis, d radii away,
 * the outline r px across in a w x w frame. */
static int render_pinhole(const sl_image *env, int w, double d, double r, int64_t spp,
                          sl_image *out)
{
    sl_error err;
    sl_scene s;
    sl_scene_init(&s);
    sl_material mat;
    sl_material_lambert(&mat, 0.18, 0.18, 0.18);
    int mi = 0;
    const double origin[3] = {0, 0, 0};
    double f = r / tan(asin(1 / d));
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = spp;
    o.seed = 777;
    o.bounces = 0;
    int ok = sl_scene_add_material(&s, &mat, &mi, &err) == SL_OK &&
             sl_scene_add_sphere(&s, origin, 1.0, mi, &err) == SL_OK;
    if (ok) {
        sl_camera_validation(&s.camera, w, w, 2.0, 0, 0);
        s.camera.type = SL_CAMERA_PERSPECTIVE;
        s.camera.fov_deg = 2 * atan(0.5 * w / f) * 180 / M_PI;
        s.camera.position[0] = s.camera.position[1] = 0;
        s.camera.position[2] = -d;
        ok = sl_scene_set_dome(&s, env, 0, 1, "truth", &err) == SL_OK &&
             sl_render(&s, &o, out, NULL, &err) == SL_OK;
    }
    if (!ok)
        printf("pinhole photo render failed: %s\n", err.message);
    sl_scene_free(&s);
    return ok;
}

/* The HDRI is the truth, so every gain should be 1: the orthographic fit
 * is off by the lens's perspective, the pinhole fit recovers 1. */
static void test_perspective(void)
{
    bool san = sl_test_sanitized();
    int w = san ? 40 : 64;
    double r = 0.4 * w;
    int64_t spp = san ? 128 : 512;
    sl_error err;
    sl_vset_desc desc;
    sl_vset_scene vs = {0};
    CHECK_OK(sl_vset_preset("stage", &desc, &err), &err);
    CHECK_OK(sl_vset_scene_make(&desc, 128, &vs, &err), &err);
    if (!vs.latlong.data)
        return;
    /* 40 radii: the virtual set's 200 mm lens at 2 m; 3 radii: a wide lens close up. */
    const double dist[2] = {40, 3};
    for (int t = 0; t < 2; t++) {
        sl_image photo = {0};
        if (!render_pinhole(&vs.latlong, w, dist[t], r, spp, &photo))
            break;
        double f = r / tan(asin(1 / dist[t]));
        sl_grey_options o;
        sl_grey_options_init(&o);
        o.circle[0] = o.circle[1] = 0.5 * w, o.circle[2] = r;
        o.spp = spp / 2;
        sl_grey_fit ortho, persp, by_dist;
        CHECK_OK(sl_grey_sphere_fit(&vs.latlong, &photo, &o, &ortho, &err), &err);
        o.focal_px = f;
        CHECK_OK(sl_grey_sphere_fit(&vs.latlong, &photo, &o, &persp, &err), &err);
        /* The distance alone (ball on the axis) gives the same camera. */
        o.focal_px = 0, o.distance = dist[t];
        CHECK_OK(sl_grey_sphere_fit(&vs.latlong, &photo, &o, &by_dist, &err), &err);
        printf("  %g radii (%dpx, r %.1f px, focal %.1f px): scale orthographic %.4f (%+.2f%%, "
               "RMSE %.4f), perspective %.4f (%+.2f%%, RMSE %.4f), by distance %.4f\n",
               dist[t], w, r, f, ortho.scale, 100 * (ortho.scale - 1), ortho.rel_rmse_after,
               persp.scale, 100 * (persp.scale - 1), persp.rel_rmse_after, by_dist.scale);
        CHECK(fabs(persp.scale - 1) < 0.003);
        CHECK(fabs(by_dist.scale - 1) < 0.003);
        for (int c = 0; c < 3; c++)
            CHECK(fabs(persp.gain[c] - 1) < 0.005);
        if (t == 1) /* at 40 radii the shape error is below the render noise */
            CHECK(persp.rel_rmse_after < ortho.rel_rmse_after);
        /* The orthographic model's bias is the lens's, well beyond the noise. */
        CHECK(fabs(ortho.scale - 1) > (t == 0 ? 0.005 : 0.03));
        sl_grey_fit_free(&ortho);
        sl_grey_fit_free(&persp);
        sl_grey_fit_free(&by_dist);
        sl_image_free(&photo);
    }
    /* A camera inside the sphere is refused. */
    sl_grey_options o;
    sl_grey_options_init(&o);
    o.circle[0] = o.circle[1] = 0.5 * w, o.circle[2] = r;
    o.distance = 0.9;
    sl_grey_fit fit;
    sl_image img = {0};
    CHECK_OK(sl_image_alloc(&img, w, w, 3, &err), &err);
    CHECK_RESULT(sl_grey_sphere_fit(&vs.latlong, &img, &o, &fit, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "inside") != NULL);
    CHECK(fit.render.data == NULL);
    sl_image_free(&img);
    sl_vset_scene_free(&vs);
}

int main(void)
{
    RUN(test_stage);
    RUN(test_perspective);
    return sl_test_finish();
}
