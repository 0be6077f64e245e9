/* SPDX-License-Identifier: BSD-3-Clause */
/* Previews: a scene-linear image as an 8-bit picture for people. Colour
 * channels only (a confidence, mask or alpha channel never becomes the
 * picture's alpha), an exposure (given, or the median luminance to mid
 * grey), then a display view of the OCIO config. docs/convert.md. */
#include "setlight/core.h"

#include <math.h>
#include <stddef.h>
#include <stdlib.h>
#include <string.h>

/* The k-th smallest of v[0..n) (v is reordered): Hoare's selection with a
 * median-of-three pivot. */
static float select_kth(float *v, ptrdiff_t n, ptrdiff_t k)
{
    ptrdiff_t lo = 0, hi = n - 1;
    while (lo < hi) {
        float a = v[lo], b = v[lo + (hi - lo) / 2], c = v[hi];
        float x = a < b ? (b < c ? b : (a < c ? c : a)) : (a < c ? a : (b < c ? c : b));
        ptrdiff_t i = lo, j = hi;
        do {
            while (v[i] < x)
                i++;
            while (x < v[j])
                j--;
            if (i <= j) {
                float t = v[i];
                v[i++] = v[j];
                v[j--] = t;
            }
        } while (i <= j);
        if (j < k)
            lo = i;
        if (k < i)
            hi = j;
    }
    return v[k];
}

/* Median luminance (Rec.709 weights) of the texels brighter than black;
 * 0 when there are none. */
static sl_result median_luminance(const sl_image *rgb, double *median, sl_error *err)
{
    ptrdiff_t n = 0;
    size_t total = (size_t)rgb->width * (size_t)rgb->height;
    float *lum = malloc(total * sizeof *lum);
    if (!lum)
        return sl_error_set(err, SL_ERR_NOMEM, "preview: out of memory");
    for (int y = 0; y < rgb->height; y++)
        for (int x = 0; x < rgb->width; x++) {
            const float *p = sl_image_pixel(rgb, x, y);
            float l = sl_luminancef(p);
            if (l > 0.0f && isfinite(l))
                lum[n++] = l;
        }
    *median = n ? select_kth(lum, n, n / 2) : 0.0;
    free(lum);
    return SL_OK;
}

sl_result sl_preview_image(const sl_image *img, const sl_preview_options *opt, sl_image *out,
                           sl_preview_result *res, sl_error *err)
{
    memset(out, 0, sizeof *out);
    memset(res, 0, sizeof *res);
    sl_result r = sl_image_convert_channels(img, 3, out, err);
    if (r)
        return r;
    const char *cs = opt->colorspace ? opt->colorspace : "lin_rec709";
    if ((r = sl_color_convert(out, cs, "lin_rec709", err)))
        goto fail;
    double stops = opt->exposure_stops;
    if (opt->auto_exposure) {
        if ((r = median_luminance(out, &res->median_luminance, err)))
            goto fail;
        stops = res->median_luminance > 0 ? log2(SL_PREVIEW_MID_GREY / res->median_luminance)
                                          : 0.0;
    }
    res->exposure_stops = stops;
    float scale = (float)exp2(stops);
    for (int y = 0; y < out->height; y++) {
        float *row = sl_image_pixel(out, 0, y);
        for (int i = 0; i < 3 * out->width; i++)
            row[i] *= scale;
    }
    if ((r = sl_color_display_view(out, "lin_rec709", NULL, opt->view, res->view,
                                   sizeof res->view, err)))
        goto fail;
    for (int y = 0; y < out->height; y++) {
        float *row = sl_image_pixel(out, 0, y);
        for (int i = 0; i < 3 * out->width; i++)
            row[i] = row[i] > 0.0f ? (row[i] < 1.0f ? row[i] : 1.0f) : 0.0f; /* NaN -> 0 */
    }
    return SL_OK;
fail:
    sl_image_free(out);
    return r;
}

sl_result sl_preview_write(const char *path, const sl_image *img, const sl_meta *meta,
                           const sl_preview_options *opt, sl_preview_result *res, sl_error *err)
{
    sl_image pic;
    sl_result r = sl_preview_image(img, opt, &pic, res, err);
    if (r)
        return r;
    r = sl_photo_write(path, &pic, meta, 8, err);
    sl_image_free(&pic);
    return r;
}
