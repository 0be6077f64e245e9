/* SPDX-License-Identifier: BSD-3-Clause */
/* Sub-pixel refinement of the solve's matches. A SIFT keypoint is where a
 * blob's scale-space extremum is, and a fisheye squeezes the same blob
 * differently in two views (radially by cos(theta/2) in an equisolid
 * lens), so the two keypoints are a few tenths of a pixel apart even when
 * the geometry is exact. Once the geometry is close, view b's patch warped
 * into view a (the local affine of the mapping) is a template that
 * Lucas-Kanade finds to a hundredth of a pixel in view a. */
#include "merge_private.h"
#include "stitch_private.h"

#include <math.h>

enum { HALF = 7 }; /* the patch: (2 HALF + 1)^2 samples */

/* Natural log of the luminance at full-resolution position (x, y),
 * bilinear; false off the image or where a sample is not positive. */
static bool log_luminance(const sl_image *img, double x, double y, double *out)
{
    double u = x - 0.5, v = y - 0.5;
    int x0 = (int)floor(u), y0 = (int)floor(v);
    if (x0 < 0 || y0 < 0 || x0 + 1 >= img->width || y0 + 1 >= img->height)
        return false;
    double fx = u - x0, fy = v - y0, l[4];
    for (int k = 0; k < 4; k++) {
        const float *p = sl_image_pixel(img, x0 + (k & 1), y0 + (k >> 1));
        l[k] = img->channels >= 3 ? sl_luminance_px(p) : p[0];
        if (!(l[k] > 0.0) || !isfinite(l[k]))
            return false;
    }
    double lum = (1 - fy) * ((1 - fx) * l[0] + fx * l[1]) + fy * ((1 - fx) * l[2] + fx * l[3]);
    *out = log(lum);
    return true;
}

static bool refine_one(const sl_stitch_view *views, solve_match *m, double (*rot)[3][3],
                       const sl_lens *u, double step)
{
    const sl_image *ia = views[m->a].radiance, *ib = views[m->b].radiance;
    double pred[2], right[2], down[2], base[2];
    if (!solve_transfer(u, rot[m->b], rot[m->a], m->pb, pred) ||
        !solve_transfer(u, rot[m->a], rot[m->b], pred, base))
        return false;
    double pr[2] = {pred[0] + step, pred[1]}, pd[2] = {pred[0], pred[1] + step};
    if (!solve_transfer(u, rot[m->a], rot[m->b], pr, right) ||
        !solve_transfer(u, rot[m->a], rot[m->b], pd, down))
        return false;
    /* Template: view b sampled at the points of view a's patch. */
    enum { N = (2 * HALF + 1) * (2 * HALF + 1) };
    double t[N], wgt[N], mean_t = 0.0, wsum = 0.0;
    for (int j = -HALF, k = 0; j <= HALF; j++)
        for (int i = -HALF; i <= HALF; i++, k++) {
            double x = m->pb[0] + i * (right[0] - base[0]) + j * (down[0] - base[0]);
            double y = m->pb[1] + i * (right[1] - base[1]) + j * (down[1] - base[1]);
            if (!log_luminance(ib, x, y, &t[k]))
                return false;
            wgt[k] = exp(-(i * i + j * j) / (0.5 * HALF * HALF));
            mean_t += wgt[k] * t[k];
            wsum += wgt[k];
        }
    mean_t /= wsum;
    /* Gauss-Newton on the shift d and a log gain that may vary linearly
     * across the patch: the views' exposures differ by a constant, their
     * vignetting by a slope that would otherwise pull a soft feature. */
    double d[2] = {0.0, 0.0}, gain[3] = {0.0, 0.0, 0.0}, tangent[2] = {0.0, 0.0};
    bool edge = false;
    for (int it = 0; it < 20; it++) {
        double a[25] = {0}, g[5] = {0};
        for (int j = -HALF, k = 0; j <= HALF; j++)
            for (int i = -HALF; i <= HALF; i++, k++) {
                double x = pred[0] + d[0] + i * step, y = pred[1] + d[1] + j * step;
                double l, lx0, lx1, ly0, ly1;
                if (!log_luminance(ia, x, y, &l) || !log_luminance(ia, x - 0.5, y, &lx0) ||
                    !log_luminance(ia, x + 0.5, y, &lx1) || !log_luminance(ia, x, y - 0.5, &ly0) ||
                    !log_luminance(ia, x, y + 0.5, &ly1))
                    return false;
                double qi = (double)i / HALF, qj = (double)j / HALF;
                double jac[5] = {lx1 - lx0, ly1 - ly0, -1.0, -qi, -qj};
                double r = l - t[k] - gain[0] - gain[1] * qi - gain[2] * qj;
                for (int p = 0; p < 5; p++) {
                    g[p] += wgt[k] * jac[p] * r;
                    for (int q = 0; q < 5; q++)
                        a[p * 5 + q] += wgt[k] * jac[p] * jac[q];
                }
            }
        /* Along an edge (a panel's border, the horizon) the shift is free in
         * one direction: when the smaller gradient eigenvalue is under a
         * tenth of the larger, the point moves only across the edge, and
         * the adjustment weighs its residual across the edge only. */
        double tr = a[0] + a[6], det = a[0] * a[6] - a[1] * a[5];
        double disc = sqrt(fmax(0.0, 0.25 * tr * tr - det));
        double big = 0.5 * tr + disc, small = 0.5 * tr - disc;
        if (it == 0 && !(small > 0.1 * big)) {
            if (!(big > 0.0))
                return false;
            /* the eigenvector of the smaller eigenvalue: the edge's direction */
            double ex = a[1], ey = small - a[0];
            if (fabs(a[1]) < 1e-12 * big) {
                ex = a[0] < a[6] ? 1.0 : 0.0;
                ey = 1.0 - ex;
            }
            double len = hypot(ex, ey);
            tangent[0] = ex / len;
            tangent[1] = ey / len;
            edge = true;
        }
        if (edge) {
            double lambda = 1e3 * big;
            for (int p = 0; p < 2; p++) {
                for (int q = 0; q < 2; q++)
                    a[p * 5 + q] += lambda * tangent[p] * tangent[q];
                g[p] += lambda * tangent[p] * (tangent[0] * d[0] + tangent[1] * d[1]);
            }
        }
        if (!merge_cholesky_solve(a, g, 5))
            return false;
        d[0] -= g[0];
        d[1] -= g[1];
        for (int p = 0; p < 3; p++)
            gain[p] -= g[2 + p];
        if (hypot(d[0], d[1]) > 3.0 * step)
            return false;
        if (hypot(g[0], g[1]) < 1e-4)
            break;
    }
    /* The patches must look alike (normalised correlation), else the
     * shift is fitted noise. */
    double sa = 0.0, saa = 0.0, stt = 0.0, sat = 0.0, la[N];
    for (int j = -HALF, k = 0; j <= HALF; j++)
        for (int i = -HALF; i <= HALF; i++, k++) {
            if (!log_luminance(ia, pred[0] + d[0] + i * step, pred[1] + d[1] + j * step, &la[k]))
                return false;
            sa += wgt[k] * la[k];
        }
    sa /= wsum;
    for (int k = 0; k < N; k++) {
        saa += wgt[k] * (la[k] - sa) * (la[k] - sa);
        stt += wgt[k] * (t[k] - mean_t) * (t[k] - mean_t);
        sat += wgt[k] * (la[k] - sa) * (t[k] - mean_t);
    }
    if (!(saa > 0.0 && stt > 0.0) || sat / sqrt(saa * stt) < 0.9)
        return false;
    m->pa[0] = pred[0] + d[0];
    m->pa[1] = pred[1] + d[1];
    m->normal[0] = edge ? -tangent[1] : 0.0;
    m->normal[1] = edge ? tangent[0] : 0.0;
    return true;
}

int solve_refine_matches(const sl_stitch_view *views, solve_match *matches, int count,
                         double (*rot)[3][3], const sl_lens *lens, double step_px)
{
    sl_lens u;
    solve_lens_unbounded(lens, &u);
    int refined = 0;
    for (int i = 0; i < count; i++) {
        if (!matches[i].inlier)
            continue;
        matches[i].inlier = refine_one(views, &matches[i], rot, &u, step_px);
        refined += matches[i].inlier;
    }
    return refined;
}
