/* SPDX-License-Identifier: BSD-3-Clause */
/* Lookups into the directional-albedo tables. Interpolation is linear in
 * each coordinate so the tabulated averages stay exact for the interpolant. */
#include "energy.h"

#include <math.h>

#include "microfacet.h"

static void cell(double x, int n, int *i, double *f)
{
    x = fmin(fmax(x, 0.0), 1.0) * (n - 1);
    int k = (int)x;
    if (k > n - 2)
        k = n - 2;
    *i = k;
    *f = x - k;
}

/* Linear in mu between the nodes mu_i = x_i^3 (keeps the averages exact). */
static void mu_cell(double mu, int *i, double *f)
{
    mu = fmin(fmax(mu, 0.0), 1.0);
    cell(cbrt(mu), SL_E_NMU, i, f);
    double a = sl_energy_mu_node(*i), b = sl_energy_mu_node(*i + 1);
    *f = fmin(fmax((mu - a) / (b - a), 0.0), 1.0);
}

/* Linear in roughness between the nodes r_j = x_j^2. */
static void r_cell(double r, int *j, double *f)
{
    r = fmin(fmax(r, 0.0), 1.0);
    cell(sqrt(r), SL_E_NR, j, f);
    double a = sl_energy_r_node(*j), b = sl_energy_r_node(*j + 1);
    *f = fmin(fmax((r - a) / (b - a), 0.0), 1.0);
}

/* Linear in t between the nodes t_k = x_k^4. */
static void t_cell(double t, int *k, double *f)
{
    t = fmin(fmax(t, 0.0), 1.0);
    cell(sqrt(sqrt(t)), SL_E_NT, k, f);
    double a = sl_energy_t_node(*k), b = sl_energy_t_node(*k + 1);
    *f = fmin(fmax((t - a) / (b - a), 0.0), 1.0);
}

static double lerp(double a, double b, double f)
{
    return a + (b - a) * f;
}

double sl_energy_e1(double mu, double roughness)
{
    int i, j;
    double fi, fj;
    mu_cell(mu, &i, &fi);
    r_cell(roughness, &j, &fj);
    const float *r0 = sl_energy_e1_table[j], *r1 = sl_energy_e1_table[j + 1];
    return lerp(lerp(r0[i], r0[i + 1], fi), lerp(r1[i], r1[i + 1], fi), fj);
}

double sl_energy_e1_avg(double roughness)
{
    int j;
    double fj;
    r_cell(roughness, &j, &fj);
    return lerp(sl_energy_e1_avg_table[j], sl_energy_e1_avg_table[j + 1], fj);
}

static double ior_t(double ior)
{
    return ior > 1.0 ? (ior - 1.0) / (ior + 1.0) : 0.0;
}

double sl_energy_ed(double mu, double roughness, double ior)
{
    int i, j, k;
    double fi, fj, fk;
    mu_cell(mu, &i, &fi);
    r_cell(roughness, &j, &fj);
    t_cell(ior_t(ior), &k, &fk);
    double v[2];
    for (int d = 0; d < 2; d++) {
        const float *r0 = sl_energy_ed_table[k + d][j], *r1 = sl_energy_ed_table[k + d][j + 1];
        v[d] = lerp(lerp(r0[i], r0[i + 1], fi), lerp(r1[i], r1[i + 1], fi), fj);
    }
    return lerp(v[0], v[1], fk);
}

double sl_energy_ed_avg(double roughness, double ior)
{
    int j, k;
    double fj, fk;
    r_cell(roughness, &j, &fj);
    t_cell(ior_t(ior), &k, &fk);
    const float *a = sl_energy_ed_avg_table[k], *b = sl_energy_ed_avg_table[k + 1];
    return lerp(lerp(a[j], a[j + 1], fj), lerp(b[j], b[j + 1], fj), fk);
}

/* Anisotropy axis, linear in y between the nodes y_n = y(1) (n/NA)^2: node 0
 * is the isotropic table, node l+1 the slab l. */
static void a_cell(double a, int *l, double *f)
{
    a = fmin(fmax(a, 0.0), 1.0);
    double y = sl_energy_a_y(a);
    cell(sqrt(y / sl_energy_a_y(1.0)), SL_E_NA + 1, l, f);
    double ya = sl_energy_a_axis_y(*l), yb = sl_energy_a_axis_y(*l + 1);
    *f = fmin(fmax((y - ya) / (yb - ya), 0.0), 1.0);
}

static double ea_slab(int l, double mu, double phi, double roughness)
{
    int i, j, m;
    double fi, fj, fm;
    mu_cell(mu, &i, &fi);
    r_cell(roughness, &j, &fj);
    cell(phi / (0.5 * SL_PI), SL_E_NPHI, &m, &fm);
    double v[2];
    for (int d = 0; d < 2; d++) {
        const float *r0 = sl_energy_ea_table[l][m + d][j], *r1 = sl_energy_ea_table[l][m + d][j + 1];
        v[d] = lerp(lerp(r0[i], r0[i + 1], fi), lerp(r1[i], r1[i + 1], fi), fj);
    }
    return lerp(v[0], v[1], fm);
}

double sl_energy_ea(double mu, double phi, double roughness, double anisotropy)
{
    int l;
    double fl;
    a_cell(anisotropy, &l, &fl);
    double v0 = l == 0 ? sl_energy_e1(mu, roughness) : ea_slab(l - 1, mu, phi, roughness);
    return lerp(v0, ea_slab(l, mu, phi, roughness), fl);
}

double sl_energy_ea_avg(double roughness, double anisotropy)
{
    int l, j;
    double fl, fj;
    a_cell(anisotropy, &l, &fl);
    r_cell(roughness, &j, &fj);
    const float *b = sl_energy_ea_avg_table[l];
    double v0 = l == 0 ? sl_energy_e1_avg(roughness)
                       : lerp(sl_energy_ea_avg_table[l - 1][j], sl_energy_ea_avg_table[l - 1][j + 1], fj);
    return lerp(v0, lerp(b[j], b[j + 1], fj), fl);
}
