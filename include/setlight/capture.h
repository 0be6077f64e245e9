/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * setlight capture: cameras (libgphoto2, virtual, folder ingest), bracket
 * plans and grouping, the session journal, and the virtual set that
 * simulates a whole on-set capture with its ground truth.
 */
#ifndef SETLIGHT_CAPTURE_H
#define SETLIGHT_CAPTURE_H

#include "setlight/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ================================================================== */
/* Virtual set: scenes and the simulated camera                        */
/* ================================================================== */

/* ================================================================== */
/* Cameras, bracket plans, journal and sessions                        */
/* ================================================================== */

#ifdef __cplusplus
}
#endif

#endif /* SETLIGHT_CAPTURE_H */
