/* SPDX-License-Identifier: BSD-3-Clause */
/* The exact geometry of a chrome-ball photo: set direction <-> photo pixel
 * for an orthographic camera or a pinhole at a finite distance, with the
 * ball anywhere in the frame. Derivations are in docs/unwrap.md.
 *
 * View frame: the camera at (0, 0, -D), the unit ball at the origin. A
 * sphere point at angle theta from -Z reflects the camera ray into a
 * direction at angle phi(theta) from -Z in the same azimuth, so the inverse
 * is one monotone function of one variable: tabulated once by bisection and
 * interpolated with a cubic. */
#include "unwrap_private.h"

#include <math.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define TABLE_N 1024

static void mat_t_vec(const double m[3][3], const double v[3], double out[3])
{
    for (int i = 0; i < 3; i++)
        out[i] = m[0][i] * v[0] + m[1][i] * v[1] + m[2][i] * v[2];
}

/* Angle from -Z of the reflection of the camera ray at sphere angle theta. */
static double reflect_angle(double distance, double theta)
{
    if (distance == 0.0)
        return 2.0 * theta;
    double s = sin(theta), c = cos(theta);
    double dx = s, dz = distance - c;
    double len = sqrt(dx * dx + dz * dz);
    double vx = dx / len, vz = dz / len;
    double vn = vx * s - vz * c;
    double wx = vx - 2.0 * vn * s, wz = vz + 2.0 * vn * c;
    return atan2(wx, -wz);
}

/* Catmull-Rom in the table: error ~h^4, about 1e-10 rad with 1024 steps. */
static double theta_for_phi(const sl_ball_view *v, double phi)
{
    if (v->distance == 0.0)
        return 0.5 * phi;
    double t = phi / v->phi_max * TABLE_N;
    int i = (int)t;
    if (i >= TABLE_N)
        i = TABLE_N - 1;
    if (i < 0)
        i = 0;
    double f = t - i;
    const double *y = v->theta_table;
    double y0 = i > 0 ? y[i - 1] : 2.0 * y[0] - y[1];
    double y3 = i + 2 <= TABLE_N ? y[i + 2] : 2.0 * y[TABLE_N] - y[TABLE_N - 1];
    double y1 = y[i], y2 = y[i + 1];
    return y1 + 0.5 * f *
                    (y2 - y0 +
                     f * (2.0 * y0 - 5.0 * y1 + 4.0 * y2 - y3 + f * (3.0 * (y1 - y2) + y3 - y0)));
}

void ball_view_map(const sl_ball_view *v, const double dir[3], ball_hit *hit)
{
    double wc[3], wv[3];
    mat_t_vec(v->cam_to_world, dir, wc);
    mat_t_vec(v->view_to_cam, wc, wv);
    ball_view_map_local(v, wv, hit);
}

void ball_view_map_local(const sl_ball_view *v, const double wv[3], ball_hit *hit)
{
    double rho = sqrt(wv[0] * wv[0] + wv[1] * wv[1]);
    double ex = 1.0, ey = 0.0;
    if (rho > 0.0) {
        ex = wv[0] / rho;
        ey = wv[1] / rho;
    }
    if (v->distance == 0.0) {
        /* theta = phi / 2: half-angle formulas without cancellation (rho^2
         * = n^2 - z^2), no trigonometry. The orthographic view frame is the
         * camera frame. */
        double z = -wv[2], n = sqrt(rho * rho + z * z), r2 = rho * rho;
        double one_minus = z > 0.0 ? r2 / (n * (n + z)) : (n - z) / n;
        double one_plus = z < 0.0 ? r2 / (n * (n - z)) : (n + z) / n;
        hit->blind = false;
        double st = sqrt(0.5 * one_minus), ct = sqrt(0.5 * one_plus);
        hit->x = v->cx - v->r * st * ex;
        hit->y = v->cy - v->r * st * ey;
        hit->cos_incidence = ct;
        return;
    }
    double phi = atan2(rho, -wv[2]);
    hit->blind = phi > v->phi_max;
    double theta = theta_for_phi(v, hit->blind ? v->phi_max : phi);
    double st = sin(theta), ct = cos(theta);
    double p[3] = {st * ex, st * ey, -ct};
    double d[3] = {p[0], p[1], p[2] + v->distance}, dc[3];
    double len = sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    double cosi = -(d[0] * p[0] + d[1] * p[1] + d[2] * p[2]) / len;
    sl_mat3_apply(v->view_to_cam, d, dc);
    double ppx = 0.5 * v->width, ppy = 0.5 * v->height;
    hit->x = ppx - v->focal_px * dc[0] / dc[2];
    hit->y = ppy - v->focal_px * dc[1] / dc[2];
    hit->cos_incidence = cosi > 0.0 ? cosi : 0.0;
}

bool sl_ball_view_dir_to_pixel(const sl_ball_view *view, const double dir[3], double *x,
                               double *y, double *cos_incidence)
{
    ball_hit h;
    ball_view_map(view, dir, &h);
    *x = h.x;
    *y = h.y;
    if (cos_incidence)
        *cos_incidence = h.cos_incidence;
    return !h.blind;
}

bool sl_ball_view_pixel_to_dir(const sl_ball_view *v, double x, double y, double dir[3],
                               double *cos_incidence)
{
    double o[3], d[3];
    if (v->distance == 0.0) {
        double px = (v->cx - x) / v->r, py = (v->cy - y) / v->r;
        double r2 = px * px + py * py;
        if (r2 > 1.0)
            return false;
        o[0] = px;
        o[1] = py;
        o[2] = -sqrt(1.0 - r2);
        d[0] = d[1] = 0.0; /* the orthographic view frame is the camera frame */
        d[2] = 1.0;
    } else {
        double ppx = 0.5 * v->width, ppy = 0.5 * v->height;
        double dc[3] = {(ppx - x) / v->focal_px, (ppy - y) / v->focal_px, 1.0};
        double n = sqrt(dc[0] * dc[0] + dc[1] * dc[1] + 1.0);
        for (int i = 0; i < 3; i++)
            dc[i] /= n;
        mat_t_vec(v->view_to_cam, dc, d);
        /* Ray from (0, 0, -D) meets the unit sphere at the nearer root. */
        double b = -v->distance * d[2];
        double c = v->distance * v->distance - 1.0;
        double disc = b * b - c;
        if (disc < 0.0)
            return false;
        double t = -b - sqrt(disc);
        o[0] = t * d[0];
        o[1] = t * d[1];
        o[2] = -v->distance + t * d[2];
    }
    /* o is the sphere point (= normal), d the unit view ray, both in the view frame. */
    double dn = d[0] * o[0] + d[1] * o[1] + d[2] * o[2];
    double wv[3] = {d[0] - 2.0 * dn * o[0], d[1] - 2.0 * dn * o[1], d[2] - 2.0 * dn * o[2]};
    double wc[3];
    sl_mat3_apply(v->view_to_cam, wv, wc);
    sl_mat3_apply(v->cam_to_world, wc, dir);
    if (cos_incidence)
        *cos_incidence = -dn;
    return true;
}

static void tangent_basis(const double d[3], double t1[3], double t2[3])
{
    double a[3] = {0, 0, 0};
    a[fabs(d[0]) < 0.6 ? 0 : (fabs(d[1]) < 0.6 ? 1 : 2)] = 1.0;
    t1[0] = d[1] * a[2] - d[2] * a[1];
    t1[1] = d[2] * a[0] - d[0] * a[2];
    t1[2] = d[0] * a[1] - d[1] * a[0];
    double n = sqrt(t1[0] * t1[0] + t1[1] * t1[1] + t1[2] * t1[2]);
    for (int i = 0; i < 3; i++)
        t1[i] /= n;
    t2[0] = d[1] * t1[2] - d[2] * t1[1];
    t2[1] = d[2] * t1[0] - d[0] * t1[2];
    t2[2] = d[0] * t1[1] - d[1] * t1[0];
}

double sl_ball_view_resolution(const sl_ball_view *v, const double dir[3])
{
    double n = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    double d[3] = {dir[0] / n, dir[1] / n, dir[2] / n}, t[2][3];
    tangent_basis(d, t[0], t[1]);
    ball_hit h;
    ball_view_map(v, d, &h);
    if (h.blind)
        return 0.0;
    const double step = 1e-5;
    double j[2][2];
    for (int k = 0; k < 2; k++) {
        double a[3], b[3];
        ball_hit ha, hb;
        for (int i = 0; i < 3; i++) {
            a[i] = d[i] + step * t[k][i];
            b[i] = d[i] - step * t[k][i];
        }
        ball_view_map(v, a, &ha);
        ball_view_map(v, b, &hb);
        j[0][k] = (ha.x - hb.x) / (2.0 * step);
        j[1][k] = (ha.y - hb.y) / (2.0 * step);
    }
    return smaller_singular_value(j);
}

/* Projected ellipse of a ball of angular radius alpha whose centre is beta
 * off the optical axis: centre offset and the two semi-axes, in focal units. */
static void ellipse_of(double beta, double alpha, double *centre, double *semi_mean)
{
    double a2 = cos(beta) * cos(beta) - sin(alpha) * sin(alpha);
    *centre = sin(beta) * cos(beta) / a2;
    double major = sin(alpha) * cos(alpha) / a2;
    double minor = sin(alpha) / sqrt(a2);
    *semi_mean = 0.5 * (major + minor);
}

/* Finds beta and alpha whose ellipse has the measured centre offset and mean
 * semi-axis (what a circle fit of that ellipse returns). alpha_fixed > 0
 * keeps alpha. */
static bool solve_ellipse(double centre, double radius, double alpha_fixed, double *beta,
                          double *alpha)
{
    double b = atan(centre), a = alpha_fixed > 0.0 ? alpha_fixed : atan(radius);
    for (int it = 0; it < 50; it++) {
        double c0, r0, c1, r1, c2, r2;
        const double h = 1e-7;
        ellipse_of(b, a, &c0, &r0);
        double f0 = c0 - centre, g0 = alpha_fixed > 0.0 ? 0.0 : r0 - radius;
        if (fabs(f0) < 1e-14 && fabs(g0) < 1e-14)
            break;
        ellipse_of(b + h, a, &c1, &r1);
        ellipse_of(b, a + h, &c2, &r2);
        double j00 = (c1 - c0) / h, j01 = (c2 - c0) / h;
        double j10 = (r1 - r0) / h, j11 = (r2 - r0) / h;
        double db, da;
        if (alpha_fixed > 0.0) {
            db = -f0 / j00;
            da = 0.0;
        } else {
            double det = j00 * j11 - j01 * j10;
            if (det == 0.0)
                return false;
            db = -(j11 * f0 - j01 * g0) / det;
            da = -(-j10 * f0 + j00 * g0) / det;
        }
        b += db;
        a += da;
        if (!(a > 0.0 && a < 0.5 * M_PI && b >= -1e-9 && b < 0.5 * M_PI))
            return false;
    }
    *beta = fabs(b);
    *alpha = a;
    return cos(*beta) * cos(*beta) > sin(a) * sin(a);
}

/* Minimal rotation taking +Z to unit vector b. */
static void rotation_from_z(const double b[3], double m[3][3])
{
    double s = hypot(b[0], b[1]), c = b[2];
    memset(m, 0, 9 * sizeof(double));
    if (s < 1e-15) {
        m[0][0] = m[1][1] = m[2][2] = 1.0;
        return;
    }
    double kx = -b[1] / s, ky = b[0] / s; /* axis z x b, normalised */
    double t = 1.0 - c;
    m[0][0] = c + kx * kx * t;
    m[0][1] = kx * ky * t;
    m[0][2] = ky * s;
    m[1][0] = kx * ky * t;
    m[1][1] = c + ky * ky * t;
    m[1][2] = -kx * s;
    m[2][0] = -ky * s;
    m[2][1] = kx * s;
    m[2][2] = c;
}

sl_result sl_ball_view_init(sl_ball_view *v, int width, int height, const sl_ball_circle *c,
                            const sl_ball_geometry *g, sl_error *err)
{
    memset(v, 0, sizeof *v);
    if (width <= 0 || height <= 0)
        return sl_error_set(err, SL_ERR_USAGE, "ball photo has no pixels");
    if (!(isfinite(c->cx) && isfinite(c->cy) && isfinite(c->r) && c->r >= 2.0))
        return sl_error_set(err, SL_ERR_USAGE, "ball circle radius must be at least 2 px");
    if (c->cx - c->r < 0.0 || c->cy - c->r < 0.0 || c->cx + c->r > width ||
        c->cy + c->r > height)
        return sl_error_set(err, SL_ERR_USAGE,
                            "ball circle %g,%g radius %g is not inside the %dx%d image", c->cx,
                            c->cy, c->r, width, height);
    v->camera = g->camera;
    v->width = width;
    v->height = height;
    v->cx = c->cx;
    v->cy = c->cy;
    v->r = c->r;
    sl_rotation_euler(g->azimuth_deg, -g->elevation_deg, g->roll_deg, v->cam_to_world);
    v->view_to_cam[0][0] = v->view_to_cam[1][1] = v->view_to_cam[2][2] = 1.0;
    v->phi_max = M_PI;

    if (g->camera == SL_BALL_PERSPECTIVE) {
        if (!(g->focal_px > 0.0) && !(g->distance > 0.0))
            return sl_error_set(err, SL_ERR_USAGE,
                                "the perspective ball model needs the focal length (or field of "
                                "view) or the camera distance");
        if (g->distance > 0.0 && !(g->distance > 1.0 + 1e-9))
            return sl_error_set(err, SL_ERR_USAGE,
                                "camera distance %g ball radii puts the camera inside the ball",
                                g->distance);
        double dx = c->cx - 0.5 * width, dy = c->cy - 0.5 * height;
        double off = hypot(dx, dy);
        double alpha = g->distance > 0.0 ? asin(1.0 / g->distance) : 0.0, beta = 0.0;
        if (g->focal_px > 0.0) {
            if (!solve_ellipse(off / g->focal_px, c->r / g->focal_px, alpha, &beta, &alpha))
                return sl_error_set(err, SL_ERR_USAGE,
                                    "ball circle %g,%g radius %g does not fit a %g px focal "
                                    "length (ball wider than the field of view?)",
                                    c->cx, c->cy, c->r, g->focal_px);
            v->focal_px = g->focal_px;
        } else {
            v->focal_px = c->r / tan(alpha);
        }
        v->distance = 1.0 / sin(alpha);
        v->ball_angle = alpha;
        v->off_axis = beta;
        v->phi_max = M_PI - alpha;
        double b[3] = {0.0, 0.0, 1.0};
        if (off > 0.0) {
            b[0] = -dx / off * sin(beta);
            b[1] = -dy / off * sin(beta);
            b[2] = cos(beta);
        }
        rotation_from_z(b, v->view_to_cam);
        double theta_max = acos(1.0 / v->distance);
        for (int i = 0; i <= TABLE_N; i++) {
            double phi = v->phi_max * i / TABLE_N, lo = 0.0, hi = theta_max;
            for (int it = 0; it < 60; it++) {
                double mid = 0.5 * (lo + hi);
                if (reflect_angle(v->distance, mid) < phi)
                    lo = mid;
                else
                    hi = mid;
            }
            v->theta_table[i] = 0.5 * (lo + hi);
        }
    }
    double back[3] = {0.0, 0.0, -1.0}, bc[3], bw[3];
    sl_mat3_apply(v->view_to_cam, back, bc);
    sl_mat3_apply(v->cam_to_world, bc, bw);
    v->centre_px_per_rad = sl_ball_view_resolution(v, bw);
    return SL_OK;
}
