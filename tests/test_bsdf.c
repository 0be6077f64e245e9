/* SPDX-License-Identifier: BSD-3-Clause */
/* BSDFs: Fresnel known values, reciprocity, energy bounds, parameter checks
 * and chi-square goodness-of-fit of every sampler against its pdf (after
 * pbrt-v4's bsdfs_test.cpp: (theta, phi) histogram, expected counts from the
 * pdf integrated over each cell, cells with expected < 5 pooled, Sidak-corrected
 * significance, outright failure for samples where the pdf is zero). */
#include <complex.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "../render/fresnel.h"
#include "setlight/render.h"
#include "testing.h"

#define PI 3.14159265358979323846

static uint64_t rng = SL_SPLITMIX64_INCREMENT;

static double rnd(void) { return sl_test_uniform(&rng); }

static void dir(double cos_theta, double phi, double w[3])
{
    double s = sqrt(fmax(0.0, 1.0 - cos_theta * cos_theta));
    w[0] = s * cos(phi);
    w[1] = s * sin(phi);
    w[2] = cos_theta;
}

static const double one[3] = {1.0, 1.0, 1.0};
static const double chrome_tint[3] = {0.559, 0.559, 0.559};
static const double gold[3] = {1.0, 0.766, 0.336};

static sl_material conductor(const double r[3], const double g[3], double rough, double aniso,
                             bool comp)
{
    sl_material m;
    sl_material_conductor(&m, r, g, rough);
    m.anisotropy = aniso;
    m.compensate = comp;
    return m;
}

static sl_material white_conductor(double rough, double aniso, bool comp)
{
    sl_material m = conductor(one, one, rough, aniso, comp);
    m.fresnel = SL_FRESNEL_ONE;
    return m;
}

static sl_material plastic(const double a[3], double ior, double rough, bool comp)
{
    sl_material m;
    sl_material_plastic(&m, a, ior, rough);
    m.compensate = comp;
    return m;
}

/* ---- Fresnel and presets ------------------------------------------- */

static void test_fresnel_known_values(void)
{
    /* Dielectric at normal incidence: ((n-1)/(n+1))^2; p-polarisation vanishes at
     * Brewster's angle, leaving rs^2/2 there. */
    sl_material m;
    double g[3] = {0.5, 0.5, 0.5};
    sl_material_plastic(&m, g, 1.5, 0.0);
    double f[3];
    sl_bsdf_sample_rec s;
    double wo[3] = {0.0, 0.0, 1.0};
    /* The smooth plastic's delta sample carries F(1) / cos. */
    bool got = false;
    for (int i = 0; i < 64 && !got; i++) {
        double u[3] = {0.3, 0.3, i / 64.0};
        if (sl_bsdf_sample(&m, wo, u, &s) && s.delta) {
            CHECK_NEAR(s.f[0], 0.04, 1e-12);
            got = true;
        }
    }
    CHECK(got);
    /* Brewster: tan(theta_B) = 1.5; rs = (cos_i - n cos_t)/(cos_i + n cos_t). */
    double tb = atan(1.5), ci = cos(tb), ct = sqrt(1.0 - sin(tb) * sin(tb) / 2.25);
    double rs = (ci - 1.5 * ct) / (ci + 1.5 * ct);
    double wb[3];
    dir(ci, 0.0, wb);
    got = false;
    for (int i = 0; i < 64 && !got; i++) {
        double u[3] = {0.3, 0.3, i / 64.0};
        if (sl_bsdf_sample(&m, wb, u, &s) && s.delta) {
            CHECK_NEAR(s.f[0] * ci, 0.5 * rs * rs, 1e-12);
            got = true;
        }
    }
    CHECK(got);

    /* Chrome mirror: reflectance at normal incidence is the documented F0
     * (Gulbrandsen's mapping reproduces r exactly); weight f cos / pdf = F. */
    sl_material_chrome(&m);
    CHECK(sl_bsdf_is_delta(&m));
    double u[3] = {0.1, 0.2, 0.3};
    CHECK(sl_bsdf_sample(&m, wo, u, &s));
    CHECK(s.delta);
    CHECK_NEAR(s.pdf, 1.0, 0);
    CHECK_NEAR(s.f[0] * s.wi[2] / s.pdf, 0.549, 1e-9);
    CHECK_NEAR(s.f[1] * s.wi[2] / s.pdf, 0.556, 1e-9);
    CHECK_NEAR(s.f[2] * s.wi[2] / s.pdf, 0.554, 1e-9);
    /* Mirror direction at an oblique angle; the reflectance there matches the
     * Fresnel equations in complex arithmetic with Gulbrandsen's n, k. */
    double wg[3];
    dir(0.2, 1.0, wg);
    CHECK(sl_bsdf_sample(&m, wg, u, &s));
    CHECK_NEAR(s.wi[0], -wg[0], 1e-15);
    CHECK_NEAR(s.wi[1], -wg[1], 1e-15);
    CHECK_NEAR(s.wi[2], wg[2], 1e-15);
    double r = 0.556, tint = 0.559, sr = sqrt(r);
    double n = tint * (1 - r) / (1 + r) + (1 - tint) * (1 + sr) / (1 - sr);
    double k = sqrt((r * (n + 1) * (n + 1) - (n - 1) * (n - 1)) / (1 - r));
    CHECK_NEAR(n, 3.19, 0.01); /* Johnson & Christy chromium at 550 nm: 3.17 + 3.30i */
    CHECK_NEAR(k, 3.33, 0.02);
    double complex eta = n + k * I;
    double cg = 0.2, si2 = 1.0 - cg * cg;
    double complex cgt = csqrt(1.0 - si2 / (eta * eta));
    double complex zs = (cg - eta * cgt) / (cg + eta * cgt);
    double complex zp = (eta * cg - cgt) / (eta * cg + cgt);
    double fresnel = 0.5 * (creal(zs * conj(zs)) + creal(zp * conj(zp)));
    CHECK_NEAR(s.f[1] * s.wi[2], fresnel, 1e-12);
    dir(1e-6, 0.0, wg);
    CHECK(sl_bsdf_sample(&m, wg, u, &s));
    CHECK_NEAR(s.f[1] * s.wi[2], 1.0, 1e-4);
    /* The non-delta part of a mirror is empty. */
    sl_bsdf_eval(&m, wo, wo, f);
    CHECK(f[0] == 0.0 && f[1] == 0.0 && f[2] == 0.0);
    CHECK(sl_bsdf_pdf(&m, wo, wo) == 0.0);

    /* Schlick conductor mirror: F0 + (1-F0)(1-cos)^5. */
    sl_material sch = conductor(gold, one, 0.0, 0.0, true);
    sch.fresnel = SL_FRESNEL_SCHLICK;
    dir(0.3, 0.0, wg);
    CHECK(sl_bsdf_sample(&sch, wg, u, &s));
    CHECK_NEAR(s.f[2] * 0.3, 0.336 + 0.664 * pow(0.7, 5.0), 1e-12);
}

/* F_avg = 2 int F mu dmu against a fine midpoint rule. */
static void test_fresnel_average(void)
{
    static const double r[3] = {0.549, 0.9, 0.05}, g[3] = {0.559, 0.1, 0.9};
    sl_material m;
    sl_material_conductor(&m, r, g, 0.5);
    for (int mode = 0; mode < 4; mode++) {
        m.fresnel = (sl_fresnel_mode)mode;
        m.ior = mode == SL_FRESNEL_DIELECTRIC ? 400.0 : 1.5;
        double fa[3], ref[3] = {0, 0, 0};
        sl_fresnel_average(&m, fa);
        const int n = 100000;
        for (int i = 0; i < n; i++) {
            double mu = (i + 0.5) / n, f[3];
            sl_fresnel_eval(&m, mu, f);
            for (int c = 0; c < 3; c++)
                ref[c] += 2.0 * f[c] * mu / n;
        }
        for (int c = 0; c < 3; c++)
            CHECK_NEAR(fa[c], ref[c], 1e-4);
    }
    /* Exact dielectric, ior 1.5: F_avg = 0.0917780 (the midpoint value). */
    m.fresnel = SL_FRESNEL_DIELECTRIC;
    m.ior = 1.5;
    double fa[3];
    sl_fresnel_average(&m, fa);
    CHECK_NEAR(fa[0], 0.091778, 2e-6);
}

/* The average is remembered per thread for the last material: alternating
 * materials that differ in one Fresnel field each must each get their own
 * (a midpoint rule with 4096 steps is the independent answer). */
static void test_fresnel_average_memo(void)
{
    sl_material ms[5];
    const double r[3] = {0.9, 0.6, 0.3}, g[3] = {1, 1, 1}, g2[3] = {1, 0.2, 1};
    sl_material_conductor(&ms[0], r, g, 0.3);
    sl_material_conductor(&ms[1], r, g2, 0.3); /* edge tint differs */
    ms[2] = ms[0];
    ms[2].base_color[2] = 0.31;                /* one reflectance differs */
    sl_material_plastic(&ms[3], r, 1.5, 0.3);
    ms[3].fresnel = SL_FRESNEL_DIELECTRIC;
    ms[4] = ms[3];
    ms[4].ior = 1.33; /* ior differs */
    double want[5][3];
    for (int i = 0; i < 5; i++) {
        want[i][0] = want[i][1] = want[i][2] = 0;
        for (int k = 0; k < 4096; k++) {
            double mu = (k + 0.5) / 4096, f[3];
            sl_fresnel_eval(&ms[i], mu, f);
            for (int c = 0; c < 3; c++)
                want[i][c] += 2 * f[c] * mu / 4096;
        }
    }
    /* each neighbour pair differs in one field */
    static const int order[] = {0, 1, 0, 2, 0, 3, 4, 3, 1, 1, 2};
    int wrong = 0;
    for (size_t i = 0; i < sizeof order / sizeof order[0]; i++) {
        double fa[3];
        sl_fresnel_average(&ms[order[i]], fa);
        for (int c = 0; c < 3; c++)
            wrong += !(fabs(fa[c] - want[order[i]][c]) < 1e-4);
    }
    CHECK(wrong == 0);
}

static void test_lambert_exact(void)
{
    sl_material m;
    sl_material_lambert(&m, 0.18, 0.18, 0.18);
    double wo[3], wi[3], f[3];
    dir(0.6, 0.3, wo);
    dir(0.2, 2.0, wi);
    sl_bsdf_eval(&m, wo, wi, f);
    CHECK_NEAR(f[0], 0.18 / PI, 1e-15);
    CHECK_NEAR(sl_bsdf_pdf(&m, wo, wi), 0.2 / PI, 1e-15);
    wi[2] = -wi[2];
    sl_bsdf_eval(&m, wo, wi, f);
    CHECK(f[0] == 0.0);
    double a[3];
    for (int i = 0; i < 3; i++) {
        double mu = (double[]){1e-6, 0.3, 1.0}[i];
        sl_bsdf_albedo(&m, mu, 1024, a);
        CHECK_NEAR(a[0], 0.18, 1e-12);
    }
    CHECK(!sl_bsdf_is_delta(&m));
}

static void test_material_check(void)
{
    sl_error err;
    sl_material m;
    sl_material_chrome(&m);
    CHECK_OK(sl_material_check(&m, &err), &err);
    sl_material_plastic(&m, one, 1.5, 0.4);
    CHECK_OK(sl_material_check(&m, &err), &err);

    sl_material bad = m;
    bad.roughness = NAN;
    CHECK_RESULT(sl_material_check(&bad, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "roughness") != NULL);
    bad = m;
    bad.roughness = 1.5;
    CHECK_RESULT(sl_material_check(&bad, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "roughness") != NULL);
    bad = m;
    bad.base_color[1] = -0.1;
    CHECK_RESULT(sl_material_check(&bad, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "base_color[1]") != NULL);
    bad = m;
    bad.edge_tint[2] = INFINITY;
    CHECK_RESULT(sl_material_check(&bad, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "edge_tint[2]") != NULL);
    bad = m;
    bad.ior = 0.5;
    CHECK_RESULT(sl_material_check(&bad, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "ior") != NULL);
    bad = m;
    bad.anisotropy = -1e-3;
    CHECK_RESULT(sl_material_check(&bad, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "anisotropy") != NULL);
    bad = m;
    bad.type = SL_MAT_COUNT;
    CHECK_RESULT(sl_material_check(&bad, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "type") != NULL);
    CHECK_RESULT(sl_material_check(&bad, NULL), SL_ERR_INPUT, NULL);
    /* A Lambert material does not use ior; zero there is fine. */
    sl_material_lambert(&m, 0.5, 0.5, 0.5);
    m.ior = 0.0;
    CHECK_OK(sl_material_check(&m, &err), &err);
}

/* ---- reciprocity and energy ---------------------------------------- */

static int test_materials(sl_material *out)
{
    static const double grey[3] = {0.5, 0.3, 0.8};
    int n = 0;
    sl_material_lambert(&out[n++], 0.7, 0.5, 0.2);
    out[n++] = conductor(gold, one, 0.4, 0.0, true);
    out[n++] = conductor(gold, one, 0.4, 0.0, false);
    out[n++] = conductor(gold, chrome_tint, 0.9, 0.6, true);
    out[n++] = white_conductor(0.7, 0.0, true);
    out[n] = conductor(gold, one, 0.6, 0.0, true);
    out[n++].fresnel = SL_FRESNEL_SCHLICK;
    out[n] = conductor(one, one, 0.5, 0.0, true);
    out[n].fresnel = SL_FRESNEL_DIELECTRIC;
    out[n++].ior = 1.6;
    out[n++] = plastic(grey, 1.5, 0.3, true);
    out[n++] = plastic(grey, 1.5, 0.3, false);
    out[n++] = plastic(one, 1.33, 0.8, true);
    out[n++] = plastic(grey, 1.5, 0.0, true);
    return n;
}

static void test_reciprocity(void)
{
    sl_material mats[16];
    int n = test_materials(mats);
    double worst = 0.0;
    for (int k = 0; k < n; k++)
        for (int i = 0; i < 2000; i++) {
            double wo[3], wi[3], a[3], b[3];
            dir(rnd(), 2.0 * PI * rnd(), wo);
            dir(rnd(), 2.0 * PI * rnd(), wi);
            sl_bsdf_eval(&mats[k], wo, wi, a);
            sl_bsdf_eval(&mats[k], wi, wo, b);
            for (int c = 0; c < 3; c++) {
                double rel = fabs(a[c] - b[c]) / fmax(1.0, fabs(a[c]));
                worst = fmax(worst, rel);
            }
        }
    CHECK_MSG(worst < 1e-12, "reciprocity: worst relative difference %.3g", worst);
}

/* Direct quadrature of f cos over the hemisphere on a (theta, phi) grid:
 * independent of the samplers. Rough lobes only (the grid resolves them). */
static void test_energy_grid(void)
{
    sl_material mats[16];
    int n = test_materials(mats);
    const int nt = 160, np = 160;
    double worst = 0.0;
    for (int k = 0; k < n; k++) {
        if (mats[k].roughness < 0.3)
            continue;
        for (int a = 0; a < 4; a++) {
            double wo[3];
            dir((double[]){0.05, 0.3, 0.7, 1.0}[a], 0.4, wo);
            double sum[3] = {0, 0, 0};
            for (int i = 0; i < nt; i++) {
                double th = (i + 0.5) * (PI / 2) / nt;
                for (int j = 0; j < np; j++) {
                    double wi[3], f[3];
                    dir(cos(th), (j + 0.5) * 2.0 * PI / np, wi);
                    sl_bsdf_eval(&mats[k], wo, wi, f);
                    for (int c = 0; c < 3; c++)
                        sum[c] += f[c] * wi[2] * sin(th) * (PI / 2 / nt) * (2 * PI / np);
                }
            }
            for (int c = 0; c < 3; c++) {
                worst = fmax(worst, sum[c]);
                CHECK_MSG(sum[c] <= 1.005, "material %d cos %.2f channel %d: int f cos = %.5f", k,
                          wo[2], c, sum[c]);
            }
        }
    }
    printf("  energy grid: largest int f cos = %.5f\n", worst);
}

/* ---- chi-square ------------------------------------------------------- */

/* Regularised upper incomplete gamma Q(a, x) (series / continued fraction). */
static double gamma_q(double a, double x)
{
    if (x <= 0.0)
        return 1.0;
    double gln = lgamma(a);
    if (x < a + 1.0) {
        double ap = a, sum = 1.0 / a, del = sum;
        for (int n = 0; n < 10000; n++) {
            ap += 1.0;
            del *= x / ap;
            sum += del;
            if (fabs(del) < fabs(sum) * 1e-15)
                break;
        }
        return 1.0 - sum * exp(-x + a * log(x) - gln);
    }
    double b = x + 1.0 - a, c = 1.0 / 1e-300, d = 1.0 / b, h = d;
    for (int i = 1; i < 10000; i++) {
        double an = -i * (i - a);
        b += 2.0;
        d = an * d + b;
        if (fabs(d) < 1e-300)
            d = 1e-300;
        c = b + an / c;
        if (fabs(c) < 1e-300)
            c = 1e-300;
        d = 1.0 / d;
        double del = d * c;
        h *= del;
        if (fabs(del - 1.0) < 1e-15)
            break;
    }
    return exp(-x + a * log(x) - gln) * h;
}

#define TH 16
#define PH 32
#define SUB 8

/* p-value of samples drawn from `sampler` against the pdf of `model`;
 * 0 when a sample lands where the pdf is zero. */
static double chi2_pvalue(const sl_material *sampler, const sl_material *model,
                          const double wo[3], int n)
{
    static double obs[TH * PH], cells[TH * PH][2];
    memset(obs, 0, sizeof obs);
    for (int i = 0; i < n; i++) {
        double u[3] = {rnd(), rnd(), rnd()};
        sl_bsdf_sample_rec s;
        if (!sl_bsdf_sample(sampler, wo, u, &s) || s.delta)
            continue;
        double th = acos(fmin(fmax(s.wi[2], -1.0), 1.0));
        double ph = atan2(s.wi[1], s.wi[0]);
        if (ph < 0)
            ph += 2 * PI;
        int ti = (int)(th / PI * TH), pi = (int)(ph / (2 * PI) * PH);
        ti = ti < TH ? ti : TH - 1;
        pi = pi < PH ? pi : PH - 1;
        obs[ti * PH + pi] += 1.0;
    }
    for (int ti = 0; ti < TH; ti++)
        for (int pi = 0; pi < PH; pi++) {
            double e = 0.0, dt = PI / TH / SUB, dp = 2 * PI / PH / SUB;
            for (int a = 0; a < SUB; a++)
                for (int b = 0; b < SUB; b++) {
                    double th = (ti + (a + 0.5) / SUB) * PI / TH;
                    double ph = (pi + (b + 0.5) / SUB) * 2 * PI / PH;
                    double w[3] = {sin(th) * cos(ph), sin(th) * sin(ph), cos(th)};
                    e += sl_bsdf_pdf(model, wo, w) * sin(th) * dt * dp;
                }
            int c = ti * PH + pi;
            if (e <= 0.0 && obs[c] > 0.0)
                return 0.0;
            cells[c][0] = e * n;
            cells[c][1] = obs[c];
        }
    qsort(cells, TH * PH, sizeof cells[0], sl_cmp_double);
    double pool_e = 0.0, pool_o = 0.0, chi2 = 0.0;
    int i = 0, dof = 0;
    while (i < TH * PH && (cells[i][0] < 5.0 || pool_e < 5.0)) {
        pool_e += cells[i][0];
        pool_o += cells[i][1];
        i++;
    }
    if (pool_e > 0.0) {
        chi2 += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        dof++;
    }
    for (; i < TH * PH; i++) {
        double d = cells[i][1] - cells[i][0];
        chi2 += d * d / cells[i][0];
        dof++;
    }
    return gamma_q(0.5 * (dof - 1), 0.5 * chi2);
}

typedef struct chi_case {
    const char *name;
    sl_material m;
    double cos_o, phi_o;
} chi_case;

static void test_chi2_samplers(void)
{
    sl_material lam;
    sl_material_lambert(&lam, 0.8, 0.8, 0.8);
    static const double grey[3] = {0.5, 0.4, 0.3};
    chi_case cases[32];
    int n = 0;
    cases[n++] = (chi_case){"cosine (Lambert)", lam, 0.5, 0.0};
    static const double rough[3] = {0.3, 0.6, 1.0}, coss[3] = {0.2, 0.7, 0.99};
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 3; c++)
            cases[n++] = (chi_case){"VNDF isotropic", white_conductor(rough[r], 0.0, false),
                                    coss[c], 0.3};
    cases[n++] = (chi_case){"VNDF anisotropic 0.8", white_conductor(0.5, 0.8, false), 0.3, 0.7};
    cases[n++] = (chi_case){"VNDF anisotropic 0.5", white_conductor(1.0, 0.5, false), 0.8, 2.0};
    cases[n++] = (chi_case){"VNDF + cosine (compensated)", white_conductor(0.8, 0.0, true), 0.4, 0.0};
    cases[n++] = (chi_case){"VNDF + cosine (gold)", conductor(gold, one, 0.5, 0.0, true), 0.6, 1.0};
    cases[n++] = (chi_case){"plastic mixture", plastic(grey, 1.5, 0.4, true), 0.5, 0.0};
    cases[n++] = (chi_case){"plastic mixture, grazing", plastic(grey, 1.5, 0.8, true), 0.2, 4.0};
    cases[n++] = (chi_case){"plastic uncompensated", plastic(grey, 1.5, 0.6, false), 0.7, 0.0};
    cases[n++] = (chi_case){"smooth plastic (diffuse part)", plastic(grey, 1.5, 0.0, true), 0.6, 0.0};
    /* Sidak: overall significance 1% across all tests. */
    double alpha = 1.0 - pow(0.99, 1.0 / n), pmin = 1.0;
    for (int i = 0; i < n; i++) {
        double wo[3];
        dir(cases[i].cos_o, cases[i].phi_o, wo);
        double p = chi2_pvalue(&cases[i].m, &cases[i].m, wo, 60000);
        CHECK_MSG(p > alpha, "chi-square %s (roughness %.2f, cos %.2f): p = %.3g < %.3g",
                  cases[i].name, cases[i].m.roughness, cases[i].cos_o, p, alpha);
        pmin = fmin(pmin, p);
        printf("    %-30s roughness %.2f cos %.2f: p = %.3g\n", cases[i].name,
               cases[i].m.roughness, cases[i].cos_o, p);
    }
    printf("  %d samplers, smallest p-value %.3g (threshold %.3g)\n", n, pmin, alpha);
}

/* Negative controls: the same machinery must reject a sampler that does not
 * match the pdf, including a near miss. */
static void test_chi2_rejects_mismatch(void)
{
    sl_material lam;
    sl_material_lambert(&lam, 0.8, 0.8, 0.8);
    sl_material ggx = white_conductor(1.0, 0.0, false);
    double wo[3];
    dir(0.5, 0.0, wo);
    double p = chi2_pvalue(&lam, &ggx, wo, 60000);
    CHECK_MSG(p < 1e-6, "cosine samples against a GGX pdf: p = %.3g", p);
    sl_material a = white_conductor(0.5, 0.0, false), b = white_conductor(0.55, 0.0, false);
    double p2 = chi2_pvalue(&a, &b, wo, 60000);
    CHECK_MSG(p2 < 1e-6, "roughness 0.5 samples against roughness 0.55 pdf: p = %.3g", p2);
    printf("  negative controls: p = %.3g, %.3g\n", p, p2);
    /* A pdf that is zero where samples land is an outright failure: the
     * non-delta pdf of a mirror is zero everywhere. */
    sl_material chrome;
    sl_material_chrome(&chrome);
    p = chi2_pvalue(&lam, &chrome, wo, 20000);
    CHECK(p == 0.0);
}

int main(void)
{
    RUN(test_fresnel_known_values);
    RUN(test_fresnel_average);
    RUN(test_fresnel_average_memo);
    RUN(test_lambert_exact);
    RUN(test_material_check);
    RUN(test_reciprocity);
    RUN(test_energy_grid);
    RUN(test_chi2_samplers);
    RUN(test_chi2_rejects_mismatch);
    return sl_test_finish();
}
