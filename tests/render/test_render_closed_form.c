/* SPDX-License-Identifier: BSD-3-Clause */
/* The renderer's closed form (render/closed_form.c): exact where an
 * unoccluded Lambert object sees the dome alone, a control variate where
 * other objects may shadow it, sampling everywhere else. Known answers:
 * a uniform dome, a brute-force quadrature of real HDRIs (the goal:
 * grey sphere 96 px, --time 1, relative RMSE <= 0.5%), and the sampled
 * renderer at high spp. */
#include <dirent.h>
#include <stdlib.h>
#include <string.h>

#include "../../render/scene_internal.h"
#include "../../render/vec3.h"
#include "setlight/render.h"
#include "sun_sky.h"
#include "testing.h"

/* Smooth sky, a sun 1e4 in two texels and a dark ground: sampling's worst case. */
static void sun_sky(sl_image *env, int w)
{
    sky_over_ground(env, w);
    for (int k = 0; k < 2; k++) {
        float *s = sl_image_pixel(env, w / 2 - w / 8 + k, w / 8);
        s[0] = 1.2e4f, s[1] = 1.0e4f, s[2] = 0.8e4f;
    }
}

static void scene_turned(sl_scene *s, const char *preset, int width, const sl_image *env,
                         double rotation, double intensity)
{
    sl_error err = {0};
    sl_scene_init(s);
    CHECK_OK(sl_scene_preset(s, preset, width, &err), &err);
    CHECK_OK(sl_scene_set_dome(s, env, rotation, intensity, "env", &err), &err);
}

static void scene_with(sl_scene *s, const char *preset, int width, const sl_image *env)
{
    scene_turned(s, preset, width, env, 0, 1);
}

/* Brute-force irradiance: every texel at its centre direction with its
 * exact solid angle; texels the horizon may cut split 4 x 4. Independent of
 * the closed form's cell sums and bounds. */
typedef struct brute {
    int w, h;
    float (*dir)[3];
    float (*pw)[3]; /* L x solid angle */
    const sl_image *env;
} brute;

static void brute_init(brute *b, const sl_image *env)
{
    b->w = env->width, b->h = env->height, b->env = env;
    size_t n = (size_t)b->w * b->h;
    b->dir = malloc(n * sizeof *b->dir);
    b->pw = malloc(n * sizeof *b->pw);
    for (int y = 0; y < b->h; y++) {
        double om = (cos(SL_PI * y / b->h) - cos(SL_PI * (y + 1) / b->h)) * 2 * SL_PI / b->w;
        for (int x = 0; x < b->w; x++) {
            double d[3];
            sl_latlong_to_dir((x + 0.5) / b->w, (y + 0.5) / b->h, d);
            const float *L = sl_image_pixel(env, x, y);
            for (int c = 0; c < 3; c++) {
                b->dir[(size_t)y * b->w + x][c] = (float)d[c];
                b->pw[(size_t)y * b->w + x][c] = (float)(L[c] * om);
            }
        }
    }
}

static void brute_free(brute *b)
{
    free(b->dir);
    free(b->pw);
}

static void brute_irradiance(const brute *b, const double n[3], double E[3])
{
    double near = 0.8 * SL_PI / b->h; /* beyond a texel's half diagonal */
    double acc[3] = {0, 0, 0};
    for (int y = 0; y < b->h; y++)
        for (int x = 0; x < b->w; x++) {
            size_t i = (size_t)y * b->w + x;
            double c = n[0] * b->dir[i][0] + n[1] * b->dir[i][1] + n[2] * b->dir[i][2];
            if (c > near) {
                for (int k = 0; k < 3; k++)
                    acc[k] += b->pw[i][k] * c;
            } else if (c > -near) {
                const float *L = sl_image_pixel(b->env, x, y);
                for (int sy = 0; sy < 4; sy++) {
                    double v0 = (y + sy / 4.0) / b->h, v1 = (y + (sy + 1) / 4.0) / b->h;
                    double om = (cos(SL_PI * v0) - cos(SL_PI * v1)) * 2 * SL_PI / (4.0 * b->w);
                    for (int sx = 0; sx < 4; sx++) {
                        double d[3];
                        sl_latlong_to_dir((x + (sx + 0.5) / 4) / b->w, 0.5 * (v0 + v1), d);
                        double cc = v3_dot(n, d);
                        if (cc > 0)
                            for (int k = 0; k < 3; k++)
                                acc[k] += L[k] * om * cc;
                    }
                }
            }
        }
    for (int k = 0; k < 3; k++)
        E[k] = acc[k];
}

/* Relative RMSE of the grey sphere's pixel centres against brute force,
 * over every stride-th pixel on the ball. */
static double grey_vs_brute(const sl_image *img, const sl_image *env, int stride)
{
    brute b;
    brute_init(&b, env);
    int size = img->width;
    double num = 0, den = 0;
    for (int py = stride / 2; py < size; py += stride)
        for (int px = stride / 2; px < size; px += stride) {
            double x = 2.0 * (px + 0.5) / size - 1.0, y = 1.0 - 2.0 * (py + 0.5) / size;
            double r2 = x * x + y * y;
            if (r2 >= 1.0)
                continue;
            double n[3] = {-x, y, -sqrt(1.0 - r2)}, E[3];
            brute_irradiance(&b, n, E);
            const float *p = sl_image_pixel(img, px, py);
            for (int c = 0; c < 3; c++) {
                double ref = 0.18 / SL_PI * E[c];
                num += (p[c] - ref) * (p[c] - ref);
                den += ref * ref;
            }
        }
    brute_free(&b);
    return sqrt(num / den);
}

/* A uniform dome: every pixel wholly on the ball is exactly 0.18 L. */
static void test_uniform_dome(void)
{
    sl_image env;
    CHECK_OK(sl_image_alloc(&env, 64, 32, 3, NULL), NULL);
    for (int y = 0; y < 32; y++)
        for (int x = 0; x < 64; x++) {
            float *p = sl_image_pixel(&env, x, y);
            p[0] = 1, p[1] = 2, p[2] = 0.5f;
        }
    sl_scene s;
    scene_with(&s, "grey", 24, &env);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 16;
    sl_image img;
    sl_render_stats st;
    sl_error err = {0};
    CHECK_OK(sl_render(&s, &o, &img, &st, &err), &err);
    CHECK(st.closed_form.used && st.closed_form.exact_pixels > 300);
    CHECK(st.closed_form.control_variate_pixels == 0);
    double worst = 0;
    for (int y = 0; y < 24; y++)
        for (int x = 0; x < 24; x++)
            if (x > 0 && y > 0 && x < 23 && y < 23) {
                /* pixel wholly on the ball: its four corners inside the disc */
                bool inside = true;
                for (int c = 0; c < 4; c++) {
                    double u = 2.0 * (x + (c & 1)) / 24 - 1, v = 2.0 * (y + (c >> 1)) / 24 - 1;
                    inside = inside && u * u + v * v < 1;
                }
                if (!inside)
                    continue;
                const float *p = sl_image_pixel(&img, x, y);
                double want[3] = {0.18, 0.36, 0.09};
                for (int c = 0; c < 3; c++)
                    worst = fmax(worst, fabs(p[c] - want[c]) / want[c]);
                CHECK(p[3] == 1);
            }
    printf("  uniform dome: worst pixel %.2e of 0.18 L, bound %.2e, %lld exact pixels\n", worst,
           st.closed_form.max_rel_bound, (long long)st.closed_form.exact_pixels);
    CHECK(worst < 1e-4);
    CHECK(worst <= st.closed_form.max_rel_bound + 1e-6);
    sl_image_free(&img);
    sl_render_stats_free(&st);
    sl_scene_free(&s);
    sl_image_free(&env);
}

/* The goal: grey sphere 96 px under each real HDRI with a 1 s
 * budget, relative RMSE against brute force <= 0.5%. */
static void test_real_hdri_goal(void)
{
    const char *dir = sl_test_data("hdri");
    if (!dir)
        return;
    DIR *d = opendir(dir);
    CHECK(d != NULL);
    if (!d)
        return;
    char names[64][256];
    int count = 0;
    struct dirent *e;
    while ((e = readdir(d)) && count < 64) {
        size_t n = strlen(e->d_name);
        if (n > 4 && !strcmp(e->d_name + n - 4, ".hdr"))
            snprintf(names[count++], sizeof names[0], "%s", e->d_name);
    }
    closedir(d);
    qsort(names, (size_t)count, sizeof names[0], (int (*)(const void *, const void *))strcmp);
    /* Sanitizers run ~20x slower: two maps, fewer pixels; the same bound. */
    int stride = sl_test_sanitized() ? 12 : 7, tested = 0;
    if (sl_test_sanitized() && count > 2)
        count = 2;
    double worst = 0;
    for (int i = 0; i < count; i++) {
        char path[4400];
        snprintf(path, sizeof path, "%.4000s/%.255s", dir, names[i]);
        sl_image env;
        sl_error err = {0};
        if (sl_latlong_read(path, NULL, &env, NULL, NULL, &err) != SL_OK)
            continue; /* not a lat-long (an angular map) */
        sl_scene s;
        scene_with(&s, "grey", 96, &env);
        sl_render_options o;
        sl_render_options_init(&o);
        o.spp = 0;
        o.time_limit = 1;
        o.pixel_centers = true;
        sl_image img;
        sl_render_stats st;
        CHECK_OK(sl_render(&s, &o, &img, &st, &err), &err);
        if (st.closed_form.cut_by_time) {
            /* --time counts the closed form's set-up: on a loaded machine
             * the plan runs out of the second (test_render_time checks the
             * budget); the accuracy is checked with the time it needs. */
            printf("  %s: plan cut by --time 1 after %.2f s (CPU %.2f s): loaded machine, goal checked "
                   "with the plan whole (no --time, 2 spp)\n", names[i], st.closed_form.seconds,
                   st.cpu_seconds);
            sl_image_free(&img);
            sl_render_stats_free(&st);
            o.time_limit = 0;
            o.spp = 2;
            CHECK_OK(sl_render(&s, &o, &img, &st, &err), &err);
        }
        double rmse = grey_vs_brute(&img, &env, stride);
        printf("  %-28s %dx%d: rel RMSE %.4f%% (bound %.2f%%, %lld exact px, finest level %d, %.2f s)\n",
               names[i], env.width, env.height, 100 * rmse, 100 * st.closed_form.max_rel_bound,
               (long long)st.closed_form.exact_pixels, st.closed_form.finest_level, st.seconds);
        CHECK_MSG(rmse <= 0.005, "%s: %.4f%%", names[i], 100 * rmse);
        CHECK(st.closed_form.sampled_pixels + st.closed_form.exact_pixels == 96 * 96);
        worst = fmax(worst, rmse);
        tested++;
        sl_image_free(&img);
        sl_render_stats_free(&st);
        sl_scene_free(&s);
        sl_image_free(&env);
    }
    printf("  %d maps, worst %.4f%%\n", tested, 100 * worst);
    CHECK(tested > 0);
}

/* Closed form and the sampled renderer agree within the sampled render's
 * own error estimate (plus the closed form's bound), box filter and pixel
 * centres, on the grey ball and on the shadow scene (control variate). */
static void agree(const char *preset, int width, bool centres, int64_t spp, double rotation)
{
    sl_image env;
    sun_sky(&env, 64);
    sl_scene s;
    scene_turned(&s, preset, width, &env, rotation, 2.0);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = spp;
    o.pixel_centers = centres;
    sl_image a, b;
    sl_render_stats sa, sb;
    sl_error err = {0};
    CHECK_OK(sl_render(&s, &o, &a, &sa, &err), &err);
    o.closed_form = false;
    CHECK_OK(sl_render(&s, &o, &b, &sb, &err), &err);
    CHECK(!sb.closed_form.used && !strcmp(sb.closed_form.reason, "off"));
    CHECK(sa.closed_form.used);
    if (!strcmp(preset, "shadow")) /* no bounces: the shadowed part computed (shadow_fill.c) */
        CHECK(sa.closed_form.control_variate_pixels == 0 && sa.closed_form.shadow_exact_pixels > 0);
    double diff;
    CHECK_OK(sl_relative_rmse(&a, &b, &diff, &err), &err);
    double est_b = sb.passes[sb.pass_count - 1].est_rel_rmse;
    double est_a = sa.passes[sa.pass_count - 1].est_rel_rmse;
    printf("  %s %d px%s, dome turned %g: closed form vs sampled %.3f%%; sampled's estimate %.3f%%, closed form's "
           "%.3f%% (%lld exact, %lld of them shadowed, %lld control variate, %lld sampled px)\n",
           preset, width, centres ? " (centres)" : "", rotation, 100 * diff, 100 * est_b, 100 * est_a,
           (long long)sa.closed_form.exact_pixels, (long long)sa.closed_form.shadow_exact_pixels,
           (long long)sa.closed_form.control_variate_pixels, (long long)sa.closed_form.sampled_pixels);
    /* Two independent errors: the sampled render's noise, and the closed
     * form's own (its sampled part, its proven bound: far above its true
     * error, so a quarter of it is allowed). */
    double est_a_noise = sa.closed_form.max_rel_bound > 0 ? est_a * 0.25 : est_a;
    CHECK_MSG(diff <= 2.0 * sqrt(est_a_noise * est_a_noise + est_b * est_b),
              "%s: difference %.4f%% above the estimates", preset, 100 * diff);
    sl_image_free(&a);
    sl_image_free(&b);
    sl_render_stats_free(&sa);
    sl_render_stats_free(&sb);
    sl_scene_free(&s);
    sl_image_free(&env);
}

static void test_agrees_with_sampling(void)
{
    int64_t spp = sl_test_sanitized() ? 1024 : 4096;
    agree("grey", 24, false, spp, 0);
    agree("grey", 24, true, spp, 0);
    agree("grey", 24, true, spp, 90); /* the sun moves to the ball's side */
    agree("shadow", 24, false, spp, 0);
    agree("shadow", 24, true, spp, 0);
    agree("shadow", 24, true, spp, 120); /* the sun's shadow elsewhere on the ground */
}

/* Where the closed form does not apply, every pixel is sampled as before:
 * rig lights, a delta (mirror) material, another strategy. */
static void test_sampler_kept(void)
{
    sl_image env;
    sun_sky(&env, 32);
    sl_error err = {0};
    for (int k = 0; k < 4; k++) {
        sl_scene s;
        scene_with(&s, k == 1 ? "chrome" : "grey", 8, &env);
        sl_render_options o;
        sl_render_options_init(&o);
        o.spp = 4;
        const char *want = "no dome and no light with a closed form (textured rects are sampled)";
        if (k == 0) {
            /* A textured rect alone: its light has no closed form. */
            sl_light l;
            memset(&l, 0, sizeof l);
            l.type = SL_LIGHT_RECT;
            v3_set(l.position, 0, 3, 0);
            v3_set(l.axis_z, 0, 1, 0);
            v3_set(l.axis_y, 0, 0, 1);
            v3_set(l.color, 1, 1, 1);
            l.intensity = 1;
            l.width = l.height = 1;
            CHECK_OK(sl_image_alloc(&l.texture, 2, 2, 3, NULL), NULL);
            for (int t = 0; t < 12; t++)
                l.texture.data[t] = (float)(1 + t % 3);
            sl_dome_free(&s.dome);
            CHECK_OK(sl_scene_add_light(&s, &l, &err), &err);
        } else if (k == 1) {
            want = "no Lambert or rough glossy object";
        } else if (k == 2) {
            /* A smooth coat: its mirror lobe is a delta, sampled. */
            sl_material_plastic(&s.materials[0], (const double[3]){0.5, 0.5, 0.5}, 1.5, 0.0);
            want = "no Lambert or rough glossy object";
        } else {
            o.strategy = SL_STRATEGY_BSDF;
            want = "strategy is not mis";
        }
        sl_image img;
        sl_render_stats st;
        CHECK_OK(sl_render(&s, &o, &img, &st, &err), &err);
        CHECK_MSG(!st.closed_form.used && !strcmp(st.closed_form.reason, want), "case %d: %s", k,
                  st.closed_form.reason);
        CHECK(st.closed_form.exact_pixels == 0 && st.closed_form.sampled_pixels == 64);
        CHECK(st.camera_rays == 4 * 64);
        sl_image_free(&img);
        sl_render_stats_free(&st);
        sl_scene_free(&s);
    }
    sl_image_free(&env);
}

int main(void)
{
    RUN(test_uniform_dome);
    RUN(test_agrees_with_sampling);
    RUN(test_sampler_kept);
    RUN(test_real_hdri_goal);
    return sl_test_finish();
}
