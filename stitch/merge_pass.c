/* SPDX-License-Identifier: BSD-3-Clause */
/* The merge proper: every frame read a strip at a time (decoded in parallel,
 * one frame per thread), then each pixel and channel merged with
 * inverse-variance weights from a Poisson-Gaussian noise model. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "merge_private.h"
#include "warp_reader.h"

enum { STRIP = 32 };

/* Fraction of full scale over which weights fade to zero below saturation,
 * so noise around the threshold does not switch a frame in and out. */
#define SHOULDER 0.05

/* The relative error predicts_clip allows a shorter frame's value beyond
 * its noise (JPEG coding, the curve). Smaller than deghost's 0.05: a pixel
 * just past a raw channel's clip (the colour matrix then mixes it below the
 * saturation code) must be caught; dropping a frame just under the clip
 * costs only noise. On the virtual set's stage JPEGs 0.05 left the 2-stop
 * bracket's 4x4 p99 1.32x the ideal estimator's, 0.03 1.01x. */
#define CLIP_MODEL_ERROR 0.03

/* A frame's terms of a pixel's weighted sum: {weight times value, weight},
 * added as one pair (one SSE2 add on x86-64). */
typedef double merge_term __attribute__((vector_size(16)));

typedef struct pass_ctx {
    const merge_ctx *m;
    const sl_merge_options *opt;
    sl_merge_result *res;
    int frames;
    double *e;              /* per rank, relative to the reference frame */
    double *inv_e, *e2;     /* per rank: 1 / e and e^2 */
    merge_frame_reader **rd; /* per rank */
    void **buf;             /* per rank: STRIP rows of RGB, float or codes (m->codes) */
    void **next;            /* per rank: the next strip, read while buf is merged */
    int ny0, ny1;           /* rows of next; ny0 == ny1: nothing to read */
    sl_error *errs;
    sl_result *results;
    int y0, y1;
    int levels;             /* 2^bits for integer frames, 0 for float */
    float *inv[3], *wb[3];  /* per level: linear value and weight without exposure */
    float *cinv[3], *cwb[3], *cfade; /* with codes, per code: the same, and the shoulder fade */
    float *rx, *rw;         /* with 8-bit codes, per rank, channel and code: linear value
                               on the output scale and weight with the exposure factor */
    merge_term *terms;      /* the same as the sums' terms: {rw * rx, rw}, exact in double */
    int shoulder_from, saturated_from; /* with 8-bit codes: the first code whose fade is
                                          below 1, and the first at 0 (the fade falls) */
    double clip_sigma2;     /* predicts_clip's margin: deghost's sigma, squared */
    double *xsat;           /* per rank and channel: the saturation code's value, output scale */
    double *xblack;         /* per rank and channel: the black code's value, output scale */
    uint16_t *hide_from;    /* with 8-bit codes, per rank pair (s * frames + r): the lowest
                               code of s whose value exceeds xsat of r in some channel
                               (256: none); below it in all three, s cannot predict r
                               clipped (merge_row_u8's gate) */
    int64_t *row_counts;    /* per row: clipped R, G, B, any; underexposed; nonfinite */
    float *out, *mask, *ghost; /* row y0 of the outputs (ghost NULL without deghost) */
    size_t out_stride, mask_stride, ghost_stride;
    double *task_cpu;       /* per worker and phase: CPU seconds of its tasks */
    int workers;
} pass_ctx;

enum { COUNT_UNDER = 4, COUNT_NONFINITE = 5, COUNT_GHOST = 6, COUNTS = 7 };

/* Inverse variance of a linearised value, before the exposure factor and
 * the pixel's shoulder fade. */
static double weight_base(const pass_ctx *p, int c, double z)
{
    const merge_ctx *m = p->m;
    if (!(z > m->black) || z >= m->saturation)
        return 0;
    const sl_response *resp = &p->res->response;
    double y = sl_response_eval(resp, c, z);
    double var = p->opt->noise_gain * y + p->opt->noise_floor;
    if (p->levels) {
        /* Quantisation: a uniform step of the code, carried through the curve. */
        double h = 1.0 / (resp->nodes - 1), lo = fmax(z - h, 0), hi = fmin(z + h, 1);
        double slope = (sl_response_eval(resp, c, hi) - sl_response_eval(resp, c, lo)) / (hi - lo);
        double step = slope / (p->levels - 1);
        var += step * step / 12;
    }
    return 1 / var;
}

static void read_next(pass_ctx *p, int r)
{
    const merge_ctx *m = p->m;
    const uint8_t *held = m->held ? m->held[m->order[r]] : NULL;
    if (held) {
        /* Merged in place: the strip's rows of the held frame. */
        size_t row = (size_t)m->width * 3 * (size_t)m->code_bytes;
        p->next[r] = (void *)(held + (size_t)p->ny0 * row);
        p->results[r] = SL_OK;
        return;
    }
    p->results[r] = p->m->codes
                        ? merge_frame_read_codes(p->rd[r], p->ny0, p->ny1, p->next[r], &p->errs[r])
                        : merge_frame_read(p->rd[r], p->ny0, p->ny1, p->next[r], &p->errs[r]);
}

/* Weighted median of x over the entries with w > 0. */
static double weighted_median(const double *x, const double *w, int n)
{
    int idx[MERGE_MAX_FRAMES], k = 0;
    double total = 0;
    for (int r = 0; r < n; r++)
        if (w[r] > 0) {
            int j = k++;
            while (j > 0 && x[idx[j - 1]] > x[r]) {
                idx[j] = idx[j - 1];
                j--;
            }
            idx[j] = r;
            total += w[r];
        }
    double run = 0;
    for (int j = 0; j < k; j++) {
        run += w[idx[j]];
        if (run >= 0.5 * total)
            return x[idx[j]];
    }
    return k ? x[idx[k - 1]] : 0;
}

/* Whether a shorter frame's value xs (weight ws) of channel c puts frame
 * rank r's pixel at or above the saturation code, beyond the noise model
 * the weights come from (deghost's sigma) plus CLIP_MODEL_ERROR. Then r is
 * clipped there even if its codes do not show it, and reads far darker
 * than the truth: a raw channel clipped before the colour matrix mixes it
 * with unclipped ones, or 4:2:0 chroma averaging a clipped light's edge
 * with its neighbours, leave every code below the saturation code. */
static inline bool predicts_clip(const pass_ctx *p, double xs, double ws, int r, int c)
{
    double d = xs - p->xsat[r * 3 + c];
    double model = CLIP_MODEL_ERROR * xs;
    return ws > 0 && d > 0 && d * d > p->clip_sigma2 * (1 / ws + model * model);
}

/* Whether frame s predicts frame r clipped in any channel. */
static bool predicts_frame_clip(const pass_ctx *p, double xs[3][MERGE_MAX_FRAMES],
                                double ws[3][MERGE_MAX_FRAMES], int s, int r)
{
    bool hidden = false;
    for (int c = 0; c < 3; c++)
        hidden |= predicts_clip(p, xs[c][s], ws[c][s], r, c);
    return hidden;
}

/* Frames of a pixel (not skipped: saturated) that the last shorter frame
 * kept predicts clipped: drop[r] set, as if saturated there, but never
 * counted as clipped (the shortest frame is always kept). A clip in one
 * frame is one in every longer frame, so only pixels whose longest
 * unsaturated frame is predicted clipped by the next shorter one are
 * looked at (the 8-bit path gates on that pair alone). Returns how many. */
static int drop_hidden_clips(const pass_ctx *p, double xs[3][MERGE_MAX_FRAMES],
                             double ws[3][MERGE_MAX_FRAMES], const bool *skip, bool *drop)
{
    int last = -1, prev = -1;
    for (int r = 0; r < p->frames; r++)
        if (!skip[r]) {
            prev = last;
            last = r;
        }
    if (prev < 0 || !predicts_frame_clip(p, xs, ws, prev, last))
        return 0;
    int ref = -1, n = 0;
    for (int r = 0; r < p->frames; r++) {
        if (skip[r])
            continue;
        drop[r] = ref >= 0 && predicts_frame_clip(p, xs, ws, ref, r);
        n += drop[r];
        ref = drop[r] ? ref : r;
    }
    return n;
}

/* A longer frame that reads black in a channel bounds the radiance there:
 * a shorter frame's value more than twice that bound is its noise (a dark
 * frame's read noise, hot pixels: a linear frame keeps them, where a
 * curve's toe crushes them to black), which its tiny exposure would scale
 * into a bright speck. Such values get no weight. Returns how many. */
static int drop_noise_above_black(const pass_ctx *p, double xs[3][MERGE_MAX_FRAMES],
                                  double ws[3][MERGE_MAX_FRAMES], const bool *satr)
{
    int n = 0;
    for (int c = 0; c < 3; c++) {
        double bound = INFINITY;
        for (int r = p->frames - 1; r >= 0; r--) {
            if (satr[r])
                continue;
            if (ws[c][r] > 0 && xs[c][r] > 2 * bound) {
                ws[c][r] = 0;
                n++;
            }
            if (xs[c][r] <= p->xblack[r * 3 + c])
                bound = fmin(bound, p->xblack[r * 3 + c]);
        }
    }
    return n;
}

/* Linear values (on the output scale) and weights of one pixel in every
 * frame, from integer codes through tables. */
static inline void fill_codes(const pass_ctx *p, size_t idx, double xs[3][MERGE_MAX_FRAMES],
                              double ws[3][MERGE_MAX_FRAMES], bool *satr)
{
    int cb = p->m->code_bytes;
    for (int r = 0; r < p->frames; r++) {
        int q[3];
        for (int c = 0; c < 3; c++)
            q[c] = merge_code(p->buf[r], cb, idx + c);
        int qm = q[0] > q[1] ? q[0] : q[1];
        qm = qm > q[2] ? qm : q[2];
        /* The pixel is saturated as a whole, and fades out by its brightest
         * channel (see fill_float). */
        float fade = p->cfade[qm];
        satr[r] = fade == 0;
        for (int c = 0; c < 3; c++) {
            xs[c][r] = p->cinv[c][q[c]] * p->inv_e[r];
            ws[c][r] = (double)(p->cwb[c][q[c]] * fade) * p->e2[r];
        }
    }
}

/* The same from float samples (float frames, or warped integer ones). */
static void fill_float(const pass_ctx *p, size_t idx, double xs[3][MERGE_MAX_FRAMES],
                       double ws[3][MERGE_MAX_FRAMES], bool *satr, int64_t *cnt)
{
    const merge_ctx *m = p->m;
    int f = p->frames;
    float sat = (float)m->saturation;
    /* A camera clips each raw channel before its colour matrix mixes
     * them, so one saturated channel spoils the pixel's others: the
     * pixel is saturated as a whole, and fades out by its brightest
     * channel. */
    double fade[MERGE_MAX_FRAMES];
    for (int r = 0; r < f; r++) {
        const float *v = (const float *)p->buf[r] + idx;
        float zmax = fmaxf(v[0], fmaxf(v[1], v[2]));
        satr[r] = zmax >= sat;
        fade[r] = satr[r] ? 0 : fmin(1, (m->saturation - zmax) / SHOULDER);
    }
    for (int c = 0; c < 3; c++)
        for (int r = 0; r < f; r++) {
            float z = ((const float *)p->buf[r])[idx + c];
            double y_lin, wb;
            if (p->levels) {
                int k = (int)(z * (float)(p->levels - 1) + 0.5f);
                k = k < 0 ? 0 : k >= p->levels ? p->levels - 1 : k;
                y_lin = p->inv[c][k];
                wb = p->wb[c][k];
            } else if (!isfinite(z)) {
                cnt[COUNT_NONFINITE]++;
                xs[c][r] = ws[c][r] = 0;
                continue;
            } else {
                y_lin = sl_response_eval(&p->res->response, c, z);
                wb = weight_base(p, c, z);
            }
            xs[c][r] = y_lin / p->e[r];
            ws[c][r] = wb * fade[r] * p->e[r] * p->e[r];
        }
}

/* Frame rank r's terms of an unsaturated 8-bit pixel q (brightest code
 * qm) added to sum: a fully weighted frame's precomputed {weight * value,
 * weight} (exact in double, so the same sums bit for bit), one 16-byte
 * load and add per channel, which the compiler pairs into one SSE2 add; in
 * the shoulder, the weight faded in float, as fill_codes does. */
static inline __attribute__((always_inline)) void add_u8(const pass_ctx *p, int r,
                                                         const uint8_t *q, int qm,
                                                         merge_term *s0, merge_term *s1,
                                                         merge_term *s2)
{
    const merge_term *t = p->terms + (size_t)r * 3 * 256;
    if (__builtin_expect(qm < p->shoulder_from, 1)) {
        *s0 += t[q[0]];
        *s1 += t[256 + q[1]];
        *s2 += t[512 + q[2]];
        return;
    }
    float fade = p->cfade[qm];
    const float *rx = p->rx + (size_t)r * 3 * 256, *rw = p->rw + (size_t)r * 3 * 256;
    merge_term faded[3];
    for (int c = 0; c < 3; c++) {
        double xv = rx[c * 256 + q[c]], wv = (double)(rw[c * 256 + q[c]] * fade);
        faded[c] = (merge_term){wv * xv, wv};
    }
    *s0 += faded[0];
    *s1 += faded[1];
    *s2 += faded[2];
}

static inline int max3(const uint8_t *q)
{
    int qm = q[0] > q[1] ? q[0] : q[1];
    return qm > q[2] ? qm : q[2];
}

/* Whether the next shorter unsaturated frame than last (the longest
 * unsaturated one) may predict it clipped (hide_from): the gate of
 * drop_hidden_u8, looked up after the sums so their loop stays lean. */
static inline bool may_hide_clip(const pass_ctx *p, const uint8_t *const *src, size_t at,
                                 int last)
{
    int prev = last - 1;
    while (prev >= 0 && max3(src[prev] + at) >= p->saturated_from)
        prev--;
    return prev >= 0 && max3(src[prev] + at) >= p->hide_from[prev * p->frames + last];
}

/* drop_hidden_clips on an 8-bit pixel at offset at of every frame: its
 * sums taken again into sum without the frames it drops; returns the
 * longest frame kept, or -1 when none is dropped (sum untouched). Only
 * pixels where it can drop one (hide_from) get here. */
static int drop_hidden_u8(const pass_ctx *p, const uint8_t *const *src, size_t at,
                          merge_term *sum)
{
    double xs[3][MERGE_MAX_FRAMES], ws[3][MERGE_MAX_FRAMES];
    bool satr[MERGE_MAX_FRAMES], drop[MERGE_MAX_FRAMES];
    for (int r = 0; r < p->frames; r++) {
        const uint8_t *q = src[r] + at;
        int qm = max3(q);
        satr[r] = qm >= p->saturated_from;
        const float *rx = p->rx + (size_t)r * 3 * 256, *rw = p->rw + (size_t)r * 3 * 256;
        for (int c = 0; c < 3 && !satr[r]; c++) {
            xs[c][r] = rx[c * 256 + q[c]];
            ws[c][r] = (double)(rw[c * 256 + q[c]] * p->cfade[qm]);
        }
    }
    if (!drop_hidden_clips(p, xs, ws, satr, drop))
        return -1;
    int last = 0;
    sum[0] = sum[1] = sum[2] = (merge_term){0, 0};
    for (int r = 0; r < p->frames; r++)
        if (!satr[r] && !drop[r]) {
            add_u8(p, r, src[r] + at, max3(src[r] + at), &sum[0], &sum[1], &sum[2]);
            last = r;
        }
    return last;
}

/* 8-bit codes without deghost (the common case): fill_codes and the sums
 * of merge_rows in one loop, from per-rank tables (add_u8). The longest
 * unsaturated frame's value (the fallback) and the shortest one's (the
 * lower bound where all are saturated) are looked up only when needed. */
static void merge_row_u8(const pass_ctx *p, int row, float *out, float *mask, int64_t *cnt)
{
    int w = p->m->width, f = p->frames;
    const uint8_t *src[MERGE_MAX_FRAMES];
    for (int r = 0; r < f; r++)
        src[r] = (const uint8_t *)p->buf[r] + (size_t)row * w * 3;
    for (int x = 0; x < w; x++) {
        merge_term s0 = {0, 0}, s1 = s0, s2 = s0;
        int nsat = 0, last = 0;
        for (int r = 0; r < f; r++) {
            const uint8_t *q = src[r] + (size_t)x * 3;
            int qm = max3(q);
            if (qm >= p->saturated_from) {
                nsat++;
                continue;
            }
            last = r;
            add_u8(p, r, q, qm, &s0, &s1, &s2);
        }
        merge_term sum[3] = {s0, s1, s2};
        if (nsat < f - 1 && may_hide_clip(p, src, (size_t)x * 3, last)) {
            int kept = drop_hidden_u8(p, src, (size_t)x * 3, sum);
            last = kept >= 0 ? kept : last;
        }
        bool any = nsat == f;
        for (int c = 0; c < 3; c++) {
            double v;
            if (any) {
                /* The shortest frame's value is a lower bound, never an estimate. */
                v = p->rx[c * 256 + src[0][(size_t)x * 3 + c]];
                mask[x * 3 + c] = 1;
                cnt[c]++;
            } else if (sum[c][1] > 0) {
                v = sum[c][0] / sum[c][1];
            } else {
                /* No weight: the longest unsaturated frame's value. */
                v = p->rx[((size_t)last * 3 + c) * 256 + src[last][(size_t)x * 3 + c]];
                cnt[COUNT_UNDER]++;
            }
            out[x * 3 + c] = (float)v;
        }
        cnt[3] += any;
    }
}

static void merge_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    pass_ctx *p = ctx;
    const merge_ctx *m = p->m;
    int w = m->width, f = p->frames;
    double xs[3][MERGE_MAX_FRAMES], ws[3][MERGE_MAX_FRAMES];
    bool satr[MERGE_MAX_FRAMES];
    for (int64_t row = begin; row < end; row++) {
        int y = p->y0 + (int)row;
        float *out = p->out + row * p->out_stride;
        float *mask = p->mask + row * p->mask_stride;
        float *ghost = p->ghost ? p->ghost + row * p->ghost_stride : NULL;
        int64_t *cnt = p->row_counts + (size_t)y * COUNTS;
        if (p->rx && !ghost) {
            merge_row_u8(p, (int)row, out, mask, cnt);
            continue;
        }
        for (int x = 0; x < w; x++) {
            size_t idx = ((size_t)row * w + x) * 3;
            if (m->codes)
                fill_codes(p, idx, xs, ws, satr);
            else
                fill_float(p, idx, xs, ws, satr, cnt);
            /* Deghost: a frame far from the weighted median (beyond the noise
             * model plus a model error) in any channel is left out. */
            bool reject[MERGE_MAX_FRAMES] = {false}, ghosted = false;
            drop_noise_above_black(p, xs, ws, satr);
            if (drop_hidden_clips(p, xs, ws, satr, reject))
                for (int r = 0; r < f; r++)
                    for (int c = 0; c < 3 && reject[r]; c++)
                        ws[c][r] = 0; /* out of deghost's median too */
            if (ghost)
                for (int c = 0; c < 3; c++) {
                    double med = weighted_median(xs[c], ws[c], f);
                    double model = p->opt->deghost_model_error * med;
                    for (int r = 0; r < f; r++) {
                        if (ws[c][r] <= 0)
                            continue;
                        double d = xs[c][r] - med, var = 1 / ws[c][r] + model * model;
                        if (d * d > p->opt->deghost_sigma * p->opt->deghost_sigma * var)
                            reject[r] = ghosted = true;
                    }
                }
            bool any = false;
            for (int c = 0; c < 3; c++) {
                double num = 0, den = 0, fallback = 0;
                int nsat = 0;
                for (int r = 0; r < f; r++) {
                    if (satr[r])
                        nsat++;
                    else if (!reject[r])
                        fallback = xs[c][r]; /* longest unsaturated so far */
                    if (!reject[r]) {
                        num += ws[c][r] * xs[c][r];
                        den += ws[c][r];
                    }
                }
                double v;
                if (nsat == f) {
                    /* The shortest frame's value is a lower bound, never an estimate. */
                    v = xs[c][0];
                    mask[x * 3 + c] = 1;
                    cnt[c]++;
                    any = true;
                } else if (den > 0) {
                    v = num / den;
                } else {
                    v = fallback;
                    cnt[COUNT_UNDER]++;
                }
                out[x * 3 + c] = (float)v;
            }
            cnt[3] += any;
            if (ghosted) {
                ghost[x] = 1;
                cnt[COUNT_GHOST]++;
            }
        }
    }
}

/* hide_from from the 8-bit tables (increasing in the code): where
 * predicts_clip can hold (xs above xsat, before its noise margin), so most
 * pixels skip drop_hidden_clips. */
static sl_result build_hide_from(pass_ctx *p, sl_error *err)
{
    int f = p->frames;
    if (!(p->hide_from = malloc((size_t)f * f * sizeof *p->hide_from)))
        return sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
    for (int s = 0; s < f; s++)
        for (int r = 0; r < f; r++) {
            int from = 256;
            for (int c = 0; c < 3; c++) {
                const float *rx = p->rx + ((size_t)s * 3 + c) * 256;
                int q = 0;
                while (q < from && !((double)rx[q] > p->xsat[r * 3 + c]))
                    q++;
                from = q;
            }
            p->hide_from[s * f + r] = (uint16_t)from;
        }
    return SL_OK;
}

static sl_result build_luts(pass_ctx *p, sl_error *err)
{
    if (p->m->is_float)
        return SL_OK;
    p->levels = 1 << p->m->bits;
    for (int c = 0; c < 3; c++) {
        p->inv[c] = malloc((size_t)p->levels * sizeof *p->inv[c]);
        p->wb[c] = malloc((size_t)p->levels * sizeof *p->wb[c]);
        if (!p->inv[c] || !p->wb[c])
            return sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
        for (int k = 0; k < p->levels; k++) {
            double z = (double)k / (p->levels - 1);
            p->inv[c][k] = (float)sl_response_eval(&p->res->response, c, z);
            p->wb[c][k] = (float)weight_base(p, c, z);
        }
    }
    if (!p->m->codes)
        return SL_OK;
    int n = p->m->code_bytes == 1 ? 256 : 65536;
    float scale = 1.0f / (float)(n - 1);
    if (!(p->cfade = malloc((size_t)n * sizeof *p->cfade)))
        return sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
    for (int c = 0; c < 3; c++)
        if (!(p->cinv[c] = malloc((size_t)n * sizeof *p->cinv[c])) ||
            !(p->cwb[c] = malloc((size_t)n * sizeof *p->cwb[c])))
            return sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
    /* The same quantisation to levels as fill_float's. */
    for (int q = 0; q < n; q++) {
        float z = (float)q * scale;
        int k = (int)(z * (float)(p->levels - 1) + 0.5f);
        k = k < 0 ? 0 : k >= p->levels ? p->levels - 1 : k;
        for (int c = 0; c < 3; c++) {
            p->cinv[c][q] = p->inv[c][k];
            p->cwb[c][q] = p->wb[c][k];
        }
        p->cfade[q] = z >= (float)p->m->saturation ? 0 : (float)fmin(1, (p->m->saturation - z) / SHOULDER);
    }
    if (n != 256)
        return SL_OK;
    p->rx = malloc((size_t)p->frames * 3 * 256 * sizeof *p->rx);
    p->rw = malloc((size_t)p->frames * 3 * 256 * sizeof *p->rw);
    p->terms = aligned_alloc(16, (size_t)p->frames * 3 * 256 * sizeof *p->terms);
    if (!p->rx || !p->rw || !p->terms)
        return sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
    while (p->shoulder_from < 256 && p->cfade[p->shoulder_from] == 1)
        p->shoulder_from++;
    p->saturated_from = p->shoulder_from;
    while (p->saturated_from < 256 && p->cfade[p->saturated_from] > 0)
        p->saturated_from++;
    for (size_t r = 0; r < (size_t)p->frames; r++)
        for (size_t c = 0; c < 3; c++)
            for (size_t q = 0; q < 256; q++) {
                size_t k = (r * 3 + c) * 256 + q;
                p->rx[k] = (float)(p->cinv[c][q] * p->inv_e[r]);
                p->rw[k] = (float)(p->cwb[c][q] * p->e2[r]);
                p->terms[k] = (merge_term){(double)p->rw[k] * p->rx[k], p->rw[k]};
            }
    return build_hide_from(p, err);
}

/* Strip buffers for a sink, or the result's images. */
static sl_result alloc_outputs(pass_ctx *p, const merge_sink *sink, sl_error *err)
{
    const merge_ctx *m = p->m;
    sl_merge_result *res = p->res;
    int w = m->width;
    if (sink) {
        p->out_stride = p->mask_stride = (size_t)w * 3;
        p->ghost_stride = (size_t)w;
        p->out = malloc((size_t)STRIP * p->out_stride * sizeof *p->out);
        p->mask = calloc((size_t)STRIP * p->mask_stride, sizeof *p->mask);
        p->ghost = p->opt->deghost ? calloc((size_t)STRIP * w, sizeof *p->ghost) : NULL;
        if (!p->out || !p->mask || (p->opt->deghost && !p->ghost))
            return sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
        return SL_OK;
    }
    sl_result r = sl_image_alloc(&res->radiance, w, m->height, 3, err);
    if (!r)
        r = sl_image_alloc(&res->clipped, w, m->height, 3, err);
    if (!r && p->opt->deghost)
        r = sl_image_alloc(&res->ghost, w, m->height, 1, err);
    return r;
}

/* Tasks of one step: reading the next strip of each frame (the first
 * `frames` tasks), then merging the current strip's rows, so a thread that
 * is done decoding merges instead of waiting for the slowest frame. */
static void step_tasks(void *ctx, int64_t begin, int64_t end, int worker)
{
    pass_ctx *p = ctx;
    double *task_cpu = p->task_cpu + (size_t)worker * SL_MERGE_PHASES;
    for (int64_t t = begin; t < end; t++) {
        double t0 = sl_thread_cpu_seconds();
        if (t < p->frames) {
            if (p->ny1 > p->ny0)
                read_next(p, (int)t);
            task_cpu[SL_MERGE_DECODE] += sl_thread_cpu_seconds() - t0;
        } else {
            merge_rows(p, t - p->frames, t - p->frames + 1, worker);
            task_cpu[SL_MERGE_PIXELS] += sl_thread_cpu_seconds() - t0;
        }
    }
}

/* Merges rows [y0, y1) (read already) while reading the next strip, and
 * hands the merged rows to the sink. */
static sl_result merge_strip(pass_ctx *p, merge_sink *sink, sl_error *err)
{
    sl_merge_result *res = p->res;
    int rows = p->y1 - p->y0;
    if (!sink) {
        p->out = sl_image_pixel(&res->radiance, 0, p->y0);
        p->mask = sl_image_pixel(&res->clipped, 0, p->y0);
        p->ghost = res->ghost.data ? sl_image_pixel(&res->ghost, 0, p->y0) : NULL;
        p->out_stride = res->radiance.stride;
        p->mask_stride = res->clipped.stride;
        p->ghost_stride = res->ghost.stride;
    } else {
        memset(p->mask, 0, (size_t)rows * p->mask_stride * sizeof *p->mask);
        if (p->ghost)
            memset(p->ghost, 0, (size_t)rows * p->ghost_stride * sizeof *p->ghost);
    }
    merge_clock clock = merge_clock_start();
    sl_parallel_for(p->frames + rows, 1, step_tasks, p);
    clock = merge_clock_split(&res->timing, clock, p->task_cpu, p->workers);
    sl_result r = SL_OK;
    for (int q = 0; q < p->frames && !r && p->ny1 > p->ny0; q++)
        if ((r = p->results[q]) && err)
            *err = p->errs[q];
    if (r || !sink)
        return r;
    /* A failed write frees its stream: forget it, so that the caller
     * aborts only the others (a second free crashed on a full disk). */
    if ((r = sl_exr_stream_write(sink->radiance, p->out, rows, p->out_stride, err)))
        sink->radiance = NULL;
    if (!r && sink->mask &&
        (r = sl_exr_stream_write(sink->mask, p->mask, rows, p->mask_stride, err)))
        sink->mask = NULL;
    if (!r && sink->ghost &&
        (r = sl_exr_stream_write(sink->ghost, p->ghost, rows, p->ghost_stride, err)))
        sink->ghost = NULL;
    merge_clock_charge(&res->timing, clock, SL_MERGE_WRITE);
    return r;
}

sl_result merge_pass(const merge_ctx *m, const sl_merge_options *opt, merge_sink *sink,
                     sl_merge_result *res, sl_error *err)
{
    int f = res->frame_count;
    pass_ctx p = {.m = m, .opt = opt, .res = res, .frames = f};
    p.clip_sigma2 = opt->deghost_sigma * opt->deghost_sigma;
    p.e = calloc((size_t)f, sizeof *p.e);
    p.inv_e = calloc((size_t)f, sizeof *p.inv_e);
    p.e2 = calloc((size_t)f, sizeof *p.e2);
    p.rd = calloc((size_t)f, sizeof *p.rd);
    void **slots = calloc((size_t)f * 2, sizeof *slots);
    p.buf = slots;
    p.next = slots ? slots + f : NULL;
    p.errs = calloc((size_t)f, sizeof *p.errs);
    p.results = calloc((size_t)f, sizeof *p.results);
    p.row_counts = calloc((size_t)m->height * COUNTS, sizeof *p.row_counts);
    p.workers = sl_threads_get();
    p.task_cpu = calloc((size_t)p.workers * SL_MERGE_PHASES, sizeof *p.task_cpu);
    sl_result r = SL_OK;
    if (!p.e || !p.inv_e || !p.e2 || !p.rd || !p.buf || !p.errs || !p.results || !p.row_counts ||
        !p.task_cpu)
        r = sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
    if (!r)
        r = alloc_outputs(&p, sink, err);
    double ref = res->output_exposure;
    for (int q = 0; q < f && !r; q++) {
        const sl_merge_frame *fr = &res->frames[m->order[q]];
        p.e[q] = fr->exposure / ref;
        p.inv_e[q] = 1 / p.e[q];
        p.e2[q] = p.e[q] * p.e[q];
        if (m->held && m->held[m->order[q]])
            continue; /* its strips are views of the held frame */
        size_t bytes = (size_t)STRIP * m->width * 3 * (m->codes ? (size_t)m->code_bytes : sizeof(float));
        p.buf[q] = malloc(bytes);
        p.next[q] = malloc(bytes);
        if (!p.buf[q] || !p.next[q])
            r = sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
        else
            r = merge_frame_open(fr->path, &fr->align, STRIP, &p.rd[q], err);
    }
    merge_clock tables = merge_clock_start();
    if (!r && (!(p.xsat = malloc((size_t)f * 3 * sizeof *p.xsat)) ||
               !(p.xblack = malloc((size_t)f * 3 * sizeof *p.xblack))))
        r = sl_error_set(err, SL_ERR_NOMEM, "merge: out of memory");
    for (int q = 0; q < f && !r; q++)
        for (int c = 0; c < 3; c++) {
            p.xsat[q * 3 + c] = sl_response_eval(&res->response, c, m->saturation) * p.inv_e[q];
            p.xblack[q * 3 + c] = sl_response_eval(&res->response, c, m->black) * p.inv_e[q];
        }
    if (!r)
        r = build_luts(&p, err);
    merge_clock_charge(&res->timing, tables, SL_MERGE_PIXELS);
    /* The first strip is read alone; then each step merges one and reads the next. */
    p.ny1 = STRIP < m->height ? STRIP : m->height;
    if (!r) {
        merge_clock clock = merge_clock_start();
        sl_parallel_for(f, 1, step_tasks, &p);
        merge_clock_split(&res->timing, clock, p.task_cpu, p.workers);
        for (int q = 0; q < f && !r; q++)
            if ((r = p.results[q]) && err)
                *err = p.errs[q];
    }
    for (int y0 = 0; y0 < m->height && !r; y0 += STRIP) {
        void **t = p.buf;
        p.buf = p.next;
        p.next = t;
        p.y0 = p.ny0;
        p.y1 = p.ny1;
        p.ny0 = p.y1;
        p.ny1 = p.y1 + STRIP < m->height ? p.y1 + STRIP : m->height;
        r = merge_strip(&p, sink, err);
    }
    if (!r) {
        bool latlong = sl_is_latlong_shape(m->width, m->height);
        double solid = 0;
        for (int y = 0; y < m->height; y++) {
            const int64_t *cnt = p.row_counts + (size_t)y * COUNTS;
            for (int c = 0; c < 3; c++)
                res->clipped_samples[c] += cnt[c];
            res->clipped_pixels += cnt[3];
            res->underexposed_samples += cnt[COUNT_UNDER];
            res->nonfinite_samples += cnt[COUNT_NONFINITE];
            res->ghost_pixels += cnt[COUNT_GHOST];
            if (latlong && cnt[3])
                solid += (double)cnt[3] * sl_latlong_texel_solid_angle(y, m->width, m->height);
        }
        res->clipped_fraction = (double)res->clipped_pixels / ((double)m->width * m->height);
        res->clipped_solid_angle = latlong ? solid : -1;
    }
    for (int q = 0; q < f; q++) {
        if (p.rd)
            merge_frame_close(p.rd[q]);
        if (slots && !(m->held && m->held[m->order[q]])) {
            free(slots[q]);
            free(slots[f + q]);
        }
    }
    for (int c = 0; c < 3; c++) {
        free(p.inv[c]);
        free(p.wb[c]);
        free(p.cinv[c]);
        free(p.cwb[c]);
    }
    if (sink) {
        free(p.out);
        free(p.mask);
        free(p.ghost);
    }
    free(p.cfade);
    free(p.xsat);
    free(p.xblack);
    free(p.hide_from);
    free(p.rx);
    free(p.rw);
    free(p.terms);
    free(p.e);
    free(p.inv_e);
    free(p.e2);
    free(p.rd);
    free(slots);
    free(p.errs);
    free(p.results);
    free(p.row_counts);
    free(p.task_cpu);
    return r;
}
