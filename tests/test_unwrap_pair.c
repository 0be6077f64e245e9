/* SPDX-License-Identifier: BSD-3-Clause */
/* Two views of one chrome ball, 90 degrees apart, ray-traced with a
 * perspective camera: the photographer (a dark blob in the environment
 * around view 1's camera, seen by view 1 only) must be gone from the merge,
 * the error behind ball 1 must drop below the single view's, and view 2's
 * azimuth, given 6 degrees off, must be found again. Also: the reflectance
 * from a patch of known radiance. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ball_fixture.h"
#include "setlight/stitch.h"
#include "testing.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

enum { OUT_W = 256 };

/* Median relative luminance error over the texels within max_deg of axis. */
static double cone_median(const sl_image *out, const sl_image *truth, const double axis[3],
                          double max_deg)
{
    int w = out->width, h = out->height, n = 0;
    double *rel = malloc(sizeof(double) * (size_t)w * h), c = cos(max_deg * M_PI / 180.0);
    if (!rel)
        return INFINITY;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / h, d);
            if (d[0] * axis[0] + d[1] * axis[1] + d[2] * axis[2] < c)
                continue;
            double lt = sl_luminance_px(sl_image_pixel(truth, x, y));
            rel[n++] = fabs(sl_luminance_px(sl_image_pixel(out, x, y)) - lt) / lt;
        }
    qsort(rel, (size_t)n, sizeof *rel, sl_cmp_double);
    double v = n ? rel[n / 2] : INFINITY;
    free(rel);
    return v;
}

/* Worst relative error of the irradiance on a grey sphere's six axis
 * normals, and of the sphere's total (the integral of L over all
 * directions), unwrapped vs truth. */
static void irradiance_errors(const sl_image *out, const sl_image *truth, double *worst_axis,
                              double *total)
{
    static const double nrm[6][3] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0},
                                     {0, -1, 0}, {0, 0, 1}, {0, 0, -1}};
    double eo[6] = {0}, et[6] = {0}, to = 0, tt = 0;
    int w = out->width, h = out->height;
    for (int y = 0; y < h; y++) {
        double dw = sl_latlong_texel_solid_angle(y, w, h);
        for (int x = 0; x < w; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / h, d);
            double lo = sl_luminance_px(sl_image_pixel(out, x, y)), lt = sl_luminance_px(sl_image_pixel(truth, x, y));
            to += lo * dw;
            tt += lt * dw;
            for (int i = 0; i < 6; i++) {
                double c = d[0] * nrm[i][0] + d[1] * nrm[i][1] + d[2] * nrm[i][2];
                if (c > 0) {
                    eo[i] += lo * c * dw;
                    et[i] += lt * c * dw;
                }
            }
        }
    }
    *worst_axis = 0;
    for (int i = 0; i < 6; i++)
        *worst_axis = fmax(*worst_axis, fabs(eo[i] / et[i] - 1.0));
    *total = to / tt - 1.0;
}

static void view_fixture(ball_fixture *f, const sl_image *env, double azimuth)
{
    ball_fixture_init(f, 320, 240);
    f->perspective = true;
    f->focal_px = 400;
    f->balls[0].px = 160;
    f->balls[0].py = 120;
    f->balls[0].distance = 5.0;
    f->azimuth_deg = azimuth;
    f->ss = sl_test_sanitized() ? 2 : 3; /* sanitizers: a quicker render */
    f->env = env;
    sl_reflectance_chrome(&f->reflectance);
}

static void view_options(const ball_fixture *f, sl_unwrap_options *o)
{
    memset(o, 0, sizeof *o);
    ball_fixture_circle(f, 0, &o->circle);
    o->geometry.camera = SL_BALL_PERSPECTIVE;
    o->geometry.focal_px = f->focal_px;
    o->geometry.azimuth_deg = f->azimuth_deg;
    o->reflectance = f->reflectance;
    o->width = OUT_W;
}

static void test_two_views(void)
{
    ball_fixture f1, f2, base;
    sl_image env = {0}, env1 = {0}, p1 = {0}, p2 = {0}, single = {0}, merged = {0},
             truth = {0};
    sl_error err;
    ball_fixture_init(&base, 8, 8);
    if (ball_fixture_truth(&base, 512, 2, &env, &err) || sl_image_copy(&env, &env1, &err)) {
        CHECK_MSG(false, "%s", err.message);
        goto done;
    }
    /* The photographer: 12 degrees of dark around view 1's camera (-Z). */
    const double cam1[3] = {0, 0, -1}, back1[3] = {0, 0, 1};
    for (int y = 0; y < env1.height; y++)
        for (int x = 0; x < env1.width; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / env1.width, (y + 0.5) / env1.height, d);
            if (-d[2] > cos(12.0 * M_PI / 180.0)) {
                float *p = sl_image_pixel(&env1, x, y);
                p[0] = p[1] = p[2] = 0.01f;
            }
        }
    view_fixture(&f1, &env1, 0.0);
    view_fixture(&f2, &env, 90.0);
    if (ball_fixture_render(&f1, &p1, &err) || ball_fixture_render(&f2, &p2, &err) ||
        ball_fixture_truth(&f2, OUT_W, 4, &truth, &err)) {
        CHECK_MSG(false, "%s", err.message);
        goto done;
    }
    sl_unwrap_pair_options po = {.search_deg = 15, .occluder_deg = 20};
    view_options(&f1, &po.views[0]);
    view_options(&f2, &po.views[1]);
    po.views[1].geometry.azimuth_deg = 84.0; /* given 6 degrees off */
    sl_unwrap_pair_info info;
    CHECK_OK(sl_unwrap(&p1, &po.views[0], &single, NULL, &err), &err);
    CHECK_OK(sl_unwrap_pair(&p1, &p2, &po, &merged, &info, &err), &err);
    if (!single.data || !merged.data)
        goto done;
    double s_back = cone_median(&single, &truth, back1, 45.0);
    double m_back = cone_median(&merged, &truth, back1, 45.0);
    double s_phot = cone_median(&single, &truth, cam1, 10.0);
    double m_phot = cone_median(&merged, &truth, cam1, 10.0);
    double m_front = cone_median(&merged, &truth, cam1, 90.0);
    printf("  azimuth given 84, refined %.3f deg (residual %.4f -> %.4f, overlap %.3f of the "
           "sphere)\n",
           info.azimuth_deg, info.residual_given, info.residual, info.overlap_fraction);
    printf("  behind ball 1 (45 deg): single %.4f, merged %.4f; photographer (10 deg): single "
           "%.4f, merged %.4f; view 1's front hemisphere merged %.4f\n",
           s_back, m_back, s_phot, m_phot, m_front);
    double s_irr, s_tot, m_irr, m_tot;
    irradiance_errors(&single, &truth, &s_irr, &s_tot);
    irradiance_errors(&merged, &truth, &m_irr, &m_tot);
    printf("  grey sphere: worst axis irradiance error single %.4f, merged %.4f; total single "
           "%+.4f, merged %+.4f\n",
           s_irr, m_irr, s_tot, m_tot);
    CHECK(m_irr <= 0.02);
    CHECK(fabs(m_tot) <= 0.02);
    CHECK(fabs(info.azimuth_deg - 90.0) <= 0.5);
    CHECK(info.residual < info.residual_given);
    CHECK(m_back < s_back);
    CHECK(m_back <= 0.02);
    CHECK(s_phot > 0.5); /* the photographer is there in view 1 alone */
    CHECK(m_phot <= 0.02);
    CHECK(m_front <= 0.02);
    /* Without the search the given angle stays. */
    sl_image_free(&merged);
    po.search_deg = 0;
    CHECK_OK(sl_unwrap_pair(&p1, &p2, &po, &merged, &info, &err), &err);
    CHECK_NEAR(info.azimuth_deg, 84.0, 1e-12);
    double off_back = merged.data ? cone_median(&merged, &truth, back1, 45.0) : 0.0;
    printf("  with the 6 deg error kept: behind ball 1 %.4f\n", off_back);
    CHECK(off_back > 2.0 * m_back);
done:
    sl_image_free(&env);
    sl_image_free(&env1);
    sl_image_free(&p1);
    sl_image_free(&p2);
    sl_image_free(&single);
    sl_image_free(&merged);
    sl_image_free(&truth);
}

static void test_patch_reflectance(void)
{
    ball_fixture f;
    ball_fixture_init(&f, 320, 240);
    f.perspective = true;
    f.focal_px = 400;
    f.balls[0].px = 170;
    f.balls[0].py = 115;
    f.balls[0].distance = 6.0;
    f.ss = sl_test_sanitized() ? 2 : 3;
    sl_reflectance_constant(&f.reflectance, 0.62, 0.55, 0.41);
    sl_image photo = {0}, out = {0}, truth = {0}, truth4 = {0};
    sl_error err;
    sl_unwrap_options o;
    view_options(&f, &o);
    sl_reflectance_constant(&o.reflectance, 1, 1, 1);
    if (ball_fixture_render(&f, &photo, &err) || sl_unwrap(&photo, &o, &out, NULL, &err) ||
        ball_fixture_truth(&f, OUT_W, 4, &truth, &err) ||
        sl_image_convert_channels(&truth, 4, &truth4, &err)) {
        CHECK_MSG(false, "%s", err.message);
        goto done;
    }
    for (int y = 0; y < truth4.height; y++)
        for (int x = 0; x < truth4.width; x++)
            sl_image_pixel(&truth4, x, y)[3] = 1.0f;
    /* The patch: 8 degrees around a direction 35 degrees off the camera's,
     * its radiance measured directly (the truth's mean there). */
    double dir[3] = {sin(35.0 * M_PI / 180.0), 0.1, -cos(35.0 * M_PI / 180.0)};
    double one[3] = {1, 1, 1}, known[3], refl[3];
    double rad = 8.0 * M_PI / 180.0;
    CHECK_OK(sl_unwrap_patch_reflectance(&truth4, dir, rad, one, known, &err), &err);
    CHECK_OK(sl_unwrap_patch_reflectance(&out, dir, rad, known, refl, &err), &err);
    printf("  patch reflectance %.4f %.4f %.4f (true 0.62 0.55 0.41)\n", refl[0], refl[1],
           refl[2]);
    CHECK_NEAR(refl[0], 0.62, 0.62 * 0.01);
    CHECK_NEAR(refl[1], 0.55, 0.55 * 0.01);
    CHECK_NEAR(refl[2], 0.41, 0.41 * 0.01);
    /* Behind the ball: not seen, refused. */
    double behind[3] = {0, 0, 1};
    CHECK(sl_unwrap_patch_reflectance(&out, behind, rad, known, refl, &err) == SL_ERR_INPUT);
    CHECK(strstr(err.message, "reflectance patch") != NULL);
    CHECK(refl[0] == 0.0);
done:
    sl_image_free(&photo);
    sl_image_free(&out);
    sl_image_free(&truth);
    sl_image_free(&truth4);
}

int main(void)
{
    RUN(test_two_views);
    RUN(test_patch_reflectance);
    return sl_test_finish();
}
