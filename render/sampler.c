/* SPDX-License-Identifier: BSD-3-Clause */
/* Sample sequences: Owen-scrambled 2D Sobol with hash-based scrambling and
 * index shuffling per dimension pair (B. Burley, "Practical Hash-based Owen
 * Scrambling", JCGT 9(4), 2020), and PCG32 for independent random numbers. */
#include <pthread.h>

#include "sampler.h"

uint64_t sl_hash64(uint64_t x)
{
    /* splitmix64 finaliser */
    x += 0x9e3779b97f4a7c15ull;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ull;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebull;
    return x ^ (x >> 31);
}

static uint32_t reverse_bits(uint32_t x)
{
    x = ((x >> 1) & 0x55555555u) | ((x & 0x55555555u) << 1);
    x = ((x >> 2) & 0x33333333u) | ((x & 0x33333333u) << 2);
    x = ((x >> 4) & 0x0f0f0f0fu) | ((x & 0x0f0f0f0fu) << 4);
    x = ((x >> 8) & 0x00ff00ffu) | ((x & 0x00ff00ffu) << 8);
    return (x >> 16) | (x << 16);
}

/* Each output bit depends only on the input bits below it (Laine-Karras). */
static uint32_t laine_karras(uint32_t x, uint32_t seed)
{
    x += seed;
    x ^= x * 0x6c50b47cu;
    x ^= x * 0xb82f1e52u;
    x ^= x * 0xc7afe638u;
    x ^= x * 0x8d22f6e6u;
    return x;
}

/* Owen scrambling of a value whose most significant bit comes first. */
static uint32_t nested_uniform_scramble(uint32_t x, uint32_t seed)
{
    return reverse_bits(laine_karras(reverse_bits(x), seed));
}

/* Sobol dimension 1 (dimension 0 is the bit-reversed index): the XOR of
 * direction numbers v_k = v_{k-1} ^ (v_{k-1} >> 1) over the set bits of i,
 * tabulated per byte of the index. */
static uint32_t sobol1_table[4][256];

static void sobol1_init(void)
{
    uint32_t v[32];
    v[0] = 1u << 31;
    for (int k = 1; k < 32; k++)
        v[k] = v[k - 1] ^ (v[k - 1] >> 1);
    for (int b = 0; b < 4; b++)
        for (int x = 0; x < 256; x++) {
            uint32_t r = 0;
            for (int k = 0; k < 8; k++)
                if (x >> k & 1)
                    r ^= v[8 * b + k];
            sobol1_table[b][x] = r;
        }
}

static pthread_once_t sobol1_once = PTHREAD_ONCE_INIT;

static uint32_t sobol_dim1(uint32_t i)
{
    return sobol1_table[0][i & 255] ^ sobol1_table[1][(i >> 8) & 255] ^
           sobol1_table[2][(i >> 16) & 255] ^ sobol1_table[3][i >> 24];
}

static double to_unit(uint32_t x) { return (double)x * (1.0 / 4294967296.0); }

static uint32_t pcg32(uint64_t *state)
{
    uint64_t old = *state;
    *state = old * 6364136223846793005ull + 1442695040888963407ull;
    uint32_t xorshifted = (uint32_t)(((old >> 18) ^ old) >> 27);
    uint32_t rot = (uint32_t)(old >> 59);
    return (xorshifted >> rot) | (xorshifted << ((32 - rot) & 31));
}

void sl_sampler_start(sl_sampler *s, uint64_t pixel_seed, uint32_t index, bool low_discrepancy)
{
    if (low_discrepancy)
        pthread_once(&sobol1_once, sobol1_init);
    s->seed = pixel_seed;
    s->index = index;
    s->dim = 0;
    s->ld = low_discrepancy;
    s->state = sl_hash_combine(pixel_seed, index);
}

void sl_sampler_2d(sl_sampler *s, double out[2])
{
    if (!s->ld) {
        out[0] = to_unit(pcg32(&s->state));
        out[1] = to_unit(pcg32(&s->state));
        return;
    }
    uint64_t h = sl_hash_combine(s->seed, s->dim++);
    uint32_t shuffled = nested_uniform_scramble(s->index, (uint32_t)h);
    uint32_t x = reverse_bits(shuffled), y = sobol_dim1(shuffled);
    out[0] = to_unit(nested_uniform_scramble(x, (uint32_t)(h >> 32)));
    out[1] = to_unit(nested_uniform_scramble(y, (uint32_t)sl_hash64(h)));
}

double sl_sampler_1d(sl_sampler *s)
{
    double u[2];
    sl_sampler_2d(s, u);
    return u[0];
}
