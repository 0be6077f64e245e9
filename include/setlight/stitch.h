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

/* ================================================================== */
/* Unwrap: chrome ball to lat-long                                     */
/* ================================================================== */

/* ================================================================== */
/* Calibrate: grey sphere and chart                                    */
/* ================================================================== */

/* ColorChecker Classic 24, chart order (patch 1 dark skin at the top left,
 * row 4 the neutrals white ... black). Positions are pixel coordinates
 * (x right, y down, pixel centres at +0.5). */
#define SL_CHART_PATCHES 24

/* The 24 patch centres from the centres of the four corner patches, in
 * the order 1 (dark skin), 6 (bluish green), 24 (black), 19 (white):
 * a projective map of the regular 6 x 4 grid, so perspective is allowed. */
sl_result sl_chart_centers_from_corners(const double corners[4][2], double centers[24][2],
                                        sl_error *err);

typedef struct sl_chart_patch {
    double center[2];
    double radius;   /* of the sampled disc, pixels */
    double rgb[3];   /* trimmed mean of the kept pixels (camera RGB) */
    double spread;   /* relative standard deviation of the kept pixels' sum */
    int pixels;      /* kept */
    int clipped;     /* at or above the clip level in any channel */
    int nonfinite;   /* NaN/Inf */
    int trimmed;     /* dropped as outliers (glare, dust) */
    bool valid;      /* usable: enough pixels, clipped fraction small */
} sl_chart_patch;

/* Samples each patch on the linear image (RGB or RGBA): a disc of
 * radius_px (0: a quarter of the distance to the nearest other centre,
 * so well inside the patch), pixels with any channel >= clip_level
 * (0: no clip test) or non-finite rejected, then the brightest and darkest
 * 10% by channel sum dropped. A patch is invalid when fewer than 4 pixels
 * remain or more than 5% of its disc is clipped. */
sl_result sl_chart_sample(const sl_image *img, const double centers[24][2], double radius_px,
                          double clip_level, sl_chart_patch patches[24], sl_error *err);

typedef struct sl_ccm_options {
    /* Constrain the fit so that the neutral patch maps exactly onto its
     * reference: neutrals stay neutral. */
    bool white_preserving;
    int neutral_patch; /* 0-based; -1: the brightest valid of patches 19..24 */
} sl_ccm_options;

void sl_ccm_options_init(sl_ccm_options *o); /* not white-preserving, neutral -1 */

typedef struct sl_ccm_fit {
    double m[3][3];      /* working-space RGB = m * camera RGB */
    double gain;         /* cbrt(det m): the matrix's overall scale */
    int used;            /* patches in the fit */
    bool used_patch[24];
    int neutral_patch;   /* the constraint's patch, or -1 */
    /* CIEDE2000 against the reference (D65, white Y = 1), -1 for patches
     * not measured. "Before" is the camera RGB read as Rec.709 and scaled
     * so the neutral patches' luminance matches (exposure removed). */
    double de_before[24], de_after[24];
    double de_before_mean, de_before_max, de_after_mean, de_after_max;
} sl_ccm_fit;

/* Weighted least squares, in double, of camera RGB onto reference
 * (linear working-space RGB, e.g. SL_COLORCHECKER_LINEAR): each patch
 * weighted by Y^(-4/3) of its reference, as CIELAB lightness is roughly
 * Y^(1/3), so dark patches are not drowned by bright ones. Invalid patches
 * are excluded; fewer than 6 valid patches is SL_ERR_INPUT. */
sl_result sl_ccm_fit_chart(const sl_chart_patch patches[24], const double reference[24][3],
                           const sl_ccm_options *o, sl_ccm_fit *fit, sl_error *err);

/* CIEDE2000 between two linear Rec.709 colours (D65, white Y = 1). */
double sl_chart_delta_e(const double rgb[3], const double ref[3]);

typedef struct sl_chart_detection {
    double centers[24][2]; /* chart order */
    double box[4][2];      /* the detector's chart outline */
    double cost;           /* the detector's fit cost (lower is better) */
    double fit_de_mean;    /* mean CIEDE2000 of the orientation's trial colour fit */
} sl_chart_detection;

/* Finds a ColorChecker Classic 24 on a linear image: OpenCV mcc runs on a
 * tone-mapped 8-bit copy (99th-percentile luminance to white, sRGB curve);
 * the patch grid follows from the detected outline, and of its eight
 * possible orientations the one whose patches (sampled on the linear data,
 * clip_level as in sl_chart_sample) best fit the reference by a colour
 * matrix is kept. SL_ERR_INPUT "no chart found" when there is none. */
sl_result sl_chart_detect(const sl_image *img, double clip_level, const char *source,
                          sl_chart_detection *out, sl_error *err);

typedef struct sl_grey_options {
    double albedo;          /* the photographed sphere's albedo (0.18) */
    double circle[3];       /* sphere outline in the photo: cx, cy, r (pixels) */
    double azimuth_deg, elevation_deg; /* the photo's view, as sl_camera_validation */
    double inner;           /* use pixels within this fraction of the radius (0.85) */
    int size;               /* virtual render, pixels across (0: 2r, at most 128) */
    int64_t spp;            /* samples per pixel of the virtual render (256) */
    uint64_t seed;
    double clip_level;      /* photo pixels at or above are ignored (0: none) */
} sl_grey_options;

void sl_grey_options_init(sl_grey_options *o);

typedef struct sl_grey_fit {
    double gain[3];      /* multiply the HDRI's channels by these */
    double scale;        /* exposure: Rec.709 luminance of gain */
    double balance[3];   /* gain / scale */
    int64_t pixels;      /* sphere pixels used */
    int64_t rejected;    /* outliers (specks, clipped, off-ratio) */
    double rel_rmse_before; /* virtual sphere under the HDRI vs photo, after exposure only */
    double rel_rmse_after;  /* with gain */
    double error_p95;       /* 95th percentile of |relative error| per pixel, after */
    /* size x size RGBA: the photo resampled to the virtual camera, the
     * virtual sphere under the calibrated HDRI, and the relative error
     * (render - photo) / photo luminance, alpha = used mask. */
    sl_image photo, render, error;
} sl_grey_fit;

void sl_grey_fit_free(sl_grey_fit *fit);

/* Renders a Lambertian sphere of the given albedo under `hdri` with the
 * validation camera and solves the per-channel gains that make it match
 * the photographed sphere: per channel the median photo/render ratio, then
 * the least-squares ratio over pixels within 20% of it. Rendering is
 * linear in the dome, so the calibrated render is the render times gain. */
sl_result sl_grey_sphere_fit(const sl_image *hdri, const sl_image *photo, const sl_grey_options *o,
                             sl_grey_fit *fit, sl_error *err);

/* Adds a "Calibration" section to a report: the chart's per-patch table
 * (pixels, clipped, CIEDE2000 before and after) and the grey sphere's
 * photo, calibrated render and error images with their numbers. Either
 * part may be NULL. Image files are prefixed with `prefix`. */
sl_result sl_calibrate_report(sl_report *rep, const char *prefix, const sl_chart_patch *patches,
                              const sl_ccm_fit *chart, const sl_grey_fit *grey, sl_error *err);

#ifdef __cplusplus
}
#endif

#endif /* SETLIGHT_STITCH_H */
