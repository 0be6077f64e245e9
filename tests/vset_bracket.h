/* SPDX-License-Identifier: BSD-3-Clause */
/* Brackets shot by the virtual set's camera (include/setlight/capture.h) of
 * a virtual-set lat-long, with the ground truth the merge must recover: the
 * noise-free, unclipped output-linear value at the reference exposure and
 * which channels no frame exposes below saturation. */
#ifndef SETLIGHT_TESTS_VSET_BRACKET_H
#define SETLIGHT_TESTS_VSET_BRACKET_H

#include "setlight/vset.h"
#include "setlight/stitch.h"

enum { VB_MAX_FRAMES = 16 };

/* The realizable oracle with one of the merge's simplifications, to measure
 * what the merge with the true curve lacks (bench/merge_crf.c
 * --realizable-variant): the model judged at each frame's observed value
 * (not iterated), each output channel's variance the sensor's in its own
 * value (no colour-matrix mixing of the raw channels' noise), frames left
 * out only by their codes (not by the model's raw clips), frames left out
 * only where they read at the clip code (not 3 sigma before an output clip),
 * all four (merge-like), or merge-like with the merge's own code rules:
 * weight 0 at or below its black code, and from the pixel's brightest code
 * fading to 0 over the 0.05 below its saturation code (merge-rules). */
typedef enum vb_realizable_variant {
    VB_REALIZABLE_ORACLE,
    VB_REALIZABLE_OBSERVED,
    VB_REALIZABLE_OWN_CHANNEL,
    VB_REALIZABLE_NO_RAW_CLIP,
    VB_REALIZABLE_NO_NEAR_CLIP,
    VB_REALIZABLE_MERGE_LIKE,
    VB_REALIZABLE_MERGE_RULES,
} vb_realizable_variant;

typedef struct vb_spec {
    const char *scene;    /* "exterior", "stage", "night" */
    const char *curve;    /* camera response preset ("canon", "srgb", "filmic") */
    const sl_vset_response *response; /* or any curve (e.g. sl_vset_response_load from the
                                         DoRF file); NULL: the preset `curve` */
    double full_well_e;   /* the sensor's electrons at raw saturation; 0: the camera's 64000 */
    double read_noise_e;  /* with full_well_e: read noise in electrons (all before the ISO
                             gain); else the camera's 2.5 before and 25.5 after it */
    int frames;           /* 7 or 5 */
    int stops;            /* 3 or 2, on the camera's full-stop shutter scale */
    bool jpeg;            /* 8-bit JPEG through the curve, else 14-bit linear in a 16-bit TIFF */
    int width;            /* lat-long width (frames are the lat-long itself) */
    double saturation;    /* the merge's saturation code (for the clipped truth) */
    uint64_t seed;
    int shift;            /* the whole bracket this many shutter steps longer than metered */
    int lie_frame;        /* this rank's EXIF time is off by lie_stops (0: none) */
    double lie_stops;
    bool lossless;        /* with jpeg: the same 8-bit codes in a TIFF (no JPEG loss) */
    bool noise_free;      /* the camera's expected value (no shot or read noise), still
                             quantised to 14 bits and, for JPEG, to 8-bit codes */
    const sl_image *latlong; /* the scene's lat-long (vb_scene), or NULL: made from scene, width */
    bool realizable;      /* also vb_bracket.realizable (iterated per pixel: costs a second) */
    vb_realizable_variant realizable_variant; /* with realizable: which one */
    bool null_space;      /* with jpeg and equal steps: also vb_bracket.null_space (as much again) */
    double alt_stops;     /* > 0: the steps alternate `stops` and this many stops, centred on
                             the metered shutter speed (times off the full-stop scale, as a
                             camera's third- or half-stop scale sets them) */
} vb_spec;

typedef struct vb_bracket {
    vb_spec spec;
    sl_vset_camera cam;
    int frames;
    int reference;             /* rank of the middle frame: the merge's scale */
    double times[VB_MAX_FRAMES];
    double ref_scale; /* the camera's exposure scale at the reference frame: truth / ref_scale
                         is the output-linear value of the radiance itself (cd/m^2 units) */
    double f_number, iso;
    char paths[VB_MAX_FRAMES][512]; /* shortest first */
    sl_image truth;   /* output-linear value at the reference exposure, noise-free, unclipped */
    sl_image clipped; /* 1 where the shortest frame is saturated in that channel (noise-free) */
    sl_image margin;  /* 1 where noise could move a channel across a threshold that matters */
    sl_image best;    /* noise-free output-linear value in the longest frame that leaves the
                         pixel unsaturated (0 when every frame saturates it) */
    double code_lo, code_hi; /* codes the bracket exposes (the response is scored over them):
                                from 2% of white (the scored floor) to the 99.9th percentile
                                of the codes of channels at least that bright in frames that
                                leave their pixel unsaturated, at most 0.9 */
    sl_image oracle;  /* the ideal estimator's merge of the written frames: the camera's true
                         curve, exposures and noise model (inverse-variance weights from the
                         noise-free value), frames used only where the truth leaves them
                         unclipped; its error is the floor set by the frames' noise */
    sl_image realizable; /* with vb_spec.realizable, the realizable oracle: the same estimator judging weights and clips
                            at its own estimate from the frames (iterated maximum likelihood),
                            not at the noise-free value; the best merge of these frames the
                            true curve, exposures and noise model allow */
    sl_image null_space; /* with vb_spec.null_space, the null-space oracle: the realizable
                            oracle told the true curve with its component periodic in ln
                            exposure (period the bracket's mean step) replaced by the one the
                            self-calibration's smoothness picks (vb_null_space_fit): the best
                            an estimator with no prior on curve shapes can do from equal steps.
                            Scored with a free scale, as a self-calibrated merge */
    double null_space_curve; /* that curve's error against the true one, as
                                vb_response_error, over code_lo..code_hi */
    bool null_space_rises;   /* that curve rises everywhere (else it is no camera's) */
} vb_bracket;

/* The scene's lat-long, to share between brackets (vb_spec.latlong). */
sl_result vb_scene(const char *name, int width, sl_vset_scene *out, sl_error *err);
/* Writes DIR/PREFIX_<rank>.{jpg,tif}. */
sl_result vb_make(const char *dir, const char *prefix, const vb_spec *spec, vb_bracket *out,
                  sl_error *err);
void vb_free(vb_bracket *b);

/* sl_merge of the bracket's frames (named longest first, as a wrangler's
 * folder might list them). */
sl_result vb_merge(const vb_bracket *b, const sl_merge_options *opt, sl_merge_result *res,
                   sl_error *err);
/* qsort's comparison of doubles, ascending. */
int vb_cmp_double(const void *a, const void *b);
/* Channels scored: not clipped in every frame (truth) and at least 2% of
 * white in the longest frame that leaves the pixel unsaturated. */
bool vb_scored(const vb_bracket *b, int x, int y, int c);

typedef struct vb_stats {
    int64_t n;
    double median, p99, scale;
} vb_stats;

/* Relative error of merged vs b's truth over block x block means of scored
 * channels (block 1: per pixel), median and p99; with fit_scale after the
 * median ratio (a self-calibrated curve knows radiance up to a factor). */
vb_stats vb_compare(const sl_image *merged, const vb_bracket *b, int block, bool fit_scale);
/* Worst error of a recovered inverse response against the true curve after
 * one free scale (the median ratio), over codes [zlo, zhi]; *worst_z gets
 * where. */
double vb_response_error(const sl_response *resp, const sl_vset_response *truth, double zlo,
                         double zhi, double *worst_z);

/* A function of ln exposure u periodic with `period`:
 * sum_j cos_coef[j] cos(2 pi (j+1) u / period) + sin_coef[j] sin(...). */
enum { VB_HARMONICS = 24 };
typedef struct vb_periodic {
    double period;
    double cos_coef[VB_HARMONICS], sin_coef[VB_HARMONICS];
} vb_periodic;
double vb_periodic_at(const vb_periodic *p, double u);
/* x exp(p(ln x) - p(0)): a linear value through g -> g + p(g) (1 stays 1). */
double vb_periodic_apply(const vb_periodic *p, double x);
/* The p for which g + p(g) (g = ln of truth's inverse) has the least of the
 * Debevec-Malik fit's smoothness penalty (merge_smoothness_row) over the
 * codes the fit weighs (above black, below saturation): the member of the
 * true curve's class under steps of `period` in ln exposure that a
 * self-calibration with no prior on curve shapes picks from noise-free
 * frames (tests/vset_null_space.c). False when it does not rise
 * everywhere or the system is singular. */
bool vb_null_space_fit(const sl_vset_response *truth, double period, double black,
                       double saturation, vb_periodic *p);
/* That member as a curve (forward table, as the truth). */
void vb_null_space_curve(const sl_vset_response *truth, const vb_periodic *p,
                         sl_vset_response *out);

/* The curve names of a DoRF database file (six lines a curve)
 * in file order, at most max; -1 when it cannot be read. */
int vb_dorf_names(const char *path, char (*names)[128], int max);
/* A DoRF curve's family (the same film or camera): the name without, in
 * turn, ".SLRR", the channel ("Red", "Green", "Blue", or R, G or B with an
 * optional digit: dscs315G2, FP2900ZB), "CD", the variant ("Standard",
 * "Push1", "Pull1", "12min", a gamma's "+2.2", a six-digit date) and "CD". */
void vb_dorf_family(const char *name, char *family, size_t size);
/* The inverse table (256 nodes, three equal channels) of a forward curve. */
sl_result vb_response_inverse(const sl_vset_response *curve, sl_response *out, sl_error *err);
/* The inverse tables of the `count` curves `names` of a DoRF file (free
 * each with sl_response_free). */
sl_result vb_dorf_inverses(const char *path, char (*names)[128], int count, sl_response *out,
                           sl_error *err);
/* The curve-shape prior of `count` DoRF curves (inverse tables, names)
 * leaving out every curve of the family of `name` (NULL: none left out). */
sl_result vb_dorf_prior(const sl_response *curves, char (*names)[128], int count,
                        const char *name, int components, sl_response_prior **out,
                        sl_error *err);

#endif
