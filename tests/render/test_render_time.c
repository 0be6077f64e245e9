/* SPDX-License-Identifier: BSD-3-Clause */
/* --time budgets the whole render, the closed form's set-up included: a
 * plan that would take several budgets is cut short (the rest sampled), the
 * call returns within the budget plus its first pass, and the seconds it
 * reports are the wall time of the call. */
#include <stdlib.h>
#include <string.h>

#include "../../render/scene_internal.h"
#include "testing.h"

/* PLAN_SLACK: how far past its 80% the plan may run, the time of the rows
 * in flight when the deadline passes (a row is far slower under ASan). */
#if defined(__SANITIZE_ADDRESS__)
#define BUDGET 1.0
#define PLAN_SLACK 0.4
#else
#define BUDGET 0.25
#define PLAN_SLACK 0.1
#endif

/* A sky with a sun of four texels: the closed form splits cells around it. */
static void sky(sl_image *env, int w)
{
    CHECK_OK(sl_image_alloc(env, w, w / 2, 3, NULL), NULL);
    for (int y = 0; y < w / 2; y++)
        for (int x = 0; x < w; x++) {
            float *p = sl_image_pixel(env, x, y);
            p[0] = p[1] = p[2] = (float)(y < w / 4 ? 0.5 + 0.4 * sin(0.1 * x) : 0.05);
        }
    for (int k = 0; k < 4; k++) {
        float *s = sl_image_pixel(env, w / 3 + (k & 1), w / 6 + (k >> 1));
        s[0] = s[1] = s[2] = 2e4f;
    }
}

/* The grey preset, 160 px, under sky(): with a tight tolerance its plan
 * takes about 9 CPU seconds (2026-11-28), far over the budget. */
static void grey_ball_under_sky(sl_scene *s, sl_image *env)
{
    sky(env, 512);
    sl_scene_init(s);
    sl_error err = {0};
    CHECK_OK(sl_scene_preset(s, "grey", 160, &err), &err);
    CHECK_OK(sl_scene_set_dome(s, env, 0, 1, "sky", &err), &err);
}

static double render_timed(const sl_scene *s, sl_render_options *o, sl_render_stats *st)
{
    sl_image img;
    sl_error err = {0};
    double t0 = sl_seconds();
    CHECK_OK(sl_render(s, o, &img, st, &err), &err);
    double wall = sl_seconds() - t0;
    int bad = 0;
    for (size_t i = 0; i < (size_t)img.width * img.height * 4; i++)
        bad += !(isfinite(img.data[i]) && img.data[i] >= 0);
    CHECK(bad == 0);
    sl_image_free(&img);
    return wall;
}

static void test_time_counts_the_closed_form(void)
{
    sl_image env;
    sl_scene s;
    grey_ball_under_sky(&s, &env);
    sl_render_options o;
    sl_render_options_init(&o);
    o.closed_form_tolerance = 1e-4;
    o.spp = 0;
    o.time_limit = BUDGET;
    sl_render_stats st;
    double wall = render_timed(&s, &o, &st);
    const sl_render_pass *last = &st.passes[st.pass_count - 1];
    printf("  --time %.2f: %.3f s wall, reported %.3f s (plan %.3f s, cut %d; %lld exact, %lld sampled "
           "px; %lld spp)\n",
           BUDGET, wall, st.seconds, st.closed_form.seconds, st.closed_form.cut_by_time,
           (long long)st.closed_form.exact_pixels, (long long)st.closed_form.sampled_pixels,
           (long long)st.spp);
    /* The reported time is the call's wall time. */
    CHECK_NEAR(st.seconds, wall, 0.02 + 0.02 * wall);
    CHECK(last->seconds <= st.seconds + 1e-9);
    /* Cut at 80% of the budget; the first pass (2 spp) may add its own time. */
    CHECK(st.closed_form.cut_by_time && !strcmp(st.stop_reason, "time"));
    CHECK(st.closed_form.seconds <= 0.8 * BUDGET + PLAN_SLACK);
    CHECK_MSG(wall <= 2 * BUDGET, "%.3f s for a %.2f s budget", wall, BUDGET);
    CHECK(st.closed_form.exact_pixels + st.closed_form.sampled_pixels == 160 * 160);
    sl_render_stats_free(&st);
    sl_scene_free(&s);
    sl_image_free(&env);
}

/* The glossy quadrature (filled after the plan) keeps to the budget too. */
static void test_time_counts_the_glossy_fill(void)
{
    sl_image env;
    sl_scene s;
    grey_ball_under_sky(&s, &env);
    sl_material_conductor(&s.materials[0], (const double[3]){0.9, 0.9, 0.9},
                          (const double[3]){0.9, 0.9, 0.9}, 0.3);
    sl_render_options o;
    sl_render_options_init(&o);
    o.pixel_centers = true;
    o.closed_form_tolerance = 1e-4;
    o.spp = 0;
    o.time_limit = BUDGET;
    sl_render_stats st;
    double wall = render_timed(&s, &o, &st);
    printf("  glossy, --time %.2f: %.3f s wall (plan %.3f s, cut %d; %lld glossy exact px)\n", BUDGET,
           wall, st.closed_form.seconds, st.closed_form.cut_by_time,
           (long long)st.closed_form.exact_pixels);
    CHECK(st.closed_form.cut_by_time && !strcmp(st.stop_reason, "time"));
    CHECK_MSG(wall <= 2 * BUDGET, "%.3f s for a %.2f s budget", wall, BUDGET);
    sl_render_stats_free(&st);
    sl_scene_free(&s);
    sl_image_free(&env);
}

/* A plan cut part-way keeps what it finished: the rows before the cut are
 * exact and the same bytes as the uncut render's (any thread count), the
 * rest is sampled, and the stats count both. plan_row_limit cuts the plan
 * at a fixed row, as the deadline would, so the test does not depend on the
 * machine's speed. */
static void test_cut_keeps_finished_rows(void)
{
    enum { W = 64, LIMIT = 24 };
    sl_image env, whole, cut;
    sl_scene s;
    sky(&env, 256);
    sl_scene_init(&s);
    sl_error err = {0};
    CHECK_OK(sl_scene_preset(&s, "grey", W, &err), &err);
    CHECK_OK(sl_scene_set_dome(&s, &env, 0, 1, "sky", &err), &err);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 2;
    sl_render_stats st_whole, st_cut;
    int threads = sl_threads_get();
    sl_threads_set(1);
    CHECK_OK(sl_render(&s, &o, &whole, &st_whole, &err), &err);
    sl_threads_set(2);
    o.plan_row_limit = LIMIT;
    CHECK_OK(sl_render(&s, &o, &cut, &st_cut, &err), &err);
    sl_threads_set(threads);
    const sl_closed_form_stats *a = &st_whole.closed_form, *b = &st_cut.closed_form;
    printf("  uncut: %lld exact; cut at row %d: %lld exact (%lld interpolated), %lld cut, %lld sampled; "
           "est. error %.3g%% against %.3g%%\n",
           (long long)a->exact_pixels, LIMIT, (long long)b->exact_pixels, (long long)b->interpolated_pixels,
           (long long)b->cut_pixels, (long long)b->sampled_pixels,
           100 * st_cut.passes[st_cut.pass_count - 1].est_rel_rmse,
           100 * st_whole.passes[st_whole.pass_count - 1].est_rel_rmse);
    CHECK(!a->cut_by_time && a->cut_pixels == 0 && a->exact_pixels > W * W / 2);
    CHECK(b->cut_by_time);
    /* The ball's rows above the cut: about LIMIT / W of its pixels. */
    CHECK(b->exact_pixels > a->exact_pixels / 5 && b->exact_pixels < a->exact_pixels / 2);
    CHECK(b->interpolated_pixels > 0 && b->interpolated_pixels <= b->exact_pixels);
    CHECK_MSG(b->exact_pixels + b->cut_pixels == a->exact_pixels, "%lld + %lld != %lld",
              (long long)b->exact_pixels, (long long)b->cut_pixels, (long long)a->exact_pixels);
    CHECK(b->exact_pixels + b->sampled_pixels == W * W);
    /* Rows before the cut are byte-identical (the row just above it takes
     * its box filter from a 3 x 3 grid, its neighbours below being cut);
     * rows after it are sampled, at 2 spp far from the closed form. */
    size_t kept_diff = 0, after_diff = 0;
    for (int y = 0; y < W; y++)
        for (int x = 0; x < W; x++)
            for (int c = 0; c < 4; c++) {
                float u = sl_image_pixel(&whole, x, y)[c], v = sl_image_pixel(&cut, x, y)[c];
                if (y < LIMIT - 1)
                    kept_diff += memcmp(&u, &v, sizeof u) != 0;
                else if (y >= LIMIT)
                    after_diff += u != v;
            }
    CHECK_MSG(kept_diff == 0, "%zu values of the finished rows differ", kept_diff);
    CHECK(after_diff > 0);
    /* The estimate stays an upper estimate: more than the uncut render's. */
    CHECK(st_cut.passes[st_cut.pass_count - 1].est_rel_rmse >
          st_whole.passes[st_whole.pass_count - 1].est_rel_rmse);
    sl_image_free(&whole);
    sl_image_free(&cut);
    sl_render_stats_free(&st_whole);
    sl_render_stats_free(&st_cut);
    sl_scene_free(&s);
    sl_image_free(&env);
}

int main(void)
{
    RUN(test_time_counts_the_closed_form);
    RUN(test_time_counts_the_glossy_fill);
    RUN(test_cut_keeps_finished_rows);
    return sl_test_finish();
}
