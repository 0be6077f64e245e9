/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * setlight render: the validation renderer. BSDFs, light and environment
 * sampling, MIS, integrators, validation scenes and convergence reports.
 * See docs/render.md.
 */
#ifndef SETLIGHT_RENDER_H
#define SETLIGHT_RENDER_H

#include "setlight/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ================================================================== */
/* BSDFs and materials                                                 */
/* ================================================================== */

/* Shading happens in a local frame: +Z is the surface normal; wo and wi
 * point away from the surface; both unit length. Values are double.
 * Models and references: docs/render-bsdf.md. */
typedef enum {
    SL_MAT_LAMBERT = 0, /* diffuse, albedo base_color */
    SL_MAT_CONDUCTOR,   /* GGX metal; Fresnel from base_color (reflectance at normal
                           incidence) and edge_tint (Gulbrandsen 2014); roughness 0 = delta mirror */
    SL_MAT_PLASTIC,     /* Lambert base_color under a GGX dielectric coat of index ior */
    SL_MAT_COUNT
} sl_material_type;

typedef enum {
    SL_FRESNEL_SCHLICK = 0, /* F0 = base_color */
    SL_FRESNEL_ARTIST,      /* Gulbrandsen: base_color + edge_tint -> complex IOR */
    SL_FRESNEL_DIELECTRIC,  /* exact, from ior */
    SL_FRESNEL_ONE          /* F = 1: the white furnace conductor */
} sl_fresnel_mode;

typedef struct sl_material {
    sl_material_type type;
    sl_fresnel_mode fresnel;
    double base_color[3];
    double edge_tint[3];
    double roughness;  /* perceptual, 0..1; GGX alpha = roughness^2 */
    double anisotropy; /* 0..1 (0 = isotropic); alpha_x, alpha_y per Kulla-Conty/Burley */
    double ior;        /* dielectric coat (plastic) */
    bool compensate;   /* Kulla-Conty multiple-scattering energy compensation */
} sl_material;

/* Result of sl_bsdf_sample (a C name cannot be both a type and a function). */
typedef struct sl_bsdf_sample_rec {
    double wi[3]; /* sampled direction, local frame */
    double f[3];  /* BSDF value; for a delta lobe: F / |cos wi| so f*cos/pdf = weight */
    double pdf;   /* solid-angle pdf; for a delta lobe the probability of choosing it */
    bool delta;
} sl_bsdf_sample_rec;

/* Presets: grey 18% Lambert, chrome (measured reflectance documented in
 * docs/render-bsdf.md), generic conductor and plastic. All compensate. */
void sl_material_lambert(sl_material *m, double r, double g, double b);
void sl_material_chrome(sl_material *m);
void sl_material_conductor(sl_material *m, const double reflectance[3], const double edge_tint[3],
                           double roughness);
void sl_material_plastic(sl_material *m, const double albedo[3], double ior, double roughness);
/* Validates parameters: NaN/negative/out-of-range -> SL_ERR_INPUT naming the field. */
sl_result sl_material_check(const sl_material *m, sl_error *err);

/* Non-delta part of the BSDF (f, not multiplied by cos). */
void sl_bsdf_eval(const sl_material *m, const double wo[3], const double wi[3], double f[3]);
/* Solid-angle pdf of sl_bsdf_sample for the non-delta part. */
double sl_bsdf_pdf(const sl_material *m, const double wo[3], const double wi[3]);
/* Samples wi given three uniform numbers; false when no direction (e.g. below the surface). */
bool sl_bsdf_sample(const sl_material *m, const double wo[3], const double u[3],
                    sl_bsdf_sample_rec *s);
/* True when the material has only a delta lobe (mirror). Lets the integrator skip light sampling. */
bool sl_bsdf_is_delta(const sl_material *m);
/* Directional albedo: integral of f cos over the hemisphere for wo at cos_theta,
 * estimated with n stratified samples (for the furnace and tests). */
void sl_bsdf_albedo(const sl_material *m, double cos_theta, int n, double albedo[3]);

/* ================================================================== */
/* Scenes, lights, cameras, integrator                                 */
/* ================================================================== */

#ifdef __cplusplus
}
#endif

#endif /* SETLIGHT_RENDER_H */
