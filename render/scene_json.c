/* SPDX-License-Identifier: BSD-3-Clause */
/* Scene files (JSON, docs/render.md). Every value is checked; a bad one is
 * SL_ERR_INPUT with the file and the field's path, e.g.
 * "scene.json: objects[2].radius must be > 0". */
#include <jansson.h>
#include <stdio.h>
#include <string.h>

#include "setlight/render.h"
#include "vec3.h"

typedef struct ctx {
    const char *path;
    sl_error *err;
} ctx;

static sl_result bad(const ctx *c, const char *field, const char *what)
{
    return sl_error_set(c->err, SL_ERR_INPUT, "%s: %s %s", c->path, field, what);
}

/* Number at key: required unless has_default; finite and >= min. */
static sl_result get_num(const ctx *c, json_t *obj, const char *prefix, const char *key, bool required,
                         double def, double min, double *out)
{
    char field[160];
    snprintf(field, sizeof field, "%s%s", prefix, key);
    json_t *v = json_object_get(obj, key);
    if (!v) {
        if (required)
            return bad(c, field, "is missing");
        *out = def;
        return SL_OK;
    }
    if (!json_is_number(v))
        return bad(c, field, "must be a number");
    double x = json_number_value(v);
    if (!isfinite(x))
        return bad(c, field, "must be finite");
    if (x < min) {
        char what[64];
        snprintf(what, sizeof what, "must be >= %g", min);
        return bad(c, field, what);
    }
    *out = x;
    return SL_OK;
}

static sl_result get_vec3(const ctx *c, json_t *obj, const char *prefix, const char *key,
                          bool required, const double def[3], double min, double out[3])
{
    char field[160];
    snprintf(field, sizeof field, "%s%s", prefix, key);
    json_t *v = json_object_get(obj, key);
    if (!v) {
        if (required)
            return bad(c, field, "is missing");
        v3_copy(out, def);
        return SL_OK;
    }
    if (!json_is_array(v) || json_array_size(v) != 3)
        return bad(c, field, "must be an array of 3 numbers");
    for (int i = 0; i < 3; i++) {
        json_t *e = json_array_get(v, (size_t)i);
        if (!json_is_number(e) || !isfinite(json_number_value(e)))
            return bad(c, field, "must be an array of 3 finite numbers");
        out[i] = json_number_value(e);
        if (out[i] < min) {
            char what[64];
            snprintf(what, sizeof what, "components must be >= %g", min);
            return bad(c, field, what);
        }
    }
    return SL_OK;
}

static sl_result read_material(const ctx *c, json_t *m, const char *name, sl_material *out)
{
    char prefix[128];
    snprintf(prefix, sizeof prefix, "materials.%s.", name);
    if (!json_is_object(m))
        return bad(c, prefix, "must be an object");
    const char *type = json_string_value(json_object_get(m, "type"));
    const double grey[3] = {0.18, 0.18, 0.18}, white[3] = {1, 1, 1};
    double col[3], tint[3], rough, ior;
    sl_result r;
    if (!type)
        return bad(c, prefix, "needs a \"type\" string (lambert, chrome, conductor, plastic)");
    if (!strcmp(type, "lambert")) {
        if ((r = get_vec3(c, m, prefix, "color", false, grey, 0, col)))
            return r;
        sl_material_lambert(out, col[0], col[1], col[2]);
    } else if (!strcmp(type, "chrome")) {
        sl_material_chrome(out);
    } else if (!strcmp(type, "conductor")) {
        if ((r = get_vec3(c, m, prefix, "reflectance", true, white, 0, col)) ||
            (r = get_vec3(c, m, prefix, "edge_tint", false, white, 0, tint)) ||
            (r = get_num(c, m, prefix, "roughness", false, 0, 0, &rough)))
            return r;
        sl_material_conductor(out, col, tint, rough);
    } else if (!strcmp(type, "plastic")) {
        if ((r = get_vec3(c, m, prefix, "color", false, grey, 0, col)) ||
            (r = get_num(c, m, prefix, "ior", false, 1.5, 1.0, &ior)) ||
            (r = get_num(c, m, prefix, "roughness", false, 0.3, 0, &rough)))
            return r;
        sl_material_plastic(out, col, ior, rough);
    } else {
        return bad(c, prefix, "type must be lambert, chrome, conductor or plastic");
    }
    sl_error merr = {0};
    if (sl_material_check(out, &merr))
        return sl_error_set(c->err, SL_ERR_INPUT, "%s: %s %s", c->path, prefix, merr.message);
    return SL_OK;
}

static sl_result read_camera(const ctx *c, json_t *j, int width, sl_camera *cam)
{
    if (!json_is_object(j))
        return bad(c, "camera", "must be an object");
    const char *type = json_string_value(json_object_get(j, "type"));
    const double pos0[3] = {0, 0, -10}, at0[3] = {0, 0, 0}, up0[3] = {0, 1, 0};
    double pos[3], at[3], up[3], aspect, size, fov;
    sl_result r;
    if ((r = get_vec3(c, j, "camera.", "position", false, pos0, -INFINITY, pos)) ||
        (r = get_vec3(c, j, "camera.", "look_at", false, at0, -INFINITY, at)) ||
        (r = get_vec3(c, j, "camera.", "up", false, up0, -INFINITY, up)) ||
        (r = get_num(c, j, "camera.", "aspect", false, 1.0, 1e-6, &aspect)) ||
        (r = get_num(c, j, "camera.", "width", false, 2.0, 1e-12, &size)) ||
        (r = get_num(c, j, "camera.", "fov", false, 40.0, 1e-6, &fov)))
        return r;
    if (!type || !strcmp(type, "orthographic"))
        cam->type = SL_CAMERA_ORTHOGRAPHIC;
    else if (!strcmp(type, "perspective"))
        cam->type = SL_CAMERA_PERSPECTIVE;
    else if (!strcmp(type, "fisheye"))
        cam->type = SL_CAMERA_FISHEYE;
    else
        return bad(c, "camera.type", "must be orthographic, perspective or fisheye");
    /* The image's height follows from the width (at most 65536, as --width)
     * and the aspect: the same bound, before it becomes an int. */
    if (!(width * aspect <= 65536.0))
        return bad(c, "camera.aspect", "makes the image taller than 65536 pixels");
    if ((cam->type == SL_CAMERA_PERSPECTIVE && fov >= 179.0) ||
        (cam->type == SL_CAMERA_FISHEYE && fov > 360.0))
        return bad(c, "camera.fov", "is too wide (perspective < 179, fisheye <= 360 degrees)");
    double f[3] = {at[0] - pos[0], at[1] - pos[1], at[2] - pos[2]}, right[3], u[3];
    if (!v3_normalize(f))
        return bad(c, "camera.look_at", "must differ from camera.position");
    v3_cross(f, up, right);
    if (!v3_normalize(right))
        return bad(c, "camera.up", "must not be parallel to the view direction");
    v3_cross(right, f, u);
    v3_copy(cam->position, pos);
    v3_copy(cam->forward, f);
    v3_copy(cam->up, u);
    cam->ortho_width = size;
    cam->fov_deg = fov;
    cam->width = width;
    cam->height = (int)(width * aspect + 0.5);
    if (cam->height < 1)
        cam->height = 1;
    return SL_OK;
}

static sl_result read_object(const ctx *c, sl_scene *s, json_t *o, size_t i, json_t *names)
{
    char prefix[64];
    snprintf(prefix, sizeof prefix, "objects[%zu].", i);
    if (!json_is_object(o))
        return bad(c, prefix, "must be an object");
    const char *type = json_string_value(json_object_get(o, "type"));
    const char *mat = json_string_value(json_object_get(o, "material"));
    if (!mat)
        return bad(c, prefix, "needs a \"material\" name");
    json_t *idx = json_object_get(names, mat);
    if (!idx) {
        char what[200];
        snprintf(what, sizeof what, "material \"%.120s\" is not defined in materials", mat);
        return bad(c, prefix, what);
    }
    int mi = (int)json_integer_value(idx);
    const double zero[3] = {0, 0, 0}, ny[3] = {0, 1, 0};
    double center[3], a[3], b[3], radius;
    sl_result r;
    if ((r = get_vec3(c, o, prefix, "center", false, zero, -INFINITY, center)))
        return r;
    sl_error serr = {0};
    if (type && !strcmp(type, "sphere")) {
        if ((r = get_num(c, o, prefix, "radius", false, 1.0, 0, &radius)))
            return r;
        if (radius <= 0)
            return bad(c, prefix, "radius must be > 0");
        r = sl_scene_add_sphere(s, center, radius, mi, &serr);
    } else if (type && !strcmp(type, "rect")) {
        if ((r = get_vec3(c, o, prefix, "u", true, zero, -INFINITY, a)) ||
            (r = get_vec3(c, o, prefix, "v", true, zero, -INFINITY, b)))
            return r;
        r = sl_scene_add_rect(s, center, a, b, mi, &serr);
    } else if (type && !strcmp(type, "disk")) {
        if ((r = get_vec3(c, o, prefix, "normal", false, ny, -INFINITY, a)) ||
            (r = get_num(c, o, prefix, "radius", false, 1.0, 0, &radius)))
            return r;
        if (radius <= 0)
            return bad(c, prefix, "radius must be > 0");
        r = sl_scene_add_disk(s, center, a, radius, mi, &serr);
    } else {
        return bad(c, prefix, "type must be sphere, rect or disk");
    }
    if (r)
        return sl_error_set(c->err, r, "%s: %s %s", c->path, prefix, serr.message);
    return SL_OK;
}

sl_result sl_scene_read_json(sl_scene *scene, const char *path, int width, sl_error *err)
{
    sl_result r = sl_check_input_size(path, SL_MAX_JSON_BYTES, "scene JSON", err);
    if (r)
        return r;
    if (width < 1)
        return sl_error_set(err, SL_ERR_USAGE, "%s: image width %d must be at least 1", path, width);
    json_error_t jerr;
    json_t *root = json_load_file(path, JSON_REJECT_DUPLICATES, &jerr);
    if (!root)
        return sl_error_set(err, SL_ERR_INPUT, "%s: line %d: %s", path, jerr.line, jerr.text);
    ctx c = {path, err};
    json_t *names = json_object();
    if (!json_is_object(root)) {
        r = bad(&c, "the top level", "must be an object");
        goto done;
    }
    const char *preset = json_string_value(json_object_get(root, "preset"));
    if (preset) {
        sl_error perr = {0};
        if ((r = sl_scene_preset(scene, preset, width, &perr))) {
            r = sl_error_set(err, SL_ERR_INPUT, "%s: preset: %s", path, perr.message);
            goto done;
        }
    }
    json_t *mats = json_object_get(root, "materials");
    if (mats && !json_is_object(mats)) {
        r = bad(&c, "materials", "must be an object of named materials");
        goto done;
    }
    json_t *objs = json_object_get(root, "objects");
    if (json_array_size(objs) > SL_RENDER_MAX_OBJECTS ||
        json_object_size(mats) > SL_RENDER_MAX_OBJECTS) {
        r = sl_error_set(err, SL_ERR_INPUT, "%s: %zu objects and %zu materials, more than a scene "
                         "may hold (%d each)", path, json_array_size(objs),
                         json_object_size(mats), SL_RENDER_MAX_OBJECTS);
        goto done;
    }
    const char *key;
    json_t *val;
    json_object_foreach(mats, key, val)
    {
        sl_material m;
        int idx;
        if ((r = read_material(&c, val, key, &m)) ||
            (r = sl_scene_add_material(scene, &m, &idx, err)))
            goto done;
        json_object_set_new(names, key, json_integer(idx));
    }
    if (objs && !json_is_array(objs)) {
        r = bad(&c, "objects", "must be an array");
        goto done;
    }
    for (size_t i = 0; i < json_array_size(objs); i++)
        if ((r = read_object(&c, scene, json_array_get(objs, i), i, names)))
            goto done;
    if (scene->shape_count == 0) {
        r = bad(&c, "objects", "must hold at least one object (or name a preset)");
        goto done;
    }
    json_t *cam = json_object_get(root, "camera");
    if (cam && (r = read_camera(&c, cam, width, &scene->camera)))
        goto done;
    if (!preset && !cam)
        sl_camera_validation(&scene->camera, width, width, 2.0, 0, 0);
    json_t *bg = json_object_get(root, "background");
    if (bg) {
        const char *b = json_string_value(bg);
        if (!b || (strcmp(b, "env") && strcmp(b, "black"))) {
            r = bad(&c, "background", "must be \"env\" or \"black\"");
            goto done;
        }
        scene->background_env = !strcmp(b, "env");
    }
    if (!preset) {
        const char *base = strrchr(path, '/');
        snprintf(scene->name, sizeof scene->name, "%s", base ? base + 1 : path);
    }
    r = SL_OK;
done:
    json_decref(names);
    json_decref(root);
    return r;
}
