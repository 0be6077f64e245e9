/* SPDX-License-Identifier: BSD-3-Clause */
/* `setlight demo` calibrate stage: the chart's colour matrix (CIEDE2000
 * before and after), and the grey ball's gains for the stitched HDRI
 * against the grey-ball photo taken back to cd/m^2 through the camera model
 * (truth/camera.json, EXIF): they should be 1. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "demo.h"
#include "setlight/render.h"

sl_result demo_stage_calibrate(demo *d, char *note, size_t n, sl_error *err)
{
    sl_merge_result chart = {0}, grey = {0};
    json_t *ct = NULL, *gt = NULL;
    double ce, ge;
    sl_image ll = {0};
    sl_grey_fit gfit;
    memset(&gfit, 0, sizeof gfit);
    sl_result r = demo_merge_probe(d, "chart", true, &chart, &ct, &ce, err);
    if (!r)
        r = demo_merge_probe(d, "grey", false, &grey, &gt, &ge, err);
    if (!r)
        r = demo_hdri(d, &ll, err);
    if (r)
        goto done;

    /* Chart: its middle frame, metered for the chart, alone: the camera clips
     * each white-balanced channel before its colour matrix, so a longer
     * frame's saturated yellow leaves the other channels wrong but below
     * the merge's saturation level. Sampled at the truth's patch centres;
     * the detector scored against them. */
    double centers[24][2];
    json_t *pc = json_object_get(json_object_get(ct, "chart"), "patch_centers");
    for (int i = 0; i < 24; i++)
        for (int j = 0; j < 2; j++)
            centers[i][j] = json_number_value(json_array_get(json_array_get(pc, (size_t)i),
                                                             (size_t)j));
    sl_chart_detection det;
    sl_error derr;
    double det_off = -1;
    if (sl_chart_detect(&chart.radiance, 0, "chart", &det, &derr) == SL_OK) {
        det_off = 0;
        for (int i = 0; i < 24; i++)
            det_off = fmax(det_off, hypot(det.centers[i][0] - centers[i][0],
                                          det.centers[i][1] - centers[i][1]));
    }
    sl_chart_patch patches[24];
    sl_ccm_options co;
    sl_ccm_options_init(&co);
    sl_ccm_fit fit;
    if ((r = sl_chart_sample(&chart.radiance, (const double(*)[2])centers, 0, 0, patches, err)))
        goto done;
    /* The camera clips its output at 0 too: a saturated yellow's blue,
     * pushed below 0 by the colour matrix, reads 0 and no matrix can map it
     * back. Such patches stay out of the fit. */
    int black_clipped = 0;
    for (int i = 0; i < 24; i++) {
        int zero = 0, all = 0;
        double rad = patches[i].radius, cx = patches[i].center[0], cy = patches[i].center[1];
        for (int y = (int)(cy - rad); y <= (int)(cy + rad); y++)
            for (int x = (int)(cx - rad); x <= (int)(cx + rad); x++) {
                if (x < 0 || y < 0 || x >= chart.radiance.width || y >= chart.radiance.height ||
                    hypot(x + 0.5 - cx, y + 0.5 - cy) > rad)
                    continue;
                const float *v = sl_image_pixel(&chart.radiance, x, y);
                all++;
                zero += fminf(v[0], fminf(v[1], v[2])) <= 1e-3f * fmaxf(v[0], fmaxf(v[1], v[2]));
            }
        if (patches[i].valid && zero > all / 10) {
            patches[i].valid = false;
            black_clipped++;
        }
    }
    if ((r = sl_ccm_fit_chart(patches, SL_COLORCHECKER_LINEAR, &co, &fit, err)))
        goto done;

    /* Grey ball: the photo back in the set's units, then the gains that make
     * the stitched HDRI render like it. */
    double minv[3][3], k;
    if ((r = demo_camera_inverse(d, minv, &k, err)))
        goto done;
    for (int y = 0; y < grey.radiance.height; y++)
        for (int x = 0; x < grey.radiance.width; x++) {
            float *p = sl_image_pixel(&grey.radiance, x, y);
            demo_set_units(p, ge, (const double(*)[3])minv, p);
        }
    json_t *tb = json_object_get(gt, "ball"), *tc = json_object_get(gt, "camera");
    sl_grey_options go;
    sl_grey_options_init(&go);
    go.circle[0] = json_number_value(json_object_get(tb, "cx"));
    go.circle[1] = json_number_value(json_object_get(tb, "cy"));
    go.circle[2] = json_number_value(json_object_get(tb, "r_px"));
    go.azimuth_deg = json_number_value(json_object_get(tc, "yaw_deg"));
    go.elevation_deg = json_number_value(json_object_get(tc, "pitch_deg"));
    /* The probe's long lens at its distance: the virtual sphere from the same pinhole. */
    go.focal_px = json_number_value(json_object_get(gt, "focal_px"));
    go.distance = json_number_value(json_object_get(tb, "distance_radii"));
    go.size = d->size == SL_VSET_SIZE_TINY ? 32 : 64;
    go.spp = 64;
    go.seed = d->seed;
    if ((r = sl_grey_sphere_fit(&ll, &grey.radiance, &go, &gfit, err)))
        goto done;
    double scale_err = gfit.scale - 1, worst_gain = 0;
    for (int c = 0; c < 3; c++)
        worst_gain = fmax(worst_gain, fabs(gfit.gain[c] - 1));

    sl_report_section(d->rep, "Calibrate");
    char det_text[1200];
    if (det_off >= 0)
        snprintf(det_text, sizeof det_text, "found by the detector within %.2f px of the truth",
                 det_off);
    else
        snprintf(det_text, sizeof det_text, "not found by the detector (%s)", derr.message);
    sl_report_text(d->rep,
                   "Chart: the middle frame of its bracket (linear TIFF); patches sampled at the truth's centres (%s); "
                   "%d patches clipped at 0 in a channel by the camera left out. Colour matrix "
                   "fitted on %d patches: CIEDE2000 mean %.2f (max %.2f) before, %.2f (max "
                   "%.2f) after.",
                   det_text, black_clipped, fit.used, fit.de_before_mean,
                   fit.de_before_max, fit.de_after_mean, fit.de_after_max);
    sl_report_text(d->rep,
                   "Grey ball: %d frames merged and taken back to cd/m^2 through the camera "
                   "model (output matrix, EXIF exposure); virtual sphere seen by the probe's "
                   "pinhole (%.0f px focal length, %.1f ball radii away). Gains for the stitched "
                   "hdri.exr to match it, all 1 for a right stitch: %.4f %.4f %.4f, exposure scale %.4f (%+.2f%%, "
                   "worst channel %.2f%%). Sphere relative RMSE %.1f%% before (exposure "
                   "only), %.1f%% after.",
                   grey.frame_count, go.focal_px, go.distance, gfit.gain[0], gfit.gain[1], gfit.gain[2], gfit.scale,
                   100 * scale_err, 100 * worst_gain, 100 * gfit.rel_rmse_before,
                   100 * gfit.rel_rmse_after);
    if ((r = sl_report_image(d->rep, "calibrate_chart.png", &chart.radiance,
                             demo_stops(d->lavg * ce), "merged chart photo (camera RGB)", err)) ||
        (r = sl_calibrate_report(d->rep, "calibrate_", patches, &fit, &gfit, err)))
        goto done;
    snprintf(note, n, "chart dE2000 %.2f -> %.2f; stitched HDRI's grey-ball exposure scale %+.2f%%",
             fit.de_before_mean, fit.de_after_mean, 100 * scale_err);
done:
    sl_grey_fit_free(&gfit);
    sl_merge_result_free(&chart);
    sl_merge_result_free(&grey);
    json_decref(ct);
    json_decref(gt);
    sl_image_free(&ll);
    return r;
}
