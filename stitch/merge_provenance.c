/* SPDX-License-Identifier: BSD-3-Clause */
/* Provenance attributes of a merge: units and scale, and what weighted it. */
#include <math.h>
#include <stdio.h>
#include <string.h>

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

sl_result merge_lens_exif(const char *const *paths, int i, const sl_meta *meta,
                          sl_merge_result *res, sl_error *err)
{
    if (i == 0) {
        res->focal_length_mm = meta->focal_length_mm > 0 ? meta->focal_length_mm : 0.0;
        snprintf(res->camera_make, sizeof res->camera_make, "%s", meta->make);
        snprintf(res->camera_model, sizeof res->camera_model, "%s", meta->model);
        snprintf(res->lens_model, sizeof res->lens_model, "%s", meta->lens);
        return SL_OK;
    }
    /* A bracket is one camera and one lens; absent fields say nothing. */
    bool focal = meta->focal_length_mm > 0 && res->focal_length_mm > 0 &&
                 fabs(meta->focal_length_mm - res->focal_length_mm) > 1e-3 * res->focal_length_mm;
    bool lens = meta->lens[0] && res->lens_model[0] && strcmp(meta->lens, res->lens_model);
    bool body = meta->model[0] && res->camera_model[0] && strcmp(meta->model, res->camera_model);
    if (focal || lens || body)
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s: %s '%s' at %g mm, but %s has '%s' at %g mm (frames from "
                            "different %s)",
                            paths[i], body ? "camera" : "lens", body ? meta->model : meta->lens,
                            meta->focal_length_mm, paths[0],
                            body ? res->camera_model : res->lens_model, res->focal_length_mm,
                            body ? "cameras" : "lenses");
    return SL_OK;
}

sl_result merge_lens_meta(sl_meta *meta, const sl_merge_result *res, sl_error *err)
{
    meta->focal_length_mm = res->focal_length_mm;
    snprintf(meta->make, sizeof meta->make, "%s", res->camera_make);
    snprintf(meta->model, sizeof meta->model, "%s", res->camera_model);
    snprintf(meta->lens, sizeof meta->lens, "%s", res->lens_model);
    return sl_stitch_lens_meta_set(meta, err);
}
