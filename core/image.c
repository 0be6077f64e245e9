/* SPDX-License-Identifier: BSD-3-Clause */
#include "setlight/core.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

/* Refuse images beyond 64k x 64k or 16 GiB of floats: a corrupt header
 * must not turn into a huge allocation. */
#define SL_MAX_DIM 65536
#define SL_MAX_FLOATS ((size_t)4 << 30)

#if defined(MADV_HUGEPAGE) && defined(MADV_NOHUGEPAGE)
/* madvise of the whole 2 MB pages inside a block. */
static void advise_whole_huge_pages(void *data, size_t bytes, int advice)
{
    const uintptr_t huge = (uintptr_t)2 << 20;
    uintptr_t a = ((uintptr_t)data + huge - 1) & ~(huge - 1);
    uintptr_t b = ((uintptr_t)data + bytes) & ~(huge - 1);
    if (b > a)
        madvise((void *)a, b - a, advice);
}
#endif

void sl_advise_huge_pages(void *data, size_t bytes)
{
#if defined(MADV_HUGEPAGE) && defined(MADV_NOHUGEPAGE)
    /* A block of a few MB or more (a 4096^2 photo is 200 MB) is faulted
     * in 2 MB pages where the system allows it: 100 page faults instead of
     * 50 000. */
    if (bytes >= (size_t)4 << 20)
        advise_whole_huge_pages(data, bytes, MADV_HUGEPAGE);
#else
    (void)data, (void)bytes;
#endif
}

void sl_advise_small_pages(void *data, size_t bytes)
{
#if defined(MADV_HUGEPAGE) && defined(MADV_NOHUGEPAGE)
    advise_whole_huge_pages(data, bytes, MADV_NOHUGEPAGE);
#else
    (void)data, (void)bytes;
#endif
}

sl_result sl_image_alloc(sl_image *img, int width, int height, int channels, sl_error *err)
{
    memset(img, 0, sizeof *img);
    if (width <= 0 || height <= 0)
        return sl_error_set(err, SL_ERR_INPUT, "image size %dx%d is empty", width, height);
    if (channels < 1 || channels > 4)
        return sl_error_set(err, SL_ERR_INPUT, "%d channels (1 to 4 supported)", channels);
    if (width > SL_MAX_DIM || height > SL_MAX_DIM ||
        (size_t)width * (size_t)height * (size_t)channels > SL_MAX_FLOATS)
        return sl_error_set(err, SL_ERR_INPUT, "image size %dx%d is too large", width, height);
    size_t stride = (size_t)width * (size_t)channels;
    size_t bytes = stride * (size_t)height * sizeof(float);
    float *data = calloc(stride * (size_t)height, sizeof(float));
    if (!data)
        return sl_error_set(err, SL_ERR_NOMEM, "out of memory for a %dx%d image", width, height);
    sl_advise_huge_pages(data, bytes);
    img->width = width;
    img->height = height;
    img->channels = channels;
    img->stride = stride;
    img->data = data;
    return SL_OK;
}

void sl_image_free(sl_image *img)
{
    if (!img)
        return;
    free(img->data);
    memset(img, 0, sizeof *img);
}

sl_result sl_image_copy(const sl_image *src, sl_image *dst, sl_error *err)
{
    return sl_image_crop(src, 0, 0, src->width, src->height, dst, err);
}

void sl_image_fill(sl_image *img, float value)
{
    for (int y = 0; y < img->height; y++) {
        float *row = sl_image_pixel(img, 0, y);
        for (size_t i = 0; i < (size_t)img->width * (size_t)img->channels; i++)
            row[i] = value;
    }
}

sl_result sl_image_crop(const sl_image *src, int x, int y, int w, int h, sl_image *dst,
                        sl_error *err)
{
    memset(dst, 0, sizeof *dst);
    if (x < 0 || y < 0 || w <= 0 || h <= 0 || x > src->width - w || y > src->height - h)
        return sl_error_set(err, SL_ERR_USAGE, "crop %dx%d+%d+%d outside the %dx%d image", w, h,
                            x, y, src->width, src->height);
    sl_result r = sl_image_alloc(dst, w, h, src->channels, err);
    if (r)
        return r;
    for (int j = 0; j < h; j++)
        memcpy(sl_image_pixel(dst, 0, j), sl_image_pixel(src, x, y + j),
               (size_t)w * (size_t)src->channels * sizeof(float));
    return SL_OK;
}

sl_result sl_image_convert_channels(const sl_image *src, int channels, sl_image *dst,
                                    sl_error *err)
{
    sl_result r = sl_image_alloc(dst, src->width, src->height, channels, err);
    if (r)
        return r;
    int sc = src->channels;
    for (int y = 0; y < src->height; y++)
        for (int x = 0; x < src->width; x++) {
            const float *s = sl_image_pixel(src, x, y);
            float *d = sl_image_pixel(dst, x, y);
            for (int c = 0; c < channels; c++) {
                if (c < 3)
                    d[c] = sc >= 3 ? s[c] : s[0];
                else
                    d[c] = sc == 4 ? s[3] : (sc == 2 ? s[1] : 1.0f);
            }
        }
    return SL_OK;
}

void sl_image_stats_compute(const sl_image *img, sl_image_stats *st)
{
    memset(st, 0, sizeof *st);
    sl_ksum sums[4] = {{0}};
    for (int c = 0; c < 4; c++) {
        st->min[c] = INFINITY;
        st->max[c] = -INFINITY;
    }
    int nc = img->channels;
    for (int y = 0; y < img->height; y++) {
        const float *row = sl_image_pixel(img, 0, y);
        for (int x = 0; x < img->width; x++)
            for (int c = 0; c < nc; c++) {
                float v = row[x * nc + c];
                if (isnan(v)) {
                    st->nan_count++;
                    continue;
                }
                if (isinf(v)) {
                    st->inf_count++;
                    continue;
                }
                if (v < 0)
                    st->negative_count++;
                if (v < st->min[c])
                    st->min[c] = v;
                if (v > st->max[c])
                    st->max[c] = v;
                /* Compensated: maps span 1e-6..1e9. */
                sl_ksum_add(&sums[c], v);
                st->finite_count[c]++;
            }
    }
    for (int c = 0; c < 4; c++) {
        st->sum[c] = sl_ksum_value(&sums[c]);
        if (st->finite_count[c] > 0)
            st->mean[c] = st->sum[c] / (double)st->finite_count[c];
        else
            st->min[c] = st->max[c] = 0;
    }
}

int64_t sl_image_sanitize(sl_image *img, float value)
{
    int64_t n = 0;
    for (int y = 0; y < img->height; y++) {
        float *row = sl_image_pixel(img, 0, y);
        for (size_t i = 0; i < (size_t)img->width * (size_t)img->channels; i++)
            if (!isfinite(row[i])) {
                row[i] = value;
                n++;
            }
    }
    return n;
}

sl_result sl_image_ensure_rgb(sl_image *img, const char *path, sl_error *err)
{
    if (img->channels >= 3)
        return SL_OK;
    sl_image rgb;
    sl_error why;
    sl_result r = sl_image_convert_channels(img, img->channels == 2 ? 4 : 3, &rgb, &why);
    if (r)
        return sl_error_set(err, r, "%s: %s", path, why.message);
    sl_image_free(img);
    *img = rgb;
    return SL_OK;
}
