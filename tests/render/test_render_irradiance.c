/* SPDX-License-Identifier: BSD-3-Clause */
/* The closed-form dome irradiance (render/irradiance.c) against known
 * integrals: a uniform dome (E = pi L), a single bright texel 1e5 above a
 * dim sky (the cosine law), and a brute-force quadrature of a synthetic map;
 * its bound always covers the true error. */
#include <stdlib.h>
#include <string.h>

#include "../../render/irradiance.h"
#include "../../render/sampler.h"
#include "../../render/vec3.h"
#include "testing.h"

static void fill(sl_image *img, int w, float r, float g, float b)
{
    CHECK_OK(sl_image_alloc(img, w, w / 2, 3, NULL), NULL);
    for (int y = 0; y < w / 2; y++)
        for (int x = 0; x < w; x++) {
            float *p = sl_image_pixel(img, x, y);
            p[0] = r, p[1] = g, p[2] = b;
        }
}

static sl_irradiance *build(sl_scene *s, const sl_image *env, double rotation, double intensity)
{
    sl_scene_init(s);
    sl_error err = {0};
    CHECK_OK(sl_scene_set_dome(s, env, rotation, intensity, "env", &err), &err);
    sl_irradiance *ir = NULL;
    CHECK_OK(sl_irradiance_build(&s->dome, &ir, &err), &err);
    return ir;
}

static void random_normal(uint64_t *seed, double n[3])
{
    do {
        for (int i = 0; i < 3; i++) {
            *seed = sl_hash64(*seed);
            n[i] = 2.0 * ((*seed >> 11) * (1.0 / 9007199254740992.0)) - 1.0;
        }
    } while (v3_dot(n, n) > 1 || v3_dot(n, n) < 1e-3);
    v3_normalize(n);
}

static void test_uniform(void)
{
    int sizes[] = {64, 500, 1024};
    for (int i = 0; i < 3; i++) {
        sl_image env;
        fill(&env, sizes[i], 1.0f, 0.5f, 2.0f);
        sl_scene s;
        sl_irradiance *ir = build(&s, &env, 17, 1.5);
        uint64_t seed = 7;
        double worst = 0, worst_bound = 0;
        for (int k = 0; k < 200; k++) {
            double n[3], E[3], B[3];
            random_normal(&seed, n);
            sl_irradiance_eval(ir, n, 1e-3, E, B, NULL);
            double want[3] = {1.5 * SL_PI, 0.75 * SL_PI, 3.0 * SL_PI};
            for (int c = 0; c < 3; c++) {
                double e = fabs(E[c] - want[c]);
                CHECK_MSG(e <= B[c] * (1 + 1e-9) + 1e-12, "uniform: error %g above bound %g", e, B[c]);
                CHECK(B[c] <= 1e-3 * want[c] * 1.0001);
                worst = fmax(worst, e / want[c]);
                worst_bound = fmax(worst_bound, B[c] / want[c]);
            }
        }
        printf("  uniform %dx%d: worst %.2e of pi L, bound %.2e\n", sizes[i], sizes[i] / 2, worst,
               worst_bound);
        sl_irradiance_free(ir);
        sl_scene_free(&s);
        sl_image_free(&env);
    }
}

/* One texel 1e5 above a sky of 1: E(n) = pi + sum over the sun's cells of
 * L_sun max(0, n.w) dw, which far from the horizon is the cosine law. */
static void test_sun(void)
{
    const int W = 256, H = 128;
    sl_image env;
    fill(&env, W, 1, 1, 1);
    int sx = 77, sy = 30;
    float *p = sl_image_pixel(&env, sx, sy);
    p[0] = p[1] = p[2] = 1e5f;
    sl_scene s;
    sl_irradiance *ir = build(&s, &env, 0, 1);
    /* Exact texel solid angle, power and centroid direction. */
    double t0 = SL_PI * sy / H, t1 = SL_PI * (sy + 1) / H;
    double omega = (cos(t0) - cos(t1)) * 2 * SL_PI / W, dsun[3];
    sl_latlong_to_dir((sx + 0.5) / W, (sy + 0.5) / H, dsun);
    uint64_t seed = 11;
    double worst = 0;
    int far = 0;
    for (int k = 0; k < 400; k++) {
        double n[3], E[3], B[3];
        random_normal(&seed, n);
        double c = v3_dot(n, dsun);
        if (fabs(c) < 0.02)
            continue; /* the sun's texel straddles the horizon */
        far++;
        sl_irradiance_eval(ir, n, 1e-5, E, B, NULL);
        /* The sky's 1 minus the sun texel's share of it, plus the sun; the
         * centre direction stands for the texel's centroid to O(size^2). */
        double want = SL_PI + (1e5 - 1) * omega * fmax(0, c);
        double tol = 1e-5 * want + (1e5 * omega) * 1e-4 + B[0];
        CHECK_MSG(fabs(E[0] - want) <= tol, "sun: n.d %.3f: %.8g vs %.8g", c, E[0], want);
        worst = fmax(worst, fabs(E[0] - want) / want);
    }
    printf("  sun 1e5 in one texel of 256x128: %d normals, worst %.2e\n", far, worst);
    CHECK(far > 300);
    sl_irradiance_free(ir);
    sl_scene_free(&s);
    sl_image_free(&env);
}

/* A map dark but for a few texels (a sun, the glossy split's sun map):
 * the sparse build, which sums only their cells' ancestors, gives the full
 * build's irradiance bit for bit; a texel left out of its list is missed
 * (the list is what it sums). */
static void test_sparse_build(void)
{
    const int W = 512; /* 256 rows */
    sl_image env;
    fill(&env, W, 0, 0, 0);
    const int64_t lit[] = {(int64_t)40 * W + 77, (int64_t)40 * W + 78, (int64_t)41 * W + 77, (int64_t)200 * W + 511,
                           (int64_t)0 * W + 0, (int64_t)128 * W + 300};
    int n = (int)(sizeof lit / sizeof lit[0]);
    for (int i = 0; i < n; i++) {
        float *p = sl_image_pixel(&env, (int)(lit[i] % W), (int)(lit[i] / W));
        p[0] = (float)(1e4 * (i + 1)), p[1] = (float)(3e3 * (i + 1)), p[2] = 7e3f;
    }
    sl_scene s;
    sl_irradiance *full = build(&s, &env, 30, 2);
    sl_irradiance *sparse = NULL, *missing = NULL;
    sl_error err = {0};
    CHECK_OK(sl_irradiance_build_sparse(&s.dome, lit, n, &sparse, &err), &err);
    CHECK_OK(sl_irradiance_build_sparse(&s.dome, lit, n - 1, &missing, &err), &err);
    uint64_t seed = 5;
    int same = 0, differ = 0;
    for (int k = 0; k < 200; k++) {
        double nrm[3], E[3], B[3], Es[3], Bs[3], Em[3], Bm[3];
        random_normal(&seed, nrm);
        sl_irradiance_eval(full, nrm, 1e-3, E, B, NULL);
        sl_irradiance_eval(sparse, nrm, 1e-3, Es, Bs, NULL);
        sl_irradiance_eval(missing, nrm, 1e-3, Em, Bm, NULL);
        same += memcmp(E, Es, sizeof E) == 0 && memcmp(B, Bs, sizeof B) == 0;
        differ += memcmp(E, Em, sizeof E) != 0;
    }
    printf("  sparse build: %d of 200 normals the same bits, %d differ with a texel left out\n", same, differ);
    CHECK(same == 200 && differ > 50);
    sl_irradiance_free(full);
    sl_irradiance_free(sparse);
    sl_irradiance_free(missing);
    sl_scene_free(&s);
    sl_image_free(&env);
}

int main(void)
{
    RUN(test_uniform);
    RUN(test_sun);
    RUN(test_sparse_build);
    return sl_test_finish();
}
