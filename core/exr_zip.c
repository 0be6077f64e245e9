/* SPDX-License-Identifier: BSD-3-Clause */
/* OpenEXR ZIP chunks compressed here rather than by zlib: after OpenEXR's
 * byte split and predictor, the low bytes of half and float samples are
 * nearly noise, which LZ77 match finding (zlib, libdeflate) spends most of
 * its time failing on. So: Huffman codes per 64 KB block, and runs of one
 * byte as matches at distance 1 (smooth and black areas). Any inflater
 * reads it (RFC 1950/1951); the split halves get blocks, and so codes, of
 * their own. */
#include "exr_zip.h"

#include <libdeflate.h>
#include <stdlib.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#define BLOCK (1 << 16)
#define LIT_SYMS 286 /* literals, end of block, 29 lengths */
#define MIN_RUN 3
#define MAX_RUN 258

/* Deflate's length codes: first length and extra bits of symbols 257.. */
static const uint16_t len_base[29] = {3,  4,  5,  6,  7,  8,   9,   10,  11,  13,
                                      15, 17, 19, 23, 27, 31,  35,  43,  51,  59,
                                      67, 83, 99, 115, 131, 163, 195, 227, 258};
static const uint8_t len_extra[29] = {0, 0, 0, 0, 0, 0, 0, 0, 1, 1, 1, 1, 2, 2, 2,
                                      2, 3, 3, 3, 3, 4, 4, 4, 4, 5, 5, 5, 5, 0};

/* The length symbol (0..28, i.e. 257..285 less 257) of a run of len bytes:
 * past the first eight, four symbols per extra bit. */
static inline int len_symbol(int len)
{
    int v = len - 3;
    if (v < 8)
        return v;
    if (len == 258)
        return 28;
    int e = 29 - __builtin_clz((unsigned)v);
    return 4 * e + (v >> e);
}

/* The bytes as OpenEXR's ZIP predicts them: even bytes, then odd bytes,
 * each stored as its difference to the one before, plus 128. */
static void split_predict(const uint8_t *raw, size_t n, uint8_t *d)
{
    size_t half = n / 2, j = 0;
#ifdef __SSE2__
    const __m128i low = _mm_set1_epi16(0xff), bias = _mm_set1_epi8((char)0x80);
    __m128i prev_e = _mm_setzero_si128(), prev_o = _mm_setzero_si128();
    for (; j + 16 <= half; j += 16) {
        __m128i a = _mm_loadu_si128((const __m128i *)(raw + 2 * j));
        __m128i b = _mm_loadu_si128((const __m128i *)(raw + 2 * j + 16));
        __m128i e = _mm_packus_epi16(_mm_and_si128(a, low), _mm_and_si128(b, low));
        __m128i o = _mm_packus_epi16(_mm_srli_epi16(a, 8), _mm_srli_epi16(b, 8));
        __m128i pe = _mm_or_si128(_mm_slli_si128(e, 1), _mm_srli_si128(prev_e, 15));
        __m128i po = _mm_or_si128(_mm_slli_si128(o, 1), _mm_srli_si128(prev_o, 15));
        _mm_storeu_si128((__m128i *)(d + j), _mm_add_epi8(_mm_sub_epi8(e, pe), bias));
        _mm_storeu_si128((__m128i *)(d + half + j), _mm_add_epi8(_mm_sub_epi8(o, po), bias));
        prev_e = e;
        prev_o = o;
    }
#endif
    for (; j < half; j++) {
        d[j] = (uint8_t)(raw[2 * j] - (j ? raw[2 * j - 2] : 0) + 128);
        d[half + j] = (uint8_t)(raw[2 * j + 1] - (j ? raw[2 * j - 1] : 0) + 128);
    }
    /* The first byte of each half: the stream's first is stored as is, the
     * odd half's first follows the last even byte. */
    if (half) {
        d[0] = raw[0];
        d[half] = (uint8_t)(raw[1] - raw[n - 2] + 128);
    }
}

/* Bits into the stream, least significant first, fewer than 8 held back;
 * past the end of the buffer they are dropped (the chunk is then stored). */
typedef struct bits {
    uint8_t *out;
    size_t at, cap;
    uint64_t buf;
    int n;
} bits;

/* Eight bytes of v, least significant first. */
static inline void store8(uint8_t *p, uint64_t v)
{
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
    memcpy(p, &v, 8);
#else
    for (int i = 0; i < 8; i++)
        p[i] = (uint8_t)(v >> (8 * i));
#endif
}

/* Whole bytes out at once, 8 stored (the spare ones are overwritten
 * later); leaves fewer than 8 bits held. The caller made sure of room. */
static inline void drain_unchecked(bits *b)
{
    store8(b->out + b->at, b->buf);
    b->at += (size_t)(b->n >> 3);
    b->buf >>= b->n & ~7;
    b->n &= 7;
}

/* The same where the buffer may run out. */
static inline void drain(bits *b)
{
    if (b->cap - b->at >= 8) {
        drain_unchecked(b);
    } else {
        for (int i = 0; i < b->n / 8 && b->at + (size_t)i < b->cap; i++)
            b->out[b->at + i] = (uint8_t)(b->buf >> (8 * i));
        size_t whole = (size_t)(b->n >> 3);
        b->at = b->cap - b->at > whole ? b->at + whole : b->cap;
        b->buf >>= b->n & ~7;
        b->n &= 7;
    }
}

/* Bits added without draining: at most 56 may be held. */
static inline void add(bits *b, uint32_t v, int n)
{
    b->buf |= (uint64_t)v << b->n;
    b->n += n;
}

/* Up to 32 bits. */
static inline void put(bits *b, uint32_t v, int n)
{
    add(b, v, n);
    drain(b);
}

static void flush(bits *b)
{
    if (b->n)
        put(b, 0, 8 - b->n);
}

typedef struct node {
    uint32_t weight;
    int16_t symbol; /* -1 for an internal node */
    int16_t parent;
} node;

static int by_weight(const void *a, const void *b)
{
    const node *x = a, *y = b;
    if (x->weight != y->weight)
        return x->weight < y->weight ? -1 : 1;
    return x->symbol - y->symbol;
}

/* Huffman code lengths of at most `limit` bits for the symbols with a
 * frequency (frequencies halved until the code fits: rare); at least two
 * symbols get one, so that the code is complete. */
static void code_lengths(const uint32_t *freq, int count, int limit, uint8_t *len)
{
    uint32_t f[LIT_SYMS];
    node t[2 * LIT_SYMS];
    int used = 0;
    for (int i = 0; i < count; i++)
        used += (f[i] = freq[i]) > 0;
    for (int i = 0; used < 2; i++)
        if (!f[i]) {
            f[i] = 1;
            used++;
        }
    for (;;) {
        int m = 0;
        for (int i = 0; i < count; i++)
            if (f[i])
                t[m++] = (node){f[i], (int16_t)i, -1};
        qsort(t, (size_t)m, sizeof *t, by_weight);
        /* Two queues: leaves by weight, then internal nodes as made (their
         * weights never decrease). */
        int leaf = 0, inner = m, made = m;
        for (int k = 0; k < m - 1; k++) {
            int pick[2];
            for (int q = 0; q < 2; q++)
                pick[q] = leaf < m && (inner == made || t[leaf].weight <= t[inner].weight)
                              ? leaf++
                              : inner++;
            t[made] = (node){t[pick[0]].weight + t[pick[1]].weight, -1, -1};
            t[pick[0]].parent = t[pick[1]].parent = (int16_t)made;
            made++;
        }
        /* Depths from the root (the last node made) down. */
        uint8_t depth[2 * LIT_SYMS];
        depth[made - 1] = 0;
        int deepest = 0;
        for (int k = made - 2; k >= 0; k--) {
            depth[k] = (uint8_t)(depth[t[k].parent] + 1);
            deepest = depth[k] > deepest ? depth[k] : deepest;
        }
        if (deepest <= limit) {
            memset(len, 0, (size_t)count);
            for (int k = 0; k < m; k++)
                len[t[k].symbol] = depth[k];
            return;
        }
        for (int i = 0; i < count; i++)
            f[i] = f[i] ? (f[i] + 1) / 2 : 0;
    }
}

/* Canonical codes (RFC 1951 3.2.2), bit-reversed: deflate sends them
 * most significant bit first into a least-significant-first stream. */
static void canonical_codes(const uint8_t *len, int count, uint16_t *code)
{
    int per_len[16] = {0}, next[16] = {0};
    for (int i = 0; i < count; i++)
        per_len[len[i]]++;
    per_len[0] = 0;
    for (int b = 1, c = 0; b < 16; b++) {
        c = (c + per_len[b - 1]) << 1;
        next[b] = c;
    }
    for (int i = 0; i < count; i++) {
        if (!len[i])
            continue;
        uint32_t c = (uint32_t)next[len[i]]++, r = 0;
        for (int b = 0; b < len[i]; b++, c >>= 1)
            r = (r << 1) | (c & 1);
        code[i] = (uint16_t)r;
    }
}

/* The block's code lengths as code-length symbols (0..15 as is, 16 repeat
 * the last 3-6 times, 17 3-10 zeros, 18 11-138 zeros) with their extra
 * values; returns how many. */
static int length_symbols(const uint8_t *lens, int count, uint8_t *sym, uint8_t *extra)
{
    int k = 0;
    for (int i = 0; i < count;) {
        int v = lens[i], run = 1;
        while (i + run < count && lens[i + run] == v)
            run++;
        i += run;
        if (v == 0) {
            for (; run >= 11; run -= run < 138 ? run : 138) {
                sym[k] = 18;
                extra[k++] = (uint8_t)((run < 138 ? run : 138) - 11);
            }
            if (run >= 3) {
                sym[k] = 17;
                extra[k++] = (uint8_t)(run - 3);
                run = 0;
            }
        } else {
            sym[k] = (uint8_t)v;
            extra[k++] = 0;
            for (run--; run >= 3; run -= run < 6 ? run : 6) {
                sym[k] = 16;
                extra[k++] = (uint8_t)((run < 6 ? run : 6) - 3);
            }
        }
        for (; run > 0; run--) {
            sym[k] = (uint8_t)v;
            extra[k++] = 0;
        }
    }
    return k;
}

/* Literals and runs of d[0 .. n) into tok (a run of r bytes as 256 + r),
 * counted into freq. A run is a byte followed by 3 or more copies of it:
 * a match at distance 1. */
static size_t tokenize(const uint8_t *d, size_t n, uint16_t *tok, uint32_t *freq)
{
    /* Literal counts in four tables: repeated bytes do not wait on one counter. */
    uint32_t lit[4][256];
    memset(lit, 0, sizeof lit);
    size_t nt = 0, i = 0;
    while (i < n) {
        /* Literals up to the next byte a run follows (up to 16 at once);
         * tok has room for 16 more than a block. */
        int lits = 1;
#ifdef __SSE2__
        if (n - i >= 19) {
            __m128i a = _mm_loadu_si128((const __m128i *)(d + i));
            __m128i b = _mm_loadu_si128((const __m128i *)(d + i + 1));
            __m128i c = _mm_loadu_si128((const __m128i *)(d + i + 2));
            __m128i e = _mm_loadu_si128((const __m128i *)(d + i + 3));
            __m128i run = _mm_and_si128(_mm_and_si128(_mm_cmpeq_epi8(a, b), _mm_cmpeq_epi8(b, c)),
                                        _mm_cmpeq_epi8(c, e));
            int starts = _mm_movemask_epi8(run);
            lits = starts ? __builtin_ctz((unsigned)starts) + 1 : 16;
            __m128i z = _mm_setzero_si128();
            _mm_storeu_si128((__m128i *)(tok + nt), _mm_unpacklo_epi8(a, z));
            _mm_storeu_si128((__m128i *)(tok + nt + 8), _mm_unpackhi_epi8(a, z));
        } else
#endif
            tok[nt] = d[i];
        if (lits == 16) {
            for (int k = 0; k < 16; k += 4) {
                lit[0][d[i + (size_t)k]]++;
                lit[1][d[i + (size_t)k + 1]]++;
                lit[2][d[i + (size_t)k + 2]]++;
                lit[3][d[i + (size_t)k + 3]]++;
            }
        } else {
            for (int k = 0; k < lits; k++)
                lit[k & 3][d[i + (size_t)k]]++;
        }
        nt += (size_t)lits;
        i += (size_t)lits;
        uint8_t v = d[i - 1];
        while (n - i >= MIN_RUN && d[i] == v && d[i + 1] == v && d[i + 2] == v) {
            size_t run = MIN_RUN, most = n - i < MAX_RUN ? n - i : MAX_RUN;
#ifdef __SSE2__
            for (__m128i vv = _mm_set1_epi8((char)v); run + 16 <= most; run += 16) {
                int same = _mm_movemask_epi8(
                    _mm_cmpeq_epi8(_mm_loadu_si128((const __m128i *)(d + i + run)), vv));
                if (same != 0xffff) {
                    run += (size_t)__builtin_ctz(~(unsigned)same);
                    break;
                }
            }
#endif
            while (run < most && d[i + run] == v)
                run++;
            tok[nt++] = (uint16_t)(256 + run);
            freq[257 + len_symbol((int)run)]++;
            i += run;
        }
    }
    for (int k = 0; k < 256; k++)
        freq[k] = lit[0][k] + lit[1][k] + lit[2][k] + lit[3][k];
    return nt;
}

/* The tokens' bits, two tokens (at most 42 bits) per drain; `room`: the
 * buffer holds the worst case (21 bits a token), no checks needed. */
static inline __attribute__((always_inline)) void put_tokens(bits *w, const uint16_t *tok,
                                                             size_t nt, const uint32_t *bits_of,
                                                             const uint8_t *len_of, bool room)
{
    size_t i = 0;
    for (; i + 2 <= nt; i += 2) {
        add(w, bits_of[tok[i]], len_of[tok[i]]);
        add(w, bits_of[tok[i + 1]], len_of[tok[i + 1]]);
        if (room)
            drain_unchecked(w);
        else
            drain(w);
    }
    for (; i < nt; i++)
        put(w, bits_of[tok[i]], len_of[tok[i]]);
}

/* d[0 .. n) as one dynamic-Huffman block: literals, and runs of the
 * previous byte as matches at distance 1. */
static void write_block(bits *b, const uint8_t *d, size_t n, uint16_t *tok, bool last)
{
    uint32_t freq[LIT_SYMS] = {0};
    size_t nt = tokenize(d, n, tok, freq);
    freq[256] = 1;
    uint8_t lens[LIT_SYMS + 2];
    uint16_t code[LIT_SYMS];
    code_lengths(freq, LIT_SYMS, 15, lens);
    canonical_codes(lens, LIT_SYMS, code);
    int hlit = LIT_SYMS;
    while (hlit > 257 && !lens[hlit - 1])
        hlit--;
    /* Two distance codes of one bit (only distance 1 is used; a complete
     * code is what every inflater accepts). */
    lens[hlit] = lens[hlit + 1] = 1;
    uint8_t sym[LIT_SYMS + 2], extra[LIT_SYMS + 2], cl_len[19];
    uint16_t cl_code[19];
    int ns = length_symbols(lens, hlit + 2, sym, extra);
    uint32_t cl_freq[19] = {0};
    for (int i = 0; i < ns; i++)
        cl_freq[sym[i]]++;
    code_lengths(cl_freq, 19, 7, cl_len);
    canonical_codes(cl_len, 19, cl_code);
    static const uint8_t order[19] = {16, 17, 18, 0, 8,  7, 9,  6, 10, 5,
                                      11, 4,  12, 3, 13, 2, 14, 1, 15};
    int hclen = 19;
    while (hclen > 4 && !cl_len[order[hclen - 1]])
        hclen--;
    put(b, last ? 1u : 0u, 1);
    put(b, 2, 2);
    put(b, (uint32_t)(hlit - 257), 5);
    put(b, 1, 5);
    put(b, (uint32_t)(hclen - 4), 4);
    for (int i = 0; i < hclen; i++)
        put(b, cl_len[order[i]], 3);
    static const uint8_t extra_bits[3] = {2, 3, 7};
    for (int i = 0; i < ns; i++) {
        put(b, cl_code[sym[i]], cl_len[sym[i]]);
        if (sym[i] >= 16)
            put(b, extra[i], extra_bits[sym[i] - 16]);
    }
    /* Every token's bits in one table: a run's length code, its extra
     * bits and the distance code (0: distance 1), at most 21 bits. */
    uint32_t bits_of[256 + MAX_RUN + 1];
    uint8_t len_of[256 + MAX_RUN + 1];
    for (int t = 0; t < 256; t++) {
        bits_of[t] = code[t];
        len_of[t] = lens[t];
    }
    for (int run = MIN_RUN; run <= MAX_RUN; run++) {
        int s = len_symbol(run), l = lens[257 + s];
        bits_of[256 + run] = code[257 + s] | (uint32_t)(run - len_base[s]) << l;
        len_of[256 + run] = (uint8_t)(l + len_extra[s] + 1);
    }
    bits w = *b; /* in registers: the stores could alias it otherwise */
    if (w.cap - w.at >= nt / 8 * 21 + 32)
        put_tokens(&w, tok, nt, bits_of, len_of, true);
    else
        put_tokens(&w, tok, nt, bits_of, len_of, false);
    put(&w, code[256], lens[256]);
    *b = w;
}

bool exr_zip_chunk(const uint8_t *raw, size_t n, exr_zip_scratch *s, uint8_t *out, size_t *size)
{
    *size = 0;
    if (n > s->bytes_cap) {
        uint8_t *p = realloc(s->bytes, n);
        if (!p)
            return false;
        s->bytes = p;
        s->bytes_cap = n;
    }
    if (!s->tokens && !(s->tokens = malloc(sizeof(uint16_t) * (BLOCK + 16))))
        return false;
    uint8_t *d = s->bytes;
    split_predict(raw, n, d);
    bits b = {out, 0, n, 0, 0};
    put(&b, 0x78, 8); /* zlib header: deflate, 32 KB window, check bits */
    put(&b, 0x01, 8);
    /* Blocks never straddle the halves: their statistics differ. */
    size_t half = n / 2;
    for (size_t at = 0; at < n;) {
        size_t end = at < half ? half : n;
        size_t len = end - at < BLOCK ? end - at : BLOCK;
        write_block(&b, d + at, len, s->tokens, at + len == n);
        at += len;
        if (b.at == b.cap)
            return true; /* not shorter: stored */
    }
    flush(&b);
    uint32_t adler = libdeflate_adler32(1, d, n);
    for (int i = 3; i >= 0; i--)
        put(&b, (adler >> (8 * i)) & 0xffu, 8);
    flush(&b);
    if (b.at < b.cap)
        *size = b.at;
    return true;
}

void exr_zip_free(exr_zip_scratch *s)
{
    free(s->bytes);
    free(s->tokens);
    memset(s, 0, sizeof *s);
}
