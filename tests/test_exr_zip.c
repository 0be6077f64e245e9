/* SPDX-License-Identifier: BSD-3-Clause */
/* core's own OpenEXR ZIP encoder (core/exr_zip.c) on chunks made to reach
 * each of its paths: runs of every length up to past two maximal matches
 * with 0 to 9 literals between them, noise in blocks with and without the
 * pair codes, several blocks per half, codes deeper than the 14-bit limit,
 * incompressible chunks (stored), and chunks of a few bytes. Each stream is
 * inflated by libdeflate and must give back the split and predicted bytes
 * exactly; the loops built for AVX2 and the portable ones must give the
 * same stream. */
#include <libdeflate.h>
#include <stdlib.h>
#include <string.h>

#include "../core/exr_zip.h"
#include "testing.h"

static uint32_t seed = 2024;

static uint32_t next_random(void)
{
    seed = seed * 1664525u + 1013904223u;
    return seed >> 8;
}

/* The raw chunk whose split and prediction (what the encoder codes) is d:
 * OpenEXR's predictor undone over the split bytes, then interleaved. */
static void unpredict(const uint8_t *d, size_t n, uint8_t *raw)
{
    size_t half = n / 2;
    uint8_t t = 0;
    for (size_t i = 0; i < n; i++) {
        t = i ? (uint8_t)(t + d[i] - 128) : d[0];
        raw[i < half ? 2 * i : 2 * (i - half) + 1] = t;
    }
}

/* d through the encoder, portable and (where the processor has it) AVX2:
 * the same stream, which inflates to d; or both stored. Returns the
 * stream's size (0: stored). */
static size_t check_chunk(const char *what, const uint8_t *d, size_t n)
{
    uint8_t *raw = malloc(n), *out[2] = {malloc(n), malloc(n)}, *back = malloc(n);
    size_t size[2] = {0, 0};
    CHECK(raw && out[0] && out[1] && back);
    if (!raw || !out[0] || !out[1] || !back) {
        free(raw);
        free(out[0]);
        free(out[1]);
        free(back);
        return 0;
    }
    unpredict(d, n, raw);
    for (int k = 0; k < 2; k++) {
        exr_zip_scratch s;
        memset(&s, 0, sizeof s);
        s.portable = k == 0;
        CHECK_MSG(exr_zip_chunk(raw, n, &s, out[k], &size[k]), "%s: out of memory", what);
        exr_zip_free(&s);
    }
    CHECK_MSG(size[0] == size[1] && memcmp(out[0], out[1], size[0]) == 0,
              "%s: portable and AVX2 streams differ (%zu, %zu bytes)", what, size[0], size[1]);
    if (size[0]) {
        size_t got = 0;
        struct libdeflate_decompressor *z = libdeflate_alloc_decompressor();
        enum libdeflate_result r = libdeflate_zlib_decompress(z, out[0], size[0], back, n, &got);
        libdeflate_free_decompressor(z);
        CHECK_MSG(r == LIBDEFLATE_SUCCESS && got == n && memcmp(back, d, n) == 0,
                  "%s: the %zu-byte stream does not inflate to the %zu bytes (result %d, %zu)",
                  what, size[0], n, (int)r, got);
    }
    free(raw);
    free(out[0]);
    free(out[1]);
    free(back);
    return size[0];
}

/* Runs of 1 to 600 copies (matches of 3 to 258, chained past 258 with one
 * or two copies left over as literals) after 0 to 9 noise literals, in
 * both halves; the stream is far smaller than the chunk. */
static void test_runs(void)
{
    size_t n = 400000, at = 0;
    uint8_t *d = calloc(n, 1);
    CHECK(d);
    if (!d)
        return;
    for (size_t len = 1; at < n; len = len % 600 + 1) {
        for (size_t k = len % 10; k > 0 && at < n; k--)
            d[at++] = (uint8_t)next_random();
        uint8_t v = (uint8_t)(at ? d[at - 1] + 1 + len % 7 : 7);
        for (size_t k = 0; k <= len && at < n; k++)
            d[at++] = v;
    }
    size_t size = check_chunk("runs", d, n);
    CHECK_MSG(size > 0 && size < n / 10, "runs: %zu bytes for %zu", size, n);
    free(d);
}

/* Noise around 128 (a predicted smooth image's low bytes): many literals
 * per block, so two to a code, three blocks per half and an odd tail; then
 * the same with a run every few hundred bytes. */
static void test_noise(void)
{
    size_t n = 2 * (2 * 131072 + 12345);
    uint8_t *d = malloc(n);
    CHECK(d);
    if (!d)
        return;
    for (int runs = 0; runs < 2; runs++) {
        for (size_t i = 0; i < n; i++) {
            uint32_t r = next_random();
            d[i] = (uint8_t)(128 + (int)(r & 15) - (int)(r >> 4 & 15) + (int)(r >> 8 & 3) -
                             (int)(r >> 10 & 3));
        }
        for (size_t i = 300; runs && i + 20 < n; i += 300 + next_random() % 200)
            memset(d + i, d[i - 1], 3 + next_random() % 17);
        size_t size = check_chunk(runs ? "noise with runs" : "noise", d, n);
        CHECK_MSG(size > n / 2 && size < n * 3 / 4, "noise: %zu bytes for %zu", size, n);
    }
    free(d);
}

/* Symbol counts 1, 2, 3, 5 .. 2584 (Fibonacci, the end of block's 1
 * before them): the Huffman tree is 17 deep, past the 14-bit limit; no
 * byte follows itself, so no runs. */
static void test_deep_code(void)
{
    enum { SYMS = 17 };
    uint32_t left[SYMS];
    size_t total = 0;
    for (int k = 0; k < SYMS; k++) {
        left[k] = k < 2 ? (uint32_t)k + 1 : left[k - 1] + left[k - 2];
        total += left[k];
    }
    size_t n = 2 * total, at = 0;
    uint8_t *d = malloc(n);
    CHECK(d);
    if (!d)
        return;
    /* The most frequent symbol left that is not the last one written. */
    for (int last = -1; at < total; at++) {
        int pick = -1;
        for (int k = 0; k < SYMS; k++)
            if (left[k] && k != last && (pick < 0 || left[k] > left[pick]))
                pick = k;
        if (pick < 0)
            break;
        left[pick]--;
        d[at] = (uint8_t)(40 + 9 * pick);
        last = pick;
    }
    CHECK_MSG(at == total, "deep code: %zu of %zu symbols placed", at, total);
    memset(d + total, 128, total);
    check_chunk("deep code", d, n);
    free(d);
}

/* Uniform noise does not compress: the chunk is stored (size 0), the
 * encoder having run past the end of its buffer. */
static void test_incompressible(void)
{
    size_t n = 2 * 140000;
    uint8_t *d = malloc(n);
    CHECK(d);
    if (!d)
        return;
    for (size_t i = 0; i < n; i++)
        d[i] = (uint8_t)next_random();
    CHECK_MSG(check_chunk("uniform noise", d, n) == 0, "uniform noise was not stored");
    free(d);
}

/* Chunks of 2 to 300 bytes (word and vector tails): zeros, one value,
 * noise; the smallest are stored (a stream needs 6 bytes of header and
 * checksum), the runs take a block header of about 16 bytes a half. */
static void test_small(void)
{
    uint8_t d[300];
    for (size_t n = 2; n <= sizeof d; n += n < 70 ? 2 : 38) {
        for (int kind = 0; kind < 3; kind++) {
            for (size_t i = 0; i < n; i++)
                d[i] = kind == 0 ? 128 : kind == 1 ? 77 : (uint8_t)next_random();
            char what[64];
            snprintf(what, sizeof what, "%zu bytes, kind %d", n, kind);
            size_t size = check_chunk(what, d, n);
            if (kind < 2 && n >= 64)
                CHECK_MSG(size > 0 && size < 40, "%s: %zu bytes", what, size);
        }
    }
}

int main(void)
{
    RUN(test_runs);
    RUN(test_noise);
    RUN(test_deep_code);
    RUN(test_incompressible);
    RUN(test_small);
    return sl_test_finish();
}
