/* SPDX-License-Identifier: BSD-3-Clause */
/* BSDF dispatch, material presets and parameter checks. Models and
 * equations: docs/render-bsdf.md. */
#include <math.h>
#include <string.h>

#include "energy.h"
#include "fresnel.h"
#include "microfacet.h"
#include "setlight/render.h"

void sl_material_lambert(sl_material *m, double r, double g, double b)
{
    memset(m, 0, sizeof *m);
    m->type = SL_MAT_LAMBERT;
    m->base_color[0] = r;
    m->base_color[1] = g;
    m->base_color[2] = b;
    m->ior = 1.5;
    m->compensate = true;
}

void sl_material_conductor(sl_material *m, const double reflectance[3], const double edge_tint[3],
                           double roughness)
{
    memset(m, 0, sizeof *m);
    m->type = SL_MAT_CONDUCTOR;
    m->fresnel = SL_FRESNEL_ARTIST;
    for (int c = 0; c < 3; c++) {
        m->base_color[c] = reflectance[c];
        m->edge_tint[c] = edge_tint[c];
    }
    m->roughness = roughness;
    m->ior = 1.5;
    m->compensate = true;
}

void sl_material_chrome(sl_material *m)
{
    /* Chromium, linear reflectance at normal incidence from Hoffman 2013
     * ("Background: Physics and Math of Shading", table of F0 values). The
     * edge tint makes Gulbrandsen's mapping give n = 3.17, k = 3.32 at the
     * green channel, close to Johnson & Christy 1974 (n 3.17, k 3.30 at
     * 550 nm). A chrome ball is polished: a mirror. */
    static const double r[3] = {0.549, 0.556, 0.554};
    static const double g[3] = {0.559, 0.559, 0.559};
    sl_material_conductor(m, r, g, 0.0);
}

void sl_material_plastic(sl_material *m, const double albedo[3], double ior, double roughness)
{
    memset(m, 0, sizeof *m);
    m->type = SL_MAT_PLASTIC;
    m->fresnel = SL_FRESNEL_DIELECTRIC;
    for (int c = 0; c < 3; c++)
        m->base_color[c] = albedo[c];
    m->roughness = roughness;
    m->ior = ior;
    m->compensate = true;
}

static sl_result bad(sl_error *err, const char *field, const char *want, double got)
{
    return sl_error_set(err, SL_ERR_INPUT, "material %s: must be %s (got %g)", field, want, got);
}

sl_result sl_material_check(const sl_material *m, sl_error *err)
{
    if ((int)m->type < 0 || m->type >= SL_MAT_COUNT)
        return bad(err, "type", "a known material type", (double)m->type);
    if ((int)m->fresnel < 0 || m->fresnel > SL_FRESNEL_ONE)
        return bad(err, "fresnel", "a known Fresnel mode", (double)m->fresnel);
    static const char *const base[3] = {"base_color[0]", "base_color[1]", "base_color[2]"};
    static const char *const tint[3] = {"edge_tint[0]", "edge_tint[1]", "edge_tint[2]"};
    for (int c = 0; c < 3; c++) {
        /* NaN fails every comparison, so test for the valid range. */
        if (!(m->base_color[c] >= 0.0 && m->base_color[c] <= 1.0))
            return bad(err, base[c], "in [0, 1]", m->base_color[c]);
        if (!(m->edge_tint[c] >= 0.0 && m->edge_tint[c] <= 1.0))
            return bad(err, tint[c], "in [0, 1]", m->edge_tint[c]);
    }
    if (!(m->roughness >= 0.0 && m->roughness <= 1.0))
        return bad(err, "roughness", "in [0, 1]", m->roughness);
    if (!(m->anisotropy >= 0.0 && m->anisotropy <= 1.0))
        return bad(err, "anisotropy", "in [0, 1]", m->anisotropy);
    bool uses_ior = m->type == SL_MAT_PLASTIC ||
                    (m->type == SL_MAT_CONDUCTOR && m->fresnel == SL_FRESNEL_DIELECTRIC);
    if (uses_ior && !(m->ior >= 1.0 && m->ior <= 1e6))
        return bad(err, "ior", "in [1, 1e6]", m->ior);
    return SL_OK;
}

static bool smooth(const sl_material *m)
{
    return m->roughness < SL_ROUGHNESS_DELTA;
}

bool sl_bsdf_is_delta(const sl_material *m)
{
    return m->type == SL_MAT_CONDUCTOR && smooth(m);
}

static double mean3(const double v[3])
{
    return (v[0] + v[1] + v[2]) / 3.0;
}

/* Kulla-Conty: the multiple-scattering lobe's Fresnel factor
 * F_avg^2 E_avg / (1 - F_avg (1 - E_avg)) (the corrected form of the
 * 2017 course notes' appendix). */
static void ms_fresnel(const sl_material *m, double e_avg, double fms[3])
{
    double favg[3];
    sl_fresnel_average(m, favg);
    for (int c = 0; c < 3; c++)
        fms[c] = favg[c] * favg[c] * e_avg / (1.0 - favg[c] * (1.0 - e_avg));
}

/* E of the single-scattering lobe with F = 1 for direction w; anisotropic GGX
 * has its own tables over the azimuth of w (folded into [0, pi/2]). */
static double e1_of(const sl_material *m, const double w[3])
{
    if (m->anisotropy <= 0.0)
        return sl_energy_e1(w[2], m->roughness);
    return sl_energy_ea(w[2], atan2(fabs(w[1]), fabs(w[0])), m->roughness, m->anisotropy);
}

/* 1 - E_avg, the energy the compensation lobe restores at most; zero when
 * there is no compensation or no energy to speak of. */
static double ms_room(const sl_material *m)
{
    if (!m->compensate || smooth(m))
        return 0.0;
    double e_avg = m->anisotropy > 0.0 ? sl_energy_ea_avg(m->roughness, m->anisotropy)
                                       : sl_energy_e1_avg(m->roughness);
    double room = 1.0 - e_avg;
    return room > 1e-6 ? room : 0.0;
}

/* Single-scattering GGX reflection f with the material's Fresnel. */
static void ggx_eval(const sl_material *m, const double wo[3], const double wi[3], double f[3])
{
    double h[3];
    f[0] = f[1] = f[2] = 0.0;
    if (!sl_half_vector(wo, wi, h))
        return;
    sl_ggx g = sl_ggx_make(m->roughness, m->anisotropy);
    double dg = sl_ggx_d(g, h) * sl_ggx_g2(g, wo, wi) / (4.0 * wo[2] * wi[2]);
    double fr[3];
    double cos_h = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
    if (m->type == SL_MAT_PLASTIC)
        fr[0] = fr[1] = fr[2] = sl_fresnel_dielectric(cos_h, m->ior);
    else
        sl_fresnel_eval(m, cos_h, fr);
    for (int c = 0; c < 3; c++)
        f[c] = fr[c] * dg;
}

/* Directional albedo of the plastic's coat at mu (the 1 - E approach uses it
 * both for the diffuse weight and for lobe selection). */
static double coat_albedo(const sl_material *m, double mu)
{
    if (smooth(m))
        return sl_fresnel_dielectric(mu, m->ior);
    return sl_energy_ed(mu, m->roughness, m->ior);
}

/* Scale of the plastic's diffuse lobe (times base_color / pi). */
static double coat_diffuse_weight(const sl_material *m, double mu_o, double mu_i)
{
    if (!m->compensate)
        return (1.0 - sl_fresnel_dielectric(mu_o, m->ior)) *
               (1.0 - sl_fresnel_dielectric(mu_i, m->ior));
    double avg;
    if (smooth(m)) {
        double favg[3];
        sl_fresnel_average(m, favg);
        avg = favg[0];
    } else {
        avg = sl_energy_ed_avg(m->roughness, m->ior);
    }
    if (avg >= 1.0)
        return 0.0;
    return (1.0 - coat_albedo(m, mu_o)) * (1.0 - coat_albedo(m, mu_i)) / (1.0 - avg);
}

/* Probability of picking the specular lobe of a plastic. */
static double coat_spec_prob(const sl_material *m, double mu_o)
{
    double es = coat_albedo(m, mu_o);
    double ed = (1.0 - es) * mean3(m->base_color);
    return es + ed > 0.0 ? es / (es + ed) : 1.0;
}

void sl_bsdf_eval(const sl_material *m, const double wo[3], const double wi[3], double f[3])
{
    f[0] = f[1] = f[2] = 0.0;
    if (!(wo[2] > 0.0 && wi[2] > 0.0))
        return;
    switch (m->type) {
    case SL_MAT_LAMBERT:
        for (int c = 0; c < 3; c++)
            f[c] = m->base_color[c] / SL_PI;
        break;
    case SL_MAT_CONDUCTOR: {
        if (smooth(m))
            break;
        ggx_eval(m, wo, wi, f);
        double room = ms_room(m);
        if (room > 0.0) {
            double fms[3];
            ms_fresnel(m, 1.0 - room, fms);
            double k = (1.0 - e1_of(m, wo)) * (1.0 - e1_of(m, wi)) / (SL_PI * room);
            for (int c = 0; c < 3; c++)
                f[c] += fms[c] * k;
        }
        break;
    }
    case SL_MAT_PLASTIC: {
        if (!smooth(m))
            ggx_eval(m, wo, wi, f);
        double kd = coat_diffuse_weight(m, wo[2], wi[2]) / SL_PI;
        for (int c = 0; c < 3; c++)
            f[c] += m->base_color[c] * kd;
        break;
    }
    default:
        break;
    }
}

/* Probability of the cosine-sampled lobe (diffuse or multiple scattering). */
static double cosine_prob(const sl_material *m, const double wo[3])
{
    switch (m->type) {
    case SL_MAT_LAMBERT:
        return 1.0;
    case SL_MAT_CONDUCTOR:
        return ms_room(m) > 0.0 ? fmin(fmax(1.0 - e1_of(m, wo), 0.0), 1.0) : 0.0;
    case SL_MAT_PLASTIC:
        return 1.0 - coat_spec_prob(m, wo[2]);
    default:
        return 0.0;
    }
}

double sl_bsdf_pdf(const sl_material *m, const double wo[3], const double wi[3])
{
    if (!(wo[2] > 0.0 && wi[2] > 0.0))
        return 0.0;
    double pc = cosine_prob(m, wo);
    double pdf = pc * wi[2] / SL_PI;
    if (m->type != SL_MAT_LAMBERT && !smooth(m))
        pdf += (1.0 - pc) *
               sl_ggx_pdf_reflect(sl_ggx_make(m->roughness, m->anisotropy), wo, wi);
    return pdf;
}

bool sl_bsdf_sample(const sl_material *m, const double wo[3], const double u[3],
                    sl_bsdf_sample_rec *s)
{
    memset(s, 0, sizeof *s);
    if (!(wo[2] > 0.0))
        return false;
    double pc = cosine_prob(m, wo);
    if (u[2] < pc || pc >= 1.0) {
        double r = sqrt(u[0]), phi = 2.0 * SL_PI * u[1];
        s->wi[0] = r * cos(phi);
        s->wi[1] = r * sin(phi);
        s->wi[2] = sqrt(fmax(0.0, 1.0 - u[0]));
    } else if (smooth(m)) {
        /* The delta lobe: mirror of a smooth conductor or of the plastic's coat. */
        s->wi[0] = -wo[0];
        s->wi[1] = -wo[1];
        s->wi[2] = wo[2];
        double fr[3];
        if (m->type == SL_MAT_PLASTIC)
            fr[0] = fr[1] = fr[2] = sl_fresnel_dielectric(wo[2], m->ior);
        else
            sl_fresnel_eval(m, wo[2], fr);
        for (int c = 0; c < 3; c++)
            s->f[c] = fr[c] / wo[2];
        s->pdf = 1.0 - pc;
        s->delta = true;
        return true;
    } else {
        double h[3];
        sl_ggx_sample_vndf(sl_ggx_make(m->roughness, m->anisotropy), wo, u[0], u[1], h);
        sl_reflect(wo, h, s->wi);
    }
    if (!(s->wi[2] > 0.0))
        return false;
    sl_bsdf_eval(m, wo, s->wi, s->f);
    s->pdf = sl_bsdf_pdf(m, wo, s->wi);
    return s->pdf > 0.0;
}

void sl_bsdf_albedo(const sl_material *m, double cos_theta, int n, double albedo[3])
{
    albedo[0] = albedo[1] = albedo[2] = 0.0;
    cos_theta = fmin(fmax(cos_theta, 1e-9), 1.0);
    double wo[3] = {sqrt(1.0 - cos_theta * cos_theta), 0.0, cos_theta};
    int k = (int)sqrt((double)(n > 1 ? n : 1));
    for (int i = 0; i < k; i++)
        for (int j = 0; j < k; j++) {
            /* Stratified in the direction, with u0 = 1 - (1-t)^3 packing strata
             * at the GGX tail (see energy_integrate.c), each weighted by its
             * exact width; a Weyl sequence picks the lobe. */
            double ta = 1.0 - (double)i / k, tb = 1.0 - (i + 1.0) / k, tm = 0.5 * (ta + tb);
            double u[3] = {1.0 - tm * tm * tm, (j + 0.5) / k,
                           fmod(0.5 + 0.6180339887498949 * (i * k + j), 1.0)};
            sl_bsdf_sample_rec s;
            if (!sl_bsdf_sample(m, wo, u, &s))
                continue;
            double w = (ta * ta * ta - tb * tb * tb) * k;
            for (int c = 0; c < 3; c++)
                albedo[c] += w * s.f[c] * s.wi[2] / s.pdf;
        }
    for (int c = 0; c < 3; c++)
        albedo[c] /= (double)k * k;
}
