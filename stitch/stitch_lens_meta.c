/* SPDX-License-Identifier: BSD-3-Clause */
/* The nominal lens of a view from what its photos' EXIF said: focal length,
 * camera body (and from it the sensor size), lens name. EXIF has no sensor
 * size a reader can rely on (FocalPlaneXResolution is missing or in odd
 * units on many bodies), so the size comes from a table of bodies. */
#include "setlight/stitch.h"

#include <math.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

typedef struct body {
    const char *model; /* EXIF Model, compared without case */
    double width_mm, height_mm;
} body;

/* Manufacturers' sensor sizes of full-frame bodies used on set. */
static const body bodies[] = {
    {"Canon EOS 5D Mark II", 36.0, 24.0},  {"Canon EOS 5D Mark III", 36.0, 24.0},
    {"Canon EOS 5D Mark IV", 36.0, 24.0},  {"Canon EOS 5DS", 36.0, 24.0},
    {"Canon EOS 5DS R", 36.0, 24.0},       {"Canon EOS 6D", 35.8, 23.9},
    {"Canon EOS 6D Mark II", 35.9, 24.0},  {"Canon EOS R", 36.0, 24.0},
    {"Canon EOS R5", 36.0, 24.0},          {"Canon EOS R6", 35.9, 23.9},
    {"NIKON D750", 35.9, 24.0},            {"NIKON D810", 35.9, 24.0},
    {"NIKON D850", 35.9, 23.9},            {"NIKON Z 7", 35.9, 23.9},
    {"ILCE-7M3", 35.6, 23.8},              {"ILCE-7RM3", 35.9, 24.0},
    {"ILCE-7RM4", 35.7, 23.8},
};

/* Full-frame diagonal, for the 35 mm equivalent focal length. */
#define FULL_FRAME_DIAGONAL_MM 43.2666

bool sl_stitch_sensor_of_body(const char *make, const char *model, double *width_mm,
                              double *height_mm)
{
    /* The virtual set's bodies (docs/virtual-set.md): a 36 x 24 mm sensor. */
    if (make && strcasecmp(make, "setlight") == 0) {
        *width_mm = 36.0;
        *height_mm = 24.0;
        return true;
    }
    if (!model)
        return false;
    for (size_t i = 0; i < sizeof bodies / sizeof bodies[0]; i++)
        if (strcasecmp(model, bodies[i].model) == 0) {
            *width_mm = bodies[i].width_mm;
            *height_mm = bodies[i].height_mm;
            return true;
        }
    return false;
}

sl_result sl_stitch_lens_meta_set(sl_meta *meta, sl_error *err)
{
    double w, h;
    if (!sl_stitch_sensor_of_body(meta->make, meta->model, &w, &h))
        return SL_OK;
    char buf[160];
    snprintf(buf, sizeof buf, "%.4g x %.4g", w, h);
    sl_result r = sl_meta_set(meta, SL_ATTR_SENSOR_MM, buf, err);
    if (!r) {
        snprintf(buf, sizeof buf, "table of camera bodies: %s %s", meta->make, meta->model);
        r = sl_meta_set(meta, SL_ATTR_SENSOR_SOURCE, buf, err);
    }
    if (!r && meta->focal_length_mm > 0) {
        snprintf(buf, sizeof buf, "%.4g", meta->focal_length_mm * FULL_FRAME_DIAGONAL_MM / hypot(w, h));
        r = sl_meta_set(meta, SL_ATTR_FOCAL_35MM, buf, err);
    }
    return r;
}

bool sl_stitch_lens_from_meta(const sl_meta *meta, sl_lens_projection projection, int width,
                              int height, sl_lens *out, char *why, size_t why_size)
{
    memset(out, 0, sizeof *out);
    double focal = meta->focal_length_mm;
    if (!(focal > 0.0) || !isfinite(focal)) {
        snprintf(why, why_size,
                 "no lens information: no focal length in its metadata; give --focal-mm and "
                 "--sensor-mm");
        return false;
    }
    double w = 0.0, h = 0.0;
    const char *given = sl_meta_get(meta, SL_ATTR_SENSOR_MM);
    if (!(given && sscanf(given, "%lf x %lf", &w, &h) == 2 && w > 0.0 && h > 0.0) &&
        !sl_stitch_sensor_of_body(meta->make, meta->model, &w, &h)) {
        snprintf(why, why_size,
                 "no lens information: the sensor size of camera '%s %s' is unknown; give "
                 "--sensor-mm",
                 meta->make, meta->model);
        return false;
    }
    /* The image is the whole sensor, either way up; a crop or a resize to
     * another shape leaves the millimetres unknown. */
    double aspect = (double)width / height, sensor = w / h;
    double width_mm = fabs(aspect / sensor - 1.0) < 0.02 ? w
                      : fabs(aspect * sensor - 1.0) < 0.02 ? h
                                                          : 0.0;
    if (width_mm == 0.0) {
        snprintf(why, why_size,
                 "no lens information: the image is %dx%d but the sensor is %g x %g mm (a crop "
                 "or another shape); give --sensor-mm",
                 width, height, w, h);
        return false;
    }
    sl_lens_nominal(out, projection, width, height, focal, width_mm);
    if (why_size)
        why[0] = '\0';
    return true;
}
