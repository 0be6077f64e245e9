/* SPDX-License-Identifier: BSD-3-Clause */
/* The glossy quadrature evaluates f thousands of times per pixel with one
 * material and one view: the conductor's complex Fresnel, its hemispherical
 * average (Kulla-Conty) and the energy-table lookups, which led the profile
 * of sl_bsdf_eval there, are taken out of the loop.
 *
 * - Fresnel: a table over cos in [0, 1] every 1/4096, linear between
 *   entries; its largest relative error (measured at every interval's
 *   midpoint when built, about 1e-7) is reported, and the quadrature adds
 *   it to its error estimate.
 * - 1 - E(mu): the energy tables are linear in mu between their nodes at
 *   fixed roughness (and index), so the row at the material's roughness is
 *   the same function, found by a guide table instead of a cube root.
 * - The multiple-scattering (conductor) or diffuse (plastic) lobe's factors
 *   that depend on wo alone are computed once per view.
 * GGX D is the isotropic form of microfacet.c's; G2 is its height-correlated
 * Smith term, Lambda(wo) once per view. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "energy.h"
#include "fresnel.h"
#include "glossy_kernel.h"
#include "microfacet.h"

static double one_minus_e(const sl_material *m, double mu)
{
    return m->type == SL_MAT_PLASTIC ? 1.0 - sl_energy_ed(mu, m->roughness, m->ior)
                                     : 1.0 - sl_energy_e1(mu, m->roughness);
}

static void fresnel_at(const sl_material *m, double c, double f[3])
{
    if (m->type == SL_MAT_PLASTIC)
        f[0] = f[1] = f[2] = sl_fresnel_dielectric(c, m->ior);
    else
        sl_fresnel_eval(m, c, f);
}

sl_result sl_glossy_material_init(sl_glossy_material *gm, const sl_material *m, sl_error *err)
{
    memset(gm, 0, sizeof *gm);
    gm->m = m;
    gm->fast = (m->type == SL_MAT_CONDUCTOR || m->type == SL_MAT_PLASTIC) && m->compensate &&
               m->anisotropy <= 0.0 && m->roughness >= SL_ROUGHNESS_DELTA;
    if (!gm->fast)
        return SL_OK;
    gm->ggx = sl_ggx_make(m->roughness, 0.0);
    gm->alpha2 = gm->ggx.ax * gm->ggx.ay;
    gm->fresnel = malloc((SL_GLOSSY_FRESNEL_N + 1) * sizeof *gm->fresnel);
    if (!gm->fresnel)
        return sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the glossy tables");
    const int N = SL_GLOSSY_FRESNEL_N;
    for (int i = 0; i <= N; i++) {
        double f[3];
        /* cos_h = wo.h > 0 always; the first entry holds F just above 0. */
        fresnel_at(m, i > 0 ? (double)i / N : 1e-9, f);
        for (int c = 0; c < 3; c++)
            gm->fresnel[i][c] = (float)f[c];
    }
    for (int i = 0; i < N; i++) {
        double f[3];
        fresnel_at(m, (i + 0.5) / N, f);
        for (int c = 0; c < 3; c++) {
            double lin = 0.5 * ((double)gm->fresnel[i][c] + gm->fresnel[i + 1][c]);
            if (f[c] > 0)
                gm->fresnel_rel_error = fmax(gm->fresnel_rel_error, fabs(lin - f[c]) / f[c]);
        }
    }
    for (int i = 0; i < SL_E_NMU; i++) {
        gm->e_node[i] = sl_energy_mu_node(i);
        gm->e_row[i] = one_minus_e(m, gm->e_node[i]);
    }
    for (int b = 0, k = 0; b <= 1024; b++) {
        while (k < SL_E_NMU - 2 && gm->e_node[k + 1] <= b / 1024.0)
            k++;
        gm->guide[b] = (unsigned char)k;
    }
    if (m->type == SL_MAT_CONDUCTOR) {
        double e_avg = sl_energy_e1_avg(m->roughness), room = 1.0 - e_avg, favg[3];
        if (room > 1e-6) {
            sl_fresnel_average(m, favg);
            for (int c = 0; c < 3; c++)
                gm->albedo_scale[c] = favg[c] * favg[c] * e_avg / (1.0 - favg[c] * (1.0 - e_avg)) /
                                      (SL_PI * room);
        } else {
            for (int i = 0; i < SL_E_NMU; i++)
                gm->e_row[i] = 0.0; /* no compensation lobe */
        }
    } else {
        double avg = sl_energy_ed_avg(m->roughness, m->ior);
        for (int c = 0; c < 3; c++)
            gm->albedo_scale[c] = avg < 1.0 ? m->base_color[c] / (SL_PI * (1.0 - avg)) : 0.0;
    }
    return SL_OK;
}

void sl_glossy_material_free(sl_glossy_material *gm)
{
    free(gm->fresnel);
    memset(gm, 0, sizeof *gm);
}

/* Clamps without libm's fmin/fmax calls (not inlined without
 * -ffinite-math-only); x is never NaN here. */
static inline double clamp01(double x) { return x < 0.0 ? 0.0 : x > 1.0 ? 1.0 : x; }

/* 1 - E(mu): linear between the energy tables' mu nodes. */
static inline double e_lookup(const sl_glossy_material *gm, double mu)
{
    mu = clamp01(mu);
    int k = gm->guide[(int)(mu * 1024.0)];
    while (k < SL_E_NMU - 2 && gm->e_node[k + 1] <= mu)
        k++;
    double a = gm->e_node[k], b = gm->e_node[k + 1];
    double f = clamp01((mu - a) / (b - a));
    return gm->e_row[k] + (gm->e_row[k + 1] - gm->e_row[k]) * f;
}

void sl_glossy_view_init(sl_glossy_view *v, const sl_glossy_material *gm, const double wo[3])
{
    memset(v, 0, sizeof *v);
    v->gm = gm;
    memcpy(v->wo, wo, sizeof v->wo);
    if (!gm->fast || !(wo[2] > 0))
        return;
    v->one_lambda_o = 1.0 + sl_ggx_lambda(gm->ggx, wo);
    /* alpha^2 / pi x 1 / (4 wo.z) x the 2 of G2's numerator */
    v->spec_coef = gm->alpha2 / (2.0 * SL_PI * wo[2]);
    double eo = e_lookup(gm, wo[2]);
    for (int c = 0; c < 3; c++)
        v->cos_lobe[c] = gm->albedo_scale[c] * eo;
}

void sl_glossy_kernel(const sl_glossy_view *v, const double wi[3], double k[3])
{
    const sl_glossy_material *gm = v->gm;
    k[0] = k[1] = k[2] = 0;
    if (!(v->wo[2] > 0.0 && wi[2] > 0.0))
        return;
    if (!gm->fast) {
        sl_bsdf_eval(gm->m, v->wo, wi, k);
        for (int c = 0; c < 3; c++)
            k[c] *= wi[2];
        return;
    }
    double h[3] = {v->wo[0] + wi[0], v->wo[1] + wi[1], v->wo[2] + wi[2]};
    double l2 = h[0] * h[0] + h[1] * h[1] + h[2] * h[2];
    double spec = 0, f[3] = {0, 0, 0};
    if (l2 > 0.0) {
        double cos_h = (v->wo[0] * h[0] + v->wo[1] * h[1] + v->wo[2] * h[2]) / sqrt(l2);
        if (h[2] > 0.0) {
            /* D G2 / (4 wo.z) with one division: for the unit half vector
             * D = alpha^2 l2^2 / (pi u^2), u = h.z^2 (alpha^2 - 1) + l2; for
             * wi, 1 + Lambda = (z + r) / (2 z) with r = sqrt(z^2 + q), q =
             * alpha^2 (x^2 + y^2), so G2 = 2 z (z + r) / (2 z (z + r)
             * (1 + Lambda(wo)) + q). */
            double z = wi[2], q = gm->alpha2 * (wi[0] * wi[0] + wi[1] * wi[1]);
            double zr = z * (z + sqrt(z * z + q));
            double u = h[2] * h[2] * (gm->alpha2 - 1.0) + l2;
            spec = v->spec_coef * l2 * l2 * zr / (u * u * (2.0 * zr * v->one_lambda_o + q));
        }
        double x = clamp01(cos_h) * SL_GLOSSY_FRESNEL_N;
        int i = (int)x;
        if (i > SL_GLOSSY_FRESNEL_N - 1)
            i = SL_GLOSSY_FRESNEL_N - 1;
        double fr = x - i;
        for (int c = 0; c < 3; c++)
            f[c] = gm->fresnel[i][c] + (gm->fresnel[i + 1][c] - gm->fresnel[i][c]) * fr;
    }
    double ei = e_lookup(gm, wi[2]) * wi[2];
    for (int c = 0; c < 3; c++)
        k[c] = f[c] * spec + v->cos_lobe[c] * ei;
}

