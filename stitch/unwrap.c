/* SPDX-License-Identifier: BSD-3-Clause */
/* Chrome-ball photo to lat-long: per output texel, a solid-angle-weighted
 * average of the photo over the texel's footprint on the ball, divided by
 * the ball's reflectance, with a confidence from the mapping's resolution. */
#include "unwrap_private.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define SUB_MAX 16
#define RING_SAMPLES 720
/* Photo pixels whose centre lies closer than this to the outline mix ball
 * and background (anti-aliasing, blur, fit error); they are never read. */
#define RIM_MARGIN 0.7
/* Sample points are kept this far inside the outline. */
#define RIM_CLAMP 0.7

typedef struct unwrap_ctx {
    const sl_image *photo; /* 3 channels, finite */
    const sl_ball_view *view;
    const sl_reflectance *refl;
    sl_image *out;
    double blind_fill[3];
} unwrap_ctx;

/* Bilinear lookup of the ball's own pixels; returns false when the point had
 * to be pulled inside the rim margin. */
static bool photo_lookup(const unwrap_ctx *c, double x, double y, double out[3])
{
    const sl_ball_view *v = c->view;
    const sl_image *img = c->photo;
    bool inside = true;
    double dx = x - v->cx, dy = y - v->cy, d = sqrt(dx * dx + dy * dy), lim = v->r - RIM_CLAMP;
    if (d > lim) {
        x = v->cx + dx * lim / d;
        y = v->cy + dy * lim / d;
        inside = false;
    }
    double fx = x - 0.5, fy = y - 0.5;
    double x0 = floor(fx), y0 = floor(fy);
    double tx = fx - x0, ty = fy - y0;
    double acc[3] = {0, 0, 0}, wsum = 0.0, keep = v->r - RIM_MARGIN;
    for (int j = 0; j < 2; j++)
        for (int i = 0; i < 2; i++) {
            int xi = (int)x0 + i, yi = (int)y0 + j;
            double w = (i ? tx : 1.0 - tx) * (j ? ty : 1.0 - ty);
            if (w == 0.0 || xi < 0 || yi < 0 || xi >= img->width || yi >= img->height)
                continue;
            double ex = xi + 0.5 - v->cx, ey = yi + 0.5 - v->cy;
            if (ex * ex + ey * ey > keep * keep)
                continue;
            const float *p = sl_image_pixel(img, xi, yi);
            for (int k = 0; k < 3; k++)
                acc[k] += w * p[k];
            wsum += w;
        }
    if (wsum > 0.0) {
        for (int k = 0; k < 3; k++)
            out[k] = acc[k] / wsum;
    } else {
        int xi = (int)floor(x), yi = (int)floor(y);
        xi = xi < 0 ? 0 : (xi >= img->width ? img->width - 1 : xi);
        yi = yi < 0 ? 0 : (yi >= img->height ? img->height - 1 : yi);
        const float *p = sl_image_pixel(img, xi, yi);
        for (int k = 0; k < 3; k++)
            out[k] = p[k];
    }
    return inside;
}

/* Radiance seen in `dir`, and whether the photo really shows it. The blind
 * cone gets the median of the rim, flat: a rim pixel next to a bright source
 * must not be stretched over the whole cone, and no detail is invented. */
static bool radiance(const unwrap_ctx *c, const double dir[3], double out[3])
{
    ball_hit h;
    ball_view_map(c->view, dir, &h);
    if (h.blind) {
        memcpy(out, c->blind_fill, sizeof c->blind_fill);
        return false;
    }
    double refl[3];
    bool seen = photo_lookup(c, h.x, h.y, out);
    sl_reflectance_eval(c->refl, h.cos_incidence, refl);
    for (int k = 0; k < 3; k++)
        out[k] /= refl[k];
    return seen;
}

static void pixel_of(const unwrap_ctx *c, double u, double v, double xy[2])
{
    double d[3];
    ball_hit h;
    sl_latlong_to_dir(u, v < 0.0 ? 0.0 : (v > 1.0 ? 1.0 : v), d);
    ball_view_map(c->view, d, &h);
    xy[0] = h.x;
    xy[1] = h.y;
}

static double smaller_singular_value(const double j[2][2])
{
    double p = j[0][0] * j[0][0] + j[1][0] * j[1][0];
    double q = j[0][1] * j[0][1] + j[1][1] * j[1][1];
    double s = j[0][0] * j[0][1] + j[1][0] * j[1][1];
    double tr = 0.5 * (p + q), det = p * q - s * s;
    return sqrt(fmax(tr - sqrt(fmax(tr * tr - det, 0.0)), 0.0));
}

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static int sub_count(double extent_px)
{
    double n = ceil(2.0 * extent_px);
    return n < 2.0 ? 2 : (n > SUB_MAX ? SUB_MAX : (int)n);
}

static void unwrap_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    const unwrap_ctx *c = ctx;
    int w = c->out->width, h = c->out->height;
    double ref = c->view->centre_px_per_rad;
    for (int64_t y = begin; y < end; y++) {
        for (int x = 0; x < w; x++) {
            double uc = (x + 0.5) / w, vc = (y + 0.5) / h, dir[3];
            /* The texel's footprint in the photo: its extent sets the sampling,
             * and per radian (longitude and latitude steps are orthogonal on
             * the sphere) it is the mapping's Jacobian. */
            double a[2], b[2], j[2][2];
            pixel_of(c, uc - 0.5 / w, vc, a);
            pixel_of(c, uc + 0.5 / w, vc, b);
            int nu = sub_count(hypot(b[0] - a[0], b[1] - a[1]));
            double lon_step = 2.0 * M_PI / w * cos(M_PI * (0.5 - vc));
            j[0][0] = (b[0] - a[0]) / lon_step;
            j[1][0] = (b[1] - a[1]) / lon_step;
            pixel_of(c, uc, vc - 0.5 / h, a);
            pixel_of(c, uc, vc + 0.5 / h, b);
            int nv = sub_count(hypot(b[0] - a[0], b[1] - a[1]));
            j[0][1] = (b[0] - a[0]) / (M_PI / h);
            j[1][1] = (b[1] - a[1]) / (M_PI / h);
            double acc[3] = {0, 0, 0}, wsum = 0.0, seen_w = 0.0;
            for (int j = 0; j < nv; j++) {
                double v = (y + (j + 0.5) / nv) / h;
                double wt = cos(M_PI * (0.5 - v)); /* solid angle per unit (u, v) */
                for (int i = 0; i < nu; i++) {
                    double u = (x + (i + 0.5) / nu) / w, val[3];
                    sl_latlong_to_dir(u, v, dir);
                    if (radiance(c, dir, val))
                        seen_w += wt;
                    for (int k = 0; k < 3; k++)
                        acc[k] += wt * val[k];
                    wsum += wt;
                }
            }
            double conf = ref > 0.0 ? smaller_singular_value(j) / ref : 0.0;
            conf = conf > 1.0 ? 1.0 : conf;
            float *p = sl_image_pixel(c->out, x, (int)y);
            for (int k = 0; k < 3; k++)
                p[k] = (float)(acc[k] / wsum);
            p[3] = (float)(conf * seen_w / wsum);
        }
    }
}

sl_result sl_unwrap(const sl_image *photo, const sl_unwrap_options *opt, sl_image *out,
                    sl_unwrap_info *info, sl_error *err)
{
    memset(out, 0, sizeof *out);
    if (info)
        memset(info, 0, sizeof *info);
    if (!photo || !photo->data || !opt)
        return sl_error_set(err, SL_ERR_USAGE, "unwrap: no photo");
    const sl_reflectance *refl = &opt->reflectance;
    for (int k = 0; k < 3; k++) {
        bool bad = refl->kind == SL_REFLECTANCE_CONDUCTOR
                       ? !(refl->n[k] > 0.0 && refl->k[k] >= 0.0 && isfinite(refl->n[k]) &&
                           isfinite(refl->k[k]))
                       : !(refl->value[k] > 0.0 && isfinite(refl->value[k]));
        if (bad)
            return sl_error_set(err, SL_ERR_USAGE,
                                "ball reflectance must be positive and finite");
    }
    if (opt->width != 0 && (opt->width < 8 || opt->width > 65536 || opt->width % 2))
        return sl_error_set(err, SL_ERR_USAGE,
                            "lat-long width must be even, from 8 to 65536, not %d", opt->width);
    sl_ball_view *view = malloc(sizeof *view);
    if (!view)
        return sl_error_set(err, SL_ERR_NOMEM, "unwrap: out of memory");
    sl_image rgb = {0};
    sl_result r = sl_ball_view_init(view, photo->width, photo->height, &opt->circle,
                                    &opt->geometry, err);
    if (r)
        goto done;
    if ((r = sl_image_convert_channels(photo, 3, &rgb, err)))
        goto done;
    int64_t nonfinite = sl_image_sanitize(&rgb, 0.0f);

    int width = opt->width;
    if (!width) {
        /* One texel per photo pixel where the ball looks back at the camera. */
        width = 4 * (int)ceil(2.0 * M_PI * view->centre_px_per_rad / 4.0);
        width = width < 16 ? 16 : (width > 65536 ? 65536 : width);
    }
    if ((r = sl_image_alloc(out, width, width / 2, 4, err)))
        goto done;

    unwrap_ctx c = {.photo = &rgb, .view = view, .refl = refl, .out = out};
    double *ring = malloc(sizeof(double) * 3 * RING_SAMPLES);
    if (!ring) {
        r = sl_error_set(err, SL_ERR_NOMEM, "unwrap: out of memory");
        goto done;
    }
    for (int i = 0; i < RING_SAMPLES; i++) {
        /* The edge of the visible range, where the blind cone starts. */
        double psi = 2.0 * M_PI * (i + 0.5) / RING_SAMPLES, phi = view->phi_max;
        double dv[3] = {sin(phi) * cos(psi), sin(phi) * sin(psi), -cos(phi)}, dc[3], dw[3];
        for (int k = 0; k < 3; k++)
            dc[k] = view->view_to_cam[k][0] * dv[0] + view->view_to_cam[k][1] * dv[1] +
                    view->view_to_cam[k][2] * dv[2];
        for (int k = 0; k < 3; k++)
            dw[k] = view->cam_to_world[k][0] * dc[0] + view->cam_to_world[k][1] * dc[1] +
                    view->cam_to_world[k][2] * dc[2];
        ball_hit h;
        double val[3], rf[3];
        ball_view_map(view, dw, &h);
        photo_lookup(&c, h.x, h.y, val);
        sl_reflectance_eval(refl, h.cos_incidence, rf);
        for (int k = 0; k < 3; k++)
            ring[k * RING_SAMPLES + i] = val[k] / rf[k];
    }
    for (int k = 0; k < 3; k++) {
        qsort(ring + k * RING_SAMPLES, RING_SAMPLES, sizeof(double), cmp_double);
        c.blind_fill[k] = 0.5 * (ring[k * RING_SAMPLES + RING_SAMPLES / 2 - 1] +
                                 ring[k * RING_SAMPLES + RING_SAMPLES / 2]);
    }
    free(ring);
    sl_parallel_for(out->height, 2, unwrap_rows, &c);

    if (info) {
        info->width = out->width;
        info->height = out->height;
        info->distance = view->distance;
        info->focal_px = view->focal_px;
        info->ball_angle_deg = view->ball_angle * 180.0 / M_PI;
        info->blind_angle_deg = info->ball_angle_deg;
        info->off_axis_deg = view->off_axis * 180.0 / M_PI;
        info->centre_px_per_rad = view->centre_px_per_rad;
        info->blind_fraction = 0.5 * (1.0 - cos(view->ball_angle));
        info->nonfinite = nonfinite;
    }
done:
    if (r)
        sl_image_free(out);
    sl_image_free(&rgb);
    free(view);
    return r;
}
