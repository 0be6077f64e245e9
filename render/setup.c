/* SPDX-License-Identifier: BSD-3-Clause */
/* Scene set-up shared by the render and converge commands. */
#include <string.h>
#include <sys/stat.h>

#include "setlight/render.h"

bool sl_scene_arg_is_file(const char *s)
{
    struct stat sb;
    size_t n = strlen(s);
    return stat(s, &sb) == 0 || (n > 5 && !strcmp(s + n - 5, ".json")) || strchr(s, '/');
}

sl_result sl_scene_load(sl_scene *scene, const char *scene_arg, int width, const char *env,
                        const char *env_colorspace, double env_rotation_deg, double env_intensity,
                        const char *rig, sl_error *err)
{
    if (!env == !rig)
        return sl_error_set(err, SL_ERR_USAGE, "give exactly one of an environment and a rig");
    sl_result r = sl_scene_arg_is_file(scene_arg) ? sl_scene_read_json(scene, scene_arg, width, err)
                                                  : sl_scene_preset(scene, scene_arg, width, err);
    if (r)
        return r;
    if (rig)
        return sl_scene_read_rig(scene, rig, err);
    sl_image img;
    if ((r = sl_latlong_read(env, env_colorspace, &img, NULL, NULL, err)))
        return r;
    r = sl_scene_set_dome(scene, &img, env_rotation_deg, env_intensity, env, err);
    sl_image_free(&img);
    return r;
}
