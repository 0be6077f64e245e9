/* SPDX-License-Identifier: BSD-3-Clause */
/* Issue 8's validation: a grey and a glossy sphere rendered under a
 * synthetic map and under the rig extracted from it (rig.json v2 read back
 * by the renderer: the rolled softbox at infinity keeps its shape) agree
 * within the 1% and 5%, and better than median cut with as many
 * lights. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rig_scenes.h"
#include "setlight/render.h"
#include "testing.h"

static int W = 24;
static int64_t SPP = 512;

static void write_rig(const sl_image *env, sl_rig_method method, int max_lights,
                      const char *name, int *count)
{
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    opt.method = method;
    opt.max_lights = max_lights;
    sl_rig rig;
    sl_error err = {0};
    CHECK_OK(sl_rig_extract(env, &opt, &rig, &err), &err);
    char json[256], res[256];
    snprintf(json, sizeof json, "%s.json", name);
    snprintf(res, sizeof res, "%s_residual.exr", name);
    CHECK_OK(sl_exr_write(sl_test_path(res), &rig.residual, NULL, SL_PIXEL_FLOAT, &err), &err);
    CHECK_OK(sl_rig_write_json(&rig, sl_test_path(json), res, &err), &err);
    *count = rig.light_count;
    sl_rig_free(&rig);
}

int main(void)
{
    if (sl_test_sanitized())
        W = 16, SPP = 512;
    sl_image env;
    CHECK_OK(sl_image_alloc(&env, 256, 128, 3, NULL), NULL);
    sc_background(&env, 0.5, true);
    scene_light sun, box;
    const double sun_rgb[3] = {4000, 3600, 3000}, box_rgb[3] = {40, 40, 38};
    sc_add(&env, &sun, 40, 60, 0, 0.0046, 0, false, sun_rgb);
    sc_add(&env, &box, 20, -50, 25, 0.25, 0.12, true, box_rgb);

    int n = 0, nmc = 0;
    write_rig(&env, SL_RIG_METHOD_REGIONS, 0, "rig", &n);
    CHECK(n >= 2);
    write_rig(&env, SL_RIG_METHOD_MEDIANCUT, n, "mediancut", &nmc);
    CHECK(nmc == n);
    const char *rigs[2] = {sl_test_path("rig.json"), sl_test_path("mediancut.json")};
    /* Measured 0.66% and 1.16% (rig.json v1, the softbox a round cone at
     * infinity: 1.3% and 24.8%). */
    const double bound[2] = {0.01, 0.05};
    for (int g = 0; g < 2; g++) {
        sl_image ref, a, b;
        sc_render_sphere(&env, NULL, g, W, SPP, &ref);
        sc_render_sphere(NULL, rigs[0], g, W, SPP, &a);
        sc_render_sphere(NULL, rigs[1], g, W, SPP, &b);
        double e_rig = 1, e_mc = 1;
        CHECK_OK(sl_relative_rmse(&a, &ref, &e_rig, NULL), NULL);
        CHECK_OK(sl_relative_rmse(&b, &ref, &e_mc, NULL), NULL);
        printf("  %s: %d lights, relative RMSE rig %.4f, median cut %.4f\n",
               g ? "glossy GGX 0.3" : "grey", n, e_rig, e_mc);
        CHECK_MSG(e_rig <= bound[g], "%s rig RMSE %.4f > %.2f", g ? "glossy" : "grey", e_rig,
                  bound[g]);
        CHECK_MSG(e_rig < e_mc, "rig %.4f not below median cut %.4f", e_rig, e_mc);
        sl_image_free(&ref);
        sl_image_free(&a);
        sl_image_free(&b);
    }
    sl_image_free(&env);

    /* v2 needs the shape at infinity: a light without axis_u, or one not
     * across its direction, is refused naming the field. */
    static const char *const bad[][2] = {
        {"{\"version\": 2, \"dome\": {\"file\": null}, \"lights\": [{\"type\": \"rect\", "
         "\"direction\": [0, 1, 0], \"solid_angle\": 0.1, \"radiance\": [1, 1, 1], "
         "\"position\": null, \"size\": null, \"texture\": null, "
         "\"angular_size\": [20, 10]}]}",
         "lights[0].axis_u"},
        {"{\"version\": 2, \"dome\": {\"file\": null}, \"lights\": [{\"type\": \"rect\", "
         "\"direction\": [0, 1, 0], \"solid_angle\": 0.1, \"radiance\": [1, 1, 1], "
         "\"position\": null, \"size\": null, \"texture\": null, \"axis_u\": [0, 1, 0], "
         "\"angular_size\": [20, 10]}]}",
         "lights[0].axis_u"},
        {"{\"version\": 2, \"dome\": {\"file\": null}, \"lights\": [{\"type\": \"rect\", "
         "\"direction\": [0, 1, 0], \"solid_angle\": 0.1, \"radiance\": [1, 1, 1], "
         "\"position\": null, \"size\": null, \"texture\": null, \"axis_u\": [1, 0, 0], "
         "\"angular_size\": [200, 10]}]}",
         "lights[0].angular_size"},
    };
    const char *bad_path = sl_test_path("bad.json");
    for (size_t k = 0; k < sizeof bad / sizeof bad[0]; k++) {
        FILE *f = fopen(bad_path, "w");
        fputs(bad[k][0], f);
        fclose(f);
        sl_scene s;
        sl_scene_init(&s);
        sl_error err = {0};
        CHECK_RESULT(sl_scene_read_rig(&s, bad_path, &err), SL_ERR_INPUT, &err);
        CHECK_MSG(strstr(err.message, "bad.json") && strstr(err.message, bad[k][1]), "%s",
                  err.message);
        CHECK(s.light_count == 0);
        sl_scene_free(&s);
    }
    return sl_test_finish();
}
