/* SPDX-License-Identifier: BSD-3-Clause */
/* The curve-shape prior (stitch/response_prior.c) on families whose
 * principal components are known: power laws z^gamma have the shapes
 * d(z) = gamma (ln z - ln z_mid), one direction with variance var(gamma)
 * times its squared length; its precision inverts the covariance along
 * the components and leaves the level free; and a prior asking for more
 * components than curves is refused. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "../stitch/merge_private.h" /* the prior's fields, merge_prior_precision */
#include "testing.h"

enum { CURVES = 7, NODES = MERGE_PRIOR_NODES };

/* Inverse table z^gamma (three equal channels), times exp(toe (1 - z)^8)
 * for a second, independent shape. */
static void power_law(sl_response *r, double gamma, double toe)
{
    sl_error err;
    CHECK_OK(sl_response_linear(r, NODES, &err), &err);
    for (int c = 0; c < 3 && r->inverse; c++)
        for (int k = 0; k < NODES; k++) {
            double z = (double)k / (NODES - 1);
            r->inverse[c * NODES + k] = pow(z, gamma) * exp(toe * pow(1 - z, 8));
        }
}

static void test_power_laws(void)
{
    sl_response curves[CURVES];
    double mean_gamma = 0, var_gamma = 0;
    for (int i = 0; i < CURVES; i++) {
        double gamma = 1.6 + 0.2 * i;
        power_law(&curves[i], gamma, 0);
        mean_gamma += gamma / CURVES;
    }
    for (int i = 0; i < CURVES; i++)
        var_gamma += pow(1.6 + 0.2 * i - mean_gamma, 2) / (CURVES - 1);
    sl_error err;
    sl_response_prior *p;
    CHECK_OK(sl_response_prior_build(curves, CURVES, 2, "power laws", &p, &err), &err);
    /* The second component has no variance: left out. */
    if (!p)
        return;
    /* The direction ln z - ln z_mid over the covered nodes, and its length. */
    double dir[NODES] = {0}, len2 = 0, zmid = (double)(NODES / 2) / (NODES - 1);
    for (int k = p->first; k < NODES; k++) {
        dir[k] = log((double)k / (NODES - 1)) - log(zmid);
        len2 += dir[k] * dir[k];
    }
    double worst_mean = 0, dot = 0;
    for (int k = 0; k < NODES; k++) {
        worst_mean = fmax(worst_mean, fabs(p->mean[k] - mean_gamma * dir[k]));
        dot += p->basis[k] * dir[k] / sqrt(len2);
    }
    printf("  power laws: mean within %.2e, first component . direction %.9f, variance %.6g "
           "(want %.6g), %d component(s), residual %.3g\n",
           worst_mean, dot, p->variance[0], var_gamma * len2, p->components, p->residual);
    CHECK(p->first == (int)ceil(0.02 * (NODES - 1)));
    CHECK_MSG(worst_mean < 1e-9, "mean off by %.3g", worst_mean);
    CHECK_MSG(fabs(fabs(dot) - 1) < 1e-9, "first component . direction %.12f", dot);
    CHECK_NEAR(p->variance[0], var_gamma * len2, 1e-9 * var_gamma * len2);
    CHECK_MSG(p->components == 1, "%d components", p->components);
    /* The precision inverts the covariance along the component (u^T P u =
     * 1 / l, but for the level left free: a part r / l) and leaves the
     * level free (P 1 = 0). */
    double *prec = malloc((size_t)NODES * NODES * sizeof *prec), pm[NODES];
    merge_prior_precision(p, 0, NODES - 1, prec, pm);
    double upu = 0, worst = 0, scale = 0;
    for (int i = 0; prec && i < NODES; i++) {
        double row = 0;
        for (int j = 0; j < NODES; j++) {
            upu += p->basis[i] * prec[i * NODES + j] * p->basis[j];
            row += prec[i * NODES + j];
            scale = fmax(scale, fabs(prec[i * NODES + j]));
        }
        worst = fmax(worst, fabs(row));
        if (i < p->first)
            CHECK(pm[i] == 0 && prec[i * NODES + i] == 0);
    }
    printf("  u^T P u l = %.6f, |P 1| at most %.2e of P's largest entry\n", upu * p->variance[0],
           worst / scale);
    CHECK_NEAR(upu * p->variance[0], 1, 1e-3);
    CHECK_MSG(worst < 1e-9 * scale, "P 1: %.3g", worst);
    free(prec);
    sl_response_prior_free(p);
    /* Two independent shapes (the gamma and a toe) need two components. */
    for (int i = 0; i < CURVES; i++) {
        sl_response_free(&curves[i]);
        power_law(&curves[i], 1.6 + 0.2 * i, 0.1 * ((i * 3) % CURVES));
    }
    CHECK_OK(sl_response_prior_build(curves, CURVES, 3, "with toes", &p, &err), &err);
    if (p) {
        printf("  gamma and toe: %d components, variances %.3g, %.3g\n", p->components,
               p->variance[0], p->variance[1]);
        CHECK(p->components == 2);
        CHECK(p->variance[1] > 1e-4 * p->variance[0]);
    }
    sl_response_prior_free(p);
    /* More components than the curves have: refused. */
    p = NULL;
    CHECK(sl_response_prior_build(curves, CURVES, CURVES, "too many", &p, &err) ==
          SL_ERR_INPUT);
    CHECK(p == NULL);
    for (int i = 0; i < CURVES; i++)
        sl_response_free(&curves[i]);
}

int main(void)
{
    RUN(test_power_laws);
    return sl_test_finish();
}
