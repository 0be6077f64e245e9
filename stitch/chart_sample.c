/* SPDX-License-Identifier: BSD-3-Clause */
/* ColorChecker patch centres from four corners, and robust patch sampling
 * on the linear image. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "calibrate_internal.h"
#include "setlight/stitch.h"

bool sl_cal_grid_centers(const double img[4][2], const double grid[4][2], double centers[24][2])
{
    double a[64] = {0}, b[8];
    for (int i = 0; i < 4; i++) {
        double u = grid[i][0], v = grid[i][1], x = img[i][0], y = img[i][1];
        double *r0 = a + (2 * i) * 8, *r1 = a + (2 * i + 1) * 8;
        r0[0] = u, r0[1] = v, r0[2] = 1, r0[6] = -u * x, r0[7] = -v * x;
        r1[3] = u, r1[4] = v, r1[5] = 1, r1[6] = -u * y, r1[7] = -v * y;
        b[2 * i] = x, b[2 * i + 1] = y;
    }
    if (!sl_cal_solve(a, b, 8))
        return false;
    for (int p = 0; p < 24; p++) {
        double u = p % 6, v = p / 6;
        double w = b[6] * u + b[7] * v + 1;
        if (!(w > 1e-9))
            return false;
        centers[p][0] = (b[0] * u + b[1] * v + b[2]) / w;
        centers[p][1] = (b[3] * u + b[4] * v + b[5]) / w;
    }
    return true;
}

sl_result sl_chart_centers_from_corners(const double corners[4][2], double centers[24][2],
                                        sl_error *err)
{
    memset(centers, 0, sizeof(double) * 48);
    /* Grid coordinates (column, row) of the corner patches 1, 6, 24, 19. */
    static const double g[4][2] = {{0, 0}, {5, 0}, {5, 3}, {0, 3}};
    for (int i = 0; i < 4; i++)
        if (!isfinite(corners[i][0]) || !isfinite(corners[i][1]))
            return sl_error_set(err, SL_ERR_USAGE, "chart corners: corner %d is not finite", i + 1);
    /* The corners must go round the chart one way: the turn has the same
     * sign at every corner (convex, not a bow-tie). */
    double s = 0;
    for (int i = 0; i < 4; i++) {
        const double *p0 = corners[i], *p1 = corners[(i + 1) % 4], *p2 = corners[(i + 2) % 4];
        double c = (p1[0] - p0[0]) * (p2[1] - p1[1]) - (p1[1] - p0[1]) * (p2[0] - p1[0]);
        if (c == 0 || (i && c * s <= 0))
            return sl_error_set(err, SL_ERR_USAGE,
                                "chart corners: not a convex quadrilateral in patch order 1, 6, 24, 19");
        s = c;
    }
    if (!sl_cal_grid_centers(corners, g, centers))
        return sl_error_set(err, SL_ERR_USAGE, "chart corners: degenerate quadrilateral");
    return SL_OK;
}

typedef struct {
    double key;
    float rgb[3];
} px_t;

static int cmp_px(const void *a, const void *b)
{
    double x = ((const px_t *)a)->key, y = ((const px_t *)b)->key;
    return (x > y) - (x < y);
}

sl_result sl_chart_sample(const sl_image *img, const double centers[24][2], double radius_px,
                          double clip_level, sl_chart_patch patches[24], sl_error *err)
{
    memset(patches, 0, sizeof(sl_chart_patch) * 24);
    if (!img || !img->data || img->channels < 3)
        return sl_error_set(err, SL_ERR_INPUT, "chart image: needs RGB");
    if (!(radius_px >= 0) || !(clip_level >= 0))
        return sl_error_set(err, SL_ERR_USAGE, "chart sampling: radius and clip level must be >= 0");
    double r_max = 0;
    for (int p = 0; p < 24; p++) {
        double r = radius_px;
        if (r == 0) {
            double dmin = INFINITY;
            for (int q = 0; q < 24; q++)
                if (q != p)
                    dmin = fmin(dmin, hypot(centers[q][0] - centers[p][0],
                                            centers[q][1] - centers[p][1]));
            r = 0.25 * dmin;
        }
        if (!(r >= 0.5) || !isfinite(centers[p][0]) || !isfinite(centers[p][1]))
            return sl_error_set(err, SL_ERR_INPUT,
                                "chart sampling: patch %d too small or not finite", p + 1);
        patches[p].center[0] = centers[p][0];
        patches[p].center[1] = centers[p][1];
        patches[p].radius = r;
        r_max = fmax(r_max, r);
    }
    size_t cap = (size_t)(M_PI * (r_max + 1) * (r_max + 1)) + 16;
    px_t *buf = malloc(cap * sizeof(*buf));
    if (!buf)
        return sl_error_set(err, SL_ERR_NOMEM, "chart sampling: out of memory");
    for (int p = 0; p < 24; p++) {
        sl_chart_patch *pt = &patches[p];
        double cx = pt->center[0], cy = pt->center[1], r = pt->radius;
        int x0 = (int)floor(cx - r), x1 = (int)ceil(cx + r);
        int y0 = (int)floor(cy - r), y1 = (int)ceil(cy + r);
        size_t n = 0;
        int disc = 0;
        for (int y = y0 < 0 ? 0 : y0; y <= y1 && y < img->height; y++)
            for (int x = x0 < 0 ? 0 : x0; x <= x1 && x < img->width; x++) {
                double dx = x + 0.5 - cx, dy = y + 0.5 - cy;
                if (dx * dx + dy * dy > r * r)
                    continue;
                disc++;
                const float *v = img->data + (size_t)y * img->stride + (size_t)x * img->channels;
                if (!isfinite(v[0]) || !isfinite(v[1]) || !isfinite(v[2])) {
                    pt->nonfinite++;
                    continue;
                }
                if (clip_level > 0 &&
                    (v[0] >= clip_level || v[1] >= clip_level || v[2] >= clip_level)) {
                    pt->clipped++;
                    continue;
                }
                buf[n].key = (double)v[0] + v[1] + v[2];
                memcpy(buf[n].rgb, v, sizeof(buf[n].rgb));
                n++;
            }
        qsort(buf, n, sizeof(*buf), cmp_px);
        size_t cut = n / 10;
        pt->trimmed = (int)(2 * cut);
        double s[3] = {0, 0, 0}, ss = 0, sk = 0;
        for (size_t i = cut; i < n - cut; i++) {
            for (int c = 0; c < 3; c++)
                s[c] += buf[i].rgb[c];
            sk += buf[i].key;
            ss += buf[i].key * buf[i].key;
        }
        size_t k = n - 2 * cut;
        pt->pixels = (int)k;
        if (k > 0) {
            for (int c = 0; c < 3; c++)
                pt->rgb[c] = s[c] / (double)k;
            double mean = sk / (double)k, var = fmax(ss / (double)k - mean * mean, 0);
            pt->spread = mean > 0 ? sqrt(var) / mean : 0;
        }
        /* A patch that varies more than noise and texture do has a shadow
         * edge or glare across it. */
        pt->valid = k >= 4 && disc > 0 && pt->clipped <= 0.05 * disc &&
                    pt->nonfinite <= 0.5 * disc && pt->spread <= SL_CHART_MAX_SPREAD;
    }
    free(buf);
    return SL_OK;
}

int64_t sl_pinned_maximum(const sl_image *img, double level[3])
{
    double top[3] = {0, 0, 0};
    int64_t at_top[3] = {0, 0, 0}, n = (int64_t)img->width * img->height;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            const float *v = sl_image_pixel(img, x, y);
            for (int c = 0; c < 3; c++) {
                if (!isfinite(v[c]) || v[c] < top[c])
                    continue;
                at_top[c] = v[c] > top[c] ? 1 : at_top[c] + 1;
                top[c] = v[c];
            }
        }
    /* Measured light is never the same float in many pixels at the very
     * top: a saturated sensor (or a merge's clipped bound) is. */
    int64_t enough = n / 1000 > 16 ? n / 1000 : 16, pinned = 0;
    for (int c = 0; c < 3; c++)
        level[c] = top[c] > 0 && at_top[c] >= enough ? top[c] : 0;
    for (int y = 0; level[0] + level[1] + level[2] > 0 && y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            const float *v = sl_image_pixel(img, x, y);
            bool any = false;
            for (int c = 0; c < 3; c++)
                any = any || (level[c] > 0 && v[c] >= level[c]);
            pinned += any;
        }
    return pinned;
}
