/* SPDX-License-Identifier: BSD-3-Clause */
/* sl_rig_extract: detection, residual, fitting, selection and ledger in order. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "lightrig_private.h"

void sl_rig_free(sl_rig *rig)
{
    if (!rig)
        return;
    free(rig->lights);
    free(rig->skipped);
    free(rig->labels);
    sl_image_free(&rig->residual);
    memset(rig, 0, sizeof *rig);
}

static sl_result check_options(const sl_rig_options *o, sl_error *err)
{
    if (o->max_lights < 0)
        return sl_error_set(err, SL_ERR_USAGE, "lightrig: max_lights must be >= 0, not %d",
                            o->max_lights);
    if (!(o->energy > 0 && o->energy <= 1))
        return sl_error_set(err, SL_ERR_USAGE, "lightrig: energy share must be in (0, 1], not %g",
                            o->energy);
    if (!(o->threshold > 1))
        return sl_error_set(err, SL_ERR_USAGE, "lightrig: threshold must be above 1, not %g",
                            o->threshold);
    if (!(o->peak_fraction >= 0 && o->peak_fraction <= 1))
        return sl_error_set(err, SL_ERR_USAGE, "lightrig: peak fraction must be in [0, 1], not %g",
                            o->peak_fraction);
    if (!(o->max_solid_angle >= 0))
        return sl_error_set(err, SL_ERR_USAGE, "lightrig: max solid angle must be >= 0");
    if (!(o->merge_degrees >= 0) || !(o->unresolved_degrees > 0 && o->unresolved_degrees < 10))
        return sl_error_set(err, SL_ERR_USAGE, "lightrig: bad merge or unresolved angle");
    if (o->distance < 0)
        return sl_error_set(err, SL_ERR_USAGE, "lightrig: distance must be positive");
    bool room = o->room[0] != 0 || o->room[1] != 0 || o->room[2] != 0;
    if (room && !(o->room[0] > 0 && o->room[1] > 0 && o->room[2] > 0))
        return sl_error_set(err, SL_ERR_USAGE, "lightrig: room sizes must all be positive");
    if (room && !(o->capture_height > 0 && o->capture_height < o->room[2]))
        return sl_error_set(err, SL_ERR_USAGE,
                            "lightrig: the room (height %g) does not contain the capture point "
                            "(height %g)",
                            o->room[2], o->capture_height);
    if (o->include_count < 0 || o->include_count > SL_RIG_MAX_TAGS || o->exclude_count < 0 ||
        o->exclude_count > SL_RIG_MAX_TAGS)
        return sl_error_set(err, SL_ERR_USAGE, "lightrig: at most %d include and exclude tags",
                            SL_RIG_MAX_TAGS);
    if (o->max_lights > 0 && o->include_count > o->max_lights)
        return sl_error_set(err, SL_ERR_USAGE, "lightrig: %d --include tags but --max-lights %d",
                            o->include_count, o->max_lights);
    for (int k = 0; k < o->include_count + o->exclude_count; k++) {
        const double *t = k < o->include_count ? o->include[k] : o->exclude[k - o->include_count];
        if (!(fabs(t[0]) <= 90 && fabs(t[1]) <= 180))
            return sl_error_set(err, SL_ERR_USAGE,
                                "lightrig: tag %g,%g: latitude must be within +-90 and longitude "
                                "within +-180 degrees",
                                t[0], t[1]);
    }
    if (o->method == SL_RIG_METHOD_MEDIANCUT && o->max_lights < 1)
        return sl_error_set(err, SL_ERR_USAGE, "lightrig: median cut needs a light count");
    return SL_OK;
}

/* RGB copy with NaN/Inf and negative samples set to 0. */
static sl_result sanitized_rgb(const sl_image *env, sl_image *rgb, int64_t *nonfinite,
                               int64_t *negative, sl_error *err)
{
    sl_result r = sl_image_alloc(rgb, env->width, env->height, 3, err);
    if (r)
        return r;
    int64_t bad = 0, neg = 0;
    for (int y = 0; y < env->height; y++)
        for (int x = 0; x < env->width; x++) {
            const float *p = sl_image_pixel(env, x, y);
            float *q = sl_image_pixel(rgb, x, y);
            for (int c = 0; c < 3; c++) {
                float v = p[env->channels >= 3 ? c : 0];
                if (!isfinite(v)) {
                    bad++;
                    v = 0;
                }
                neg += v < 0;
                q[c] = v > 0 ? v : 0;
            }
        }
    *nonfinite = bad;
    *negative = neg;
    return SL_OK;
}


sl_result sl_rig_extract(const sl_image *env, const sl_rig_options *opt, sl_rig *rig,
                         sl_error *err)
{
    memset(rig, 0, sizeof *rig);
    sl_result r = check_options(opt, err);
    if (r)
        return r;
    if (!env || !env->data || !sl_is_latlong_shape(env->width, env->height))
        return sl_error_set(err, SL_ERR_INPUT, "lightrig: not a lat-long: %dx%d is not 2:1",
                            env ? env->width : 0, env ? env->height : 0);
    if (env->height < 4)
        return sl_error_set(err, SL_ERR_INPUT,
                            "lightrig: a %dx%d lat-long is too small (8x4 at least)", env->width,
                            env->height);
    int w = env->width, h = env->height;
    size_t n = (size_t)w * h;
    sl_image rgb = {0};
    float *lum = NULL;
    sl_rig_light *cand = NULL;
    bool *keep = NULL;
    int *tags = NULL;
    rig->width = w;
    rig->height = h;
    if ((r = sanitized_rgb(env, &rgb, &rig->nonfinite, &rig->negative, err)))
        goto fail;
    rig->labels = calloc(n, sizeof *rig->labels);
    lum = malloc(n * sizeof *lum);
    if (!rig->labels || !lum) {
        r = sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%dx%d map)", w, h);
        goto fail;
    }
    if ((r = sl_image_alloc(&rig->residual, w, h, 3, err)))
        goto fail;
    if (opt->method == SL_RIG_METHOD_MEDIANCUT) {
        if ((r = rig_mediancut(&rgb, opt, rig, err)))
            goto fail;
        rig_ledger(&rgb, rig);
        goto done;
    }

    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const float *p = sl_image_pixel(&rgb, x, y);
            double v[3] = {p[0], p[1], p[2]};
            lum[(size_t)y * w + x] = (float)sl_luminance(v);
        }
    double med = rig_weighted_median(lum, w, h, err, &r);
    if (r)
        goto fail;
    double base = med;
    if (!(base > 0)) {
        /* Mostly black (a night sky, a studio): fall back on the mean. */
        sl_ksum s = {0};
        for (int y = 0; y < h; y++) {
            double om = sl_latlong_texel_solid_angle(y, w, h);
            for (int x = 0; x < w; x++)
                sl_ksum_add(&s, lum[(size_t)y * w + x] * om);
        }
        base = sl_ksum_value(&s) / (4 * M_PI);
    }
    rig->median_luminance = med;
    rig->threshold_luminance = opt->threshold * base;

    int count = 0;
    if (base > 0 &&
        (r = rig_detect(lum, w, h, rig->threshold_luminance, opt->peak_fraction,
                        opt->merge_degrees * M_PI / 180, 2,
                        rig->labels, &count, err)))
        goto fail;
    /* by label; tags may add up to SL_RIG_MAX_TAGS regions */
    tags = calloc((size_t)count + SL_RIG_MAX_TAGS + 1, sizeof *tags);
    if (!tags) {
        r = sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%d regions)", count);
        goto fail;
    }
    if ((r = rig_apply_tags(lum, w, h, opt, rig->labels, &count, tags, err)))
        goto fail;
    if ((r = rig_fill(&rgb, rig->labels, &rig->residual, err)))
        goto fail;

    cand = calloc((size_t)(count ? count : 1), sizeof *cand);
    keep = calloc((size_t)(count ? count : 1), sizeof *keep);
    if (!cand || !keep) {
        r = sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%d regions)", count);
        goto fail;
    }
    bool *valid = keep; /* reused: fit success first, then the selection */
    /* Texels of each region, by counting sort on the label. */
    int *first = calloc((size_t)count + 2, sizeof *first);
    int *texels = malloc((n ? n : 1) * sizeof *texels);
    if (!first || !texels) {
        free(first);
        free(texels);
        r = sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%d regions)", count);
        goto fail;
    }
    for (size_t i = 0; i < n; i++)
        if (rig->labels[i])
            first[rig->labels[i] + 1]++;
    for (int l = 1; l <= count; l++)
        first[l + 1] += first[l];
    for (size_t i = 0; i < n; i++)
        if (rig->labels[i])
            texels[first[rig->labels[i]]++] = (int)i;
    /* first[l] has moved to the end of region l, the start of region l + 1 */
    for (int i = 0; i < count; i++) {
        int b = i ? first[i] : 0;
        valid[i] = rig_fit_region(&rgb, &rig->residual, texels + b, first[i + 1] - b, opt,
                                  &cand[i]);
    }
    free(first);
    free(texels);
    /* Regions with nothing above their fill go back to the dome as they were. */
    int nvalid = 0;
    int *remap = calloc((size_t)count + 1, sizeof *remap);
    if (!remap) {
        r = sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%d regions)", count);
        goto fail;
    }
    for (int i = 0; i < count; i++)
        if (valid[i]) {
            cand[nvalid] = cand[i];
            tags[nvalid] = tags[i + 1]; /* by candidate from here on */
            remap[i + 1] = ++nvalid;
        }
    for (size_t i = 0; i < n; i++) {
        if (rig->labels[i] && !remap[rig->labels[i]])
            memcpy(sl_image_pixel(&rig->residual, (int)(i % (size_t)w), (int)(i / (size_t)w)),
                   sl_image_pixel(&rgb, (int)(i % (size_t)w), (int)(i / (size_t)w)),
                   3 * sizeof(float));
        rig->labels[i] = remap[rig->labels[i]];
    }
    memset(keep, 0, (size_t)(count ? count : 1) * sizeof *keep);
    r = rig_select(cand, nvalid, opt, tags, keep, &rig->skipped, &rig->skipped_count, err);
    if (r) {
        free(remap);
        goto fail;
    }
    /* Kept lights in rank order; labels renumbered to 1..light_count. */
    sl_ranked *ord = calloc((size_t)(nvalid ? nvalid : 1), sizeof *ord);
    rig->lights = calloc((size_t)(nvalid ? nvalid : 1), sizeof *rig->lights);
    if (!ord || !rig->lights) {
        free(ord);
        free(remap);
        r = sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%d lights)", nvalid);
        goto fail;
    }
    for (int i = 0; i < nvalid; i++) {
        ord[i].value = cand[i].share;
        ord[i].index = i;
    }
    qsort(ord, (size_t)nvalid, sizeof *ord, sl_cmp_ranked_desc);
    memset(remap, 0, ((size_t)count + 1) * sizeof *remap);
    for (int k = 0; k < nvalid; k++) {
        int i = (int)ord[k].index;
        if (!keep[i])
            continue;
        rig->lights[rig->light_count] = cand[i];
        rig_place_light(&rig->lights[rig->light_count], opt);
        remap[i + 1] = ++rig->light_count;
    }
    free(ord);
    for (size_t i = 0; i < n; i++) {
        int l = rig->labels[i];
        if (l && !remap[l]) {
            /* Skipped: its texels stay in the dome untouched. */
            memcpy(sl_image_pixel(&rig->residual, (int)(i % (size_t)w), (int)(i / (size_t)w)),
                   sl_image_pixel(&rgb, (int)(i % (size_t)w), (int)(i / (size_t)w)),
                   3 * sizeof(float));
        }
        rig->labels[i] = remap[l];
    }
    free(remap);
    rig_ledger(&rgb, rig);

done:
    free(tags);
    free(cand);
    free(keep);
    free(lum);
    sl_image_free(&rgb);
    return SL_OK;
fail:
    free(tags);
    free(cand);
    free(keep);
    free(lum);
    sl_image_free(&rgb);
    sl_rig_free(rig);
    return r;
}
