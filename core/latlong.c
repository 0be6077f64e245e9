/* SPDX-License-Identifier: BSD-3-Clause */
/* Lat-long geometry (OpenEXR orientation, texel centres at (x + 0.5) / w),
 * bilinear lookup and rotations. docs/geometry.md has the diagrams. */
#include "setlight/core.h"

#include <math.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

void sl_latlong_to_dir(double u, double v, double dir[3])
{
    double lon = M_PI * (1.0 - 2.0 * u);
    double lat = M_PI * (0.5 - v);
    double cl = cos(lat);
    dir[0] = sin(lon) * cl;
    dir[1] = sin(lat);
    dir[2] = cos(lon) * cl;
}

void sl_dir_to_latlong(const double dir[3], double *u, double *v)
{
    double h = hypot(dir[0], dir[2]);
    /* atan2 on both angles: accurate near the poles and for unnormalised input. */
    double lon = (h == 0.0) ? 0.0 : atan2(dir[0], dir[2]);
    double lat = atan2(dir[1], h);
    double uu = 0.5 - lon / (2.0 * M_PI);
    if (uu >= 1.0)
        uu -= 1.0;
    if (uu < 0.0)
        uu = 0.0;
    *u = uu;
    *v = 0.5 - lat / M_PI;
}

double sl_latlong_texel_solid_angle(int y, int width, int height)
{
    if (width <= 0 || height <= 0 || y < 0 || y >= height)
        return 0.0;
    double lat_top = M_PI * (0.5 - (double)y / height);
    double lat_bottom = M_PI * (0.5 - (double)(y + 1) / height);
    /* sin a - sin b as a product: no cancellation near the equator. */
    double band = 2.0 * cos(0.5 * (lat_top + lat_bottom)) * sin(0.5 * (lat_top - lat_bottom));
    return 2.0 * M_PI / width * band;
}

void sl_latlong_lookup(const sl_image *img, double u, double v, float *out)
{
    int w = img->width, h = img->height, c = img->channels;
    double x = u * w - 0.5, y = v * h - 0.5;
    if (!isfinite(x) || !isfinite(y)) {
        for (int k = 0; k < c; k++)
            out[k] = 0.0f;
        return;
    }
    double fx0 = floor(x), fy0 = floor(y);
    double tx = x - fx0, ty = y - fy0;
    long x0 = (long)fmod(fx0, (double)w);
    if (x0 < 0)
        x0 += w;
    long x1 = x0 + 1 == w ? 0 : x0 + 1;
    long y0 = (long)fy0, y1 = y0 + 1;
    if (y0 < 0)
        y0 = 0;
    if (y0 > h - 1)
        y0 = h - 1;
    if (y1 < 0)
        y1 = 0;
    if (y1 > h - 1)
        y1 = h - 1;
    const float *p00 = sl_image_pixel(img, (int)x0, (int)y0);
    const float *p10 = sl_image_pixel(img, (int)x1, (int)y0);
    const float *p01 = sl_image_pixel(img, (int)x0, (int)y1);
    const float *p11 = sl_image_pixel(img, (int)x1, (int)y1);
    for (int k = 0; k < c; k++) {
        double top = p00[k] + tx * ((double)p10[k] - p00[k]);
        double bot = p01[k] + tx * ((double)p11[k] - p01[k]);
        out[k] = (float)(top + ty * (bot - top));
    }
}

bool sl_is_latlong_shape(int width, int height)
{
    return width > 0 && height > 0 && width == 2 * height;
}

/* Right-handed rotation by `degrees` about axis 0 (X), 1 (Y) or 2 (Z). */
static void axis_rotation(int axis, double degrees, double r[3][3])
{
    double a = degrees * (M_PI / 180.0);
    double c = cos(a), s = sin(a);
    int i = (axis + 1) % 3, j = (axis + 2) % 3;
    for (int p = 0; p < 3; p++)
        for (int q = 0; q < 3; q++)
            r[p][q] = p == q ? 1.0 : 0.0;
    r[i][i] = c;
    r[i][j] = -s;
    r[j][i] = s;
    r[j][j] = c;
}

void sl_rotation_y(double degrees, double rot[3][3]) { axis_rotation(1, degrees, rot); }

void sl_rotation_euler(double yaw_deg, double pitch_deg, double roll_deg, double rot[3][3])
{
    double ry[3][3], rx[3][3], rz[3][3];
    axis_rotation(1, yaw_deg, ry);
    axis_rotation(0, pitch_deg, rx);
    axis_rotation(2, roll_deg, rz);
    sl_mat3_mul(rx, rz, rot);
    sl_mat3_mul(ry, rot, rot);
}
