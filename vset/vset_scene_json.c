/* SPDX-License-Identifier: BSD-3-Clause */
/* Scene JSON files for the virtual set, and the light list written as
 * ground truth. Unknown keys are errors so that a misspelt field is not
 * silently ignored. */
#include <jansson.h>
#include <string.h>

#include "vset_internal.h"

typedef struct jctx {
    const char *path;
    sl_error *err;
} jctx;

static sl_result fail_type(jctx *j, const char *where, const char *what)
{
    return sl_error_set(j->err, SL_ERR_INPUT, "%s: %s: expected %s", j->path, where, what);
}

static sl_result get_number(jctx *j, json_t *obj, const char *key, const char *where,
                            bool required, double *out)
{
    json_t *v = json_object_get(obj, key);
    char at[160];
    snprintf(at, sizeof at, "%s%s%s", where, *where ? "." : "", key);
    if (!v) {
        if (required)
            return sl_error_set(j->err, SL_ERR_INPUT, "%s: %s: missing field \"%s\"", j->path,
                                *where ? where : "scene", key);
        return SL_OK;
    }
    if (!json_is_number(v))
        return fail_type(j, at, "a number");
    *out = json_number_value(v);
    return SL_OK;
}

static bool key_allowed(const char *key, const char *const *allowed)
{
    for (int i = 0; allowed[i]; i++)
        if (!strcmp(key, allowed[i]))
            return true;
    return false;
}

static sl_result check_keys(jctx *j, json_t *obj, const char *where, const char *const *allowed)
{
    const char *key;
    json_t *v;
    json_object_foreach(obj, key, v)
    {
        (void)v;
        if (!key_allowed(key, allowed))
            return sl_error_set(j->err, SL_ERR_INPUT, "%s: %s: unknown field \"%s\"", j->path,
                                *where ? where : "scene", key);
    }
    return SL_OK;
}

static sl_result read_light(jctx *j, json_t *o, int index, sl_vset_light *l)
{
    static const char *const keys[] = {"type", "name", "azimuth", "elevation", "diameter",
                                       "width", "height", "roll", "kelvin", "rgb",
                                       "luminance", "transmission", NULL};
    char where[64];
    snprintf(where, sizeof where, "lights[%d]", index);
    if (!json_is_object(o))
        return fail_type(j, where, "an object");
    sl_result r = check_keys(j, o, where, keys);
    if (r)
        return r;
    memset(l, 0, sizeof *l);
    json_t *type = json_object_get(o, "type");
    if (!type)
        return sl_error_set(j->err, SL_ERR_INPUT, "%s: %s: missing field \"type\"", j->path,
                            where);
    if (!json_is_string(type))
        return fail_type(j, where, "\"type\" to be a string");
    const char *t = json_string_value(type);
    json_t *name = json_object_get(o, "name");
    if (name && !json_is_string(name))
        return fail_type(j, where, "\"name\" to be a string");
    snprintf(l->name, sizeof l->name, "%s", name ? json_string_value(name) : t);
    if ((r = get_number(j, o, "azimuth", where, true, &l->azimuth_deg)) ||
        (r = get_number(j, o, "elevation", where, true, &l->elevation_deg)))
        return r;
    bool uniform = true;
    if (!strcmp(t, "sun")) {
        l->shape = SL_VSET_SHAPE_DISK;
        l->emit = SL_VSET_EMIT_SUN;
        l->width_deg = VSET_SUN_DIAMETER_DEG;
        uniform = false;
        if ((r = get_number(j, o, "diameter", where, false, &l->width_deg)))
            return r;
        l->height_deg = l->width_deg;
    } else if (!strcmp(t, "disk")) {
        l->shape = SL_VSET_SHAPE_DISK;
        if ((r = get_number(j, o, "diameter", where, true, &l->width_deg)))
            return r;
        l->height_deg = l->width_deg;
    } else if (!strcmp(t, "rect") || !strcmp(t, "window")) {
        l->shape = SL_VSET_SHAPE_RECT;
        if ((r = get_number(j, o, "width", where, true, &l->width_deg)) ||
            (r = get_number(j, o, "height", where, true, &l->height_deg)) ||
            (r = get_number(j, o, "roll", where, false, &l->roll_deg)))
            return r;
        if (!strcmp(t, "window")) {
            l->emit = SL_VSET_EMIT_WINDOW;
            l->luminance = 0.8;
            uniform = false;
            if ((r = get_number(j, o, "transmission", where, false, &l->luminance)))
                return r;
        }
    } else {
        return sl_error_set(j->err, SL_ERR_INPUT,
                            "%s: %s: unknown type \"%s\" (sun, disk, rect, window)", j->path,
                            where, t);
    }
    if (uniform) {
        if ((r = get_number(j, o, "luminance", where, true, &l->luminance)))
            return r;
        json_t *rgb = json_object_get(o, "rgb");
        if ((r = get_number(j, o, "kelvin", where, false, &l->kelvin)))
            return r;
        if (rgb) {
            char at[96];
            snprintf(at, sizeof at, "%s.rgb", where);
            if (!json_is_array(rgb) || json_array_size(rgb) != 3)
                return fail_type(j, at, "an array of 3 numbers");
            for (int c = 0; c < 3; c++) {
                json_t *v = json_array_get(rgb, (size_t)c);
                if (!json_is_number(v))
                    return fail_type(j, at, "an array of 3 numbers");
                l->rgb[c] = json_number_value(v);
            }
        } else if (!json_object_get(o, "kelvin")) {
            return sl_error_set(j->err, SL_ERR_INPUT,
                                "%s: %s: missing field \"kelvin\" (or \"rgb\")", j->path, where);
        }
    }
    return SL_OK;
}

sl_result sl_vset_desc_read_json(const char *path, sl_vset_desc *d, sl_error *err)
{
    memset(d, 0, sizeof *d);
    json_t *root;
    sl_result r = sl_json_load_file(path, "scene JSON", JSON_REJECT_DUPLICATES, &root, err);
    if (r)
        return r;
    jctx j = {path, err};
    static const char *const keys[] = {"name", "background", "turbidity", "ground_albedo",
                                       "room_illuminance", "dark_luminance", "sun_azimuth",
                                       "sun_elevation", "lights", NULL};
    json_t *bg, *lights, *name;
    if (!json_is_object(root)) {
        r = fail_type(&j, "scene", "a JSON object");
        goto done;
    }
    if ((r = check_keys(&j, root, "", keys)))
        goto done;
    /* Defaults match the presets; a file states what differs. */
    sl_vset_desc dflt;
    sl_vset_preset("exterior", &dflt, NULL);
    d->sun_azimuth_deg = dflt.sun_azimuth_deg;
    d->sun_elevation_deg = dflt.sun_elevation_deg;
    d->turbidity = dflt.turbidity;
    d->ground_albedo = dflt.ground_albedo;
    d->room_illuminance = dflt.room_illuminance;
    d->dark_luminance = dflt.dark_luminance;
    name = json_object_get(root, "name");
    if (name && !json_is_string(name)) {
        r = fail_type(&j, "name", "a string");
        goto done;
    }
    snprintf(d->name, sizeof d->name, "%s", name ? json_string_value(name) : "custom");
    bg = json_object_get(root, "background");
    if (!bg) {
        r = sl_error_set(err, SL_ERR_INPUT, "%s: scene: missing field \"background\"", path);
        goto done;
    }
    if (!json_is_string(bg)) {
        r = fail_type(&j, "background", "a string (sky, room, dark)");
        goto done;
    }
    if (!strcmp(json_string_value(bg), "sky"))
        d->background = SL_VSET_BG_SKY;
    else if (!strcmp(json_string_value(bg), "room"))
        d->background = SL_VSET_BG_ROOM;
    else if (!strcmp(json_string_value(bg), "dark"))
        d->background = SL_VSET_BG_DARK;
    else {
        r = sl_error_set(err, SL_ERR_INPUT, "%s: background: unknown \"%s\" (sky, room, dark)",
                         path, json_string_value(bg));
        goto done;
    }
    if ((r = get_number(&j, root, "turbidity", "", false, &d->turbidity)) ||
        (r = get_number(&j, root, "ground_albedo", "", false, &d->ground_albedo)) ||
        (r = get_number(&j, root, "room_illuminance", "", false, &d->room_illuminance)) ||
        (r = get_number(&j, root, "dark_luminance", "", false, &d->dark_luminance)) ||
        (r = get_number(&j, root, "sun_azimuth", "", false, &d->sun_azimuth_deg)) ||
        (r = get_number(&j, root, "sun_elevation", "", false, &d->sun_elevation_deg)))
        goto done;
    lights = json_object_get(root, "lights");
    if (!lights) {
        r = sl_error_set(err, SL_ERR_INPUT, "%s: scene: missing field \"lights\"", path);
        goto done;
    }
    if (!json_is_array(lights)) {
        r = fail_type(&j, "lights", "an array");
        goto done;
    }
    if (json_array_size(lights) > SL_VSET_MAX_LIGHTS) {
        r = sl_error_set(err, SL_ERR_INPUT, "%s: lights: %zu lights (at most %d)", path,
                         json_array_size(lights), SL_VSET_MAX_LIGHTS);
        goto done;
    }
    for (size_t i = 0; i < json_array_size(lights); i++) {
        if ((r = read_light(&j, json_array_get(lights, i), (int)i, &d->lights[i])))
            goto done;
        d->light_count++;
    }
    sl_error verr;
    if ((r = sl_vset_desc_validate(d, &verr)))
        sl_error_set(err, r, "%s: %s", path, verr.message);
done:
    json_decref(root);
    return r;
}

static json_t *vec3(const double v[3])
{
    return json_pack("[fff]", v[0], v[1], v[2]);
}

char *sl_vset_lights_json(const sl_vset_scene *scene)
{
    static const char *const shapes[] = {"disk", "rect"};
    static const char *const emits[] = {"uniform", "sun", "window"};
    static const char *const bgs[] = {"sky", "room", "dark"};
    const sl_vset_desc *d = &scene->desc;
    json_t *arr = json_array();
    for (int i = 0; i < d->light_count; i++) {
        const sl_vset_light *l = &d->lights[i];
        json_t *o = json_pack(
            "{s:s, s:s, s:s, s:f, s:f, s:f, s:f, s:f, s:o, s:f, s:o, s:o}", "name", l->name,
            "shape", shapes[l->shape], "emit", emits[l->emit], "azimuth_deg", l->azimuth_deg,
            "elevation_deg", l->elevation_deg, "width_deg", l->width_deg, "height_deg",
            l->height_deg, "roll_deg", l->roll_deg, "direction", vec3(l->dir), "solid_angle_sr",
            l->solid_angle, "radiance_rgb", vec3(l->radiance), "integral_rgb",
            vec3(l->integral));
        json_array_append_new(arr, o);
    }
    json_t *root = json_pack(
        "{s:s, s:s, s:s, s:s, s:i, s:i, s:o, s:f, s:f, s:f, s:o}", "scene", d->name,
        "units", "luminance-scaled linear Rec.709, 1 = 1 cd/m^2", "latlong",
        "OpenEXR lat-long: +Y up, centre column +Z, azimuth 90 = +X", "background",
        bgs[d->background], "width", scene->latlong.width, "height", scene->latlong.height,
        "total_integral_rgb", vec3(scene->total), "sun_azimuth_deg", d->sun_azimuth_deg,
        "sun_elevation_deg", d->sun_elevation_deg, "turbidity", d->turbidity, "lights", arr);
    char *s = json_dumps(root, JSON_INDENT(2) | JSON_REAL_PRECISION(10));
    json_decref(root);
    return s;
}
