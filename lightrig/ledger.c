/* SPDX-License-Identifier: BSD-3-Clause */
/* The energy ledger: integral of the map, of the dome and of the lights,
 * per channel, compensated sums in double. */
#include <math.h>

#include "lightrig_private.h"

void rig_ledger(const sl_image *rgb, sl_rig *rig)
{
    int w = rgb->width, h = rgb->height;
    sl_ksum orig[3] = {{0}}, dome[3] = {{0}}, lights[3] = {{0}};
    for (int y = 0; y < h; y++) {
        double om = sl_latlong_texel_solid_angle(y, w, h);
        for (int x = 0; x < w; x++) {
            const float *p = sl_image_pixel(rgb, x, y), *q = sl_image_pixel(&rig->residual, x, y);
            for (int c = 0; c < 3; c++) {
                sl_ksum_add(&orig[c], (double)p[c] * om);
                sl_ksum_add(&dome[c], (double)q[c] * om);
            }
        }
    }
    for (int i = 0; i < rig->light_count; i++)
        for (int c = 0; c < 3; c++)
            sl_ksum_add(&lights[c], rig->lights[i].integral[c]);
    rig->relative_error = 0;
    for (int c = 0; c < 3; c++) {
        rig->original[c] = sl_ksum_value(&orig[c]);
        rig->dome[c] = sl_ksum_value(&dome[c]);
        rig->lights_sum[c] = sl_ksum_value(&lights[c]);
        double diff = fabs(rig->lights_sum[c] + rig->dome[c] - rig->original[c]);
        double e = rig->original[c] > 0 ? diff / rig->original[c] : diff;
        if (e > rig->relative_error)
            rig->relative_error = e;
    }
}
