/* SPDX-License-Identifier: BSD-3-Clause */
/* sl_calibrate_run from files to files, as a non-CLI caller runs it: an
 * HDRI at half the true light and a grey sphere rendered under the true
 * light; the run writes the calibrated HDRI with its provenance and the
 * report, and returns the exposure scale 2. A failing run leaves the
 * earlier output as it was. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/render.h"
#include "setlight/stitch.h"
#include "testing.h"

/* A sky brightening to the zenith with a warm bright patch: enough
 * structure that the grey sphere's shading depends on the map. */
static void make_env(sl_image *env, sl_error *err)
{
    CHECK_OK(sl_image_alloc(env, 64, 32, 3, err), err);
    for (int y = 0; y < env->height; y++)
        for (int x = 0; x < env->width; x++) {
            float *p = sl_image_pixel(env, x, y);
            float sky = 0.2f + 0.8f * (1.0f - (float)y / env->height);
            bool patch = x >= 40 && x < 44 && y >= 8 && y < 12;
            p[0] = sky * 0.9f + (patch ? 30.0f : 0);
            p[1] = sky + (patch ? 25.0f : 0);
            p[2] = sky * 1.2f + (patch ? 15.0f : 0);
        }
}

static void test_grey_alone(void)
{
    sl_error err;
    sl_image env = {0}, half = {0}, photo = {0};
    make_env(&env, &err);
    CHECK_OK(sl_image_copy(&env, &half, &err), &err);
    for (int y = 0; y < half.height; y++)
        for (int x = 0; x < half.width; x++)
            for (int c = 0; c < 3; c++)
                sl_image_pixel(&half, x, y)[c] *= 0.5f;
    sl_scene s;
    sl_scene_init(&s);
    sl_render_options ro;
    sl_render_options_init(&ro);
    ro.spp = 256;
    ro.seed = 9;
    CHECK_OK(sl_scene_preset(&s, "grey", 48, &err), &err);
    CHECK_OK(sl_scene_set_dome(&s, &env, 0, 1, "truth", &err), &err);
    CHECK_OK(sl_render(&s, &ro, &photo, NULL, &err), &err);
    sl_scene_free(&s);
    sl_meta meta;
    sl_meta_init(&meta);
    meta.envmap = SL_ENVMAP_LATLONG;
    const char *hdri_path = sl_test_path("env.exr");
    char hdri[4096], grey[4096], out[4096], rep[4096];
    snprintf(hdri, sizeof hdri, "%s", hdri_path);
    snprintf(grey, sizeof grey, "%s", sl_test_path("grey.exr"));
    snprintf(out, sizeof out, "%s", sl_test_path("cal.exr"));
    snprintf(rep, sizeof rep, "%s", sl_test_path("report"));
    CHECK_OK(sl_image_write(hdri, &half, &meta, SL_PIXEL_FLOAT, &err), &err);
    meta.envmap = SL_ENVMAP_NONE;
    CHECK_OK(sl_image_write(grey, &photo, &meta, SL_PIXEL_FLOAT, &err), &err);
    sl_meta_free(&meta);

    sl_calibrate_run_options o;
    sl_calibrate_run_options_init(&o);
    CHECK(o.hdri_in_chart && o.sun_repair && o.absolute && o.clip < 0 &&
          o.exposure_tolerance == 1 && o.grey.albedo == 0.18 && o.grey.spp == 256 &&
          !strcmp(o.out_colorspace, "lin_rec709") && o.camera.camera == -1);
    o.hdri_path = hdri;
    o.grey_path = grey;
    o.out_path = out;
    o.report_dir = rep;
    o.grey.circle[0] = o.grey.circle[1] = o.grey.circle[2] = 24;
    o.grey.spp = 128;
    sl_calibrate_run_result res;
    CHECK_OK(sl_calibrate_run(&o, &res, &err), &err);
    printf("  scale %.4f (true 2), gains %.4f %.4f %.4f, sphere error %.4f -> %.4f\n", res.scale,
           res.grey_gain[0], res.grey_gain[1], res.grey_gain[2], res.grey_rel_rmse_before,
           res.grey_rel_rmse_after);
    CHECK(fabs(res.scale / 2 - 1) < 0.01);
    CHECK(res.grey_used && !res.chart_used && res.grey_rel_rmse_after < 0.02);
    CHECK(res.cd_m2_per_unit == 0 && !res.sun.repaired && res.negative_samples == 0);
    CHECK_NEAR(res.matrix[0][0], res.grey_gain[0], 1e-12);
    CHECK(res.matrix[0][1] == 0 && res.matrix[2][0] == 0);
    CHECK(res.json && strstr(res.json, "\"scale\"") && strstr(res.json, "\"grey\""));

    /* The output: its pixels are the HDRI times the gains, its provenance names the inputs. */
    sl_image cal = {0};
    sl_meta cm;
    sl_meta_init(&cm);
    CHECK_OK(sl_image_read(out, &cal, &cm, &err), &err);
    CHECK(cal.width == 64 && cal.height == 32 && cm.envmap == SL_ENVMAP_LATLONG);
    CHECK(sl_meta_get(&cm, "setlight:source") && !strcmp(sl_meta_get(&cm, "setlight:source"), hdri));
    CHECK(sl_meta_get(&cm, "setlight:units") && !strcmp(sl_meta_get(&cm, "setlight:units"), "relative"));
    const char *scale = sl_meta_get(&cm, "setlight:calibration_scale");
    CHECK(scale && fabs(strtod(scale, NULL) - res.scale) < 1e-6 * res.scale);
    const char *cmd = sl_meta_get(&cm, "setlight:command");
    CHECK(cmd && strstr(cmd, "calibrate") && strstr(cmd, grey));
    CHECK(sl_meta_get(&cm, "setlight:calibration_matrix") != NULL);
    const float *p = sl_image_pixel(&cal, 10, 20), *q = sl_image_pixel(&half, 10, 20);
    for (int c = 0; c < 3; c++)
        CHECK(fabs(p[c] / (q[c] * res.grey_gain[c]) - 1) < 2e-3); /* half floats */
    char path[4200];
    snprintf(path, sizeof path, "%s/calibrate.json", rep);
    char *text = sl_test_read_file(path, NULL);
    CHECK(text && !strcmp(text, res.json));
    free(text);
    snprintf(path, sizeof path, "%s/calibrate.html", rep);
    CHECK(sl_test_file_exists(path));
    sl_image_free(&cal);
    sl_meta_free(&cm);
    sl_calibrate_run_result_free(&res);

    /* A circle on nothing: refused, the earlier output and report kept. */
    size_t before_size = 0, after_size = 0;
    char *before = sl_test_read_file(out, &before_size);
    o.grey.circle[0] = 4, o.grey.circle[1] = 4, o.grey.circle[2] = 2;
    o.write_float = true;
    sl_result r = sl_calibrate_run(&o, &res, &err);
    CHECK(r != SL_OK && res.json == NULL);
    char *after = sl_test_read_file(out, &after_size);
    CHECK(before && after && before_size == after_size && !memcmp(before, after, before_size));
    free(before);
    free(after);
    CHECK(sl_test_count_files(sl_test_tmpdir()) == 4); /* env, grey, cal, report: no temporary */

    /* Neither a chart nor a grey sphere: a usage error, nothing written. */
    sl_calibrate_run_options_init(&o);
    o.hdri_path = hdri;
    o.out_path = sl_test_path("none.exr");
    CHECK_RESULT(sl_calibrate_run(&o, &res, &err), SL_ERR_USAGE, &err);
    CHECK(!sl_test_file_exists(sl_test_path("none.exr")));

    sl_image_free(&env);
    sl_image_free(&half);
    sl_image_free(&photo);
}

int main(void)
{
    RUN(test_grey_alone);
    return sl_test_finish();
}
