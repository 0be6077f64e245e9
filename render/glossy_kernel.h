/* SPDX-License-Identifier: BSD-3-Clause */
/* The glossy quadrature's integrand k(wi) = f(wo, wi) wi.z with what does
 * not depend on wi computed once (glossy_kernel.c). Private to render/. */
#ifndef SETLIGHT_RENDER_GLOSSY_KERNEL_H
#define SETLIGHT_RENDER_GLOSSY_KERNEL_H

#include <stdbool.h>
#include "microfacet.h"
#include "setlight/render.h"

/* Cosines of the Fresnel table: 1/4096 apart. */
#define SL_GLOSSY_FRESNEL_N 4096

/* Per material, built once per render. fast: isotropic and compensated,
 * the case the tables cover; any other material is evaluated by
 * sl_bsdf_eval itself. */
typedef struct sl_glossy_material {
    const sl_material *m;
    bool fast;
    sl_ggx ggx;
    double alpha2;            /* GGX alpha^2 */
    float (*fresnel)[3];      /* F(i / N), i = 0..N, per channel */
    double fresnel_rel_error; /* largest relative error of its linear interpolation */
    double e_row[32];         /* 1 - E(mu) at the energy tables' mu nodes */
    double e_node[32];
    unsigned char guide[1025]; /* node index of mu = b / 1024 */
    double albedo_scale[3];   /* the cosine lobe: (1 - E(mu_o)) (1 - E(mu_i)) times this */
} sl_glossy_material;

/* Per (material, view): wo in the shading frame. */
typedef struct sl_glossy_view {
    const sl_glossy_material *gm;
    double wo[3];
    double one_lambda_o; /* 1 + Smith Lambda(wo) */
    double spec_coef;    /* alpha^2 / (2 pi wo.z) */
    double cos_lobe[3]; /* albedo_scale (1 - E(mu_o)) */
} sl_glossy_view;

sl_result sl_glossy_material_init(sl_glossy_material *gm, const sl_material *m, sl_error *err);
void sl_glossy_material_free(sl_glossy_material *gm);
void sl_glossy_view_init(sl_glossy_view *v, const sl_glossy_material *gm, const double wo[3]);
/* k = f(wo, wi) max(0, wi.z) per channel, wi in the shading frame; equal to
 * sl_bsdf_eval's within gm->fresnel_rel_error of the specular term. */
void sl_glossy_kernel(const sl_glossy_view *v, const double wi[3], double k[3]);

#endif
