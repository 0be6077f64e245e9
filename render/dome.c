/* SPDX-License-Identifier: BSD-3-Clause */
/* The dome light: a lat-long image, piecewise constant per texel, sampled in
 * proportion to luminance x sin(theta) with a 2D distribution built in double
 * precision (maps spanning 1e-6..1e9 keep their small texels). The (u,v) pdf
 * becomes a solid-angle pdf through dω = 2 π² sin(theta) du dv. */
#include <stdlib.h>
#include <string.h>

#include "scene_internal.h"
#include "vec3.h"

/* Radiance and (u,v) pdf side by side, so an escaped ray costs one cache
 * line. Both MIS techniques weight with this float pdf, so their weights
 * still sum to one exactly; estimates divide by the double pdf. */
struct sl_dome_sampler {
    sl_distrib2d dist;
    float (*texels)[4]; /* r, g, b, pdf over (u,v) */
    int w, h;
    bool valid; /* some texel has energy */
};

static const float *packed(const sl_dome_sampler *ds, double u, double v)
{
    int x = (int)(u * ds->w), y = (int)(v * ds->h);
    x = x < 0 ? 0 : x >= ds->w ? ds->w - 1 : x;
    y = y < 0 ? 0 : y >= ds->h ? ds->h - 1 : y;
    return ds->texels[(size_t)y * (size_t)ds->w + (size_t)x];
}

static const float *texel(const sl_image *img, double u, double v)
{
    int x = (int)(u * img->width), y = (int)(v * img->height);
    x = x < 0 ? 0 : x >= img->width ? img->width - 1 : x;
    y = y < 0 ? 0 : y >= img->height ? img->height - 1 : y;
    return sl_image_pixel(img, x, y);
}

void sl_dome_radiance(const sl_dome *dome, const double d[3], double L[3])
{
    if (!dome->present) {
        L[0] = L[1] = L[2] = 0;
        return;
    }
    double m[3], u, v;
    m3_mul_transpose(dome->rot, d, m);
    sl_dir_to_latlong(m, &u, &v);
    const float *t = texel(&dome->image, u, v);
    for (int c = 0; c < 3; c++)
        L[c] = dome->intensity * t[c];
}

void sl_dome_background(const sl_dome *dome, const double d[3], double L[3])
{
    if (!dome->present) {
        L[0] = L[1] = L[2] = 0;
        return;
    }
    double m[3], u, v;
    float px[3];
    m3_mul_transpose(dome->rot, d, m);
    sl_dir_to_latlong(m, &u, &v);
    sl_latlong_lookup(&dome->image, u, v, px);
    for (int c = 0; c < 3; c++)
        L[c] = dome->intensity * px[c];
}

bool sl_dome_can_sample(const sl_dome *dome)
{
    return dome->present && dome->sampler && dome->sampler->valid && dome->intensity > 0;
}

bool sl_dome_sample(const sl_dome *dome, const double u[2], double wi[3], double L[3], double *pdf,
                    double *mis_pdf)
{
    double uv[2], p;
    sl_distrib2d_sample(&dome->sampler->dist, u[0], u[1], uv, &p);
    double sin_theta = sin(SL_PI * uv[1]);
    if (!(p > 0) || sin_theta < 1e-12) {
        *pdf = 0;
        return false;
    }
    double m[3];
    sl_latlong_to_dir(uv[0], uv[1], m);
    m3_mul(dome->rot, m, wi);
    const float *t = packed(dome->sampler, uv[0], uv[1]);
    for (int c = 0; c < 3; c++)
        L[c] = dome->intensity * t[c];
    *pdf = p / (2.0 * SL_PI * SL_PI * sin_theta);
    if (mis_pdf)
        *mis_pdf = t[3] / (2.0 * SL_PI * SL_PI * sin_theta);
    return true;
}

void sl_dome_radiance_pdf(const sl_dome *dome, const double d[3], double L[3], double *pdf)
{
    double m[3], u, v;
    m3_mul_transpose(dome->rot, d, m);
    sl_dir_to_latlong(m, &u, &v);
    const float *t = packed(dome->sampler, u, v);
    for (int c = 0; c < 3; c++)
        L[c] = dome->intensity * t[c];
    double sin_theta = sqrt(m[0] * m[0] + m[2] * m[2]);
    *pdf = sin_theta < 1e-12 ? 0 : t[3] / (2.0 * SL_PI * SL_PI * sin_theta);
}

double sl_dome_pdf(const sl_dome *dome, const double wi[3])
{
    double m[3], u, v;
    m3_mul_transpose(dome->rot, wi, m);
    double sin_theta = sqrt(m[0] * m[0] + m[2] * m[2]);
    if (sin_theta < 1e-12)
        return 0;
    sl_dir_to_latlong(m, &u, &v);
    return sl_distrib2d_pdf(&dome->sampler->dist, u, v) / (2.0 * SL_PI * SL_PI * sin_theta);
}

void sl_dome_free(sl_dome *dome)
{
    if (dome->sampler) {
        sl_distrib2d_free(&dome->sampler->dist);
        free(dome->sampler->texels);
        free(dome->sampler);
    }
    sl_image_free(&dome->image);
    memset(dome, 0, sizeof *dome);
}

/* The rows of the sampling tables, over both threads: a 2048 x 1024 map's
 * two sweeps are most of their 0.07 CPU s, and the rest map's tables are
 * built after a --time cut, when every millisecond is the sampling's. */
typedef struct sampler_job {
    sl_dome *dome;
    double *func;  /* luminance x sin(theta) per texel */
    uint8_t *lit;  /* per row: some texel has energy */
} sampler_job;

static void func_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    sampler_job *j = ctx;
    int w = j->dome->image.width, h = j->dome->image.height;
    for (int64_t y = begin; y < end; y++) {
        double st = sin(SL_PI * ((double)y + 0.5) / h);
        for (int x = 0; x < w; x++) {
            const float *t = sl_image_pixel(&j->dome->image, x, (int)y);
            double c[3] = {t[0], t[1], t[2]};
            /* The largest channel keeps the pdf positive wherever radiance is. */
            double lum = fmax(luminance709(c), fmax(c[0], fmax(c[1], c[2])) * 1e-3);
            j->func[(size_t)y * w + x] = lum * st;
            j->lit[y] |= lum > 0;
        }
    }
}

static void texel_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    sampler_job *j = ctx;
    const sl_dome_sampler *ds = j->dome->sampler;
    int w = ds->w, h = ds->h;
    for (int64_t y = begin; y < end; y++)
        for (int x = 0; x < w; x++) {
            const float *t = sl_image_pixel(&j->dome->image, x, (int)y);
            float *d = ds->texels[(size_t)y * w + x];
            d[0] = t[0], d[1] = t[1], d[2] = t[2];
            d[3] = (float)sl_distrib2d_pdf(&ds->dist, (x + 0.5) / w, ((double)y + 0.5) / h);
        }
}

/* The sampling tables of dome->image (RGB, sanitised); frees the dome on
 * failure. */
static sl_result build_sampler(sl_dome *dome, const char *name, sl_error *err)
{
    int w = dome->image.width, h = dome->image.height;
    sampler_job j = {dome, malloc((size_t)w * (size_t)h * sizeof *j.func), calloc((size_t)h, 1)};
    dome->sampler = calloc(1, sizeof *dome->sampler);
    if (!j.func || !j.lit || !dome->sampler) {
        free(j.func);
        free(j.lit);
        sl_dome_free(dome);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory for the dome distribution", name);
    }
    sl_parallel_for(h, 16, func_rows, &j);
    bool any = false;
    for (int y = 0; y < h; y++)
        any = any || j.lit[y];
    free(j.lit);
    sl_result r = sl_distrib2d_init(&dome->sampler->dist, j.func, w, h, err);
    free(j.func);
    if (r) {
        sl_dome_free(dome);
        return r;
    }
    dome->sampler->valid = any;
    dome->sampler->w = w, dome->sampler->h = h;
    dome->sampler->texels = malloc((size_t)w * (size_t)h * sizeof *dome->sampler->texels);
    if (!dome->sampler->texels) {
        sl_dome_free(dome);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory for the dome", name);
    }
    sl_parallel_for(h, 16, texel_rows, &j);
    return SL_OK;
}

sl_result sl_dome_init_like(sl_dome *out, const sl_dome *like, const sl_image *rgb, sl_error *err)
{
    memset(out, 0, sizeof *out);
    sl_result r = sl_image_copy(rgb, &out->image, err);
    if (r || (r = build_sampler(out, "render", err)))
        return r;
    memcpy(out->rot, like->rot, sizeof out->rot);
    out->intensity = like->intensity;
    out->present = true;
    return SL_OK;
}

sl_result sl_scene_set_dome(sl_scene *scene, const sl_image *env, double rotation_deg,
                            double intensity, const char *source, sl_error *err)
{
    const char *name = source ? source : "dome";
    sl_dome_free(&scene->dome);
    if (!env || !env->data || env->width < 1 || env->height < 1 || env->channels < 1)
        return sl_error_set(err, SL_ERR_INPUT, "%s: empty environment image", name);
    if (!sl_is_latlong_shape(env->width, env->height))
        return sl_error_set(err, SL_ERR_INPUT, "%s: %dx%d is not a lat-long (width must be 2 x height)",
                            name, env->width, env->height);
    if (!isfinite(intensity) || intensity < 0 || !isfinite(rotation_deg))
        return sl_error_set(err, SL_ERR_INPUT, "%s: dome intensity must be finite and >= 0, rotation finite",
                            name);
    sl_dome *dome = &scene->dome;
    /* Per texel: the dome's RGB (12 bytes), the sampling function (8), the
     * 2D distribution (20) and the lookup texels (16). */
    char what[96];
    snprintf(what, sizeof what, "a %dx%d dome with its sampling tables", env->width, env->height);
    sl_result r =
        sl_memory_check((uint64_t)env->width * (uint64_t)env->height * 56, name, what, err);
    if (r)
        return r;
    if ((r = sl_image_alloc(&dome->image, env->width, env->height, 3, err)))
        return r;
    int w = env->width, h = env->height;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const float *s = sl_image_pixel(env, x, y);
            float *d = sl_image_pixel(&dome->image, x, y);
            for (int c = 0; c < 3; c++) {
                float v = s[env->channels >= 3 ? c : 0];
                if (!isfinite(v) || v < 0) {
                    dome->bad_texels++;
                    v = 0;
                }
                d[c] = v;
            }
        }
    if ((r = build_sampler(dome, name, err)))
        return r;
    sl_rotation_y(rotation_deg, dome->rot);
    dome->intensity = intensity;
    dome->present = true;
    return SL_OK;
}
