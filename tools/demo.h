/* SPDX-License-Identifier: BSD-3-Clause */
/* Private to `setlight demo`: the state the stages share and the helpers
 * that read the simulated capture back as any pipeline would. */
#ifndef SETLIGHT_DEMO_H
#define SETLIGHT_DEMO_H

#include <jansson.h>
#include <stddef.h>

#include "setlight/vset.h"
#include "setlight/stitch.h"

typedef struct demo {
    const char *dir;
    char capture[4096];
    sl_vset_size size;
    uint64_t seed;
    bool force;
    sl_report *rep;
    /* filled by the stages */
    sl_vset_capture_summary summary;
    double lavg;
    char hdri[4300];        /* the stitched HDRI (cd/m^2) calibrate, rig and render use */
    sl_image confidence;    /* its coverage: the stitch's confidence per texel */
    json_t *facts;          /* headline numbers by stage, for --json */
} demo;

/* Luminance a against b over the texels keep marks, on a width x height
 * lat-long: median and 95th percentile of |a / b - 1|, the energy ratio
 * minus 1, solid angle and texels compared. */
typedef struct demo_diff {
    double median, p95, energy, solid_angle;
    int texels;
} demo_diff;
sl_result demo_diff_luminance(const double *a, const double *b, const unsigned char *keep,
                              int width, int height, demo_diff *out, sl_error *err);

typedef sl_result (*demo_stage_fn)(demo *d, char *note, size_t note_size, sl_error *err);

/* DIR/name parsed; NULL with err set (the message names the file). */
json_t *demo_load_json(const char *dir, const char *name, sl_error *err);
sl_result demo_truth_latlong(const demo *d, sl_image *ll, sl_error *err);
/* The stitched HDRI (d->hdri) calibrate, rig and render use. */
sl_result demo_hdri(const demo *d, sl_image *ll, sl_error *err);
/* truth/camera.json's output_from_rec709 and k. */
sl_result demo_camera(const demo *d, double out_from_rec709[3][3], double *k, sl_error *err);
/* Its inverse, rec709_from_output: a merged value back to the set's cd/m^2. */
sl_result demo_camera_inverse(const demo *d, double rec709_from_output[3][3], double *k,
                              sl_error *err);
/* One merged pixel (RGB, the reference frame's exposure k t (ISO/100) / N^2)
 * back in the set's units: rec709_from_output * p / exposure. */
void demo_set_units(const float *p, double exposure, const double rec709_from_output[3][3],
                    float *out);
/* Merges a probe's bracket (its linear TIFFs, linear response, EXIF
 * exposures), or with middle_only takes its middle frame alone. *truth gets the probe's entry of truth/probes.json (a new
 * reference), *exposure the reference frame's k t (ISO/100) / N^2: merged
 * value = exposure * output_from_rec709 * radiance. */
sl_result demo_merge_probe(const demo *d, const char *kind, bool middle_only,
                           sl_merge_result *res, json_t **truth, double *exposure, sl_error *err);
/* A linear image as the report shows it: exposure so the log-average is 18% grey. */
double demo_stops(double lavg);

sl_result demo_stage_stitch(demo *d, char *note, size_t n, sl_error *err);
sl_result demo_stage_unwrap(demo *d, char *note, size_t n, sl_error *err);
sl_result demo_stage_calibrate(demo *d, char *note, size_t n, sl_error *err);
sl_result demo_stage_rig(demo *d, char *note, size_t n, sl_error *err);

#endif
