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

/* Adds a source: inside(dir) tested on 16x16 sub-texels. Rect: half-sides
 * a, b (tangent units) along u and v = dir x u; disk: angular radius a. */
static inline void sc_add(sl_image *img, scene_light *L, double lat, double lon, double roll_deg,
                          double a, double b, bool rect, const double rgb[3])
{
    int w = img->width, h = img->height;
    double d[3], up[3] = {0, 1, 0}, e1[3], e2[3];
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
    double r = roll_deg * M_PI / 180, u[3], v[3];
    for (int i = 0; i < 3; i++) {
        u[i] = cos(r) * e1[i] + sin(r) * e2[i];
        v[i] = -sin(r) * e1[i] + cos(r) * e2[i];
    }
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

#endif
