/* SPDX-License-Identifier: BSD-3-Clause */
/* Private helpers of the calibrate stage. */
#ifndef SETLIGHT_CALIBRATE_INTERNAL_H
#define SETLIGHT_CALIBRATE_INTERNAL_H

#include <stdbool.h>

/* Solves a x = b in place (a: n x n row-major, b: n) by Gaussian
 * elimination with partial pivoting; false when singular. */
bool sl_cal_solve(double *a, double *b, int n);



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
