/* SPDX-License-Identifier: BSD-3-Clause */
/* GGX D, height-correlated Smith G2 and VNDF sampling. Formulas: Heitz 2014
 * "Understanding the masking-shadowing function", Heitz 2018 "Sampling the
 * GGX distribution of visible normals" (JCGT 7(4)). */
#include "microfacet.h"

#include <math.h>

sl_ggx sl_ggx_make(double roughness, double anisotropy)
{
    double alpha = roughness * roughness;
    double aspect = sqrt(1.0 - 0.9 * anisotropy);
    sl_ggx g = {alpha / aspect, alpha * aspect};
    return g;
}

double sl_ggx_d(sl_ggx g, const double h[3])
{
    if (h[2] <= 0.0)
        return 0.0;
    double x = h[0] / g.ax, y = h[1] / g.ay;
    double t = x * x + y * y + h[2] * h[2];
    return 1.0 / (SL_PI * g.ax * g.ay * t * t);
}

double sl_ggx_lambda(sl_ggx g, const double w[3])
{
    double z2 = w[2] * w[2];
    double s = g.ax * g.ax * w[0] * w[0] + g.ay * g.ay * w[1] * w[1];
    if (s <= 0.0)
        return 0.0;
    if (z2 <= 0.0)
        return INFINITY;
    /* (-1 + sqrt(1 + s/z2)) / 2 without cancellation for small s/z2. */
    double a = s / z2;
    return a / (2.0 * (1.0 + sqrt(1.0 + a)));
}

double sl_ggx_g1(sl_ggx g, const double w[3])
{
    return 1.0 / (1.0 + sl_ggx_lambda(g, w));
}

double sl_ggx_g2(sl_ggx g, const double wo[3], const double wi[3])
{
    return 1.0 / (1.0 + sl_ggx_lambda(g, wo) + sl_ggx_lambda(g, wi));
}

void sl_ggx_sample_vndf(sl_ggx g, const double wo[3], double u1, double u2, double h[3])
{
    /* Stretch to the hemisphere configuration. */
    double vx = g.ax * wo[0], vy = g.ay * wo[1], vz = wo[2];
    double len = sqrt(vx * vx + vy * vy + vz * vz);
    vx /= len;
    vy /= len;
    vz /= len;
    double lensq = vx * vx + vy * vy;
    double t1x = 1.0, t1y = 0.0;
    if (lensq > 0.0) {
        double inv = 1.0 / sqrt(lensq);
        t1x = -vy * inv;
        t1y = vx * inv;
    }
    /* T2 = V x T1 (T1.z = 0). */
    double t2x = -vz * t1y, t2y = vz * t1x, t2z = vx * t1y - vy * t1x;
    double r = sqrt(u1), phi = 2.0 * SL_PI * u2;
    double p1 = r * cos(phi), p2 = r * sin(phi);
    double s = 0.5 * (1.0 + vz);
    p2 = (1.0 - s) * sqrt(fmax(0.0, 1.0 - p1 * p1)) + s * p2;
    double p3 = sqrt(fmax(0.0, 1.0 - p1 * p1 - p2 * p2));
    double nx = p1 * t1x + p2 * t2x + p3 * vx;
    double ny = p1 * t1y + p2 * t2y + p3 * vy;
    double nz = p2 * t2z + p3 * vz;
    /* Unstretch. */
    h[0] = g.ax * nx;
    h[1] = g.ay * ny;
    h[2] = fmax(0.0, nz);
    double hl = sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    if (hl > 0.0) {
        h[0] /= hl;
        h[1] /= hl;
        h[2] /= hl;
    } else {
        h[0] = h[1] = 0.0;
        h[2] = 1.0;
    }
}

bool sl_half_vector(const double wo[3], const double wi[3], double h[3])
{
    double x = wo[0] + wi[0], y = wo[1] + wi[1], z = wo[2] + wi[2];
    double l = sqrt(x * x + y * y + z * z);
    if (!(l > 0.0))
        return false;
    h[0] = x / l;
    h[1] = y / l;
    h[2] = z / l;
    return true;
}

void sl_reflect(const double wo[3], const double h[3], double wi[3])
{
    double d = 2.0 * (wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2]);
    for (int i = 0; i < 3; i++)
        wi[i] = d * h[i] - wo[i];
}

double sl_ggx_pdf_reflect(sl_ggx g, const double wo[3], const double wi[3])
{
    double h[3];
    if (wo[2] <= 0.0 || wi[2] <= 0.0 || !sl_half_vector(wo, wi, h))
        return 0.0;
    return sl_ggx_g1(g, wo) * sl_ggx_d(g, h) / (4.0 * wo[2]);
}
