/* SPDX-License-Identifier: BSD-3-Clause */
/* rig.json versions 1 and 2 (the light-rig extractor's format,
 * docs/lightrig.md) turned into renderer lights: each light, seen from the
 * capture point at the origin, keeps the rig's direction, solid angle and
 * radiance; with version 2 also its shape and roll at infinity. Paths are
 * relative to the rig's folder. */
#include <jansson.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/render.h"
#include "vec3.h"

static void resolve(const char *rig, const char *file, char *out, size_t n)
{
    const char *slash = strrchr(rig, '/');
    if (file[0] == '/' || !slash)
        snprintf(out, n, "%s", file);
    else
        snprintf(out, n, "%.*s/%s", (int)(slash - rig), rig, file);
}

/* n finite numbers, each >= lo. */
static bool nums(json_t *v, int n, double lo, double *out)
{
    if (!json_is_array(v) || json_array_size(v) != (size_t)n)
        return false;
    for (int i = 0; i < n; i++) {
        json_t *e = json_array_get(v, (size_t)i);
        out[i] = json_number_value(e);
        if (!json_is_number(e) || !isfinite(out[i]) || out[i] < lo)
            return false;
    }
    return true;
}

static sl_result read_image(const char *path, const char *field, const char *file, sl_image *img,
                            sl_error *err)
{
    char full[4096];
    resolve(path, file, full, sizeof full);
    sl_error ierr = {0};
    if (sl_image_read_linear(full, NULL, img, NULL, NULL, &ierr))
        return sl_error_set(err, SL_ERR_INPUT, "%s: %s: %s", path, field, ierr.message);
    return SL_OK;
}

/* A rect at infinity becomes a rect this far away (metres): the validation
 * scenes are a few metres across, so the parallax is under 0.03 degrees. */
#define RIG_FAR 1e4

static sl_result read_light(sl_scene *scene, const char *path, json_t *j, size_t i, int version,
                            sl_error *err)
{
    char field[64];
    const char *type = json_string_value(json_object_get(j, "type"));
    double dir[3], omega, rad[3], pos[3] = {0, 0, 0}, size[2] = {0, 0};
    json_t *jpos = json_object_get(j, "position"), *jsize = json_object_get(j, "size");
    json_t *jtex = json_object_get(j, "texture");
    double axis_u[3] = {0, 0, 0}, ang[2] = {0, 0};
    const char *bad = NULL;
    if (!json_is_object(j))
        bad = "";
    else if (!type || (strcmp(type, "rect") && strcmp(type, "disk") && strcmp(type, "sphere") &&
                       strcmp(type, "distant")))
        bad = "type";
    else if (!nums(json_object_get(j, "direction"), 3, -INFINITY, dir) || !v3_normalize(dir))
        bad = "direction";
    else if (omega = json_number_value(json_object_get(j, "solid_angle")),
             !json_is_number(json_object_get(j, "solid_angle")) ||
                 !(omega > 0 && omega <= 4 * SL_PI))
        bad = "solid_angle";
    else if (!nums(json_object_get(j, "radiance"), 3, 0, rad))
        bad = "radiance";
    else if (!json_is_null(jpos) && !nums(jpos, 3, -INFINITY, pos))
        bad = "position";
    else if (json_is_null(jpos) != json_is_null(jsize) ||
             (!json_is_null(jsize) && !(nums(jsize, 2, 0, size) && size[0] > 0 && size[1] > 0)))
        bad = "size";
    else if (!json_is_null(jtex) && (!json_is_string(jtex) || strcmp(type, "rect") ||
                                     (version < 2 && json_is_null(jpos))))
        bad = "texture";
    else if (version >= 2 && (!nums(json_object_get(j, "axis_u"), 3, -INFINITY, axis_u) ||
                              !v3_normalize(axis_u) || fabs(v3_dot(axis_u, dir)) > 1e-3))
        bad = "axis_u";
    else if (version >= 2 && (!nums(json_object_get(j, "angular_size"), 2, 0, ang) ||
                              !(ang[0] > 0 && ang[0] <= 360 && ang[1] > 0 && ang[1] <= 360) ||
                              (!strcmp(type, "rect") && !(ang[0] < 180 && ang[1] < 180))))
        bad = "angular_size";
    if (bad) {
        snprintf(field, sizeof field, "lights[%zu]%s%s", i, *bad ? "." : "", bad);
        return sl_error_set(err, SL_ERR_INPUT, "%s: %s is missing, of the wrong type, not finite "
                            "or out of range", path, field);
    }
    sl_light l;
    memset(&l, 0, sizeof l);
    l.intensity = 1;
    v3_copy(l.color, rad);
    /* Every light emits along its -Z, toward the capture point. */
    v3_copy(l.axis_z, dir);
    if (json_is_null(jpos) && version >= 2 && !strcmp(type, "rect")) {
        /* A rect at infinity: far away, with its angular size and roll,
         * and the radiance that keeps its solid angle's power exactly. */
        double tu = tan(0.5 * ang[0] * SL_PI / 180), tv = tan(0.5 * ang[1] * SL_PI / 180);
        double om = 4 * asin(tu * tv / sqrt((1 + tu * tu) * (1 + tv * tv)));
        for (int k = 0; k < 3; k++)
            l.color[k] *= omega / om;
        l.type = SL_LIGHT_RECT;
        for (int k = 0; k < 3; k++)
            l.position[k] = RIG_FAR * dir[k];
        l.width = 2 * RIG_FAR * tu;
        l.height = 2 * RIG_FAR * tv;
    } else if (json_is_null(jpos)) {
        /* At infinity: the cone of the rig's solid angle. A cone cannot
         * exceed a hemisphere (median cut's regions can), so there the
         * radiance carries the rest of the region's power. */
        double c = 1 - omega / (2 * SL_PI), cmin = cos(0.5 * 179.9 * SL_PI / 180);
        if (c < cmin) {
            for (int k = 0; k < 3; k++)
                l.color[k] *= omega / (2 * SL_PI * (1 - cmin));
            c = cmin;
        }
        l.type = SL_LIGHT_DISTANT;
        l.angle_deg = 2 * acos(c) * 180 / SL_PI;
    } else {
        /* Placed, facing the capture point, sized by the rig. */
        v3_copy(l.position, pos);
        if (v3_normalize(pos))
            v3_copy(l.axis_z, pos);
        l.type = !strcmp(type, "sphere") ? SL_LIGHT_SPHERE
                 : !strcmp(type, "disk") ? SL_LIGHT_DISK : SL_LIGHT_RECT;
        l.width = size[0];
        l.height = size[1];
        l.radius = 0.5 * size[0];
    }
    if (version >= 2) {
        /* the rig's frame: X = axis_u (the width), Y = direction x axis_u */
        v3_cross(l.axis_z, axis_u, l.axis_y);
    } else {
        /* v1 carries no roll: +Y up unless the light is overhead or underfoot. */
        v3_set(l.axis_y, 0, fabs(l.axis_z[1]) > 0.9 ? 0 : 1, fabs(l.axis_z[1]) > 0.9 ? 1 : 0);
    }
    if (json_is_string(jtex)) {
        snprintf(field, sizeof field, "lights[%zu].texture", i);
        sl_result r = read_image(path, field, json_string_value(jtex), &l.texture, err);
        if (r)
            return r;
        /* UsdLux (and setlight rig) put the texture's first column at the
         * light's +X; the renderer samples column 0 at -X. */
        for (int y = 0; y < l.texture.height; y++)
            for (int x = 0; x < l.texture.width / 2; x++) {
                float *a = sl_image_pixel(&l.texture, x, y);
                float *b = sl_image_pixel(&l.texture, l.texture.width - 1 - x, y);
                for (int c = 0; c < l.texture.channels; c++) {
                    float t = a[c];
                    a[c] = b[c];
                    b[c] = t;
                }
            }
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
    sl_result r = sl_check_input_size(path, SL_MAX_JSON_BYTES, "rig JSON", err);
    if (r)
        return r;
    json_error_t jerr;
    json_t *root = json_load_file(path, JSON_REJECT_DUPLICATES, &jerr);
    if (!root)
        return sl_error_set(err, SL_ERR_INPUT, "%s: line %d: %s", path, jerr.line, jerr.text);
    json_t *lights = json_object_get(root, "lights"), *dome = json_object_get(root, "dome");
    json_t *version = json_object_get(root, "version");
    json_t *file = dome ? json_object_get(dome, "file") : NULL;
    if (!json_is_object(root) || !json_is_integer(version) ||
        json_integer_value(version) < 1 || json_integer_value(version) > 2) {
        r = sl_error_set(err, SL_ERR_INPUT, "%s: version is not 1 or 2 (a rig.json from "
                                            "setlight rig is expected)", path);
        goto done;
    }
    if (!json_is_array(lights)) {
        r = sl_error_set(err, SL_ERR_INPUT, "%s: lights is not an array", path);
        goto done;
    }
    if (json_array_size(lights) > SL_RENDER_MAX_LIGHTS) {
        r = sl_error_set(err, SL_ERR_INPUT, "%s: %zu lights, more than a rig may hold (%d)", path,
                         json_array_size(lights), SL_RENDER_MAX_LIGHTS);
        goto done;
    }
    if (!json_is_object(dome) || !(json_is_null(file) || json_is_string(file))) {
        r = sl_error_set(err, SL_ERR_INPUT, "%s: dome is not an object with a file (or null)",
                         path);
        goto done;
    }
    for (size_t i = 0; i < json_array_size(lights); i++)
        if ((r = read_light(scene, path, json_array_get(lights, i), i,
                            (int)json_integer_value(version), err)))
            goto done;
    if (json_is_string(file)) {
        sl_image env;
        if ((r = read_image(path, "dome.file", json_string_value(file), &env, err)))
            goto done;
        char full[4096];
        resolve(path, json_string_value(file), full, sizeof full);
        r = sl_scene_set_dome(scene, &env, 0, 1, full, err);
        sl_image_free(&env);
        if (r)
            goto done;
    }
    r = SL_OK;
done:
    json_decref(root);
    return r;
}
