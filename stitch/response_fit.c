/* SPDX-License-Identifier: BSD-3-Clause */
/* Debevec-Malik response recovery (SIGGRAPH 1997), solved in double. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "merge_private.h"

enum { BINS = 64 };

/* Codes within this of saturation fade out of the fit. */
#define SHOULDER 0.05

static double hat(double z, double black, double saturation)
{
    if (z <= black || z >= saturation)
        return 0;
    return z < 0.5 ? z : 1 - z;
}

/* A sample's weight. One code step moves ln g(z) by about 1 / z for a
 * gamma-like curve, so codes below mid-grey count in proportion to z (the
 * hat's rising half); above it they are measured as well as mid-grey, and
 * only the last SHOULDER below saturation fades out (as in the merge),
 * where the hat would discount the upper codes that pin the curve's top. */
static double sample_weight(double z, double black, double saturation)
{
    if (z <= black || z >= saturation)
        return 0;
    return fmin(z, 0.5) * fmin(1, (saturation - z) / SHOULDER);
}

/* Cholesky of the symmetric positive definite n x n matrix a (lower part
 * overwritten), then solves a x = b in place. False when not positive. */
static bool cholesky_solve(double *a, double *b, int n)
{
    for (int j = 0; j < n; j++) {
        double d = a[j * n + j];
        for (int k = 0; k < j; k++)
            d -= a[j * n + k] * a[j * n + k];
        if (!(d > 0))
            return false;
        d = sqrt(d);
        a[j * n + j] = d;
        for (int i = j + 1; i < n; i++) {
            double s = a[i * n + j];
            for (int k = 0; k < j; k++)
                s -= a[i * n + k] * a[j * n + k];
            a[i * n + j] = s / d;
        }
    }
    for (int i = 0; i < n; i++) {
        double s = b[i];
        for (int k = 0; k < i; k++)
            s -= a[i * n + k] * b[k];
        b[i] = s / a[i * n + i];
    }
    for (int i = n - 1; i >= 0; i--) {
        double s = b[i];
        for (int k = i + 1; k < n; k++)
            s -= a[k * n + i] * b[k];
        b[i] = s / a[i * n + i];
    }
    return true;
}

/* Picks up to max_samples positions for one channel, spread evenly over a
 * crude log radiance (each value read in the frame where it is nearest
 * mid-grey), in a seeded random order so they also spread over the frame. */
int merge_choose_samples(const merge_samples *s, int c, const double *log_exposure, double black,
                         double saturation, int max_samples, uint64_t seed, int *chosen)
{
    int n = s->count, f = s->frames;
    double *key = malloc((size_t)n * sizeof *key);
    int *order = malloc((size_t)n * sizeof *order);
    if (!key || !order) {
        free(key);
        free(order);
        return -1;
    }
    double lo = INFINITY, hi = -INFINITY;
    int valid = 0;
    for (int i = 0; i < n; i++) {
        double best = 2, k = NAN;
        for (int r = 0; r < f; r++) {
            double z = s->z[((size_t)i * f + r) * 3 + c];
            if (z > black && merge_usable(s, i, r, saturation) && fabs(z - 0.5) < best) {
                best = fabs(z - 0.5);
                k = log(z) - log_exposure[r];
            }
        }
        key[i] = k;
        if (!isnan(k)) {
            order[valid++] = i;
            lo = fmin(lo, k);
            hi = fmax(hi, k);
        }
    }
    uint64_t state = seed ^ (0x5851f42d4c957f2dull * (uint64_t)(c + 1));
    for (int i = valid - 1; i > 0; i--) {
        int j = (int)(merge_rand(&state) % (uint64_t)(i + 1));
        int t = order[i];
        order[i] = order[j];
        order[j] = t;
    }
    int quota = (max_samples + BINS - 1) / BINS, used[BINS] = {0}, m = 0;
    double scale = hi > lo ? BINS / (hi - lo) : 0;
    for (int t = 0; t < valid && m < max_samples; t++) {
        int b = (int)((key[order[t]] - lo) * scale);
        b = b < 0 ? 0 : b >= BINS ? BINS - 1 : b;
        if (used[b] < quota) {
            used[b]++;
            chosen[m++] = order[t];
        }
    }
    free(key);
    free(order);
    return m;
}

void merge_response_finish(double *inv, int nodes, const char *source, sl_response *out)
{
    inv[0] = 0;
    for (int k = 1; k < nodes; k++)
        if (!(inv[k] > inv[k - 1]))
            inv[k] = inv[k - 1] * (1 + 1e-9) + 1e-300;
    double top = inv[nodes - 1];
    for (int k = 0; k < nodes; k++)
        inv[k] /= top;
    for (int c = 1; c < 3; c++)
        memcpy(inv + (size_t)c * nodes, inv, (size_t)nodes * sizeof *inv);
    out->channels = 3;
    out->nodes = nodes;
    out->inverse = inv;
    snprintf(out->source, sizeof out->source, "%s", source);
}

sl_result merge_fit_response(const merge_samples *s, const double *log_exposure, int nodes,
                             double lambda, int max_samples, double black, double saturation,
                             uint64_t seed, sl_response *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    int f = s->frames;
    size_t nn = (size_t)nodes * (size_t)nodes;
    double *a = malloc(nn * sizeof *a);
    double *b = malloc((size_t)nodes * sizeof *b);
    double *inv = calloc((size_t)nodes * 3, sizeof *inv);
    int *chosen = malloc((size_t)(s->count > 0 ? s->count : 1) * 3 * sizeof *chosen);
    int *idx = malloc((size_t)f * 2 * sizeof *idx);
    double *val = malloc((size_t)f * 2 * sizeof *val);
    sl_result r = SL_OK;
    if (!a || !b || !inv || !chosen || !idx || !val) {
        r = sl_error_set(err, SL_ERR_NOMEM, "response: out of memory");
        goto done;
    }
    /* One curve for the three channels: cameras apply one tone curve after
     * their colour matrix, and a curve per channel would leave each
     * channel's scale to its own extrapolation to white (a colour cast). */
    memset(a, 0, nn * sizeof *a);
    memset(b, 0, (size_t)nodes * sizeof *b);
    int equations = 0, total = 0;
    for (int c = 0; c < 3 && !r; c++) {
        int *ch = chosen + (size_t)c * s->count;
        int m = merge_choose_samples(s, c, log_exposure, black, saturation, max_samples, seed, ch);
        if (m < 0) {
            r = sl_error_set(err, SL_ERR_NOMEM, "response: out of memory");
            break;
        }
        total += m;
        for (int t = 0; t < m; t++) {
            const float *zi = s->z + (size_t)ch[t] * f * 3;
            /* u = sum of w^2 * (interpolation row) over the frames, d = sum w^2. */
            int nz = 0;
            double d = 0, sb = 0;
            for (int q = 0; q < f; q++) {
                double z = zi[q * 3 + c];
                double w = merge_usable(s, ch[t], q, saturation) ? sample_weight(z, black, saturation) : 0;
                if (w <= 0)
                    continue;
                double w2 = w * w, p = z * (nodes - 1);
                int k = (int)p;
                if (k >= nodes - 1)
                    k = nodes - 2;
                double al = p - k;
                int ks[2] = {k, k + 1};
                double cs[2] = {1 - al, al};
                for (int e = 0; e < 2; e++) {
                    for (int e2 = 0; e2 < 2; e2++)
                        a[ks[e] * nodes + ks[e2]] += w2 * cs[e] * cs[e2];
                    b[ks[e]] += w2 * log_exposure[q] * cs[e];
                    idx[nz] = ks[e];
                    val[nz++] = w2 * cs[e];
                }
                d += w2;
                sb += w2 * log_exposure[q];
                equations++;
            }
            if (d <= 0)
                continue;
            for (int e = 0; e < nz; e++) {
                for (int e2 = 0; e2 < nz; e2++)
                    a[idx[e] * nodes + idx[e2]] -= val[e] * val[e2] / d;
                b[idx[e]] -= val[e] * sb / d;
            }
        }
    }
    if (!r && total < 16)
        r = sl_error_set(err, SL_ERR_INPUT,
                         "too few well-exposed pixels (%d) to recover the response; give "
                         "--response linear or a curve file",
                         total);
    if (!r) {
        /* Smoothness of g against ln z: gamma-like curves are nearly straight
         * there, while the log-periodic wiggle that brackets with wide steps
         * cannot pin down (Debevec-Malik's weak spot) is strongly curved.
         * Residual: the second derivative at node k times sqrt of its share
         * of ln z, scaled by equations so lambda does not depend on the
         * number of samples. */
        double l2 = lambda * lambda * (double)equations / nodes;
        for (int k = 2; k < nodes - 1; k++) {
            double h1 = log((double)k / (k - 1)), h2 = log((double)(k + 1) / k);
            double share = 0.5 * (h1 + h2), base = 2 / (h1 + h2);
            double w = hat((double)k / (nodes - 1), 0, 1) + 1e-3;
            double wl = l2 * w * w * share * share * share; /* (g'' * share)^2 * share */
            int ks[3] = {k - 1, k, k + 1};
            double cs[3] = {base / h1, -base * (1 / h1 + 1 / h2), base / h2};
            for (int e = 0; e < 3; e++)
                for (int e2 = 0; e2 < 3; e2++)
                    a[ks[e] * nodes + ks[e2]] += wl * cs[e] * cs[e2];
        }
        /* ln 0 has no place on that axis: node 0 follows node 1 and 2 straight. */
        a[0] += l2;
        a[1] -= 2 * l2;
        a[2] += l2;
        a[nodes] -= 2 * l2;
        a[nodes + 1] += 4 * l2;
        a[nodes + 2] -= 2 * l2;
        a[2 * nodes] += l2;
        a[2 * nodes + 1] -= 2 * l2;
        a[2 * nodes + 2] += l2;
        /* g(mid) = 0 fixes the free offset; the curve is rescaled below. */
        a[(nodes / 2) * nodes + nodes / 2] += 1 + (double)equations;
        if (!cholesky_solve(a, b, nodes))
            r = sl_error_set(err, SL_ERR_INPUT,
                             "the response cannot be recovered from these frames (singular "
                             "system); give --response linear or a curve file");
    }
    if (!r) {
        for (int k = 1; k < nodes; k++)
            inv[k] = exp(b[k]);
        merge_response_finish(inv, nodes, "debevec-malik", out);
        inv = NULL;
    }
done:
    free(a);
    free(b);
    free(inv);
    free(chosen);
    free(idx);
    free(val);
    return r;
}
