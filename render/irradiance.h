/* SPDX-License-Identifier: BSD-3-Clause */
/* Closed-form irradiance from the dome with a proven bound (irradiance.c).
 * Private to render/. */
#ifndef SETLIGHT_RENDER_IRRADIANCE_H
#define SETLIGHT_RENDER_IRRADIANCE_H

#include <stdint.h>
#include "setlight/render.h"

typedef struct sl_irradiance sl_irradiance;
typedef struct sl_irradiance_cost {
    int64_t evaluations, cells; /* normals evaluated, lat-long cells visited */
    int finest_level;           /* finest cell split to: mip level, < 0 inside a texel */
} sl_irradiance_cost;
/* Counts evaluations that visited `cells` cells, split down to level finest. */
void sl_irradiance_cost_add(sl_irradiance_cost *cost, int64_t evaluations, int64_t cells, int finest);
/* Mip levels of the dome's exact cell sums (intensity and rotation kept). */
sl_result sl_irradiance_build(const sl_dome *dome, sl_irradiance **out, sl_error *err);
/* The same for a dome whose radiance is zero but at texels[0..count-1]
 * (y * width + x, distinct): only their cells' ancestors are summed, with
 * the same bits as sl_irradiance_build's (the glossy split's sun map). */
sl_result sl_irradiance_build_sparse(const sl_dome *dome, const int64_t *texels, int64_t count,
                                     sl_irradiance **out, sl_error *err);
void sl_irradiance_free(sl_irradiance *ir);
int sl_irradiance_top_level(const sl_irradiance *ir);
/* E[c] = integral of L max(0, n.w) dw for the world normal n, and bound[c]
 * >= |E - exact| per channel, refined until bound <= tol x E (or no room). */
void sl_irradiance_eval(const sl_irradiance *ir, const double n[3], double tol, double E[3],
                        double bound[3], sl_irradiance_cost *cost);

/* How far a quadrature over the dome's cells refines (sl_irradiance_integrate,
 * and the glossy one, glossy.h): until its error is below tol x (its value
 * + floor) per channel (floor: radiance or irradiance known from elsewhere,
 * e.g. the rest of the map, or NULL); start_cells (NULL: every top-level
 * cell) lists the cells (y * width + x) of mip level start_level that hold
 * any light, where the refinement starts (at most SL_QUAD_START_MAX). */
#define SL_QUAD_START_MAX 128
typedef struct sl_quad {
    double tol;
    const double *floor;
    const int *start_cells;
    int start_count, start_level;
} sl_quad;
/* sl_irradiance_eval with those controls (floor in E's units). */
void sl_irradiance_integrate(const sl_irradiance *ir, const double n[3], const sl_quad *q,
                             double E[3], double bound[3], sl_irradiance_cost *cost);

#endif
