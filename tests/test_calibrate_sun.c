/* SPDX-License-Identifier: BSD-3-Clause */
/* Clipped-sun repair on the virtual set's `exterior` (the sun about 1e5
 * times the sky): the HDRI is the true map at a known exposure with the sun
 * clipped to a shortest exposure's bound (and flagged in a mask, as the
 * merge does); the grey-sphere photo is rendered under the true map. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/vset.h"
#include "setlight/render.h"
#include "setlight/stitch.h"
#include "testing.h"

static const double H = 0.25; /* the HDRI's exposure relative to the truth */

static int render_photo(const sl_image *env, int n, int64_t spp, double az, double el,
                        sl_image *out)
{
    sl_error err;
    sl_scene s;
    sl_scene_init(&s);
    sl_material mat;
    sl_material_lambert(&mat, 0.18, 0.18, 0.18);
    int mi = 0;
    const double origin[3] = {0, 0, 0};
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = spp;
    o.seed = 777; /* not the fit's seed: independent noise */
    o.bounces = 0;
    int ok = sl_scene_add_material(&s, &mat, &mi, &err) == SL_OK &&
             sl_scene_add_sphere(&s, origin, 1.0, mi, &err) == SL_OK;
    if (ok)
        sl_camera_validation(&s.camera, n, n, 2.0, az, el);
    ok = ok && sl_scene_set_dome(&s, env, 0, 1, "truth", &err) == SL_OK &&
         sl_render(&s, &o, out, NULL, &err) == SL_OK;
    if (!ok)
        printf("photo render failed: %s\n", err.message);
    sl_scene_free(&s);
    return ok;
}

static void integral(const sl_image *img, double out[3])
{
    out[0] = out[1] = out[2] = 0;
    for (int y = 0; y < img->height; y++) {
        double da = sl_latlong_texel_solid_angle(y, img->width, img->height);
        for (int x = 0; x < img->width; x++)
            for (int c = 0; c < 3; c++)
                out[c] += da * img->data[(size_t)y * img->stride + (size_t)x * img->channels + c];
    }
}

static void test_exterior(void)
{
    bool san = sl_test_sanitized();
    int w = san ? 128 : 256, n = san ? 32 : 48;
    int64_t spp = san ? 64 : 128;
    sl_error err;
    sl_vset_desc desc;
    sl_vset_scene vs = {0};
    CHECK_OK(sl_vset_preset("exterior", &desc, &err), &err);
    CHECK_OK(sl_vset_scene_make(&desc, w, &vs, &err), &err);
    if (!vs.latlong.data)
        return;
    const sl_vset_light *sun = NULL;
    for (int i = 0; i < vs.desc.light_count; i++)
        if (vs.desc.lights[i].emit == SL_VSET_EMIT_SUN)
            sun = &vs.desc.lights[i];
    CHECK(sun != NULL);
    if (!sun)
        return;
    /* The photo: seen from the sun's side, 40 degrees round, so both the lit
     * side and the terminator are in view. */
    double az = sun->azimuth_deg + 180 + 40, el = 10;
    sl_image photo = {0};
    if (!render_photo(&vs.latlong, n, 2 * spp, az, el, &photo))
        return;
    /* The HDRI: the truth times H, clipped at a shortest exposure's bound
     * 4x the brightest texel more than 2 degrees from the sun. */
    double sky_max = 0;
    for (int y = 0; y < vs.latlong.height; y++)
        for (int x = 0; x < vs.latlong.width; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / (w / 2), d);
            if (d[0] * sun->dir[0] + d[1] * sun->dir[1] + d[2] * sun->dir[2] > cos(2 * M_PI / 180))
                continue;
            const float *v = vs.latlong.data + (size_t)y * vs.latlong.stride + (size_t)x * 3;
            for (int c = 0; c < 3; c++)
                sky_max = fmax(sky_max, v[c]);
        }
    double bound = 4 * sky_max * H;
    sl_image hdri = {0}, mask = {0};
    CHECK_OK(sl_image_alloc(&hdri, w, w / 2, 3, &err), &err);
    CHECK_OK(sl_image_alloc(&mask, w, w / 2, 3, &err), &err);
    int64_t flagged = 0;
    for (int y = 0; y < w / 2; y++)
        for (int x = 0; x < w; x++) {
            const float *t = vs.latlong.data + (size_t)y * vs.latlong.stride + (size_t)x * 3;
            float *v = hdri.data + (size_t)y * hdri.stride + (size_t)x * 3;
            float *m = mask.data + (size_t)y * mask.stride + (size_t)x * 3;
            bool any = false;
            for (int c = 0; c < 3; c++) {
                double e = t[c] * H;
                m[c] = e > bound ? 1.0f : 0.0f;
                v[c] = (float)fmin(e, bound);
                any = any || e > bound;
            }
            flagged += any;
        }
    double truth_int[3], clipped_int[3];
    for (int c = 0; c < 3; c++)
        truth_int[c] = vs.total[c] * H;
    integral(&hdri, clipped_int);
    double sun_truth[3];
    for (int c = 0; c < 3; c++)
        sun_truth[c] = sun->radiance[c] * H;

    sl_grey_options go;
    sl_grey_options_init(&go);
    go.circle[0] = go.circle[1] = go.circle[2] = n / 2.0;
    go.azimuth_deg = az;
    go.elevation_deg = el;
    go.spp = spp;
    /* Before repair: the exposure fit is pulled off and the sphere misses its sun. */
    sl_grey_fit before;
    CHECK_OK(sl_grey_sphere_fit(&hdri, &photo, &go, &before, &err), &err);
    sl_sun_options so;
    sl_sun_options_init(&so);
    sl_sun_repair rep;
    CHECK_OK(sl_sun_repair_fit(&hdri, &mask, &photo, &go, &so, &rep, &err), &err);
    sl_grey_fit after;
    CHECK_OK(sl_grey_sphere_fit(&hdri, &photo, &go, &after, &err), &err);
    double repaired_int[3];
    integral(&hdri, repaired_int);
    double ang = acos(fmin(1, rep.direction[0] * sun->dir[0] + rep.direction[1] * sun->dir[1] +
                                  rep.direction[2] * sun->dir[2])) * 180 / M_PI;
    double missing = sl_luminance(truth_int) - sl_luminance(clipped_int);
    printf("  exterior %d wide, sphere %d px, %lld spp: %lld texels clipped (%.2e sr), centroid "
           "%.3f deg off the sun\n",
           w, n, (long long)spp, (long long)rep.clipped_texels, rep.solid_angle, ang);
    printf("  before: sun bound %.4g (truth %.4g, %.2f%%), grey fit scale %.4f (truth %.4f), rel "
           "RMSE %.4f inliers %lld rejected %lld; repair's gains-only rel RMSE %.4f\n",
           sl_luminance(rep.bound), sl_luminance(sun_truth), 100 * sl_luminance(rep.bound) / sl_luminance(sun_truth), before.scale,
           1 / H, before.rel_rmse_after, (long long)before.pixels, (long long)before.rejected,
           rep.rel_rmse_before);
    printf("  fitted sun %.5g %.5g %.5g (truth %.5g %.5g %.5g), lum %+.2f%%, sigma %.2f%%\n",
           rep.radiance[0], rep.radiance[1], rep.radiance[2], sun_truth[0], sun_truth[1],
           sun_truth[2], 100 * (sl_luminance(rep.radiance) / sl_luminance(sun_truth) - 1),
           100 * sl_luminance(rep.radiance_sigma) / sl_luminance(rep.radiance));
    printf("  energy: missing %.5g (%.1f%% of the map), added %.5g (%+.2f%%); after: scale %.4f "
           "(%+.2f%%), rel RMSE %.4f, p95 %.4f, rejected %lld\n",
           missing, 100 * missing / sl_luminance(truth_int), sl_luminance(rep.energy_added),
           100 * (sl_luminance(rep.energy_added) / missing - 1), after.scale, 100 * (after.scale * H - 1),
           after.rel_rmse_after, after.error_p95, (long long)after.rejected);
    CHECK(flagged > 0 && rep.clipped_texels == flagged);
    CHECK(ang < 1.0);
    /* Before: most of the sun is gone and the grey sphere says so. */
    CHECK(sl_luminance(rep.bound) < 0.5 * sl_luminance(sun_truth));
    CHECK(missing > 0.3 * sl_luminance(truth_int));
    CHECK(rep.rel_rmse_before > 0.10);
    CHECK(before.rejected > before.pixels / 10 || fabs(before.scale * H - 1) > 0.1);
    /* After: the bounds. */
    CHECK(after.rel_rmse_after < 0.03);
    CHECK(rep.rel_rmse_after < 0.03);
    for (int c = 0; c < 3; c++)
        CHECK(fabs(rep.radiance[c] / sun_truth[c] - 1) < 0.10);
    CHECK(fabs(sl_luminance(rep.energy_added) / missing - 1) < 0.10);
    CHECK(fabs(sl_luminance(repaired_int) / sl_luminance(truth_int) - 1) < 0.10);
    CHECK(fabs(after.scale * H - 1) < 0.03);
    CHECK(sl_luminance(rep.radiance_sigma) < 0.1 * sl_luminance(rep.radiance) && sl_luminance(rep.radiance_sigma) > 0);
    sl_grey_fit_free(&before);
    sl_grey_fit_free(&after);

    /* An empty mask: nothing to do, the map untouched. */
    sl_image copy = {0};
    CHECK_OK(sl_image_alloc(&copy, w, w / 2, 3, &err), &err);
    memcpy(copy.data, hdri.data, (size_t)w * (w / 2) * 3 * sizeof(float));
    memset(mask.data, 0, (size_t)w * (w / 2) * 3 * sizeof(float));
    CHECK_OK(sl_sun_repair_fit(&hdri, &mask, &photo, &go, &so, &rep, &err), &err);
    CHECK(!rep.repaired && rep.clipped_texels == 0);
    CHECK(memcmp(copy.data, hdri.data, (size_t)w * (w / 2) * 3 * sizeof(float)) == 0);
    /* A source behind the sphere as seen from the camera: no fit, map untouched. */
    for (int y = 0; y < w / 2; y++)
        for (int x = 0; x < w; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / (w / 2), d);
            /* the camera looks along this direction, so the source behind it lights the far side */
            double back[3] = {sin(az * M_PI / 180) * cos(0.3), sin(0.3), cos(az * M_PI / 180) * cos(0.3)};
            if (d[0] * back[0] + d[1] * back[1] + d[2] * back[2] > cos(1.5 * M_PI / 180))
                mask.data[(size_t)y * mask.stride + (size_t)x * 3] = 1;
        }
    CHECK_RESULT(sl_sun_repair_fit(&hdri, &mask, &photo, &go, &so, &rep, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "does not light") != NULL);
    CHECK(memcmp(copy.data, hdri.data, (size_t)w * (w / 2) * 3 * sizeof(float)) == 0);
    /* A mask of another size. */
    sl_image small = {0};
    CHECK_OK(sl_image_alloc(&small, 16, 8, 1, &err), &err);
    CHECK_RESULT(sl_sun_repair_fit(&hdri, &small, &photo, &go, &so, &rep, &err), SL_ERR_INPUT, &err);
    sl_image_free(&small);
    sl_image_free(&copy);
    sl_image_free(&hdri);
    sl_image_free(&mask);
    sl_image_free(&photo);
    sl_vset_scene_free(&vs);
}

int main(void)
{
    RUN(test_exterior);
    return sl_test_finish();
}
