/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * setlight stitch: bracketed exposures to HDR radiance (merge), chrome-ball
 * and fisheye views to lat-long (unwrap), and calibration against the grey
 * sphere and the Macbeth chart (calibrate).
 *
 * Map: one section per stage, in pipeline order, each under a banner
 * comment; its entry calls; its sources.
 *   Merge: brackets to HDR radiance   sl_merge, sl_merge_to_exr, sl_response_*,
 *                                     sl_align_bracket  merge*.c response*.c align.c
 *   Unwrap: chrome ball to lat-long   sl_unwrap, sl_unwrap_pair, sl_ball_detect
 *                                     unwrap*.c ball_detect*.c fisheye_check.c
 *   Calibrate: grey sphere and chart  sl_ccm_fit_chart, sl_grey_sphere_fit,
 *                                     sl_chart_detect, sl_sun_repair_fit
 *                                     calibrate*.c chart_*.c
 *   Stitch: views, solve, image circle, lens from EXIF, lens profiles,
 *   lens-calibrate, blend and the stitch call
 *                                     sl_stitch, sl_stitch_solve, sl_stitch_blend,
 *                                     sl_lens_profile_read, sl_lens_calibrate
 *                                     stitch*.c lens_*.c warp_reader.c
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

/* A Gaussian prior on curve shapes for the self-calibrated fit: the mean
 * and top principal components of ln f^-1(z) - ln f^-1(z_mid) over a set of
 * curves (channel 0 of each), codes 0.02 and up (docs/merge.md "Real camera
 * curves"). `name` is what the merge's report calls it. */
typedef struct sl_response_prior sl_response_prior;
sl_result sl_response_prior_build(const sl_response *curves, int count, int components,
                                  const char *name, sl_response_prior **out, sl_error *err);
void sl_response_prior_free(sl_response_prior *prior);
/* A curve's squared Mahalanobis distance from the prior's mean shape, per
 * covered node (about 1 for a curve drawn from the prior). */
double sl_response_prior_distance(const sl_response_prior *prior, const sl_response *curve,
                                  int channel);

/* AUTO: Debevec-Malik from the bracket; ROBERTSON: Robertson-Borman-Stevenson. */
typedef enum {
    SL_RESPONSE_LINEAR = 0,
    SL_RESPONSE_AUTO,
    SL_RESPONSE_GIVEN,
    SL_RESPONSE_ROBERTSON
} sl_response_mode;
typedef enum { SL_EXPOSURES_EXIF = 0, SL_EXPOSURES_DATA } sl_exposure_source;
/* Samples of the radiance EXR: auto is half where half loses nothing the
 * noise model would notice (docs/merge.md, "Output encoding"), else float. */
typedef enum { SL_MERGE_PIXELS_AUTO = 0, SL_MERGE_PIXELS_HALF, SL_MERGE_PIXELS_FLOAT } sl_merge_pixels;
/* Frame registration: OFF merges the frames as shot; ON registers them
 * (sl_align_bracket); AUTO (the default) measures the misalignment during
 * the sample pass on a reduced luminance image and registers the frames
 * when one moved by more than align_auto_px anywhere on the frame. ON is 1
 * so that code setting the former `bool align` to true still aligns. */
typedef enum { SL_ALIGN_OFF = 0, SL_ALIGN_ON = 1, SL_ALIGN_AUTO = 2 } sl_align_mode;

typedef struct sl_merge_options {
    const double *times;        /* seconds per frame in the given order; NULL: EXIF */
    sl_exposure_source exposures; /* which exposures the merge uses */
    sl_response_mode response_mode;
    const sl_response *response; /* for SL_RESPONSE_GIVEN */
    double smoothness;          /* Debevec-Malik lambda; 0: 10 (widest step / 3 stops)^1.5 */
    bool use_response_prior;    /* a prior on curve shapes in the self-calibrated fit (default
                                   off: docs/merge.md "Real camera curves") */
    const sl_response_prior *response_prior; /* that prior; NULL: the built-in one (the
                                                201 curves of Columbia's DoRF database) */
    double response_prior_weight; /* its strength against the data's noise model; 0: 1000 */
    bool refine_response;       /* refine the self-calibrated curve from 8-bit lossless
                                   frames by maximum likelihood under the noise (docs/merge.md
                                   "Refining the curve under the noise"); default off: it
                                   costs 1-2 s a bracket (setlight response turns it on) */
    int samples;                /* response samples per channel; 0: default 4000 */
    double noise_gain;          /* Poisson term: var(y) = gain * y + floor, y linear in [0, 1] */
    double noise_floor;         /*   0, 0: defaults 2e-5, 1e-6 (docs/merge.md) */
    double saturation;          /* z at or above which a sample is saturated; 0: from the
                                   frames: 0.95 through a curve from a lossy codec (JPEG rings
                                   a few codes below 255 inside clipped areas), 1 (the clip
                                   code) through a curve from lossless codes (PNG, TIFF) not
                                   resampled by alignment, 0.98 with SL_RESPONSE_LINEAR or
                                   files marked linear (raw) */
    double black;               /* z at or below which a sample has no weight; 0: 0.004 */
    double tolerance_stops;     /* EXIF vs data disagreement reported above; 0: 0.2 */
    uint64_t seed;              /* for sample positions */
    bool deghost;               /* leave out frames that disagree with the others */
    double deghost_sigma;       /* disagreement: beyond this many standard deviations (5) */
    double deghost_model_error; /* relative error added to the noise model (0.05) */
    bool absolute;              /* output in cd/m^2 from EXIF time, f-number and ISO:
                                   L = SL_MERGE_K_SAT * y * N^2 / (t * ISO) (docs/merge.md) */
    sl_align_mode align;        /* default SL_ALIGN_AUTO */
    double align_auto_px;       /* AUTO aligns beyond this displacement (default 0.5 px) */
    double align_max_shift;     /* pixels; larger shifts are refused (default 64) */
    double align_max_angle;     /* degrees; larger rotations are refused (default 2) */
    sl_merge_pixels pixels;     /* radiance EXR samples (default auto) */
    sl_exr_compression compression; /* radiance EXR compression (default ZIP) */
    double hold_mb;             /* integer frames kept decoded between the sample and merge
                                   passes, up to this many MB (default 384); the others
                                   are decoded twice */
} sl_merge_options;

/* ISO 12232 saturation-based speed: a sensor saturates at H = 78 / ISO lux s,
 * and H = q L t / N^2 with q = 0.65 (lens transmission, vignetting, cos^4 at
 * the centre), so a linear value y (1 = saturation) is L = 78 / q * y N^2 /
 * (t ISO) cd/m^2. 78 / 0.65 = 120. */
#define SL_MERGE_K_SAT 120.0

/* Fills the defaults above. */
void sl_merge_options_init(sl_merge_options *opt);

/* Where frame content sits relative to the reference frame: the scene point
 * at position p of the reference (pixels, top-left corner (0, 0)) is at
 * q = R(angle) (p - c) + c + (dx, dy) in the frame, c the image centre and
 * R a rotation by `angle` degrees from +x towards +y (clockwise on screen). */
typedef struct sl_align_transform {
    double dx, dy, angle;
    int64_t pixels;   /* pixels the estimate rests on (alignment resolution) */
    bool applied;     /* false: left as it is (reference, nothing to go on, or not needed) */
    bool refused;     /* no estimate: too few usable pixels or beyond the limits (note) */
    /* The shift and angle the fits' typical residuals amount to (rms residual
     * over rms derivative, chained from the reference): smooth content or a
     * poor tone match make them large; motion within twice them is doubtful. */
    double shift_spread_px, angle_spread_deg;
    char note[96];    /* why not applied, "" otherwise */
} sl_align_transform;

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
    sl_align_transform align;        /* measured or registered (not with SL_ALIGN_OFF) */
} sl_merge_frame;

/* Where a merge's time went. Each phase has wall seconds and CPU seconds
 * of every thread (per-thread CPU clocks around each task); where threads
 * do two phases at once (decoding the next strip while merging this one)
 * the wall is split by their CPU shares. The phases add up to `seconds`
 * and to the process CPU time the merge took: what no phase claims
 * (opening files, thread start-up, waiting) is "other". */
typedef enum sl_merge_phase {
    SL_MERGE_DECODE,  /* reading and decoding the frames */
    SL_MERGE_SAMPLE,  /* the sample pass's own work: counts, block maxima, samples */
    SL_MERGE_FIT,     /* response, exposure check, encoding choice */
    SL_MERGE_PIXELS,  /* the merge arithmetic: tables and weighted sums */
    SL_MERGE_WRITE,   /* converting, compressing and writing the EXRs */
    SL_MERGE_ALIGN,   /* measuring and estimating the frames' misalignment (not the
                         decoding the sample pass does anyway) */
    SL_MERGE_OTHER,
    SL_MERGE_PHASES
} sl_merge_phase;

typedef struct sl_merge_timing {
    double wall[SL_MERGE_PHASES], cpu[SL_MERGE_PHASES];
} sl_merge_timing;

/* Phase names for reports: "decode", "sample", "fit", "merge", "write", "align",
 * "other". */
const char *sl_merge_phase_name(sl_merge_phase phase);

/* How far to trust the response (merge_judge.c): increasing, and the
 * frames, linearised through it and divided by their exposures, agreeing on
 * each sample pixel's radiance (well-exposed samples; deviations from the
 * pixel's mean log radiance, in stops). Not plausible: not monotone, or the
 * frames disagree by more than 0.1 stops RMS; the merge then warns. */
typedef struct sl_merge_response_check {
    bool monotone;
    bool plausible;
    double frame_rms_stops, frame_p90_stops;
    int64_t compared; /* frame values compared */
    char note[200];
} sl_merge_response_check;

typedef struct sl_merge_result {
    sl_image radiance;          /* RGB, relative radiance (the reference frame's scale), or
                                   absolute (cd/m^2) with options.absolute */
    sl_image clipped;           /* RGB, 1 where the channel is saturated in every frame */
    sl_image ghost;             /* with deghost: 1 channel, 1 where a frame was left out */
    sl_response response;
    sl_merge_response_check response_check;
    /* The curve-shape prior of the self-calibrated fit ("" when none), and
     * whether it was dropped: the curve fitted without it was further from
     * it than any of its own curves' (response_prior_distance[0]; [1]: the
     * curve fitted with it; sl_response_prior_distance, 0 when not fitted). */
    char response_prior[64];
    bool response_prior_dropped;
    double response_prior_distance[2];
    /* The self-calibrated curve refined by maximum likelihood under the
     * sensor's noise: done or why not, the series it used, the fitted noise
     * law per channel (var = gain * y + floor, y on the curve's 0..1 scale),
     * the log-likelihood gained and the largest change of ln g it made. */
    bool response_refined;
    char response_refine_note[96];
    int response_refine_series;
    double response_refine_gain_nats;
    double response_refine_moved;
    double response_noise_gain[3], response_noise_floor[3];
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
    /* Provenance: what scaled and weighted the merge. */
    double output_exposure;     /* radiance = y / e * output_exposure: the reference
                                   frame's exposure, or SL_MERGE_K_SAT when absolute */
    bool absolute;              /* radiance in cd/m^2 (green = luminance for a camera whose
                                   green is luminance); else relative */
    double noise_gain, noise_floor, black, saturation;
    int width, height;          /* of the frames and the radiance */
    /* The photos' lens EXIF, carried into the merged EXR (0 or "" when
     * absent); every frame of the bracket agrees. */
    double focal_length_mm;
    char camera_make[64], camera_model[64], lens_model[128];
    /* Radiance EXR encoding: samples and compression, and why. */
    sl_pixel_type pixel_type;
    sl_exr_compression compression;
    double max_value;           /* bound on any merged value: the brightest code of the
                                   shortest frame; 0 when unbounded (float frames) */
    char encoding_note[160];
    int held_frames;            /* frames decoded once (kept between the passes) */
    /* Alignment: the mode asked for, the largest displacement of any frame
     * against the reference anywhere on the frame (px; -1 when not
     * measured), whether the frames were registered, and why in words. */
    sl_align_mode align_mode;
    double misalignment_px;
    bool aligned;
    char align_note[160];
    double align_measure_cpu;   /* CPU seconds of the measurement alone (AUTO): adding up
                                   luminance in the sample pass and the estimate */
    double seconds;             /* wall */
    double cpu_seconds;         /* CPU of every thread */
    sl_merge_timing timing;
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
/* Registers the frames of a bracket (median-threshold bitmaps over an image
 * pyramid, then Gauss-Newton refinement of translation and rotation to a
 * fraction of a pixel) on their luminance, each frame against its
 * neighbour in exposure with the tones matched through the two frames'
 * histograms, chained to the reference (the median exposure). Pixels
 * saturated or black in either frame take no part, so mostly clipped or
 * dark frames are left unaligned with a note rather than given a false
 * shift. exposures: any positive value per frame that orders them.
 * out[i] for frame i; opt gives black, saturation and the limits. */
sl_result sl_align_bracket(const char *const *paths, int count, const double *exposures,
                           const sl_merge_options *opt, sl_align_transform *out, sl_error *err);
/* How far a transform moves the farthest point of a width x height frame
 * (px): the shift plus the rotation's reach at the corners. */
double sl_align_displacement(const sl_align_transform *t, int width, int height);
/* The same counting only the motion beyond twice its spread: the shift if
 * |shift| > 2 shift_spread_px, the rotation's reach if |angle| > 2
 * angle_spread_deg (what SL_ALIGN_AUTO compares with align_auto_px). */
double sl_align_sure_displacement(const sl_align_transform *t, int width, int height);

/* Writes the radiance EXR (res->pixel_type, res->compression) with provenance attributes and, when
 * mask_path / ghost_path are not NULL, the clipped mask (RGB) and the ghost
 * mask (Y, needs a deghosted result) beside it, each atomically; on failure
 * none of them is left. */
sl_result sl_merge_write(const char *path, const char *mask_path, const char *ghost_path,
                         const sl_merge_result *res, sl_error *err);
/* sl_merge and sl_merge_write in one pass: each strip is written as soon
 * as it is merged, so memory is a strip per frame, not the radiance;
 * out->radiance, clipped and ghost stay empty. The same pixels and
 * attributes as the two calls. */
sl_result sl_merge_to_exr(const char *const *paths, int count, const sl_merge_options *opt,
                          const char *path, const char *mask_path, const char *ghost_path,
                          sl_merge_result *out, sl_error *err);

/* ---- The merge stage, files to files ---- */

typedef struct sl_merge_run_options {
    const char *const *frame_paths; /* the bracket, any order */
    int frame_count;
    const char *out_path;           /* the radiance EXR (merge) or the response JSON (response) */
    const char *mask_path;          /* NULL: OUT_clipped.exr beside the output */
    bool no_mask;                   /* no clipped mask */
    const char *ghost_path;         /* with merge.deghost; NULL: OUT_ghost.exr */
    sl_merge_options merge;         /* sl_merge_options_init */
} sl_merge_run_options;

void sl_merge_run_options_init(sl_merge_run_options *o);

typedef struct sl_merge_run_result {
    sl_merge_result merge;          /* every number (radiance and masks stay empty) */
    char mask_path[4096], ghost_path[4096]; /* as written ("" none) */
    char *json;                     /* what `merge --json` (`response --json`) prints (owned) */
} sl_merge_run_result;

/* sl_merge_to_exr with the masks' default names beside the output; logs
 * each frame's alignment and exposure warnings and the summary line. The
 * files are written atomically with their provenance (docs/merge.md); on
 * failure none is left and earlier ones stay. */
sl_result sl_merge_run(const sl_merge_run_options *o, sl_merge_run_result *res, sl_error *err);
/* The response alone (sl_merge_response) written to o->out_path as JSON. */
sl_result sl_response_run(const sl_merge_run_options *o, sl_merge_run_result *res, sl_error *err);
void sl_merge_run_result_free(sl_merge_run_result *res);

/* ================================================================== */
/* Unwrap: chrome ball to lat-long                                     */
/* ================================================================== */

/* The ball's outline in the photo, in pixels of the full image: the image's
 * top-left corner is (0, 0) and pixel (i, j) has its centre at
 * (i + 0.5, j + 0.5). */
typedef struct sl_ball_circle {
    double cx, cy, r;
    double residual;  /* RMS distance (px) of the edge points to the circle; 0 if given */
    int edge_points;  /* sub-pixel edge points the fit used; 0 if given */
    double uncertainty; /* largest standard error (px) of cx, cy and r; 0 if given */
} sl_ball_circle;

/* Finds one chrome ball: circle candidates on a copy at most 640 px across
 * (the frame itself, for a tight crop, and OpenCV's Hough transform on a
 * log-tonemapped copy), sub-pixel edge points along rays from each
 * candidate's centre and a robust least-squares circle fit; outlines with a
 * flat inside (discs, dials) or a circle on the same centre (rings) are not
 * balls, circles inside a ball are its reflections, and the largest ball is
 * taken when the others are under 0.7 of its radius. The ball's outline is
 * fitted again on the full image. SL_ERR_INPUT when no ball is found, when
 * two or more similar ones are, when the ball is cut by the frame edge
 * (circle then holds the clipped ball's outline) or when its outline is
 * measured too weakly (standard error over 0.25 px and 0.1% of the radius);
 * `name` (a file name) starts the message. */
sl_result sl_ball_detect(const sl_image *photo, const char *name, sl_ball_circle *circle,
                         sl_error *err);

/* What tells a circular fisheye photo from a chrome ball or an angular map:
 * a fisheye's image circle sits on a black frame with a dark band on every
 * side and its light falls off toward the edge; a ball sits in the set (the
 * frame around it is the scene) with a bright Fresnel rim; angular and
 * mirror-ball maps are dark outside but fill their square frame. */
typedef struct sl_fisheye_evidence {
    double border_level; /* frame border's 90th percentile / the centre's median */
    bool round;          /* a bright disc on a dark frame was found */
    double cx, cy, r;    /* its outline (px), when round */
    double dark_outside; /* fraction of the frame beyond the disc that is dark */
    double margin;       /* narrowest dark band between the disc and a frame side, in radii */
    double rim_ratio;    /* luminance at 0.95-0.985 radii over that at 0.80-0.90 */
    bool map;            /* looked like a fisheye but is lit to its square frame's
                            edge on black: a map (see sl_probe_map_check) */
    bool fisheye;
} sl_fisheye_evidence;

/* Fills ev; SL_ERR_INPUT ("NAME: looks like a circular fisheye image ...;
 * use 'setlight stitch'") when the photo is a circular fisheye's. srgb: the
 * pixels are sRGB-encoded (linearised for the measurement). */
sl_result sl_fisheye_check(const sl_image *photo, bool srgb, const char *name,
                           sl_fisheye_evidence *ev, sl_error *err);

/* Is this image a light-probe map (angular or mirror-ball) rather than a
 * photo of a ball? A map is a disc inscribed in its square frame with every
 * pixel beyond it black (remapping leaves nothing there); a photo, even
 * cropped to the ball, shows the set in its corners. Sets *is_map; when it
 * is one, SL_ERR_INPUT ("NAME: a disc filling its frame on pure black is a
 * light-probe map, ...") naming 'setlight convert --from angular'. */
sl_result sl_probe_map_check(const sl_image *photo, const char *name, bool *is_map,
                             sl_error *err);

typedef enum {
    SL_BALL_ORTHOGRAPHIC = 0, /* camera infinitely far: the classic mirror-ball map */
    SL_BALL_PERSPECTIVE       /* pinhole camera at a finite distance */
} sl_ball_camera;

/* How the photo was taken. The camera frame looks along +Z with +Y up and
 * image right -X (the renderer's validation camera); azimuth, elevation and
 * roll place it in the set: world = Ry(azimuth) Rx(-elevation) Rz(roll) cam,
 * so azimuth +90 looks along +X, elevation +90 looks up (+Y), and a positive
 * roll turns the camera's up toward its right. */
typedef struct sl_ball_geometry {
    sl_ball_camera camera;
    /* Perspective only. focal_px: the focal length in pixels of this image
     * (focal_mm * image_width / sensor_width_mm), principal point at the image
     * centre; with it the ball may sit anywhere in the frame and its distance
     * comes from its apparent size. distance: camera to ball centre in ball
     * radii (distance_mm / (diameter_mm / 2)); overrides the apparent size.
     * At least one must be > 0; with only the distance the ball is taken to
     * be on the optical axis. */
    double focal_px;
    double distance;
    double azimuth_deg, elevation_deg, roll_deg;
} sl_ball_geometry;

/* A ball photo's camera as a user states it (unwrap's and calibrate's
 * options): the model, the lens, the distance. 0: not given. */
typedef struct sl_ball_lens {
    int camera; /* sl_ball_camera, or -1: perspective when anything gives the geometry */
    double focal_mm, sensor_mm, fov_deg, distance_mm, diameter_mm;
} sl_ball_lens;

void sl_ball_lens_init(sl_ball_lens *lens); /* camera -1, the rest 0 */
/* For a photo `width` pixels wide: the focal length in pixels (the lens,
 * the EXIF focal length when only the sensor width is given, or the field
 * of view; 0 unknown) and the distance in ball radii (0 unknown). */
void sl_ball_lens_geometry(const sl_ball_lens *lens, int width, double exif_focal_mm,
                           double *focal_px, double *distance);

typedef enum {
    SL_REFLECTANCE_CONSTANT = 0, /* R per channel at every angle (1 = ideal mirror) */
    SL_REFLECTANCE_CONDUCTOR     /* exact unpolarised Fresnel of a metal, n + ik per channel */
} sl_reflectance_kind;

typedef struct sl_reflectance {
    sl_reflectance_kind kind;
    double value[3];
    double n[3], k[3];
} sl_reflectance;

void sl_reflectance_constant(sl_reflectance *refl, double r, double g, double b);
/* A neutral conductor n = 3.2, k = 3.3: 0.55 at normal incidence rising to
 * 1 at grazing, typical of chrome-plated balls. */
void sl_reflectance_chrome(sl_reflectance *refl);
/* Reflectance per channel for the cosine of the angle of incidence. */
void sl_reflectance_eval(const sl_reflectance *refl, double cos_incidence, double out[3]);

/* The mapping between set directions and photo pixels for one ball photo. */
typedef struct sl_ball_view {
    sl_ball_camera camera;
    int width, height;         /* photo size */
    double cx, cy, r;          /* the circle */
    double focal_px;           /* perspective: the pinhole used */
    double distance;           /* perspective: camera to centre in ball radii; 0 orthographic */
    double ball_angle;         /* angular radius of the ball seen from the camera (rad) */
    double off_axis;           /* angle between the optical axis and the ball centre (rad) */
    double phi_max;            /* largest angle from the view axis's reverse seen: pi - ball_angle */
    double cam_to_world[3][3];
    double view_to_cam[3][3];  /* view frame: +Z from the camera through the ball centre */
    double theta_table[1025];  /* sphere angle for reflected angle, uniform in [0, phi_max] */
    double centre_px_per_rad;  /* photo resolution where the ball reflects back at the camera */
} sl_ball_view;

/* SL_ERR_USAGE when the circle is not inside the photo or the perspective
 * model lacks focal length and distance. */
sl_result sl_ball_view_init(sl_ball_view *view, int width, int height, const sl_ball_circle *c,
                            const sl_ball_geometry *g, sl_error *err);
/* Set direction -> photo pixel (x, y) on the ball and the cosine of the
 * angle of incidence there. Directions in the blind cone behind the ball
 * return false and the rim point of the same azimuth. */
bool sl_ball_view_dir_to_pixel(const sl_ball_view *view, const double dir[3], double *x,
                               double *y, double *cos_incidence);
/* Photo pixel -> reflected set direction; false off the ball. */
bool sl_ball_view_pixel_to_dir(const sl_ball_view *view, double x, double y, double dir[3],
                               double *cos_incidence);
/* Photo pixels per radian of set direction along the direction of least
 * resolution (the smaller singular value of the mapping); 0 in the blind cone. */
double sl_ball_view_resolution(const sl_ball_view *view, const double dir[3]);

typedef struct sl_unwrap_options {
    sl_ball_circle circle;
    sl_ball_geometry geometry;
    sl_reflectance reflectance;
    int width; /* output lat-long width; 0 = matched to the ball's resolution */
    /* RGB only (3 channels): the confidence is neither computed nor stored.
     * sl_unwrap_pair ignores it (its merge weights are the confidences). */
    bool no_confidence;
} sl_unwrap_options;

typedef struct sl_unwrap_info {
    int width, height;
    double distance;          /* camera distance in ball radii; 0 orthographic */
    double focal_px;
    double ball_angle_deg;    /* angular radius of the ball seen from the camera */
    double blind_angle_deg;   /* half-angle of the cone behind the ball the photo cannot see */
    double off_axis_deg;
    double centre_px_per_rad;
    double blind_fraction;    /* of the sphere's solid angle */
    int64_t nonfinite;        /* NaN/Inf photo samples replaced by 0 */
} sl_unwrap_info;

/* Unwraps a linear HDR photo of a chrome ball into a lat-long of the set's
 * radiance (OpenEXR orientation), 4 channels: RGB and a confidence in [0, 1]
 * (the resolution relative to the ball's centre; 0 in the blind cone, where
 * RGB is a smooth fill from the rim, never detail); 3 with no_confidence.
 * Each output texel is the solid-angle-weighted average of the photo over its
 * footprint, sampled finely enough that bright sources do not alias. Pixels
 * are divided by the reflectance at their angle of incidence. info may be
 * NULL. */
sl_result sl_unwrap(const sl_image *photo, const sl_unwrap_options *opt, sl_image *out,
                    sl_unwrap_info *info, sl_error *err);

/* Where sl_unwrap_stream hands the lat-long over. */
typedef struct sl_unwrap_sink {
    /* Once, before any row: the size and geometry (info), and the channels
     * per texel (3, or 4 with the confidence). */
    sl_result (*begin)(void *user, const sl_unwrap_info *info, int channels, sl_error *err);
    /* The next `count` rows in order, width * channels floats each,
     * `stride` floats apart; valid during the call only. */
    sl_result (*rows)(void *user, const float *rows, int count, size_t stride, sl_error *err);
    void *user;
} sl_unwrap_sink;

/* sl_unwrap a strip of rows at a time into a sink (e.g. an sl_exr_stream):
 * the same texels, without the whole lat-long in memory. A sink's failure
 * stops the unwrap and is returned. */
sl_result sl_unwrap_stream(const sl_image *photo, const sl_unwrap_options *opt,
                           const sl_unwrap_sink *sink, sl_unwrap_info *info, sl_error *err);

/* Two photos of the same ball from different places (about 90 degrees
 * apart around the ball is best). */
typedef struct sl_unwrap_pair_options {
    sl_unwrap_options views[2]; /* the same width (0: the larger default) */
    /* View 2's azimuth is searched within +-search_deg of the given one
     * for the best agreement of the two unwraps where both are confident;
     * 0: taken as given. */
    double search_deg;
    /* Half-angle of the cone around each camera's direction (the camera
     * and photographer reflected at the ball's centre) left to the other
     * view wherever it sees it; 0: none. */
    double occluder_deg;
} sl_unwrap_pair_options;

typedef struct sl_unwrap_pair_info {
    sl_unwrap_info views[2];
    double azimuth_given_deg, azimuth_deg; /* view 2's, as given and as used */
    /* Median |log| luminance ratio of the two views in the overlap (both
     * confidences >= 0.25, outside both occluder cones), at the given and
     * the used azimuth. */
    double residual_given, residual;
    double overlap_fraction; /* of the sphere's solid angle */
} sl_unwrap_pair_info;

/* Unwraps both photos and merges them into one lat-long (RGB and
 * confidence), weighting each texel by each view's confidence, with each
 * occluder cone given to the other view. info may be NULL. */
sl_result sl_unwrap_pair(const sl_image *photo1, const sl_image *photo2,
                         const sl_unwrap_pair_options *opt, sl_image *out,
                         sl_unwrap_pair_info *info, sl_error *err);

/* The ball's reflectance from a patch of known radiance: the mean of an
 * unwrap made with reflectance 1 (RGB and confidence) over the cone of
 * half-angle radius_rad around dir, divided by the patch's radiance, per
 * channel. SL_ERR_INPUT when the patch is not seen with confidence >= 0.25
 * over at least 90% of it, or is black. */
sl_result sl_unwrap_patch_reflectance(const sl_image *latlong, const double dir[3],
                                      double radius_rad, const double radiance[3],
                                      double reflectance[3], sl_error *err);

/* ---- The unwrap stage, files to files ---- */

typedef struct sl_unwrap_run_options {
    const char *photo_paths[2];   /* the ball photos (read scene-linear, as every command reads) */
    int photo_count;              /* 1 or 2 (the same ball from about 90 degrees round it) */
    const char *out_path;         /* the lat-long EXR */
    const char *input_colorspace; /* NULL: the file's own, else sRGB for 8/16-bit */
    /* views[0]: camera angles, reflectance (1), width (0: one texel per
     * photo pixel at the ball's centre) and, when have_circle[0], the circle;
     * views[1]: its circle when have_circle[1]; search_deg (20),
     * occluder_deg (20). View 2's camera is view 1's turned 90 degrees in
     * azimuth unless have_camera2[k] gives azimuth, elevation, roll. */
    sl_unwrap_pair_options pair;
    bool have_circle[2];
    bool have_camera2[3];
    double camera2[3];
    sl_ball_lens camera;          /* the photos' camera model, lens and distance */
    bool have_patch;              /* solve the reflectance from a patch of known radiance: */
    double patch[6];              /* azimuth, elevation, radius (degrees), radiance R, G, B */
    bool confidence;              /* write the confidence as alpha (true) */
    bool write_float;             /* 32-bit float instead of half */
    sl_exr_compression compression; /* ZIP */
} sl_unwrap_run_options;

void sl_unwrap_run_options_init(sl_unwrap_run_options *o);

typedef struct sl_unwrap_run_result {
    sl_unwrap_pair_info info;     /* views[0] (and views[1]); the pair's numbers with two */
    sl_ball_circle circle[2];     /* as used */
    bool detected[2];             /* found by sl_ball_detect rather than given */
    sl_ball_camera camera;
    int width, height;            /* of the lat-long */
    sl_reflectance reflectance;   /* as used (solved from the patch when given) */
    double patch_reflectance[3];
    bool streamed;                /* rows written as they were unwrapped */
    bool ldr_linearised;          /* an 8/16-bit photo was linearised */
    double seconds, read_detect_s, read_detect_cpu, unwrap_s, unwrap_cpu, write_s, write_cpu;
    char *json;                   /* what `unwrap --json` prints (owned) */
} sl_unwrap_run_result;

/* Reads the photos, finds the ball unless given, unwraps (one view, or two
 * merged), solves the reflectance from the patch when asked and writes
 * the lat-long atomically with its provenance (setlight:source,
 * setlight:ball_circle, setlight:ball_camera, ...; docs/unwrap.md): on
 * failure no output and an earlier file stays. SL_ERR_USAGE for a given
 * circle outside the photo; SL_ERR_INPUT for a fisheye photo, no ball or
 * several, a patch not seen. */
sl_result sl_unwrap_run(const sl_unwrap_run_options *o, sl_unwrap_run_result *res,
                        sl_error *err);
void sl_unwrap_run_result_free(sl_unwrap_run_result *res);

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
 * remain, more than 5% of its disc is clipped, or the kept pixels' relative
 * spread exceeds SL_CHART_MAX_SPREAD (a shadow edge or glare across it). */
#define SL_CHART_MAX_SPREAD 0.15
sl_result sl_chart_sample(const sl_image *img, const double centers[24][2], double radius_px,
                          double clip_level, sl_chart_patch patches[24], sl_error *err);

/* A clip level the file does not state: per channel (RGB), the image's
 * largest finite value when at least 16 pixels (and 0.1% of them) hold
 * exactly it, as a saturated sensor or a merge's clipped bound leaves
 * them; else 0. Returns the pixels at or above a found level. */
int64_t sl_pinned_maximum(const sl_image *img, double level[3]);

typedef struct sl_ccm_options {
    /* Constrain the fit so that the neutral patch maps exactly onto its
     * reference: neutrals stay neutral. */
    bool white_preserving;
    int neutral_patch; /* 0-based; -1: the brightest valid of patches 19..24 */
    /* Patches lit differently from the rest (part of the chart in shadow,
     * glare): after a first fit, only the largest group whose fitted /
     * reference luminance ratios agree within this factor is kept, and the
     * fit redone (up to 3 rounds). 0 or 1: off. Default 1.5. */
    double outlier_ratio;
} sl_ccm_options;

/* Not white-preserving, neutral -1, outlier_ratio 1.5. */
void sl_ccm_options_init(sl_ccm_options *o);

typedef struct sl_ccm_fit {
    double m[3][3];      /* working-space RGB = m * camera RGB */
    double gain;         /* cbrt(det m): the matrix's overall scale */
    int used;            /* patches in the fit */
    bool used_patch[24];
    bool outlier[24];    /* valid, but left out as lit differently (shadow, glare) */
    int outliers;
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

/* The matrix used downstream (the plate matrix): fit->m scaled so the
 * neutral patch (the constraint's, else the first used of 22, 21, 20, 19:
 * neutral 3.5 upward, white last as it clips first) keeps its luminance, since the chart's light level is unknown; exposure
 * is left to the grey sphere. */
void sl_ccm_plate_matrix(const sl_chart_patch patches[24], const sl_ccm_fit *fit,
                         double plate[3][3]);

typedef enum {
    SL_CHART_SPACE_LAB_D50 = 0, /* CIELAB, D50 white (as X-Rite publishes) */
    SL_CHART_SPACE_XYZ_D50,     /* CIE XYZ under D50, white Y = 1 or 100 */
    SL_CHART_SPACE_LIN_REC709   /* linear Rec.709 (D65), the working space */
} sl_chart_space;

/* Reads 24 reference values in chart order (docs/calibrate.md): CSV with a
 * header row "L,a,b", "X,Y,Z" or "R,G,B" (an extra first column, e.g. the
 * patch name, allowed), or JSON {"space": "lab_d50" | "xyz_d50" |
 * "lin_rec709", "patches": [[v1, v2, v3] x 24]}; "#" lines are comments.
 * Converted to linear Rec.709 (Bradford D50 -> D65). SL_ERR_NOT_FOUND when
 * missing; SL_ERR_INPUT naming the file and line when malformed. space
 * may be NULL. */
sl_result sl_chart_reference_read(const char *path, double reference[24][3], sl_chart_space *space,
                                  sl_error *err);

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

/* Judging a chart fit (sl_chart_judge): what a ColorChecker in one light,
 * photographed by a camera, must look like. */
#define SL_CHART_MIN_USED 12          /* patches under one light: most of the chart */
#define SL_CHART_MAX_CONTRAST_ERROR 2.0 /* neutral row's log contrast vs the reference's */
#define SL_CHART_MIN_CHROMA_RATIO 3.0 /* colour patches' saturation over the neutrals' */
#define SL_CHART_MAX_CONDITION 50.0   /* the colour matrix's sigma_max / sigma_min */

enum {
    SL_CHART_FEW_PATCHES = 1 << 0, /* fewer than SL_CHART_MIN_USED patches in the fit */
    SL_CHART_NEUTRALS = 1 << 1,    /* neutral row unusable, out of order or of the wrong contrast */
    SL_CHART_COLOURS = 1 << 2,     /* colour patches grey, unusable or out of hue order */
    SL_CHART_MATRIX = 1 << 3,      /* no camera's matrix: swaps colours, ill-conditioned */
    SL_CHART_DELTA_E = 1 << 4      /* far from the reference even after the fit */
};

typedef struct sl_chart_judgement {
    bool plausible;        /* no reason below */
    unsigned reasons;      /* SL_CHART_* bits */
    int used;              /* patches in the fit */
    int neutrals_used;     /* of patches 19..24 */
    int order_breaks;      /* neutral steps that do not get darker */
    double neutral_slope;  /* d log(measured) / d log(reference) over the used neutrals */
    int colours_usable;    /* of patches 13..18 */
    double colour_chroma;  /* the least saturation among them, white-balanced on the neutrals */
    double neutral_chroma; /* the median among the used neutrals */
    int hue_turns;         /* their hues in the reference's order go round this often (1) */
    double condition;      /* of the fitted matrix */
    double de_after_mean;
    double de_limit;       /* sl_chart_identity_delta_e of the reference */
    char text[640];        /* every reason, "; "-separated; empty when plausible */
} sl_chart_judgement;

/* Judges a chart fit (patches as sampled, the fit, its reference): refuses
 * it when fewer than SL_CHART_MIN_USED patches share one light, fewer than
 * 3 neutrals are used or they do not darken patch by patch from white to
 * black, their log contrast is off the reference's by more than
 * SL_CHART_MAX_CONTRAST_ERROR either way, the colour patches 13..18
 * (white-balanced on the neutrals) are not SL_CHART_MIN_CHROMA_RATIO times
 * as saturated as the neutrals or not in the reference's hue order, the
 * matrix has determinant <= 0, condition above SL_CHART_MAX_CONDITION or
 * sends white below zero, or the mean CIEDE2000 after the fit exceeds sl_chart_identity_delta_e.
 * Every reason is listed in text. */
/* The median over the reference's patches of the CIEDE2000 to the nearest
 * other patch (13.1 for the ColorChecker Classic): a fit no closer than
 * that has not told the patches apart. */
double sl_chart_identity_delta_e(const double reference[24][3]);
void sl_chart_judge(const sl_chart_patch patches[24], const sl_ccm_fit *fit,
                    const double reference[24][3], sl_chart_judgement *j);

typedef struct sl_grey_options {
    double albedo;          /* the photographed sphere's albedo (0.18) */
    double circle[3];       /* sphere outline in the photo: cx, cy, r (pixels) */
    double azimuth_deg, elevation_deg; /* the photo's view, as sl_camera_validation */
    double inner;           /* use pixels within this fraction of the radius (0.85) */
    int size;               /* virtual render, pixels across (0: 2r, at most 128) */
    int64_t spp;            /* samples per pixel of the virtual render (256) */
    uint64_t seed;
    double clip_level;      /* photo pixels at or above are ignored (0: none) */
    /* The photo's camera as in sl_ball_geometry: both 0 orthographic; else a
     * pinhole with focal_px (focal length in pixels of the photo, principal
     * point at its centre; the distance then follows from the circle) and/or
     * distance (camera to sphere centre in sphere radii; alone, the sphere is
     * on the optical axis). The virtual sphere is rendered from there. */
    double focal_px;
    double distance;
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
 * photo's camera geometry (the validation camera's view, orthographic or
 * the pinhole of o->focal_px / o->distance) and solves the per-channel gains that make it match
 * the photographed sphere: per channel the median photo/render ratio, then
 * the least-squares ratio over pixels within 20% of it. Rendering is
 * linear in the dome, so the calibrated render is the render times gain. */
sl_result sl_grey_sphere_fit(const sl_image *hdri, const sl_image *photo, const sl_grey_options *o,
                             sl_grey_fit *fit, sl_error *err);

/* Absolute calibration: the luminance (cd/m^2) of a linear value 1.0
 * (raw saturation) in a photo taken at this exposure, from ISO 12232's
 * saturation-based speed: L = 78 N^2 / (q S t), q = 0.65 (lens
 * transmission, cos^4 at the centre), i.e. 120 N^2 / (S t). 0 when any
 * value is missing (<= 0). */
double sl_exposure_luminance(double time_s, double f_number, double iso);

/* ---- Clipped-sun repair ---- */

typedef struct sl_sun_options {
    double diameter_deg; /* the clipped source's angular diameter (0.53: the sun) */
} sl_sun_options;

void sl_sun_options_init(sl_sun_options *o);

typedef struct sl_sun_repair {
    bool repaired;            /* false when the mask flags nothing (nothing done) */
    int64_t clipped_texels;   /* flagged in the mask (any channel >= 0.5) */
    double solid_angle;       /* of the flagged texels, sr */
    double direction[3];      /* their solid-angle-weighted centroid: the source's centre */
    double azimuth_deg, elevation_deg; /* of direction, lat-long convention */
    double source_solid_angle;  /* of the disc, sr */
    /* Radiances of the disc in the HDRI's units (before the gains): */
    double bound[3];          /* what the clipped map held above the sky (a lower bound) */
    double fitted[3];         /* the least-squares fit */
    double radiance[3];       /* written: fitted, but at least bound */
    double radiance_sigma[3]; /* standard error of fitted, from the fit's residuals */
    double gain[3];           /* the exposure gains fitted with it */
    double energy_before[3];  /* integral of the map over the sphere before, L * sr */
    double energy_added[3];   /* integral of what the repair added */
    double rel_rmse_before;   /* grey sphere, best gains under the clipped map */
    double rel_rmse_after;    /* best gains and the fitted source */
    int64_t pixels;           /* grey sphere pixels in the fit */
} sl_sun_repair;

/* Repairs a source clipped in every frame of the merge (`mask`: the merge's
 * clipped mask, the HDRI's size, any channel >= 0.5 flagged). The source is
 * a disc of o->diameter_deg at the flagged texels' centroid; the flagged
 * texels and those the disc touches are refilled with the mean of a ring
 * round them, then per channel photo = g * render(sky) + g * L * render(disc)
 * is solved by least squares over the grey sphere (options as for
 * sl_grey_sphere_fit; the photo in the HDRI's working space) and the disc
 * written into `hdri` at radiance L. With no flagged texel, nothing is done
 * (repaired false). SL_ERR_INPUT when the flagged texels are not one source,
 * the source does not light the visible side of the sphere, or no fit. */
sl_result sl_sun_repair_fit(sl_image *hdri, const sl_image *mask, const sl_image *photo,
                            const sl_grey_options *grey, const sl_sun_options *o,
                            sl_sun_repair *out, sl_error *err);

/* Adds a "Calibration" section to a report: the chart's per-patch table
 * (pixels, clipped, CIEDE2000 before and after) and the grey sphere's
 * photo, calibrated render and error images with their numbers. Either
 * part may be NULL. Image files are prefixed with `prefix`. */
sl_result sl_calibrate_report(sl_report *rep, const char *prefix, const sl_chart_patch *patches,
                              const sl_ccm_fit *chart, const sl_grey_fit *grey, sl_error *err);

/* Where the patches were found: the photo (linear) cropped to the patches
 * and two pitches round them, scaled to `width` pixels, the brightest
 * patch at 0.85; each sampled disc outlined and labelled with its number,
 * green when used, orange "L" when left out as lit differently, red when
 * excluded with its reason (C clipped, S not uniform, N too few pixels).
 * fit may be NULL (every patch red). */
sl_result sl_chart_overlay(const sl_image *photo, const sl_chart_patch patches[24],
                           const sl_ccm_fit *fit, int width, sl_image *out, sl_error *err);

/* Adds the chart's verdict (a ColorChecker, or the reasons it was refused)
 * and the overlay (768 px wide) as `file` to a report. */
sl_result sl_calibrate_report_chart(sl_report *rep, const char *file, const sl_image *photo,
                                    const sl_chart_patch patches[24], const sl_ccm_fit *fit,
                                    const sl_chart_judgement *judgement, sl_error *err);

/* Sets every negative sample of the colour channels to 0 (a colour matrix
 * sends colours outside the working gamut, and noise round black, below
 * zero) and returns how many; *fraction (may be NULL) gets their share of
 * the image's summed absolute values. */
int64_t sl_calibrate_clamp_negative(sl_image *img, double *fraction);

/* ---- The calibrate stage, files to files ---- */

typedef struct sl_calibrate_run_options {
    const char *hdri_path;       /* the lat-long to calibrate (read as sl_latlong_read) */
    const char *out_path;        /* the calibrated lat-long (EXR) */
    const char *chart_path;      /* chart photo, or NULL */
    const char *grey_path;       /* grey-sphere photo, or NULL; at least one of the two */
    const char *report_dir;      /* DIR/calibrate.html and DIR/calibrate.json, or NULL */
    const char *chart_reference; /* CSV or JSON file of 24 values; NULL: classic24 */
    const char *clipped_mask;    /* NULL: the HDRI's setlight:merge:clipped_mask if it exists */
    const char *out_colorspace;  /* OCIO name ("lin_rec709") */
    const char *chart_colorspace, *grey_colorspace; /* NULL: the file's own, else sRGB/linear */
    bool have_corners;           /* corners: centres of patches 1, 6, 24, 19 instead of detection */
    double corners[4][2];
    double clip;                 /* photo clip level; < 0: none for float, 0.999 for 8/16-bit (-1) */
    bool hdri_in_chart;          /* the HDRI is in the chart camera's RGB (true) */
    bool sun_repair;             /* repair a source clipped in every frame (true) */
    bool absolute;               /* cd/m^2 from the grey photo's EXIF (true) */
    double exposure_tolerance;   /* stops the grey photo's EXIF may disagree with the HDRI's (1) */
    bool write_float;            /* 32-bit float output instead of half */
    sl_ball_lens camera;         /* the grey photo's camera */
    sl_ccm_options ccm;
    sl_grey_options grey;        /* circle[2] > 0: the sphere's outline, else found */
    sl_sun_options sun;
} sl_calibrate_run_options;

void sl_calibrate_run_options_init(sl_calibrate_run_options *o);

typedef struct sl_calibrate_run_result {
    double matrix[3][3];         /* T: HDRI values to output values, as the metadata records */
    bool chart_used;             /* the chart was judged a ColorChecker and its matrix used */
    double plate_matrix[3][3];   /* P, when chart_used */
    bool hdri_in_chart;          /* P applied to the HDRI */
    bool chart_sampled;          /* chart and judgement hold a fit (used or refused) */
    sl_ccm_fit chart;
    sl_chart_judgement judgement;
    bool grey_used;
    double grey_circle[3], grey_gain[3];
    double grey_rel_rmse_before, grey_rel_rmse_after, grey_error_p95;
    int64_t grey_pixels;
    double scale;                /* exposure scale (1 without a grey sphere) */
    sl_sun_repair sun;           /* sun.repaired: a clipped source was repaired */
    double cd_m2_per_unit;       /* absolute scale applied, 0: relative units */
    char absolute_from[256];
    int64_t negative_samples;    /* samples set to 0 after the transform */
    double negative_fraction;
    char *json;                  /* every number above and more: what `calibrate --json`
                                  * prints and DIR/calibrate.json holds (owned) */
} sl_calibrate_run_result;

/* Reads the HDRI and the photos, calibrates (docs/calibrate.md), writes the
 * calibrated HDRI with its provenance (setlight:calibration_matrix, ...)
 * and the report as one output set: on failure every earlier output stays.
 * SL_ERR_INPUT with a message naming the file for input that does not fit
 * (no chart and no grey sphere usable, exposure contradiction, ...). Logs
 * warnings and one info line per part through sl_log. */
sl_result sl_calibrate_run(const sl_calibrate_run_options *o, sl_calibrate_run_result *res,
                           sl_error *err);
void sl_calibrate_run_result_free(sl_calibrate_run_result *res);

/* ================================================================== */
/* Stitch: views                                                       */
/* ================================================================== */

/* One fisheye (or rectilinear) view of a stitch: its merged HDR radiance,
 * the merge's per-pixel confidence and the lens and pose. All views of one
 * stitch share one lens (one camera body and lens); the solve writes the
 * solved lens into every view. */
typedef struct sl_stitch_view {
    const char *name;          /* file name, for messages */
    const sl_image *radiance;  /* RGB(A) scene-linear view, as merge writes it */
    const sl_image *weight;    /* optional per-pixel confidence in [0,1] (merge's masks), or NULL */
    sl_lens lens;              /* in: nominal or profile; out (solve): solved */
    sl_view_pose pose;         /* in: nominal; out (solve): solved */
} sl_stitch_view;

/* ================================================================== */
/* Stitch: solve                                                       */
/* ================================================================== */

/* What sl_stitch_solve solves. The poses of views 1.. are always solved
 * (view 0 fixes the frame) unless solve_poses is false; the lens values
 * each have a switch, so a lens profile can be kept as it is. */
typedef struct sl_stitch_solve_options {
    bool solve_poses;        /* yaw, pitch, roll of views 1..count-1 (default true) */
    bool solve_focal;        /* focal_px (default true) */
    bool solve_centre;       /* cx, cy (default true) */
    int radial_terms;        /* 0: keep k; 1: k1; 2: k1, k2 (default) */
    bool solve_vignette;     /* vignette v1, v2 from the overlaps' radiance ratios (default true) */
    const char *detector;    /* "sift" (default) or "akaze" */
    int feature_width;       /* features on copies this many pixels wide at most (default 1536) */
    int max_features;        /* per view (default 6000) */
    double circle_margin;    /* features kept this fraction of the circle radius inside it (0.02) */
    double ratio;            /* Lowe's ratio test (default 0.8) */
    double ransac_deg;       /* RANSAC inlier threshold, angle between the rays of the
                                nominal lens (default 2: the lens is not solved yet) */
    int ransac_iterations;   /* default 2000 */
    double inlier_px;        /* after the adjustment, a match is kept within this many
                                pixels of the features' copies (default 2) */
    int min_inliers;         /* a pair with fewer falls back to the nominal rotation (default 25) */
    /* The shared lens (focal, centre, radial terms) moves only when the
     * solved pairs' RANSAC inliers number at least min_lens_inliers
     * (default 30) and their points spread over the circle: RMS distance
     * from their centroid in their view at least min_lens_spread of the
     * circle radius (default 0.1: a cluster in one
     * spot is 0.05, one pair's crescent of overlap 0.15); else only the poses are solved and the
     * result says why (lens_held, lens_note). */
    int min_lens_inliers;
    double min_lens_spread;
    double max_correction_deg; /* a pair whose rotation differs more from the nominal one is
                                  refused as inconsistent and falls back; matches further
                                  than 1.5 times this from their nominal place are dropped
                                  (default 10) */
    uint64_t seed;           /* RANSAC sampling */
    /* The image circle is the lens's field stop, centred on its optical
     * axis: its centre measures the optical centre apart from the
     * overlaps. centre_from_circle (default true) weighs it into the
     * centre's solve by its own uncertainty, unless the overlaps' centre
     * disagrees with it beyond that (then the overlaps' alone; the result
     * says which). circles: each view's circle in the views' pixels
     * (count entries), or NULL: found by the solve (sl_stitch_circle_find). */
    bool centre_from_circle;
    const struct sl_stitch_circle *circles;
    /* A view (or group) no solved pair places is turned to where its
     * overlaps' radiance agrees with the placed views' once the lens and
     * vignetting are solved (default true), when its worst-determined axis
     * is known to radiance_max_sigma_deg (default 0.02); else it keeps its
     * nominal pose. */
    bool radiance_poses;
    double radiance_max_sigma_deg;
    /* The focal, radial terms, vignetting, rotations and gains refined
     * together by the solved pairs' smooth overlap radiance and the
     * matches, each weighed by its own scatter, after the vignetting fit
     * (default true): kept when the joint cost falls. */
    bool radiance_lens;
} sl_stitch_solve_options;

void sl_stitch_solve_options_init(sl_stitch_solve_options *o);

typedef enum {
    SL_STITCH_PAIR_SOLVED = 0,   /* its inliers are in the adjustment */
    SL_STITCH_PAIR_NO_OVERLAP,   /* the nominal poses do not overlap: not matched */
    SL_STITCH_PAIR_FEW_MATCHES,  /* fallback: too few inliers (a featureless pair) */
    SL_STITCH_PAIR_INCONSISTENT, /* fallback: its rotation is far from the nominal one */
    SL_STITCH_PAIR_RADIANCE      /* no features: placed from its overlap's radiance */
} sl_stitch_pair_status;

/* "solved", "no overlap", "too few matches", "inconsistent with the nominal poses",
 * "solved from radiance" */
const char *sl_stitch_pair_status_name(sl_stitch_pair_status s);

typedef struct sl_stitch_pair {
    int a, b;                    /* view indices, a < b */
    double overlap_sr;           /* solid angle both nominal views see, steradians */
    int matches;                 /* after the ratio test and the cross check */
    int inliers;                 /* after RANSAC on the sphere */
    sl_stitch_pair_status status;
    bool fallback;               /* its relative rotation is the nominal one */
    double rms_px, max_px;       /* reprojection error of its inliers after the adjustment */
    char why[160];               /* for a fallback: what was found, for the report */
} sl_stitch_pair;

typedef struct sl_stitch_solve_result {
    int views;
    sl_view_pose *pose_nominal;  /* views entries each */
    sl_view_pose *pose;          /* solved */
    double *gain;                /* per-view radiance gain solved with the vignetting (view 0: 1) */
    int *features;               /* features found per view */
    sl_lens lens_nominal;        /* the lens the solve started from (view 0's) */
    sl_lens lens;                /* solved */
    int pairs;
    sl_stitch_pair *pair;
    int pairs_solved, pairs_fallback;
    int pairs_radiance;          /* featureless pairs placed from their radiance instead */
    int inliers;                 /* matches in the adjustment */
    double rms_px, max_px;       /* reprojection error over them, pixels of the full views */
    int iterations;              /* Levenberg-Marquardt iterations */
    int lens_inliers;            /* the inliers the lens gate counted */
    double lens_spread;          /* their spread over the circle (see min_lens_spread) */
    bool lens_held;              /* the lens stayed nominal: too few or clustered inliers */
    char lens_note[200];         /* why it was held, for the report */
    bool vignette_solved;        /* false: too few overlap samples, or not asked */
    int vignette_samples;
    double vignette_rms_log;     /* RMS of the log radiance ratios after the fit */
    /* The lens refined by the overlaps' radiance: kept, its samples, the
     * log residual before and after, the focal's change by it. */
    bool radiance_lens;
    int radiance_lens_samples;
    double radiance_lens_rms[2];
    double radiance_lens_focal_change;
    /* The centre: from the image circles (their views, centre and one
     * standard deviation per axis), from the overlaps alone (and its
     * standard deviations), whether the circles' was used, and why (the
     * note gives no pixels: the solve may run on reduced copies). */
    int circle_views;
    double circle_centre[2], circle_sigma[2];
    double overlap_centre[2], overlap_sigma[2];
    bool centre_from_circle;
    char centre_note[320];

    double seconds_features, seconds_match, seconds_adjust, seconds_radiance, seconds_total;
} sl_stitch_solve_result;

/* Solves the views' poses and their shared lens from the overlaps:
 * features on a log-encoded copy of each view inside its image circle,
 * matched between overlapping pairs, RANSAC on the sphere, a bundle
 * adjustment of the poses (view 0 fixed) and the lens, the inliers refined
 * to sub-pixel on the full-resolution views and adjusted again, then the
 * vignetting from the radiance ratios (docs/stitch.md, "Solve"). Overwrites views[i].lens and views[i].pose with
 * the solution; a pair without enough good matches keeps its nominal
 * relative rotation and res says so. Views of different sizes or
 * projections, or a view with no image (NULL) are SL_ERR_INPUT. res is
 * filled (free with sl_stitch_solve_result_free) whatever the status. */
sl_result sl_stitch_solve(sl_stitch_view *views, int count, const sl_stitch_solve_options *opt,
                          sl_stitch_solve_result *res, sl_error *err);
void sl_stitch_solve_result_free(sl_stitch_solve_result *res);

/* ------------------------------------------------------------------ */
/* Stitch: image circle                                                 */
/* ------------------------------------------------------------------ */

/* The image circle of a circular fisheye view, fitted to its edge. */
typedef struct sl_stitch_circle sl_stitch_circle;
struct sl_stitch_circle {
    double cx, cy, radius; /* px; (0, 0) is the top-left corner of the top-left pixel */
    double rms_px;         /* RMS distance of the edge points on the circle from it */
    double support;        /* fraction of the rays cast with an edge point on the circle */
    int rays, edges;       /* rays cast, edge points on the circle */
    double radius_vs_nominal; /* radius / the nominal lens's circle_radius_px; 0 without */
};

/* Finds the image circle of an HDR (scene-linear) fisheye view: a coarse
 * disc from sl_fisheye_check's evidence (dark frame border, dark outside,
 * no Fresnel rim), then along 720 rays from its centre the sub-pixel point
 * where the radiance falls halfway from the inside's level to the dark
 * frame's (a box-filtered step edge crosses half at the edge itself), then
 * a least-squares circle with outliers (a sun, a dark patch at the rim)
 * dropped. nominal (may be NULL) only fills radius_vs_nominal. SL_ERR_INPUT
 * "NAME: no image circle: ..." for a frame with no image circle (a
 * rectilinear photo, a chrome-ball crop, a lat-long) or too few edge points
 * on one circle. */
sl_result sl_stitch_circle_find(const sl_image *radiance, const char *name,
                                const sl_lens *nominal, sl_stitch_circle *out, sl_error *err);

/* ------------------------------------------------------------------ */
/* Stitch: lens from EXIF                                               */
/* ------------------------------------------------------------------ */

/* What merge carries from the photos' EXIF into the merged EXR (OpenEXR's
 * standard attributes, written from sl_meta): nominalFocalLength (mm),
 * cameraMake, cameraModel, lensModel; and setlight's own, when the body's
 * sensor is known: */
#define SL_ATTR_SENSOR_MM "setlight:lens:sensor_mm" /* "W x H" in mm, e.g. "36 x 24" */
#define SL_ATTR_SENSOR_SOURCE "setlight:lens:sensor_source" /* where it came from */
#define SL_ATTR_FOCAL_35MM "setlight:lens:focal_35mm" /* 35 mm equivalent (diagonal) */

/* The sensor size (mm) of a camera body from its EXIF make and model (a
 * table of common bodies and the virtual set's camera); false if unknown. */
bool sl_stitch_sensor_of_body(const char *make, const char *model, double *width_mm,
                              double *height_mm);
/* Adds the SL_ATTR_SENSOR_* and SL_ATTR_FOCAL_35MM attributes to meta when
 * its body is known (make, model and focal length are already there). */
sl_result sl_stitch_lens_meta_set(sl_meta *meta, sl_error *err);
/* The nominal lens of a width x height view from its metadata: focal length
 * from EXIF (nominalFocalLength in an EXR, FocalLength in a photo), sensor
 * width from SL_ATTR_SENSOR_MM or else the body table, projection as given.
 * False when a value is missing; `why` then says which, e.g. "no focal length
 * in its metadata: give --focal-mm and --sensor-mm". */
bool sl_stitch_lens_from_meta(const sl_meta *meta, sl_lens_projection projection, int width,
                              int height, sl_lens *out, char *why, size_t why_size);

/* ================================================================== */
/* Stitch: lens profiles                                               */
/* ================================================================== */

/* How a lens profile's numbers were found. */
typedef enum {
    SL_LENS_SOURCE_NOMINAL = 0, /* from the nominal focal length and sensor size */
    SL_LENS_SOURCE_OVERLAPS,    /* solved from the overlaps of a stitch */
    SL_LENS_SOURCE_CHESSBOARD,  /* solved from chessboard photos (lens-calibrate) */
    SL_LENS_SOURCE_COUNT
} sl_lens_source;

/* "nominal", "overlaps", "chessboard"; -1 if unknown. */
int sl_lens_source_from_name(const char *name);
const char *sl_lens_source_name(sl_lens_source source);

/* One solved lens on one camera body, in the pixels of a lens.width x
 * lens.height image; a shoot's later setups reuse it (docs/formats.md,
 * "Lens profiles"). */
typedef struct sl_lens_profile {
    sl_lens lens;
    char camera[128];    /* "make model" as EXIF has them; "" when unknown */
    char lens_name[128]; /* EXIF lens model; "" when unknown */
    sl_lens_source source;
    double rms_px;       /* reprojection residual of the solve; -1 when not solved */
    double max_px;       /* its largest residual; -1 when not solved */
    int images;          /* photos or views the solve used (0 nominal) */
} sl_lens_profile;

/* JSON {"format": "setlight-lens", "version": 1, ...}. A file with a field
 * missing or of the wrong type, an unknown projection, NaN, a centre off the
 * image, a radius r(theta) that does not increase over the field or a
 * vignetting gain that is not positive over it is SL_ERR_INPUT with one
 * line naming the file and the field. */
sl_result sl_lens_profile_read(const char *path, sl_lens_profile *out, sl_error *err);
/* Written atomically; the same checks as read (SL_ERR_INPUT on a profile
 * that read would refuse). */
sl_result sl_lens_profile_write(const char *path, const sl_lens_profile *profile, sl_error *err);
/* Whether `profile` applies to views width x height from `camera` with
 * `lens` (either "" or NULL when unknown: not compared). A different camera
 * or lens (case-insensitive; "Make Model" and "Model" name one camera when
 * the longer only adds words in front), or a size of another aspect ratio, does not
 * fit: false, `why` says which. A size of the same aspect ratio fits with
 * focal length, centre and circle scaled (`why` then says so; "" for an
 * exact fit). *fitted (may be NULL) gets the lens for that size. */
bool sl_lens_profile_fits(const sl_lens_profile *profile, int width, int height,
                          const char *camera, const char *lens, sl_lens *fitted, char *why,
                          size_t why_size);
/* Checks a lens as read and write do; `where` names it in the message. */
sl_result sl_lens_check(const sl_lens *lens, const char *where, sl_error *err);

/* ================================================================== */
/* Stitch: lens-calibrate (a lens profile from chessboard photos)       */
/* ================================================================== */

typedef struct sl_lens_calibrate_options {
    int board_cols, board_rows;  /* inner corners along the board's rows and columns */
    double square_mm;            /* square size; only the board poses depend on it (25) */
    sl_lens_projection projection; /* default equisolid */
    double focal_mm;             /* nominal focal length; 0: the photos' EXIF */
    double sensor_width_mm;      /* width of the sensor area the photo covers (required) */
    int radial_terms;            /* radial correction terms solved, 0..3; -1 (default):
                                    as many as the corners support (sl_lens_calibrate) */
} sl_lens_calibrate_options;

void sl_lens_calibrate_options_init(sl_lens_calibrate_options *opt);

typedef struct sl_lens_calibrate_photo {
    char name[256];
    bool found;     /* the board was found */
    bool used;      /* its corners are in the solve */
    char why[160];  /* why not, when not used */
    double rms_px;  /* its corners' reprojection error under the solved lens */
    double max_px;
} sl_lens_calibrate_photo;

typedef struct sl_lens_calibrate_result {
    sl_lens_profile profile;       /* the solved lens, source chessboard */
    sl_lens nominal;               /* the lens from focal_mm and sensor_width_mm */
    double nominal_focal_mm;
    double focal_mm;               /* the solved focal length in the same mm */
    int radial_terms;              /* k terms solved */
    int photo_count, used;
    sl_lens_calibrate_photo *photos; /* photo_count, owned */
} sl_lens_calibrate_result;

/* The solve alone: `count` boards' cols x rows corners (pixels, top-left
 * corner of the image at (0, 0); row by row, x along a row) seen through
 * one lens. `lens` holds the nominal lens on entry and the solved one on
 * return (focal length, centre, radial terms; projection, field and
 * vignetting kept). rms_px and max_px (count each, may be NULL) get each
 * board's residual; *rms and *max the overall ones. A bundle adjustment
 * (Levenberg-Marquardt) of the lens and each board's pose, each pose seeded
 * by a homography of the nominal lens's rays. SL_ERR_INPUT when the solve
 * does not converge to a lens whose radius increases over the field. */
sl_result sl_lens_calibrate_corners(const double *corners, int count,
                                    const sl_lens_calibrate_options *opt, sl_lens *lens,
                                    double *rms_px, double *max_px, double *rms, double *max,
                                    sl_error *err);

/* lens-calibrate: finds the board in each photo (OpenCV), leaves out the
 * photos without it (each says why) and solves the lens from the others (at
 * least 3). Photos of different sizes or cameras: SL_ERR_INPUT naming the
 * file. res->photos is allocated (also on failure after reading began). */
sl_result sl_lens_calibrate(const char *const *paths, int count,
                            const sl_lens_calibrate_options *opt, sl_lens_calibrate_result *res,
                            sl_error *err);
void sl_lens_calibrate_result_free(sl_lens_calibrate_result *res);

/* ================================================================== */
/* Stitch: blend and the stitch call                                   */
/* ================================================================== */

#define SL_STITCH_MAX_VIEWS 16

/* How the views are blended into the lat-long (docs/stitch.md "Blend"). */
typedef struct sl_stitch_blend_options {
    int width;               /* lat-long width (even); 0: sl_stitch_default_width */
    int max_width;           /* cap of the default width (8192) */
    int supersample;         /* samples per texel side; 0: from the views' density (one
                                view pixel apart, 4x finer on hard edges) */
    double ramp_deg;         /* each view's weight falls to 0 over this many degrees
                                inside its field's edge (cos^2 ramp; 15) */
    double ghost_ratio;      /* views that both see a texel well (weight >= 0.25) and
                                differ by more than this fraction of the brighter, plus
                                the noise floor, disagree: the best single view is
                                taken and the texel counted as a ghost (0.3); <= 0: off */
    double noise_floor;      /* absolute floor of that test; < 0: 1e-3 of the median
                                luminance of the stitch */
    double nadir_mask_deg;   /* directions within this of the nadir are not taken from
                                any view (a tripod, a head): filled; 0: none */
    const sl_image *mask;    /* a lat-long (any 2:1 size): texels > 0.5 are not taken
                                from any view (filled); NULL: none */
} sl_stitch_blend_options;

void sl_stitch_blend_options_init(sl_stitch_blend_options *opt);

/* The lat-long width that keeps the views' pixel density on the horizon:
 * 2 pi focal_px rounded up to a multiple of 8, capped at max_width. */
int sl_stitch_default_width(const sl_lens *lens, int max_width);

typedef struct sl_stitch_coverage {
    int width, height;
    double seen_sr;          /* solid angle taken from the views (some weight > 0) */
    double filled_sr;        /* solid angle filled from the seen border (no view, or masked) */
    double masked_sr;        /* of filled_sr: masked (nadir or mask image) */
    double low_sr;           /* of seen_sr: confidence under 0.5 (circles' edges) */
    double view_sr[SL_STITCH_MAX_VIEWS]; /* solid angle each view contributes to */
    int64_t ghost_texels;    /* texels where views disagreed: the best single view taken */
    double ghost_sr;
    int64_t filled_texels;
    int supersample;         /* samples per texel side */
    int supersample_hot;     /* ... where a view has a hard edge (a sun, a lamp) */
    int64_t hot_texels;      /* texels sampled that finely */
    double power[3];         /* integral of L over the sphere (W/sr units x sr), per channel */
    double seen_power[3];    /* the same over the seen texels only */
} sl_stitch_coverage;

/* Where the blend hands the lat-long over, a strip of rows at a time: RGB
 * then the confidence in A, width * 4 floats per row, `stride` floats
 * apart, valid during the call only. */
typedef sl_result (*sl_stitch_rows_fn)(void *user, const float *rows, int y0, int count,
                                       size_t stride, sl_error *err);

/* Blends views (their lens and pose as they are: nominal, profile or
 * solved) into a lat-long in radiance: per texel, ss x ss samples, each
 * view's radiance divided by its vignetting gain and weighted by the
 * angle from its centre (1 + cos theta) / 2 times a cos^2 ramp to 0 at the
 * field's edge times its confidence image; a weighted mean, so no light is
 * made or lost and nothing is negative. Unseen or masked texels are filled
 * smoothly from the seen border (diffusion on a coarse lat-long) and get
 * confidence 0. A = min(1, sum of the views' weights). The rows go to
 * `sink` in order. SL_ERR_INPUT naming the view for a view with a NaN/Inf
 * sample or a radiance whose size is not its lens's. */
sl_result sl_stitch_blend_stream(const sl_stitch_view *views, int count,
                                 const sl_stitch_blend_options *opt, sl_stitch_rows_fn sink,
                                 void *user, sl_stitch_coverage *cov, sl_error *err);
/* The same into a whole image (RGBA). */
sl_result sl_stitch_blend(const sl_stitch_view *views, int count,
                          const sl_stitch_blend_options *opt, sl_image *out,
                          sl_stitch_coverage *cov, sl_error *err);

typedef struct sl_stitch_options {
    sl_stitch_blend_options blend;
    /* The nominal lens: given whole (a profile), else from projection,
     * focal and sensor (each 0 / -1: the files' metadata). */
    const sl_lens *lens;
    const char *lens_profile; /* a lens profile (JSON) to read and fit to the views */
    const char *save_lens;   /* write the lens used (solved) as a profile here */
    int projection;          /* sl_lens_projection; -1: equisolid */
    double focal_mm;
    double sensor_mm[2];     /* width, height (height 0: width * height / width of the image) */
    /* Nominal poses in degrees; a list shorter than the views: the rest
     * default (yaws evenly spaced over 360 from 0, pitch and roll 0). */
    int yaw_count, pitch_count, roll_count;
    double yaw_deg[SL_STITCH_MAX_VIEWS], pitch_deg[SL_STITCH_MAX_VIEWS],
        roll_deg[SL_STITCH_MAX_VIEWS];
    bool solve;              /* solve lens and poses from the overlaps (default true) */
    const char *input_colorspace; /* NULL: the files' */
    sl_pixel_type pixel_type;     /* half (default; float when a view's radiance
                                     exceeds half's 65504) or float */
    sl_exr_compression compression;
    /* An HTML report here (FILE.html; its images beside it, named
     * FILE_*.png): the solved lens and its change, the pairs, the
     * reprojection error, the coverage and confidence map, the views'
     * thumbnails with their circles. NULL: none. */
    const char *report;
} sl_stitch_options;

void sl_stitch_options_init(sl_stitch_options *opt);

typedef enum {
    SL_STITCH_READ = 0, SL_STITCH_CIRCLE, SL_STITCH_SOLVE,
    SL_STITCH_BLEND, /* the coarse pass and fill, the blend, the EXR's encoding and writing */
    SL_STITCH_PHASES
} sl_stitch_phase;
const char *sl_stitch_phase_name(sl_stitch_phase phase);

typedef struct sl_stitch_view_result {
    char path[1024];
    int width, height;
    sl_view_pose nominal, pose;  /* as given, as used (solved) */
    bool confidence;             /* a merge clipped mask weighted it */
    char confidence_source[4096];
    /* How the blend held the view's radiance: float, or half (a view wider
     * than 3072 px): as it is when every sample is a half value, else
     * `half_rounded`: divided by 2^half_exp2 (its peak at half's top) and
     * rounded, each sample within 2^-11 (0.049%) relative except the
     * `below_half_normal` under half's normal range once scaled (under
     * about 1e-9 of the peak: coarser), `flushed_to_zero` of them 0. */
    bool held_as_half, half_rounded;
    int half_exp2;
    int64_t below_half_normal, flushed_to_zero;
} sl_stitch_view_result;

typedef struct sl_stitch_result {
    int view_count;
    sl_stitch_view_result views[SL_STITCH_MAX_VIEWS];
    sl_lens lens_nominal, lens;  /* as given, as used */
    char lens_source[1024];      /* where the nominal lens came from */
    sl_stitch_circle circle;     /* view 0's image circle */
    bool circle_found;
    bool solved;
    sl_stitch_solve_result solve; /* pairs, matches, errors (when solved) */
    char solve_note[512];        /* why not solved, or what the solve did */
    sl_stitch_coverage coverage;
    bool float_samples;          /* half was asked but the radiance needs float */
    double wall[SL_STITCH_PHASES], cpu[SL_STITCH_PHASES];
    double seconds, cpu_seconds;
} sl_stitch_result;

/* Stitches HDR views (files: EXR or any image setlight reads, all one
 * camera, lens and size) into one lat-long EXR at out_path, written in
 * strips (atomic: nothing is left on failure): RGB and the confidence in
 * A, `envmap`, chromaticities and setlight:stitch:* provenance. The lens:
 * opt->lens, else projection/focal/sensor from the options, else the
 * files' EXIF; SL_ERR_INPUT naming the file when neither says. Refused
 * (SL_ERR_INPUT naming the file or the pair): views of different sizes, a
 * NaN/Inf sample, views that do not overlap the others. One view makes a
 * partial lat-long. res may be NULL. */
sl_result sl_stitch(const char *const *view_paths, int count, const char *out_path,
                    const sl_stitch_options *opt, sl_stitch_result *res, sl_error *err);
void sl_stitch_result_free(sl_stitch_result *res);

/* ---- The stitch stage, files to files ---- */

typedef struct sl_stitch_run_options {
    const char *const *view_paths; /* the merged HDR fisheye views */
    int view_count;                /* 1 .. SL_STITCH_MAX_VIEWS */
    const char *out_path;          /* the lat-long EXR */
    const char *mask_path;         /* a 2:1 nadir mask (the tripod's cone), or NULL */
    sl_stitch_options stitch;      /* sl_stitch_options_init; blend.mask is set from mask_path */
} sl_stitch_run_options;

void sl_stitch_run_options_init(sl_stitch_run_options *o);

typedef struct sl_stitch_run_result {
    sl_stitch_result stitch;       /* lens, solve, views, coverage, timing */
    char *json;                    /* what `stitch --json` prints (owned) */
} sl_stitch_run_result;

/* Reads the mask, stitches (sl_stitch: the views read, solved, blended and
 * written with their provenance) and logs the summary and each pair left
 * at its nominal rotation. */
sl_result sl_stitch_run(const sl_stitch_run_options *o, sl_stitch_run_result *res,
                        sl_error *err);
void sl_stitch_run_result_free(sl_stitch_run_result *res);

#ifdef __cplusplus
}
#endif

#endif /* SETLIGHT_STITCH_H */
