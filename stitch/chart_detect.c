/* SPDX-License-Identifier: BSD-3-Clause */
/* ColorChecker detection: mcc on a tone-mapped copy, patches on the linear
 * data, orientation chosen by the colour fit. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "calibrate_internal.h"
#include "setlight/render.h"
#include "setlight/stitch.h"

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

/* 99th percentile of luminance over a subsample of finite, unclipped pixels. */
static double white_level(const sl_image *img, double clip_level)
{
    size_t n = (size_t)img->width * img->height, step = n / 65536 + 1, k = 0;
    float *v = malloc((n / step + 1) * sizeof(float));
    if (!v)
        return -1;
    for (size_t i = 0; i < n; i += step) {
        const float *p = img->data + (i / img->width) * img->stride + (i % img->width) * img->channels;
        float y = sl_luminancef(p);
        bool clipped = clip_level > 0 && (p[0] >= clip_level || p[1] >= clip_level ||
                                          p[2] >= clip_level);
        if (isfinite(y) && y > 0 && !clipped)
            v[k++] = y;
    }
    double w = 0;
    if (k) {
        qsort(v, k, sizeof(float), cmp_float);
        w = v[(size_t)(0.99 * (double)(k - 1))];
    }
    free(v);
    return w;
}

sl_result sl_chart_detect(const sl_image *img, double clip_level, const char *source,
                          sl_chart_detection *out, sl_error *err)
{
    memset(out, 0, sizeof(*out));
    if (!source)
        source = "chart image";
    if (!img || !img->data || img->channels < 3)
        return sl_error_set(err, SL_ERR_INPUT, "%s: chart detection needs RGB", source);
    double white = white_level(img, clip_level);
    if (white < 0)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", source);
    if (!(white > 0))
        return sl_error_set(err, SL_ERR_INPUT, "%s: no chart found (the image is black)", source);
    /* mcc is slow on large images and needs no more than ~800 pixels
     * across a chart that fills the frame: box-average down by f. */
    int f = (int)ceil((img->width > img->height ? img->width : img->height) / 800.0);
    int w = img->width / f, h = img->height / f;
    if (w < 1 || h < 1)
        return sl_error_set(err, SL_ERR_INPUT, "%s: no chart found (image too small)", source);
    unsigned char *bgr = malloc((size_t)w * h * 3);
    if (!bgr)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", source);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double sum[3] = {0, 0, 0};
            for (int dy = 0; dy < f; dy++)
                for (int dx = 0; dx < f; dx++) {
                    const float *p = img->data + (size_t)(y * f + dy) * img->stride +
                                     (size_t)(x * f + dx) * img->channels;
                    for (int c = 0; c < 3; c++)
                        sum[c] += isfinite(p[c]) ? p[c] : 0.0;
                }
            unsigned char *q = bgr + ((size_t)y * w + x) * 3;
            for (int c = 0; c < 3; c++) {
                double v = sum[c] / ((double)f * f) / white;
                v = sl_linear_to_srgb((float)(v < 0 ? 0 : v > 1 ? 1 : v));
                q[2 - c] = (unsigned char)lrint(v * 255.0);
            }
        }
    char msg[256] = "";
    int found = sl_cal_mcc_detect(bgr, w, h, out->box, &out->cost, msg, sizeof(msg));
    free(bgr);
    for (int i = 0; i < 4; i++)
        for (int c = 0; c < 2; c++)
            out->box[i][c] *= f;
    if (found < 0)
        return sl_error_set(err, SL_ERR_INTERNAL, "%s: chart detector failed: %s", source, msg);
    if (found == 0)
        return sl_error_set(err, SL_ERR_INPUT, "%s: no chart found", source);
    /* The outline is mcc's chart box: a 0.25 margin round 2.5-wide cells at
     * pitch 2.75, so the first centre is 6/11 pitch inside it. */
    static const double g[4][2] = {{-6.0 / 11, -6.0 / 11}, {61.0 / 11, -6.0 / 11},
                                   {61.0 / 11, 39.0 / 11}, {-6.0 / 11, 39.0 / 11}};
    double best = INFINITY;
    /* Orientations are judged on every usable patch: the outlier test would
     * let a wrong one keep only the patches it happens to fit. */
    sl_ccm_options co;
    sl_ccm_options_init(&co);
    co.outlier_ratio = 0;
    for (int k = 0; k < 4; k++)
        for (int d = -1; d <= 1; d += 2) {
            double quad[4][2], c[24][2];
            for (int i = 0; i < 4; i++) {
                int j = ((k + d * i) % 4 + 4) % 4;
                quad[i][0] = out->box[j][0];
                quad[i][1] = out->box[j][1];
            }
            if (!sl_cal_grid_centers(quad, g, c))
                continue;
            sl_chart_patch p[24];
            sl_ccm_fit fit;
            if (sl_chart_sample(img, c, 0, clip_level, p, NULL) ||
                sl_ccm_fit_chart(p, SL_COLORCHECKER_LINEAR, &co, &fit, NULL))
                continue;
            if (fit.de_after_mean < best) {
                best = fit.de_after_mean;
                memcpy(out->centers, c, sizeof(c));
            }
        }
    if (!isfinite(best))
        return sl_error_set(err, SL_ERR_INPUT, "%s: no chart found (outline found, patches unusable)",
                            source);
    out->fit_de_mean = best;
    return SL_OK;
}
