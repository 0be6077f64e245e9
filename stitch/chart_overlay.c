/* SPDX-License-Identifier: BSD-3-Clause */
/* Where the patches were found: the chart photo round the patches, each
 * sampled disc outlined in the colour of its fate and labelled with its
 * number, and the reason an excluded one was left out. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "setlight/render.h"
#include "setlight/stitch.h"

/* 3 x 5 glyphs, rows top to bottom, 3 bits each (4 = left column). */
static const char glyph_chars[] = "0123456789CSNL";
static const unsigned char glyphs[][5] = {
    {7, 5, 5, 5, 7}, {2, 6, 2, 2, 7}, {7, 1, 7, 4, 7}, {7, 1, 7, 1, 7}, {5, 5, 7, 1, 1},
    {7, 4, 7, 1, 7}, {7, 4, 7, 5, 7}, {7, 1, 1, 1, 1}, {7, 5, 7, 5, 7}, {7, 5, 7, 1, 7},
    {7, 4, 4, 4, 7}, {7, 4, 7, 1, 7}, {5, 7, 7, 5, 5}, {4, 4, 4, 4, 7}};

static const float used_rgb[3] = {0.1f, 1, 0.1f}, lit_rgb[3] = {1, 0.6f, 0},
                   excluded_rgb[3] = {1, 0.05f, 0.05f}, black[3] = {0, 0, 0};

static void put(sl_image *img, int x, int y, const float *c)
{
    if (x >= 0 && y >= 0 && x < img->width && y < img->height)
        memcpy(sl_image_pixel(img, x, y), c, 3 * sizeof(float));
}

/* Text with its top left at (x0, y0), s pixels a glyph cell, on a black box. */
static void draw_text(sl_image *img, const char *text, int x0, int y0, int s, const float *c)
{
    int len = (int)strlen(text);
    for (int y = y0 - s; y < y0 + 6 * s; y++)
        for (int x = x0 - s; x < x0 + len * 4 * s; x++)
            put(img, x, y, black);
    for (int k = 0; k < len; k++) {
        const char *g = strchr(glyph_chars, text[k]);
        if (!g || !*g)
            continue;
        const unsigned char *rows = glyphs[g - glyph_chars];
        for (int r = 0; r < 5 * s; r++)
            for (int col = 0; col < 3 * s; col++)
                if (rows[r / s] & (4 >> (col / s)))
                    put(img, x0 + k * 4 * s + col, y0 + r, c);
    }
}

static void draw_circle(sl_image *img, double cx, double cy, double r, const float *c)
{
    for (int y = (int)floor(cy - r - 3); y <= (int)ceil(cy + r + 3); y++)
        for (int x = (int)floor(cx - r - 3); x <= (int)ceil(cx + r + 3); x++) {
            double d = hypot(x + 0.5 - cx, y + 0.5 - cy) - r;
            if (fabs(d) < 1.0)
                put(img, x, y, c);
            else if (fabs(d) < 2.0)
                put(img, x, y, black);
        }
}

/* Why patch p is not in the fit, as one letter. */
static const char *reason_code(const sl_chart_patch *p, const sl_ccm_fit *fit, int k)
{
    if (fit && fit->used_patch[k])
        return "";
    if (p->clipped > 0.05 * (p->pixels + p->clipped + p->trimmed + p->nonfinite))
        return "C";
    if (p->pixels < 4 || !(p->pixels > 0))
        return "N";
    if (p->spread > SL_CHART_MAX_SPREAD)
        return "S";
    if (fit && fit->outlier[k])
        return "L";
    return "";
}

sl_result sl_chart_overlay(const sl_image *photo, const sl_chart_patch patches[24],
                           const sl_ccm_fit *fit, int width, sl_image *out, sl_error *err)
{
    memset(out, 0, sizeof(*out));
    if (!photo || !photo->data || photo->channels < 3 || width < 1)
        return sl_error_set(err, SL_ERR_USAGE, "chart overlay: needs an RGB photo and a width");
    /* The crop: the patch centres and two pitches round them. */
    double x0 = INFINITY, y0 = INFINITY, x1 = -INFINITY, y1 = -INFINITY, pitch = 0;
    for (int p = 0; p < 24; p++) {
        x0 = fmin(x0, patches[p].center[0]), x1 = fmax(x1, patches[p].center[0]);
        y0 = fmin(y0, patches[p].center[1]), y1 = fmax(y1, patches[p].center[1]);
        pitch = fmax(pitch, 4 * patches[p].radius);
    }
    if (!isfinite(x0 + x1 + y0 + y1 + pitch))
        return sl_error_set(err, SL_ERR_INPUT, "chart overlay: patch centres not finite");
    x0 = fmax(0, x0 - 2 * pitch), y0 = fmax(0, y0 - 2 * pitch);
    x1 = fmin(photo->width, x1 + 2 * pitch), y1 = fmin(photo->height, y1 + 2 * pitch);
    if (!(x1 - x0 >= 1 && y1 - y0 >= 1)) {
        x0 = 0, y0 = 0, x1 = photo->width, y1 = photo->height;
    }
    double s = width / (x1 - x0);
    int height = (int)fmax(1, fmin(4.0 * width, lround((y1 - y0) * s)));
    sl_result r = sl_image_alloc(out, width, height, 3, err);
    if (r)
        return r;
    /* Exposure: the brightest patch to 0.85. */
    double top = 0;
    for (int p = 0; p < 24; p++)
        if (patches[p].pixels > 0)
            top = fmax(top, fmax(patches[p].rgb[0], fmax(patches[p].rgb[1], patches[p].rgb[2])));
    double k = top > 0 && isfinite(top) ? 0.85 / top : 1;
    /* Each output pixel the mean of the photo pixels under it (one at least). */
    for (int y = 0; y < height; y++)
        for (int x = 0; x < width; x++) {
            int sx0 = (int)floor(x0 + x / s), sx1 = (int)floor(x0 + (x + 1) / s);
            int sy0 = (int)floor(y0 + y / s), sy1 = (int)floor(y0 + (y + 1) / s);
            sx1 = sx1 > sx0 ? sx1 : sx0 + 1, sy1 = sy1 > sy0 ? sy1 : sy0 + 1;
            double sum[3] = {0, 0, 0};
            int n = 0;
            for (int v = sy0; v < sy1 && v < photo->height; v++)
                for (int u = sx0; u < sx1 && u < photo->width; u++) {
                    const float *q = sl_image_pixel(photo, u, v);
                    for (int c = 0; c < 3; c++)
                        sum[c] += isfinite(q[c]) ? q[c] : 0;
                    n++;
                }
            float *o = sl_image_pixel(out, x, y);
            for (int c = 0; c < 3; c++)
                o[c] = n ? (float)fmax(0, sum[c] / n * k) : 0;
        }
    int cell = width >= 600 ? 3 : 2;
    for (int p = 0; p < 24; p++) {
        const sl_chart_patch *pt = &patches[p];
        double cx = (pt->center[0] - x0) * s, cy = (pt->center[1] - y0) * s, rad = pt->radius * s;
        const char *why = reason_code(pt, fit, p);
        const float *c = fit && fit->used_patch[p] ? used_rgb : !strcmp(why, "L") ? lit_rgb
                                                                                   : excluded_rgb;
        draw_circle(out, cx, cy, fmax(rad, 3), c);
        char label[8];
        snprintf(label, sizeof label, "%d%s", p + 1, why);
        draw_text(out, label, (int)lround(cx - fmax(rad, 3)), (int)lround(cy - fmax(rad, 3)) - 7 * cell,
                  cell, c);
    }
    return SL_OK;
}

sl_result sl_calibrate_report_chart(sl_report *rep, const char *file, const sl_image *photo,
                                    const sl_chart_patch patches[24], const sl_ccm_fit *fit,
                                    const sl_chart_judgement *judgement, sl_error *err)
{
    sl_report_section(rep, "Chart: where the patches were found");
    if (judgement && judgement->plausible)
        sl_report_text(rep, "Chart: a ColorChecker (neutral row ordered, log contrast %.2f of "
                       "the chart's; colour patches in hue order; matrix condition %.1f).",
                       judgement->neutral_slope, judgement->condition);
    else if (judgement)
        sl_report_text(rep, "Chart refused, not used: %s.", judgement->text);
    sl_image img;
    sl_result r = sl_chart_overlay(photo, patches, fit, 768, &img, err);
    if (r)
        return r;
    r = sl_report_image(rep, file, &img, 0,
                        "where the patches were found: each sampled disc and its patch number; "
                        "green used, orange L lit differently from the rest, red excluded "
                        "(C clipped, S not uniform: an edge, glare or not a patch, N too few "
                        "pixels)",
                        err);
    sl_image_free(&img);
    return r;
}
