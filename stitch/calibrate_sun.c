/* SPDX-License-Identifier: BSD-3-Clause */
/* Clipped-sun repair: a source clipped in every frame of the merge holds
 * only a lower bound in the HDRI; the grey sphere's shading holds the
 * missing energy. A disc of the source's known size at the clipped
 * region's centroid is fitted, with the exposure gains, to the photo. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "calibrate_internal.h"

#define SUN_SUBSAMPLES 16

void sl_sun_options_init(sl_sun_options *o)
{
    memset(o, 0, sizeof(*o));
    o->diameter_deg = 0.53;
}

static double dot3(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static bool masked(const sl_image *mask, int x, int y)
{
    const float *m = mask->data + (size_t)y * mask->stride + (size_t)x * mask->channels;
    for (int c = 0; c < (mask->channels < 3 ? mask->channels : 3); c++)
        if (m[c] >= 0.5f)
            return true;
    return false;
}

static void texel_dir(int x, int y, int w, int h, double d[3])
{
    sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / h, d);
}

/* Fraction of each texel's solid angle inside the disc (cos_r: cosine of
 * its angular radius), by cos(latitude)-weighted subsamples. */
static double disc_coverage(int x, int y, int w, int h, const double centre[3], double cos_r)
{
    double in = 0, all = 0;
    for (int j = 0; j < SUN_SUBSAMPLES; j++)
        for (int i = 0; i < SUN_SUBSAMPLES; i++) {
            double u = (x + (i + 0.5) / SUN_SUBSAMPLES) / w;
            double v = (y + (j + 0.5) / SUN_SUBSAMPLES) / h;
            double d[3];
            sl_latlong_to_dir(u, v, d);
            double wgt = cos(M_PI * (0.5 - v));
            all += wgt;
            if (dot3(d, centre) >= cos_r)
                in += wgt;
        }
    return all > 0 ? in / all : 0;
}

sl_result sl_sun_repair_fit(sl_image *hdri, const sl_image *mask, const sl_image *photo,
                            const sl_grey_options *grey, const sl_sun_options *opt,
                            sl_sun_repair *out, sl_error *err)
{
    memset(out, 0, sizeof(*out));
    sl_sun_options so;
    if (opt)
        so = *opt;
    else
        sl_sun_options_init(&so);
    sl_grey_options go;
    if (grey)
        go = *grey;
    else
        sl_grey_options_init(&go);
    if (!(so.diameter_deg > 0 && so.diameter_deg < 90))
        return sl_error_set(err, SL_ERR_USAGE, "sun repair: source diameter %g degrees not in (0, 90)",
                            so.diameter_deg);
    sl_cal_view view;
    sl_result r = sl_cal_grey_check(&go, photo, &view, err);
    if (r)
        return r;
    int w = hdri->width, h = hdri->height;
    if (!mask || !mask->data || mask->width != w || mask->height != h || mask->channels < 1)
        return sl_error_set(err, SL_ERR_INPUT,
                            "sun repair: the clipped mask is not the HDRI's size (%dx%d)", w, h);
    /* The clipped region: count, solid angle, centroid. */
    double sum[3] = {0, 0, 0};
    for (int y = 0; y < h; y++) {
        double da = sl_latlong_texel_solid_angle(y, w, h);
        for (int x = 0; x < w; x++)
            if (masked(mask, x, y)) {
                double d[3];
                texel_dir(x, y, w, h, d);
                for (int c = 0; c < 3; c++)
                    sum[c] += da * d[c];
                out->clipped_texels++;
                out->solid_angle += da;
            }
    }
    for (int y = 0; y < h; y++) {
        double da = sl_latlong_texel_solid_angle(y, w, h);
        for (int x = 0; x < w; x++) {
            const float *v = hdri->data + (size_t)y * hdri->stride + (size_t)x * hdri->channels;
            for (int c = 0; c < 3; c++)
                out->energy_before[c] += da * v[c];
        }
    }
    if (out->clipped_texels == 0)
        return SL_OK;
    double len = sqrt(dot3(sum, sum));
    if (!(len > 0.5 * out->solid_angle))
        return sl_error_set(err, SL_ERR_INPUT,
                            "sun repair: the clipped texels (%lld) are spread over the sphere, not "
                            "one source",
                            (long long)out->clipped_texels);
    for (int c = 0; c < 3; c++)
        out->direction[c] = sum[c] / len;
    out->elevation_deg = asin(fmax(-1, fmin(1, out->direction[1]))) * 180 / M_PI;
    out->azimuth_deg = atan2(out->direction[0], out->direction[2]) * 180 / M_PI;
    double rad = so.diameter_deg * M_PI / 360, cos_r = cos(rad);
    out->source_solid_angle = 2 * M_PI * (1 - cos_r);

    /* Region Q (clipped or touched by the disc), the disc's unit-radiance
     * image, and the sky fill for Q from a ring round it. */
    size_t texels = (size_t)w * h;
    float *cover = calloc(texels, sizeof(float));
    unsigned char *inq = calloc(texels, 1);
    sl_image filled = {0}, unit = {0}, r0 = {0}, rs = {0}, ph = {0};
    if (!cover || !inq) {
        r = sl_error_set(err, SL_ERR_NOMEM, "sun repair: out of memory");
        goto done;
    }
    double reach = rad + M_PI / h, covered = 0, qmax = 0;
    for (int y = 0; y < h; y++) {
        double da = sl_latlong_texel_solid_angle(y, w, h);
        for (int x = 0; x < w; x++) {
            double d[3];
            texel_dir(x, y, w, h, d);
            double ang = acos(fmax(-1, fmin(1, dot3(d, out->direction))));
            size_t i = (size_t)y * w + x;
            if (ang <= reach) {
                cover[i] = (float)disc_coverage(x, y, w, h, out->direction, cos_r);
                covered += da * cover[i];
            }
            inq[i] = cover[i] > 0 || masked(mask, x, y);
            if (inq[i])
                qmax = fmax(qmax, ang);
        }
    }
    if (!(covered > 0)) {
        r = sl_error_set(err, SL_ERR_INPUT, "sun repair: the source disc covers no texel");
        goto done;
    }
    double norm = out->source_solid_angle / covered; /* the disc's integral is exact */
    double ring_out = qmax + 2 * M_PI / h, fill[3] = {0, 0, 0}, ring_sa = 0;
    for (int y = 0; y < h; y++) {
        double da = sl_latlong_texel_solid_angle(y, w, h);
        for (int x = 0; x < w; x++) {
            double d[3];
            texel_dir(x, y, w, h, d);
            if (inq[(size_t)y * w + x] || acos(fmax(-1, fmin(1, dot3(d, out->direction)))) > ring_out)
                continue;
            const float *v = hdri->data + (size_t)y * hdri->stride + (size_t)x * hdri->channels;
            for (int c = 0; c < 3; c++)
                fill[c] += da * v[c];
            ring_sa += da;
        }
    }
    for (int c = 0; c < 3; c++)
        fill[c] = ring_sa > 0 ? fill[c] / ring_sa : 0;
    if ((r = sl_image_alloc(&filled, w, h, 3, err)) || (r = sl_image_alloc(&unit, w, h, 3, err)))
        goto done;
    for (int y = 0; y < h; y++) {
        double da = sl_latlong_texel_solid_angle(y, w, h);
        for (int x = 0; x < w; x++) {
            size_t i = (size_t)y * w + x;
            const float *v = hdri->data + (size_t)y * hdri->stride + (size_t)x * hdri->channels;
            float *f = filled.data + (size_t)y * filled.stride + (size_t)x * 3;
            float *u = unit.data + (size_t)y * unit.stride + (size_t)x * 3;
            for (int c = 0; c < 3; c++) {
                f[c] = inq[i] ? (float)fill[c] : v[c];
                u[c] = (float)(cover[i] * norm);
                /* What the clipped map holds in Q above the sky: the bound. */
                if (inq[i])
                    out->bound[c] += da * (v[c] - fill[c]) / out->source_solid_angle;
            }
        }
    }
    for (int c = 0; c < 3; c++)
        out->bound[c] = fmax(0, out->bound[c]);

    /* The sphere under the sky alone and under the unit disc alone;
     * rendering is linear in the dome. */
    int n = sl_cal_sphere_size(&go);
    if ((r = sl_cal_render_sphere(&filled, &go, &view, n, &r0, err)) ||
        (r = sl_cal_render_sphere(&unit, &go, &view, n, &rs, err)) ||
        (r = sl_image_alloc(&ph, n, n, 4, err)))
        goto done;
    sl_cal_resample_photo(photo, &go, &view, &ph);
    /* Per channel: photo = g * sky + y * disc (y = g * radiance), least squares. */
    double a00[3] = {0}, a01[3] = {0}, a11[3] = {0}, b0[3] = {0}, b1[3] = {0}, bb[3] = {0};
    double slit = 0;
    for (size_t p = 0; p < (size_t)n * n; p++) {
        const float *q = ph.data + p * 4, *k0 = r0.data + p * 4, *ks = rs.data + p * 4;
        if (q[3] == 0)
            continue;
        out->pixels++;
        for (int c = 0; c < 3; c++) {
            a00[c] += (double)k0[c] * k0[c];
            a01[c] += (double)k0[c] * ks[c];
            a11[c] += (double)ks[c] * ks[c];
            b0[c] += (double)k0[c] * q[c];
            b1[c] += (double)ks[c] * q[c];
            bb[c] += (double)q[c] * q[c];
        }
        slit += ks[1] > 0;
    }
    if (out->pixels < 16) {
        r = sl_error_set(err, SL_ERR_INPUT, "sun repair: only %lld usable grey sphere pixels",
                         (long long)out->pixels);
        goto done;
    }
    if (slit < 8) {
        r = sl_error_set(err, SL_ERR_INPUT,
                         "sun repair: the clipped source (azimuth %.1f, elevation %.1f) does not "
                         "light the visible side of the grey sphere",
                         out->azimuth_deg, out->elevation_deg);
        goto done;
    }
    double e0 = 0, e1 = 0, ref = 0, g[3], yv[3], cov[3][3];
    for (int c = 0; c < 3; c++) {
        double det = a00[c] * a11[c] - a01[c] * a01[c];
        if (!(det > 1e-9 * a00[c] * a11[c])) {
            r = sl_error_set(err, SL_ERR_INPUT,
                             "sun repair: the sky and the source shade the sphere alike (no fit)");
            goto done;
        }
        g[c] = (a11[c] * b0[c] - a01[c] * b1[c]) / det;
        yv[c] = (a00[c] * b1[c] - a01[c] * b0[c]) / det;
        /* Residual sums from the normal equations. */
        double rss = bb[c] - 2 * (g[c] * b0[c] + yv[c] * b1[c]) + g[c] * g[c] * a00[c] +
                     2 * g[c] * yv[c] * a01[c] + yv[c] * yv[c] * a11[c];
        double s2 = fmax(0, rss) / (double)(out->pixels - 2);
        cov[c][0] = s2 * a11[c] / det;  /* var g */
        cov[c][1] = -s2 * a01[c] / det; /* cov g, y */
        cov[c][2] = s2 * a00[c] / det;  /* var y */
        e1 += fmax(0, rss);
        ref += bb[c];
        /* Before: the gains alone under the map as it was (sky + bound). */
        double c00 = a00[c] + 2 * out->bound[c] * a01[c] + out->bound[c] * out->bound[c] * a11[c];
        double c0 = b0[c] + out->bound[c] * b1[c];
        e0 += c00 > 0 ? fmax(0, bb[c] - c0 * c0 / c00) : bb[c];
    }
    if (!(g[0] > 0 && g[1] > 0 && g[2] > 0)) {
        r = sl_error_set(err, SL_ERR_INPUT, "sun repair: no positive exposure fits the grey sphere");
        goto done;
    }
    out->rel_rmse_before = sqrt(e0 / ref);
    out->rel_rmse_after = sqrt(e1 / ref);
    for (int c = 0; c < 3; c++) {
        double x = yv[c] / g[c];
        /* Delta method for y / g. */
        double var = (cov[c][2] - 2 * x * cov[c][1] + x * x * cov[c][0]) / (g[c] * g[c]);
        out->fitted[c] = x;
        out->radiance_sigma[c] = sqrt(fmax(0, var));
        out->gain[c] = g[c];
        /* The clipped value is a lower bound on the source. */
        out->radiance[c] = fmax(x, out->bound[c]);
    }
    for (int y = 0; y < h; y++) {
        double da = sl_latlong_texel_solid_angle(y, w, h);
        for (int x = 0; x < w; x++) {
            size_t i = (size_t)y * w + x;
            if (!inq[i])
                continue;
            float *v = hdri->data + (size_t)y * hdri->stride + (size_t)x * hdri->channels;
            for (int c = 0; c < 3; c++) {
                float nv = (float)(fill[c] + out->radiance[c] * cover[i] * norm);
                out->energy_added[c] += da * ((double)nv - v[c]);
                v[c] = nv;
            }
        }
    }
    out->repaired = true;
done:
    free(cover);
    free(inq);
    sl_image_free(&filled);
    sl_image_free(&unit);
    sl_image_free(&r0);
    sl_image_free(&rs);
    sl_image_free(&ph);
    return r;
}
