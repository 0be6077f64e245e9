/* SPDX-License-Identifier: BSD-3-Clause */
/* Two photos of one ball merged into one lat-long: view 2's azimuth refined
 * from the overlap, each texel weighted by the views' confidences, and the
 * camera and photographer reflected at each ball's centre left to the other
 * view. */
#include "unwrap_private.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

/* Overlap: both confidences at least this. */
#define OVERLAP_CONF 0.25
/* Width of the lat-long the azimuth is searched on: twice the views' own
 * resolution (the golden section then resolves a small fraction of a
 * texel), within these bounds. */
#define SEARCH_WIDTH_MIN 256
#define SEARCH_WIDTH_MAX 720
/* Log ratios beyond this (a factor 1.65) count as this much: a moved
 * object or a reflection of the other camera does not pull the fit. */
#define LOG_CLAMP 0.5
/* Weight a view keeps inside its own occluder cone, so that it still fills
 * what the other view does not see. */
#define OCCLUDED_WEIGHT 1e-3

/* Direction from the ball toward the camera, in the set. */
static void camera_dir(const sl_ball_view *v, double out[3])
{
    double axis_cam[3] = {v->view_to_cam[0][2], v->view_to_cam[1][2], v->view_to_cam[2][2]}, w[3];
    sl_mat3_apply(v->cam_to_world, axis_cam, w);
    for (int k = 0; k < 3; k++)
        out[k] = -w[k];
}

/* 0 inside the occluder cone, 1 beyond 1.5 times its angle, smooth between. */
static double occluder_weight(const double d[3], const double cam[3], double occ_rad)
{
    if (!(occ_rad > 0.0))
        return 1.0;
    double c = d[0] * cam[0] + d[1] * cam[1] + d[2] * cam[2];
    double a = acos(c > 1.0 ? 1.0 : (c < -1.0 ? -1.0 : c));
    double t = (a - occ_rad) / (0.5 * occ_rad);
    t = t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t);
    return t * t * (3.0 - 2.0 * t);
}

static double log_lum(const float *p, double eps)
{
    return log(sl_luminance_px(p) + eps);
}

typedef struct search_ctx {
    int w, h;
    int n;           /* texels of view 1 in the search */
    int *idx;        /* their y * w + x */
    double *weight;  /* solid angle */
    double *la;      /* view 1's log luminance */
    float *lb, *cb;  /* view 2's log luminance and confidence, whole map */
} search_ctx;

/* View 2 turned by s degrees of azimuth: a turn about +Y adds s to the
 * longitude, so view 2's texel for (x, y) lies s / 360 of the width to the
 * right. Writes |log ratio| (clamped) per overlapping texel when out != NULL. */
static double search_cost(const search_ctx *c, double s_deg, double *out, int *count,
                          double *overlap)
{
    double shift = s_deg / 360.0 * c->w, sum = 0.0, wsum = 0.0;
    int m = 0;
    for (int i = 0; i < c->n; i++) {
        int y = c->idx[i] / c->w, x = c->idx[i] % c->w;
        double xb = x + shift;
        xb -= c->w * floor(xb / c->w);
        int x0 = (int)xb, x1 = x0 + 1 < c->w ? x0 + 1 : 0;
        double t = xb - x0;
        const float *lb = c->lb + (size_t)y * c->w, *cb = c->cb + (size_t)y * c->w;
        double conf = cb[x0] + t * (cb[x1] - cb[x0]);
        if (conf < OVERLAP_CONF)
            continue;
        double d = fabs(c->la[i] - (lb[x0] + t * (lb[x1] - lb[x0])));
        d = d > LOG_CLAMP ? LOG_CLAMP : d;
        sum += c->weight[i] * d;
        wsum += c->weight[i];
        if (out)
            out[m] = d;
        m++;
    }
    if (count)
        *count = m;
    if (overlap)
        *overlap = wsum;
    /* No overlap at all is the worst fit. */
    return wsum > 0.0 ? sum / wsum : LOG_CLAMP;
}

static double median_cost(const search_ctx *c, double s_deg, double *scratch, double *overlap)
{
    int m = 0;
    search_cost(c, s_deg, scratch, &m, overlap);
    if (!m)
        return NAN;
    qsort(scratch, (size_t)m, sizeof(double), sl_cmp_double);
    return m % 2 ? scratch[m / 2] : 0.5 * (scratch[m / 2 - 1] + scratch[m / 2]);
}

/* Finds view 2's azimuth offset on small unwraps of both views. */
static sl_result refine_azimuth(const sl_image *p1, const sl_image *p2,
                                const sl_unwrap_pair_options *opt, int width, double *best_deg,
                                sl_unwrap_pair_info *info, sl_error *err)
{
    sl_unwrap_options o1 = opt->views[0], o2 = opt->views[1];
    width = 2 * ((width + 1) / 2);
    width = width < SEARCH_WIDTH_MIN ? SEARCH_WIDTH_MIN
                                     : (width > SEARCH_WIDTH_MAX ? SEARCH_WIDTH_MAX : width);
    o1.width = o2.width = width;
    o1.no_confidence = o2.no_confidence = false;
    sl_image a = {0}, b = {0};
    search_ctx c = {.w = width, .h = width / 2};
    size_t n = (size_t)c.w * c.h;
    double *scratch = NULL;
    sl_result r;
    if ((r = sl_unwrap(p1, &o1, &a, NULL, err)) || (r = sl_unwrap(p2, &o2, &b, NULL, err)))
        goto done;
    c.idx = malloc(sizeof(int) * n);
    c.weight = malloc(sizeof(double) * n);
    c.la = malloc(sizeof(double) * n);
    c.lb = malloc(sizeof(float) * n);
    c.cb = malloc(sizeof(float) * n);
    scratch = malloc(sizeof(double) * n);
    if (!c.idx || !c.weight || !c.la || !c.lb || !c.cb || !scratch) {
        r = sl_error_set(err, SL_ERR_NOMEM, "unwrap: out of memory");
        goto done;
    }
    sl_ball_view v1, v2;
    if ((r = sl_ball_view_init(&v1, p1->width, p1->height, &o1.circle, &o1.geometry, err)) ||
        (r = sl_ball_view_init(&v2, p2->width, p2->height, &o2.circle, &o2.geometry, err)))
        goto done;
    double cam1[3], cam2[3], occ = opt->occluder_deg * M_PI / 180.0;
    camera_dir(&v1, cam1);
    camera_dir(&v2, cam2);
    /* Luminance floor: a thousandth of view 1's mean, so black texels do not
     * dominate the log ratios. */
    double mean = 0.0, msum = 0.0;
    for (int y = 0; y < c.h; y++)
        for (int x = 0; x < c.w; x++) {
            const float *p = sl_image_pixel(&a, x, y);
            double wt = sl_latlong_texel_solid_angle(y, c.w, c.h) * p[3];
            mean += wt * sl_luminance_px(p);
            msum += wt;
        }
    double eps = msum > 0.0 ? 1e-3 * mean / msum : 1e-6;
    eps = eps > 0.0 ? eps : 1e-6;
    for (int y = 0; y < c.h; y++)
        for (int x = 0; x < c.w; x++) {
            const float *pa = sl_image_pixel(&a, x, y), *pb = sl_image_pixel(&b, x, y);
            c.lb[(size_t)y * c.w + x] = (float)log_lum(pb, eps);
            c.cb[(size_t)y * c.w + x] = pb[3];
            double d[3];
            sl_latlong_to_dir((x + 0.5) / c.w, (y + 0.5) / c.h, d);
            if (pa[3] < OVERLAP_CONF || occluder_weight(d, cam1, occ) < 1.0 ||
                occluder_weight(d, cam2, occ + opt->search_deg * M_PI / 180.0) < 1.0)
                continue;
            c.idx[c.n] = y * c.w + x;
            c.weight[c.n] = sl_latlong_texel_solid_angle(y, c.w, c.h);
            c.la[c.n] = log_lum(pa, eps);
            c.n++;
        }
    /* Coarse scan at half a texel, then golden section around the best. */
    double step = 0.5 * 360.0 / c.w, best = 0.0, best_cost = search_cost(&c, 0.0, NULL, NULL, NULL);
    int steps = (int)ceil(opt->search_deg / step);
    for (int i = -steps; i <= steps; i++) {
        double s = i * step * (opt->search_deg / (steps * step));
        double cost = search_cost(&c, s, NULL, NULL, NULL);
        if (cost < best_cost) {
            best_cost = cost;
            best = s;
        }
    }
    const double g = 0.5 * (sqrt(5.0) - 1.0);
    double lo = best - step, hi = best + step;
    double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
    double f1 = search_cost(&c, x1, NULL, NULL, NULL), f2 = search_cost(&c, x2, NULL, NULL, NULL);
    for (int it = 0; it < 30; it++) {
        if (f1 < f2) {
            hi = x2;
            x2 = x1;
            f2 = f1;
            x1 = hi - g * (hi - lo);
            f1 = search_cost(&c, x1, NULL, NULL, NULL);
        } else {
            lo = x1;
            x1 = x2;
            f1 = f2;
            x2 = lo + g * (hi - lo);
            f2 = search_cost(&c, x2, NULL, NULL, NULL);
        }
    }
    double fine = 0.5 * (lo + hi);
    if (search_cost(&c, fine, NULL, NULL, NULL) <= best_cost)
        best = fine;
    *best_deg = best;
    if (info) {
        double overlap = 0.0;
        info->residual_given = median_cost(&c, 0.0, scratch, NULL);
        info->residual = median_cost(&c, best, scratch, &overlap);
        info->overlap_fraction = overlap / (4.0 * M_PI);
    }
done:
    sl_image_free(&a);
    sl_image_free(&b);
    free(c.idx);
    free(c.weight);
    free(c.la);
    free(c.lb);
    free(c.cb);
    free(scratch);
    return r;
}

typedef struct merge_ctx {
    sl_image *a;
    const sl_image *b;
    double cam1[3], cam2[3], occ;
} merge_ctx;

static void merge_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    const merge_ctx *m = ctx;
    int w = m->a->width, h = m->a->height;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < w; x++) {
            float *pa = sl_image_pixel(m->a, x, (int)y);
            const float *pb = sl_image_pixel(m->b, x, (int)y);
            double d[3];
            sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / h, d);
            double wa = pa[3] * (occluder_weight(d, m->cam1, m->occ) + OCCLUDED_WEIGHT);
            double wb = pb[3] * (occluder_weight(d, m->cam2, m->occ) + OCCLUDED_WEIGHT);
            if (!(wa + wb > 0.0)) {
                /* Neither view sees it: both hold a flat fill from their rims. */
                for (int k = 0; k < 3; k++)
                    pa[k] = 0.5f * (pa[k] + pb[k]);
                pa[3] = 0.0f;
                continue;
            }
            double s = 1.0 / (wa + wb);
            for (int k = 0; k < 4; k++)
                pa[k] = (float)((wa * pa[k] + wb * pb[k]) * s);
        }
}

sl_result sl_unwrap_pair(const sl_image *photo1, const sl_image *photo2,
                         const sl_unwrap_pair_options *opt, sl_image *out,
                         sl_unwrap_pair_info *info, sl_error *err)
{
    memset(out, 0, sizeof *out);
    if (info)
        memset(info, 0, sizeof *info);
    if (!photo1 || !photo2 || !opt)
        return sl_error_set(err, SL_ERR_USAGE, "unwrap: two photos needed");
    if (!(opt->search_deg >= 0.0 && opt->search_deg <= 90.0) ||
        !(opt->occluder_deg >= 0.0 && opt->occluder_deg <= 60.0))
        return sl_error_set(err, SL_ERR_USAGE,
                            "azimuth search must be 0-90 deg and the occluder cone 0-60 deg");
    sl_unwrap_options o[2] = {opt->views[0], opt->views[1]};
    o[0].no_confidence = o[1].no_confidence = false;
    sl_ball_view v[2];
    const sl_image *photos[2] = {photo1, photo2};
    sl_result r;
    for (int i = 0; i < 2; i++)
        if ((r = sl_ball_view_init(&v[i], photos[i]->width, photos[i]->height, &o[i].circle,
                                   &o[i].geometry, err)))
            return r;
    if (o[0].width != o[1].width) {
        if (o[0].width && o[1].width)
            return sl_error_set(err, SL_ERR_USAGE, "both views need the same lat-long width");
        o[0].width = o[1].width = o[0].width | o[1].width;
    }
    int w0 = unwrap_auto_width(&v[0]), w1 = unwrap_auto_width(&v[1]);
    int own = w0 > w1 ? w0 : w1;
    if (!o[0].width)
        o[0].width = o[1].width = own;
    double offset = 0.0;
    if (info) {
        info->azimuth_given_deg = o[1].geometry.azimuth_deg;
        info->residual_given = info->residual = info->overlap_fraction = NAN;
    }
    if (opt->search_deg > 0.0) {
        if ((r = refine_azimuth(photo1, photo2, opt, 2 * own, &offset, info, err)))
            return r;
        o[1].geometry.azimuth_deg += offset;
        if ((r = sl_ball_view_init(&v[1], photo2->width, photo2->height, &o[1].circle,
                                   &o[1].geometry, err)))
            return r;
    }
    if (info)
        info->azimuth_deg = o[1].geometry.azimuth_deg;

    sl_image b = {0};
    if ((r = sl_unwrap(photo1, &o[0], out, info ? &info->views[0] : NULL, err)) ||
        (r = sl_unwrap(photo2, &o[1], &b, info ? &info->views[1] : NULL, err))) {
        sl_image_free(out);
        return r;
    }
    merge_ctx m = {.a = out, .b = &b, .occ = opt->occluder_deg * M_PI / 180.0};
    camera_dir(&v[0], m.cam1);
    camera_dir(&v[1], m.cam2);
    sl_parallel_for(out->height, 16, merge_rows, &m);
    sl_image_free(&b);
    return SL_OK;
}
