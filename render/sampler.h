/* SPDX-License-Identifier: BSD-3-Clause */
/* Random numbers and sample sequences (sampler.c). Private to render/. */
#ifndef SETLIGHT_RENDER_SAMPLER_H
#define SETLIGHT_RENDER_SAMPLER_H

#include <stdbool.h>
#include <stdint.h>

uint64_t sl_hash64(uint64_t x);
static inline uint64_t sl_hash_combine(uint64_t a, uint64_t b)
{
    return sl_hash64(a ^ (b + 0x9e3779b97f4a7c15ull + (a << 6) + (a >> 2)));
}

/* One stream of sample values for one pixel sample. Low-discrepancy mode:
 * each pair of dimensions is a 2D Sobol sequence with hash-based Owen
 * scrambling and its own index shuffle (Burley 2020), so sample `index` of a
 * pixel is well stratified against the other indices of that pixel. */
typedef struct sl_sampler {
    uint64_t seed;
    uint32_t index;
    uint32_t dim;
    bool ld;
    uint64_t state; /* random mode: PCG state */
} sl_sampler;

void sl_sampler_start(sl_sampler *s, uint64_t pixel_seed, uint32_t index, bool low_discrepancy);
void sl_sampler_2d(sl_sampler *s, double out[2]);
double sl_sampler_1d(sl_sampler *s);

#endif
