/* SPDX-License-Identifier: BSD-3-Clause */
/* The rig as USD ASCII with UsdLux lights. Radiance = intensity x
 * 2^exposure x color with inputs:normalize = 0 (docs/lightrig.md). */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "lightrig_private.h"

/* color with luminance 1, intensity in [1, 2), exposure a whole number. */
static void split_radiance(const double rad[3], double color[3], double *intensity,
                           int *exposure)
{
    double y = sl_luminance(rad);
    if (!(y > 0)) {
        color[0] = color[1] = color[2] = 1;
        *intensity = 0;
        *exposure = 0;
        return;
    }
    for (int c = 0; c < 3; c++)
        color[c] = rad[c] / y;
    *exposure = (int)floor(log2(y));
    *intensity = y / ldexp(1.0, *exposure);
}

/* A rect at infinity is written as a RectLight this far away (metres),
 * sized to its angular extent: USD has no rect at infinity, and a set is
 * tens of metres across, so the parallax stays under about 0.1 degree. */
#define RIG_USD_FAR 1e4

static bool far_rect(const sl_rig_light *L)
{
    return !L->has_position && L->shape == SL_RIG_RECT;
}

static void put_matrix(FILE *f, const sl_rig_light *L)
{
    double p[3] = {0, 0, 0};
    for (int a = 0; a < 3; a++)
        p[a] = L->has_position ? L->position[a] : far_rect(L) ? RIG_USD_FAR * L->direction[a] : 0;
    fprintf(f,
            "        matrix4d xformOp:transform = ( (%.17g, %.17g, %.17g, 0), (%.17g, %.17g, "
            "%.17g, 0), (%.17g, %.17g, %.17g, 0), (%.17g, %.17g, %.17g, 1) )\n"
            "        uniform token[] xformOpOrder = [\"xformOp:transform\"]\n",
            L->axis_u[0], L->axis_u[1], L->axis_u[2], L->axis_v[0], L->axis_v[1], L->axis_v[2],
            L->direction[0], L->direction[1], L->direction[2], p[0], p[1], p[2]);
}

/* Escapes a path for an @asset@ reference (no @ allowed inside). */
static bool asset_ok(const char *s)
{
    return s && !strchr(s, '@') && !strchr(s, '\n');
}

static void write_light(FILE *f, const sl_rig_light *L, int index)
{
    const char *type = L->shape == SL_RIG_RECT     ? "RectLight"
                       : !L->has_position          ? "DistantLight"
                       : L->shape == SL_RIG_SPHERE ? "SphereLight"
                                                   : "DiskLight";
    double color[3], intensity, rad[3];
    int exposure;
    double tu = tan(0.5 * L->angular_size[0]), tv = tan(0.5 * L->angular_size[1]);
    /* far rect: the radiance that keeps the power over its exact solid angle */
    double k = far_rect(L) ? L->solid_angle / (4 * asin(tu * tv / sqrt((1 + tu * tu) *
                                                                         (1 + tv * tv))))
                           : 1;
    for (int c = 0; c < 3; c++)
        rad[c] = L->radiance[c] * k;
    split_radiance(rad, color, &intensity, &exposure);
    fprintf(f, "\n    def %s \"light_%02d\"\n    {\n", type, index);
    if (far_rect(L)) {
        fprintf(f, "        float inputs:width = %.9g\n        float inputs:height = %.9g\n",
                2 * RIG_USD_FAR * tu, 2 * RIG_USD_FAR * tv);
        if (L->texture[0] && asset_ok(L->texture))
            fprintf(f, "        asset inputs:texture:file = @%s@\n", L->texture);
    } else if (!L->has_position) {
        /* The disk of the same solid angle: same radiance, same power. */
        double r = acos(1 - L->solid_angle / (2 * M_PI));
        fprintf(f, "        float inputs:angle = %.9g\n", 2 * r * 180 / M_PI);
    } else if (L->shape == SL_RIG_RECT) {
        fprintf(f, "        float inputs:width = %.9g\n        float inputs:height = %.9g\n",
                L->size[0], L->size[1]);
        if (L->texture[0] && asset_ok(L->texture))
            fprintf(f, "        asset inputs:texture:file = @%s@\n", L->texture);
    } else {
        fprintf(f, "        float inputs:radius = %.9g\n", 0.5 * L->size[0]);
    }
    fprintf(f,
            "        float inputs:intensity = %.9g\n"
            "        float inputs:exposure = %d\n"
            "        color3f inputs:color = (%.9g, %.9g, %.9g)\n"
            "        bool inputs:normalize = 0\n",
            intensity, exposure, color[0], color[1], color[2]);
    put_matrix(f, L);
    fprintf(f,
            "        custom string setlight:shape = \"%s\"\n"
            "        custom double setlight:solidAngle = %.17g\n"
            "        custom double3 setlight:integral = (%.17g, %.17g, %.17g)\n"
            "        custom double2 setlight:angularSize = (%.17g, %.17g)\n"
            "        custom bool setlight:atInfinity = %d\n"
            "    }\n",
            sl_rig_shape_name(L->shape), L->solid_angle, L->integral[0], L->integral[1],
            L->integral[2], L->angular_size[0] * 180 / M_PI, L->angular_size[1] * 180 / M_PI,
            !L->has_position);
}

sl_result sl_rig_write_usda(const sl_rig *rig, const char *path, const char *dome_file,
                            sl_error *err)
{
    if (dome_file && !asset_ok(dome_file))
        return sl_error_set(err, SL_ERR_USAGE, "%s: dome file name '%s' cannot be a USD asset",
                            path, dome_file);
    char *buf = NULL;
    size_t size = 0;
    FILE *f = open_memstream(&buf, &size);
    if (!f)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    fprintf(f,
            "#usda 1.0\n"
            "(\n"
            "    defaultPrim = \"rig\"\n"
            "    metersPerUnit = 1\n"
            "    upAxis = \"Y\"\n"
            "    doc = \"setlight %s light rig: %d lights plus a residual dome; lights + dome = "
            "map within %.3g (relative)\"\n"
            ")\n\n"
            "def Xform \"rig\"\n{\n",
            sl_version(), rig->light_count, rig->relative_error);
    /* The lat-long is used as-is: USD's DomeLight follows OpenEXR's
     * orientation on a Y-up stage (docs/geometry.md), so no transform. */
    fprintf(f, "    def DomeLight \"dome\"\n    {\n");
    if (dome_file)
        fprintf(f, "        asset inputs:texture:file = @%s@\n", dome_file);
    fprintf(f,
            "        token inputs:texture:format = \"latlong\"\n"
            "        float inputs:intensity = 1\n"
            "        float inputs:exposure = 0\n"
            "        color3f inputs:color = (1, 1, 1)\n"
            "        custom double3 setlight:integral = (%.17g, %.17g, %.17g)\n"
            "    }\n",
            rig->dome[0], rig->dome[1], rig->dome[2]);
    for (int i = 0; i < rig->light_count; i++)
        write_light(f, &rig->lights[i], i + 1);
    fprintf(f, "}\n");
    if (fclose(f) != 0) {
        free(buf);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    }
    sl_result r = sl_write_file_atomic(path, buf, size, err);
    free(buf);
    return r;
}
