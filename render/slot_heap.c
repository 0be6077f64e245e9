/* SPDX-License-Identifier: BSD-3-Clause */
#include "slot_heap.h"

#include <string.h>

static double key_of(const sl_slot_heap *h, int slot)
{
    double k;
    memcpy(&k, (const char *)h->pool + (size_t)slot * h->stride, sizeof k);
    return k;
}

void sl_slot_heap_push(sl_slot_heap *h, const void *elem)
{
    int slot = h->nfree > 0 ? h->free_list[--h->nfree] : h->used++;
    memcpy((char *)h->pool + (size_t)slot * h->stride, elem, h->stride);
    double key = key_of(h, slot);
    int i = h->count++;
    while (i > 0) {
        int p = (i - 1) / 2;
        if (key_of(h, h->heap[p]) >= key)
            break;
        h->heap[i] = h->heap[p];
        i = p;
    }
    h->heap[i] = slot;
}

void sl_slot_heap_pop(sl_slot_heap *h, void *out)
{
    int top_slot = h->heap[0], last = h->heap[--h->count];
    memcpy(out, (const char *)h->pool + (size_t)top_slot * h->stride, h->stride);
    h->free_list[h->nfree++] = top_slot;
    double last_key = key_of(h, last);
    int i = 0;
    for (;;) {
        int c = 2 * i + 1;
        if (c >= h->count)
            break;
        if (c + 1 < h->count && key_of(h, h->heap[c + 1]) > key_of(h, h->heap[c]))
            c++;
        if (key_of(h, h->heap[c]) <= last_key)
            break;
        h->heap[i] = h->heap[c];
        i = c;
    }
    if (h->count > 0)
        h->heap[i] = last;
}
