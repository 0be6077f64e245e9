/* SPDX-License-Identifier: BSD-3-Clause */
/* Leaves out the sampling a pixel does not need. A Lambert object under the
 * dome alone has the closed-form radiance rho/pi E(n) (irradiance.c); a
 * pixel gets it when the object is the first hit at the pixel's centre and
 * four corners (the silhouette of a sphere, rect or disk is convex under an
 * orthographic or perspective camera, so it covers the pixel) and every other object lies behind the tangent
 * plane of every point it shows, so no direction of its hemisphere can be
 * shadowed and no light can bounce onto it. A covered pixel that other
 * objects may shadow keeps the closed form as a control variate: the
 * integrator samples only the shadowed difference. Any other pixel is
 * sampled as before.
 *
 * Pixel filter: the sampled renderer averages over a box (or takes the
 * centre with pixel_centers). Here the box mean is the centre value plus
 * the 5-point Laplacian term (h^2/24), exact to O(h^4), where the four
 * neighbours show the same object; else a 3x3 grid of sub-pixel midpoints.
 * The size of that correction (or the centre - 3x3 difference / 8) is the
 * footprint error estimate added to the quadrature's proven bound. */
#include <stdlib.h>
#include <string.h>

#include "area_closed_form.h"
#include "closed_form.h"
#include "glossy.h"
#include "irradiance.h"
#include "normal_fill.h"
#include "scene_internal.h"
#include "shadow_fill.h"
#include "vec3.h"

#define DEFAULT_TOLERANCE 1e-2

void sl_closed_form_free(sl_closed_form *cf)
{
    for (int i = 0; cf->gmat && i < cf->gmat_count; i++)
        sl_glossy_material_free(&cf->gmat[i]);
    free(cf->gmat);
    if (cf->gdome)
        sl_glossy_dome_free(cf->gdome);
    free(cf->gdome);
    sl_dome_free(&cf->rest_dome);
    sl_irradiance_free(cf->ir);
    free(cf->mode);
    free(cf->shape);
    free(cf->value);
    free(cf->bound);
    memset(cf, 0, sizeof *cf);
}

void sl_closed_form_radiance(const sl_closed_form *cf, const sl_scene *scene, int shape,
                             const double n[3], double out[3], double bound[3],
                             sl_irradiance_cost *cost)
{
    const sl_material *m = &scene->materials[scene->shapes[shape].material];
    double E[3], B[3];
    sl_irradiance_eval(cf->ir, n, cf->tol, E, B, cost);
    for (int c = 0; c < 3; c++) {
        out[c] = m->base_color[c] / SL_PI * E[c];
        bound[c] = m->base_color[c] / SL_PI * B[c];
    }
}

void sl_closed_form_radiance_view(const sl_closed_form *cf, const sl_scene *scene, int shape,
                                  const double n[3], const double wo[3], double out[3],
                                  double bound[3], sl_irradiance_cost *cost)
{
    const sl_material *m = &scene->materials[scene->shapes[shape].material];
    if (m->type == SL_MAT_LAMBERT) {
        sl_closed_form_radiance(cf, scene, shape, n, out, bound, cost);
        return;
    }
    sl_glossy_scratch *s = sl_glossy_scratch_new();
    if (!s) { /* no room to integrate: the bound says so */
        out[0] = out[1] = out[2] = 0;
        bound[0] = bound[1] = bound[2] = INFINITY;
        return;
    }
    sl_glossy_quad q = {.tol = cf->tol};
    sl_glossy_integrate(cf->ir, &cf->gmat[scene->shapes[shape].material], n, wo, &q, s, out, bound,
                        cost);
    sl_glossy_scratch_free(s);
}

static bool has_closed_form(const sl_material *m)
{
    return m->type == SL_MAT_LAMBERT || sl_glossy_applies(m);
}

/* Largest distance of shape b's points from a point, and the farthest
 * reach of b along n from p: max over q in b of n.(q - p). */
static double reach_along(const sl_shape *b, const double p[3], const double n[3])
{
    double d[3] = {b->center[0] - p[0], b->center[1] - p[1], b->center[2] - p[2]};
    double base = v3_dot(n, d);
    switch (b->type) {
    case SL_SHAPE_SPHERE:
        return base + b->radius;
    case SL_SHAPE_RECT:
        return base + fabs(v3_dot(n, b->u)) + fabs(v3_dot(n, b->v));
    case SL_SHAPE_DISK: {
        double c = v3_dot(n, b->normal);
        return base + b->radius * sqrt(fmax(0.0, 1.0 - c * c));
    }
    }
    return INFINITY;
}

static double extent(const sl_shape *b)
{
    return b->type == SL_SHAPE_RECT ? v3_length(b->u) + v3_length(b->v) : b->radius;
}

typedef struct plan_job {
    const sl_scene *scene;
    const sl_render_options *o;
    sl_closed_form *cf;
    double (*centre)[3]; /* centre value per pixel */
    sl_irradiance_cost *row_cost;
    double *row_foot; /* largest relative footprint estimate per row */
    sl_glossy_pixels glossy; /* pixels left to sl_glossy_fill: glossy at centres */
    double deadline;  /* --time: rows not planned by then are sampled */
    uint8_t *row_cut; /* the row ran into the deadline */
    int32_t *row_late; /* rim pixels of a finished row the deadline left to sampling */
    uint8_t *drop;     /* filter_rows: pixels it leaves to sampling, applied after it, so
                          that no pixel's neighbours change while it runs */
    uint8_t *lambert;  /* the pixel's dome part is left to the Lambert fill */
    int64_t *point;    /* its point in the fill, and its first sub-point (box filter), or -1 */
    int64_t *sub;
    sl_lambert_points pts;
    double (*pt_n)[3];
} plan_job;

static void plan_job_free(plan_job *j)
{
    free(j->centre);
    free(j->row_cost);
    free(j->row_foot);
    free(j->row_cut);
    free(j->row_late);
    free(j->drop);
    free(j->lambert);
    free(j->point);
    free(j->sub);
    free(j->pt_n);
    free(j->pts.E);
    free(j->pts.bound);
    free(j->pts.interpolated);
    free(j->pts.at_tol);
    free(j->glossy.state);
    free(j->glossy.n);
    free(j->glossy.wo);
    free(j->glossy.coarse);
}

/* The plan's share of a --time budget: the first pass (one sample per half
 * of every pixel left to sampling) always follows it. */
#define PLAN_TIME_SHARE 0.8
#define CONTROL_TIME_SHARE 0.4
/* Where control variates' shadowed part is computed (fill_shadows), the
 * Lambert fill stops here and the shadows' finer tolerance at the plan's
 * share; they always finish, coarser past it. */
#define SHADOW_FILL_START 0.6

/* Every closed-form pixel glossy at its centre, with no rig light: those
 * integrate the map's sun and rest (glossy_fill.c), not the whole map, so
 * the whole map's levels are built only if a pixel needs them. */
static bool glossy_at_centres_only(const sl_scene *scene, const sl_render_options *o)
{
    if (!o->pixel_centers || scene->light_count)
        return false;
    for (int i = 0; i < scene->shape_count; i++)
        if (scene->materials[scene->shapes[i].material].type == SL_MAT_LAMBERT)
            return false;
    return true;
}

static bool ray_at(const sl_camera *cam, double sx, double sy, double o[3], double d[3])
{
    return sl_camera_ray(cam, sx / cam->width, sy / cam->height, o, d);
}

/* Is every other shape behind the tangent plane at each of the points? One
 * in the plane (the chart's patches) hides no direction above it. */
static bool unshadowed(const sl_scene *scene, int a, const sl_hit *pts, int npts, double margin)
{
    for (int b = 0; b < scene->shape_count; b++) {
        if (b == a)
            continue;
        for (int i = 0; i < npts; i++) {
            double scale = 1e-9 * (1.0 + fabs(pts[i].p[0]) + fabs(pts[i].p[1]) + fabs(pts[i].p[2]));
            if (!(reach_along(&scene->shapes[b], pts[i].p, pts[i].n) <= scale - margin))
                return false;
        }
    }
    return true;
}

static void classify_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    plan_job *j = ctx;
    const sl_scene *scene = j->scene;
    const sl_camera *cam = &scene->camera;
    sl_closed_form *cf = j->cf;
    /* The pixel corners of a row's top and bottom edges, each traced once
     * for the two pixels that share it. */
    int w = cam->width;
    sl_hit *corner = j->o->pixel_centers ? NULL : malloc(2 * ((size_t)w + 1) * sizeof *corner);
    uint8_t *corner_ok = j->o->pixel_centers ? NULL : malloc(2 * ((size_t)w + 1));
    for (int64_t y = begin; y < end; y++) {
        /* Past the deadline only the Lambert fill's pixels go on: their
         * first pass is cheap, a glossy or box-filtered quadrature is not. */
        bool late = sl_seconds() > j->deadline;
        for (int k = 0; corner && corner_ok && k < 2 * (w + 1); k++) {
            double org[3], dir[3];
            corner_ok[k] = ray_at(cam, k % (w + 1), (double)y + k / (w + 1), org, dir) &&
                           sl_scene_intersect(scene, org, dir, 0.0, INFINITY, &corner[k]);
        }
        for (int x = 0; x < cam->width; x++) {
            size_t pix = (size_t)y * (size_t)cam->width + (size_t)x;
            double org[3], dir[3];
            sl_hit h[5];
            if (!ray_at(cam, x + 0.5, y + 0.5, org, dir) ||
                !sl_scene_intersect(scene, org, dir, 0.0, INFINITY, &h[0]) || h[0].inside)
                continue;
            double dir0[3];
            v3_copy(dir0, dir);
            int a = h[0].shape;
            if (!has_closed_form(&scene->materials[scene->shapes[a].material]))
                continue;
            int npts = 1;
            bool covered = true;
            if (!j->o->pixel_centers)
                for (int c = 0; c < 4 && covered; c++) {
                    /* no memory for the corners: not known to be covered */
                    int k = (c >> 1) * (w + 1) + x + (c & 1);
                    covered = corner && corner_ok && corner_ok[k] && corner[k].shape == a && !corner[k].inside;
                    if (covered)
                        h[npts] = corner[k];
                    npts++;
                }
            if (!covered)
                continue;
            /* Normals turn across a sphere's patch: points between the
             * corners reach a little farther than the corners do. */
            double margin = 0;
            const sl_shape *sa = &scene->shapes[a];
            if (sa->type == SL_SHAPE_SPHERE && npts > 1) {
                double cmin = 1;
                for (int i = 1; i < npts; i++)
                    cmin = fmin(cmin, v3_dot(h[0].n, h[i].n));
                double far = 0;
                for (int b = 0; b < scene->shape_count; b++)
                    if (b != a) {
                        double d[3] = {scene->shapes[b].center[0] - sa->center[0],
                                       scene->shapes[b].center[1] - sa->center[1],
                                       scene->shapes[b].center[2] - sa->center[2]};
                        far = fmax(far, v3_length(d) + extent(&scene->shapes[b]) + sa->radius);
                    }
                margin = cmin > 0.5 ? 2.0 * far * (1.0 / cmin - 1.0) : INFINITY;
            }
            const sl_material *ma = &scene->materials[sa->material];
            /* The glossy quadrature integrates the dome alone: with a rig's
             * lights a glossy pixel is sampled. */
            if (ma->type != SL_MAT_LAMBERT && scene->light_count)
                continue;
            double B[3], wo[3] = {-dir0[0], -dir0[1], -dir0[2]};
            bool to_fill = ma->type == SL_MAT_LAMBERT && cf->ir;
            if (late && !to_fill) {
                j->row_late[y]++; /* left to sampling */
                continue;
            }
            if (j->o->pixel_centers && sl_glossy_applies(ma)) {
                cf->mode[pix] = unshadowed(scene, a, h, npts, margin) ? SL_PIXEL_EXACT : SL_PIXEL_CONTROL;
                cf->shape[pix] = a;
                j->glossy.state[pix] = SL_GLOSSY_PENDING;
                v3_copy(j->glossy.n[pix], h[0].n);
                v3_copy(j->glossy.wo[pix], wo);
                continue;
            }
            /* A Lambert pixel's dome part is left to the fill (interpolated
             * where checked); its lights' part is computed here. */
            if (!(to_fill ? sl_lights_irradiance(scene, h[0].p, h[0].n, cf->tol, j->centre[pix], B)
                          : sl_closed_form_radiance_at(cf, scene, a, h[0].p, h[0].n, wo, j->centre[pix],
                                                       B, &j->row_cost[y])))
                continue;
            cf->mode[pix] = unshadowed(scene, a, h, npts, margin) &&
                                    !sl_lights_may_shadow(scene, h, npts, margin)
                                ? SL_PIXEL_EXACT
                                : SL_PIXEL_CONTROL;
            cf->shape[pix] = a;
            for (int c = 0; c < 3; c++)
                cf->bound[pix][c] = (float)B[c];
            if (to_fill) {
                j->lambert[pix] = 1;
                v3_copy(j->glossy.n[pix], h[0].n);
            }
        }
    }
    free(corner);
    free(corner_ok);
}

/* The box mean over a pixel from an n x n grid of sub-pixel midpoints on shape a. */
static bool grid_mean(const plan_job *j, int a, int x, int y, int n, double mean[3], double bound[3],
                      sl_irradiance_cost *cost)
{
    const sl_camera *cam = &j->scene->camera;
    mean[0] = mean[1] = mean[2] = 0;
    for (int sy = 0; sy < n; sy++)
        for (int sx = 0; sx < n; sx++) {
            double org[3], dir[3], v[3], b[3];
            sl_hit h;
            if (!ray_at(cam, x + (sx + 0.5) / n, y + (sy + 0.5) / n, org, dir) ||
                !sl_shape_intersect(j->scene, a, org, dir, &h))
                return false;
            double wo[3] = {-dir[0], -dir[1], -dir[2]};
            if (!sl_closed_form_radiance_at(j->cf, j->scene, a, h.p, h.n, wo, v, b, cost))
                return false;
            for (int c = 0; c < 3; c++) {
                mean[c] += v[c] / (n * n);
                bound[c] = fmax(bound[c], b[c]);
            }
        }
    return true;
}

/* The box mean of a pixel from its centre and its four neighbours' (they
 * show the same object), or, on a flat Lambert shape under the dome alone,
 * its centre value; else it needs a 3 x 3 grid of sub-pixel points. */
static bool inner_pixel(const plan_job *j, int x, int y)
{
    const sl_closed_form *cf = j->cf;
    int w = j->scene->camera.width, hgt = j->scene->camera.height;
    size_t pix = (size_t)y * (size_t)w + (size_t)x;
    int a = cf->shape[pix];
    /* A cut row's centres were never finished: no neighbour there. */
    bool inner = x > 0 && y > 0 && x + 1 < w && y + 1 < hgt && !j->row_cut[y - 1] && !j->row_cut[y + 1];
    const size_t nb[4] = {pix - 1, pix + 1, pix - (size_t)w, pix + (size_t)w};
    for (int k = 0; k < 4 && inner; k++)
        inner = cf->mode[nb[k]] != SL_PIXEL_SAMPLED && cf->shape[nb[k]] == a;
    return inner;
}

static bool flat_under_dome(const plan_job *j, int a)
{
    const sl_scene *scene = j->scene;
    return scene->shapes[a].type != SL_SHAPE_SPHERE && !scene->light_count &&
           scene->materials[scene->shapes[a].material].type == SL_MAT_LAMBERT;
}

/* The sub-pixel points of a 3 x 3 grid on shape a, for the Lambert fill:
 * normals and the rig lights' irradiance. False when a point misses the
 * shape (rounding at a corner). */
#define GRID 3
static bool grid_points(const plan_job *j, int a, int x, int y, double (*n)[3], double (*E)[3],
                        double (*B)[3])
{
    const sl_camera *cam = &j->scene->camera;
    for (int k = 0; k < GRID * GRID; k++) {
        double org[3], dir[3];
        sl_hit h;
        if (!ray_at(cam, x + (k % GRID + 0.5) / GRID, y + (k / GRID + 0.5) / GRID, org, dir) ||
            !sl_shape_intersect(j->scene, a, org, dir, &h) ||
            !sl_lights_irradiance(j->scene, h.p, h.n, j->cf->tol, E[k], B[k]))
            return false;
        v3_copy(n[k], h.n);
    }
    return true;
}

static void filter_rows(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    plan_job *j = ctx;
    const sl_camera *cam = &j->scene->camera;
    sl_closed_form *cf = j->cf;
    int w = cam->width;
    for (int64_t y = begin; y < end; y++) {
        if (j->row_cut[y])
            continue; /* sampled: set after every row is done */
        bool late = sl_seconds() > j->deadline; /* then rim pixels are sampled */
        for (int x = 0; x < w; x++) {
            size_t pix = (size_t)y * (size_t)w + (size_t)x;
            if (cf->mode[pix] == SL_PIXEL_SAMPLED)
                continue;
            const double *fc = j->centre[pix];
            if (j->o->pixel_centers) {
                for (int c = 0; c < 3; c++)
                    cf->value[pix][c] = (float)fc[c];
                continue;
            }
            int a = cf->shape[pix];
            bool inner = inner_pixel(j, x, (int)y);
            const size_t nb[4] = {pix - 1, pix + 1, pix - (size_t)w, pix + (size_t)w};
            double mean[3], foot[3], bound[3] = {cf->bound[pix][0], cf->bound[pix][1], cf->bound[pix][2]};
            if (inner) {
                for (int c = 0; c < 3; c++) {
                    double lap = j->centre[nb[0]][c] + j->centre[nb[1]][c] + j->centre[nb[2]][c] +
                                 j->centre[nb[3]][c] - 4.0 * fc[c];
                    mean[c] = fc[c] + lap / 24.0;
                    foot[c] = fabs(lap / 24.0);
                }
            } else if (flat_under_dome(j, a)) {
                /* A flat Lambert shape under the dome alone has one normal,
                 * so one irradiance: its box mean is its centre value (the
                 * chart's patch edges). */
                for (int c = 0; c < 3; c++)
                    mean[c] = fc[c], foot[c] = 0;
            } else if (j->sub[pix] >= 0) {
                /* The fill's 3 x 3 points. */
                const double *rho = j->scene->materials[j->scene->shapes[a].material].base_color;
                for (int c = 0; c < 3; c++) {
                    mean[c] = 0;
                    for (int k = 0; k < GRID * GRID; k++) {
                        int64_t q = j->sub[pix] + k;
                        mean[c] += rho[c] / SL_PI * j->pts.E[q][c] / (GRID * GRID);
                        bound[c] = fmax(bound[c], rho[c] / SL_PI * j->pts.bound[q][c]);
                    }
                    foot[c] = fabs(mean[c] - fc[c]) / 8.0;
                }
            } else {
                /* Midpoint rules err as h^2: the 3x3 grid's error is about
                 * (centre - 3x3) / 8. */
                if (late || !grid_mean(j, a, x, (int)y, 3, mean, bound, &j->row_cost[y])) {
                    j->drop[pix] = 1; /* rounding at a corner, or --time */
                    j->row_late[y] += late;
                    continue;
                }
                for (int c = 0; c < 3; c++)
                    foot[c] = fabs(mean[c] - fc[c]) / 8.0;
            }
            for (int c = 0; c < 3; c++) {
                cf->value[pix][c] = (float)fmax(0.0, mean[c]);
                cf->bound[pix][c] = (float)(bound[c] + foot[c]);
                if (mean[c] > 0)
                    j->row_foot[y] = fmax(j->row_foot[y], foot[c] / mean[c]);
            }
        }
    }
}

/* The Lambert pixels' dome part (normal_fill.c): the points are their
 * centres and, where the box filter needs them, 3 x 3 sub-pixel points;
 * every one gets a value whenever the deadline falls. Writes each centre's
 * radiance, bound and interpolation state. */
static sl_result fill_lambert(plan_job *j, double deadline, sl_closed_form_stats *st, sl_error *err)
{
    const sl_scene *scene = j->scene;
    const sl_camera *cam = &scene->camera;
    sl_closed_form *cf = j->cf;
    size_t npix = (size_t)cam->width * (size_t)cam->height;
    int64_t count = 0;
    for (int y = 0; y < cam->height; y++)
        for (int x = 0; x < cam->width; x++) {
            size_t pix = (size_t)y * (size_t)cam->width + (size_t)x;
            j->point[pix] = j->sub[pix] = -1;
            if (!j->lambert[pix])
                continue;
            j->point[pix] = count++;
            if (!j->o->pixel_centers && !inner_pixel(j, x, y) && !flat_under_dome(j, cf->shape[pix]))
                j->sub[pix] = (count += GRID * GRID) - GRID * GRID;
        }
    size_t np = (size_t)(count > 0 ? count : 1);
    j->pt_n = malloc(np * sizeof *j->pt_n);
    j->pts.E = malloc(np * sizeof *j->pts.E);
    j->pts.bound = malloc(np * sizeof *j->pts.bound);
    j->pts.interpolated = calloc(np, 1);
    j->pts.at_tol = calloc(np, 1);
    if (!j->pt_n || !j->pts.E || !j->pts.bound || !j->pts.interpolated || !j->pts.at_tol)
        return sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the Lambert points");
    j->pts.count = count;
    j->pts.n = (const double(*)[3])j->pt_n;
    for (size_t pix = 0; pix < npix; pix++) {
        int64_t q = j->point[pix];
        if (q < 0)
            continue;
        v3_copy(j->pt_n[q], j->glossy.n[pix]);
        for (int c = 0; c < 3; c++)
            j->pts.E[q][c] = j->centre[pix][c], j->pts.bound[q][c] = cf->bound[pix][c];
        if (j->sub[pix] >= 0 &&
            !grid_points(j, cf->shape[pix], (int)(pix % (size_t)cam->width), (int)(pix / (size_t)cam->width),
                         j->pt_n + j->sub[pix], j->pts.E + j->sub[pix], j->pts.bound + j->sub[pix])) {
            /* Rounding at a corner: sampled, its sub-points given a harmless normal. */
            j->drop[pix] = 1;
            for (int k = 0; k < GRID * GRID; k++) {
                v3_copy(j->pt_n[j->sub[pix] + k], j->glossy.n[pix]);
                memset(j->pts.E[j->sub[pix] + k], 0, sizeof j->pts.E[0]);
                memset(j->pts.bound[j->sub[pix] + k], 0, sizeof j->pts.bound[0]);
            }
            j->sub[pix] = -1;
        }
    }
    sl_lambert_fill_stats fs;
    sl_result res = sl_lambert_fill(cf->gdome, cf->tol, &j->pts, deadline, j->o->plan_eval_limit, &fs, err);
    if (res)
        return res;
    st->evaluations += fs.cost.evaluations;
    st->cells += fs.cost.cells;
    if (fs.cost.evaluations && fs.cost.finest_level < st->finest_level)
        st->finest_level = fs.cost.finest_level;
    st->cut_by_time |= fs.cut;
    for (size_t pix = 0; pix < npix; pix++) {
        int64_t q = j->point[pix];
        if (q < 0)
            continue;
        const double *rho = scene->materials[scene->shapes[cf->shape[pix]].material].base_color;
        for (int c = 0; c < 3; c++) {
            j->centre[pix][c] = rho[c] / SL_PI * j->pts.E[q][c];
            cf->bound[pix][c] = (float)(rho[c] / SL_PI * j->pts.bound[q][c]);
        }
        j->glossy.state[pix] = j->pts.interpolated[q] ? SL_GLOSSY_INTERPOLATED : SL_GLOSSY_DONE;
        bool at_tol = j->pts.at_tol[q];
        for (int k = 0; k < GRID * GRID && j->sub[pix] >= 0; k++)
            at_tol &= j->pts.at_tol[j->sub[pix] + k];
        j->lambert[pix] = at_tol ? 1 : 2; /* 2: a cut left it short of the tolerance */
    }
    return SL_OK;
}

/* With no bounces and no rig light, a Lambert control variate's shadowed
 * part is computed (shadow_fill.c) instead of sampled, after the pixel
 * filter gave its unoccluded value (with the box filter S is a box mean
 * too): the pixel becomes exact. Pixels whose blockers are not handled
 * stay control variates. */
static sl_result fill_shadows(plan_job *j, double deadline, sl_closed_form_stats *st, sl_error *err)
{
    const sl_scene *scene = j->scene;
    sl_closed_form *cf = j->cf;
    int w = scene->camera.width, h = scene->camera.height;
    size_t npix = (size_t)w * h;
    sl_shadow_pixels px = {.w = w, .h = h, .shape = cf->shape, .box = !j->o->pixel_centers};
    px.state = calloc(npix, 1);
    double(*floor)[3] = malloc(npix * sizeof *floor);
    px.S = malloc(npix * sizeof *px.S);
    px.bound = malloc(npix * sizeof *px.bound);
    px.floor = (const double(*)[3])floor;
    sl_result res = SL_OK;
    if (!px.state || !floor || !px.S || !px.bound) {
        res = sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the shadowed pixels");
        goto done;
    }
    for (size_t pix = 0; pix < npix; pix++) {
        if (!j->lambert[pix] || cf->mode[pix] != SL_PIXEL_CONTROL || j->point[pix] < 0)
            continue;
        px.state[pix] = SL_SHADOW_PENDING;
        memcpy(floor[pix], j->pts.E[j->point[pix]], sizeof floor[pix]);
    }
    sl_irradiance_cost cost = {.finest_level = sl_irradiance_top_level(cf->ir)};
    if ((res = sl_shadow_fill(scene, cf->ir, cf->tol, &px, deadline, &cost, err)))
        goto done;
    st->shadow_evaluations += cost.evaluations;
    st->shadow_cells += cost.cells;
    for (size_t pix = 0; pix < npix; pix++) {
        int s = px.state[pix];
        if (s != SL_SHADOW_DONE && s != SL_SHADOW_INTERPOLATED)
            continue;
        const double *rho = scene->materials[scene->shapes[cf->shape[pix]].material].base_color;
        for (int c = 0; c < 3; c++) {
            cf->value[pix][c] = (float)fmax(0.0, cf->value[pix][c] - rho[c] / SL_PI * px.S[pix][c]);
            cf->bound[pix][c] += (float)(rho[c] / SL_PI * px.bound[pix][c]);
        }
        cf->mode[pix] = SL_PIXEL_EXACT;
        st->shadow_exact_pixels++;
        if (s == SL_SHADOW_INTERPOLATED)
            j->glossy.state[pix] = SL_GLOSSY_INTERPOLATED;
    }
done:
    free(px.state);
    free(floor);
    free(px.S);
    free(px.bound);
    return res;
}

static const char *not_applicable(const sl_scene *scene, const sl_render_options *o)
{
    if (!o->closed_form)
        return "off";
    if (o->strategy != SL_STRATEGY_MIS)
        return "strategy is not mis";
    const char *lights = sl_closed_form_lights_unfit(scene);
    if (lights)
        return lights;
    if (scene->camera.type == SL_CAMERA_FISHEYE)
        return "fisheye camera (silhouettes not convex in the image)";
    for (int i = 0; i < scene->shape_count; i++)
        if (has_closed_form(&scene->materials[scene->shapes[i].material]))
            return NULL;
    return "no Lambert or rough glossy object";
}

sl_result sl_closed_form_plan(sl_closed_form *cf, const sl_scene *scene, const sl_render_options *o,
                              sl_closed_form_stats *st, sl_error *err)
{
    memset(cf, 0, sizeof *cf);
    memset(st, 0, sizeof *st);
    const sl_camera *cam = &scene->camera;
    size_t npix = (size_t)cam->width * (size_t)cam->height;
    st->sampled_pixels = (int64_t)npix;
    const char *why = not_applicable(scene, o);
    if (why) {
        snprintf(st->reason, sizeof st->reason, "%s", why);
        return SL_OK;
    }
    double t0 = sl_seconds();
    cf->tol = o->closed_form_tolerance > 0 ? o->closed_form_tolerance : DEFAULT_TOLERANCE;
    if (o->target_error > 0)
        cf->tol = fmin(cf->tol, 0.5 * o->target_error);
    sl_error local = {0};
    bool defer_whole = glossy_at_centres_only(scene, o);
    if (scene->dome.present && !defer_whole && sl_irradiance_build(&scene->dome, &cf->ir, &local)) {
        snprintf(st->reason, sizeof st->reason, "%.95s", local.message);
        return SL_OK;
    }
    cf->gmat_count = scene->material_count;
    cf->gmat = calloc((size_t)(scene->material_count > 0 ? scene->material_count : 1), sizeof *cf->gmat);
    if (!cf->gmat) {
        sl_closed_form_free(cf);
        return sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the closed form");
    }
    for (int i = 0; i < scene->material_count; i++) {
        sl_result r = sl_glossy_applies(&scene->materials[i])
                          ? sl_glossy_material_init(&cf->gmat[i], &scene->materials[i], err)
                          : SL_OK;
        if (r) {
            sl_closed_form_free(cf);
            return r;
        }
    }
    plan_job j = {.scene = scene, .o = o, .cf = cf};
    cf->mode = calloc(npix, 1);
    cf->shape = calloc(npix, sizeof *cf->shape);
    cf->value = calloc(npix, sizeof *cf->value);
    cf->bound = calloc(npix, sizeof *cf->bound);
    j.centre = calloc(npix, sizeof *j.centre);
    j.row_cost = calloc((size_t)cam->height, sizeof *j.row_cost);
    j.row_foot = calloc((size_t)cam->height, sizeof *j.row_foot);
    j.glossy.state = calloc(npix, 1);
    j.glossy.n = malloc(npix * sizeof *j.glossy.n);
    j.glossy.wo = malloc(npix * sizeof *j.glossy.wo);
    j.glossy.value = j.centre;
    j.glossy.coarse = calloc(npix, 1);
    j.row_cut = calloc((size_t)cam->height, 1);
    j.row_late = calloc((size_t)cam->height, sizeof *j.row_late);
    j.drop = calloc(npix, 1);
    j.lambert = calloc(npix, 1);
    j.point = malloc(npix * sizeof *j.point);
    j.sub = malloc(npix * sizeof *j.sub);
    j.deadline = o->time_limit > 0 ? t0 + PLAN_TIME_SHARE * o->time_limit : INFINITY;
    if (j.point && j.sub) /* no fill point (memset -1: every byte 0xff) */
        memset(j.point, 0xff, npix * sizeof *j.point), memset(j.sub, 0xff, npix * sizeof *j.sub);
    if (!cf->mode || !cf->shape || !cf->value || !cf->bound || !j.centre || !j.row_cost ||
        !j.row_foot || !j.row_cut || !j.row_late || !j.drop || !j.lambert || !j.point || !j.sub || !j.glossy.state || !j.glossy.n || !j.glossy.wo ||
        !j.glossy.coarse) {
        plan_job_free(&j);
        sl_closed_form_free(cf);
        return sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the closed form");
    }
    sl_parallel_for(cam->height, 1, classify_rows, &j);
    sl_result res = SL_OK;
    bool pending = false, lambert = false, control = false, shadows = false;
    for (size_t i = 0; i < npix; i++) {
        pending |= j.glossy.state[i] == SL_GLOSSY_PENDING;
        lambert |= j.lambert[i];
        control |= cf->mode[i] == SL_PIXEL_CONTROL;
    }
    if (pending || lambert) {
        cf->gdome = calloc(1, sizeof *cf->gdome);
        res = cf->gdome ? SL_OK : sl_error_set(err, SL_ERR_NOMEM, "render: out of memory for the dome split");
        /* Without room for the split the whole map is the rest: slower, as exact. */
        sl_error split_err = {0};
        if (!res && sl_glossy_dome_build(&scene->dome, cf->ir, cf->gdome, &split_err))
            cf->gdome->rest = cf->ir;
        if (!res) {
            st->sun_texels = cf->gdome->sun_texels;
            st->sun_share = cf->gdome->sun_share;
        }
    }
    /* The whole map's levels, deferred: needed by a control variate, or as
     * the rest when the map had no sun to split off (or no room for it). */
    bool need_whole = control || (cf->gdome && !cf->gdome->rest);
    if (!res && scene->dome.present && !cf->ir && need_whole) {
        if (sl_irradiance_build(&scene->dome, &cf->ir, &local)) {
            plan_job_free(&j);
            sl_closed_form_free(cf);
            memset(st, 0, sizeof *st);
            st->sampled_pixels = (int64_t)npix;
            snprintf(st->reason, sizeof st->reason, "%.95s", local.message);
            return SL_OK;
        }
        if (cf->gdome && !cf->gdome->rest)
            cf->gdome->rest = cf->ir;
    }
    const sl_irradiance *levels = cf->ir ? cf->ir : cf->gdome ? cf->gdome->rest : NULL;
    st->finest_level = st->top_level = levels ? sl_irradiance_top_level(levels) : 0;
    if (!res && lambert) {
        /* Control variates leave the shadowed part to sampling: it gets
         * the larger part of the budget; with no bounces and no rig light
         * it is computed after the pixel filter (fill_shadows). The glossy
         * fill, after, half of what is left. */
        shadows = control && o->bounces == 0 && !scene->light_count;
        double share = shadows ? SHADOW_FILL_START : control ? CONTROL_TIME_SHARE : PLAN_TIME_SHARE;
        double until = o->time_limit > 0 ? t0 + share * o->time_limit : INFINITY;
        if (pending)
            until = sl_seconds() + 0.5 * (until - sl_seconds());
        res = fill_lambert(&j, until, st, err);
    }
    if (!res && pending) {
        /* The coarse pass runs to the plan's share of the budget too: the
         * pixels it leaves are sampled in the rest (test_render_time). */
        sl_glossy_limits lim = {.deadline = j.deadline,
                                .row_limit = o->plan_row_limit,
                                .coarse_row_limit = o->plan_coarse_row_limit,
                                .coarse_block_limit = o->plan_coarse_block_limit};
        res = sl_glossy_fill(cf, scene, &j.glossy, cam->width, cam->height, j.row_cost, &lim, j.row_cut, err);
    }
    if (res) {
        plan_job_free(&j);
        sl_closed_form_free(cf);
        return res;
    }
    free(j.glossy.n);
    free(j.glossy.wo);
    j.glossy.n = j.glossy.wo = NULL;
    sl_parallel_for(cam->height, 1, filter_rows, &j);
    for (size_t i = 0; i < npix; i++)
        if (j.drop[i])
            cf->mode[i] = SL_PIXEL_SAMPLED;
    if (shadows && (res = fill_shadows(&j, j.deadline, st, err))) {
        plan_job_free(&j);
        sl_closed_form_free(cf);
        return res;
    }
    for (int y = 0; y < cam->height; y++) {
        st->cut_pixels += j.row_late[y];
        st->cut_by_time |= j.row_late[y] > 0;
    }
    bool sun_only = false;
    for (int y = 0; y < cam->height; y++)
        if (j.row_cut[y]) {
            /* Glossy pixels keep what the fill gave them in a cut row: all
             * (the full plan's or the coarse pass's rest) or their sun, the
             * rest sampled. */
            for (int x = 0; x < cam->width; x++) {
                size_t pix = (size_t)y * (size_t)cam->width + (size_t)x;
                int gs = j.glossy.state[pix];
                bool keep = cf->mode[pix] == SL_PIXEL_SUN ||
                            (cf->mode[pix] == SL_PIXEL_EXACT && (gs == SL_GLOSSY_DONE || gs == SL_GLOSSY_INTERPOLATED));
                if (keep)
                    for (int c = 0; c < 3; c++)
                        cf->value[pix][c] = (float)j.centre[pix][c];
                else if (cf->mode[pix] != SL_PIXEL_SAMPLED)
                    cf->mode[pix] = SL_PIXEL_SAMPLED, st->cut_pixels++;
                st->cut_pixels += cf->mode[pix] == SL_PIXEL_SUN;
                st->sun_exact_pixels += cf->mode[pix] == SL_PIXEL_SUN;
                sun_only |= cf->mode[pix] == SL_PIXEL_SUN;
            }
            st->cut_by_time = true;
        }
    if (sun_only && (res = sl_dome_init_like(&cf->rest_dome, &scene->dome, &cf->gdome->rest_dome.image, err))) {
        plan_job_free(&j);
        sl_closed_form_free(cf);
        return res;
    }
    st->used = true;
    st->tolerance = cf->tol;
    sl_closed_form_count_lights(scene, &st->lights_exact, &st->lights_sampled);
    for (int y = 0; y < cam->height; y++) {
        st->evaluations += j.row_cost[y].evaluations;
        st->cells += j.row_cost[y].cells;
        if (j.row_cost[y].evaluations && j.row_cost[y].finest_level < st->finest_level)
            st->finest_level = j.row_cost[y].finest_level;
    }
    st->sampled_pixels = 0;
    for (size_t i = 0; i < npix; i++) {
        int m = cf->mode[i];
        st->sampled_pixels += m == SL_PIXEL_SAMPLED || m == SL_PIXEL_SUN;
        st->exact_pixels += m == SL_PIXEL_EXACT;
        st->control_variate_pixels += m == SL_PIXEL_CONTROL;
        if (m == SL_PIXEL_SAMPLED || m == SL_PIXEL_SUN)
            continue;
        int k = 0;
        while (k < st->object_count && st->objects[k] != cf->shape[i])
            k++;
        if (k == st->object_count && k < SL_CLOSED_FORM_MAX_OBJECTS) {
            st->objects[st->object_count++] = cf->shape[i];
            st->object_material[k] = scene->materials[scene->shapes[cf->shape[i]].material].type;
        }
        bool interpolated = j.glossy.state[i] == SL_GLOSSY_INTERPOLATED;
        st->interpolated_pixels += interpolated;
        st->at_tolerance_pixels += j.lambert[i] != 2 && !j.glossy.coarse[i];
        st->coarse_pixels += j.glossy.coarse[i] != 0;
        st->provisional_pixels += j.glossy.coarse[i] == SL_GLOSSY_COARSE_PROVISIONAL;
        st->refined_pixels += j.glossy.coarse[i] == SL_GLOSSY_COARSE_REFINED;
        if (k < SL_CLOSED_FORM_MAX_OBJECTS) {
            st->object_exact[k] += m == SL_PIXEL_EXACT;
            st->object_control[k] += m == SL_PIXEL_CONTROL;
            st->object_interpolated[k] += interpolated;
        }
        double worst = 0;
        for (int c = 0; c < 3; c++)
            if (cf->value[i][c] > 0) {
                double rel = cf->bound[i][c] / cf->value[i][c];
                worst = fmax(worst, rel);
                st->max_rel_bound = fmax(st->max_rel_bound, rel);
                if (k < SL_CLOSED_FORM_MAX_OBJECTS)
                    st->object_max_rel_bound[k] = fmax(st->object_max_rel_bound[k], rel);
            }
        st->rms_rel_bound += worst * worst;
    }
    int64_t closed = st->exact_pixels + st->control_variate_pixels;
    st->rms_rel_bound = closed ? sqrt(st->rms_rel_bound / (double)closed) : 0;
    st->coarse_tolerance = st->coarse_pixels ? SL_GLOSSY_COARSE * cf->tol : 0;
    for (int y = 0; y < cam->height; y++)
        st->max_footprint_error = fmax(st->max_footprint_error, j.row_foot[y]);
    plan_job_free(&j);
    st->seconds = sl_seconds() - t0;
    return SL_OK;
}
