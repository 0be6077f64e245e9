/* SPDX-License-Identifier: BSD-3-Clause */
/* Textured rect lights: the region's crop, resampled on the light's plane. */
#include <math.h>
#include <stdlib.h>
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
    sl_ksum mean[3] = {{0}}, wsum = {0};
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
                sl_ksum_add(&mean[k], p[k] * wacc);
            sl_ksum_add(&wsum, wacc);
        }
    /* The renderer (and UsdLux) multiply the texture by the light's colour,
     * which is already the mean radiance: each channel's mean over the solid
     * angle must be 1, or the colour counts twice (a luminance mean tinted a
     * warm window's red up 43% and its blue down 43%). */
    double m[3];
    for (int k = 0; k < 3; k++)
        m[k] = sl_ksum_value(&mean[k]) / sl_ksum_value(&wsum);
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

/* Per light: the solid-angle-weighted coefficient of variation of the
 * luminance above the dome over its region's texels at least EDGE texels
 * inside the edge (the detector grows every region by 2 texels of soft
 * edge; anti-aliased rims would read as variation), and how many texels
 * that is; the variation is 0 when fewer than SL_RIG_TEXTURE_MIN_TEXELS.
 * One pass over the map for all lights. */
#define EDGE 3
static sl_result region_variations(const sl_rig *rig, const sl_image *env, double *variation,
                                   int *interior, sl_error *err)
{
    const int w = rig->width, h = rig->height, n = rig->light_count;
    sl_ksum *sums = calloc((size_t)3 * (n > 0 ? n : 1), sizeof *sums);
    if (!sums)
        return sl_error_set(err, SL_ERR_NOMEM, "rig textures: out of memory");
    memset(interior, 0, (size_t)n * sizeof *interior);
    for (int y = EDGE; y < h - EDGE; y++) {
        double dw = cos(M_PI * (0.5 - (y + 0.5) / h));
        for (int x = 0; x < w; x++) {
            int label = rig->labels[(size_t)y * w + x];
            if (label < 1 || label > n)
                continue;
            bool inside = true;
            for (int j = -EDGE; j <= EDGE && inside; j++)
                for (int i = -EDGE; i <= EDGE && inside; i++)
                    inside = rig->labels[(size_t)(y + j) * w + rig_wrap_x(x + i, w)] == label;
            if (!inside)
                continue;
            const float *p = sl_image_pixel(env, x, y), *q = sl_image_pixel(&rig->residual, x, y);
            double o[3], d[3];
            for (int c = 0; c < 3; c++) {
                float v = p[env->channels >= 3 ? c : 0];
                o[c] = isfinite(v) && v > 0 ? v : 0;
                d[c] = q[c];
            }
            double e = sl_luminance(o) - sl_luminance(d);
            e = e > 0 ? e : 0;
            sl_ksum *s = &sums[3 * (label - 1)];
            sl_ksum_add(&s[0], dw);
            sl_ksum_add(&s[1], e * dw);
            sl_ksum_add(&s[2], e * e * dw);
            interior[label - 1]++;
        }
    }
    for (int k = 0; k < n; k++) {
        const sl_ksum *s = &sums[3 * k];
        double W = sl_ksum_value(&s[0]), m = W > 0 ? sl_ksum_value(&s[1]) / W : 0;
        double var = m > 0 ? sl_ksum_value(&s[2]) / W - m * m : 0;
        variation[k] = interior[k] >= SL_RIG_TEXTURE_MIN_TEXELS && var > 0 ? sqrt(var) / m : 0;
    }
    free(sums);
    return SL_OK;
}

sl_result sl_rig_write_textures_mode(sl_rig *rig, const sl_image *env, const char *prefix,
                                     sl_rig_texture_mode mode, sl_error *err)
{
    if (!env || env->width != rig->width || env->height != rig->height || !rig->labels)
        return sl_error_set(err, SL_ERR_USAGE, "%s: textures need the rig's own map", prefix);
    int count = rig->light_count > 0 ? rig->light_count : 1;
    double *variation = malloc((size_t)count * sizeof *variation);
    int *interior = malloc((size_t)count * sizeof *interior);
    sl_result r = variation && interior
                      ? region_variations(rig, env, variation, interior, err)
                      : sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", prefix);
    for (int i = 0; !r && i < rig->light_count; i++) {
        sl_rig_light *L = &rig->lights[i];
        int n = interior[i];
        L->variation = variation[i];
        bool graded = L->variation >= SL_RIG_TEXTURE_VARIATION;
        char why[80];
        if (n < SL_RIG_TEXTURE_MIN_TEXELS)
            snprintf(why, sizeof why, "%d texels inside its edge", n);
        else
            snprintf(why, sizeof why, "variation %.3f %s %.2f", L->variation,
                     graded ? ">=" : "<", SL_RIG_TEXTURE_VARIATION);
        bool tex = mode == SL_RIG_TEXTURES_ALL || (mode == SL_RIG_TEXTURES_AUTO && graded);
        const char *head = mode == SL_RIG_TEXTURES_NONE ? "textures off"
                           : mode == SL_RIG_TEXTURES_ALL ? "textures forced"
                           : graded                      ? "graded"
                           : n < SL_RIG_TEXTURE_MIN_TEXELS ? "too small to grade"
                                                           : "uniform";
        char shape[96];
        if (L->shape != SL_RIG_RECT && mode != SL_RIG_TEXTURES_NONE) {
            /* UsdLux (and the renderer) texture rect lights only */
            snprintf(shape, sizeof shape, "a %s: UsdLux textures rect lights only%s",
                     sl_rig_shape_name(L->shape), tex ? ", stays uniform" : "");
            head = shape;
            tex = false;
        }
        snprintf(L->texture_reason, sizeof L->texture_reason, "%s (%s)", head, why);
        if (tex)
            r = write_one(rig, env, i, prefix, err);
    }
    free(variation);
    free(interior);
    return r;
}

sl_result sl_rig_write_textures(sl_rig *rig, const sl_image *env, const char *prefix,
                                sl_error *err)
{
    return sl_rig_write_textures_mode(rig, env, prefix, SL_RIG_TEXTURES_ALL, err);
}
