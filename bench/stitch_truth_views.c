/* SPDX-License-Identifier: BSD-3-Clause */
/* The views of a `setlight simulate` capture without the camera (no noise,
 * no JPEG, no merge): its truth lat-long through the true fisheye at the
 * head's true pose, as the capture renders them before shooting. The
 * merged views minus these are the merge's noise (docs/stitch.md, "The
 * noise floor of the point matches").
 *   build/bench/bench_stitch_truth_views TRUTH_LATLONG.exr WIDTH HEIGHT VIEWS SEED SS OUTDIR */
#include <stdio.h>
#include <stdlib.h>

#include "setlight/core.h"
#include "setlight/vset.h"

int main(int argc, char **argv)
{
    if (argc != 8) {
        fprintf(stderr, "usage: %s TRUTH_LATLONG.exr WIDTH HEIGHT VIEWS SEED SS OUTDIR\n", argv[0]);
        return 2;
    }
    int width = atoi(argv[2]), height = atoi(argv[3]), views = atoi(argv[4]), ss = atoi(argv[6]);
    sl_error err;
    sl_image latlong = {0};
    if (sl_image_read(argv[1], &latlong, NULL, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    sl_lens lens;
    sl_vset_fisheye_true(&lens, width, height);
    int rc = 0;
    for (int v = 0; v < views && !rc; v++) {
        sl_view_pose plan = {360.0 * v / views, 0, 0}, pose;
        sl_vset_head_pose(strtoull(argv[5], NULL, 10), v, &plan, &pose);
        sl_image out = {0};
        char path[4096];
        snprintf(path, sizeof path, "%s/clean%d.exr", argv[7], v);
        if (sl_vset_view_image(&lens, &pose, &latlong, ss, &out, &err) ||
            sl_image_write(path, &out, NULL, SL_PIXEL_FLOAT, &err)) {
            fprintf(stderr, "%s\n", err.message);
            rc = 1;
        }
        sl_image_free(&out);
    }
    sl_image_free(&latlong);
    return rc;
}
