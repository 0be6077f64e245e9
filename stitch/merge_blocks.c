/* SPDX-License-Identifier: BSD-3-Clause */
/* JPEG blocks spoilt by a saturated pixel. A JPEG codes 8x8 blocks of
 * luma and, with subsampled chroma, 16x16 (4:2:0) or 16x8 (4:2:2) blocks
 * of colour (the MCU), aligned to the image origin. A clipped light's
 * DCT ringing and its colour, averaged into the block's chroma, spread
 * over the block's other pixels, whose codes then stop being a function
 * of their exposure. */
#include <math.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#include "merge_private.h"

/* A block overexposed by more than this factor (linear, over the saturation
 * code's value) is spoilt. */
#define SPOIL_EXCESS 2.0

/* The brightest code of each block: the block row's rows folded into one
 * by an elementwise maximum over contiguous samples (vectorised), then each
 * block's samples of that row (the per-pixel loop with its divisions cost
 * as much as decoding the JPEG). The largest code maps to the largest
 * value, so the result is the same as scaling every code first. */
enum { FOLD = 1536 }; /* samples: a multiple of 3 * bw for every JPEG MCU width (8 to 32) */

static void fold_u8(uint8_t *fold, const uint8_t *q, size_t n)
{
    size_t j = 0;
#ifdef __SSE2__
    for (; j + 16 <= n; j += 16)
        _mm_storeu_si128((__m128i *)(fold + j),
                         _mm_max_epu8(_mm_loadu_si128((const __m128i *)(fold + j)),
                                      _mm_loadu_si128((const __m128i *)(q + j))));
#endif
    for (; j < n; j++)
        fold[j] = q[j] > fold[j] ? q[j] : fold[j];
}

static void fold_u16(uint16_t *fold, const uint16_t *q, size_t n)
{
    for (size_t j = 0; j < n; j++)
        fold[j] = q[j] > fold[j] ? q[j] : fold[j];
}

#define BLOCK_MAX_CODES(T, FOLD_ROW)                                                                       \
    {                                                                                              \
        T fold[FOLD];                                                                              \
        int group = FOLD / (3 * bw);                                                               \
        for (int by = 0; by < nby; by++) {                                                         \
            int y0 = by * bh, y1 = y0 + bh < rows ? y0 + bh : rows;                                \
            for (int bx0 = 0; bx0 < nbx; bx0 += group) {                                           \
                int bx1 = bx0 + group < nbx ? bx0 + group : nbx;                                   \
                size_t s0 = (size_t)bx0 * bw * 3;                                                  \
                size_t s1 = (size_t)(bx1 * bw < width ? bx1 * bw : width) * 3, n = s1 - s0;        \
                const T *q = (const T *)buf + (size_t)y0 * width * 3 + s0;                         \
                memcpy(fold, q, n * sizeof *fold);                                                 \
                for (int y = y0 + 1; y < y1; y++)                                                  \
                    FOLD_ROW(fold, q += (size_t)width * 3, n);                                     \
                for (int bx = bx0; bx < bx1; bx++) {                                               \
                    size_t j0 = (size_t)(bx - bx0) * bw * 3, j1 = j0 + (size_t)bw * 3;             \
                    unsigned k = 0;                                                                \
                    for (size_t j = j0; j < j1 && j < n; j++)                                      \
                        k = fold[j] > k ? fold[j] : k;                                             \
                    out[(size_t)by * nbx + bx] = (float)k * scale;                                 \
                }                                                                                  \
            }                                                                                      \
        }                                                                                          \
    }

void merge_block_max(const void *buf, int code_bytes, double top, int width, int rows, int bw,
                     int bh, float *out)
{
    int nbx = (width + bw - 1) / bw, nby = (rows + bh - 1) / bh;
    float scale = code_bytes ? (float)(1 / top) : 1.0f;
    if (code_bytes == 1) {
        BLOCK_MAX_CODES(uint8_t, fold_u8)
        return;
    }
    if (code_bytes == 2) {
        BLOCK_MAX_CODES(uint16_t, fold_u16)
        return;
    }
    memset(out, 0, (size_t)nbx * nby * sizeof *out);
    for (int y = 0; y < rows; y++) {
        float *row = out + (size_t)(y / bh) * nbx;
        size_t at = (size_t)y * width * 3;
        for (int x = 0; x < width; x++, at += 3) {
            const float *f = (const float *)buf + at;
            float v = fmaxf(f[0], fmaxf(f[1], f[2]));
            if (v > row[x / bw])
                row[x / bw] = v;
        }
    }
}

/* The brightest code of frame i's block holding pixel pos. */
static float block_at(const merge_ctx *m, int i, int64_t pos)
{
    int bw = m->block[2 * i], bh = m->block[2 * i + 1];
    int x = (int)(pos % m->width), y = (int)(pos / m->width);
    return m->block_max[i][(size_t)(y / bh) * ((m->width + bw - 1) / bw) + x / bw];
}

void merge_block_codes(const merge_ctx *m, int r, int64_t pos, float codes[2])
{
    int i = m->order[r], s = r > 0 ? m->order[r - 1] : -1;
    codes[0] = m->block_max[i] ? block_at(m, i, pos) : -1;
    codes[1] = s >= 0 && m->block_max[s] ? block_at(m, s, pos) : -1;
}

/* The linear value of the saturation code, the brightest of the channels. */
static double saturation_value(const merge_ctx *m, const sl_response *resp)
{
    double ysat = 0;
    for (int c = 0; c < 3; c++)
        ysat = fmax(ysat, merge_response_at(resp, c, m->saturation));
    return ysat;
}

static inline bool spoilt_codes(const merge_ctx *m, const sl_response *resp, const double *loge,
                                int r, const float codes[2], double ysat)
{
    if (codes[0] < 0 || codes[0] < m->saturation)
        return false;
    if (codes[1] < 0)
        return true;
    float z = codes[1];
    if (z >= m->saturation)
        return true;
    double y = 0;
    for (int c = 0; c < 3; c++)
        y = fmax(y, merge_response_at(resp, c, z));
    return y * exp(loge[r] - loge[r - 1]) > SPOIL_EXCESS * ysat;
}

bool merge_block_spoilt_codes(const merge_ctx *m, const sl_response *resp, const double *loge,
                              int r, const float codes[2])
{
    return spoilt_codes(m, resp, loge, r, codes, saturation_value(m, resp));
}

void merge_block_spoilt_all(const merge_ctx *m, const sl_response *resp, const double *loge,
                            const float *codes, uint8_t *spoilt)
{
    double ysat = saturation_value(m, resp);
    int f = m->samples.frames;
    for (size_t e = 0; e < (size_t)m->samples.count * (size_t)f; e++)
        spoilt[e] = spoilt_codes(m, resp, loge, (int)(e % (size_t)f), codes + 2 * e, ysat);
}

bool merge_block_spoilt(const merge_ctx *m, const sl_response *resp, const double *loge, int r,
                        int64_t pos)
{
    float codes[2];
    merge_block_codes(m, r, pos, codes);
    return merge_block_spoilt_codes(m, resp, loge, r, codes);
}
