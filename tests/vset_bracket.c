/* SPDX-License-Identifier: BSD-3-Clause */
#include "vset_bracket.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* The full-stop shutter speeds the virtual camera writes to EXIF (as in
 * vset/vset_capture.c); the simulated exposure is the nominal time. */
static const double shutter[] = {1.0 / 8000, 1.0 / 4000, 1.0 / 2000, 1.0 / 1000, 1.0 / 500,
                                 1.0 / 250,  1.0 / 125,  1.0 / 60,   1.0 / 30,   1.0 / 15,
                                 1.0 / 8,    1.0 / 4,    1.0 / 2,    1,          2,
                                 4,          8,          15,         30};
enum { SHUTTERS = (int)(sizeof shutter / sizeof shutter[0]) };

/* Aperture, ISO and white balance as the virtual set's wrangler sets them. */
static void scene_settings(const char *scene, double *n, double *iso, double *kelvin)
{
    *n = 8, *iso = 100, *kelvin = 3200;
    if (strcmp(scene, "exterior") == 0)
        *n = 16, *kelvin = 5500;
    else if (strcmp(scene, "night") == 0)
        *n = 4, *iso = 400;
}

/* Metered like the virtual set: the log-average luminance at 12% of raw
 * saturation, the bracket centred there and kept on the shutter scale. */
static void plan(const vb_spec *s, const sl_vset_camera *cam, const sl_image *ll, double n,
                 double iso, double *times)
{
    double t = 0.12 * n * n / (sl_vset_log_average(ll) * cam->k * iso / 100.0);
    int centre = 0;
    for (int i = 1; i < SHUTTERS; i++)
        if (fabs(log(shutter[i] / t)) < fabs(log(shutter[centre] / t)))
            centre = i;
    if (s->alt_stops > 0) {
        double at = 0, ref = 0;
        for (int k = 0; k < s->frames; k++) {
            times[k] = at;
            if (k == (s->frames - 1) / 2)
                ref = at;
            at += k % 2 ? s->alt_stops : s->stops;
        }
        for (int k = 0; k < s->frames; k++)
            times[k] = shutter[centre] * exp2(times[k] - ref + s->shift);
        return;
    }
    int first = centre - (s->frames - 1) / 2 * s->stops + s->shift;
    int last = first + (s->frames - 1) * s->stops;
    if (last > SHUTTERS - 1)
        first -= last - (SHUTTERS - 1);
    if (first < 0)
        first = 0;
    for (int k = 0; k < s->frames; k++)
        times[k] = shutter[first + k * s->stops];
}

/* Noise-free camera output (linear, per channel) of radiance rgb at an
 * exposure scale: sensor clip, white balance and its clip, colour matrix,
 * output clip. *balanced gets the largest white-balanced sensor value. */
static void develop(const sl_vset_camera *cam, const float *rgb, double scale, double out[3],
                    double *balanced)
{
    double bal[3];
    *balanced = 0;
    for (int i = 0; i < 3; i++) {
        double s = 0;
        for (int j = 0; j < 3; j++)
            s += cam->cam_from_rec709[i][j] * rgb[j];
        s *= scale;
        bal[i] = cam->wb[i] * fmin(s, 1.0);
        *balanced = fmax(*balanced, cam->wb[i] * s);
        bal[i] = fmin(bal[i], 1.0);
    }
    for (int i = 0; i < 3; i++) {
        double o = 0;
        for (int j = 0; j < 3; j++)
            o += cam->ccm[i][j] * bal[j];
        out[i] = fmin(fmax(o, 0.0), 1.0);
    }
}

/* vb_bracket.code_lo, code_hi (night: the whole scene sits in a few codes
 * above the floor even at 30 s, so the curve above them is extrapolated),
 * the percentile from a histogram of 1024 code bins. */
enum { CODE_BINS = 1024 };

static void exposed_codes(vb_bracket *b, const sl_image *ll, double sat_lin)
{
    int64_t hist[CODE_BINS] = {0}, n = 0;
    for (int k = 0; k < b->frames; k++) {
        sl_vset_exposure e = {b->times[k], b->f_number, b->iso};
        double sk = sl_vset_exposure_scale(&b->cam, &e);
        for (int y = 0; y < ll->height; y++)
            for (int x = 0; x < ll->width; x++) {
                double o[3], bal;
                develop(&b->cam, sl_image_pixel(ll, x, y), sk, o, &bal);
                if (fmax(o[0], fmax(o[1], o[2])) >= sat_lin || bal >= 1)
                    continue;
                for (int c = 0; c < 3; c++)
                    if (o[c] >= 0.02) {
                        double z = sl_vset_response_apply(&b->cam.response, o[c]);
                        hist[(int)fmin(z * CODE_BINS, CODE_BINS - 1)]++;
                        n++;
                    }
            }
    }
    b->code_lo = sl_vset_response_apply(&b->cam.response, 0.02);
    int64_t below = 0;
    int bin = 0;
    while (bin < CODE_BINS - 1 && (below += hist[bin]) < (int64_t)(0.999 * (double)n))
        bin++;
    b->code_hi = fmax(b->code_lo, fmin(0.9, (bin + 1.0) / CODE_BINS));
}

/* What the camera's model knows: all of it for the ideal estimator and the
 * realizable oracle; the realizable oracle's variants (vb_realizable_variant)
 * take away what a merge does not know. */
typedef struct model_knows {
    bool mixing;    /* an output channel's variance mixes the raw channels' noise */
    bool raw_clips; /* frames left out within 3 sigma of a raw (balanced) clip */
    bool near_clip; /* frames left out within 3 sigma of the output's clip */
    double merge_black; /* > 0: weights cut at this black code and faded below the merge's
                           saturation code, as the merge's */
} model_knows;

static const model_knows knows_all = {true, true, true, 0};

/* The merge's black code (its default). */
static double merge_black(void)
{
    sl_merge_options defaults;
    sl_merge_options_init(&defaults);
    return defaults.black > 0 ? defaults.black : 0.004;
}

/* The camera's model of a frame at exposure scale sk for a pixel of Rec.709
 * radiance lv: each output channel's expected linear value out[c] and its
 * variance var[c] (shot and read noise of the raw channels through white
 * balance and colour matrix, or without knows.mixing the sensor's noise at
 * out[c] itself, 14-bit quantisation and, through the curve, the 8-bit code
 * step at out[c]). False where the value is within 3 sigma of a clip (raw or
 * balanced, with knows.raw_clips; output, or near code 1 for JPEG, with
 * knows.near_clip). */
static bool frame_model(const vb_bracket *b, const double lv[3], double sk, model_knows knows,
                        double out[3], double var[3])
{
    const sl_vset_camera *cam = &b->cam;
    double q = 1.0 / ((1u << cam->raw_bits) - 1u), qvar = q * q / 12;
    double raw[3], var_raw[3];
    sl_mat3_apply(cam->cam_from_rec709, lv, raw);
    bool usable = true;
    for (int j = 0; j < 3; j++) {
        raw[j] *= sk;
        double sd = b->spec.noise_free ? 0 : sl_vset_sensor_noise_std(cam, b->iso, raw[j]);
        var_raw[j] = sd * sd + qvar;
        usable = usable && (!knows.raw_clips || cam->wb[j] * (raw[j] + 3 * sqrt(var_raw[j])) < 1);
    }
    for (int c = 0; c < 3; c++) {
        out[c] = var[c] = 0;
        for (int j = 0; j < 3; j++) {
            double m = cam->ccm[c][j] * cam->wb[j];
            out[c] += m * raw[j];
            var[c] += m * m * var_raw[j];
        }
        if (!knows.mixing) { /* as if the channel were a raw one, as a merge models it */
            double sd = b->spec.noise_free ? 0 : sl_vset_sensor_noise_std(cam, b->iso, out[c]);
            var[c] = sd * sd + qvar;
        }
        var[c] += qvar; /* the output's own 14 bits */
        double top = out[c] + 3 * sqrt(var[c]);
        usable = usable && (!knows.near_clip ||
                            (b->spec.jpeg ? sl_vset_response_apply(&cam->response, top) < 0.98
                                          : top < 1));
        if (b->spec.jpeg) {
            double step =
                1 / (255 * fmax(sl_vset_response_slope(&cam->response, fmax(out[c], 0)), 1e-3));
            var[c] += step * step / 12;
        }
    }
    return usable;
}

/* The frames as written, read back and linearised through the true curve,
 * each scaled to the reference exposure (value[k], three channels a pixel;
 * to_ref[k] the scale), and whether each pixel reads at a clip (a code of
 * 0.98 or more through the curve, 1 for linear data) in any channel
 * (at_clip[k]). */
typedef struct frames_read {
    double *value[VB_MAX_FRAMES];
    uint8_t *at_clip[VB_MAX_FRAMES];
    double scale[VB_MAX_FRAMES], to_ref[VB_MAX_FRAMES];
} frames_read;

static void frames_free(frames_read *fr)
{
    for (int k = 0; k < VB_MAX_FRAMES; k++) {
        free(fr->value[k]);
        free(fr->at_clip[k]);
    }
}

/* Linearised through the true curve, or with believed through the true
 * curve's g + p(g) (the null-space oracle). */
static sl_result frames_load(const vb_bracket *b, const vb_periodic *believed, frames_read *fr,
                             sl_error *err)
{
    memset(fr, 0, sizeof *fr);
    for (int k = 0; k < b->frames; k++) {
        sl_image f = {0};
        sl_result r = sl_photo_read(b->paths[k], &f, NULL, err);
        if (r)
            return r;
        size_t n = (size_t)f.width * f.height;
        fr->at_clip[k] = calloc(n, 1);
        fr->value[k] = malloc(n * 3 * sizeof(double));
        if (!fr->at_clip[k] || !fr->value[k]) {
            sl_image_free(&f);
            return sl_error_set(err, SL_ERR_NOMEM, "oracle: out of memory");
        }
        sl_vset_exposure e = {b->times[k], b->f_number, b->iso};
        fr->scale[k] = sl_vset_exposure_scale(&b->cam, &e);
        fr->to_ref[k] = b->ref_scale / fr->scale[k];
        for (size_t i = 0; i < 3 * n; i++) {
            double v = f.data[i];
            fr->at_clip[k][i / 3] |= b->spec.jpeg ? v >= 0.98 : v >= 1;
            if (b->spec.jpeg)
                v = sl_vset_response_invert(&b->cam.response, v);
            if (believed)
                v = vb_periodic_apply(believed, v);
            fr->value[k][i] = v * fr->to_ref[k];
        }
        sl_image_free(&f);
    }
    return SL_OK;
}

/* The merge's rules on frame k's codes at pixel i, as factors of its
 * weights (stitch/merge_pass.c): 0 at or below the black code, and fading
 * from 1 to 0 over the 0.05 below the saturation code by the pixel's
 * brightest channel. False where that fade is 0 (saturated). */
static bool merge_code_weights(const vb_bracket *b, const frames_read *fr, int k, size_t i,
                               double black, double cut[3])
{
    double z[3], zmax = 0;
    for (int c = 0; c < 3; c++) {
        double v = fr->value[k][3 * i + c] / fr->to_ref[k];
        z[c] = b->spec.jpeg ? sl_vset_response_apply(&b->cam.response, v) : v;
        zmax = fmax(zmax, z[c]);
    }
    double fade = fmin(1, fmax(0, (b->spec.saturation - zmax) / 0.05));
    for (int c = 0; c < 3; c++)
        cut[c] = z[c] <= black ? 0 : fade;
    return fade > 0;
}

/* One pixel's estimate (three channels, output-linear at the reference
 * exposure) from the frames, each frame k weighted by the inverse of its
 * variance under the camera's model for radiance at[k], used where the model
 * leaves it 3 sigma clear of every clip it knows (and, with censor, where it
 * does not read at a clip); where no frame is, the shortest frame's value (a
 * lower bound; with the merge's code rules, as the merge, the longest frame
 * its saturation leaves). Returns how many frames were used. */
static int pixel_estimate(const vb_bracket *b, const frames_read *fr, size_t i,
                          const double at[][3], model_knows knows, bool censor, double est[3])
{
    double num[3] = {0}, den[3] = {0};
    int used = 0, fallback = 0;
    for (int k = 0; k < b->frames; k++) {
        double out[3], var[3], cut[3] = {1, 1, 1};
        if (!frame_model(b, at[k], fr->scale[k], knows, out, var) ||
            (censor && fr->at_clip[k][i]))
            continue;
        if (knows.merge_black > 0 && merge_code_weights(b, fr, k, i, knows.merge_black, cut))
            fallback = k;
        used++;
        for (int c = 0; c < 3; c++) {
            double w = cut[c] / (var[c] * fr->to_ref[k] * fr->to_ref[k]);
            num[c] += w * fr->value[k][3 * i + c];
            den[c] += w;
        }
    }
    for (int c = 0; c < 3; c++)
        est[c] = den[c] > 0 ? num[c] / den[c] : fr->value[fallback][3 * i + c];
    return used;
}

/* The ideal estimator (vb_bracket.oracle): weights and clips judged at the
 * noise-free radiance, which only the truth knows. */
static void oracle_ideal(vb_bracket *b, const sl_image *ll, const frames_read *fr)
{
    for (int y = 0; y < ll->height; y++)
        for (int x = 0; x < ll->width; x++) {
            const float *l = sl_image_pixel(ll, x, y);
            double at[VB_MAX_FRAMES][3], est[3];
            for (int k = 0; k < b->frames; k++)
                at[k][0] = l[0], at[k][1] = l[1], at[k][2] = l[2];
            size_t i = (size_t)y * ll->width + x;
            pixel_estimate(b, fr, i, at, knows_all, false, est);
            for (int c = 0; c < 3; c++)
                b->oracle.data[3 * i + c] = (float)est[c];
        }
}

/* Rounds of the realizable oracle's maximum-likelihood iteration: the
 * weights move by a few percent per round once the clip decisions settle. */
enum { REALIZABLE_ROUNDS = 8 };

/* Rec.709 radiance of output-linear values v at the reference exposure. */
static void radiance_of(const vb_bracket *b, const double to_radiance[3][3], const double v[3],
                        double lv[3])
{
    double t[3] = {v[0] / b->ref_scale, v[1] / b->ref_scale, v[2] / b->ref_scale};
    sl_mat3_apply(to_radiance, t, lv);
}

/* What the realizable oracle's model knows in each variant. */
static model_knows variant_knows(vb_realizable_variant v)
{
    model_knows k = knows_all;
    bool merge_like = v == VB_REALIZABLE_MERGE_LIKE || v == VB_REALIZABLE_MERGE_RULES;
    k.mixing = v != VB_REALIZABLE_OWN_CHANNEL && !merge_like;
    k.raw_clips = v != VB_REALIZABLE_NO_RAW_CLIP && !merge_like;
    k.near_clip = v != VB_REALIZABLE_NO_NEAR_CLIP && !merge_like;
    k.merge_black = v == VB_REALIZABLE_MERGE_RULES ? merge_black() : 0;
    return k;
}

/* The realizable oracle (vb_bracket.realizable): the ideal estimator with
 * the noise-free radiance it judges weights and clips at replaced by its
 * own estimate from the frames, iterated (maximum likelihood under the
 * Gaussian model: the weights evaluated at the current estimate, not at the
 * noisy observed codes, which favour the values noise pushed down). It
 * starts from the longest frame whose codes read below 0.9 (none: the
 * shortest) and leaves out frames that read at a clip (censored). The
 * observed and merge-like variants judge each frame at its own value
 * instead, once, as a merge does. */
static void oracle_realizable(const vb_bracket *b, const frames_read *fr,
                              vb_realizable_variant variant, sl_image *out)
{
    double m[3][3], to_radiance[3][3];
    sl_vset_camera_output_matrix(&b->cam, m);
    if (!sl_mat3_invert(m, to_radiance))
        return;
    model_knows knows = variant_knows(variant);
    bool observed = variant == VB_REALIZABLE_OBSERVED || variant == VB_REALIZABLE_MERGE_LIKE ||
                    variant == VB_REALIZABLE_MERGE_RULES;
    for (size_t i = 0; i < (size_t)out->width * out->height; i++) {
        double est[3], at[VB_MAX_FRAMES][3];
        if (observed) {
            for (int k = 0; k < b->frames; k++)
                radiance_of(b, to_radiance, &fr->value[k][3 * i], at[k]);
            pixel_estimate(b, fr, i, at, knows, true, est);
            for (int c = 0; c < 3; c++)
                out->data[3 * i + c] = (float)est[c];
            continue;
        }
        int k0 = 0;
        for (int k = b->frames - 1; k > 0 && !k0; k--) {
            bool low = true;
            for (int c = 0; c < 3; c++) {
                double v = fr->value[k][3 * i + c] / fr->to_ref[k];
                low = low && (b->spec.jpeg ? sl_vset_response_apply(&b->cam.response, v) : v) < 0.9;
            }
            if (low)
                k0 = k;
        }
        for (int c = 0; c < 3; c++)
            est[c] = fr->value[k0][3 * i + c];
        for (int round = 0; round < REALIZABLE_ROUNDS; round++) {
            double next[3];
            radiance_of(b, to_radiance, est, at[0]);
            for (int k = 1; k < b->frames; k++)
                memcpy(at[k], at[0], sizeof at[0]);
            pixel_estimate(b, fr, i, at, knows, true, next);
            double moved = 0;
            for (int c = 0; c < 3; c++) {
                moved = fmax(moved, fabs(next[c] - est[c]) / fmax(fabs(est[c]), 1e-9));
                est[c] = next[c];
            }
            if (moved < 1e-6)
                break;
        }
        for (int c = 0; c < 3; c++)
            out->data[3 * i + c] = (float)est[c];
    }
}

/* The null-space oracle (vb_bracket.null_space): the realizable oracle of
 * frames linearised through the curve the self-calibration's smoothness
 * picks from the true curve's class (vb_null_space_fit), with that curve's
 * code steps and clip in its noise model. */
static sl_result oracle_null_space(vb_bracket *b, const sl_image *ll, sl_error *err)
{
    double black = merge_black();
    double period = log(b->times[b->frames - 1] / b->times[0]) / (b->frames - 1);
    vb_periodic p;
    b->null_space_rises =
        vb_null_space_fit(&b->cam.response, period, black, b->spec.saturation, &p);
    vb_bracket believed = *b;
    vb_null_space_curve(&b->cam.response, &p, &believed.cam.response);
    sl_response curve = {0};
    sl_result r = sl_response_linear(&curve, 256, err);
    for (int c = 0; c < 3 && !r; c++)
        for (int k = 0; k < 256; k++)
            curve.inverse[c * 256 + k] = vb_periodic_apply(
                &p, sl_vset_response_invert(&b->cam.response, k / 255.0));
    double wz;
    if (!r)
        b->null_space_curve =
            vb_response_error(&curve, &b->cam.response, b->code_lo, b->code_hi, &wz);
    sl_response_free(&curve);
    frames_read fr;
    memset(&fr, 0, sizeof fr);
    if (!r && !(r = frames_load(b, &p, &fr, err)) &&
        !(r = sl_image_alloc(&b->null_space, ll->width, ll->height, 3, err)))
        oracle_realizable(&believed, &fr, VB_REALIZABLE_ORACLE, &b->null_space);
    frames_free(&fr);
    return r;
}

static sl_result oracle_make(vb_bracket *b, const sl_image *ll, sl_error *err)
{
    frames_read fr;
    sl_result r = frames_load(b, NULL, &fr, err);
    if (!r && !(r = sl_image_alloc(&b->oracle, ll->width, ll->height, 3, err)))
        oracle_ideal(b, ll, &fr);
    if (!r && b->spec.realizable &&
        !(r = sl_image_alloc(&b->realizable, ll->width, ll->height, 3, err)))
        oracle_realizable(b, &fr, b->spec.realizable_variant, &b->realizable);
    frames_free(&fr);
    if (!r && b->spec.null_space && b->spec.jpeg &&
        (!(b->spec.alt_stops > 0) || b->spec.alt_stops == b->spec.stops))
        r = oracle_null_space(b, ll, err);
    return r;
}

sl_result vb_scene(const char *name, int width, sl_vset_scene *out, sl_error *err)
{
    sl_vset_desc desc;
    memset(out, 0, sizeof *out);
    sl_result r = sl_vset_preset(name, &desc, err);
    return r ? r : sl_vset_scene_make(&desc, width, out, err);
}

sl_result vb_make(const char *dir, const char *prefix, const vb_spec *spec, vb_bracket *out,
                  sl_error *err)
{
    memset(out, 0, sizeof *out);
    out->spec = *spec;
    if (spec->frames < 2 || spec->frames > VB_MAX_FRAMES)
        return sl_error_set(err, SL_ERR_USAGE, "vset bracket: 2..%d frames", VB_MAX_FRAMES);
    double kelvin;
    sl_result r;
    scene_settings(spec->scene, &out->f_number, &out->iso, &kelvin);
    sl_vset_camera_default(&out->cam, kelvin);
    if (spec->response)
        out->cam.response = *spec->response;
    else if ((r = sl_vset_response_preset(spec->curve, &out->cam.response, err)))
        return r;
    if (spec->full_well_e > 0) {
        out->cam.full_well_e = spec->full_well_e;
        out->cam.read_noise_pre_e = spec->read_noise_e;
        out->cam.read_noise_post_e = 0;
    }
    sl_vset_scene scene = {0};
    if (!spec->latlong && (r = vb_scene(spec->scene, spec->width, &scene, err)))
        return r;
    const sl_image *ll = spec->latlong ? spec->latlong : &scene.latlong;
    int w = ll->width, h = ll->height;
    out->frames = spec->frames;
    out->reference = (spec->frames - 1) / 2;
    plan(spec, &out->cam, ll, out->f_number, out->iso, out->times);
    double m[3][3];
    sl_vset_camera_output_matrix(&out->cam, m);
    sl_vset_exposure e0 = {out->times[0], out->f_number, out->iso};
    sl_vset_exposure eref = {out->times[out->reference], out->f_number, out->iso};
    double s0 = sl_vset_exposure_scale(&out->cam, &e0);
    double sref = sl_vset_exposure_scale(&out->cam, &eref);
    out->ref_scale = sref;
    /* The merge's threshold in linear terms: codes at or above it are saturated. */
    double sat_lin = spec->jpeg ? sl_vset_response_invert(&out->cam.response, spec->saturation)
                                : spec->saturation;
    if ((r = sl_image_alloc(&out->truth, w, h, 3, err)) ||
        (r = sl_image_alloc(&out->clipped, w, h, 3, err)) ||
        (r = sl_image_alloc(&out->margin, w, h, 3, err)) ||
        (r = sl_image_alloc(&out->best, w, h, 3, err))) {
        sl_vset_scene_free(&scene);
        return r;
    }
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const float *l = sl_image_pixel(ll, x, y);
            float *t = sl_image_pixel(&out->truth, x, y);
            for (int i = 0; i < 3; i++) {
                double v = 0;
                for (int j = 0; j < 3; j++)
                    v += m[i][j] * l[j];
                t[i] = (float)(v * sref);
            }
            /* Saturated as a whole (the merge's rule): any channel at the
             * saturation code, or a balanced raw channel clipped (it spoils
             * the others through the colour matrix). */
            double o[3], bal;
            develop(&out->cam, l, s0, o, &bal);
            double omax = fmax(o[0], fmax(o[1], o[2]));
            bool clipped = omax >= sat_lin || bal >= 1;
            bool near = fabs(omax / sat_lin - 1) < 0.05 || fabs(bal - 1) < 0.05;
            float *best = sl_image_pixel(&out->best, x, y);
            best[0] = best[1] = best[2] = 0;
            for (int k = spec->frames - 1; k >= 0; k--) {
                sl_vset_exposure ek = {out->times[k], out->f_number, out->iso};
                double sk = sl_vset_exposure_scale(&out->cam, &ek), ok[3], bk;
                develop(&out->cam, l, sk, ok, &bk);
                if (fmax(ok[0], fmax(ok[1], ok[2])) < sat_lin && bk < 1) {
                    for (int c = 0; c < 3; c++)
                        best[c] = (float)(t[c] * sk / sref);
                    break;
                }
            }
            for (int c = 0; c < 3; c++) {
                sl_image_pixel(&out->clipped, x, y)[c] = clipped ? 1.0f : 0.0f;
                sl_image_pixel(&out->margin, x, y)[c] = near ? 1.0f : 0.0f;
            }
        }
    /* Noise-free: a well so deep that shot noise is below a 14-bit step and
     * no read noise; the sensor's expected value, quantised as before. */
    sl_vset_camera body = out->cam;
    if (spec->noise_free)
        body.full_well_e = 1e12, body.read_noise_pre_e = body.read_noise_post_e = 0;
    for (int k = 0; k < spec->frames && !r; k++) {
        sl_vset_exposure e = {out->times[k], out->f_number, out->iso};
        sl_vset_shot shot;
        if ((r = sl_vset_camera_shoot(&body, &e, ll, spec->seed * 131 + (uint64_t)k, &shot,
                                      err)))
            break;
        sl_meta meta;
        sl_meta_init(&meta);
        meta.exposure_time = out->times[k] * (k == spec->lie_frame ? exp2(spec->lie_stops) : 1);
        meta.f_number = out->f_number;
        meta.iso = out->iso;
        snprintf(out->paths[k], sizeof out->paths[k], "%s/%s_%d.%s", dir, prefix, k,
                 spec->jpeg && !spec->lossless ? "jpg" : "tif");
        if (spec->jpeg)
            r = sl_photo_write(out->paths[k], &shot.encoded, &meta, 8, err);
        else {
            sl_vset_quantize(&shot.linear, out->cam.raw_bits);
            r = sl_photo_write(out->paths[k], &shot.linear, &meta, 16, err);
        }
        sl_meta_free(&meta);
        sl_vset_shot_free(&shot);
    }
    if (!r) {
        exposed_codes(out, ll, sat_lin);
        r = oracle_make(out, ll, err);
    }
    sl_vset_scene_free(&scene);
    return r;
}

void vb_free(vb_bracket *b)
{
    sl_image_free(&b->truth);
    sl_image_free(&b->clipped);
    sl_image_free(&b->margin);
    sl_image_free(&b->best);
    sl_image_free(&b->oracle);
    sl_image_free(&b->realizable);
    sl_image_free(&b->null_space);
}
int vb_cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Channels scored: not clipped in every frame (truth) and at least 2% of
 * white in the longest frame that leaves the pixel unsaturated (darker ones
 * are a few codes of noise in every frame). */
bool vb_scored(const vb_bracket *b, int x, int y, int c)
{
    return sl_image_pixel(&b->clipped, x, y)[c] == 0 &&
           sl_image_pixel(&b->best, x, y)[c] >= 0.02;
}

/* Relative error of merged vs truth over `block` x `block` means of scored
 * channels (blocks with every channel scored): block 1 is per pixel, noise
 * included; block 4 averages 16 pixels, which leaves what the merge itself
 * gets wrong (curve, exposures, weights) above a quarter of the noise. With
 * fit_scale after the median ratio (a self-calibrated curve knows radiance
 * only up to a factor). */
vb_stats vb_compare(const sl_image *merged, const vb_bracket *b, int block, bool fit_scale)
{
    vb_stats st = {0, NAN, NAN, 1};
    size_t cap = (size_t)merged->width * merged->height * 3;
    double *e = malloc(cap * sizeof *e);
    if (!e)
        return st;
    size_t m = 0;
    for (int by = 0; by + block <= merged->height; by += block)
        for (int bx = 0; bx + block <= merged->width; bx += block)
            for (int c = 0; c < 3; c++) {
                double sm = 0, st_ = 0;
                bool ok = true;
                for (int y = by; y < by + block && ok; y++)
                    for (int x = bx; x < bx + block; x++) {
                        ok = ok && vb_scored(b, x, y, c);
                        sm += sl_image_pixel(merged, x, y)[c];
                        st_ += sl_image_pixel(&b->truth, x, y)[c];
                    }
                if (ok)
                    e[m++] = sm / st_;
            }
    if (m) {
        if (fit_scale) {
            qsort(e, m, sizeof *e, vb_cmp_double);
            st.scale = e[m / 2];
        }
        for (size_t i = 0; i < m; i++)
            e[i] = fabs(e[i] / st.scale - 1);
        qsort(e, m, sizeof *e, vb_cmp_double);
        st.median = e[m / 2];
        st.p99 = e[(size_t)(0.99 * (double)(m - 1))];
    }
    st.n = (int64_t)m;
    free(e);
    return st;
}

/* Worst error of the recovered inverse response after one free scale (the
 * median ratio), over codes [zlo, zhi]: the codes whose linear value the
 * bracket exposes (vb_bracket.code_lo, code_hi). */
double vb_response_error(const sl_response *resp, const sl_vset_response *truth,
                             double zlo, double zhi, double *worst_z)
{
    double worst = 0;
    for (int c = 0; c < 3; c++) {
        double ratio[256];
        int n = 0;
        for (double z = zlo; z <= zhi + 1e-9 && n < 256; z += 1.0 / 255)
            ratio[n++] = sl_response_eval(resp, c, z) / sl_vset_response_invert(truth, z);
        double sorted[256];
        memcpy(sorted, ratio, (size_t)n * sizeof *ratio);
        qsort(sorted, (size_t)n, sizeof *sorted, vb_cmp_double);
        double s = sorted[n / 2];
        for (int i = 0; i < n; i++)
            if (fabs(ratio[i] / s - 1) > worst) {
                worst = fabs(ratio[i] / s - 1);
                *worst_z = zlo + i / 255.0;
            }
    }
    return worst;
}


int vb_dorf_names(const char *path, char (*names)[128], int max)
{
    FILE *f = fopen(path, "r");
    if (!f)
        return -1;
    /* Each curve is six lines: name, type, "I =", samples, "B =", samples;
     * lines are long (1024 samples), so read them in pieces. */
    char buf[4096];
    int n = 0, line = 0;
    bool at_start = true;
    while (fgets(buf, sizeof buf, f)) {
        size_t len = strlen(buf);
        if (at_start && line % 6 == 0 && n < max) {
            buf[strcspn(buf, "\r\n")] = 0;
            /* names are short; a longer line is cut to 127 characters */
            buf[127] = 0;
            memcpy(names[n++], buf, strlen(buf) + 1);
        }
        at_start = len > 0 && buf[len - 1] == '\n';
        line += at_start;
    }
    fclose(f);
    return n;
}

/* Removes `suffix` from the end of s when it is there. */
static bool strip_suffix(char *s, const char *suffix)
{
    size_t n = strlen(s), k = strlen(suffix);
    if (n <= k || strcmp(s + n - k, suffix) != 0)
        return false;
    s[n - k] = 0;
    return true;
}

/* Removes a trailing run of digits (and '.') of `min` to `max` characters
 * after `prefix` ("Push", "+", ""); false if there is none. */
static bool strip_number(char *s, const char *prefix, int min, int max)
{
    size_t n = strlen(s), d = n;
    while (d > 0 && (isdigit((unsigned char)s[d - 1]) || s[d - 1] == '.'))
        d--;
    size_t k = strlen(prefix);
    if ((int)(n - d) < min || (int)(n - d) > max || d < k + 1 ||
        strncmp(s + d - k, prefix, k) != 0)
        return false;
    s[d - k] = 0;
    return true;
}

void vb_dorf_family(const char *name, char *family, size_t size)
{
    char s[128];
    snprintf(s, sizeof s, "%s", name);
    strip_suffix(s, ".SLRR");
    if (!strip_suffix(s, "Red") && !strip_suffix(s, "Green") && !strip_suffix(s, "Blue")) {
        size_t n = strlen(s), d = n > 0 && isdigit((unsigned char)s[n - 1]) ? n - 1 : n;
        if (d > 1 && strchr("RGB", s[d - 1]) && isalnum((unsigned char)s[d - 2]))
            s[d - 1] = 0;
    }
    strip_suffix(s, "CD");
    bool variant = strip_suffix(s, "Standard") || strip_number(s, "Push", 1, 1) ||
                   strip_number(s, "Pull", 1, 1) || strip_number(s, "+", 1, 4);
    if (!variant && strip_suffix(s, "min"))
        strip_number(s, "", 1, 2);
    else if (!variant)
        strip_number(s, "", 6, 6); /* a date: optura981111 */
    strip_suffix(s, "CD");
    snprintf(family, size, "%s", s);
}

sl_result vb_response_inverse(const sl_vset_response *curve, sl_response *out, sl_error *err)
{
    sl_result r = sl_response_linear(out, 256, err);
    for (int c = 0; c < 3 && !r; c++)
        for (int k = 0; k < 256; k++)
            out->inverse[c * 256 + k] = sl_vset_response_invert(curve, k / 255.0);
    return r;
}

sl_result vb_dorf_inverses(const char *path, char (*names)[128], int count, sl_response *out,
                           sl_error *err)
{
    sl_result r = SL_OK;
    for (int i = 0; i < count && !r; i++) {
        sl_vset_response resp;
        r = sl_vset_response_load(path, names[i], &resp, err);
        if (!r)
            r = vb_response_inverse(&resp, &out[i], err);
    }
    return r;
}

sl_result vb_dorf_prior(const sl_response *curves, char (*names)[128], int count,
                        const char *name, int components, sl_response_prior **out,
                        sl_error *err)
{
    char left_out[128] = "", family[128];
    if (name)
        vb_dorf_family(name, left_out, sizeof left_out);
    sl_response *kept = malloc((size_t)count * sizeof *kept);
    if (!kept)
        return sl_error_set(err, SL_ERR_NOMEM, "out of memory");
    int n = 0;
    for (int i = 0; i < count; i++) {
        vb_dorf_family(names[i], family, sizeof family);
        if (!name || strcmp(family, left_out) != 0)
            kept[n++] = curves[i];
    }
    char label[160];
    snprintf(label, sizeof label, "dorf-without-%s", name ? left_out : "none");
    sl_result r = sl_response_prior_build(kept, n, components, label, out, err);
    free(kept);
    return r;
}
sl_result vb_merge(const vb_bracket *b, const sl_merge_options *opt, sl_merge_result *res,
                   sl_error *err)
{
    const char *paths[VB_MAX_FRAMES];
    for (int k = 0; k < b->frames; k++)
        paths[k] = b->paths[b->frames - 1 - k];
    return sl_merge(paths, b->frames, opt, res, err);
}
