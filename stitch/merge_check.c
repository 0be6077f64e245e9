/* SPDX-License-Identifier: BSD-3-Clause */
/* Exposure ratios measured from the pixels, to check what EXIF claims. */
#include <math.h>
#include <stdlib.h>

#include "merge_private.h"

/* Fewer usable pixel pairs than this and a ratio is not trusted. */
enum { MIN_PAIRS = 32 };

static int cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int merge_fit_ratios(const merge_samples *s, const sl_response *resp, double black,
                     double saturation, double *ratio)
{
    int f = s->frames, fitted = 0;
    /* Well exposed: above 1% of full scale in linear terms (dark codes are
     * few and noisy) and clear of the shoulder. */
    double lo = fmax(2 * black, 0.02), hi = saturation - 0.04, ylo = 0.01;
    double *r = malloc((size_t)s->count * 3 * sizeof *r);
    for (int q = 0; q + 1 < f; q++) {
        ratio[q] = 0;
        if (!r)
            continue;
        int n = 0;
        for (int i = 0; i < s->count; i++)
            for (int c = 0; c < 3; c++) {
                double z0 = s->z[((size_t)i * f + q) * 3 + c];
                double z1 = s->z[((size_t)i * f + q + 1) * 3 + c];
                if (!(z0 > lo && z0 < hi && z1 > lo && z1 < hi))
                    continue;
                double y0 = sl_response_eval(resp, c, z0), y1 = sl_response_eval(resp, c, z1);
                if (y0 > ylo && y1 > ylo)
                    r[n++] = y1 / y0;
            }
        if (n < MIN_PAIRS)
            continue;
        qsort(r, (size_t)n, sizeof *r, cmp_double);
        ratio[q] = n % 2 ? r[n / 2] : 0.5 * (r[n / 2 - 1] + r[n / 2]);
        fitted++;
    }
    free(r);
    return fitted;
}
