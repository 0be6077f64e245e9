/* SPDX-License-Identifier: BSD-3-Clause */
/* The floor of `setlight stitch` (docs/stitch.md, "Speed"): only reading
 * the views (as the stitch does: a half RGB EXR through
 * sl_exr_read_half_rgb, anything else sl_image_read_linear) and only writing a
 * lat-long (a stitch's own output, read first and not timed) 32 rows at a
 * time through sl_exr_stream, as half (or float with --float) ZIP.
 *   build/bench/bench_stitch_io_floor [--float] LATLONG.exr VIEW... */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "setlight/core.h"

int main(int argc, char **argv)
{
    int a = 1;
    sl_pixel_type type = SL_PIXEL_HALF;
    if (a < argc && !strcmp(argv[a], "--float")) {
        type = SL_PIXEL_FLOAT;
        a++;
    }
    if (argc - a < 2) {
        fprintf(stderr, "usage: bench_stitch_io_floor [--float] LATLONG.exr VIEW...\n");
        return 2;
    }
    sl_error err;
    double wall = sl_seconds(), cpu = sl_cpu_seconds();
    for (int i = a + 1; i < argc; i++) {
        sl_image img = {0};
        uint16_t *half = NULL;
        int w, h;
        sl_meta meta;
        if (sl_exr_read_half_rgb(argv[i], &half, &w, &h, &meta, &err) ||
            (!half && sl_image_read_linear(argv[i], NULL, &img, NULL, NULL, &err))) {
            fprintf(stderr, "%s\n", err.message);
            return 1;
        }
        sl_meta_free(&meta);
        free(half);
        sl_image_free(&img);
    }
    double read_wall = sl_seconds() - wall, read_cpu = sl_cpu_seconds() - cpu;
    sl_image ll = {0};
    if (sl_exr_read(argv[a], &ll, NULL, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    char tmp[4096];
    snprintf(tmp, sizeof tmp, "%s.floor.exr", argv[a]);
    wall = sl_seconds(), cpu = sl_cpu_seconds();
    sl_exr_stream *s;
    sl_result r = sl_exr_stream_open(tmp, ll.width, ll.height, ll.channels, NULL, type, SL_EXR_ZIP,
                                     &s, &err);
    for (int y = 0; !r && y < ll.height; y += 32) {
        int n = ll.height - y < 32 ? ll.height - y : 32;
        r = sl_exr_stream_write(s, sl_image_pixel(&ll, 0, y), n, (size_t)ll.width * ll.channels,
                                &err);
    }
    if (!r)
        r = sl_exr_stream_finish(s, NULL, &err);
    if (r) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    double write_wall = sl_seconds() - wall, write_cpu = sl_cpu_seconds() - cpu;
    remove(tmp);
    printf("read %d views: %.2f s wall, %.2f s CPU; write %dx%d %s: %.2f s wall, %.2f s CPU; "
           "floor %.2f s wall, %.2f s CPU\n",
           argc - a - 1, read_wall, read_cpu, ll.width, ll.height,
           type == SL_PIXEL_HALF ? "half" : "float", write_wall, write_cpu, read_wall + write_wall,
           read_cpu + write_cpu);
    sl_image_free(&ll);
    return 0;
}
