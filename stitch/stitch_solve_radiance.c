/* SPDX-License-Identifier: BSD-3-Clause */
/* Views no solved pair places (a clear sky gives their overlaps no
 * features), turned to where their overlaps' radiance agrees with the
 * placed views: direct photometric alignment of the log radiance, coarse to
 * fine, over the group's three rotation angles and each moved view's gain,
 * the lens and vignetting held at what the features solved (docs/stitch.md,
 * "Solve", step 9). */
#include "merge_private.h"
#include "stitch_private.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define DEG (M_PI / 180.0)

enum { LEVELS = 3, MAX_ITERATIONS = 10 };
/* Each level's reduction of the features' copies: the first pulls a pose
 * a few pixels off into reach, the last is the data itself; and the
 * directions sampled over the sphere at each (the reduced levels only
 * bring the pose near). */
static const int level_factor[LEVELS] = {4, 2, 1};
static const int level_directions[LEVELS] = {10000, 10000, 40000};
/* Huber scale of the log radiance residual (2% of radiance). */
#define HUBER_LOG 0.02
/* A sample whose 2 x 2 pixels span more than this in log radiance sits on
 * a hard edge (the sun's rim, the horizon) where bilinear values are not
 * the scene's: left out. */
#define EDGE_LOG 0.2
/* The least noise a sample's log radiance is taken to have (0.5%): a
 * merged view's noise and what bilinear lookups miss. Synthetic views fit
 * to 1e-4, which would make any faint structure look decisive. */
#define NOISE_FLOOR_LOG 0.005
/* Samples inside this share of the circle: the pose may move them. */
#define INNER_CIRCLE 0.95

typedef struct radiance_sample {
    int moving, ref;  /* view indices */
    double dir[3];    /* world direction */
    double ref_log;   /* the placed view's log radiance there, its falloff and gain removed */
} radiance_sample;

typedef struct radiance_problem {
    int count;
    const bool *moving, *placed;
    double (*rot)[3][3];
    const sl_lens *lens, *inner;
    solve_log_image *img; /* per view, the current level */
    radiance_sample *s;
    int n;
    int slot[SL_STITCH_MAX_VIEWS]; /* gain parameter index of a moving view */
    int params;
} radiance_problem;

static bool view_log(const radiance_problem *p, const solve_log_image *l, const double rot[3][3],
                     const double d[3], double *out)
{
    return solve_log_radiance(l, p->lens, p->inner, rot, d, EDGE_LOG, out);
}

/* The moving views' samples: directions they and a placed view both see
 * (at the current pose), with the placed view's log radiance. */
static int collect(radiance_problem *p, const double *log_gain, int directions, int cap)
{
    int n = 0;
    for (int i = 0; i < directions && n < cap; i++) {
        double d[3];
        solve_sphere_dir(i, directions, d);
        for (int m = 0; m < p->count && n < cap; m++) {
            double lm;
            if (!p->moving[m] || !view_log(p, &p->img[m], (const double (*)[3])p->rot[m], d, &lm))
                continue;
            for (int o = 0; o < p->count && n < cap; o++) {
                double lo;
                if (!p->placed[o] ||
                    !view_log(p, &p->img[o], (const double (*)[3])p->rot[o], d, &lo))
                    continue;
                radiance_sample *s = &p->s[n++];
                s->moving = m;
                s->ref = o;
                memcpy(s->dir, d, sizeof s->dir);
                s->ref_log = lo - log_gain[o];
            }
        }
    }
    return n;
}

/* Residuals with the moving views turned by Exp(w) (world frame) and their
 * log gains x[3 + slot]: NaN where a sample left the data. */
static void residuals(const radiance_problem *p, const double w[3], const double *x, double *r)
{
    double turned[SL_STITCH_MAX_VIEWS][3][3];
    for (int v = 0; v < p->count; v++)
        if (p->moving[v]) {
            memcpy(turned[v], p->rot[v], sizeof turned[v]);
            solve_rotate(turned[v], w);
        }
    for (int i = 0; i < p->n; i++) {
        const radiance_sample *s = &p->s[i];
        double lm;
        r[i] = view_log(p, &p->img[s->moving], (const double (*)[3])turned[s->moving], s->dir, &lm)
                   ? lm - x[3 + p->slot[s->moving]] - s->ref_log
                   : NAN;
    }
}

typedef struct radiance_fit {
    double rms_start, rms; /* log radiance residual at the nominal pose and the solved one */
    double sigma_deg;      /* one standard deviation along the worst-determined axis */
} radiance_fit;

/* Gauss-Newton with a Huber loss on the current level's samples; on the
 * last level also the fit's spread and the rotation's conditioning. */
static bool gauss_newton(const radiance_problem *p, double *x, bool last, radiance_fit *fit)
{
    int np = p->params, n = p->n;
    double *r0 = malloc((size_t)n * sizeof *r0), *rp = malloc((size_t)n * sizeof *rp),
           *rm = malloc((size_t)n * sizeof *rm), *jac = malloc((size_t)n * 3 * sizeof *jac);
    double h = 0.25 * p->img[0].scale / p->lens->focal_px; /* a quarter pixel of the level */
    bool ok = r0 && rp && rm && jac && np <= 3 + SL_STITCH_MAX_VIEWS;
    double hess[(3 + SL_STITCH_MAX_VIEWS) * (3 + SL_STITCH_MAX_VIEWS)], g[3 + SL_STITCH_MAX_VIEWS];
    double sum_sq = 0.0, weights = 0.0;
    for (int it = 0; ok && it <= MAX_ITERATIONS; it++) {
        residuals(p, x, x, r0);
        for (int k = 0; k < 3; k++) {
            double wp[3] = {x[0], x[1], x[2]}, wm[3] = {x[0], x[1], x[2]};
            wp[k] += h;
            wm[k] -= h;
            residuals(p, wp, x, rp);
            residuals(p, wm, x, rm);
            for (int i = 0; i < n; i++)
                jac[3 * i + k] = (rp[i] - rm[i]) / (2.0 * h);
        }
        memset(hess, 0, sizeof hess);
        memset(g, 0, sizeof g);
        sum_sq = weights = 0.0;
        for (int i = 0; i < n; i++) {
            double j[3 + SL_STITCH_MAX_VIEWS] = {0};
            memcpy(j, jac + 3 * i, 3 * sizeof *j);
            j[3 + p->slot[p->s[i].moving]] = -1.0;
            if (!isfinite(r0[i]) || !isfinite(j[0] + j[1] + j[2]))
                continue;
            double wt = fabs(r0[i]) <= HUBER_LOG ? 1.0 : HUBER_LOG / fabs(r0[i]);
            sum_sq += wt * r0[i] * r0[i];
            weights += wt;
            for (int a = 0; a < np; a++) {
                g[a] += wt * j[a] * r0[i];
                for (int b = 0; b < np; b++)
                    hess[a * np + b] += wt * j[a] * j[b];
            }
        }
        if (weights < 4.0 * np) {
            ok = false;
            break;
        }
        if (it == MAX_ITERATIONS)
            break; /* hess and the spread at the final x */
        double step[3 + SL_STITCH_MAX_VIEWS];
        double a[(3 + SL_STITCH_MAX_VIEWS) * (3 + SL_STITCH_MAX_VIEWS)];
        memcpy(a, hess, sizeof a);
        for (int u = 0; u < np; u++)
            step[u] = -g[u];
        if (!merge_cholesky_solve(a, step, np)) {
            ok = false;
            break;
        }
        for (int u = 0; u < np; u++)
            x[u] += step[u];
        if (fabs(step[0]) + fabs(step[1]) + fabs(step[2]) < 2e-6) /* 1e-4 deg */
            it = MAX_ITERATIONS - 1; /* one more pass for hess at the solution */
    }
    fit->rms = weights > 0.0 ? sqrt(sum_sq / weights) : INFINITY;
    if (ok && last) {
        /* The rotation block with the gains eliminated (each gain's column
         * touches only its own view's samples: the gain block is diagonal). */
        double s[3][3], ev[3];
        for (int a = 0; a < 3; a++)
            for (int b = 0; b < 3; b++) {
                s[a][b] = hess[a * np + b];
                for (int c = 3; c < np; c++)
                    s[a][b] -= hess[a * np + c] * hess[c * np + b] / hess[c * np + c];
            }
        sl_mat3_sym_eigenvalues((const double (*)[3])s, ev);
        double var = fmax(sum_sq / fmax(1.0, weights - np), NOISE_FLOOR_LOG * NOISE_FLOOR_LOG);
        fit->sigma_deg = ev[2] > 0.0 ? sqrt(var / ev[2]) / DEG : INFINITY;
    }
    free(r0), free(rp), free(rm), free(jac);
    return ok;
}

bool solve_radiance_turn(int count, const solve_features *feat, double (*rot)[3][3],
                         const bool *moving, const bool *placed, const sl_lens *lens,
                         double *gain, double max_turn_deg, double max_sigma_deg, char *why,
                         size_t why_size)
{
    radiance_problem p = {.count = count, .moving = moving, .placed = placed, .rot = rot,
                          .lens = lens};
    sl_lens inner = *lens;
    if (inner.circle_radius_px > 0.0)
        inner.circle_radius_px *= INNER_CIRCLE;
    p.inner = &inner;
    double log_gain[SL_STITCH_MAX_VIEWS], x[3 + SL_STITCH_MAX_VIEWS] = {0};
    int cap = 2 * level_directions[LEVELS - 1];
    solve_log_image img[SL_STITCH_MAX_VIEWS] = {{0}};
    p.img = img;
    p.s = malloc((size_t)cap * sizeof *p.s);
    p.params = 3;
    bool ok = p.s != NULL && count <= SL_STITCH_MAX_VIEWS;
    for (int v = 0; ok && v < count; v++) {
        log_gain[v] = log(gain[v] > 0.0 ? gain[v] : 1.0);
        if (moving[v]) {
            p.slot[v] = p.params - 3;
            x[p.params++] = log_gain[v];
        }
    }
    radiance_fit fit = {.rms_start = INFINITY, .rms = INFINITY, .sigma_deg = INFINITY};
    for (int level = 0; ok && level < LEVELS; level++) {
        for (int v = 0; ok && v < count; v++) {
            free(img[v].log);
            ok = solve_log_image_make(&feat[v], level_factor[level], &img[v]);
        }
        /* The samples at the pose reached so far. */
        double turned[SL_STITCH_MAX_VIEWS][3][3];
        memcpy(turned, rot, (size_t)count * sizeof *rot);
        for (int v = 0; v < count; v++)
            if (moving[v])
                solve_rotate(turned[v], x);
        p.rot = turned;
        p.n = ok ? collect(&p, log_gain, level_directions[level], cap) : 0;
        p.rot = rot;
        ok = ok && p.n >= 200;
        if (ok && level == LEVELS - 1) {
            /* The spread at the nominal pose, on the data itself. */
            double *r = malloc((size_t)p.n * sizeof *r), zero[3 + SL_STITCH_MAX_VIEWS];
            memcpy(zero, x, sizeof zero);
            zero[0] = zero[1] = zero[2] = 0.0;
            if (r) {
                residuals(&p, zero, zero, r);
                double sq = 0.0;
                int used = 0;
                for (int i = 0; i < p.n; i++)
                    if (isfinite(r[i])) {
                        sq += r[i] * r[i];
                        used++;
                    }
                fit.rms_start = used ? sqrt(sq / used) : INFINITY;
            }
            free(r);
        }
        ok = ok && gauss_newton(&p, x, level == LEVELS - 1, &fit);
    }
    double turn = sqrt(x[0] * x[0] + x[1] * x[1] + x[2] * x[2]) / DEG;
    bool accept = ok && turn <= max_turn_deg && fit.sigma_deg <= max_sigma_deg &&
                  fit.rms <= fit.rms_start;
    if (!ok)
        snprintf(why, why_size, "radiance: %d overlap samples, too few for a pose", p.n);
    else if (accept)
        snprintf(why, why_size,
                 "no features; by radiance (%d samples): turned %.3f deg, known to %.4f deg, "
                 "log residual %.4f (nominal %.4f)",
                 p.n, turn, fit.sigma_deg, fit.rms, fit.rms_start);
    else
        snprintf(why, why_size,
                 "radiance: turn %.2f deg known to %.3f deg (needs %.3f), residual %.4f "
                 "(nominal %.4f)",
                 turn, fit.sigma_deg, max_sigma_deg, fit.rms, fit.rms_start);
    if (accept)
        for (int v = 0; v < count; v++)
            if (moving[v]) {
                solve_rotate(rot[v], x);
                gain[v] = exp(x[3 + p.slot[v]]);
            }
    for (int v = 0; v < count; v++)
        free(img[v].log);
    free(p.s);
    return accept;
}

