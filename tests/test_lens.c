/* SPDX-License-Identifier: BSD-3-Clause */
/* The lens model: known radii of each projection, the virtual set's 8 mm
 * fisheye reproduced exactly by the nominal lens and a view pose, pixel ->
 * ray -> pixel round trips with a radial correction and an off-centre axis,
 * and pose <-> matrix round trips. */
#include "testing.h"

#include "setlight/vset.h"

#include <math.h>
#include <stdint.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static uint64_t rng_state = 0x2545F4914F6CDD1Dull;

static double rng_uniform(void) { return sl_test_uniform(&rng_state); }

static void mat_vec(const double m[3][3], const double v[3], double out[3])
{
    for (int i = 0; i < 3; i++)
        out[i] = m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2];
}

static void known_radii(void)
{
    sl_lens lens;
    sl_lens_nominal(&lens, SL_LENS_EQUISOLID, 1800, 1200, 8.0, 36.0);
    CHECK_NEAR(lens.focal_px, 400.0, 1e-12);
    CHECK_NEAR(sl_lens_radius(&lens, 0.5 * M_PI), 400.0 * sqrt(2.0), 1e-9);
    CHECK_NEAR(lens.circle_radius_px, 400.0 * sqrt(2.0), 1e-9);
    CHECK(sl_lens_radius(&lens, 0.5 * M_PI + 0.01) < 0); /* beyond the field */
    const double expect[SL_LENS_PROJECTION_COUNT] = {2 * sin(0.3), 0.6, 2 * tan(0.3), sin(0.6),
                                                     tan(0.6)};
    for (int p = 0; p < SL_LENS_PROJECTION_COUNT; p++) {
        sl_lens_nominal(&lens, (sl_lens_projection)p, 4000, 3000, 10.0, 40.0);
        CHECK_NEAR(sl_lens_radius(&lens, 0.6), 1000.0 * expect[p], 1e-9);
        CHECK_NEAR(sl_lens_theta(&lens, 1000.0 * expect[p]), 0.6, 1e-12);
        CHECK(sl_lens_projection_from_name(sl_lens_projection_name((sl_lens_projection)p)) == p);
    }
    CHECK(sl_lens_projection_from_name("fisheye") == -1);
    /* A rectilinear lens sees out to its frame's corner, and has no circle. */
    sl_lens_nominal(&lens, SL_LENS_RECTILINEAR, 4000, 3000, 10.0, 40.0);
    CHECK_NEAR(lens.max_theta_deg, atan(2500.0 / 1000.0) * 180 / M_PI, 1e-9);
    CHECK(lens.circle_radius_px == 0);
    /* A fisheye whose circle is larger than the frame (full-frame fisheye). */
    sl_lens_nominal(&lens, SL_LENS_EQUISOLID, 6000, 4000, 16.0, 36.0);
    CHECK(lens.circle_radius_px == 0);
}

/* The virtual set's probe camera (its own rectilinear lens code): the
 * nominal lens and the pose reproduce its pixel <-> direction map for any
 * view. */
static void matches_virtual_set(void)
{
    sl_vset_lens vl;
    sl_vset_lens_rectilinear(&vl, 12);
    const int w = 900, h = 600;
    sl_lens lens;
    sl_lens_nominal(&lens, SL_LENS_RECTILINEAR, w, h, vl.focal_mm, vl.sensor_width_mm);
    double worst = 0;
    int compared = 0, disagree = 0;
    for (int v = 0; v < 20; v++) {
        sl_vset_view view = {360 * rng_uniform() - 180, 60 * rng_uniform() - 30,
                             20 * rng_uniform() - 10};
        sl_view_pose pose = {view.yaw_deg, view.pitch_deg, view.roll_deg};
        double m[3][3];
        sl_view_pose_matrix(&pose, m);
        for (int i = 0; i < 200; i++) {
            double x = w * rng_uniform(), y = h * rng_uniform(), d1[3], d2[3], ray[3];
            bool a = sl_vset_lens_to_dir(&vl, &view, w, h, x, y, d1);
            bool b = sl_lens_pixel_to_ray(&lens, x, y, ray);
            /* The two may disagree only on the frame's edge itself. */
            if (a != b) {
                disagree++;
                continue;
            }
            if (!a)
                continue;
            mat_vec(m, ray, d2);
            double e = fabs(d1[0] - d2[0]) + fabs(d1[1] - d2[1]) + fabs(d1[2] - d2[2]);
            worst = e > worst ? e : worst;
            compared++;
            double x2, y2;
            CHECK(sl_vset_lens_from_dir(&vl, &view, w, h, d1, &x2, &y2));
            CHECK(sl_lens_ray_to_pixel(&lens, ray, &x2, &y2));
            CHECK_NEAR(x2, x, 1e-7);
            CHECK_NEAR(y2, y, 1e-7);
        }
    }
    printf("virtual-set rectilinear lens: %d pixels compared, worst direction difference "
           "%.3g, %d on the frame's edge\n",
           compared, worst, disagree);
    CHECK(compared > 3900);
    CHECK(worst < 1e-12);
    CHECK(disagree <= 2);
}

static void round_trips(void)
{
    for (int p = 0; p < SL_LENS_PROJECTION_COUNT; p++) {
        sl_lens lens;
        sl_lens_nominal(&lens, (sl_lens_projection)p, 1600, 1200, 8.0, 24.0);
        lens.cx += 7.5;
        lens.cy -= 4.25;
        lens.k[0] = 0.02;
        lens.k[1] = -0.01;
        lens.k[2] = 0.002;
        if (p == SL_LENS_RECTILINEAR) {
            sl_lens_nominal(&lens, SL_LENS_RECTILINEAR, 1600, 1200, 24.0, 36.0);
            lens.k[0] = -0.05;
        }
        double worst = 0;
        int seen = 0;
        for (int i = 0; i < 4000; i++) {
            double x = lens.width * rng_uniform(), y = lens.height * rng_uniform(), ray[3];
            if (!sl_lens_pixel_to_ray(&lens, x, y, ray))
                continue;
            CHECK_NEAR(ray[0] * ray[0] + ray[1] * ray[1] + ray[2] * ray[2], 1.0, 1e-12);
            double x2, y2;
            if (!sl_lens_ray_to_pixel(&lens, ray, &x2, &y2)) {
                CHECK_MSG(false, "%s: ray at (%g, %g) does not map back",
                          sl_lens_projection_name((sl_lens_projection)p), x, y);
                continue;
            }
            double e = hypot(x2 - x, y2 - y);
            worst = e > worst ? e : worst;
            seen++;
        }
        CHECK_MSG(worst < 1e-8, "%s: worst round trip %g px",
                  sl_lens_projection_name((sl_lens_projection)p), worst);
        CHECK(seen > 1000);
    }
    /* Rays behind a fisheye's field are refused, not wrapped. */
    sl_lens lens;
    sl_lens_nominal(&lens, SL_LENS_EQUIDISTANT, 1600, 1200, 8.0, 36.0);
    double behind[3] = {0.1, 0.0, -1.0}, x, y;
    CHECK(!sl_lens_ray_to_pixel(&lens, behind, &x, &y));
    double on_axis[3] = {0, 0, 2.0};
    CHECK(sl_lens_ray_to_pixel(&lens, on_axis, &x, &y));
    CHECK_NEAR(x, 800.0, 1e-12);
    CHECK_NEAR(y, 600.0, 1e-12);
}

static void vignette(void)
{
    sl_lens lens;
    sl_lens_nominal(&lens, SL_LENS_EQUISOLID, 1000, 1000, 8.0, 36.0);
    CHECK_NEAR(sl_lens_vignette(&lens, 500, 500), 1.0, 1e-15);
    lens.vignette[0] = -0.2;
    lens.vignette[1] = 0.05;
    double s = 100.0 / lens.focal_px;
    CHECK_NEAR(sl_lens_vignette(&lens, 600, 500), 1 - 0.2 * s * s + 0.05 * pow(s, 4), 1e-12);
}

static void poses(void)
{
    double worst = 0;
    for (int i = 0; i < 500; i++) {
        sl_view_pose a = {360 * rng_uniform() - 180, 178 * rng_uniform() - 89,
                          360 * rng_uniform() - 180},
                     b;
        double m[3][3], m2[3][3];
        sl_view_pose_matrix(&a, m);
        /* A rotation: right x down = forward. */
        double c[3] = {m[1][0] * m[2][1] - m[2][0] * m[1][1], m[2][0] * m[0][1] - m[0][0] * m[2][1],
                       m[0][0] * m[1][1] - m[1][0] * m[0][1]};
        for (int k = 0; k < 3; k++)
            CHECK_NEAR(c[k], m[k][2], 1e-12);
        sl_view_pose_from_matrix(m, &b);
        sl_view_pose_matrix(&b, m2);
        for (int r = 0; r < 3; r++)
            for (int k = 0; k < 3; k++)
                worst = fmax(worst, fabs(m[r][k] - m2[r][k]));
        CHECK_NEAR(b.yaw_deg, a.yaw_deg, 1e-9);
        CHECK_NEAR(b.pitch_deg, a.pitch_deg, 1e-9);
        CHECK_NEAR(b.roll_deg, a.roll_deg, 1e-9);
    }
    CHECK(worst < 1e-12);
    /* Straight up: the yaw folds into the roll, the matrix survives. */
    sl_view_pose up = {40, 90, 10}, back;
    double m[3][3], m2[3][3];
    sl_view_pose_matrix(&up, m);
    sl_view_pose_from_matrix(m, &back);
    sl_view_pose_matrix(&back, m2);
    for (int r = 0; r < 3; r++)
        for (int k = 0; k < 3; k++)
            CHECK_NEAR(m2[r][k], m[r][k], 1e-9);
    CHECK_NEAR(back.yaw_deg, 0.0, 1e-12);
    /* At yaw 0 the view looks along +Z, image right is -X, image down -Y. */
    sl_view_pose zero = {0, 0, 0};
    sl_view_pose_matrix(&zero, m);
    CHECK(m[0][0] == -1 && m[1][1] == -1 && m[2][2] == 1);
}

/* The virtual set renders any lens at any pose: each pixel of a point-
 * sampled view is the environment in the direction the lens and the pose
 * give, times the lens's vignetting; nothing outside the image circle. */
static void view_image(void)
{
    sl_image env = {0}, b = {0};
    sl_error err = {0};
    CHECK_RESULT(sl_image_alloc(&env, 64, 32, 3, &err), SL_OK, &err);
    for (int y = 0; y < 32; y++)
        for (int x = 0; x < 64; x++) {
            float *p = sl_image_pixel(&env, x, y);
            p[0] = (float)(1 + x);
            p[1] = (float)(1 + y);
            p[2] = (float)((x * 7 + y * 3) % 11);
        }
    sl_view_pose pose = {30, 10, 5};
    sl_lens lens;
    sl_lens_nominal(&lens, SL_LENS_EQUISOLID, 96, 64, 8, 36);
    lens.cx += 1.5;
    lens.k[0] = 0.02;
    lens.vignette[0] = -0.1;
    double m[3][3];
    sl_view_pose_matrix(&pose, m);
    CHECK_RESULT(sl_vset_view_image(&lens, &pose, &env, 1, &b, &err), SL_OK, &err);
    double worst = 0;
    int inside = 0;
    for (int y = 0; y < 64; y++)
        for (int x = 0; x < 96; x++) {
            double ray[3], d[3], u, v;
            float want[4] = {0, 0, 0, 0};
            if (sl_lens_pixel_to_ray(&lens, x + 0.5, y + 0.5, ray)) {
                mat_vec(m, ray, d);
                sl_dir_to_latlong(d, &u, &v);
                sl_latlong_lookup(&env, u, v, want);
                for (int c = 0; c < 3; c++)
                    want[c] *= (float)sl_lens_vignette(&lens, x + 0.5, y + 0.5);
                inside++;
            }
            for (int c = 0; c < 3; c++)
                worst = fmax(worst, fabs(sl_image_pixel(&b, x, y)[c] - want[c]));
        }
    CHECK_MSG(worst < 1e-4, "view image differs from the lens's own map by %g", worst);
    CHECK(inside > 2000 && inside < 96 * 64 - 500); /* a circle inside the frame */
    sl_image_free(&b);
    CHECK(sl_vset_view_image(&lens, &pose, &env, 2, &b, &err) == SL_OK);
    sl_image img = b;
    CHECK(sl_vset_view_image(&lens, &pose, &img, 2, &b, &err) == SL_ERR_INPUT);
    sl_image_free(&img);
    sl_image_free(&env);
}

int main(void)
{
    known_radii();
    matches_virtual_set();
    round_trips();
    vignette();
    poses();
    view_image();
    return sl_test_finish();
}
