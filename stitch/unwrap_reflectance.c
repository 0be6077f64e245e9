/* SPDX-License-Identifier: BSD-3-Clause */
/* Reflectance of the ball: a constant, or the exact unpolarised Fresnel
 * reflectance of a conductor with complex index n + ik (core.h's, shared
 * with the renderer). */
#include "setlight/stitch.h"

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

void sl_reflectance_eval(const sl_reflectance *refl, double cos_incidence, double out[3])
{
    double c = cos_incidence < 0.0 ? 0.0 : (cos_incidence > 1.0 ? 1.0 : cos_incidence);
    for (int i = 0; i < 3; i++)
        out[i] = refl->kind == SL_REFLECTANCE_CONDUCTOR
                     ? sl_fresnel_conductor(c, refl->n[i], refl->k[i])
                     : refl->value[i];
}
