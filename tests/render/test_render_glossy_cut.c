/* SPDX-License-Identifier: BSD-3-Clause */
/* A glossy plan cut by --time. Cut after the coarse pass (plan_row_limit
 * = 1: the full plan stops before any ball row), every cut pixel keeps the
 * coarse pass's closed form (its refinement included), within its reported
 * error estimate of a tight plan; cut inside the coarse pass, after its 8
 * or 4 px blocks, so do those its blocks reached. Cut right after the sun
 * pass (plan_coarse_row_limit = 1, as a budget that ran out there), the
 * coarse pass's first blocks still complete (the same pixels and values as
 * a cut after them), and every pixel they do not cover keeps its sun exact
 * and samples only the rest of the map (the map without the sun's
 * texels): the estimate converges to the uncut closed form (no sun counted
 * twice or missed), and at equal spp its noise is far below the whole-map
 * sampler's. */
#include <stdlib.h>
#include <string.h>

#include "../../render/closed_form.h"
#include "../../render/glossy.h"
#include "setlight/render.h"
#include "testing.h"

#define WIDTH 48

/* A smooth sky (brighter above) and a sun of four texels holding ~90% of
 * the power. */
static void sun_and_sky(sl_image *env)
{
    int w = 256;
    CHECK_OK(sl_image_alloc(env, w, w / 2, 3, NULL), NULL);
    for (int y = 0; y < w / 2; y++)
        for (int x = 0; x < w; x++) {
            float *p = sl_image_pixel(env, x, y);
            double sky = y < w / 4 ? 0.5 + 0.3 * sin(0.05 * x) : 0.1;
            p[0] = (float)sky, p[1] = (float)(0.9 * sky), p[2] = (float)(1.2 * sky);
        }
    for (int k = 0; k < 4; k++) {
        float *s = sl_image_pixel(env, w / 3 + (k & 1), w / 6 + (k >> 1));
        s[0] = s[1] = s[2] = 2e4f;
    }
}

/* sun_and_sky() with a lamp in the rest (below the sun's threshold), whose
 * reflection makes blocks fail their check. */
static void sun_sky_and_lamp(sl_image *env)
{
    sun_and_sky(env);
    for (int y = 20; y < 26; y++)
        for (int x = 150; x < 158; x++) {
            float *p = sl_image_pixel(env, x, y);
            p[0] = p[1] = p[2] = 20.0f;
        }
}

typedef struct cut_case {
    const char *name;
    bool plastic;
    double roughness;
} cut_case;

static void scene_at(sl_scene *s, const sl_image *env, const cut_case *c, int width)
{
    sl_error err = {0};
    sl_scene_init(s);
    CHECK_OK(sl_scene_preset(s, "grey", width, &err), &err);
    CHECK_OK(sl_scene_set_dome(s, env, 0, 1, "sky", &err), &err);
    if (c->plastic)
        sl_material_plastic(&s->materials[0], (const double[3]){0.5, 0.5, 0.5}, 1.5, c->roughness);
    else
        sl_material_conductor(&s->materials[0], (const double[3]){0.9, 0.9, 0.9}, (const double[3]){1, 1, 1},
                              c->roughness);
}

static void scene_for(sl_scene *s, const sl_image *env, const cut_case *c)
{
    scene_at(s, env, c, WIDTH);
}

/* row_limit < 0: the closed form off (the whole map sampled); > 0: the
 * plan and its coarse pass cut there. */
static void render(const sl_scene *s, int64_t spp, int row_limit, sl_image *img, sl_render_stats *st)
{
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = spp;
    o.pixel_centers = true;
    o.closed_form = row_limit >= 0;
    o.plan_row_limit = o.plan_coarse_row_limit = row_limit > 0 ? row_limit : 0;
    sl_error err = {0};
    CHECK_OK(sl_render(s, &o, img, st, &err), &err);
}

typedef struct diff {
    double bias, se, rmse, mean, rms; /* over the ball's pixels: mean difference, its standard
                                         error, RMS difference, the reference's mean and RMS */
    int64_t n;
    bool finite;
} diff;

/* img against ref over the pixels ref covers wholly (the ball). */
static diff compare(const sl_image *img, const sl_image *ref)
{
    diff d = {.finite = true};
    double s = 0, s2 = 0, m = 0, m2 = 0;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            const float *a = sl_image_pixel(img, x, y), *b = sl_image_pixel(ref, x, y);
            if (b[3] < 1)
                continue;
            for (int c = 0; c < 3; c++) {
                d.finite &= isfinite(a[c]) && a[c] >= 0;
                double e = (double)a[c] - b[c];
                s += e, s2 += e * e, m += b[c], m2 += (double)b[c] * b[c];
                d.n++;
            }
        }
    d.bias = s / d.n;
    d.rmse = sqrt(s2 / d.n);
    d.se = sqrt(fmax(0.0, s2 / d.n - d.bias * d.bias) / (d.n - 1));
    d.mean = m / d.n;
    d.rms = sqrt(m2 / d.n);
    return d;
}

static void check_case(const sl_image *env, const cut_case *c)
{
    sl_scene s;
    scene_for(&s, env, c);
    sl_image ref, cut, whole;
    sl_render_stats rs, cs, ws;
    render(&s, 2, 0, &ref, &rs);
    CHECK(rs.closed_form.used && !rs.closed_form.cut_by_time && rs.closed_form.sun_texels == 4);
    int64_t ball = rs.closed_form.exact_pixels;
    CHECK(ball > 1000);

    /* (a) Sun exact, the rest sampled: unbiased, within its own error
     * (fewer samples under sanitizers: the limit follows the standard error). */
    int64_t spp = sl_test_sanitized() ? 64 : 256;
    render(&s, spp, 1, &cut, &cs);
    CHECK(cs.closed_form.cut_by_time);
    /* Row 0 (the limit) is finished; of the other rows' pixels, those the
     * coarse pass's first blocks covered keep their value (metal 0.8: 261;
     * metal 0.3's and plastic 0.4's lobes are too narrow for 16 px blocks
     * at 48 px), the others are sun exact. */
    CHECK_MSG(cs.closed_form.sun_exact_pixels + cs.closed_form.exact_pixels == ball &&
                  cs.closed_form.exact_pixels - cs.closed_form.coarse_pixels <= WIDTH &&
                  cs.closed_form.sun_exact_pixels > ball * 8 / 10 && cs.closed_form.cut_pixels == cs.closed_form.sun_exact_pixels,
              "%s: %lld sun-exact, %lld exact, %lld cut pixels, %lld on the ball", c->name,
              (long long)cs.closed_form.sun_exact_pixels, (long long)cs.closed_form.exact_pixels,
              (long long)cs.closed_form.cut_pixels, (long long)ball);
    diff a = compare(&cut, &ref);
    CHECK(a.finite);
    printf("  %s: sun exact + rest at %lld spp: bias %.4f%% (se %.4f%%), rel RMSE %.3f%% (over the RMS, as "
           "the estimate: %.3f%%; estimate %.3f%%)\n",
           c->name, (long long)spp, 100 * a.bias / a.mean, 100 * a.se / a.mean, 100 * a.rmse / a.mean,
           100 * a.rmse / a.rms,
           100 * cs.passes[cs.pass_count - 1].est_rel_rmse);
    /* The uncut closed form's own error is ~0.1% (its estimate 1%, glossy.c). */
    CHECK_MSG(fabs(a.bias) <= 4 * a.se + 1e-3 * a.mean, "%s: bias %g, se %g", c->name, a.bias, a.se);
    double est = cs.passes[cs.pass_count - 1].est_rel_rmse;
    /* The estimate's normalisation (RMS over RMS); the reference's own
     * error (~0.1-0.3%) comes on top. */
    CHECK_MSG(a.rmse / a.rms < 1.5 * est + 3e-3, "%s: rel RMSE %g above the estimate %g", c->name,
              a.rmse / a.rms, est);

    /* (b) At equal spp the whole map's sampler carries the sun's variance. */
    sl_image_free(&cut);
    sl_render_stats_free(&cs);
    render(&s, 16, 1, &cut, &cs);
    render(&s, 16, -1, &whole, &ws);
    diff b = compare(&cut, &ref), o = compare(&whole, &ref);
    printf("  %s at 16 spp: rest sampled %.3f%%, whole map sampled %.3f%%: %.1fx\n", c->name,
           100 * b.rmse / b.mean, 100 * o.rmse / o.mean, o.rmse / b.rmse);
    CHECK_MSG(o.rmse > 4.0 * b.rmse, "%s: whole map %g vs rest %g", c->name, o.rmse, b.rmse);

    sl_image_free(&ref);
    sl_image_free(&cut);
    sl_image_free(&whole);
    sl_render_stats_free(&rs);
    sl_render_stats_free(&cs);
    sl_render_stats_free(&ws);
    sl_scene_free(&s);
}

/* Cut after the coarse pass: every ball pixel but row 0's keeps the coarse
 * closed form (none sampled), each within its error estimate of a plan at
 * a 10 times tighter tolerance (plus that plan's own estimate). */
static void check_coarse(const sl_image *env, const cut_case *c)
{
    sl_scene s;
    scene_for(&s, env, c);
    sl_render_options o;
    sl_render_options_init(&o);
    o.pixel_centers = true;
    sl_closed_form tight, cut;
    sl_closed_form_stats ts, cs;
    sl_error err = {0};
    o.closed_form_tolerance = 1e-3;
    CHECK_OK(sl_closed_form_plan(&tight, &s, &o, &ts, &err), &err);
    o.closed_form_tolerance = 0;
    o.plan_row_limit = 1;
    CHECK_OK(sl_closed_form_plan(&cut, &s, &o, &cs, &err), &err);
    int64_t ball = ts.exact_pixels, outside = 0;
    CHECK(!ts.cut_by_time && cs.cut_by_time && ball > 1000);
    CHECK_MSG(cs.exact_pixels == ball && cs.cut_pixels == 0 && cs.sun_exact_pixels == 0 &&
                  cs.coarse_pixels > ball * 9 / 10 && cs.coarse_pixels == cs.exact_pixels - cs.at_tolerance_pixels,
              "%s: %lld exact, %lld coarse, %lld at the tolerance, %lld cut of %lld", c->name,
              (long long)cs.exact_pixels, (long long)cs.coarse_pixels, (long long)cs.at_tolerance_pixels,
              (long long)cs.cut_pixels, (long long)ball);
    CHECK(cs.coarse_tolerance == SL_GLOSSY_COARSE * cs.tolerance);
    /* The refinement ran where the coarse pass interpolated (metal 0.3's
     * lobe is too narrow for blocks at 48 px): the pixels with the largest
     * estimates evaluated (each within its estimate, below). */
    CHECK_MSG(cs.interpolated_pixels > 0 ? cs.refined_pixels > 0 : cs.refined_pixels == 0, "%s: %lld refined",
              c->name, (long long)cs.refined_pixels);
    double worst = 0, num = 0, den = 0;
    for (size_t i = 0; i < (size_t)WIDTH * WIDTH; i++) {
        if (tight.mode[i] != SL_PIXEL_EXACT)
            continue;
        CHECK(cut.mode[i] == SL_PIXEL_EXACT);
        for (int k = 0; k < 3; k++) {
            double d = fabs((double)cut.value[i][k] - tight.value[i][k]), b = (double)cut.bound[i][k] + tight.bound[i][k];
            CHECK(isfinite(cut.value[i][k]) && cut.value[i][k] >= 0);
            outside += d > b;
            worst = fmax(worst, d / b);
            num += d * d, den += (double)tight.value[i][k] * tight.value[i][k];
        }
    }
    printf("  %s: %lld of %lld ball pixels coarse (tolerance %g; %lld refined), rel RMSE %.3f%% to the tight "
           "plan at an RMS estimate of %.3f%%; worst %.2f x its estimate\n",
           c->name, (long long)cs.coarse_pixels, (long long)ball, cs.coarse_tolerance, (long long)cs.refined_pixels,
           100 * sqrt(num / den),
           100 * cs.rms_rel_bound, worst);
    CHECK_MSG(outside == 0, "%s: %lld values outside their estimates", c->name, (long long)outside);
    sl_closed_form_free(&tight);
    sl_closed_form_free(&cut);
    sl_scene_free(&s);
}

/* Wide enough for whole 8 px blocks narrow enough for metal 0.3's lobe. */
#define BLOCKS_WIDTH 96

/* Cut in the coarse pass right after its 8 px or its 4 px blocks (as a
 * deadline there): every pixel a whole block covered keeps a closed form
 * (measured at 96 px: 65-90% of the ball after the 4 px blocks),
 * the pixels of a block that failed its check (the lamp's reflection) its
 * interpolation, each within its error estimate of the tight plan (plus
 * that plan's); only pixels no block covered (the rim) are left to
 * sampling, with their sun exact. */
static void check_provisional(const sl_image *env, const cut_case *c)
{
    sl_scene s;
    scene_at(&s, env, c, BLOCKS_WIDTH);
    sl_render_options o;
    sl_render_options_init(&o);
    o.pixel_centers = true;
    sl_closed_form tight;
    sl_closed_form_stats ts;
    sl_error err = {0};
    o.closed_form_tolerance = 1e-3;
    CHECK_OK(sl_closed_form_plan(&tight, &s, &o, &ts, &err), &err);
    o.closed_form_tolerance = 0;
    int64_t ball = ts.exact_pixels, exact_before = 0;
    /* A cut right after the sun pass (row 0 finished): the first (16 px)
     * blocks complete all the same, the same pixels and values as a cut
     * after them. */
    sl_closed_form first, after16;
    sl_closed_form_stats fs, as;
    o.plan_coarse_row_limit = 1;
    CHECK_OK(sl_closed_form_plan(&first, &s, &o, &fs, &err), &err);
    o.plan_coarse_row_limit = 0, o.plan_coarse_block_limit = 16;
    CHECK_OK(sl_closed_form_plan(&after16, &s, &o, &as, &err), &err);
    size_t row1 = BLOCKS_WIDTH, np = (size_t)BLOCKS_WIDTH * BLOCKS_WIDTH;
    int64_t from_blocks = 0;
    for (size_t i = row1; i < np; i++)
        from_blocks += first.mode[i] == SL_PIXEL_EXACT;
    CHECK_MSG(memcmp(first.mode + row1, after16.mode + row1, np - row1) == 0 &&
                  memcmp(first.value + row1, after16.value + row1, (np - row1) * sizeof *first.value) == 0 &&
                  (c->roughness < 0.5 || from_blocks > ball / 4),
              "%s: cut after the sun pass %lld exact, after the 16 px blocks %lld", c->name,
              (long long)fs.exact_pixels, (long long)as.exact_pixels);
    printf("  %s, cut right after the sun pass: %lld of %lld pixels from the first blocks\n", c->name,
           (long long)from_blocks, (long long)ball);
    sl_closed_form_free(&first);
    sl_closed_form_free(&after16);
    for (int size = 8; size >= 4; size /= 2) {
        sl_closed_form cut;
        sl_closed_form_stats cs;
        o.plan_coarse_block_limit = size;
        CHECK_OK(sl_closed_form_plan(&cut, &s, &o, &cs, &err), &err);
        int64_t outside = 0;
        double worst = 0;
        for (size_t i = 0; i < (size_t)BLOCKS_WIDTH * BLOCKS_WIDTH; i++) {
            if (cut.mode[i] != SL_PIXEL_EXACT)
                continue;
            bool out = false;
            for (int k = 0; k < 3; k++) {
                double d = fabs((double)cut.value[i][k] - tight.value[i][k]),
                       b = (double)cut.bound[i][k] + tight.bound[i][k];
                CHECK(isfinite(cut.value[i][k]) && cut.value[i][k] >= 0);
                out |= d > b;
                worst = fmax(worst, d / b);
            }
            outside += out;
        }
        printf("  %s, cut after the %d px blocks: %lld exact (%lld of them a failed block's interpolation), "
               "%lld sun exact of %lld; worst %.2f x its estimate\n",
               c->name, size, (long long)cs.exact_pixels, (long long)cs.provisional_pixels,
               (long long)cs.sun_exact_pixels, (long long)ball, worst);
        /* Metal 0.3's lobe is too narrow for 8 px blocks at this size:
         * its first blocks are of 4 px. Metal 0.8's failed blocks all
         * pass their biquadratic check: none is left provisional. */
        CHECK_MSG(cs.cut_by_time && cs.exact_pixels + cs.sun_exact_pixels == ball &&
                      cs.coarse_pixels == cs.exact_pixels && cs.exact_pixels >= exact_before &&
                      (size > 4 || ((cs.provisional_pixels > 0 || c->roughness >= 0.5) && cs.exact_pixels > ball / 2)),
                  "%s: %lld exact, %lld coarse, %lld provisional, %lld sun exact of %lld", c->name,
                  (long long)cs.exact_pixels, (long long)cs.coarse_pixels, (long long)cs.provisional_pixels,
                  (long long)cs.sun_exact_pixels, (long long)ball);
        CHECK_MSG(outside == 0, "%s: %lld values outside their estimates", c->name, (long long)outside);
        exact_before = cs.exact_pixels;
        sl_closed_form_free(&cut);
    }
    sl_closed_form_free(&tight);
    sl_scene_free(&s);
}

/* Each check under env_of() for metal 0.3, metal 0.8 and plastic 0.4. */
static void for_each_case_under(void (*env_of)(sl_image *env), void (*check)(const sl_image *env, const cut_case *c))
{
    sl_image env;
    env_of(&env);
    const cut_case cases[] = {{"metal 0.3", false, 0.3}, {"metal 0.8", false, 0.8}, {"plastic 0.4", true, 0.4}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++)
        check(&env, &cases[i]);
    sl_image_free(&env);
}

static void test_cut_keeps_the_coarse_pass(void)
{
    for_each_case_under(sun_and_sky, check_coarse);
}

static void test_cut_keeps_failed_blocks(void)
{
    for_each_case_under(sun_sky_and_lamp, check_provisional);
}

static void test_sun_exact_rest_sampled(void)
{
    for_each_case_under(sun_and_sky, check_case);
}

int main(void)
{
    RUN(test_cut_keeps_the_coarse_pass);
    RUN(test_cut_keeps_failed_blocks);
    RUN(test_sun_exact_rest_sampled);
    return sl_test_finish();
}
