/* SPDX-License-Identifier: BSD-3-Clause */
/* A Gaussian prior on camera-curve shapes for the self-calibrated fit:
 * the mean and principal components of d(z) = g(z) - g(z_mid), g = ln f^-1,
 * over a set of measured curves (docs/merge.md "Real camera curves").
 * Equal bracket steps leave g free along g + p(g), p periodic in ln
 * exposure; the fit's smoothness picks a member of that class, and the
 * prior pulls it towards the shapes real curves have. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "merge_private.h"

/* Below this code ln f^-1 runs to -inf and says little about a shape. */
#define PRIOR_FROM_CODE 0.02
/* Linear values below this fraction of mid-grey's count as this (a curve
 * black before PRIOR_FROM_CODE would otherwise have d = -inf there). */
#define PRIOR_FLOOR 1e-4

int merge_prior_first_node(int nodes)
{
    return (int)ceil(PRIOR_FROM_CODE * (nodes - 1));
}

/* A curve's shape at node k of `nodes`: ln f^-1 less its value at mid-grey
 * (mid: f^-1 there), floored as PRIOR_FLOOR says. */
static double shape_at(const sl_response *curve, int channel, int k, int nodes, double mid)
{
    double y = sl_response_eval(curve, channel, (double)k / (nodes - 1));
    return log(fmax(y, PRIOR_FLOOR * mid) / mid);
}

/* Eigenvalues (descending, into ev) and unit eigenvectors (columns of v)
 * of the symmetric n x n matrix a (destroyed) by cyclic Jacobi rotations:
 * short, and exact enough for a few hundred curves. */
static void jacobi_eigen(double *a, int n, double *ev, double *v)
{
    for (int i = 0; i < n * n; i++)
        v[i] = 0;
    for (int i = 0; i < n; i++)
        v[i * n + i] = 1;
    for (int sweep = 0; sweep < 60; sweep++) {
        double off = 0, diag = 0;
        for (int i = 0; i < n; i++) {
            diag += a[i * n + i] * a[i * n + i];
            for (int j = i + 1; j < n; j++)
                off += a[i * n + j] * a[i * n + j];
        }
        if (off <= 1e-30 * diag)
            break;
        for (int p = 0; p < n; p++)
            for (int q = p + 1; q < n; q++) {
                double apq = a[p * n + q];
                if (fabs(apq) < 1e-300)
                    continue;
                double theta = (a[q * n + q] - a[p * n + p]) / (2 * apq);
                double t = (theta >= 0 ? 1 : -1) / (fabs(theta) + sqrt(theta * theta + 1));
                double c = 1 / sqrt(t * t + 1), s = t * c;
                for (int k = 0; k < n; k++) { /* columns p, q */
                    double akp = a[k * n + p], akq = a[k * n + q];
                    a[k * n + p] = c * akp - s * akq;
                    a[k * n + q] = s * akp + c * akq;
                }
                for (int k = 0; k < n; k++) { /* rows p, q */
                    double apk = a[p * n + k], aqk = a[q * n + k];
                    a[p * n + k] = c * apk - s * aqk;
                    a[q * n + k] = s * apk + c * aqk;
                }
                for (int k = 0; k < n; k++) {
                    double vkp = v[k * n + p], vkq = v[k * n + q];
                    v[k * n + p] = c * vkp - s * vkq;
                    v[k * n + q] = s * vkp + c * vkq;
                }
            }
    }
    /* Sort descending (selection: n is small). */
    for (int i = 0; i < n; i++)
        ev[i] = a[i * n + i];
    for (int i = 0; i < n; i++) {
        int best = i;
        for (int j = i + 1; j < n; j++)
            if (ev[j] > ev[best])
                best = j;
        if (best == i)
            continue;
        double t = ev[i];
        ev[i] = ev[best];
        ev[best] = t;
        for (int k = 0; k < n; k++) {
            t = v[k * n + i];
            v[k * n + i] = v[k * n + best];
            v[k * n + best] = t;
        }
    }
}

sl_result sl_response_prior_build(const sl_response *curves, int count, int components,
                                  const char *name, sl_response_prior **out, sl_error *err)
{
    *out = NULL;
    int nodes = MERGE_PRIOR_NODES, first = merge_prior_first_node(nodes), dim = nodes - first;
    if (count < 2 || components < 1 || components >= count || components >= dim)
        return sl_error_set(err, SL_ERR_INPUT,
                            "response prior: %d curves cannot give %d components", count,
                            components);
    sl_response_prior *p = calloc(1, sizeof *p);
    /* mean, basis and variance in one block */
    double *own = malloc(((size_t)components * nodes + nodes + components) * sizeof *own);
    double *x = malloc((size_t)count * dim * sizeof *x);
    double *gram = malloc((size_t)count * count * sizeof *gram);
    double *ev = malloc((size_t)count * sizeof *ev);
    double *vec = malloc((size_t)count * count * sizeof *vec);
    if (!p || !own || !x || !gram || !ev || !vec) {
        free(p), free(own), free(x), free(gram), free(ev), free(vec);
        return sl_error_set(err, SL_ERR_NOMEM, "response prior: out of memory");
    }
    double *mean = own, *variance = own + nodes, *basis = own + nodes + components;
    memset(mean, 0, (size_t)nodes * sizeof *mean);
    *p = (sl_response_prior){.nodes = nodes, .first = first, .mean = mean, .basis = basis,
                             .variance = variance, .owned = own};
    snprintf(p->name, sizeof p->name, "%s", name ? name : "");
    /* Each curve's shape d on the covered nodes, and their mean. */
    for (int i = 0; i < count; i++) {
        double mid = sl_response_eval(&curves[i], 0, (double)(nodes / 2) / (nodes - 1));
        for (int k = first; k < nodes; k++)
            x[(size_t)i * dim + k - first] = shape_at(&curves[i], 0, k, nodes, mid);
    }
    for (int j = 0; j < dim; j++) {
        double s = 0;
        for (int i = 0; i < count; i++)
            s += x[(size_t)i * dim + j];
        mean[first + j] = s / count;
        for (int i = 0; i < count; i++)
            x[(size_t)i * dim + j] -= s / count;
    }
    /* Principal components through the curves' Gram matrix (count x count,
     * smaller than dim x dim): X X^T v = l v gives X^T v / sqrt(l). */
    for (int i = 0; i < count; i++)
        for (int j = 0; j <= i; j++) {
            double s = 0;
            for (int k = 0; k < dim; k++)
                s += x[(size_t)i * dim + k] * x[(size_t)j * dim + k];
            gram[i * count + j] = gram[j * count + i] = s;
        }
    double total = 0;
    for (int i = 0; i < count; i++)
        total += gram[i * count + i];
    jacobi_eigen(gram, count, ev, vec);
    /* Components the curves do not vary along (a family of fewer shapes
     * than asked for) are left out: their direction is rounding noise. */
    while (components > 1 && !(ev[components - 1] > 1e-12 * ev[0]))
        components--;
    p->components = components;
    double kept = 0;
    for (int c = 0; c < components; c++) {
        double l = fmax(ev[c], 1e-300);
        for (int k = 0; k < nodes; k++) {
            double s = 0;
            for (int i = 0; k >= first && i < count; i++)
                s += x[(size_t)i * dim + k - first] * vec[i * count + c];
            basis[(size_t)c * nodes + k] = s / sqrt(l);
        }
        variance[c] = ev[c] / (count - 1);
        kept += ev[c];
    }
    /* What the components leave, spread evenly over the covered nodes
     * (probabilistic PCA's isotropic residual). */
    p->residual = fmax((total - kept) / (count - 1) / (dim - components), 1e-9 * p->variance[0]);
    free(x), free(gram), free(ev), free(vec);
    *out = p;
    return SL_OK;
}

void sl_response_prior_free(sl_response_prior *p)
{
    if (!p)
        return;
    free(p->owned);
    free(p);
}

void merge_prior_precision(const sl_response_prior *p, int lo, int hi, double *prec,
                           double *prec_mean)
{
    int n = p->nodes, kc = p->components;
    lo = lo > p->first ? lo : p->first;
    hi = hi < n - 1 ? hi : n - 1;
    memset(prec, 0, (size_t)n * n * sizeof *prec);
    memset(prec_mean, 0, (size_t)n * sizeof *prec_mean);
    if (hi - lo < 2)
        return;
    /* The prior's marginal on nodes lo..hi, C = U L U^T + r I, inverted by
     * Woodbury: P = (I - U^T M^-1 U) / r with M = r L^-1 + U U^T (K x K). */
    double *mm = malloc((size_t)kc * kc * sizeof *mm), *col = malloc((size_t)kc * kc * sizeof *col);
    double *v = malloc((size_t)kc * n * sizeof *v), *rhs = malloc((size_t)kc * sizeof *rhs);
    double *ones = malloc((size_t)n * sizeof *ones);
    if (!mm || !col || !v || !rhs || !ones) {
        free(mm), free(col), free(v), free(rhs), free(ones);
        return; /* no prior rather than a wrong one */
    }
    for (int a = 0; a < kc; a++)
        for (int b = 0; b < kc; b++) {
            double s = a == b ? p->residual / p->variance[a] : 0;
            for (int k = lo; k <= hi; k++)
                s += p->basis[(size_t)a * n + k] * p->basis[(size_t)b * n + k];
            mm[a * kc + b] = s;
        }
    bool ok = true;
    for (int k = lo; k <= hi && ok; k++) { /* V = M^-1 U, a node at a time */
        memcpy(col, mm, (size_t)kc * kc * sizeof *col);
        for (int a = 0; a < kc; a++)
            rhs[a] = p->basis[(size_t)a * n + k];
        ok = merge_cholesky_solve(col, rhs, kc);
        for (int a = 0; a < kc; a++)
            v[(size_t)a * n + k] = rhs[a];
    }
    for (int i = lo; i <= hi && ok; i++)
        for (int j = lo; j <= hi; j++) {
            double s = i == j;
            for (int a = 0; a < kc; a++)
                s -= p->basis[(size_t)a * n + i] * v[(size_t)a * n + j];
            prec[i * n + j] = s / p->residual;
        }
    /* The level is the data's (and g(mid) = 0's): a free offset c on the
     * shape, integrated out, leaves P - P 1 1^T P / (1^T P 1). */
    double total = 0;
    for (int i = lo; i <= hi && ok; i++) {
        double s = 0;
        for (int j = lo; j <= hi; j++)
            s += prec[i * n + j];
        ones[i] = s;
        total += s;
    }
    for (int i = lo; i <= hi && ok && total > 0; i++)
        for (int j = lo; j <= hi; j++)
            prec[i * n + j] -= ones[i] * ones[j] / total;
    for (int i = lo; i <= hi && ok; i++) {
        double s = 0;
        for (int j = lo; j <= hi; j++)
            s += prec[i * n + j] * p->mean[j];
        prec_mean[i] = s;
    }
    if (!ok)
        memset(prec, 0, (size_t)n * n * sizeof *prec);
    free(mm), free(col), free(v), free(rhs), free(ones);
}

double sl_response_prior_distance(const sl_response_prior *p, const sl_response *curve, int channel)
{
    int n = p->nodes, first = p->first;
    double mid = sl_response_eval(curve, channel, (double)(n / 2) / (n - 1));
    double *d = malloc((size_t)n * sizeof *d);
    if (!d || !(mid > 0)) {
        free(d);
        return NAN;
    }
    for (int k = first; k < n; k++)
        d[k] = shape_at(curve, channel, k, n, mid) - p->mean[k];
    /* d^T P d = |d|^2 / r + sum_c (1 / l_c - 1 / r) (u_c . d)^2 */
    double s = 0;
    for (int k = first; k < n; k++)
        s += d[k] * d[k];
    s /= p->residual;
    for (int c = 0; c < p->components; c++) {
        double u = 0;
        for (int k = first; k < n; k++)
            u += p->basis[(size_t)c * n + k] * d[k];
        s += (1 / p->variance[c] - 1 / p->residual) * u * u;
    }
    free(d);
    return s / (n - first);
}
