/* SPDX-License-Identifier: BSD-3-Clause */
/* The merge's performance reference (issue 5: the merge within 1.2x of only
 * decoding the frames): every frame read once, 32 rows at a time, through the
 * merge's reader (integer codes, or float for float frames), frames in
 * parallel on sl_threads_get() threads. Prints wall and CPU seconds of the
 * decoding, and apart from it those of loading the image module (OpenImageIO,
 * loaded on the first photo call: in a merge that is "other", not decoding).
 *   build/bench/bench_decode FRAME... */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "setlight/core.h"

typedef struct job {
    char **paths;
    sl_result *results;
    sl_error *errs;
} job;

static void decode(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    job *j = ctx;
    for (int64_t i = begin; i < end; i++) {
        sl_photo_strips *s;
        sl_photo_strip_info info;
        sl_result r = sl_photo_strips_open(j->paths[i], &s, &info, &j->errs[i]);
        size_t bytes = info.code_bytes ? (size_t)info.code_bytes : sizeof(float);
        void *buf = r ? NULL : malloc((size_t)32 * info.width * 3 * bytes);
        for (int y = 0; !r && buf && y < info.height; y += 32) {
            int y1 = y + 32 < info.height ? y + 32 : info.height;
            r = info.code_bytes ? sl_photo_strips_read_codes(s, y, y1, buf, &j->errs[i])
                                : sl_photo_strips_read(s, y, y1, buf, &j->errs[i]);
        }
        free(buf);
        sl_photo_strips_close(s);
        j->results[i] = r;
    }
}

int main(int argc, char **argv)
{
    if (argc < 2) {
        fprintf(stderr, "usage: bench_decode FRAME...\n");
        return 2;
    }
    int n = argc - 1;
    sl_result results[256];
    sl_error errs[256];
    if (n > 256)
        n = 256;
    job j = {argv + 1, results, errs};
    double l0 = sl_seconds(), lc0 = sl_cpu_seconds();
    sl_photo_strips *first;
    sl_photo_strip_info info;
    if (sl_photo_strips_open(argv[1], &first, &info, &errs[0])) {
        fprintf(stderr, "bench_decode: %s\n", errs[0].message);
        return 1;
    }
    sl_photo_strips_close(first);
    double w0 = sl_seconds(), c0 = sl_cpu_seconds();
    sl_parallel_for(n, 1, decode, &j);
    double w1 = sl_seconds(), c1 = sl_cpu_seconds();
    for (int i = 0; i < n; i++)
        if (results[i]) {
            fprintf(stderr, "bench_decode: %s\n", errs[i].message);
            return 1;
        }
    printf("module load: wall %.3f s, CPU %.3f s\n", w0 - l0, c0 - lc0);
    printf("decode only: %d frames, wall %.3f s, CPU %.3f s, %d threads\n", n, w1 - w0, c1 - c0,
           sl_threads_get());
    return 0;
}
