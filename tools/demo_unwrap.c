/* SPDX-License-Identifier: BSD-3-Clause */
/* `setlight demo` unwrap stage: the chrome ball's bracket merged, the ball
 * found, unwrapped with the perspective model and compared with the truth. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "demo.h"

#define CW 128
#define CH 64

/* Solid-angle-weighted mean luminance of img on a CW x CH grid (img's
 * size a multiple of it). */
static void coarse_luminance(const sl_image *img, double *out)
{
    static double wsum[CW * CH];
    memset(wsum, 0, sizeof wsum);
    memset(out, 0, sizeof(double) * CW * CH);
    int fx = img->width / CW, fy = img->height / CH;
    for (int y = 0; y < img->height; y++) {
        double dw = sl_latlong_texel_solid_angle(y, img->width, img->height);
        for (int x = 0; x < img->width; x++) {
            const float *p = sl_image_pixel(img, x, y);
            int i = (y / fy) * CW + x / fx;
            out[i] += dw * (sl_luminance_px(p));
            wsum[i] += dw;
        }
    }
    for (int i = 0; i < CW * CH; i++)
        out[i] /= wsum[i];
}

/* Luminance-weighted mean direction of img's texels within `radius`
 * (radians) of `axis`; false when they carry no light. */
static bool light_centroid(const sl_image *img, const double axis[3], double radius,
                           double out[3])
{
    double s[3] = {0, 0, 0}, cos_r = cos(radius);
    for (int y = 0; y < img->height; y++) {
        double dw = sl_latlong_texel_solid_angle(y, img->width, img->height);
        for (int x = 0; x < img->width; x++) {
            double dir[3];
            sl_latlong_to_dir((x + 0.5) / img->width, (y + 0.5) / img->height, dir);
            if (dir[0] * axis[0] + dir[1] * axis[1] + dir[2] * axis[2] < cos_r)
                continue;
            const float *p = sl_image_pixel(img, x, y);
            double w = dw * (sl_luminance_px(p));
            for (int c = 0; c < 3; c++)
                s[c] += w * dir[c];
        }
    }
    double len = sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
    if (!(len > 0))
        return false;
    for (int c = 0; c < 3; c++)
        out[c] = s[c] / len;
    return true;
}

static double angle_deg(const double a[3], const double b[3])
{
    double c = a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    return acos(fmax(-1, fmin(1, c))) * 180 / M_PI;
}

/* The chrome ball's map against the stitched HDRI, two ways of seeing the
 * same set: luminance on the 128 x 64 grid over the front hemisphere where
 * the stitch saw every texel, the energy there, and where each puts the
 * truth's lights that face the ball (the luminance-weighted centre of each
 * within its size plus 5 degrees of the truth's direction). */
static sl_result cross_check(demo *d, const sl_image *ball, const double *ball_coarse,
                             const double toward[3], char *note, size_t n, sl_error *err)
{
    sl_image hdri = {0};
    double *h = malloc(sizeof(double) * CW * CH);
    unsigned char *keep = calloc(CW * CH, 1);
    json_t *lights = NULL;
    sl_result r = SL_OK;
    if (!h || !keep) {
        r = sl_error_set(err, SL_ERR_NOMEM, "demo unwrap: out of memory");
        goto done;
    }
    if ((r = demo_hdri(d, &hdri, err)))
        goto done;
    if (hdri.width % CW || hdri.height % CH || d->confidence.width != hdri.width ||
        d->confidence.height != hdri.height) {
        r = sl_error_set(err, SL_ERR_INTERNAL, "%s: %dx%d, not a multiple of %dx%d", d->hdri,
                         hdri.width, hdri.height, CW, CH);
        goto done;
    }
    coarse_luminance(&hdri, h);
    int fx = hdri.width / CW, fy = hdri.height / CH;
    for (int y = 0; y < CH; y++)
        for (int x = 0; x < CW; x++) {
            double dir[3];
            sl_latlong_to_dir((x + 0.5) / CW, (y + 0.5) / CH, dir);
            bool seen = dir[0] * toward[0] + dir[1] * toward[1] + dir[2] * toward[2] > 0;
            for (int j = 0; j < fy && seen; j++)
                for (int i = 0; i < fx && seen; i++)
                    seen = *sl_image_pixel(&d->confidence, x * fx + i, y * fy + j) > 0;
            keep[y * CW + x] = seen;
        }
    demo_diff diff;
    if ((r = demo_diff_luminance(ball_coarse, h, keep, CW, CH, &diff, err)))
        goto done;
    if (!(lights = demo_load_json(d->capture, "truth/lights.json", err))) {
        r = err ? err->code : SL_ERR_INPUT;
        goto done;
    }
    sl_report_text(d->rep,
                   "Cross-check of the stitched HDRI: the chrome ball's map against hdri.exr "
                   "over the front hemisphere where the stitch saw every texel (%.2f sr, "
                   "128x64): median relative difference %.1f%%, 95th percentile %.1f%%, "
                   "energy ratio %.4f (ball / stitch). Each truth light facing the ball, where "
                   "each map puts it:",
                   diff.solid_angle, 100 * diff.median, 100 * diff.p95, 1 + diff.energy);
    static const char *const head[] = {"light", "truth az, el", "stitch az, el",
                                       "ball az, el", "stitch to ball (deg)"};
    sl_report_table_begin(d->rep, 5, head);
    json_t *arr = json_object_get(lights, "lights");
    double worst = 0;
    int compared = 0;
    for (size_t i = 0; i < json_array_size(arr); i++) {
        json_t *l = json_array_get(arr, i), *dj = json_object_get(l, "direction");
        double td[3], sd[3], bd[3];
        for (int c = 0; c < 3; c++)
            td[c] = json_number_value(json_array_get(dj, (size_t)c));
        if (td[0] * toward[0] + td[1] * toward[1] + td[2] * toward[2] <= 0)
            continue;
        double radius = sqrt(json_number_value(json_object_get(l, "solid_angle_sr")) / M_PI) +
                        5 * M_PI / 180;
        if (!light_centroid(&hdri, td, radius, sd) || !light_centroid(ball, td, radius, bd))
            continue;
        double a = angle_deg(sd, bd);
        worst = fmax(worst, a);
        compared++;
        char c[5][64];
        const double *ds[3] = {td, sd, bd};
        snprintf(c[0], 64, "%s", json_string_value(json_object_get(l, "name")));
        for (int k = 0; k < 3; k++)
            snprintf(c[k + 1], 64, "%.1f, %.1f", atan2(ds[k][0], ds[k][2]) * 180 / M_PI,
                     asin(fmax(-1, fmin(1, ds[k][1]))) * 180 / M_PI);
        snprintf(c[4], 64, "%.2f", a);
        const char *cells[5] = {c[0], c[1], c[2], c[3], c[4]};
        sl_report_table_row(d->rep, cells);
    }
    sl_report_table_end(d->rep);
    json_object_set_new(d->facts, "unwrap_vs_stitch",
                        json_pack("{s:f, s:f, s:f, s:f, s:i, s:f}", "solid_angle_sr",
                                  diff.solid_angle, "median_rel_difference", diff.median,
                                  "p95_rel_difference", diff.p95, "energy_ratio",
                                  1 + diff.energy, "lights", compared, "worst_light_deg",
                                  worst));
    sl_report_text(d->rep, "Lights compared: %d, worst angle between the two maps %.2f deg.",
                   compared, worst);
    snprintf(note, n, "; vs stitch median %.1f%%, p95 %.1f%%, energy ratio %.3f, lights within %.2f deg",
             100 * diff.median, 100 * diff.p95, 1 + diff.energy, worst);
done:
    json_decref(lights);
    free(h);
    free(keep);
    sl_image_free(&hdri);
    return r;
}

sl_result demo_stage_unwrap(demo *d, char *note, size_t n, sl_error *err)
{
    sl_merge_result mr;
    json_t *truth = NULL;
    double exposure, minv[3][3], k;
    sl_image ll = {0}, ball = {0}, est = {0};
    double *a = NULL, *b = NULL, *rel = NULL;
    sl_result r = demo_merge_probe(d, "chrome", false, &mr, &truth, &exposure, err);
    if (r)
        return r;
    if ((r = demo_camera_inverse(d, minv, &k, err)) || (r = demo_truth_latlong(d, &ll, err)))
        goto done;
    json_t *tb = json_object_get(truth, "ball"), *tc = json_object_get(truth, "camera");
    double tcx = json_number_value(json_object_get(tb, "cx"));
    double tcy = json_number_value(json_object_get(tb, "cy"));
    double tr = json_number_value(json_object_get(tb, "r_px"));

    /* Find the ball as on set; the truth circle if the detector cannot. */
    sl_unwrap_options o;
    memset(&o, 0, sizeof o);
    sl_error derr;
    bool detected = sl_ball_detect(&mr.radiance, "chrome ball", &o.circle, &derr) == SL_OK;
    if (!detected) {
        o.circle.cx = tcx;
        o.circle.cy = tcy;
        o.circle.r = tr;
    }
    double centre_off = hypot(o.circle.cx - tcx, o.circle.cy - tcy), r_off = o.circle.r - tr;
    o.geometry.camera = SL_BALL_PERSPECTIVE;
    o.geometry.focal_px = json_number_value(json_object_get(truth, "focal_px"));
    o.geometry.distance = json_number_value(json_object_get(tb, "distance_radii"));
    o.geometry.azimuth_deg = json_number_value(json_object_get(tc, "yaw_deg"));
    o.geometry.elevation_deg = json_number_value(json_object_get(tc, "pitch_deg"));
    o.geometry.roll_deg = json_number_value(json_object_get(tc, "roll_deg"));
    sl_reflectance_chrome(&o.reflectance);
    o.width = ll.width / 2;
    sl_unwrap_info info;
    double t0 = sl_seconds();
    if ((r = sl_unwrap(&mr.radiance, &o, &ball, &info, err)))
        goto done;
    double unwrap_s = sl_seconds() - t0;
    /* Back to the set's units: radiance = M^-1 * merged / exposure. */
    if ((r = sl_image_alloc(&est, ball.width, ball.height, 3, err)))
        goto done;
    for (int y = 0; y < ball.height; y++)
        for (int x = 0; x < ball.width; x++) {
            demo_set_units(sl_image_pixel(&ball, x, y), exposure, (const double(*)[3])minv,
                           sl_image_pixel(&est, x, y));
        }
    char path[4300];
    snprintf(path, sizeof path, "%s/unwrap_chrome.exr", d->dir);
    if ((r = sl_exr_write(path, &est, NULL, SL_PIXEL_FLOAT, err)))
        goto done;

    /* The front hemisphere (toward the camera), both maps on a 128 x 64 grid. */
    a = malloc(sizeof(double) * CW * CH);
    b = malloc(sizeof(double) * CW * CH);
    rel = malloc(sizeof(double) * CW * CH);
    if (!a || !b || !rel) {
        r = sl_error_set(err, SL_ERR_NOMEM, "demo unwrap: out of memory");
        goto done;
    }
    coarse_luminance(&est, a);
    coarse_luminance(&ll, b);
    json_t *fw = json_object_get(tc, "forward");
    double toward[3] = {-json_number_value(json_array_get(fw, 0)),
                        -json_number_value(json_array_get(fw, 1)),
                        -json_number_value(json_array_get(fw, 2))};
    double ea = 0, eb = 0, se = 0, sb = 0;
    int cnt = 0;
    for (int y = 0; y < CH; y++) {
        double dw = sl_latlong_texel_solid_angle(y, CW, CH);
        for (int x = 0; x < CW; x++) {
            double dir[3];
            sl_latlong_to_dir((x + 0.5) / CW, (y + 0.5) / CH, dir);
            if (dir[0] * toward[0] + dir[1] * toward[1] + dir[2] * toward[2] <= 0)
                continue;
            int i = y * CW + x;
            ea += a[i] * dw;
            eb += b[i] * dw;
            se += dw * (a[i] - b[i]) * (a[i] - b[i]);
            sb += dw * b[i] * b[i];
            rel[cnt++] = fabs(a[i] / (b[i] > 1e-9 ? b[i] : 1e-9) - 1);
        }
    }
    qsort(rel, (size_t)cnt, sizeof *rel, sl_cmp_double);
    double energy = ea / eb - 1, rrmse = sqrt(se / sb), median = rel[cnt / 2],
           p90 = rel[(int)(0.9 * cnt)];

    sl_report_section(d->rep, "Unwrap");
    sl_report_text(d->rep,
                   "Chrome ball (%.0f mm at %.1f m, %.0f mm lens): %d linear TIFFs merged in "
                   "%.2f s. Ball %s: centre %.2f px and radius %+.2f px from the truth (r = "
                   "%.1f px). Unwrapped with the perspective model (ball seen %.2f deg wide, "
                   "blind cone %.1f deg) to %dx%d in %.2f s, then divided by the exposure and "
                   "the camera's output matrix (truth/camera.json) to return to cd/m^2.",
                   1000 * json_number_value(json_object_get(tb, "diameter_m")),
                   json_number_value(json_object_get(truth, "distance_m")),
                   json_number_value(json_object_get(truth, "focal_mm")), mr.frame_count,
                   mr.seconds, detected ? "detected" : "not detected (truth circle used)",
                   centre_off, r_off, tr, 2 * info.ball_angle_deg, info.blind_angle_deg,
                   ball.width, ball.height, unwrap_s);
    sl_report_text(d->rep,
                   "Against truth/latlong.exr over the front hemisphere (toward the camera), "
                   "both averaged to 128x64: energy %+.2f%%, relative RMSE %.1f%%, median "
                   "texel error %.1f%%, 90th percentile %.1f%%.",
                   100 * energy, 100 * rrmse, 100 * median, 100 * p90);
    if ((r = sl_report_image(d->rep, "unwrap_ball.png", &mr.radiance,
                             demo_stops(d->lavg * exposure), "merged chrome ball (camera RGB)",
                             err)) ||
        (r = sl_report_image(d->rep, "unwrap_chrome.png", &est, demo_stops(d->lavg),
                             "unwrap_chrome.exr: the set from the chrome ball, cd/m^2", err)))
        goto done;
    int used = snprintf(note, n,
                        "ball %s (%.2f px off); front hemisphere energy %+.1f%%, median texel "
                        "error %.1f%%",
                        detected ? "detected" : "from truth", centre_off, 100 * energy,
                        100 * median);
    if (used > 0 && (size_t)used < n)
        r = cross_check(d, &est, a, toward, note + used, n - (size_t)used, err);
done:
    free(a);
    free(b);
    free(rel);
    json_decref(truth);
    sl_merge_result_free(&mr);
    sl_image_free(&ll);
    sl_image_free(&ball);
    sl_image_free(&est);
    return r;
}
