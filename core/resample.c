/* SPDX-License-Identifier: BSD-3-Clause */
/* Separable resampling: x then y, each axis through a table of (source
 * index, weight) taps. Shrinking an axis uses exact box coverage (an output
 * pixel is the integral of the input over its footprint divided by its
 * width), so every input pixel hands out exactly its own weight and the mean
 * is kept; enlarging uses pixel-centre-aligned linear interpolation. */
#include "setlight/core.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct taps {
    int *first;    /* per output: index of its first tap in idx/wt */
    int *count;
    int *idx;
    double *wt;
} taps;

static void taps_free(taps *t)
{
    free(t->first);
    free(t->count);
    free(t->idx);
    free(t->wt);
}

static bool taps_build(int n_src, int n_dst, taps *t)
{
    memset(t, 0, sizeof *t);
    double scale = (double)n_src / n_dst;
    size_t max_taps = n_dst < n_src ? (size_t)ceil(scale) + 2 : 2;
    t->first = malloc(sizeof(int) * (size_t)n_dst);
    t->count = malloc(sizeof(int) * (size_t)n_dst);
    t->idx = malloc(sizeof(int) * (size_t)n_dst * max_taps);
    t->wt = malloc(sizeof(double) * (size_t)n_dst * max_taps);
    if (!t->first || !t->count || !t->idx || !t->wt) {
        taps_free(t);
        return false;
    }
    int k = 0;
    for (int i = 0; i < n_dst; i++) {
        t->first[i] = k;
        if (n_dst < n_src) {
            /* Footprint [a, b) in source pixels; exact fractional coverage. */
            double a = (double)i * n_src / n_dst, b = (double)(i + 1) * n_src / n_dst;
            int j0 = (int)floor(a), j1 = (int)ceil(b);
            if (j1 > n_src)
                j1 = n_src;
            for (int j = j0; j < j1; j++) {
                double lo = a > j ? a : j, hi = b < j + 1 ? b : j + 1;
                if (hi > lo) {
                    t->idx[k] = j;
                    t->wt[k++] = (hi - lo) / scale;
                }
            }
        } else if (n_dst == n_src) {
            t->idx[k] = i;
            t->wt[k++] = 1.0;
        } else {
            double x = (i + 0.5) * scale - 0.5;
            if (x < 0.0)
                x = 0.0;
            if (x > n_src - 1)
                x = n_src - 1;
            int j = (int)floor(x);
            if (j > n_src - 2)
                j = n_src - 2 < 0 ? 0 : n_src - 2;
            double f = x - j;
            t->idx[k] = j;
            t->wt[k++] = 1.0 - f;
            if (n_src > 1) {
                t->idx[k] = j + 1;
                t->wt[k++] = f;
            }
        }
        t->count[i] = k - t->first[i];
    }
    return true;
}

typedef struct pass_ctx {
    const sl_image *src;
    sl_image *dst;
    const taps *t;
} pass_ctx;

static void pass_x(void *vctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    const pass_ctx *p = vctx;
    int c = p->src->channels;
    for (int64_t y = begin; y < end; y++) {
        const float *in = sl_image_pixel(p->src, 0, (int)y);
        float *out = sl_image_pixel(p->dst, 0, (int)y);
        for (int x = 0; x < p->dst->width; x++) {
            double acc[4] = {0, 0, 0, 0};
            for (int k = p->t->first[x]; k < p->t->first[x] + p->t->count[x]; k++) {
                const float *s = in + (size_t)p->t->idx[k] * (size_t)c;
                for (int ch = 0; ch < c; ch++)
                    acc[ch] += p->t->wt[k] * s[ch];
            }
            for (int ch = 0; ch < c; ch++)
                out[(size_t)x * (size_t)c + (size_t)ch] = (float)acc[ch];
        }
    }
}

static void pass_y(void *vctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    const pass_ctx *p = vctx;
    size_t n = (size_t)p->dst->width * (size_t)p->dst->channels;
    for (int64_t y = begin; y < end; y++) {
        float *out = sl_image_pixel(p->dst, 0, (int)y);
        int k0 = p->t->first[y], k1 = k0 + p->t->count[y];
        for (size_t i = 0; i < n; i++) {
            double acc = 0.0;
            for (int k = k0; k < k1; k++)
                acc += p->t->wt[k] * sl_image_pixel(p->src, 0, p->t->idx[k])[i];
            out[i] = (float)acc;
        }
    }
}

sl_result sl_image_resample(const sl_image *src, int width, int height, sl_image *dst,
                            sl_error *err)
{
    memset(dst, 0, sizeof *dst);
    if (!src || !src->data || src->width <= 0 || src->height <= 0)
        return sl_error_set(err, SL_ERR_INPUT, "resample: empty source image");
    if (width <= 0 || height <= 0)
        return sl_error_set(err, SL_ERR_USAGE, "resample: target size %dx%d is empty", width,
                            height);
    sl_image mid = {0};
    taps tx, ty;
    bool ok_x = taps_build(src->width, width, &tx);
    bool ok_y = taps_build(src->height, height, &ty);
    sl_result r = SL_OK;
    if (!ok_x || !ok_y)
        r = sl_error_set(err, SL_ERR_NOMEM, "resample: out of memory for %dx%d", width, height);
    if (!r)
        r = sl_image_alloc(&mid, width, src->height, src->channels, err);
    if (!r)
        r = sl_image_alloc(dst, width, height, src->channels, err);
    if (!r) {
        pass_ctx px = {src, &mid, &tx};
        sl_parallel_for(src->height, 8, pass_x, &px);
        pass_ctx py = {&mid, dst, &ty};
        sl_parallel_for(height, 8, pass_y, &py);
    }
    if (ok_x)
        taps_free(&tx);
    if (ok_y)
        taps_free(&ty);
    sl_image_free(&mid);
    return r;
}
