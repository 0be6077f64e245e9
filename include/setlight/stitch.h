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

/* The ball's outline in the photo, in pixels of the full image: the image's
 * top-left corner is (0, 0) and pixel (i, j) has its centre at
 * (i + 0.5, j + 0.5). */
typedef struct sl_ball_circle {
    double cx, cy, r;
    double residual;  /* RMS distance (px) of the edge points to the circle; 0 if given */
    int edge_points;  /* sub-pixel edge points the fit used; 0 if given */
} sl_ball_circle;

/* Finds one chrome ball: circle candidates from OpenCV's Hough transform on
 * a log-tonemapped copy, then sub-pixel edge points on the HDR image along
 * rays from each candidate's centre and a robust least-squares circle fit.
 * SL_ERR_INPUT when no ball is found, when two or more are, or when the ball
 * is cut by the frame edge (circle then holds the clipped ball's outline);
 * `name` (a file name) starts the message. */
sl_result sl_ball_detect(const sl_image *photo, const char *name, sl_ball_circle *circle,
                         sl_error *err);

typedef enum {
    SL_BALL_ORTHOGRAPHIC = 0, /* camera infinitely far: the classic mirror-ball map */
    SL_BALL_PERSPECTIVE       /* pinhole camera at a finite distance */
} sl_ball_camera;

/* How the photo was taken. The camera frame looks along +Z with +Y up and
 * image right -X (the renderer's validation camera); azimuth, elevation and
 * roll place it in the set: world = Ry(azimuth) Rx(-elevation) Rz(roll) cam,
 * so azimuth +90 looks along +X, elevation +90 looks up (+Y), and a positive
 * roll turns the camera's up toward its right. */
typedef struct sl_ball_geometry {
    sl_ball_camera camera;
    /* Perspective only. focal_px: the focal length in pixels of this image
     * (focal_mm * image_width / sensor_width_mm), principal point at the image
     * centre; with it the ball may sit anywhere in the frame and its distance
     * comes from its apparent size. distance: camera to ball centre in ball
     * radii (distance_mm / (diameter_mm / 2)); overrides the apparent size.
     * At least one must be > 0; with only the distance the ball is taken to
     * be on the optical axis. */
    double focal_px;
    double distance;
    double azimuth_deg, elevation_deg, roll_deg;
} sl_ball_geometry;

typedef enum {
    SL_REFLECTANCE_CONSTANT = 0, /* R per channel at every angle (1 = ideal mirror) */
    SL_REFLECTANCE_CONDUCTOR     /* exact unpolarised Fresnel of a metal, n + ik per channel */
} sl_reflectance_kind;

typedef struct sl_reflectance {
    sl_reflectance_kind kind;
    double value[3];
    double n[3], k[3];
} sl_reflectance;

void sl_reflectance_constant(sl_reflectance *refl, double r, double g, double b);
/* A neutral conductor n = 3.2, k = 3.3: 0.55 at normal incidence rising to
 * 1 at grazing, typical of chrome-plated balls. */
void sl_reflectance_chrome(sl_reflectance *refl);
/* Reflectance per channel for the cosine of the angle of incidence. */
void sl_reflectance_eval(const sl_reflectance *refl, double cos_incidence, double out[3]);

/* The mapping between set directions and photo pixels for one ball photo. */
typedef struct sl_ball_view {
    sl_ball_camera camera;
    int width, height;         /* photo size */
    double cx, cy, r;          /* the circle */
    double focal_px;           /* perspective: the pinhole used */
    double distance;           /* perspective: camera to centre in ball radii; 0 orthographic */
    double ball_angle;         /* angular radius of the ball seen from the camera (rad) */
    double off_axis;           /* angle between the optical axis and the ball centre (rad) */
    double phi_max;            /* largest angle from the view axis's reverse seen: pi - ball_angle */
    double cam_to_world[3][3];
    double view_to_cam[3][3];  /* view frame: +Z from the camera through the ball centre */
    double theta_table[1025];  /* sphere angle for reflected angle, uniform in [0, phi_max] */
    double centre_px_per_rad;  /* photo resolution where the ball reflects back at the camera */
} sl_ball_view;

/* SL_ERR_USAGE when the circle is not inside the photo or the perspective
 * model lacks focal length and distance. */
sl_result sl_ball_view_init(sl_ball_view *view, int width, int height, const sl_ball_circle *c,
                            const sl_ball_geometry *g, sl_error *err);
/* Set direction -> photo pixel (x, y) on the ball and the cosine of the
 * angle of incidence there. Directions in the blind cone behind the ball
 * return false and the rim point of the same azimuth. */
bool sl_ball_view_dir_to_pixel(const sl_ball_view *view, const double dir[3], double *x,
                               double *y, double *cos_incidence);
/* Photo pixel -> reflected set direction; false off the ball. */
bool sl_ball_view_pixel_to_dir(const sl_ball_view *view, double x, double y, double dir[3],
                               double *cos_incidence);
/* Photo pixels per radian of set direction along the direction of least
 * resolution (the smaller singular value of the mapping); 0 in the blind cone. */
double sl_ball_view_resolution(const sl_ball_view *view, const double dir[3]);

typedef struct sl_unwrap_options {
    sl_ball_circle circle;
    sl_ball_geometry geometry;
    sl_reflectance reflectance;
    int width; /* output lat-long width; 0 = matched to the ball's resolution */
} sl_unwrap_options;

typedef struct sl_unwrap_info {
    int width, height;
    double distance;          /* camera distance in ball radii; 0 orthographic */
    double focal_px;
    double ball_angle_deg;    /* angular radius of the ball seen from the camera */
    double blind_angle_deg;   /* half-angle of the cone behind the ball the photo cannot see */
    double off_axis_deg;
    double centre_px_per_rad;
    double blind_fraction;    /* of the sphere's solid angle */
    int64_t nonfinite;        /* NaN/Inf photo samples replaced by 0 */
} sl_unwrap_info;

/* Unwraps a linear HDR photo of a chrome ball into a lat-long of the set's
 * radiance (OpenEXR orientation), 4 channels: RGB and a confidence in [0, 1]
 * (the resolution relative to the ball's centre; 0 in the blind cone, where
 * RGB is a smooth fill from the rim, never detail). Each output texel is the
 * solid-angle-weighted average of the photo over its footprint, sampled finely
 * enough that bright sources do not alias. Pixels are divided by the
 * reflectance at their angle of incidence. info may be NULL. */
sl_result sl_unwrap(const sl_image *photo, const sl_unwrap_options *opt, sl_image *out,
                    sl_unwrap_info *info, sl_error *err);

/* ================================================================== */
/* Calibrate: grey sphere and chart                                    */
/* ================================================================== */

#ifdef __cplusplus
}
#endif

#endif /* SETLIGHT_STITCH_H */
