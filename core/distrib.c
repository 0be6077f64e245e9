/* SPDX-License-Identifier: BSD-3-Clause */
/* Piecewise-constant 1D and 2D sampling distributions (pbrt-v4's
 * PiecewiseConstant1D/2D), built in double with compensated running sums so
 * that values from 1e-6 to 1e9 in one map keep their exact probabilities. */
#include "setlight/core.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* The largest double below 1: samples live in [0, 1). */
#define ONE_MINUS_EPS 0x1.fffffffffffffp-1

/* Largest i in [lo, hi] with cdf[i] <= u (cdf[lo] <= u). For u < 1 the bin
 * found always has cdf[i+1] > u >= cdf[i], so it has non-zero probability. */
static int search_bin(const double *cdf, int lo, int hi, double u)
{
    while (lo < hi) {
        int mid = lo + (hi - lo + 1) / 2;
        if (cdf[mid] <= u)
            lo = mid;
        else
            hi = mid - 1;
    }
    return lo;
}

sl_result sl_distrib1d_init(sl_distrib1d *d, const double *func, int n, sl_error *err)
{
    memset(d, 0, sizeof *d);
    if (n <= 0 || !func)
        return sl_error_set(err, SL_ERR_USAGE, "distribution: %d values", n);
    for (int i = 0; i < n; i++)
        if (!isfinite(func[i]) || func[i] < 0.0)
            return sl_error_set(err, SL_ERR_INPUT, "distribution: value %d is %g", i, func[i]);
    d->func = malloc(sizeof(double) * (size_t)n);
    d->cdf = malloc(sizeof(double) * ((size_t)n + 1));
    d->guide = malloc(sizeof(int) * ((size_t)n + 1));
    if (!d->func || !d->cdf || !d->guide) {
        sl_distrib1d_free(d);
        return sl_error_set(err, SL_ERR_NOMEM, "distribution: out of memory for %d values", n);
    }
    memcpy(d->func, func, sizeof(double) * (size_t)n);
    d->n = n;
    /* Neumaier-compensated prefix sums: cdf[i] is the correctly rounded
     * partial sum, so a tiny bin after a huge one keeps its own width. */
    sl_ksum sum = {0};
    d->cdf[0] = 0.0;
    for (int i = 0; i < n; i++) {
        sl_ksum_add(&sum, func[i]);
        d->cdf[i + 1] = sl_ksum_value(&sum);
    }
    double total = d->cdf[n];
    if (!isfinite(total)) {
        sl_distrib1d_free(d);
        return sl_error_set(err, SL_ERR_INPUT, "distribution: sum of %d values overflows", n);
    }
    d->integral = total / n;
    if (total > 0.0) {
        for (int i = 1; i < n; i++)
            d->cdf[i] = d->cdf[i] / total;
    } else {
        for (int i = 1; i < n; i++)
            d->cdf[i] = (double)i / n;
    }
    d->cdf[n] = 1.0;
    /* Cut points (Chen & Asau 1974): the search for u in [k/n, (k+1)/n) is
     * confined to [guide[k], guide[k+1]], a bin or two for smooth maps, and
     * finds exactly the bin the full binary search finds. */
    for (int k = 0, i = 0; k <= n; k++) {
        double u = k < n ? (double)k / n : ONE_MINUS_EPS;
        while (i < n - 1 && d->cdf[i + 1] <= u)
            i++;
        d->guide[k] = i;
    }
    return SL_OK;
}

void sl_distrib1d_free(sl_distrib1d *d)
{
    if (!d)
        return;
    free(d->func);
    free(d->cdf);
    free(d->guide);
    memset(d, 0, sizeof *d);
}

/* Largest i in [0, n-1] with cdf[i] <= u, for u in [0, 1). */
static int find_bin(const sl_distrib1d *d, double u)
{
    int n = d->n, k = (int)(u * n);
    /* k / n <= u < (k + 1) / n in the arithmetic the guide was built with */
    k = k < 0 ? 0 : k > n - 1 ? n - 1 : k;
    while (k > 0 && (double)k / n > u)
        k--;
    while (k < n - 1 && (double)(k + 1) / n <= u)
        k++;
    return search_bin(d->cdf, d->guide[k], d->guide[k + 1], u);
}

static double clamp_u(double u)
{
    if (!(u >= 0.0))
        return 0.0;
    return u < 1.0 ? u : ONE_MINUS_EPS;
}

double sl_distrib1d_sample(const sl_distrib1d *d, double u, double *pdf, int *offset)
{
    u = clamp_u(u);
    int o = find_bin(d, u);
    double width = d->cdf[o + 1] - d->cdf[o];
    double du = width > 0.0 ? (u - d->cdf[o]) / width : 0.0;
    if (du >= 1.0)
        du = ONE_MINUS_EPS;
    if (pdf)
        *pdf = d->integral > 0.0 ? d->func[o] / d->integral : 1.0;
    if (offset)
        *offset = o;
    double x = (o + du) / d->n;
    return x < 1.0 ? x : ONE_MINUS_EPS;
}

int sl_distrib1d_sample_discrete(const sl_distrib1d *d, double u, double *pmf)
{
    int o = find_bin(d, clamp_u(u));
    if (pmf)
        *pmf = d->integral > 0.0 ? d->func[o] / (d->integral * d->n) : 1.0 / d->n;
    return o;
}

double sl_distrib1d_pdf(const sl_distrib1d *d, double x)
{
    if (!(x >= 0.0 && x <= 1.0))
        return 0.0;
    int o = (int)(x * d->n);
    if (o > d->n - 1)
        o = d->n - 1;
    return d->integral > 0.0 ? d->func[o] / d->integral : 1.0;
}

sl_result sl_distrib2d_init(sl_distrib2d *d, const double *func, int nu, int nv, sl_error *err)
{
    memset(d, 0, sizeof *d);
    if (nu <= 0 || nv <= 0 || !func)
        return sl_error_set(err, SL_ERR_USAGE, "distribution: %dx%d values", nu, nv);
    d->conditional = calloc((size_t)nv, sizeof(sl_distrib1d));
    double *marg = malloc(sizeof(double) * (size_t)nv);
    if (!d->conditional || !marg) {
        free(marg);
        sl_distrib2d_free(d);
        return sl_error_set(err, SL_ERR_NOMEM, "distribution: out of memory for %dx%d", nu, nv);
    }
    d->nu = nu;
    d->nv = nv;
    for (int v = 0; v < nv; v++) {
        sl_result r = sl_distrib1d_init(&d->conditional[v], func + (size_t)v * (size_t)nu, nu,
                                        err);
        if (r) {
            free(marg);
            sl_distrib2d_free(d);
            return r;
        }
        marg[v] = d->conditional[v].integral;
    }
    sl_result r = sl_distrib1d_init(&d->marginal, marg, nv, err);
    free(marg);
    if (r)
        sl_distrib2d_free(d);
    return r;
}

void sl_distrib2d_free(sl_distrib2d *d)
{
    if (!d)
        return;
    if (d->conditional)
        for (int v = 0; v < d->nv; v++)
            sl_distrib1d_free(&d->conditional[v]);
    free(d->conditional);
    sl_distrib1d_free(&d->marginal);
    memset(d, 0, sizeof *d);
}

void sl_distrib2d_sample(const sl_distrib2d *d, double u0, double u1, double uv[2], double *pdf)
{
    double pdf_v, pdf_u;
    int v;
    uv[1] = sl_distrib1d_sample(&d->marginal, u1, &pdf_v, &v);
    uv[0] = sl_distrib1d_sample(&d->conditional[v], u0, &pdf_u, NULL);
    if (pdf)
        *pdf = pdf_u * pdf_v;
}

double sl_distrib2d_pdf(const sl_distrib2d *d, double u, double v)
{
    if (!(u >= 0.0 && u <= 1.0 && v >= 0.0 && v <= 1.0))
        return 0.0;
    int iv = (int)(v * d->nv);
    if (iv > d->nv - 1)
        iv = d->nv - 1;
    return sl_distrib1d_pdf(&d->conditional[iv], u) * sl_distrib1d_pdf(&d->marginal, v);
}
