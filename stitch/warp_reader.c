/* SPDX-License-Identifier: BSD-3-Clause */
/* Strip reading with the alignment applied (see warp_reader.h). */
#include "warp_reader.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>


struct merge_frame_reader {
    sl_photo_strips *rd;
    int width, height;
    bool warp;
    double c, s, tx, ty, cx, cy;
    float *ring;   /* source rows, row r in slot r % cap */
    int cap;
    int lo, hi;    /* rows [lo, hi) of the source are in the ring */
};

sl_result merge_frame_open(const char *path, const sl_align_transform *align, int max_rows,
                           merge_frame_reader **reader, sl_error *err)
{
    *reader = NULL;
    merge_frame_reader *fr = calloc(1, sizeof *fr);
    if (!fr)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    sl_photo_strip_info info;
    sl_result r = sl_photo_strips_open(path, &fr->rd, &info, err);
    if (r) {
        free(fr);
        return r;
    }
    fr->width = info.width;
    fr->height = info.height;
    if (align && align->applied) {
        double th = align->angle * M_PI / 180;
        fr->warp = true;
        fr->c = cos(th);
        fr->s = sin(th);
        fr->tx = align->dx;
        fr->ty = align->dy;
        fr->cx = 0.5 * info.width;
        fr->cy = 0.5 * info.height;
        /* A strip's source rows span its height, the rotation across the
         * width, and two rows either side for the cubic weights. */
        double span = max_rows + fabs(fr->s) * info.width + fabs(fr->c - 1) * max_rows + 10;
        fr->cap = span < info.height ? (int)span : info.height;
        fr->ring = malloc((size_t)fr->cap * info.width * 3 * sizeof *fr->ring);
        if (!fr->ring) {
            merge_frame_close(fr);
            return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
        }
    }
    *reader = fr;
    return SL_OK;
}

/* Catmull-Rom weights for taps at -1, 0, 1, 2 (bilinear blurs a sharp
 * texture by several percent; this keeps it near the noise). */
static void cubic_weights(float f, float w[4])
{
    float f2 = f * f, f3 = f2 * f;
    w[0] = -0.5f * f3 + f2 - 0.5f * f;
    w[1] = 1.5f * f3 - 2.5f * f2 + 1;
    w[2] = -1.5f * f3 + 2 * f2 + 0.5f * f;
    w[3] = 0.5f * f3 - 0.5f * f2;
}

/* Source row of reference position (x, y), in the frame's pixel-centre index space. */
static double source_y(const merge_frame_reader *fr, double x, double y)
{
    return fr->s * (x - fr->cx) + fr->c * (y - fr->cy) + fr->cy + fr->ty - 0.5;
}

/* Reads source rows up to `need_hi`, dropping rows below `need_lo`. */
static sl_result fill(merge_frame_reader *fr, int need_lo, int need_hi, sl_error *err)
{
    if (need_lo > fr->lo)
        fr->lo = need_lo < fr->hi ? need_lo : fr->hi;
    while (fr->hi < need_hi) {
        /* Rows below lo are read into the ring too (a reader cannot skip). */
        int slot = fr->hi % fr->cap, n = need_hi - fr->hi;
        n = n < fr->cap - slot ? n : fr->cap - slot;
        sl_result r = sl_photo_strips_read(fr->rd, fr->hi, fr->hi + n,
                                       fr->ring + (size_t)slot * fr->width * 3, err);
        if (r)
            return r;
        fr->hi += n;
        if (fr->hi - fr->lo > fr->cap)
            fr->lo = fr->hi - fr->cap;
    }
    return SL_OK;
}

sl_result merge_frame_read(merge_frame_reader *fr, int y0, int y1, float *rgb, sl_error *err)
{
    if (!fr->warp)
        return sl_photo_strips_read(fr->rd, y0, y1, rgb, err);
    int w = fr->width, h = fr->height;
    double ys[4] = {source_y(fr, 0, y0), source_y(fr, w, y0), source_y(fr, 0, y1),
                    source_y(fr, w, y1)};
    double lo = ys[0], hi = ys[0];
    for (int k = 1; k < 4; k++) {
        lo = fmin(lo, ys[k]);
        hi = fmax(hi, ys[k]);
    }
    int need_lo = (int)floor(lo) - 2, need_hi = (int)floor(hi) + 4;
    need_lo = need_lo < 0 ? 0 : need_lo > h - 1 ? h - 1 : need_lo;
    need_hi = need_hi > h ? h : need_hi < 1 ? 1 : need_hi;
    sl_result r = fill(fr, need_lo, need_hi, err);
    if (r)
        return r;
    int rlo = fr->lo, rhi = fr->hi - 1;
    for (int y = y0; y < y1; y++) {
        double py = y + 0.5 - fr->cy;
        /* Source position of pixel x, stepped along the row. */
        double qx = fr->c * (0.5 - fr->cx) - fr->s * py + fr->cx + fr->tx - 0.5;
        double qy = fr->s * (0.5 - fr->cx) + fr->c * py + fr->cy + fr->ty - 0.5;
        float *dst = rgb + (size_t)(y - y0) * w * 3;
        for (int x = 0; x < w; x++, qx += fr->c, qy += fr->s) {
            double ux = qx < 0 ? 0 : qx > w - 1 ? w - 1 : qx;
            double uy = qy < rlo ? rlo : qy > rhi ? rhi : qy;
            int ix = (int)ux, iy = (int)uy;
            float wx[4], wy[4];
            cubic_weights((float)(ux - ix), wx);
            cubic_weights((float)(uy - iy), wy);
            int cols[4];
            for (int k = 0; k < 4; k++) {
                int cx = ix - 1 + k;
                cols[k] = (cx < 0 ? 0 : cx > w - 1 ? w - 1 : cx) * 3;
            }
            float acc[3] = {0, 0, 0};
            for (int j = 0; j < 4; j++) {
                int ry = iy - 1 + j;
                ry = ry < rlo ? rlo : ry > rhi ? rhi : ry;
                const float *row = fr->ring + (size_t)(ry % fr->cap) * w * 3;
                for (int c = 0; c < 3; c++) {
                    float h = wx[0] * row[cols[0] + c] + wx[1] * row[cols[1] + c] +
                              wx[2] * row[cols[2] + c] + wx[3] * row[cols[3] + c];
                    acc[c] += wy[j] * h;
                }
            }
            /* Cubic overshoot must not make a negative code. */
            for (int c = 0; c < 3; c++)
                dst[x * 3 + c] = acc[c] > 0 ? acc[c] : 0;
        }
    }
    return SL_OK;
}

sl_result merge_frame_read_codes(merge_frame_reader *fr, int y0, int y1, void *codes,
                                 sl_error *err)
{
    if (fr->warp)
        return sl_error_set(err, SL_ERR_INTERNAL, "merge: codes asked of a warped frame");
    return sl_photo_strips_read_codes(fr->rd, y0, y1, codes, err);
}

void merge_frame_close(merge_frame_reader *fr)
{
    if (!fr)
        return;
    sl_photo_strips_close(fr->rd);
    free(fr->ring);
    free(fr);
}

bool merge_frame_covers(const sl_align_transform *align, int w, int h, int x, int y)
{
    if (!align->applied)
        return true;
    double th = align->angle * M_PI / 180, c = cos(th), s = sin(th);
    double px = x + 0.5 - 0.5 * w, py = y + 0.5 - 0.5 * h;
    double qx = c * px - s * py + 0.5 * w + align->dx, qy = s * px + c * py + 0.5 * h + align->dy;
    /* Two pixels in: the cubic weights reach that far. */
    return qx >= 2 && qy >= 2 && qx <= w - 2 && qy <= h - 2;
}
