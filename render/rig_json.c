/* SPDX-License-Identifier: BSD-3-Clause */
/* Light rigs as JSON (docs/render.md): an optional dome and a list of
 * UsdLux-style lights. Paths are relative to the rig's folder. */
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "render_internal.h"

static void resolve(const char *rig, const char *file, char *out, size_t n)
{
    const char *slash = strrchr(rig, '/');
    if (file[0] == '/' || !slash)
        snprintf(out, n, "%s", file);
    else
        snprintf(out, n, "%.*s/%s", (int)(slash - rig), rig, file);
}

static bool num(json_t *o, const char *key, double def, double *out)
{
    json_t *v = json_object_get(o, key);
    if (!v) {
        *out = def;
        return true;
    }
    *out = json_number_value(v);
    return json_is_number(v) && isfinite(*out);
}

static bool vec3(json_t *o, const char *key, const double def[3], double out[3])
{
    json_t *v = json_object_get(o, key);
    if (!v) {
        v3_copy(out, def);
        return true;
    }
    if (!json_is_array(v) || json_array_size(v) != 3)
        return false;
    for (int i = 0; i < 3; i++) {
        json_t *e = json_array_get(v, (size_t)i);
        out[i] = json_number_value(e);
        if (!json_is_number(e) || !isfinite(out[i]))
            return false;
    }
    return true;
}

static sl_result read_light(sl_scene *scene, const char *path, json_t *j, size_t i, sl_error *err)
{
    sl_light l;
    memset(&l, 0, sizeof l);
    const char *type = json_string_value(json_object_get(j, "type"));
    if (!type)
        return sl_error_set(err, SL_ERR_INPUT, "%s: lights[%zu].type is missing", path, i);
    if (!strcmp(type, "rect"))
        l.type = SL_LIGHT_RECT;
    else if (!strcmp(type, "disk"))
        l.type = SL_LIGHT_DISK;
    else if (!strcmp(type, "sphere"))
        l.type = SL_LIGHT_SPHERE;
    else if (!strcmp(type, "distant"))
        l.type = SL_LIGHT_DISTANT;
    else
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s: lights[%zu].type '%s' is not rect, disk, sphere or distant", path, i,
                            type);
    const double zero[3] = {0, 0, 0}, down[3] = {0, -1, 0}, one[3] = {1, 1, 1}, y[3] = {0, 1, 0},
                 z[3] = {0, 0, 1};
    double dir[3], up[3];
    json_t *norm = json_object_get(j, "normalize");
    const char *field = NULL;
    if (!vec3(j, "position", zero, l.position))
        field = "position";
    else if (!vec3(j, "direction", down, dir))
        field = "direction";
    else if (!vec3(j, "up", fabs(dir[1]) > 0.9 * v3_length(dir) ? z : y, up))
        field = "up";
    else if (!vec3(j, "color", one, l.color))
        field = "color";
    else if (!num(j, "intensity", 1.0, &l.intensity))
        field = "intensity";
    else if (!num(j, "exposure", 0.0, &l.exposure))
        field = "exposure";
    else if (!num(j, "width", 1.0, &l.width))
        field = "width";
    else if (!num(j, "height", 1.0, &l.height))
        field = "height";
    else if (!num(j, "radius", 0.5, &l.radius))
        field = "radius";
    else if (!num(j, "angle", 0.53, &l.angle_deg))
        field = "angle";
    else if (norm && !json_is_boolean(norm))
        field = "normalize";
    if (field)
        return sl_error_set(err, SL_ERR_INPUT, "%s: lights[%zu].%s has the wrong type or is not finite",
                            path, i, field);
    l.normalize = json_is_true(norm);
    /* UsdLux lights emit along their -Z axis. */
    for (int k = 0; k < 3; k++) {
        l.axis_z[k] = -dir[k];
        l.axis_y[k] = up[k];
    }
    const char *tex = json_string_value(json_object_get(j, "texture"));
    if (tex) {
        char full[4096];
        resolve(path, tex, full, sizeof full);
        sl_error terr = {0};
        sl_result r = sl_image_read(full, &l.texture, NULL, &terr);
        if (r)
            return sl_error_set(err, r, "%s: lights[%zu].texture: %s", path, i, terr.message);
    }
    sl_error lerr = {0};
    sl_result r = sl_scene_add_light(scene, &l, &lerr);
    if (r)
        return sl_error_set(err, r, "%s: lights[%zu]: %s", path, i,
                            strchr(lerr.message, ':') ? strchr(lerr.message, ':') + 2 : lerr.message);
    return SL_OK;
}

sl_result sl_scene_read_rig(sl_scene *scene, const char *path, sl_error *err)
{
    sl_result r = sl_check_input_file(path, err);
    if (r)
        return r;
    json_error_t jerr;
    json_t *root = json_load_file(path, JSON_REJECT_DUPLICATES, &jerr);
    if (!root)
        return sl_error_set(err, SL_ERR_INPUT, "%s: line %d: %s", path, jerr.line, jerr.text);
    json_t *lights = json_object_get(root, "lights"), *dome = json_object_get(root, "dome");
    if (!json_is_object(root) || (lights && !json_is_array(lights)) || (dome && !json_is_object(dome))) {
        r = sl_error_set(err, SL_ERR_INPUT, "%s: a rig is an object with a \"lights\" array and an "
                                            "optional \"dome\" object", path);
        goto done;
    }
    for (size_t i = 0; i < json_array_size(lights); i++)
        if ((r = read_light(scene, path, json_array_get(lights, i), i, err)))
            goto done;
    if (dome) {
        const char *file = json_string_value(json_object_get(dome, "file"));
        double rot, inten;
        if (!file || !num(dome, "rotation", 0, &rot) || !num(dome, "intensity", 1, &inten)) {
            r = sl_error_set(err, SL_ERR_INPUT,
                             "%s: dome needs a \"file\" and numeric rotation/intensity", path);
            goto done;
        }
        char full[4096];
        resolve(path, file, full, sizeof full);
        sl_image env;
        if ((r = sl_image_read(full, &env, NULL, err)))
            goto done;
        r = sl_scene_set_dome(scene, &env, rot, inten, full, err);
        sl_image_free(&env);
        if (r)
            goto done;
    }
    if (!dome && scene->light_count == 0) {
        r = sl_error_set(err, SL_ERR_INPUT, "%s: the rig has no lights and no dome", path);
        goto done;
    }
    r = SL_OK;
done:
    json_decref(root);
    return r;
}
