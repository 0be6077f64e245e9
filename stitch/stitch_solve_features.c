/* SPDX-License-Identifier: BSD-3-Clause */
/* The solve's features: a log-encoded 8-bit copy of each HDR view at about
 * feature_width pixels, masked to its image circle and to the merge's
 * confident pixels, through OpenCV's SIFT or AKAZE; and the cross-checked
 * matches between two views. */
#include "merge_private.h"
#include "stitch_private.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Luminance (or the one channel) of the view at the features' scale, and
 * the confidence at that scale. */
static sl_result reduced_copies(const sl_stitch_view *view, int width, int height,
                                solve_features *out, sl_error *err)
{
    sl_image small = {0};
    sl_result r = sl_image_resample(view->radiance, width, height, &small, err);
    if (r == SL_OK)
        r = sl_image_alloc(&out->luminance, width, height, 1, err);
    if (r == SL_OK)
        r = sl_image_alloc(&out->confidence, width, height, 1, err);
    if (r == SL_OK && view->weight) {
        sl_image w = {0};
        r = sl_image_resample(view->weight, width, height, &w, err);
        for (int y = 0; r == SL_OK && y < height; y++)
            for (int x = 0; x < width; x++)
                *sl_image_pixel(&out->confidence, x, y) = *sl_image_pixel(&w, x, y);
        sl_image_free(&w);
    } else if (r == SL_OK) {
        sl_image_fill(&out->confidence, 1.0f);
    }
    for (int y = 0; r == SL_OK && y < height; y++)
        for (int x = 0; x < width; x++) {
            const float *p = sl_image_pixel(&small, x, y);
            float l = small.channels >= 3 ? sl_luminancef(p)
                                          : p[0];
            *sl_image_pixel(&out->luminance, x, y) = isfinite(l) ? l : -1.0f;
        }
    sl_image_free(&small);
    return r;
}

sl_result solve_find_features(const sl_stitch_view *view, const sl_stitch_solve_options *opt,
                              solve_features *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    const sl_lens *lens = &view->lens;
    int full_w = view->radiance->width, full_h = view->radiance->height;
    double scale = full_w > opt->feature_width ? (double)full_w / opt->feature_width : 1.0;
    int w = (int)lround(full_w / scale), h = (int)lround(full_h / scale);
    out->scale = (double)full_w / w;
    sl_result r = reduced_copies(view, w, h, out, err);
    size_t n = (size_t)w * h;
    unsigned char *gray = r == SL_OK ? calloc(n, 1) : NULL;
    unsigned char *mask = r == SL_OK ? calloc(n, 1) : NULL;
    double *logs = r == SL_OK ? malloc(n * sizeof *logs) : NULL; /* float values */
    if (r == SL_OK && (!gray || !mask || !logs))
        r = sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory for its features", view->name);
    /* Inside the circle, less a margin: the circle's own edge is the
     * strongest feature of a fisheye frame and matches nothing. */
    double cx = lens->cx / out->scale, cy = lens->cy / out->scale;
    double radius = lens->circle_radius_px > 0.0 ? lens->circle_radius_px / out->scale : 1e30;
    radius -= opt->circle_margin * (radius < 1e29 ? radius : 0.0) + 4.0;
    size_t kept = 0;
    for (int y = 0; r == SL_OK && y < h; y++)
        for (int x = 0; x < w; x++) {
            float l = *sl_image_pixel(&out->luminance, x, y);
            float c = *sl_image_pixel(&out->confidence, x, y);
            bool in = hypot(x + 0.5 - cx, y + 0.5 - cy) < radius && l > 0.0f && c >= 0.5f;
            mask[(size_t)y * w + x] = in ? 255 : 0;
            if (in)
                logs[kept++] = log2f(l);
        }
    if (r == SL_OK && kept < 64) {
        /* Nothing to find features in: the pair logic reports the fallback. */
        out->desc_bytes = STITCH_DESC_MAX;
        free(gray), free(mask), free(logs);
        return SL_OK;
    }
    if (r == SL_OK) {
        /* The log range of the circle's middle 98%: a sun or a black
         * corner does not squeeze the rest into a few codes. */
        int k_hi = (int)(kept - 1 - kept / 100), k_lo = (int)(kept / 100);
        float hi = (float)merge_select_kth(logs, (int)kept, k_hi);
        float lo = (float)merge_select_kth(logs, k_hi + 1, k_lo); /* among the k_hi + 1 smallest */
        float span = hi > lo ? hi - lo : 1.0f;
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                float l = *sl_image_pixel(&out->luminance, x, y);
                float v = l > 0.0f ? 255.0f * (log2f(l) - lo) / span : 0.0f;
                gray[(size_t)y * w + x] = (unsigned char)(v < 0.0f ? 0 : v > 255.0f ? 255 : v + 0.5f);
            }
        out->xy = malloc((size_t)opt->max_features * 2 * sizeof *out->xy);
        out->desc = malloc((size_t)opt->max_features * STITCH_DESC_MAX);
        if (!out->xy || !out->desc)
            r = sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory for its features", view->name);
    }
    if (r == SL_OK) {
        char msg[256] = "";
        int detector = opt->detector && strcmp(opt->detector, "akaze") == 0 ? STITCH_DETECT_AKAZE
                                                                             : STITCH_DETECT_SIFT;
        /* Only the circle's bounding box goes to the detector: a 3:2
         * frame's sides are black. */
        int x0 = w, x1 = -1, y0 = h, y1 = -1;
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++)
                if (mask[(size_t)y * w + x]) {
                    x0 = x < x0 ? x : x0;
                    x1 = x > x1 ? x : x1;
                    y0 = y < y0 ? y : y0;
                    y1 = y > y1 ? y : y1;
                }
        x0 = x0 > 8 ? x0 - 8 : 0;
        y0 = y0 > 8 ? y0 - 8 : 0;
        x1 = x1 + 9 < w ? x1 + 9 : w;
        y1 = y1 + 9 < h ? y1 + 9 : h;
        int cw = x1 - x0, ch = y1 - y0;
        for (int y = 0; y < ch; y++) {
            memmove(gray + (size_t)y * cw, gray + (size_t)(y + y0) * w + x0, (size_t)cw);
            memmove(mask + (size_t)y * cw, mask + (size_t)(y + y0) * w + x0, (size_t)cw);
        }
        int found = stitch_features_cxx(gray, mask, cw, ch, detector, opt->max_features, out->xy,
                                        out->desc, &out->desc_bytes, msg, sizeof msg);
        if (found < 0)
            r = sl_error_set(err, SL_ERR_UNSUPPORTED, "%s: %s", view->name, msg);
        else
            out->count = found;
        for (int i = 0; i < out->count; i++) {
            out->xy[2 * i] = (float)((out->xy[2 * i] + x0) * out->scale);
            out->xy[2 * i + 1] = (float)((out->xy[2 * i + 1] + y0) * out->scale);
        }
    }
    free(gray), free(mask), free(logs);
    if (r != SL_OK)
        solve_features_free(out);
    return r;
}

void solve_features_free(solve_features *f)
{
    free(f->xy);
    free(f->desc);
    sl_image_free(&f->luminance);
    sl_image_free(&f->confidence);
    memset(f, 0, sizeof *f);
}

/* The descriptors of the features with keep[i] set (all when keep is
 * NULL), packed; index[k] is the feature of the k-th. */
static int pack(const solve_features *f, const bool *keep, unsigned char **desc, int **index)
{
    *desc = malloc((size_t)(f->count + 1) * STITCH_DESC_MAX);
    *index = malloc((size_t)(f->count + 1) * sizeof **index);
    if (!*desc || !*index)
        return -1;
    int n = 0;
    for (int i = 0; i < f->count; i++)
        if (!keep || keep[i]) {
            memcpy(*desc + (size_t)n * STITCH_DESC_MAX, f->desc + (size_t)i * STITCH_DESC_MAX,
                   STITCH_DESC_MAX);
            (*index)[n++] = i;
        }
    return n;
}

sl_result solve_match_features(const solve_features *a, const bool *keep_a,
                               const solve_features *b, const bool *keep_b,
                               const sl_stitch_solve_options *opt, int **pairs, int *count,
                               sl_error *err)
{
    *pairs = NULL;
    *count = 0;
    unsigned char *da = NULL, *db = NULL;
    int *ia = NULL, *ib = NULL;
    int na = pack(a, keep_a, &da, &ia), nb = pack(b, keep_b, &db, &ib);
    int cap = na < nb ? na : nb;
    sl_result r = SL_OK;
    if (na < 0 || nb < 0 || !(*pairs = malloc((size_t)(cap > 0 ? cap : 1) * 2 * sizeof **pairs)))
        r = sl_error_set(err, SL_ERR_NOMEM, "stitch solve: out of memory for matches");
    if (r == SL_OK && na >= 2 && nb >= 2) {
        char msg[256] = "";
        int detector = opt->detector && strcmp(opt->detector, "akaze") == 0
                           ? STITCH_DETECT_AKAZE
                           : STITCH_DETECT_SIFT;
        int n = stitch_match_cxx(da, na, db, nb, a->desc_bytes, detector, opt->ratio, *pairs, cap,
                                 msg, sizeof msg);
        if (n < 0)
            r = sl_error_set(err, SL_ERR_UNSUPPORTED, "stitch solve: %s", msg);
        for (int k = 0; k < n; k++) {
            (*pairs)[2 * k] = ia[(*pairs)[2 * k]];
            (*pairs)[2 * k + 1] = ib[(*pairs)[2 * k + 1]];
        }
        *count = n > 0 ? n : 0;
    }
    if (r != SL_OK) {
        free(*pairs);
        *pairs = NULL;
    }
    free(da), free(db), free(ia), free(ib);
    return r;
}
