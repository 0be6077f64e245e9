/* SPDX-License-Identifier: BSD-3-Clause */
/* The shadowed part of a Lambert control variate, computed instead of
 * sampled (shadow_fill.c). Private to render/. */
#ifndef SETLIGHT_RENDER_SHADOW_FILL_H
#define SETLIGHT_RENDER_SHADOW_FILL_H

#include "irradiance.h"
#include "scene_internal.h"

/* The directions other shapes block from a point, in the map's frame:
 * each a spherical cap (a sphere) or a convex spherical polygon (a rect's
 * corners seen from the point). */
#define SL_BLOCKERS_MAX 8
typedef struct sl_blocker {
    int edges;           /* 0: a cap; else the polygon's edge count */
    double axis[3];      /* cap: its axis */
    double cos_s, sin_s; /* cap: its angular radius */
    double edge[4][3];   /* polygon: unit normals of its edges' great circles, inward */
} sl_blocker;
typedef struct sl_blockers {
    int count;
    sl_blocker b[SL_BLOCKERS_MAX];
} sl_blockers;

/* What the shapes other than `shape` block above the tangent plane of
 * point p (world normal n), in the frame of ir. False when one of them is
 * neither a sphere nor a rect and reaches above that plane, p lies inside
 * a sphere, or there are more than SL_BLOCKERS_MAX of them. */
bool sl_blockers_at(const sl_scene *scene, const sl_irradiance *ir, int shape, const double p[3],
                    const double n[3], sl_blockers *out);

/* S = integral over the blocked directions of L(w) max(0, n.w) dw (world
 * normal n) for the piecewise-constant map of ir, and bound >= |S - exact|
 * per channel: cells of the map wholly inside a blocked set count like the
 * irradiance's (irradiance.c), cells wholly outside every one not at all,
 * and cells that straddle an edge are split (mip level by level, then
 * inside a texel) until the summed bound is within q->tol x (S + floor).
 * Only q->tol and q->floor are used. */
void sl_shadow_integrate(const sl_irradiance *ir, const sl_blockers *bl, const double n[3], const sl_quad *q,
                         double S[3], double bound[3], sl_irradiance_cost *cost);

/* Pixels whose shadowed part to compute, at their centres. */
enum { SL_SHADOW_NONE = 0, SL_SHADOW_PENDING, SL_SHADOW_DONE, SL_SHADOW_INTERPOLATED };
typedef struct sl_shadow_pixels {
    int w, h;
    uint8_t *state;           /* per pixel: SL_SHADOW_*; pending ones are filled */
    const int32_t *shape;     /* the shape a pixel shows */
    const double (*floor)[3]; /* its unoccluded irradiance (the tolerance's scale) */
    double (*S)[3];           /* out: its shadowed irradiance */
    double (*bound)[3];       /* out: its error (an estimate where interpolated) */
    bool box;                 /* the box filter: S is the pixel's mean */
} sl_shadow_pixels;

/* Fills S at every pending pixel: on a lattice of 16 x 16 px blocks, each
 * interpolated bilinearly where its centre and edge midpoints agree with
 * the interpolation (within a quarter of tol x the floor), else split down
 * to 4 x 4 px; pixels no block interpolates are evaluated one by one. Each
 * point's bound is within tol x the floor, or 4 tol x the floor once the
 * deadline (as sl_seconds) has passed: the fill always finishes. With
 * the box filter an interpolated pixel keeps its centre value (the box
 * mean of the bilinear interpolation); one that no checked block covers
 * takes its centre plus the 5-point Laplacian term where its 4 neighbours
 * have S on the same shape and the term is within a quarter of tol x the
 * floor (its size added to the bound; larger, at a shadow's edge, it is
 * no estimate of the box mean), else
 * the mean of a 3 x 3 grid of sub-pixel points (bound: their mean bound
 * plus |centre - mean| / 8, the midpoint rule's h^2 error). Pixels whose
 * blockers sl_blockers_at refuses stay pending. */
sl_result sl_shadow_fill(const sl_scene *scene, const sl_irradiance *ir, double tol, sl_shadow_pixels *px,
                         double deadline, sl_irradiance_cost *cost, sl_error *err);

#endif
