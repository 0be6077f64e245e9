/* SPDX-License-Identifier: BSD-3-Clause */
/* Private helpers of the calibrate stage. */
#ifndef SETLIGHT_CALIBRATE_INTERNAL_H
#define SETLIGHT_CALIBRATE_INTERNAL_H

#include <stdbool.h>

/* Solves a x = b in place (a: n x n row-major, b: n) by Gaussian
 * elimination with partial pivoting; false when singular. */
bool sl_cal_solve(double *a, double *b, int n);

#endif
