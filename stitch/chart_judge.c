/* SPDX-License-Identifier: BSD-3-Clause */
/* Is what was found a ColorChecker? The fit is judged against the chart's
 * physics: one light over most of it, the neutral row's reflectances
 * falling step by step white to black with the reference's contrast, the
 * colour patches more colourful than the neutrals and in the reference's
 * hue order round the colour circle, and a colour matrix a camera can
 * have. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "calibrate_internal.h"
#include "setlight/stitch.h"

/* Camera RGB has no luminance of its own; for neutral patches (flat
 * spectra) any positive weighting orders them alike. */
static double level(const double rgb[3]) { return rgb[0] + rgb[1] + rgb[2]; }

/* Hue angle and saturation of a white-balanced linear colour. */
static void hue_chroma(const double rgb[3], const double wb[3], double *hue, double *chroma)
{
    double r = rgb[0] * wb[0], g = rgb[1] * wb[1], b = rgb[2] * wb[2];
    double mx = fmax(r, fmax(g, b)), mn = fmin(r, fmin(g, b));
    *hue = atan2(sqrt(3.0) * (g - b), 2 * r - g - b);
    *chroma = mx > 0 ? (mx - mn) / mx : 0;
}

/* sigma_max / sigma_min. */
static double condition3(const double m[3][3])
{
    double mtm[3][3], ev[3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            mtm[i][j] = m[0][i] * m[0][j] + m[1][i] * m[1][j] + m[2][i] * m[2][j];
    sl_mat3_sym_eigenvalues(mtm, ev);
    return ev[2] > 0 ? sqrt(ev[0] / ev[2]) : INFINITY;
}

/* Median of v[0..n) (sorted in place); 0 when n is 0. */
static double median(double *v, int n)
{
    if (n <= 0)
        return 0;
    qsort(v, (size_t)n, sizeof(double), sl_cmp_double);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

double sl_chart_identity_delta_e(const double reference[24][3])
{
    /* The median over patches of the CIEDE2000 to the nearest other one
     * (13.1 for the ColorChecker Classic). */
    double nearest[24];
    for (int p = 0; p < 24; p++) {
        nearest[p] = INFINITY;
        for (int q = 0; q < 24; q++)
            if (q != p)
                nearest[p] = fmin(nearest[p], sl_chart_delta_e(reference[p], reference[q]));
    }
    return median(nearest, 24);
}

/* Appends "; "-separated text. */
static void say(sl_chart_judgement *j, unsigned reason, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
static void say(sl_chart_judgement *j, unsigned reason, const char *fmt, ...)
{
    j->reasons |= reason;
    size_t n = strlen(j->text);
    if (n + 3 >= sizeof(j->text))
        return;
    if (n)
        n += (size_t)snprintf(j->text + n, sizeof(j->text) - n, "; ");
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(j->text + n, sizeof(j->text) - n, fmt, ap);
    va_end(ap);
}

void sl_chart_judge(const sl_chart_patch patches[24], const sl_ccm_fit *fit,
                    const double reference[24][3], sl_chart_judgement *j)
{
    memset(j, 0, sizeof(*j));
    j->used = fit->used;
    j->de_after_mean = fit->de_after_mean;
    /* One light: the outlier test keeps the largest group of patches lit
     * alike; unless that is most of the chart, the chart's light (and so
     * the chart) is not identified. */
    if (fit->used < SL_CHART_MIN_USED)
        say(j, SL_CHART_FEW_PATCHES, "only %d of 24 patches fit one colour matrix under one light "
            "(at least %d)", fit->used, SL_CHART_MIN_USED);

    /* The neutral row, patches 19..24 (white 0.90 down to black 0.03). */
    double lx[6], ly[6], previous = INFINITY;
    int n = 0;
    for (int p = 18; p < 24; p++) {
        if (!fit->used_patch[p])
            continue;
        double m = level(patches[p].rgb), r = level(reference[p]);
        j->order_breaks += !(m < previous);
        previous = m;
        lx[n] = m > 0 ? log(m) : -INFINITY;
        ly[n++] = log(r);
    }
    j->neutrals_used = n;
    if (n < 3) {
        say(j, SL_CHART_NEUTRALS, "only %d of the 6 neutral patches in the fit (at least 3)", n);
    } else {
        /* d log(measured) / d log(reference): 1 for a linear camera; flare
         * lowers it, a tone curve bends it, a flat wall makes it 0. */
        double mx = 0, my = 0, sxy = 0, syy = 0;
        for (int i = 0; i < n; i++)
            mx += lx[i] / n, my += ly[i] / n;
        for (int i = 0; i < n; i++)
            sxy += (lx[i] - mx) * (ly[i] - my), syy += (ly[i] - my) * (ly[i] - my);
        j->neutral_slope = isfinite(mx) ? sxy / syy : 0;
        if (j->order_breaks)
            say(j, SL_CHART_NEUTRALS, "the neutral row does not darken step by step from white "
                "to black (%d steps not darker)", j->order_breaks);
        else if (!(j->neutral_slope >= 1 / SL_CHART_MAX_CONTRAST_ERROR &&
                   j->neutral_slope <= SL_CHART_MAX_CONTRAST_ERROR))
            say(j, SL_CHART_NEUTRALS, "the neutral row's contrast is %.2f times the chart's in "
                "log terms (%.2f..%.2f)", j->neutral_slope, 1 / SL_CHART_MAX_CONTRAST_ERROR,
                SL_CHART_MAX_CONTRAST_ERROR);
    }

    /* The six colour patches 13..18 (blue, green, red, yellow, magenta,
     * cyan), white-balanced on the neutrals: as colourful as the chart's,
     * and round the hue circle in the reference's order. */
    double wb[3] = {0, 0, 0}, wr[3] = {0, 0, 0};
    for (int p = 18; p < 24; p++)
        for (int c = 0; c < 3; c++) {
            wb[c] += fit->used_patch[p] ? patches[p].rgb[c] : 0;
            wr[c] += reference[p][c];
        }
    for (int c = 0; c < 3; c++) {
        wb[c] = wb[c] > 0 ? 1 / wb[c] : 0;
        wr[c] = wr[c] > 0 ? 1 / wr[c] : 0;
    }
    /* The neutrals' median saturation: the black patch's is all offset
     * and noise. */
    double neutral[6], chroma[6], hue_ref[6], hue[6];
    int nn = 0;
    for (int p = 18; p < 24; p++)
        if (fit->used_patch[p]) {
            double h;
            hue_chroma(patches[p].rgb, wb, &h, &neutral[nn++]);
        }
    double neutral_chroma = median(neutral, nn);
    int k = 0;
    for (int p = 12; p < 18; p++) {
        if (!patches[p].valid || !(patches[p].pixels > 0))
            continue;
        double c;
        hue_chroma(reference[p], wr, &hue_ref[k], &c);
        hue_chroma(patches[p].rgb, wb, &hue[k], &chroma[k]);
        k++;
    }
    j->colours_usable = k;
    j->neutral_chroma = neutral_chroma;
    if (k < 3) {
        say(j, SL_CHART_COLOURS, "only %d of the 6 colour patches (blue ... cyan) usable "
            "(at least 3)", k);
    } else if (nn >= 1) {
        /* The smallest of the colour patches' saturations. */
        double least = 1;
        for (int i = 0; i < k; i++)
            least = fmin(least, chroma[i]);
        j->colour_chroma = least;
        if (!(least > SL_CHART_MIN_CHROMA_RATIO * neutral_chroma))
            say(j, SL_CHART_COLOURS, "the colour patches are hardly more colourful than the "
                "neutral row (saturation %.2f against %.2f)", least, neutral_chroma);
        /* Winding number of the measured hues taken in the reference's
         * order: one turn when the order round the circle is kept. */
        int idx[6];
        for (int i = 0; i < k; i++)
            idx[i] = i;
        for (int a = 1; a < k; a++)
            for (int b = a; b > 0 && hue_ref[idx[b]] < hue_ref[idx[b - 1]]; b--) {
                int t = idx[b];
                idx[b] = idx[b - 1];
                idx[b - 1] = t;
            }
        double turn = 0;
        for (int i = 0; i < k; i++) {
            double d = hue[idx[(i + 1) % k]] - hue[idx[i]];
            turn += d - 2 * M_PI * floor(d / (2 * M_PI));
        }
        j->hue_turns = (int)lround(turn / (2 * M_PI));
        if (j->hue_turns != 1 && !(j->reasons & SL_CHART_COLOURS))
            say(j, SL_CHART_COLOURS, "the colour patches are out of the chart's hue order");
    }

    /* A camera's colour matrix: orientation kept (its red, green and blue
     * see long, middle and short wavelengths), white sent to a positive
     * colour, and no direction amplified by much more than the others. */
    double det = fit->m[0][0] * (fit->m[1][1] * fit->m[2][2] - fit->m[1][2] * fit->m[2][1]) -
                 fit->m[0][1] * (fit->m[1][0] * fit->m[2][2] - fit->m[1][2] * fit->m[2][0]) +
                 fit->m[0][2] * (fit->m[1][0] * fit->m[2][1] - fit->m[1][1] * fit->m[2][0]);
    j->condition = condition3(fit->m);
    bool white_positive = true;
    for (int c = 0; c < 3; c++)
        white_positive = white_positive &&
                         fit->m[c][0] * (wb[0] > 0 ? 1 / wb[0] : 0) +
                                 fit->m[c][1] * (wb[1] > 0 ? 1 / wb[1] : 0) +
                                 fit->m[c][2] * (wb[2] > 0 ? 1 / wb[2] : 0) > 0;
    if (!(det > 0))
        say(j, SL_CHART_MATRIX, "the colour matrix swaps colours (determinant %.3g)", det);
    else if (!(j->condition <= SL_CHART_MAX_CONDITION))
        say(j, SL_CHART_MATRIX, "the colour matrix is ill-conditioned (condition %.0f, at most "
            "%.0f)", j->condition, SL_CHART_MAX_CONDITION);
    else if (nn >= 1 && !white_positive)
        say(j, SL_CHART_MATRIX, "the colour matrix sends the neutral row below zero");

    /* Patches no nearer their references than neighbouring patches are
     * to each other are not identified. */
    j->de_limit = sl_chart_identity_delta_e(reference);
    if (!(fit->de_after_mean <= j->de_limit))
        say(j, SL_CHART_DELTA_E, "the patches are still %.1f CIEDE2000 from the chart after "
            "the best matrix (patches %.1f apart on the chart)", fit->de_after_mean, j->de_limit);
    j->plausible = j->reasons == 0;
}
