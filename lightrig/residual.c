/* SPDX-License-Identifier: BSD-3-Clause */
/* The residual dome: extracted regions painted out by push-pull on the
 * lat-long. Levels halve both sides; sums are weighted by texel solid angle
 * (so rows near the poles count for what they cover) and wrap in longitude.
 * Each level blends its own average with the upsampled coarser fill by the
 * known fraction of its footprint, which keeps the fill smooth. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "lightrig_private.h"

typedef struct level {
    int w, h;
    double *v;    /* 3 per texel: weighted sums, then averages */
    double *wk;   /* known weight */
    double *wf;   /* full weight (all known) */
} level;

static void free_levels(level *lv, int count)
{
    for (int i = 0; i < count; i++) {
        free(lv[i].v);
        free(lv[i].wk);
        free(lv[i].wf);
    }
}

static bool alloc_level(level *l, int w, int h)
{
    size_t n = (size_t)w * h;
    l->w = w;
    l->h = h;
    l->v = calloc(n * 3, sizeof *l->v);
    l->wk = calloc(n, sizeof *l->wk);
    l->wf = calloc(n, sizeof *l->wf);
    return l->v && l->wk && l->wf;
}

/* Bilinear sample of level l's averages at fine texel (x, y) of a level
 * twice its size: wrap in x, clamp in y. */
static void upsample(const level *l, int x, int y, double out[3])
{
    double cx = (x + 0.5) / 2.0 - 0.5, cy = (y + 0.5) / 2.0 - 0.5;
    int x0 = (int)floor(cx), y0 = (int)floor(cy);
    double fx = cx - x0, fy = cy - y0;
    out[0] = out[1] = out[2] = 0;
    for (int j = 0; j < 2; j++) {
        int yy = y0 + j;
        yy = yy < 0 ? 0 : yy >= l->h ? l->h - 1 : yy;
        double wy = j ? fy : 1 - fy;
        for (int i = 0; i < 2; i++) {
            int xx = rig_wrap_x(x0 + i, l->w);
            double wgt = wy * (i ? fx : 1 - fx);
            const double *p = l->v + 3 * ((size_t)yy * l->w + xx);
            for (int c = 0; c < 3; c++)
                out[c] += wgt * p[c];
        }
    }
}

sl_result rig_fill(const sl_image *rgb, const int *labels, sl_image *out, sl_error *err)
{
    int w = rgb->width, h = rgb->height;
    level lv[32];
    int nl = 0;
    memset(lv, 0, sizeof lv);
    if (!alloc_level(&lv[0], w, h))
        goto nomem;
    nl = 1;
    sl_ksum tot[3] = {{0}}, totw = {0};
    for (int y = 0; y < h; y++) {
        double om = sl_latlong_texel_solid_angle(y, w, h);
        for (int x = 0; x < w; x++) {
            size_t i = (size_t)y * w + x;
            lv[0].wf[i] = om;
            if (labels[i])
                continue;
            const float *p = sl_image_pixel(rgb, x, y);
            lv[0].wk[i] = om;
            for (int c = 0; c < 3; c++) {
                lv[0].v[3 * i + c] = om * p[c];
                sl_ksum_add(&tot[c], om * p[c]);
            }
            sl_ksum_add(&totw, om);
        }
    }
    /* Push: sums of 2x2 children, wrapping in x. */
    while (nl < 32 && lv[nl - 1].h > 1 && lv[nl - 1].w > 2) {
        const level *f = &lv[nl - 1];
        level *g = &lv[nl];
        if (!alloc_level(g, (f->w + 1) / 2, (f->h + 1) / 2))
            goto nomem;
        nl++;
        for (int y = 0; y < f->h; y++)
            for (int x = 0; x < f->w; x++) {
                size_t i = (size_t)y * f->w + x, o = (size_t)(y / 2) * g->w + x / 2;
                g->wk[o] += f->wk[i];
                g->wf[o] += f->wf[i];
                for (int c = 0; c < 3; c++)
                    g->v[3 * o + c] += f->v[3 * i + c];
            }
    }
    /* Averages; the coarsest level's empty texels take the global mean. */
    double mean[3];
    double tw = sl_ksum_value(&totw);
    for (int c = 0; c < 3; c++)
        mean[c] = tw > 0 ? sl_ksum_value(&tot[c]) / tw : 0;
    for (int k = 0; k < nl; k++) {
        level *l = &lv[k];
        for (size_t i = 0; i < (size_t)l->w * l->h; i++)
            for (int c = 0; c < 3; c++)
                l->v[3 * i + c] = l->wk[i] > 0 ? l->v[3 * i + c] / l->wk[i]
                                  : k == nl - 1 ? mean[c]
                                                : 0;
    }
    /* Pull: blend each level with the coarser fill by its known fraction. */
    for (int k = nl - 2; k >= 0; k--) {
        level *l = &lv[k];
        const level *g = &lv[k + 1];
        for (int y = 0; y < l->h; y++)
            for (int x = 0; x < l->w; x++) {
                size_t i = (size_t)y * l->w + x;
                double a = l->wf[i] > 0 ? l->wk[i] / l->wf[i] : 0, up[3];
                if (a >= 1)
                    continue;
                upsample(g, x, y, up);
                for (int c = 0; c < 3; c++)
                    l->v[3 * i + c] = a * l->v[3 * i + c] + (1 - a) * up[c];
            }
    }
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            size_t i = (size_t)y * w + x;
            const float *p = sl_image_pixel(rgb, x, y);
            float *q = sl_image_pixel(out, x, y);
            for (int c = 0; c < 3; c++) {
                float f = (float)lv[0].v[3 * i + c];
                /* Never more than the original: no light gets negative energy. */
                q[c] = labels[i] ? (f < p[c] ? f : p[c]) : p[c];
            }
        }
    free_levels(lv, nl);
    return SL_OK;
nomem:
    free_levels(lv, nl + 1 < 32 ? nl + 1 : 32);
    return sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%dx%d map)", w, h);
}
