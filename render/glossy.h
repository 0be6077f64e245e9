/* SPDX-License-Identifier: BSD-3-Clause */
/* Closed form for glossy lobes under the dome (glossy.c) and the cells of
 * the irradiance mip levels it integrates over (irradiance.c). Private to
 * render/. */
#ifndef SETLIGHT_RENDER_GLOSSY_H
#define SETLIGHT_RENDER_GLOSSY_H

#include "closed_form.h"
#include "glossy_kernel.h"
#include "irradiance.h"
#include "scene_internal.h"
#include "vec3.h"

/* One lat-long cell of the piecewise-constant dome, in the map's frame:
 * a block of mip level `level` >= 0, or (level < 0) a piece of texel (x, y)
 * split -level times. */
typedef struct sl_dome_cell {
    double p[3];         /* per channel: integral of L dw (intensity not applied) */
    double v[3][3];      /* per channel: integral of L w dw */
    double centre[3];    /* direction of the cell's centre */
    double cos_r, sin_r; /* bounding cone radius about the centre */
    bool wide;           /* the cone reaches past 90 degrees */
    double spread_uniform; /* 1 - |V| / P were the cell's radiance uniform */
    double t0, t1, a, b; /* colatitude and longitude ranges */
    double corner[4][3]; /* directions of (t0, a), (t0, b), (t1, a), (t1, b) */
    int level, x, y;
} sl_dome_cell;

/* The map's rotation (map to world) and intensity. */
void sl_irradiance_frame(const sl_irradiance *ir, double rot[3][3], double *intensity);
void sl_irradiance_level_size(const sl_irradiance *ir, int k, int *w, int *h);
void sl_irradiance_cell(const sl_irradiance *ir, int k, int x, int y, sl_dome_cell *c);
void sl_irradiance_piece(const sl_irradiance *ir, int level, int x, int y, double t0, double t1,
                         double a, double b, sl_dome_cell *c);
/* The cells a cell splits into (a block's four, fewer at the map's edge;
 * a texel's or a piece's four quarters, its geometry t0, t1, a, b), in
 * row order; returns their count. */
int sl_irradiance_children(const sl_irradiance *ir, int level, int x, int y, double t0, double t1, double a,
                           double b, sl_dome_cell out[4]);
/* The irradiance quadrature's share of cell c at normal n (map frame),
 * max(0, n.w) integrated over it: -1 wholly below the horizon (all 0), 1
 * wholly above (exactly n.V), 0 cut by it; lower <= exact <= upper per
 * channel, est between them (intensity not applied). */
int sl_irradiance_cell_share(const double n[3], const sl_dome_cell *c, double lower[3], double est[3],
                             double upper[3]);

/* A material the glossy quadrature integrates: a rough (not delta)
 * conductor or plastic. */
bool sl_glossy_applies(const sl_material *m);

/* Radiance toward wo (world, unit, away from the surface) of material m at
 * world normal n under the dome alone: integral of L(w) f(wo, w) max(0, n.w)
 * dw, f the full sl_bsdf_eval (single and multiple scattering, the
 * plastic's diffuse), refined until the error estimate is below tol x the
 * value. err[c] estimates |out - exact| (not a proven bound). Builds the
 * material's tables each call: sl_glossy_integrate is the one to loop. */
void sl_glossy_eval(const sl_irradiance *ir, const sl_material *m, const double n[3],
                    const double wo[3], double tol, double out[3], double err[3],
                    sl_irradiance_cost *cost);

/* One evaluation's cells; one per thread. */
typedef struct sl_glossy_scratch sl_glossy_scratch;
sl_glossy_scratch *sl_glossy_scratch_new(void);
void sl_glossy_scratch_free(sl_glossy_scratch *s);
/* Integrand evaluations made with s so far (tests: a split reuses its
 * parent's points). */
int64_t sl_glossy_scratch_kernel_calls(const sl_glossy_scratch *s);

/* How far sl_glossy_integrate refines: irradiance.h's controls, the floor
 * in radiance. */
#define SL_GLOSSY_START_MAX SL_QUAD_START_MAX
typedef sl_quad sl_glossy_quad;
void sl_glossy_integrate(const sl_irradiance *ir, const sl_glossy_material *gm, const double n[3],
                         const double wo[3], const sl_glossy_quad *q, sl_glossy_scratch *scratch,
                         double out[3], double err[3], sl_irradiance_cost *cost);

/* Up to SL_GLOSSY_BATCH neighbouring pixels' integrals over one set of
 * cells: a cell is split while any of them asks for it, so each pixel's
 * value and error estimate are those of sl_glossy_integrate on a finer
 * partition, and the cells' geometry and refinement are paid once. One q
 * for all; out[i], err[i] per pixel. */
#define SL_GLOSSY_BATCH 4
void sl_glossy_integrate_batch(const sl_irradiance *ir, const sl_glossy_material *const *gm,
                               const double (*n)[3], const double (*wo)[3], int count,
                               const sl_glossy_quad *q, sl_glossy_scratch *scratch, double (*out)[3],
                               double (*err)[3], sl_irradiance_cost *cost);

/* The dome split for the glossy pixels (glossy_fill.c): the few brightest
 * texels (a sun) in one map, evaluated at every pixel, and the rest, whose
 * reflection is smooth across the image and is interpolated where checked.
 * With no texel that stands out, sun is NULL and rest is the whole map. */
typedef struct sl_glossy_dome {
    const sl_irradiance *rest;
    sl_irradiance *sun;
    sl_irradiance *own_rest; /* rest when it is not the whole map */
    sl_dome sun_dome, rest_dome;
    int *sun_cells;          /* the sun map's cells with light at sun_level */
    int sun_cell_count, sun_level;
    int64_t sun_texels;
    double sun_share;        /* the sun texels' share of the luminous power */
} sl_glossy_dome;
sl_result sl_glossy_dome_build(const sl_dome *dome, const sl_irradiance *whole, sl_glossy_dome *gd,
                               sl_error *err);
void sl_glossy_dome_free(sl_glossy_dome *gd);

/* Closed-form pixels left to the fill: glossy ones at pixel centres. The
 * rest of the map is evaluated on a lattice of 16 x 16 px blocks, refined
 * to 8 and 4 px blocks, and interpolated
 * bilinearly inside a block whose centre and edge midpoints, evaluated too,
 * agree with the interpolation (glossy_fill.c says how closely; the largest
 * difference is added to its pixels' error); the sun is evaluated at every
 * pixel, to a quarter of the tolerance of the pixel's whole value. */
enum { SL_GLOSSY_NONE = 0, SL_GLOSSY_PENDING, SL_GLOSSY_DONE, SL_GLOSSY_INTERPOLATED };
typedef struct sl_glossy_pixels {
    uint8_t *state;        /* per pixel: SL_GLOSSY_* */
    double (*n)[3];        /* world normal of a pending pixel */
    double (*wo)[3];       /* its view direction */
    double (*value)[3];    /* out: its radiance */
    uint8_t *coarse;       /* out: where it keeps the coarse pass's rest (a cut row):
                              SL_GLOSSY_COARSE_KEPT, ..._PROVISIONAL from a failed block,
                              ..._REFINED evaluated by the coarse pass's refinement */
} sl_glossy_pixels;
/* Under --time the rest is first evaluated at every pixel at this times
 * the tolerance (the coarse pass), for the rows the full plan does not
 * reach; its blocks interpolate where their check passes at
 * SL_GLOSSY_COARSE_CHECK times the tolerance. */
#define SL_GLOSSY_COARSE 8.0
enum { SL_GLOSSY_COARSE_KEPT = 1, SL_GLOSSY_COARSE_PROVISIONAL, SL_GLOSSY_COARSE_REFINED };
#define SL_GLOSSY_COARSE_CHECK 6.0
/* Where sl_glossy_fill is cut: the coarse pass's and the full plan's rows
 * not started by deadline (seconds, as sl_seconds); tests: the full
 * plan's from row_limit, the coarse pass's from coarse_row_limit on when
 * > 0, every row after the coarse pass's blocks of coarse_block_limit px
 * (16, 8 or 4) when > 0. */
typedef struct sl_glossy_limits {
    double deadline;
    int row_limit, coarse_row_limit, coarse_block_limit;
} sl_glossy_limits;
/* Fills value and cf->bound of every pending pixel (cf->shape set);
 * costs per image row. Every pixel's sun first; when the plan may be cut
 * (a finite deadline or a test's limit) the coarse pass, ended by its
 * refinement (the interpolated pixels with the largest estimates
 * evaluated); then the image
 * blocks' rest and row by row in image order each row in full (its
 * pixels' own evaluations and the sun). Rows the cut left are marked in
 * row_cut: their pixels keep the sun plus the best rest known (the full
 * plan's blocks', else the coarse pass's), or without one the sun alone
 * (cf->mode SL_PIXEL_SUN, the rest to be sampled); finished rows keep their
 * values. */
sl_result sl_glossy_fill(const sl_closed_form *cf, const sl_scene *scene, sl_glossy_pixels *px,
                         int w, int h, sl_irradiance_cost *row_cost, const sl_glossy_limits *lim,
                         uint8_t *row_cut, sl_error *err);

/* The blocks' check (glossy_fill.c): v, e the values and error estimates
 * at a block's corners (top left, top right, bottom left, bottom right),
 * edge midpoints (top, left, right, bottom) and centre. True when the
 * bilinear interpolation of the corners agrees at the other five within
 * tol x the point's scale (NULL: its value) past slack x the points'
 * largest error; err is, either way, the interpolated values' error
 * estimate (that largest error plus the largest difference). */
bool sl_fill_check(const double v[9][3], const double e[9][3], const double (*scale)[3], double tol, double slack,
                   double err[3]);
/* Bilinear interpolation of corners v (as above) at (fx, fy) in [0, 1]^2. */
void sl_fill_bilinear(const double v[4][3], double fx, double fy, double out[3]);

/* closed_form.c: the closed-form radiance of a shape toward the viewer wo,
 * Lambert (irradiance) or glossy. */
void sl_closed_form_radiance_view(const sl_closed_form *cf, const sl_scene *scene, int shape,
                                  const double n[3], const double wo[3], double out[3],
                                  double bound[3], sl_irradiance_cost *cost);

#endif
