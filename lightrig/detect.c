/* SPDX-License-Identifier: BSD-3-Clause */
/* Bright regions on the sphere: a threshold relative to the map's median,
 * connected components with longitude wrap and pole crossing, fragments of
 * one fixture merged, and a ring of texels added for the soft edge. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "lightrig_private.h"

void rig_texel_dir(int x, int y, int w, int h, double dir[3])
{
    sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / h, dir);
}

typedef struct lum_row {
    float lum;
    int row;
} lum_row;

static int cmp_lum(const void *a, const void *b)
{
    float x = ((const lum_row *)a)->lum, y = ((const lum_row *)b)->lum;
    return (x > y) - (x < y);
}

double rig_weighted_median(const float *lum, int w, int h, sl_error *err, sl_result *res)
{
    size_t n = (size_t)w * h;
    lum_row *v = malloc(n * sizeof *v);
    *res = SL_OK;
    if (!v) {
        *res = sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%dx%d map)", w, h);
        return 0;
    }
    for (size_t i = 0; i < n; i++) {
        v[i].lum = lum[i];
        v[i].row = (int)(i / (size_t)w);
    }
    qsort(v, n, sizeof *v, cmp_lum);
    /* Half of the sphere (2 pi) is darker than the median. */
    double acc = 0, med = 0;
    for (size_t i = 0; i < n; i++) {
        acc += sl_latlong_texel_solid_angle(v[i].row, w, h);
        if (acc >= 2 * M_PI) {
            med = v[i].lum;
            break;
        }
    }
    if (acc < 2 * M_PI && n)
        med = v[n - 1].lum;
    free(v);
    return med;
}

/* 8-neighbours of (x, y) with wrap in x; the top and bottom rows also touch
 * the texels across the pole. Returns the count written to nx, ny. */
static int neighbours(int x, int y, int w, int h, int *nx, int *ny)
{
    int n = 0;
    for (int dy = -1; dy <= 1; dy++) {
        for (int dx = -1; dx <= 1; dx++) {
            if (!dx && !dy)
                continue;
            int yy = y + dy, xx = x + dx;
            if (yy < 0 || yy >= h) {
                /* across the pole: same row, half a turn away */
                yy = y;
                xx += w / 2;
            }
            nx[n] = rig_wrap_x(xx, w);
            ny[n] = yy;
            n++;
        }
    }
    return n;
}




/* Labels the 8-connected components (wrap, pole) of mask into labels (1..),
 * in scan order; returns the count. */
static int components(const unsigned char *mask, int w, int h, int *labels, int *queue)
{
    size_t n = (size_t)w * h;
    int count = 0;
    for (size_t i = 0; i < n; i++) {
        if (labels[i] || !mask[i])
            continue;
        count++;
        size_t head = 0, tail = 0;
        queue[tail++] = (int)i;
        labels[i] = count;
        while (head < tail) {
            int p = queue[head++], nx[8], ny[8];
            int k = neighbours(p % w, p / w, w, h, nx, ny);
            for (int j = 0; j < k; j++) {
                size_t q = (size_t)ny[j] * w + nx[j];
                if (!labels[q] && mask[q]) {
                    labels[q] = count;
                    queue[tail++] = (int)q;
                }
            }
        }
    }
    return count;
}

sl_result rig_detect(const float *lum, int w, int h, double threshold_lum, double peak_fraction,
                     double merge_rad, int ring, int *labels, int *count, sl_error *err)
{
    size_t n = (size_t)w * h;
    *count = 0;
    int *queue = malloc(n * sizeof *queue), *group = calloc(n, sizeof *group);
    unsigned char *seed = calloc(n, 1), *a = malloc(n), *b = malloc(n);
    int *rowsum = malloc(((size_t)w + 1) * sizeof *rowsum);
    if (!queue || !group || !seed || !a || !b || !rowsum) {
        free(queue);
        free(group);
        free(seed);
        free(a);
        free(b);
        free(rowsum);
        return sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%dx%d map)", w, h);
    }
    for (size_t i = 0; i < n; i++)
        seed[i] = lum[i] > threshold_lum;
    /* A fixture is much brighter than the lit surface around it (a lamp over
     * a white cyclorama, the sun in its aureole): within each connected
     * bright area only what reaches peak_fraction of its peak seeds a light. */
    int nc = components(seed, w, h, group, queue);
    float *peak = calloc((size_t)nc + 1, sizeof *peak);
    if (!peak) {
        free(queue);
        free(group);
        free(seed);
        free(a);
        free(b);
        free(rowsum);
        return sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%dx%d map)", w, h);
    }
    for (size_t i = 0; i < n; i++)
        if (group[i] && lum[i] > peak[group[i]])
            peak[group[i]] = lum[i];
    for (size_t i = 0; i < n; i++) {
        if (group[i] && !(lum[i] >= peak_fraction * peak[group[i]]))
            seed[i] = 0;
        group[i] = 0;
    }
    free(peak);

    /* Fragments of one fixture: seeds grown by half the merge angle (a box
     * of that angular half-size: wider in texels toward the poles) that
     * touch are one group. Separable, so linear in the map size. */
    double dlon = 2 * M_PI / w, dlat = M_PI / h;
    int ky = (int)lround(0.5 * merge_rad / dlat);
    for (int y = 0; y < h; y++) {
        const unsigned char *s = seed + (size_t)y * w;
        unsigned char *o = a + (size_t)y * w;
        double c = cos(M_PI * (0.5 - (y + 0.5) / h));
        double kxd = 0.5 * merge_rad / (dlon * c);
        int kx = kxd >= w / 2 ? w / 2 : (int)lround(kxd);
        rowsum[0] = 0;
        for (int x = 0; x < w; x++)
            rowsum[x + 1] = rowsum[x] + s[x];
        for (int x = 0; x < w; x++) {
            if (2 * kx + 1 >= w) {
                o[x] = rowsum[w] > 0;
                continue;
            }
            int lo = x - kx, hi = x + kx + 1, sum;
            if (lo < 0)
                sum = rowsum[hi] + rowsum[w] - rowsum[w + lo];
            else if (hi > w)
                sum = rowsum[w] - rowsum[lo] + rowsum[hi - w];
            else
                sum = rowsum[hi] - rowsum[lo];
            o[x] = sum > 0;
        }
    }
    for (int x = 0; x < w; x++) {
        int run = 0; /* seeds of column x within [y - ky, y + ky] */
        for (int y = 0; y < ky && y < h; y++)
            run += a[(size_t)y * w + x];
        for (int y = 0; y < h; y++) {
            if (y + ky < h)
                run += a[(size_t)(y + ky) * w + x];
            if (y - ky - 1 >= 0)
                run -= a[(size_t)(y - ky - 1) * w + x];
            b[(size_t)y * w + x] = run > 0;
        }
    }
    components(b, w, h, group, queue);
    /* Regions: the seeds, numbered by group in order of first appearance. */
    int m = 0;
    int *newid = group; /* reuse: group ids map to region ids in place */
    int *map = calloc(n + 1, sizeof *map);
    if (!map) {
        free(queue);
        free(group);
        free(seed);
        free(a);
        free(b);
        free(rowsum);
        return sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%dx%d map)", w, h);
    }
    for (size_t i = 0; i < n; i++) {
        if (!seed[i])
            continue;
        int g = newid[i];
        if (!map[g])
            map[g] = ++m;
        labels[i] = map[g];
    }
    free(map);

    /* Grow every region by `ring` texels (breadth first, first come keeps). */
    size_t tail = 0;
    for (size_t i = 0; i < n; i++)
        if (labels[i])
            queue[tail++] = (int)i;
    size_t head = 0;
    for (int step = 0; step < ring; step++) {
        size_t end = tail;
        while (head < end) {
            int p = queue[head++], nx[8], ny[8];
            int k = neighbours(p % w, p / w, w, h, nx, ny);
            for (int j = 0; j < k; j++) {
                size_t q = (size_t)ny[j] * w + nx[j];
                if (!labels[q]) {
                    labels[q] = labels[p];
                    queue[tail++] = (int)q;
                }
            }
        }
    }
    *count = m;
    free(queue);
    free(group);
    free(seed);
    free(a);
    free(b);
    free(rowsum);
    return SL_OK;
}
