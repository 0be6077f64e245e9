/* SPDX-License-Identifier: BSD-3-Clause */
/* Which pixels are exact, control variates or sampled, and their closed-form
 * values (closed_form.c). Private to render/. */
#ifndef SETLIGHT_RENDER_CLOSED_FORM_H
#define SETLIGHT_RENDER_CLOSED_FORM_H

#include <stdint.h>
#include "irradiance.h"
#include "setlight/render.h"

typedef struct sl_closed_form sl_closed_form;
/* SL_PIXEL_SUN: a glossy pixel the --time plan cut, its sun exact (value,
 * bound) and the rest of the map sampled from rest_dome. */
enum { SL_PIXEL_SAMPLED = 0, SL_PIXEL_EXACT, SL_PIXEL_CONTROL, SL_PIXEL_SUN };
struct sl_closed_form {
    sl_irradiance *ir;
    double tol;
    uint8_t *mode;     /* per pixel: SL_PIXEL_* */
    int32_t *shape;    /* the object an exact or control pixel shows */
    float (*value)[3]; /* its closed-form value, pixel filter applied */
    float (*bound)[3]; /* proven quadrature bound + pixel-filter estimate */
    struct sl_glossy_material *gmat; /* per scene material: the glossy tables */
    struct sl_glossy_dome *gdome;    /* the dome's sun and rest, for glossy pixel centres */
    int gmat_count;
    sl_dome rest_dome; /* the map without its sun, with its sampling tables
                          (present when some pixel is SL_PIXEL_SUN) */
};

/* Decides per pixel what is exact, what is a control variate and what is
 * sampled, and computes the closed-form values. Not applicable is not an
 * error: every pixel is then sampled and stats->reason says why. */
sl_result sl_closed_form_plan(sl_closed_form *cf, const sl_scene *scene, const sl_render_options *o,
                              sl_closed_form_stats *stats, sl_error *err);
void sl_closed_form_free(sl_closed_form *cf);
/* Lambert radiance rho/pi E(n) of a shape's material at world normal n. */
void sl_closed_form_radiance(const sl_closed_form *cf, const sl_scene *scene, int shape,
                             const double n[3], double out[3], double bound[3],
                             sl_irradiance_cost *cost);

#endif
