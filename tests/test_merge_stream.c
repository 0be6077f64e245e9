/* SPDX-License-Identifier: BSD-3-Clause */
/* Frames held between the passes or decoded twice: the same radiance.
 * sl_merge_to_exr (strips written as merged) against sl_merge + sl_merge_write
 * (radiance held whole) on a bracket with a sun clipped in every frame: the
 * same pixels (float: exactly; half: within its rounding), the same mask and
 * attributes (counts known only after the pass finished in place), the half
 * or float choice, and no file left on failure. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "merge_fixture.h"
#include "setlight/stitch.h"
#include "testing.h"

static const char *attr(const sl_meta *m, const char *name)
{
    const char *v = sl_meta_get(m, name);
    return v ? v : "";
}

/* Worst relative error of b against a (above half's normal range) and
 * absolute error below it. */
static void compare(const sl_image *a, const sl_image *b, double *rel, double *abs_err)
{
    *rel = *abs_err = 0;
    for (int y = 0; y < a->height; y++)
        for (int x = 0; x < a->width; x++)
            for (int c = 0; c < 3; c++) {
                double u = sl_image_pixel(a, x, y)[c], v = sl_image_pixel(b, x, y)[c];
                if (fabs(u) >= 0x1p-14)
                    *rel = fmax(*rel, fabs(v / u - 1));
                else
                    *abs_err = fmax(*abs_err, fabs(v - u));
            }
}

static void test_stream_matches_memory(void)
{
    sl_error err;
    mf_bracket b = {.width = 128, .height = 64, .frames = 5, .stops = 2, .curve = MF_GAMMA,
                    .bits = 8, .ext = "jpg", .sun = true, .noise_gain = 2e-5,
                    .noise_floor = 1e-6, .seed = 3};
    mf_result truth;
    CHECK_OK(mf_make_bracket(sl_test_tmpdir(), "st", &b, &truth, &err), &err);
    const char *paths[MF_MAX_FRAMES];
    for (int k = 0; k < b.frames; k++)
        paths[k] = truth.paths[k];
    for (int half = 0; half < 2; half++) {
        sl_merge_options opt;
        sl_merge_options_init(&opt);
        opt.response_mode = SL_RESPONSE_AUTO;
        opt.pixels = half ? SL_MERGE_PIXELS_AUTO : SL_MERGE_PIXELS_FLOAT;
        sl_merge_result mem, str;
        CHECK_OK(sl_merge(paths, b.frames, &opt, &mem, &err), &err);
        const char *mp = sl_test_path(half ? "mem_h.exr" : "mem_f.exr");
        const char *mm = sl_test_path(half ? "mem_h_mask.exr" : "mem_f_mask.exr");
        const char *sp = sl_test_path(half ? "str_h.exr" : "str_f.exr");
        const char *sm = sl_test_path(half ? "str_h_mask.exr" : "str_f_mask.exr");
        CHECK_OK(sl_merge_write(mp, mm, NULL, &mem, &err), &err);
        CHECK_OK(sl_merge_to_exr(paths, b.frames, &opt, sp, sm, NULL, &str, &err), &err);
        if (!mem.radiance.data || !str.frames)
            continue;
        /* Auto picks half here: 8-bit frames bound every value. */
        CHECK(mem.pixel_type == (half ? SL_PIXEL_HALF : SL_PIXEL_FLOAT));
        CHECK(str.pixel_type == mem.pixel_type && str.compression == SL_EXR_ZIP);
        CHECK(str.radiance.data == NULL && str.width == 128 && str.height == 64);
        CHECK(str.clipped_pixels == mem.clipped_pixels && mem.clipped_pixels > 0);
        CHECK(str.clipped_solid_angle == mem.clipped_solid_angle);
        /* The bound holds. */
        sl_image_stats st;
        sl_image_stats_compute(&mem.radiance, &st);
        double top = 0;
        for (int c = 0; c < 3; c++)
            top = fmax(top, st.max[c]);
        CHECK_MSG(top <= mem.max_value * (1 + 1e-6), "max %g, bound %g", top, mem.max_value);
        sl_image a = {0}, bb = {0}, ma = {0}, mb = {0};
        sl_meta meta_a, meta_b;
        CHECK_OK(sl_exr_read(mp, &a, &meta_a, &err), &err);
        CHECK_OK(sl_exr_read(sp, &bb, &meta_b, &err), &err);
        CHECK_OK(sl_exr_read(mm, &ma, NULL, &err), &err);
        CHECK_OK(sl_exr_read(sm, &mb, NULL, &err), &err);
        if (a.data && bb.data && ma.data && mb.data) {
            double rel, abs_err;
            compare(&a, &bb, &rel, &abs_err);
            CHECK_MSG(rel == 0 && abs_err == 0, "files differ: %g %g", rel, abs_err);
            compare(&ma, &mb, &rel, &abs_err);
            CHECK(rel == 0 && abs_err == 0);
            /* Against the float radiance: half rounds to nearest. */
            compare(&mem.radiance, &bb, &rel, &abs_err);
            printf("  %s: file vs merged radiance, worst relative %.3g, absolute %.3g\n",
                   half ? "half" : "float", rel, abs_err);
            CHECK(rel <= (half ? 0x1p-11 : 0) && abs_err <= (half ? 0x1p-25 : 0));
            const char *names[] = {"setlight:merge:clipped_pixels",
                                   "setlight:merge:clipped_fraction",
                                   "setlight:merge:clipped_solid_angle_sr",
                                   "setlight:merge:encoding", "setlight:merge:units"};
            for (int i = 0; i < 5; i++)
                CHECK_MSG(strcmp(attr(&meta_a, names[i]), attr(&meta_b, names[i])) == 0,
                          "%s: '%s' vs '%s'", names[i], attr(&meta_a, names[i]),
                          attr(&meta_b, names[i]));
            CHECK(atoll(attr(&meta_b, "setlight:merge:clipped_pixels")) == mem.clipped_pixels);
            CHECK(strncmp(attr(&meta_b, "setlight:merge:encoding"), half ? "half, ZIP" : "float, ZIP",
                          9) == 0);
            sl_meta_free(&meta_a);
            sl_meta_free(&meta_b);
        }
        sl_image_free(&a);
        sl_image_free(&bb);
        sl_image_free(&ma);
        sl_image_free(&mb);
        sl_merge_result_free(&mem);
        sl_merge_result_free(&str);
    }
    mf_result_free(&truth);
}

/* Half only where it loses nothing: unbounded float frames and a noise model
 * finer than half's rounding get float; --half is obeyed. */
static void test_encoding_choice(void)
{
    sl_error err;
    mf_bracket b = {.width = 64, .height = 32, .frames = 3, .stops = 2, .curve = MF_LINEAR,
                    .bits = 16, .ext = "tif", .noise_gain = 2e-5, .noise_floor = 1e-6, .seed = 5};
    mf_result truth;
    CHECK_OK(mf_make_bracket(sl_test_tmpdir(), "enc", &b, &truth, &err), &err);
    const char *paths[MF_MAX_FRAMES];
    for (int k = 0; k < b.frames; k++)
        paths[k] = truth.paths[k];
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    opt.response_mode = SL_RESPONSE_LINEAR;
    sl_merge_result res;
    CHECK_OK(sl_merge_response(paths, b.frames, &opt, &res, &err), &err);
    /* Linear 16-bit, 2-stop steps: the shortest frame's white is 4x the reference's. */
    CHECK(res.pixel_type == SL_PIXEL_HALF);
    CHECK_NEAR(res.max_value, 4.0, 1e-9);
    sl_merge_result_free(&res);
    opt.noise_gain = 1e-9;
    opt.noise_floor = 1e-12;
    CHECK_OK(sl_merge_response(paths, b.frames, &opt, &res, &err), &err);
    CHECK(res.pixel_type == SL_PIXEL_FLOAT);
    CHECK(strstr(res.encoding_note, "above a quarter") != NULL);
    sl_merge_result_free(&res);
    opt.pixels = SL_MERGE_PIXELS_HALF;
    CHECK_OK(sl_merge_response(paths, b.frames, &opt, &res, &err), &err);
    CHECK(res.pixel_type == SL_PIXEL_HALF);
    sl_merge_result_free(&res);
    mf_result_free(&truth);
}

/* A corrupt frame stops the stream: no radiance, no mask, no temporary file. */
static void test_failure_leaves_nothing(void)
{
    sl_error err;
    mf_bracket b = {.width = 64, .height = 64, .frames = 3, .stops = 2, .curve = MF_GAMMA,
                    .bits = 8, .ext = "jpg", .noise_gain = 2e-5, .noise_floor = 1e-6, .seed = 9};
    mf_result truth;
    CHECK_OK(mf_make_bracket(sl_test_tmpdir(), "fail", &b, &truth, &err), &err);
    const char *paths[3] = {truth.paths[0], truth.paths[1], NULL};
    /* A JPEG cut in its pixel data: the header reads, the rows do not. */
    const char *cut = sl_test_path("fail_cut.jpg");
    FILE *in = fopen(truth.paths[2], "rb"), *out = fopen(cut, "wb");
    char buf[1200];
    size_t n = in ? fread(buf, 1, sizeof buf, in) : 0;
    if (out)
        fwrite(buf, 1, n, out);
    if (in)
        fclose(in);
    if (out)
        fclose(out);
    paths[2] = cut;
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    sl_merge_result res;
    const char *op = sl_test_path("fail.exr"), *om = sl_test_path("fail_mask.exr");
    sl_result r = sl_merge_to_exr(paths, 3, &opt, op, om, NULL, &res, &err);
    CHECK(r == SL_ERR_INPUT);
    if (r)
        CHECK(strstr(err.message, "fail_cut.jpg") != NULL);
    CHECK(access(op, F_OK) != 0 && access(om, F_OK) != 0);
    /* A ghost mask needs deghost. */
    paths[2] = truth.paths[2];
    CHECK_RESULT(sl_merge_to_exr(paths, 3, &opt, op, om, sl_test_path("g.exr"), &res, &err),
                 SL_ERR_USAGE, &err);
    CHECK(access(op, F_OK) != 0 && access(om, F_OK) != 0);
    mf_result_free(&truth);
}

/* Frames kept between the passes (decoded once) or decoded again give the
 * same radiance, bit for bit, whatever the budget holds. */
static void test_hold_budget(void)
{
    sl_error err;
    mf_bracket b = {.width = 96, .height = 80, .frames = 5, .stops = 2, .curve = MF_GAMMA,
                    .bits = 8, .ext = "jpg", .sun = true, .noise_gain = 2e-5,
                    .noise_floor = 1e-6, .seed = 11};
    mf_result truth;
    CHECK_OK(mf_make_bracket(sl_test_tmpdir(), "hold", &b, &truth, &err), &err);
    const char *paths[MF_MAX_FRAMES];
    for (int k = 0; k < b.frames; k++)
        paths[k] = truth.paths[k];
    double frame_mb = 96 * 80 * 3 / 1e6;
    const double budgets[3] = {0, 2.5 * frame_mb, 384};
    const int expect_held[3] = {0, 2, 5};
    sl_merge_result res[3];
    for (int k = 0; k < 3; k++) {
        sl_merge_options opt;
        sl_merge_options_init(&opt);
        opt.response_mode = SL_RESPONSE_AUTO;
        opt.hold_mb = budgets[k];
        CHECK_OK(sl_merge(paths, b.frames, &opt, &res[k], &err), &err);
        CHECK_MSG(res[k].held_frames == expect_held[k], "budget %g MB: %d held", budgets[k],
                  res[k].held_frames);
    }
    /* The phases add up to the totals, and each frame was decoded and merged. */
    for (int k = 0; k < 3; k++) {
        double wall = 0, cpu = 0;
        for (int q = 0; q < SL_MERGE_PHASES; q++) {
            wall += res[k].timing.wall[q];
            cpu += res[k].timing.cpu[q];
            CHECK_MSG(res[k].timing.cpu[q] >= -1e-9 && res[k].timing.wall[q] >= -1e-9,
                      "%s: %g s wall, %g s CPU", sl_merge_phase_name((sl_merge_phase)q),
                      res[k].timing.wall[q], res[k].timing.cpu[q]);
        }
        CHECK_NEAR(wall, res[k].seconds, 1e-9);
        CHECK_NEAR(cpu, res[k].cpu_seconds, 1e-9);
        CHECK(res[k].timing.cpu[SL_MERGE_DECODE] > 0 && res[k].timing.cpu[SL_MERGE_PIXELS] > 0);
        CHECK(res[k].timing.cpu[SL_MERGE_WRITE] == 0); /* sl_merge writes nothing */
    }
    CHECK(strcmp(sl_merge_phase_name(SL_MERGE_PIXELS), "merge") == 0);
    for (int k = 1; k < 3; k++)
        if (res[0].radiance.data && res[k].radiance.data) {
            size_t n = (size_t)res[0].radiance.height * res[0].radiance.stride;
            CHECK(memcmp(res[0].radiance.data, res[k].radiance.data, n * sizeof(float)) == 0);
            CHECK(memcmp(res[0].clipped.data, res[k].clipped.data, n * sizeof(float)) == 0);
            CHECK(res[k].clipped_pixels == res[0].clipped_pixels);
        }
    /* The response alone decodes each frame once anyway: nothing held. */
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    sl_merge_result only;
    CHECK_OK(sl_merge_response(paths, b.frames, &opt, &only, &err), &err);
    CHECK(only.held_frames == 0);
    sl_merge_result_free(&only);
    for (int k = 0; k < 3; k++)
        sl_merge_result_free(&res[k]);
    mf_result_free(&truth);
}

int main(void)
{
    RUN(test_hold_budget);
    RUN(test_stream_matches_memory);
    RUN(test_encoding_choice);
    RUN(test_failure_leaves_nothing);
    return sl_test_finish();
}
