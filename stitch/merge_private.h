/* SPDX-License-Identifier: BSD-3-Clause */
/* Pieces of the merge shared between its files (stitch/merge*.c, response*.c). */
#ifndef SETLIGHT_STITCH_MERGE_PRIVATE_H
#define SETLIGHT_STITCH_MERGE_PRIVATE_H

#include <math.h>

#include "setlight/stitch.h"

/* Frames per merge (per-pixel work keeps them on the stack). */
enum { MERGE_MAX_FRAMES = 64 };

/* Pixel values at sample positions: z[(i * frames + r) * 3 + c] for
 * position i and frame rank r (shortest exposure first); spoilt[i * frames
 * + r] is 1 where that frame's JPEG block is spoilt by a clipped pixel
 * (merge_block_spoilt; for the exposure check and the response fit). */
typedef struct merge_samples {
    int count;
    int frames;
    double code_step; /* the frames' code step on the 0..1 scale (0: float frames) */
    bool coded;       /* some frame is block-coded (JPEG): its coding error, often many
                         codes near an edge, is in no noise model */
    float *z;
    uint8_t *spoilt;
} merge_samples;

/* The brightest channel of position i in frame rank r. A camera clips each
 * raw channel before its colour matrix mixes them, so one saturated channel
 * spoils the pixel's others: saturation is judged on this. */
static inline float merge_zmax(const merge_samples *s, int i, int r)
{
    /* Samples are finite (sample_frame): no fmaxf, which at -O2 is a call
     * into libm, made for every sample by every round of the fit. */
    const float *v = s->z + ((size_t)i * s->frames + r) * 3;
    float hi = v[0] > v[1] ? v[0] : v[1];
    return hi > v[2] ? hi : v[2];
}

/* Position i in frame rank r below `limit` and its JPEG block not spoilt
 * by a clipped pixel (merge_block_spoilt). */
static inline bool merge_usable(const merge_samples *s, int i, int r, double limit)
{
    return merge_zmax(s, i, r) < limit && !s->spoilt[(size_t)i * s->frames + r];
}

/* The brightest channel of every block of a strip of `rows` rows (starting
 * on a block row): out[(y / bh) * ceil(width / bw) + x / bw] for y
 * relative to the strip, on the 0..1 code scale. buf holds RGB codes
 * (code_bytes 1 or 2, full scale `top`) or floats (code_bytes 0). */
void merge_block_max(const void *buf, int code_bytes, double top, int width, int rows, int bw,
                     int bh, float *out);

/* Debevec-Malik: the log inverse response g(z) on `nodes` nodes such that
 * g(z_ir) = ln E_i + ln e_r, with hat weights, smoothness `lambda` on the
 * second derivative of g against ln z, the curve-shape prior (if any) at
 * prior_weight, and samples chosen stratified over scene intensity. Solved in double through the Schur complement of the
 * per-sample unknowns (a dense nodes x nodes Cholesky, merge_cholesky_solve). */
sl_result merge_fit_response(const merge_samples *s, const double *log_exposure, int nodes,
                             double lambda, int max_samples, double black, double saturation,
                             double noise_gain, double noise_floor, uint64_t seed,
                             const sl_response_prior *prior, double prior_weight,
                             sl_response *out, sl_error *err);

/* The self-calibrated curve refined under the noise (response_ml.c). */
typedef struct merge_refine_report {
    bool refined;
    char note[96];
    int series, steps;
    double start_loglik, loglik; /* the first curve's and the refined one's, under the
                                    fitted noise and scene */
    double moved;                /* largest change of ln g (scale free) */
    double noise_gain[3], noise_floor[3];
} merge_refine_report;
/* Refines resp (one curve for the three channels, 256 nodes) by maximum
 * likelihood of 8-bit lossless samples under a fitted noise law, reading
 * up to max_positions sample positions; other samples, too few series, or
 * a refinement no likelier than resp or moving it by more than a factor 2
 * leave it as it is (rep->note says why). */
sl_result merge_refine_response(const merge_samples *s, const double *log_exposure,
                                int max_positions, sl_response *resp, merge_refine_report *rep,
                                sl_error *err);

/* The curve-shape prior (response_prior.c): mean and components on
 * MERGE_PRIOR_NODES code nodes, zero below node `first`; the built-in
 * prior keeps 16 components (the DoRF measurement levels off there,
 * docs/merge.md). */
enum { MERGE_PRIOR_NODES = 256, MERGE_PRIOR_COMPONENTS = 16 };
struct sl_response_prior {
    int nodes, first, components;
    const double *mean;     /* nodes values, 0 below first */
    const double *basis;    /* components rows of nodes values, unit length */
    const double *variance; /* components values, descending */
    double residual;        /* variance per node beyond the components */
    char name[64];
    double *owned;          /* the three above when built (not the table's) */
};
/* First node the prior covers for a fit on `nodes` nodes. */
int merge_prior_first_node(int nodes);
/* The precision P (nodes x nodes) of the prior's marginal on nodes lo..hi
 * (those the data reach; from its first node), with the shape's level left
 * free (P 1 = 0), and P mean; zero elsewhere. The fit adds w P to its
 * matrix and w P mean to its right side. */
void merge_prior_precision(const sl_response_prior *p, int lo, int hi, double *prec,
                           double *prec_mean);
/* The built-in prior: DoRF's 201 curves (response_prior_dorf.c, generated). */
extern const sl_response_prior merge_prior_dorf;

/* The fit's smoothness term at node k (2 <= k <= nodes - 2): the second
 * derivative of g against ln z from nodes k - 1, k, k + 1 is
 * cs[0] g[k-1] + cs[1] g[k] + cs[2] g[k+1]; returns its weight times
 * scale (the fit's lambda^2 times its equations over nodes). Also what the
 * tests' null-space oracle minimises (tests/vset_null_space.c). */
double merge_smoothness_row(int k, int nodes, double scale, double cs[3]);

/* Cholesky of the symmetric positive definite n x n matrix a (row-major;
 * its lower part overwritten by the factor), then solves a x = b in place
 * (b gets x). False when a is not positive definite. */
bool merge_cholesky_solve(double *a, double *b, int n);

/* Writes the JSON text of `o` (json_t *, decref'd here; NULL: out of
 * memory) with a final newline atomically to path; `precision` significant
 * digits for reals. The response and the lens profile files. */
sl_result stitch_json_write(const char *path, void *o, int precision, sl_error *err);
/* Loads a JSON file into *o (json_t **; the caller decrefs): SL_ERR_NOT_FOUND
 * for a missing file, SL_ERR_INPUT "not JSON" with the line. */
sl_result stitch_json_read(const char *path, void *o, sl_error *err);
/* For the solver's test and measurement (test_merge_solve): when set, the
 * Debevec-Malik fit shows it each round's system before solving it. */
extern void (*merge_fit_system_hook)(const double *a, const double *b, int n);

/* Robertson-Borman-Stevenson: the same curve from the same samples by
 * alternating irradiance and per-code estimates (response_robertson.c). */
sl_result merge_fit_robertson(const merge_samples *s, const double *log_exposure, int nodes,
                              int max_samples, double black, double saturation, uint64_t seed,
                              sl_response *out, sl_error *err);

/* The curve node at or below code z (0 <= z <= 1) of a response with
 * `nodes` nodes, and z's offset from it in node steps (*frac, 0 .. 1). */
static inline int merge_response_node(double z, int nodes, double *frac)
{
    double p = z * (nodes - 1);
    int k = (int)p;
    if (k >= nodes - 1)
        k = nodes - 2;
    *frac = p - k;
    return k;
}

/* sl_response_eval, inline for the loops that evaluate the curve at every
 * sample (the exposure check, the response check, the JPEG blocks): the
 * call across files was a tenth of a small bracket's fit. */
static inline double merge_response_at(const sl_response *resp, int channel, double z)
{
    const double *row = resp->inverse + (size_t)channel * (size_t)resp->nodes;
    if (!(z > 0))
        return row[0];
    if (z >= 1)
        return row[resp->nodes - 1];
    double a;
    int k = merge_response_node(z, resp->nodes, &a);
    return row[k] * (1 - a) + row[k + 1] * a;
}

/* The curve at the codes of 8-bit samples, looked up by the loops that
 * evaluate it at every sample and frame (the exposure check, the response
 * check, the fit's choice of samples): per code k its sample value
 * (float)k * (1.0f / 255), as the sample pass stores it, ln z, and per
 * channel the curve's value y and ln y (NAN where y <= 0). A value that is
 * no code's (float or resampled frames) is evaluated as before, so the
 * results are the same bit for bit. */
typedef struct merge_code_curve {
    bool codes; /* 8-bit samples: the tables are filled */
    float z[256];
    double log_z[256];
    double y[3][256], log_y[3][256];
} merge_code_curve;
/* resp NULL: ln z only. */
void merge_code_curve_init(merge_code_curve *t, const merge_samples *s, const sl_response *resp);

/* The code whose sample value z is, or -1. */
static inline int merge_code_of(const merge_code_curve *t, float z)
{
    if (!t->codes || !(z >= 0 && z <= 1))
        return -1;
    int k = (int)(z * 255.0f + 0.5f);
    return t->z[k] == z ? k : -1;
}

static inline double merge_code_curve_y(const merge_code_curve *t, const sl_response *resp, int c,
                                        float z)
{
    int k = merge_code_of(t, z);
    return k >= 0 ? t->y[c][k] : merge_response_at(resp, c, z);
}

/* Finishes a fitted inverse response: inv[0 .. nodes) (inv holds 3 x nodes)
 * made increasing from 0 (noise at the ends must not fold it) and 1 at
 * the top, copied to all three channels (one curve for the three: the
 * samples of every channel fit it), and handed to out with its source
 * name; out owns inv. */
void merge_response_finish(double *inv, int nodes, const char *source, sl_response *out);

/* Up to max_samples positions for channel c, spread over a crude log
 * radiance and over the frame; returns how many (-1 out of memory).
 * usable: merge_usable(s, i, r, saturation) at [i * frames + r], found once
 * for the three channels, or NULL. */
int merge_choose_samples(const merge_samples *s, int c, const double *log_exposure, double black,
                         double saturation, int max_samples, uint64_t seed,
                         const uint8_t *usable, int *chosen);

/* The k-th smallest of v[0..n) (Hoare's selection; reorders v, leaving the
 * k smallest in v[0..k)). */
double merge_select_kth(double *v, int n, int k);

/* Exposure ratio between neighbouring ranks from pixels well exposed in
 * both (median of linearised ratios); ratio[r] = e[r+1] / e[r], 0 when too
 * few pixels are usable; log_exif[r] the ranks' EXIF exposures (where the
 * longer frame's floor is). Returns how many ratios could be fitted. */
int merge_fit_ratios(const merge_samples *s, const sl_response *resp, double black,
                     double saturation, const double *log_exif, double *ratio);

/* Timing by phase (merge_clock.c): a stretch starts at a clock (wall and
 * process CPU); charging it to a phase returns the clock for the next. */
typedef struct merge_clock {
    double wall, cpu;
} merge_clock;
merge_clock merge_clock_start(void);
merge_clock merge_clock_charge(sl_merge_timing *t, merge_clock since, sl_merge_phase phase);
/* A parallel stretch: task[w * SL_MERGE_PHASES + phase] is the CPU the
 * tasks of worker w (of `workers`) measured per phase, zeroed here for the
 * next stretch; the rest of its CPU is other's, and its wall is split by
 * CPU shares. */
merge_clock merge_clock_split(sl_merge_timing *t, merge_clock since, double *task, int workers);
/* The totals since start (res->seconds, cpu_seconds); other gets what no
 * phase claimed, so the phases add up to them. */
void merge_clock_finish(sl_merge_result *res, merge_clock start);

/* A frame's luminance box-averaged to the alignment measurement's
 * resolution (at most 2^18 pixels), filled strip by strip while the sample
 * pass decodes the frame anyway (align.c). */
typedef struct align_plane {
    int w, h, scale;
    float *v;       /* per block: luminance sum */
    uint8_t *state; /* per block: 2 a pixel saturated, 1 a pixel dark, 0 usable */
    uint16_t *row;  /* scratch for 8-bit rows: luminance and flag per pixel */
    uint8_t *row_flag;
} align_plane;
sl_result align_plane_init(align_plane *p, int width, int height, sl_error *err);
/* Adds rows y0 .. y1 of a strip (codes of code_bytes, or floats with 0). */
void align_plane_add(align_plane *p, const void *strip, int code_bytes, int width, int y0, int y1,
                     double black, double saturation);
void align_plane_free(align_plane *p);
/* sl_align_bracket's estimate on the planes (which it consumes): out[i]
 * for frame i, none applied yet. */
sl_result align_measure(align_plane *planes, int count, const char *const *paths,
                        const double *exposures, const sl_merge_options *opt, int width,
                        int height, sl_align_transform *out, sl_error *err);

/* State shared by the merge stages (merge.c, merge_pass.c). */
typedef struct merge_ctx {
    int width, height, bits;
    bool is_float;
    bool marked_linear;    /* every frame's file says it is linear light (raw, linear ICC) */
    bool lossless;         /* every frame's codes stored exactly (no JPEG: sl_photo_strip_info) */
    int code_bytes;        /* frames' integer container: 1 or 2 bytes, 0 float */
    bool codes;            /* frames read as integer codes (integer and none warped) */
    uint8_t *code_class;   /* with codes, per code: 1 saturated, 2 black */
    uint8_t **held;        /* per frame: its codes kept from the sample pass, or NULL */
    int held_slots;        /* entries of held */
    int orientation;
    int *block;            /* per frame: JPEG block width and height (2 ints), 0 0 none */
    float **block_max;     /* per frame: its blocks' brightest code (merge_block_max), or NULL */
    double black, saturation;
    int *order;            /* order[rank] = frame index, shortest exposure first */
    int64_t *sample_pos;   /* y * width + x, increasing */
    merge_samples samples;
    int64_t *white_pixels; /* per frame: pixels saturated in every channel */
    double *ratio;         /* per rank: fitted e[r+1] / e[r], 0 unknown */
    double *offsets;       /* scratch, one per frame */
    double *log_fit;       /* per rank: chained fitted log exposure */
    double *prev_fit;      /* per frame: fitted exposure of the previous round */
    double *scratch;       /* frames^2 doubles */
    align_plane *measure;  /* per frame, filled by the sample pass (SL_ALIGN_AUTO), or NULL */
    int measure_frames;
    /* per sample and rank: its block's brightest code in that frame and in
     * the next shorter one (merge_block_codes; -1 none), or NULL */
    float *spoil_codes;
} merge_ctx;

/* Whether frame rank r's JPEG block at pixel pos (y * width + x) is
 * spoilt: a pixel in it saturated, by more than a little. How far a block
 * is overexposed comes from the next shorter frame's same block: its
 * brightest linear value (through resp) times the exposure step, over the
 * linear value of the saturation code. The energy the clip removed, spread
 * by the block's DCT and chroma averaging, is what biases the block's other
 * pixels; a sky clipped by a fraction of a stop barely moves them, a lamp
 * clipped by seven stops moves its neighbours by tens of percent. With no
 * shorter frame (or that one saturated there too) any saturated pixel
 * spoils the block. loge: log exposure per rank. */
bool merge_block_spoilt(const merge_ctx *m, const sl_response *resp, const double *loge, int r,
                        int64_t pos);
/* The two codes merge_block_spoilt looks at for rank r at pixel pos:
 * codes[0] the frame's block's brightest (-1 when the frame has no
 * blocks), codes[1] the next shorter frame's (-1 none). They depend on the
 * frames only, not on the curve or the exposures: the fit's rounds judge
 * them again (merge_block_spoilt_codes) without finding them again. */
void merge_block_codes(const merge_ctx *m, int r, int64_t pos, float codes[2]);
bool merge_block_spoilt_codes(const merge_ctx *m, const sl_response *resp, const double *loge,
                              int r, const float codes[2]);
/* merge_block_spoilt_codes for every sample and rank: spoilt[e] from
 * codes[2 e .. 2 e + 1], e = i * frames + rank. */
void merge_block_spoilt_all(const merge_ctx *m, const sl_response *resp, const double *loge,
                            const float *codes, uint8_t *spoilt);

/* Saturation when the options leave it 0 (merge_prepare resolves it once
 * the frames are open): frames through a lossy codec (JPEG) ring a few codes
 * below white inside clipped areas; linear frames (raw, linear TIFF) clip at
 * their white level, and a lower threshold throws away the best-exposed
 * values of every pixel near it (on the virtual set's 2-stop linear
 * brackets, a third more noise than the ideal estimator's at 0.95, 2% more at
 * 0.98); lossless codes through a curve neither ring nor sit under a white
 * level, so only the clip code is saturated: the codes below it are the
 * best-exposed frame's, which a curve's shoulder spreads over a wide range
 * (DoRF's 201 curves, docs/merge.md: the merge told the true curve within
 * 1.1x of the ideal estimator's median error on 139 of them at 0.95, on all
 * 201 at the clip code). */
#define MERGE_SATURATION_CURVE 0.95
#define MERGE_SATURATION_LINEAR 0.98
#define MERGE_SATURATION_LOSSLESS 1.0

static inline double merge_saturation_default(sl_response_mode mode, bool lossless)
{
    return mode == SL_RESPONSE_LINEAR ? MERGE_SATURATION_LINEAR
           : lossless                 ? MERGE_SATURATION_LOSSLESS
                                      : MERGE_SATURATION_CURVE;
}

/* The caller's options, or the defaults when it gives none; a saturation
 * of 0 stays 0 (the default, chosen from the frames). */
static inline sl_merge_options merge_options_or_default(const sl_merge_options *opt)
{
    sl_merge_options o;
    if (opt)
        o = *opt;
    else
        sl_merge_options_init(&o);
    return o;
}

/* Fills res->response_check from the samples (before they are released);
 * `recovered`: the curve was fitted to this bracket. */
void merge_judge_response(const merge_ctx *m, sl_merge_result *res, bool recovered);

/* Everything before the pixels are merged: frames, samples, response,
 * exposure check. With `hold`, frames that fit opt->hold_mb keep their codes
 * from the sample pass for the merge pass. */
sl_result merge_prepare(const char *const *paths, int count, const sl_merge_options *opt,
                        bool hold, merge_ctx *m, sl_merge_result *out, sl_error *err);
/* Where merged strips go instead of out's images: EXR streams (mask and
 * ghost may be NULL). */
typedef struct merge_sink {
    sl_exr_stream *radiance, *mask, *ghost;
} merge_sink;
/* Merges the frames strip by strip into out->radiance, out->clipped (and
 * out->ghost with deghost), or with a sink into its streams; a stream whose
 * write failed is freed (sl_exr_stream_write) and set to NULL in the sink. */
sl_result merge_pass(const merge_ctx *m, const sl_merge_options *opt, merge_sink *sink,
                     sl_merge_result *out, sl_error *err);
/* The radiance EXR's attributes; the counts only known after the pass are
 * written at a fixed width, so a streamed file's header can be finished in
 * place. */
sl_result merge_output_meta(const char *path, const char *mask_path, const char *ghost_path,
                            const sl_merge_result *res, sl_meta *meta, sl_error *err);
/* A mask's attributes (it names the radiance). */
sl_result merge_mask_meta(const char *path, const sl_merge_result *res, sl_meta *meta,
                          sl_error *err);
void merge_ctx_free(merge_ctx *m);
/* Units, output scale and weights as EXR attributes (setlight:merge:units,
 * output_exposure, weights). */
/* Keeps frame i's lens EXIF (focal length, camera, lens) in res: frame 0's,
 * and SL_ERR_INPUT when a later frame names another lens or camera. */
sl_result merge_lens_exif(const char *const *paths, int i, const sl_meta *meta,
                          sl_merge_result *res, sl_error *err);
/* The lens EXIF of res into the merged EXR's metadata (sl_stitch_lens_meta_set). */
sl_result merge_lens_meta(sl_meta *meta, const sl_merge_result *res, sl_error *err);
sl_result merge_provenance_meta(sl_meta *meta, const sl_merge_result *res, sl_error *err);

/* Sample i of a strip of integer codes (uint8_t or uint16_t). */
static inline int merge_code(const void *buf, int bytes, size_t i)
{
    return bytes == 1 ? ((const uint8_t *)buf)[i] : ((const uint16_t *)buf)[i];
}

#endif
