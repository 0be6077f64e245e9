/* SPDX-License-Identifier: BSD-3-Clause */
/* Convergence: MIS with Owen-scrambled Sobol reaches a given error with
 * fewer samples than BSDF-only or light-only sampling on the refs and
 * materials scenes; the report's table and SVG are written. */
#include <stdlib.h>
#include <string.h>

#include "setlight/render.h"
#include "testing.h"

/* Sanitizer builds run about 20x slower: smaller images, same assertions. */
#if defined(__SANITIZE_ADDRESS__)
#define WIDTH 24
#else
#define WIDTH 48
#endif

/* Sky gradient with a small sun: both sampling strategies have a weak spot. */
static void sky_with_sun(sl_image *env)
{
    CHECK_OK(sl_image_alloc(env, 64, 32, 3, NULL), NULL);
    for (int y = 0; y < 32; y++)
        for (int x = 0; x < 64; x++) {
            float *p = sl_image_pixel(env, x, y);
            double d[3];
            sl_latlong_to_dir((x + 0.5) / 64, (y + 0.5) / 32, d);
            p[0] = (float)(0.3 + 0.5 * fmax(0, d[1]));
            p[1] = (float)(0.35 + 0.6 * fmax(0, d[1]));
            p[2] = (float)(0.5 + 0.9 * fmax(0, d[1]));
        }
    float *sun = sl_image_pixel(env, 20, 9);
    sun[0] = 2000, sun[1] = 1800, sun[2] = 1500;
}

static void converge_scene(const char *preset, int width)
{
    sl_image env;
    sky_with_sun(&env);
    sl_scene s;
    sl_scene_init(&s);
    sl_error err = {0};
    CHECK_OK(sl_scene_preset(&s, preset, width, &err), &err);
    CHECK_OK(sl_scene_set_dome(&s, &env, 0, 1, "sky", &err), &err);
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = 64;
    /* Pixel centres: the sun in the chrome ball would otherwise make pixel
     * coverage noise, the same for every lighting strategy, dominate. */
    o.pixel_centers = true;
    sl_converge_report rep;
    CHECK_OK(sl_converge_run(&s, &o, NULL, 512, &rep, &err), &err);
    CHECK(rep.count == 7);
    const sl_converge_curve *mis = NULL, *bsdf = NULL, *light = NULL, *closed = NULL;
    for (int i = 0; i < rep.count; i++) {
        if (!strcmp(rep.curves[i].name, "mis+sobol"))
            mis = &rep.curves[i];
        if (!strcmp(rep.curves[i].name, "bsdf"))
            bsdf = &rep.curves[i];
        if (!strcmp(rep.curves[i].name, "light"))
            light = &rep.curves[i];
        if (!strcmp(rep.curves[i].name, "closed-form"))
            closed = &rep.curves[i];
    }
    CHECK(mis && bsdf && light && closed);
    if (!mis || !bsdf || !light || !closed)
        return;
    /* the error MIS+Sobol has after 16 samples per pixel */
    double target = -1;
    for (int k = 0; k < mis->stats.pass_count; k++)
        if (mis->stats.passes[k].spp == 16)
            target = mis->stats.passes[k].ref_rel_rmse;
    CHECK(target > 0);
    double n_mis = sl_converge_spp_to_reach(mis, target), n_bsdf = sl_converge_spp_to_reach(bsdf, target),
           n_light = sl_converge_spp_to_reach(light, target);
    printf("  %s: error %.4g reached at spp mis+sobol %.1f, bsdf %.1f, light %.1f (-1: not in 64)\n",
           preset, target, n_mis, n_bsdf, n_light);
    CHECK(n_mis > 0 && n_mis <= 16);
    CHECK(n_bsdf < 0 || n_bsdf > n_mis);
    CHECK(n_light < 0 || n_light > n_mis);
    /* The closed form (exact Lambert and rough glossy pixels, the rest as
     * mis+sobol) reaches that error in fewer samples. */
    double n_closed = sl_converge_spp_to_reach(closed, target);
    printf("  %s: closed form reaches it at %.1f spp, %.3f s (mis+sobol: %.3f s); %lld exact pixels\n",
           preset, n_closed, sl_converge_seconds_to_reach(closed, target),
           sl_converge_seconds_to_reach(mis, target), (long long)closed->stats.closed_form.exact_pixels);
    CHECK(closed->stats.closed_form.used && closed->stats.closed_form.exact_pixels > 0);
    CHECK(n_closed >= 0 && n_closed <= n_mis);
    char name[64];
    snprintf(name, sizeof name, "%s.svg", preset);
    CHECK_OK(sl_converge_write_svg(&rep, sl_test_path(name), &err), &err);
    snprintf(name, sizeof name, "%s.md", preset);
    CHECK_OK(sl_converge_write_table(&rep, target, sl_test_path(name), &err), &err);
    CHECK(sl_test_file_exists(sl_test_path(name)));
    sl_converge_report_free(&rep);
    sl_scene_free(&s);
    sl_image_free(&env);
}

static void test_converge_refs(void) { converge_scene("refs", WIDTH); }
static void test_converge_materials(void) { converge_scene("materials", WIDTH); }

int main(void)
{
    RUN(test_converge_refs);
    RUN(test_converge_materials);
    return sl_test_finish();
}
