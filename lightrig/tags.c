/* SPDX-License-Identifier: BSD-3-Clause */
/* Artist tags: regions kept or left in the dome by hand, as on set. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "lightrig_private.h"

#define TAG_RADIUS (2 * M_PI / 180)
/* An included region grown from scratch stays within this of its seed. */
#define TAG_GROW_RADIUS (15 * M_PI / 180)

static double texel_angle(int x, int y, int w, int h, const double d[3])
{
    double t[3];
    rig_texel_dir(x, y, w, h, t);
    double c[3] = {t[1] * d[2] - t[2] * d[1], t[2] * d[0] - t[0] * d[2], t[0] * d[1] - t[1] * d[0]};
    return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]),
                 t[0] * d[0] + t[1] * d[1] + t[2] * d[2]);
}

static void tag_dir(const double latlon[2], double d[3])
{
    double la = latlon[0] * M_PI / 180, lo = latlon[1] * M_PI / 180;
    d[0] = sin(lo) * cos(la);
    d[1] = sin(la);
    d[2] = cos(lo) * cos(la);
}

/* Rows that can hold texels within `radius` of d. */
static void search_rows(const double d[3], double radius, int h, int *y0, int *y1)
{
    double u, v;
    sl_dir_to_latlong(d, &u, &v);
    int yc = (int)(v * h), dy = (int)ceil(radius / (M_PI / h)) + 1;
    *y0 = yc - dy < 0 ? 0 : yc - dy;
    *y1 = yc + dy >= h ? h - 1 : yc + dy;
}

/* Label of the region nearest to d within TAG_RADIUS, 0 if none; also the
 * brightest texel there (for growing a new region). */
static int region_at(const float *lum, const int *labels, int w, int h, const double d[3],
                     size_t *brightest)
{
    int y0, y1, best = 0;
    double best_a = INFINITY, peak = -1;
    search_rows(d, TAG_RADIUS, h, &y0, &y1);
    for (int y = y0; y <= y1; y++)
        for (int x = 0; x < w; x++) {
            double a = texel_angle(x, y, w, h, d);
            if (a > TAG_RADIUS)
                continue;
            size_t i = (size_t)y * w + x;
            if (labels[i] && a < best_a) {
                best_a = a;
                best = labels[i];
            }
            if (lum[i] > peak) {
                peak = lum[i];
                *brightest = i;
            }
        }
    return best;
}

sl_result rig_apply_tags(const float *lum, int w, int h, const sl_rig_options *opt, int *labels,
                         int *count, int *tags, sl_error *err)
{
    size_t n = (size_t)w * h;
    int *queue = NULL;
    for (int k = 0; k < opt->exclude_count; k++) {
        double d[3];
        size_t b = 0;
        tag_dir(opt->exclude[k], d);
        int l = region_at(lum, labels, w, h, d, &b);
        if (l)
            tags[l] = -(k + 1);
    }
    for (int k = 0; k < opt->include_count; k++) {
        double d[3];
        size_t b = (size_t)-1;
        tag_dir(opt->include[k], d);
        int l = region_at(lum, labels, w, h, d, &b);
        if (l) {
            tags[l] = k + 1;
            continue;
        }
        if (b == (size_t)-1 || !(lum[b] > 0)) {
            free(queue);
            return sl_error_set(err, SL_ERR_USAGE, "--include %g,%g: the map is black there",
                                opt->include[k][0], opt->include[k][1]);
        }
        if (!queue && !(queue = malloc(n * sizeof *queue)))
            return sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%dx%d map)", w, h);
        /* Grow from the brightest texel over what is at least half as bright. */
        int label = ++*count;
        double floor_lum = 0.5 * lum[b], seed_dir[3];
        rig_texel_dir((int)(b % (size_t)w), (int)(b / (size_t)w), w, h, seed_dir);
        size_t head = 0, tail = 0;
        queue[tail++] = (int)b;
        labels[b] = label;
        while (head < tail) {
            int p = queue[head++];
            int px = p % w, py = p / w;
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    int yy = py + dy, xx = px + dx;
                    if (yy < 0 || yy >= h) {
                        yy = py;
                        xx += w / 2;
                    }
                    xx = rig_wrap_x(xx, w);
                    size_t q = (size_t)yy * w + xx;
                    if (labels[q] || !(lum[q] >= floor_lum) ||
                        texel_angle(xx, yy, w, h, seed_dir) > TAG_GROW_RADIUS)
                        continue;
                    labels[q] = label;
                    queue[tail++] = (int)q;
                }
        }
        /* and its soft edge, as for detected regions */
        size_t start = 0;
        for (int step = 0; step < 2; step++) {
            size_t end = tail;
            for (size_t j = start; j < end; j++) {
                int p = queue[j], px = p % w, py = p / w;
                for (int dy = -1; dy <= 1; dy++)
                    for (int dx = -1; dx <= 1; dx++) {
                        int yy = py + dy, xx = px + dx;
                        if (yy < 0 || yy >= h) {
                            yy = py;
                            xx += w / 2;
                        }
                        size_t q = (size_t)yy * w + rig_wrap_x(xx, w);
                        if (!labels[q]) {
                            labels[q] = label;
                            queue[tail++] = (int)q;
                        }
                    }
            }
            start = end;
        }
        tags[label] = k + 1;
    }
    free(queue);
    return SL_OK;
}
