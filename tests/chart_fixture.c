/* SPDX-License-Identifier: BSD-3-Clause */
/* Synthetic chart photos: a white brick wall, coloured squares, a
 * ColorChecker (see chart_fixture.h). */
#include "chart_fixture.h"
#include "testing.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "setlight/render.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

void chart_fixture_init(chart_fixture *f)
{
    memset(f, 0, sizeof(*f));
    f->width = 640;
    f->height = 480;
    f->exposure = 0.8;
    f->light[0] = 1.0, f->light[1] = 0.95, f->light[2] = 0.85;
    f->center[0] = 320, f->center[1] = 240;
    f->pitch = 40;
    for (int p = 0; p < 24; p++)
        f->order[p] = p;
    f->seed = 1;
}

/* A hash of integers to [0, 1). */
static double hash01(uint64_t a, uint64_t b, uint64_t seed)
{
    uint64_t h = a * 0x9E3779B97F4A7C15ull ^ (b + 0x632BE59BD9B4E019ull) * 0xC2B2AE3D27D4EB4Full ^ seed;
    h ^= h >> 31;
    h *= 0xD6E8FEB86659FD93ull;
    h ^= h >> 29;
    return (double)(h >> 11) / 9007199254740992.0;
}

/* Painted white brick in running bond: bricks 30 x 63 px (at 480 rows),
 * recessed mortar 2.4 px, each brick's paint up to 15% different, a 10%
 * grain on every pixel, the light falling off a little across the frame.
 * mcc takes this wall for a chart. */
static void wall(const chart_fixture *f, double x, double y, double rgb[3])
{
    double bh = f->height / 16.0, bw = 2.1 * bh, mortar = 0.08 * bh;
    double row = floor(y / bh), shift = fmod(row, 2.0) * 0.5 * bw;
    double col = floor((x + shift) / bw);
    double u = x + shift - col * bw, v = y - row * bh;
    bool in_mortar = u < mortar || v < mortar;
    double grain = 1 + 0.1 * (2 * hash01((uint64_t)(x * 2), (uint64_t)(y * 2), f->seed) - 1);
    double brick = 1 + 0.15 * (2 * hash01((uint64_t)(col + 1000), (uint64_t)(row + 1000), f->seed + 7) - 1);
    static const double paint[3] = {0.80, 0.79, 0.76}, mortar_rgb[3] = {0.46, 0.45, 0.43};
    double falloff = 1 - 0.15 * (x / f->width) * (y / f->height);
    for (int c = 0; c < 3; c++)
        rgb[c] = (in_mortar ? mortar_rgb[c] : paint[c] * brick) * grain * falloff;
}

/* Five sticky-note colours at places and sizes no chart has. */
static bool square(const chart_fixture *f, int i, double x, double y, double rgb[3])
{
    static const double spot[5][4] = {
        {0.18, 0.22, 0.07, 20}, {0.71, 0.30, 0.05, -12}, {0.40, 0.75, 0.10, 35},
        {0.83, 0.68, 0.06, 5},  {0.27, 0.60, 0.09, 0}};
    static const double colour[5][3] = {
        {0.60, 0.05, 0.05}, {0.05, 0.10, 0.55}, {0.10, 0.50, 0.08}, {0.80, 0.65, 0.03},
        {0.55, 0.08, 0.40}};
    double cx = spot[i][0] * f->width, cy = spot[i][1] * f->height, half = spot[i][2] * f->height / 2;
    double a = spot[i][3] * M_PI / 180, dx = x - cx, dy = y - cy;
    double u = cos(a) * dx + sin(a) * dy, v = -sin(a) * dx + cos(a) * dy;
    if (fabs(u) > half || fabs(v) > half)
        return false;
    memcpy(rgb, colour[i], 3 * sizeof(double));
    return true;
}

/* Board coordinates of a photo point: (column, row) with patch 1's centre
 * at (0, 0). */
static void to_board(const chart_fixture *f, double x, double y, double *u, double *v)
{
    double a = f->angle_deg * M_PI / 180, dx = x - f->center[0], dy = y - f->center[1];
    *u = (cos(a) * dx + sin(a) * dy) / f->pitch + 2.5;
    *v = (-sin(a) * dx + cos(a) * dy) / f->pitch + 1.5;
}

void chart_fixture_center(const chart_fixture *f, int p, double xy[2])
{
    double a = f->angle_deg * M_PI / 180, u = (p % 6 - 2.5) * f->pitch, v = (p / 6 - 1.5) * f->pitch;
    xy[0] = f->center[0] + cos(a) * u - sin(a) * v;
    xy[1] = f->center[1] + sin(a) * u + cos(a) * v;
}

static void scene(const chart_fixture *f, double x, double y, double rgb[3])
{
    if (f->chart) {
        double u, v;
        to_board(f, x, y, &u, &v);
        /* Cells 2.5 wide at pitch 2.75 (mcc's model) on a black board
         * reaching 0.6 pitch past the outer patches. */
        if (u > -1.1 && u < 6.1 && v > -1.1 && v < 4.1) {
            double cu = floor(u + 0.5), cv = floor(v + 0.5), half = 0.5 * 2.5 / 2.75;
            bool in = cu >= 0 && cu < 6 && cv >= 0 && cv < 4 && fabs(u - cu) < half &&
                      fabs(v - cv) < half;
            for (int c = 0; c < 3; c++)
                rgb[c] = in ? SL_COLORCHECKER_LINEAR[f->order[(int)(cv * 6 + cu)]][c] : 0.03;
            return;
        }
    }
    for (int i = 0; i < f->squares && i < 5; i++)
        if (square(f, i, x, y, rgb))
            return;
    wall(f, x, y, rgb);
}

sl_result chart_fixture_render(const chart_fixture *f, sl_image *img, sl_error *err)
{
    sl_result r = sl_image_alloc(img, f->width, f->height, 3, err);
    if (r)
        return r;
    for (int y = 0; y < f->height; y++)
        for (int x = 0; x < f->width; x++) {
            double sum[3] = {0, 0, 0};
            for (int s = 0; s < 9; s++) {
                double rgb[3];
                scene(f, x + (s % 3 + 0.5) / 3, y + (s / 3 + 0.5) / 3, rgb);
                for (int c = 0; c < 3; c++)
                    sum[c] += rgb[c];
            }
            float *p = sl_image_pixel(img, x, y);
            for (int c = 0; c < 3; c++)
                p[c] = (float)fmin(sum[c] / 9 * f->exposure * f->light[c], 1.0);
        }
    return SL_OK;
}

bool chart_fixture_kind(chart_fixture *f, const char *kind)
{
    chart_fixture_init(f);
    if (!strcmp(kind, "chartsquares")) {
        f->squares = 5;
    } else if (!strcmp(kind, "chartshuffled")) {
        f->chart = true;
        /* Every patch elsewhere: the chart's colours, not its layout. */
        static const int shuffled[24] = {16, 3, 22, 9, 18, 0, 13, 20, 6, 11, 1, 23,
                                         4, 19, 8, 15, 2, 21, 10, 7, 14, 5, 17, 12};
        memcpy(f->order, shuffled, sizeof(shuffled));
    } else if (!strcmp(kind, "chartok")) {
        f->chart = true;
    } else if (!strcmp(kind, "charttiny")) {
        f->chart = true;
        f->pitch = 6;
    } else if (!strcmp(kind, "chartcut")) {
        f->chart = true;
        f->center[0] = 590; /* columns 5 and 6 past the right edge */
    } else if (!strcmp(kind, "chartclipped")) {
        f->chart = true;
        f->exposure *= pow(2, 1.6);
    } else if (strcmp(kind, "chartwall") != 0) {
        return false;
    }
    return true;
}

int chart_fixture_main(const char *kind, const char *out)
{
    chart_fixture f;
    if (!chart_fixture_kind(&f, kind)) {
        fprintf(stderr, "make_fixture: unknown chart kind %s\n", kind);
        return 2;
    }
    sl_image img = {0};
    sl_meta meta;
    sl_error err;
    sl_meta_init(&meta);
    sl_result r = chart_fixture_render(&f, &img, &err);
    const char *dot = strrchr(out, '.');
    return sl_test_fixture_write(out, &img, &meta, dot && !strcmp(dot, ".jpg"), r, &err);
}
