/* SPDX-License-Identifier: BSD-3-Clause */
/* Vector and 3x3 matrix maths, orthonormal frames and small helpers of the
 * renderer. Private to render/. */
#ifndef SETLIGHT_RENDER_VEC3_H
#define SETLIGHT_RENDER_VEC3_H

#include <math.h>
#include <stdbool.h>

#define SL_PI 3.14159265358979323846

static inline double v3_dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}
static inline void v3_cross(const double a[3], const double b[3], double out[3])
{
    double x = a[1] * b[2] - a[2] * b[1], y = a[2] * b[0] - a[0] * b[2],
           z = a[0] * b[1] - a[1] * b[0];
    out[0] = x, out[1] = y, out[2] = z;
}
static inline double v3_length(const double a[3]) { return sqrt(v3_dot(a, a)); }
static inline bool v3_normalize(double a[3])
{
    double l = v3_length(a);
    if (!(l > 0) || !isfinite(l))
        return false;
    a[0] /= l, a[1] /= l, a[2] /= l;
    return true;
}
static inline void v3_set(double out[3], double x, double y, double z)
{
    out[0] = x, out[1] = y, out[2] = z;
}
static inline void v3_copy(double out[3], const double a[3])
{
    out[0] = a[0], out[1] = a[1], out[2] = a[2];
}
static inline bool v3_finite(const double a[3])
{
    return isfinite(a[0]) && isfinite(a[1]) && isfinite(a[2]);
}
static inline void m3_mul(const double m[3][3], const double a[3], double out[3])
{
    double x = m[0][0] * a[0] + m[0][1] * a[1] + m[0][2] * a[2];
    double y = m[1][0] * a[0] + m[1][1] * a[1] + m[1][2] * a[2];
    double z = m[2][0] * a[0] + m[2][1] * a[1] + m[2][2] * a[2];
    out[0] = x, out[1] = y, out[2] = z;
}
static inline void m3_mul_transpose(const double m[3][3], const double a[3], double out[3])
{
    double x = m[0][0] * a[0] + m[1][0] * a[1] + m[2][0] * a[2];
    double y = m[0][1] * a[0] + m[1][1] * a[1] + m[2][1] * a[2];
    double z = m[0][2] * a[0] + m[1][2] * a[1] + m[2][2] * a[2];
    out[0] = x, out[1] = y, out[2] = z;
}
static inline double luminance709(const double c[3])
{
    return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
}
/* Power heuristic with beta = 2. */
static inline double mis_power(double a, double b)
{
    double a2 = a * a, b2 = b * b;
    return a2 + b2 > 0 ? a2 / (a2 + b2) : 0.0;
}

/* Orthonormal frame with n as +Z (Duff et al. 2017). */
typedef struct frame {
    double t[3], b[3], n[3];
} frame;
void frame_from_normal(frame *f, const double n[3]);
static inline void frame_to_local(const frame *f, const double v[3], double out[3])
{
    double x = v3_dot(v, f->t), y = v3_dot(v, f->b), z = v3_dot(v, f->n);
    out[0] = x, out[1] = y, out[2] = z;
}
static inline void frame_to_world(const frame *f, const double v[3], double out[3])
{
    for (int i = 0; i < 3; i++)
        out[i] = f->t[i] * v[0] + f->b[i] * v[1] + f->n[i] * v[2];
}

#endif
