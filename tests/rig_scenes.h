/* SPDX-License-Identifier: BSD-3-Clause */
/* Synthetic lat-longs with known lights for the lightrig tests: a smooth sky,
 * textured walls, and disks / rectangles added with exact-coverage
 * antialiasing (16x16 sub-texels weighted by their exact solid angle), so
 * each source's integral over the sphere is known analytically. */
#ifndef SETLIGHT_RIG_SCENES_H
#define SETLIGHT_RIG_SCENES_H

#include <math.h>
#include <string.h>

#include "setlight/core.h"
#include "setlight/lightrig.h"
#include "setlight/render.h"
#include "testing.h"

typedef struct scene_light {
    double dir[3];
    double solid_angle; /* analytic */
    double rgb[3];      /* radiance */
    bool rect;
} scene_light;

static inline double sc_dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static inline void sc_dir(double lat_deg, double lon_deg, double d[3])
{
    double la = lat_deg * M_PI / 180, lo = lon_deg * M_PI / 180;
    d[0] = sin(lo) * cos(la);
    d[1] = sin(la);
    d[2] = cos(lo) * cos(la);
}

static inline double sc_angle(const double a[3], const double b[3])
{
    double c[3] = {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
    return atan2(sqrt(sc_dot(c, c)), sc_dot(a, b));
}

/* Smooth sky over darker ground; walls: a band of value noise (up to 2.5x
 * the sky) below the horizon, which must never become a light. */
static inline double sc_hash(int x, int y)
{
    unsigned h = (unsigned)x * 374761393u + (unsigned)y * 668265263u;
    h = (h ^ (h >> 13)) * 1274126177u;
    return ((h ^ (h >> 16)) & 0xffff) / 65535.0;
}

static inline double sc_noise(double x, double y)
{
    int ix = (int)floor(x), iy = (int)floor(y);
    double fx = x - ix, fy = y - iy;
    fx = fx * fx * (3 - 2 * fx);
    fy = fy * fy * (3 - 2 * fy);
    double a = sc_hash(ix, iy), b = sc_hash(ix + 1, iy), c = sc_hash(ix, iy + 1),
           d = sc_hash(ix + 1, iy + 1);
    return (a + (b - a) * fx) * (1 - fy) + (c + (d - c) * fx) * fy;
}

static inline void sc_background(sl_image *img, double sky, bool walls)
{
    int w = img->width, h = img->height;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / h, d);
            float *p = sl_image_pixel(img, x, y);
            double s = d[1] > 0 ? sky * (0.6 + 0.4 * d[1]) : sky * 0.5;
            double rgb[3] = {s * 0.8, s * 0.9, s * 1.1};
            if (walls && d[1] < 0.05 && d[1] > -0.6) {
                /* plaster and brick-like texture, octaves of value noise */
                double u = (x + 0.5) * 64.0 / w, v = (y + 0.5) * 32.0 / h;
                double n = 0.5 * sc_noise(u, v) + 0.3 * sc_noise(2 * u, 2 * v) +
                           0.2 * sc_noise(4 * u, 4 * v);
                double t = sky * 0.3 * exp(2.1 * n);
                rgb[0] = t * 1.05;
                rgb[1] = t;
                rgb[2] = t * 0.85;
            }
            for (int c = 0; c < 3; c++)
                p[c] = (float)rgb[c];
        }
}

/* The grey sphere (or, glossy, a GGX 0.3 conductor) `width` pixels wide,
 * direct light only, pixel centres, lit by the map env or by the rig file
 * (rig.json, read as the renderer reads it); objects only. */
static inline void sc_render_sphere(const sl_image *env, const char *rig_json, bool glossy,
                                    int width, int64_t spp, sl_image *out)
{
    sl_scene s;
    sl_scene_init(&s);
    sl_error err = {0};
    CHECK_OK(sl_scene_preset(&s, "grey", width, &err), &err);
    if (glossy) {
        const double f0[3] = {0.9, 0.9, 0.9}, tint[3] = {0.95, 0.95, 0.95};
        sl_material_conductor(&s.materials[0], f0, tint, 0.3);
    }
    if (env)
        CHECK_OK(sl_scene_set_dome(&s, env, 0, 1, "map", &err), &err);
    else
        CHECK_OK(sl_scene_read_rig(&s, rig_json, &err), &err);
    s.background_env = false;
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = spp;
    o.pixel_centers = true;
    o.bounces = 0;
    sl_render_stats st;
    CHECK_OK(sl_render(&s, &o, out, &st, &err), &err);
    sl_render_stats_free(&st);
    sl_scene_free(&s);
}

/* The frame of a source at (lat, lon) rolled by roll_deg: its direction d
 * and the unit axes u, v = d x u across it. */
static inline void sc_frame(double lat, double lon, double roll_deg, double d[3], double u[3],
                            double v[3])
{
    double up[3] = {0, 1, 0}, e1[3], e2[3];
    sc_dir(lat, lon, d);
    if (fabs(d[1]) > 0.9) {
        up[0] = 1;
        up[1] = 0;
    }
    e1[0] = up[1] * d[2] - up[2] * d[1];
    e1[1] = up[2] * d[0] - up[0] * d[2];
    e1[2] = up[0] * d[1] - up[1] * d[0];
    double l = sqrt(sc_dot(e1, e1));
    for (int i = 0; i < 3; i++)
        e1[i] /= l;
    e2[0] = d[1] * e1[2] - d[2] * e1[1];
    e2[1] = d[2] * e1[0] - d[0] * e1[2];
    e2[2] = d[0] * e1[1] - d[1] * e1[0];
    double r = roll_deg * M_PI / 180;
    for (int i = 0; i < 3; i++) {
        u[i] = cos(r) * e1[i] + sin(r) * e2[i];
        v[i] = -sin(r) * e1[i] + cos(r) * e2[i];
    }
}

/* Adds a source: inside(dir) tested on 16x16 sub-texels. Rect: half-sides
 * a, b (tangent units) along u and v = dir x u; disk: angular radius a. */
static inline void sc_add(sl_image *img, scene_light *L, double lat, double lon, double roll_deg,
                          double a, double b, bool rect, const double rgb[3])
{
    int w = img->width, h = img->height;
    double d[3], u[3], v[3];
    sc_frame(lat, lon, roll_deg, d, u, v);
    double reach = rect ? atan(hypot(a, b)) : a;
    double diag = hypot(2 * M_PI / w, M_PI / h);
    /* sub-texels fine enough that the coverage error is well under 0.1% */
    double texel = M_PI / h, size = rect ? 2 * atan(fmin(a, b)) : 2 * a;
    int S = (int)ceil(40 * texel / size);
    S = S < 16 ? 16 : S;
    for (int y = 0; y < h; y++) {
        double lat_top = M_PI * (0.5 - (double)y / h);
        for (int x = 0; x < w; x++) {
            double c[3];
            sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / h, c);
            double ang = sc_angle(c, d);
            if (ang > reach + diag)
                continue;
            double cover = 0, total = 0;
            for (int sy = 0; sy < S; sy++) {
                double la0 = lat_top - M_PI / h * sy / S, la1 = lat_top - M_PI / h * (sy + 1) / S;
                double wgt = sin(la0) - sin(la1);
                for (int sx = 0; sx < S; sx++) {
                    double p[3];
                    sl_latlong_to_dir((x + (sx + 0.5) / S) / w, (y + (sy + 0.5) / S) / h, p);
                    bool in;
                    if (rect) {
                        double z = sc_dot(p, d);
                        in = z > 0 && fabs(sc_dot(p, u) / z) <= a && fabs(sc_dot(p, v) / z) <= b;
                    } else {
                        in = sc_angle(p, d) <= a;
                    }
                    total += wgt;
                    if (in)
                        cover += wgt;
                }
            }
            float *px = sl_image_pixel(img, x, y);
            double f = cover / total;
            for (int k = 0; k < 3; k++)
                px[k] = (float)((1 - f) * px[k] + f * rgb[k]);
        }
    }
    memcpy(L->dir, d, sizeof d);
    memcpy(L->rgb, rgb, sizeof L->rgb);
    L->rect = rect;
    L->solid_angle = rect ? 4 * asin(a * b / sqrt((1 + a * a) * (1 + b * b)))
                          : 2 * M_PI * (1 - cos(a));
}

/* Diffuse irradiance E(n) for a set of normals: what a grey (Lambertian)
 * sphere shows of a map, and of a rig (dome texels plus each light as its
 * fitted shape). rig_rmse: relative RMSE over 48 normals. */
static inline void irradiance_map(const sl_image *img, const double n[][3], int count, double *e)
{
    for (int k = 0; k < count; k++)
        e[k] = 0;
    for (int y = 0; y < img->height; y++) {
        double om = sl_latlong_texel_solid_angle(y, img->width, img->height);
        for (int x = 0; x < img->width; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / img->width, (y + 0.5) / img->height, d);
            const float *p = sl_image_pixel(img, x, y);
            double l = sl_luminance_px(p);
            for (int k = 0; k < count; k++) {
                double c = sc_dot(n[k], d);
                if (c > 0)
                    e[k] += l * om * c;
            }
        }
    }
}

/* Adds a light's irradiance over the normals, the light rendered as its
 * fitted shape (rect or cap, uniform radiance over its solid angle; distant
 * lights as caps too) by a 24 x 24 quadrature. */
static inline void light_irradiance(const sl_rig_light *L, const double n[][3], int count,
                                    double *e)
{
    enum { Q = 24 };
    const double *d = L->direction, *u = L->axis_u, *v = L->axis_v;
    double y = sl_luminance(L->radiance);
    bool rect = L->shape == SL_RIG_RECT;
    double a = tan(L->angular_size[0] / 2), b = tan(L->angular_size[1] / 2);
    double r = acos(fmax(-1, 1 - L->solid_angle / (2 * M_PI)));
    double wsum = 0, dirs[Q * Q][3], wts[Q * Q];
    for (int j = 0; j < Q; j++)
        for (int i = 0; i < Q; i++) {
            double p[3], w;
            if (rect) {
                double X = (2 * (i + 0.5) / Q - 1) * a, Y = (2 * (j + 0.5) / Q - 1) * b;
                for (int k = 0; k < 3; k++)
                    p[k] = d[k] + X * u[k] + Y * v[k];
                w = pow(1 + X * X + Y * Y, -1.5);
            } else {
                /* cap: uniform in cos(theta) and in phi */
                double ct = 1 - (1 - cos(r)) * (j + 0.5) / Q, st = sqrt(1 - ct * ct);
                double ph = 2 * M_PI * (i + 0.5) / Q;
                for (int k = 0; k < 3; k++)
                    p[k] = ct * d[k] + st * (cos(ph) * u[k] + sin(ph) * v[k]);
                w = 1;
            }
            double l = sqrt(sc_dot(p, p));
            for (int k = 0; k < 3; k++)
                dirs[j * Q + i][k] = p[k] / l;
            wts[j * Q + i] = w;
            wsum += w;
        }
    for (int k = 0; k < count; k++) {
        double acc = 0;
        for (int q = 0; q < Q * Q; q++) {
            double c = sc_dot(n[k], dirs[q]);
            if (c > 0)
                acc += wts[q] * c;
        }
        e[k] += y * L->solid_angle * acc / wsum;
    }
}

static inline double rig_rmse(const sl_image *img, const sl_rig *rig)
{
    enum { N = 48 };
    double n[N][3], e0[N], e1[N];
    for (int k = 0; k < N; k++) {
        /* Fibonacci sphere */
        double z = 1 - (2 * k + 1.0) / N, r = sqrt(1 - z * z), phi = k * 2.399963229728653;
        n[k][0] = r * cos(phi);
        n[k][1] = z;
        n[k][2] = r * sin(phi);
    }
    irradiance_map(img, n, N, e0);
    irradiance_map(&rig->residual, n, N, e1);
    for (int i = 0; i < rig->light_count; i++)
        light_irradiance(&rig->lights[i], n, N, e1);
    double se = 0, s0 = 0;
    for (int k = 0; k < N; k++) {
        se += (e1[k] - e0[k]) * (e1[k] - e0[k]);
        s0 += e0[k] * e0[k];
    }
    return sqrt(se / s0);
}

#endif
