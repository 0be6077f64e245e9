/* SPDX-License-Identifier: BSD-3-Clause */
/* Lens model of a view: a fisheye or rectilinear projection with a radial
 * polynomial correction, an optical centre off the image centre and a radial
 * vignetting falloff; and the pose (yaw, pitch, roll) of the view. The frame
 * conventions are those of the virtual set's camera (docs/geometry.md). */
#include "setlight/core.h"

#include <math.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define DEG (M_PI / 180.0)

static const char *const lens_names[SL_LENS_PROJECTION_COUNT] = {
    "equisolid", "equidistant", "stereographic", "orthographic", "rectilinear"};

int sl_lens_projection_from_name(const char *name)
{
    if (!name)
        return -1;
    for (int i = 0; i < SL_LENS_PROJECTION_COUNT; i++)
        if (strcmp(name, lens_names[i]) == 0)
            return i;
    return -1;
}

const char *sl_lens_projection_name(sl_lens_projection p)
{
    return (p >= 0 && p < SL_LENS_PROJECTION_COUNT) ? lens_names[p] : "unknown";
}

/* The ideal radius over the focal length, q = g(theta); -1 where the
 * projection cannot image theta. */
static double ideal_q(sl_lens_projection p, double theta)
{
    switch (p) {
    case SL_LENS_EQUISOLID:
        return 2.0 * sin(0.5 * theta);
    case SL_LENS_EQUIDISTANT:
        return theta;
    case SL_LENS_STEREOGRAPHIC:
        return theta < M_PI ? 2.0 * tan(0.5 * theta) : -1.0;
    case SL_LENS_ORTHOGRAPHIC:
        return theta <= 0.5 * M_PI + 1e-12 ? sin(theta) : -1.0;
    case SL_LENS_RECTILINEAR:
        return theta < 0.5 * M_PI ? tan(theta) : -1.0;
    default:
        return -1.0;
    }
}

static double ideal_theta(sl_lens_projection p, double q)
{
    switch (p) {
    case SL_LENS_EQUISOLID:
        return q <= 2.0 ? 2.0 * asin(0.5 * q) : -1.0;
    case SL_LENS_EQUIDISTANT:
        return q;
    case SL_LENS_STEREOGRAPHIC:
        return 2.0 * atan(0.5 * q);
    case SL_LENS_ORTHOGRAPHIC:
        return q <= 1.0 ? asin(q) : -1.0;
    case SL_LENS_RECTILINEAR:
        return atan(q);
    default:
        return -1.0;
    }
}

static double radial_poly(const double k[3], double q)
{
    double q2 = q * q;
    return q * (1.0 + q2 * (k[0] + q2 * (k[1] + q2 * k[2])));
}

static double radial_slope(const double k[3], double q)
{
    double q2 = q * q;
    return 1.0 + q2 * (3.0 * k[0] + q2 * (5.0 * k[1] + q2 * 7.0 * k[2]));
}

void sl_lens_nominal(sl_lens *lens, sl_lens_projection p, int width, int height,
                     double focal_mm, double sensor_width_mm)
{
    memset(lens, 0, sizeof *lens);
    lens->projection = p;
    lens->width = width;
    lens->height = height;
    lens->focal_px = focal_mm * width / sensor_width_mm;
    lens->cx = 0.5 * width;
    lens->cy = 0.5 * height;
    double half_diagonal = 0.5 * hypot(width, height);
    if (p == SL_LENS_RECTILINEAR) {
        lens->max_theta_deg = atan(half_diagonal / lens->focal_px) / DEG;
        return;
    }
    lens->max_theta_deg = 90.0;
    double r90 = lens->focal_px * ideal_q(p, 0.5 * M_PI);
    if (r90 < half_diagonal)
        lens->circle_radius_px = r90;
}

double sl_lens_radius(const sl_lens *lens, double theta)
{
    if (!(theta >= 0.0) || theta > lens->max_theta_deg * DEG + 1e-12)
        return -1.0;
    double q = ideal_q(lens->projection, theta);
    if (q < 0.0 || radial_slope(lens->k, q) <= 0.0)
        return -1.0;
    return lens->focal_px * radial_poly(lens->k, q);
}

double sl_lens_theta(const sl_lens *lens, double radius_px)
{
    if (!(radius_px >= 0.0) || !(lens->focal_px > 0.0))
        return -1.0;
    double target = radius_px / lens->focal_px, q = target;
    /* Newton on q (1 + k1 q^2 + ...) = target; the correction is small and
     * monotone over the field, so a few steps from q = target converge. */
    for (int it = 0; it < 50; it++) {
        double slope = radial_slope(lens->k, q);
        if (slope <= 0.0)
            return -1.0;
        double step = (radial_poly(lens->k, q) - target) / slope;
        q -= step;
        if (fabs(step) < 1e-14 * (1.0 + q))
            break;
    }
    if (!(q >= 0.0) || fabs(radial_poly(lens->k, q) - target) > 1e-9 * (1.0 + target))
        return -1.0;
    double theta = ideal_theta(lens->projection, q);
    if (theta < 0.0 || theta > lens->max_theta_deg * DEG + 1e-9)
        return -1.0;
    return theta;
}

bool sl_lens_pixel_to_ray(const sl_lens *lens, double x, double y, double ray[3])
{
    double dx = x - lens->cx, dy = y - lens->cy, r = hypot(dx, dy);
    if (lens->circle_radius_px > 0.0 && r > lens->circle_radius_px)
        return false;
    double theta = sl_lens_theta(lens, r);
    if (theta < 0.0)
        return false;
    double st = sin(theta);
    ray[0] = r > 0.0 ? st * dx / r : 0.0;
    ray[1] = r > 0.0 ? st * dy / r : 0.0;
    ray[2] = cos(theta);
    return true;
}

bool sl_lens_ray_to_pixel(const sl_lens *lens, const double ray[3], double *x, double *y)
{
    double s = hypot(ray[0], ray[1]);
    if (!(s > 0.0) && !(ray[2] > 0.0))
        return false;
    double r = sl_lens_radius(lens, atan2(s, ray[2]));
    if (r < 0.0 || (lens->circle_radius_px > 0.0 && r > lens->circle_radius_px))
        return false;
    double px = lens->cx + (s > 0.0 ? r * ray[0] / s : 0.0);
    double py = lens->cy + (s > 0.0 ? r * ray[1] / s : 0.0);
    if (px < 0.0 || py < 0.0 || px > lens->width || py > lens->height)
        return false;
    *x = px;
    *y = py;
    return true;
}

double sl_lens_vignette(const sl_lens *lens, double x, double y)
{
    double s2 = (pow(x - lens->cx, 2) + pow(y - lens->cy, 2)) / (lens->focal_px * lens->focal_px);
    const double *v = lens->vignette;
    return 1.0 + s2 * (v[0] + s2 * (v[1] + s2 * v[2]));
}

/* The camera's right and up axes before roll, for a forward axis at yaw. */
static void unrolled_axes(double yaw, const double f[3], double r0[3], double u0[3])
{
    r0[0] = -cos(yaw);
    r0[1] = 0.0;
    r0[2] = sin(yaw);
    u0[0] = r0[1] * f[2] - r0[2] * f[1];
    u0[1] = r0[2] * f[0] - r0[0] * f[2];
    u0[2] = r0[0] * f[1] - r0[1] * f[0];
}

void sl_view_pose_matrix(const sl_view_pose *pose, double m[3][3])
{
    double yaw = pose->yaw_deg * DEG, pitch = pose->pitch_deg * DEG, roll = pose->roll_deg * DEG;
    double f[3] = {sin(yaw) * cos(pitch), sin(pitch), cos(yaw) * cos(pitch)}, r0[3], u0[3];
    unrolled_axes(yaw, f, r0, u0);
    for (int k = 0; k < 3; k++) {
        m[k][0] = cos(roll) * r0[k] + sin(roll) * u0[k];
        m[k][1] = sin(roll) * r0[k] - cos(roll) * u0[k]; /* down = -up */
        m[k][2] = f[k];
    }
}

void sl_view_pose_from_matrix(const double m[3][3], sl_view_pose *pose)
{
    double f[3] = {m[0][2], m[1][2], m[2][2]};
    double n = sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
    for (int k = 0; k < 3; k++)
        f[k] /= n;
    double pitch = asin(f[1] > 1.0 ? 1.0 : (f[1] < -1.0 ? -1.0 : f[1]));
    double yaw = hypot(f[0], f[2]) > 1e-12 ? atan2(f[0], f[2]) : 0.0;
    double r0[3], u0[3];
    unrolled_axes(yaw, f, r0, u0);
    double along_r0 = m[0][0] * r0[0] + m[1][0] * r0[1] + m[2][0] * r0[2];
    double along_u0 = m[0][0] * u0[0] + m[1][0] * u0[1] + m[2][0] * u0[2];
    pose->yaw_deg = yaw / DEG;
    pose->pitch_deg = pitch / DEG;
    pose->roll_deg = atan2(along_u0, along_r0) / DEG;
}
