/* SPDX-License-Identifier: BSD-3-Clause */
/* The null space of self-calibration from a bracket of equal steps and the
 * member of a curve's class the Debevec-Malik fit's smoothness picks from it
 * (vb_null_space_fit; the null-space oracle of tests/vset_bracket.c).
 *
 * With every step `period` in ln exposure, the frames of a pixel of radiance
 * E read g^-1(ln E + ln e_q), and g -> g + p(g) with p periodic of that
 * period shifts every frame's estimate by the same p(ln E + ln e_0): the
 * frames agree as well as through the true curve, so no data term can tell
 * the two apart, and only the fit's smoothness chooses p. The smoothness is
 * quadratic in g, g + p(g) is linear in p, so the best p over a Fourier
 * basis is one linear solve. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "../stitch/merge_private.h" /* merge_smoothness_row, merge_cholesky_solve */
#include "vset_bracket.h"

/* The fit's nodes (sl_merge's default response nodes: one per 8-bit code). */
enum { FIT_NODES = 256 };

double vb_periodic_at(const vb_periodic *p, double u)
{
    double s = 0, w = 2 * M_PI * u / p->period;
    for (int j = 0; j < VB_HARMONICS; j++)
        s += p->cos_coef[j] * cos((j + 1) * w) + p->sin_coef[j] * sin((j + 1) * w);
    return s;
}

double vb_periodic_apply(const vb_periodic *p, double x)
{
    return x > 0 ? x * exp(vb_periodic_at(p, log(x)) - vb_periodic_at(p, 0)) : 0;
}

/* Least of 1 + p'(u) over a period (the curve g + p(g) rises where it is
 * positive). */
static double periodic_min_rise(const vb_periodic *p)
{
    double least = INFINITY;
    for (int i = 0; i < 2048; i++) {
        double w = 2 * M_PI * i / 2048, d = 0;
        for (int j = 0; j < VB_HARMONICS; j++)
            d += (j + 1) * (p->sin_coef[j] * cos((j + 1) * w) - p->cos_coef[j] * sin((j + 1) * w));
        least = fmin(least, 1 + d * 2 * M_PI / p->period);
    }
    return least;
}

bool vb_null_space_fit(const sl_vset_response *truth, double period, double black,
                       double saturation, vb_periodic *p)
{
    enum { N = 2 * VB_HARMONICS };
    memset(p, 0, sizeof *p);
    p->period = period;
    /* g at the fit's nodes; the data pins only the codes it weighs (above
     * black, below saturation): beyond them the fit's g is free and its
     * smoothness there can be made zero, so only rows inside count. */
    double g[FIT_NODES];
    bool pinned[FIT_NODES];
    for (int k = 0; k < FIT_NODES; k++) {
        double z = (double)k / (FIT_NODES - 1), x = sl_vset_response_invert(truth, z);
        pinned[k] = z > black && z < saturation && x > 0;
        g[k] = pinned[k] ? log(x) : 0;
    }
    double a[N * N] = {0}, rhs[N] = {0}, row[N];
    for (int k = 2; k < FIT_NODES - 1; k++) {
        if (!pinned[k - 1] || !pinned[k] || !pinned[k + 1])
            continue;
        double cs[3], wl = merge_smoothness_row(k, FIT_NODES, 1, cs), dg = 0;
        memset(row, 0, sizeof row);
        for (int e = 0; e < 3; e++) {
            double u = g[k - 1 + e], w = 2 * M_PI * u / period;
            dg += cs[e] * u;
            for (int j = 0; j < VB_HARMONICS; j++) {
                row[2 * j] += cs[e] * cos((j + 1) * w);
                row[2 * j + 1] += cs[e] * sin((j + 1) * w);
            }
        }
        for (int i = 0; i < N; i++) {
            rhs[i] -= wl * row[i] * dg;
            for (int j = 0; j < N; j++)
                a[i * N + j] += wl * row[i] * row[j];
        }
    }
    /* A harmonic no row sees (too fine for the nodes) stays at zero. */
    double trace = 0;
    for (int i = 0; i < N; i++)
        trace += a[i * N + i];
    for (int i = 0; i < N; i++)
        a[i * N + i] += 1e-12 * trace / N + 1e-300;
    if (!merge_cholesky_solve(a, rhs, N))
        return false;
    for (int j = 0; j < VB_HARMONICS; j++) {
        p->cos_coef[j] = rhs[2 * j];
        p->sin_coef[j] = rhs[2 * j + 1];
    }
    return periodic_min_rise(p) > 0;
}

void vb_null_space_curve(const sl_vset_response *truth, const vb_periodic *p,
                         sl_vset_response *out)
{
    *out = *truth;
    snprintf(out->name, sizeof out->name, "%.100s (null space)", truth->name);
    /* code'(x') = code(x) with x' = h(x) = x exp(p(ln x) - p(0)): h rises
     * from 0 to 1 (vb_null_space_fit's check), so bisection finds x. */
    for (int i = 1; i < SL_VSET_CRF_SAMPLES - 1; i++) {
        double target = (double)i / (SL_VSET_CRF_SAMPLES - 1), lo = -60, hi = 0;
        for (int it = 0; it < 80; it++) {
            double mid = 0.5 * (lo + hi);
            if (vb_periodic_apply(p, exp(mid)) < target)
                lo = mid;
            else
                hi = mid;
        }
        out->curve[i] = sl_vset_response_apply(truth, exp(0.5 * (lo + hi)));
    }
}
