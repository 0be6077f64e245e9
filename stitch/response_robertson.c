/* SPDX-License-Identifier: BSD-3-Clause */
/* Robertson, Borman and Stevenson's response recovery (ICIP 1999): each
 * sample's irradiance from the curve (weighted least squares over the
 * frames), then each code's linear value from the irradiances (the mean of
 * E t over the observations of that code), alternated to convergence. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "merge_private.h"

enum { ROUNDS = 40 };

/* Robertson's weight: a bump over the code, zero at black and saturation. */
static double weight(double z, double black, double saturation)
{
    if (z <= black || z >= saturation)
        return 0;
    double u = 2 * z - 1;
    return exp(-4 * u * u);
}

typedef struct obs {
    int sample; /* index into e[] */
    int bin;
    double t, w;
} obs;

sl_result merge_fit_robertson(const merge_samples *s, const double *log_exposure, int nodes,
                              int max_samples, double black, double saturation, uint64_t seed,
                              sl_response *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    int f = s->frames;
    size_t cap = (size_t)(s->count > 0 ? s->count : 1) * 3;
    int *chosen = malloc(cap * sizeof *chosen);
    obs *o = malloc(cap * (size_t)f * sizeof *o);
    double *e = malloc(cap * sizeof *e), *num = calloc(cap, sizeof *num), *den = calloc(cap, sizeof *den);
    double *inv = calloc((size_t)nodes * 3, sizeof *inv), *sum = malloc((size_t)nodes * sizeof *sum);
    int *cnt = malloc((size_t)nodes * sizeof *cnt);
    sl_result r = SL_OK;
    if (!chosen || !o || !e || !num || !den || !inv || !sum || !cnt) {
        r = sl_error_set(err, SL_ERR_NOMEM, "response: out of memory");
        goto done;
    }
    /* Observations of the chosen samples of every channel (one curve). */
    size_t n = 0;
    int samples = 0;
    for (int c = 0; c < 3; c++) {
        int m = merge_choose_samples(s, c, log_exposure, black, saturation, max_samples, seed,
                                     NULL, chosen);
        if (m < 0) {
            r = sl_error_set(err, SL_ERR_NOMEM, "response: out of memory");
            goto done;
        }
        for (int t = 0; t < m; t++, samples++)
            for (int q = 0; q < f; q++) {
                double z = s->z[((size_t)chosen[t] * f + q) * 3 + c];
                double w = merge_usable(s, chosen[t], q, saturation) ? weight(z, black, saturation) : 0;
                if (w <= 0)
                    continue;
                int k = (int)lround(z * (nodes - 1));
                o[n++] = (obs){samples, k < 0 ? 0 : k >= nodes ? nodes - 1 : k, exp(log_exposure[q]), w};
            }
    }
    if (samples < 16) {
        r = sl_error_set(err, SL_ERR_INPUT,
                         "too few well-exposed pixels (%d) to recover the response; give "
                         "--response linear or a curve file",
                         samples);
        goto done;
    }
    /* Start from a 2.2 gamma: the part of the curve the data leave free (a
     * wiggle with the period of one exposure step) stays as it starts. */
    double *g = inv;
    for (int k = 0; k < nodes; k++)
        g[k] = pow((double)k / (nodes - 1), 2.2);
    double mid = g[nodes / 2];
    for (int round = 0; round < ROUNDS; round++) {
        memset(num, 0, (size_t)samples * sizeof *num);
        memset(den, 0, (size_t)samples * sizeof *den);
        for (size_t i = 0; i < n; i++) {
            num[o[i].sample] += o[i].w * o[i].t * g[o[i].bin];
            den[o[i].sample] += o[i].w * o[i].t * o[i].t;
        }
        for (int i = 0; i < samples; i++)
            e[i] = den[i] > 0 ? num[i] / den[i] : 0;
        memset(sum, 0, (size_t)nodes * sizeof *sum);
        memset(cnt, 0, (size_t)nodes * sizeof *cnt);
        for (size_t i = 0; i < n; i++) {
            sum[o[i].bin] += e[o[i].sample] * o[i].t;
            cnt[o[i].bin]++;
        }
        for (int k = 0; k < nodes; k++)
            if (cnt[k])
                g[k] = sum[k] / cnt[k];
        /* The scale is free: hold the middle code where it started. */
        double scale = g[nodes / 2] > 0 ? mid / g[nodes / 2] : 1;
        for (int k = 0; k < nodes; k++)
            g[k] *= scale;
    }
    /* Codes never observed: straight between observed neighbours, to 0 at
     * code 0, and on with the last observed slope above. */
    int first = -1, last = -1;
    for (int k = 0; k < nodes; k++)
        if (cnt[k]) {
            if (first < 0)
                first = k;
            last = k;
        }
    if (first < 0 || last - first < 2) {
        r = sl_error_set(err, SL_ERR_INPUT,
                         "the response cannot be recovered from these frames (too few codes "
                         "observed); give --response linear or a curve file");
        goto done;
    }
    for (int k = 0; k < first; k++)
        g[k] = g[first] * k / first;
    int prev = first;
    for (int k = first + 1; k <= last; k++)
        if (cnt[k]) {
            for (int j = prev + 1; j < k; j++)
                g[j] = g[prev] + (g[k] - g[prev]) * (j - prev) / (k - prev);
            prev = k;
        }
    int below = last - 1;
    while (below > first && !cnt[below])
        below--;
    double slope = (g[last] - g[below]) / (last - below);
    for (int k = last + 1; k < nodes; k++)
        g[k] = g[last] + slope * (k - last);
    merge_response_finish(inv, nodes, "robertson", out);
    inv = NULL;
done:
    free(chosen);
    free(o);
    free(e);
    free(num);
    free(den);
    free(inv);
    free(sum);
    free(cnt);
    return r;
}
