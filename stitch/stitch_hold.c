/* SPDX-License-Identifier: BSD-3-Clause */
/* How the stitch holds a view between reading it and blending it: its
 * float radiance scanned for NaN/Inf, its peak and whether every sample is
 * a half value, then kept as half (0.14 GB for 24 MP instead of 0.29;
 * converted in the float view's own memory): as it is when every sample is
 * a half value (what merge writes), else divided by a power of two that
 * puts its peak at half's top and rounded; and a copy reduced by a whole
 * factor for the solve. */
#include "stitch_blend_private.h"

#define IMATH_HALF_NO_LOOKUP_TABLE /* Imath's conversions alone, without libImath */
#include <Imath/half.h>
#include <immintrin.h>
#if defined(__x86_64__) && defined(__GNUC__)
#include <cpuid.h>
#endif
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define SCAN_ROWS 64

typedef struct scan_job {
    const sl_image *img;
    int64_t *bad;   /* per chunk */
    float *peak;    /* per chunk */
    float *mag;     /* per chunk: the largest |RGB sample| */
    bool *inexact;  /* per chunk: an RGB sample that is not a half value */
    bool f16c;
} scan_job;

/* Eight samples of a row scanned at once where the CPU has F16C: their
 * non-finite count, peak, largest magnitude and whether each is a half
 * value (the same answers as the loop of scan_rows). */
#if (defined(__x86_64__) || defined(__i386__)) && !defined(__clang__) && __GNUC__ >= 12
#define HAVE_F16C_ROWS 1
__attribute__((target("f16c,avx"))) static int scan_f16c(const float *src, int n, int64_t *bad,
                                                         float *peak, float *mag, bool *inexact)
{
    const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
    const __m256 big = _mm256_set1_ps(3.40282347e38f);
    __m256 top = _mm256_set1_ps(*peak), top_abs = _mm256_set1_ps(*mag);
    int i = 0, nonfinite = 0;
    bool off = false;
    for (; i + 8 <= n; i += 8) {
        __m256 v = _mm256_loadu_ps(src + i), a = _mm256_and_ps(v, abs_mask);
        __m256 finite = _mm256_cmp_ps(a, big, _CMP_LE_OQ);
        nonfinite += 8 - __builtin_popcount((unsigned)_mm256_movemask_ps(finite));
        top = _mm256_max_ps(top, _mm256_and_ps(finite, v)); /* a NaN lane counts 0 */
        top_abs = _mm256_max_ps(top_abs, _mm256_and_ps(finite, a));
        __m256 back = _mm256_cvtph_ps(_mm256_cvtps_ph(v, _MM_FROUND_TO_NEAREST_INT));
        off |= _mm256_movemask_ps(_mm256_cmp_ps(back, v, _CMP_NEQ_UQ)) != 0;
    }
    float t[8], ta[8];
    _mm256_storeu_ps(t, top);
    _mm256_storeu_ps(ta, top_abs);
    for (int k = 0; k < 8; k++) {
        *peak = t[k] > *peak ? t[k] : *peak;
        *mag = ta[k] > *mag ? ta[k] : *mag;
    }
    *bad += nonfinite;
    *inexact |= off;
    return i;
}
#endif

static void scan_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    scan_job *j = ctx;
    const sl_image *img = j->img;
    const float *table = stitch_half_table();
    int64_t bad = 0;
    float peak = 0.0f, mag = 0.0f;
    bool inexact = false;
    for (int64_t y = begin; y < end; y++) {
        const float *row = sl_image_pixel(img, 0, (int)y);
        int done = 0;
#ifdef HAVE_F16C_ROWS
        if (img->channels == 3 && j->f16c) /* whole pixels: 8 of them a step of 3 */
            done = scan_f16c(row, 3 * img->width / 24 * 24, &bad, &peak, &mag, &inexact) / 3;
#endif
        for (int x = done; x < img->width; x++)
            for (int c = 0; c < img->channels; c++) {
                float v = row[x * img->channels + c];
                bool finite = isfinite(v);
                bad += !finite;
                if (finite && c < 3 && v > peak)
                    peak = v;
                if (finite && c < 3 && fabsf(v) > mag)
                    mag = fabsf(v);
                if (c < 3)
                    inexact |= !finite || table[imath_float_to_half(v)] != v;
            }
    }
    j->bad[begin / SCAN_ROWS] = bad;
    j->peak[begin / SCAN_ROWS] = peak;
    j->mag[begin / SCAN_ROWS] = mag;
    j->inexact[begin / SCAN_ROWS] = inexact;
}

bool stitch_cpu_f16c(void)
{
#if defined(__x86_64__) && defined(__GNUC__)
    /* cpuid for F16C: clang's __builtin_cpu_supports does not know it; AVX
     * (which the OS must enable for these VEX instructions) it does */
    unsigned a, b, c, d;
    return __builtin_cpu_supports("avx") && __get_cpuid(1, &a, &b, &c, &d) && (c & bit_F16C);
#else
    return false;
#endif
}

/* Whether the F16C row loops built here (GCC 12 and later) can run. */
static bool cpu_f16c(void)
{
#ifdef HAVE_F16C_ROWS
    return stitch_cpu_f16c();
#else
    return false;
#endif
}

sl_result stitch_view_scan(const sl_image *img, int64_t *bad, double *peak, double *magnitude,
                           bool *half_exact, sl_error *err)
{
    int64_t chunks = (img->height + SCAN_ROWS - 1) / SCAN_ROWS;
    scan_job j = {img, calloc((size_t)chunks, sizeof(int64_t)),
                  calloc((size_t)chunks, sizeof(float)), calloc((size_t)chunks, sizeof(float)),
                  calloc((size_t)chunks, sizeof(bool)), cpu_f16c()};
    if (!j.bad || !j.peak || !j.mag || !j.inexact) {
        free(j.bad), free(j.peak), free(j.mag), free(j.inexact);
        return sl_error_set(err, SL_ERR_NOMEM, "stitch: out of memory");
    }
    sl_parallel_for(img->height, SCAN_ROWS, scan_rows, &j);
    *bad = 0;
    *peak = *magnitude = 0.0;
    *half_exact = img->channels >= 3;
    for (int64_t i = 0; i < chunks; i++) {
        *bad += j.bad[i];
        *peak = fmax(*peak, j.peak[i]);
        *magnitude = fmax(*magnitude, j.mag[i]);
        *half_exact &= !j.inexact[i];
    }
    free(j.bad), free(j.peak), free(j.mag), free(j.inexact);
    return SL_OK;
}

bool stitch_half_exponent(double magnitude, int *exp2)
{
    *exp2 = 0;
    if (!(magnitude <= 1e30))
        return false;
    if (!(magnitude > 0.0))
        return true; /* black: any scale */
    int e;
    frexp(magnitude, &e); /* magnitude = m 2^e, m in [0.5, 1): 2^(e - 16) puts it in [32768, 65536) */
    *exp2 = e - 16;
    if (ldexp(magnitude, -*exp2) > 65504.0)
        (*exp2)++;
    return true;
}

typedef struct half_scan_job {
    const stitch_half_image *img;
    int64_t *bad;     /* per chunk */
    uint16_t *top;    /* per chunk: the largest finite positive sample's bits */
} half_scan_job;

/* A positive finite half's bits order as its value: the peak is the
 * largest pattern under 0x7c00 (Inf); the exponent all ones is Inf or NaN. */
static void half_scan_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    half_scan_job *j = ctx;
    size_t n = (size_t)(end - begin) * j->img->width * 3;
    const uint16_t *p = j->img->rgb + (size_t)begin * j->img->width * 3;
    int64_t bad = 0;
    uint16_t top = 0;
    size_t i = 0;
#ifdef __SSE2__
    /* Eight at a time: as int16 a negative half is below 0, a positive
     * finite one its value's order; Inf and NaN are zeroed for the max. */
    const __m128i exp_mask = _mm_set1_epi16(0x7c00);
    __m128i top8 = _mm_setzero_si128();
    for (; i + 8 <= n; i += 8) {
        __m128i v = _mm_loadu_si128((const __m128i *)(p + i));
        __m128i odd = _mm_cmpeq_epi16(_mm_and_si128(v, exp_mask), exp_mask);
        unsigned mask = (unsigned)_mm_movemask_epi8(odd);
        if (mask) /* rare: no library call for the count otherwise */
            bad += __builtin_popcount(mask) / 2;
        top8 = _mm_max_epi16(top8, _mm_andnot_si128(odd, v));
    }
    uint16_t t[8];
    _mm_storeu_si128((__m128i *)t, top8);
    for (int k = 0; k < 8; k++)
        top = t[k] > top ? t[k] : top;
#endif
    for (; i < n; i++) {
        uint16_t h = p[i];
        bad += (h & 0x7c00u) == 0x7c00u;
        top = h < 0x7c00u && h > top ? h : top;
    }
    j->bad[begin / SCAN_ROWS] = bad;
    j->top[begin / SCAN_ROWS] = top;
}

sl_result stitch_half_scan(const stitch_half_image *img, int64_t *bad, double *peak,
                           sl_error *err)
{
    int64_t chunks = (img->height + SCAN_ROWS - 1) / SCAN_ROWS;
    half_scan_job j = {img, calloc((size_t)chunks, sizeof(int64_t)),
                       calloc((size_t)chunks, sizeof(uint16_t))};
    if (!j.bad || !j.top) {
        free(j.bad), free(j.top);
        return sl_error_set(err, SL_ERR_NOMEM, "stitch: out of memory");
    }
    sl_parallel_for(img->height, SCAN_ROWS, half_scan_rows, &j);
    uint16_t top = 0;
    *bad = 0;
    for (int64_t i = 0; i < chunks; i++) {
        *bad += j.bad[i];
        top = j.top[i] > top ? j.top[i] : top;
    }
    *peak = stitch_half_table()[top];
    free(j.bad), free(j.top);
    return SL_OK;
}

sl_result stitch_half_to_float(stitch_half_image *h, sl_image *img, sl_error *err)
{
    sl_result r = sl_image_alloc(img, h->width, h->height, 3, err);
    if (r)
        return r;
    const float *table = stitch_half_table();
    const float scale = ldexpf(1.0f, h->exp2); /* a power of two: the product exact */
    for (int y = 0; y < h->height; y++) {
        const uint16_t *src = h->rgb + (size_t)y * h->width * 3;
        float *dst = sl_image_pixel(img, 0, y);
        for (int i = 0; i < 3 * h->width; i++)
            dst[i] = table[src[i]] * scale;
    }
    stitch_half_free(h);
    return SL_OK;
}

typedef struct half_job {
    const sl_image *img;
    stitch_half_image *out;
    const float *table;
    bool *inexact; /* per row */
    bool f16c;
} half_job;

/* Eight floats to half and back in one instruction each, where the CPU
 * has F16C; the tail and other CPUs through Imath's conversion. (gcc
 * only, as core/exr.c's rows: clang 14's __builtin_cpu_supports does not
 * know "f16c", and the fuzz build is clang.) */
#ifdef HAVE_F16C_ROWS
__attribute__((target("f16c,avx"))) static int row_f16c(const float *src, uint16_t *dst, int n,
                                                        bool *inexact)
{
    int i = 0;
    for (; i + 8 <= n; i += 8) {
        __m256 v = _mm256_loadu_ps(src + i);
        __m128i h = _mm256_cvtps_ph(v, _MM_FROUND_TO_NEAREST_INT);
        _mm_storeu_si128((__m128i *)(dst + i), h);
        __m256 back = _mm256_cvtph_ps(h);
        /* ordered equal: a NaN never comes here (scanned before) */
        if (_mm256_movemask_ps(_mm256_cmp_ps(back, v, _CMP_NEQ_UQ)))
            *inexact = true;
    }
    return i;
}
#endif

static void half_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    half_job *j = ctx;
    const sl_image *img = j->img;
    int w = img->width, ch = img->channels;
    for (int64_t y = begin; y < end; y++) {
        const float *row = sl_image_pixel(img, 0, (int)y);
        uint16_t *dst = j->out->rgb + (size_t)y * w * 3;
        bool inexact = false;
        int done = 0;
#ifdef HAVE_F16C_ROWS
        if (ch == 3 && j->f16c)
            done = row_f16c(row, dst, 3 * w, &inexact);
#endif
        for (int k = done; k < 3 * w; k++) {
            float v = row[(k / 3) * ch + k % 3];
            dst[k] = imath_float_to_half(v);
            inexact |= j->table[dst[k]] != v;
        }
        j->inexact[y] = inexact;
    }
}

bool stitch_view_to_half(const sl_image *img, stitch_half_image *out, sl_error *err)
{
    memset(out, 0, sizeof *out);
    if (img->channels < 3)
        return false;
    out->width = img->width;
    out->height = img->height;
    out->rgb = malloc((size_t)img->width * img->height * 3 * sizeof(uint16_t));
    bool *inexact = calloc((size_t)img->height, sizeof(bool));
    if (out->rgb) /* the blend's lookups follow curves through it */
        sl_advise_huge_pages(out->rgb, (size_t)img->width * img->height * 3 * sizeof(uint16_t));
    if (!out->rgb || !inexact) {
        free(out->rgb), free(inexact);
        memset(out, 0, sizeof *out);
        (void)err;
        return false; /* the float view is kept: right, only larger */
    }
    half_job j = {img, out, stitch_half_table(), inexact, cpu_f16c()};
    sl_parallel_for(img->height, 16, half_rows, &j);
    bool exact = true;
    for (int y = 0; y < img->height; y++)
        exact &= !inexact[y];
    free(inexact);
    if (!exact) {
        free(out->rgb);
        memset(out, 0, sizeof *out);
    }
    return exact;
}

/* Halves under 2^-14 (exponent bits 0) whose float was not 0: below
 * half's normal range, and of them those that became 0. */
static void count_loss(const uint16_t *h, const float *src, int n, int channels,
                       stitch_half_loss *loss)
{
    for (int k = 0; k < n; k++)
        if (!(h[k] & 0x7c00u) && src[(k / 3) * channels + k % 3] != 0.0f) {
            loss->below_normal++;
            loss->flushed += !(h[k] & 0x7fffu);
        }
}

bool stitch_view_take_half(sl_image *img, int exp2, stitch_half_image *out,
                           stitch_half_loss *loss)
{
    memset(out, 0, sizeof *out);
    if (loss)
        memset(loss, 0, sizeof *loss);
    int w = img->width, h = img->height;
    size_t row_halves = (size_t)w * 3;
    uint16_t *row = malloc(row_halves * sizeof *row);
    float *scaled = exp2 ? malloc(row_halves * sizeof *scaled) : NULL;
    if (!row || (exp2 && !scaled) || img->channels < 3) {
        free(row), free(scaled);
        return false;
    }
    uint16_t *dst = (uint16_t *)img->data;
    const float inv = ldexpf(1.0f, -exp2); /* a power of two: the division exact */
#ifdef HAVE_F16C_ROWS
    bool f16c = cpu_f16c(), inexact = false; /* the flag is not read */
#endif
    /* Row by row in order, each through `row`: half row y ends at or
     * before the start of float row (y + 1) / 2, so it only overwrites
     * rows already read. */
    for (int y = 0; y < h; y++) {
        const float *src = sl_image_pixel(img, 0, y);
        int ch = img->channels;
        if (scaled) { /* RGB only, divided by 2^exp2 */
            for (size_t k = 0; k < row_halves; k++)
                scaled[k] = src[(k / 3) * ch + k % 3] * inv;
            src = scaled;
            ch = 3;
        }
        int done = 0;
#ifdef HAVE_F16C_ROWS
        if (ch == 3 && f16c)
            done = row_f16c(src, row, 3 * w, &inexact);
#endif
        for (int k = done; k < 3 * w; k++)
            row[k] = imath_float_to_half(src[(k / 3) * ch + k % 3]);
        if (loss)
            count_loss(row, src, 3 * w, ch, loss);
        memcpy(dst + (size_t)y * row_halves, row, row_halves * sizeof *row);
    }
    free(row);
    free(scaled);
    /* the float tail goes back to the system (a large block shrinks in place) */
    uint16_t *kept = realloc(dst, (size_t)h * row_halves * sizeof *kept);
    out->rgb = kept ? kept : dst;
    out->width = w;
    out->height = h;
    out->exp2 = exp2;
    memset(img, 0, sizeof *img);
    return true;
}

void stitch_half_free(stitch_half_image *h)
{
    free(h->rgb);
    memset(h, 0, sizeof *h);
}

int stitch_solve_factor(int width, int height, int max_width)
{
    if (width <= max_width)
        return 1;
    /* 2 or 4: the lens scales there and back without rounding */
    for (int k = 2; k <= 4; k *= 2)
        if (width / k <= max_width && width % k == 0 && height % k == 0)
            return k;
    return 1;
}

/* A half row as floats: four at a time through F16C where the processor
 * has it, else, and for the tail, through the table. */
static void half_row_to_float(const uint16_t *src, size_t n, const float *table, bool f16c,
                              float *out)
{
    size_t i = 0;
#ifdef STITCH_HAVE_F16C_ASM
    for (; f16c && i + 4 <= n; i += 4)
        _mm_storeu_ps(out + i, stitch_halves_to_floats(src + i));
#else
    (void)f16c;
#endif
    for (; i < n; i++)
        out[i] = table[src[i]];
}

typedef struct reduce_job {
    const sl_image *src;          /* or, not NULL, half: */
    const stitch_half_image *half;
    sl_image *dst;
    int k;
    float *mid; /* per worker: k rows of the x pass */
    float *row; /* per worker: two half source rows as float */
    bool f16c;  /* half rows converted through F16C */
} reduce_job;

/* sl_image_resample's box taps for a factor k of 2 or 4, both passes per
 * output row (the k rows of the x pass in the worker's scratch): the same
 * operations in the same order (double sums of 1/k times each sample, each
 * pass rounded to float), the same bytes, without its full-height
 * intermediate image (0.14 GB of fresh pages for a 24 MP view). */
static void reduce_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    const reduce_job *j = ctx;
    const int k = j->k, ch = j->dst->channels, w = j->dst->width;
    const size_t n = (size_t)w * ch;
    const double tap = 1.0 / k; /* exact: the taps' (hi - lo) / scale */
    float *mid = j->mid + (size_t)worker * k * n;
    const float *table = j->half ? stitch_half_table() : NULL;
    for (int64_t y = begin; y < end; y++) {
        for (int t = 0; t < k; t++) {
            const float *in;
            if (j->half) { /* the float view's row, exactly */
                size_t m = (size_t)j->half->width * 3;
                const uint16_t *src = j->half->rgb + ((size_t)y * k + t) * m;
                float *row = j->row + (size_t)worker * m;
                half_row_to_float(src, m, table, j->f16c, row);
                in = row;
            } else {
                in = sl_image_pixel(j->src, 0, (int)y * k + t);
            }
            float *m = mid + (size_t)t * n;
            for (int x = 0; x < w; x++)
                for (int c = 0; c < ch; c++) {
                    double acc = 0.0;
                    for (int i = 0; i < k; i++)
                        acc += tap * in[((size_t)x * k + i) * ch + c];
                    m[(size_t)x * ch + c] = (float)acc;
                }
        }
        float *out = sl_image_pixel(j->dst, 0, (int)y);
        for (size_t i = 0; i < n; i++) {
            double acc = 0.0;
            for (int t = 0; t < k; t++)
                acc += tap * mid[(size_t)t * n + i];
            out[i] = (float)acc;
        }
    }
}

/* reduce_rows() for k = 2 of a half view, in float: 0.5 a + 0.5 b of two
 * half values is what the double sums give before their rounding to float
 * (the products exact, and a float addition rounds the exact sum once,
 * where the double one is exact or lands on the same float): the same
 * bytes, both passes at once. */
static void reduce_half_rows_2(void *ctx, int64_t begin, int64_t end, int worker)
{
    const reduce_job *j = ctx;
    const int w = j->dst->width;
    const size_t m = (size_t)j->half->width * 3;
    const float *table = stitch_half_table();
    float *r0 = j->row + (size_t)worker * 2 * m, *r1 = r0 + m;
    for (int64_t y = begin; y < end; y++) {
        const uint16_t *src = j->half->rgb + (size_t)y * 2 * m;
        half_row_to_float(src, m, table, j->f16c, r0);
        half_row_to_float(src + m, m, table, j->f16c, r1);
        float *out = sl_image_pixel(j->dst, 0, (int)y);
        for (int x = 0; x < w; x++)
            for (int c = 0; c < 3; c++) {
                float top = 0.5f * r0[6 * x + c] + 0.5f * r0[6 * x + 3 + c];
                float bottom = 0.5f * r1[6 * x + c] + 0.5f * r1[6 * x + 3 + c];
                out[3 * x + c] = 0.5f * top + 0.5f * bottom;
            }
    }
}

static sl_result reduce(const sl_image *src, const stitch_half_image *half, int k, sl_image *dst,
                        sl_error *err)
{
    int w = half ? half->width : src->width, h = half ? half->height : src->height;
    int ch = half ? 3 : src->channels;
    sl_result r = sl_image_alloc(dst, w / k, h / k, ch, err);
    if (r)
        return r;
    /* written in order, read by the solve's reduction and a few patches */
    sl_advise_small_pages(dst->data, dst->stride * (size_t)dst->height * sizeof(float));
    int workers = sl_threads_get();
    reduce_job j = {src, half, dst, k,
                    malloc((size_t)workers * k * dst->width * ch * sizeof(float)),
                    half ? malloc((size_t)workers * 2 * w * 3 * sizeof(float)) : NULL,
                    stitch_cpu_f16c() && !stitch_rays_portable_only};
    if (!j.mid || (half && !j.row)) {
        free(j.mid), free(j.row);
        sl_image_free(dst);
        return sl_error_set(err, SL_ERR_NOMEM, "stitch: out of memory");
    }
    sl_parallel_for(dst->height, 16, half && k == 2 ? reduce_half_rows_2 : reduce_rows, &j);
    free(j.mid), free(j.row);
    return SL_OK;
}

sl_result stitch_reduce(const sl_image *src, int k, sl_image *dst, sl_error *err)
{
    if ((k != 2 && k != 4) || src->width % k || src->height % k)
        return sl_image_resample(src, src->width / k, src->height / k, dst, err);
    return reduce(src, NULL, k, dst, err);
}

sl_result stitch_reduce_half(const stitch_half_image *src, int k, sl_image *dst, sl_error *err)
{
    if ((k != 2 && k != 4) || src->width % k || src->height % k)
        return sl_error_set(err, SL_ERR_INTERNAL, "stitch: a half view reduced by %d", k);
    return reduce(NULL, src, k, dst, err);
}

void stitch_lens_scale(sl_lens *lens, double s, int width, int height)
{
    lens->width = width;
    lens->height = height;
    lens->focal_px *= s;
    lens->cx *= s;
    lens->cy *= s;
    lens->circle_radius_px *= s;
}
