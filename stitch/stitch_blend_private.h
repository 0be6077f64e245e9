/* SPDX-License-Identifier: BSD-3-Clause */
/* Inside the stitch's blend and fill (stitch_blend.c, stitch_fill.c, stitch.c). */
#ifndef SETLIGHT_STITCH_BLEND_PRIVATE_H
#define SETLIGHT_STITCH_BLEND_PRIVATE_H

#include "setlight/stitch.h"

#include <math.h>
#include <stdint.h>

/* A view's radiance as half RGB, 3 samples a pixel, rows packed: what the
 * stitch holds a view as when every sample of it is a half value (as
 * merge writes them), half the memory of float and the same lookups. */
typedef struct stitch_half_image {
    uint16_t *rgb;
    int width, height;
    int exp2; /* the radiance is the half values times 2^exp2 (0: as they are) */
} stitch_half_image;

/* What holding a float view as scaled half lost beyond half's rounding
 * (relative 2^-11 = 0.049% for every sample in half's normal range). */
typedef struct stitch_half_loss {
    int64_t below_normal; /* non-zero samples under half's normal range once scaled: coarser */
    int64_t flushed;      /* of them, those that became 0 */
} stitch_half_loss;

/* The float value of every half bit pattern (the blend's lookups). */
const float *stitch_half_table(void);

/* Counts the non-finite samples of a view, finds its largest RGB sample,
 * its largest RGB magnitude (|sample|: a negative one too) and whether
 * every RGB sample is a half value. */
sl_result stitch_view_scan(const sl_image *img, int64_t *bad, double *peak, double *magnitude,
                           bool *half_exact, sl_error *err);
/* The power of two a view whose largest magnitude is `magnitude` is
 * divided by to be held as half: its largest sample then between 32768
 * and 65504 (half's top, so the dark end keeps the most range). False
 * for a view half cannot hold so (beyond 1e30: kept float). */
bool stitch_half_exponent(double magnitude, int *exp2);
/* A view as half, converted in its own memory (no new pages; the float
 * tail freed): img is emptied. Each sample is divided by 2^exp2 (exact)
 * and rounded to half; with exp2 from stitch_half_exponent none overflows.
 * loss (may be NULL: a view whose samples are all half values, exp2 0,
 * loses nothing) counts the samples under half's normal range. False
 * (img kept) only for fewer than 3 channels or no memory for one row. */
bool stitch_view_take_half(sl_image *img, int exp2, stitch_half_image *out,
                           stitch_half_loss *loss);
/* The view as half when every RGB sample converts exactly (what merge
 * writes), else false and nothing held (the float view is used). */
bool stitch_view_to_half(const sl_image *img, stitch_half_image *out, sl_error *err);
void stitch_half_free(stitch_half_image *h);
/* A half view read as such (sl_exr_read_half_rgb): its Inf/NaN samples
 * counted and its largest RGB sample, as stitch_view_scan on its float. */
sl_result stitch_half_scan(const stitch_half_image *img, int64_t *bad, double *peak,
                           sl_error *err);
/* The half view as a float RGB image (the same values); h is freed. */
sl_result stitch_half_to_float(stitch_half_image *h, sl_image *img, sl_error *err);
/* The image circle (sl_stitch_circle_find) of a half view (exp2 0): the
 * same answer as on its float values. */
sl_result stitch_circle_find_half(const stitch_half_image *img, const char *name,
                                  sl_stitch_circle *out, sl_error *err);
/* The factor, 2 or 4, that divides the view's width and height and brings
 * the width to max_width or under, or 1. */
int stitch_solve_factor(int width, int height, int max_width);
/* src reduced by k (2 or 4: the same bytes as sl_image_resample to
 * width / k x height / k, in one pass and no intermediate image; another
 * factor: sl_image_resample). */
sl_result stitch_reduce(const sl_image *src, int k, sl_image *dst, sl_error *err);
/* The same from a half view (exp2 0; k 2 or 4, dividing its size): the
 * bytes stitch_reduce gives on its float values. */
sl_result stitch_reduce_half(const stitch_half_image *src, int k, sl_image *dst, sl_error *err);
/* A lens scaled by s for an image of width x height (focal, centre, circle). */
void stitch_lens_scale(sl_lens *lens, double s, int width, int height);

/* A view ready for lookups: its lens, world -> camera rotation, optical
 * axis in the world and its field. */
typedef struct stitch_view_prep {
    sl_lens lens;
    const sl_image *radiance, *weight;
    const stitch_half_image *half; /* not NULL: the radiance, in place of `radiance` */
    const float *half_table;       /* each half pattern's radiance (its 2^exp2 applied) */
    float *scaled_table;           /* owned: half_table when the view's exp2 is not 0 */
    double to_cam[3][3];
    double axis[3];
    double theta_max, cos_max, ramp; /* radians */
    double cos_ramp;                 /* cos of where the edge ramp starts */
    /* The weight over the edge ramp as a function of cos(theta), so the
     * blend takes a lookup where it took an acos, a cos and a sin. */
    double *ramp_table;
    double ramp_step_inv;            /* entries per unit of cos(theta) */
    int ramp_entries;
    /* The lens as q(u) = r^2 / u at u = 1 - cos(theta) (smooth for every
     * projection), so a ray's pixel takes a table lookup and one sqrt
     * instead of atan2, hypot and the radial polynomial; -1: no pixel. */
    double *q_table;
    double u_step;                   /* the table's spacing in u */
    int q_entries;
} stitch_view_prep;

/* What one lat-long row adds to the coverage. */
typedef struct stitch_row_stats {
    double seen_sr, filled_sr, masked_sr, low_sr, ghost_sr;
    int64_t ghost_texels, filled_texels, hot_texels;
    double view_sr[SL_STITCH_MAX_VIEWS];
    double power[3], seen_power[3];
} stitch_row_stats;

/* Checks the views (size against the lens, NaN/Inf samples unless the
 * caller has: `scanned`) and prepares them. half (NULL, or count
 * entries): a view whose entry has pixels is looked up there and its
 * radiance image is not used. */
sl_result stitch_prepare_views(const sl_stitch_view *views, int count,
                               const sl_stitch_blend_options *opt,
                               const stitch_half_image *half, bool scanned,
                               stitch_view_prep *prep, sl_error *err);
/* Frees what stitch_prepare_views allocated (prep may be half filled). */
void stitch_release_views(stitch_view_prep *prep, int count);
/* The pixel of view v a unit camera-frame ray sees, from its lens table;
 * false outside its field, circle or frame. r2 is the squared distance
 * from the centre (for the vignetting). Inline: the blend's inner loop. */
static inline bool stitch_view_pixel(const stitch_view_prep *v, const double ray[3], double *x,
                                     double *y, double *r2)
{
    double u = 1.0 - ray[2], t = u / v->u_step;
    if (!(t >= 0.0) || t >= v->q_entries - 1 || !(ray[2] > -1.0)) /* straight back: no pixel */
        return false;
    int i = (int)t;
    double q0 = v->q_table[i], q1 = v->q_table[i + 1];
    if (q0 < 0.0 || q1 < 0.0)
        return false;
    double q = q0 + (t - i) * (q1 - q0), rr = u * q;
    const sl_lens *l = &v->lens;
    if (l->circle_radius_px > 0.0 && rr > l->circle_radius_px * l->circle_radius_px)
        return false;
    /* r / sin(theta) = sqrt(q u / (1 - z^2)) = sqrt(q / (1 + z)) */
    double k = sqrt(q / (1.0 + ray[2]));
    double px = l->cx + k * ray[0], py = l->cy + k * ray[1];
    if (px < 0.0 || py < 0.0 || px > l->width || py > l->height)
        return false;
    *x = px;
    *y = py;
    *r2 = rr;
    return true;
}

/* A view as the blend's float inner loop reads it (stitch_rays.c): its
 * prep's tables, rotation, lens and vignetting in float. */
typedef struct stitch_ray_view {
    float *q, *ramp;           /* q_table; ramp_table plus its last entry again */
    float q_last, u_step_inv;  /* the lens table's last index, entries per unit of u */
    float ramp_last, ramp_step_inv;
    float to_cam[3][3], axis[3];
    float cos_max, cos_ramp;
    float cx, cy, width, height, circle_r2, inv_f2, vignette[3];
} stitch_ray_view;

bool stitch_ray_view_init(const stitch_view_prep *p, stitch_ray_view *v);
void stitch_ray_view_free(stitch_ray_view *v);
/* For n samples of one lat-long sub-row (latitude's sine and cosine, each
 * sample's longitude's): the view pixel each sees (px, py), its blend
 * weight, 0 where the view does not see it (ramp_weight()), and 1 / its
 * vignetting gain, 0 where the gain is 1e-6 or under. */
void stitch_rays(const stitch_ray_view *v, const float *sin_lon, const float *cos_lon,
                 float sin_lat, float cos_lat, int n, float *px, float *py, float *weight,
                 float *inv_gain);
/* Tests: the portable loops (stitch_rays without AVX2; a half view's
 * lookups and solve copy through the table, not F16C): the same bytes. */
extern bool stitch_rays_portable_only;

/* Whether the processor (and its OS) can run F16C's conversions. */
bool stitch_cpu_f16c(void);

#if defined(__x86_64__) && defined(__GNUC__)
#define STITCH_HAVE_F16C_ASM 1
#include <immintrin.h>
/* Four halves to floats in one instruction (F16C), where stitch_cpu_f16c()
 * says so. Inline assembly, not the intrinsic: the loops calling it are
 * built for the baseline processor. */
static inline __m128 stitch_halves_to_floats(const uint16_t *h)
{
    const uint16_t(*four)[4] = (const void *)h;
    __m128 f;
    __asm__("vcvtph2ps %1, %0" : "=x"(f) : "m"(*four));
    return f;
}
#endif

/* Tests and benchmarks only: every texel's samples (its finer ones on a
 * hard edge too) through the double loop, one sample at a time, that the
 * float row loop is checked against. */
extern bool stitch_blend_reference;

/* Blend weight of a view for a ray theta (radians) off its axis. */
double stitch_view_weight(const stitch_view_prep *v, double theta);
/* The blend into a sink or, when `whole` is not NULL, into that image;
 * half and scanned as for stitch_prepare_views. */
sl_result stitch_blend_run(const sl_stitch_view *views, int count,
                           const stitch_half_image *half, bool scanned,
                           const sl_stitch_blend_options *opt, sl_stitch_rows_fn sink,
                           void *user, sl_image *whole, sl_stitch_coverage *cov, sl_error *err);

/* What the stitch's report shows beside its numbers: each view's thumbnail
 * and its circle in the thumbnail's pixels, and the lat-long reduced to a
 * small RGBA map (A: mean confidence; filled: the share of filled texels). */
typedef struct stitch_report_images {
    sl_image thumb[SL_STITCH_MAX_VIEWS];
    double circle[SL_STITCH_MAX_VIEWS][3]; /* cx, cy, r; r 0: none found */
    sl_image map;                          /* RGBA means of the lat-long's texels */
    sl_image filled;                       /* share of filled texels (channel 0) */
} stitch_report_images;

/* Writes the report page (opt->report) of a stitch: summary on top. */
sl_result stitch_report_write(const char *path, const sl_stitch_result *res,
                              const stitch_report_images *img, const char *out_path,
                              sl_error *err);

/* Fills the texels of an RGBA lat-long whose A is 0 from those whose A is
 * above 0: pull-push, then diffusion on the sphere (across the poles and
 * the longitude seam). A values are left as they are. Non-negative in,
 * non-negative out. Nothing seen: left black. */
sl_result stitch_fill(sl_image *latlong, sl_error *err);
/* Median of n values (reorders them). */
double stitch_median(float *v, size_t n);

#endif
