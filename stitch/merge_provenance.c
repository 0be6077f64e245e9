/* SPDX-License-Identifier: BSD-3-Clause */
/* Provenance attributes of a merge: units and scale, and what weighted it. */
#include <stdio.h>

#include "merge_private.h"

sl_result merge_provenance_meta(sl_meta *meta, const sl_merge_result *res, sl_error *err)
{
    char buf[512];
    if (res->absolute)
        snprintf(buf, sizeof buf,
                 "cd/m^2: L = %g * y * N^2 / (t * ISO), y the linear value (1 = saturation); "
                 "ISO 12232 saturation speed with lens factor q = 0.65",
                 SL_MERGE_K_SAT);
    else
        snprintf(buf, sizeof buf, "relative: the reference frame's linear value");
    sl_result r = sl_meta_set(meta, "setlight:merge:units", buf, err);
    if (!r) {
        snprintf(buf, sizeof buf, "%.9g", res->output_exposure);
        r = sl_meta_set(meta, "setlight:merge:output_exposure", buf, err);
    }
    if (!r) {
        snprintf(buf, sizeof buf,
                 "inverse variance: var = %.9g * y + %.9g + quantisation step^2 / 12; no weight "
                 "at or below code %.9g or where any channel is at or above code %.9g; fade over "
                 "the 0.05 below",
                 res->noise_gain, res->noise_floor, res->black, res->saturation);
        r = sl_meta_set(meta, "setlight:merge:weights", buf, err);
    }
    if (!r) {
        static const char *names[] = {"ZIP", "PIZ", "no", "RLE"};
        snprintf(buf, sizeof buf, "%s, %s compression (%s)",
                 res->pixel_type == SL_PIXEL_HALF ? "half" : "float", names[res->compression],
                 res->encoding_note);
        r = sl_meta_set(meta, "setlight:merge:encoding", buf, err);
    }
    return r;
}
