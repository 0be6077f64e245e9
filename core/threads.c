/* SPDX-License-Identifier: BSD-3-Clause */
/* Parallel loops over fixed chunks. Chunk boundaries depend only on the
 * count and the grain, so any per-chunk reduction is the same for every
 * thread count; threads only change who computes which chunk. */
#include "setlight/core.h"

#include <pthread.h>
#include <stdlib.h>
#include <unistd.h>

static int thread_count;

void sl_threads_set(int count) { thread_count = count > 0 ? count : 0; }

int sl_threads_get(void)
{
    if (thread_count > 0)
        return thread_count;
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n > 0 ? (int)n : 1;
}

typedef struct loop {
    int64_t count, grain, next;
    sl_range_fn fn;
    void *ctx;
} loop;

typedef struct worker_arg {
    loop *l;
    int index;
} worker_arg;

static void *worker_main(void *arg)
{
    worker_arg *w = arg;
    loop *l = w->l;
    for (;;) {
        int64_t begin = __atomic_fetch_add(&l->next, l->grain, __ATOMIC_RELAXED);
        if (begin >= l->count)
            break;
        int64_t end = begin + l->grain < l->count ? begin + l->grain : l->count;
        l->fn(l->ctx, begin, end, w->index);
    }
    return NULL;
}

void sl_parallel_for(int64_t count, int64_t grain, sl_range_fn fn, void *ctx)
{
    if (count <= 0)
        return;
    if (grain < 1)
        grain = 1;
    int64_t chunks = (count + grain - 1) / grain;
    int n = sl_threads_get();
    if (n > chunks)
        n = (int)chunks;
    loop l = {count, grain, 0, fn, ctx};
    if (n <= 1) {
        worker_arg w = {&l, 0};
        worker_main(&w);
        return;
    }
    pthread_t *tids = calloc((size_t)n, sizeof *tids);
    worker_arg *args = calloc((size_t)n, sizeof *args);
    int started = 0;
    if (tids && args) {
        for (int i = 1; i < n; i++) {
            args[i].l = &l;
            args[i].index = i;
            if (pthread_create(&tids[i], NULL, worker_main, &args[i]) != 0)
                break;
            started = i;
        }
    }
    worker_arg self = {&l, 0};
    worker_main(&self);
    for (int i = 1; i <= started; i++)
        pthread_join(tids[i], NULL);
    free(tids);
    free(args);
}
