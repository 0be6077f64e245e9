/* SPDX-License-Identifier: BSD-3-Clause */
/* Reprojection between projections with supersampling and an optional
 * rotation. With world_dir = rot * map_dir, the source is the map and the
 * output the world: output direction d looks up the source at rot^T d, so
 * content at source direction s lands at rot * s. */
#include "projection_private.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define SS_MAX 8

typedef struct reproject_ctx {
    const sl_image *src;
    sl_image *dst;
    sl_projection from, to;
    double rot[3][3];
    int ss;
} reproject_ctx;

/* Disc images (mirror ball, angular) keep data in every texel that touches
 * the disc, so that bilinear lookups up to the rim never mix in the empty
 * corners; texels further out are 0. */
static bool disc_texel_used(int x, int y, int size)
{
    double px = (x + 0.5) * 2.0 / size - 1.0, py = (y + 0.5) * 2.0 / size - 1.0;
    double lim = 1.0 + 1.5 / size; /* just over half a texel diagonal, sqrt(2) / size */
    return px * px + py * py <= lim * lim;
}

/* Bilinear inside one rectangle of texels [x0, x0+w) x [y0, y0+h) with edge
 * clamping; used for whole circle images and for single cube faces. Texels
 * whose centre lies more than 0.75 texel outside the disc carry no data
 * (mirror ball corners) and are left out with the weights renormalised. */
static bool bilinear_rect(const sl_image *img, int x0, int y0, int w, int h, double fx,
                          double fy, bool disc, double *acc)
{
    double x = fx * w - 0.5, y = fy * h - 0.5;
    double xf = floor(x), yf = floor(y);
    double tx = x - xf, ty = y - yf;
    int c = img->channels;
    double sum[4] = {0, 0, 0, 0}, wsum = 0.0;
    for (int j = 0; j < 2; j++) {
        int yy = (int)yf + j;
        yy = yy < 0 ? 0 : (yy > h - 1 ? h - 1 : yy);
        double wy = j ? ty : 1.0 - ty;
        for (int i = 0; i < 2; i++) {
            int xx = (int)xf + i;
            xx = xx < 0 ? 0 : (xx > w - 1 ? w - 1 : xx);
            double wt = wy * (i ? tx : 1.0 - tx);
            if (wt == 0.0)
                continue;
            if (disc && !disc_texel_used(xx, yy, w))
                continue;
            const float *p = sl_image_pixel(img, x0 + xx, y0 + yy);
            for (int k = 0; k < c; k++)
                sum[k] += wt * p[k];
            wsum += wt;
        }
    }
    if (wsum <= 0.0)
        return false;
    for (int k = 0; k < c; k++)
        acc[k] += sum[k] / wsum;
    return true;
}

static bool lookup(const reproject_ctx *r, const double dir[3], double *acc)
{
    const sl_image *s = r->src;
    double u, v;
    switch (r->from) {
    case SL_PROJ_LATLONG: {
        float px[4];
        sl_dir_to_latlong(dir, &u, &v);
        sl_latlong_lookup(s, u, v, px);
        for (int k = 0; k < s->channels; k++)
            acc[k] += px[k];
        return true;
    }
    case SL_PROJ_CUBEMAP: {
        int face = sl_dir_to_cube_face(dir, &u, &v);
        return bilinear_rect(s, 0, face * s->width, s->width, s->width, u, v, false, acc);
    }
    default:
        if (!sl_dir_to_projection(r->from, dir, &u, &v))
            return false;
        return bilinear_rect(s, 0, 0, s->width, s->height, u, v, true, acc);
    }
}

static void reproject_rows(void *vctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    const reproject_ctx *r = vctx;
    sl_image *d = r->dst;
    int c = d->channels, ss = r->ss;
    bool disc = r->to == SL_PROJ_MIRRORBALL || r->to == SL_PROJ_ANGULAR;
    for (int64_t y = begin; y < end; y++) {
        for (int x = 0; x < d->width; x++) {
            double acc[4] = {0, 0, 0, 0};
            int n = 0;
            bool used = !disc || disc_texel_used(x, (int)y, d->width);
            for (int sy = 0; used && sy < ss; sy++) {
                double v = (y + (sy + 0.5) / ss) / d->height;
                for (int sx = 0; sx < ss; sx++) {
                    double u = (x + (sx + 0.5) / ss) / d->width, sv = v, o[3], m[3];
                    if (disc) { /* rim texels: samples outside move radially onto the rim */
                        double px = 2.0 * u - 1.0, py = 1.0 - 2.0 * v;
                        double rr = sqrt(px * px + py * py);
                        if (rr > 1.0) {
                            u = 0.5 * (px / rr + 1.0);
                            sv = 0.5 * (1.0 - py / rr);
                        }
                    }
                    if (!sl_projection_to_dir(r->to, u, sv, o))
                        continue;
                    for (int i = 0; i < 3; i++) /* rot^T * o */
                        m[i] = r->rot[0][i] * o[0] + r->rot[1][i] * o[1] + r->rot[2][i] * o[2];
                    if (lookup(r, m, acc))
                        n++;
                }
            }
            float *out = sl_image_pixel(d, x, (int)y);
            for (int k = 0; k < c; k++) {
                double val = n ? acc[k] / n : 0.0;
                out[k] = isfinite(val) ? (float)val : 0.0f;
            }
        }
    }
}

/* Valid texels per steradian: how finely a projection samples the sphere. */
static double texel_density(sl_projection p, int w, int h)
{
    double area = (double)w * h;
    if (p == SL_PROJ_MIRRORBALL || p == SL_PROJ_ANGULAR)
        area *= M_PI / 4.0;
    return area / (4.0 * M_PI);
}

sl_result sl_reproject(const sl_image *src, sl_projection from, sl_projection to, int width,
                       const double rot[3][3], sl_image *dst, sl_error *err)
{
    memset(dst, 0, sizeof *dst);
    if (from < 0 || from >= SL_PROJ_COUNT || to < 0 || to >= SL_PROJ_COUNT)
        return sl_error_set(err, SL_ERR_USAGE, "reproject: unknown projection %d -> %d",
                            (int)from, (int)to);
    if (!src || !src->data || src->width <= 0 || src->height <= 0)
        return sl_error_set(err, SL_ERR_INPUT, "reproject: empty source image");
    if ((from == SL_PROJ_MIRRORBALL || from == SL_PROJ_ANGULAR) && src->width != src->height)
        return sl_error_set(err, SL_ERR_INPUT, "reproject: %s source is %dx%d, not square",
                            sl_projection_name(from), src->width, src->height);
    if (from == SL_PROJ_CUBEMAP && src->height != 6 * src->width)
        return sl_error_set(err, SL_ERR_INPUT,
                            "reproject: cube map source is %dx%d, not w x 6w", src->width,
                            src->height);
    int w, h;
    sl_projection_size(to, width, &w, &h);
    if (width <= 0 || w <= 0 || h <= 0)
        return sl_error_set(err, SL_ERR_USAGE, "reproject: width %d is too small for %s", width,
                            sl_projection_name(to));
    sl_result res = sl_image_alloc(dst, w, h, src->channels, err);
    if (res)
        return res;

    /* Same projection, same size, no rotation: a copy, not a resampling blur. */
    bool identity = true;
    for (int i = 0; rot && i < 3; i++)
        for (int j = 0; j < 3; j++)
            identity = identity && rot[i][j] == (i == j ? 1.0 : 0.0);
    if (identity && from == to && w == src->width && h == src->height) {
        for (int y = 0; y < h; y++)
            memcpy(sl_image_pixel(dst, 0, y), sl_image_pixel(src, 0, y),
                   sizeof(float) * (size_t)w * (size_t)src->channels);
        return SL_OK;
    }
    reproject_ctx r = {src, dst, from, to, {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, 2};
    if (rot)
        memcpy(r.rot, rot, sizeof r.rot);
    double ratio = texel_density(from, src->width, src->height) / texel_density(to, w, h);
    int ss = (int)ceil(sqrt(ratio));
    r.ss = ss < 2 ? 2 : (ss > SS_MAX ? SS_MAX : ss);
    sl_parallel_for(h, 4, reproject_rows, &r);
    return SL_OK;
}
