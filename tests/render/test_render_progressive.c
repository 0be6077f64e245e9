/* SPDX-License-Identifier: BSD-3-Clause */
/* Progressive rendering: stop conditions, the half-buffer error estimate
 * against the true error, stats JSON, option and scene-file validation,
 * perspective and fisheye cameras. */
#include <jansson.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/render.h"
#include "testing.h"

static void sky(sl_image *env)
{
    CHECK_OK(sl_image_alloc(env, 32, 16, 3, NULL), NULL);
    for (int y = 0; y < 16; y++)
        for (int x = 0; x < 32; x++) {
            float *p = sl_image_pixel(env, x, y);
            p[0] = p[1] = p[2] = (float)(0.2 + (y < 8 ? 1.0 : 0.1) + (x == 9 && y == 4 ? 400 : 0));
        }
}

static void grey_scene(sl_scene *s, int width)
{
    sl_image env;
    sky(&env);
    sl_scene_init(s);
    CHECK_OK(sl_scene_preset(s, "grey", width, NULL), NULL);
    CHECK_OK(sl_scene_set_dome(s, &env, 0, 1, "sky", NULL), NULL);
    sl_image_free(&env);
}

static void test_stop_conditions(void)
{
    sl_scene s;
    grey_scene(&s, 16);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 0;
    o.target_error = 0.01;
    sl_image img;
    sl_render_stats st;
    sl_error err = {0};
    CHECK_OK(sl_render(&s, &o, &img, &st, &err), &err);
    CHECK(!strcmp(st.stop_reason, "target-error"));
    CHECK(st.passes[st.pass_count - 1].est_rel_rmse <= 0.01);
    CHECK(st.pass_count < 2 || st.passes[st.pass_count - 2].est_rel_rmse > 0.01);
    for (int k = 0; k < st.pass_count; k++)
        CHECK((st.passes[k].spp & (st.passes[k].spp - 1)) == 0); /* powers of two */
    sl_image_free(&img);
    sl_render_stats_free(&st);

    o.target_error = 0;
    o.time_limit = 0.15;
    double t0 = sl_seconds();
    CHECK_OK(sl_render(&s, &o, &img, &st, &err), &err);
    double took = sl_seconds() - t0;
    CHECK(!strcmp(st.stop_reason, "time"));
    CHECK(took < 1.0);
    CHECK(st.spp >= 2);
    sl_image_free(&img);
    sl_render_stats_free(&st);

    o.time_limit = 0;
    o.spp = 7; /* rounded up to even */
    CHECK_OK(sl_render(&s, &o, &img, &st, &err), &err);
    CHECK(st.spp == 8 && !strcmp(st.stop_reason, "spp"));
    /* Exact pixels (the ball's inside, closed form) trace no camera rays. */
    CHECK(st.closed_form.used && st.closed_form.exact_pixels > 100);
    CHECK(st.closed_form.exact_pixels + st.closed_form.sampled_pixels == 16 * 16);
    CHECK(st.camera_rays == 8 * st.closed_form.sampled_pixels);
    sl_image_free(&img);
    sl_render_stats_free(&st);
    sl_scene_free(&s);
}

/* Adaptive sampling under --target-error: background pixels (no variance)
 * and pixels within their share of the target stop early, the samples taken
 * are fewer than pixels x spp and counted, the image is still within the
 * target of a converged render (true error, not only the estimate), and the
 * background stays exactly black. */
static void test_adaptive_sampling(void)
{
    sl_scene s;
    grey_scene(&s, 32);
    sl_render_options o;
    sl_render_options_init(&o);
    sl_image ref, img;
    sl_render_stats st;
    sl_error err = {0};
    /* The sampler's own adaptivity: the grey ball's closed form would leave
     * it nothing to sample (test_render_closed_form). */
    o.closed_form = false;
    o.spp = 4096;
    CHECK_OK(sl_render(&s, &o, &ref, NULL, &err), &err);
    o.spp = 0;
    o.target_error = 0.004;
    o.reference = &ref;
    CHECK_OK(sl_render(&s, &o, &img, &st, &err), &err);
    const int npix = 32 * 32;
    double true_err = st.passes[st.pass_count - 1].ref_rel_rmse;
    printf("  adaptive: spp %lld, samples %lld of %lld, %lld pixels stopped early, est %.4f, "
           "true %.4f\n",
           (long long)st.spp, (long long)st.samples, (long long)st.spp * npix,
           (long long)st.pixels_stopped_early, st.passes[st.pass_count - 1].est_rel_rmse,
           true_err);
    CHECK(!strcmp(st.stop_reason, "target-error"));
    CHECK(st.pixels_stopped_early >= 200); /* the 21% of background at least */
    CHECK(st.samples < st.spp * npix && st.samples > 0);
    CHECK(st.camera_rays == st.samples);
    CHECK(true_err < 2.0 * o.target_error);
    int lit_wrong = 0;
    for (int y = 0; y < 32; y++)
        for (int x = 0; x < 32; x++) {
            const float *p = sl_image_pixel(&img, x, y);
            double dx = (x + 0.5) / 16 - 1, dy = (y + 0.5) / 16 - 1;
            if (dx * dx + dy * dy > 1.2 && (p[0] != 0 || p[3] != 0))
                lit_wrong++;
        }
    CHECK(lit_wrong == 0);
    /* Without a target nothing stops early: every pixel has spp samples. */
    sl_image_free(&img);
    sl_render_stats_free(&st);
    o.target_error = 0;
    o.spp = 32;
    CHECK_OK(sl_render(&s, &o, &img, &st, &err), &err);
    CHECK(st.pixels_stopped_early == 0 && st.samples == 32 * npix);
    sl_image_free(&img);
    sl_render_stats_free(&st);
    sl_image_free(&ref);
    sl_scene_free(&s);
}

/* The half-buffer estimate tracks the true error (within a factor of 2
 * once past a few passes), for both sequences. */
static void test_error_estimate(void)
{
    sl_scene s;
    grey_scene(&s, 16);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 1024;
    o.seed = 99;
    sl_image ref, img;
    sl_render_stats st;
    CHECK_OK(sl_render(&s, &o, &ref, NULL, NULL), NULL);
    for (int ld = 0; ld < 2; ld++) {
        o.spp = 64;
        o.seed = 3;
        o.low_discrepancy = ld;
        o.reference = &ref;
        CHECK_OK(sl_render(&s, &o, &img, &st, NULL), NULL);
        for (int k = 2; k < st.pass_count; k++) {
            double e = st.passes[k].est_rel_rmse, t = st.passes[k].ref_rel_rmse;
            CHECK_MSG(e > 0.5 * t && e < 2.0 * t, "%s pass %d: estimate %g, true %g",
                      ld ? "sobol" : "random", k, e, t);
        }
        sl_image_free(&img);
        sl_render_stats_free(&st);
    }
    sl_image_free(&ref);
    sl_scene_free(&s);
}

static void test_stats_json(void)
{
    sl_scene s;
    grey_scene(&s, 8);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 8;
    sl_image img;
    sl_render_stats st;
    CHECK_OK(sl_render(&s, &o, &img, &st, NULL), NULL);
    const char *path = sl_test_path("stats.json");
    sl_error err = {0};
    CHECK_OK(sl_render_stats_write_json(&st, &o, path, &err), &err);
    json_t *j = json_load_file(path, 0, NULL);
    CHECK(j != NULL);
    CHECK(json_integer_value(json_object_get(j, "spp")) == 8);
    CHECK((int)json_array_size(json_object_get(j, "passes")) == st.pass_count);
    CHECK(json_integer_value(json_object_get(j, "shadow_rays_skipped")) > 0);
    CHECK(!strcmp(json_string_value(json_object_get(j, "strategy")), "mis"));
    json_decref(j);
    sl_image_free(&img);
    sl_render_stats_free(&st);
    sl_scene_free(&s);
}

static void test_bad_options(void)
{
    sl_scene s;
    grey_scene(&s, 8);
    sl_render_options o;
    sl_render_options_init(&o);
    sl_image img;
    sl_error err = {0};
    o.spp = 0;
    CHECK_RESULT(sl_render(&s, &o, &img, NULL, &err), SL_ERR_USAGE, &err);
    CHECK(img.data == NULL);
    o.spp = 4;
    o.bounces = -1;
    CHECK_RESULT(sl_render(&s, &o, &img, NULL, &err), SL_ERR_USAGE, &err);
    o.bounces = 0;
    sl_image small;
    CHECK_OK(sl_image_alloc(&small, 4, 4, 3, NULL), NULL);
    o.reference = &small;
    CHECK_RESULT(sl_render(&s, &o, &img, NULL, &err), SL_ERR_INPUT, &err);
    o.reference = NULL;
    s.camera.width = 0;
    CHECK_RESULT(sl_render(&s, &o, &img, NULL, &err), SL_ERR_USAGE, &err);
    sl_image_free(&small);
    sl_scene_free(&s);
    sl_scene_init(&s);
    CHECK_RESULT(sl_scene_preset(&s, "teapot", 8, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "teapot") != NULL);
    sl_image env;
    CHECK_OK(sl_image_alloc(&env, 30, 16, 3, NULL), NULL);
    CHECK_RESULT(sl_scene_set_dome(&s, &env, 0, 1, "odd.exr", &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "odd.exr") != NULL);
    sl_image_free(&env);
    sl_scene_free(&s);
}

static const char *write_text(const char *name, const char *text)
{
    const char *path = sl_test_path(name);
    FILE *f = fopen(path, "w");
    fputs(text, f);
    fclose(f);
    return path;
}

static void test_scene_files(void)
{
    sl_scene s;
    sl_error err = {0};
    const char *ok = write_text(
        "ok.json", "{\"materials\": {\"g\": {\"type\": \"lambert\", \"color\": [0.5, 0.5, 0.5]},"
                   " \"m\": {\"type\": \"conductor\", \"reflectance\": [0.9, 0.8, 0.5], \"roughness\": 0.3}},"
                   " \"objects\": [{\"type\": \"sphere\", \"material\": \"m\"},"
                   " {\"type\": \"disk\", \"center\": [0, -1, 0], \"normal\": [0, 1, 0], \"radius\": 3, \"material\": \"g\"}],"
                   " \"camera\": {\"type\": \"fisheye\", \"position\": [0, 0, -3], \"fov\": 180}}");
    sl_scene_init(&s);
    CHECK_OK(sl_scene_read_json(&s, ok, 24, &err), &err);
    CHECK(s.shape_count == 2 && s.material_count == 2 && s.camera.type == SL_CAMERA_FISHEYE);
    sl_image env;
    sky(&env);
    CHECK_OK(sl_scene_set_dome(&s, &env, 0, 1, "sky", NULL), NULL);
    s.background_env = true;
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 4;
    sl_image img;
    CHECK_OK(sl_render(&s, &o, &img, NULL, &err), &err);
    /* outside the fisheye's image circle: nothing; the centre sees the sphere */
    CHECK(sl_image_pixel(&img, 0, 0)[0] == 0 && sl_image_pixel(&img, 0, 0)[3] == 0);
    CHECK(sl_image_pixel(&img, 12, 12)[3] == 1);
    sl_image_free(&img);
    sl_scene_free(&s);
    sl_image_free(&env);

    struct {
        const char *text, *field;
    } bad[] = {
        {"{\"materials\": {\"g\": {\"type\": \"lambert\"}}, \"objects\": [{\"type\": \"sphere\", \"radius\": -2, \"material\": \"g\"}]}", "objects[0].radius"},
        {"{\"materials\": {\"g\": {\"type\": \"lambert\", \"color\": [1, -1, 0]}}, \"objects\": []}", "materials.g.color"},
        {"{\"materials\": {\"g\": {\"type\": \"lambert\"}}, \"objects\": [{\"type\": \"cube\", \"material\": \"g\"}]}", "objects[0]"},
        {"{\"materials\": {\"g\": {\"type\": \"lambert\"}}, \"objects\": [{\"type\": \"sphere\", \"material\": \"h\"}]}", "\"h\""},
        {"{\"objects\": [{\"type\": \"sphere\", \"center\": [0, \"x\", 0], \"material\": \"g\"}], \"materials\": {\"g\": {\"type\": \"lambert\"}}}", "center"},
        {"{\"materials\": {\"g\": {\"type\": \"plastic\", \"ior\": 0.5}}, \"objects\": [{\"type\": \"sphere\", \"material\": \"g\"}]}", "ior"},
        {"{\"preset\": \"grey\", \"camera\": {\"type\": \"perspective\", \"fov\": -3}}", "camera.fov"},
        /* fuzz_scene_json: an aspect of 1e308 overflowed the int height */
        {"{\"preset\": \"grey\", \"camera\": {\"type\": \"perspective\", \"aspect\": 1e308}}", "camera.aspect"},
        {"{\"materials\": {\"g\": {\"type\": \"lambert\", \"color\": [NaN, 0, 0]}}}", "line 1"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        const char *p = write_text("bad.json", bad[i].text);
        sl_scene_init(&s);
        CHECK_RESULT(sl_scene_read_json(&s, p, 8, &err), SL_ERR_INPUT, &err);
        CHECK_MSG(strstr(err.message, "bad.json") && strstr(err.message, bad[i].field),
                  "case %zu: message '%s' lacks '%s'", i, err.message, bad[i].field);
        sl_scene_free(&s);
    }
    sl_scene_init(&s);
    CHECK_RESULT(sl_scene_read_json(&s, sl_test_path("absent.json"), 8, &err), SL_ERR_NOT_FOUND, &err);
    sl_scene_free(&s);
}

int main(void)
{
    RUN(test_stop_conditions);
    RUN(test_adaptive_sampling);
    RUN(test_error_estimate);
    RUN(test_stats_json);
    RUN(test_bad_options);
    RUN(test_scene_files);
    return sl_test_finish();
}
