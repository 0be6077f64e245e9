/* SPDX-License-Identifier: BSD-3-Clause */
/* Colour-correction matrix from chart patches, with CIEDE2000 before and
 * after. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "calibrate_internal.h"
#include "setlight/stitch.h"

double sl_chart_delta_e(const double rgb[3], const double ref[3])
{
    double x1[3], x2[3], l1[3], l2[3];
    sl_rec709_to_xyz(rgb, x1);
    sl_rec709_to_xyz(ref, x2);
    sl_xyz_to_lab(x1, SL_WHITE_D65, l1);
    sl_xyz_to_lab(x2, SL_WHITE_D65, l2);
    return sl_ciede2000(l1, l2);
}

void sl_ccm_options_init(sl_ccm_options *o)
{
    memset(o, 0, sizeof(*o));
    o->neutral_patch = -1;
    o->outlier_ratio = 2.0;
}

static double det3(const double m[3][3])
{
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
           m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
}

static void summarise(const double *de, const bool *have, double *mean, double *max)
{
    double s = 0, mx = 0;
    int n = 0;
    for (int p = 0; p < 24; p++)
        if (have[p]) {
            s += de[p];
            mx = fmax(mx, de[p]);
            n++;
        }
    *mean = n ? s / n : -1;
    *max = n ? mx : -1;
}

static sl_result fit_once(const sl_chart_patch patches[24], const double reference[24][3],
                          const sl_ccm_options *opt, const bool exclude[24], sl_ccm_fit *fit,
                          sl_error *err)
{
    memset(fit, 0, sizeof(*fit));
    fit->neutral_patch = -1;
    double w[24];
    for (int p = 0; p < 24; p++) {
        double y = sl_luminance(reference[p]);
        bool ok = patches[p].valid && !exclude[p] && y > 0 && isfinite(y);
        for (int c = 0; c < 3; c++)
            ok = ok && isfinite(patches[p].rgb[c]) && isfinite(reference[p][c]);
        fit->used_patch[p] = ok;
        fit->used += ok;
        w[p] = ok ? pow(y, -4.0 / 3.0) : 0;
    }
    if (fit->used < 6)
        return sl_error_set(err, SL_ERR_INPUT,
                            "chart: only %d usable patches (6 needed for a colour matrix)",
                            fit->used);
    int n = -1;
    if (opt->white_preserving) {
        n = opt->neutral_patch;
        if (n < 0) {
            for (int p = 18; p < 24; p++)
                if (fit->used_patch[p] && (n < 0 || sl_luminance(patches[p].rgb) >
                                                         sl_luminance(patches[n].rgb)))
                    n = p;
            if (n < 0)
                return sl_error_set(err, SL_ERR_INPUT,
                                    "chart: no usable neutral patch for a white-preserving fit");
        } else if (n >= 24 || !fit->used_patch[n]) {
            return sl_error_set(err, SL_ERR_INPUT, "chart: neutral patch %d is not usable", n + 1);
        }
        fit->neutral_patch = n;
    }
    double a[9] = {0};
    for (int p = 0; p < 24; p++)
        if (fit->used_patch[p])
            for (int i = 0; i < 3; i++)
                for (int j = 0; j < 3; j++)
                    a[i * 3 + j] += w[p] * patches[p].rgb[i] * patches[p].rgb[j];
    for (int row = 0; row < 3; row++) {
        /* Normal equations, bordered by the neutral constraint when asked:
         * [A c; c^T 0] [m; lambda] = [b; r]. */
        int k = n >= 0 ? 4 : 3;
        double kkt[16] = {0}, b[4] = {0};
        for (int i = 0; i < 3; i++) {
            for (int j = 0; j < 3; j++)
                kkt[i * k + j] = a[i * 3 + j];
            for (int p = 0; p < 24; p++)
                if (fit->used_patch[p])
                    b[i] += w[p] * patches[p].rgb[i] * reference[p][row];
        }
        if (n >= 0) {
            for (int i = 0; i < 3; i++)
                kkt[i * k + 3] = kkt[3 * k + i] = patches[n].rgb[i];
            b[3] = reference[n][row];
        }
        if (!sl_cal_solve(kkt, b, k))
            return sl_error_set(err, SL_ERR_INPUT,
                                "chart: patch colours are degenerate (no colour matrix fits)");
        for (int j = 0; j < 3; j++)
            fit->m[row][j] = b[j];
    }
    double d = det3(fit->m);
    fit->gain = cbrt(d);
    /* "Before": exposure removed through the neutrals' luminance. */
    double ym = 0, yr = 0;
    for (int p = 18; p < 24; p++)
        if (fit->used_patch[p]) {
            ym += sl_luminance(patches[p].rgb);
            yr += sl_luminance(reference[p]);
        }
    if (!(ym > 0)) {
        ym = yr = 0;
        for (int p = 0; p < 24; p++)
            if (fit->used_patch[p]) {
                ym += sl_luminance(patches[p].rgb);
                yr += sl_luminance(reference[p]);
            }
    }
    double k_before = ym > 0 ? yr / ym : 1;
    bool measured[24];
    for (int p = 0; p < 24; p++) {
        measured[p] = patches[p].pixels > 0;
        fit->de_before[p] = fit->de_after[p] = -1;
        if (!measured[p])
            continue;
        double before[3], after[3];
        for (int c = 0; c < 3; c++) {
            before[c] = k_before * patches[p].rgb[c];
            after[c] = fit->m[c][0] * patches[p].rgb[0] + fit->m[c][1] * patches[p].rgb[1] +
                       fit->m[c][2] * patches[p].rgb[2];
        }
        fit->de_before[p] = sl_chart_delta_e(before, reference[p]);
        fit->de_after[p] = sl_chart_delta_e(after, reference[p]);
    }
    /* Statistics over the patches in the fit; excluded ones are listed per patch. */
    summarise(fit->de_before, fit->used_patch, &fit->de_before_mean, &fit->de_before_max);
    summarise(fit->de_after, fit->used_patch, &fit->de_after_mean, &fit->de_after_max);
    if (!isfinite(d) || d == 0)
        return sl_error_set(err, SL_ERR_INPUT, "chart: the fitted colour matrix is singular");
    return SL_OK;
}

sl_result sl_ccm_fit_chart(const sl_chart_patch patches[24], const double reference[24][3],
                           const sl_ccm_options *opt, sl_ccm_fit *fit, sl_error *err)
{
    sl_ccm_options defaults;
    sl_ccm_options_init(&defaults);
    if (!opt)
        opt = &defaults;
    bool excl[24] = {false};
    sl_result r = fit_once(patches, reference, opt, excl, fit, err);
    if (r || !(opt->outlier_ratio > 1))
        return r;
    /* A shadow across part of the chart (or glare, or a reflection) makes
     * those patches darker or brighter than any colour matrix can explain:
     * keep the largest group whose fitted/reference luminance ratios lie
     * within outlier_ratio of each other (the brighter on a tie), refit. */
    for (int round = 0; round < 3; round++) {
        double lq[24][2];
        int m = 0;
        for (int p = 0; p < 24; p++) {
            if (!fit->used_patch[p])
                continue;
            double v[3];
            sl_mat3_apply(fit->m, patches[p].rgb, v);
            double q = sl_luminance(v) / sl_luminance(reference[p]);
            lq[m][0] = q > 0 ? log(q) : -1e300;
            lq[m++][1] = p;
        }
        qsort(lq, (size_t)m, sizeof(lq[0]), sl_cmp_double);
        int best = 0, bi = 0;
        for (int i = 0, j = 0; i < m; i++) {
            while (j < m && lq[j][0] - lq[i][0] <= log(opt->outlier_ratio))
                j++;
            if (j - i >= best)
                best = j - i, bi = i;
        }
        if (best == m || best < 6)
            break;
        for (int k = 0; k < m; k++)
            if (k < bi || k >= bi + best)
                excl[(int)lq[k][1]] = true;
        if ((r = fit_once(patches, reference, opt, excl, fit, err)))
            return r;
    }
    for (int p = 0; p < 24; p++) {
        fit->outlier[p] = excl[p];
        fit->outliers += excl[p];
    }
    return SL_OK;
}

void sl_ccm_plate_matrix(const sl_chart_patch patches[24], const sl_ccm_fit *fit,
                         double plate[3][3])
{
    /* The chart's light level is unknown: keep the neutral patch's
     * luminance, leave exposure to the grey sphere. */
    int n = fit->neutral_patch;
    for (int k = 21; n < 0 && k >= 18; k--)
        if (fit->used_patch[k])
            n = k;
    double y_in = 0, y_out = 0;
    if (n >= 0) {
        double v[3];
        sl_mat3_apply(fit->m, patches[n].rgb, v);
        y_in = sl_luminance(patches[n].rgb);
        y_out = sl_luminance(v);
    }
    double k = y_out > 0 && y_in > 0 ? y_in / y_out : 1 / fit->gain;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            plate[i][j] = fit->m[i][j] * k;
}
