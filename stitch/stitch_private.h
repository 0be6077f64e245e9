/* SPDX-License-Identifier: BSD-3-Clause */
/* The fisheye stitch's private interface: the OpenCV feature shim
 * (stitch_features_cxx.cpp, loaded through opencv_module.c). */
#ifndef SETLIGHT_STITCH_PRIVATE_H
#define SETLIGHT_STITCH_PRIVATE_H

#include <stddef.h>

#include "setlight/stitch.h"

/* Descriptor bytes: SIFT's 128 values saturated to bytes (OpenCV's SIFT
 * already scales them to 0..255), AKAZE's 61-byte binary strings. */
#define STITCH_DESC_MAX 128
enum { STITCH_DETECT_SIFT = 0, STITCH_DETECT_AKAZE = 1 };

/* Keypoints of an 8-bit image where mask (may be NULL) is non-zero: at
 * most max_out, strongest first; xy gets their positions (pixel centres at
 * +0.5, as sl_lens), desc max_out * STITCH_DESC_MAX bytes. Returns the
 * count, -1 on failure (msg says why); *desc_bytes gets the descriptor
 * size. */
int stitch_features_cxx(const unsigned char *gray, const unsigned char *mask, int width,
                        int height, int detector, int max_out, float *xy, unsigned char *desc,
                        int *desc_bytes, char *msg, size_t msg_size);

/* Mutual nearest neighbours between two descriptor sets that pass Lowe's
 * ratio test both ways (L2 for SIFT, Hamming for AKAZE): up to max_out
 * index pairs (ia, ib) into pairs. Returns the count, -1 on failure. */
int stitch_match_cxx(const unsigned char *desc_a, int count_a, const unsigned char *desc_b,
                     int count_b, int desc_bytes, int detector, double ratio, int *pairs,
                     int max_out, char *msg, size_t msg_size);

/* ---- the solve (stitch_solve*.c) ---------------------------------- */

/* One view's features, positions in the full view's pixels; and its
 * luminance at the features' scale (for the vignetting), with the merge's
 * confidence (1 where the view has no weight image). */
typedef struct solve_features {
    int count;
    float *xy;
    unsigned char *desc;
    int desc_bytes;
    double scale;        /* full pixels per feature-copy pixel */
    sl_image luminance;  /* 1 channel, at the features' scale */
    sl_image confidence; /* 1 channel, same size */
} solve_features;

sl_result solve_find_features(const sl_stitch_view *view, const sl_stitch_solve_options *opt,
                              solve_features *out, sl_error *err);
void solve_features_free(solve_features *f);
/* Cross-checked ratio-test matches between the features with keep set
 * (NULL: all); *pairs (index pairs into a's and b's features) is malloc'd. */
sl_result solve_match_features(const solve_features *a, const bool *keep_a,
                               const solve_features *b, const bool *keep_b,
                               const sl_stitch_solve_options *opt, int **pairs, int *count,
                               sl_error *err);

/* A match between views a < b, full-resolution pixel positions. */
typedef struct solve_match {
    int pair;      /* index into the result's pairs */
    int a, b;
    double pa[2], pb[2];
    /* A point on an edge (refined across it only): the unit normal in view
     * a, and the match's one residual is b's point seen in a along it;
     * (0, 0) for a point. */
    double normal[2];
    bool inlier;
} solve_match;

/* The lens with its bounds lifted (no circle, no frame, the widest field
 * the projection has), for residuals of points near the circle's edge. */
void solve_lens_unbounded(const sl_lens *lens, sl_lens *out);
/* The pixel of view `to` that sees what pixel px_from of view `from` sees. */
bool solve_transfer(const sl_lens *unbounded, const double from[3][3], const double to[3][3],
                    const double px_from[2], double px_to[2]);
/* Sub-pixel match positions: each inlier's point in view a re-found by
 * Lucas-Kanade on the full-resolution log luminance against view b's
 * patch warped through the current geometry; a match that does not
 * converge is dropped. Returns how many were refined. */
int solve_refine_matches(const sl_stitch_view *views, solve_match *matches, int count,
                         double (*rot)[3][3], const sl_lens *lens, double step_px);
/* world_dir expressed in the camera frame of a view whose cam_to_world is rot. */
void solve_to_camera(const double rot[3][3], const double world[3], double cam[3]);
/* Direction i of n spread evenly over the sphere (a Fibonacci lattice). */
void solve_sphere_dir(int i, int n, double dir[3]);
/* R <- Exp(w) R for a rotation vector w (radians). */
void solve_rotate(double r[3][3], const double w[3]);
/* Angle in degrees between two rotations. */
double solve_rotation_angle(const double a[3][3], const double b[3][3]);

/* A measurement of the optical centre beside the overlaps (the image
 * circle's centre): pixels, one standard deviation per axis. */
typedef struct solve_centre_prior {
    double cx, cy, sigma_x, sigma_y;
} solve_centre_prior;

/* The bundle adjustment: rotations rot[view] (cam_to_world) of the views
 * with free[view] set, and the lens values opt asks for, over the matches
 * marked inlier. Huber loss of scale huber_px. prior (may be NULL) adds the
 * centre's measurement, weighed against the matches' own residual
 * variance. centre_cov (may be NULL) gets the solved centre's covariance
 * (px^2: xx, xy, yy; zeros when the centre is not solved). Returns
 * iterations. */
int solve_adjust(solve_match *matches, int count, double (*rot)[3][3], const bool *free_view,
                 int views, sl_lens *lens, const sl_stitch_solve_options *opt, double huber_px,
                 const solve_centre_prior *prior, double centre_cov[3]);
/* Reprojection error of one match (both directions), pixels; -1 if a ray
 * cannot be formed. */
double solve_match_error(const solve_match *m, double (*rot)[3][3], const sl_lens *unbounded,
                         double *err_b_in_a, double *err_a_in_b);

/* The match's residuals, pixels: b's point seen in a (x, y), a's in b (x,
 * y); an edge's one residual across it first, the rest 0. False if a ray
 * cannot be formed. */
bool solve_match_residuals(const solve_match *m, double (*rot)[3][3], const sl_lens *unbounded,
                           double res[4]);

/* The optical centre measured by the views' image circles (opt->circles,
 * else found): the inverse-variance mean of the views' centres (a view far
 * from the others' median left out), its spread widened by their scatter;
 * false (res->centre_note says why) when there is none. */
bool solve_centre_from_circles(const sl_stitch_view *views, int count,
                               const sl_stitch_solve_options *opt, solve_centre_prior *prior,
                               sl_stitch_solve_result *res);
/* Appends to res->centre_note ("; " between notes). */
void solve_centre_note(sl_stitch_solve_result *res, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* Whether the centre the overlaps solve alone (covariance cov: xx, xy,
 * yy) agrees with the circles' within chance; fills res's centre fields
 * and note. */
bool solve_centre_agrees(const solve_centre_prior *prior, const sl_lens *overlaps,
                         const double cov[3], sl_stitch_solve_result *res);

/* Vignetting v1, v2 and per-view gains from the radiance ratios in the
 * overlaps of res's solved pairs; fills res's vignette fields and gain. */
void solve_vignette(int count, const solve_features *feat, double (*rot)[3][3], sl_lens *lens,
                    sl_stitch_solve_result *res);

/* A view's ln luminance at the features' scale reduced `factor` times by
 * 2 x 2 means; NaN where the merge was not confident or the view is dark,
 * and wherever a reduction reaches such a pixel. */
typedef struct solve_log_image {
    float *log;
    int width, height;
    double scale; /* full pixels per pixel */
} solve_log_image;
bool solve_log_image_make(const solve_features *f, int factor, solve_log_image *out);
/* ln radiance a view (cam_to_world rot) sees in world direction d, its
 * vignetting (lens) removed, bilinear; false outside inner's circle, off
 * the data, or on a hard edge (its 2 x 2 pixels spanning more than
 * edge_log). */
bool solve_log_radiance(const solve_log_image *l, const sl_lens *lens, const sl_lens *inner,
                        const double rot[3][3], const double d[3], double edge_log, double *out);

/* Turns the views with moving set (one group, rigidly) to where their
 * overlaps' log radiance agrees with the placed views' (lens, vignetting and
 * the other views' gains held; each moving view's gain solved with it):
 * coarse to fine Gauss-Newton over the group's rotation. Applied (rot and
 * gain updated) and true only when the turn is within max_turn_deg, its
 * worst-determined axis known to max_sigma_deg (the Hessian's smallest
 * eigenvalue against the residuals' spread) and the residual fell; why
 * says which. */
bool solve_radiance_turn(int count, const solve_features *feat, double (*rot)[3][3],
                         const bool *moving, const bool *placed, const sl_lens *lens,
                         double *gain, double max_turn_deg, double max_sigma_deg, char *why,
                         size_t why_size);
/* The lens refined by the overlaps' smooth radiance together with the
 * features (stitch_solve_radiance_lens.c): ln focal, k1, k2 (as opt
 * solves them), v1, v2, the free views' rotations and the gains by
 * Gauss-Newton on the log radiance difference at the solved pairs'
 * overlaps and the inlier matches' reprojection residuals, each weighed by
 * its own scatter at the features' solution, from which it starts.
 * Applied (lens, rot, gain updated) and true when the joint cost fell. */
typedef struct solve_radiance_lens_result {
    int samples;
    double rms_start, rms; /* Huber-weighted RMS log residual before and after */
    double px_start, px;   /* RMS reprojection residual (per coordinate) before and after */
    double focal_change;   /* relative */
    bool kept;
} solve_radiance_lens_result;
bool solve_radiance_lens(int count, const solve_features *feat, double (*rot)[3][3],
                         const bool *free_view, const sl_stitch_pair *pair, int pairs,
                         const solve_match *matches, int match_count,
                         const sl_stitch_solve_options *opt, sl_lens *lens, double *gain,
                         solve_radiance_lens_result *out);

#endif
