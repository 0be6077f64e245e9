/* SPDX-License-Identifier: BSD-3-Clause */
/* Reflectance of the ball: a constant, or the exact unpolarised Fresnel
 * reflectance of a conductor with complex index n + ik. */
#include "setlight/stitch.h"

#include <complex.h>
#include <math.h>
#include <string.h>

void sl_reflectance_constant(sl_reflectance *refl, double r, double g, double b)
{
    memset(refl, 0, sizeof *refl);
    refl->kind = SL_REFLECTANCE_CONSTANT;
    refl->value[0] = r;
    refl->value[1] = g;
    refl->value[2] = b;
}

void sl_reflectance_chrome(sl_reflectance *refl)
{
    memset(refl, 0, sizeof *refl);
    refl->kind = SL_REFLECTANCE_CONDUCTOR;
    for (int c = 0; c < 3; c++) {
        refl->n[c] = 3.2;
        refl->k[c] = 3.3;
    }
}

static double fresnel_conductor(double cos_i, double n, double k)
{
    double complex eta = n + k * I;
    double sin2 = 1.0 - cos_i * cos_i;
    double complex cos_t = csqrt(1.0 - sin2 / (eta * eta));
    double complex r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    double complex r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    double a = cabs(r_par), b = cabs(r_perp);
    return 0.5 * (a * a + b * b);
}

void sl_reflectance_eval(const sl_reflectance *refl, double cos_incidence, double out[3])
{
    double c = cos_incidence < 0.0 ? 0.0 : (cos_incidence > 1.0 ? 1.0 : cos_incidence);
    for (int i = 0; i < 3; i++)
        out[i] = refl->kind == SL_REFLECTANCE_CONDUCTOR
                     ? fresnel_conductor(c, refl->n[i], refl->k[i])
                     : refl->value[i];
}
