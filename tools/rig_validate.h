/* SPDX-License-Identifier: BSD-3-Clause */
/* The rig command's validation renders (private to tools/). */
#ifndef SETLIGHT_RIG_VALIDATE_H
#define SETLIGHT_RIG_VALIDATE_H

#include "setlight/core.h"

#define RIG_VALIDATE_SCENES 3

typedef struct rig_validation {
    int width;
    int64_t spp;
    const char *scene[RIG_VALIDATE_SCENES]; /* "grey", "chrome", "shadow" */
    double error[RIG_VALIDATE_SCENES];      /* relative RMSE, rig against map */
    double seconds;
} rig_validation;

/* Renders the grey, chrome and shadow presets (width pixels wide, spp
 * samples, direct light and one bounce) under the map and under the rig
 * file (rig.json, read back as the renderer reads it) with the same seed,
 * and compares them on the objects (camera rays that miss see black). */
sl_result rig_validate(const sl_image *env, const char *rig_json, int width, int64_t spp,
                       rig_validation *out, sl_error *err);

#endif
