/* SPDX-License-Identifier: BSD-3-Clause */
/* Textured rect lights: the region's crop, resampled on the light's plane. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "lightrig_private.h"

#define TEXTURE_SIZE 64 /* pixels along the longer side */
#define SUPER 3         /* samples per pixel side */

/* Light above the dome at texel of direction d, if the texel is in region label. */
static bool excess_at(const sl_rig *rig, const sl_image *env, int label, const double d[3],
                      double e[3])
{
    double u, v;
    sl_dir_to_latlong(d, &u, &v);
    int x = (int)(u * rig->width), y = (int)(v * rig->height);
    x = x >= rig->width ? rig->width - 1 : x;
    y = y >= rig->height ? rig->height - 1 : y;
    if (rig->labels[(size_t)y * rig->width + x] != label)
        return false;
    const float *p = sl_image_pixel(env, x, y), *q = sl_image_pixel(&rig->residual, x, y);
    for (int c = 0; c < 3; c++) {
        float o = p[env->channels >= 3 ? c : 0];
        double val = isfinite(o) && o > 0 ? (double)o - q[c] : 0;
        e[c] = val > 0 ? val : 0;
    }
    return true;
}

static sl_result write_one(sl_rig *rig, const sl_image *env, int index, const char *prefix,
                           sl_error *err)
{
    sl_rig_light *L = &rig->lights[index];
    double a = tan(L->angular_size[0] / 2), b = tan(L->angular_size[1] / 2);
    int tw = TEXTURE_SIZE, th = (int)lround(TEXTURE_SIZE * b / a);
    if (th > tw) {
        th = TEXTURE_SIZE;
        tw = (int)lround(TEXTURE_SIZE * a / b);
    }
    tw = tw < 4 ? 4 : tw;
    th = th < 4 ? 4 : th;
    sl_image img = {0};
    sl_result r = sl_image_alloc(&img, tw, th, 3, err);
    if (r)
        return r;
    rig_sum mean[3] = {{0}}, wsum = {0};
    for (int t = 0; t < th; t++)
        for (int s = 0; s < tw; s++) {
            double acc[3] = {0, 0, 0}, wacc = 0;
            for (int j = 0; j < SUPER; j++)
                for (int i = 0; i < SUPER; i++) {
                    /* seen from the capture point: its right is the light's -X */
                    double X = (1 - 2 * (s + (i + 0.5) / SUPER) / tw) * a;
                    double Y = (1 - 2 * (t + (j + 0.5) / SUPER) / th) * b;
                    double d[3], e[3];
                    for (int k = 0; k < 3; k++)
                        d[k] = L->direction[k] + X * L->axis_u[k] + Y * L->axis_v[k];
                    /* solid angle of a plane element at unit distance */
                    double dw = pow(1 + X * X + Y * Y, -1.5);
                    if (excess_at(rig, env, index + 1, d, e))
                        for (int k = 0; k < 3; k++)
                            acc[k] += e[k] * dw;
                    wacc += dw;
                }
            float *p = sl_image_pixel(&img, s, t);
            for (int k = 0; k < 3; k++)
                p[k] = (float)(acc[k] / wacc);
            for (int k = 0; k < 3; k++)
                rig_sum_add(&mean[k], p[k] * wacc);
            rig_sum_add(&wsum, wacc);
        }
    /* The renderer (and UsdLux) multiply the texture by the light's colour,
     * which is already the mean radiance: each channel's mean over the solid
     * angle must be 1, or the colour counts twice (a luminance mean tinted a
     * warm window's red up 43% and its blue down 43%). */
    double m[3];
    for (int k = 0; k < 3; k++)
        m[k] = rig_sum_get(&mean[k]) / rig_sum_get(&wsum);
    if (!(m[0] > 0 || m[1] > 0 || m[2] > 0)) {
        sl_image_free(&img);
        return SL_OK; /* nothing to show: the light stays plain */
    }
    for (int t = 0; t < th; t++)
        for (int s = 0; s < tw; s++)
            for (int k = 0; k < 3; k++) {
                float *p = sl_image_pixel(&img, s, t) + k;
                *p = m[k] > 0 ? (float)(*p / m[k]) : 1.0f;
            }
    char path[4096];
    if (snprintf(path, sizeof path, "%s_light_%02d.exr", prefix, index + 1) >= (int)sizeof path) {
        sl_image_free(&img);
        return sl_error_set(err, SL_ERR_USAGE, "%s: name too long", prefix);
    }
    const char *slash = strrchr(path, '/');
    if (strlen(slash ? slash + 1 : path) >= sizeof L->texture) {
        sl_image_free(&img);
        return sl_error_set(err, SL_ERR_USAGE, "%s: texture name too long", path);
    }
    sl_meta meta;
    sl_meta_init(&meta);
    sl_meta_set_rec709(&meta);
    r = sl_exr_write(path, &img, &meta, SL_PIXEL_FLOAT, err);
    sl_meta_free(&meta);
    sl_image_free(&img);
    if (r)
        return r;
    if (snprintf(L->texture, sizeof L->texture, "%s", slash ? slash + 1 : path) >=
        (int)sizeof L->texture)
        return sl_error_set(err, SL_ERR_INTERNAL, "%s: texture name too long", path);
    return SL_OK;
}

sl_result sl_rig_write_textures(sl_rig *rig, const sl_image *env, const char *prefix,
                                sl_error *err)
{
    if (!env || env->width != rig->width || env->height != rig->height || !rig->labels)
        return sl_error_set(err, SL_ERR_USAGE, "%s: textures need the rig's own map", prefix);
    for (int i = 0; i < rig->light_count; i++) {
        if (rig->lights[i].shape != SL_RIG_RECT)
            continue;
        sl_result r = write_one(rig, env, i, prefix, err);
        if (r)
            return r;
    }
    return SL_OK;
}
