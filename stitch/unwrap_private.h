/* SPDX-License-Identifier: BSD-3-Clause */
/* Internal pieces of the chrome-ball unwrap shared by its files. */
#ifndef SETLIGHT_UNWRAP_PRIVATE_H
#define SETLIGHT_UNWRAP_PRIVATE_H

#include "setlight/stitch.h"

#include <math.h>

/* One set direction on the ball: photo pixel and cosine of incidence.
 * blind: the direction is farther than phi_max from the view axis's reverse
 * (0 = straight back at the camera), beyond what the ball shows; the pixel
 * is then the rim point of the same azimuth. */
typedef struct ball_hit {
    double x, y;
    double cos_incidence;
    bool blind;
} ball_hit;

void ball_view_map(const sl_ball_view *view, const double dir[3], ball_hit *hit);
/* The same for a direction already in the view frame (unit). */
void ball_view_map_local(const sl_ball_view *view, const double wv[3], ball_hit *hit);

/* For tests: true makes the unwrap take its portable row loop even where
 * the processor has AVX2 and FMA (the row loop built for them is used
 * otherwise). Not thread-safe; false by default. */
void unwrap_use_portable_rows(bool on);

/* For tests: false makes each point pulled onto the rim clamp circle look
 * the photo up itself instead of through the circle's table (true by
 * default). Not thread-safe. */
void unwrap_use_rim_table(bool on);

/* The default lat-long width for a view: one texel per photo pixel where
 * the ball looks back at the camera. */
int unwrap_auto_width(const sl_ball_view *view);

/* C shim over OpenCV's HoughCircles: up to max_out circles (x, y, r)
 * on an 8-bit single-channel image, strongest first, from the kinds of
 * transform asked for (the classic one's time grows fastest with clutter
 * and size; edge_threshold is its Canny threshold, lower for soft edges).
 * Returns the count, or -1 when OpenCV failed. */
enum { BALL_HOUGH_ALT = 1, BALL_HOUGH_CLASSIC = 2 };
int ball_hough_cxx(const unsigned char *gray, int width, int height, double min_radius,
                   double max_radius, double min_dist, int kinds, double edge_threshold,
                   float *out, int max_out);

/* A point of an outline (pixels). */
typedef struct ball_point {
    double x, y;
} ball_point;

/* Geometric least-squares circle (Gauss-Newton from the algebraic Kasa fit)
 * through the points flagged in use[]; c holds a start (cx, cy, r) and gets
 * the fit. False with fewer than 8 points or a degenerate fit. */
bool ball_circle_fit(const ball_point *p, const bool *use, int n, double c[3]);

/* The smaller singular value of a 2x2 Jacobian (photo pixels per unit of
 * the two directions): how little the mapping stretches any direction. */
static inline double smaller_singular_value(const double j[2][2])
{
    double p = j[0][0] * j[0][0] + j[1][0] * j[1][0];
    double q = j[0][1] * j[0][1] + j[1][1] * j[1][1];
    double s = j[0][0] * j[0][1] + j[1][0] * j[1][1];
    double tr = 0.5 * (p + q), det = p * q - s * s, disc = tr * tr - det;
    double e = tr - sqrt(disc > 0.0 ? disc : 0.0);
    return sqrt(e > 0.0 ? e : 0.0);
}

#endif
