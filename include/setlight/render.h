/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * setlight render: the validation renderer. BSDFs, light and environment
 * sampling, MIS, integrators, validation scenes and convergence reports.
 * See docs/render.md.
 */
#ifndef SETLIGHT_RENDER_H
#define SETLIGHT_RENDER_H

#include "setlight/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ================================================================== */
/* BSDFs and materials                                                 */
/* ================================================================== */

/* ================================================================== */
/* Scenes, lights, cameras, integrator                                 */
/* ================================================================== */

#ifdef __cplusplus
}
#endif

#endif /* SETLIGHT_RENDER_H */
