/* SPDX-License-Identifier: BSD-3-Clause */
/* Filling the directions no view saw (a 3-view rig's pole caps beyond the
 * circles, a masked nadir): a smooth, non-negative interpolation of the
 * seen border on a coarse lat-long. */
#include "stitch_blend_private.h"

#include <stdlib.h>
#include <string.h>

/* Diffusion sweeps after the pull-push start: enough for a 256-wide map's
 * largest hole (a pole cap) to lose the start's blockiness. */
#define DIFFUSION_SWEEPS 400

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

double stitch_median(float *v, size_t n)
{
    if (!n)
        return 0.0;
    qsort(v, n, sizeof *v, cmp_float);
    return v[n / 2];
}

/* Pull-push: each level halves the width and height (wrapping in
 * longitude); an unseen texel takes its parent's mean of seen values. */
static sl_result pull_push(float *rgb, unsigned char *known, int w, int h, sl_error *err)
{
    if (w < 2 || h < 2 || (w % 2) || (h % 2)) {
        /* The coarsest level: unseen texels take the mean of the seen ones. */
        double s[3] = {0, 0, 0};
        int64_t n = 0;
        for (int i = 0; i < w * h; i++)
            if (known[i]) {
                for (int c = 0; c < 3; c++)
                    s[c] += rgb[3 * i + c];
                n++;
            }
        for (int i = 0; i < w * h; i++)
            if (!known[i] && n)
                for (int c = 0; c < 3; c++)
                    rgb[3 * i + c] = (float)(s[c] / n);
        return SL_OK;
    }
    int pw = w / 2, ph = h / 2;
    float *prgb = calloc((size_t)pw * ph * 3, sizeof(float));
    unsigned char *pk = calloc((size_t)pw * ph, 1);
    if (!prgb || !pk) {
        free(prgb);
        free(pk);
        return sl_error_set(err, SL_ERR_NOMEM, "stitch: out of memory in the fill");
    }
    for (int y = 0; y < ph; y++)
        for (int x = 0; x < pw; x++) {
            double s[3] = {0, 0, 0};
            int n = 0;
            for (int dy = 0; dy < 2; dy++)
                for (int dx = 0; dx < 2; dx++) {
                    int i = (2 * y + dy) * w + 2 * x + dx;
                    if (known[i]) {
                        for (int c = 0; c < 3; c++)
                            s[c] += rgb[3 * i + c];
                        n++;
                    }
                }
            if (n) {
                for (int c = 0; c < 3; c++)
                    prgb[3 * (y * pw + x) + c] = (float)(s[c] / n);
                pk[y * pw + x] = 1;
            }
        }
    sl_result r = pull_push(prgb, pk, pw, ph, err);
    if (!r)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                int i = y * w + x;
                if (!known[i])
                    memcpy(rgb + 3 * i, prgb + 3 * ((y / 2) * pw + x / 2), 3 * sizeof(float));
            }
    free(prgb);
    free(pk);
    return r;
}

sl_result stitch_fill(sl_image *ll, sl_error *err)
{
    int w = ll->width, h = ll->height;
    size_t n = (size_t)w * h;
    float *rgb = malloc(n * 3 * sizeof(float));
    unsigned char *known = malloc(n);
    if (!rgb || !known) {
        free(rgb);
        free(known);
        return sl_error_set(err, SL_ERR_NOMEM, "stitch: out of memory in the fill");
    }
    size_t seen = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const float *p = sl_image_pixel(ll, x, y);
            size_t i = (size_t)y * w + x;
            known[i] = p[3] > 0;
            seen += known[i];
            for (int c = 0; c < 3; c++)
                rgb[3 * i + c] = known[i] ? p[c] : 0.0f;
        }
    sl_result r = SL_OK;
    if (seen && seen < n) {
        r = pull_push(rgb, known, w, h, err);
        /* Gauss-Seidel sweeps of the 4-neighbour mean over the unseen texels;
         * a pole's neighbour is the texel half a turn round in the same row. */
        for (int it = 0; !r && it < DIFFUSION_SWEEPS; it++)
            for (int y = 0; y < h; y++)
                for (int x = 0; x < w; x++) {
                    size_t i = (size_t)y * w + x;
                    if (known[i])
                        continue;
                    size_t nb[4];
                    nb[0] = (size_t)y * w + (x + 1) % w;
                    nb[1] = (size_t)y * w + (x + w - 1) % w;
                    nb[2] = y > 0 ? i - w : (size_t)y * w + (x + w / 2) % w;
                    nb[3] = y + 1 < h ? i + w : (size_t)y * w + (x + w / 2) % w;
                    for (int c = 0; c < 3; c++)
                        rgb[3 * i + c] = 0.25f * (rgb[3 * nb[0] + c] + rgb[3 * nb[1] + c] +
                                                  rgb[3 * nb[2] + c] + rgb[3 * nb[3] + c]);
                }
    }
    if (!r)
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                float *p = sl_image_pixel(ll, x, y);
                size_t i = (size_t)y * w + x;
                for (int c = 0; c < 3; c++)
                    p[c] = rgb[3 * i + c];
            }
    free(rgb);
    free(known);
    return r;
}
