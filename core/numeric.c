/* SPDX-License-Identifier: BSD-3-Clause */
/* Small numeric helpers shared by the modules (core.h). */
#include <math.h>

#include "setlight/core.h"

int sl_cmp_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

double sl_fresnel_conductor(double cos_i, double n, double k)
{
    cos_i = fmin(fmax(cos_i, 0.0), 1.0);
    double c2 = cos_i * cos_i, s2 = 1.0 - c2;
    double n2 = n * n, k2 = k * k;
    double t0 = n2 - k2 - s2;
    double a2b2 = sqrt(t0 * t0 + 4.0 * n2 * k2);
    double a = sqrt(fmax(0.0, 0.5 * (a2b2 + t0)));
    double t1 = a2b2 + c2, t2 = 2.0 * cos_i * a;
    double rs = (t1 - t2) / (t1 + t2);
    double t3 = c2 * a2b2 + s2 * s2, t4 = t2 * s2;
    double rp = rs * (t3 - t4) / (t3 + t4);
    return 0.5 * (rs + rp);
}

int sl_cmp_ranked_desc(const void *a, const void *b)
{
    const sl_ranked *x = a, *y = b;
    if (x->value != y->value)
        return x->value < y->value ? 1 : -1;
    return (x->index > y->index) - (x->index < y->index);
}
