/* SPDX-License-Identifier: BSD-3-Clause */
/* Calibration end to end on the virtual set: the `stage` (tungsten-lit)
 * seen by the simulated 5D Mark II balanced for daylight. The chart and the
 * grey sphere are rendered under the true map and photographed by
 * sl_vset_camera_shoot (sensor matrix, white balance, colour matrix, noise,
 * raw quantisation); the HDRI is the true map through the same camera's
 * output matrix at another exposure. The calibration (docs/calibrate.md,
 * "How the parts combine"): plate matrix P from the chart, applied to the
 * grey photo and the HDRI, then the grey sphere's gains g: T = diag(g) P. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/vset.h"
#include "setlight/render.h"
#include "setlight/stitch.h"
#include "testing.h"

#ifndef KELVIN
#define KELVIN 3200
#endif

static int render(const sl_image *env, const char *preset, int width, int64_t spp, sl_image *out)
{
    sl_error err;
    sl_scene s;
    sl_scene_init(&s);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = spp;
    o.seed = 4242;
    o.bounces = 0;
    int ok = sl_scene_preset(&s, preset, width, &err) == SL_OK &&
             sl_scene_set_dome(&s, env, 0, 1, "truth", &err) == SL_OK &&
             sl_render(&s, &o, out, NULL, &err) == SL_OK;
    if (!ok)
        printf("%s render failed: %s\n", preset, err.message);
    sl_scene_free(&s);
    return ok;
}

/* Exposure scale putting the image's brightest pixel at `peak` of raw
 * saturation, as a time at f/4 ISO 100. */
static double expose(const sl_vset_camera *cam, const sl_image *img, double peak,
                     sl_vset_exposure *e)
{
    double mx = 0;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            const float *v = img->data + (size_t)y * img->stride + (size_t)x * img->channels;
            double s[3];
            for (int c = 0; c < 3; c++)
                s[c] = cam->wb[c] * (cam->cam_from_rec709[c][0] * v[0] +
                                     cam->cam_from_rec709[c][1] * v[1] +
                                     cam->cam_from_rec709[c][2] * v[2]);
            mx = fmax(mx, fmax(s[0], fmax(s[1], s[2])));
        }
    e->f_number = 4, e->iso = 100, e->time_s = 1;
    e->time_s = peak / (mx * sl_vset_exposure_scale(cam, e));
    return sl_vset_exposure_scale(cam, e);
}

static void apply(sl_image *img, const double m[3][3])
{
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            float *v = img->data + (size_t)y * img->stride + (size_t)x * img->channels;
            double in[3] = {v[0], v[1], v[2]}, o[3];
            sl_mat3_apply(m, in, o);
            for (int c = 0; c < 3; c++)
                v[c] = (float)o[c];
        }
}

static void test_stage(void)
{
    bool san = sl_test_sanitized();
    int cw = san ? 120 : 180, n = san ? 48 : 64;
    int64_t spp = san ? 128 : 256;
    sl_error err;
    sl_vset_desc desc;
    sl_vset_scene vs = {0};
    CHECK_OK(sl_vset_preset("stage", &desc, &err), &err);
    CHECK_OK(sl_vset_scene_make(&desc, 128, &vs, &err), &err);
    sl_vset_camera cam;
    sl_vset_camera_default(&cam, KELVIN);
    /* Camera RGB as a raw developer gives it (white-balanced, no colour
     * matrix: out-of-gamut colours are not clipped): wb * cam_from_rec709. */
    double m_out[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            m_out[i][j] = cam.wb[i] * cam.cam_from_rec709[i][j];

    /* The plate camera's photos. */
    sl_image chart_rad = {0}, grey_rad = {0};
    if (!render(&vs.latlong, "chart", cw, spp / 4, &chart_rad) ||
        !render(&vs.latlong, "grey", 2 * n, spp, &grey_rad))
        return;
    sl_vset_exposure ec, eg;
    expose(&cam, &chart_rad, 0.9, &ec);
    double s_grey = expose(&cam, &grey_rad, 0.9, &eg);
    sl_vset_shot chart = {0}, grey = {0};
    CHECK_OK(sl_vset_camera_shoot(&cam, &ec, &chart_rad, 11, &chart, &err), &err);
    CHECK_OK(sl_vset_camera_shoot(&cam, &eg, &grey_rad, 12, &grey, &err), &err);
    /* The HDRI: same camera, 3.3 stops under the grey photo. */
    const double s_hdri = s_grey / 9.85;
    sl_image hdri = {0};
    CHECK_OK(sl_image_alloc(&hdri, vs.latlong.width, vs.latlong.height, 3, &err), &err);
    for (int y = 0; y < hdri.height; y++)
        for (int x = 0; x < hdri.width; x++)
            for (int c = 0; c < 3; c++)
                hdri.data[(size_t)y * hdri.stride + (size_t)x * 3 + c] =
                    vs.latlong.data[(size_t)y * vs.latlong.stride + (size_t)x * 3 + c];
    double m_h[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            m_h[i][j] = m_out[i][j] * s_hdri;
    apply(&hdri, m_h);
    if (!chart.sensor.data || !grey.sensor.data)
        return;
    const double wb[3][3] = {{cam.wb[0], 0, 0}, {0, cam.wb[1], 0}, {0, 0, cam.wb[2]}};
    apply(&chart.sensor, wb);
    apply(&grey.sensor, wb);
    /* Chart: the preset's 6 x 4 grid at pitch 0.32 of a 2.0-wide view. */
    double centers[24][2];
    for (int p = 0; p < 24; p++) {
        centers[p][0] = cw * (0.5 + (p % 6 - 2.5) * 0.16);
        centers[p][1] = cw * (0.34 + (p / 6 - 1.5) * 0.16);
    }
    sl_chart_patch patches[24];
    CHECK_OK(sl_chart_sample(&chart.sensor, (const double(*)[2])centers, 0, 0.999, patches, &err),
             &err);
    sl_ccm_fit fit;
    CHECK_OK(sl_ccm_fit_chart(patches, SL_COLORCHECKER_LINEAR, NULL, &fit, &err), &err);
    double plate[3][3];
    sl_ccm_plate_matrix(patches, &fit, plate);
    /* The grey photo and the HDRI through the plate matrix, then the gains. */
    apply(&grey.sensor, plate);
    apply(&hdri, plate);
    sl_grey_options go;
    sl_grey_options_init(&go);
    go.circle[0] = go.circle[1] = go.circle[2] = n;
    go.size = n;
    go.spp = 2 * spp;
    go.seed = 99;
    go.clip_level = 0; /* the photo is under saturation by construction */
    sl_grey_fit gf;
    CHECK_OK(sl_grey_sphere_fit(&hdri, &grey.sensor, &go, &gf, &err), &err);
    double truth = s_grey / s_hdri;
    printf("  stage, 5D Mark II at %d K: chart %d px exposure %.4g s, grey %d px %.4g s; "
           "%d patches used\n",
           KELVIN, cw, ec.time_s, n, eg.time_s, fit.used);
    printf("  CIEDE2000 before %.2f mean %.2f max, after %.3f mean %.3f max\n", fit.de_before_mean,
           fit.de_before_max, fit.de_after_mean, fit.de_after_max);
    printf("  gains %.4f %.4f %.4f, scale %.4f (truth %.4f, %+.3f%%), rel RMSE before %.4f after "
           "%.4f, p95 %.4f\n",
           gf.gain[0], gf.gain[1], gf.gain[2], gf.scale, truth, 100 * (gf.scale / truth - 1),
           gf.rel_rmse_before, gf.rel_rmse_after, gf.error_p95);
    int worst = 0;
    for (int p = 0; p < 24; p++)
        if (fit.used_patch[p] && fit.de_after[p] > fit.de_after[worst])
            worst = p;
    printf("  worst patch %d (%s): %.3f, spread %.4f, %d px\n", worst + 1,
           SL_COLORCHECKER_NAMES[worst], fit.de_after[worst], patches[worst].spread,
           patches[worst].pixels);
    /* The simulated camera's raw RGB of a real chart: a ColorChecker. */
    sl_chart_judgement judged;
    sl_chart_judge(patches, &fit, SL_COLORCHECKER_LINEAR, &judged);
    printf("  judged: %s (neutral log contrast %.3f, matrix condition %.2f)\n",
           judged.plausible ? "a ColorChecker" : judged.text, judged.neutral_slope,
           judged.condition);
    CHECK_MSG(judged.plausible, "virtual chart refused: %s", judged.text);
    CHECK(fit.used >= 22);
    CHECK(fit.de_before_mean > 10); /* the tungsten balance is visibly off */
    CHECK(fit.de_after_mean <= 1.0);
    CHECK(fit.de_after_max <= 3.0);
    CHECK(fabs(gf.scale / truth - 1) < 0.01);
    for (int c = 0; c < 3; c++)
        CHECK(fabs(gf.gain[c] / truth - 1) < 0.02);
    CHECK(gf.rel_rmse_after < 0.02);
    /* The calibrated HDRI is the set as the plate camera sees it in the
     * working space: diag(g) P (M s_hdri L) against P (M s_grey L). */
    double pm[3][3], e = 0, ref = 0;
    sl_mat3_mul(plate, m_out, pm);
    for (int y = 0; y < hdri.height; y++) {
        double da = sl_latlong_texel_solid_angle(y, hdri.width, hdri.height);
        for (int x = 0; x < hdri.width; x++) {
            const float *t = vs.latlong.data + (size_t)y * vs.latlong.stride + (size_t)x * 3;
            const float *v = hdri.data + (size_t)y * hdri.stride + (size_t)x * 3;
            double l[3] = {t[0] * s_grey, t[1] * s_grey, t[2] * s_grey}, want[3];
            sl_mat3_apply(pm, l, want);
            for (int c = 0; c < 3; c++) {
                e += da * (gf.gain[c] * v[c] - want[c]) * (gf.gain[c] * v[c] - want[c]);
                ref += da * want[c] * want[c];
            }
        }
    }
    printf("  calibrated HDRI vs the plate's view of the set: rel RMSE %.4f%%\n",
           100 * sqrt(e / ref));
    CHECK(sqrt(e / ref) < 0.01);
    /* Absolute: the grey photo's exposure (t, f/4, ISO 100) gives cd/m^2 per
     * unit; the set's radiance is in cd/m^2. The plate matrix keeps the
     * neutral patch's luminance as the camera's RGB gives it (read as
     * Rec.709): the light's luminance comes back to that camera's fidelity
     * (white-balanced to tungsten, it reads 4-5% low here). */
    double a = sl_exposure_luminance(eg.time_s, eg.f_number, eg.iso), yl = 0, yt = 0;
    for (int y = 0; y < hdri.height; y++) {
        double da = sl_latlong_texel_solid_angle(y, hdri.width, hdri.height);
        for (int x = 0; x < hdri.width; x++) {
            const float *t = vs.latlong.data + (size_t)y * vs.latlong.stride + (size_t)x * 3;
            const float *v = hdri.data + (size_t)y * hdri.stride + (size_t)x * 3;
            yt += da * (sl_luminance_px(t));
            yl += da * a * (0.2126 * gf.gain[0] * v[0] + 0.7152 * gf.gain[1] * v[1] +
                            0.0722 * gf.gain[2] * v[2]);
        }
    }
    printf("  absolute: %.6g cd/m^2 per unit (1/s %.6g); sphere-integrated luminance %.5g vs "
           "truth %.5g (%+.2f%%)\n",
           a, 1 / s_grey, yl, yt, 100 * (yl / yt - 1));
    CHECK(fabs(a * s_grey - 1) < 1e-9);
    CHECK(fabs(yl / yt - 1) < 0.06);
    sl_grey_fit_free(&gf);
    sl_vset_shot_free(&chart);
    sl_vset_shot_free(&grey);
    sl_image_free(&chart_rad);
    sl_image_free(&grey_rad);
    sl_image_free(&hdri);
    sl_vset_scene_free(&vs);
}

int main(void)
{
    RUN(test_stage);
    return sl_test_finish();
}
