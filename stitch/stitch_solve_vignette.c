/* SPDX-License-Identifier: BSD-3-Clause */
/* The vignetting of the solved lens: the ratio of two views' radiance at
 * the same direction is the ratio of their falloffs there (times a per-view
 * gain), so V(s) = 1 + v1 s^2 + v2 s^4 and the gains come from a robust
 * least-squares fit of the log ratios at directions both views see. */
#include "merge_private.h"
#include "stitch_private.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { DIRECTIONS = 40000, MIN_SAMPLES = 200 };

typedef struct ratio_sample {
    int a, b;
    double sa2, sb2; /* (r / f)^2 in each view */
    double log_ratio; /* ln L_a - ln L_b */
} ratio_sample;

/* Bilinear luminance at full-resolution (x, y); false near an edge (a
 * misregistered edge is not a falloff), where the merge was not confident,
 * or dark. */
static bool smooth_sample(const solve_features *f, double x, double y, double dark, double *out)
{
    double u = x / f->scale - 0.5, v = y / f->scale - 0.5;
    int x0 = (int)floor(u), y0 = (int)floor(v);
    if (x0 < 1 || y0 < 1 || x0 + 2 >= f->luminance.width || y0 + 2 >= f->luminance.height)
        return false;
    double lo = INFINITY, hi = -INFINITY;
    for (int j = -1; j <= 2; j++)
        for (int i = -1; i <= 2; i++) {
            double l = *sl_image_pixel(&f->luminance, x0 + i, y0 + j);
            if (*sl_image_pixel(&f->confidence, x0 + i, y0 + j) < 0.99f)
                return false;
            lo = l < lo ? l : lo;
            hi = l > hi ? l : hi;
        }
    if (!(lo > dark) || hi > 1.1 * lo)
        return false;
    double fx = u - x0, fy = v - y0;
    const sl_image *L = &f->luminance;
    *out = (1 - fy) * ((1 - fx) * *sl_image_pixel(L, x0, y0) + fx * *sl_image_pixel(L, x0 + 1, y0)) +
           fy * ((1 - fx) * *sl_image_pixel(L, x0, y0 + 1) + fx * *sl_image_pixel(L, x0 + 1, y0 + 1));
    return true;
}

static double median_luminance(const sl_image *l)
{
    size_t n = 0, total = (size_t)l->width * l->height;
    double *v = malloc(total * sizeof *v); /* float values */
    if (!v)
        return 0.0;
    for (int y = 0; y < l->height; y++)
        for (int x = 0; x < l->width; x++)
            if (*sl_image_pixel(l, x, y) > 0.0f)
                v[n++] = *sl_image_pixel(l, x, y);
    double m = n ? merge_select_kth(v, (int)n, (int)(n / 2)) : 0.0;
    free(v);
    return m;
}

static int collect(int count, const solve_features *feat,
                   double (*rot)[3][3], const sl_stitch_solve_result *res, const sl_lens *lens,
                   ratio_sample *out, int cap)
{
    double *dark = calloc((size_t)count, sizeof *dark);
    if (!dark)
        return 0;
    for (int v = 0; v < count; v++)
        dark[v] = 1e-3 * median_luminance(&feat[v].luminance) + 1e-12;
    sl_lens inner = *lens;
    if (inner.circle_radius_px > 0.0)
        inner.circle_radius_px *= 0.97;
    int n = 0;
    for (int i = 0; i < DIRECTIONS && n < cap; i++) {
        double d[3];
        solve_sphere_dir(i, DIRECTIONS, d);
        for (int p = 0; p < res->pairs && n < cap; p++) {
            const sl_stitch_pair *pr = &res->pair[p];
            if (pr->status != SL_STITCH_PAIR_SOLVED)
                continue;
            double px[2][2], lum[2];
            bool ok = true;
            int v[2] = {pr->a, pr->b};
            for (int s = 0; s < 2 && ok; s++) {
                double c[3];
                solve_to_camera((const double (*)[3])rot[v[s]], d, c);
                ok = sl_lens_ray_to_pixel(&inner, c, &px[s][0], &px[s][1]) &&
                     smooth_sample(&feat[v[s]], px[s][0], px[s][1], dark[v[s]], &lum[s]);
            }
            if (!ok)
                continue;
            double f2 = lens->focal_px * lens->focal_px;
            out[n].a = pr->a;
            out[n].b = pr->b;
            out[n].sa2 = (pow(px[0][0] - lens->cx, 2) + pow(px[0][1] - lens->cy, 2)) / f2;
            out[n].sb2 = (pow(px[1][0] - lens->cx, 2) + pow(px[1][1] - lens->cy, 2)) / f2;
            out[n].log_ratio = log(lum[0] / lum[1]);
            n++;
        }
    }
    free(dark);
    return n;
}

static double falloff(double v1, double v2, double s2)
{
    return 1.0 + s2 * (v1 + s2 * v2);
}

void solve_vignette(int count, const solve_features *feat, double (*rot)[3][3], sl_lens *lens,
                    sl_stitch_solve_result *res)
{
    int cap = DIRECTIONS * 2;
    ratio_sample *s = malloc((size_t)cap * sizeof *s);
    int n = s ? collect(count, feat, rot, res, lens, s, cap) : 0;
    res->vignette_samples = n;
    int np = 2 + (count - 1);
    double *jtj = malloc((size_t)np * np * sizeof *jtj), *jtr = malloc((size_t)np * sizeof *jtr);
    double *x = calloc((size_t)np, sizeof *x);
    if (n < MIN_SAMPLES || np > 64 || !jtj || !jtr || !x)
        goto done;
    /* x = (v1, v2, ln g_1 .. ln g_{count-1}); ln g_0 = 0. Gauss-Newton
     * with a Huber loss on the log ratio (0.05: 5% of radiance). */
    const double huber = 0.05;
    double s2_max = 0.0;
    for (int i = 0; i < n; i++) {
        s2_max = s[i].sa2 > s2_max ? s[i].sa2 : s2_max;
        s2_max = s[i].sb2 > s2_max ? s[i].sb2 : s2_max;
    }
    double sum_sq = 0.0, weights = 0.0;
    for (int it = 0; it < 30; it++) {
        memset(jtj, 0, (size_t)np * np * sizeof *jtj);
        memset(jtr, 0, (size_t)np * sizeof *jtr);
        sum_sq = weights = 0.0;
        for (int i = 0; i < n; i++) {
            double va = falloff(x[0], x[1], s[i].sa2), vb = falloff(x[0], x[1], s[i].sb2);
            if (!(va > 0.0 && vb > 0.0))
                continue;
            double ga = s[i].a ? x[1 + s[i].a] : 0.0, gb = s[i].b ? x[1 + s[i].b] : 0.0;
            double r = s[i].log_ratio - (log(va) - log(vb) + ga - gb);
            double w = fabs(r) <= huber ? 1.0 : huber / fabs(r);
            sum_sq += w * r * r;
            weights += w;
            double j[64] = {0};
            j[0] = s[i].sa2 / va - s[i].sb2 / vb;
            j[1] = s[i].sa2 * s[i].sa2 / va - s[i].sb2 * s[i].sb2 / vb;
            if (s[i].a)
                j[1 + s[i].a] += 1.0;
            if (s[i].b)
                j[1 + s[i].b] -= 1.0;
            for (int u = 0; u < np && u < 64; u++) {
                jtr[u] += w * j[u] * r;
                for (int v = 0; v < np && v < 64; v++)
                    jtj[u * np + v] += w * j[u] * j[v];
            }
        }
        /* A light ridge: v2 (and v1) stay put where the overlaps' radii
         * cannot tell them apart. */
        for (int u = 0; u < np; u++)
            jtj[u * np + u] += 1e-6 * n + 1e-9;
        if (!merge_cholesky_solve(jtj, jtr, np))
            goto done;
        double change = 0.0;
        for (int u = 0; u < np; u++) {
            x[u] += jtr[u];
            change += fabs(jtr[u]);
        }
        if (change < 1e-9)
            break;
    }
    /* The falloff must stay positive and finite over the field it was
     * measured on, else it is not a vignetting. */
    for (int k = 0; k <= 16; k++)
        if (!(falloff(x[0], x[1], s2_max * k / 16.0) > 0.05))
            goto done;
    lens->vignette[0] = x[0];
    lens->vignette[1] = x[1];
    lens->vignette[2] = 0.0;
    for (int v = 1; v < count; v++)
        res->gain[v] = exp(x[1 + v]);
    res->vignette_solved = true;
    res->vignette_rms_log = weights > 0.0 ? sqrt(sum_sq / weights) : 0.0;
done:
    free(s), free(jtj), free(jtr), free(x);
}
