/* SPDX-License-Identifier: BSD-3-Clause */
/* sl_unwrap_run from files to files, as a non-CLI caller runs it: a
 * ray-traced orthographic chrome ball unwrapped with its circle given and
 * found; the lat-long carries its provenance and matches the environment
 * where the ball saw it well; bad input leaves the earlier output. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ball_fixture.h"
#include "setlight/stitch.h"
#include "testing.h"

static double lum(const float *p)
{
    return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
}

static void test_run(void)
{
    sl_error err;
    ball_fixture f;
    ball_fixture_init(&f, 160, 120);
    f.balls[0].px = 80, f.balls[0].py = 60, f.balls[0].r = 40;
    f.clutter = false;
    f.ss = 2;
    sl_image photo = {0};
    CHECK_OK(ball_fixture_render(&f, &photo, &err), &err);
    char in[4096], out[4096];
    snprintf(in, sizeof in, "%s", sl_test_path("ball.exr"));
    snprintf(out, sizeof out, "%s", sl_test_path("ball_ll.exr"));
    CHECK_OK(sl_image_write(in, &photo, NULL, SL_PIXEL_FLOAT, &err), &err);

    sl_unwrap_run_options o;
    sl_unwrap_run_options_init(&o);
    CHECK(o.photo_count == 1 && o.confidence && o.compression == SL_EXR_ZIP &&
          o.pair.search_deg == 20 && o.pair.occluder_deg == 20 && o.camera.camera == -1 &&
          o.pair.views[0].reflectance.value[1] == 1);
    o.photo_paths[0] = in;
    o.out_path = out;
    o.pair.views[0].circle = (sl_ball_circle){.cx = 80, .cy = 60, .r = 40};
    o.have_circle[0] = true;
    o.pair.views[0].width = 64;
    sl_unwrap_run_result res;
    CHECK_OK(sl_unwrap_run(&o, &res, &err), &err);
    CHECK(res.width == 64 && res.height == 32 && res.camera == SL_BALL_ORTHOGRAPHIC &&
          !res.detected[0] && res.streamed && !res.ldr_linearised);
    CHECK(res.json && strstr(res.json, "\"circle\"") && strstr(res.json, "\"streamed\": true"));
    sl_unwrap_run_result_free(&res);

    /* The file: RGB and confidence, its provenance, the environment where seen. */
    sl_image ll = {0}, truth = {0};
    sl_meta m;
    sl_meta_init(&m);
    CHECK_OK(sl_image_read(out, &ll, &m, &err), &err);
    CHECK(ll.width == 64 && ll.height == 32 && ll.channels == 4 && m.envmap == SL_ENVMAP_LATLONG);
    CHECK(sl_meta_get(&m, "setlight:source") && !strcmp(sl_meta_get(&m, "setlight:source"), in));
    const char *circle = sl_meta_get(&m, "setlight:ball_circle");
    CHECK(circle && !strcmp(circle, "80.0000,60.0000,40.0000"));
    const char *camera = sl_meta_get(&m, "setlight:ball_camera");
    CHECK(camera && strstr(camera, "orthographic"));
    CHECK(sl_meta_get(&m, "setlight:ball_reflectance") != NULL);
    sl_meta_free(&m);
    CHECK_OK(ball_fixture_truth(&f, 64, 4, &truth, &err), &err);
    double sum_out = 0, sum_truth = 0;
    int seen = 0;
    for (int y = 0; y < 32; y++)
        for (int x = 0; x < 64; x++) {
            const float *p = sl_image_pixel(&ll, x, y);
            if (p[3] < 0.5)
                continue;
            seen++;
            sum_out += lum(p);
            sum_truth += lum(sl_image_pixel(&truth, x, y));
        }
    printf("  %d texels seen with confidence >= 0.5: mean luminance %.4f, truth %.4f\n", seen,
           sum_out / seen, sum_truth / seen);
    CHECK(seen > 300 && fabs(sum_out / sum_truth - 1) < 0.05);
    sl_image_free(&ll);
    sl_image_free(&truth);

    /* The circle found instead: the traced outline within half a pixel. */
    char out2[4096];
    snprintf(out2, sizeof out2, "%s", sl_test_path("found.exr"));
    o.out_path = out2;
    o.have_circle[0] = false;
    CHECK_OK(sl_unwrap_run(&o, &res, &err), &err);
    sl_ball_circle want;
    ball_fixture_circle(&f, 0, &want);
    CHECK(res.detected[0] && hypot(res.circle[0].cx - want.cx, res.circle[0].cy - want.cy) < 0.5 &&
          fabs(res.circle[0].r - want.r) < 0.5);
    sl_unwrap_run_result_free(&res);

    /* A circle outside the photo: a usage error naming the file, the earlier output kept. */
    size_t before_size = 0, after_size = 0;
    char *before = sl_test_read_file(out, &before_size);
    int files = sl_test_count_files(sl_test_tmpdir());
    o.out_path = out;
    o.have_circle[0] = true;
    o.pair.views[0].circle = (sl_ball_circle){.cx = 150, .cy = 60, .r = 40};
    CHECK_RESULT(sl_unwrap_run(&o, &res, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "ball.exr") != NULL && res.json == NULL);
    char *after = sl_test_read_file(out, &after_size);
    CHECK(before && after && before_size == after_size && !memcmp(before, after, before_size));
    free(before);
    free(after);
    CHECK(sl_test_count_files(sl_test_tmpdir()) == files);
    sl_image_free(&photo);
}

int main(void)
{
    RUN(test_run);
    return sl_test_finish();
}
