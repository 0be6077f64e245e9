/* SPDX-License-Identifier: BSD-3-Clause */
/* The views' log radiance for the solve's photometric steps (a view placed
 * by its overlaps' radiance, the lens refined by it): the features' copies
 * in ln luminance, reduced, and looked up along a world direction with the
 * vignetting removed. */
#include "stitch_private.h"

#include <math.h>
#include <stdlib.h>

/* ln luminance of a view's features' copy (NaN where not confident or
 * dark) reduced `factor` times by 2 x 2 means: NaN wherever the reduction
 * reaches such a pixel (an edge of the circle is not averaged into the
 * sky). */
bool solve_log_image_make(const solve_features *f, int factor, solve_log_image *out)
{
    int w = f->luminance.width, h = f->luminance.height;
    float *a = malloc((size_t)w * h * sizeof *a);
    out->log = NULL;
    if (!a)
        return false;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float l = *sl_image_pixel(&f->luminance, x, y);
            bool ok = l > 0.0f && *sl_image_pixel(&f->confidence, x, y) >= 0.99f;
            a[(size_t)y * w + x] = ok ? logf(l) : NAN;
        }
    double scale = f->scale;
    for (int k = 1; k < factor && w >= 32 && h >= 32; k *= 2) {
        int hw = w / 2, hh = h / 2;
        for (int y = 0; y < hh; y++)
            for (int x = 0; x < hw; x++) {
                const float *p = a + (size_t)(2 * y) * w + 2 * x;
                a[(size_t)y * hw + x] = 0.25f * (p[0] + p[1] + p[w] + p[w + 1]);
            }
        /* 2 hw pixels of the old rows are the new hw: the image stays in
         * place (each new row is written after the rows it reads from). */
        w = hw, h = hh;
        scale *= 2.0;
    }
    out->log = a;
    out->width = w;
    out->height = h;
    out->scale = scale;
    return true;
}

/* Bilinear ln radiance at full-resolution (x, y); false off the data or on
 * a hard edge (a 2 x 2 cell spanning more than edge_log). */
static bool log_at(const solve_log_image *l, double x, double y, double edge_log, double *out)
{
    double u = x / l->scale - 0.5, v = y / l->scale - 0.5;
    int x0 = (int)floor(u), y0 = (int)floor(v);
    if (x0 < 0 || y0 < 0 || x0 + 1 >= l->width || y0 + 1 >= l->height)
        return false;
    const float *p = l->log + (size_t)y0 * l->width + x0;
    double a = p[0], b = p[1], c = p[l->width], d = p[l->width + 1];
    double lo = fmin(fmin(a, b), fmin(c, d)), hi = fmax(fmax(a, b), fmax(c, d));
    if (!(hi - lo <= edge_log)) /* NaN fails too */
        return false;
    double fx = u - x0, fy = v - y0;
    *out = (1 - fy) * ((1 - fx) * a + fx * b) + fy * ((1 - fx) * c + fx * d);
    return true;
}

bool solve_log_radiance(const solve_log_image *l, const sl_lens *lens, const sl_lens *inner,
                        const double rot[3][3], const double d[3], double edge_log, double *out)
{
    double c[3], x, y, v;
    solve_to_camera(rot, d, c);
    if (!sl_lens_ray_to_pixel(inner, c, &x, &y) || !log_at(l, x, y, edge_log, &v))
        return false;
    double g = sl_lens_vignette(lens, x, y);
    if (!(g > 0.0))
        return false;
    *out = v - log(g);
    return true;
}
