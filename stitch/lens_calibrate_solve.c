/* SPDX-License-Identifier: BSD-3-Clause */
/* lens-calibrate's solve: chessboard corners to the project's own lens model
 * (any of its projections, rays up to 90 degrees off-axis and beyond, which
 * OpenCV's cv::fisheye cannot represent). Each board's pose is seeded by a
 * homography of the nominal lens's rays, then a Levenberg-Marquardt bundle
 * adjustment moves the focal length, the centre, the radial terms and every
 * pose together. */
#include "setlight/stitch.h"

#include "merge_private.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define POSE_PARAMS 6
/* Residual of a corner the lens cannot image at some trial step: large, so
 * the step is refused, finite, so the sums stay numbers. */
#define UNSEEN_PX 1e4

void sl_lens_calibrate_options_init(sl_lens_calibrate_options *opt)
{
    memset(opt, 0, sizeof *opt);
    opt->square_mm = 25.0;
    opt->projection = SL_LENS_EQUISOLID;
    opt->radial_terms = -1;
}

static void rodrigues(const double r[3], double m[3][3])
{
    double th = sqrt(r[0] * r[0] + r[1] * r[1] + r[2] * r[2]);
    double k[3] = {0, 0, 0}, c = cos(th), s = sin(th);
    if (th > 1e-15)
        for (int i = 0; i < 3; i++)
            k[i] = r[i] / th;
    double kx[3][3] = {{0, -k[2], k[1]}, {k[2], 0, -k[0]}, {-k[1], k[0], 0}};
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            m[i][j] = (i == j ? c : 0.0) + s * kx[i][j] + (1.0 - c) * k[i] * k[j];
}

static void rodrigues_inverse(const double m[3][3], double r[3])
{
    double c = 0.5 * (m[0][0] + m[1][1] + m[2][2] - 1.0);
    c = c > 1.0 ? 1.0 : (c < -1.0 ? -1.0 : c);
    double th = acos(c);
    double w[3] = {m[2][1] - m[1][2], m[0][2] - m[2][0], m[1][0] - m[0][1]};
    if (th < 1e-9) {
        for (int i = 0; i < 3; i++)
            r[i] = 0.5 * w[i];
        return;
    }
    if (th < M_PI - 1e-4) {
        for (int i = 0; i < 3; i++)
            r[i] = th / (2.0 * sin(th)) * w[i];
        return;
    }
    /* Near a half turn the antisymmetric part vanishes: the axis is the
     * column of (R + I) / 2 = k k^T with the largest diagonal. */
    int a = 0;
    for (int i = 1; i < 3; i++)
        if (m[i][i] > m[a][a])
            a = i;
    double k[3];
    for (int i = 0; i < 3; i++)
        k[i] = 0.5 * (m[i][a] + m[a][i]) + (i == a ? 1.0 : 0.0);
    double n = sqrt(k[0] * k[0] + k[1] * k[1] + k[2] * k[2]);
    double sign = (k[0] * w[0] + k[1] * w[1] + k[2] * w[2]) < 0 ? -1.0 : 1.0;
    for (int i = 0; i < 3; i++)
        r[i] = sign * th * k[i] / n;
}

typedef struct problem {
    const double *obs;   /* count boards x n corners x (x, y) */
    double *board;       /* n points (x, y) in mm, z = 0 */
    int count, n, nk;
    sl_lens base;        /* projection, size, vignetting, field relaxed to 180 deg */
} problem;

static int global_params(const problem *p)
{
    return 3 + p->nk;
}

static void lens_from(const problem *p, const double *x, sl_lens *l)
{
    *l = p->base;
    l->focal_px = x[0];
    l->cx = x[1];
    l->cy = x[2];
    for (int i = 0; i < 3; i++)
        l->k[i] = i < p->nk ? x[3 + i] : 0.0;
}

/* The 2 n residuals (projected minus found, pixels) of board b. */
static void board_residuals(const problem *p, const sl_lens *l, const double *pose, int b,
                            double *res)
{
    double m[3][3];
    rodrigues(pose, m);
    const double *obs = p->obs + (size_t)b * p->n * 2;
    for (int i = 0; i < p->n; i++) {
        const double *q = p->board + 2 * i;
        double x[3];
        for (int k = 0; k < 3; k++)
            x[k] = m[k][0] * q[0] + m[k][1] * q[1] + pose[3 + k];
        double s = hypot(x[0], x[1]);
        double r = sl_lens_radius(l, atan2(s, x[2]));
        if (r < 0) {
            res[2 * i] = res[2 * i + 1] = UNSEEN_PX;
            continue;
        }
        res[2 * i] = l->cx + (s > 0 ? r * x[0] / s : 0.0) - obs[2 * i];
        res[2 * i + 1] = l->cy + (s > 0 ? r * x[1] / s : 0.0) - obs[2 * i + 1];
    }
}

static double all_residuals(const problem *p, const double *x, double *res)
{
    sl_lens l;
    lens_from(p, x, &l);
    int g = global_params(p);
    double sum = 0;
    for (int b = 0; b < p->count; b++) {
        double *rb = res + (size_t)b * p->n * 2;
        board_residuals(p, &l, x + g + POSE_PARAMS * b, b, rb);
        for (int i = 0; i < 2 * p->n; i++)
            sum += rb[i] * rb[i];
    }
    return sum;
}

static double step_size(double v)
{
    return 1e-6 * (fabs(v) > 1.0 ? fabs(v) : 1.0);
}

/* Central-difference Jacobian: jg (rows x g) for the lens, jp (rows x 6) for
 * each row's own board. */
static void jacobian(const problem *p, double *x, double *jg, double *jp, double *plus,
                     double *minus)
{
    int g = global_params(p), rows = 2 * p->n * p->count, bn = 2 * p->n;
    for (int j = 0; j < g; j++) {
        double v = x[j], h = step_size(v);
        x[j] = v + h;
        all_residuals(p, x, plus);
        x[j] = v - h;
        all_residuals(p, x, minus);
        x[j] = v;
        for (int i = 0; i < rows; i++)
            jg[(size_t)i * g + j] = (plus[i] - minus[i]) / (2 * h);
    }
    sl_lens l;
    lens_from(p, x, &l);
    for (int b = 0; b < p->count; b++) {
        double *pose = x + g + POSE_PARAMS * b;
        for (int j = 0; j < POSE_PARAMS; j++) {
            double v = pose[j], h = step_size(v);
            pose[j] = v + h;
            board_residuals(p, &l, pose, b, plus);
            pose[j] = v - h;
            board_residuals(p, &l, pose, b, minus);
            pose[j] = v;
            for (int i = 0; i < bn; i++)
                jp[((size_t)b * bn + i) * POSE_PARAMS + j] = (plus[i] - minus[i]) / (2 * h);
        }
    }
}

/* Levenberg-Marquardt on x (lens then poses). Returns the final sum of squares. */
static double minimise(const problem *p, double *x, int iterations, bool *ok)
{
    int g = global_params(p), np = g + POSE_PARAMS * p->count, rows = 2 * p->n * p->count;
    int bn = 2 * p->n;
    double *res = malloc((size_t)rows * sizeof *res);
    double *plus = malloc((size_t)rows * sizeof *plus);
    double *minus = malloc((size_t)rows * sizeof *minus);
    double *jg = malloc((size_t)rows * g * sizeof *jg);
    double *jp = malloc((size_t)rows * POSE_PARAMS * sizeof *jp);
    double *a = malloc((size_t)np * np * sizeof *a);
    double *sys = malloc((size_t)np * np * sizeof *sys);
    double *grad = malloc((size_t)np * sizeof *grad);
    double *delta = malloc((size_t)np * sizeof *delta);
    double *trial = malloc((size_t)np * sizeof *trial);
    *ok = res && plus && minus && jg && jp && a && sys && grad && delta && trial;
    double cost = *ok ? all_residuals(p, x, res) : INFINITY, lambda = 1e-3;
    for (int it = 0; *ok && it < iterations; it++) {
        jacobian(p, x, jg, jp, plus, minus);
        memset(a, 0, (size_t)np * np * sizeof *a);
        memset(grad, 0, (size_t)np * sizeof *grad);
        /* Each row touches the lens and its own board's pose only. */
        for (int i = 0; i < rows; i++) {
            int b = i / bn, cols[3 + 3 + POSE_PARAMS];
            double v[3 + 3 + POSE_PARAMS];
            int nc = 0;
            for (int j = 0; j < g; j++, nc++) {
                cols[nc] = j;
                v[nc] = jg[(size_t)i * g + j];
            }
            for (int j = 0; j < POSE_PARAMS; j++, nc++) {
                cols[nc] = g + POSE_PARAMS * b + j;
                v[nc] = jp[(size_t)i * POSE_PARAMS + j];
            }
            for (int s = 0; s < nc; s++) {
                grad[cols[s]] += v[s] * res[i];
                for (int t = 0; t < nc; t++)
                    a[(size_t)cols[s] * np + cols[t]] += v[s] * v[t];
            }
        }
        bool improved = false;
        while (!improved && lambda < 1e12) {
            memcpy(sys, a, (size_t)np * np * sizeof *sys);
            for (int j = 0; j < np; j++) {
                sys[(size_t)j * np + j] += lambda * a[(size_t)j * np + j] + 1e-12;
                delta[j] = -grad[j];
            }
            if (merge_cholesky_solve(sys, delta, np)) {
                for (int j = 0; j < np; j++)
                    trial[j] = x[j] + delta[j];
                double c = all_residuals(p, trial, plus);
                if (c < cost) {
                    improved = true;
                    double gain = cost - c;
                    memcpy(x, trial, (size_t)np * sizeof *x);
                    memcpy(res, plus, (size_t)rows * sizeof *res);
                    cost = c;
                    lambda = lambda / 3 > 1e-12 ? lambda / 3 : 1e-12;
                    if (gain < 1e-12 * (cost + 1e-30))
                        it = iterations;
                    continue;
                }
            }
            lambda *= 4;
        }
        if (!improved)
            break;
    }
    free(res);
    free(plus);
    free(minus);
    free(jg);
    free(jp);
    free(a);
    free(sys);
    free(grad);
    free(delta);
    free(trial);
    return cost;
}

static void cross(const double a[3], const double b[3], double c[3])
{
    c[0] = a[1] * b[2] - a[2] * b[1];
    c[1] = a[2] * b[0] - a[0] * b[2];
    c[2] = a[0] * b[1] - a[1] * b[0];
}

static bool normalise(double v[3])
{
    double n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    if (!(n > 0))
        return false;
    for (int i = 0; i < 3; i++)
        v[i] /= n;
    return true;
}

/* A board's pose from the rays the nominal lens gives its corners: turned
 * so the board's mean ray is the axis (a fisheye sees boards near 90 deg
 * off-axis, where x/z would blow up), a homography from the board plane to
 * the turned rays (h33 = 1, normal equations) is split into R and t. */
static bool seed_pose(const problem *p, const sl_lens *l, int b, double pose[6])
{
    int n = p->n;
    const double *obs = p->obs + (size_t)b * n * 2;
    double *rays = malloc((size_t)n * 3 * sizeof *rays);
    if (!rays)
        return false;
    double mean[3] = {0, 0, 0};
    bool ok = true;
    for (int i = 0; i < n && ok; i++) {
        ok = sl_lens_pixel_to_ray(l, obs[2 * i], obs[2 * i + 1], rays + 3 * i);
        for (int k = 0; ok && k < 3; k++)
            mean[k] += rays[3 * i + k];
    }
    double turn[3][3], helper[3] = {1, 0, 0};
    ok = ok && normalise(mean);
    if (ok) {
        if (fabs(mean[0]) > 0.6) {
            helper[0] = 0;
            helper[1] = 1;
        }
        double u[3], v[3];
        cross(helper, mean, u);
        normalise(u);
        cross(mean, u, v);
        for (int k = 0; k < 3; k++) {
            turn[0][k] = u[k];
            turn[1][k] = v[k];
            turn[2][k] = mean[k];
        }
    }
    /* Board coordinates scaled to about [-1, 1] for a well-conditioned system. */
    double bx0 = 0, by0 = 0, scale = 0;
    for (int i = 0; i < n; i++) {
        bx0 += p->board[2 * i] / n;
        by0 += p->board[2 * i + 1] / n;
    }
    for (int i = 0; i < n; i++)
        scale = fmax(scale, fmax(fabs(p->board[2 * i] - bx0), fabs(p->board[2 * i + 1] - by0)));
    double ata[64] = {0}, atb[8] = {0};
    for (int i = 0; i < n && ok; i++) {
        double t[3];
        sl_mat3_apply(turn, rays + 3 * i, t);
        if (!(t[2] > 0.05)) {
            ok = false;
            break;
        }
        double u = t[0] / t[2], v = t[1] / t[2];
        double bx = (p->board[2 * i] - bx0) / scale, by = (p->board[2 * i + 1] - by0) / scale;
        double rows[2][8] = {{bx, by, 1, 0, 0, 0, -u * bx, -u * by},
                             {0, 0, 0, bx, by, 1, -v * bx, -v * by}};
        double rhs[2] = {u, v};
        for (int r = 0; r < 2; r++)
            for (int j = 0; j < 8; j++) {
                atb[j] += rows[r][j] * rhs[r];
                for (int k = 0; k < 8; k++)
                    ata[j * 8 + k] += rows[r][j] * rows[r][k];
            }
    }
    free(rays);
    if (!ok || !merge_cholesky_solve(ata, atb, 8))
        return false;
    double hn[3][3] = {{atb[0], atb[1], atb[2]}, {atb[3], atb[4], atb[5]}, {atb[6], atb[7], 1}};
    double norm[3][3] = {{1 / scale, 0, -bx0 / scale}, {0, 1 / scale, -by0 / scale}, {0, 0, 1}};
    double h[3][3];
    sl_mat3_mul(hn, norm, h);
    double h1[3] = {h[0][0], h[1][0], h[2][0]}, h2[3] = {h[0][1], h[1][1], h[2][1]};
    double h3[3] = {h[0][2], h[1][2], h[2][2]};
    double lambda = 2.0 / (sqrt(h1[0] * h1[0] + h1[1] * h1[1] + h1[2] * h1[2]) +
                           sqrt(h2[0] * h2[0] + h2[1] * h2[1] + h2[2] * h2[2]));
    if (h3[2] * lambda < 0)
        lambda = -lambda;
    double r1[3], r2[3], r3[3], t[3];
    for (int k = 0; k < 3; k++) {
        r1[k] = lambda * h1[k];
        r2[k] = lambda * h2[k];
        t[k] = lambda * h3[k];
    }
    if (!normalise(r1))
        return false;
    double d = r1[0] * r2[0] + r1[1] * r2[1] + r1[2] * r2[2];
    for (int k = 0; k < 3; k++)
        r2[k] -= d * r1[k];
    if (!normalise(r2))
        return false;
    cross(r1, r2, r3);
    /* Back from the turned frame: camera = turn^T turned. */
    double rt[3][3] = {{r1[0], r2[0], r3[0]}, {r1[1], r2[1], r3[1]}, {r1[2], r2[2], r3[2]}};
    double back[3][3], rc[3][3];
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            back[i][j] = turn[j][i];
    sl_mat3_mul(back, rt, rc);
    rodrigues_inverse(rc, pose);
    sl_mat3_apply(back, t, pose + 3);
    return true;
}

sl_result sl_lens_calibrate_corners(const double *corners, int count,
                                    const sl_lens_calibrate_options *opt, sl_lens *lens,
                                    double *rms_px, double *max_px, double *rms, double *max,
                                    sl_error *err)
{
    int cols = opt->board_cols, rows = opt->board_rows;
    if (cols < 2 || rows < 2 || cols * rows > 10000 || !(opt->square_mm > 0) ||
        opt->radial_terms < 0 || opt->radial_terms > 3 || count < 1)
        return sl_error_set(err, SL_ERR_USAGE,
                            "lens-calibrate: board %dx%d, square %g mm, %d radial terms, %d boards",
                            cols, rows, opt->square_mm, opt->radial_terms, count);
    problem p = {.obs = corners, .count = count, .n = cols * rows, .nk = opt->radial_terms,
                 .base = *lens};
    p.base.max_theta_deg = p.base.projection == SL_LENS_RECTILINEAR    ? 89.999
                           : p.base.projection == SL_LENS_ORTHOGRAPHIC ? 90.0
                                                                       : 180.0;
    p.base.circle_radius_px = 0;
    int g = global_params(&p), np = g + POSE_PARAMS * count;
    p.board = malloc((size_t)p.n * 2 * sizeof *p.board);
    double *x = malloc((size_t)np * sizeof *x);
    double *res = malloc((size_t)2 * p.n * count * sizeof *res);
    if (!p.board || !x || !res) {
        free(p.board);
        free(x);
        free(res);
        return sl_error_set(err, SL_ERR_NOMEM, "lens-calibrate: out of memory");
    }
    for (int r = 0; r < rows; r++)
        for (int c = 0; c < cols; c++) {
            p.board[2 * (r * cols + c)] = c * opt->square_mm;
            p.board[2 * (r * cols + c) + 1] = r * opt->square_mm;
        }
    sl_result result = SL_OK;
    sl_lens seed = p.base;
    memset(seed.k, 0, sizeof seed.k);
    x[0] = lens->focal_px;
    x[1] = lens->cx;
    x[2] = lens->cy;
    for (int i = 0; i < p.nk; i++)
        x[3 + i] = 0.0;
    for (int b = 0; b < count && !result; b++)
        if (!seed_pose(&p, &seed, b, x + g + POSE_PARAMS * b))
            result = sl_error_set(err, SL_ERR_INPUT,
                                  "lens-calibrate: board %d: the nominal lens gives no pose for "
                                  "its corners (corners outside the lens's field?)",
                                  b + 1);
    bool ok = true;
    if (!result)
        minimise(&p, x, 200, &ok);
    if (!result && !ok)
        result = sl_error_set(err, SL_ERR_NOMEM, "lens-calibrate: out of memory");
    if (!result) {
        sl_lens solved;
        lens_from(&p, x, &solved);
        all_residuals(&p, x, res);
        double total = 0, worst = 0;
        for (int b = 0; b < count; b++) {
            double sum = 0, bmax = 0;
            for (int i = 0; i < p.n; i++) {
                const double *e = res + ((size_t)b * p.n + i) * 2;
                double d2 = e[0] * e[0] + e[1] * e[1];
                sum += d2;
                bmax = fmax(bmax, sqrt(d2));
            }
            total += sum;
            worst = fmax(worst, bmax);
            if (rms_px)
                rms_px[b] = sqrt(sum / p.n);
            if (max_px)
                max_px[b] = bmax;
        }
        if (rms)
            *rms = sqrt(total / ((double)p.n * count));
        if (max)
            *max = worst;
        solved.max_theta_deg = lens->max_theta_deg;
        solved.circle_radius_px = 0;
        if (lens->circle_radius_px > 0) {
            double r = sl_lens_radius(&solved, solved.max_theta_deg * (M_PI / 180.0));
            solved.circle_radius_px = r > 0 ? r : 0;
        }
        if (!(worst < UNSEEN_PX))
            result = sl_error_set(err, SL_ERR_INPUT,
                                  "lens-calibrate: the solve did not converge (corners left "
                                  "outside the lens's field)");
        else if (!(result = sl_lens_check(&solved, "lens-calibrate: solved lens", err)))
            *lens = solved;
    }
    free(p.board);
    free(x);
    free(res);
    return result;
}
