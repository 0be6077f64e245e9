/* SPDX-License-Identifier: BSD-3-Clause */
#include "merge_fixture.h"
#include "testing.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

double mf_curve_forward(mf_curve curve, double y)
{
    y = y < 0 ? 0 : y > 1 ? 1 : y;
    double p = pow(y, 1 / 2.2);
    switch (curve) {
    case MF_GAMMA:
        return p;
    case MF_SCURVE:
        return 0.5 * p + 0.5 * p * p * (3 - 2 * p);
    default:
        return y;
    }
}

double mf_curve_inverse(mf_curve curve, double z)
{
    double lo = 0, hi = 1;
    for (int i = 0; i < 60; i++) {
        double mid = 0.5 * (lo + hi);
        if (mf_curve_forward(curve, mid) < z)
            lo = mid;
        else
            hi = mid;
    }
    return 0.5 * (lo + hi);
}

static double gauss(uint64_t *s)
{
    double u1 = ((sl_test_rand(s) >> 11) + 0.5) / 9007199254740992.0;
    double u2 = sl_test_uniform(s);
    return sqrt(-2 * log(u1)) * cos(6.283185307179586 * u2);
}

/* Smooth scene over the bracket's range: log2 radiance from a slope, waves
 * and a bright band, with a colour tint that varies slowly. */
static void scene(const mf_bracket *b, int x, int y, float rgb[3])
{
    /* From 5 stops under the longest frame's white to 0.6 stop under the
     * shortest frame's white: every value is well exposed in some frame. */
    double half = b->stops * (b->frames - 1) / 2, lo = -half - 5, hi = half - 0.6;
    double u = (x + 0.5) / b->width, v = (y + 0.5) / b->height;
    double t = 0.55 * u + 0.25 * (0.5 + 0.5 * sin(9 * u + 4 * v)) + 0.2 * v * v;
    double l2 = lo + (hi - lo) * t;
    double tint[3] = {1 + 0.15 * sin(5 * v), 1, 1 + 0.15 * cos(7 * u)};
    for (int c = 0; c < 3; c++)
        rgb[c] = (float)(exp2(l2) * tint[c]);
    if (b->sun) {
        double dx = (x + 0.5) - 0.7 * b->width, dy = (y + 0.5) - 0.3 * b->height;
        if (dx * dx + dy * dy < 6.0 * 6.0)
            for (int c = 0; c < 3; c++)
                rgb[c] = (float)(exp2(b->stops * (b->frames - 1) / 2 + 4) * (1 + 0.1 * c));
    }
}

sl_result mf_make_bracket(const char *dir, const char *prefix, const mf_bracket *b,
                          mf_result *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    if (b->frames < 1 || b->frames > MF_MAX_FRAMES)
        return sl_error_set(err, SL_ERR_USAGE, "fixture: 1..%d frames", MF_MAX_FRAMES);
    sl_result r;
    if ((r = sl_image_alloc(&out->radiance, b->width, b->height, 3, err)) ||
        (r = sl_image_alloc(&out->clipped, b->width, b->height, 3, err)))
        return r;
    out->frames = b->frames;
    double mid = (b->frames - 1) / 2.0;
    double shortest = exp2(-b->stops * mid);
    for (int y = 0; y < b->height; y++)
        for (int x = 0; x < b->width; x++) {
            float *p = sl_image_pixel(&out->radiance, x, y);
            scene(b, x, y, p);
            for (int c = 0; c < 3; c++)
                sl_image_pixel(&out->clipped, x, y)[c] = p[c] * shortest >= 1 ? 1.0f : 0.0f;
        }
    if ((r = sl_image_alloc(&out->ghost, b->width, b->height, 1, err)))
        return r;
    for (int y = (int)(0.4 * b->height); b->ghost && y < (int)(0.7 * b->height); y++)
        for (int x = (int)(0.3 * b->width); x < (int)(0.45 * b->width); x++)
            *sl_image_pixel(&out->ghost, x, y) = 1;
    sl_image frame = {0};
    if ((r = sl_image_alloc(&frame, b->width, b->height, 3, err)))
        return r;
    uint64_t state = b->seed * 0x2545f4914f6cdd1dull + 1;
    for (int k = 0; k < b->frames && !r; k++) {
        double gain = exp2(b->stops * (k - mid));
        for (int y = 0; y < b->height; y++)
            for (int x = 0; x < b->width; x++)
                for (int c = 0; c < 3; c++) {
                    double lin = sl_image_pixel(&out->radiance, x, y)[c] * gain;
                    if (b->ghost && k == b->ghost_frame && *sl_image_pixel(&out->ghost, x, y) > 0)
                        lin *= 0.25;
                    double clipped = lin > 1 ? 1 : lin;
                    double noisy = lin + sqrt(b->noise_gain * clipped + b->noise_floor) * gauss(&state);
                    sl_image_pixel(&frame, x, y)[c] = (float)mf_curve_forward(b->curve, noisy);
                }
        out->times[k] = gain / 30; /* the middle frame at 1/30 s */
        sl_meta meta;
        sl_meta_init(&meta);
        meta.exposure_time = out->times[k] * (k == b->lie_frame ? exp2(b->lie_stops) : 1);
        meta.f_number = 8;
        meta.iso = 100;
        snprintf(out->paths[k], sizeof out->paths[k], "%s/%s_%d.%s", dir, prefix, k, b->ext);
        r = sl_photo_write(out->paths[k], &frame, &meta, b->bits, err);
        sl_meta_free(&meta);
    }
    sl_image_free(&frame);
    return r;
}

sl_result mf_write_flat(const char *path, int width, int height, float value, int bits,
                        double time, sl_error *err)
{
    sl_image img = {0};
    sl_result r = sl_image_alloc(&img, width, height, 3, err);
    if (r)
        return r;
    sl_image_fill(&img, value);
    sl_meta meta;
    sl_meta_init(&meta);
    if (time > 0) {
        meta.exposure_time = time;
        meta.f_number = 8;
        meta.iso = 100;
    }
    r = sl_photo_write(path, &img, &meta, bits, err);
    sl_meta_free(&meta);
    sl_image_free(&img);
    return r;
}

void mf_result_free(mf_result *r)
{
    sl_image_free(&r->radiance);
    sl_image_free(&r->clipped);
    sl_image_free(&r->ghost);
}

int64_t mf_compare(const sl_image *merged, const mf_result *truth, bool fit_scale,
                   double *median, double *p99, double *scale)
{
    size_t n = (size_t)truth->radiance.width * truth->radiance.height * 3, m = 0;
    double *e = malloc(n * sizeof *e);
    if (!e)
        return 0;
    for (int y = 0; y < truth->radiance.height; y++)
        for (int x = 0; x < truth->radiance.width; x++)
            for (int c = 0; c < 3; c++)
                if (sl_image_pixel(&truth->clipped, x, y)[c] == 0)
                    e[m++] = sl_image_pixel(merged, x, y)[c] / sl_image_pixel(&truth->radiance, x, y)[c];
    double s = 1;
    if (fit_scale && m) {
        qsort(e, m, sizeof *e, sl_cmp_double);
        s = e[m / 2];
    }
    for (size_t i = 0; i < m; i++)
        e[i] = fabs(e[i] / s - 1);
    qsort(e, m, sizeof *e, sl_cmp_double);
    *median = m ? e[m / 2] : NAN;
    *p99 = m ? e[(size_t)(0.99 * (double)(m - 1))] : NAN;
    if (scale)
        *scale = s;
    free(e);
    return (int64_t)m;
}
