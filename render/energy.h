/* SPDX-License-Identifier: BSD-3-Clause */
/* Directional-albedo tables for Kulla-Conty multiple-scattering compensation
 * (Kulla & Conty 2017) and for the energy-conserving diffuse-under-coat
 * (the "1 - E" approach). Tables are generated offline by
 * scripts/gen_energy_tables.c into render/energy_tables.c. Private to render/. */
#ifndef SETLIGHT_RENDER_ENERGY_H
#define SETLIGHT_RENDER_ENERGY_H

/* Grid: mu_i = (i/(NMU-1))^3, roughness_j = (j/(NR-1))^2 (perceptual,
 * alpha = r^2) and t_k = (k/(NT-1))^4 with t = (ior-1)/(ior+1) = sqrt(F0): dense
 * at grazing, low roughness and index near 1, where E changes fastest (on a
 * scale of mu ~ alpha, and of ior - 1 ~ mu^2 / 2 at grazing). Entry mu = 0
 * holds the value at mu = 1e-6. Averages are exact for the piecewise-linear-in-mu
 * interpolant, so int (1 - E(mu)) mu dmu matches (1 - E_avg)/2 exactly and the
 * compensation lobes integrate to what they claim. */
#define SL_E_NMU 32
#define SL_E_NR 32
#define SL_E_NT 20

/* Anisotropic GGX with F = 1: nodes in y = 1/aspect - 1 = ax/alpha - 1 at
 * y_l = y(1) ((l+1)/NA)^2, y = 0 being the isotropic table; E bends most near
 * y = 0 (at azimuth 0 it rises, then falls), so the nodes are densest there.
 * The azimuth of wo is folded into [0, pi/2], phi_m = m/(NPHI-1) pi/2 (E is
 * symmetric about both axes of the anisotropy). Interpolation is linear in y
 * and phi between nodes. The average over the hemisphere is exact for the
 * interpolant (trapezoid over phi of the row averages), so the compensation
 * lobe closes energy exactly as in the isotropic case. */
#define SL_E_NA 8
#define SL_E_NPHI 9

/* E(mu, r) of the single-scattering isotropic GGX lobe with F = 1. */
extern const float sl_energy_e1_table[SL_E_NR][SL_E_NMU];
extern const float sl_energy_e1_avg_table[SL_E_NR];
/* The same with the exact dielectric Fresnel of index (1+t)/(1-t). */
extern const float sl_energy_ed_table[SL_E_NT][SL_E_NR][SL_E_NMU];
extern const float sl_energy_ed_avg_table[SL_E_NT][SL_E_NR];

extern const float sl_energy_ea_table[SL_E_NA][SL_E_NPHI][SL_E_NR][SL_E_NMU];
extern const float sl_energy_ea_avg_table[SL_E_NA][SL_E_NR];

/* Single-scattering directional albedo by stratified VNDF quadrature with
 * k x k samples: F = 1 when ior <= 0, else the exact dielectric Fresnel.
 * Roughness below SL_ROUGHNESS_DELTA is the mirror: E = F(mu). */
double sl_energy_integrate(double mu, double roughness, double ior, int k);
/* The same for anisotropic GGX with F = 1 and wo at azimuth phi. */
double sl_energy_integrate_aniso(double mu, double phi, double roughness, double anisotropy,
                                 int k);
/* Positions of the mu, roughness, anisotropy and azimuth nodes. */
double sl_energy_a_node(int l);
/* The anisotropy axis coordinate y = 1/sqrt(1 - 0.9 a) - 1, and y of axis
 * node n (0: the isotropic table, n >= 1: anisotropic slab n - 1). */
double sl_energy_a_y(double anisotropy);
double sl_energy_a_axis_y(int n);
double sl_energy_phi_node(int m);
double sl_energy_mu_node(int i);
double sl_energy_r_node(int j);
double sl_energy_t_node(int k);
/* Index of slab k: (1+t)/(1-t), or 0 (meaning F = 1) for t = 1. */
double sl_energy_t_ior(int k);
/* Exact 2 int E mu dmu of the piecewise-linear (in mu) interpolant through e[]. */
double sl_energy_average(const double e[SL_E_NMU]);

/* Interpolated lookups (bilinear / trilinear), arguments clamped to the grid. */
double sl_energy_e1(double mu, double roughness);
double sl_energy_e1_avg(double roughness);
double sl_energy_ed(double mu, double roughness, double ior);
double sl_energy_ed_avg(double roughness, double ior);
/* Anisotropic E at |azimuth| folded into [0, pi/2], and its hemispherical average. */
double sl_energy_ea(double mu, double phi, double roughness, double anisotropy);
double sl_energy_ea_avg(double roughness, double anisotropy);

#endif
