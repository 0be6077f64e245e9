/* SPDX-License-Identifier: BSD-3-Clause */
/* Scoring: what `setlight process` made of a virtual-set capture against
 * the set's truth. The only code that reads truth/ besides the simulator. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/render.h"
#include "vset_internal.h"

/* ---- image against truth ---------------------------------------------- */

/* Fills out from the per-texel ratios (test / truth luminance) and the two
 * power sums; rel is reused for the errors. */
static void finish_score(double *ratio, size_t n, double power_test, double power_truth,
                         double solid_angle, sl_vset_image_score *out)
{
    memset(out, 0, sizeof *out);
    out->pixels = (int64_t)n;
    out->solid_angle_sr = solid_angle;
    if (n == 0)
        return;
    double *sorted = ratio + n; /* the caller allocates 2n */
    memcpy(sorted, ratio, n * sizeof *ratio);
    qsort(sorted, n, sizeof *sorted, sl_cmp_double);
    double scale = sorted[n / 2];
    out->scale = scale;
    if (!(scale > 0))
        return;
    for (size_t i = 0; i < n; i++)
        sorted[i] = fabs(ratio[i] / scale - 1);
    qsort(sorted, n, sizeof *sorted, sl_cmp_double);
    out->median = sorted[n / 2];
    out->p95 = sorted[(size_t)(0.95 * (double)(n - 1))];
    out->power = power_truth > 0 ? power_test / scale / power_truth : 0;
}

static double test_luminance(const float *p, const double m[3][3])
{
    if (!m)
        return sl_luminance_px(p);
    double v[3] = {p[0], p[1], p[2]}, o[3];
    sl_mat3_apply(m, v, o);
    return sl_luminance(o);
}

sl_result sl_vset_score_latlong(const sl_image *test, const double rec709_from_test[3][3],
                                const sl_image *truth, double band_deg, const double toward[3],
                                sl_vset_image_score *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    if (test->channels < 3 || truth->channels < 3 || !sl_is_latlong_shape(test->width, test->height) ||
        !sl_is_latlong_shape(truth->width, truth->height))
        return sl_error_set(err, SL_ERR_INPUT, "score: lat-longs must be 2:1 RGB(A), not %dx%d "
                            "and %dx%d", test->width, test->height, truth->width, truth->height);
    size_t texels = (size_t)test->width * test->height;
    double *ratio = malloc(2 * texels * sizeof *ratio);
    if (!ratio)
        return sl_error_set(err, SL_ERR_NOMEM, "score: out of memory");
    size_t n = 0;
    double pt = 0, pr = 0, sr = 0;
    for (int y = 0; y < test->height; y++) {
        double v = (y + 0.5) / test->height, lat = 90 - 180 * v;
        double dw = sl_latlong_texel_solid_angle(y, test->width, test->height);
        for (int x = 0; x < test->width; x++) {
            double u = (x + 0.5) / test->width, dir[3];
            const float *p = sl_image_pixel(test, x, y);
            float t[4];
            sl_latlong_lookup(truth, u, v, t);
            double a = test_luminance(p, rec709_from_test), b = sl_luminance_px(t);
            /* power over the whole sphere, the band and coverage aside */
            pt += a * dw;
            pr += b * dw;
            if (fabs(lat) > band_deg || (test->channels == 4 && !(p[3] > 0)) || !(b > VSET_SCORE_DARK))
                continue;
            if (toward) {
                sl_latlong_to_dir(u, v, dir);
                if (v3_dot(dir, toward) <= 0)
                    continue;
            }
            sr += dw;
            ratio[n++] = a / b;
        }
    }
    finish_score(ratio, n, pt, pr, sr, out);
    free(ratio);
    return SL_OK;
}

sl_result sl_vset_score_image(const sl_image *test, const double rec709_from_test[3][3],
                              const sl_image *truth, const sl_image *clipped,
                              sl_vset_image_score *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    if (test->width != truth->width || test->height != truth->height || test->channels < 3 ||
        truth->channels < 3 ||
        (clipped && (clipped->width != test->width || clipped->height != test->height)))
        return sl_error_set(err, SL_ERR_INPUT, "score: image %dx%d against a truth of %dx%d",
                            test->width, test->height, truth->width, truth->height);
    size_t pixels = (size_t)test->width * test->height;
    double *ratio = malloc(2 * pixels * sizeof *ratio);
    if (!ratio)
        return sl_error_set(err, SL_ERR_NOMEM, "score: out of memory");
    size_t n = 0;
    double pt = 0, pr = 0;
    for (int y = 0; y < test->height; y++)
        for (int x = 0; x < test->width; x++) {
            double a = test_luminance(sl_image_pixel(test, x, y), rec709_from_test);
            double b = sl_luminance_px(sl_image_pixel(truth, x, y));
            bool clip = false;
            for (int c = 0; clipped && c < clipped->channels; c++)
                clip |= sl_image_pixel(clipped, x, y)[c] > 0;
            if (clip || !(b > VSET_SCORE_DARK))
                continue;
            pt += a;
            pr += b;
            ratio[n++] = a / b;
        }
    finish_score(ratio, n, pt, pr, 0, out);
    free(ratio);
    return SL_OK;
}

/* ---- rig against the true lamps ------------------------------------------ */

static void json_vec3(json_t *a, double v[3])
{
    for (int c = 0; c < 3; c++)
        v[c] = json_number_value(json_array_get(a, (size_t)c));
}

sl_result sl_vset_score_rig(const char *rig_json, const char *lights_json, double scale,
                            const double white[3], double match_deg, sl_vset_rig_score *out,
                            sl_error *err)
{
    memset(out, 0, sizeof *out);
    json_t *rig = NULL, *truth = NULL;
    sl_result r;
    if ((r = sl_json_load_file(rig_json, "rig JSON", 0, &rig, err)) ||
        (r = sl_json_load_file(lights_json, "truth lights JSON", 0, &truth, err))) {
        json_decref(rig);
        return r;
    }
    json_t *rl = json_object_get(rig, "lights"), *tl = json_object_get(truth, "lights");
    out->rig_lights = (int)json_array_size(rl);
    out->truth_lights = (int)json_array_size(tl);
    if (!json_is_array(rl) || !json_is_array(tl) || out->truth_lights > SL_VSET_MAX_LIGHTS) {
        r = sl_error_set(err, SL_ERR_INPUT, "%s or %s: no light list", rig_json, lights_json);
        goto done;
    }
    /* Each true lamp to the rig light nearest in direction; a rig light may
     * take several lamps (fixtures closer than the rig's merge distance), so
     * its power is compared with the sum of those it took. */
    double *taken = calloc((size_t)out->rig_lights + 1, sizeof *taken);
    if (!taken) {
        r = sl_error_set(err, SL_ERR_NOMEM, "score: out of memory");
        goto done;
    }
    double angle_sum = 0;
    for (int i = 0; i < out->truth_lights; i++) {
        json_t *l = json_array_get(tl, (size_t)i);
        double td[3], ti[3];
        json_vec3(json_object_get(l, "direction"), td);
        json_vec3(json_object_get(l, "integral_rgb"), ti);
        for (int ch = 0; ch < 3 && white; ch++)
            ti[ch] *= white[ch];
        int best = -1;
        double best_cos = -2;
        for (int k = 0; k < out->rig_lights; k++) {
            double rd[3];
            json_vec3(json_object_get(json_array_get(rl, (size_t)k), "direction"), rd);
            v3_normalize(rd);
            double c = v3_dot(td, rd);
            if (c > best_cos) {
                best_cos = c;
                best = k;
            }
        }
        double angle = acos(fmax(-1, fmin(1, best_cos))) / VSET_DEG;
        if (best < 0 || angle > match_deg)
            continue;
        out->matched++;
        angle_sum += angle;
        out->direction_worst_deg = fmax(out->direction_worst_deg, angle);
        taken[best] += sl_luminance(ti);
    }
    out->direction_mean_deg = out->matched ? angle_sum / out->matched : 0;
    double worst = 0, ratios[SL_VSET_MAX_LIGHTS];
    int groups = 0;
    for (int k = 0; k < out->rig_lights && groups < SL_VSET_MAX_LIGHTS; k++) {
        if (!(taken[k] > 0))
            continue;
        double ri[3];
        json_vec3(json_object_get(json_array_get(rl, (size_t)k), "integral"), ri);
        double q = sl_luminance(ri) / (scale > 0 ? scale : 1) / taken[k];
        if (groups == 0 || fabs(q - 1) > fabs(worst - 1))
            worst = q;
        ratios[groups++] = q;
    }
    free(taken);
    if (groups) {
        qsort(ratios, (size_t)groups, sizeof *ratios, sl_cmp_double);
        out->power_median = ratios[groups / 2];
        out->power_worst = worst;
    }
done:
    json_decref(rig);
    json_decref(truth);
    return r;
}
