/* SPDX-License-Identifier: BSD-3-Clause */
/* A max-heap of elements kept in a pool of slots, each element beginning
 * with its double key; popped slots are reused. The closed forms' cell
 * refinement (irradiance.c, glossy.c) keeps its open cells in one.
 * Private to render/. */
#ifndef SETLIGHT_RENDER_SLOT_HEAP_H
#define SETLIGHT_RENDER_SLOT_HEAP_H

#include <stddef.h>

typedef struct sl_slot_heap {
    void *pool;    /* elements of `stride` bytes; the caller's storage */
    size_t stride;
    int *heap;     /* heap order: slots; as many as the pool holds */
    int *free_list;
    int count, nfree, used;
} sl_slot_heap;

static inline void sl_slot_heap_clear(sl_slot_heap *h) { h->count = h->nfree = h->used = 0; }
/* The element at heap position i (0: the largest key). */
static inline void *sl_slot_heap_at(const sl_slot_heap *h, int i)
{
    return (char *)h->pool + (size_t)h->heap[i] * h->stride;
}
/* Copies elem in; the caller keeps count below the pool's size. */
void sl_slot_heap_push(sl_slot_heap *h, const void *elem);
/* Copies the element with the largest key out and frees its slot. */
void sl_slot_heap_pop(sl_slot_heap *h, void *out);

/* Per-channel running sums of the open cells' estimates and bounds, on
 * which a refinement stops; sign +1 when a cell is pushed, -1 popped. */
typedef struct sl_open_sums {
    double mid[3], bnd[3];
} sl_open_sums;
static inline void sl_open_sums_add(sl_open_sums *s, const double mid[3], const double bnd[3], double sign)
{
    for (int c = 0; c < 3; c++)
        s->mid[c] += sign * mid[c], s->bnd[c] += sign * bnd[c];
}

#endif
