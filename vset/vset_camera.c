/* SPDX-License-Identifier: BSD-3-Clause */
/* The simulated camera body: exposure, Poisson-Gaussian sensor noise, raw
 * clipping and quantisation, white balance, colour matrix and response.
 * docs/virtual-set.md gives the equations and where the constants come
 * from. Each pixel's noise depends only on the seed and its position, so
 * shots are identical for any thread count. */
#include <string.h>

#include "vset_internal.h"

/* Adobe DNG ColorMatrix2 (D65) of the Canon EOS 5D Mark II: XYZ -> camera. */
static const double xyz_to_cam_5d2[3][3] = {{0.4716, 0.0603, -0.0830},
                                            {-0.7798, 1.5474, 0.2480},
                                            {-0.1496, 0.1937, 0.6651}};

/* Black level as a fraction of the raw range (2048 of 16383 on Canon). */
#define RAW_BLACK 0.125

/* Picture-style saturation of the in-camera rendering. */
#define CAMERA_SATURATION 1.15

static void white_balance_for(const double cam[3][3], double kelvin, double wb[3])
{
    double rgb[3], raw[3];
    if (kelvin > 0)
        sl_vset_kelvin_rgb(kelvin, rgb);
    else
        rgb[0] = rgb[1] = rgb[2] = 1.0;
    sl_mat3_apply(cam, rgb, raw);
    for (int c = 0; c < 3; c++)
        wb[c] = raw[1] / raw[c];
}

void sl_vset_camera_default(sl_vset_camera *cam, double wb_kelvin)
{
    memset(cam, 0, sizeof *cam);
    snprintf(cam->make, sizeof cam->make, "setlight");
    snprintf(cam->model, sizeof cam->model, "virtual full-frame (5D Mark II colour)");
    cam->k = 100.0 * 0.65 / 78.0;
    cam->full_well_e = 64000;
    cam->read_noise_pre_e = 2.5;
    cam->read_noise_post_e = 25.5;
    cam->raw_bits = 14;
    double rgb_to_xyz[3][3];
    for (int j = 0; j < 3; j++) {
        double e[3] = {j == 0, j == 1, j == 2}, col[3];
        sl_rec709_to_xyz(e, col);
        for (int i = 0; i < 3; i++)
            rgb_to_xyz[i][j] = col[i];
    }
    sl_mat3_mul(xyz_to_cam_5d2, rgb_to_xyz, cam->cam_from_rec709);
    /* Scale so that a white of luminance L gives green = L. */
    double g = cam->cam_from_rec709[1][0] + cam->cam_from_rec709[1][1] + cam->cam_from_rec709[1][2];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            cam->cam_from_rec709[i][j] /= g;
    white_balance_for(cam->cam_from_rec709, wb_kelvin, cam->wb);
    /* The rendering matrix is built for D65 (white-balanced camera RGB to
     * Rec.709), then saturated like a camera picture style. */
    double wb65[3], inv[3][3], d[3][3] = {{0}};
    white_balance_for(cam->cam_from_rec709, 0, wb65);
    sl_mat3_invert(cam->cam_from_rec709, inv);
    for (int c = 0; c < 3; c++)
        d[c][c] = 1.0 / wb65[c];
    sl_mat3_mul(inv, d, cam->ccm);
    const double lw[3] = {0.2126390059, 0.7151686788, 0.0721923154};
    double sat[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            sat[i][j] = (1.0 - CAMERA_SATURATION) * lw[j] + (i == j ? CAMERA_SATURATION : 0);
    sl_mat3_mul(sat, cam->ccm, cam->ccm);
    sl_vset_response_preset("canon", &cam->response, NULL);
}

double sl_vset_exposure_scale(const sl_vset_camera *cam, const sl_vset_exposure *e)
{
    return e->time_s * (e->iso / 100.0) * cam->k / (e->f_number * e->f_number);
}

static double full_well(const sl_vset_camera *cam, double iso)
{
    return cam->full_well_e * 100.0 / iso;
}

static double read_noise(const sl_vset_camera *cam, double iso)
{
    double post = cam->read_noise_post_e * 100.0 / iso;
    return sqrt(cam->read_noise_pre_e * cam->read_noise_pre_e + post * post);
}

double sl_vset_sensor_noise_std(const sl_vset_camera *cam, double iso, double x)
{
    double fw = full_well(cam, iso), rn = read_noise(cam, iso);
    double e = x > 0 ? x * fw : 0;
    return sqrt(e + rn * rn) / fw;
}

void sl_vset_camera_output_matrix(const sl_vset_camera *cam, double m[3][3])
{
    double d[3][3] = {{0}};
    for (int c = 0; c < 3; c++)
        d[c][c] = cam->wb[c];
    sl_mat3_mul(cam->ccm, d, m);
    sl_mat3_mul(m, cam->cam_from_rec709, m);
}

void sl_vset_quantize(sl_image *img, int bits)
{
    double levels = (double)((1u << bits) - 1u);
    for (int y = 0; y < img->height; y++) {
        float *row = sl_image_pixel(img, 0, y);
        for (int i = 0; i < img->width * img->channels; i++) {
            double v = row[i] < 0 ? 0 : row[i] > 1 ? 1 : row[i];
            row[i] = (float)(floor(v * levels + 0.5) / levels);
        }
    }
}

/* Photo-electrons: Poisson by multiplication of uniforms for small means,
 * the normal approximation (rounded) above 30, where it is within a
 * fraction of a percent in mean and variance. */
static double poisson(double lambda, uint64_t seed, uint64_t index)
{
    if (lambda <= 0)
        return 0;
    if (lambda > 30) {
        double v = floor(lambda + sqrt(lambda) * vset_gauss(seed, 3, index) + 0.5);
        return v < 0 ? 0 : v;
    }
    double limit = exp(-lambda), p = 1.0;
    int k = 0;
    do {
        p *= vset_uniform(seed, 4, index * 256u + (uint64_t)k);
        k++;
    } while (p > limit && k < 255);
    return k - 1;
}

typedef struct shoot_ctx {
    const sl_vset_camera *cam;
    const sl_image *radiance;
    sl_vset_shot *shot;
    double scale, fw, rn;
    uint64_t seed;
} shoot_ctx;

static void shoot_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    const shoot_ctx *s = ctx;
    const sl_vset_camera *cam = s->cam;
    int w = s->radiance->width;
    double levels = (double)((1u << cam->raw_bits) - 1u);
    for (int64_t y = begin; y < end; y++) {
        for (int x = 0; x < w; x++) {
            const float *p = sl_image_pixel(s->radiance, x, (int)y);
            double L[3] = {p[0], p[1], p[2]}, raw[3];
            sl_mat3_apply(cam->cam_from_rec709, L, raw);
            uint64_t id = ((uint64_t)y * (uint64_t)w + (uint64_t)x) * 3u;
            for (int c = 0; c < 3; c++) {
                double mean_e = raw[c] * s->scale * s->fw;
                if (!(mean_e > 0))
                    mean_e = 0;
                if (mean_e > 4 * s->fw)
                    mean_e = 4 * s->fw; /* far past saturation: clipped anyway */
                double e = poisson(mean_e, s->seed, id + (uint64_t)c) +
                           s->rn * vset_gauss(s->seed, 5, id + (uint64_t)c);
                /* Black-level-subtracted raw: read noise may dip below
                 * zero (down to the black level), saturation clips at 1. */
                double v = e / s->fw;
                v = v < -RAW_BLACK ? -RAW_BLACK : v > 1 ? 1 : v;
                raw[c] = floor(v * levels + 0.5) / levels;
            }
            /* White-balanced channels clip at the saturation level, as
             * raw developers do, so blown highlights render white, not pink. */
            double bal[3], lin[3];
            for (int c = 0; c < 3; c++)
                bal[c] = fmin(raw[c] * cam->wb[c], 1.0);
            sl_mat3_apply(cam->ccm, bal, lin);
            float *ps = sl_image_pixel(&s->shot->sensor, x, (int)y);
            float *pl = sl_image_pixel(&s->shot->linear, x, (int)y);
            float *pe = sl_image_pixel(&s->shot->encoded, x, (int)y);
            for (int c = 0; c < 3; c++) {
                double v = lin[c] < 0 ? 0 : lin[c] > 1 ? 1 : lin[c];
                ps[c] = (float)raw[c];
                pl[c] = (float)v;
                pe[c] = (float)sl_vset_response_apply(&cam->response, v);
            }
        }
    }
}

sl_result sl_vset_camera_shoot(const sl_vset_camera *cam, const sl_vset_exposure *e,
                               const sl_image *radiance, uint64_t seed, sl_vset_shot *shot,
                               sl_error *err)
{
    memset(shot, 0, sizeof *shot);
    if (!(e->time_s > 0 && e->f_number > 0 && e->iso > 0) || !isfinite(e->time_s) ||
        !isfinite(e->f_number) || !isfinite(e->iso))
        return sl_error_set(err, SL_ERR_USAGE,
                            "exposure %g s, f/%g, ISO %g: all must be positive", e->time_s,
                            e->f_number, e->iso);
    if (radiance->channels < 3)
        return sl_error_set(err, SL_ERR_INPUT, "camera needs an RGB radiance image, not %d channels",
                            radiance->channels);
    if (cam->raw_bits < 8 || cam->raw_bits > 16)
        return sl_error_set(err, SL_ERR_USAGE, "raw bit depth %d (8..16)", cam->raw_bits);
    sl_result r;
    int w = radiance->width, h = radiance->height;
    if ((r = sl_image_alloc(&shot->sensor, w, h, 3, err)) ||
        (r = sl_image_alloc(&shot->linear, w, h, 3, err)) ||
        (r = sl_image_alloc(&shot->encoded, w, h, 3, err))) {
        sl_vset_shot_free(shot);
        return r;
    }
    shoot_ctx s = {cam, radiance, shot, sl_vset_exposure_scale(cam, e), full_well(cam, e->iso),
                   read_noise(cam, e->iso), seed};
    sl_parallel_for(h, 8, shoot_rows, &s);
    return SL_OK;
}

void sl_vset_shot_free(sl_vset_shot *shot)
{
    if (!shot)
        return;
    sl_image_free(&shot->sensor);
    sl_image_free(&shot->linear);
    sl_image_free(&shot->encoded);
}
