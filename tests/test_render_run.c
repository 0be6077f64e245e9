/* SPDX-License-Identifier: BSD-3-Clause */
/* sl_render_run from files to files, as a non-CLI caller runs it: the grey
 * preset under a uniform white environment of radiance 2 is, on the
 * sphere, 0.18 * 2 (Lambert, no shadowing on a lone convex sphere, direct
 * light only); the image, its provenance and the statistics are written;
 * a missing environment refuses the run and leaves no file. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/render.h"
#include "testing.h"

static void test_run(void)
{
    sl_error err;
    sl_image env = {0};
    CHECK_OK(sl_image_alloc(&env, 32, 16, 3, &err), &err);
    for (int y = 0; y < 16; y++)
        for (int x = 0; x < 32; x++)
            for (int c = 0; c < 3; c++)
                sl_image_pixel(&env, x, y)[c] = 2.0f;
    sl_meta meta;
    sl_meta_init(&meta);
    meta.envmap = SL_ENVMAP_LATLONG;
    char envp[4096], out[4096], stats[4096];
    snprintf(envp, sizeof envp, "%s", sl_test_path("white.exr"));
    snprintf(out, sizeof out, "%s", sl_test_path("grey.exr"));
    snprintf(stats, sizeof stats, "%s", sl_test_path("stats.json"));
    CHECK_OK(sl_image_write(envp, &env, &meta, SL_PIXEL_FLOAT, &err), &err);
    sl_meta_free(&meta);
    sl_image_free(&env);

    sl_render_run_options o;
    sl_render_run_options_init(&o);
    CHECK(!strcmp(o.scene, "grey") && o.width == 512 && o.intensity == 1 && o.render.spp == 64);
    o.env_path = envp;
    o.out_path = out;
    o.stats_path = stats;
    o.width = 32;
    o.render.spp = 16;
    o.render.bounces = 0;
    sl_render_run_result res;
    CHECK_OK(sl_render_run(&o, &res, &err), &err);
    CHECK(res.width == 32 && res.height == 32 && res.stats.spp == 16 && res.ref_rel_rmse == -1);
    CHECK(res.json && strstr(res.json, "\"spp\": 16"));
    sl_render_run_result_free(&res);
    sl_image img = {0};
    sl_meta m;
    sl_meta_init(&m);
    CHECK_OK(sl_image_read(out, &img, &m, &err), &err);
    const char *prov = sl_meta_get(&m, "setlight:render");
    CHECK(prov && strstr(prov, "scene=grey") && strstr(prov, envp) && strstr(prov, "spp=16"));
    /* The sphere's centre pixel. */
    const float *p = sl_image_pixel(&img, 16, 16);
    printf("  centre %.4f %.4f %.4f (0.36 expected)\n", p[0], p[1], p[2]);
    for (int c = 0; c < 3; c++)
        CHECK(fabs(p[c] - 0.36) < 0.02);
    CHECK(sl_test_file_exists(stats));
    sl_image_free(&img);
    sl_meta_free(&m);

    /* No environment there: refused, nothing written. */
    o.env_path = sl_test_path("gone.exr");
    o.out_path = sl_test_path("none.exr");
    o.stats_path = NULL;
    int files = sl_test_count_files(sl_test_tmpdir());
    sl_result r = sl_render_run(&o, &res, &err);
    CHECK(r == SL_ERR_NOT_FOUND || r == SL_ERR_INPUT);
    CHECK(strstr(err.message, "gone.exr") != NULL && res.json == NULL);
    sl_render_run_result_free(&res);
    CHECK(sl_test_count_files(sl_test_tmpdir()) == files);
}

int main(void)
{
    RUN(test_run);
    return sl_test_finish();
}
