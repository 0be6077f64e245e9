/* SPDX-License-Identifier: BSD-3-Clause */
/* Internal pieces of the chrome-ball unwrap shared by its files. */
#ifndef SETLIGHT_UNWRAP_PRIVATE_H
#define SETLIGHT_UNWRAP_PRIVATE_H

#include "setlight/stitch.h"

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

/* The default lat-long width for a view: one texel per photo pixel where
 * the ball looks back at the camera. */
int unwrap_auto_width(const sl_ball_view *view);

/* C shim over OpenCV's HoughCircles: up to max_out circles (x, y, r)
 * on an 8-bit single-channel image, strongest first. Returns the count, or
 * -1 when OpenCV failed. */
int ball_hough_cxx(const unsigned char *gray, int width, int height, double min_radius,
                   double max_radius, double min_dist, float *out, int max_out);

#endif
