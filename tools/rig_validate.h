/* SPDX-License-Identifier: BSD-3-Clause */
/* The rig command's validation renders and their report (private to tools/). */
#ifndef SETLIGHT_RIG_VALIDATE_H
#define SETLIGHT_RIG_VALIDATE_H

#include "setlight/core.h"
#include "setlight/lightrig.h"

#define RIG_VALIDATE_SCENES 3

typedef struct rig_validation {
    int width;
    int64_t spp;      /* samples per pixel done (requested, rounded up to a multiple of 4) */
    int64_t spp_done; /* the last scene's, while rendering */
    const char *scene[RIG_VALIDATE_SCENES]; /* "grey", "chrome", "shadow" */
    double error[RIG_VALIDATE_SCENES];      /* relative RMSE, rig against map */
    double seconds_map[RIG_VALIDATE_SCENES], seconds_rig[RIG_VALIDATE_SCENES];
    /* The Monte Carlo noise of the rig-minus-map difference (relative to
     * the map render, from two half renders with different seeds) and the
     * error left when it is taken out: sqrt(max(0, error^2 - noise^2)). */
    double noise[RIG_VALIDATE_SCENES];
    double beyond_noise[RIG_VALIDATE_SCENES];
    double seconds, cpu_seconds; /* wall and process CPU time of the whole validation */
    /* The renders as compared: RGBA, RGB multiplied by the map render's
     * alpha (the objects only). Freed by rig_validation_free. */
    sl_image map[RIG_VALIDATE_SCENES], rig[RIG_VALIDATE_SCENES];
} rig_validation;

/* Renders the grey, chrome and shadow presets (width pixels wide, spp
 * samples, direct light and one bounce) under the map and under the rig
 * file (rig.json, read back as the renderer reads it) with the same seeds,
 * and compares them on the objects (camera rays that miss see black).
 * Free *out with rig_validation_free, also after failure. */
sl_result rig_validate(const sl_image *env, const char *rig_json, int width, int64_t spp,
                       rig_validation *out, sl_error *err);
void rig_validation_free(rig_validation *v);

/* Adds the validation to a report: a table (relative RMSE, spp, size,
 * render times) and for each scene the render under the map, under the rig
 * and a false-colour difference, as PNGs named PREFIX<scene>_map.png,
 * PREFIX<scene>_rig.png, PREFIX<scene>_diff.png, plus PREFIXdiff_scale.png
 * (the colour bar). PREFIX may name a subfolder of the report's folder
 * ("RIG.validate/"), which must exist. */
sl_result rig_validate_report(sl_report *rep, const rig_validation *v, const char *prefix,
                              sl_error *err);

/* Checks that DIR/NAME.html and DIR/NAME can be replaced: each absent, or
 * a file and a folder respectively. */
sl_result rig_validate_report_check(const char *dir, const char *name, sl_error *err);

/* The temporary folder a report is built in (sl_temp_dir_create). */
typedef struct rig_report_tmp {
    char path[4096];
    int handle;
} rig_report_tmp;

/* `setlight rig --validate`'s report: DIR/NAME.html with its images (and
 * the renders as float EXR) in DIR/NAME/. Built in a temporary folder in
 * DIR (*tmp) and added to the open output set (the folder and the page),
 * which renames them into place with the rig's files. The caller removes
 * *tmp with sl_temp_dir_remove after the set's commit or abort; on a
 * failure here nothing is left. `about` is the first paragraph (input,
 * rig, settings). */
sl_result rig_validate_write_report(const char *dir, const char *name, const char *about,
                                    const rig_validation *v, const sl_rig *rig,
                                    const sl_image *env, rig_report_tmp *tmp, sl_error *err);

#endif
