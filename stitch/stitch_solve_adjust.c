/* SPDX-License-Identifier: BSD-3-Clause */
/* The solve's bundle adjustment: Levenberg-Marquardt over the free views'
 * rotations and the shared lens, minimising the pixel reprojection error of
 * the inlier matches both ways with a Huber loss. Small dense normal
 * equations (3 per view plus up to 5 lens values); forward differences. */
#include "merge_private.h"
#include "stitch_private.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

void solve_lens_unbounded(const sl_lens *lens, sl_lens *out)
{
    *out = *lens;
    out->circle_radius_px = 0.0;
    out->width = out->height = 1 << 28;
    switch (lens->projection) {
    case SL_LENS_ORTHOGRAPHIC:
        out->max_theta_deg = 90.0;
        break;
    case SL_LENS_RECTILINEAR:
        out->max_theta_deg = 89.0;
        break;
    default:
        out->max_theta_deg = 150.0;
    }
}

void solve_rotate(double r[3][3], const double w[3])
{
    double t = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    double e[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
    if (t > 0.0) {
        double k[3] = {w[0] / t, w[1] / t, w[2] / t}, s = sin(t), c = 1.0 - cos(t);
        double kx[3][3] = {{0, -k[2], k[1]}, {k[2], 0, -k[0]}, {-k[1], k[0], 0}};
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                double kk = 0.0;
                for (int m = 0; m < 3; m++)
                    kk += kx[i][m] * kx[m][j];
                e[i][j] += s * kx[i][j] + c * kk;
            }
    }
    sl_mat3_mul(e, r, r);
}

double solve_rotation_angle(const double a[3][3], const double b[3][3])
{
    double tr = 0.0; /* trace of a^T b */
    for (int i = 0; i < 3; i++)
        for (int k = 0; k < 3; k++)
            tr += a[k][i] * b[k][i];
    double c = 0.5 * (tr - 1.0);
    return acos(c > 1.0 ? 1.0 : c < -1.0 ? -1.0 : c) * 180.0 / M_PI;
}

void solve_to_camera(const double rot[3][3], const double world[3], double cam[3])
{
    for (int i = 0; i < 3; i++)
        cam[i] = rot[0][i] * world[0] + rot[1][i] * world[1] + rot[2][i] * world[2];
}

void solve_sphere_dir(int i, int n, double dir[3])
{
    const double golden = M_PI * (3.0 - sqrt(5.0));
    double y = 1.0 - 2.0 * (i + 0.5) / n, r = sqrt(1.0 - y * y);
    dir[0] = r * cos(golden * i);
    dir[1] = y;
    dir[2] = r * sin(golden * i);
}

bool solve_transfer(const sl_lens *unbounded, const double from[3][3], const double to[3][3],
                    const double px_from[2], double px_to[2])
{
    double ray[3], w[3], c[3];
    if (!sl_lens_pixel_to_ray(unbounded, px_from[0], px_from[1], ray))
        return false;
    sl_mat3_apply(from, ray, w);
    solve_to_camera(to, w, c);
    return sl_lens_ray_to_pixel(unbounded, c, &px_to[0], &px_to[1]);
}

/* Pixel in view `to` of the camera ray `ray` of view `from`. */
static bool transfer(const sl_lens *lens, const double from[3][3], const double to[3][3],
                     const double ray[3], double px[2])
{
    double w[3], c[3];
    sl_mat3_apply(from, ray, w);
    solve_to_camera(to, w, c);
    return sl_lens_ray_to_pixel(lens, c, &px[0], &px[1]);
}

/* The four residuals of a match: b's point seen in a, a's point seen in b. */
static bool residuals(const solve_match *m, double (*rot)[3][3], const sl_lens *lens,
                      const double ray_a[3], const double ray_b[3], double res[4])
{
    double pa[2], pb[2];
    if (!transfer(lens, rot[m->b], rot[m->a], ray_b, pa) ||
        !transfer(lens, rot[m->a], rot[m->b], ray_a, pb))
        return false;
    res[0] = pa[0] - m->pa[0];
    res[1] = pa[1] - m->pa[1];
    res[2] = pb[0] - m->pb[0];
    res[3] = pb[1] - m->pb[1];
    if (m->normal[0] != 0.0 || m->normal[1] != 0.0) {
        /* along an edge the position says nothing: only across it */
        res[0] = m->normal[0] * res[0] + m->normal[1] * res[1];
        res[1] = res[2] = res[3] = 0.0;
    }
    return true;
}

bool solve_match_residuals(const solve_match *m, double (*rot)[3][3], const sl_lens *unbounded,
                           double res[4])
{
    double ra[3], rb[3];
    return sl_lens_pixel_to_ray(unbounded, m->pa[0], m->pa[1], ra) &&
           sl_lens_pixel_to_ray(unbounded, m->pb[0], m->pb[1], rb) &&
           residuals(m, rot, unbounded, ra, rb, res);
}

double solve_match_error(const solve_match *m, double (*rot)[3][3], const sl_lens *unbounded,
                         double *err_b_in_a, double *err_a_in_b)
{
    double ra[3], rb[3], res[4];
    if (!sl_lens_pixel_to_ray(unbounded, m->pa[0], m->pa[1], ra) ||
        !sl_lens_pixel_to_ray(unbounded, m->pb[0], m->pb[1], rb) ||
        !residuals(m, rot, unbounded, ra, rb, res))
        return -1.0;
    double e1 = hypot(res[0], res[1]), e2 = hypot(res[2], res[3]);
    if (m->normal[0] != 0.0 || m->normal[1] != 0.0)
        e2 = e1; /* an edge's one residual, counted once for each way */
    if (err_b_in_a)
        *err_b_in_a = e1;
    if (err_a_in_b)
        *err_a_in_b = e2;
    return e1 > e2 ? e1 : e2;
}

enum { LENS_F, LENS_CX, LENS_CY, LENS_K1, LENS_K2, LENS_PARAMS };

static double *lens_field(sl_lens *l, int which)
{
    switch (which) {
    case LENS_F:
        return &l->focal_px;
    case LENS_CX:
        return &l->cx;
    case LENS_CY:
        return &l->cy;
    case LENS_K1:
        return &l->k[0];
    default:
        return &l->k[1];
    }
}

typedef struct adjust_layout {
    int views;
    int *view_param; /* first parameter of each view, -1 when fixed */
    int lens_param[LENS_PARAMS];
    int n;
    /* the centre prior's weight per axis (0: none) and its centre */
    double prior_weight[2], prior_centre[2];
} adjust_layout;

/* The matches' weighted squared residuals and their count (the residual
 * variance of the last evaluate). */
typedef struct adjust_spread {
    double sum_sq;
    int count;
} adjust_spread;

/* Huber-weighted cost and, when jtj is set, the normal equations; spread
 * (may be NULL) gets the matches' residual sums. */
static double evaluate(const solve_match *matches, int count, double (*rot)[3][3],
                       const sl_lens *lens, const adjust_layout *lay, double huber, double *jtj,
                       double *jtr, adjust_spread *spread)
{
    int n = lay->n;
    if (jtj) {
        memset(jtj, 0, (size_t)n * n * sizeof *jtj);
        memset(jtr, 0, (size_t)n * sizeof *jtr);
    }
    double cost = 0.0;
    double jac[4][3 + 3 + LENS_PARAMS];
    int idx[3 + 3 + LENS_PARAMS];
    for (int i = 0; i < count; i++) {
        const solve_match *m = &matches[i];
        if (!m->inlier)
            continue;
        double ra[3], rb[3], r0[4];
        if (!sl_lens_pixel_to_ray(lens, m->pa[0], m->pa[1], ra) ||
            !sl_lens_pixel_to_ray(lens, m->pb[0], m->pb[1], rb) ||
            !residuals(m, rot, lens, ra, rb, r0))
            continue;
        double w[2];
        bool edge = m->normal[0] != 0.0 || m->normal[1] != 0.0;
        for (int d = 0; d < 2; d++) {
            double e = hypot(r0[2 * d], r0[2 * d + 1]);
            w[d] = e <= huber ? 1.0 : huber / e;
            cost += e <= huber ? 0.5 * e * e : huber * (e - 0.5 * huber);
            if (spread && (d == 0 || !edge)) {
                spread->sum_sq += w[d] * e * e;
                spread->count += edge ? 1 : 2;
            }
        }
        if (!jtj)
            continue;
        int k = 0;
        const double h_rot = 1e-7;
        int vs[2] = {m->a, m->b};
        for (int s = 0; s < 2; s++) {
            if (lay->view_param[vs[s]] < 0)
                continue;
            for (int c = 0; c < 3; c++) {
                double save[3][3], dw[3] = {0, 0, 0}, rp[4];
                memcpy(save, rot[vs[s]], sizeof save);
                dw[c] = h_rot;
                solve_rotate(rot[vs[s]], dw);
                bool ok = residuals(m, rot, lens, ra, rb, rp);
                memcpy(rot[vs[s]], save, sizeof save);
                for (int q = 0; q < 4; q++)
                    jac[q][k] = ok ? (rp[q] - r0[q]) / h_rot : 0.0;
                idx[k++] = lay->view_param[vs[s]] + c;
            }
        }
        for (int p = 0; p < LENS_PARAMS; p++) {
            if (lay->lens_param[p] < 0)
                continue;
            sl_lens lp = *lens;
            double *f = lens_field(&lp, p);
            double h = p == LENS_F ? 1e-6 * lens->focal_px : p <= LENS_CY ? 1e-4 : 1e-7;
            *f += h;
            double ra2[3], rb2[3], rp[4];
            bool ok = sl_lens_pixel_to_ray(&lp, m->pa[0], m->pa[1], ra2) &&
                      sl_lens_pixel_to_ray(&lp, m->pb[0], m->pb[1], rb2) &&
                      residuals(m, rot, &lp, ra2, rb2, rp);
            for (int q = 0; q < 4; q++)
                jac[q][k] = ok ? (rp[q] - r0[q]) / h : 0.0;
            idx[k++] = lay->lens_param[p];
        }
        for (int q = 0; q < 4; q++) {
            double wq = w[q / 2];
            for (int u = 0; u < k; u++) {
                jtr[idx[u]] += wq * jac[q][u] * r0[q];
                for (int v = 0; v < k; v++)
                    jtj[idx[u] * n + idx[v]] += wq * jac[q][u] * jac[q][v];
            }
        }
    }
    /* The centre's measurement: a quadratic pull toward it. */
    for (int a = 0; a < 2; a++) {
        int k = lay->lens_param[LENS_CX + a];
        if (k < 0 || !(lay->prior_weight[a] > 0.0))
            continue;
        double d = (a ? lens->cy : lens->cx) - lay->prior_centre[a];
        cost += 0.5 * lay->prior_weight[a] * d * d;
        if (jtj) {
            jtr[k] += lay->prior_weight[a] * d;
            jtj[k * n + k] += lay->prior_weight[a];
        }
    }
    return cost;
}

/* The centre's covariance from the normal equations at the solution:
 * sigma^2 (J^T J)^-1 over the centre's two parameters. */
static void centre_covariance(const double *jtj, const adjust_layout *lay, double sigma2,
                              double cov[3])
{
    int n = lay->n, kx = lay->lens_param[LENS_CX], ky = lay->lens_param[LENS_CY];
    cov[0] = cov[1] = cov[2] = 0.0;
    double *a = malloc((size_t)n * n * sizeof *a), *col = malloc((size_t)n * sizeof *col);
    for (int c = 0; a && col && kx >= 0 && ky >= 0 && c < 2; c++) {
        memcpy(a, jtj, (size_t)n * n * sizeof *a);
        for (int i = 0; i < n; i++)
            col[i] = i == (c ? ky : kx);
        if (!merge_cholesky_solve(a, col, n))
            break;
        if (c == 0) {
            cov[0] = sigma2 * col[kx];
            cov[1] = sigma2 * col[ky];
        } else {
            cov[2] = sigma2 * col[ky];
        }
    }
    free(a), free(col);
}

static void apply_step(double (*rot)[3][3], sl_lens *lens, const adjust_layout *lay,
                       const double *step)
{
    for (int v = 0; v < lay->views; v++)
        if (lay->view_param[v] >= 0) {
            double w[3] = {-step[lay->view_param[v]], -step[lay->view_param[v] + 1],
                           -step[lay->view_param[v] + 2]};
            solve_rotate(rot[v], w);
        }
    for (int p = 0; p < LENS_PARAMS; p++)
        if (lay->lens_param[p] >= 0)
            *lens_field(lens, p) -= step[lay->lens_param[p]];
}

int solve_adjust(solve_match *matches, int count, double (*rot)[3][3], const bool *free_view,
                 int views, sl_lens *lens, const sl_stitch_solve_options *opt, double huber_px,
                 const solve_centre_prior *prior, double centre_cov[3])
{
    adjust_layout lay = {.views = views, .n = 0};
    if (centre_cov)
        centre_cov[0] = centre_cov[1] = centre_cov[2] = 0.0;
    lay.view_param = malloc((size_t)views * sizeof *lay.view_param);
    if (!lay.view_param)
        return 0;
    for (int v = 0; v < views; v++) {
        lay.view_param[v] = free_view[v] ? lay.n : -1;
        if (free_view[v])
            lay.n += 3;
    }
    bool want[LENS_PARAMS] = {opt->solve_focal, opt->solve_centre, opt->solve_centre,
                              opt->radial_terms >= 1, opt->radial_terms >= 2};
    for (int p = 0; p < LENS_PARAMS; p++)
        lay.lens_param[p] = want[p] ? lay.n++ : -1;
    int n = lay.n, iterations = 0;
    double *jtj = malloc((size_t)n * n * sizeof *jtj), *jtr = malloc((size_t)n * sizeof *jtr);
    double *a = malloc((size_t)n * n * sizeof *a), *step = malloc((size_t)n * sizeof *step);
    double (*rot_try)[3][3] = malloc((size_t)views * sizeof *rot_try);
    if (n == 0 || !jtj || !jtr || !a || !step || !rot_try)
        goto done;
    sl_lens lens_u;
    solve_lens_unbounded(lens, &lens_u);
    double lambda = 1e-3;
    adjust_spread spread = {0.0, 0};
    double cost = evaluate(matches, count, rot, &lens_u, &lay, huber_px, jtj, jtr, &spread);
    if (prior && lay.lens_param[LENS_CX] >= 0 && spread.count > 0) {
        /* Weighed as one more measurement of the residuals' variance: the
         * matches' at the start (a loose first round pulls less), floored
         * at (0.02 px)^2 so a handful of exact matches do not make it a
         * hard constraint. */
        double var = fmax(spread.sum_sq / spread.count, 0.02 * 0.02);
        lay.prior_centre[0] = prior->cx;
        lay.prior_centre[1] = prior->cy;
        lay.prior_weight[0] = var / (prior->sigma_x * prior->sigma_x);
        lay.prior_weight[1] = var / (prior->sigma_y * prior->sigma_y);
        cost = evaluate(matches, count, rot, &lens_u, &lay, huber_px, jtj, jtr, NULL);
    }
    for (iterations = 0; iterations < 100; iterations++) {
        bool accepted = false;
        for (int attempt = 0; attempt < 12 && !accepted; attempt++) {
            memcpy(a, jtj, (size_t)n * n * sizeof *a);
            for (int i = 0; i < n; i++) {
                a[i * n + i] += lambda * (jtj[i * n + i] > 0.0 ? jtj[i * n + i] : 1.0);
                step[i] = jtr[i];
            }
            if (!merge_cholesky_solve(a, step, n)) {
                lambda *= 10.0;
                continue;
            }
            memcpy(rot_try, rot, (size_t)views * sizeof *rot_try);
            sl_lens try_lens = lens_u;
            apply_step(rot_try, &try_lens, &lay, step);
            double c = evaluate(matches, count, rot_try, &try_lens, &lay, huber_px, NULL, NULL,
                                NULL);
            if (c <= cost) {
                double gain = cost - c;
                memcpy(rot, rot_try, (size_t)views * sizeof *rot_try);
                lens_u = try_lens;
                lambda = lambda * 0.3 > 1e-9 ? lambda * 0.3 : 1e-9;
                accepted = true;
                if (gain <= 1e-10 * (cost + 1e-12)) {
                    cost = c;
                    goto converged;
                }
                cost = evaluate(matches, count, rot, &lens_u, &lay, huber_px, jtj, jtr, NULL);
            } else {
                lambda *= 10.0;
            }
        }
        if (!accepted)
            break;
    }
converged:
    if (centre_cov) {
        spread = (adjust_spread){0.0, 0};
        evaluate(matches, count, rot, &lens_u, &lay, huber_px, jtj, jtr, &spread);
        if (spread.count > n)
            centre_covariance(jtj, &lay, spread.sum_sq / (spread.count - n), centre_cov);
    }
    /* Keep the caller's bounds: only the solved values change. */
    for (int p = 0; p < LENS_PARAMS; p++)
        *lens_field(lens, p) = *lens_field(&lens_u, p);
done:
    free(jtj), free(jtr), free(a), free(step), free(rot_try), free(lay.view_param);
    return iterations;
}
