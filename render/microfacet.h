/* SPDX-License-Identifier: BSD-3-Clause */
/* GGX (Trowbridge-Reitz) microfacet distribution with height-correlated
 * Smith masking-shadowing and visible-normal sampling (Heitz 2014, 2018).
 * Local frame: +Z is the macro normal. Private to render/. */
#ifndef SETLIGHT_RENDER_MICROFACET_H
#define SETLIGHT_RENDER_MICROFACET_H

#include <stdbool.h>

#define SL_PI 3.14159265358979323846

/* Below this perceptual roughness a lobe is narrower than 1e-6 rad and is
 * treated as a delta (mirror) lobe: evaluating D there only adds round-off. */
#define SL_ROUGHNESS_DELTA 1e-3

typedef struct sl_ggx {
    double ax, ay;
} sl_ggx;

/* alpha = roughness^2; anisotropy stretches it as Burley 2012 / Kulla-Conty
 * 2017: aspect = sqrt(1 - 0.9 anisotropy), ax = alpha/aspect, ay = alpha*aspect,
 * so ax*ay = alpha^2 and the isotropic energy tables apply with alpha. */
sl_ggx sl_ggx_make(double roughness, double anisotropy);
double sl_ggx_d(sl_ggx g, const double h[3]);
double sl_ggx_lambda(sl_ggx g, const double w[3]);
double sl_ggx_g1(sl_ggx g, const double w[3]);
/* Height-correlated masking-shadowing 1 / (1 + Lambda(wo) + Lambda(wi)). */
double sl_ggx_g2(sl_ggx g, const double wo[3], const double wi[3]);
/* Samples a visible normal for wo (wo.z > 0) from two uniforms (Heitz 2018). */
void sl_ggx_sample_vndf(sl_ggx g, const double wo[3], double u1, double u2, double h[3]);
/* Solid-angle pdf of wi = reflect(wo, h) with h from sl_ggx_sample_vndf:
 * G1(wo) D(h) / (4 wo.z). Zero unless both are above the surface. */
double sl_ggx_pdf_reflect(sl_ggx g, const double wo[3], const double wi[3]);
/* Unit half vector of wo and wi; false when they are opposite. */
bool sl_half_vector(const double wo[3], const double wi[3], double h[3]);
void sl_reflect(const double wo[3], const double h[3], double wi[3]);

#endif
