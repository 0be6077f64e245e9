/* SPDX-License-Identifier: BSD-3-Clause */
/* OpenEXR ZIP chunks compressed by core itself (exr_zip.c). */
#ifndef SETLIGHT_CORE_EXR_ZIP_H
#define SETLIGHT_CORE_EXR_ZIP_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef struct pair_codes pair_codes;

/* One thread's buffers, kept from chunk to chunk; start zeroed. */
typedef struct exr_zip_scratch {
    uint8_t *bytes; /* the chunk split and predicted */
    size_t bytes_cap;
    uint64_t *equal;   /* one block's "byte equals the next" bits, then run starts */
    uint32_t *runs;    /* one block's runs: start << 9 | length */
    pair_codes *pairs; /* codes of two literals at once */
    bool portable;     /* set: not the loops built for AVX2 (tests compare the two) */
} exr_zip_scratch;

/* The n raw bytes of a chunk (per line, per channel in file order, samples
 * little-endian; n even: samples are 2 or 4 bytes) as OpenEXR's ZIP stores
 * them: bytes split and delta-predicted, then a zlib stream, written to out
 * (n bytes). *size is the stream's length, or 0 when it would not be
 * shorter than n (OpenEXR then stores the chunk as it is). False when out
 * of memory. */
bool exr_zip_chunk(const uint8_t *raw, size_t n, exr_zip_scratch *s, uint8_t *out, size_t *size);
void exr_zip_free(exr_zip_scratch *s);

#endif
