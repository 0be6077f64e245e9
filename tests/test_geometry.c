/* SPDX-License-Identifier: BSD-3-Clause */
/* Lat-long orientation and solid angles, projection round trips, mirror-ball
 * orientation, cube faces, rotations and reprojection accuracy. */
#include "testing.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static uint64_t rng_state = SL_SPLITMIX64_INCREMENT;

/* splitmix64: fixed seed, same numbers everywhere. */
static double rng_uniform(void) { return sl_test_uniform(&rng_state); }

static void random_dir(double d[3])
{
    double z = 1.0 - 2.0 * rng_uniform(), phi = 2.0 * M_PI * rng_uniform();
    double s = sqrt(1.0 - z * z);
    d[0] = s * cos(phi);
    d[1] = s * sin(phi);
    d[2] = z;
}

static double dir_dist(const double a[3], const double b[3])
{
    return sqrt((a[0] - b[0]) * (a[0] - b[0]) + (a[1] - b[1]) * (a[1] - b[1]) +
                (a[2] - b[2]) * (a[2] - b[2]));
}

static void test_latlong_orientation(void)
{
    double d[3];
    int w = 1024, h = 512;
    /* The row through the equator has v = 0.5 only between rows; use u alone. */
    sl_latlong_to_dir(0.5, 0.5, d);
    CHECK_NEAR(d[2], 1.0, 1e-15);
    sl_latlong_to_dir(0.25, 0.5, d);
    CHECK_NEAR(d[0], 1.0, 1e-15);
    sl_latlong_to_dir(0.75, 0.5, d);
    CHECK_NEAR(d[0], -1.0, 1e-15);
    sl_latlong_to_dir(0.0, 0.5, d);
    CHECK_NEAR(d[2], -1.0, 1e-15);
    /* Texel centres: centre column x = w/2 is half a texel right of +Z. */
    sl_latlong_to_dir((w / 2 + 0.5) / w, (h / 2 + 0.5) / h, d);
    CHECK(d[2] > 0.9999);
    CHECK(d[0] < 0.0); /* right of centre turns toward -X */
    sl_latlong_to_dir((w / 4 + 0.5) / w, 0.5, d);
    CHECK(d[0] > 0.9999);
    sl_latlong_to_dir((3 * w / 4 + 0.5) / w, 0.5, d);
    CHECK(d[0] < -0.9999);
    sl_latlong_to_dir(0.5, 0.5 / h, d); /* top row */
    CHECK(d[1] > 0.99998);
    sl_latlong_to_dir(0.5, (h - 0.5) / h, d); /* bottom row */
    CHECK(d[1] < -0.99998);
    sl_latlong_to_dir(0.5 / w, 0.5, d); /* column 0: longitude just below +pi */
    CHECK(d[2] < -0.9999 && d[0] > 0.0);

    double worst = 0.0;
    for (int i = 0; i < 100000; i++) {
        double a[3], b[3], u, v;
        random_dir(a);
        sl_dir_to_latlong(a, &u, &v);
        CHECK_MSG(u >= 0.0 && u < 1.0 && v >= 0.0 && v <= 1.0, "uv %g %g", u, v);
        sl_latlong_to_dir(u, v, b);
        double e = dir_dist(a, b);
        worst = e > worst ? e : worst;
    }
    printf("  latlong dir->uv->dir max error %.3g\n", worst);
    CHECK(worst < 1e-12);
    CHECK(sl_is_latlong_shape(1024, 512));
    CHECK(!sl_is_latlong_shape(1000, 512));
    CHECK(!sl_is_latlong_shape(0, 0));
}

static void test_solid_angles(void)
{
    int sizes[][2] = {{8, 4}, {1024, 512}, {4096, 2048}, {10, 7}, {3, 1}};
    for (size_t s = 0; s < sizeof sizes / sizeof sizes[0]; s++) {
        int w = sizes[s][0], h = sizes[s][1];
        double sum = 0.0;
        for (int y = 0; y < h; y++)
            sum += w * sl_latlong_texel_solid_angle(y, w, h);
        printf("  %dx%d: sum of texel solid angles - 4 pi = %.3g\n", w, h, sum - 4 * M_PI);
        CHECK_NEAR(sum, 4.0 * M_PI, 1e-9);
    }
    /* Row 0 of an 8x4: the cap from 90 to 45 degrees over 1/8 of the longitude. */
    CHECK_NEAR(sl_latlong_texel_solid_angle(0, 8, 4), 2 * M_PI / 8 * (1 - sqrt(0.5)), 1e-15);
    CHECK(sl_latlong_texel_solid_angle(4, 8, 4) == 0.0);
}

static void test_latlong_lookup(void)
{
    sl_image img;
    CHECK_OK(sl_image_alloc(&img, 8, 4, 1, NULL), NULL);
    for (int y = 0; y < 4; y++)
        for (int x = 0; x < 8; x++)
            sl_image_pixel(&img, x, y)[0] = (float)(10 * y + x);
    float v;
    sl_latlong_lookup(&img, 3.5 / 8, 1.5 / 4, &v); /* texel centre */
    CHECK_NEAR(v, 13.0, 1e-6);
    sl_latlong_lookup(&img, 4.0 / 8, 1.5 / 4, &v); /* halfway between x 3 and 4 */
    CHECK_NEAR(v, 13.5, 1e-6);
    sl_latlong_lookup(&img, 0.0, 1.5 / 4, &v); /* wraps: half x 7, half x 0 */
    CHECK_NEAR(v, 13.5, 1e-6);
    sl_latlong_lookup(&img, 1.0, 2.0 / 4, &v); /* wrap and between rows 1 and 2 */
    CHECK_NEAR(v, 18.5, 1e-6);
    sl_latlong_lookup(&img, 0.5 / 8, 0.0, &v); /* pole clamps to row 0 */
    CHECK_NEAR(v, 0.0, 1e-6);
    sl_latlong_lookup(&img, 0.5 / 8, 1.0, &v);
    CHECK_NEAR(v, 30.0, 1e-6);
    sl_image_free(&img);
}

static void test_projection_names(void)
{
    for (int p = 0; p < SL_PROJ_COUNT; p++)
        CHECK(sl_projection_from_name(sl_projection_name((sl_projection)p)) == p);
    CHECK(sl_projection_from_name("fisheye") == -1);
    CHECK(sl_projection_from_name(NULL) == -1);
    int w, h;
    sl_projection_size(SL_PROJ_LATLONG, 1024, &w, &h);
    CHECK(w == 1024 && h == 512);
    sl_projection_size(SL_PROJ_MIRRORBALL, 1024, &w, &h);
    CHECK(w == 512 && h == 512);
    sl_projection_size(SL_PROJ_ANGULAR, 1024, &w, &h);
    CHECK(w == 512 && h == 512);
    sl_projection_size(SL_PROJ_CUBEMAP, 1024, &w, &h);
    CHECK(w == 256 && h == 1536);
}

static void test_projection_round_trips(void)
{
    for (int p = 0; p < SL_PROJ_COUNT; p++) {
        double worst_uv = 0.0, worst_dir = 0.0;
        int n = 0;
        for (int j = 0; j < 300; j++)
            for (int i = 0; i < 300; i++) {
                double u = (i + 0.5) / 300, v = (j + 0.5) / 300, d[3], u2, v2;
                if (!sl_projection_to_dir((sl_projection)p, u, v, d))
                    continue;
                n++;
                CHECK_NEAR(d[0] * d[0] + d[1] * d[1] + d[2] * d[2], 1.0, 1e-14);
                CHECK(sl_dir_to_projection((sl_projection)p, d, &u2, &v2));
                double e = fmax(fabs(u - u2), fabs(v - v2));
                worst_uv = e > worst_uv ? e : worst_uv;
            }
        for (int i = 0; i < 20000; i++) {
            double a[3], b[3], u, v;
            random_dir(a);
            CHECK(sl_dir_to_projection((sl_projection)p, a, &u, &v));
            CHECK(sl_projection_to_dir((sl_projection)p, u, v, b));
            double e = dir_dist(a, b);
            worst_dir = e > worst_dir ? e : worst_dir;
        }
        printf("  %s: %d valid grid points, uv round trip %.3g, dir round trip %.3g\n",
               sl_projection_name((sl_projection)p), n, worst_uv, worst_dir);
        CHECK(worst_uv < 1e-9);
        CHECK(worst_dir < 1e-9);
        if (p == SL_PROJ_MIRRORBALL || p == SL_PROJ_ANGULAR)
            CHECK(abs(n - (int)(M_PI / 4 * 90000)) < 400); /* the disc only */
        else
            CHECK(n == 90000);
    }
    double d[3];
    CHECK(!sl_projection_to_dir(SL_PROJ_MIRRORBALL, 0.02, 0.02, d)); /* corner */
    CHECK(!sl_projection_to_dir(SL_PROJ_LATLONG, 1.5, 0.5, d));
}

static void test_mirrorball_orientation(void)
{
    double d[3], u, v;
    CHECK(sl_projection_to_dir(SL_PROJ_MIRRORBALL, 0.5, 0.5, d)); /* centre reflects back */
    CHECK_NEAR(d[2], -1.0, 1e-15);
    CHECK(sl_projection_to_dir(SL_PROJ_MIRRORBALL, 1.0, 0.5, d)); /* rim reflects +Z */
    CHECK_NEAR(d[2], 1.0, 1e-15);
    CHECK(sl_projection_to_dir(SL_PROJ_MIRRORBALL, 0.5, 0.0, d));
    CHECK_NEAR(d[2], 1.0, 1e-15);
    /* Image right at px = sin 45 deg reflects sideways: world -X (the camera looks
     * along +Z with +Y up, so its right is -X). */
    CHECK(sl_projection_to_dir(SL_PROJ_MIRRORBALL, 0.5 * (1 + sqrt(0.5)), 0.5, d));
    CHECK_NEAR(d[0], -1.0, 1e-12);
    /* Top at py = sin 45 deg reflects +Y. */
    CHECK(sl_projection_to_dir(SL_PROJ_MIRRORBALL, 0.5, 0.5 * (1 - sqrt(0.5)), d));
    CHECK_NEAR(d[1], 1.0, 1e-12);
    double behind[3] = {0, 0, 1};
    CHECK(sl_dir_to_projection(SL_PROJ_MIRRORBALL, behind, &u, &v));
    CHECK_NEAR(hypot(2 * u - 1, 2 * v - 1), 1.0, 1e-15);
    double zero[3] = {0, 0, 0};
    CHECK(!sl_dir_to_projection(SL_PROJ_LATLONG, zero, &u, &v));
}

static void test_cubemap_faces(void)
{
    /* Face centres in OpenEXR's order +X -X +Y -Y +Z -Z, stacked vertically. */
    static const double axes[6][3] = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                      {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};
    for (int f = 0; f < 6; f++) {
        double d[3], u, v;
        CHECK(sl_projection_to_dir(SL_PROJ_CUBEMAP, 0.5, (f + 0.5) / 6, d));
        CHECK(dir_dist(d, axes[f]) < 1e-15);
        CHECK(sl_dir_to_projection(SL_PROJ_CUBEMAP, axes[f], &u, &v));
        CHECK_NEAR(u, 0.5, 1e-15);
        CHECK_NEAR(v, (f + 0.5) / 6, 1e-15);
    }
    /* Per-face orientation from ImfEnvmap.cpp: on +Z image right is -X and
     * up is +Y; on -Z right is +X; on +X right is +Z and up +Y; the top of
     * +Y is +Z and the top of -Y is -Z. */
    double d[3];
    sl_projection_to_dir(SL_PROJ_CUBEMAP, 0.9, 4.5 / 6, d);
    CHECK(d[0] < -0.5);
    sl_projection_to_dir(SL_PROJ_CUBEMAP, 0.5, 4.1 / 6, d);
    CHECK(d[1] > 0.5);
    sl_projection_to_dir(SL_PROJ_CUBEMAP, 0.9, 5.5 / 6, d);
    CHECK(d[0] > 0.5);
    sl_projection_to_dir(SL_PROJ_CUBEMAP, 0.9, 0.5 / 6, d);
    CHECK(d[2] > 0.5);
    sl_projection_to_dir(SL_PROJ_CUBEMAP, 0.5, 0.1 / 6, d);
    CHECK(d[1] > 0.5);
    sl_projection_to_dir(SL_PROJ_CUBEMAP, 0.5, 2.1 / 6, d);
    CHECK(d[2] > 0.5);
    sl_projection_to_dir(SL_PROJ_CUBEMAP, 0.5, 3.1 / 6, d);
    CHECK(d[2] < -0.5);
    /* Texel (0,0) of a 4-wide +X face, OpenEXR pixel (x=0, y=3) of that face
     * has pif = (0, 0) -> direction (1, -1, -1) in OpenEXR's corner-centred
     * grid; ours (texel centres) is the inner point (1, 1-1/4, -(1-1/4)). */
    sl_projection_to_dir(SL_PROJ_CUBEMAP, 0.5 / 4, 3.5 / 24, d);
    CHECK_NEAR(d[1] / d[0], -0.75, 1e-12);
    CHECK_NEAR(d[2] / d[0], -0.75, 1e-12);
}

static void test_rotations(void)
{
    double r[3][3], z[3] = {0, 0, 1};
    sl_rotation_y(90.0, r);
    double o[3];
    for (int i = 0; i < 3; i++)
        o[i] = r[i][0] * z[0] + r[i][1] * z[1] + r[i][2] * z[2];
    CHECK_NEAR(o[0], 1.0, 1e-15); /* +Z turns toward +X */
    CHECK_NEAR(o[2], 0.0, 1e-15);
    double angles[][3] = {{0, 0, 0}, {37, 0, 0}, {10, 20, 30}, {-170, 89, -45}, {400, -30, 5}};
    for (size_t k = 0; k < sizeof angles / sizeof angles[0]; k++) {
        sl_rotation_euler(angles[k][0], angles[k][1], angles[k][2], r);
        double worst = 0.0;
        for (int i = 0; i < 3; i++)
            for (int j = 0; j < 3; j++) {
                double dot = r[0][i] * r[0][j] + r[1][i] * r[1][j] + r[2][i] * r[2][j];
                worst = fmax(worst, fabs(dot - (i == j)));
            }
        double det = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1]) -
                     r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0]) +
                     r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        CHECK(worst < 1e-15);
        CHECK_NEAR(det, 1.0, 1e-15);
    }
    /* Euler order: R = Ry(yaw) Rx(pitch) Rz(roll); pitch 90 takes +Z to -Y. */
    sl_rotation_euler(90, 90, 0, r);
    CHECK_NEAR(r[1][2], -1.0, 1e-15);
    sl_rotation_euler(90, 0, 90, r); /* roll takes +X to +Y, yaw leaves Y */
    CHECK_NEAR(r[1][0], 1.0, 1e-15);
    sl_rotation_euler(90, 0, 0, r);
    double ry[3][3];
    sl_rotation_y(90, ry);
    CHECK(memcmp(r, ry, sizeof r) == 0);
}

/* A smooth positive function of direction (spherical harmonics up to l = 2). */
static double smooth(const double d[3], int ch)
{
    return 1.0 + 0.4 * d[0] + 0.3 * d[1] * (ch + 1) - 0.2 * d[2] + 0.25 * d[0] * d[1] +
           0.15 * (3 * d[2] * d[2] - 1) * 0.5;
}

static void fill_smooth_latlong(sl_image *img)
{
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / img->width, (y + 0.5) / img->height, d);
            for (int c = 0; c < img->channels; c++)
                sl_image_pixel(img, x, y)[c] = (float)smooth(d, c);
        }
}

static void test_reproject_round_trip(void)
{
    sl_error err;
    sl_image src, cst;
    CHECK_OK(sl_image_alloc(&src, 256, 128, 3, &err), &err);
    CHECK_OK(sl_image_alloc(&cst, 256, 128, 3, &err), &err);
    fill_smooth_latlong(&src);
    sl_image_fill(&cst, 2.5f);
    /* Bounds per projection: bilinear + box-filter blur of an l <= 2 function. */
    static const double max_bound[SL_PROJ_COUNT] = {1e-6, 0.01, 0.006, 0.006};
    for (int p = 0; p < SL_PROJ_COUNT; p++) {
        sl_image mid, back, cmid, cback;
        CHECK_OK(sl_reproject(&src, SL_PROJ_LATLONG, (sl_projection)p, 256, NULL, &mid, &err),
                 &err);
        CHECK_OK(sl_reproject(&mid, (sl_projection)p, SL_PROJ_LATLONG, 256, NULL, &back, &err),
                 &err);
        CHECK_OK(sl_reproject(&cst, SL_PROJ_LATLONG, (sl_projection)p, 256, NULL, &cmid, &err),
                 &err);
        CHECK_OK(sl_reproject(&cmid, (sl_projection)p, SL_PROJ_LATLONG, 256, NULL, &cback,
                              &err),
                 &err);
        if (!back.data || !cback.data)
            continue;
        double worst = 0.0, sum = 0.0, cworst = 0.0;
        int n = 0;
        for (int y = 0; y < 128; y++)
            for (int x = 0; x < 256; x++) {
                double d[3];
                sl_latlong_to_dir((x + 0.5) / 256, (y + 0.5) / 128, d);
                for (int c = 0; c < 3; c++)
                    cworst = fmax(cworst, fabs(sl_image_pixel(&cback, x, y)[c] - 2.5));
                /* The mirror ball squeezes the half sphere around +Z into its
                 * outer ring; leave out the 30 degrees around +Z. */
                if (p == SL_PROJ_MIRRORBALL && d[2] > cos(M_PI / 6))
                    continue;
                for (int c = 0; c < 3; c++) {
                    double e = fabs(sl_image_pixel(&back, x, y)[c] - sl_image_pixel(&src, x, y)[c]);
                    worst = fmax(worst, e);
                    sum += e;
                    n++;
                }
            }
        /* Constant in the valid area of the intermediate too. */
        double mworst = 0.0;
        for (int y = 0; y < cmid.height; y++)
            for (int x = 0; x < cmid.width; x++) {
                double u = (x + 0.5) / cmid.width, v = (y + 0.5) / cmid.height, d[3];
                if (sl_projection_to_dir((sl_projection)p, u, v, d))
                    mworst = fmax(mworst, fabs(sl_image_pixel(&cmid, x, y)[0] - 2.5));
                else if (p == SL_PROJ_MIRRORBALL && hypot(2 * u - 1, 2 * v - 1) > 1.02)
                    CHECK(sl_image_pixel(&cmid, x, y)[0] == 0.0f);
            }
        printf("  latlong -> %s -> latlong (256 wide): smooth max %.3g mean %.3g; constant "
               "max %.3g, in %s %.3g\n",
               sl_projection_name((sl_projection)p), worst, sum / n, cworst,
               sl_projection_name((sl_projection)p), mworst);
        CHECK(worst < max_bound[p]);
        CHECK(sum / n < max_bound[p] / 5);
        CHECK(cworst < 1e-6);
        CHECK(mworst < 1e-6);
        sl_image_free(&mid);
        sl_image_free(&back);
        sl_image_free(&cmid);
        sl_image_free(&cback);
    }
    sl_image_free(&src);
    sl_image_free(&cst);
}

static void test_reproject_rotation(void)
{
    sl_error err;
    sl_image src, dst;
    CHECK_OK(sl_image_alloc(&src, 64, 32, 1, &err), &err);
    /* A bright texel at the centre column (+Z) on the equator. */
    sl_image_pixel(&src, 32, 15)[0] = 1000.0f;
    double r[3][3];
    sl_rotation_y(90.0, r);
    CHECK_OK(sl_reproject(&src, SL_PROJ_LATLONG, SL_PROJ_LATLONG, 64, r, &dst, &err), &err);
    /* Content at +Z moves to +X, a quarter width in: column 32 -> 16. */
    int bx = -1, by = -1;
    double best = -1.0, total_src = 0.0, total_dst = 0.0;
    for (int y = 0; y < 32; y++)
        for (int x = 0; x < 64; x++) {
            double vv = sl_image_pixel(&dst, x, y)[0];
            total_dst += vv;
            total_src += sl_image_pixel(&src, x, y)[0];
            if (vv > best) {
                best = vv;
                bx = x;
                by = y;
            }
        }
    CHECK(bx == 16 && by == 15);
    CHECK_NEAR(total_dst / total_src, 1.0, 1e-6); /* a whole-column shift keeps the sum */
    sl_image_free(&dst);

    CHECK_OK(sl_reproject(&src, SL_PROJ_LATLONG, SL_PROJ_LATLONG, 64, NULL, &dst, &err), &err);
    CHECK(memcmp(dst.data, src.data, sizeof(float) * 64 * 32) == 0); /* identity is exact */
    sl_image_free(&dst);

    CHECK_RESULT(sl_reproject(&src, SL_PROJ_MIRRORBALL, SL_PROJ_LATLONG, 64, NULL, &dst, &err),
                 SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "not square") != NULL);
    CHECK(dst.data == NULL);
    CHECK_RESULT(sl_reproject(&src, SL_PROJ_LATLONG, SL_PROJ_CUBEMAP, 3, NULL, &dst, &err),
                 SL_ERR_USAGE, &err);
    CHECK_RESULT(sl_reproject(&src, SL_PROJ_LATLONG, (sl_projection)9, 64, NULL, &dst, &err),
                 SL_ERR_USAGE, &err);
    sl_image_free(&src);
}

static void test_reproject_orientation_and_threads(void)
{
    sl_error err;
    sl_image src, ball, ball1;
    CHECK_OK(sl_image_alloc(&src, 128, 64, 1, &err), &err);
    /* A bright texel looking along +X (quarter width, equator). */
    sl_image_pixel(&src, 32, 31)[0] = 1000.0f;
    sl_image_pixel(&src, 32, 32)[0] = 1000.0f;
    CHECK_OK(sl_reproject(&src, SL_PROJ_LATLONG, SL_PROJ_MIRRORBALL, 256, NULL, &ball, &err),
             &err);
    /* +X is the camera's left: it shows at px = -sin 45 deg, i.e. image left. */
    int bx = -1, by = -1;
    float best = -1.0f;
    for (int y = 0; y < ball.height; y++)
        for (int x = 0; x < ball.width; x++)
            if (sl_image_pixel(&ball, x, y)[0] > best) {
                best = sl_image_pixel(&ball, x, y)[0];
                bx = x;
                by = y;
            }
    double px = 2.0 * (bx + 0.5) / ball.width - 1.0, py = 1.0 - 2.0 * (by + 0.5) / ball.height;
    printf("  +X texel on the 128-wide ball at (%.3f, %.3f)\n", px, py);
    CHECK(fabs(px + sqrt(0.5)) < 0.03 && fabs(py) < 0.03);
    /* Same bytes for one thread and for several. */
    int saved = sl_threads_get();
    sl_threads_set(1);
    CHECK_OK(sl_reproject(&src, SL_PROJ_LATLONG, SL_PROJ_MIRRORBALL, 256, NULL, &ball1, &err),
             &err);
    sl_threads_set(saved);
    CHECK(ball1.data && memcmp(ball.data, ball1.data, sizeof(float) * 128 * 128) == 0);
    sl_image_free(&ball);
    sl_image_free(&ball1);
    sl_image_free(&src);
}

/* Debevec's angular map (Light Probe Image Gallery; HDR Toolbox's
 * Angular2Direction): image point (px, py), py up, theta = atan2(py, px),
 * phi = pi r; direction (cos theta sin phi, sin theta sin phi, -cos phi):
 * centre forward -Z, image right +X, image up +Y. */
static void debevec_angular_dir(double px, double py, double d[3])
{
    double r = hypot(px, py), phi = M_PI * r, theta = atan2(py, px);
    d[0] = cos(theta) * sin(phi);
    d[1] = sin(theta) * sin(phi);
    d[2] = -cos(phi);
}

/* Index of the largest first-channel value. */
static void brightest(const sl_image *img, int *bx, int *by)
{
    float best = -1.0f;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++)
            if (sl_image_pixel(img, x, y)[0] > best) {
                best = sl_image_pixel(img, x, y)[0];
                *bx = x;
                *by = y;
            }
}

static void test_angular_orientation(void)
{
    double d[3], u, v;
    /* Centre +Z (forward), image right -X, image up +Y, rim -Z. */
    CHECK(sl_projection_to_dir(SL_PROJ_ANGULAR, 0.5, 0.5, d));
    CHECK_NEAR(d[2], 1.0, 1e-15);
    CHECK(sl_projection_to_dir(SL_PROJ_ANGULAR, 0.75, 0.5, d)); /* r = 1/2: 90 deg */
    CHECK_NEAR(d[0], -1.0, 1e-15);
    CHECK(sl_projection_to_dir(SL_PROJ_ANGULAR, 0.5, 0.25, d));
    CHECK_NEAR(d[1], 1.0, 1e-15);
    CHECK(sl_projection_to_dir(SL_PROJ_ANGULAR, 0.5, 1.0, d));
    CHECK_NEAR(d[2], -1.0, 1e-15);
    double back[3] = {0, 0, -1};
    CHECK(sl_dir_to_projection(SL_PROJ_ANGULAR, back, &u, &v));
    CHECK_NEAR(hypot(2 * u - 1, 2 * v - 1), 1.0, 1e-15);
    /* The published definition turned half a turn about +Y (its forward -Z
     * becomes OpenEXR's lat-long centre +Z): a rotation, no mirror. */
    double worst = 0.0;
    for (int j = 0; j < 64; j++)
        for (int i = 0; i < 64; i++) {
            double px = (i + 0.5) / 32 - 1, py = 1 - (j + 0.5) / 32, a[3];
            if (px * px + py * py > 1)
                continue;
            CHECK(sl_projection_to_dir(SL_PROJ_ANGULAR, 0.5 * (px + 1), 0.5 * (1 - py), d));
            debevec_angular_dir(px, py, a);
            double turned[3] = {-a[0], a[1], -a[2]};
            worst = fmax(worst, dir_dist(d, turned));
        }
    printf("  angular vs Debevec's definition turned 180 deg about Y: max %.3g\n", worst);
    CHECK(worst < 1e-12);

    /* A bright texel goes to the right place both ways. */
    sl_error err;
    sl_image ang, ll, ang2;
    CHECK_OK(sl_image_alloc(&ang, 64, 64, 1, &err), &err);
    /* image right on the horizontal line, r = 1/2: looking along -X */
    for (int y = 31; y <= 32; y++)
        for (int x = 47; x <= 48; x++)
            sl_image_pixel(&ang, x, y)[0] = 1000.0f;
    CHECK_OK(sl_reproject(&ang, SL_PROJ_ANGULAR, SL_PROJ_LATLONG, 128, NULL, &ll, &err), &err);
    int bx = -1, by = -1;
    brightest(&ll, &bx, &by);
    sl_latlong_to_dir((bx + 0.5) / 128, (by + 0.5) / 64, d);
    printf("  angular image-right texel -> lat-long (%d, %d), dir (%.3f, %.3f, %.3f)\n", bx, by,
           d[0], d[1], d[2]);
    CHECK(d[0] < -0.99); /* column 96 of 128: three quarters in */
    CHECK(abs(bx - 96) <= 1 && (by == 31 || by == 32));
    sl_image_free(&ll);
    sl_image_free(&ang);

    CHECK_OK(sl_image_alloc(&ll, 128, 64, 1, &err), &err);
    /* +X (a quarter in, equator) and +Y 45 degrees up from +Z, weaker. */
    sl_image_pixel(&ll, 32, 31)[0] = sl_image_pixel(&ll, 32, 32)[0] = 1000.0f;
    sl_image_pixel(&ll, 64, 15)[0] = sl_image_pixel(&ll, 63, 15)[0] = 100.0f;
    CHECK_OK(sl_reproject(&ll, SL_PROJ_LATLONG, SL_PROJ_ANGULAR, 128, NULL, &ang2, &err), &err);
    brightest(&ang2, &bx, &by);
    double px = 2.0 * (bx + 0.5) / ang2.width - 1.0, py = 1.0 - 2.0 * (by + 0.5) / ang2.height;
    printf("  lat-long +X texel -> angular (%.3f, %.3f)\n", px, py);
    CHECK(fabs(px + 0.5) < 0.04 && fabs(py) < 0.04); /* image left, r = 1/2 */
    /* Mask the +X peak; the next one is the +Y-of-forward texel, straight up
     * from the centre at r = 45/180. */
    for (int y = 0; y < ang2.height; y++)
        for (int x = 0; x < ang2.width / 2; x++)
            sl_image_pixel(&ang2, x, y)[0] = 0.0f;
    brightest(&ang2, &bx, &by);
    px = 2.0 * (bx + 0.5) / ang2.width - 1.0;
    py = 1.0 - 2.0 * (by + 0.5) / ang2.height;
    printf("  lat-long texel 45 deg above +Z -> angular (%.3f, %.3f)\n", px, py);
    CHECK(fabs(px) < 0.04 && fabs(py - 0.25) < 0.04);
    sl_image_free(&ll);
    sl_image_free(&ang2);
}

/* Log luminance of every texel (floor 1e-4), malloc'd. */
static double *log_luminance(const sl_image *img)
{
    double *l = malloc(sizeof *l * (size_t)img->width * (size_t)img->height);
    for (int y = 0; l && y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            const float *p = sl_image_pixel(img, x, y);
            double lum = img->channels >= 3 ? sl_luminance_px(p) : p[0];
            l[(size_t)y * img->width + x] = log(fmax(lum, 1e-4));
        }
    return l;
}

/* Solid-angle weighted normalised correlation of two w x h lat-longs' log
 * luminances, b's columns mirrored (u -> 1 - u) when `mirror` and turned by
 * `shift` columns. */
static double latlong_log_correlation(const double *a, const double *b, int w, int h,
                                      bool mirror, int shift)
{
    double sw = 0, sa = 0, sb = 0, saa = 0, sbb = 0, sab = 0;
    for (int y = 0; y < h; y++) {
        double wt = sl_latlong_texel_solid_angle(y, w, h);
        for (int x = 0; x < w; x++) {
            double la = a[(size_t)y * w + x];
            double lb = b[(size_t)y * w + ((mirror ? w - 1 - x : x) + shift) % w];
            sw += wt;
            sa += wt * la;
            sb += wt * lb;
            saa += wt * la * la;
            sbb += wt * lb * lb;
            sab += wt * la * lb;
        }
    }
    double ma = sa / sw, mb = sb / sw;
    return (sab / sw - ma * mb) / sqrt((saa / sw - ma * ma) * (sbb / sw - mb * mb));
}

/* Debevec's Grace Cathedral angular probe against the lat-long of the same
 * probe in colour-science's datasets: the conversion matches as it is, and
 * no turn of its mirror image comes close. */
static void test_angular_probe_real(void)
{
    const char *probe_path = sl_test_data("probes/grace_probe_angular.hdr");
    const char *ref_path = sl_test_data("hdri/Grace_Cathedral_500x250.hdr");
    if (!probe_path || !ref_path)
        return;
    sl_error err;
    sl_image probe = {0}, ref = {0}, conv = {0};
    CHECK_OK(sl_image_read(probe_path, &probe, NULL, &err), &err);
    CHECK_OK(sl_image_read(ref_path, &ref, NULL, &err), &err);
    CHECK_OK(sl_reproject(&probe, SL_PROJ_ANGULAR, SL_PROJ_LATLONG, ref.width, NULL, &conv, &err),
             &err);
    double *lref = NULL, *lconv = NULL;
    if (!conv.data || ref.height != conv.height || !(lref = log_luminance(&ref)) ||
        !(lconv = log_luminance(&conv))) {
        CHECK(false);
    } else {
        int w = ref.width, h = ref.height;
        double best[2] = {-2, -2};
        int best_shift[2] = {0, 0};
        for (int m = 0; m < 2; m++)
            for (int s = 0; s < w; s += 2) {
                double c = latlong_log_correlation(lref, lconv, w, h, m, s);
                if (c > best[m]) {
                    best[m] = c;
                    best_shift[m] = s;
                }
            }
        double as_is = latlong_log_correlation(lref, lconv, w, h, false, 0);
        printf("  Grace probe -> lat-long vs Grace_Cathedral_500x250: log-luminance correlation "
               "%.4f as is; best turn %d columns; mirrored (u -> 1 - u): %.4f, best %.4f "
               "(turned %d columns)\n",
               as_is, best_shift[0], latlong_log_correlation(lref, lconv, w, h, true, 0), best[1],
               best_shift[1]);
        CHECK(as_is > 0.99);
        CHECK(best_shift[0] == 0);
        CHECK(best[1] < 0.7);
    }
    free(lref);
    free(lconv);
    sl_image_free(&probe);
    sl_image_free(&ref);
    sl_image_free(&conv);
}

int main(void)
{
    RUN(test_latlong_orientation);
    RUN(test_solid_angles);
    RUN(test_latlong_lookup);
    RUN(test_projection_names);
    RUN(test_projection_round_trips);
    RUN(test_mirrorball_orientation);
    RUN(test_cubemap_faces);
    RUN(test_rotations);
    RUN(test_reproject_round_trip);
    RUN(test_reproject_rotation);
    RUN(test_reproject_orientation_and_threads);
    RUN(test_angular_orientation);
    RUN(test_angular_probe_real);
    return sl_test_finish();
}
