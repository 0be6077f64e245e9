/* SPDX-License-Identifier: BSD-3-Clause */
/* Preview: the map tone-mapped to sRGB with every light's region outlined
 * and its number (1-based, the USD/JSON order) drawn at its direction. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "lightrig_private.h"

/* 3x5 digits, rows top to bottom, 3 bits each (4 = left column). */
static const unsigned char digits[10][5] = {
    {7, 5, 5, 5, 7}, {2, 6, 2, 2, 7}, {7, 1, 7, 4, 7}, {7, 1, 7, 1, 7}, {5, 5, 7, 1, 1},
    {7, 4, 7, 1, 7}, {7, 4, 7, 5, 7}, {7, 1, 1, 1, 1}, {7, 5, 7, 5, 7}, {7, 5, 7, 1, 7}};

static const float palette[6][3] = {{1, 0.2f, 0.2f}, {0.2f, 1, 0.2f}, {0.3f, 0.5f, 1},
                                    {1, 1, 0.2f},    {1, 0.2f, 1},    {0.2f, 1, 1}};

static void put(sl_image *img, int x, int y, const float *c)
{
    if (y < 0 || y >= img->height)
        return;
    float *p = sl_image_pixel(img, rig_wrap_x(x, img->width), y);
    memcpy(p, c, 3 * sizeof(float));
}

/* Draws number n centred at (cx, cy), digits s pixels per cell, with a dark border. */
static void draw_number(sl_image *img, int n, int cx, int cy, int s, const float *color)
{
    char text[16];
    int len = snprintf(text, sizeof text, "%d", n);
    int tw = len * 4 * s - s, th = 5 * s;
    int x0 = cx - tw / 2, y0 = cy - th / 2;
    static const float black[3] = {0, 0, 0};
    for (int pass = 0; pass < 2; pass++)
        for (int k = 0; k < len; k++) {
            const unsigned char *g = digits[text[k] - '0'];
            for (int r = 0; r < 5; r++)
                for (int c = 0; c < 3; c++) {
                    if (!(g[r] & (4 >> c)))
                        continue;
                    for (int yy = 0; yy < s; yy++)
                        for (int xx = 0; xx < s; xx++) {
                            int px = x0 + k * 4 * s + c * s + xx, py = y0 + r * s + yy;
                            if (pass == 0) {
                                for (int dy = -1; dy <= 1; dy++)
                                    for (int dx = -1; dx <= 1; dx++)
                                        put(img, px + dx, py + dy, black);
                            } else {
                                put(img, px, py, color);
                            }
                        }
                }
        }
}

sl_result sl_rig_write_preview(const sl_rig *rig, const sl_image *env, const char *path,
                               sl_error *err)
{
    int w = rig->width, h = rig->height;
    if (!env || env->width != w || env->height != h)
        return sl_error_set(err, SL_ERR_USAGE, "%s: preview map is not the rig's size", path);
    sl_image img = {0};
    sl_result r = sl_image_alloc(&img, w, h, 3, err);
    if (r)
        return r;
    /* The median maps to middle grey; highlights roll off (Reinhard). */
    double scale = rig->median_luminance > 0 ? 0.18 / rig->median_luminance
                   : rig->threshold_luminance > 0 ? 1.44 / rig->threshold_luminance
                                                  : 1;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const float *p = sl_image_pixel(env, x, y);
            float *q = sl_image_pixel(&img, x, y);
            for (int c = 0; c < 3; c++) {
                double v = p[env->channels >= 3 ? c : 0];
                v = isfinite(v) && v > 0 ? v * scale : 0;
                q[c] = sl_linear_to_srgb((float)(v / (1 + v)));
            }
        }
    if (rig->labels) {
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                int l = rig->labels[(size_t)y * w + x];
                if (!l)
                    continue;
                bool edge = y == 0 || y == h - 1;
                int nx[4] = {x - 1, x + 1, x, x}, ny[4] = {y, y, y - 1, y + 1};
                for (int k = 0; k < 4 && !edge; k++)
                    edge = rig->labels[(size_t)ny[k] * w + rig_wrap_x(nx[k], w)] != l;
                if (edge)
                    put(&img, x, y, palette[(l - 1) % 6]);
            }
    }
    int s = h >= 256 ? h / 256 + 1 : 1;
    for (int i = 0; i < rig->light_count; i++) {
        double u, v;
        sl_dir_to_latlong(rig->lights[i].direction, &u, &v);
        int cy = (int)(v * h);
        /* Beside the light, not on it, so the outline stays visible. */
        cy += cy < h / 2 ? 6 * s + 2 : -(6 * s + 2);
        draw_number(&img, i + 1, (int)(u * w), cy, s, palette[i % 6]);
    }
    r = sl_photo_write(path, &img, NULL, 8, err);
    sl_image_free(&img);
    return r;
}
