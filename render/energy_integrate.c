/* SPDX-License-Identifier: BSD-3-Clause */
/* Quadrature behind the energy tables; shared by the offline generator and
 * the test that checks the committed tables are current. */
#include <math.h>

#include "energy.h"
#include "fresnel.h"
#include "microfacet.h"

static double integrate(double mu, double phi, double roughness, double anisotropy, double ior,
                        int k)
{
    mu = fmin(fmax(mu, 1e-6), 1.0);
    if (roughness < SL_ROUGHNESS_DELTA)
        return ior > 0.0 ? sl_fresnel_dielectric(mu, ior) : 1.0;
    sl_ggx g = sl_ggx_make(roughness, anisotropy);
    double s = sqrt(1.0 - mu * mu);
    double wo[3] = {s * cos(phi), s * sin(phi), mu};
    double sum = 0.0;
    for (int i = 0; i < k; i++) {
        /* u1 = 1 - (1-s)^3 packs strata near u1 = 1, where the heavy GGX tail
         * sends wi below the horizon (a uniform grid resolves that edge badly);
         * each stratum is weighted by its exact width. */
        double qa = 1.0 - (double)i / k, qb = 1.0 - (i + 1.0) / k, qm = 0.5 * (qa + qb);
        double u1 = 1.0 - qm * qm * qm, jac = (qa * qa * qa - qb * qb * qb) * k;
        for (int j = 0; j < k; j++) {
            double h[3], wi[3];
            sl_ggx_sample_vndf(g, wo, u1, (j + 0.5) / k, h);
            sl_reflect(wo, h, wi);
            if (wi[2] <= 0.0)
                continue;
            /* f cos / pdf = F G2 / G1 for VNDF sampling. */
            double w = sl_ggx_g2(g, wo, wi) / sl_ggx_g1(g, wo);
            double cos_h = wo[0] * h[0] + wo[1] * h[1] + wo[2] * h[2];
            sum += jac * (ior > 0.0 ? w * sl_fresnel_dielectric(cos_h, ior) : w);
        }
    }
    return sum / ((double)k * k);
}

double sl_energy_integrate(double mu, double roughness, double ior, int k)
{
    return integrate(mu, 0.0, roughness, 0.0, ior, k);
}

double sl_energy_integrate_aniso(double mu, double phi, double roughness, double anisotropy,
                                 int k)
{
    return integrate(mu, phi, roughness, anisotropy, 0.0, k);
}

double sl_energy_a_y(double anisotropy)
{
    return 1.0 / sqrt(1.0 - 0.9 * anisotropy) - 1.0;
}

double sl_energy_a_axis_y(int n)
{
    double x = (double)n / SL_E_NA;
    return x * x * sl_energy_a_y(1.0);
}

double sl_energy_a_node(int l)
{
    if (l == SL_E_NA - 1)
        return 1.0;
    double aspect = 1.0 / (1.0 + sl_energy_a_axis_y(l + 1));
    return fmin((1.0 - aspect * aspect) / 0.9, 1.0);
}

double sl_energy_phi_node(int m)
{
    return 0.5 * SL_PI * m / (SL_E_NPHI - 1);
}

double sl_energy_mu_node(int i)
{
    double x = (double)i / (SL_E_NMU - 1);
    return x * x * x;
}

double sl_energy_r_node(int j)
{
    double x = (double)j / (SL_E_NR - 1);
    return x * x;
}

double sl_energy_t_node(int k)
{
    double x = (double)k / (SL_E_NT - 1);
    return x * x * x * x;
}

double sl_energy_t_ior(int k)
{
    double t = sl_energy_t_node(k);
    return k == SL_E_NT - 1 ? 0.0 : (1.0 + t) / (1.0 - t);
}

double sl_energy_average(const double e[SL_E_NMU])
{
    double s = 0.0;
    for (int i = 0; i + 1 < SL_E_NMU; i++) {
        double a = sl_energy_mu_node(i), b = sl_energy_mu_node(i + 1), h = b - a;
        s += h * (e[i] * (2.0 * a + b) + e[i + 1] * (a + 2.0 * b)) / 6.0;
    }
    return 2.0 * s;
}
