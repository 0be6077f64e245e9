/* SPDX-License-Identifier: BSD-3-Clause */
/* Scene construction with validation of every shape. */
#include <stdlib.h>
#include <string.h>

#include "scene_internal.h"
#include "vec3.h"

void sl_scene_init(sl_scene *scene)
{
    memset(scene, 0, sizeof *scene);
    sl_camera_validation(&scene->camera, 256, 256, 2.0, 0, 0);
}

void sl_scene_free(sl_scene *scene)
{
    for (int i = 0; i < scene->light_count; i++) {
        sl_image_free(&scene->lights[i].texture);
        sl_distrib2d_free(&scene->lights[i].texture_dist);
    }
    free(scene->lights);
    free(scene->shapes);
    free(scene->materials);
    sl_dome_free(&scene->dome);
    memset(scene, 0, sizeof *scene);
}

sl_result sl_scene_add_material(sl_scene *scene, const sl_material *m, int *index, sl_error *err)
{
    sl_result r = sl_material_check(m, err);
    if (r)
        return r;
    sl_material *nm = realloc(scene->materials, (size_t)(scene->material_count + 1) * sizeof *nm);
    if (!nm)
        return sl_error_set(err, SL_ERR_NOMEM, "scene: out of memory for materials");
    scene->materials = nm;
    nm[scene->material_count] = *m;
    if (index)
        *index = scene->material_count;
    scene->material_count++;
    return SL_OK;
}

static sl_result add_shape(sl_scene *scene, const sl_shape *s, sl_error *err)
{
    if (s->material < 0 || s->material >= scene->material_count)
        return sl_error_set(err, SL_ERR_INPUT, "scene: shape refers to material %d of %d",
                            s->material, scene->material_count);
    sl_shape *ns = realloc(scene->shapes, (size_t)(scene->shape_count + 1) * sizeof *ns);
    if (!ns)
        return sl_error_set(err, SL_ERR_NOMEM, "scene: out of memory for shapes");
    scene->shapes = ns;
    ns[scene->shape_count++] = *s;
    return SL_OK;
}

sl_result sl_scene_add_sphere(sl_scene *scene, const double center[3], double radius, int material,
                              sl_error *err)
{
    if (!v3_finite(center) || !isfinite(radius) || !(radius > 0))
        return sl_error_set(err, SL_ERR_INPUT, "scene: sphere needs a finite centre and radius > 0");
    sl_shape s = {.type = SL_SHAPE_SPHERE, .radius = radius, .material = material};
    v3_copy(s.center, center);
    return add_shape(scene, &s, err);
}

sl_result sl_scene_add_rect(sl_scene *scene, const double center[3], const double u[3],
                            const double v[3], int material, sl_error *err)
{
    sl_shape s = {.type = SL_SHAPE_RECT, .material = material};
    v3_copy(s.center, center);
    v3_copy(s.u, u);
    double n[3];
    v3_cross(u, v, n);
    /* Keep v's length but make it orthogonal to u. */
    double vlen = v3_length(v), w[3];
    v3_cross(n, u, w);
    if (!v3_finite(center) || !v3_finite(u) || !v3_finite(v) || !v3_normalize(n) ||
        !v3_normalize(w) || !(v3_length(u) > 0))
        return sl_error_set(err, SL_ERR_INPUT,
                            "scene: rect needs a finite centre and two non-parallel, non-zero edges");
    for (int i = 0; i < 3; i++)
        s.v[i] = w[i] * vlen;
    v3_copy(s.normal, n);
    return add_shape(scene, &s, err);
}

sl_result sl_scene_add_disk(sl_scene *scene, const double center[3], const double normal[3],
                            double radius, int material, sl_error *err)
{
    sl_shape s = {.type = SL_SHAPE_DISK, .radius = radius, .material = material};
    v3_copy(s.center, center);
    v3_copy(s.normal, normal);
    if (!v3_finite(center) || !v3_finite(normal) || !v3_normalize(s.normal) || !isfinite(radius) ||
        !(radius > 0))
        return sl_error_set(err, SL_ERR_INPUT,
                            "scene: disk needs a finite centre, a non-zero normal and radius > 0");
    return add_shape(scene, &s, err);
}
