/* SPDX-License-Identifier: BSD-3-Clause */
/* OpenEXR ZIP chunks compressed here rather than by zlib: after OpenEXR's
 * byte split and predictor, the low bytes of half and float samples are
 * nearly noise, which LZ77 match finding (zlib, libdeflate) spends most of
 * its time failing on. So: Huffman codes per 128 KB block, and runs of one
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
/* The predictor, the equal-byte scan and the block's loops built for AVX2
 * and BMI2 too (shifts by a register count in one instruction), used
 * where the processor has them: the same bytes either way. */
#if (defined(__x86_64__) || defined(__i386__)) && (defined(__clang__) || __GNUC__ >= 12)
#define HAVE_AVX2 1
#include <immintrin.h>
#endif

/* Inlined everywhere: the block's loops are built twice. */
#define INLINE static inline __attribute__((always_inline))

/* 128 KB: 8% fewer instructions than 64 KB (the codes are made half as
 * often) and 0.06% smaller on the unwrap bench; 256 KB, 3% fewer but
 * larger again. */
#define BLOCK (1 << 17)
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
INLINE int len_symbol(int len)
{
    int v = len - 3;
    if (v < 8)
        return v;
    if (len == 258)
        return 28;
    int e = 29 - __builtin_clz((unsigned)v);
    return 4 * e + (v >> e);
}

/* split_predict from pair j on (the vector loops' tail), and the first
 * byte of each half: the stream's first is stored as is, the odd half's
 * first follows the last even byte. */
static void predict_rest(const uint8_t *raw, size_t n, size_t j, uint8_t *d)
{
    size_t half = n / 2;
    for (; j < half; j++) {
        d[j] = (uint8_t)(raw[2 * j] - (j ? raw[2 * j - 2] : 0) + 128);
        d[half + j] = (uint8_t)(raw[2 * j + 1] - (j ? raw[2 * j - 1] : 0) + 128);
    }
    if (half) {
        d[0] = raw[0];
        d[half] = (uint8_t)(raw[1] - raw[n - 2] + 128);
    }
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
    predict_rest(raw, n, j, d);
}

#ifdef HAVE_AVX2
__attribute__((target("avx2"))) static void split_predict_avx2(const uint8_t *raw, size_t n,
                                                              uint8_t *d)
{
    size_t half = n / 2, j = 0;
    const __m256i low = _mm256_set1_epi16(0xff), bias = _mm256_set1_epi8((char)0x80);
    __m256i prev_e = _mm256_setzero_si256(), prev_o = _mm256_setzero_si256();
    for (; j + 32 <= half; j += 32) {
        __m256i a = _mm256_loadu_si256((const __m256i *)(raw + 2 * j));
        __m256i b = _mm256_loadu_si256((const __m256i *)(raw + 2 * j + 32));
        /* Packing works per 128-bit lane: the quarters back in order. */
        __m256i e = _mm256_permute4x64_epi64(
            _mm256_packus_epi16(_mm256_and_si256(a, low), _mm256_and_si256(b, low)), 0xd8);
        __m256i o = _mm256_permute4x64_epi64(
            _mm256_packus_epi16(_mm256_srli_epi16(a, 8), _mm256_srli_epi16(b, 8)), 0xd8);
        /* Each byte's predecessor: the vector one byte up, the last of the
         * previous vector first. */
        __m256i pe = _mm256_alignr_epi8(e, _mm256_permute2x128_si256(prev_e, e, 0x21), 15);
        __m256i po = _mm256_alignr_epi8(o, _mm256_permute2x128_si256(prev_o, o, 0x21), 15);
        _mm256_storeu_si256((__m256i *)(d + j), _mm256_add_epi8(_mm256_sub_epi8(e, pe), bias));
        _mm256_storeu_si256((__m256i *)(d + half + j),
                            _mm256_add_epi8(_mm256_sub_epi8(o, po), bias));
        prev_e = e;
        prev_o = o;
    }
    predict_rest(raw, n, j, d);
}
#endif

/* Bits into the stream, least significant first, fewer than 8 held back;
 * past the end of the buffer they are dropped (the chunk is then stored). */
typedef struct bits {
    uint8_t *out;
    size_t at, cap;
    uint64_t buf;
    size_t n;
} bits;

/* Eight bytes of v, least significant first. */
INLINE void store8(uint8_t *p, uint64_t v)
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
INLINE void drain_unchecked(bits *b)
{
    store8(b->out + b->at, b->buf);
    b->at += b->n >> 3;
    b->buf >>= b->n & 56;
    b->n &= 7;
}

/* The same where the buffer may run out. */
INLINE void drain(bits *b)
{
    if (b->cap - b->at >= 8) {
        drain_unchecked(b);
    } else {
        for (size_t i = 0; i < b->n / 8 && b->at + i < b->cap; i++)
            b->out[b->at + i] = (uint8_t)(b->buf >> (8 * i));
        size_t whole = b->n >> 3;
        b->at = b->cap - b->at > whole ? b->at + whole : b->cap;
        b->buf >>= b->n & 56;
        b->n &= 7;
    }
}

/* Bits added without draining: at most 64 may be held. */
INLINE void add(bits *b, uint32_t v, size_t n)
{
    b->buf |= (uint64_t)v << b->n;
    b->n += n;
}

/* Up to 32 bits. */
INLINE void put(bits *b, uint32_t v, size_t n)
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

/* t[0 .. m) sorted by weight, ties in the order they are in (by symbol):
 * insertion for a few, else a radix sort on the weight, a byte a pass
 * (qsort was most of the code lengths' time). */
static void sort_by_weight(node *t, int m)
{
    if (m <= 32) {
        for (int k = 1; k < m; k++) {
            node x = t[k];
            int j = k;
            for (; j > 0 && t[j - 1].weight > x.weight; j--)
                t[j] = t[j - 1];
            t[j] = x;
        }
        return;
    }
    node tmp[LIT_SYMS], *from = t, *to = tmp;
    uint32_t most = 0;
    for (int k = 0; k < m; k++)
        most |= t[k].weight;
    for (int shift = 0; shift < 32 && most >> shift; shift += 8) {
        int at[256] = {0};
        for (int k = 0; k < m; k++)
            at[from[k].weight >> shift & 255]++;
        for (int b = 0, sum = 0; b < 256; b++) {
            int c = at[b];
            at[b] = sum;
            sum += c;
        }
        for (int k = 0; k < m; k++)
            to[at[from[k].weight >> shift & 255]++] = from[k];
        node *x = from;
        from = to;
        to = x;
    }
    if (from != t)
        memcpy(t, from, sizeof *t * (size_t)m);
}

/* Huffman code lengths of at most `limit` bits for the symbols with a
 * frequency; at least two symbols get one, so that the code is complete.
 * Depths past the limit are cut to it and the code made whole again as
 * miniz does (a longest code dropped and a shorter one split, until the
 * Kraft sum is 1); the shortest codes go to the most frequent symbols. */
static void code_lengths(const uint32_t *freq, int count, int limit, uint8_t *len)
{
    node t[2 * LIT_SYMS];
    int used = 0, m = 0;
    for (int i = 0; i < count; i++)
        used += freq[i] > 0;
    for (int i = 0; i < count; i++) {
        uint32_t f = freq[i];
        if (!f && used < 2) {
            f = 1;
            used++;
        }
        if (f)
            t[m++] = (node){f, (int16_t)i, -1};
    }
    sort_by_weight(t, m);
    /* Two queues: leaves by weight, then internal nodes as made (their
     * weights never decrease). */
    int leaf = 0, inner = m, made = m;
    for (int k = 0; k < m - 1; k++) {
        int pick[2];
        for (int q = 0; q < 2; q++)
            pick[q] = leaf < m && (inner == made || t[leaf].weight <= t[inner].weight) ? leaf++
                                                                                       : inner++;
        t[made] = (node){t[pick[0]].weight + t[pick[1]].weight, -1, -1};
        t[pick[0]].parent = t[pick[1]].parent = (int16_t)made;
        made++;
    }
    /* Depths from the root (the last node made) down; leaves per depth. */
    uint8_t depth[2 * LIT_SYMS];
    int per_len[16] = {0};
    depth[made - 1] = 0;
    for (int k = made - 2; k >= 0; k--) {
        depth[k] = (uint8_t)(depth[t[k].parent] + 1);
        if (k < m)
            per_len[depth[k] < limit ? depth[k] : limit]++;
    }
    uint32_t kraft = 0;
    for (int b = 1; b <= limit; b++)
        kraft += (uint32_t)per_len[b] << (limit - b);
    for (; kraft > 1u << limit; kraft--) {
        per_len[limit]--;
        for (int b = limit - 1; b > 0; b--)
            if (per_len[b]) {
                per_len[b]--;
                per_len[b + 1] += 2;
                break;
            }
    }
    memset(len, 0, (size_t)count);
    for (int b = 1, k = m - 1; b <= limit; b++)
        for (int c = per_len[b]; c > 0; c--)
            len[t[k--].symbol] = (uint8_t)b;
}

/* Bytes with their bits in reverse order. */
#define R2(n) n, n + 128, n + 64, n + 192
#define R4(n) R2(n), R2(n + 32), R2(n + 16), R2(n + 48)
#define R6(n) R4(n), R4(n + 8), R4(n + 4), R4(n + 12)
static const uint8_t reversed[256] = {R6(0), R6(2), R6(1), R6(3)};
#undef R2
#undef R4
#undef R6

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
        uint32_t c = (uint32_t)next[len[i]]++;
        uint32_t r = (uint32_t)reversed[c & 255] << 8 | reversed[c >> 8];
        code[i] = (uint16_t)(r >> (16 - len[i]));
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

INLINE uint64_t load8(const uint8_t *p)
{
    uint64_t v;
    memcpy(&v, p, 8);
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_BIG_ENDIAN__
    v = __builtin_bswap64(v);
#endif
    return v;
}

#ifdef HAVE_AVX2
/* equal_next's first `words` words. */
__attribute__((target("avx2"))) static void equal_words_avx2(const uint8_t *d, size_t words,
                                                            uint64_t *eq)
{
    for (size_t w = 0; w < words; w++) {
        const uint8_t *p = d + 64 * w;
        __m256i a = _mm256_loadu_si256((const __m256i *)p);
        __m256i b = _mm256_loadu_si256((const __m256i *)(p + 1));
        __m256i c = _mm256_loadu_si256((const __m256i *)(p + 32));
        __m256i e = _mm256_loadu_si256((const __m256i *)(p + 33));
        eq[w] = (uint32_t)_mm256_movemask_epi8(_mm256_cmpeq_epi8(a, b)) |
                (uint64_t)(uint32_t)_mm256_movemask_epi8(_mm256_cmpeq_epi8(c, e)) << 32;
    }
}
#endif

/* Bit p of eq (64 to a word): d[p] == d[p + 1]; zero from bit n - 1 on,
 * and one more word of zeros. Then bit p of starts: d[p] is followed by
 * 3 copies of it, and one more word of zeros. */
INLINE void equal_next(const uint8_t *d, size_t n, uint64_t *eq, uint64_t *starts, bool wide)
{
    size_t words = (n + 63) / 64, w = 0;
#ifdef HAVE_AVX2
    if (wide) {
        w = n ? (n - 1) / 64 : 0; /* whole words with the byte after them */
        equal_words_avx2(d, w, eq);
    }
#else
    (void)wide;
#endif
#ifdef __SSE2__
    for (; (w + 1) * 64 < n; w++) {
        const uint8_t *p = d + 64 * w;
        uint64_t m = 0;
        for (int k = 0; k < 4; k++) {
            __m128i a = _mm_loadu_si128((const __m128i *)(p + 16 * k));
            __m128i b = _mm_loadu_si128((const __m128i *)(p + 16 * k + 1));
            m |= (uint64_t)(uint32_t)_mm_movemask_epi8(_mm_cmpeq_epi8(a, b)) << (16 * k);
        }
        eq[w] = m;
    }
#else
    /* Eight bytes at a time: a zero byte of x ^ y marks an equal pair. */
    const uint64_t low7 = 0x7f7f7f7f7f7f7f7full;
    for (; (w + 1) * 64 < n; w++) {
        uint64_t m = 0;
        for (int k = 0; k < 8; k++) {
            const uint8_t *p = d + 64 * w + 8 * k;
            uint64_t z = load8(p) ^ load8(p + 1);
            uint64_t zero = ~(((z & low7) + low7) | z | low7);
            m |= ((zero >> 7) * 0x0102040810204080ull) >> 56 << (8 * k);
        }
        eq[w] = m;
    }
#endif
    for (; w < words; w++) {
        uint64_t m = 0;
        for (size_t p = 64 * w; p < 64 * w + 64 && p + 1 < n; p++)
            m |= (uint64_t)(d[p] == d[p + 1]) << (p & 63);
        eq[w] = m;
    }
    eq[words] = 0;
    for (w = 0; w < words; w++) {
        uint64_t e = eq[w], next = eq[w + 1];
        starts[w] = e & (e >> 1 | next << 63) & (e >> 2 | next << 62);
    }
    starts[words] = 0;
}

/* How many copies of d[p] follow it. */
INLINE size_t copies(const uint64_t *eq, size_t p)
{
    size_t w = p >> 6;
    uint64_t y = ~eq[w] >> (p & 63);
    if (y)
        return (size_t)__builtin_ctzll(y);
    size_t k = 64 - (p & 63);
    while (!~eq[++w])
        k += 64;
    return k + (size_t)__builtin_ctzll(~eq[w]);
}

/* Counts of the bytes d[0 .. n): four tables, so that repeated bytes do
 * not wait on one counter. */
INLINE void count_bytes(const uint8_t *d, size_t n, uint32_t (*lit)[256])
{
    size_t i = 0;
    for (; i + 8 <= n; i += 8) {
        lit[0][d[i]]++;
        lit[1][d[i + 1]]++;
        lit[2][d[i + 2]]++;
        lit[3][d[i + 3]]++;
        lit[0][d[i + 4]]++;
        lit[1][d[i + 5]]++;
        lit[2][d[i + 6]]++;
        lit[3][d[i + 7]]++;
    }
    /* The last up to 7 (most segments between runs are short). */
    switch (n - i) {
    case 7:
        lit[2][d[i + 6]]++;
        __attribute__((fallthrough));
    case 6:
        lit[1][d[i + 5]]++;
        __attribute__((fallthrough));
    case 5:
        lit[0][d[i + 4]]++;
        __attribute__((fallthrough));
    case 4:
        lit[3][d[i + 3]]++;
        __attribute__((fallthrough));
    case 3:
        lit[2][d[i + 2]]++;
        __attribute__((fallthrough));
    case 2:
        lit[1][d[i + 1]]++;
        __attribute__((fallthrough));
    case 1:
        lit[0][d[i]]++;
        break;
    default:
        break;
    }
}

/* The runs of d[0 .. n) into runs (start << 9 | length), counted into
 * freq with the literals between them; returns how many. A run is 3 to
 * 258 copies of the byte before: a match at distance 1. Literals go up to
 * the first byte followed by 3 copies of it; those copies are runs (a
 * leftover one or two, literals). */
INLINE size_t tokenize(const uint8_t *d, size_t n, const uint64_t *eq, const uint64_t *starts,
                       uint32_t *runs, uint32_t *freq)
{
    uint32_t lit[4][256], per_len[MAX_RUN + 1];
    memset(lit, 0, sizeof lit);
    memset(per_len, 0, sizeof per_len);
    size_t words = (n + 63) / 64, nr = 0, i = 0;
    for (;;) {
        size_t w = i >> 6;
        uint64_t x = starts[w] & ~0ull << (i & 63);
        while (!x && ++w < words)
            x = starts[w];
        if (!x)
            break;
        size_t p = 64 * w + (size_t)__builtin_ctzll(x), left = copies(eq, p);
        count_bytes(d + i, p + 1 - i, lit);
        for (i = p + 1; left > MAX_RUN; i += MAX_RUN, left -= MAX_RUN) {
            runs[nr++] = (uint32_t)(i << 9 | MAX_RUN);
            per_len[MAX_RUN]++;
        }
        if (left >= MIN_RUN) {
            runs[nr++] = (uint32_t)(i << 9 | left);
            per_len[left]++;
            i += left;
        }
    }
    count_bytes(d + i, n - i, lit);
    for (int k = 0; k < 256; k++)
        freq[k] = lit[0][k] + lit[1][k] + lit[2][k] + lit[3][k];
    for (int run = MIN_RUN; run <= MAX_RUN; run++)
        freq[257 + len_symbol(run)] += per_len[run];
    return nr;
}

/* Two literals' codes in one: the first byte in the low 8 bits of the
 * index. */
struct pair_codes {
    uint32_t code[1 << 16];
    uint8_t len[1 << 16];
};

#ifdef HAVE_AVX2
__attribute__((target("avx2"))) static void pair_codes_avx2(const uint32_t *code,
                                                           const uint8_t *len, pair_codes *pc)
{
    /* Eight first symbols at a time against every second one. */
    for (int a = 0; a < 256; a += 8) {
        __m256i first = _mm256_loadu_si256((const __m256i *)(code + a));
        __m256i shift = _mm256_cvtepu8_epi32(_mm_loadl_epi64((const __m128i *)(len + a)));
        for (int b = 0; b < 256; b += 2) {
            __m256i s0 = _mm256_set1_epi32((int)code[b]), s1 = _mm256_set1_epi32((int)code[b + 1]);
            _mm256_storeu_si256((__m256i *)(pc->code + 256 * b + a),
                                _mm256_or_si256(first, _mm256_sllv_epi32(s0, shift)));
            _mm256_storeu_si256((__m256i *)(pc->code + 256 * (b + 1) + a),
                                _mm256_or_si256(first, _mm256_sllv_epi32(s1, shift)));
        }
    }
    for (int b = 0; b < 256; b++) {
        __m256i second = _mm256_set1_epi8((char)len[b]);
        for (int a = 0; a < 256; a += 32)
            _mm256_storeu_si256(
                (__m256i *)(pc->len + 256 * b + a),
                _mm256_add_epi8(_mm256_loadu_si256((const __m256i *)(len + a)), second));
    }
}
#endif

INLINE void drain_if(bits *b, bool room)
{
    if (room)
        drain_unchecked(b);
    else
        drain(b);
}

/* Literals d[i .. end), four (at most 56 bits) per drain; up to two are
 * left held, with room for a run (at most 20 bits) before the next drain.
 * `room`: the buffer holds the worst case, no checks needed. */
INLINE void put_literals(bits *w, const uint8_t *d, size_t i, size_t end, const uint32_t *code,
                         const uint8_t *len, const pair_codes *pc, bool room)
{
    /* Pairs read as 16-bit words: only where pair codes are made (x86,
     * little-endian). */
    for (; pc && i + 8 <= end; i += 8) {
        uint16_t p[4];
        memcpy(&p[0], d + i, 2);
        memcpy(&p[1], d + i + 2, 2);
        memcpy(&p[2], d + i + 4, 2);
        memcpy(&p[3], d + i + 6, 2);
        add(w, pc->code[p[0]], pc->len[p[0]]);
        add(w, pc->code[p[1]], pc->len[p[1]]);
        drain_if(w, room);
        add(w, pc->code[p[2]], pc->len[p[2]]);
        add(w, pc->code[p[3]], pc->len[p[3]]);
        drain_if(w, room);
    }
    for (; i + 4 <= end; i += 4) {
        if (pc) {
            uint16_t p[2];
            memcpy(&p[0], d + i, 2);
            memcpy(&p[1], d + i + 2, 2);
            add(w, pc->code[p[0]], pc->len[p[0]]);
            add(w, pc->code[p[1]], pc->len[p[1]]);
        } else {
            add(w, code[d[i]], len[d[i]]);
            add(w, code[d[i + 1]], len[d[i + 1]]);
            add(w, code[d[i + 2]], len[d[i + 2]]);
            add(w, code[d[i + 3]], len[d[i + 3]]);
        }
        drain_if(w, room);
    }
    if (i < end) {
        add(w, code[d[i]], len[d[i]]);
        if (i + 1 < end) {
            add(w, code[d[i + 1]], len[d[i + 1]]);
            if (i + 2 < end) {
                add(w, code[d[i + 2]], len[d[i + 2]]);
                drain_if(w, room);
            }
        }
    }
}

/* The block's literals and runs, then the end of block. */
INLINE void put_tokens(bits *w, const uint8_t *d, size_t n, const uint32_t *runs, size_t nr,
                       const uint32_t *bits_of, const uint8_t *len_of, const pair_codes *pc,
                       bool room)
{
    size_t i = 0;
    for (size_t k = 0; k < nr; k++) {
        size_t at = runs[k] >> 9, run = runs[k] & 511;
        /* Mostly one or two literals before a run: held with it. */
        if (at - i <= 2) {
            if (at > i)
                add(w, bits_of[d[i]], len_of[d[i]]);
            if (at > i + 1)
                add(w, bits_of[d[i + 1]], len_of[d[i + 1]]);
        } else {
            put_literals(w, d, i, at, bits_of, len_of, pc, room);
        }
        add(w, bits_of[256 + run], len_of[256 + run]);
        drain_if(w, room);
        i = at + run;
    }
    put_literals(w, d, i, n, bits_of, len_of, pc, room);
    put(w, bits_of[256], len_of[256]);
}

/* A block's header (final bit, codes) from its symbol counts, and its
 * tokens' bits: the literals and the end of block as they are, a run of r
 * bytes at 256 + r (its length code, its extra bits and the distance code
 * 0, distance 1: at most 20 bits). Codes are at most 14 bits (not 15:
 * 0.003% larger on the unwrap bench), so that 4 literals fit one drain
 * (which leaves up to 7 bits held). Returns how many bits the tokens
 * take. */
static uint64_t block_codes(bits *b, const uint32_t *freq, bool last, uint32_t *bits_of,
                            uint8_t *len_of)
{
    uint8_t lens[LIT_SYMS + 2];
    uint16_t code[LIT_SYMS];
    code_lengths(freq, LIT_SYMS, 14, lens);
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
    uint64_t total = 0;
    for (int t = 0; t < 257; t++) {
        bits_of[t] = code[t];
        len_of[t] = lens[t];
        total += (uint64_t)freq[t] * lens[t];
    }
    for (int sy = 0; sy < 29; sy++)
        total += (uint64_t)freq[257 + sy] * (lens[257 + sy] + len_extra[sy] + 1u);
    for (int run = MIN_RUN; run <= MAX_RUN; run++) {
        int sy = len_symbol(run), l = lens[257 + sy];
        bits_of[256 + run] = code[257 + sy] | (uint32_t)(run - len_base[sy]) << l;
        len_of[256 + run] = (uint8_t)(l + len_extra[sy] + 1);
    }
    return total;
}

/* d[0 .. n) as one dynamic-Huffman block: literals, and runs of the
 * previous byte as matches at distance 1. */
INLINE void block(bits *b, const uint8_t *d, size_t n, exr_zip_scratch *s, bool last, bool wide)
{
    uint32_t freq[LIT_SYMS] = {0};
    uint64_t *eq = s->equal, *starts = s->equal + BLOCK / 64 + 1;
    equal_next(d, n, eq, starts, wide);
    size_t nr = tokenize(d, n, eq, starts, s->runs, freq);
    freq[256] = 1;
    uint32_t bits_of[256 + MAX_RUN + 1];
    uint8_t len_of[256 + MAX_RUN + 1];
    uint64_t size = block_codes(b, freq, last, bits_of, len_of);
    pair_codes *pc = NULL;
#ifdef HAVE_AVX2
    /* Literals in pairs where there are enough of them to pay for the
     * table (65536 codes made in about 50000 instructions, 4 saved per
     * literal). */
    size_t lits = 0;
    for (int k = 0; k < 256; k++)
        lits += freq[k];
    if (wide && lits >= 1 << 14 && (s->pairs || (s->pairs = malloc(sizeof *s->pairs)))) {
        pc = s->pairs;
        pair_codes_avx2(bits_of, len_of, pc);
    }
#endif
    bits w = *b; /* in registers: the stores could alias it otherwise */
    /* Room for the block's bits, the held ones and a drain's 8-byte store. */
    bool room = w.cap - w.at >= size / 8 + 16;
    if (pc && room)
        put_tokens(&w, d, n, s->runs, nr, bits_of, len_of, pc, true);
    else if (pc)
        put_tokens(&w, d, n, s->runs, nr, bits_of, len_of, pc, false);
    else if (room)
        put_tokens(&w, d, n, s->runs, nr, bits_of, len_of, NULL, true);
    else
        put_tokens(&w, d, n, s->runs, nr, bits_of, len_of, NULL, false);
    *b = w;
}

static void write_block(bits *b, const uint8_t *d, size_t n, exr_zip_scratch *s, bool last)
{
    block(b, d, n, s, last, false);
}

#ifdef HAVE_AVX2
__attribute__((target("avx2,bmi,bmi2"))) static void write_block_avx2(bits *b, const uint8_t *d,
                                                                    size_t n, exr_zip_scratch *s,
                                                                    bool last)
{
    block(b, d, n, s, last, true);
}
#endif

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
    if (!s->equal && !(s->equal = malloc(sizeof(uint64_t) * 2 * (BLOCK / 64 + 1))))
        return false;
    if (!s->runs && !(s->runs = malloc(sizeof(uint32_t) * (BLOCK / MIN_RUN + 1))))
        return false;
    uint8_t *d = s->bytes;
#ifdef HAVE_AVX2
    bool avx2 =
        !s->portable && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("bmi2");
    if (avx2)
        split_predict_avx2(raw, n, d);
    else
#endif
        split_predict(raw, n, d);
    bits b = {out, 0, n, 0, 0};
    put(&b, 0x78, 8); /* zlib header: deflate, 32 KB window, check bits */
    put(&b, 0x01, 8);
    /* Blocks never straddle the halves: their statistics differ. */
    size_t half = n / 2;
    for (size_t at = 0; at < n;) {
        size_t end = at < half ? half : n;
        size_t len = end - at < BLOCK ? end - at : BLOCK;
#ifdef HAVE_AVX2
        if (avx2)
            write_block_avx2(&b, d + at, len, s, at + len == n);
        else
#endif
            write_block(&b, d + at, len, s, at + len == n);
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
    free(s->equal);
    free(s->runs);
    free(s->pairs);
    memset(s, 0, sizeof *s);
}
