/* SPDX-License-Identifier: BSD-3-Clause */
/* Piecewise-constant distributions: chi-square goodness of fit (with
 * negative controls that must reject), the 1e-6..1e9 range case, degenerate
 * inputs, the chi-square p-value itself, and lat-long environment sampling. */
#include "testing.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static uint64_t rng_state;

static double rng_uniform(void) { return sl_test_uniform(&rng_state); }

static void test_chi2_pvalue(void)
{
    /* Closed forms: Q(1/2, x) = erfc(sqrt x), Q(1, x) = exp(-x),
     * Q(3/2, x) = erfc(sqrt x) + 2 sqrt(x / pi) exp(-x), Q(2, x) = (1 + x) exp(-x). */
    double xs[] = {0.001, 0.1, 0.5, 1.0, 2.5, 3.0, 10.0, 40.0, 200.0};
    double worst = 0.0;
    for (size_t i = 0; i < sizeof xs / sizeof xs[0]; i++) {
        double x = xs[i];
        double ref[4] = {erfc(sqrt(x)), exp(-x), erfc(sqrt(x)) + 2 * sqrt(x / M_PI) * exp(-x),
                         (1 + x) * exp(-x)};
        for (int k = 0; k < 4; k++) {
            double p = sl_chi2_pvalue(2 * x, k + 1);
            double rel = fabs(p - ref[k]) / ref[k];
            worst = fmax(worst, rel);
            CHECK_MSG(rel < 1e-9, "dof %d stat %g: %.15g vs %.15g", k + 1, 2 * x, p, ref[k]);
        }
    }
    printf("  closed-form dof 1..4: max relative error %.3g\n", worst);
    /* Published 5% critical values. */
    CHECK_NEAR(sl_chi2_pvalue(3.841458820694124, 1), 0.05, 1e-12);
    CHECK_NEAR(sl_chi2_pvalue(18.307038053275146, 10), 0.05, 1e-12);
    CHECK_NEAR(sl_chi2_pvalue(124.3421134, 100), 0.05, 1e-8);
    CHECK_NEAR(sl_chi2_pvalue(1074.679449, 1000), 0.05, 1e-7);
    CHECK_NEAR(sl_chi2_pvalue(3.84, 1), 0.05, 1e-4);
    CHECK_NEAR(sl_chi2_pvalue(1000.0, 1000), 0.4940527, 2e-6); /* median lies just below the mean */
    CHECK(sl_chi2_pvalue(0.0, 5) == 1.0);
    CHECK(sl_chi2_pvalue(-1.0, 5) == 1.0);
    CHECK(sl_chi2_pvalue(5.0, 0) == 0.0);
    CHECK(sl_chi2_pvalue(INFINITY, 3) == 0.0);
}

/* The cut-point search must find exactly the bin of a full search: the
 * largest i with cdf[i] <= u, at bin and cut-point edges, across zero bins,
 * and for a spike that takes almost all of the mass. */
static void test_1d_guided_search(void)
{
    enum { N = 1000 };
    static double f[N];
    for (int i = 0; i < N; i++)
        f[i] = (i % 7 == 3 || (i > 200 && i < 260)) ? 0.0 : 1e-6 + (i * 31 % 13);
    f[500] = 1e9;
    sl_distrib1d d;
    sl_error err;
    CHECK_OK(sl_distrib1d_init(&d, f, N, &err), &err);
    int wrong = 0, tried = 0;
    for (int k = 0; k <= 4 * N; k++) {
        double base[3] = {(double)k / (4 * N), (double)(k % N) / N, k < N ? d.cdf[k] : 0.5};
        for (int j = 0; j < 3; j++)
            for (int e = -2; e <= 2; e++) {
                double u = base[j];
                for (int m = 0; m < (e < 0 ? -e : e); m++)
                    u = nextafter(u, e < 0 ? -1.0 : 2.0);
                if (!(u >= 0.0 && u < 1.0))
                    continue;
                int full = 0;
                for (int i = 0; i < N; i++)
                    if (d.cdf[i] <= u)
                        full = i;
                tried++;
                wrong += sl_distrib1d_sample_discrete(&d, u, NULL) != full;
            }
    }
    CHECK(tried > 50000);
    CHECK(wrong == 0);
    sl_distrib1d_free(&d);
}

static void test_1d_fit(void)
{
    enum { N = 64, HB = 256, S = 100000 };
    double f[N];
    for (int i = 0; i < N; i++)
        f[i] = (i % 9 == 4) ? 0.0 : 0.2 + (double)((i * 37) % 17) * (i < 32 ? 1.0 : 0.05);
    sl_distrib1d d;
    sl_error err;
    CHECK_OK(sl_distrib1d_init(&d, f, N, &err), &err);
    double sum = 0.0;
    for (int i = 0; i < N; i++)
        sum += f[i];
    CHECK_NEAR(d.integral, sum / N, 1e-14);
    CHECK(d.cdf[0] == 0.0 && d.cdf[N] == 1.0);

    /* Histogram finer than the bins, so shape inside a bin counts too. */
    static double obs[HB], expct[HB], wrong[HB];
    memset(obs, 0, sizeof obs);
    rng_state = 1;
    int bad_pdf = 0, bad_off = 0;
    for (int s = 0; s < S; s++) {
        double pdf;
        int off;
        double x = sl_distrib1d_sample(&d, rng_uniform(), &pdf, &off);
        if (!(x >= 0.0 && x < 1.0) || off != (int)(x * N) || f[off] == 0.0)
            bad_off++;
        if (fabs(pdf - f[off] / d.integral) > 1e-12 || fabs(sl_distrib1d_pdf(&d, x) - pdf) > 0)
            bad_pdf++;
        obs[(int)(x * HB)] += 1.0;
    }
    CHECK(bad_off == 0);
    CHECK(bad_pdf == 0);
    for (int b = 0; b < HB; b++) {
        expct[b] = S * f[b * N / HB] / sum / (HB / N);
        /* Negative control: the same shape with every other bin 10% too heavy. */
        wrong[b] = S * f[b * N / HB] * ((b * N / HB) % 2 ? 1.0 : 1.1);
    }
    double wsum = 0.0;
    for (int b = 0; b < HB; b++)
        wsum += wrong[b];
    for (int b = 0; b < HB; b++)
        wrong[b] *= S / wsum;
    int dof;
    double p = sl_test_chi2(obs, expct, HB, &dof);
    int wdof;
    double pw = sl_test_chi2(obs, wrong, HB, &wdof);
    printf("  1D: %d samples, p = %.4f (dof %d); wrong pdf p = %.3g\n", S, p, dof, pw);
    CHECK(p > 0.01);
    CHECK(pw < 1e-6);

    /* Discrete sampling: pmf and frequencies. */
    memset(obs, 0, sizeof obs);
    for (int s = 0; s < S; s++) {
        double pmf;
        int i = sl_distrib1d_sample_discrete(&d, rng_uniform(), &pmf);
        CHECK_MSG(fabs(pmf - f[i] / sum) < 1e-15, "pmf %d", i);
        obs[i] += 1.0;
    }
    for (int i = 0; i < N; i++)
        expct[i] = S * f[i] / sum;
    p = sl_test_chi2(obs, expct, N, &dof);
    printf("  1D discrete: p = %.4f (dof %d)\n", p, dof);
    CHECK(p > 0.01);

    /* The pdf integrates to 1 (midpoint rule is exact on a piecewise constant). */
    double integ = 0.0;
    for (int k = 0; k < N * 10; k++)
        integ += sl_distrib1d_pdf(&d, (k + 0.5) / (N * 10)) / (N * 10);
    CHECK_NEAR(integ, 1.0, 1e-12);

    /* Every cdf boundary, and the doubles either side, lands in a bin with mass. */
    int landed_on_zero = 0;
    for (int i = 0; i <= N; i++) {
        double us[3] = {d.cdf[i], nextafter(d.cdf[i], 0.0), nextafter(d.cdf[i], 2.0)};
        for (int k = 0; k < 3; k++) {
            int off;
            double x = sl_distrib1d_sample(&d, us[k], NULL, &off);
            if (f[off] == 0.0 || !(x < 1.0))
                landed_on_zero++;
            if (f[sl_distrib1d_sample_discrete(&d, us[k], NULL)] == 0.0)
                landed_on_zero++;
        }
    }
    CHECK(landed_on_zero == 0);
    sl_distrib1d_free(&d);
}

static void test_1d_extreme_range(void)
{
    enum { N = 1001, BIG = 500 };
    static double f[N];
    for (int i = 0; i < N; i++)
        f[i] = 1e-6;
    f[BIG] = 1e9;
    sl_distrib1d d;
    sl_error err;
    CHECK_OK(sl_distrib1d_init(&d, f, N, &err), &err);
    double total = 1e9 + (N - 1) * 1e-6;
    double worst = 0.0;
    for (int i = 0; i <= N; i++) {
        double exact = i <= BIG ? i * 1e-6 / total : (1e9 + (i - 1) * 1e-6) / total;
        if (exact > 0)
            worst = fmax(worst, fabs(d.cdf[i] - exact) / exact);
    }
    printf("  1e-6 .. 1e9: max relative cdf error %.3g\n", worst);
    CHECK(worst < 1e-9);
    /* Before the peak the tiny bins have exact widths; after it, the widths
     * are ~1e-15 next to 1.0 where doubles are spaced 1.1e-16; with both
     * ends rounded (half a spacing each) a width is right to 0.111: the best
     * a double u can do. */
    double wb = 0.0, wa = 0.0;
    for (int i = 0; i < N; i++) {
        if (i == BIG)
            continue;
        double rel = fabs((d.cdf[i + 1] - d.cdf[i]) / (1e-6 / total) - 1.0);
        if (i < BIG)
            wb = fmax(wb, rel);
        else
            wa = fmax(wa, rel);
    }
    printf("  tiny bin probability error: before the peak %.3g, after %.3g\n", wb, wa);
    CHECK(wb < 1e-9);
    CHECK(wa < 0.12);
    int missed = 0;
    for (int i = 0; i < N; i++) {
        if (i == BIG)
            continue;
        double us[2] = {d.cdf[i], nextafter(d.cdf[i], 1.0)};
        for (int k = 0; k < 2; k++) {
            int off;
            double pdf;
            sl_distrib1d_sample(&d, us[k], &pdf, &off);
            if (off != i || fabs(pdf / (1e-6 / d.integral) - 1.0) > 1e-12)
                missed++;
            double pmf;
            if (sl_distrib1d_sample_discrete(&d, us[k], &pmf) != i ||
                fabs(pmf / (1e-6 / total) - 1.0) > 1e-12)
                missed++;
        }
    }
    CHECK(missed == 0);
    int off;
    sl_distrib1d_sample(&d, 0.5, NULL, &off);
    CHECK(off == BIG);
    sl_distrib1d_free(&d);
}

static void test_1d_degenerate(void)
{
    sl_distrib1d d;
    sl_error err;
    double zeros[5] = {0, 0, 0, 0, 0};
    CHECK_OK(sl_distrib1d_init(&d, zeros, 5, &err), &err);
    CHECK(d.integral == 0.0);
    double pdf;
    int off;
    CHECK_NEAR(sl_distrib1d_sample(&d, 0.3, &pdf, &off), 0.3, 1e-15);
    CHECK(pdf == 1.0 && off == 1);
    double pmf;
    CHECK(sl_distrib1d_sample_discrete(&d, 0.99, &pmf) == 4);
    CHECK_NEAR(pmf, 0.2, 1e-15);
    CHECK(sl_distrib1d_sample(&d, 1.0, NULL, NULL) < 1.0);
    CHECK(sl_distrib1d_sample(&d, 2.0, NULL, NULL) < 1.0);
    sl_distrib1d_free(&d);

    double one[1] = {3.0};
    CHECK_OK(sl_distrib1d_init(&d, one, 1, &err), &err);
    CHECK(sl_distrib1d_sample(&d, nextafter(1.0, 0.0), &pdf, &off) < 1.0);
    CHECK(pdf == 1.0 && off == 0);
    sl_distrib1d_free(&d);

    double bad[3] = {1.0, NAN, 2.0};
    CHECK_RESULT(sl_distrib1d_init(&d, bad, 3, &err), SL_ERR_INPUT, &err);
    CHECK(d.func == NULL && d.cdf == NULL && d.n == 0);
    CHECK(strstr(err.message, "value 1") != NULL);
    bad[1] = INFINITY;
    CHECK_RESULT(sl_distrib1d_init(&d, bad, 3, &err), SL_ERR_INPUT, &err);
    bad[1] = -1e-30;
    CHECK_RESULT(sl_distrib1d_init(&d, bad, 3, &err), SL_ERR_INPUT, &err);
    double huge[2] = {1.5e308, 1.5e308};
    CHECK_RESULT(sl_distrib1d_init(&d, huge, 2, &err), SL_ERR_INPUT, &err);
    CHECK_RESULT(sl_distrib1d_init(&d, one, 0, &err), SL_ERR_USAGE, &err);
    sl_distrib1d_free(&d); /* safe after failure */

    sl_distrib2d d2;
    double grid[6] = {1, 2, 3, 4, NAN, 6};
    CHECK_RESULT(sl_distrib2d_init(&d2, grid, 3, 2, &err), SL_ERR_INPUT, &err);
    CHECK(d2.conditional == NULL && d2.nu == 0);
    sl_distrib2d_free(&d2);
}

static void test_2d_fit(void)
{
    enum { NU = 16, NV = 8, HU = 32, HV = 16, S = 100000 };
    static double f[NU * NV];
    for (int v = 0; v < NV; v++)
        for (int u = 0; u < NU; u++)
            f[v * NU + u] = (v == 3) ? 0.0 : 0.1 + (double)((u * 7 + v * 13) % 11) * (u + 1);
    sl_distrib2d d;
    sl_error err;
    CHECK_OK(sl_distrib2d_init(&d, f, NU, NV, &err), &err);
    double sum = 0.0;
    for (int i = 0; i < NU * NV; i++)
        sum += f[i];
    static double obs[HU * HV], expct[HU * HV], wrong[HU * HV];
    memset(obs, 0, sizeof obs);
    rng_state = 7;
    int bad = 0;
    for (int s = 0; s < S; s++) {
        double uv[2], pdf;
        double a = rng_uniform(), b = rng_uniform();
        sl_distrib2d_sample(&d, a, b, uv, &pdf);
        int iu = (int)(uv[0] * NU), iv = (int)(uv[1] * NV);
        double want = f[iv * NU + iu] / (sum / (NU * NV));
        if (!(uv[0] < 1.0 && uv[1] < 1.0) || fabs(pdf - want) > 1e-12 * want ||
            fabs(sl_distrib2d_pdf(&d, uv[0], uv[1]) - pdf) > 1e-12 * want)
            bad++;
        obs[(int)(uv[1] * HV) * HU + (int)(uv[0] * HU)] += 1.0;
    }
    CHECK(bad == 0);
    for (int hv = 0; hv < HV; hv++)
        for (int hu = 0; hu < HU; hu++) {
            double fv = f[(hv * NV / HV) * NU + hu * NU / HU];
            expct[hv * HU + hu] = S * fv / sum / ((HU / NU) * (HV / NV));
            /* Negative control: treat u and v as independent (product of marginals). */
            double mu = 0.0, mv = 0.0;
            for (int v = 0; v < NV; v++)
                mu += f[v * NU + hu * NU / HU];
            for (int u = 0; u < NU; u++)
                mv += f[(hv * NV / HV) * NU + u];
            wrong[hv * HU + hu] = S * (mu / sum) * (mv / sum) / ((HU / NU) * (HV / NV));
        }
    int dof, wdof;
    double p = sl_test_chi2(obs, expct, HU * HV, &dof);
    double pw = sl_test_chi2(obs, wrong, HU * HV, &wdof);
    printf("  2D: %d samples, p = %.4f (dof %d); independent-marginals pdf p = %.3g\n", S, p,
           dof, pw);
    CHECK(p > 0.01);
    CHECK(pw < 1e-6);
    double integ = 0.0;
    for (int j = 0; j < 4 * NV; j++)
        for (int i = 0; i < 4 * NU; i++)
            integ += sl_distrib2d_pdf(&d, (i + 0.5) / (4 * NU), (j + 0.5) / (4 * NV));
    CHECK_NEAR(integ / (16 * NU * NV), 1.0, 1e-12);
    sl_distrib2d_free(&d);
}

/* How the renderer samples a lat-long: weights = luminance x sin(theta) at
 * the texel centre, which is exactly proportional to the texel's solid angle
 * (2 pi / w * 2 sin(pi / 2h) * cos(latitude)). */
static void test_envmap_sampling(void)
{
    enum { W = 64, H = 32, S = 200000 };
    static double lum[W * H], func[W * H];
    double sun[3] = {0.6, 0.64, -0.48};
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / W, (y + 0.5) / H, d);
            double dd = (d[0] - sun[0]) * (d[0] - sun[0]) + (d[1] - sun[1]) * (d[1] - sun[1]) +
                        (d[2] - sun[2]) * (d[2] - sun[2]);
            lum[y * W + x] = 0.2 + 0.15 * (d[1] + 1) + 40.0 * exp(-dd / 0.01);
            func[y * W + x] = lum[y * W + x] * sin(M_PI * (y + 0.5) / H);
        }
    sl_distrib2d d;
    sl_error err;
    CHECK_OK(sl_distrib2d_init(&d, func, W, H, &err), &err);
    double power = 0.0; /* integral of luminance over the sphere */
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            power += lum[y * W + x] * sl_latlong_texel_solid_angle(y, W, H);
    static double obs[W * H], expct[W * H], wrong[W * H];
    memset(obs, 0, sizeof obs);
    rng_state = 99;
    double est = 0.0;
    for (int s = 0; s < S; s++) {
        double uv[2], pdf, dir[3], u2, v2;
        sl_distrib2d_sample(&d, rng_uniform(), rng_uniform(), uv, &pdf);
        sl_latlong_to_dir(uv[0], uv[1], dir);
        double sin_theta = sqrt(fmax(0.0, 1.0 - dir[1] * dir[1]));
        double pdf_sa = pdf / (2.0 * M_PI * M_PI * sin_theta); /* per steradian */
        /* Bin by direction, as a renderer's histogram would. */
        sl_dir_to_latlong(dir, &u2, &v2);
        int x = (int)(u2 * W), y = (int)(v2 * H);
        x = x > W - 1 ? W - 1 : x;
        y = y > H - 1 ? H - 1 : y;
        obs[y * W + x] += 1.0;
        est += lum[y * W + x] / pdf_sa;
    }
    est /= S;
    double wsum = 0.0;
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            expct[y * W + x] = S * lum[y * W + x] * sl_latlong_texel_solid_angle(y, W, H) / power;
            wrong[y * W + x] = lum[y * W + x]; /* forgets the solid angle */
            wsum += wrong[y * W + x];
        }
    for (int i = 0; i < W * H; i++)
        wrong[i] *= S / wsum;
    int dof, wdof;
    double p = sl_test_chi2(obs, expct, W * H, &dof);
    double pw = sl_test_chi2(obs, wrong, W * H, &wdof);
    printf("  envmap: p = %.4f (dof %d); luminance-only pdf p = %.3g; "
           "MC power %.6g vs %.6g (rel %.3g)\n",
           p, dof, pw, est, power, est / power - 1);
    CHECK(p > 0.01);
    CHECK(pw < 1e-6);
    CHECK_NEAR(est / power, 1.0, 0.01);
    sl_distrib2d_free(&d);
}

int main(void)
{
    RUN(test_chi2_pvalue);
    RUN(test_1d_fit);
    RUN(test_1d_guided_search);
    RUN(test_1d_extreme_range);
    RUN(test_1d_degenerate);
    RUN(test_2d_fit);
    RUN(test_envmap_sampling);
    return sl_test_finish();
}
