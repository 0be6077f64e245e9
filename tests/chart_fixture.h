/* SPDX-License-Identifier: BSD-3-Clause */
/* Synthetic chart photos of the kinds that fool a chart detector: a white
 * brick wall (mortar lines, brick-to-brick and pixel texture, no chart),
 * the wall with coloured squares that are not a ColorChecker (a few
 * scattered ones, or a 6 x 4 grid of the chart's own colours in another
 * order), and a real ColorChecker painted on it (exact patch reflectances
 * SL_COLORCHECKER_LINEAR) that may be tiny, cut by the frame or
 * overexposed. Linear RGB, 3 channels, values clipped at 1 like a sensor;
 * every patch centre known. */
#ifndef SETLIGHT_CHART_FIXTURE_H
#define SETLIGHT_CHART_FIXTURE_H

#include <stdbool.h>
#include <stdint.h>

#include "setlight/core.h"

typedef struct chart_fixture {
    int width, height;
    double exposure;   /* value of a reflectance-1 surface under the light */
    double light[3];   /* the light's colour (multiplies every reflectance) */
    bool chart;        /* paint a 6 x 4 grid of patches on a black board */
    double center[2];  /* the grid's centre, pixels */
    double pitch;      /* patch pitch, pixels */
    double angle_deg;  /* in-plane turn of the board */
    int order[24];     /* reference patch shown at each place (identity: a ColorChecker) */
    int squares;       /* coloured squares scattered on the wall, not in a grid */
    uint64_t seed;
} chart_fixture;

/* A 640 x 480 wall under a slightly warm light, exposure 0.8, no chart;
 * order the identity, a board pitch of 40 px at the centre when chart is set. */
void chart_fixture_init(chart_fixture *f);

/* Renders the photo (3 channels, 3 x 3 samples per pixel). */
sl_result chart_fixture_render(const chart_fixture *f, sl_image *img, sl_error *err);

/* The centre of place p (0..23, chart order) in the photo. */
void chart_fixture_center(const chart_fixture *f, int p, double xy[2]);

/* Sets f up as make_fixture's kind (below); false for an unknown one. */
bool chart_fixture_kind(chart_fixture *f, const char *kind);

/* make_fixture's chart kinds; OUT ending in .jpg is written as an 8-bit
 * sRGB JPEG, else a linear EXR:
 *   chartwall      the white brick wall alone
 *   chartsquares   the wall with five coloured squares scattered on it
 *   chartshuffled  the wall with a 6 x 4 board of the chart's colours in
 *                  another order
 *   chartok        a ColorChecker on the wall (pitch 40 px)
 *   charttiny      a ColorChecker 36 px across (pitch 6 px)
 *   chartcut       a ColorChecker with its right two columns out of frame
 *   chartclipped   a ColorChecker overexposed 1.6 stops (11 patches clip) */
int chart_fixture_main(const char *kind, const char *out);

#endif
