/* SPDX-License-Identifier: BSD-3-Clause */
/* Private helpers of the virtual set: small vector maths and counter-based
 * random numbers whose value depends only on (seed, stream, index). */
#ifndef SETLIGHT_VSET_INTERNAL_H
#define SETLIGHT_VSET_INTERNAL_H

#include <math.h>
#include <stdint.h>

#include "setlight/vset.h"

#define VSET_PI 3.14159265358979323846
#define VSET_DEG (VSET_PI / 180.0)

/* Scoring: truth luminance this dim or less is not compared (black
 * borders, outside an image circle): a ratio to nothing says nothing. */
#define VSET_SCORE_DARK 1e-9

static inline double v3_dot(const double a[3], const double b[3])
{
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
}

static inline void v3_cross(const double a[3], const double b[3], double out[3])
{
    double x = a[1] * b[2] - a[2] * b[1];
    double y = a[2] * b[0] - a[0] * b[2];
    double z = a[0] * b[1] - a[1] * b[0];
    out[0] = x;
    out[1] = y;
    out[2] = z;
}

static inline void v3_normalize(double v[3])
{
    double n = sqrt(v3_dot(v, v));
    if (n > 0) {
        v[0] /= n;
        v[1] /= n;
        v[2] /= n;
    }
}

/* Azimuth/elevation in degrees -> unit direction (core.h lat-long axes). */
static inline void vset_azel_dir(double az_deg, double el_deg, double d[3])
{
    double az = az_deg * VSET_DEG, el = el_deg * VSET_DEG;
    d[0] = sin(az) * cos(el);
    d[1] = sin(el);
    d[2] = cos(az) * cos(el);
}

/* Camera frame of a view: forward, right (image +x) and up (image -y). */
static inline void vset_view_frame(const sl_vset_view *v, double f[3], double r[3], double u[3])
{
    vset_azel_dir(v->yaw_deg, v->pitch_deg, f);
    double yaw = v->yaw_deg * VSET_DEG, roll = v->roll_deg * VSET_DEG;
    double r0[3] = {-cos(yaw), 0, sin(yaw)}, u0[3];
    v3_cross(r0, f, u0);
    for (int k = 0; k < 3; k++) {
        r[k] = cos(roll) * r0[k] + sin(roll) * u0[k];
        u[k] = -sin(roll) * r0[k] + cos(roll) * u0[k];
    }
}

/* A uniform double in (0, 1) for (seed, stream, index). */
static inline double vset_uniform(uint64_t seed, uint64_t stream, uint64_t index)
{
    uint64_t h = sl_splitmix64_hash(seed ^ sl_splitmix64_hash(stream * 0x632be59bd9b4e019ull + index));
    return ((double)(h >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

/* Smooth value noise in 2D and its fractal sum, in about [0, 1]. */
double vset_value_noise(double x, double y, uint64_t salt);
double vset_fbm(double x, double y, int octaves, uint64_t salt);

/* The sun's angular diameter and disk solid angle. */
#define VSET_SUN_DIAMETER_DEG 0.53

/* Precomputed daylight: Preetham sky for a sun position and turbidity,
 * the sun's radiance and the ground it lights. */
typedef struct vset_daylight {
    double sun_dir[3];
    double turbidity;
    double perez[3][5]; /* A..E for Y, x, y */
    double zenith[3];   /* Y (cd/m^2), x, y at the zenith */
    double norm[3];     /* Perez F(0, theta_sun) for Y, x, y */
    double sun_rgb[3];  /* sun disk radiance */
    double ground_irr[3]; /* sun + sky irradiance on the ground */
    double albedo;
} vset_daylight;

void vset_daylight_init(vset_daylight *d, double sun_az_deg, double sun_el_deg,
                        double turbidity, double ground_albedo);
/* Sky (above the horizon) or textured lit ground (below), no sun disk. */
void vset_daylight_radiance(const vset_daylight *d, const double dir[3], double rgb[3]);

/* A standard normal variate for (seed, stream, index) by Box-Muller. */
static inline double vset_gauss(uint64_t seed, uint64_t stream, uint64_t index)
{
    double u1 = vset_uniform(seed, stream, 2 * index), u2 = vset_uniform(seed, stream, 2 * index + 1);
    return sqrt(-2.0 * log(u1)) * cos(2.0 * VSET_PI * u2);
}


#endif
