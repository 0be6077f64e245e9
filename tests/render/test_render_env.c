/* SPDX-License-Identifier: BSD-3-Clause */
/* The renderer under a dome: grey sphere against brute-force quadrature of
 * the irradiance, chi-square of the dome sampler, chrome highlight position
 * against core's mirror-ball projection, stability grid, determinism. */
#include <stdlib.h>
#include <string.h>

#include "../../render/sampler.h"
#include "../../render/scene_internal.h"
#include "../../render/vec3.h"
#include "testing.h"

/* Sanitizer builds run about 20x slower: they check fewer pixels, each to
 * the same accuracy. */
#if defined(__SANITIZE_ADDRESS__)
#define GREY_SIZE 4
#else
#define GREY_SIZE 8
#endif

/* Smooth sky plus two bright spots: a synthetic map that always exists. */
static void synthetic_env(sl_image *env, int w)
{
    CHECK_OK(sl_image_alloc(env, w, w / 2, 3, NULL), NULL);
    for (int y = 0; y < w / 2; y++)
        for (int x = 0; x < w; x++) {
            float *p = sl_image_pixel(env, x, y);
            double d[3];
            sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / (w / 2), d);
            p[0] = (float)(0.2 + 0.8 * fmax(0, d[1]));
            p[1] = (float)(0.3 + 0.5 * fmax(0, d[1]) + 0.1 * d[0] * d[0]);
            p[2] = (float)(0.5 + 0.3 * d[2] * d[2]);
        }
    float *a = sl_image_pixel(env, w / 2 + 3, w / 8), *b = sl_image_pixel(env, w / 5, w / 4 + 2);
    a[0] = 300, a[1] = 250, a[2] = 200;
    b[0] = 20, b[1] = 40, b[2] = 80;
}

/* Irradiance at normal n: sum over texels of L * integral of max(0, n.w)
 * over the texel, each texel split into ss x ss exact solid-angle cells.
 * The cells of non-black texels are listed once per map. */
typedef struct quad_cells {
    double (*dir)[3];
    double (*weight)[3]; /* L * cell solid angle */
    size_t n;
} quad_cells;

static void quad_cells_build(quad_cells *q, const sl_image *env, int ss)
{
    int w = env->width, h = env->height;
    q->dir = malloc((size_t)w * h * ss * ss * sizeof *q->dir);
    q->weight = malloc((size_t)w * h * ss * ss * sizeof *q->weight);
    q->n = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            const float *L = sl_image_pixel(env, x, y);
            if (L[0] == 0 && L[1] == 0 && L[2] == 0)
                continue;
            for (int sy = 0; sy < ss; sy++) {
                double v0 = (y + (double)sy / ss) / h, v1 = (y + (sy + 1.0) / ss) / h;
                double lat0 = SL_PI * (0.5 - v0), lat1 = SL_PI * (0.5 - v1);
                double omega = (2.0 * SL_PI / (w * ss)) * (sin(lat0) - sin(lat1));
                for (int sx = 0; sx < ss; sx++) {
                    sl_latlong_to_dir((x + (sx + 0.5) / ss) / w, 0.5 * (v0 + v1), q->dir[q->n]);
                    for (int c = 0; c < 3; c++)
                        q->weight[q->n][c] = L[c] * omega;
                    q->n++;
                }
            }
        }
}

static void quad_cells_free(quad_cells *q)
{
    free(q->dir);
    free(q->weight);
}

static void quadrature_irradiance(const quad_cells *q, const double n[3], double E[3])
{
    E[0] = E[1] = E[2] = 0;
    for (size_t i = 0; i < q->n; i++) {
        double c = v3_dot(n, q->dir[i]);
        if (c > 0)
            for (int k = 0; k < 3; k++)
                E[k] += q->weight[i][k] * c;
    }
}

/* Worst relative pixel error of a grey-sphere render against quadrature. */
static double grey_vs_quadrature(const sl_image *env, int size, int64_t spp, double *mean_err)
{
    sl_scene s;
    sl_scene_init(&s);
    sl_error err = {0};
    CHECK_OK(sl_scene_preset(&s, "grey", size, &err), &err);
    CHECK_OK(sl_scene_set_dome(&s, env, 0, 1, "env", &err), &err);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = spp;
    o.pixel_centers = true;
    sl_image img;
    sl_render_stats st;
    CHECK_OK(sl_render(&s, &o, &img, &st, &err), &err);
    double worst = 0, sum = 0;
    int count = 0;
    quad_cells q;
    quad_cells_build(&q, env, 4);
    for (int py = 0; py < size; py++)
        for (int px = 0; px < size; px++) {
            double x = 2.0 * (px + 0.5) / size - 1.0, y = 1.0 - 2.0 * (py + 0.5) / size;
            double r2 = x * x + y * y;
            const float *p = sl_image_pixel(&img, px, py);
            if (r2 >= 1.0) {
                CHECK(p[3] == 0 && p[0] == 0);
                continue;
            }
            double n[3] = {-x, y, -sqrt(1.0 - r2)}, E[3];
            quadrature_irradiance(&q, n, E);
            for (int c = 0; c < 3; c++) {
                double ref = 0.18 / SL_PI * E[c];
                double e = fabs(p[c] - ref) / ref;
                worst = fmax(worst, e);
                sum += e;
                count++;
            }
        }
    quad_cells_free(&q);
    *mean_err = sum / count;
    sl_image_free(&img);
    sl_render_stats_free(&st);
    sl_scene_free(&s);
    return worst;
}

static void test_grey_synthetic(void)
{
    sl_image env;
    synthetic_env(&env, 64);
    double mean, worst = grey_vs_quadrature(&env, GREY_SIZE, 16384, &mean);
    printf("  synthetic 64x32: worst pixel %.4f%%, mean %.4f%%\n", 100 * worst, 100 * mean);
    CHECK(worst < 0.005);
    sl_image_free(&env);
}

static void test_grey_real_hdri(void)
{
    const char *path = sl_test_data("hdri/small/grace_256x128.hdr");
    if (!path)
        return;
    sl_image full, env;
    sl_error err = {0};
    CHECK_OK(sl_image_read(path, &full, NULL, &err), &err);
    CHECK_OK(sl_image_resample(&full, 64, 32, &env, &err), &err);
    double mean, worst = grey_vs_quadrature(&env, GREY_SIZE, 32768, &mean);
    printf("  grace 64x32: worst pixel %.4f%%, mean %.4f%%\n", 100 * worst, 100 * mean);
    CHECK(worst < 0.005);
    sl_image_free(&full);
    sl_image_free(&env);
}


static int dir_bin(const double d[3], int nt, int np)
{
    double phi = atan2(d[0], d[2]);
    if (phi < 0)
        phi += 2 * SL_PI;
    int i = (int)((1.0 - d[1]) * 0.5 * nt), j = (int)(phi / (2 * SL_PI) * np);
    i = i < 0 ? 0 : i >= nt ? nt - 1 : i;
    j = j < 0 ? 0 : j >= np ? np - 1 : j;
    return i * np + j;
}

/* Equal-area bins in (cos theta about +Y, phi); expected counts integrate
 * the dome's solid-angle pdf over each bin. */
static void chi2_dome(double rotation)
{
    enum { NT = 12, NP = 24 };
    const int64_t N = 200000;
    sl_image env;
    synthetic_env(&env, 32);
    sl_scene s;
    sl_scene_init(&s);
    CHECK_OK(sl_scene_set_dome(&s, &env, rotation, 2.0, "env", NULL), NULL);
    static double expected[NT * NP];
    static double observed[NT * NP];
    memset(observed, 0, sizeof observed);
    /* Each texel's probability is uniform in (u,v), so uniform in (theta,
     * phi) over a theta band and a phi interval (the dome turns about +Y):
     * its share of each bin is the exact overlap of those intervals. */
    memset(expected, 0, sizeof expected);
    double total = 0;
    int w = env.width, h = env.height;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            /* from the solid-angle pdf: dω = 2 π² sin(theta) du dv */
            double mc[3], dc[3], v = (y + 0.5) / h;
            sl_latlong_to_dir((x + 0.5) / w, v, mc);
            m3_mul(s.dome.rot, mc, dc);
            double mass =
                sl_dome_pdf(&s.dome, dc) * 2 * SL_PI * SL_PI * sin(SL_PI * v) / (w * h);
            double phi_c = atan2(dc[0], dc[2]), dphi = 2 * SL_PI / w;
            for (int i = 0; i < NT; i++) {
                double b0 = acos(1.0 - 2.0 * i / NT) / SL_PI, b1 = acos(1.0 - 2.0 * (i + 1) / NT) / SL_PI;
                double fv = (fmin(b1, (y + 1.0) / h) - fmax(b0, (double)y / h)) * h;
                if (fv <= 0)
                    continue;
                for (int j = 0; j < NP; j++)
                    for (int k = -1; k <= 1; k++) {
                        double p0 = 2 * SL_PI * j / NP + 2 * SL_PI * k, p1 = p0 + 2 * SL_PI / NP;
                        double fp = (fmin(p1, phi_c + 0.5 * dphi) - fmax(p0, phi_c - 0.5 * dphi)) / dphi;
                        if (fp > 0) {
                            expected[i * NP + j] += mass * fv * fp;
                            total += mass * fv * fp;
                        }
                    }
            }
        }
    CHECK_NEAR(total, 1.0, 1e-9);
    sl_sampler smp;
    int64_t rejected = 0, mismatched = 0;
    for (int64_t k = 0; k < N; k++) {
        double u[2], wi[3], L[3], pdf;
        sl_sampler_start(&smp, 7, (uint32_t)k, false);
        sl_sampler_2d(&smp, u);
        if (!sl_dome_sample(&s.dome, u, wi, L, &pdf, NULL)) {
            rejected++;
            continue;
        }
        if (!(fabs(pdf - sl_dome_pdf(&s.dome, wi)) <= 1e-6 * pdf))
            mismatched++;
        observed[dir_bin(wi, NT, NP)]++;
    }
    CHECK(rejected == 0);
    CHECK(mismatched == 0);
    for (int b = 0; b < NT * NP; b++)
        expected[b] *= N;
    int dof;
    double p = sl_test_chi2(observed, expected, NT * NP, &dof);
    printf("  rotation %g: dof %d, p %.3f\n", rotation, dof, p);
    CHECK(p > 0.001);
    sl_scene_free(&s);
    sl_image_free(&env);
}

static void test_dome_chi2(void)
{
    chi2_dome(0);
    chi2_dome(25);
}

/* One bright texel in a black map: the chrome ball shows it where core's
 * mirror-ball projection puts that direction. */
static void test_chrome_highlight(void)
{
    const int W = 64, size = 128, tx = 6, ty = 13;
    sl_image env;
    CHECK_OK(sl_image_alloc(&env, W, W / 2, 3, NULL), NULL);
    sl_image_fill(&env, 0);
    float *t = sl_image_pixel(&env, tx, ty);
    t[0] = t[1] = t[2] = 1000;
    sl_scene s;
    sl_scene_init(&s);
    sl_error err = {0};
    CHECK_OK(sl_scene_preset(&s, "chrome", size, &err), &err);
    CHECK_OK(sl_scene_set_dome(&s, &env, 0, 1, "env", &err), &err);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 2;
    o.pixel_centers = true;
    sl_image img;
    CHECK_OK(sl_render(&s, &o, &img, NULL, &err), &err);
    double sx = 0, sy = 0, sw = 0;
    for (int y = 0; y < size; y++)
        for (int x = 0; x < size; x++) {
            double v = sl_image_pixel(&img, x, y)[1];
            sx += v * (x + 0.5), sy += v * (y + 0.5), sw += v;
        }
    double d[3], u, v;
    sl_latlong_to_dir((tx + 0.5) / W, (ty + 0.5) / (W / 2), d);
    CHECK(sl_dir_to_projection(SL_PROJ_MIRRORBALL, d, &u, &v));
    CHECK(sw > 0);
    printf("  highlight at (%.2f, %.2f), projection says (%.2f, %.2f)\n", sx / sw, sy / sw, u * size,
           v * size);
    CHECK_NEAR(sx / sw, u * size, 2.0);
    CHECK_NEAR(sy / sw, v * size, 2.0);
    sl_image_free(&img);
    sl_scene_free(&s);
    sl_image_free(&env);
}

/* A perfect mirror ball rendered by the validation camera unwraps through
 * core's mirror-ball projection into the environment that lit it. */
static void test_mirror_ball_unwraps(void)
{
    const int W = 64;
    sl_image env;
    CHECK_OK(sl_image_alloc(&env, W, W / 2, 3, NULL), NULL);
    for (int y = 0; y < W / 2; y++)
        for (int x = 0; x < W; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / W, (y + 0.5) / (W / 2), d);
            float *p = sl_image_pixel(&env, x, y);
            p[0] = (float)(1.0 + 0.8 * d[0]); /* distinct in every axis direction */
            p[1] = (float)(1.0 + 0.8 * d[1]);
            p[2] = (float)(1.0 + 0.8 * d[2]);
        }
    sl_scene s;
    sl_scene_init(&s);
    sl_material m;
    const double one[3] = {1, 1, 1}, c[3] = {0, 0, 0};
    sl_material_conductor(&m, one, one, 0.0);
    m.fresnel = SL_FRESNEL_ONE;
    int mi;
    CHECK_OK(sl_scene_add_material(&s, &m, &mi, NULL), NULL);
    CHECK_OK(sl_scene_add_sphere(&s, c, 1, mi, NULL), NULL);
    sl_camera_validation(&s.camera, 256, 256, 2.0, 0, 0);
    CHECK_OK(sl_scene_set_dome(&s, &env, 0, 1, "env", NULL), NULL);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 4;
    sl_image ball, ll;
    sl_error err = {0};
    CHECK_OK(sl_render(&s, &o, &ball, NULL, &err), &err);
    CHECK_OK(sl_reproject(&ball, SL_PROJ_MIRRORBALL, SL_PROJ_LATLONG, W, NULL, &ll, &err), &err);
    double worst = 0;
    for (int y = 0; y < W / 2; y++)
        for (int x = 0; x < W; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / W, (y + 0.5) / (W / 2), d);
            if (d[2] > 0.5)
                continue; /* near +Z the ball's rim squeezes too much into a pixel */
            for (int k = 0; k < 3; k++)
                worst = fmax(worst, fabs(sl_image_pixel(&ll, x, y)[k] - sl_image_pixel(&env, x, y)[k]) /
                                        sl_image_pixel(&env, x, y)[k]);
        }
    printf("  unwrapped mirror ball vs environment: worst %.2f%%\n", 100 * worst);
    CHECK(worst < 0.03);
    sl_image_free(&ball);
    sl_image_free(&ll);
    sl_scene_free(&s);
    sl_image_free(&env);
}

static void render_check_finite(const sl_scene *s, const sl_render_options *o, sl_image *img,
                                sl_render_stats *st)
{
    sl_error err = {0};
    CHECK_OK(sl_render(s, o, img, st, &err), &err);
    sl_image_stats is;
    sl_image_stats_compute(img, &is);
    CHECK(is.nan_count == 0 && is.inf_count == 0);
    CHECK(st->nonfinite_samples == 0);
}

/* A black dome but for one texel of 1e9: exact per-pixel answer, no fireflies. */
static void test_single_hot_texel(void)
{
    const int W = 64, size = 16;
    sl_image env;
    CHECK_OK(sl_image_alloc(&env, W, W / 2, 3, NULL), NULL);
    sl_image_fill(&env, 0);
    float *t = sl_image_pixel(&env, 40, 12);
    t[0] = t[1] = t[2] = 1e9f;
    sl_scene s;
    sl_scene_init(&s);
    CHECK_OK(sl_scene_preset(&s, "grey", size, NULL), NULL);
    CHECK_OK(sl_scene_set_dome(&s, &env, 0, 1, "env", NULL), NULL);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 64;
    o.pixel_centers = true;
    sl_image img;
    sl_render_stats st;
    render_check_finite(&s, &o, &img, &st);
    double worst = 0, peak = 0.18 / SL_PI * 1e9 * sl_latlong_texel_solid_angle(12, W, W / 2);
    quad_cells q;
    quad_cells_build(&q, &env, 8);
    for (int py = 0; py < size; py++)
        for (int px = 0; px < size; px++) {
            double x = 2.0 * (px + 0.5) / size - 1.0, y = 1.0 - 2.0 * (py + 0.5) / size;
            if (x * x + y * y >= 1)
                continue;
            double n[3] = {-x, y, -sqrt(1 - x * x - y * y)}, E[3];
            quadrature_irradiance(&q, n, E);
            double ref = 0.18 / SL_PI * E[0], val = sl_image_pixel(&img, px, py)[0];
            CHECK(val <= 1.02 * peak);
            if (ref > 0.05 * peak)
                worst = fmax(worst, fabs(val - ref) / ref);
        }
    quad_cells_free(&q);
    printf("  1e9 texel: worst lit pixel %.3f%%\n", 100 * worst);
    CHECK(worst < 0.01);
    sl_image_free(&img);
    sl_render_stats_free(&st);
    sl_scene_free(&s);
    sl_image_free(&env);
}

static void test_black_and_bad_domes(void)
{
    sl_image env;
    CHECK_OK(sl_image_alloc(&env, 32, 16, 3, NULL), NULL);
    sl_image_fill(&env, 0);
    sl_scene s;
    sl_scene_init(&s);
    CHECK_OK(sl_scene_preset(&s, "refs", 24, NULL), NULL);
    CHECK_OK(sl_scene_set_dome(&s, &env, 0, 1, "black", NULL), NULL);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 4;
    sl_image img;
    sl_render_stats st;
    render_check_finite(&s, &o, &img, &st);
    CHECK(!st.dome_sampled);
    sl_image_stats is;
    sl_image_stats_compute(&img, &is);
    CHECK(is.max[0] == 0 && is.max[1] == 0 && is.max[2] == 0);
    sl_image_free(&img);
    sl_render_stats_free(&st);

    /* NaN, Inf and negative texels: counted, zeroed, never in the output. */
    sl_image_fill(&env, 1.0f);
    sl_image_pixel(&env, 3, 3)[0] = NAN;
    sl_image_pixel(&env, 7, 9)[2] = INFINITY;
    sl_image_pixel(&env, 20, 5)[1] = -4.0f;
    CHECK_OK(sl_scene_set_dome(&s, &env, 0, 1, "bad", NULL), NULL);
    CHECK(s.dome.bad_texels == 3);
    s.background_env = true;
    render_check_finite(&s, &o, &img, &st);
    CHECK(st.dome_bad_texels == 3);
    sl_image_free(&img);
    sl_render_stats_free(&st);
    sl_scene_free(&s);
    sl_image_free(&env);
}

/* Conductors and plastics from mirror to rough under a sky with a 1e9 texel,
 * at every angle including grazing, with a bounce: finite, and never
 * brighter than the brightest texel. */
static void test_roughness_grid(void)
{
    const double rough[] = {0, 1e-7, 1e-4, 1e-2, 1};
    sl_image env;
    CHECK_OK(sl_image_alloc(&env, 32, 16, 3, NULL), NULL);
    sl_image_fill(&env, 1.0f);
    float *t = sl_image_pixel(&env, 11, 5);
    t[0] = t[1] = t[2] = 1e9f;
    for (size_t i = 0; i < sizeof rough / sizeof rough[0]; i++)
        for (int kind = 0; kind < 2; kind++) {
            sl_scene s;
            sl_scene_init(&s);
            sl_material m;
            double refl[3] = {0.9, 0.9, 0.9}, tint[3] = {1, 1, 1}, c[3] = {0, 0, 0};
            if (kind == 0)
                sl_material_conductor(&m, refl, tint, rough[i]);
            else
                sl_material_plastic(&m, refl, 1.5, rough[i]);
            int mi;
            CHECK_OK(sl_scene_add_material(&s, &m, &mi, NULL), NULL);
            CHECK_OK(sl_scene_add_sphere(&s, c, 1, mi, NULL), NULL);
            /* a ground seen at 0.5 degrees: grazing on the plane as well as at the rim */
            double g[3] = {0, -1, 0}, u[3] = {0, 0, 50}, v[3] = {50, 0, 0};
            CHECK_OK(sl_scene_add_rect(&s, g, u, v, mi, NULL), NULL);
            sl_camera_validation(&s.camera, 16, 16, 3.0, 10, 0.5);
            CHECK_OK(sl_scene_set_dome(&s, &env, 0, 1, "env", NULL), NULL);
            sl_render_options o;
            sl_render_options_init(&o);
            o.spp = 16;
            o.bounces = 1;
            sl_image img;
            sl_render_stats st;
            render_check_finite(&s, &o, &img, &st);
            sl_image_stats is;
            sl_image_stats_compute(&img, &is);
            CHECK_MSG(is.max[0] <= 1e9 && is.min[0] >= 0, "%s roughness %g: range %g..%g",
                      kind ? "plastic" : "conductor", rough[i], is.min[0], is.max[0]);
            sl_image_free(&img);
            sl_render_stats_free(&st);
            sl_scene_free(&s);
        }
    sl_image_free(&env);
}

/* Same bytes for 1, 2 and 3 threads; a different seed changes them. */
static void test_determinism(void)
{
    sl_image env;
    synthetic_env(&env, 32);
    sl_scene s;
    sl_scene_init(&s);
    CHECK_OK(sl_scene_preset(&s, "refs", 40, NULL), NULL);
    CHECK_OK(sl_scene_set_dome(&s, &env, 15, 1, "env", NULL), NULL);
    s.background_env = true;
    sl_light l = {.type = SL_LIGHT_RECT, .width = 1, .height = 0.5, .intensity = 5};
    v3_set(l.position, 0, 3, -2), v3_set(l.axis_z, 0, 1, 0.3), v3_set(l.axis_y, 0, 0, 1);
    v3_set(l.color, 1, 0.9, 0.8);
    CHECK_OK(sl_scene_add_light(&s, &l, NULL), NULL);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 6;
    o.bounces = 1;
    sl_image img[4];
    for (int k = 0; k < 3; k++) {
        sl_threads_set(k + 1);
        CHECK_OK(sl_render(&s, &o, &img[k], NULL, NULL), NULL);
    }
    o.seed = 2;
    CHECK_OK(sl_render(&s, &o, &img[3], NULL, NULL), NULL);
    sl_threads_set(0);
    size_t bytes = (size_t)img[0].height * img[0].stride * sizeof(float);
    CHECK(memcmp(img[0].data, img[1].data, bytes) == 0);
    CHECK(memcmp(img[0].data, img[2].data, bytes) == 0);
    CHECK(memcmp(img[0].data, img[3].data, bytes) != 0);
    for (int k = 0; k < 4; k++)
        sl_image_free(&img[k]);
    sl_scene_free(&s);
    sl_image_free(&env);
}

int main(void)
{
    RUN(test_grey_synthetic);
    RUN(test_grey_real_hdri);
    RUN(test_dome_chi2);
    RUN(test_chrome_highlight);
    RUN(test_mirror_ball_unwraps);
    RUN(test_single_hot_texel);
    RUN(test_black_and_bad_domes);
    RUN(test_roughness_grid);
    RUN(test_determinism);
    return sl_test_finish();
}
