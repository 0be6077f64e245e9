/* SPDX-License-Identifier: BSD-3-Clause */
/* Issue 8 on the virtual set: the rig of the `stage`, `exterior` and `night`
 * ground-truth lat-longs (capture.h) against their true light lists. Every
 * true light is found, directions within 1 degree, solid angle within 10%
 * (resolved lights), power within 3%, no extra light (the room's textured
 * walls, the sky), nothing lost to the dome, ledger within 0.1%. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "rig_scenes.h"
#include "setlight/vset.h"
#include "setlight/lightrig.h"
#include "setlight/render.h"
#include "testing.h"

/* 1024 wide: the stage's 0.8-degree kino tubes are 2.3 texels across.
 * The exterior and night sources are unresolved at either width, so under
 * sanitizers those two run at 512. */
static int W = 1024, W_UNRESOLVED = 1024;

static void run_scene(const char *name, int width, double *worst)
{
    sl_vset_desc desc;
    sl_vset_scene sc;
    sl_error err = {0};
    CHECK_OK(sl_vset_preset(name, &desc, &err), &err);
    CHECK_OK(sl_vset_scene_make(&desc, width, &sc, &err), &err);
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    opt.energy = 1;
    sl_rig rig;
    CHECK_OK(sl_rig_extract(&sc.latlong, &opt, &rig, &err), &err);
    const sl_vset_desc *d = &sc.desc;
    CHECK_MSG(rig.light_count == d->light_count, "%s: %d lights, %d true (no false lights)",
              name, rig.light_count, d->light_count);
    double texel = 2 * M_PI / width;
    bool used[SL_VSET_MAX_LIGHTS] = {false};
    for (int i = 0; i < d->light_count; i++) {
        const sl_vset_light *t = &d->lights[i];
        int best = -1;
        double ang = 1e9;
        for (int k = 0; k < rig.light_count; k++) {
            double a = sc_angle(rig.lights[k].direction, t->dir);
            if (a < ang) {
                ang = a;
                best = k;
            }
        }
        CHECK_MSG(best >= 0, "%s: %s not found", name, t->name);
        if (best < 0)
            continue;
        CHECK_MSG(!used[best], "%s: %s shares a light with another", name, t->name);
        used[best] = true;
        const sl_rig_light *f = &rig.lights[best];
        double deg = ang * 180 / M_PI;
        CHECK_MSG(deg < 1, "%s: %s direction off by %.3f deg", name, t->name, deg);
        /* A source narrower than two texels has no measurable size: it is a
         * distant light of the assumed diameter. */
        bool resolved = fmin(t->width_deg, t->shape == SL_VSET_SHAPE_RECT ? t->height_deg
                                                                          : t->width_deg) *
                            M_PI / 180 >= 2 * texel;
        double sa = f->solid_angle / t->solid_angle - 1;
        if (resolved) {
            CHECK_MSG(f->shape != SL_RIG_DISTANT, "%s: %s is resolved but distant", name,
                      t->name);
            CHECK_MSG(fabs(sa) < 0.10, "%s: %s solid angle %+.1f%%", name, t->name, 100 * sa);
            CHECK_MSG(f->shape == (t->shape == SL_VSET_SHAPE_RECT ? SL_RIG_RECT : SL_RIG_DISK),
                      "%s: %s fitted as a %s", name, t->name, sl_rig_shape_name(f->shape));
        }
        double pw = 0;
        for (int c = 0; c < 3; c++) {
            double e = f->integral[c] / t->integral[c] - 1;
            CHECK_MSG(fabs(e) < 0.03, "%s: %s power ch %d %+.2f%%", name, t->name, c, 100 * e);
            pw = fmax(pw, fabs(e));
        }
        worst[0] = fmax(worst[0], deg);
        if (resolved)
            worst[1] = fmax(worst[1], fabs(sa));
        worst[2] = fmax(worst[2], pw);
        printf("  %s %-12s %-7s dir %.3f deg, solid angle %+.1f%%%s, power %+.2f%% (G)\n", name,
               t->name, sl_rig_shape_name(f->shape), deg, 100 * sa,
               resolved ? "" : " (unresolved)", 100 * (f->integral[1] / t->integral[1] - 1));
    }
    /* The automatic texture choice: the stage's window, a graded source,
     * and none of the uniform fixtures (tubes, softbox, bulbs, sun, lamps). */
    char prefix[64];
    snprintf(prefix, sizeof prefix, "vset_%s", name);
    CHECK_OK(sl_rig_write_textures_mode(&rig, &sc.latlong, sl_test_path(prefix),
                                        SL_RIG_TEXTURES_AUTO, &err), &err);
    for (int k = 0; k < rig.light_count; k++) {
        int best = 0;
        for (int i = 1; i < d->light_count; i++)
            if (sc_angle(rig.lights[k].direction, d->lights[i].dir) <
                sc_angle(rig.lights[k].direction, d->lights[best].dir))
                best = i;
        bool window = !strcmp(d->lights[best].name, "window");
        printf("  %s %-12s %s%s\n", name, d->lights[best].name,
               rig.lights[k].texture[0] ? "textured, " : "", rig.lights[k].texture_reason);
        CHECK_MSG((rig.lights[k].texture[0] != 0) == window, "%s: %s textured %d (%s)", name,
                  d->lights[best].name, rig.lights[k].texture[0] != 0,
                  rig.lights[k].texture_reason);
    }
    CHECK_MSG(rig.relative_error < 1e-3, "%s: ledger %.3g", name, rig.relative_error);
    /* Nothing bright left in the dome: no skipped candidate carries more
     * than a glint's share. */
    for (int s = 0; s < rig.skipped_count; s++)
        CHECK_MSG(rig.skipped[s].share < 0.005, "%s: skipped %.2f%% (%s)", name,
                  100 * rig.skipped[s].share, rig.skipped[s].reason);
    printf("  %s: %d lights, ledger %.2g\n", name, rig.light_count, rig.relative_error);
    sl_rig_free(&rig);
    sl_vset_scene_free(&sc);
}

static double worst[3];

static int RENDER_W = 1024, SPHERE_PX = 24;
static int64_t SPHERE_SPP = 1024;

/* Issue 8's bounds on the stage with the default rig (default options,
 * textures chosen automatically: the window only): grey sphere within 1%,
 * glossy within 5% (measured 0.44% and 1.03% at 1024 spp, 24 px; 6.45% and
 * 29.3% with no textures). */
static void test_stage_render(void)
{
    sl_vset_desc desc;
    sl_vset_scene sc;
    sl_error err = {0};
    CHECK_OK(sl_vset_preset("stage", &desc, &err), &err);
    CHECK_OK(sl_vset_scene_make(&desc, RENDER_W, &sc, &err), &err);
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    sl_rig rig;
    CHECK_OK(sl_rig_extract(&sc.latlong, &opt, &rig, &err), &err);
    CHECK_OK(sl_rig_write_textures_mode(&rig, &sc.latlong, sl_test_path("vset_stage"),
                                        SL_RIG_TEXTURES_AUTO, &err), &err);
    int textured = 0;
    for (int k = 0; k < rig.light_count; k++) {
        printf("  stage light %d %-6s %s%s\n", k + 1, sl_rig_shape_name(rig.lights[k].shape),
               rig.lights[k].texture[0] ? "textured, " : "", rig.lights[k].texture_reason);
        textured += rig.lights[k].texture[0] != 0;
    }
    CHECK(textured == 1);
    CHECK_OK(sl_exr_write(sl_test_path("vset_stage_dome.exr"), &rig.residual, NULL,
                          SL_PIXEL_FLOAT, &err), &err);
    const char *json = sl_test_path("vset_stage.json");
    CHECK_OK(sl_rig_write_json(&rig, json, "vset_stage_dome.exr", &err), &err);
    const double bound[2] = {0.01, 0.05};
    for (int g = 0; g < 2; g++) {
        sl_image ref, a;
        sc_render_sphere(&sc.latlong, NULL, g, SPHERE_PX, SPHERE_SPP, &ref);
        sc_render_sphere(NULL, json, g, SPHERE_PX, SPHERE_SPP, &a);
        for (int y = 0; y < ref.height; y++)
            for (int x = 0; x < ref.width; x++) {
                float *pa = sl_image_pixel(&ref, x, y), *pb = sl_image_pixel(&a, x, y);
                for (int c = 0; c < 3; c++) {
                    pa[c] *= pa[3];
                    pb[c] *= pa[3];
                }
            }
        double e = 1;
        CHECK_OK(sl_relative_rmse(&a, &ref, &e, NULL), NULL);
        printf("  stage %s sphere: relative RMSE default rig %.4f (bound %.2f)\n",
               g ? "glossy GGX 0.3" : "grey", e, bound[g]);
        CHECK_MSG(e <= bound[g], "%s %.4f > %.2f", g ? "glossy" : "grey", e, bound[g]);
        sl_image_free(&ref);
        sl_image_free(&a);
    }
    sl_rig_free(&rig);
    sl_vset_scene_free(&sc);
}

static void test_stage(void) { run_scene("stage", W, worst); }
static void test_exterior(void) { run_scene("exterior", W_UNRESOLVED, worst); }
static void test_night(void) { run_scene("night", W_UNRESOLVED, worst); }

int main(void)
{
    if (sl_test_sanitized()) {
        W_UNRESOLVED = 512;
        /* fewer pixels, not fewer samples: at 256 spp the grey sphere's noise
         * alone is 1.2%, above the 1% the test asserts */
        SPHERE_PX = 12;
    }
    RUN(test_stage);
    RUN(test_exterior);
    RUN(test_night);
    RUN(test_stage_render);
    printf("  worst: direction %.3f deg, solid angle %.1f%%, power %.2f%%\n", worst[0],
           100 * worst[1], 100 * worst[2]);
    return sl_test_finish();
}
