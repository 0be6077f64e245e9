/* SPDX-License-Identifier: BSD-3-Clause */
/* sl_merge against synthetic brackets with a known radiance and response:
 * radiance error, recovered response, clipped pixels, EXIF check, files. */
#include <stdlib.h>
#include <string.h>

#include "merge_fixture.h"
#include "setlight/stitch.h"
#include "testing.h"

static bool sanitized(void) { return getenv("SETLIGHT_SANITIZED") != NULL; }

static mf_bracket bracket(int frames, double stops, mf_curve curve, int bits, const char *ext)
{
    mf_bracket b = {.width = 256, .height = 128, .frames = frames, .stops = stops,
                    .curve = curve, .bits = bits, .ext = ext, .sun = true,
                    .noise_gain = 2e-5, .noise_floor = 1e-6, .seed = 7};
    if (sanitized()) {
        b.width = 128;
        b.height = 64;
    }
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

int main(void)
{
    RUN(test_jpeg_gamma_7x3);
    RUN(test_jpeg_scurve_5x2);
    RUN(test_tiff16_linear_7x3);
    RUN(test_tiff16_linear_5x2);
    return sl_test_finish();
}
