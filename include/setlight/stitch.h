/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * setlight stitch: bracketed exposures to HDR radiance (merge), chrome-ball
 * and fisheye views to lat-long (unwrap), and calibration against the grey
 * sphere and the Macbeth chart (calibrate).
 */
#ifndef SETLIGHT_STITCH_H
#define SETLIGHT_STITCH_H

#include "setlight/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ================================================================== */
/* Merge: brackets to HDR radiance                                     */
/* ================================================================== */

/* An inverse camera response: pixel value z in [0, 1] -> linear exposure,
 * sampled at z = k / (nodes - 1) per channel and interpolated linearly.
 * Increasing, with inverse[nodes - 1] = 1 (the value a saturated pixel
 * would linearise to). docs/merge.md describes the JSON file form. */
typedef struct sl_response {
    int channels;    /* 3 */
    int nodes;       /* >= 2 */
    double *inverse; /* channels rows of nodes values; owned */
    char source[64]; /* "linear", "debevec-malik", or the file it came from */
} sl_response;

sl_result sl_response_linear(sl_response *resp, int nodes, sl_error *err);
void sl_response_free(sl_response *resp);
/* Linear exposure for value z (clamped to [0, 1]) in one channel. */
double sl_response_eval(const sl_response *resp, int channel, double z);
/* JSON files {"format": "setlight-response", "version": 1, ...}; written atomically. */
sl_result sl_response_read(const char *path, sl_response *resp, sl_error *err);
sl_result sl_response_write(const char *path, const sl_response *resp, sl_error *err);

typedef enum { SL_RESPONSE_LINEAR = 0, SL_RESPONSE_AUTO, SL_RESPONSE_GIVEN } sl_response_mode;
typedef enum { SL_EXPOSURES_EXIF = 0, SL_EXPOSURES_DATA } sl_exposure_source;

typedef struct sl_merge_options {
    const double *times;        /* seconds per frame in the given order; NULL: EXIF */
    sl_exposure_source exposures; /* which exposures the merge uses */
    sl_response_mode response_mode;
    const sl_response *response; /* for SL_RESPONSE_GIVEN */
    double smoothness;          /* Debevec-Malik lambda; 0: 10 (widest step / 3 stops)^1.5 */
    int samples;                /* response samples per channel; 0: default 4000 */
    double noise_gain;          /* Poisson term: var(y) = gain * y + floor, y linear in [0, 1] */
    double noise_floor;         /*   0, 0: defaults 2e-5, 1e-6 (docs/merge.md) */
    double saturation;          /* z at or above which a sample is saturated (JPEG rings a few codes below 255 inside clipped areas); default 0.95 */
    double black;               /* z at or below which a sample has no weight; 0: 0.004 */
    double tolerance_stops;     /* EXIF vs data disagreement reported above; 0: 0.2 */
    uint64_t seed;              /* for sample positions */
    bool deghost;               /* leave out frames that disagree with the others */
    double deghost_sigma;       /* disagreement: beyond this many standard deviations (5) */
    double deghost_model_error; /* relative error added to the noise model (0.05) */
} sl_merge_options;

/* Fills the defaults above. */
void sl_merge_options_init(sl_merge_options *opt);

typedef struct sl_merge_frame {
    char *path;
    double exif_time, f_number, iso; /* 0 when absent */
    double time;                     /* seconds used (EXIF or --times) */
    double exif_exposure;            /* relative exposure t * ISO / N^2 (t when N, ISO absent) */
    double fitted_exposure;          /* from the pixel data, on the same scale; 0 if unknown */
    double disagreement_stops;       /* log2(fitted / exif) after the common offset */
    bool disagrees;                  /* |disagreement| > tolerance */
    double exposure;                 /* the one the merge used */
    int rank;                        /* 0 = shortest exposure */
    double saturated_fraction;       /* pixels with a channel at or above saturation */
    double black_fraction;           /* pixels with every channel at or below black */
} sl_merge_frame;

typedef struct sl_merge_result {
    sl_image radiance;          /* RGB, relative radiance (the reference frame's scale) */
    sl_image clipped;           /* RGB, 1 where the channel is saturated in every frame */
    sl_image ghost;             /* with deghost: 1 channel, 1 where a frame was left out */
    sl_response response;
    sl_merge_frame *frames;     /* in the given order */
    int frame_count;
    int reference;              /* frame whose exposure scales the radiance (median) */
    int bits;                   /* bits per sample of the frames */
    int64_t clipped_pixels;     /* pixels with any channel clipped in every frame */
    int64_t clipped_samples[3];
    double clipped_fraction;    /* clipped_pixels / pixels */
    double clipped_solid_angle; /* steradians when the frames are 2:1 lat-longs, else -1 */
    int64_t underexposed_samples; /* no frame above black: longest frame's value kept */
    int64_t disagreeing_frames;
    int64_t ghost_pixels;       /* with deghost: pixels where a frame was left out */
    int64_t nonfinite_samples;  /* NaN/Inf input samples (float frames), given no weight */
    int fitted_ratios;          /* neighbour ratios measured from the data (of frames - 1) */
    double seconds;
} sl_merge_result;

/* Merges a bracket of frames (any order, same size and bit depth, at most
 * 64) into radiance. With deghost, per pixel, a frame whose value is more
 * than deghost_sigma deviations (noise model plus model error) from the
 * weighted median of the frames in any channel is left out. Frames are read a strip at a time. Pixels saturated in every
 * frame get the lower bound from the shortest exposure and a 1 in
 * `clipped`; no NaN, Inf or negative value is produced. On failure `out`
 * is left empty. */
sl_result sl_merge(const char *const *paths, int count, const sl_merge_options *opt,
                   sl_merge_result *out, sl_error *err);
void sl_merge_result_free(sl_merge_result *res);
/* Recovers the response alone (Debevec-Malik) and checks the exposures. */
sl_result sl_merge_response(const char *const *paths, int count, const sl_merge_options *opt,
                            sl_merge_result *out, sl_error *err);
/* Writes the radiance EXR (float) with provenance attributes and, when
 * mask_path / ghost_path are not NULL, the clipped mask (RGB) and the ghost
 * mask (Y, needs a deghosted result) beside it, each atomically; on failure
 * none of them is left. */
sl_result sl_merge_write(const char *path, const char *mask_path, const char *ghost_path,
                         const sl_merge_result *res, sl_error *err);

/* ================================================================== */
/* Unwrap: chrome ball to lat-long                                     */
/* ================================================================== */

/* ================================================================== */
/* Calibrate: grey sphere and chart                                    */
/* ================================================================== */

#ifdef __cplusplus
}
#endif

#endif /* SETLIGHT_STITCH_H */
