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

typedef struct comp {
    double dir[3];   /* energy-weighted mean, unit */
    double radius;   /* largest angle from dir to a texel edge */
    double energy;
} comp;

static int uf_find(int *parent, int i)
{
    while (parent[i] != i) {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    return i;
}

static double angle_between(const double a[3], const double b[3])
{
    double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
                   a[0] * b[1] - a[1] * b[0]};
    return atan2(sqrt(c[0] * c[0] + c[1] * c[1] + c[2] * c[2]),
                 a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
}

sl_result rig_detect(const float *lum, int w, int h, double threshold_lum, double merge_rad,
                     int ring, int *labels, int *count, sl_error *err)
{
    size_t n = (size_t)w * h;
    *count = 0;
    int *queue = malloc(n * sizeof *queue);
    if (!queue)
        return sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%dx%d map)", w, h);

    /* Connected components of the seeds, in scan order. */
    int ncomp = 0;
    for (size_t i = 0; i < n; i++) {
        if (labels[i] || !(lum[i] > threshold_lum))
            continue;
        ncomp++;
        size_t head = 0, tail = 0;
        queue[tail++] = (int)i;
        labels[i] = ncomp;
        while (head < tail) {
            int p = queue[head++], nx[8], ny[8];
            int k = neighbours(p % w, p / w, w, h, nx, ny);
            for (int j = 0; j < k; j++) {
                size_t q = (size_t)ny[j] * w + nx[j];
                if (!labels[q] && lum[q] > threshold_lum) {
                    labels[q] = ncomp;
                    queue[tail++] = (int)q;
                }
            }
        }
    }
    if (!ncomp) {
        free(queue);
        return SL_OK;
    }

    comp *c = calloc((size_t)ncomp, sizeof *c);
    int *parent = malloc((size_t)ncomp * sizeof *parent);
    if (!c || !parent) {
        free(queue);
        free(c);
        free(parent);
        return sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%d regions)", ncomp);
    }
    double dv[3];
    for (size_t i = 0; i < n; i++) {
        if (!labels[i])
            continue;
        comp *k = &c[labels[i] - 1];
        int y = (int)(i / (size_t)w);
        double e = lum[i] * sl_latlong_texel_solid_angle(y, w, h);
        rig_texel_dir((int)(i % (size_t)w), y, w, h, dv);
        for (int a = 0; a < 3; a++)
            k->dir[a] += e * dv[a];
        k->energy += e;
    }
    for (int j = 0; j < ncomp; j++) {
        double l = sqrt(c[j].dir[0] * c[j].dir[0] + c[j].dir[1] * c[j].dir[1] +
                        c[j].dir[2] * c[j].dir[2]);
        for (int a = 0; a < 3; a++)
            c[j].dir[a] = l > 0 ? c[j].dir[a] / l : (a == 2);
        parent[j] = j;
    }
    /* Half the texel's angular diagonal, so a one-texel fragment has a size. */
    double half_texel = 0.5 * hypot(2 * M_PI / w, M_PI / h);
    for (size_t i = 0; i < n; i++) {
        if (!labels[i])
            continue;
        comp *k = &c[labels[i] - 1];
        rig_texel_dir((int)(i % (size_t)w), (int)(i / (size_t)w), w, h, dv);
        double a = angle_between(k->dir, dv) + half_texel;
        if (a > k->radius)
            k->radius = a;
    }
    /* Candidate pairs by bounding caps, then the exact gap between their
     * outline texels (centre distance less one texel). */
    int *bstart = calloc((size_t)ncomp + 1, sizeof *bstart);
    double *bdir = NULL;
    size_t nb = 0;
    if (!bstart)
        goto nomem;
    for (int pass = 0; pass < 2; pass++) {
        int *fill = pass ? calloc((size_t)ncomp, sizeof *fill) : NULL;
        if (pass && !fill)
            goto nomem;
        for (size_t i = 0; i < n; i++) {
            if (!labels[i])
                continue;
            int x = (int)(i % (size_t)w), y = (int)(i / (size_t)w), nx[8], ny[8];
            int k = neighbours(x, y, w, h, nx, ny);
            bool edge = false;
            for (int j = 0; j < k && !edge; j++)
                edge = labels[(size_t)ny[j] * w + nx[j]] != labels[i];
            if (!edge)
                continue;
            int l = labels[i] - 1;
            if (!pass) {
                bstart[l + 1]++;
                nb++;
            } else {
                rig_texel_dir(x, y, w, h, &bdir[3 * (size_t)(bstart[l] + fill[l]++)]);
            }
        }
        free(fill);
        if (!pass) {
            for (int j = 0; j < ncomp; j++)
                bstart[j + 1] += bstart[j];
            bdir = malloc((nb ? nb : 1) * 3 * sizeof *bdir);
            if (!bdir)
                goto nomem;
        }
    }
    double texel = M_PI / h;
    for (int a = 0; a < ncomp; a++)
        for (int b = a + 1; b < ncomp; b++) {
            double gap = angle_between(c[a].dir, c[b].dir) - c[a].radius - c[b].radius;
            if (gap >= merge_rad)
                continue;
            int ra = uf_find(parent, a), rb = uf_find(parent, b);
            if (ra == rb)
                continue;
            double best = INFINITY;
            for (int i = bstart[a]; i < bstart[a + 1] && best - texel >= merge_rad; i++)
                for (int j = bstart[b]; j < bstart[b + 1]; j++) {
                    double g = angle_between(&bdir[3 * (size_t)i], &bdir[3 * (size_t)j]);
                    best = g < best ? g : best;
                }
            if (best - texel < merge_rad)
                parent[ra > rb ? ra : rb] = ra < rb ? ra : rb;
        }
    free(bstart);
    free(bdir);
    bstart = NULL;
    bdir = NULL;
    /* Renumber roots 1..count in order of first appearance. */
    int *newid = calloc((size_t)ncomp, sizeof *newid);
    if (!newid)
        goto nomem;
    int m = 0;
    for (size_t i = 0; i < n; i++) {
        if (!labels[i])
            continue;
        int r = uf_find(parent, labels[i] - 1);
        if (!newid[r])
            newid[r] = ++m;
        labels[i] = newid[r];
    }

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
    free(newid);
    free(queue);
    free(c);
    free(parent);
    return SL_OK;
nomem:
    free(bstart);
    free(bdir);
    free(queue);
    free(c);
    free(parent);
    return sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (%d regions)", ncomp);
}
