/* SPDX-License-Identifier: BSD-3-Clause */
/* Exposure ratios measured from the pixels, to check what EXIF claims. */
#include <math.h>
#include <stdlib.h>

#include "merge_private.h"

/* Fewer usable pixel pairs than this and a ratio is not trusted. */
enum { MIN_PAIRS = 32 };

double merge_select_kth(double *v, int n, int k)
{
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        double pivot = v[lo + (hi - lo) / 2];
        int i = lo, j = hi;
        while (i <= j) {
            while (v[i] < pivot)
                i++;
            while (v[j] > pivot)
                j--;
            if (i <= j) {
                double t = v[i];
                v[i++] = v[j];
                v[j--] = t;
            }
        }
        if (k <= j)
            hi = j;
        else if (k >= i)
            lo = i;
        else
            break;
    }
    return v[k];
}

int merge_fit_ratios(const merge_samples *s, const sl_response *resp, double black,
                     double saturation, const double *log_exif, double *ratio)
{
    int f = s->frames, fitted = 0;
    /* Well exposed: above 1% of full scale in linear terms (dark codes are
     * few and noisy) and clear of the shoulder. For lossless frames the
     * floor is judged in the longer frame only, at 1% times the EXIF step:
     * picking pairs by the shorter frame's own noisy value keeps those that
     * noise pushed up, which biases the ratio (a 4000-electron sensor: honest
     * steps measured 0.3-1.2 stops off, and the curve fitted to them). JPEG
     * frames keep the floor in both: their dark codes carry DCT error the
     * median does not average out (the night set's 5x2 JPEGs named a frame
     * at +0.34 stops). */
    double lo = fmax(2 * black, 0.02), hi = saturation - 0.04, ylo = 0.01;
    double *r = malloc((size_t)s->count * 3 * sizeof *r);
    merge_code_curve curve;
    merge_code_curve_init(&curve, s, resp);
    for (int q = 0; q + 1 < f; q++) {
        ratio[q] = 0;
        if (!r)
            continue;
        /* A step seen only in spoilt JPEG blocks (a dark frame's lamps) is
         * not measured: their pairs are biased by tens of percent. */
        int n = 0;
        double y0lo = s->coded ? ylo : 0, z0lo = s->coded ? lo : 0;
        double y1lo = s->coded ? ylo : ylo * exp(log_exif[q + 1] - log_exif[q]);
        for (int i = 0; i < s->count; i++) {
            if (!merge_usable(s, i, q, hi) || !merge_usable(s, i, q + 1, hi))
                continue;
            for (int c = 0; c < 3; c++) {
                double z0 = s->z[((size_t)i * f + q) * 3 + c];
                double z1 = s->z[((size_t)i * f + q + 1) * 3 + c];
                if (!(z0 > z0lo && z1 > lo))
                    continue;
                double y0 = merge_code_curve_y(&curve, resp, c, (float)z0),
                       y1 = merge_code_curve_y(&curve, resp, c, (float)z1);
                if (y0 > y0lo && y1 > y1lo)
                    r[n++] = y1 / y0;
            }
        }
        if (n < MIN_PAIRS)
            continue;
        double upper = merge_select_kth(r, n, n / 2);
        /* The selection leaves the n / 2 smallest first: the lower middle is their largest. */
        double lower = r[0];
        for (int k = 1; k < n / 2; k++)
            lower = r[k] > lower ? r[k] : lower;
        ratio[q] = n % 2 ? upper : 0.5 * (upper + lower);
        fitted++;
    }
    free(r);
    return fitted;
}
