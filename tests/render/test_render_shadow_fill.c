/* SPDX-License-Identifier: BSD-3-Clause */
/* The shadowed part computed instead of sampled (render/shadow_fill.c):
 * known answers under a uniform dome (a ball over a plane loses exactly
 * its lower hemisphere; a ground point loses the sphere's cap), and a sun
 * shadowed or not against a brute force with the renderer's own ray
 * visibility. */
#include <stdlib.h>
#include <string.h>

#include "../../render/area_closed_form.h"
#include "../../render/irradiance.h"
#include "../../render/sampler.h"
#include "../../render/scene_internal.h"
#include "../../render/shadow_fill.h"
#include "../../render/vec3.h"
#include "setlight/render.h"
#include "sun_sky.h"
#include "testing.h"

static void uniform(sl_image *img, int w, float L)
{
    CHECK_OK(sl_image_alloc(img, w, w / 2, 3, NULL), NULL);
    for (int y = 0; y < w / 2; y++)
        for (int x = 0; x < w; x++) {
            float *p = sl_image_pixel(img, x, y);
            p[0] = p[1] = p[2] = L;
        }
}

/* A unit ball at the origin over a (2 half x 2 half) ground at y = -1. */
static void ball_on_ground(sl_scene *s, const sl_image *env, double half, double rotation)
{
    sl_error err = {0};
    sl_scene_init(s);
    sl_material m;
    sl_material_lambert(&m, 0.18, 0.18, 0.18);
    int mat;
    CHECK_OK(sl_scene_add_material(s, &m, &mat, &err), &err);
    double c0[3] = {0, 0, 0}, c1[3] = {0, -1, 0}, u[3] = {0, 0, half}, v[3] = {half, 0, 0};
    CHECK_OK(sl_scene_add_sphere(s, c0, 1.0, mat, &err), &err);
    CHECK_OK(sl_scene_add_rect(s, c1, u, v, mat, &err), &err);
    CHECK_OK(sl_scene_set_dome(s, env, rotation, 1.0, "env", &err), &err);
}

/* The ball on its ground under env, and the dome's irradiance cells. */
static sl_irradiance *lit_scene(sl_scene *s, const sl_image *env, double half, double rotation)
{
    ball_on_ground(s, env, half, rotation);
    sl_irradiance *ir = NULL;
    sl_error err = {0};
    CHECK_OK(sl_irradiance_build(&s->dome, &ir, &err), &err);
    return ir;
}

static void lit_free(sl_irradiance *ir, sl_scene *s, sl_image *env)
{
    sl_irradiance_free(ir);
    sl_scene_free(s);
    sl_image_free(env);
}

/* S at point p, normal n of shape `shape`, at tolerance tol of floor. */
static void shadow_at(const sl_scene *s, const sl_irradiance *ir, int shape, const double p[3], const double n[3],
                      double tol, double floor, double S[3], double B[3])
{
    sl_blockers bl;
    CHECK(sl_blockers_at(s, ir, shape, p, n, &bl));
    double fl[3] = {floor, floor, floor};
    sl_quad q = {.tol = tol, .floor = fl};
    sl_shadow_integrate(ir, &bl, n, &q, S, B, NULL);
}

/* Uniform dome L = 1: a ball point over a ground 1e6 wide loses the lower
 * hemisphere, pi (1 - n_y) / 2 (the ground's far edge leaves a sliver of
 * at most 2 pi x 2e-6 sr); a ground point at distance d from the contact
 * loses the ball's cap, pi sin^2 s cos a = pi / (d^2 + 1)^1.5. */
static void test_uniform_known(void)
{
    sl_image env;
    uniform(&env, 256, 1.0f);
    sl_scene s;
    sl_irradiance *ir = lit_scene(&s, &env, 1e6, 30);
    double worst = 0, worst_rel_bound = 0;
    for (int k = 0; k <= 12; k++) {
        double a = SL_PI * k / 12.0 + 0.1; /* 0.1 .. 180 degrees past the top, not the contact */
        if (a > SL_PI - 0.05)
            a = SL_PI - 0.05;
        double n[3] = {sin(a) * 0.6, cos(a), sin(a) * 0.8}, S[3], B[3];
        shadow_at(&s, ir, 0, n, n, 1e-3, SL_PI, S, B);
        double want = SL_PI * (1.0 - n[1]) / 2.0, sliver = 2 * SL_PI * 2e-6;
        double e = fabs(S[0] - want);
        CHECK_MSG(e <= B[0] + sliver, "ball n_y %.3f: S %.6f, want %.6f, bound %.2g", n[1], S[0], want, B[0]);
        /* the plane's far edge runs 2e-6 rad under the map's equator: the
         * deepest split stops near, not at, the tolerance */
        CHECK(B[0] <= 4e-3 * SL_PI);
        worst = fmax(worst, e / SL_PI), worst_rel_bound = fmax(worst_rel_bound, B[0] / SL_PI);
    }
    printf("  ball over a plane: worst |S - pi (1 - n_y) / 2| %.2e of pi (bounds up to %.2e)\n", worst,
           worst_rel_bound);
    worst = 0;
    const double ds[] = {0.25, 0.5, 1, 2, 4, 10};
    for (int k = 0; k < 6; k++) {
        double p[3] = {ds[k] * 0.8, -1, ds[k] * 0.6}, n[3] = {0, 1, 0}, S[3], B[3];
        shadow_at(&s, ir, 1, p, n, 1e-3, SL_PI, S, B);
        double want = SL_PI / pow(ds[k] * ds[k] + 1, 1.5);
        double e = fabs(S[0] - want);
        CHECK_MSG(e <= B[0], "ground d %.2f: S %.6f, want %.6f, bound %.2g", ds[k], S[0], want, B[0]);
        worst = fmax(worst, e / SL_PI);
    }
    printf("  ground point vs the ball's cap: worst %.2e of pi\n", worst);
    /* Nothing above the horizon blocked: exactly 0. */
    double p[3] = {0, 1, 0}, n[3] = {0, 1, 0}, S[3], B[3];
    shadow_at(&s, ir, 0, p, n, 1e-3, SL_PI, S, B);
    CHECK(S[0] == 0 && B[0] == 0);
    lit_free(ir, &s, &env);
}

/* Uniform dome L = 1, the preset's 8 x 8 ground: at random points of the
 * ball S is the ground quad's cosine-weighted solid angle (Lambert's
 * polygon formula, area_closed_form.c), and at random ground points the
 * ball's cap's (Snyder's formula), within S's bound. */
static void test_uniform_polygon_and_cap(void)
{
    sl_image env;
    uniform(&env, 128, 1.0f);
    sl_scene s;
    sl_irradiance *ir = lit_scene(&s, &env, 4, 0);
    double quad[4][3] = {{4, -1, 4}, {-4, -1, 4}, {-4, -1, -4}, {4, -1, -4}};
    uint64_t seed = 11;
    double worst = 0;
    int outside = 0;
    for (int k = 0; k < 60; k++) {
        double u[3];
        for (int i = 0; i < 3; i++)
            u[i] = ((seed = sl_hash64(seed)) >> 11) * (1.0 / 9007199254740992.0);
        double S[3], B[3], want;
        if (k < 40) { /* a ball point: p = n */
            double z = 2 * u[0] - 1, ph = 2 * SL_PI * u[1], r = sqrt(1 - z * z);
            double n[3] = {r * cos(ph), z, r * sin(ph)};
            shadow_at(&s, ir, 0, n, n, 1e-3, SL_PI, S, B);
            want = sl_polygon_cosine_integral((const double(*)[3])quad, 4, n, n);
        } else { /* a ground point, off the contact */
            double p[3] = {8 * u[0] - 4, -1, 8 * u[1] - 4}, n[3] = {0, 1, 0};
            if (p[0] * p[0] + p[2] * p[2] < 0.01)
                continue;
            double a[3] = {-p[0], 1, -p[2]}, D = v3_length(a);
            for (int i = 0; i < 3; i++)
                a[i] /= D;
            shadow_at(&s, ir, 1, p, n, 1e-3, SL_PI, S, B);
            want = sl_cap_cosine_integral(a, 1.0 / (D * D), n);
        }
        outside += want == 0;
        CHECK_MSG(fabs(S[0] - want) <= B[0] + 1e-9, "point %d: S %.6f, want %.6f, bound %.2g", k, S[0], want, B[0]);
        worst = fmax(worst, fabs(S[0] - want) / SL_PI);
    }
    CHECK(outside > 0 && outside < 30); /* the ball's top sees no ground */
    printf("  ball and ground points vs the polygon and cap formulas: worst %.2e of pi\n", worst);
    lit_free(ir, &s, &env);
}

/* A sun of 3 x 3 texels (1e4) over the sky: at ground points the ball
 * hides it or not; S against a brute force over every texel in 8 x 8
 * pieces with the renderer's own ray visibility (sl_scene_occluded). */
static void test_sun_brute(void)
{
    sl_image env;
    int w = 128;
    sky_over_ground(&env, w);
    for (int y = 0; y < 3; y++)
        for (int x = 0; x < 3; x++) {
            float *t = sl_image_pixel(&env, w / 2 + 10 + x, w / 8 + y);
            t[0] = t[1] = t[2] = 1e4f;
        }
    sl_scene s;
    sl_irradiance *ir = lit_scene(&s, &env, 4, 0);
    /* the sun's direction, and ground points on its shadow's axis */
    double sun[3];
    sl_latlong_to_dir((w / 2 + 11.5) / w, (w / 8 + 1.5) / (w / 2), sun);
    int inside = 0;
    double worst = 0;
    for (int k = 0; k < 7; k++) {
        double t = (1.0 + 0.25 * k) / sun[1]; /* from the ball's centre down the sun's line... */
        double p[3] = {-sun[0] * t, -1, -sun[2] * t}, n[3] = {0, 1, 0}, S[3], B[3];
        double E[3], EB[3];
        sl_irradiance_eval(ir, n, 1e-3, E, EB, NULL);
        shadow_at(&s, ir, 1, p, n, 1e-3, E[0], S, B);
        /* brute force */
        double want = 0;
        for (int y = 0; y < w / 2; y++)
            for (int x = 0; x < w; x++) {
                const float *L = sl_image_pixel(&env, x, y);
                for (int j = 0; j < 8; j++)
                    for (int i = 0; i < 8; i++) {
                        double th0 = SL_PI * (y + j / 8.0) / (w / 2), th1 = SL_PI * (y + (j + 1) / 8.0) / (w / 2);
                        double dw = (cos(th0) - cos(th1)) * 2 * SL_PI / (w * 8.0), d[3];
                        sl_latlong_to_dir((x + (i + 0.5) / 8.0) / w, (y + (j + 0.5) / 8.0) / (w / 2), d);
                        if (d[1] <= 0)
                            continue;
                        double o[3];
                        sl_offset_origin(p, n, d, o);
                        if (sl_scene_occluded(&s, o, d, INFINITY))
                            want += L[0] * d[1] * dw;
                    }
            }
        inside += want > 1e-3 * E[0] * 10;
        double e = fabs(S[0] - want) / E[0];
        worst = fmax(worst, e);
        printf("  ground %.2f along the sun's shadow: S/E %.4f, brute force %.4f, bound %.4f\n", 0.25 * k,
               S[0] / E[0], want / E[0], B[0] / E[0]);
        /* the brute force's own error: a texel's 8 x 8 pieces, each all or nothing */
        CHECK_MSG(e <= B[0] / E[0] + 2e-3, "%.4f off, bound %.4f", e, B[0] / E[0]);
    }
    CHECK(inside >= 2);        /* some points in the sun's shadow */
    printf("  worst %.4f of E\n", worst);
    lit_free(ir, &s, &env);
}

/* With bounces the shadowed part stays sampled (control variates), as
 * before, at pixel centres and with the box filter. (test_render_closed_form: the shadow
 * preset's exact pixels against the sampled renderer.) */
static void test_control_kept(void)
{
    sl_image env;
    sky_over_ground(&env, 32);
    for (int k = 0; k < 2; k++) {
        sl_scene s;
        sl_error err = {0};
        sl_scene_init(&s);
        CHECK_OK(sl_scene_preset(&s, "shadow", 16, &err), &err);
        CHECK_OK(sl_scene_set_dome(&s, &env, 0, 1, "env", &err), &err);
        sl_render_options o;
        sl_render_options_init(&o);
        o.spp = 4;
        o.pixel_centers = k == 0;
        o.bounces = 1;
        sl_image img;
        sl_render_stats st;
        CHECK_OK(sl_render(&s, &o, &img, &st, &err), &err);
        CHECK(st.closed_form.control_variate_pixels > 0 && st.closed_form.shadow_exact_pixels == 0);
        sl_image_free(&img);
        sl_render_stats_free(&st);
        sl_scene_free(&s);
    }
    sl_image_free(&env);
}

/* A deadline already past: the shadow fill still gives every shadowed
 * pixel its value (its points at 4 x the tolerance), none is left to
 * sampling, and the image stays within 0.5% of the uncut one. */
static void test_deadline(void)
{
    sl_image env;
    sky_over_ground(&env, 64);
    float *sun = sl_image_pixel(&env, 20, 8);
    sun[0] = sun[1] = sun[2] = 2e4f;
    sl_scene s;
    sl_error err = {0};
    sl_scene_init(&s);
    CHECK_OK(sl_scene_preset(&s, "shadow", 48, &err), &err);
    CHECK_OK(sl_scene_set_dome(&s, &env, 0, 1, "env", &err), &err);
    /* [0] uncut, [1] the deadline past */
    sl_image img[2];
    sl_render_stats st[2];
    for (int k = 0; k < 2; k++) {
        sl_render_options o;
        sl_render_options_init(&o);
        o.pixel_centers = true;
        o.spp = k == 0 ? 2 : 0;
        o.time_limit = k == 0 ? 0 : 1e-6;
        CHECK_OK(sl_render(&s, &o, &img[k], &st[k], &err), &err);
    }
    const sl_closed_form_stats *uncut = &st[0].closed_form, *cut = &st[1].closed_form;
    double diff;
    CHECK_OK(sl_relative_rmse(&img[1], &img[0], &diff, &err), &err);
    printf("  deadline past: %lld shadowed pixels exact (uncut %lld), %lld control variates; %.4f%% from the "
           "uncut image, RMS bound %.3f%%\n",
           (long long)cut->shadow_exact_pixels, (long long)uncut->shadow_exact_pixels,
           (long long)cut->control_variate_pixels, 100 * diff, 100 * cut->rms_rel_bound);
    CHECK(cut->cut_by_time && cut->control_variate_pixels == 0);
    CHECK(cut->shadow_exact_pixels == uncut->shadow_exact_pixels);
    /* the 0.5%; the reported bounds (the cut Lambert fill's
     * coarse sun among them) are far above it */
    CHECK_MSG(diff <= 0.005, "%.4f%% from the uncut image", 100 * diff);
    for (int k = 0; k < 2; k++) {
        sl_image_free(&img[k]);
        sl_render_stats_free(&st[k]);
    }
    sl_scene_free(&s);
    sl_image_free(&env);
}

int main(void)
{
    RUN(test_uniform_known);
    RUN(test_uniform_polygon_and_cap);
    RUN(test_sun_brute);
    RUN(test_control_kept);
    RUN(test_deadline);
    return sl_test_finish();
}
