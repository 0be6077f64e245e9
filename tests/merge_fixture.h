/* SPDX-License-Identifier: BSD-3-Clause */
/* Synthetic brackets with a known answer, for the merge tests: a smooth
 * radiance lat-long (plus an optional sun), frames taken through a known
 * camera response with Poisson-Gaussian noise from a seeded generator,
 * quantised and clipped, written as real files with EXIF. */
#ifndef SETLIGHT_TESTS_MERGE_FIXTURE_H
#define SETLIGHT_TESTS_MERGE_FIXTURE_H

#include "setlight/core.h"

enum { MF_MAX_FRAMES = 16 };

typedef enum { MF_LINEAR = 0, MF_GAMMA, MF_SCURVE } mf_curve;

typedef struct mf_bracket {
    int width, height;
    int frames;
    double stops;       /* between neighbouring frames */
    mf_curve curve;
    int bits;           /* 8 or 16 */
    const char *ext;    /* "jpg", "tif", "png" */
    bool sun;           /* a disc bright enough to clip in every frame */
    double noise_gain;  /* var(y) = gain * y + floor, y linear in [0, 1] */
    double noise_floor;
    uint64_t seed;
    int lie_frame;      /* this frame's EXIF time is off by lie_stops (0 stops: no lie) */
    double lie_stops;
    bool ghost;         /* a dark object (a quarter of the radiance) in one frame only */
    int ghost_frame;
} mf_bracket;

typedef struct mf_result {
    sl_image radiance;  /* truth: what the middle frame would record, unclipped */
    sl_image clipped;   /* truth: 1 where the shortest frame saturates (noise-free) */
    sl_image ghost;     /* truth: 1 channel, 1 where the object is (when ghost) */
    int frames;
    char paths[MF_MAX_FRAMES][512];
    double times[MF_MAX_FRAMES]; /* true seconds (EXIF has them unless a frame lies) */
} mf_result;

/* The camera's curve: linear value y in [0, 1] -> value z in [0, 1], and back. */
double mf_curve_forward(mf_curve curve, double y);
double mf_curve_inverse(mf_curve curve, double z);

/* Writes DIR/PREFIX_<rank>.<ext>, shortest exposure first (f/8, ISO 100). */
sl_result mf_make_bracket(const char *dir, const char *prefix, const mf_bracket *b,
                          mf_result *out, sl_error *err);
void mf_result_free(mf_result *r);

/* A frame of one value everywhere, with EXIF time (none when time <= 0). */
sl_result mf_write_flat(const char *path, int width, int height, float value, int bits,
                        double time, sl_error *err);

/* Relative errors |merged / (scale * truth) - 1| over samples the truth marks
 * not clipped; scale = 1 or, when fit_scale, the median of merged / truth.
 * Fills the median and 99th percentile; returns the number of samples. */
int64_t mf_compare(const sl_image *merged, const mf_result *truth, bool fit_scale,
                   double *median, double *p99, double *scale);

#endif
