/* SPDX-License-Identifier: BSD-3-Clause */
/* Pieces shared by the lightrig files; not public. */
#ifndef SETLIGHT_LIGHTRIG_PRIVATE_H
#define SETLIGHT_LIGHTRIG_PRIVATE_H

#include "setlight/lightrig.h"

/* The texel across the north/south pole from (x, 0) or (x, h-1) is x + w/2. */
static inline int rig_wrap_x(int x, int w)
{
    return ((x % w) + w) % w;
}

/* Centre direction of texel (x, y). */
void rig_texel_dir(int x, int y, int w, int h, double dir[3]);

/* detect.c: candidate regions. lum is w x h luminance (finite, >= 0).
 * labels (w x h, zeroed by caller) get 1..count; seeds are texels above
 * threshold_lum and above peak_fraction of the brightest texel connected
 * to them, fragments closer than merge_rad (gap between edges) join,
 * and every region grows by `ring` texels to take in its soft edge. */
sl_result rig_detect(const float *lum, int w, int h, double threshold_lum, double peak_fraction,
                     double merge_rad, int ring, int *labels, int *count, sl_error *err);

/* Solid-angle-weighted median of lum (0 for an all-zero map). */
double rig_weighted_median(const float *lum, int w, int h, sl_error *err, sl_result *res);

/* residual.c: fills texels with labels != 0 by push-pull (longitude wrap,
 * solid-angle weights) from the rest; writes min(fill, original) there and
 * the original elsewhere into out (RGB, allocated by the caller). */
sl_result rig_fill(const sl_image *rgb, const int *labels, sl_image *out, sl_error *err);

/* fit.c: fits one region (its texel indices y * w + x) against original
 * and residual; false when the region has no energy above its fill. */
bool rig_fit_region(const sl_image *rgb, const sl_image *residual, const int *texels, int count,
                    const sl_rig_options *opt, sl_rig_light *light);
/* Positions a fitted light on the sphere/room of opt (no-op at infinity). */
void rig_place_light(sl_rig_light *light, const sl_rig_options *opt);
/* Ranks candidates and chooses the kept ones (keep[i] true); fills skipped. */
sl_result rig_select(sl_rig_light *cand, int count, const sl_rig_options *opt, const int *tags,
                     bool *keep, sl_rig_skip **skipped, int *skipped_count, sl_error *err);

/* tags.c: the artist tags of opt on the regions of labels (count regions).
 * Includes with no region there get a new one (count grows). tags (count
 * + SL_RIG_MAX_TAGS + 1 entries, by label) get +k for include k, -k for
 * exclude k (1-based). */
sl_result rig_apply_tags(const float *lum, int w, int h, const sl_rig_options *opt, int *labels,
                         int *count, int *tags, sl_error *err);

/* ledger.c: rig->original, lights_sum, dome, relative_error. */
void rig_ledger(const sl_image *rgb, sl_rig *rig);

/* mediancut.c: Debevec 2005 median cut with max_lights regions (all energy
 * in the lights, black dome). */
sl_result rig_mediancut(const sl_image *rgb, const sl_rig_options *opt, sl_rig *rig,
                        sl_error *err);


/* The temporary folder the validation report is built in (sl_temp_dir_create). */
typedef struct sl_rig_report_tmp {
    char path[4096];
    int handle;
} sl_rig_report_tmp;

/* The validation report: DIR/NAME.html with its images (and the renders
 * as float EXR) in DIR/NAME/. Built in a temporary folder in DIR (*tmp)
 * and added to the open output set (the folder and the page), which
 * renames them into place with the rig's files. The caller removes *tmp
 * with sl_temp_dir_remove after the set's commit or abort; on a failure
 * here nothing is left. `about` is the first paragraph (input, rig,
 * settings). */
sl_result sl_rig_validate_write_report(const char *dir, const char *name, const char *about,
                                       const sl_rig_validation *v, const sl_rig *rig,
                                       const sl_image *env, sl_rig_report_tmp *tmp,
                                       sl_error *err);

#endif
