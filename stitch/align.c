/* SPDX-License-Identifier: BSD-3-Clause */
/* Frame registration for the merge: median-threshold bitmaps (Ward 2003)
 * over a pyramid for the coarse translation, then Gauss-Newton on
 * translation and rotation for the sub-pixel answer. Frames are compared
 * on luminance with the tones of one mapped onto the other through their
 * histograms (exposure normalisation without knowing the response). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#include "merge_private.h"

/* Alignment works on at most this many pixels (box-averaged blocks). */
enum { ALIGN_PIXELS = 3000000, MIN_TOP = 24, MAX_LEVELS = 8, HIST = 4096 };
/* The measurement (SL_ALIGN_AUTO) works on at most this many. */
enum { MEASURE_PIXELS = 1 << 18 };

/* Luminance in [0, 1]; BLACK below the black level (or too dark to carry
 * signal: a few noisy codes only give a false match), SAT at saturation. */
#define DARK 0.05
#define SAT_MARGIN 0.1
#define BLACK (-1.0f)
#define SAT 2.0f

typedef struct plane {
    int w, h;
    float *v;
} plane;

typedef struct luma {
    int levels;
    plane lv[MAX_LEVELS]; /* lv[0] at the alignment resolution */
    /* per level: 1 where a pixel and its four neighbours are valid (inner_mask), or NULL */
    uint8_t *inner[MAX_LEVELS];
} luma;

static void luma_free(luma *l)
{
    for (int i = 0; i < l->levels; i++) {
        free(l->lv[i].v);
        free(l->inner[i]);
    }
    memset(l, 0, sizeof *l);
}

/* Well-exposed pixels (in both frames) a full estimate uses: 5% of the
 * image. A dark frame's lamps and windows, or a clipped frame's shadows,
 * can be fewer and still place it (a 640x427 room's 1/1000 s frame: 3 900
 * pixels, within 0.1 px; two dozen lamps on 320 of 120 000 pixels, within
 * 0.25 px), but they can also pull the fit away (align_pair checks it
 * then); under 0.1% the frame is not measured. */
static int64_t pixels_share(const plane *p, int divisor)
{
    int64_t n = (int64_t)p->w * p->h / divisor;
    return n < 200 ? 200 : n;
}
static int64_t min_overlap(const plane *p) { return pixels_share(p, 20); }
static int64_t min_few(const plane *p) { return pixels_share(p, 1000); }

static inline bool valid(float v) { return v >= 0 && v <= 1; }

/* The pixels of p refine can use as the reference frame's: 1 where the
 * pixel and its four neighbours are valid (0 on the border); found once
 * per frame rather than in every iteration. NULL: out of memory. */
static uint8_t *inner_mask(const plane *p)
{
    uint8_t *m = calloc((size_t)p->w * p->h, 1);
    for (int y = 1; m && y < p->h - 1; y++) {
        const float *r = p->v + (size_t)y * p->w;
        uint8_t *o = m + (size_t)y * p->w;
        for (int x = 1; x < p->w - 1; x++)
            o[x] = valid(r[x]) && valid(r[x - 1]) && valid(r[x + 1]) && valid(r[x - p->w]) &&
                   valid(r[x + p->w]);
    }
    return m;
}

/* Reads a frame into block-averaged luminance; a block with any black or
 * saturated pixel takes that state (saturation wins). */
static sl_result read_luma(const char *path, int scale, const sl_merge_options *opt, plane *out,
                           sl_error *err)
{
    sl_photo_strips *rd;
    sl_photo_strip_info info;
    sl_result r = sl_photo_strips_open(path, &rd, &info, err);
    if (r)
        return r;
    int w = info.width / scale, h = info.height / scale, fw = info.width;
    out->w = w;
    out->h = h;
    out->v = malloc((size_t)w * h * sizeof *out->v);
    float *buf = malloc((size_t)scale * fw * 3 * sizeof *buf);
    double *acc = malloc((size_t)w * sizeof *acc);
    unsigned char *state = malloc((size_t)w);
    if (!out->v || !buf || !acc || !state)
        r = sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    float black = (float)fmax(opt->black, DARK), sat = (float)(opt->saturation - SAT_MARGIN);
    for (int by = 0; by < h && !r; by++) {
        if ((r = sl_photo_strips_read(rd, by * scale, (by + 1) * scale, buf, err)))
            break;
        memset(acc, 0, (size_t)w * sizeof *acc);
        memset(state, 0, (size_t)w);
        for (int j = 0; j < scale; j++)
            for (int x = 0; x < w * scale; x++) {
                const float *p = buf + ((size_t)j * fw + x) * 3;
                int bx = x / scale;
                double y = sl_luminance_px(p);
                if (!(p[0] < sat && p[1] < sat && p[2] < sat))
                    state[bx] = 2; /* also NaN */
                else if (y <= black)
                    state[bx] = state[bx] ? state[bx] : 1;
                acc[bx] += y;
            }
        float *dst = out->v + (size_t)by * w;
        double inv = 1.0 / ((double)scale * scale);
        for (int x = 0; x < w; x++)
            dst[x] = state[x] == 2 ? SAT : state[x] == 1 ? BLACK : (float)fmin(acc[x] * inv, 1);
    }
    sl_photo_strips_close(rd);
    free(buf);
    free(acc);
    free(state);
    return r;
}

/* Halves a plane; a block is valid only when its four pixels are. */
static sl_result halve(const plane *src, plane *dst, sl_error *err)
{
    dst->w = src->w / 2;
    dst->h = src->h / 2;
    dst->v = malloc((size_t)dst->w * dst->h * sizeof *dst->v);
    if (!dst->v)
        return sl_error_set(err, SL_ERR_NOMEM, "align: out of memory");
    for (int y = 0; y < dst->h; y++)
        for (int x = 0; x < dst->w; x++) {
            const float *a = src->v + (size_t)(2 * y) * src->w + 2 * x, *b = a + src->w;
            float q[4] = {a[0], a[1], b[0], b[1]}, v = 0;
            bool ok = true;
            for (int k = 0; k < 4; k++) {
                ok = ok && valid(q[k]);
                v += q[k];
            }
            float out = 0.25f * v;
            if (!ok) {
                out = BLACK;
                for (int k = 0; k < 4; k++)
                    out = q[k] == SAT ? SAT : out;
            }
            dst->v[(size_t)y * dst->w + x] = out;
        }
    return SL_OK;
}

static sl_result build_pyramid(luma *l, sl_error *err)
{
    l->levels = 1;
    while (l->levels < MAX_LEVELS && l->lv[l->levels - 1].w / 2 >= MIN_TOP &&
           l->lv[l->levels - 1].h / 2 >= MIN_TOP) {
        sl_result r = halve(&l->lv[l->levels - 1], &l->lv[l->levels], err);
        if (r)
            return r;
        l->levels++;
    }
    return SL_OK;
}

/* Tone map from b's luminance to a's: equal ranks in the two histograms
 * (frames of one scene differ by a monotonic function of exposure).
 * Black pixels rank lowest and saturated ones highest. */
static void match_tones(const plane *a, const plane *b, float *map)
{
    double ha[HIST + 2], hb[HIST + 2];
    double *h[2] = {ha, hb};
    const plane *p[2] = {a, b};
    for (int k = 0; k < 2; k++) {
        memset(h[k], 0, (HIST + 2) * sizeof(double));
        size_t n = (size_t)p[k]->w * p[k]->h;
        for (size_t i = 0; i < n; i++) {
            float v = p[k]->v[i];
            int bin = v == BLACK ? 0 : v == SAT ? HIST + 1 : 1 + (int)fminf(v * HIST, HIST - 1);
            h[k][bin]++;
        }
        for (int i = 1; i < HIST + 2; i++)
            h[k][i] += h[k][i - 1];
        for (int i = 0; i < HIST + 2; i++)
            h[k][i] /= h[k][HIST + 1];
    }
    /* For b's bin centre: the rank's value in a (linear between bin edges). */
    int j = 0;
    for (int i = 1; i <= HIST; i++) {
        double rank = 0.5 * (hb[i - 1] + hb[i]);
        while (j < HIST + 1 && ha[j] < rank)
            j++;
        float v;
        if (j == 0)
            v = BLACK;
        else if (j == HIST + 1)
            v = SAT;
        else {
            double lo = ha[j - 1], hi = ha[j], f = hi > lo ? (rank - lo) / (hi - lo) : 0.5;
            v = (float)((j - 1 + f) / HIST);
        }
        map[i - 1] = v;
    }
}

static void apply_map(const plane *b, const float *map, plane *out)
{
    size_t n = (size_t)b->w * b->h;
    for (size_t i = 0; i < n; i++) {
        float v = b->v[i];
        out->v[i] = valid(v) ? map[(int)fminf(v * HIST, HIST - 1)] : v;
    }
}

/* Median of a's values that b' can also show, over pixels valid in a. */
static float threshold(const plane *a, const plane *bm)
{
    float lo = 1, hi = 0;
    size_t n = (size_t)bm->w * bm->h;
    for (size_t i = 0; i < n; i++)
        if (valid(bm->v[i])) {
            lo = fminf(lo, bm->v[i]);
            hi = fmaxf(hi, bm->v[i]);
        }
    int hist[HIST] = {0};
    int64_t total = 0;
    n = (size_t)a->w * a->h;
    for (size_t i = 0; i < n; i++) {
        float v = a->v[i];
        if (valid(v) && v >= lo && v <= hi) {
            hist[(int)fminf(v * HIST, HIST - 1)]++;
            total++;
        }
    }
    int64_t run = 0;
    for (int i = 0; i < HIST; i++)
        if ((run += hist[i]) * 2 >= total)
            return (i + 0.5f) / HIST;
    return 0.5f;
}

/* A plane's bits for the bitmap test, once per pair rather than per shift
 * tried: 0 where a pixel is invalid or within eps of the threshold (it
 * says nothing), else 1 below the threshold and 2 above. */
static void mtb_bits(const plane *p, float t, float eps, uint8_t *out)
{
    size_t n = (size_t)p->w * p->h;
    for (size_t i = 0; i < n; i++) {
        float v = p->v[i];
        out[i] = !valid(v) || fabsf(v - t) < eps ? 0 : v > t ? 2 : 1;
    }
}

/* Fraction of differing bits between a and b' (their mtb_bits ba, bb)
 * shifted by (sx, sy), over pixels that say something in both; *count
 * gets how many. */
static double mtb_cost(const plane *a, const uint8_t *ba, const plane *b, const uint8_t *bb,
                       int sx, int sy, int64_t *count)
{
    int64_t diff = 0, n = 0;
    for (int y = 0; y < a->h; y++) {
        int yb = y + sy;
        if (yb < 0 || yb >= b->h)
            continue;
        const uint8_t *ra = ba + (size_t)y * a->w, *rb = bb + (size_t)yb * b->w + sx;
        int x0 = sx < 0 ? -sx : 0, x1 = a->w < b->w - sx ? a->w : b->w - sx;
        int row_n = 0, row_diff = 0, x = x0;
#ifdef __SSE2__
        /* Sixteen pixels a step; byte counters (a hit subtracts -1), summed
         * every 255 steps, before they could wrap. */
        const __m128i zero = _mm_setzero_si128(), three = _mm_set1_epi8(3);
        while (x + 16 <= x1) {
            __m128i cn = zero, cd = zero;
            for (int k = 0; k < 255 && x + 16 <= x1; k++, x += 16) {
                __m128i u = _mm_loadu_si128((const __m128i *)(ra + x));
                __m128i v = _mm_loadu_si128((const __m128i *)(rb + x));
                __m128i none = _mm_or_si128(_mm_cmpeq_epi8(u, zero), _mm_cmpeq_epi8(v, zero));
                cn = _mm_sub_epi8(cn, _mm_andnot_si128(none, _mm_set1_epi8(-1)));
                cd = _mm_sub_epi8(cd, _mm_cmpeq_epi8(_mm_xor_si128(u, v), three));
            }
            __m128i sn = _mm_sad_epu8(cn, zero), sd = _mm_sad_epu8(cd, zero);
            row_n += _mm_cvtsi128_si32(sn) + _mm_cvtsi128_si32(_mm_srli_si128(sn, 8));
            row_diff += _mm_cvtsi128_si32(sd) + _mm_cvtsi128_si32(_mm_srli_si128(sd, 8));
        }
#endif
        for (; x < x1; x++) {
            int u = ra[x], v = rb[x];
            row_n += (u != 0) & (v != 0);
            row_diff += (u ^ v) == 3;
        }
        n += row_n;
        diff += row_diff;
    }
    *count = n;
    return n ? (double)diff / (double)n : 1;
}

typedef struct rigid {
    double tx, ty, th; /* at level 0 of the alignment resolution, radians */
} rigid;

/* Gauss-Newton on (tx, ty, th) at one level: residual b'(T p) - a(p) with
 * a's gradient, Huber weights. Returns pixels used in the last iteration.
 * spread[0] gets the shift the fit's typical residual amounts to (rms
 * residual over rms gradient in its weakest direction, level-0 pixels),
 * spread[1] the angle (over
 * the rms derivative by the angle, radians): a tone map off by that
 * residual in smooth content moves the estimate by about as much, whatever
 * the pixel count, so a smaller motion is not believed. */
static int64_t refine(const plane *a, const uint8_t *inner, const plane *b, int level, double tol,
                      bool quick, rigid *t, double spread[2])
{
    double s = ldexp(1, level), cx = 0.5 * a->w, cy = 0.5 * a->h;
    int64_t used = 0;
    for (int it = 0; it < 12; it++) {
        double H[3][3] = {{0}}, g[3] = {0}, rss = 0;
        double c = cos(t->th), sn = sin(t->th), tx = t->tx / s, ty = t->ty / s;
        used = 0;
        for (int y = 1; y < a->h - 1; y++) {
            const float *ra = a->v + (size_t)y * a->w;
            const uint8_t *ok = inner + (size_t)y * a->w;
            for (int x = 1; x < a->w - 1; x++) {
                if (!ok[x])
                    continue;
                float va = ra[x], l = ra[x - 1], rr = ra[x + 1], u = ra[x - a->w], d = ra[x + a->w];
                double px = x + 0.5 - cx, py = y + 0.5 - cy;
                double qx = c * px - sn * py + cx + tx - 0.5, qy = sn * px + c * py + cy + ty - 0.5;
                int ix = (int)floor(qx), iy = (int)floor(qy);
                if (ix < 0 || iy < 0 || ix + 1 >= b->w || iy + 1 >= b->h)
                    continue;
                const float *q0 = b->v + (size_t)iy * b->w + ix, *q1 = q0 + b->w;
                if (!valid(q0[0]) || !valid(q0[1]) || !valid(q1[0]) || !valid(q1[1]))
                    continue;
                double fx = qx - ix, fy = qy - iy;
                double vb = (1 - fy) * ((1 - fx) * q0[0] + fx * q0[1]) + fy * ((1 - fx) * q1[0] + fx * q1[1]);
                double r = vb - va, gx = 0.5 * (rr - l), gy = 0.5 * (d - u);
                double J[3] = {gx, gy, gx * (-sn * px - c * py) + gy * (c * px - sn * py)};
                double wgt = fabs(r) < 0.03 ? 1 : 0.03 / fabs(r);
                for (int i = 0; i < 3; i++) {
                    g[i] += wgt * J[i] * r;
                    for (int j = 0; j < 3; j++)
                        H[i][j] += wgt * J[i] * J[j];
                }
                rss += wgt * r * r;
                used++;
            }
        }
        if (used < min_few(a))
            return used;
        /* The shift's weakest direction: a ramp (gradients all one way)
         * leaves a shift along it free to stand in for a tone error. */
        double tr = H[0][0] + H[1][1], dif = H[0][0] - H[1][1];
        double weakest = 0.5 * (tr - sqrt(dif * dif + 4 * H[0][1] * H[0][1]));
        spread[0] = weakest > 0 ? s * sqrt(rss / weakest) : INFINITY;
        spread[1] = H[2][2] > 0 ? sqrt(rss / H[2][2]) : INFINITY;
        /* Gauss-Newton step: H d = -g. */
        double m[3][4];
        for (int i = 0; i < 3; i++) {
            for (int j = 0; j < 3; j++)
                m[i][j] = H[i][j] + (i == j ? 1e-9 * (H[0][0] + H[1][1]) : 0);
            m[i][3] = -g[i];
        }
        bool singular = false;
        for (int k = 0; k < 3 && !singular; k++) {
            int piv = k;
            for (int i = k + 1; i < 3; i++)
                if (fabs(m[i][k]) > fabs(m[piv][k]))
                    piv = i;
            if (!(fabs(m[piv][k]) > 0)) {
                singular = true;
                break;
            }
            for (int j = 0; j < 4; j++) {
                double tmp = m[k][j];
                m[k][j] = m[piv][j];
                m[piv][j] = tmp;
            }
            for (int i = 0; i < 3; i++)
                if (i != k) {
                    double f = m[i][k] / m[k][k];
                    for (int j = k; j < 4; j++)
                        m[i][j] -= f * m[k][j];
                }
        }
        if (singular)
            return 0;
        double dx = m[0][3] / m[0][0], dy = m[1][3] / m[1][1], dth = m[2][3] / m[2][2];
        t->tx += dx * s;
        t->ty += dy * s;
        t->th += dth;
        /* The measurement counts a motion only beyond twice the spread:
         * steps under a tenth of it cannot change that, and on smooth
         * content (a sky's gradient) they wander for every iteration. */
        double stop = quick ? fmax(tol, 0.1 * spread[0] / s) : tol;
        if (fabs(dx) < stop && fabs(dy) < stop && fabs(dth) * a->w < stop)
            break;
    }
    return used;
}

enum { JOINT = 256 };

/* The tone map again, now from pixel pairs under the current transform:
 * per bin of b's value, the mean of a's values it meets (a histogram
 * match is off by the content the motion brings in and out of frame). */
static void joint_tones(const plane *a, const plane *b, const rigid *t, float *map)
{
    double sa[JOINT] = {0}, sb[JOINT] = {0}, n[JOINT] = {0};
    double c = cos(t->th), sn = sin(t->th), cx = 0.5 * a->w, cy = 0.5 * a->h;
    for (int y = 0; y < a->h; y++)
        for (int x = 0; x < a->w; x++) {
            float va = a->v[(size_t)y * a->w + x];
            double px = x + 0.5 - cx, py = y + 0.5 - cy;
            int qx = (int)floor(c * px - sn * py + cx + t->tx), qy = (int)floor(sn * px + c * py + cy + t->ty);
            if (!valid(va) || qx < 0 || qy < 0 || qx >= b->w || qy >= b->h)
                continue;
            float vb = b->v[(size_t)qy * b->w + qx];
            if (!valid(vb))
                continue;
            int k = (int)fminf(vb * JOINT, JOINT - 1);
            sa[k] += va;
            sb[k] += vb;
            n[k]++;
        }
    double xs[JOINT], ys[JOINT];
    int m = 0;
    for (int k = 0; k < JOINT; k++)
        if (n[k] >= 20) {
            xs[m] = sb[k] / n[k];
            ys[m] = m ? fmax(sa[k] / n[k], ys[m - 1]) : sa[k] / n[k];
            m++;
        }
    if (m < 2)
        return;
    int j = 0;
    for (int i = 0; i < HIST; i++) {
        double v = (i + 0.5) / HIST;
        while (j + 2 < m && xs[j + 1] < v)
            j++;
        double f = (v - xs[j]) / (xs[j + 1] - xs[j]);
        map[i] = (float)(ys[j] + f * (ys[j + 1] - ys[j]));
    }
}

/* Estimates b relative to a (both at the alignment resolution). */
/* How hard an estimate works: Gauss-Newton stops when a step moves less
 * than tol pixels; rounds of the joint tone map. The measurement (quick)
 * needs a tenth of a pixel to decide, registration a hundredth. */
typedef struct effort {
    double tol;
    int rounds;
    bool quick;
} effort;
static const effort FULL = {1e-4, 4, false}, QUICK = {5e-3, 1, true};

/* bits: scratch for both frames' mtb_bits at every level (2 x the
 * pyramid's pixels). */
static void align_pair(const luma *a, const luma *b, float *map, luma *bm, uint8_t *bits,
                       const sl_merge_options *opt, double scale, effort how, rigid *out,
                       int64_t *used, double spread[2], char *note, size_t note_size)
{
    spread[0] = spread[1] = INFINITY;
    memset(out, 0, sizeof *out);
    *used = 0;
    match_tones(&a->lv[0], &b->lv[0], map);
    for (int i = 0; i < bm->levels; i++)
        apply_map(&b->lv[i], map, &bm->lv[i]);
    float t = threshold(&a->lv[0], &bm->lv[0]), eps = 4.0f / 255;
    uint8_t *ba[MAX_LEVELS], *bb[MAX_LEVELS];
    for (int i = 0; i < a->levels; i++) {
        size_t n = (size_t)a->lv[i].w * a->lv[i].h;
        ba[i] = bits;
        bb[i] = bits + n;
        bits += 2 * n;
        mtb_bits(&a->lv[i], t, eps, ba[i]);
        mtb_bits(&bm->lv[i], t, eps, bb[i]);
    }
    int top = a->levels - 1;
    int range = (int)ceil(opt->align_max_shift / (scale * ldexp(1, top))) + 1;
    int sx = 0, sy = 0;
    double best = 2;
    int64_t n = 0;
    for (int y = -range; y <= range; y++)
        for (int x = -range; x <= range; x++) {
            int64_t cnt;
            double cost = mtb_cost(&a->lv[top], ba[top], &bm->lv[top], bb[top], x, y, &cnt);
            cost += 1e-9 * (x * x + y * y); /* ties go to the smaller shift */
            if (cnt * 4 >= n && cost < best) {
                best = cost;
                sx = x;
                sy = y;
                n = cnt > n ? cnt : n;
            }
        }
    for (int lv = top - 1; lv >= 0; lv--) {
        int cx = 2 * sx, cy = 2 * sy;
        best = 2;
        for (int y = -1; y <= 1; y++)
            for (int x = -1; x <= 1; x++) {
                int64_t cnt;
                double cost = mtb_cost(&a->lv[lv], ba[lv], &bm->lv[lv], bb[lv], cx + x, cy + y,
                                       &cnt);
                cost += 1e-9 * (x * x + y * y);
                if (cnt > 0 && cost < best) {
                    best = cost;
                    sx = cx + x;
                    sy = cy + y;
                }
            }
    }
    out->tx = sx;
    out->ty = sy;
    /* Refine from a level where a degree of rotation moves the corners a
     * few pixels at most, down to full alignment resolution. */
    int start = 0;
    while (start + 1 < a->levels && a->lv[start].w > 256)
        start++;
    for (int lv = start; lv >= 0; lv--)
        *used = refine(&a->lv[lv], a->inner[lv], &bm->lv[lv], lv, how.tol, how.quick, out, spread);
    for (int round = 0; round < how.rounds && *used >= min_overlap(&a->lv[0]); round++) {
        joint_tones(&a->lv[0], &b->lv[0], out, map);
        apply_map(&b->lv[0], map, &bm->lv[0]);
        *used = refine(&a->lv[0], a->inner[0], &bm->lv[0], 0, how.tol, how.quick, out, spread);
    }
    /* A fit on few pixels must be sure to within a pixel, and stay by the
     * bitmaps' match unless the bitmaps agree better where it went (their
     * coarse-to-fine search can stop a few pixels off when few pixels carry
     * them): on a clipped frame's dark corners it can wander off by tens of
     * pixels, or settle a pixel off within its spread. */
    bool few = *used < min_overlap(&a->lv[0]);
    double wander = hypot(out->tx - sx, out->ty - sy);
    bool strayed = few && wander > 1.5;
    if (strayed) {
        int64_t n_mtb, n_fit;
        double at_mtb = mtb_cost(&a->lv[0], ba[0], &bm->lv[0], bb[0], sx, sy, &n_mtb);
        double at_fit = mtb_cost(&a->lv[0], ba[0], &bm->lv[0], bb[0], (int)lround(out->tx),
                                 (int)lround(out->ty), &n_fit);
        strayed = !(n_fit > 0 && at_fit <= at_mtb);
    }
    if (*used < min_few(&a->lv[0]))
        snprintf(note, note_size, "%lld pixels well exposed in both frames (too few)",
                 (long long)*used);
    else if (strayed)
        snprintf(note, note_size,
                 "%d pixels well exposed in both frames (few, and the fit strayed %.0f px)",
                 (int)*used, fmin(wander * scale, 9999));
    else if (few && !(spread[0] <= 1))
        snprintf(note, note_size,
                 "%d pixels well exposed in both frames (few, and the fit's spread is %.1f px)",
                 (int)*used, fmin(spread[0] * scale, 9999));
    else
        return;
    memset(out, 0, sizeof *out);
}

typedef struct luma_job {
    const char *const *paths;
    const sl_merge_options *opt;
    int scale;
    luma *l;
    sl_error *errs;
    sl_result *results;
} luma_job;

static void luma_frames(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    luma_job *job = ctx;
    for (int64_t i = begin; i < end; i++) {
        sl_result r = read_luma(job->paths[i], job->scale, job->opt, &job->l[i].lv[0], &job->errs[i]);
        job->l[i].levels = 1;
        if (!r)
            r = build_pyramid(&job->l[i], &job->errs[i]);
        job->results[i] = r;
    }
}

static int cmp_exposure(const void *a, const void *b, void *ctx)
{
    const double *e = ctx;
    double x = e[*(const int *)a], y = e[*(const int *)b];
    return (x > y) - (x < y);
}

/* One direction's chain of estimates (below or above the reference), with
 * its own scratch: the two run side by side (estimate). */
typedef struct chain_job {
    luma *l;
    int count, scale, width, height, ref;
    const int *order;
    const sl_merge_options *opt;
    effort how;
    sl_align_transform *out;
    rigid chain[MERGE_MAX_FRAMES];
    double spreads[MERGE_MAX_FRAMES][2];
    float *map[2];
    luma bm[2];
    uint8_t *bits[2];
} chain_job;

static void chain_direction(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    chain_job *j = ctx;
    const sl_merge_options *opt = j->opt;
    luma *l = j->l;
    int scale = j->scale;
    rigid *chain = j->chain;
    double(*spreads)[2] = j->spreads;
    for (int64_t task = begin; task < end; task++) {
        int dir = task ? 1 : -1;
        for (int q = j->ref + dir; q >= 0 && q < j->count; q += dir) {
            int fa = j->order[q - dir], fb = j->order[q];
            sl_align_transform *o = &j->out[fb];
            rigid step, prev = chain[q - dir];
            int64_t used;
            double spread[2];
            align_pair(&l[fa], &l[fb], j->map[task], &j->bm[task], j->bits[task], opt, scale,
                       j->how, &step, &used, spread, o->note, sizeof o->note);
            double c = cos(step.th), s = sin(step.th);
            chain[q].th = prev.th + step.th;
            chain[q].tx = c * prev.tx - s * prev.ty + step.tx;
            chain[q].ty = s * prev.tx + c * prev.ty + step.ty;
            o->pixels = used;
            if (fabs(step.tx * scale) > opt->align_max_shift ||
                fabs(step.ty * scale) > opt->align_max_shift ||
                fabs(step.th * 180 / M_PI) > opt->align_max_angle)
                snprintf(o->note, sizeof o->note, "beyond the limits (%.1f px, %.2f deg)",
                         opt->align_max_shift, opt->align_max_angle);
            o->refused = o->note[0] != '\0';
            /* Steps' spreads add like independent errors. */
            for (int k = 0; k < 2; k++)
                spreads[q][k] = o->refused ? spreads[q - dir][k]
                                           : hypot(spreads[q - dir][k], spread[k] * (k ? 1 : scale));
            o->shift_spread_px = spreads[q][0];
            o->angle_spread_deg = spreads[q][1] * 180 / M_PI;
            if (o->refused)
                chain[q] = prev; /* unaligned: where its neighbour sits */
            /* To full resolution, where the centre may sit up to half a
             * block off the alignment image's: R (p - c') + c' + t = R
             * (p - c) + c + t + (I - R)(c' - c). */
            double th = chain[q].th, ct = cos(th), st = sin(th);
            double ex = 0.5 * l[0].lv[0].w * scale - 0.5 * j->width;
            double ey = 0.5 * l[0].lv[0].h * scale - 0.5 * j->height;
            o->dx = chain[q].tx * scale + ex - (ct * ex - st * ey);
            o->dy = chain[q].ty * scale + ey - (st * ex + ct * ey);
            o->angle = th * 180 / M_PI;
            /* Sub-0.05 px everywhere on the frame: resampling would only blur. */
            o->applied = sl_align_displacement(o, j->width, j->height) > 0.05;
        }
    }
}

/* Chains pairwise estimates outward from the reference (the median
 * exposure) over frames l[] at 1/scale of width x height; out[i] in full
 * resolution pixels. The chains below and above the reference share
 * nothing but it, so they run in parallel (the same answers on any
 * number of threads). */
static sl_result estimate(luma *l, int count, const double *exposures, const sl_merge_options *opt,
                          int scale, int width, int height, effort how, sl_align_transform *out,
                          sl_error *err)
{
    chain_job *j = calloc(1, sizeof *j);
    int *order = malloc((size_t)count * sizeof *order);
    sl_result r = !j || !order ? sl_error_set(err, SL_ERR_NOMEM, "align: out of memory") : SL_OK;
    size_t pixels = 0;
    for (int i = 0; i < l[0].levels; i++)
        pixels += (size_t)l[0].lv[i].w * l[0].lv[i].h;
    for (int d = 0; d < 2 && !r; d++) {
        j->map[d] = malloc(HIST * sizeof *j->map[d]);
        j->bits[d] = malloc(2 * pixels);
        if (!j->map[d] || !j->bits[d])
            r = sl_error_set(err, SL_ERR_NOMEM, "align: out of memory");
        for (int i = 0; i < l[0].levels && !r; i++) {
            j->bm[d].lv[i] = l[0].lv[i];
            if (!(j->bm[d].lv[i].v = malloc((size_t)l[0].lv[i].w * l[0].lv[i].h * sizeof(float))))
                r = sl_error_set(err, SL_ERR_NOMEM, "align: out of memory");
            else
                j->bm[d].levels = i + 1;
        }
    }
    /* refine's levels: from the first at most 256 wide (align_pair) down. */
    for (int i = 0; i < count && !r; i++)
        for (int lv = 0; lv < l[i].levels && (lv == 0 || l[i].lv[lv - 1].w > 256); lv++)
            if (!l[i].inner[lv] && !(l[i].inner[lv] = inner_mask(&l[i].lv[lv])))
                r = sl_error_set(err, SL_ERR_NOMEM, "align: out of memory");
    if (!r) {
        for (int i = 0; i < count; i++)
            order[i] = i;
        qsort_r(order, (size_t)count, sizeof *order, cmp_exposure, (void *)exposures);
        j->ref = (count - 1) / 2;
        snprintf(out[order[j->ref]].note, sizeof out[order[j->ref]].note, "reference");
        /* Outward from the reference, each frame against its neighbour;
         * transforms compose: q = R(a+b) (p - c) + R(b) t_a + t_b + c. */
        j->l = l;
        j->count = count;
        j->scale = scale;
        j->width = width;
        j->height = height;
        j->order = order;
        j->opt = opt;
        j->how = how;
        j->out = out;
        sl_parallel_for(2, 1, chain_direction, j);
    }
    for (int d = 0; j && d < 2; d++) {
        luma_free(&j->bm[d]);
        free(j->map[d]);
        free(j->bits[d]);
    }
    free(j);
    free(order);
    return r;
}

double sl_align_displacement(const sl_align_transform *t, int width, int height)
{
    return hypot(t->dx, t->dy) + fabs(t->angle * M_PI / 180) * 0.5 * hypot(width, height);
}

double sl_align_sure_displacement(const sl_align_transform *t, int width, int height)
{
    double shift = hypot(t->dx, t->dy), reach = fabs(t->angle * M_PI / 180) * 0.5 * hypot(width, height);
    return (shift > 2 * t->shift_spread_px ? shift : 0) +
           (fabs(t->angle) > 2 * t->angle_spread_deg ? reach : 0);
}

static sl_result check_limits(const char *const *paths, int count, const sl_merge_options *opt,
                              sl_error *err)
{
    if (count < 2 || count > MERGE_MAX_FRAMES)
        return sl_error_set(err, SL_ERR_USAGE, "%s: alignment needs 2 to %d frames",
                            count > 0 ? paths[0] : "(no frames)", MERGE_MAX_FRAMES);
    if (!(opt->align_max_shift > 0) || !(opt->align_max_angle > 0) || !(opt->align_max_angle <= 10))
        return sl_error_set(err, SL_ERR_USAGE,
                            "%s: alignment limits out of range (shift > 0, 0 < angle <= 10)",
                            paths[0]);
    return SL_OK;
}

sl_result sl_align_bracket(const char *const *paths, int count, const double *exposures,
                           const sl_merge_options *opt_in, sl_align_transform *out, sl_error *err)
{
    memset(out, 0, (size_t)(count > 0 ? count : 0) * sizeof *out);
    sl_merge_options opt = merge_options_or_default(opt_in);
    sl_result r = check_limits(paths, count, &opt, err);
    if (r)
        return r;
    sl_photo_strips *rd;
    sl_photo_strip_info info;
    if ((r = sl_photo_strips_open(paths[0], &rd, &info, err)))
        return r;
    sl_photo_strips_close(rd);
    if (opt.saturation == 0)
        opt.saturation = merge_saturation_default(opt.response_mode, info.lossless);
    int scale = 1;
    while ((double)(info.width / scale) * (info.height / scale) > ALIGN_PIXELS)
        scale++;
    luma *l = calloc((size_t)count, sizeof *l);
    sl_error *errs = calloc((size_t)count, sizeof *errs);
    sl_result *results = calloc((size_t)count, sizeof *results);
    if (!l || !errs || !results)
        r = sl_error_set(err, SL_ERR_NOMEM, "align: out of memory");
    if (!r) {
        luma_job job = {paths, &opt, scale, l, errs, results};
        sl_parallel_for(count, 1, luma_frames, &job);
        for (int i = 0; i < count && !r; i++)
            if ((r = results[i]) && err)
                *err = errs[i];
    }
    for (int i = 1; i < count && !r; i++)
        if (l[i].lv[0].w != l[0].lv[0].w || l[i].lv[0].h != l[0].lv[0].h)
            r = sl_error_set(err, SL_ERR_INPUT, "%s: size differs from %s", paths[i], paths[0]);
    if (!r)
        r = estimate(l, count, exposures, &opt, scale, info.width, info.height, FULL, out, err);
    for (int i = 0; l && i < count; i++)
        luma_free(&l[i]);
    free(l);
    free(errs);
    free(results);
    if (r)
        memset(out, 0, (size_t)count * sizeof *out);
    return r;
}

/* The measurement's resolution: at most MEASURE_PIXELS, so that its
 * estimate costs a fraction of decoding the frames. */
int align_measure_scale(int width, int height)
{
    int scale = 1;
    while ((double)(width / scale) * (height / scale) > MEASURE_PIXELS)
        scale++;
    return scale;
}

sl_result align_plane_init(align_plane *p, int width, int height, sl_error *err)
{
    memset(p, 0, sizeof *p);
    p->scale = align_measure_scale(width, height);
    p->w = width / p->scale;
    p->h = height / p->scale;
    p->v = calloc((size_t)p->w * p->h, sizeof *p->v);
    p->state = calloc((size_t)p->w * p->h, 1);
    p->row = malloc((size_t)width * sizeof *p->row);
    p->row_flag = malloc((size_t)width);
    if (!p->v || !p->state || !p->row || !p->row_flag) {
        align_plane_free(p);
        return sl_error_set(err, SL_ERR_NOMEM, "align: out of memory");
    }
    return SL_OK;
}

void align_plane_free(align_plane *p)
{
    free(p->v);
    free(p->state);
    free(p->row);
    free(p->row_flag);
    memset(p, 0, sizeof *p);
}

/* From 4x4 blocks up every other row of a block is enough for the
 * measurement (the same rows in every frame, so no shift between them):
 * half the cost of adding up. */
static inline bool row_used(int y, int scale) { return scale < 4 || (y % scale) % 2 == 0; }
static inline int rows_used(int scale) { return scale < 4 ? scale : (scale + 1) / 2; }

/* 8-bit rows: luminance as 54 R + 183 G + 19 B (out of 256 * 255) and a
 * flag per pixel (2 saturated, 1 dark) in a loop the compiler vectorises,
 * then summed per block; the float path cost 9 ns a pixel, 1.4 s on a
 * 24-megapixel bracket of 7. */
static void add_rows_u8(align_plane *p, const uint8_t *strip, int width, int y0, int y1,
                        float black, float sat, uint16_t *lum, uint8_t *flag)
{
    int xs = p->w * p->scale, sat_code = (int)ceilf(sat * 255);
    int black_lum = (int)floorf(black * 256 * 255);
    for (int y = y0; y < y1 && y / p->scale < p->h; y++) {
        if (!row_used(y, p->scale))
            continue;
        const uint8_t *q = strip + (size_t)(y - y0) * width * 3;
        for (int x = 0; x < xs; x++) {
            int r = q[3 * x], g = q[3 * x + 1], b = q[3 * x + 2];
            int l = 54 * r + 183 * g + 19 * b, hi = r > g ? r : g;
            hi = hi > b ? hi : b;
            lum[x] = (uint16_t)l;
            flag[x] = hi >= sat_code ? 2 : l <= black_lum ? 1 : 0;
        }
        float *sum = p->v + (size_t)(y / p->scale) * p->w;
        uint8_t *state = p->state + (size_t)(y / p->scale) * p->w;
        for (int bx = 0, x = 0; bx < p->w; bx++) {
            uint32_t acc = 0;
            uint8_t st = state[bx];
            for (int j = 0; j < p->scale; j++, x++) {
                acc += lum[x];
                st = flag[x] > st ? flag[x] : st;
            }
            sum[bx] += (float)acc * (1.0f / (256 * 255));
            state[bx] = st;
        }
    }
}

/* As read_luma, a row at a time: sums of luminance per block, a block's
 * state 2 when a pixel in it is saturated (or NaN), else 1 when one is dark. */
void align_plane_add(align_plane *p, const void *strip, int code_bytes, int width, int y0, int y1,
                     double black_in, double saturation)
{
    float black = (float)fmax(black_in, DARK), sat = (float)(saturation - SAT_MARGIN);
    if (code_bytes == 1 && p->row) {
        add_rows_u8(p, strip, width, y0, y1, black, sat, p->row, p->row_flag);
        return;
    }
    float unit = code_bytes == 2 ? 1.0f / 65535 : 1;
    for (int y = y0; y < y1 && y / p->scale < p->h; y++) {
        if (!row_used(y, p->scale))
            continue;
        float *sum = p->v + (size_t)(y / p->scale) * p->w;
        uint8_t *state = p->state + (size_t)(y / p->scale) * p->w;
        size_t at = (size_t)(y - y0) * width * 3;
        for (int bx = 0; bx < p->w; bx++) {
            float acc = 0;
            uint8_t st = state[bx];
            for (int j = 0; j < p->scale; j++, at += 3) {
                float c[3];
                for (int k = 0; k < 3; k++)
                    c[k] = code_bytes ? (float)merge_code(strip, code_bytes, at + k) * unit
                                      : ((const float *)strip)[at + k];
                float lum = sl_luminancef(c);
                if (!(c[0] < sat && c[1] < sat && c[2] < sat))
                    st = 2;
                else if (lum <= black && !st)
                    st = 1;
                acc += lum;
            }
            sum[bx] += acc;
            state[bx] = st;
        }
    }
}

sl_result align_measure(align_plane *planes, int count, const char *const *paths,
                        const double *exposures, const sl_merge_options *opt, int width,
                        int height, sl_align_transform *out, sl_error *err)
{
    memset(out, 0, (size_t)count * sizeof *out);
    sl_result r = check_limits(paths, count, opt, err);
    luma *l = calloc((size_t)count, sizeof *l);
    if (!r && !l)
        r = sl_error_set(err, SL_ERR_NOMEM, "align: out of memory");
    for (int i = 0; i < count && !r; i++) {
        align_plane *p = &planes[i];
        float inv = 1.0f / (float)(p->scale * rows_used(p->scale));
        for (size_t k = 0; k < (size_t)p->w * p->h; k++)
            p->v[k] = p->state[k] == 2 ? SAT : p->state[k] == 1 ? BLACK : fminf(p->v[k] * inv, 1);
        /* The pyramid takes the plane over. */
        l[i].lv[0] = (plane){p->w, p->h, p->v};
        l[i].levels = 1;
        p->v = NULL;
        r = build_pyramid(&l[i], err);
    }
    if (!r)
        r = estimate(l, count, exposures, opt, planes[0].scale, width, height, QUICK, out, err);
    for (int i = 0; l && i < count; i++)
        luma_free(&l[i]);
    free(l);
    return r;
}
