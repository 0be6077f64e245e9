/* SPDX-License-Identifier: BSD-3-Clause */
/* Private: the closed-form irradiance of a rig's lights (area_closed_form.c)
 * and the closed form of a Lambert point lit by the dome and the lights. */
#ifndef SETLIGHT_AREA_CLOSED_FORM_H
#define SETLIGHT_AREA_CLOSED_FORM_H

#include "closed_form.h"
#include "irradiance.h"
#include "scene_internal.h"
#include "vec3.h"

/* Integral of max(0, n.w) over the solid angle a planar convex polygon
 * (world vertices, either winding) subtends from p, clipped at the plane
 * through p normal to n (Lambert's formula). Irradiance = radiance x this. */
double sl_polygon_cosine_integral(const double (*v)[3], int nv, const double p[3], const double n[3]);

/* The same for a spherical cap of angular radius sigma (sin^2 sigma given)
 * around the unit axis a: exact, horizon included (Snyder 1996). */
double sl_cap_cosine_integral(const double a[3], double sin2_sigma, const double n[3]);

/* True when the light's irradiance has a closed form (every light but a
 * textured rect, which stays sampled). */
bool sl_light_has_closed_form(const sl_light *l);

/* Unoccluded irradiance E (per channel) of light l at p with normal n and a
 * proven bound of |E - exact| (disks: between the inscribed and circumscribed
 * polygons, with enough sides for a relative gap of tol; 0 otherwise but
 * rounding). False where none is defined (p inside a sphere light). */
bool sl_light_irradiance(const sl_light *l, const double p[3], const double n[3], double tol,
                         double E[3], double bound[3]);

/* The sum of the closed-form lights' unoccluded irradiance at p with normal
 * n and its bound; false where one has none (p inside a sphere light). */
bool sl_lights_irradiance(const sl_scene *scene, const double p[3], const double n[3], double tol,
                          double E[3], double bound[3]);

/* Radiance towards wo of a shape's material at world point p, normal n:
 * Lambert, rho/pi (E_dome(n) + sum of the closed-form lights' E(p, n));
 * a rough glossy lobe, the dome integrated against it (dome alone); bound as
 * sl_closed_form_radiance. False where there is no closed form there. */
bool sl_closed_form_radiance_at(const sl_closed_form *cf, const sl_scene *scene, int shape,
                                const double p[3], const double n[3], const double wo[3],
                                double out[3], double bound[3], sl_irradiance_cost *cost);

/* Why the closed form cannot take the scene's lights (a sphere light
 * touching an object, nothing to compute), or NULL. */
const char *sl_closed_form_lights_unfit(const sl_scene *scene);

/* Can a rig's light block another source (the dome, another light) at the
 * points, or must a light without a closed form be sampled there? Then the
 * pixel is a control variate, not exact. margin widens the test between a
 * sphere's corner normals (closed_form.c). */
bool sl_lights_may_shadow(const sl_scene *scene, const sl_hit *pts, int npts, double margin);

/* Lights with and without a closed form (stats). */
void sl_closed_form_count_lights(const sl_scene *scene, int *exact, int *sampled);

#endif
