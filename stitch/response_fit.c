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

/* x . y over n, in four partial sums: the fit solves its system once per
 * reweighting round, and one running sum is a chain of dependent adds. */
static double dot(const double *x, const double *y, int n)
{
    double s0 = 0, s1 = 0, s2 = 0, s3 = 0;
    int k = 0;
    for (; k + 4 <= n; k += 4) {
        s0 += x[k] * y[k];
        s1 += x[k + 1] * y[k + 1];
        s2 += x[k + 2] * y[k + 2];
        s3 += x[k + 3] * y[k + 3];
    }
    for (; k < n; k++)
        s0 += x[k] * y[k];
    return (s0 + s1) + (s2 + s3);
}

void (*merge_fit_system_hook)(const double *a, const double *b, int n);

/* Kept over OpenCV's Cholesky (cv::solve, DECOMP_CHOLESKY): on the fit's
 * own 256 x 256 systems it is 6 to 12 times faster with a residual 3 to 4
 * times smaller (test_merge_solve, docs/merge.md). */
bool merge_cholesky_solve(double *a, double *b, int n)
{
    for (int j = 0; j < n; j++) {
        double d = a[j * n + j] - dot(a + j * n, a + j * n, j);
        if (!(d > 0))
            return false;
        d = sqrt(d);
        a[j * n + j] = d;
        for (int i = j + 1; i < n; i++)
            a[i * n + j] = (a[i * n + j] - dot(a + i * n, a + j * n, j)) / d;
    }
    for (int i = 0; i < n; i++)
        b[i] = (b[i] - dot(a + i * n, b, i)) / a[i * n + i];
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
                         double saturation, int max_samples, uint64_t seed,
                         const uint8_t *usable, int *chosen)
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
    merge_code_curve curve;
    merge_code_curve_init(&curve, s, NULL);
    for (int i = 0; i < n; i++) {
        double best = 2, k = NAN, z_best = 0;
        int r_best = -1;
        for (int r = 0; r < f; r++) {
            double z = s->z[((size_t)i * f + r) * 3 + c];
            if (z > black &&
                (usable ? usable[(size_t)i * f + r] != 0 : merge_usable(s, i, r, saturation)) &&
                fabs(z - 0.5) < best) {
                best = fabs(z - 0.5);
                z_best = z;
                r_best = r;
            }
        }
        if (r_best >= 0) { /* one logarithm a sample, of the frame chosen */
            int code = merge_code_of(&curve, (float)z_best);
            k = (code >= 0 ? curve.log_z[code] : log(z_best)) - log_exposure[r_best];
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
        int j = (int)(sl_splitmix64(&state) % (uint64_t)(i + 1));
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

/* Iteratively reweighted rounds of the fit (Tukey's biweight on each
 * frame's residual): JPEG's DCT coding moves a pixel's code by a step or
 * two everywhere but by many near a bright edge (ringing, chroma bleed),
 * differently in each frame, and least squares bends the curve to meet
 * those half way (stage 5x2 JPEGs: 2.5% off, 1.2% with these rounds). */
enum { ROBUST_ROUNDS = 4 };
/* Tukey's cut-off in robust standard deviations (1.4826 MAD) of the
 * residuals, but never below CUT_STEPS code steps: away from edges JPEG
 * coding moves a code by a step or two and a lossless bracket's residuals
 * are a fraction of a step, discrete, so their MAD can collapse and cut
 * honest values (at 3 steps the noise-free night curve went 0.6 -> 1.1%;
 * at 12 the stage 5x2 one crept back to 2%). */
#define TUKEY_CUT 6.0
#define CUT_STEPS 8.0

/* Adds one channel's samples (positions ch[0..m)) to the normal equations
 * a, b with the per-sample unknowns eliminated (Schur complement): frame
 * q of sample t weighted by w[t * f + q]^2 rw[t * f + q]. Adds the robust
 * weights of the equations to *equations. */
static void add_samples(int f, int m, const float *w, const float *rw, const float *pos,
                        const float *target, int nodes, double *a, double *b, int *idx,
                        double *val, double *equations)
{
    for (int t = 0; t < m; t++) {
        /* u = sum of w^2 * (interpolation row) over the frames, d = sum w^2. */
        int nz = 0;
        double d = 0, sb = 0;
        for (int q = 0; q < f; q++) {
            size_t e = (size_t)t * f + q;
            double w2 = (double)w[e] * w[e] * rw[e], al;
            if (w2 <= 0)
                continue;
            int k = merge_response_node(pos[e], nodes, &al);
            int ks[2] = {k, k + 1};
            double cs[2] = {1 - al, al};
            for (int j = 0; j < 2; j++) {
                for (int j2 = 0; j2 < 2; j2++)
                    a[ks[j] * nodes + ks[j2]] += w2 * cs[j] * cs[j2];
                b[ks[j]] += w2 * target[e] * cs[j];
                idx[nz] = ks[j];
                val[nz++] = w2 * cs[j];
            }
            d += w2;
            sb += w2 * target[e];
            *equations += rw[e];
        }
        if (d <= 0)
            continue;
        for (int j = 0; j < nz; j++) {
            for (int j2 = 0; j2 < nz; j2++)
                a[idx[j] * nodes + idx[j2]] -= val[j] * val[j2] / d;
            b[idx[j]] -= val[j] * sb / d;
        }
    }
}

/* One channel's weighted residuals w (g(pos) - target - ln E), ln E the
 * sample's estimate (its frames' mean, weights w^2 rw), into res[t * f + q],
 * and the floor of Tukey's cut-off there (CUT_STEPS code steps, as a
 * residual) into cut; NAN where a frame is not used or is a sample's only
 * one (it fits exactly and says nothing). The magnitudes are appended to
 * mag; returns how many. */
static int sample_residuals(int f, double code_step, int m, const float *w, const float *rw,
                            const float *pos, const float *target, const double *g, int nodes,
                            float *res, float *cut, double *mag)
{
    int n = 0;
    double v[MERGE_MAX_FRAMES], slope[MERGE_MAX_FRAMES];
    for (int t = 0; t < m; t++) {
        const float *wt = w + (size_t)t * f, *rwt = rw + (size_t)t * f;
        int used = 0;
        for (int q = 0; q < f; q++)
            if (wt[q] > 0) {
                double al;
                size_t e = (size_t)t * f + q;
                int k = merge_response_node(pos[e], nodes, &al);
                v[q] = g[k] + al * (g[k + 1] - g[k]) - target[e];
                slope[q] = (g[k + 1] - g[k]) * (nodes - 1);
                used++;
            }
        /* A sample the last round set aside entirely is judged again from
         * the mean of all its frames under the new curve. */
        double d = 0, sum = 0;
        for (int pass = 0; pass < 2 && !(d > 0); pass++)
            for (int q = 0; q < f; q++)
                if (wt[q] > 0) {
                    double w2 = (double)wt[q] * wt[q] * (pass ? 1 : rwt[q]);
                    d += w2;
                    sum += w2 * v[q];
                }
        for (int q = 0; q < f; q++) {
            size_t e = (size_t)t * f + q;
            res[e] = NAN;
            if (wt[q] > 0 && used > 1 && d > 0) {
                res[e] = (float)(wt[q] * (v[q] - sum / d));
                cut[e] = (float)(CUT_STEPS * wt[q] * fabs(slope[q]) * code_step);
                mag[n++] = fabs(res[e]);
            }
        }
    }
    return n;
}

/* The fit's equations g(z) = ln E + ln e put the curve at each frame's
 * observed code, and a noisy code is a biased witness of its own exposure:
 * among the pixels read at a low, noisy code, the true exposures lean
 * towards where the scene has more of them (regression to the mean), so
 * g there, and through the chain of frames the whole curve, bends (the
 * DoRF curves through a 4000-electron sensor: 5-20% off, noise-free 1-3%).
 * These rounds fit the forward model instead, code = g^-1(ln E + ln e)
 * plus noise, by Gauss-Newton: each equation is placed at the code z* the
 * current curve and the sample's exposure predict, with the observed
 * code's offset carried to first order, g(z*) + g'(z*) (z - z*) = ln E +
 * ln e. Given E (set by every frame, mostly the well-exposed ones) the
 * noise sits in the observation only, and its mean is zero. Not for JPEG
 * frames: their coding error is no noise model's (the night set's 7x3
 * JPEG curve went 0.2 -> 15% off with these rounds). */
enum { FORWARD_ROUNDS = 3 };

/* g at code z, interpolated between its nodes. */
static double curve_at(const double *g, int nodes, double z)
{
    double al;
    int k = merge_response_node(z, nodes, &al);
    return g[k] + al * (g[k + 1] - g[k]);
}

/* One channel's equations moved to the codes the curve g predicts
 * (pos, target as above) from the samples' exposures under the current
 * equations, and weighted by the noise model (var y = noise_gain y +
 * noise_floor, y in [0, 1]) there. */
static void forward_equations(const merge_samples *s, int c, const int *ch, int m, float *w,
                              const float *rw, const double *log_exposure, const double *g,
                              const double *rising, int nodes, double noise_gain,
                              double noise_floor, double saturation, float *pos, float *target)
{
    int f = s->frames;
    double mid_grey = 0.5 / sqrt(noise_gain * 0.5 + noise_floor);
    for (int t = 0; t < m; t++) {
        const float *zi = s->z + (size_t)ch[t] * f * 3;
        double d = 0, sum = 0;
        for (size_t e = (size_t)t * f; e < (size_t)(t + 1) * f; e++) {
            double w2 = (double)w[e] * w[e] * rw[e];
            if (w2 > 0) {
                d += w2;
                sum += w2 * (curve_at(g, nodes, pos[e]) - target[e]);
            }
        }
        if (!(d > 0))
            continue;
        double log_e = sum / d;
        for (int q = 0; q < f; q++) {
            size_t e = (size_t)t * f + q;
            if (!(w[e] > 0))
                continue;
            double u = log_e + log_exposure[q], z = zi[q * 3 + c];
            /* z*: where the (non-decreasing) curve reaches u. */
            int lo = 0, hi = nodes - 1;
            if (u <= rising[0] || u >= rising[nodes - 1])
                continue; /* beyond the curve: keep the observed code */
            while (hi - lo > 1) {
                int mid = (lo + hi) / 2;
                if (rising[mid] <= u)
                    lo = mid;
                else
                    hi = mid;
            }
            double span = rising[hi] - rising[lo];
            double zs = (lo + (span > 0 ? (u - rising[lo]) / span : 0.5)) / (nodes - 1);
            double slope = span * (nodes - 1);
            pos[e] = (float)zs;
            target[e] = (float)(log_exposure[q] - slope * (z - zs));
            /* Weights from the model, not the noisy code (a weight that
             * grows with the observed code favours the samples noise pushed
             * up): the inverse deviation of ln y under the merge's noise
             * model and a code step, relative to mid-grey's. */
            double y = exp(u - rising[nodes - 1]), step = y * slope * s->code_step;
            double var = noise_gain * y + noise_floor + step * step / 12;
            w[e] = (float)(0.5 * y / sqrt(var) / mid_grey * fmin(1, (saturation - z) / SHOULDER));
        }
    }
}

double merge_smoothness_row(int k, int nodes, double scale, double cs[3])
{
    double h1 = log((double)k / (k - 1)), h2 = log((double)(k + 1) / k);
    double share = 0.5 * (h1 + h2), base_k = 2 / (h1 + h2);
    double w = hat((double)k / (nodes - 1), 0, 1) + 1e-3;
    cs[0] = base_k / h1;
    cs[1] = -base_k * (1 / h1 + 1 / h2);
    cs[2] = base_k / h2;
    return scale * w * w * share * share * share; /* (g'' * share)^2 * share */
}

/* Sum of the equations' squared weights, robust weights included. */
static double weight_sum(const float *w, const float *rw, size_t n)
{
    double sum = 0;
    for (size_t e = 0; e < n; e++)
        sum += (double)w[e] * w[e] * rw[e];
    return sum;
}

sl_result merge_fit_response(const merge_samples *s, const double *log_exposure, int nodes,
                             double lambda, int max_samples, double black, double saturation,
                             double noise_gain, double noise_floor, uint64_t seed,
                             const sl_response_prior *prior, double prior_weight,
                             sl_response *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    int f = s->frames;
    size_t nn = (size_t)nodes * (size_t)nodes, per = (size_t)(s->count > 0 ? s->count : 1);
    size_t most = max_samples < 1 ? 1 : (size_t)max_samples < per ? (size_t)max_samples : per;
    size_t eqs = 3 * most * (size_t)f;
    double *a = malloc(nn * sizeof *a);
    double *b = malloc((size_t)nodes * sizeof *b);
    double *inv = calloc((size_t)nodes * 3, sizeof *inv);
    int *chosen = malloc(per * 3 * sizeof *chosen);
    int *idx = malloc((size_t)f * 2 * sizeof *idx);
    double *val = malloc((size_t)f * 2 * sizeof *val);
    float *wt = malloc(eqs * sizeof *wt);
    float *rw = malloc(eqs * sizeof *rw);
    float *res = malloc(eqs * sizeof *res);
    float *cut = malloc(eqs * sizeof *cut);
    double *mag = malloc(eqs * sizeof *mag);
    float *pos = malloc(eqs * sizeof *pos);
    float *target = malloc(eqs * sizeof *target);
    double *rising = malloc((size_t)nodes * sizeof *rising);
    uint8_t *usable = malloc(per * (size_t)f); /* optional: NULL finds them per channel */
    if (prior && prior->nodes != nodes)
        prior = NULL;
    double *prec = prior ? malloc(nn * sizeof *prec) : NULL;
    double *prec_mean = prior ? malloc((size_t)nodes * sizeof *prec_mean) : NULL;
    sl_result r = SL_OK;
    if (!a || !b || !inv || !chosen || !idx || !val || !wt || !rw || !res || !cut || !mag ||
        !pos || !target || !rising || (prior && (!prec || !prec_mean))) {
        r = sl_error_set(err, SL_ERR_NOMEM, "response: out of memory");
        goto done;
    }
    int m[3], total = 0;
    size_t base[3];
    for (size_t e = 0; usable && e < (size_t)s->count * f; e++)
        usable[e] = merge_usable(s, (int)(e / (size_t)f), (int)(e % (size_t)f), saturation);
    for (int c = 0; c < 3 && !r; c++) {
        m[c] = merge_choose_samples(s, c, log_exposure, black, saturation, max_samples, seed,
                                    usable, chosen + (size_t)c * per);
        if (m[c] < 0)
            r = sl_error_set(err, SL_ERR_NOMEM, "response: out of memory");
        base[c] = (size_t)total * f;
        total += m[c];
    }
    if (!r && total < 16)
        r = sl_error_set(err, SL_ERR_INPUT,
                         "too few well-exposed pixels (%d) to recover the response; give "
                         "--response linear or a curve file",
                         total);
    /* Each equation's weight, and the robust one (1 to start with). */
    for (int c = 0; c < 3 && !r; c++)
        for (int t = 0; t < m[c]; t++) {
            int i = chosen[(size_t)c * per + t];
            for (int q = 0; q < f; q++) {
                size_t e = base[c] + (size_t)t * f + q;
                double z = s->z[((size_t)i * f + q) * 3 + c];
                wt[e] = merge_usable(s, i, q, saturation)
                            ? (float)sample_weight(z, black, saturation)
                            : 0;
                rw[e] = 1;
                pos[e] = (float)z;
                target[e] = (float)log_exposure[q];
            }
        }
    /* The data rows' weight per unit of likelihood under the noise model:
     * a row's weight is var(mid-grey)^1/2 over its deviation in ln y (the
     * forward rounds' model weights; the hat weights are 0.5 at mid-grey
     * as those are), times the rescaling that keeps the data's total. */
    double unit = noise_gain * 0.5 + noise_floor;
    int rounds = ROBUST_ROUNDS + (s->coded ? 0 : FORWARD_ROUNDS);
    for (int round = 0; round < rounds && !r; round++) {
        /* One curve for the three channels: cameras apply one tone curve after
         * their colour matrix, and a curve per channel would leave each
         * channel's scale to its own extrapolation to white (a colour cast). */
        memset(a, 0, nn * sizeof *a);
        memset(b, 0, (size_t)nodes * sizeof *b);
        double equations = 0;
        for (int c = 0; c < 3; c++)
            add_samples(f, m[c], wt + base[c], rw + base[c], pos + base[c], target + base[c],
                        nodes, a, b, idx, val, &equations);
        /* The prior speaks for the codes the data reach: beyond them the
         * smoothness extrapolates as without it. */
        if (prior) {
            double most = 0;
            int lo = nodes, hi = -1;
            for (int k = 0; k < nodes; k++)
                most = fmax(most, a[k * nodes + k]);
            for (int k = 0; k < nodes; k++)
                if (a[k * nodes + k] > 1e-3 * most) {
                    lo = k < lo ? k : lo;
                    hi = k;
                }
            merge_prior_precision(prior, lo, hi, prec, prec_mean);
        }
        /* Smoothness of g against ln z: gamma-like curves are nearly straight
         * there, while the log-periodic wiggle that brackets with wide steps
         * cannot pin down (Debevec-Malik's weak spot) is strongly curved.
         * Residual: the second derivative at node k times sqrt of its share
         * of ln z, scaled by the (robustly weighted) equations so lambda
         * depends neither on the number of samples nor on how many the
         * reweighting set aside. */
        double l2 = lambda * lambda * equations / nodes;
        for (int k = 2; k < nodes - 1; k++) {
            double cs[3], wl = merge_smoothness_row(k, nodes, l2, cs);
            int ks[3] = {k - 1, k, k + 1};
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
        a[(nodes / 2) * nodes + nodes / 2] += 1 + equations;
        /* The prior on curve shapes, as a Gaussian posterior would weigh it
         * against rows of that weight. */
        for (size_t e = 0; prior && e < nn; e++)
            a[e] += prior_weight * unit * prec[e];
        for (int k = 0; prior && k < nodes; k++)
            b[k] += prior_weight * unit * prec_mean[k];
        if (merge_fit_system_hook)
            merge_fit_system_hook(a, b, nodes);
        if (!merge_cholesky_solve(a, b, nodes)) {
            r = sl_error_set(err, SL_ERR_INPUT,
                             "the response cannot be recovered from these frames (singular "
                             "system); give --response linear or a curve file");
            break;
        }
        if (round == rounds - 1)
            break;
        if (round >= ROBUST_ROUNDS - 1) {
            rising[0] = b[0];
            for (int k = 1; k < nodes; k++)
                rising[k] = fmax(b[k], rising[k - 1]);
            double before = weight_sum(wt, rw, (size_t)total * f);
            for (int c = 0; c < 3; c++)
                forward_equations(s, c, chosen + (size_t)c * per, m[c], wt + base[c],
                                  rw + base[c], log_exposure, b, rising, nodes, noise_gain,
                                  noise_floor, saturation, pos + base[c], target + base[c]);
            /* The data's total weight as before: the smoothness keeps its share
             * (a dark scene's samples all weigh little under the noise model). */
            double after = weight_sum(wt, rw, (size_t)total * f);
            for (size_t e = 0; e < (size_t)total * f && after > 0; e++)
                wt[e] = (float)(wt[e] * sqrt(before / after));
            if (after > 0)
                unit = (noise_gain * 0.5 + noise_floor) * before / after;
            continue;
        }
        int n = 0;
        for (int c = 0; c < 3; c++)
            n += sample_residuals(f, s->code_step, m[c], wt + base[c], rw + base[c],
                                  pos + base[c], target + base[c], b, nodes, res + base[c],
                                  cut + base[c], mag + n);
        if (n == 0)
            break;
        double sigma = 1.4826 * merge_select_kth(mag, n, n / 2);
        for (size_t e = 0; e < (size_t)total * f; e++) {
            if (isnan(res[e]))
                continue;
            double scale = fmax(TUKEY_CUT * sigma, cut[e]), u = scale > 0 ? res[e] / scale : 0;
            rw[e] = fabs(u) < 1 ? (float)((1 - u * u) * (1 - u * u)) : 0;
        }
    }
    if (!r) {
        for (int k = 1; k < nodes; k++)
            inv[k] = exp(b[k]);
        merge_response_finish(inv, nodes, "debevec-malik", out);
        inv = NULL;
    }
done:
    free(prec);
    free(prec_mean);
    free(usable);
    free(a);
    free(b);
    free(inv);
    free(chosen);
    free(idx);
    free(val);
    free(wt);
    free(rw);
    free(res);
    free(cut);
    free(mag);
    free(pos);
    free(target);
    free(rising);
    return r;
}
