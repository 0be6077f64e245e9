/* SPDX-License-Identifier: BSD-3-Clause */
/* sl_stitch_run from files to files, as a non-CLI caller runs it: three
 * equisolid fisheye views of a synthetic sky (rendered through the lens at
 * known poses) stitched with the lens and poses given, with a nadir mask
 * image; the lat-long, its provenance and the coverage; a mask that is not
 * 2:1 refused with no output. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/capture.h"
#include "setlight/stitch.h"
#include "setlight/vset.h"
#include "testing.h"

static double lum(const float *p)
{
    return 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
}

/* Smooth in direction, brighter toward the zenith, so any texel's truth is
 * close to its neighbours'. */
static void make_sky(sl_image *sky, sl_error *err)
{
    CHECK_OK(sl_image_alloc(sky, 256, 128, 3, err), err);
    for (int y = 0; y < 128; y++)
        for (int x = 0; x < 256; x++) {
            float *p = sl_image_pixel(sky, x, y);
            double lat = M_PI / 2 - M_PI * (y + 0.5) / 128, lon = 2 * M_PI * (x + 0.5) / 256;
            double v = 1.0 + 0.8 * sin(lat) + 0.3 * cos(lon);
            p[0] = (float)(0.9 * v), p[1] = (float)v, p[2] = (float)(1.2 * v);
        }
}

static void test_run(void)
{
    sl_error err;
    sl_image sky = {0};
    make_sky(&sky, &err);
    sl_lens lens;
    sl_lens_nominal(&lens, SL_LENS_EQUISOLID, 320, 240, 8.0, 36.0);
    lens.circle_radius_px = sl_lens_radius(&lens, 0.5 * M_PI);
    char names[3][4096];
    const char *paths[3];
    for (int i = 0; i < 3; i++) {
        sl_view_pose pose = {120.0 * i, 0, 0};
        sl_image view = {0};
        CHECK_OK(sl_vset_view_image(&lens, &pose, &sky, 2, &view, &err), &err);
        snprintf(names[i], sizeof names[i], "%s", sl_test_path(i == 0 ? "v0.exr" : i == 1 ? "v1.exr" : "v2.exr"));
        paths[i] = names[i];
        CHECK_OK(sl_exr_write(paths[i], &view, NULL, SL_PIXEL_FLOAT, &err), &err);
        sl_image_free(&view);
    }
    /* The mask: the bottom 22.5 degrees (texels > 0.5 are not taken from any view). */
    sl_image mask = {0};
    CHECK_OK(sl_image_alloc(&mask, 64, 32, 1, &err), &err);
    for (int y = 0; y < 32; y++)
        for (int x = 0; x < 64; x++)
            sl_image_pixel(&mask, x, y)[0] = y >= 28 ? 1.0f : 0.0f;
    char maskp[4096], out[4096];
    snprintf(maskp, sizeof maskp, "%s", sl_test_path("mask.exr"));
    snprintf(out, sizeof out, "%s", sl_test_path("ll.exr"));
    CHECK_OK(sl_exr_write(maskp, &mask, NULL, SL_PIXEL_FLOAT, &err), &err);
    sl_image_free(&mask);

    sl_stitch_run_options o;
    sl_stitch_run_options_init(&o);
    CHECK(o.stitch.solve && o.stitch.projection == -1 && !o.mask_path);
    o.view_paths = paths;
    o.view_count = 3;
    o.out_path = out;
    o.mask_path = maskp;
    o.stitch.lens = &lens;
    o.stitch.solve = false;
    o.stitch.blend.width = 128;
    sl_stitch_run_result res;
    CHECK_OK(sl_stitch_run(&o, &res, &err), &err);
    const sl_stitch_coverage *cv = &res.stitch.coverage;
    printf("  %dx%d, seen %.3f sr, masked %.3f sr\n", cv->width, cv->height, cv->seen_sr,
           cv->masked_sr);
    CHECK(cv->width == 128 && cv->height == 64);
    /* The mask's 4 of 32 rows: the cap below -67.5 degrees. */
    CHECK_NEAR(cv->masked_sr, 2 * M_PI * (1 - cos(22.5 * M_PI / 180)), 0.01);
    CHECK(res.json && strstr(res.json, "\"coverage\""));
    sl_stitch_run_result_free(&res);

    sl_image ll = {0};
    sl_meta m;
    sl_meta_init(&m);
    CHECK_OK(sl_image_read(out, &ll, &m, &err), &err);
    CHECK(ll.width == 128 && ll.channels == 4 && m.envmap == SL_ENVMAP_LATLONG);
    CHECK(sl_meta_get(&m, "setlight:stitch:views") != NULL &&
          sl_meta_get(&m, "setlight:stitch:coverage") != NULL);
    /* On the horizon in front of view 1 (the centre column): the sky's value. */
    double got = lum(sl_image_pixel(&ll, 64, 32)), want = lum(sl_image_pixel(&sky, 128, 64));
    printf("  horizon ahead: %.4f, sky %.4f\n", got, want);
    CHECK(fabs(got / want - 1) < 0.03);
    CHECK(sl_image_pixel(&ll, 10, 63)[3] == 0.0f); /* masked: filled, no confidence */
    sl_image_free(&ll);
    sl_meta_free(&m);

    /* A mask that is not a lat-long: refused, nothing written. */
    sl_image bad = {0};
    CHECK_OK(sl_image_alloc(&bad, 30, 30, 1, &err), &err);
    CHECK_OK(sl_exr_write(maskp, &bad, NULL, SL_PIXEL_FLOAT, &err), &err);
    sl_image_free(&bad);
    o.out_path = sl_test_path("none.exr");
    CHECK_RESULT(sl_stitch_run(&o, &res, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "mask.exr") && strstr(err.message, "not a 2:1"));
    CHECK(!sl_test_file_exists(sl_test_path("none.exr")));
    sl_stitch_run_result_free(&res);
    sl_image_free(&sky);
}

int main(void)
{
    RUN(test_run);
    return sl_test_finish();
}
