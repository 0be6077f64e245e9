/* SPDX-License-Identifier: BSD-3-Clause */
/* Synthetic chrome-ball photos by exact ray tracing, with their ground
 * truth: an orthographic or pinhole camera (principal point at the image
 * centre) placed in the set by azimuth/elevation/roll, one or two mirror
 * spheres, reflection at the hit point, a procedural environment with small
 * bright sources (or any lat-long), a reflectance, supersampled pixels and a
 * cluttered background. Independent of the unwrap code except for the
 * camera-to-set rotation (sl_rotation_euler). */
#ifndef SETLIGHT_BALL_FIXTURE_H
#define SETLIGHT_BALL_FIXTURE_H

#include "setlight/stitch.h"

#define BALL_FIXTURE_SOURCES 3

typedef struct ball_fixture_ball {
    /* Orthographic: the outline in pixels (pixel centres at i + 0.5).
     * Perspective: the pixel where the centre projects and the distance
     * from the camera in ball radii. */
    double px, py;
    double r;        /* orthographic radius in pixels */
    double distance; /* perspective */
} ball_fixture_ball;

/* Round things in the background that are not balls. */
typedef enum { BALL_THING_DISC, BALL_THING_RING, BALL_THING_DIAL } ball_thing_kind;

typedef struct ball_thing {
    ball_thing_kind kind;
    double x, y, r; /* outline (px) */
    double inner;   /* ring: inner radius (px) */
    double value;   /* grey level */
} ball_thing;

#define BALL_FIXTURE_THINGS 8

typedef struct ball_fixture {
    int width, height;
    bool perspective;
    double focal_px;
    double azimuth_deg, elevation_deg, roll_deg;
    int ball_count; /* 1 or 2 */
    ball_fixture_ball balls[2];
    sl_reflectance reflectance;
    const sl_image *env; /* lat-long to reflect; NULL for the procedural one */
    int ss;              /* sub-samples per pixel axis, near the balls (1 elsewhere) */
    bool clutter;        /* textured background instead of a flat 0.05 */
    bool ss_rim_only;    /* supersample only within 2 px of an outline (fast big frames) */
    int thing_count;
    ball_thing things[BALL_FIXTURE_THINGS]; /* drawn over the background */
} ball_fixture;

/* A fixture with the defaults: orthographic, 1 ball, reflectance 1, ss 4, clutter. */
void ball_fixture_init(ball_fixture *f, int width, int height);

/* The procedural environment (smooth sky and ground and three small bright
 * discs) in set direction `dir` (unit). */
void ball_fixture_env(const double dir[3], double rgb[3]);
/* Centre direction (unit) and angular radius (rad) of bright source i. */
void ball_fixture_source(int i, double dir[3], double *radius);

/* Renders the photo (3 channels). */
sl_result ball_fixture_render(const ball_fixture *f, sl_image *photo, sl_error *err);

/* Ground truth: the environment box-filtered over each texel of a
 * width x width/2 lat-long (sub x sub solid-angle-weighted samples). */
sl_result ball_fixture_truth(const ball_fixture *f, int width, int sub, sl_image *out,
                             sl_error *err);

/* The outline a circle fit sees for ball i, measured on the traced
 * silhouette: ellipse centre and mean semi-axis. */
void ball_fixture_circle(const ball_fixture *f, int i, sl_ball_circle *c);

/* Traces the camera ray through photo point (x, y) to ball i: the reflected
 * set direction and the cosine of incidence; false on a miss. */
bool ball_fixture_trace(const ball_fixture *f, int i, double x, double y, double dir[3],
                        double *cos_incidence);

/* A circular fisheye photo of the procedural environment (equisolid,
 * 180 degrees, looking along +Z, image circle of `radius` px at the frame
 * centre, light falling off by 40% toward its edge) on a black frame with
 * a little sensor noise: what unwrap and convert must not take for a ball. */
sl_result ball_fixture_fisheye(int width, int height, double radius, sl_image *photo,
                               sl_error *err);

/* make_fixture's ball kinds (200x160 perspective chrome ball, focal 180 px):
 * ball, balljpg (8-bit sRGB JPEG), balltwo, ballclip, ballnone, ball90
 * (the same set from azimuth 90, for two-view merging), ballfill (an
 * orthographic chrome ball filling a 256x256 frame, r 128) and ballfisheye
 * (a 300x200 circular fisheye photo, radius 90 px, not a ball). */
int ball_fixture_main(const char *kind, const char *out);

#endif
