/* SPDX-License-Identifier: BSD-3-Clause */
/* The validation scenes. All use the validation camera (sl_camera_validation)
 * unless noted; layouts are in docs/render.md. */
#include <stdio.h>
#include <string.h>

#include "setlight/render.h"
#include "vec3.h"

const char *sl_scene_preset_names(void) { return "grey chrome chart refs shadow materials"; }

static int image_height(int width, double aspect)
{
    int h = (int)(width * aspect + 0.5);
    return h < 1 ? 1 : h;
}

/* The chart: 4 rows of 6 patches on a black frame in the plane z = cz,
 * facing -Z (the validation camera). Patch 1 (dark skin) at the image's
 * top left, which is +X because image right is -X. Frame 2.0 x 1.36. */
#define CHART_W 2.0
#define CHART_H 1.36
static sl_result add_chart(sl_scene *s, double cx, double cy, double cz, sl_error *err)
{
    sl_material m;
    int frame;
    sl_material_lambert(&m, 0.02, 0.02, 0.02);
    sl_result r = sl_scene_add_material(s, &m, &frame, err);
    if (r)
        return r;
    double c[3] = {cx, cy, cz}, u[3] = {0.5 * CHART_W, 0, 0}, v[3] = {0, 0.5 * CHART_H, 0};
    /* u x v = +Z; the face is two-sided, so the frame looks the same from -Z. */
    if ((r = sl_scene_add_rect(s, c, u, v, frame, err)))
        return r;
    const double pitch = 0.32, half = 0.13;
    for (int i = 0; i < 24; i++) {
        int row = i / 6, col = i % 6, idx;
        const double *a = SL_COLORCHECKER_LINEAR[i];
        sl_material_lambert(&m, a[0], a[1], a[2]);
        if ((r = sl_scene_add_material(s, &m, &idx, err)))
            return r;
        double pc[3] = {cx + (2.5 - col) * pitch, cy + (1.5 - row) * pitch, cz - 1e-3};
        double pu[3] = {half, 0, 0}, pv[3] = {0, half, 0};
        if ((r = sl_scene_add_rect(s, pc, pu, pv, idx, err)))
            return r;
    }
    return SL_OK;
}

static sl_result add_sphere_mat(sl_scene *s, const sl_material *m, double x, double y, double z,
                                sl_error *err)
{
    int idx;
    sl_result r = sl_scene_add_material(s, m, &idx, err);
    if (r)
        return r;
    double c[3] = {x, y, z};
    return sl_scene_add_sphere(s, c, 1.0, idx, err);
}

sl_result sl_scene_preset(sl_scene *s, const char *name, int width, sl_error *err)
{
    if (width < 1)
        return sl_error_set(err, SL_ERR_USAGE, "preset %s: width %d must be at least 1",
                            name ? name : "(none)", width);
    sl_material m;
    sl_result r;
    const char *n = name ? name : "";
    if (!strcmp(n, "grey") || !strcmp(n, "chrome")) {
        if (n[0] == 'g')
            sl_material_lambert(&m, 0.18, 0.18, 0.18);
        else
            sl_material_chrome(&m);
        r = add_sphere_mat(s, &m, 0, 0, 0, err);
        sl_camera_validation(&s->camera, width, width, 2.0, 0, 0);
    } else if (!strcmp(n, "chart")) {
        r = add_chart(s, 0, 0, 0, err);
        sl_camera_validation(&s->camera, width, image_height(width, CHART_H / CHART_W), CHART_W, 0,
                             0);
    } else if (!strcmp(n, "refs")) {
        /* grey | chrome | chart from image left (+X) to right (-X) */
        sl_material_lambert(&m, 0.18, 0.18, 0.18);
        if (!(r = add_sphere_mat(s, &m, 2.3, 0, 0, err))) {
            sl_material_chrome(&m);
            if (!(r = add_sphere_mat(s, &m, 0, 0, 0, err)))
                r = add_chart(s, -2.4, 0, 0, err);
        }
        sl_camera_validation(&s->camera, width, image_height(width, 2.4 / 7.2), 7.2, 0, 0);
    } else if (!strcmp(n, "shadow")) {
        sl_material_lambert(&m, 0.18, 0.18, 0.18);
        if (!(r = add_sphere_mat(s, &m, 0, 0, 0, err))) {
            int ground;
            if (!(r = sl_scene_add_material(s, &m, &ground, err))) {
                double c[3] = {0, -1, 0}, u[3] = {0, 0, 4}, v[3] = {4, 0, 0}; /* normal +Y */
                r = sl_scene_add_rect(s, c, u, v, ground, err);
            }
        }
        sl_camera_validation(&s->camera, width, image_height(width, 0.75), 5.0, 0, 25);
    } else if (!strcmp(n, "materials")) {
        /* Top row metal, bottom row plastic; roughness 0, 0.2 ... 1 from left. */
        double metal[3], tint[3] = {1, 1, 1}, albedo[3] = {0.5, 0.08, 0.05};
        sl_material_chrome(&m);
        memcpy(metal, m.base_color, sizeof metal);
        r = SL_OK;
        for (int i = 0; i < 6 && !r; i++) {
            double x = (2.5 - i) * 2.2;
            sl_material_conductor(&m, metal, tint, 0.2 * i);
            if (!(r = add_sphere_mat(s, &m, x, 1.1, 0, err))) {
                sl_material_plastic(&m, albedo, 1.5, 0.2 * i);
                r = add_sphere_mat(s, &m, x, -1.1, 0, err);
            }
        }
        sl_camera_validation(&s->camera, width, image_height(width, 4.4 / 13.2), 13.2, 0, 0);
    } else {
        return sl_error_set(err, SL_ERR_USAGE, "unknown scene preset '%s' (known: %s)", n,
                            sl_scene_preset_names());
    }
    if (!r)
        snprintf(s->name, sizeof s->name, "%s", n);
    return r;
}
