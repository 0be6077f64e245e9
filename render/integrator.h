/* SPDX-License-Identifier: BSD-3-Clause */
/* The path integrator's state and one camera sample (integrator.c).
 * Private to render/. */
#ifndef SETLIGHT_RENDER_INTEGRATOR_H
#define SETLIGHT_RENDER_INTEGRATOR_H

#include <stdbool.h>
#include <stdint.h>
#include "sampler.h"
#include "setlight/render.h"

typedef struct sl_closed_form sl_closed_form; /* closed_form.h */
typedef struct sl_counters {
    int64_t camera_rays, shadow_rays, bsdf_rays, shadow_skipped, zero_weight, nonfinite;
    int64_t culled, behind;
} sl_counters;

typedef struct sl_integrator {
    const sl_scene *scene;
    const sl_render_options *o;
    bool can_occlude; /* more than one shape: a shadow ray could hit something
                         (a lone sphere can also shadow its own inside) */
    bool light_sampling; /* strategy samples lights and the dome */
    bool dome_sampling;
    int area_lights; /* rect, disk and sphere lights: they block the shadow rays of
                        other lights and of the dome */
    const sl_closed_form *cf; /* NULL: every pixel sampled */
} sl_integrator;

void sl_integrator_init(sl_integrator *it, const sl_scene *scene, const sl_render_options *o);
/* One camera sample: rgb radiance and alpha (coverage). */
void sl_integrate_sample(const sl_integrator *it, sl_sampler *s, int px, int py, double rgba[4],
                         sl_counters *c);

#endif
