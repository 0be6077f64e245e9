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

#ifdef __cplusplus
}
#endif

#endif /* SETLIGHT_STITCH_H */
