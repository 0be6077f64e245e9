/* SPDX-License-Identifier: BSD-3-Clause */
/* Lenses of the simulated camera: the probes' rectilinear lens (r = f tan
 * theta) pointing anywhere by yaw, pitch and roll; the HDRI fisheye as the
 * core lens model, nominal and true; the head's true poses; and the image of
 * an environment at infinity through any core lens. */
#include <string.h>

#include "vset_internal.h"

void sl_vset_lens_rectilinear(sl_vset_lens *lens, double focal_mm)
{
    memset(lens, 0, sizeof *lens);
    snprintf(lens->name, sizeof lens->name, "%gmm rectilinear", focal_mm);
    lens->type = SL_VSET_LENS_RECTILINEAR;
    lens->focal_mm = focal_mm;
    lens->sensor_width_mm = 36;
    lens->vignette_a = -0.15;
    lens->vignette_b = 0;
}

static double pitch_mm(const sl_vset_lens *lens, int width) { return lens->sensor_width_mm / width; }

bool sl_vset_lens_to_dir(const sl_vset_lens *lens, const sl_vset_view *view, int width,
                         int height, double x, double y, double dir[3])
{
    double p = pitch_mm(lens, width);
    double sx = (x - 0.5 * width) * p, sy = (0.5 * height - y) * p;
    double r = sqrt(sx * sx + sy * sy), theta = atan(r / lens->focal_mm);
    double f[3], ri[3], u[3];
    vset_view_frame(view, f, ri, u);
    double st = sin(theta), ct = cos(theta);
    double cx = r > 0 ? sx / r : 0, cy = r > 0 ? sy / r : 0;
    for (int k = 0; k < 3; k++)
        dir[k] = ct * f[k] + st * (cx * ri[k] + cy * u[k]);
    return true;
}

bool sl_vset_lens_from_dir(const sl_vset_lens *lens, const sl_vset_view *view, int width,
                           int height, const double dir[3], double *x, double *y)
{
    double f[3], ri[3], u[3];
    vset_view_frame(view, f, ri, u);
    double cz = v3_dot(dir, f), cx = v3_dot(dir, ri), cy = v3_dot(dir, u);
    double s = sqrt(cx * cx + cy * cy);
    double theta = atan2(s, cz);
    if (theta >= 0.5 * VSET_PI)
        return false;
    double r = lens->focal_mm * tan(theta);
    double p = pitch_mm(lens, width);
    double sx = s > 0 ? r * cx / s : 0, sy = s > 0 ? r * cy / s : 0;
    *x = 0.5 * width + sx / p;
    *y = 0.5 * height - sy / p;
    return true;
}

double sl_vset_lens_vignette(const sl_vset_lens *lens, int width, int height, double x,
                             double y)
{
    double dx = x - 0.5 * width, dy = y - 0.5 * height;
    double rho2 = (dx * dx + dy * dy) / (0.25 * ((double)width * width + (double)height * height));
    double g = 1.0 + lens->vignette_a * rho2 + lens->vignette_b * rho2 * rho2;
    double p = pitch_mm(lens, width);
    double t2 = (dx * dx + dy * dy) * p * p / (lens->focal_mm * lens->focal_mm);
    double c2 = 1.0 / (1.0 + t2); /* cos^2 theta */
    g *= c2 * c2;
    return g > 0 ? g : 0;
}

typedef struct view_ctx {
    const sl_lens *lens;
    double rot[3][3];
    const sl_image *env;
    sl_image *out;
    int ss;
} view_ctx;

static void view_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    const view_ctx *s = ctx;
    int w = s->out->width, n = s->ss;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < w; x++) {
            double acc[3] = {0, 0, 0};
            for (int j = 0; j < n; j++)
                for (int i = 0; i < n; i++) {
                    double px = x + (i + 0.5) / n, py = (double)y + (j + 0.5) / n, ray[3], d[3],
                           u, v;
                    float rgb[4];
                    if (!sl_lens_pixel_to_ray(s->lens, px, py, ray))
                        continue;
                    sl_mat3_apply(s->rot, ray, d);
                    sl_dir_to_latlong(d, &u, &v);
                    sl_latlong_lookup(s->env, u, v, rgb);
                    double g = sl_lens_vignette(s->lens, px, py);
                    for (int c = 0; c < 3; c++)
                        acc[c] += g * rgb[c];
                }
            float *p = sl_image_pixel(s->out, x, (int)y);
            for (int c = 0; c < 3; c++)
                p[c] = (float)(acc[c] / (n * n));
        }
}

sl_result sl_vset_view_image(const sl_lens *lens, const sl_view_pose *pose,
                             const sl_image *latlong, int ss, sl_image *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    if (latlong->channels < 3 || !sl_is_latlong_shape(latlong->width, latlong->height))
        return sl_error_set(err, SL_ERR_INPUT,
                            "environment is %dx%d with %d channels, not an RGB lat-long",
                            latlong->width, latlong->height, latlong->channels);
    if (!(lens->focal_px > 0) || lens->width < 1 || lens->height < 1 || ss < 1 || ss > 16)
        return sl_error_set(err, SL_ERR_USAGE,
                            "lens focal length, image size or supersampling (%d) invalid", ss);
    sl_result r = sl_image_alloc(out, lens->width, lens->height, 3, err);
    if (r)
        return r;
    view_ctx s = {.lens = lens, .env = latlong, .out = out, .ss = ss};
    sl_view_pose_matrix(pose, s.rot);
    sl_parallel_for(lens->height, 4, view_rows, &s);
    return SL_OK;
}

void sl_vset_fisheye_nominal(sl_lens *lens, int width, int height)
{
    sl_lens_nominal(lens, SL_LENS_EQUISOLID, width, height, SL_VSET_FISHEYE_FOCAL_MM,
                    SL_VSET_SENSOR_WIDTH_MM);
}

void sl_vset_fisheye_true(sl_lens *lens, int width, int height)
{
    sl_vset_fisheye_nominal(lens, width, height);
    /* Off its label as real glass is: the stitch's solve must find these. */
    lens->focal_px *= 8.12 / SL_VSET_FISHEYE_FOCAL_MM;
    lens->cx += 0.006 * width;
    lens->cy -= 0.004 * width;
    lens->k[0] = 0.02;
    lens->k[1] = -0.01;
    lens->vignette[0] = -0.034;
    lens->vignette[1] = -0.003;
    lens->max_theta_deg = 90.0;
    lens->circle_radius_px = sl_lens_radius(lens, 0.5 * VSET_PI);
}

/* A signed error of size lo..hi degrees from (seed, stream, index). */
static double head_error(uint64_t seed, uint64_t index, double lo, double hi)
{
    double size = lo + (hi - lo) * vset_uniform(seed, 11, 2 * index);
    return vset_uniform(seed, 11, 2 * index + 1) < 0.5 ? -size : size;
}

void sl_vset_head_pose(uint64_t seed, int view, const sl_view_pose *plan, sl_view_pose *out)
{
    *out = *plan;
    if (view == 0)
        return;
    uint64_t id = (uint64_t)view * 3u;
    double pitch = head_error(seed, id + 1, 0.3, 0.5);
    out->yaw_deg += head_error(seed, id, 0.5, 1.0);
    /* At the zenith the head can only tilt down from it. */
    out->pitch_deg += plan->pitch_deg >= 90.0 ? -fabs(pitch) : pitch;
    out->roll_deg += head_error(seed, id + 2, 0.3, 0.5);
}
