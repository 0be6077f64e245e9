/* SPDX-License-Identifier: BSD-3-Clause */
/* The calibrate stage from files to files: the HDRI made to match the
 * plate camera through a ColorChecker and a grey sphere shot in the same
 * light; the calibrated HDRI and its report written as one output set. */
#include <errno.h>
#include <float.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "setlight/render.h"
#include "setlight/stitch.h"

void sl_calibrate_run_options_init(sl_calibrate_run_options *o)
{
    memset(o, 0, sizeof *o);
    o->out_colorspace = "lin_rec709";
    o->clip = -1;
    o->hdri_in_chart = true;
    o->sun_repair = true;
    o->absolute = true;
    o->exposure_tolerance = 1;
    sl_ball_lens_init(&o->camera);
    sl_ccm_options_init(&o->ccm);
    sl_grey_options_init(&o->grey);
    sl_sun_options_init(&o->sun);
}

void sl_calibrate_run_result_free(sl_calibrate_run_result *res)
{
    free(res->json);
    res->json = NULL;
}

static void mat_apply(const double m[3][3], float *v)
{
    double r[3];
    for (int c = 0; c < 3; c++)
        r[c] = m[c][0] * v[0] + m[c][1] * v[1] + m[c][2] * v[2];
    for (int c = 0; c < 3; c++)
        v[c] = (float)r[c];
}

static void apply_image(sl_image *img, const double m[3][3])
{
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++)
            mat_apply(m, img->data + (size_t)y * img->stride + (size_t)x * img->channels);
}

/* Brings a photo into the working space (linear Rec.709) as every command
 * does (sl_image_linearize: from `cs`, or NULL for the file's own space,
 * sRGB for 8/16-bit photos that name none). Clipping is judged on the
 * file's values before the conversion (*level: the --clip level, < 0 for
 * the default: 0.999 for 8/16-bit photos, none for float); clipped pixels
 * then carry `marker` and *level becomes what the later stages test against. */
static sl_result to_working(sl_image *img, const char *path, sl_meta *meta, const char *cs,
                            double *level, float marker, sl_error *err)
{
    if (*level < 0 && !meta->is_float)
        *level = 0.999;
    /* No level given for a float file: values pinned at its top are clipped. */
    double pinned[3] = {0, 0, 0};
    int64_t pinned_count = *level < 0 ? sl_pinned_maximum(img, pinned) : 0;
    if (pinned_count)
        sl_log(SL_LOG_WARN, "%s: %lld pixels pinned at the image's maximum (%g %g %g per "
               "channel, 0: none) taken as clipped (--clip LEVEL sets the level)", path,
               (long long)pinned_count, pinned[0], pinned[1], pinned[2]);
    unsigned char *clipped = NULL;
    if (*level > 0 || pinned_count) {
        clipped = calloc((size_t)img->width * img->height, 1);
        if (!clipped)
            return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
        for (int y = 0; y < img->height; y++)
            for (int x = 0; x < img->width; x++) {
                const float *v = img->data + (size_t)y * img->stride + (size_t)x * img->channels;
                bool over = *level > 0 && (v[0] >= *level || v[1] >= *level || v[2] >= *level);
                for (int c = 0; c < 3; c++)
                    over = over || (pinned[c] > 0 && v[c] >= pinned[c]);
                clipped[(size_t)y * img->width + x] = over;
            }
    }
    sl_result r = sl_image_linearize(img, meta, path, cs, NULL, err);
    if (r) {
        free(clipped);
        return r;
    }
    if (clipped) {
        for (int y = 0; y < img->height; y++)
            for (int x = 0; x < img->width; x++)
                if (clipped[(size_t)y * img->width + x]) {
                    float *v = img->data + (size_t)y * img->stride + (size_t)x * img->channels;
                    v[0] = v[1] = v[2] = marker;
                }
        free(clipped);
        *level = isnan(marker) ? 0 : marker;
    } else {
        *level = 0;
    }
    return SL_OK;
}

static json_t *json_matrix(const double m[3][3])
{
    json_t *a = json_array();
    for (int i = 0; i < 3; i++)
        json_array_append_new(a, json_pack("[f,f,f]", m[i][0], m[i][1], m[i][2]));
    return a;
}

static json_t *judgement_json(const sl_chart_judgement *j)
{
    return json_pack("{s:b, s:s, s:i, s:i, s:i, s:f, s:i, s:f, s:f, s:i, s:f, s:f}", "plausible",
                     j->plausible, "reasons", j->text, "patches_used", j->used, "neutrals_used",
                     j->neutrals_used, "order_breaks", j->order_breaks, "neutral_slope",
                     j->neutral_slope, "colours_usable", j->colours_usable, "colour_chroma",
                     j->colour_chroma, "neutral_chroma", j->neutral_chroma, "hue_turns",
                     j->hue_turns, "condition", j->condition, "delta_e_limit", j->de_limit);
}


sl_result sl_calibrate_run(const sl_calibrate_run_options *o, sl_calibrate_run_result *res,
                           sl_error *err_out)
{
    sl_image hdri = {0}, chart = {0}, grey = {0}, mask = {0};
    sl_meta hmeta, cmeta, gmeta, mmeta, out_meta;
    sl_meta_init(&hmeta);
    sl_meta_init(&cmeta);
    sl_meta_init(&gmeta);
    sl_meta_init(&mmeta);
    sl_meta_init(&out_meta);
    sl_grey_fit gfit = {0};
    sl_sun_repair sun = {0};
    sl_error err = {0};
    sl_result r;
    json_t *js = json_object();
    sl_grey_options gopt = o->grey;
    bool have_circle = gopt.circle[2] > 0;
    memset(res, 0, sizeof *res);
    if (!js)
        return sl_error_set(err_out, SL_ERR_NOMEM, "out of memory");
    if (!o->hdri_path || !o->out_path || (!o->chart_path && !o->grey_path) ||
        (o->have_corners && !o->chart_path)) {
        json_decref(js);
        return sl_error_set(err_out, SL_ERR_USAGE, "calibrate needs an HDRI, an output and a "
                            "chart or a grey sphere photo (corners only with a chart)");
    }
    double t[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, plate[3][3], reference[24][3];
    bool chart_used = false, plate_on_hdri = false;
    double abs_scale = 0; /* cd/m^2 per unit of the calibrated HDRI, 0: relative */
    char abs_from[256] = "";
    int64_t neg_samples = 0;
    double neg_fraction = 0;
    char mask_buf[4096];
    sl_chart_patch p[24];
    sl_ccm_fit fit;
    sl_chart_judgement judgement;
    bool chart_sampled = false;
    memset(&fit, 0, sizeof(fit));
    memset(&judgement, 0, sizeof(judgement));

    memcpy(reference, SL_COLORCHECKER_LINEAR, sizeof(reference));
    if (o->chart_reference && (r = sl_chart_reference_read(o->chart_reference, reference, NULL, &err)))
        goto fail;
    /* Scene-linear Rec.709, as every command reads a lat-long. */
    if ((r = sl_latlong_read(o->hdri_path, NULL, &hdri, &hmeta, NULL, &err)))
        goto fail;
    if (hdri.channels < 3) {
        r = sl_error_set(&err, SL_ERR_INPUT, "%s: not an RGB lat-long (%dx%d, %d channels)",
                         o->hdri_path, hdri.width, hdri.height, hdri.channels);
        goto fail;
    }
    {
        sl_image_stats st;
        sl_image_stats_compute(&hdri, &st);
        if (st.nan_count + st.inf_count) {
            sl_log(SL_LOG_WARN, "%s: %lld NaN and %lld Inf samples replaced by 0", o->hdri_path,
                   (long long)st.nan_count, (long long)st.inf_count);
            sl_image_sanitize(&hdri, 0.0f);
        }
    }
    if (o->chart_path) {
        if ((r = sl_image_read(o->chart_path, &chart, &cmeta, &err)))
            goto fail;
        if (chart.channels < 3) {
            r = sl_error_set(&err, SL_ERR_INPUT, "%s: the chart photo needs RGB", o->chart_path);
            goto fail;
        }
        double level = o->clip;
        if ((r = to_working(&chart, o->chart_path, &cmeta, o->chart_colorspace, &level, FLT_MAX, &err)))
            goto fail;
        double centers[24][2];
        json_t *jc = json_object();
        json_object_set_new(js, "chart", jc);
        json_object_set_new(jc, "file", json_string(o->chart_path));
        json_object_set_new(jc, "reference", json_string(o->chart_reference ? o->chart_reference : "classic24"));
        if (o->have_corners) {
            r = sl_chart_centers_from_corners((const double(*)[2])o->corners, centers, &err);
            json_object_set_new(jc, "located", json_string("o->corners"));
        } else {
            sl_chart_detection det;
            r = sl_chart_detect(&chart, level, o->chart_path, &det, &err);
            if (!r)
                memcpy(centers, det.centers, sizeof(centers));
            json_object_set_new(jc, "located", json_string(r ? "not found" : "detected"));
        }
        if (r == SL_ERR_INPUT && !o->have_corners && o->grey_path) {
            /* No chart: the grey sphere alone still calibrates exposure and balance. */
            sl_log(SL_LOG_WARN, "%s; continuing with the grey sphere alone", err.message);
        } else if (r) {
            goto fail;
        } else {
            if ((r = sl_chart_sample(&chart, (const double(*)[2])centers, 0, level, p, &err)))
                goto fail;
            chart_sampled = true;
            if ((r = sl_ccm_fit_chart(p, (const double(*)[3])reference, &o->ccm, &fit, &err))) {
                if (r != SL_ERR_INPUT || !o->grey_path) {
                    sl_error_set(&err, r, "%s: %s", o->chart_path, err.message);
                    goto fail;
                }
                /* Too few patches for any matrix: judged as such below. */
                memset(&fit, 0, sizeof(fit));
                snprintf(judgement.text, sizeof judgement.text, "%.600s", err.message);
                judgement.reasons = SL_CHART_FEW_PATCHES;
            } else {
                sl_chart_judge(p, &fit, (const double(*)[3])reference, &judgement);
            }
            json_t *jp = json_array();
            int invalid = 0;
            for (int q = 0; q < 24; q++) {
                invalid += !p[q].valid;
                json_array_append_new(
                    jp, json_pack("{s:i, s:s, s:[f,f], s:i, s:i, s:f, s:b, s:b, s:f, s:f}", "patch",
                                  q + 1, "name", SL_COLORCHECKER_NAMES[q], "center",
                                  p[q].center[0], p[q].center[1], "pixels", p[q].pixels,
                                  "clipped", p[q].clipped, "spread", p[q].spread, "outlier",
                                  fit.outlier[q], "used", fit.used_patch[q], "delta_e_before",
                                  fit.de_before[q], "delta_e_after", fit.de_after[q]));
            }
            json_object_set_new(jc, "patches", jp);
            json_object_set_new(jc, "matrix", json_matrix(fit.m));
            json_object_set_new(jc, "patches_used", json_integer(fit.used));
            json_object_set_new(jc, "patches_invalid", json_integer(invalid));
            json_object_set_new(jc, "patches_outliers", json_integer(fit.outliers));
            json_object_set_new(jc, "delta_e_before_mean", json_real(fit.de_before_mean));
            json_object_set_new(jc, "delta_e_before_max", json_real(fit.de_before_max));
            json_object_set_new(jc, "delta_e_after_mean", json_real(fit.de_after_mean));
            json_object_set_new(jc, "delta_e_after_max", json_real(fit.de_after_max));
            json_object_set_new(jc, "judgement", judgement_json(&judgement));
            if (!judgement.plausible) {
                /* Not a ColorChecker, or not one a matrix can be trusted from. */
                if (!o->grey_path) {
                    r = sl_error_set(&err, SL_ERR_INPUT, "%s: not a usable ColorChecker: %s",
                                     o->chart_path, judgement.text);
                    goto fail;
                }
                sl_log(SL_LOG_WARN, "%s: not a usable ColorChecker (%s); calibrating with the "
                       "grey sphere alone", o->chart_path, judgement.text);
            } else {
                sl_ccm_plate_matrix(p, &fit, plate);
                chart_used = true;
                sl_log(SL_LOG_INFO,
                       "%s: ColorChecker, %d of 24 patches used (%d excluded, %d lit "
                       "differently); CIEDE2000 mean %.2f -> %.2f, max %.2f -> %.2f",
                       o->chart_path, fit.used, invalid, fit.outliers, fit.de_before_mean,
                       fit.de_after_mean, fit.de_before_max, fit.de_after_max);
            }
            json_object_set_new(jc, "used", json_boolean(chart_used));
        }
    }
    if (chart_used && (o->hdri_in_chart || !o->grey_path)) {
        /* The HDRI in the chart camera's RGB: into the working space through P. */
        apply_image(&hdri, plate);
        memcpy(t, plate, sizeof(t));
        plate_on_hdri = true;
    }
    if (o->grey_path) {
        if ((r = sl_image_read(o->grey_path, &grey, &gmeta, &err)))
            goto fail;
        if (grey.channels < 3) {
            r = sl_error_set(&err, SL_ERR_INPUT, "%s: the grey-sphere photo needs RGB", o->grey_path);
            goto fail;
        }
        if (!have_circle) {
            /* Found as unwrap finds a chrome ball: Hough candidates, sub-pixel edge fit. */
            sl_ball_circle found;
            if ((r = sl_ball_detect(&grey, o->grey_path, &found, &err))) {
                if (r == SL_ERR_INPUT)
                    sl_error_set(&err, r,
                                 "%s: no grey sphere found (one whole sphere in the frame is "
                                 "needed; or give --grey-circle CX,CY,R)",
                                 o->grey_path);
                goto fail;
            }
            gopt.circle[0] = found.cx, gopt.circle[1] = found.cy, gopt.circle[2] = found.r;
        }
        /* Clipped pixels are judged on the file's values and carry NaN from
         * then on, which the fit skips. */
        double level = o->clip;
        if ((r = to_working(&grey, o->grey_path, &gmeta, o->grey_colorspace, &level, NAN, &err)))
            goto fail;
        if (chart_used) {
            /* Shot on the plate's camera, like the chart. */
            apply_image(&grey, plate);
        }
        gopt.clip_level = level;
        /* The photo's camera, as unwrap takes it: focal length in pixels of
         * this image from the lens (EXIF when only the sensor is given) or
         * the field of view; distance in sphere radii. */
        sl_ball_lens_geometry(&o->camera, grey.width, gmeta.focal_length_mm, &gopt.focal_px,
                                  &gopt.distance);
        if (o->camera.camera == SL_BALL_ORTHOGRAPHIC)
            gopt.focal_px = gopt.distance = 0;
        else if (o->camera.camera == SL_BALL_PERSPECTIVE && gopt.focal_px == 0 && gopt.distance == 0) {
            r = sl_error_set(&err, SL_ERR_USAGE,
                             "%s: --camera perspective needs the focal length (--focal-mm and "
                             "--sensor-mm, EXIF, or --fov) or --distance", o->grey_path);
            goto fail;
        }
        /* The merge's clipped mask: a source clipped in every frame. */
        const char *mp = o->clipped_mask ? o->clipped_mask : sl_meta_get(&hmeta, "setlight:merge:clipped_mask");
        if (mp && !o->clipped_mask && access(mp, R_OK) != 0) {
            /* Recorded relative to where the merge ran: try beside the HDRI. */
            const char *slash = strrchr(o->hdri_path, '/'), *base = strrchr(mp, '/');
            snprintf(mask_buf, sizeof mask_buf, "%.*s%s", slash ? (int)(slash - o->hdri_path + 1) : 0,
                     o->hdri_path, base ? base + 1 : mp);
            if (access(mask_buf, R_OK) == 0) {
                mp = mask_buf;
            } else {
                sl_log(SL_LOG_WARN, "%s: its clipped mask %s is missing; no sun repair", o->hdri_path,
                       mp);
                mp = NULL;
            }
        }
        if (mp && o->sun_repair) {
            if ((r = sl_image_read(mp, &mask, &mmeta, &err)))
                goto fail;
            r = sl_sun_repair_fit(&hdri, &mask, &grey, &gopt, &o->sun, &sun, &err);
            if (r == SL_ERR_INPUT) {
                sl_log(SL_LOG_WARN, "%s: %s; not repaired", mp, err.message);
                json_object_set_new(js, "sun_repair", json_pack("{s:s, s:s}", "mask", mp,
                                                                "error", err.message));
                memset(&sun, 0, sizeof(sun));
            } else if (r) {
                goto fail;
            }
        }
        if ((r = sl_grey_sphere_fit(&hdri, &grey, &gopt, &gfit, &err))) {
            sl_error_set(&err, r, "%s: %s", o->grey_path, err.message);
            goto fail;
        }
        double g[3][3] = {{gfit.gain[0], 0, 0}, {0, gfit.gain[1], 0}, {0, 0, gfit.gain[2]}};
        apply_image(&hdri, g);
        sl_mat3_mul(g, t, t);
        /* Absolute: the grey photo's exposure gives cd/m^2 per unit. */
        double lp = sl_exposure_luminance(gmeta.exposure_time, gmeta.f_number, gmeta.iso);
        if (lp > 0) {
            /* The HDRI's own exposure: its EXIF, else the merge's reference frame. */
            double eh = hmeta.exposure_time > 0 && hmeta.f_number > 0 && hmeta.iso > 0
                            ? hmeta.exposure_time * hmeta.iso / (hmeta.f_number * hmeta.f_number)
                            : 0;
            const char *ref = sl_meta_get(&hmeta, "setlight:merge:reference_exposure");
            if (!(eh > 0) && ref)
                eh = strtod(ref, NULL);
            double ep = gmeta.exposure_time * gmeta.iso / (gmeta.f_number * gmeta.f_number);
            if (eh > 0 && isfinite(eh)) {
                /* Photo units per HDRI unit: the metadata says ep / eh, the sphere says scale. */
                double stops = log2(gfit.scale * eh / ep);
                json_object_set_new(js, "exposure_check",
                                    json_pack("{s:f, s:f, s:f, s:f}", "hdri_exposure", eh,
                                              "grey_exposure", ep, "disagreement_stops", stops,
                                              "tolerance_stops", o->exposure_tolerance));
                if (!(fabs(stops) <= o->exposure_tolerance)) {
                    r = sl_error_set(&err, SL_ERR_INPUT,
                                     "%s: exposure metadata (%g s, f/%g, ISO %g) contradicts "
                                     "the HDRI's (reference exposure %g): the grey sphere puts "
                                     "them %.2f stops apart (tolerance %g)",
                                     o->grey_path, gmeta.exposure_time, gmeta.f_number, gmeta.iso,
                                     eh, stops, o->exposure_tolerance);
                    goto fail;
                }
            }
            if (o->absolute) {
                abs_scale = lp;
                snprintf(abs_from, sizeof abs_from, "%s: %g s, f/%g, ISO %g", o->grey_path,
                         gmeta.exposure_time, gmeta.f_number, gmeta.iso);
                double a[3][3] = {{lp, 0, 0}, {0, lp, 0}, {0, 0, lp}};
                apply_image(&hdri, a);
                sl_mat3_mul(a, t, t);
            }
        }
        json_object_set_new(js, "grey",
                            json_pack("{s:s, s:[f,f,f], s:[f,f,f], s:f, s:[f,f,f], s:I, s:I, s:f, s:f, s:f}",
                                      "file", o->grey_path, "circle", gopt.circle[0],
                                      gopt.circle[1], gopt.circle[2], "gain", gfit.gain[0],
                                      gfit.gain[1],
                                      gfit.gain[2], "scale", gfit.scale, "balance",
                                      gfit.balance[0], gfit.balance[1], gfit.balance[2], "pixels",
                                      (json_int_t)gfit.pixels, "rejected",
                                      (json_int_t)gfit.rejected, "rel_rmse_before",
                                      gfit.rel_rmse_before, "rel_rmse_after",
                                      gfit.rel_rmse_after, "error_p95", gfit.error_p95));
        json_object_set_new(json_object_get(js, "grey"), "camera",
                            json_pack("{s:s, s:f, s:f}", "model",
                                      gopt.focal_px > 0 || gopt.distance > 0 ? "perspective"
                                                                             : "orthographic",
                                      "focal_px", gopt.focal_px, "distance_radii", gopt.distance));
        if (sun.repaired) {
            /* In the output's units: times the gains and the absolute scale. */
            double k = abs_scale > 0 ? abs_scale : 1, rad[3], sig[3], added[3], before[3];
            for (int ch = 0; ch < 3; ch++) {
                rad[ch] = sun.radiance[ch] * gfit.gain[ch] * k;
                sig[ch] = sun.radiance_sigma[ch] * gfit.gain[ch] * k;
                added[ch] = sun.energy_added[ch] * gfit.gain[ch] * k;
                before[ch] = sun.energy_before[ch] * gfit.gain[ch] * k;
            }
            double la = 0.2126 * added[0] + 0.7152 * added[1] + 0.0722 * added[2];
            double lb = 0.2126 * before[0] + 0.7152 * before[1] + 0.0722 * before[2];
            sl_log(SL_LOG_INFO,
                   "%s: clipped source at azimuth %.2f, elevation %.2f repaired: radiance %.4g "
                   "(+-%.2f%%), %.1f%% energy added; grey sphere error %.2f%% -> %.2f%%",
                   o->hdri_path, sun.azimuth_deg, sun.elevation_deg,
                   0.2126 * rad[0] + 0.7152 * rad[1] + 0.0722 * rad[2],
                   100 * sun.radiance_sigma[1] / fmax(sun.fitted[1], 1e-30),
                   lb > 0 ? 100 * la / lb : 0, 100 * sun.rel_rmse_before,
                   100 * gfit.rel_rmse_after);
            json_object_set_new(
                js, "sun_repair",
                json_pack("{s:s, s:I, s:f, s:f, s:f, s:f, s:f, s:[f,f,f], s:[f,f,f], s:[f,f,f], "
                          "s:[f,f,f], s:f, s:f, s:f}",
                          "mask", mp, "clipped_texels",
                          (json_int_t)sun.clipped_texels, "clipped_solid_angle_sr",
                          sun.solid_angle, "azimuth_deg", sun.azimuth_deg, "elevation_deg",
                          sun.elevation_deg, "diameter_deg", o->sun.diameter_deg,
                          "source_solid_angle_sr", sun.source_solid_angle, "radiance", rad[0],
                          rad[1], rad[2], "radiance_sigma", sig[0], sig[1], sig[2],
                          "energy_before", before[0], before[1], before[2], "energy_added",
                          added[0], added[1], added[2], "energy_added_fraction",
                          lb > 0 ? la / lb : 0, "rel_rmse_before", sun.rel_rmse_before,
                          "rel_rmse_after", sun.rel_rmse_after));
        }
    } else if (!chart_used) {
        r = sl_error_set(&err, SL_ERR_INPUT, "%s: nothing to calibrate with", o->hdri_path);
        goto fail;
    }
    char buf[512];
    snprintf(buf, sizeof buf, "%.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g", t[0][0], t[0][1],
             t[0][2], t[1][0], t[1][1], t[1][2], t[2][0], t[2][1], t[2][2]);
    if ((r = sl_meta_set(&out_meta, "setlight:calibration_matrix", buf, &err)))
        goto fail;
    if (chart_used) {
        snprintf(buf, sizeof buf, "%.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g", plate[0][0],
                 plate[0][1], plate[0][2], plate[1][0], plate[1][1], plate[1][2], plate[2][0],
                 plate[2][1], plate[2][2]);
        if ((r = sl_meta_set(&out_meta, "setlight:plate_matrix", buf, &err)) ||
            (r = sl_meta_set(&out_meta, "setlight:calibration_hdri_in",
                             plate_on_hdri ? "chart" : "working", &err)))
            goto fail;
    }
    /* The chart's reference reflectances are for a white light, so a chart
     * fit makes the light on the chart white; the grey sphere alone keeps
     * its photo's white balance. */
    const char *white = chart_used ? "chart" : "camera";
    snprintf(buf, sizeof buf, "%.9g", o->grey_path ? gfit.scale : 1.0);
    if ((r = sl_meta_set(&out_meta, "setlight:calibration_white", white, &err)) ||
        (r = sl_meta_set(&out_meta, "setlight:calibration_scale", buf, &err)) ||
        (r = sl_meta_set(&out_meta, "setlight:source", o->hdri_path, &err)) ||
        (r = sl_meta_set(&out_meta, "setlight:units", abs_scale > 0 ? "cd/m^2" : "relative",
                         &err)))
        goto fail;
    if (abs_scale > 0) {
        snprintf(buf, sizeof buf, "%.9g", abs_scale);
        if ((r = sl_meta_set(&out_meta, "setlight:absolute_scale", buf, &err)) ||
            (r = sl_meta_set(&out_meta, "setlight:absolute_from", abs_from, &err)))
            goto fail;
    }
    if (sun.repaired) {
        snprintf(buf, sizeof buf,
                 "azimuth %.4f elevation %.4f diameter %.4f radiance %.9g %.9g %.9g sigma %.9g %.9g "
                 "%.9g (before the calibration transform)",
                 sun.azimuth_deg, sun.elevation_deg, o->sun.diameter_deg, sun.radiance[0],
                 sun.radiance[1], sun.radiance[2], sun.radiance_sigma[0], sun.radiance_sigma[1],
                 sun.radiance_sigma[2]);
        if ((r = sl_meta_set(&out_meta, "setlight:sun_repair", buf, &err)))
            goto fail;
    }
    snprintf(buf, sizeof buf, "setlight %s calibrate%s%s%s%s", sl_version(),
             chart_used ? " --chart " : "", chart_used ? o->chart_path : "",
             o->grey_path ? " --grey " : "", o->grey_path ? o->grey_path : "");
    if ((r = sl_meta_set(&out_meta, "setlight:command", buf, &err)) ||
        (r = sl_meta_set_color_space(&out_meta, o->out_colorspace, &err)))
        goto fail;
    if (strcmp(o->out_colorspace, "lin_rec709") != 0 &&
        (r = sl_color_convert(&hdri, "lin_rec709", o->out_colorspace, &err)))
        goto fail;
    {
        /* Never negative radiance: colours outside the working gamut and
         * noise round black come out of a matrix below zero. */
        int64_t neg = sl_calibrate_clamp_negative(&hdri, &neg_fraction);
        neg_samples = neg;
        if (neg)
            sl_log(SL_LOG_WARN, "%s: %lld samples below zero after calibration (colours outside "
                   "the output's gamut, noise round black) set to 0: %.3g%% of the light",
                   o->hdri_path, (long long)neg, 100 * neg_fraction);
        json_object_set_new(js, "negative_clamped",
                            json_pack("{s:I, s:f}", "samples", (json_int_t)neg, "fraction",
                                      neg_fraction));
    }
    out_meta.envmap = SL_ENVMAP_LATLONG;
    /* The HDRI and the report are one set, renamed into place together:
     * an interrupt or a failure leaves every earlier one as it was. */
    char report_glob[4096];
    snprintf(report_glob, sizeof report_glob, "%s/*", o->report_dir ? o->report_dir : "");
    const char *members[2] = {o->out_path, o->report_dir ? report_glob : NULL};
    if ((r = sl_output_set_begin(members, 2, &err)))
        goto fail;
    if ((r = sl_image_write(o->out_path, &hdri, &out_meta, o->write_float ? SL_PIXEL_FLOAT : SL_PIXEL_HALF,
                            &err)))
        goto fail;
    json_object_set_new(js, "hdri", json_string(o->hdri_path));
    json_object_set_new(js, "output", json_string(o->out_path));
    json_object_set_new(js, "hdri_in", json_string(plate_on_hdri ? "chart" : "working"));
    json_object_set_new(js, "white", json_string(white));
    json_object_set_new(js, "matrix", json_matrix(t));
    if (chart_used)
        json_object_set_new(js, "plate_matrix", json_matrix(plate));
    json_object_set_new(js, "scale", json_real(o->grey_path ? gfit.scale : 1.0));
    json_object_set_new(js, "units", json_string(abs_scale > 0 ? "cd/m^2" : "relative"));
    if (abs_scale > 0)
        json_object_set_new(js, "absolute",
                            json_pack("{s:f, s:s}", "cd_m2_per_unit", abs_scale, "from", abs_from));
    if (o->report_dir) {
        if (mkdir(o->report_dir, 0777) && errno != EEXIST) {
            r = sl_error_set(&err, SL_ERR_IO, "%s: cannot create the report folder: %s",
                             o->report_dir, strerror(errno));
            goto fail;
        }
        sl_report *rep = NULL;
        if ((r = sl_report_new(&rep, o->report_dir, "calibrate", "setlight calibrate", &err)))
            goto fail;
        sl_report_text(rep, "HDRI %s calibrated to %s.", o->hdri_path, o->out_path);
        if (sun.repaired)
            sl_report_text(rep,
                           "Clipped source at azimuth %.2f, elevation %.2f (%lld texels clipped): "
                           "fitted radiance %.4g (+-%.2f%%, in the HDRI's units before the "
                           "transform); grey sphere error with the clipped map %.2f%%, with "
                           "the repair %.2f%%.",
                           sun.azimuth_deg, sun.elevation_deg, (long long)sun.clipped_texels,
                           0.2126 * sun.radiance[0] + 0.7152 * sun.radiance[1] +
                               0.0722 * sun.radiance[2],
                           100 * sun.radiance_sigma[1] / fmax(sun.fitted[1], 1e-30),
                           100 * sun.rel_rmse_before, 100 * sun.rel_rmse_after);
        if (abs_scale > 0)
            sl_report_text(rep, "Absolute: %.6g cd/m^2 per unit of the grey photo (%s).",
                           abs_scale, abs_from);
        if ((r = sl_calibrate_report(rep, "", chart_used ? p : NULL, chart_used ? &fit : NULL,
                                     o->grey_path ? &gfit : NULL, &err)) ||
            (chart_sampled &&
             (r = sl_calibrate_report_chart(rep, "chart_patches.png", &chart, p, &fit, &judgement,
                                            &err)))) {
            sl_report_free(rep);
            goto fail;
        }
        if ((r = sl_report_finish(rep, &err)))
            goto fail;
        char *text = json_dumps(js, JSON_INDENT(2));
        char path[4096];
        snprintf(path, sizeof path, "%s/calibrate.json", o->report_dir);
        r = text ? sl_write_file_atomic(path, text, strlen(text), &err)
                 : sl_error_set(&err, SL_ERR_NOMEM, "%s: out of memory", path);
        free(text);
        if (r)
            goto fail;
    }
    if ((r = sl_output_set_commit(&err)))
        goto fail;
    memcpy(res->matrix, t, sizeof t);
    res->chart_used = chart_used;
    if (chart_used)
        memcpy(res->plate_matrix, plate, sizeof plate);
    res->hdri_in_chart = plate_on_hdri;
    res->chart_sampled = chart_sampled;
    res->chart = fit;
    res->judgement = judgement;
    res->grey_used = o->grey_path != NULL;
    if (res->grey_used) {
        memcpy(res->grey_circle, gopt.circle, sizeof gopt.circle);
        memcpy(res->grey_gain, gfit.gain, sizeof gfit.gain);
        res->grey_rel_rmse_before = gfit.rel_rmse_before;
        res->grey_rel_rmse_after = gfit.rel_rmse_after;
        res->grey_error_p95 = gfit.error_p95;
        res->grey_pixels = gfit.pixels;
    }
    res->scale = o->grey_path ? gfit.scale : 1.0;
    res->sun = sun;
    res->cd_m2_per_unit = abs_scale;
    snprintf(res->absolute_from, sizeof res->absolute_from, "%s", abs_from);
    res->negative_samples = neg_samples;
    res->negative_fraction = neg_fraction;
    res->json = json_dumps(js, JSON_INDENT(2));
    if (!res->json) {
        r = sl_error_set(&err, SL_ERR_NOMEM, "%s: out of memory", o->out_path);
        goto fail;
    }
    r = SL_OK;

fail:
    if (r)
        sl_output_set_abort();
    json_decref(js);
    sl_grey_fit_free(&gfit);
    sl_image_free(&hdri);
    sl_image_free(&chart);
    sl_image_free(&grey);
    sl_image_free(&mask);
    sl_meta_free(&hmeta);
    sl_meta_free(&cmeta);
    sl_meta_free(&gmeta);
    sl_meta_free(&mmeta);
    sl_meta_free(&out_meta);
    if (r && err_out)
        *err_out = err;
    return r;
}
