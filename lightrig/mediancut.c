/* SPDX-License-Identifier: BSD-3-Clause */
/* Median cut (Debevec 2005, "A Median Cut Algorithm for Light Probe
 * Sampling"): the lat-long is cut into regions of equal luminous energy,
 * always across the longer side (width measured times cos(latitude)); each
 * region becomes one light at its energy centroid carrying the region's
 * whole integral. The baseline for comparison: the dome is left black. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "lightrig_private.h"

typedef struct box {
    int x0, y0, x1, y1; /* [x0, x1) x [y0, y1) */
    double energy;
} box;

/* Summed-area table of luminance x solid angle, (w+1) x (h+1). */
static double sat_sum(const double *s, int w, const box *b)
{
    size_t W = (size_t)w + 1;
    return s[(size_t)b->y1 * W + b->x1] - s[(size_t)b->y0 * W + b->x1] -
           s[(size_t)b->y1 * W + b->x0] + s[(size_t)b->y0 * W + b->x0];
}

static int cmp_box(const void *a, const void *b)
{
    const box *x = a, *y = b;
    return (x->energy < y->energy) - (x->energy > y->energy);
}

/* Splits b at the energy median of its longer side; false if it is one texel. */
static bool split_box(const double *s, int w, int h, const box *b, box *lo, box *hi)
{
    int bw = b->x1 - b->x0, bh = b->y1 - b->y0;
    if (bw < 2 && bh < 2)
        return false;
    double lat = M_PI * (0.5 - 0.5 * (b->y0 + b->y1) / h);
    bool cut_x = bh < 2 || (bw >= 2 && bw * (2 * M_PI / w) * cos(lat) > bh * (M_PI / h));
    *lo = *b;
    *hi = *b;
    int a0 = cut_x ? b->x0 : b->y0, a1 = cut_x ? b->x1 : b->y1, best = a0 + 1;
    double half = 0.5 * b->energy;
    for (int m = a0 + 1; m < a1; m++) {
        box t = *b;
        if (cut_x)
            t.x1 = m;
        else
            t.y1 = m;
        best = m;
        if (sat_sum(s, w, &t) >= half)
            break;
    }
    if (cut_x) {
        lo->x1 = best;
        hi->x0 = best;
    } else {
        lo->y1 = best;
        hi->y0 = best;
    }
    lo->energy = sat_sum(s, w, lo);
    hi->energy = sat_sum(s, w, hi);
    return true;
}

sl_result rig_mediancut(const sl_image *rgb, const sl_rig_options *opt, sl_rig *rig,
                        sl_error *err)
{
    int w = rgb->width, h = rgb->height, n = opt->max_lights;
    size_t W = (size_t)w + 1;
    double *s = calloc(W * ((size_t)h + 1), sizeof *s);
    box *boxes = calloc((size_t)n, sizeof *boxes);
    box *next = calloc((size_t)n, sizeof *next);
    rig->lights = calloc((size_t)n, sizeof *rig->lights);
    sl_result r = SL_OK;
    if (!s || !boxes || !next || !rig->lights) {
        r = sl_error_set(err, SL_ERR_NOMEM, "lightrig: out of memory (median cut, %d lights)", n);
        goto out;
    }
    for (int y = 0; y < h; y++) {
        double om = sl_latlong_texel_solid_angle(y, w, h), row = 0;
        for (int x = 0; x < w; x++) {
            const float *p = sl_image_pixel(rgb, x, y);
            double v[3] = {p[0], p[1], p[2]};
            row += sl_luminance(v) * om;
            s[(size_t)(y + 1) * W + x + 1] = s[(size_t)y * W + x + 1] + row;
        }
    }
    int count = 1;
    boxes[0] = (box){0, 0, w, h, 0};
    boxes[0].energy = sat_sum(s, w, &boxes[0]);
    /* Levels of Debevec's cut; when n is not a power of two the last level
     * splits the most energetic regions first. */
    while (count < n) {
        qsort(boxes, (size_t)count, sizeof *boxes, cmp_box);
        int m = 0, before = count;
        for (int i = 0; i < before; i++) {
            box lo, hi;
            if (count < n && split_box(s, w, h, &boxes[i], &lo, &hi)) {
                next[m++] = lo;
                next[m++] = hi;
                count++;
            } else {
                next[m++] = boxes[i];
            }
        }
        memcpy(boxes, next, (size_t)m * sizeof *boxes);
        if (count == before)
            break; /* every region is one texel */
    }
    qsort(boxes, (size_t)count, sizeof *boxes, cmp_box);
    double total = 0;
    for (int i = 0; i < count; i++)
        total += boxes[i].energy;
    for (int i = 0; i < count; i++) {
        sl_rig_light *L = &rig->lights[i];
        sl_ksum integ[3] = {{0}};
        double d[3] = {0, 0, 0}, dv[3], om_sum = 0;
        for (int y = boxes[i].y0; y < boxes[i].y1; y++) {
            double om = sl_latlong_texel_solid_angle(y, w, h);
            for (int x = boxes[i].x0; x < boxes[i].x1; x++) {
                const float *p = sl_image_pixel(rgb, x, y);
                double v[3] = {p[0], p[1], p[2]}, e = sl_luminance(v) * om;
                for (int c = 0; c < 3; c++)
                    sl_ksum_add(&integ[c], v[c] * om);
                rig_texel_dir(x, y, w, h, dv);
                for (int a = 0; a < 3; a++)
                    d[a] += (e > 0 ? e : om * 1e-30) * dv[a];
                om_sum += om;
                rig->labels[(size_t)y * w + x] = i + 1;
            }
        }
        double l = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
        for (int a = 0; a < 3; a++)
            L->direction[a] = l > 0 ? d[a] / l : (a == 2);
        /* a frame for the USD transform */
        double helper[3] = {0, 1, 0};
        if (fabs(L->direction[1]) > 0.9) {
            helper[0] = 1;
            helper[1] = 0;
        }
        double *dd = L->direction, *au = L->axis_u, *av = L->axis_v;
        au[0] = helper[1] * dd[2] - helper[2] * dd[1];
        au[1] = helper[2] * dd[0] - helper[0] * dd[2];
        au[2] = helper[0] * dd[1] - helper[1] * dd[0];
        double la = sqrt(au[0] * au[0] + au[1] * au[1] + au[2] * au[2]);
        for (int a = 0; a < 3; a++)
            au[a] /= la;
        av[0] = dd[1] * au[2] - dd[2] * au[1];
        av[1] = dd[2] * au[0] - dd[0] * au[2];
        av[2] = dd[0] * au[1] - dd[1] * au[0];
        L->shape = SL_RIG_DISTANT;
        L->solid_angle = om_sum;
        double rr = acos(1 - fmin(om_sum, 4 * M_PI) / (2 * M_PI));
        L->angular_size[0] = L->angular_size[1] = 2 * rr;
        for (int c = 0; c < 3; c++) {
            L->integral[c] = sl_ksum_value(&integ[c]);
            L->radiance[c] = L->integral[c] / om_sum;
        }
        L->share = total > 0 ? boxes[i].energy / total : 0;
        L->texels = (boxes[i].x1 - boxes[i].x0) * (boxes[i].y1 - boxes[i].y0);
    }
    rig->light_count = count;
    /* All energy is in the lights. */
    sl_image_fill(&rig->residual, 0.0f);
out:
    free(s);
    free(boxes);
    free(next);
    return r;
}
