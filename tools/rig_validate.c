/* SPDX-License-Identifier: BSD-3-Clause */
/* Validation for `setlight rig --validate`: the grey, chrome and
 * shadow scenes rendered under the map and under the rig. */
#include "rig_validate.h"

#include "setlight/render.h"

static sl_result render_one(const char *preset, const sl_image *env, const char *rig_json,
                            int width, int64_t spp, sl_image *out, sl_error *err)
{
    sl_scene s;
    sl_scene_init(&s);
    sl_result r = sl_scene_preset(&s, preset, width, err);
    if (!r)
        r = env ? sl_scene_set_dome(&s, env, 0, 1, "map", err)
                : sl_scene_read_rig(&s, rig_json, err);
    /* The lighting is compared, not the map seen behind the objects. */
    s.background_env = false;
    if (!r) {
        sl_render_options o;
        sl_render_options_init(&o);
        o.spp = spp;
        /* one bounce: the shadow scene's ground lights the sphere's underside */
        o.bounces = 1;
        sl_render_stats st;
        r = sl_render(&s, &o, out, &st, err);
        if (!r)
            sl_render_stats_free(&st);
    }
    sl_scene_free(&s);
    return r;
}

sl_result rig_validate(const sl_image *env, const char *rig_json, int width, int64_t spp,
                       rig_validation *v, sl_error *err)
{
    static const char *const scenes[RIG_VALIDATE_SCENES] = {"grey", "chrome", "shadow"};
    double t0 = sl_seconds();
    v->width = width;
    v->spp = spp;
    sl_result r = SL_OK;
    for (int k = 0; k < RIG_VALIDATE_SCENES && !r; k++) {
        sl_image a = {0}, b = {0};
        v->scene[k] = scenes[k];
        v->error[k] = -1;
        if (!(r = render_one(scenes[k], env, NULL, width, spp, &a, err)) &&
            !(r = render_one(scenes[k], NULL, rig_json, width, spp, &b, err))) {
            /* Only the objects: a rig light seen directly (a rect far
             * away) is not the map behind them. */
            for (int y = 0; y < a.height; y++)
                for (int x = 0; x < a.width; x++) {
                    float *pa = sl_image_pixel(&a, x, y), *pb = sl_image_pixel(&b, x, y);
                    for (int c = 0; c < 3; c++) {
                        pa[c] *= pa[3];
                        pb[c] *= pa[3];
                    }
                }
            r = sl_relative_rmse(&b, &a, &v->error[k], err);
        }
        sl_image_free(&a);
        sl_image_free(&b);
    }
    v->seconds = sl_seconds() - t0;
    return r;
}
