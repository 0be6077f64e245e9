/* SPDX-License-Identifier: BSD-3-Clause */
/* Synthetic chrome-ball photos by exact ray tracing (see ball_fixture.h). */
#include "ball_fixture.h"
#include "testing.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static const double source_dir[BALL_FIXTURE_SOURCES][3] = {
    {0.35, 0.55, -0.75}, /* in front of the ball, up and to the camera's left */
    {0.95, 0.25, 0.10},  /* to the side */
    {-0.55, 0.35, 0.55}, /* behind the ball's equator, seen near the rim */
};
static const double source_radius_deg[BALL_FIXTURE_SOURCES] = {3.0, 2.5, 3.0};
static const double source_rgb[BALL_FIXTURE_SOURCES][3] = {
    {120, 110, 100}, {60, 70, 90}, {80, 80, 80}};

void ball_fixture_source(int i, double dir[3], double *radius)
{
    const double *s = source_dir[i];
    double n = sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
    for (int k = 0; k < 3; k++)
        dir[k] = s[k] / n;
    *radius = source_radius_deg[i] * M_PI / 180.0;
}

void ball_fixture_env(const double dir[3], double rgb[3])
{
    double y = dir[1], lon = atan2(dir[0], dir[2]);
    double sky[3] = {0.25 + 0.3 * y, 0.35 + 0.35 * y, 0.55 + 0.45 * y};
    double m = 1.0 + 0.15 * sin(3.0 * lon) * (1.0 - fabs(y));
    double g = 1.0 + 0.25 * sin(4.0 * lon + 2.0 * y);
    double ground[3] = {0.30 * g, 0.26 * g, 0.20 * g};
    double t = y / 0.1 + 0.5; /* blend across the horizon */
    t = t < 0.0 ? 0.0 : (t > 1.0 ? 1.0 : t);
    t = t * t * (3.0 - 2.0 * t);
    for (int k = 0; k < 3; k++)
        rgb[k] = t * sky[k] * m + (1.0 - t) * ground[k];
    for (int i = 0; i < BALL_FIXTURE_SOURCES; i++) {
        double s[3], rad;
        ball_fixture_source(i, s, &rad);
        if (dir[0] * s[0] + dir[1] * s[1] + dir[2] * s[2] > cos(rad))
            for (int k = 0; k < 3; k++)
                rgb[k] += source_rgb[i][k];
    }
}

static void env_lookup(const ball_fixture *f, const double dir[3], double rgb[3])
{
    if (!f->env) {
        ball_fixture_env(dir, rgb);
        return;
    }
    double u, v;
    float px[4];
    sl_dir_to_latlong(dir, &u, &v);
    sl_latlong_lookup(f->env, u, v, px);
    for (int k = 0; k < 3; k++)
        rgb[k] = px[k];
}

void ball_fixture_init(ball_fixture *f, int width, int height)
{
    memset(f, 0, sizeof *f);
    f->width = width;
    f->height = height;
    f->ball_count = 1;
    f->balls[0].px = 0.5 * width;
    f->balls[0].py = 0.5 * height;
    f->balls[0].r = 0.4 * (width < height ? width : height);
    f->balls[0].distance = 10.0;
    sl_reflectance_constant(&f->reflectance, 1.0, 1.0, 1.0);
    f->ss = 4;
    f->clutter = true;
}

static void ball_centre(const ball_fixture *f, int i, double c[3])
{
    const ball_fixture_ball *b = &f->balls[i];
    double d[3] = {(0.5 * f->width - b->px) / f->focal_px, (0.5 * f->height - b->py) / f->focal_px,
                   1.0};
    double n = sqrt(d[0] * d[0] + d[1] * d[1] + 1.0);
    for (int k = 0; k < 3; k++)
        c[k] = b->distance * d[k] / n;
}

bool ball_fixture_trace(const ball_fixture *f, int i, double x, double y, double dir[3],
                        double *cos_incidence)
{
    double w[3], cosi;
    if (!f->perspective) {
        const ball_fixture_ball *b = &f->balls[i];
        double px = (b->px - x) / b->r, py = (b->py - y) / b->r, r2 = px * px + py * py;
        if (r2 > 1.0)
            return false;
        double nz = -sqrt(1.0 - r2);
        /* view (0, 0, 1) reflected about n = (px, py, nz) */
        w[0] = -2.0 * nz * px;
        w[1] = -2.0 * nz * py;
        w[2] = 1.0 - 2.0 * nz * nz;
        cosi = -nz;
    } else {
        double c[3], d[3] = {(0.5 * f->width - x) / f->focal_px,
                             (0.5 * f->height - y) / f->focal_px, 1.0};
        double n = sqrt(d[0] * d[0] + d[1] * d[1] + 1.0);
        for (int k = 0; k < 3; k++)
            d[k] /= n;
        ball_centre(f, i, c);
        double dc = d[0] * c[0] + d[1] * c[1] + d[2] * c[2];
        double cc = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
        double disc = dc * dc - cc + 1.0;
        if (disc < 0.0)
            return false;
        double t = dc - sqrt(disc), nn[3];
        for (int k = 0; k < 3; k++)
            nn[k] = t * d[k] - c[k];
        double dn = d[0] * nn[0] + d[1] * nn[1] + d[2] * nn[2];
        for (int k = 0; k < 3; k++)
            w[k] = d[k] - 2.0 * dn * nn[k];
        cosi = -dn;
    }
    double rot[3][3];
    sl_rotation_euler(f->azimuth_deg, -f->elevation_deg, f->roll_deg, rot);
    for (int k = 0; k < 3; k++)
        dir[k] = rot[k][0] * w[0] + rot[k][1] * w[1] + rot[k][2] * w[2];
    double n = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    for (int k = 0; k < 3; k++)
        dir[k] /= n;
    if (cos_incidence)
        *cos_incidence = cosi;
    return true;
}

static double hash01(uint32_t a, uint32_t b)
{
    uint32_t h = a * 0x9E3779B1u ^ (b + 0x7F4A7C15u) * 0x85EBCA77u;
    h ^= h >> 15;
    h *= 0x2C1B3C6Du;
    h ^= h >> 12;
    h *= 0x297A2D39u;
    h ^= h >> 15;
    return (h & 0xFFFFFF) / 16777216.0;
}

/* Blocks of grey and colour (23 x 17 px), diagonal stripes and a few tiny
 * hot spots. */
static void background(const ball_fixture *f, double x, double y, double rgb[3])
{
    if (!f->clutter) {
        rgb[0] = rgb[1] = rgb[2] = 0.05; /* a dark backdrop */
        return;
    }
    int bx = (int)floor(x / 23.0), by = (int)floor(y / 17.0);
    double base = 0.08 + 0.4 * hash01((uint32_t)bx, (uint32_t)by);
    double stripe = fmod(x + 0.6 * y, 61.0) < 4.0 ? 0.6 : 1.0;
    for (int k = 0; k < 3; k++)
        rgb[k] = base * stripe * (0.7 + 0.6 * hash01((uint32_t)(bx + 31 * k), (uint32_t)by + 7));
    if (hash01((uint32_t)bx + 1000, (uint32_t)by) > 0.8) {
        double dx = x - (bx + 0.5) * 23.0, dy = y - (by + 0.5) * 17.0;
        if (dx * dx + dy * dy < 1.5 * 1.5)
            rgb[0] = rgb[1] = rgb[2] = 30.0;
    }
}

/* A dial: white face, a dark bezel, twelve tick marks and two hands. */
static double dial(const ball_thing *t, double dx, double dy)
{
    double rho = hypot(dx, dy) / t->r, a = atan2(dy, dx);
    if (rho > 0.92)
        return 0.03;
    double tick = fmod(a / (2.0 * M_PI) * 12.0 + 12.5, 1.0) - 0.5; /* turns from a tick */
    if (rho > 0.78 && fabs(tick) * 2.0 * M_PI / 12.0 * rho * t->r < 0.02 * t->r)
        return 0.03;
    const double hands[2][2] = {{0.3, 0.75}, {1.9, 0.55}}; /* angle (rad), length */
    for (int h = 0; h < 2; h++) {
        double ux = cos(hands[h][0]), uy = sin(hands[h][0]);
        double along = (dx * ux + dy * uy) / t->r, across = fabs(-dx * uy + dy * ux) / t->r;
        if (along > 0.0 && along < hands[h][1] && across < 0.025)
            return 0.03;
    }
    return t->value;
}

/* The topmost round thing at (x, y), if any. */
static bool thing_at(const ball_fixture *f, double x, double y, double rgb[3])
{
    for (int i = f->thing_count - 1; i >= 0; i--) {
        const ball_thing *t = &f->things[i];
        double dx = x - t->x, dy = y - t->y, d = hypot(dx, dy);
        if (d > t->r || (t->kind == BALL_THING_RING && d < t->inner))
            continue;
        double v = t->kind == BALL_THING_DIAL ? dial(t, dx, dy) : t->value;
        rgb[0] = rgb[1] = rgb[2] = v;
        return true;
    }
    return false;
}

sl_result ball_fixture_render(const ball_fixture *f, sl_image *photo, sl_error *err)
{
    sl_result r = sl_image_alloc(photo, f->width, f->height, 3, err);
    if (r)
        return r;
    sl_ball_circle circles[2];
    for (int b = 0; b < f->ball_count; b++)
        ball_fixture_circle(f, b, &circles[b]);
    for (int y = 0; y < f->height; y++)
        for (int x = 0; x < f->width; x++) {
            /* Only pixels near a ball need supersampling (it is what is measured). */
            int ss = 1;
            for (int b = 0; b < f->ball_count; b++) {
                double d = hypot(x + 0.5 - circles[b].cx, y + 0.5 - circles[b].cy);
                if (f->ss_rim_only ? fabs(d - circles[b].r) < 2.0 : d < 1.1 * circles[b].r + 3.0)
                    ss = f->ss > 0 ? f->ss : 1;
            }
            for (int t = 0; t < f->thing_count; t++)
                if (fabs(hypot(x + 0.5 - f->things[t].x, y + 0.5 - f->things[t].y) -
                         f->things[t].r) < 2.0)
                    ss = f->ss > 0 ? f->ss : 1;
            double acc[3] = {0, 0, 0};
            for (int j = 0; j < ss; j++)
                for (int i = 0; i < ss; i++) {
                    double sx = x + (i + 0.5) / ss, sy = y + (j + 0.5) / ss, rgb[3], dir[3];
                    double cosi, best = 1e300;
                    bool hit = false;
                    for (int b = 0; b < f->ball_count; b++) {
                        double d[3];
                        if (!ball_fixture_trace(f, b, sx, sy, d, &cosi))
                            continue;
                        /* Nearest ball: the one whose centre is closer will do for
                         * balls that do not overlap in the image. */
                        double key = f->perspective ? f->balls[b].distance : (double)b;
                        if (key < best) {
                            best = key;
                            memcpy(dir, d, sizeof dir);
                            double refl[3];
                            env_lookup(f, dir, rgb);
                            sl_reflectance_eval(&f->reflectance, cosi, refl);
                            for (int k = 0; k < 3; k++)
                                rgb[k] *= refl[k];
                            hit = true;
                        }
                    }
                    if (!hit && !thing_at(f, sx, sy, rgb))
                        background(f, sx, sy, rgb);
                    for (int k = 0; k < 3; k++)
                        acc[k] += rgb[k];
                }
            float *p = sl_image_pixel(photo, x, y);
            for (int k = 0; k < 3; k++)
                p[k] = (float)(acc[k] / (ss * ss));
        }
    return SL_OK;
}

sl_result ball_fixture_truth(const ball_fixture *f, int width, int sub, sl_image *out,
                             sl_error *err)
{
    int h = width / 2;
    sl_result r = sl_image_alloc(out, width, h, 3, err);
    if (r)
        return r;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < width; x++) {
            double acc[3] = {0, 0, 0}, wsum = 0.0;
            for (int j = 0; j < sub; j++) {
                double v = (y + (j + 0.5) / sub) / h, wt = cos(M_PI * (0.5 - v));
                for (int i = 0; i < sub; i++) {
                    double u = (x + (i + 0.5) / sub) / width, d[3], rgb[3];
                    sl_latlong_to_dir(u, v, d);
                    env_lookup(f, d, rgb);
                    for (int k = 0; k < 3; k++)
                        acc[k] += wt * rgb[k];
                    wsum += wt;
                }
            }
            float *p = sl_image_pixel(out, x, y);
            for (int k = 0; k < 3; k++)
                p[k] = (float)(acc[k] / wsum);
        }
    return SL_OK;
}

/* Largest sign * a[i] of a smooth periodic sequence, refined by a parabola
 * through the best sample and its neighbours. */
static double extreme(const double *a, int n, double sign)
{
    int best = 0;
    for (int i = 1; i < n; i++)
        if (sign * a[i] > sign * a[best])
            best = i;
    double y0 = sign * a[(best + n - 1) % n], y1 = sign * a[best], y2 = sign * a[(best + 1) % n];
    double den = y2 - 2.0 * y1 + y0;
    return den < 0.0 ? y1 - (y2 - y0) * (y2 - y0) / (8.0 * den) : y1;
}

void ball_fixture_circle(const ball_fixture *f, int i, sl_ball_circle *c)
{
    memset(c, 0, sizeof *c);
    const ball_fixture_ball *b = &f->balls[i];
    if (!f->perspective) {
        c->cx = b->px;
        c->cy = b->py;
        c->r = b->r;
        return;
    }
    /* Silhouette: the tangent cone from the camera, projected. */
    double cc[3], axis[3], e1[3], e2[3];
    ball_centre(f, i, cc);
    for (int k = 0; k < 3; k++)
        axis[k] = cc[k] / b->distance;
    double a[3] = {1, 0, 0};
    e1[0] = axis[1] * a[2] - axis[2] * a[1];
    e1[1] = axis[2] * a[0] - axis[0] * a[2];
    e1[2] = axis[0] * a[1] - axis[1] * a[0];
    double n = sqrt(e1[0] * e1[0] + e1[1] * e1[1] + e1[2] * e1[2]);
    for (int k = 0; k < 3; k++)
        e1[k] /= n;
    e2[0] = axis[1] * e1[2] - axis[2] * e1[1];
    e2[1] = axis[2] * e1[0] - axis[0] * e1[2];
    e2[2] = axis[0] * e1[1] - axis[1] * e1[0];
    double alpha = asin(1.0 / b->distance), ppx = 0.5 * f->width, ppy = 0.5 * f->height;
    double ux = b->px - ppx, uy = b->py - ppy, ul = hypot(ux, uy);
    if (ul > 0.0) {
        ux /= ul;
        uy /= ul;
    } else {
        ux = 1.0;
        uy = 0.0;
    }
    enum { N = 3600 };
    double along[N], across[N];
    for (int s = 0; s < N; s++) {
        double t = 2.0 * M_PI * s / N, d[3];
        for (int k = 0; k < 3; k++)
            d[k] = cos(alpha) * axis[k] + sin(alpha) * (cos(t) * e1[k] + sin(t) * e2[k]);
        double x = -f->focal_px * d[0] / d[2], y = -f->focal_px * d[1] / d[2];
        along[s] = x * ux + y * uy;
        across[s] = -x * uy + y * ux;
    }
    double hi = extreme(along, N, 1.0), lo = -extreme(along, N, -1.0);
    double perp = extreme(across, N, 1.0);
    c->cx = ppx + 0.5 * (lo + hi) * ux;
    c->cy = ppy + 0.5 * (lo + hi) * uy;
    c->r = 0.5 * (0.5 * (hi - lo) + perp);
}

sl_result ball_fixture_fisheye(int width, int height, double radius, sl_image *photo,
                               sl_error *err)
{
    sl_result r = sl_image_alloc(photo, width, height, 3, err);
    if (r)
        return r;
    for (int y = 0; y < height; y++)
        for (int x = 0; x < width; x++) {
            float *p = sl_image_pixel(photo, x, y);
            double acc[3] = {0, 0, 0};
            for (int j = 0; j < 2; j++)
                for (int i = 0; i < 2; i++) {
                    double dx = (x + 0.25 + 0.5 * i - 0.5 * width) / radius;
                    double dy = (0.5 * height - y - 0.25 - 0.5 * j) / radius;
                    double rho = hypot(dx, dy), rgb[3] = {0, 0, 0};
                    if (rho < 1.0) {
                        /* equisolid: rho = sin(theta / 2) / sin(45 deg) */
                        double theta = 2.0 * asin(rho * sin(M_PI / 4.0));
                        double s = rho > 0.0 ? sin(theta) / rho : 0.0;
                        double dir[3] = {-dx * s, dy * s, cos(theta)};
                        ball_fixture_env(dir, rgb);
                        for (int k = 0; k < 3; k++)
                            rgb[k] *= 1.0 - 0.4 * rho * rho;
                    }
                    for (int k = 0; k < 3; k++)
                        acc[k] += 0.25 * rgb[k];
                }
            double noise = 0.002 * (1.0 + hash01((uint32_t)x, (uint32_t)y));
            for (int k = 0; k < 3; k++)
                p[k] = (float)(acc[k] + noise);
        }
    return SL_OK;
}

int ball_fixture_main(const char *kind, const char *out)
{
    ball_fixture f;
    ball_fixture_init(&f, 200, 160);
    f.ss = 3;
    f.perspective = true;
    f.focal_px = 180; /* --focal-mm 18 --sensor-mm 20 */
    f.balls[0].distance = 4.0;
    f.balls[0].px = 104;
    f.balls[0].py = 86;
    sl_reflectance_chrome(&f.reflectance);
    if (!strcmp(kind, "ballnone")) {
        f.ball_count = 0;
    } else if (!strcmp(kind, "balltwo")) {
        f.ball_count = 2;
        f.balls[0].px = 52;
        f.balls[0].distance = 5.0;
        f.balls[1] = f.balls[0];
        f.balls[1].px = 150;
    } else if (!strcmp(kind, "ballclip")) {
        f.balls[0].px = 160; /* 6.5 px cut off on the right */
    } else if (!strcmp(kind, "ballfill")) {
        ball_fixture_init(&f, 256, 256); /* a tight crop: the outline touches all four sides */
        f.ss = 3;
        f.ss_rim_only = true;
        f.balls[0].px = f.balls[0].py = f.balls[0].r = 128;
        sl_reflectance_chrome(&f.reflectance);
    } else if (!strcmp(kind, "ball90")) {
        f.azimuth_deg = 90; /* the same ball from a quarter turn around it */
        f.balls[0].px = 96;
    } else if (strcmp(kind, "ball") != 0 && strcmp(kind, "balljpg") != 0 &&
               strcmp(kind, "ballfisheye") != 0 && strcmp(kind, "ballfill") != 0) {
        fprintf(stderr, "make_fixture: unknown ball kind %s\n", kind);
        return 2;
    }
    sl_image img = {0};
    sl_meta meta;
    sl_error err;
    sl_meta_init(&meta);
    sl_result r = !strcmp(kind, "ballfisheye") ? ball_fixture_fisheye(300, 200, 90, &img, &err)
                                               : ball_fixture_render(&f, &img, &err);
    return sl_test_fixture_write(out, &img, &meta, !strcmp(kind, "balljpg"), r, &err);
}
