/* SPDX-License-Identifier: BSD-3-Clause */
/* sl_rig_run from files to files, as a non-CLI caller runs it: a sky with
 * one bright square lamp gives one light; the USD, JSON, residual (with its
 * provenance), preview and validation report are written, the ledger
 * closes, and a failed run keeps the earlier outputs. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/lightrig.h"
#include "testing.h"

static void test_run(void)
{
    sl_error err;
    sl_image env = {0};
    CHECK_OK(sl_image_alloc(&env, 128, 64, 3, &err), &err);
    for (int y = 0; y < env.height; y++)
        for (int x = 0; x < env.width; x++) {
            float *p = sl_image_pixel(&env, x, y);
            bool lamp = x >= 80 && x < 84 && y >= 20 && y < 24;
            p[0] = lamp ? 400.0f : 0.5f;
            p[1] = lamp ? 380.0f : 0.6f;
            p[2] = lamp ? 300.0f : 0.8f;
        }
    sl_meta meta;
    sl_meta_init(&meta);
    meta.envmap = SL_ENVMAP_LATLONG;
    char in[4096], usda[4096], json[4096], preview[4096], path[4200];
    snprintf(in, sizeof in, "%s", sl_test_path("env.exr"));
    snprintf(usda, sizeof usda, "%s", sl_test_path("rig.usda"));
    snprintf(json, sizeof json, "%s", sl_test_path("rig.json"));
    snprintf(preview, sizeof preview, "%s", sl_test_path("rig_preview.png"));
    CHECK_OK(sl_image_write(in, &env, &meta, SL_PIXEL_FLOAT, &err), &err);
    sl_meta_free(&meta);

    sl_rig_run_options o;
    sl_rig_run_options_init(&o);
    CHECK(o.validate_spp == 0 && o.validate_width == 96 && o.textures == SL_RIG_TEXTURES_AUTO &&
          o.rig.energy == 0.9);
    o.input_path = in;
    o.out_path = usda;
    o.json_path = json;
    o.preview_path = preview;
    o.validate_spp = 8;
    o.validate_width = 24;
    sl_rig_run_result res;
    CHECK_OK(sl_rig_run(&o, &res, &err), &err);
    printf("  %d lights, ledger %.2g, validation grey %.4f chrome %.4f shadow %.4f\n",
           res.rig.light_count, res.rig.relative_error, res.validation.error[0],
           res.validation.error[1], res.validation.error[2]);
    CHECK(res.rig.light_count == 1 && !res.black && res.rig.relative_error < 1e-4);
    /* The lamp's direction: column 82 of 128 is longitude -(82/128 - 0.5) 360 deg. */
    const double *d = res.rig.lights[0].direction;
    double lon = atan2(d[0], d[2]) * 180 / M_PI, lat = asin(d[1]) * 180 / M_PI;
    CHECK(fabs(lon - (-(82.0 / 128 - 0.5) * 360)) < 3 && fabs(lat - (90 - 22.0 / 64 * 180)) < 3);
    CHECK(res.validated && res.validation.width == 24 && res.validation.spp >= 8);
    for (int k = 0; k < SL_RIG_VALIDATE_SCENES; k++)
        CHECK(isfinite(res.validation.error[k]) && res.validation.error[k] < 0.5);
    CHECK(res.json && strstr(res.json, "\"validation\"") && strstr(res.json, "\"lights\": 1"));
    snprintf(path, sizeof path, "%s", sl_test_path("rig_residual.exr"));
    CHECK(!strcmp(res.residual_path, path));
    sl_image dome = {0};
    sl_meta dm;
    sl_meta_init(&dm);
    CHECK_OK(sl_image_read(path, &dome, &dm, &err), &err);
    CHECK(dm.envmap == SL_ENVMAP_LATLONG && sl_meta_get(&dm, "setlight:source") &&
          !strcmp(sl_meta_get(&dm, "setlight:source"), in));
    CHECK(sl_meta_get(&dm, "setlight:command") && strstr(sl_meta_get(&dm, "setlight:command"), "rig"));
    /* The lamp is painted out of the dome. */
    CHECK(dome.width == 128 && sl_image_pixel(&dome, 82, 22)[0] < 10);
    sl_image_free(&dome);
    sl_meta_free(&dm);
    char *usd = sl_test_read_file(usda, NULL);
    CHECK(usd && strstr(usd, "rig_residual.exr") && strstr(usd, "Light"));
    free(usd);
    CHECK(sl_test_file_exists(json) && sl_test_file_exists(preview));
    CHECK(sl_test_file_exists(sl_test_path("rig.validate.html")) &&
          !strcmp(res.report_path, sl_test_path("rig.validate.html")));
    CHECK(sl_test_count_files(sl_test_path("rig.validate")) > 9);
    sl_rig_run_result_free(&res);

    /* A missing input: refused, the earlier rig kept, no temporary left. */
    int files = sl_test_count_files(sl_test_tmpdir());
    size_t before_size = 0, after_size = 0;
    char *before = sl_test_read_file(usda, &before_size);
    o.input_path = sl_test_path("missing.exr");
    CHECK_RESULT(sl_rig_run(&o, &res, &err), SL_ERR_NOT_FOUND, &err);
    CHECK(strstr(err.message, "missing.exr") != NULL && res.json == NULL);
    sl_rig_run_result_free(&res);
    char *after = sl_test_read_file(usda, &after_size);
    CHECK(before && after && before_size == after_size && !memcmp(before, after, before_size));
    free(before);
    free(after);
    CHECK(sl_test_count_files(sl_test_tmpdir()) == files);
    sl_image_free(&env);
}

int main(void)
{
    RUN(test_run);
    return sl_test_finish();
}
