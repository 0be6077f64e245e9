/* SPDX-License-Identifier: BSD-3-Clause */
/* rig.json, version 2 (schema in docs/lightrig.md). */
#include <jansson.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "lightrig_private.h"

/* rig.json as written and as sl_rig_json_string returns it. */
#define RIG_JSON_FLAGS (JSON_INDENT(2) | JSON_REAL_PRECISION(17))

static json_t *vec(const double *v, int n)
{
    json_t *a = json_array();
    for (int i = 0; i < n; i++)
        json_array_append_new(a, json_real(v[i]));
    return a;
}

static json_t *rig_json(const sl_rig *rig, const char *dome_file)
{
    json_t *lights = json_array(), *skipped = json_array();
    for (int i = 0; i < rig->light_count; i++) {
        const sl_rig_light *L = &rig->lights[i];
        json_t *o = json_object();
        json_object_set_new(o, "type", json_string(sl_rig_shape_name(L->shape)));
        json_object_set_new(o, "direction", vec(L->direction, 3));
        json_object_set_new(o, "solid_angle", json_real(L->solid_angle));
        json_object_set_new(o, "radiance", vec(L->radiance, 3));
        json_object_set_new(o, "integral", vec(L->integral, 3));
        json_object_set_new(o, "position", L->has_position ? vec(L->position, 3) : json_null());
        json_object_set_new(o, "size", L->has_position ? vec(L->size, 2) : json_null());
        json_object_set_new(o, "texture", L->texture[0] ? json_string(L->texture) : json_null());
        /* v2, optional for readers: the texture choice and its reason */
        json_object_set_new(o, "textured", json_boolean(L->texture[0] != 0));
        json_object_set_new(o, "texture_variation", json_real(L->variation));
        json_object_set_new(o, "texture_reason", json_string(L->texture_reason));
        /* v2: the shape at infinity (degrees: full angular width along
         * axis_u, height along direction x axis_u) and the two rankings */
        json_object_set_new(o, "axis_u", vec(L->axis_u, 3));
        double deg[2] = {L->angular_size[0] * 180 / M_PI, L->angular_size[1] * 180 / M_PI};
        json_object_set_new(o, "angular_size", vec(deg, 2));
        json_object_set_new(o, "share", json_real(L->share));
        json_object_set_new(o, "share_glossy", json_real(L->share_glossy));
        json_array_append_new(lights, o);
    }
    for (int i = 0; i < rig->skipped_count; i++) {
        const sl_rig_skip *s = &rig->skipped[i];
        json_t *o = json_object();
        json_object_set_new(o, "direction", vec(s->direction, 3));
        json_object_set_new(o, "solid_angle", json_real(s->solid_angle));
        json_object_set_new(o, "integral", vec(s->integral, 3));
        json_object_set_new(o, "share", json_real(s->share));
        json_object_set_new(o, "share_glossy", json_real(s->share_glossy));
        json_object_set_new(o, "reason", json_string(s->reason));
        json_array_append_new(skipped, o);
    }
    json_t *dome = json_object();
    json_object_set_new(dome, "file", dome_file ? json_string(dome_file) : json_null());
    json_object_set_new(dome, "integral", vec(rig->dome, 3));
    json_t *ledger = json_object();
    json_object_set_new(ledger, "original", vec(rig->original, 3));
    json_object_set_new(ledger, "lights", vec(rig->lights_sum, 3));
    json_object_set_new(ledger, "dome", vec(rig->dome, 3));
    json_object_set_new(ledger, "relative_error", json_real(rig->relative_error));
    json_t *root = json_object();
    json_object_set_new(root, "version", json_integer(2));
    json_object_set_new(root, "lights", lights);
    json_object_set_new(root, "dome", dome);
    json_object_set_new(root, "ledger", ledger);
    json_object_set_new(root, "skipped", skipped);
    return root;
}

char *sl_rig_json_string(const sl_rig *rig, const char *dome_file)
{
    json_t *root = rig_json(rig, dome_file);
    char *s = json_dumps(root, RIG_JSON_FLAGS);
    json_decref(root);
    return s;
}

sl_result sl_rig_write_json(const sl_rig *rig, const char *path, const char *dome_file,
                            sl_error *err)
{
    json_t *root = rig_json(rig, dome_file);
    sl_result r = sl_json_write_atomic(path, root, RIG_JSON_FLAGS, err);
    json_decref(root);
    return r;
}
