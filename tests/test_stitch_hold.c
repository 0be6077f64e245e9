/* SPDX-License-Identifier: BSD-3-Clause */
/* How the stitch holds its views (stitch/stitch_hold.c) and what the blend
 * does with them: a view kept as half as it is only when every sample
 * converts exactly, else scaled by a power of two within half's rounding, a half file read as half the same as read as float, the blend of half views the same bytes as of the float views,
 * the solve's reduction factor, and the per-row spans of the views' fields
 * never losing a direction a view sees (the seen solid angle of one view is
 * its field's, wherever it points); the blend's float row loop against the
 * double lens model and the double loop it replaced. */
#include "testing.h"

#include "../stitch/stitch_blend_private.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static double uniform(uint64_t *s)
{
    *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(*s >> 11) / 9007199254740992.0;
}

/* Radiance over 1e-3..1e3 with hard steps (hot texels), every sample a
 * half value (as merge writes them): each is the table's value of a
 * random half pattern in that range. */
static void half_valued(sl_image *img, uint64_t seed)
{
    const float *table = stitch_half_table();
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            float *p = sl_image_pixel(img, x, y);
            bool lamp = ((x / 37) + (y / 23)) % 5 == 0;
            for (int c = 0; c < 3; c++) {
                /* halves 0x1400 (~1e-3) .. 0x6000 (~512) */
                uint16_t h = (uint16_t)(0x1400 + (int)(uniform(&seed) * (0x6000 - 0x1400)));
                p[c] = table[lamp ? h | 0x0800 : h];
            }
        }
}

static void half_only_when_exact(void)
{
    sl_error err;
    sl_image img;
    CHECK_OK(sl_image_alloc(&img, 97, 13, 3, &err), &err); /* odd width: F16C's tail too */
    half_valued(&img, 3);
    stitch_half_image h;
    CHECK(stitch_view_to_half(&img, &h, &err));
    const float *table = stitch_half_table();
    int same = 0;
    for (int y = 0; h.rgb && y < img.height; y++)
        for (int x = 0; x < img.width; x++)
            for (int c = 0; c < 3; c++)
                same += table[h.rgb[((size_t)y * img.width + x) * 3 + c]] ==
                        sl_image_pixel(&img, x, y)[c];
    CHECK_MSG(same == 97 * 13 * 3, "%d of %d samples kept", same, 97 * 13 * 3);
    /* the scan finds it exact, and the view converted in its own memory
     * is the same half */
    int64_t bad = -1;
    double peak = 0, mag = 0;
    bool exact = false;
    CHECK_OK(stitch_view_scan(&img, &bad, &peak, &mag, &exact, &err), &err);
    CHECK(exact && bad == 0);
    sl_image copy;
    CHECK_OK(sl_image_copy(&img, &copy, &err), &err);
    stitch_half_image in_place;
    CHECK(stitch_view_take_half(&copy, 0, &in_place, NULL));
    CHECK(copy.data == NULL && in_place.width == 97 && in_place.height == 13);
    CHECK(h.rgb && in_place.rgb &&
          !memcmp(h.rgb, in_place.rgb, (size_t)97 * 13 * 3 * sizeof(uint16_t)));
    stitch_half_free(&in_place);
    stitch_half_free(&h);
    /* one sample half cannot hold, at the tail or in the vector body: not
     * taken, and the scan says so */
    const float odd[] = {0.1f, 70000.0f, 1e-9f, 1.0f + 1.0f / 4096.0f};
    for (size_t k = 0; k < sizeof odd / sizeof *odd; k++) {
        half_valued(&img, 3);
        int x = k % 2 ? 96 : 5;
        sl_image_pixel(&img, x, 7)[k % 3] = odd[k];
        CHECK_MSG(!stitch_view_to_half(&img, &h, &err), "%g was taken as half", odd[k]);
        CHECK(h.rgb == NULL);
        CHECK_OK(stitch_view_scan(&img, &bad, &peak, &mag, &exact, &err), &err);
        CHECK_MSG(!exact && bad == 0, "%g: scanned as half", odd[k]);
        CHECK(peak == (odd[k] > 512.0f ? odd[k] : peak));
    }
    /* NaN and Inf counted, in the vector body and the tail, and left out
     * of the peak */
    half_valued(&img, 3);
    double clean_peak;
    CHECK_OK(stitch_view_scan(&img, &bad, &clean_peak, &mag, &exact, &err), &err);
    sl_image_pixel(&img, 3, 2)[1] = NAN;
    sl_image_pixel(&img, 96, 4)[2] = INFINITY;
    sl_image_pixel(&img, 40, 9)[0] = -INFINITY;
    CHECK_OK(stitch_view_scan(&img, &bad, &peak, &mag, &exact, &err), &err);
    CHECK_MSG(bad == 3 && !exact && peak == clean_peak, "%lld bad, peak %g (clean %g)",
              (long long)bad, peak, clean_peak);
    sl_image_free(&img);
}

/* The solve's copy reduced in one pass: the bytes of sl_image_resample. */
static void reduce_is_resample(void)
{
    sl_error err;
    for (int k = 2; k <= 4; k += 2)
        for (int ch = 1; ch <= 3; ch += 2) {
            sl_image img, a, b;
            CHECK_OK(sl_image_alloc(&img, 40 * k, 52 * k, ch, &err), &err);
            uint64_t seed = 7;
            for (size_t i = 0; i < (size_t)img.width * img.height * ch; i++)
                img.data[i] = (float)exp(20.0 * uniform(&seed) - 10.0); /* 1e-4 .. 2e4 */
            CHECK_OK(stitch_reduce(&img, k, &a, &err), &err);
            CHECK_OK(sl_image_resample(&img, img.width / k, img.height / k, &b, &err), &err);
            CHECK(a.width == b.width && a.height == b.height && a.channels == ch);
            CHECK_MSG(!memcmp(a.data, b.data, (size_t)a.width * a.height * ch * sizeof(float)),
                      "k %d, %d channels: not the bytes of sl_image_resample", k, ch);
            sl_image_free(&img), sl_image_free(&a), sl_image_free(&b);
        }
}

/* A fisheye-like frame: a disc of half_valued radiance round (cx, cy) of
 * radius r on black. */
static void disc_view(sl_image *img, double cx, double cy, double r, uint64_t seed)
{
    half_valued(img, seed);
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++)
            if (hypot(x + 0.5 - cx, y + 0.5 - cy) > r)
                memset(sl_image_pixel(img, x, y), 0, 3 * sizeof(float));
}

/* A sky near 1e-3 and a sun near 1e6 (radiance a float view holds, not
 * half values: each sample a random factor of 1 to 1.3 off): */
static void sun_and_sky(sl_image *img, double cx, double cy, double r, uint64_t seed)
{
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            float *p = sl_image_pixel(img, x, y);
            double d = hypot(x + 0.5 - cx, y + 0.5 - cy);
            bool sun = hypot(x + 0.5 - (cx + 0.4 * r), y + 0.5 - cy) < 6.0;
            for (int c = 0; c < 3; c++)
                p[c] = d > r ? 0.0f : (float)((sun ? 1e6 / 1.3 : 1e-3) * (1.0 + 0.3 * uniform(&seed)));
        }
}

/* A view wider than 3072 px (held as half by sl_stitch), filled by `fill`
 * with a disc of radius 110 px round its middle. */
static void wide_view(sl_image *img, void (*fill)(sl_image *, double, double, double, uint64_t),
                      sl_error *err)
{
    CHECK_OK(sl_image_alloc(img, 3200, 240, 3, err), err);
    fill(img, 1601.0, 120.0, 110.0, 9);
}

/* A half EXR read straight into half: the samples' bits as the float read
 * has them, and the scan, the solve's reduced copies and the image circle
 * on it the float view's; a file it does not read is left to sl_exr_read. */
static void half_read_is_the_float_read(void)
{
    sl_error err;
    sl_image img, back;
    CHECK_OK(sl_image_alloc(&img, 320, 200, 3, &err), &err);
    disc_view(&img, 163.0, 98.5, 90.0, 5);
    const char *path = sl_test_path("half_view.exr");
    CHECK_OK(sl_exr_write(path, &img, NULL, SL_PIXEL_HALF, &err), &err);
    stitch_half_image h = {0};
    sl_meta meta, fmeta;
    CHECK_OK(sl_exr_read_half_rgb(path, &h.rgb, &h.width, &h.height, &meta, &err), &err);
    CHECK_OK(sl_exr_read(path, &back, &fmeta, &err), &err);
    CHECK(h.rgb && h.width == 320 && h.height == 200 && back.channels == 3);
    CHECK(sl_test_same_meta("half read", &meta, &fmeta));
    const float *table = stitch_half_table();
    int same = 0;
    for (int y = 0; h.rgb && y < 200; y++)
        for (int x = 0; x < 320; x++)
            for (int c = 0; c < 3; c++) {
                float a = table[h.rgb[((size_t)y * 320 + x) * 3 + c]];
                float b = sl_image_pixel(&back, x, y)[c];
                same += a == b || (isnan(a) && isnan(b));
            }
    CHECK_MSG(same == 320 * 200 * 3, "%d of %d samples the float read's", same, 320 * 200 * 3);
    /* NaN, Inf and -Inf (sl_exr_write writes none): counted, not the peak */
    const uint16_t odd[3] = {0x7e00, 0x7c00, 0xfc00};
    for (int i = 0; h.rgb && i < 3; i++) {
        h.rgb[(100 * 320 + 150 + i) * 3 + i] = odd[i];
        sl_image_pixel(&back, 150 + i, 100)[i] = table[odd[i]];
    }
    int64_t bad = 0, fbad = 0;
    double peak = 0, fpeak = 0, fmag = 0;
    bool exact;
    CHECK_OK(stitch_half_scan(&h, &bad, &peak, &err), &err);
    CHECK_OK(stitch_view_scan(&back, &fbad, &fpeak, &fmag, &exact, &err), &err);
    CHECK_MSG(bad == 3 && fbad == 3 && peak == fpeak && peak > 100.0 && peak < 65504.0, "%lld/%lld bad, peak %g/%g",
              (long long)bad, (long long)fbad, peak, fpeak);
    /* the same in a view whose samples are not a multiple of the scan's
     * eight: odd values in the tail too */
    stitch_half_image small = {calloc(13 * 7 * 3, sizeof(uint16_t)), 13, 7, 0};
    sl_image fsmall;
    CHECK_OK(sl_image_alloc(&fsmall, 13, 7, 3, &err), &err);
    uint64_t seed = 17;
    for (int i = 0; small.rgb && i < 13 * 7 * 3; i++) {
        small.rgb[i] = (uint16_t)(uniform(&seed) * 0x10000);
        if ((small.rgb[i] & 0x7c00) == 0x7c00)
            small.rgb[i] ^= 0x4000; /* finite: the odd ones are placed below */
        if (i == 5 || i == 13 * 7 * 3 - 1)
            small.rgb[i] = i == 5 ? 0x7e01 : 0xfc00;
        sl_image_pixel(&fsmall, (i / 3) % 13, i / 39)[i % 3] = table[small.rgb[i]];
    }
    CHECK_OK(stitch_half_scan(&small, &bad, &peak, &err), &err);
    CHECK_OK(stitch_view_scan(&fsmall, &fbad, &fpeak, &fmag, &exact, &err), &err);
    CHECK_MSG(bad == 2 && fbad == 2 && peak == fpeak && peak > 0.0, "%lld/%lld bad, peak %g/%g",
              (long long)bad, (long long)fbad, peak, fpeak);
    stitch_half_free(&small);
    sl_image_free(&fsmall);
    /* a clean view: its reduced copies and circle */
    disc_view(&img, 163.0, 98.5, 90.0, 5);
    CHECK_OK(sl_exr_write(path, &img, NULL, SL_PIXEL_HALF, &err), &err);
    stitch_half_free(&h);
    sl_meta_free(&meta);
    CHECK_OK(sl_exr_read_half_rgb(path, &h.rgb, &h.width, &h.height, &meta, &err), &err);
    for (int k = 2; h.rgb && k <= 4; k += 2) {
        sl_image a, b;
        CHECK_OK(stitch_reduce_half(&h, k, &a, &err), &err);
        CHECK_OK(stitch_reduce(&img, k, &b, &err), &err);
        CHECK_MSG(a.width == b.width && a.height == b.height &&
                      !memcmp(a.data, b.data, (size_t)a.width * a.height * 3 * sizeof(float)),
                  "reduced by %d: not the float view's copy", k);
        sl_image_free(&a), sl_image_free(&b);
    }
    /* random finite halves over the whole range (subnormals, signs, the
     * largest): the half copy's float sums the same bytes as the double
     * ones of the float view, through F16C and through the table */
    stitch_half_image rnd = {malloc(38 * 22 * 3 * sizeof(uint16_t)), 38, 22, 0};
    sl_image frnd;
    CHECK_OK(sl_image_alloc(&frnd, 38, 22, 3, &err), &err);
    for (int i = 0; rnd.rgb && i < 38 * 22 * 3; i++) {
        rnd.rgb[i] = (uint16_t)(uniform(&seed) * 0x10000);
        if ((rnd.rgb[i] & 0x7c00) == 0x7c00)
            rnd.rgb[i] ^= 0x4000;
        sl_image_pixel(&frnd, (i / 3) % 38, i / (38 * 3))[i % 3] = table[rnd.rgb[i]];
    }
    for (int portable = 0; rnd.rgb && portable < 2; portable++) {
        sl_image a, b;
        stitch_rays_portable_only = portable;
        CHECK_OK(stitch_reduce_half(&rnd, 2, &a, &err), &err);
        stitch_rays_portable_only = false;
        CHECK_OK(stitch_reduce(&frnd, 2, &b, &err), &err);
        CHECK_MSG(!memcmp(a.data, b.data, (size_t)a.width * a.height * 3 * sizeof(float)),
                  "random halves reduced by 2 (%s): not the float view's copy",
                  portable ? "table" : "F16C");
        sl_image_free(&a), sl_image_free(&b);
    }
    stitch_half_free(&rnd);
    sl_image_free(&frnd);
    sl_stitch_circle ch, cf;
    CHECK_OK(stitch_circle_find_half(&h, "half", &ch, &err), &err);
    CHECK_OK(sl_stitch_circle_find(&img, "half", NULL, &cf, &err), &err);
    CHECK_MSG(!memcmp(&ch, &cf, sizeof ch) && fabs(ch.cx - 163.0) < 2.0 &&
                  fabs(ch.radius - 90.0) < 2.0,
              "circle %g,%g r %g, on float %g,%g r %g", ch.cx, ch.cy, ch.radius, cf.cx, cf.cy,
              cf.radius);
    stitch_half_free(&h);
    sl_meta_free(&meta);
    /* float samples, an A channel, no file: not read here */
    const char *other = sl_test_path("float_view.exr");
    CHECK_OK(sl_exr_write(other, &img, NULL, SL_PIXEL_FLOAT, &err), &err);
    CHECK_OK(sl_exr_read_half_rgb(other, &h.rgb, &h.width, &h.height, &meta, &err), &err);
    CHECK(h.rgb == NULL);
    sl_image rgba;
    CHECK_OK(sl_image_convert_channels(&img, 4, &rgba, &err), &err);
    CHECK_OK(sl_exr_write(other, &rgba, NULL, SL_PIXEL_HALF, &err), &err);
    CHECK_OK(sl_exr_read_half_rgb(other, &h.rgb, &h.width, &h.height, &meta, &err), &err);
    CHECK(h.rgb == NULL);
    CHECK_OK(sl_exr_read_half_rgb(sl_test_path("none.exr"), &h.rgb, &h.width, &h.height, &meta,
                                  &err),
             &err);
    CHECK(h.rgb == NULL);
    sl_image_free(&rgba);
    sl_image_free(&back);
    sl_meta_free(&fmeta);
    sl_image_free(&img);
}

/* sl_stitch of a large half EXR view (read as half) and of the same
 * samples as a float EXR (read as float, then held as half): the same
 * lat-long. */
static void stitch_of_half_file_is_of_float_file(void)
{
    sl_error err;
    sl_image img;
    wide_view(&img, disc_view, &err);
    const char *half_path = sl_test_path("wide_half.exr"), *float_path =
                                                                sl_test_path("wide_float.exr");
    CHECK_OK(sl_exr_write(half_path, &img, NULL, SL_PIXEL_HALF, &err), &err);
    CHECK_OK(sl_exr_write(float_path, &img, NULL, SL_PIXEL_FLOAT, &err), &err);
    sl_image_free(&img);
    sl_stitch_options opt;
    sl_stitch_options_init(&opt);
    opt.focal_mm = 8.0;
    opt.sensor_mm[0] = 36.0;
    opt.blend.width = 256;
    sl_image out[2];
    const char *views[2] = {half_path, float_path};
    for (int i = 0; i < 2; i++) {
        const char *o = sl_test_path(i ? "from_float.exr" : "from_half.exr");
        sl_stitch_result res;
        CHECK_OK(sl_stitch(&views[i], 1, o, &opt, &res, &err), &err);
        /* the 110 px circle's 8.9 degrees: 0.075 sr */
        CHECK_MSG(fabs(res.coverage.seen_sr - 0.075) < 0.02, "%g sr seen", res.coverage.seen_sr);
        sl_stitch_result_free(&res);
        CHECK_OK(sl_exr_read(o, &out[i], NULL, &err), &err);
    }
    CHECK(out[0].width == 256 && out[1].width == 256 &&
          !memcmp(out[0].data, out[1].data, (size_t)256 * 128 * 4 * sizeof(float)));
    sl_image_free(&out[0]), sl_image_free(&out[1]);
}

/* A float view held as half divided by a power of two: 1e6 does not
 * overflow half's 65504, 1e-3 keeps half's 11 bits (each sample within
 * 2^-11 relative), and what falls under half's normal range is counted. */
static void scaled_half_keeps_the_light(void)
{
    sl_error err;
    sl_image img, copy;
    CHECK_OK(sl_image_alloc(&img, 97, 61, 3, &err), &err); /* odd width: F16C's tail too */
    sun_and_sky(&img, 48.0, 30.0, 28.0, 5);
    sl_image_pixel(&img, 3, 3)[0] = 1e-6f;   /* 2^-24 once scaled: a subnormal */
    sl_image_pixel(&img, 96, 60)[2] = 1e-13f; /* flushed */
    int64_t bad;
    double peak, mag;
    bool exact;
    int exp2 = 99;
    CHECK_OK(stitch_view_scan(&img, &bad, &peak, &mag, &exact, &err), &err);
    CHECK(!exact && bad == 0 && peak == mag && peak > 9e5);
    CHECK(stitch_half_exponent(mag, &exp2));
    CHECK_MSG(exp2 == 4 && ldexp(mag, -exp2) <= 65504.0 && ldexp(mag, -exp2) > 32768.0,
              "2^%d for %g", exp2, mag);
    CHECK_OK(sl_image_copy(&img, &copy, &err), &err);
    stitch_half_image h;
    stitch_half_loss loss;
    CHECK(stitch_view_take_half(&copy, exp2, &h, &loss));
    CHECK(copy.data == NULL && h.exp2 == 4);
    CHECK_MSG(loss.below_normal == 2 && loss.flushed == 1, "%lld under normal, %lld flushed",
              (long long)loss.below_normal, (long long)loss.flushed);
    sl_image back;
    CHECK_OK(stitch_half_to_float(&h, &back, &err), &err);
    double worst = 0.0, sun_max = 0.0;
    int odd = 0; /* non-finite, negative, or 0 where the view is not 0 and not the flushed one */
    for (int y = 0; y < img.height; y++)
        for (int x = 0; x < img.width; x++)
            for (int c = 0; c < 3; c++) {
                double a = sl_image_pixel(&img, x, y)[c], b = sl_image_pixel(&back, x, y)[c];
                odd += !isfinite(b) || b < 0.0 || (b == 0.0) != (a < 1e-9);
                if (a > 1e-4) /* the counted two are not held to it */
                    worst = fmax(worst, fabs(b / a - 1.0));
                sun_max = fmax(sun_max, b);
            }
    CHECK_MSG(odd == 0 && worst <= ldexp(1.0, -11) && sun_max > 9e5,
              "%d odd samples, worst %.3g relative, sun %g", odd, worst, sun_max);
    /* beyond what a float holds once rounded: kept float */
    CHECK(!stitch_half_exponent(1e31, &exp2) && stitch_half_exponent(0.0, &exp2) && exp2 == 0);
    sl_image_free(&back);
    sl_image_free(&img);
}

/* sl_stitch of a large float view of a 1e6 sun over a 1e-3 sky (held as
 * scaled half) against the blend of the float view itself: every texel
 * within half's rounding, the power within 0.05%, nothing negative or
 * non-finite, and the result says how the view was held. */
static void stitch_of_scaled_half_is_of_float(void)
{
    sl_error err;
    sl_image img;
    wide_view(&img, sun_and_sky, &err);
    const char *path = sl_test_path("sun_float.exr"), *o = sl_test_path("sun_stitch.exr");
    CHECK_OK(sl_exr_write(path, &img, NULL, SL_PIXEL_FLOAT, &err), &err);
    sl_stitch_options opt;
    sl_stitch_options_init(&opt);
    opt.focal_mm = 8.0;
    opt.sensor_mm[0] = 36.0;
    opt.blend.width = 256;
    sl_stitch_result res;
    CHECK_OK(sl_stitch(&path, 1, o, &opt, &res, &err), &err);
    const sl_stitch_view_result *vr = &res.views[0];
    CHECK_MSG(vr->held_as_half && vr->half_rounded && vr->half_exp2 == 4 &&
                  vr->below_half_normal == 0 && res.float_samples,
              "held %d rounded %d 2^%d, %lld under normal", vr->held_as_half, vr->half_rounded,
              vr->half_exp2, (long long)vr->below_half_normal);
    sl_stitch_view v = {"float", &img, NULL, res.lens, res.views[0].pose};
    sl_image ref = {0}, out = {0};
    sl_stitch_coverage cov;
    CHECK_OK(stitch_blend_run(&v, 1, NULL, false, &opt.blend, NULL, NULL, &ref, &cov, &err),
             &err);
    CHECK_OK(sl_exr_read(o, &out, NULL, &err), &err);
    double worst = 0.0, p_ref = 0.0, p_out = 0.0;
    int bad = 0;
    for (int y = 0; y < out.height; y++)
        for (int x = 0; x < out.width; x++)
            for (int c = 0; c < 3; c++) {
                double a = sl_image_pixel(&ref, x, y)[c], b = sl_image_pixel(&out, x, y)[c];
                bad += !isfinite(b) || b < 0.0;
                if (a > 0.0)
                    worst = fmax(worst, fabs(b / a - 1.0));
                p_ref += a;
                p_out += b;
            }
    CHECK_MSG(bad == 0 && worst <= ldexp(1.0, -11) + 1e-6 && fabs(p_out / p_ref - 1.0) < 5e-4 &&
                  p_ref > 1e6,
              "%d bad texels, worst %.3g relative, power %.6f of the float view's", bad, worst,
              p_out / p_ref);
    sl_stitch_result_free(&res);
    sl_image_free(&ref), sl_image_free(&out), sl_image_free(&img);
}

static void solve_factor(void)
{
    CHECK(stitch_solve_factor(6000, 4000, 3072) == 2);
    CHECK(stitch_solve_factor(12000, 8000, 3072) == 4);
    CHECK(stitch_solve_factor(3072, 2048, 3072) == 1); /* small enough */
    CHECK(stitch_solve_factor(6001, 4000, 3072) == 1); /* 2 does not divide it: full size */
    CHECK(stitch_solve_factor(6000, 4001, 3072) == 1);
    sl_lens lens;
    sl_lens_nominal(&lens, SL_LENS_EQUISOLID, 6000, 4000, 8.0, 36.0);
    lens.cx += 3.7;
    sl_lens back = lens;
    stitch_lens_scale(&back, 0.5, 3000, 2000);
    CHECK(back.width == 3000 && back.focal_px == 0.5 * lens.focal_px);
    stitch_lens_scale(&back, 2.0, 6000, 4000);
    CHECK(!memcmp(&back, &lens, sizeof lens)); /* there and back exactly */
}

/* Three views of half_valued radiance (hard steps: hot texels), lens with
 * radial terms and vignetting, turned off every axis. */
static void three_views(sl_image img[3], sl_stitch_view v[3], sl_error *err)
{
    for (int i = 0; i < 3; i++) {
        CHECK_OK(sl_image_alloc(&img[i], 360, 240, 3, err), err);
        half_valued(&img[i], 11 + (uint64_t)i);
        sl_lens lens;
        sl_lens_nominal(&lens, SL_LENS_EQUISOLID, 360, 240, 8.0, 36.0);
        lens.k[0] = 0.02;
        lens.vignette[0] = -0.2;
        lens.circle_radius_px = sl_lens_radius(&lens, M_PI / 2);
        v[i] = (sl_stitch_view){"view", &img[i], NULL, lens, {120.0 * i, 10.0 * i, -5.0 * i}};
    }
}

static void blend_of_half_is_blend_of_float(void)
{
    sl_error err;
    sl_image img[3];
    stitch_half_image half[3];
    sl_stitch_view v[3];
    three_views(img, v, &err);
    for (int i = 0; i < 3; i++)
        CHECK(stitch_view_to_half(&img[i], &half[i], &err));
    sl_stitch_blend_options opt;
    sl_stitch_blend_options_init(&opt);
    opt.width = 512;
    sl_stitch_view only_half[3]; /* no float image: the half one is what is read */
    for (int i = 0; i < 3; i++) {
        only_half[i] = v[i];
        only_half[i].radiance = NULL;
    }
    /* as read (exp2 0), and held at 2^5 (the float views 32 times brighter:
     * exactly the half values times 2^5) */
    for (int exp2 = 0; exp2 <= 5; exp2 += 5) {
        for (int i = 0; exp2 && i < 3; i++) {
            half[i].exp2 = exp2;
            for (int y = 0; y < img[i].height; y++)
                for (int x = 0; x < img[i].width * 3; x++)
                    sl_image_pixel(&img[i], 0, y)[x] *= 32.0f;
        }
        sl_image from_float = {0}, from_half = {0};
        sl_stitch_coverage cf, ch;
        CHECK_OK(stitch_blend_run(v, 3, NULL, false, &opt, NULL, NULL, &from_float, &cf, &err),
                 &err);
        /* the half lookups through F16C where the processor has it, and
         * through the table (the portable loops) */
        for (int portable = 0; portable < 2; portable++) {
            stitch_rays_portable_only = portable;
            CHECK_OK(stitch_blend_run(only_half, 3, half, true, &opt, NULL, NULL, &from_half, &ch,
                                      &err),
                     &err);
            stitch_rays_portable_only = false;
            CHECK_MSG(cf.hot_texels > 1000, "%lld texels sampled finely: the edges are not tested",
                      (long long)cf.hot_texels);
            CHECK(cf.hot_texels == ch.hot_texels && cf.ghost_texels == ch.ghost_texels);
            size_t bytes = (size_t)from_float.height * from_float.stride * sizeof(float);
            CHECK_MSG(from_half.data && !memcmp(from_float.data, from_half.data, bytes),
                      "the blend of the half views (2^%d) differs from the float views' (%s loops)",
                      exp2, portable ? "portable" : "processor's");
            sl_image_free(&from_half);
        }
        sl_image_free(&from_float);
    }
    for (int i = 0; i < 3; i++) {
        stitch_half_free(&half[i]);
        sl_image_free(&img[i]);
    }
}

/* One view of a 60-degree field, pointed anywhere (up to the pole, across
 * the longitude seam): every texel whose centre is inside its field (less
 * a tenth of a degree, where the edge ramp is still above 0) is seen,
 * every texel a tenth of a degree beyond it is not: a row span cut short would leave
 * seen texels unseen. */
static void spans_lose_nothing(void)
{
    sl_error err;
    sl_image img;
    CHECK_OK(sl_image_alloc(&img, 400, 400, 3, &err), &err);
    sl_image_fill(&img, 1.0f);
    static const sl_view_pose poses[] = {{0, 0, 0},    {179.5, 0, 0}, {-179.5, 20, 0},
                                         {30, 50, 10}, {90, 89, 0},   {200, -75, 0}};
    for (size_t k = 0; k < sizeof poses / sizeof *poses; k++) {
        sl_lens lens;
        sl_lens_nominal(&lens, SL_LENS_EQUISOLID, 400, 400, 8.0, 24.0);
        lens.max_theta_deg = 60.0;
        lens.circle_radius_px = sl_lens_radius(&lens, M_PI / 3);
        sl_stitch_view v = {"view", &img, NULL, lens, poses[k]};
        sl_stitch_blend_options opt;
        sl_stitch_blend_options_init(&opt);
        opt.width = 720;
        opt.supersample = 1; /* one sample, at the texel's centre */
        sl_image out = {0};
        sl_stitch_coverage cov;
        CHECK_OK(sl_stitch_blend(&v, 1, &opt, &out, &cov, &err), &err);
        double m[3][3];
        sl_view_pose_matrix(&poses[k], m);
        int lost = 0, extra = 0, inside = 0;
        for (int y = 0; out.data && y < out.height; y++)
            for (int x = 0; x < out.width; x++) {
                double lon = M_PI * (1.0 - 2.0 * (x + 0.5) / out.width);
                double lat = M_PI * (0.5 - (y + 0.5) / out.height);
                double d[3] = {sin(lon) * cos(lat), sin(lat), cos(lon) * cos(lat)};
                double theta = acos(fmin(1.0, d[0] * m[0][2] + d[1] * m[1][2] + d[2] * m[2][2]));
                bool seen = sl_image_pixel(&out, x, y)[3] > 0.0f;
                inside += theta < 59.9 * M_PI / 180;
                lost += theta < 59.9 * M_PI / 180 && !seen;
                extra += theta > 60.1 * M_PI / 180 && seen;
            }
        CHECK_MSG(lost == 0 && extra == 0 && inside > 10000,
                  "pose %zu: %d texels inside the field unseen, %d outside seen (of %d)", k, lost,
                  extra, inside);
        sl_image_free(&out);
    }
    sl_image_free(&img);
}


/* stitch_rays (float, 8 at a time) against the double lens model: every
 * direction of a sphere's grid, the pixel from sl_lens_ray_to_pixel, the weight
 * from stitch_view_weight; the portable loop the same bytes as the AVX2 one. */
static void rays_match_the_lens(void)
{
    sl_error err;
    sl_image img[3];
    sl_stitch_view v[3];
    three_views(img, v, &err);
    sl_stitch_blend_options opt;
    sl_stitch_blend_options_init(&opt);
    stitch_view_prep prep[3];
    CHECK_OK(stitch_prepare_views(v, 3, &opt, NULL, false, prep, &err), &err);
    enum { N = 1001 };
    float sin_lon[N], cos_lon[N], px[N], py[N], w[N], ig[N], px2[N], py2[N], w2[N], ig2[N];
    for (int i = 0; i < N; i++) {
        double lon = M_PI * (1.0 - 2.0 * (i + 0.5) / N);
        sin_lon[i] = (float)sin(lon);
        cos_lon[i] = (float)cos(lon);
    }
    double px_err = 0, w_err = 0, g_err = 0;
    int seen = 0, wrong_side = 0, bytes_differ = 0;
    for (int k = 0; k < 3; k++) {
        stitch_ray_view rv;
        CHECK(stitch_ray_view_init(&prep[k], &rv));
        double m[3][3];
        sl_view_pose_matrix(&v[k].pose, m);
        for (int row = 0; row < 181; row++) {
            double lat = M_PI * (0.5 - (row + 0.5) / 181);
            float sl = (float)sin(lat), cl = (float)cos(lat);
            stitch_rays_portable_only = false;
            stitch_rays(&rv, sin_lon, cos_lon, sl, cl, N, px, py, w, ig);
            stitch_rays_portable_only = true;
            stitch_rays(&rv, sin_lon, cos_lon, sl, cl, N, px2, py2, w2, ig2);
            stitch_rays_portable_only = false;
            bytes_differ += memcmp(px, px2, sizeof px) || memcmp(py, py2, sizeof py) ||
                            memcmp(w, w2, sizeof w) || memcmp(ig, ig2, sizeof ig);
            for (int i = 0; i < N; i++) {
                double d[3] = {(double)sin_lon[i] * cl, sl, (double)cos_lon[i] * cl}, cam[3];
                for (int r = 0; r < 3; r++)
                    cam[r] = m[0][r] * d[0] + m[1][r] * d[1] + m[2][r] * d[2];
                double theta = acos(fmax(-1.0, fmin(1.0, cam[2])));
                double want = stitch_view_weight(&prep[k], theta), x, y;
                bool in = sl_lens_ray_to_pixel(&v[k].lens, cam, &x, &y) &&
                          theta < v[k].lens.max_theta_deg * M_PI / 180;
                if (!in || !(want > 1e-4)) {
                    wrong_side += w[i] > 1e-4f;
                    continue;
                }
                seen++;
                wrong_side += !(w[i] > 0.0f);
                px_err = fmax(px_err, hypot(px[i] - x, py[i] - y));
                w_err = fmax(w_err, fabs(w[i] - want));
                g_err = fmax(g_err, fabs(ig[i] * sl_lens_vignette(&v[k].lens, x, y) - 1.0));
            }
        }
        stitch_ray_view_free(&rv);
    }
    stitch_release_views(prep, 3);
    CHECK_MSG(seen > 200000 && wrong_side == 0, "%d samples seen, %d on the wrong side", seen,
              wrong_side);
    CHECK_MSG(px_err < 2e-3 && w_err < 2e-6 && g_err < 2e-6,
              "float against double: pixel %.3g px, weight %.3g, gain %.3g", px_err, w_err,
              g_err);
    CHECK_MSG(bytes_differ == 0, "%d rows differ between the AVX2 and the portable loop",
              bytes_differ);
    for (int i = 0; i < 3; i++)
        sl_image_free(&img[i]);
}

/* The blend's float row loop against the double loop one sample at a time
 * (stitch_blend_reference), on views of random radiance (neighbours up to
 * 5e5 apart, so a third of the texels are hot): the same texels sampled
 * finely (to 0.1%), the same power to 1e-5, the confidence to 1e-5, and
 * each texel as close as float positions allow. A view pixel's position in
 * float is some 1e-5 px from the double one; at a hard step that moves a
 * hot texel by up to a few 1e-3 of its value, while the 4 x 4 sampling of
 * such a texel is itself several % from an 8 x 8 one: the float loop within
 * 1% of a texel's value and within 1e-3 of the double loop's own sampling
 * error (RMS over the texels, relative). */
static void float_rows_match_the_double_loop(void)
{
    sl_error err;
    sl_image img[3];
    sl_stitch_view v[3];
    three_views(img, v, &err);
    sl_stitch_blend_options opt;
    sl_stitch_blend_options_init(&opt);
    opt.width = 512;
    sl_image out[3] = {{0}, {0}, {0}};
    sl_stitch_coverage cov[3];
    for (int r = 0; r < 3; r++) {
        sl_stitch_blend_options o = opt;
        if (r == 2)
            o.supersample = 8; /* the double loop's sampling error: 8 x 8 everywhere */
        stitch_blend_reference = r >= 1;
        CHECK_OK(sl_stitch_blend(v, 3, &o, &out[r], &cov[r], &err), &err);
    }
    stitch_blend_reference = false;
    CHECK_MSG(cov[1].hot_texels > 1000 &&
                  llabs(cov[0].hot_texels - cov[1].hot_texels) <= cov[1].hot_texels / 1000,
              "hot texels: float %lld, double %lld", (long long)cov[0].hot_texels,
              (long long)cov[1].hot_texels);
    int n = 0;
    double max_a = 0, max_rel = 0, sum_float = 0, sum_sampling = 0;
    for (int y = 0; out[2].data && y < out[0].height; y++)
        for (int x = 0; x < out[0].width; x++, n++) {
            const float *a = sl_image_pixel(&out[0], x, y), *b = sl_image_pixel(&out[1], x, y);
            const float *fine = sl_image_pixel(&out[2], x, y);
            for (int c = 0; c < 3; c++) {
                double d = fabs(a[c] - b[c]) / fmax(1e-3, fmax(a[c], b[c]));
                double s = fabs(fine[c] - b[c]) / fmax(1e-3, fmax(fine[c], b[c]));
                max_rel = fmax(max_rel, d);
                sum_float += d * d;
                sum_sampling += s * s;
            }
            max_a = fmax(max_a, fabs(a[3] - b[3]));
        }
    double rms_float = sqrt(sum_float / (3.0 * n)), rms_sampling = sqrt(sum_sampling / (3.0 * n));
    CHECK_MSG(n > 0 && max_rel < 1e-2 && rms_float < 1e-3 * rms_sampling && max_a < 1e-5,
              "float against double: up to %.3g relative, RMS %.3g (the double loop's own "
              "sampling error %.3g); confidence off by up to %.3g",
              max_rel, rms_float, rms_sampling, max_a);
    for (int c = 0; c < 3; c++)
        CHECK_NEAR(cov[0].power[c] / cov[1].power[c], 1.0, 1e-5);
    for (int r = 0; r < 3; r++)
        sl_image_free(&out[r]);
    for (int i = 0; i < 3; i++)
        sl_image_free(&img[i]);
}

int main(void)
{
    RUN(half_only_when_exact);
    RUN(scaled_half_keeps_the_light);
    RUN(stitch_of_scaled_half_is_of_float);
    RUN(solve_factor);
    RUN(reduce_is_resample);
    RUN(half_read_is_the_float_read);
    RUN(stitch_of_half_file_is_of_float_file);
    RUN(blend_of_half_is_blend_of_float);
    RUN(spans_lose_nothing);
    RUN(rays_match_the_lens);
    RUN(float_rows_match_the_double_loop);
    return sl_test_finish();
}
