/* SPDX-License-Identifier: BSD-3-Clause */
/* Private helpers of the calibrate stage. */
#ifndef SETLIGHT_CALIBRATE_INTERNAL_H
#define SETLIGHT_CALIBRATE_INTERNAL_H

#include <stdbool.h>

#include "setlight/stitch.h"

/* Solves a x = b in place (a: n x n row-major, b: n) by Gaussian
 * elimination with partial pivoting; false when singular. */
bool sl_cal_solve(double *a, double *b, int n);

/* Grey sphere helpers shared by the fit and the clipped-sun repair. */
/* The virtual camera: perspective (distance > 0) looks at the sphere's
 * centre with the sphere's outline spanning its image; a virtual pixel's
 * ray is traced to the photo through the pinhole (focal_px, principal
 * point ppx, ppy; view_to_cam as sl_ball_view's). */
typedef struct sl_cal_view {
    double distance;   /* sphere radii; 0 orthographic */
    double tan_half;   /* tan of the sphere's angular radius */
    double focal_px, ppx, ppy;
    double view_to_cam[3][3];
} sl_cal_view;
/* Checks the options against the photo and sets up the view. */
sl_result sl_cal_grey_check(const sl_grey_options *o, const sl_image *photo, sl_cal_view *view,
                            sl_error *err);
/* Pixels across the virtual render. */
int sl_cal_sphere_size(const sl_grey_options *o);
/* The virtual sphere (albedo, view, spp, seed of o) under env, n x n RGBA. */
sl_result sl_cal_render_sphere(const sl_image *env, const sl_grey_options *o, const sl_cal_view *v,
                               int n, sl_image *out, sl_error *err);
/* The photo's circle resampled onto out (n x n RGBA, allocated), each
 * pixel the mean over its footprint: alpha 1 where the pixel is within
 * o->inner of the radius and every tap is finite and below o->clip_level,
 * else 0 and black. */
void sl_cal_resample_photo(const sl_image *photo, const sl_grey_options *o, const sl_cal_view *v,
                           sl_image *out);

#include <stddef.h>

/* OpenCV mcc on an 8-bit BGR image: 1 and the chart's four box corners
 * (pixels) when a ColorChecker Classic 24 is found, 0 when none is, -1 on
 * an OpenCV error (msg gets its text). */
int sl_cal_mcc_detect(const unsigned char *bgr, int width, int height, double box[4][2],
                      double *cost, char *msg, size_t msg_size);

/* Patch centres from four image points and their (column, row) grid
 * coordinates (patch 1 at (0, 0), patch 24 at (5, 3)). */
bool sl_cal_grid_centers(const double img[4][2], const double grid[4][2], double centers[24][2]);
#endif
