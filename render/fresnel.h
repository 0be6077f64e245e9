/* SPDX-License-Identifier: BSD-3-Clause */
/* Fresnel reflectance: Schlick, exact dielectric, exact conductor (complex
 * IOR) and the artist-friendly conductor mapping of Gulbrandsen 2014.
 * Private to render/. */
#ifndef SETLIGHT_RENDER_FRESNEL_H
#define SETLIGHT_RENDER_FRESNEL_H

#include "setlight/render.h"

double sl_fresnel_schlick(double f0, double cos_i);
/* Unpolarised reflectance from outside a dielectric of relative index eta;
 * 1 under total internal reflection (eta < 1). cos_i in (0, 1]. */
double sl_fresnel_dielectric(double cos_i, double eta);
/* sl_fresnel_conductor: core.h. */
/* Gulbrandsen 2014: reflectance r at normal incidence and edge tint g
 * (both 0..1) -> n, k. r is clamped below 1 (F = 1 is handled by the caller). */
void sl_fresnel_artist_nk(double r, double g, double *n, double *k);
/* The material's Fresnel term per channel at cos_i = wo.h. */
void sl_fresnel_eval(const sl_material *m, double cos_i, double f[3]);
/* Hemispherical average 2 * int_0^1 F(mu) mu dmu per channel
 * (closed form for Schlick, 8-point Gauss-Legendre otherwise). */
void sl_fresnel_average(const sl_material *m, double favg[3]);

#endif
