/* SPDX-License-Identifier: BSD-3-Clause */
/* --time budgets the whole render, the closed form's set-up included: a
 * plan that would take several budgets is cut short (the rest sampled), the
 * call returns within the budget plus its first pass, and the seconds it
 * reports are the wall time of the call. */
#include <stdlib.h>
#include <string.h>

#include "../../render/closed_form.h"
#include "../../render/scene_internal.h"
#include "testing.h"

/* PLAN_SLACK: how far past its 80% the plan may run: the start-up that
 * always runs (classifying the pixels, the dome's sun/rest split, the
 * Lambert fill's first pass at a coarse tolerance once past the deadline)
 * and the work in flight when the deadline passes, on a machine loaded by
 * other jobs (far slower under ASan: 1.21 s of plan for a 1 s budget at a
 * load of 6 on 2 cores). */
#if defined(__SANITIZE_ADDRESS__)
#define BUDGET 1.0
#define PLAN_SLACK 0.6
#else
#define BUDGET 0.25
#define PLAN_SLACK 0.2
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
    printf("  glossy, --time %.2f: %.3f s wall (plan %.3f s, cut %d; %lld glossy exact px, %lld of them from the "
           "coarse pass, %lld sun exact + rest sampled at %lld spp)\n",
           BUDGET, wall, st.closed_form.seconds, st.closed_form.cut_by_time, (long long)st.closed_form.exact_pixels,
           (long long)st.closed_form.coarse_pixels, (long long)st.closed_form.sun_exact_pixels, (long long)st.spp);
    CHECK(st.closed_form.cut_by_time && !strcmp(st.stop_reason, "time"));
    /* The sun comes first, then the coarse pass (far from finished at this
     * tolerance): every pixel the cut left keeps the coarse pass's closed
     * form or its sun exact. */
    CHECK(st.closed_form.coarse_pixels + st.closed_form.sun_exact_pixels > 0 &&
          st.closed_form.sun_exact_pixels == st.closed_form.cut_pixels && st.spp >= 2);
    CHECK_MSG(wall <= 2 * BUDGET, "%.3f s for a %.2f s budget", wall, BUDGET);
    sl_render_stats_free(&st);
    sl_scene_free(&s);
    sl_image_free(&env);
}

/* Per-pixel closed form of a plan (values, bounds), for comparing a cut
 * plan with the uncut one. */
static void plan(const sl_scene *s, const sl_render_options *o, sl_closed_form *cf, sl_closed_form_stats *st)
{
    sl_error err = {0};
    CHECK_OK(sl_closed_form_plan(cf, s, o, st, &err), &err);
}

/* Relative RMSE of a's closed-form values against b's, and of a's bounds
 * (the same pixels, the same normalisation); counts the pixels where the
 * two differ by more than their two bounds. */
static double compare_plans(const sl_closed_form *a, const sl_closed_form *b, size_t npix, double *rms_bound,
                            int64_t *outside)
{
    double num = 0, den = 0, bnum = 0;
    *outside = 0;
    for (size_t i = 0; i < npix; i++) {
        if (a->mode[i] == SL_PIXEL_SAMPLED || b->mode[i] == SL_PIXEL_SAMPLED)
            continue;
        for (int c = 0; c < 3; c++) {
            double d = (double)a->value[i][c] - b->value[i][c];
            num += d * d;
            den += (double)b->value[i][c] * b->value[i][c];
            bnum += (double)a->bound[i][c] * a->bound[i][c];
            *outside += fabs(d) > (double)a->bound[i][c] + b->bound[i][c] + 1e-6 * b->value[i][c];
        }
    }
    *rms_bound = den > 0 ? sqrt(bnum / den) : 0;
    return den > 0 ? sqrt(num / den) : 0;
}

/* A plan cut part-way (plan_eval_limit: the deterministic stand-in for the
 * deadline) still gives every closed-form pixel its closed form: the
 * coarse pass's interpolation, refined where it had time. No pixel falls
 * back to sampling; each is within its reported bound of the uncut plan
 * (plus the uncut plan's own bound), the bound says more than the uncut
 * one, and the cut plan is the same bytes on any thread count. */
static void test_cut_keeps_every_pixel(void)
{
    enum { W = 64, LIMIT = 40 };
    sl_image env;
    sl_scene s;
    sky(&env, 256);
    sl_scene_init(&s);
    sl_error err = {0};
    CHECK_OK(sl_scene_preset(&s, "grey", W, &err), &err);
    CHECK_OK(sl_scene_set_dome(&s, &env, 0, 1, "sky", &err), &err);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 2;
    sl_closed_form whole, cut, cut1;
    sl_closed_form_stats a, b, b1;
    int threads = sl_threads_get();
    sl_threads_set(1);
    plan(&s, &o, &whole, &a);
    o.plan_eval_limit = LIMIT;
    plan(&s, &o, &cut1, &b1);
    sl_threads_set(2);
    plan(&s, &o, &cut, &b);
    sl_threads_set(threads);
    size_t npix = (size_t)W * W;
    double rms_bound;
    int64_t outside;
    double rmse = compare_plans(&cut, &whole, npix, &rms_bound, &outside);
    printf("  uncut: %lld exact, %lld evaluations, rms bound %.3g%%; cut after %d: %lld exact, %lld at the "
           "tolerance, rms bound %.3g%% (max %.3g%%), actual rel RMSE %.3g%%, %lld values outside their bounds\n",
           (long long)a.exact_pixels, (long long)a.evaluations, 100 * a.rms_rel_bound, LIMIT,
           (long long)b.exact_pixels, (long long)b.at_tolerance_pixels, 100 * b.rms_rel_bound,
           100 * b.max_rel_bound, 100 * rmse, (long long)outside);
    CHECK(!a.cut_by_time && a.at_tolerance_pixels == a.exact_pixels && a.exact_pixels > W * W / 2);
    CHECK(b.cut_by_time && b.cut_pixels == 0);
    /* Every pixel keeps its closed form; some short of the tolerance. */
    CHECK(b.exact_pixels == a.exact_pixels && b.sampled_pixels == a.sampled_pixels);
    CHECK(b.at_tolerance_pixels < b.exact_pixels);
    CHECK(b.rms_rel_bound > a.rms_rel_bound);
    CHECK_MSG(outside == 0, "%lld values outside their bounds", (long long)outside);
    /* The bound is an upper estimate, and small after the first pass. */
    CHECK(rmse <= rms_bound);
    CHECK_MSG(b.rms_rel_bound < 0.03, "rms bound %.3g", b.rms_rel_bound);
    CHECK_MSG(!memcmp(cut.value, cut1.value, npix * sizeof *cut.value) &&
                  !memcmp(cut.bound, cut1.bound, npix * sizeof *cut.bound),
              "the cut plan depends on the thread count");
    sl_closed_form_free(&whole);
    sl_closed_form_free(&cut);
    sl_closed_form_free(&cut1);
    sl_scene_free(&s);
    sl_image_free(&env);
}

/* A budget cut right after the coarse pass, on a real map: the grey ball's
 * closed form is still within COARSE_RMSE of the uncut plan. */
#define COARSE_RMSE 0.005
static void test_coarse_pass_on_a_real_map(void)
{
    const char *dir = sl_test_data("hdri");
    if (!dir)
        return;
    char path[4200];
    snprintf(path, sizeof path, "%.4000s/rooitou_park_1k.hdr", dir);
    sl_image env;
    sl_error err = {0};
    if (sl_latlong_read(path, NULL, &env, NULL, NULL, &err)) {
        printf("  skipped: %s\n", err.message);
        return;
    }
    /* Sanitizers run ~20x slower: a quarter of the pixels. */
    const int W = sl_test_sanitized() ? 64 : 128;
    sl_scene s;
    sl_scene_init(&s);
    CHECK_OK(sl_scene_preset(&s, "grey", W, &err), &err);
    CHECK_OK(sl_scene_set_dome(&s, &env, 0, 1, "rooitou_park", &err), &err);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 2;
    sl_closed_form whole, cut;
    sl_closed_form_stats a, b;
    plan(&s, &o, &whole, &a);
    o.plan_eval_limit = 1; /* the first batch after the coarse pass */
    plan(&s, &o, &cut, &b);
    double rms_bound;
    int64_t outside;
    double rmse = compare_plans(&cut, &whole, (size_t)W * W, &rms_bound, &outside);
    printf("  rooitou_park %d px, cut after the coarse pass: rel RMSE %.3g%% (bound: rms %.3g%%, max %.3g%%), "
           "%lld values outside their bounds; %lld of %lld evaluations\n",
           W, 100 * rmse, 100 * rms_bound, 100 * b.max_rel_bound, (long long)outside, (long long)b.evaluations,
           (long long)a.evaluations);
    CHECK(b.cut_by_time && b.exact_pixels == a.exact_pixels);
    CHECK_MSG(rmse <= COARSE_RMSE, "rel RMSE %.3g", rmse);
    CHECK(rmse <= rms_bound);
    CHECK_MSG(outside == 0, "%lld values outside their bounds", (long long)outside);
    sl_closed_form_free(&whole);
    sl_closed_form_free(&cut);
    sl_scene_free(&s);
    sl_image_free(&env);
}

int main(void)
{
    RUN(test_time_counts_the_closed_form);
    RUN(test_time_counts_the_glossy_fill);
    RUN(test_cut_keeps_every_pixel);
    RUN(test_coarse_pass_on_a_real_map);
    return sl_test_finish();
}
