/* SPDX-License-Identifier: BSD-3-Clause */
/* The Lambert closed form's progressive fill over the sphere of normals
 * (normal_fill.c). Private to render/. */
#ifndef SETLIGHT_RENDER_NORMAL_FILL_H
#define SETLIGHT_RENDER_NORMAL_FILL_H

#include "glossy.h"

/* Points of Lambert objects under the dome (pixel centres, and the
 * sub-pixel points of the box filter's 3 x 3 grids). */
typedef struct sl_lambert_points {
    int64_t count;
    const double (*n)[3]; /* world normals */
    double (*E)[3];       /* in: the rig lights' irradiance; out: plus the dome's */
    double (*bound)[3];   /* in: its bound; out: the total's (an estimate where interpolated) */
    uint8_t *interpolated; /* out: the map's rest interpolated over normals */
    uint8_t *at_tol;       /* out: refined to the tolerance (0: a cut left it coarser) */
} sl_lambert_points;

typedef struct sl_lambert_fill_stats {
    bool cut;                /* the deadline or eval_limit ended the refinement */
    int64_t coarse_evaluations; /* the first pass's */
    sl_irradiance_cost cost;
} sl_lambert_fill_stats;

/* Every point gets a value and its bound from a first coarse pass (the sun
 * at each point; the rest interpolated over cube-face blocks of 45
 * degrees); blocks are then refined, the largest error first, until every
 * one is within the tolerance, the deadline (sl_seconds) passes, or
 * eval_limit (> 0; tests' deterministic stand-in for the deadline)
 * evaluations of the rest have been made after the first pass. */
sl_result sl_lambert_fill(const sl_glossy_dome *gd, double tol, sl_lambert_points *pts, double deadline,
                          int64_t eval_limit, sl_lambert_fill_stats *st, sl_error *err);

#endif
