/* SPDX-License-Identifier: BSD-3-Clause */
/* The lens refined by the overlaps' radiance: the features fix the
 * geometry to a few hundredths of a pixel, and the vignetting fitted after
 * it absorbs what is left (a focal 0.04% long moves every ray's pixel and
 * every pixel's falloff); on smooth radiance the two views of an overlap
 * agree only where both are right. So the focal, the radial terms, the
 * vignetting, the free views' rotations and the gains are refined together
 * by Gauss-Newton on the log radiance difference of the solved pairs'
 * overlaps and the inlier matches' reprojection residuals, each weighed by
 * its own scatter at the features' solution, from which it starts: where
 * the radiance is noisy the features hold the lens (docs/stitch.md,
 * "Solve", step 8). */
#include "merge_private.h"
#include "stitch_private.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

enum {
    DIRECTIONS = 40000,
    ITERATIONS = 8,
    LENS_PARAMS = 5, /* ln focal, k1, k2, v1, v2 */
    MAX_PARAMS = LENS_PARAMS + 4 * SL_STITCH_MAX_VIEWS,
    MIN_SAMPLES = 500
};
/* Only smooth radiance takes part: a 2 x 2 cell spanning more than 2% is
 * texture, whose bilinear values misplace it by more than the geometry's
 * hundredths of a pixel (with 0.2, as the pose uses, the refinement moved
 * the stage's focal 0.17% the wrong way). */
#define SMOOTH_LOG 0.02
#define HUBER_LOG 0.02
#define INNER_CIRCLE 0.95
/* A refinement beyond these is not the hundredths of a pixel the features
 * leave: it is not kept. */
#define MAX_FOCAL_CHANGE 0.005
#define MAX_K_CHANGE 0.01

typedef struct lens_problem {
    int count;
    double (*rot)[3][3];
    const sl_lens *start;
    solve_log_image *img;
    int (*views)[2]; /* per sample: the pair's views */
    double (*dir)[3];
    int n;
    const solve_match *matches; /* the inliers */
    int match_count;
    int total;                  /* residuals: n radiance, then 4 per match */
    double sigma_log, sigma_px; /* each kind's scatter at the start */
    int rot_slot[SL_STITCH_MAX_VIEWS], gain_slot[SL_STITCH_MAX_VIEWS]; /* -1: held */
    bool lens_free[LENS_PARAMS];
    int params;
} lens_problem;

/* The lens and rotations at parameters x (offsets from the start). */
static void lens_at(const lens_problem *p, const double *x, sl_lens *lens, sl_lens *inner,
                    double (*rot)[3][3])
{
    *lens = *p->start;
    lens->focal_px *= exp(x[0]);
    lens->k[0] += x[1];
    lens->k[1] += x[2];
    lens->vignette[0] += x[3];
    lens->vignette[1] += x[4];
    *inner = *lens;
    if (inner->circle_radius_px > 0.0)
        inner->circle_radius_px *= INNER_CIRCLE;
    for (int v = 0; v < p->count; v++) {
        memcpy(rot[v], p->rot[v], sizeof rot[v]);
        if (p->rot_slot[v] >= 0)
            solve_rotate(rot[v], x + p->rot_slot[v]);
    }
}

/* The radiance residuals of samples [begin, end) at one point (each
 * sample's alone: the same values on any number of threads). */
typedef struct residual_job {
    const lens_problem *p;
    const double *x;
    const sl_lens *lens, *inner;
    const double (*rot)[3][3];
    double *r;
} residual_job;

static void radiance_residuals(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    const residual_job *j = ctx;
    const lens_problem *p = j->p;
    for (int64_t i = begin; i < end; i++) {
        int a = p->views[i][0], b = p->views[i][1];
        double la, lb;
        if (!solve_log_radiance(&p->img[a], j->lens, j->inner, j->rot[a], p->dir[i],
                                SMOOTH_LOG, &la) ||
            !solve_log_radiance(&p->img[b], j->lens, j->inner, j->rot[b], p->dir[i],
                                SMOOTH_LOG, &lb)) {
            j->r[i] = NAN;
            continue;
        }
        double ga = p->gain_slot[a] >= 0 ? j->x[p->gain_slot[a]] : 0.0;
        double gb = p->gain_slot[b] >= 0 ? j->x[p->gain_slot[b]] : 0.0;
        j->r[i] = (la - ga) - (lb - gb);
    }
}

/* Per sample ln L_a - ln g_a - (ln L_b - ln g_b), NaN where a view's data
 * ends (on every core: the refinement evaluates them some 200 times); then
 * each match's four reprojection residuals (pixels). */
static void residuals(const lens_problem *p, const double *x, double *r)
{
    sl_lens lens, inner, unbounded;
    double rot[SL_STITCH_MAX_VIEWS][3][3];
    lens_at(p, x, &lens, &inner, rot);
    solve_lens_unbounded(&lens, &unbounded);
    for (int i = 0; i < p->match_count; i++) {
        double *e = r + p->n + 4 * i;
        if (!solve_match_residuals(&p->matches[i], rot, &unbounded, e))
            e[0] = e[1] = e[2] = e[3] = NAN;
    }
    residual_job j = {p, x, &lens, &inner, (const double (*)[3][3])rot, r};
    sl_parallel_for(p->n, 2048, radiance_residuals, &j);
}

/* The weight of residual i of value r: a radiance sample's Huber weight
 * over its kind's variance, a match's over its. */
static double weight(const lens_problem *p, int i, double r)
{
    if (i >= p->n)
        return 1.0 / (p->sigma_px * p->sigma_px);
    double huber = fabs(r) <= HUBER_LOG ? 1.0 : HUBER_LOG / fabs(r);
    return huber / (p->sigma_log * p->sigma_log);
}

/* The residuals at x: each kind's RMS (Huber-weighted for the radiance,
 * per coordinate for the matches) and the joint cost (weighted squares
 * over the residuals that are finite). */
typedef struct lens_cost {
    double rms_log, rms_px, cost;
} lens_cost;

static lens_cost evaluate(const lens_problem *p, const double *x, double *r)
{
    residuals(p, x, r);
    double sum[2] = {0, 0}, weights[2] = {0, 0}, cost = 0.0;
    int used = 0;
    for (int i = 0; i < p->total; i++) {
        if (!isfinite(r[i]))
            continue;
        int kind = i >= p->n;
        double huber = kind ? 1.0 : fabs(r[i]) <= HUBER_LOG ? 1.0 : HUBER_LOG / fabs(r[i]);
        /* an edge's unused residuals are 0: not coordinates */
        if (kind && r[i] == 0.0)
            continue;
        sum[kind] += huber * r[i] * r[i];
        weights[kind] += huber;
        cost += weight(p, i, r[i]) * r[i] * r[i];
        used++;
    }
    lens_cost c = {weights[0] > 0 ? sqrt(sum[0] / weights[0]) : INFINITY,
                   weights[1] > 0 ? sqrt(sum[1] / weights[1]) : 0.0,
                   used ? cost / used : INFINITY};
    return c;
}

/* The directions both views of a solved pair see, smooth in both. */
static int collect(lens_problem *p, const sl_stitch_pair *pair, int pairs, int cap)
{
    sl_lens inner = *p->start;
    if (inner.circle_radius_px > 0.0)
        inner.circle_radius_px *= INNER_CIRCLE;
    int n = 0;
    for (int i = 0; i < DIRECTIONS; i++) {
        double d[3], l;
        solve_sphere_dir(i, DIRECTIONS, d);
        for (int k = 0; k < pairs && n < cap; k++) {
            const sl_stitch_pair *pr = &pair[k];
            if (pr->status != SL_STITCH_PAIR_SOLVED ||
                !solve_log_radiance(&p->img[pr->a], p->start, &inner,
                                    (const double (*)[3])p->rot[pr->a], d, SMOOTH_LOG, &l) ||
                !solve_log_radiance(&p->img[pr->b], p->start, &inner,
                                    (const double (*)[3])p->rot[pr->b], d, SMOOTH_LOG, &l))
                continue;
            p->views[n][0] = pr->a;
            p->views[n][1] = pr->b;
            memcpy(p->dir[n], d, sizeof d);
            n++;
        }
    }
    return n;
}

/* One Gauss-Newton step: x += the step; false when it cannot be solved. */
static bool step(const lens_problem *p, double *x, double *r0, double *rp, double *rm,
                 double *jac)
{
    int np = p->params, n = p->total;
    double h[MAX_PARAMS];
    bool numeric[MAX_PARAMS];
    for (int k = 0; k < np; k++) {
        /* steps of about a tenth of a pixel at the circle's edge */
        h[k] = k < LENS_PARAMS ? 1e-4 : 0.25 / p->start->focal_px;
        numeric[k] = k < LENS_PARAMS ? p->lens_free[k] : true;
    }
    for (int v = 0; v < p->count; v++)
        if (p->gain_slot[v] >= 0)
            numeric[p->gain_slot[v]] = false;
    residuals(p, x, r0);
    for (int k = 0; k < np; k++) {
        if (!numeric[k])
            continue;
        double keep = x[k];
        x[k] = keep + h[k];
        residuals(p, x, rp);
        x[k] = keep - h[k];
        residuals(p, x, rm);
        x[k] = keep;
        for (int i = 0; i < n; i++)
            jac[(size_t)i * np + k] = (rp[i] - rm[i]) / (2.0 * h[k]);
    }
    double hess[MAX_PARAMS * MAX_PARAMS] = {0}, g[MAX_PARAMS] = {0};
    for (int i = 0; i < n; i++) {
        double *j = jac + (size_t)i * np;
        for (int k = 0; k < np; k++)
            if (!numeric[k])
                j[k] = 0.0;
        if (i < p->n) { /* a radiance sample: the two views' gains */
            int a = p->views[i][0], b = p->views[i][1];
            if (p->gain_slot[a] >= 0)
                j[p->gain_slot[a]] = -1.0;
            if (p->gain_slot[b] >= 0)
                j[p->gain_slot[b]] = 1.0;
        }
        bool finite = isfinite(r0[i]);
        for (int k = 0; k < np && finite; k++)
            finite = isfinite(j[k]);
        if (!finite)
            continue;
        double w = weight(p, i, r0[i]);
        for (int a2 = 0; a2 < np; a2++) {
            g[a2] -= w * j[a2] * r0[i];
            for (int b2 = 0; b2 < np; b2++)
                hess[a2 * np + b2] += w * j[a2] * j[b2];
        }
    }
    /* A held value has a zero column: a unit diagonal keeps it put. */
    for (int k = 0; k < np; k++)
        hess[k * np + k] = hess[k * np + k] > 0.0 ? hess[k * np + k] * (1.0 + 1e-9) : 1.0;
    if (!merge_cholesky_solve(hess, g, np))
        return false;
    for (int k = 0; k < np; k++)
        x[k] += g[k];
    return true;
}

bool solve_radiance_lens(int count, const solve_features *feat, double (*rot)[3][3],
                         const bool *free_view, const sl_stitch_pair *pair, int pairs,
                         const solve_match *matches, int match_count,
                         const sl_stitch_solve_options *opt, sl_lens *lens, double *gain,
                         solve_radiance_lens_result *out)
{
    memset(out, 0, sizeof *out);
    if (count > SL_STITCH_MAX_VIEWS)
        return false;
    solve_log_image img[SL_STITCH_MAX_VIEWS] = {{0}};
    lens_problem p = {.count = count, .rot = rot, .start = lens, .img = img,
                      .lens_free = {opt->solve_focal, opt->radial_terms >= 1,
                                    opt->radial_terms >= 2, true, true}};
    double x[MAX_PARAMS] = {0};
    p.params = LENS_PARAMS;
    bool ok = true;
    for (int v = 0; v < count; v++) {
        p.rot_slot[v] = free_view[v] ? p.params : -1;
        p.params += free_view[v] ? 3 : 0;
    }
    for (int v = 0; v < count && ok; v++) {
        p.gain_slot[v] = v > 0 ? p.params++ : -1;
        if (v > 0)
            x[p.gain_slot[v]] = log(gain[v] > 0.0 ? gain[v] : 1.0);
        ok = solve_log_image_make(&feat[v], 1, &img[v]);
    }
    int cap = pairs * DIRECTIONS / 2 + 1;
    p.views = ok ? malloc((size_t)cap * sizeof *p.views) : NULL;
    p.dir = ok ? malloc((size_t)cap * sizeof *p.dir) : NULL;
    p.n = p.views && p.dir ? collect(&p, pair, pairs, cap) : 0;
    out->samples = p.n;
    /* the inlier matches, in one block */
    solve_match *inliers = malloc((size_t)(match_count + 1) * sizeof *inliers);
    for (int i = 0; inliers && i < match_count; i++)
        if (matches[i].inlier)
            inliers[p.match_count++] = matches[i];
    p.matches = inliers;
    p.total = p.n + 4 * p.match_count;
    size_t n = (size_t)p.total;
    double *r0 = malloc((n + 1) * sizeof *r0), *rp = malloc((n + 1) * sizeof *rp),
           *rm = malloc((n + 1) * sizeof *rm), *jac = malloc((n + 1) * p.params * sizeof *jac);
    ok = ok && inliers && p.n >= MIN_SAMPLES && r0 && rp && rm && jac;
    /* Each kind weighed by its own scatter at the features' solution. */
    p.sigma_log = p.sigma_px = 1.0;
    lens_cost start = ok ? evaluate(&p, x, r0) : (lens_cost){INFINITY, INFINITY, INFINITY};
    p.sigma_log = fmax(start.rms_log, 1e-4);
    p.sigma_px = fmax(start.rms_px, 0.01);
    if (ok)
        start = evaluate(&p, x, r0);
    out->rms_start = start.rms_log;
    out->px_start = start.rms_px;
    lens_cost best = start;
    double best_x[MAX_PARAMS];
    memcpy(best_x, x, sizeof x);
    for (int it = 0; ok && it < ITERATIONS; it++) {
        if (!step(&p, x, r0, rp, rm, jac))
            break;
        lens_cost c = evaluate(&p, x, r0);
        if (!(c.cost < best.cost))
            break;
        bool settled = c.cost > best.cost * (1.0 - 1e-4);
        best = c;
        memcpy(best_x, x, sizeof x);
        if (settled)
            break;
    }
    out->rms = best.rms_log;
    out->px = best.rms_px;
    out->focal_change = exp(best_x[0]) - 1.0;
    bool kept = ok && best.cost < start.cost && fabs(out->focal_change) <= MAX_FOCAL_CHANGE &&
                fabs(best_x[1]) <= MAX_K_CHANGE && fabs(best_x[2]) <= MAX_K_CHANGE;
    if (kept) {
        sl_lens refined, inner;
        double turned[SL_STITCH_MAX_VIEWS][3][3];
        lens_at(&p, best_x, &refined, &inner, turned);
        *lens = refined;
        memcpy(rot, turned, (size_t)count * sizeof *rot);
        for (int v = 1; v < count; v++)
            gain[v] = exp(best_x[p.gain_slot[v]]);
    }
    out->kept = kept;
    for (int v = 0; v < count; v++)
        free(img[v].log);
    free(p.views), free(p.dir), free(inliers), free(r0), free(rp), free(rm), free(jac);
    return kept;
}
