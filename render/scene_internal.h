/* SPDX-License-Identifier: BSD-3-Clause */
/* The scene's parts as the integrator sees them: ray queries on the shapes,
 * camera rays, the dome and the lights (evaluation and sampling).
 * Private to render/. */
#ifndef SETLIGHT_RENDER_SCENE_INTERNAL_H
#define SETLIGHT_RENDER_SCENE_INTERNAL_H

#include <stdbool.h>
#include "setlight/render.h"

/* ---- shapes (shapes.c) ---- */
typedef struct sl_hit {
    double t;
    double p[3];
    double n[3]; /* geometric normal, facing the incoming ray */
    int shape;
    bool inside; /* a sphere seen from inside: its concave side can occlude */
} sl_hit;

/* Nearest hit with t in (tmin, tmax). */
bool sl_scene_intersect(const sl_scene *scene, const double o[3], const double d[3], double tmin,
                        double tmax, sl_hit *hit);
bool sl_scene_occluded(const sl_scene *scene, const double o[3], const double d[3], double tmax);
/* Nearest hit of the ray on one shape alone (others ignored). */
bool sl_shape_intersect(const sl_scene *scene, int shape, const double o[3], const double d[3],
                        sl_hit *hit);
/* Ray origin nudged off a surface at p (normal n) toward direction d. */
void sl_offset_origin(const double p[3], const double n[3], const double d[3], double out[3]);

/* ---- camera (camera.c) ---- */
/* Ray through image position (sx, sy) in [0,1]^2 (y down); false outside a fisheye circle. */
bool sl_camera_ray(const sl_camera *cam, double sx, double sy, double o[3], double d[3]);

/* ---- dome (dome.c) ---- */
/* Radiance (intensity applied) arriving from world direction d, piecewise constant per texel. */
void sl_dome_radiance(const sl_dome *dome, const double d[3], double L[3]);
/* Bilinear radiance for what the camera sees directly. */
void sl_dome_background(const sl_dome *dome, const double d[3], double L[3]);
/* True when the dome has energy to importance-sample. */
bool sl_dome_can_sample(const sl_dome *dome);
/* Samples a world direction; pdf is per solid angle (the estimator's);
 * mis_pdf (may be NULL) is the value sl_dome_radiance_pdf gives for the same
 * direction, for MIS weights. False (pdf 0) at a pole. */
bool sl_dome_sample(const sl_dome *dome, const double u[2], double wi[3], double L[3], double *pdf,
                    double *mis_pdf);
/* Solid-angle pdf in double precision (tests). */
double sl_dome_pdf(const sl_dome *dome, const double wi[3]);
/* Radiance and the MIS pdf at once (one lookup); only when sl_dome_can_sample. */
void sl_dome_radiance_pdf(const sl_dome *dome, const double d[3], double L[3], double *pdf);
void sl_dome_free(sl_dome *dome);
/* A dome of map rgb (RGB, sanitised, like's size) with like's rotation and
 * intensity and its own sampling tables (the glossy pixels' rest map). */
sl_result sl_dome_init_like(sl_dome *out, const sl_dome *like, const sl_image *rgb, sl_error *err);

/* ---- lights (lights.c) ---- */
/* Samples a direction toward the light from p; dist is the distance to the
 * sampled point (INFINITY for distant lights). delta: a direction with no
 * solid angle (pdf is then 1 and L is irradiance). */
bool sl_light_sample(const sl_light *l, const double p[3], const double u[2], double wi[3],
                     double *dist, double L[3], double *pdf, bool *delta);
/* Solid-angle pdf of sl_light_sample for direction wi hitting the light at dist. */
double sl_light_pdf(const sl_light *l, const double p[3], const double wi[3], double dist);
/* A ray (o, d) reaching the light before tmax: distance and emitted radiance. */
bool sl_light_intersect(const sl_light *l, const double o[3], const double d[3], double tmax,
                        double *t, double L[3]);

/* Upper bound of the irradiance the light can deliver at p with normal n
 * (max channel), INFINITY when none is known (p inside its bounding sphere,
 * a texture). *behind: p sees only the back of a one-sided light or the light
 * is wholly below the horizon: exactly 0. */
double sl_light_irradiance_bound(const sl_light *l, const double p[3], const double n[3],
                                 bool *behind);

#endif
