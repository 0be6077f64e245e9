/* SPDX-License-Identifier: BSD-3-Clause */
/* Upper tail of the chi-square distribution through the regularized upper
 * incomplete gamma function Q(a, x): a series for x < a + 1 and a Lentz
 * continued fraction beyond (the classic split, where each converges fast). */
#include "setlight/core.h"

#include <float.h>
#include <math.h>

#define ITER_MAX 10000
#define TINY 1e-300

/* P(a, x) by its power series. */
static double gamma_p_series(double a, double x)
{
    double ap = a, term = 1.0 / a, sum = term;
    for (int n = 0; n < ITER_MAX; n++) {
        ap += 1.0;
        term *= x / ap;
        sum += term;
        if (fabs(term) < fabs(sum) * DBL_EPSILON)
            break;
    }
    return sum * exp(-x + a * log(x) - lgamma(a));
}

/* Q(a, x) by its continued fraction (modified Lentz). */
static double gamma_q_fraction(double a, double x)
{
    double b = x + 1.0 - a, c = 1.0 / TINY, d = 1.0 / b, h = d;
    for (int i = 1; i < ITER_MAX; i++) {
        double an = -i * (i - a);
        b += 2.0;
        d = an * d + b;
        if (fabs(d) < TINY)
            d = TINY;
        c = b + an / c;
        if (fabs(c) < TINY)
            c = TINY;
        d = 1.0 / d;
        double delta = d * c;
        h *= delta;
        if (fabs(delta - 1.0) < DBL_EPSILON)
            break;
    }
    return exp(-x + a * log(x) - lgamma(a)) * h;
}

double sl_chi2_pvalue(double stat, int dof)
{
    if (!(stat > 0.0))
        return 1.0;
    if (dof <= 0) /* a chi-square with no freedom is the constant 0 */
        return 0.0;
    if (isinf(stat))
        return 0.0;
    double a = 0.5 * dof, x = 0.5 * stat;
    if (x < a + 1.0) {
        double q = 1.0 - gamma_p_series(a, x);
        return q < 0.0 ? 0.0 : q;
    }
    return gamma_q_fraction(a, x);
}
