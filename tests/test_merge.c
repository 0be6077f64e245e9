/* SPDX-License-Identifier: BSD-3-Clause */
/* sl_merge against synthetic brackets with a known radiance and response:
 * radiance error, recovered response, clipped pixels, EXIF check, files. */
#include <stdlib.h>
#include <string.h>

#include "merge_fixture.h"
#include "setlight/stitch.h"
#include "testing.h"


static mf_bracket bracket(int frames, double stops, mf_curve curve, int bits, const char *ext)
{
    mf_bracket b = {.width = 256, .height = 128, .frames = frames, .stops = stops,
                    .curve = curve, .bits = bits, .ext = ext, .sun = true,
                    .noise_gain = 2e-5, .noise_floor = 1e-6, .seed = 7};
    return b;
}

/* Frames passed longest first: the merge must not depend on the order. */
static void paths_of(const mf_result *t, const char **paths)
{
    for (int k = 0; k < t->frames; k++)
        paths[k] = t->paths[t->frames - 1 - k];
}

/* Worst relative error of the recovered inverse response (after a common
 * scale) over values the bracket exposes well. */
static double response_error(const sl_response *resp, mf_curve curve, double zlo, double zhi)
{
    double worst = 0;
    for (int c = 0; c < 3; c++) {
        double num = 0, den = 0;
        for (double z = zlo; z <= zhi; z += 1.0 / 255) {
            double t = mf_curve_inverse(curve, z), g = sl_response_eval(resp, c, z);
            num += t * g;
            den += g * g;
        }
        double s = num / den;
        for (double z = zlo; z <= zhi; z += 1.0 / 255) {
            double t = mf_curve_inverse(curve, z), g = s * sl_response_eval(resp, c, z);
            worst = fmax(worst, fabs(g / t - 1));
        }
    }
    return worst;
}

/* Samples where the masks differ; with `rim` only those more than two pixels
 * from the truth's edge count (JPEG rings at the sun's rim). */
static int64_t mask_mismatch(const sl_image *got, const sl_image *truth, bool rim)
{
    int64_t n = 0;
    for (int y = 0; y < got->height; y++)
        for (int x = 0; x < got->width; x++)
            for (int c = 0; c < 3; c++) {
                float t = sl_image_pixel(truth, x, y)[c];
                if (sl_image_pixel(got, x, y)[c] == t)
                    continue;
                bool edge = false;
                for (int dy = -2; dy <= 2 && rim; dy++)
                    for (int dx = -2; dx <= 2; dx++) {
                        int xx = x + dx, yy = y + dy;
                        if (xx >= 0 && yy >= 0 && xx < got->width && yy < got->height &&
                            sl_image_pixel(truth, xx, yy)[c] != t)
                            edge = true;
                    }
                n += !edge;
            }
    return n;
}

static void check_clean(const sl_image *img)
{
    sl_image_stats st;
    sl_image_stats_compute(img, &st);
    CHECK(st.nan_count == 0 && st.inf_count == 0 && st.negative_count == 0);
}

static void accuracy_case(const char *name, mf_bracket b, sl_response_mode mode)
{
    sl_error err;
    mf_result truth;
    CHECK_OK(mf_make_bracket(sl_test_tmpdir(), name, &b, &truth, &err), &err);
    const char *paths[MF_MAX_FRAMES];
    paths_of(&truth, paths);
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    opt.response_mode = mode;
    sl_merge_result res;
    double t0 = sl_seconds();
    CHECK_OK(sl_merge(paths, b.frames, &opt, &res, &err), &err);
    double secs = sl_seconds() - t0;
    if (res.radiance.data) {
        double med, p99, scale;
        int64_t n = mf_compare(&res.radiance, &truth, mode == SL_RESPONSE_AUTO, &med, &p99, &scale);
        printf("  %s: %lld samples, median %.3f%%, p99 %.3f%%, scale %.4f, clipped %lld px "
               "(%.5f sr), %d disagreeing, %.2f s\n",
               name, (long long)n, 100 * med, 100 * p99, scale, (long long)res.clipped_pixels,
               res.clipped_solid_angle, (int)res.disagreeing_frames, secs);
        CHECK_MSG(med <= 0.01, "%s median error %.4f", name, med);
        CHECK_MSG(p99 <= 0.05, "%s p99 error %.4f", name, p99);
        bool jpeg = strcmp(b.ext, "jpg") == 0;
        int64_t all = mask_mismatch(&res.clipped, &truth.clipped, false);
        int64_t off_rim = mask_mismatch(&res.clipped, &truth.clipped, true);
        printf("  %s: clipped mask differs in %lld samples (%lld off the sun's rim)\n", name,
               (long long)all, (long long)off_rim);
        CHECK(jpeg ? off_rim == 0 : all == 0);
        /* The sun (and only it) is clipped: its solid angle from the truth. */
        double sr = 0;
        for (int y = 0; y < truth.clipped.height; y++)
            for (int x = 0; x < truth.clipped.width; x++)
                sr += sl_image_pixel(&truth.clipped, x, y)[1] *
                      sl_latlong_texel_solid_angle(y, truth.clipped.width, truth.clipped.height);
        CHECK_NEAR(res.clipped_solid_angle, sr, jpeg ? 0.1 * sr : 1e-9);
        /* Clipped values are the shortest frame's lower bound, not an estimate:
         * its linear value (>= 0.95 of white) over its exposure. A recovered
         * response is extrapolated above saturation, so it gets 15% there. */
        double lower = exp2(-b.stops * (b.frames - 1) / 2.0);
        double blo = mode == SL_RESPONSE_AUTO ? 0.85 : 0.95, bhi = mode == SL_RESPONSE_AUTO ? 1.15 : 1.0001;
        bool bound_ok = true;
        for (int y = 0; y < truth.clipped.height; y++)
            for (int x = 0; x < truth.clipped.width; x++)
                for (int c = 0; c < 3; c++)
                    if (sl_image_pixel(&res.clipped, x, y)[c] == 1)
                        bound_ok = bound_ok && sl_image_pixel(&res.radiance, x, y)[c] * lower / scale > blo &&
                                   sl_image_pixel(&res.radiance, x, y)[c] * lower / scale < bhi;
        CHECK(bound_ok);
        CHECK(res.disagreeing_frames == 0);
        CHECK(res.fitted_ratios == b.frames - 1);
        check_clean(&res.radiance);
        if (mode == SL_RESPONSE_AUTO) {
            /* Well exposed: above 2% linear and below the shoulder (weights
             * fade from 0.90 to zero at saturation, 0.95). */
            double zlo = mf_curve_forward(b.curve, 0.02), zhi = 0.90;
            double re = response_error(&res.response, b.curve, zlo, zhi);
            printf("  %s: response error %.3f%% over z in [%.3f, %.3f]\n", name, 100 * re, zlo, zhi);
            CHECK_MSG(re <= 0.02, "%s response error %.4f", name, re);
        }
    }
    sl_merge_result_free(&res);
    /* Deghost must not fire on a static scene (JPEG and curve errors included). */
    opt.deghost = true;
    CHECK_OK(sl_merge(paths, b.frames, &opt, &res, &err), &err);
    if (res.radiance.data) {
        double med, p99;
        mf_compare(&res.radiance, &truth, mode == SL_RESPONSE_AUTO, &med, &p99, NULL);
        double alarms = (double)res.ghost_pixels / ((double)b.width * b.height);
        printf("  %s with deghost: median %.3f%%, p99 %.3f%%, false ghost pixels %.3f%%\n", name,
               100 * med, 100 * p99, 100 * alarms);
        CHECK(med <= 0.01 && p99 <= 0.05);
        CHECK(alarms <= 0.01);
    }
    sl_merge_result_free(&res);
    mf_result_free(&truth);
}

static void test_jpeg_gamma_7x3(void)
{
    accuracy_case("gamma7x3", bracket(7, 3, MF_GAMMA, 8, "jpg"), SL_RESPONSE_AUTO);
}

static void test_jpeg_scurve_5x2(void)
{
    accuracy_case("scurve5x2", bracket(5, 2, MF_SCURVE, 8, "jpg"), SL_RESPONSE_AUTO);
}

static void test_tiff16_linear_7x3(void)
{
    accuracy_case("linear7x3", bracket(7, 3, MF_LINEAR, 16, "tif"), SL_RESPONSE_LINEAR);
}

static void test_tiff16_linear_5x2(void)
{
    accuracy_case("linear5x2", bracket(5, 2, MF_LINEAR, 16, "tif"), SL_RESPONSE_LINEAR);
}

/* The response check: a 16-bit gamma bracket merged through the curve
 * recovered from it has frames that agree within their noise (0.07 stops
 * RMS, most of it the dark codes' shot noise: plausible); the same frames
 * through a linear response, a curve known to be wrong, disagree by far
 * more than 0.15 stops and are flagged. */
static void test_response_check(void)
{
    sl_error err;
    mf_result truth;
    mf_bracket b = bracket(5, 2, MF_GAMMA, 16, "tif");
    CHECK_OK(mf_make_bracket(sl_test_tmpdir(), "check5x2", &b, &truth, &err), &err);
    const char *paths[MF_MAX_FRAMES];
    paths_of(&truth, paths);
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    opt.response_mode = SL_RESPONSE_AUTO;
    sl_merge_result res;
    CHECK_OK(sl_merge_response(paths, b.frames, &opt, &res, &err), &err);
    const sl_merge_response_check *rc = &res.response_check;
    printf("  recovered curve: %.4f stops RMS (p90 %.4f) over %lld values: %s\n",
           rc->frame_rms_stops, rc->frame_p90_stops, (long long)rc->compared, rc->note);
    CHECK(rc->monotone && rc->plausible && rc->compared > 1000 && rc->frame_rms_stops < 0.1);
    sl_merge_result_free(&res);
    opt.response_mode = SL_RESPONSE_LINEAR;
    CHECK_OK(sl_merge_response(paths, b.frames, &opt, &res, &err), &err);
    printf("  linear taken for a gamma curve: %.4f stops RMS: %s\n", rc->frame_rms_stops,
           rc->note);
    CHECK(!rc->plausible && rc->frame_rms_stops > 0.15 && strstr(rc->note, "disagree"));
    sl_merge_result_free(&res);
    mf_result_free(&truth);
}

/* Linear 16-bit TIFFs marked linear by their ICC profile (as a raw
 * converter's export): --response auto takes them as linear. A pixel black
 * in the longer frames with a noise spike in the shortest one (read noise,
 * a hot pixel) stays dark: the longer frames' black bounds it. */
static void test_linear_files_and_dark_noise(void)
{
    const double times[3] = {0.001, 0.01, 0.1};
    char paths_buf[3][4096];
    const char *paths[3];
    sl_error err;
    for (int k = 0; k < 3; k++) {
        sl_image img;
        CHECK_OK(sl_image_alloc(&img, 16, 16, 3, &err), &err);
        for (int y = 0; y < 16; y++)
            for (int x = 0; x < 16; x++)
                for (int c = 0; c < 3; c++) /* left half mid-grey, right half black */
                    sl_image_pixel(&img, x, y)[c] = x < 8 ? (float)(2.0 * times[k]) : 0.0f;
        if (k == 0)
            sl_image_pixel(&img, 12, 8)[0] = 0.01f; /* 2.5 times black, in the shortest */
        sl_meta meta;
        sl_meta_init(&meta);
        meta.exposure_time = times[k];
        snprintf(meta.colorspace, sizeof meta.colorspace, "lin_rec709");
        snprintf(paths_buf[k], sizeof paths_buf[k], "%s/darknoise_%d.tif", sl_test_tmpdir(), k);
        paths[k] = paths_buf[k];
        CHECK_OK(sl_photo_write(paths[k], &img, &meta, 16, &err), &err);
        sl_meta_free(&meta);
        sl_image_free(&img);
    }
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    opt.response_mode = SL_RESPONSE_AUTO;
    opt.align = SL_ALIGN_OFF;
    sl_merge_result res;
    CHECK_OK(sl_merge(paths, 3, &opt, &res, &err), &err);
    CHECK_MSG(!strcmp(res.response.source, "linear (as the files say)"), "response %s",
              res.response.source);
    if (res.radiance.data) {
        /* Reference: the middle frame (0.01 s): grey reads 0.02 there. */
        double grey = sl_image_pixel(&res.radiance, 3, 8)[0];
        double speck = sl_image_pixel(&res.radiance, 12, 8)[0];
        printf("  grey %.5f (0.02), noise speck %.5f (was 0.1 before the bound)\n", grey, speck);
        CHECK_NEAR(grey, 0.02, 2e-4);
        CHECK_MSG(speck < 0.001, "the shortest frame's noise became %.5f", speck);
    }
    sl_merge_result_free(&res);
}

/* One frame's EXIF claims a stop more than it got: the check names that
 * frame alone, and --exposures data still merges within the bounds. */
static void test_exif_lie(void)
{
    sl_error err;
    mf_bracket b = bracket(5, 2, MF_GAMMA, 8, "jpg");
    b.lie_frame = 1;
    b.lie_stops = 1;
    mf_result truth;
    CHECK_OK(mf_make_bracket(sl_test_tmpdir(), "lie", &b, &truth, &err), &err);
    const char *paths[MF_MAX_FRAMES];
    paths_of(&truth, paths);
    for (int data = 0; data < 2; data++) {
        sl_merge_options opt;
        sl_merge_options_init(&opt);
        opt.response_mode = SL_RESPONSE_AUTO;
        opt.exposures = data ? SL_EXPOSURES_DATA : SL_EXPOSURES_EXIF;
        sl_merge_result res;
        CHECK_OK(sl_merge(paths, b.frames, &opt, &res, &err), &err);
        if (!res.frames)
            continue;
        CHECK(res.disagreeing_frames == 1);
        for (int i = 0; i < res.frame_count; i++) {
            bool liar = strcmp(res.frames[i].path, truth.paths[1]) == 0;
            CHECK(res.frames[i].disagrees == liar);
            if (liar) {
                printf("  exposures %s: %s off by %.3f stops\n", data ? "data" : "exif",
                       res.frames[i].path, res.frames[i].disagreement_stops);
                CHECK_NEAR(res.frames[i].disagreement_stops, -1, 0.1);
            }
        }
        double med, p99;
        mf_compare(&res.radiance, &truth, true, &med, &p99, NULL);
        printf("  exposures %s: median %.3f%%, p99 %.3f%%\n", data ? "data" : "exif", 100 * med,
               100 * p99);
        if (data) {
            CHECK(med <= 0.01);
            CHECK(p99 <= 0.05);
        } else {
            CHECK(p99 > 0.05); /* trusting the lie must show */
        }
        check_clean(&res.radiance);
        sl_merge_result_free(&res);
    }
    mf_result_free(&truth);
}

/* A response saved to a file and given back merges to the same bytes; a
 * shot with a different step size reuses it. */
static void test_response_file(void)
{
    sl_error err;
    mf_bracket b = bracket(5, 2, MF_SCURVE, 8, "jpg");
    mf_result truth;
    CHECK_OK(mf_make_bracket(sl_test_tmpdir(), "resp", &b, &truth, &err), &err);
    const char *paths[MF_MAX_FRAMES];
    paths_of(&truth, paths);
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    opt.response_mode = SL_RESPONSE_AUTO;
    sl_merge_result a, c;
    CHECK_OK(sl_merge_response(paths, b.frames, &opt, &a, &err), &err);
    const char *file = sl_test_path("crf.json");
    CHECK_OK(sl_response_write(file, &a.response, &err), &err);
    sl_response back;
    CHECK_OK(sl_response_read(file, &back, &err), &err);
    double worst = 0;
    for (int k = 0; k < back.nodes * 3 && back.inverse; k++)
        worst = fmax(worst, fabs(back.inverse[k] - a.response.inverse[k]));
    CHECK(worst < 1e-9);
    /* Reuse on a 7x3 bracket of the same camera. */
    mf_bracket b2 = bracket(7, 3, MF_SCURVE, 8, "jpg");
    b2.seed = 11;
    mf_result truth2;
    CHECK_OK(mf_make_bracket(sl_test_tmpdir(), "resp2", &b2, &truth2, &err), &err);
    paths_of(&truth2, paths);
    opt.response_mode = SL_RESPONSE_GIVEN;
    opt.response = &back;
    CHECK_OK(sl_merge(paths, b2.frames, &opt, &c, &err), &err);
    if (c.radiance.data) {
        double med, p99;
        mf_compare(&c.radiance, &truth2, true, &med, &p99, NULL);
        printf("  reused response on 7x3: median %.3f%%, p99 %.3f%%\n", 100 * med, 100 * p99);
        CHECK(med <= 0.01 && p99 <= 0.05);
    }
    /* Files that are not responses. */
    const char *bad = sl_test_path("bad.json");
    CHECK_OK(sl_write_file_atomic(bad, "{\"format\": \"other\"}", 19, &err), &err);
    sl_response junk;
    CHECK_RESULT(sl_response_read(bad, &junk, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "bad.json") != NULL);
    CHECK_RESULT(sl_response_read(sl_test_path("missing.json"), &junk, &err), SL_ERR_NOT_FOUND, &err);
    sl_response_free(&back);
    sl_merge_result_free(&a);
    sl_merge_result_free(&c);
    mf_result_free(&truth);
    mf_result_free(&truth2);
}

/* Same bytes for 1 and 2 threads. */
static void test_deterministic(void)
{
    sl_error err;
    mf_bracket b = bracket(3, 2, MF_GAMMA, 8, "jpg");
    mf_result truth;
    CHECK_OK(mf_make_bracket(sl_test_tmpdir(), "det", &b, &truth, &err), &err);
    const char *paths[MF_MAX_FRAMES];
    paths_of(&truth, paths);
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    opt.response_mode = SL_RESPONSE_AUTO;
    sl_merge_result r1, r2;
    sl_threads_set(1);
    CHECK_OK(sl_merge(paths, b.frames, &opt, &r1, &err), &err);
    sl_threads_set(2);
    CHECK_OK(sl_merge(paths, b.frames, &opt, &r2, &err), &err);
    sl_threads_set(0);
    size_t n = (size_t)r1.radiance.stride * r1.radiance.height * sizeof(float);
    CHECK(r1.radiance.data && r2.radiance.data && memcmp(r1.radiance.data, r2.radiance.data, n) == 0);
    sl_merge_result_free(&r1);
    sl_merge_result_free(&r2);
    mf_result_free(&truth);
}

/* Every bad input: the error code, and a message naming the frame. */
static void expect_fail(const char *what, const char *const *paths, int n, const double *times,
                        sl_result code, const char *named)
{
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    opt.times = times;
    opt.response_mode = SL_RESPONSE_LINEAR;
    sl_merge_result res;
    sl_error err;
    sl_result r = sl_merge(paths, n, &opt, &res, &err);
    CHECK_MSG(r == code, "%s: %s, expected %s (%s)", what, sl_result_name(r), sl_result_name(code),
              r ? err.message : "");
    if (r) {
        CHECK_MSG(strstr(err.message, named) != NULL, "%s: message '%s' does not name %s", what,
                  err.message, named);
        CHECK_MSG(strchr(err.message, '\n') == NULL, "%s: message spans lines", what);
    }
    CHECK(res.radiance.data == NULL || r == SL_OK);
    sl_merge_result_free(&res);
}

static void test_bad_inputs(void)
{
    sl_error err;
    char p[8][512];
    for (int i = 0; i < 8; i++)
        snprintf(p[i], sizeof p[i], "%s", sl_test_path("x"));
    const char *d = sl_test_tmpdir();
    /* a small good bracket to spoil */
    mf_bracket b = bracket(3, 2, MF_LINEAR, 8, "tif");
    b.width = 32;
    b.height = 16;
    mf_result t;
    CHECK_OK(mf_make_bracket(d, "good", &b, &t, &err), &err);
    const char *good[3] = {t.paths[0], t.paths[1], t.paths[2]};

    expect_fail("one frame", good, 1, NULL, SL_ERR_USAGE, t.paths[0]);

    snprintf(p[0], sizeof p[0], "%s/small.tif", d);
    CHECK_OK(mf_write_flat(p[0], 16, 16, 0.5f, 8, 1.0, &err), &err);
    const char *sizes[3] = {t.paths[0], p[0], t.paths[2]};
    expect_fail("sizes", sizes, 3, NULL, SL_ERR_INPUT, p[0]);

    double dup[3] = {0.01, 0.02, 0.01};
    expect_fail("duplicate times", good, 3, dup, SL_ERR_INPUT, t.paths[2]);

    mf_bracket bp = b;
    bp.ext = "png"; /* PNG keeps no EXIF exposure */
    mf_result tp;
    CHECK_OK(mf_make_bracket(d, "noexif", &bp, &tp, &err), &err);
    const char *noexif[3] = {tp.paths[0], tp.paths[1], tp.paths[2]};
    expect_fail("no EXIF", noexif, 3, NULL, SL_ERR_INPUT, tp.paths[0]);
    double times[3] = {t.times[0], t.times[1], t.times[2]};
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    opt.times = times;
    opt.response_mode = SL_RESPONSE_LINEAR;
    sl_merge_result ok;
    CHECK_OK(sl_merge(noexif, 3, &opt, &ok, &err), &err); /* --times rescues it */
    sl_merge_result_free(&ok);

    /* corrupt middle frame: the good file cut in half */
    snprintf(p[1], sizeof p[1], "%s/cut.tif", d);
    size_t size = 0;
    char *whole = sl_test_read_file(t.paths[1], &size);
    FILE *out = fopen(p[1], "wb");
    if (whole && out)
        fwrite(whole, 1, size / 2, out);
    if (out)
        fclose(out);
    free(whole);
    const char *cut[3] = {t.paths[0], p[1], t.paths[2]};
    expect_fail("corrupt middle", cut, 3, times, SL_ERR_INPUT, p[1]);

    const char *black[3], *white[3];
    for (int i = 0; i < 3; i++) {
        snprintf(p[2 + i], sizeof p[2 + i], "%s/black%d.tif", d, i);
        CHECK_OK(mf_write_flat(p[2 + i], 32, 16, 0.0f, 8, times[i], &err), &err);
        black[i] = p[2 + i];
    }
    expect_fail("all black", black, 3, NULL, SL_ERR_INPUT, p[2]);
    for (int i = 0; i < 3; i++) {
        snprintf(p[5 + i], sizeof p[5 + i], "%s/white%d.tif", d, i);
        CHECK_OK(mf_write_flat(p[5 + i], 32, 16, 1.0f, 8, times[i], &err), &err);
        white[i] = p[5 + i];
    }
    expect_fail("all saturated", white, 3, NULL, SL_ERR_INPUT, p[5]);

    char tiny[2][512];
    for (int i = 0; i < 2; i++) {
        snprintf(tiny[i], sizeof tiny[i], "%s/tiny%d.tif", d, i);
        CHECK_OK(mf_write_flat(tiny[i], 1, 1, 0.5f, 8, times[i], &err), &err);
    }
    const char *tinyp[2] = {tiny[0], tiny[1]};
    expect_fail("1x1", tinyp, 2, NULL, SL_ERR_INPUT, tiny[0]);

    char deep[512];
    snprintf(deep, sizeof deep, "%s/deep.tif", d);
    CHECK_OK(mf_write_flat(deep, 32, 16, 0.5f, 16, times[2] * 4, &err), &err);
    const char *mixed[3] = {t.paths[0], t.paths[1], deep};
    expect_fail("mixed depths", mixed, 3, NULL, SL_ERR_INPUT, deep);

    const char *missing[2] = {t.paths[0], sl_test_path("nope.tif")};
    expect_fail("missing", missing, 2, NULL, SL_ERR_NOT_FOUND, "nope.tif");
    mf_result_free(&t);
    mf_result_free(&tp);
}

/* Real brackets (when present): merge, check exposures, clean output. */
static void real_case(const char *name, const char *const *paths, int n, const double *times)
{
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    opt.times = times;
    opt.response_mode = SL_RESPONSE_AUTO;
    sl_merge_result res;
    sl_error err;
    CHECK_OK(sl_merge(paths, n, &opt, &res, &err), &err);
    if (!res.radiance.data)
        return;
    check_clean(&res.radiance);
    printf("  %s: %dx%d, %d frames, %d of %d steps measured, %lld disagreeing, clipped %.4f%%, %.2f s\n",
           name, res.radiance.width, res.radiance.height, n, res.fitted_ratios, n - 1,
           (long long)res.disagreeing_frames, 100 * res.clipped_fraction, res.seconds);
    for (int i = 0; i < n; i++)
        if (res.frames[i].fitted_exposure > 0)
            printf("    %s: EXIF %.6g, data %.6g (%+.2f stops)\n", res.frames[i].path,
                   res.frames[i].exif_exposure, res.frames[i].fitted_exposure,
                   res.frames[i].disagreement_stops);
    CHECK(res.fitted_ratios >= 1);
    sl_merge_result_free(&res);
}

static void test_real_brackets(void)
{
    if (sl_test_sanitized()) {
        sl_test_skip("real brackets under sanitizers (too slow)");
        return;
    }
    const char *dir = sl_test_data("brackets/memorial");
    if (dir) {
        /* Frames 0064..0072 (1/4 .. 1/64... from shutter_times.txt), by --times. */
        static const double t[9] = {4, 2, 1, 0.5, 0.25, 0.125, 1.0 / 16, 1.0 / 32, 1.0 / 64};
        char buf[9][1024];
        const char *paths[9];
        for (int i = 0; i < 9; i++) {
            snprintf(buf[i], sizeof buf[i], "%s/memorial00%d.png", dir, 64 + i);
            paths[i] = buf[i];
        }
        real_case("memorial", paths, 9, t);
    }
    static const char *room[7] = {"stack_room_exp_0.jpg", "stack_room_exp_1.jpg",
                                  "stack_room_exp_2.jpg", "stack_room_exp_3.jpg",
                                  "stack_room_exp_4.jpg", "stack_room_exp_5.jpg",
                                  "stack_room_exp_6.jpg"};
    if ((dir = sl_test_data("brackets/stack_room"))) {
        char buf[7][1024];
        const char *paths[7];
        for (int i = 0; i < 7; i++) {
            snprintf(buf[i], sizeof buf[i], "%s/%s", dir, room[i]);
            paths[i] = buf[i];
        }
        real_case("stack_room", paths, 7, NULL);
    }
    if ((dir = sl_test_data("brackets/stack_ghost"))) {
        char buf[3][1024];
        const char *paths[3];
        for (int i = 0; i < 3; i++) {
            snprintf(buf[i], sizeof buf[i], "%s/IMG_09%d.JPG", dir, 59 + i);
            paths[i] = buf[i];
        }
        real_case("stack_ghost", paths, 3, NULL);
    }
}

static void test_float_tiff_7x3(void)
{
    accuracy_case("float7x3", bracket(7, 3, MF_LINEAR, 32, "tif"), SL_RESPONSE_LINEAR);
}

/* A dark object in one frame only (linear frames: a recovered response is
 * not robust to it yet): deghost finds it and the merge inside it comes
 * back to the background's radiance. */
static void test_deghost(void)
{
    sl_error err;
    mf_bracket b = bracket(5, 2, MF_LINEAR, 16, "tif");
    b.ghost = true;
    b.ghost_frame = 3;
    mf_result truth;
    CHECK_OK(mf_make_bracket(sl_test_tmpdir(), "ghost", &b, &truth, &err), &err);
    const char *paths[MF_MAX_FRAMES];
    paths_of(&truth, paths);
    double inside_err[2] = {0, 0};
    for (int dg = 0; dg < 2; dg++) {
        sl_merge_options opt;
        sl_merge_options_init(&opt);
        opt.response_mode = SL_RESPONSE_LINEAR;
        opt.deghost = dg;
        /* The object is the scene's only texture: auto alignment registers
         * the frame on it (12 px, reported); this test is about deghosting. */
        opt.align = SL_ALIGN_OFF;
        sl_merge_result res;
        CHECK_OK(sl_merge(paths, b.frames, &opt, &res, &err), &err);
        if (!res.radiance.data)
            continue;
        double scale, med, p99;
        mf_compare(&res.radiance, &truth, true, &med, &p99, &scale);
        /* Median error inside the object; ghost mask hits and false alarms. */
        int64_t in = 0, hit = 0, out = 0, alarm = 0, n = 0;
        double *e = malloc((size_t)b.width * b.height * 3 * sizeof *e);
        for (int y = 0; y < b.height && e; y++)
            for (int x = 0; x < b.width; x++) {
                bool obj = *sl_image_pixel(&truth.ghost, x, y) > 0;
                bool marked = res.ghost.data && *sl_image_pixel(&res.ghost, x, y) > 0;
                in += obj;
                hit += obj && marked;
                out += !obj;
                alarm += !obj && marked;
                for (int c = 0; c < 3 && obj; c++)
                    e[n++] = fabs(sl_image_pixel(&res.radiance, x, y)[c] /
                                      (scale * sl_image_pixel(&truth.radiance, x, y)[c]) - 1);
            }
        for (int64_t i = 1; i < n; i++) { /* small: insertion sort */
            double v = e[i];
            int64_t j = i - 1;
            while (j >= 0 && e[j] > v) {
                e[j + 1] = e[j];
                j--;
            }
            e[j + 1] = v;
        }
        inside_err[dg] = n ? e[n / 2] : 1;
        free(e);
        printf("  deghost %s: object median error %.2f%%, whole-image median %.3f%% p99 %.3f%%, "
               "object marked %.1f%%, false alarms %.2f%%\n",
               dg ? "on " : "off", 100 * inside_err[dg], 100 * med, 100 * p99,
               100.0 * hit / (in ? in : 1), 100.0 * alarm / (out ? out : 1));
        if (dg) {
            CHECK(inside_err[1] <= 0.02);
            CHECK(hit >= in * 95 / 100);
            CHECK(alarm <= out / 100);
            CHECK(res.ghost_pixels == hit + alarm);
        }
        check_clean(&res.radiance);
        sl_merge_result_free(&res);
    }
    CHECK(inside_err[0] > 0.1); /* the object really spoils a plain merge */
    mf_result_free(&truth);
}

/* Each frame's saturated and black fractions (counted five pixels at a
 * time from 8-bit codes, the rest one by one) against a pattern with a
 * known count: per pixel one of white, one channel clipped, black, one
 * channel above black, mid grey; 37 columns so strips end off the stride. */
static void test_frame_fractions(void)
{
    static const float pattern[5][3] = {
        {1, 1, 1}, {0.5f, 1, 0.5f}, {0, 0, 0}, {0, 0, 0.5f}, {0.5f, 0.5f, 0.5f}};
    const int w = 37, h = 9;
    double times[3] = {0.25, 1, 4};
    char p[3][512];
    const char *paths[3];
    sl_error err;
    int64_t sat = 0, black = 0;
    for (int i = 0; i < 3; i++) {
        char name[32];
        snprintf(name, sizeof name, "frac%d.tif", i);
        snprintf(p[i], sizeof p[i], "%s", sl_test_path(name));
        paths[i] = p[i];
        sl_image img = {0};
        CHECK_OK(sl_image_alloc(&img, w, h, 3, &err), &err);
        for (int y = 0; y < h; y++)
            for (int x = 0; x < w; x++) {
                /* Frame 1 shifts the pattern, frame 2 is mid grey. */
                int k = (y * w + x + i * 2) % 7;
                float *px = sl_image_pixel(&img, x, y);
                for (int c = 0; c < 3; c++)
                    px[c] = i == 2 || k >= 5 ? 0.5f : pattern[k][c];
                if (i == 0) {
                    sat += k < 2;
                    black += k == 2;
                }
            }
        sl_meta meta;
        sl_meta_init(&meta);
        CHECK_OK(sl_photo_write(p[i], &img, &meta, 8, &err), &err);
        sl_meta_free(&meta);
        sl_image_free(&img);
    }
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    opt.times = times;
    opt.response_mode = SL_RESPONSE_LINEAR;
    sl_merge_result res;
    CHECK_OK(sl_merge(paths, 3, &opt, &res, &err), &err);
    double n = (double)w * h;
    /* Frame 1 holds the same pattern shifted: the same counts up to the
     * pixels the shift moves across the image's end. */
    int64_t sat1 = 0, black1 = 0;
    for (int j = 0; j < w * h; j++) {
        int k = (j + 2) % 7;
        sat1 += k < 2;
        black1 += k == 2;
    }
    for (int i = 0; i < 3 && res.frame_count == 3; i++) {
        const sl_merge_frame *f = &res.frames[i];
        double es = i == 0 ? (double)sat / n : i == 1 ? (double)sat1 / n : 0;
        double eb = i == 0 ? (double)black / n : i == 1 ? (double)black1 / n : 0;
        CHECK_MSG(f->saturated_fraction == es, "frame %d: saturated %.6f, expected %.6f", i,
                  f->saturated_fraction, es);
        CHECK_MSG(f->black_fraction == eb, "frame %d: black %.6f, expected %.6f", i,
                  f->black_fraction, eb);
    }
    sl_merge_result_free(&res);
}

int main(void)
{
    RUN(test_jpeg_gamma_7x3);
    RUN(test_jpeg_scurve_5x2);
    RUN(test_tiff16_linear_7x3);
    RUN(test_tiff16_linear_5x2);
    RUN(test_response_check);
    RUN(test_linear_files_and_dark_noise);
    RUN(test_float_tiff_7x3);
    RUN(test_exif_lie);
    RUN(test_deghost);
    RUN(test_response_file);
    RUN(test_deterministic);
    RUN(test_bad_inputs);
    RUN(test_frame_fractions);
    RUN(test_real_brackets);
    return sl_test_finish();
}
