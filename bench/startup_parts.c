/* SPDX-License-Identifier: BSD-3-Clause */
/* The parts of a command's start-up that happen on first use, in one
 * process, CPU time of each: the OCIO config (first colour-space name), a
 * PNG header (libpng), a first header of the second file and a second one:
 * a TIFF is read by libtiff; a file core leaves to OpenImageIO (a Radiance
 * .hdr, a palette TIFF) starts it on the first (dlopen of its ~260
 * libraries).
 *   build/bench/bench_startup X.png X.tif|X.hdr
 * docs/performance.md has the numbers; never run as a timed test. */
#include <stdio.h>

#include "setlight/core.h"

static double ms_since(double *t0)
{
    double now = sl_cpu_seconds(), ms = 1e3 * (now - *t0);
    *t0 = now;
    return ms;
}

static void header(const char *what, const char *path)
{
    sl_error err;
    sl_meta meta;
    double t = sl_cpu_seconds();
    sl_result r = sl_photo_read_meta(path, &meta, NULL, NULL, NULL, &err);
    printf("%-44s %8.2f ms CPU%s%s\n", what, ms_since(&t), r ? "  FAILED: " : "",
           r ? err.message : "");
    sl_meta_free(&meta);
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: bench_startup X.png X.tif|X.hdr\n");
        return 2;
    }
    printf("%-44s %8.2f ms CPU\n", "process start to main", 1e3 * sl_cpu_seconds());
    double t = sl_cpu_seconds();
    const char *name = sl_color_space_name("sRGB");
    printf("%-44s %8.2f ms CPU (%s)\n", "OCIO config (first colour-space name)", ms_since(&t),
           name ? name : "none");
    header("PNG header (libpng)", argv[1]);
    header("first header of the second file", argv[2]);
    header("second header", argv[2]);
    return 0;
}
