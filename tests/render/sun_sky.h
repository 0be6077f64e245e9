/* SPDX-License-Identifier: BSD-3-Clause */
/* Shared by the closed-form tests: a smooth sky over a dark ground that
 * each test puts its own sun in. */
#ifndef SETLIGHT_TESTS_RENDER_SUN_SKY_H
#define SETLIGHT_TESTS_RENDER_SUN_SKY_H

#include <stdlib.h>
#include <string.h>

#include "testing.h"

static inline void sky_over_ground(sl_image *env, int w)
{
    CHECK_OK(sl_image_alloc(env, w, w / 2, 3, NULL), NULL);
    for (int y = 0; y < w / 2; y++)
        for (int x = 0; x < w; x++) {
            float *p = sl_image_pixel(env, x, y);
            double d[3];
            sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / (w / 2), d);
            double up = fmax(0, d[1]);
            p[0] = (float)(d[1] > 0 ? 0.3 + 0.5 * up : 0.05);
            p[1] = (float)(d[1] > 0 ? 0.5 + 0.4 * up : 0.04);
            p[2] = (float)(d[1] > 0 ? 0.9 + 0.2 * d[0] * d[0] : 0.03);
        }
}

#endif
