/* SPDX-License-Identifier: BSD-3-Clause */
/* Colour space <-> file metadata: the chromaticities an EXR carries and the
 * name setlight records, kept in step. */
#include "setlight/core.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

typedef struct space_xy {
    const char *name; /* canonical OCIO name in core/ocio/config.ocio */
    float xy[8];
} space_xy;

/* Rec.709 (ITU-R BT.709), ACES AP1 and AP0 (SMPTE ST 2065-1, ACES white
 * ~D60), CIE XYZ with D65 white. sRGB shares Rec.709's primaries. */
static const space_xy spaces[] = {
    {"lin_rec709", {0.64f, 0.33f, 0.30f, 0.60f, 0.15f, 0.06f, 0.3127f, 0.3290f}},
    {"srgb", {0.64f, 0.33f, 0.30f, 0.60f, 0.15f, 0.06f, 0.3127f, 0.3290f}},
    {"gamma22_rec709", {0.64f, 0.33f, 0.30f, 0.60f, 0.15f, 0.06f, 0.3127f, 0.3290f}},
    {"gamma18_rec709", {0.64f, 0.33f, 0.30f, 0.60f, 0.15f, 0.06f, 0.3127f, 0.3290f}},
    {"rec709_camera", {0.64f, 0.33f, 0.30f, 0.60f, 0.15f, 0.06f, 0.3127f, 0.3290f}},
    {"acescg", {0.713f, 0.293f, 0.165f, 0.830f, 0.128f, 0.044f, 0.32168f, 0.33767f}},
    {"acescct", {0.713f, 0.293f, 0.165f, 0.830f, 0.128f, 0.044f, 0.32168f, 0.33767f}},
    {"aces2065-1", {0.7347f, 0.2653f, 0.0f, 1.0f, 0.0001f, -0.077f, 0.32168f, 0.33767f}},
    {"cie_xyz_d65", {1.0f, 0.0f, 0.0f, 1.0f, 0.0f, 0.0f, 0.3127f, 0.3290f}},
};

bool sl_color_space_chromaticities(const char *name, float xy[8])
{
    const char *canonical = name ? sl_color_space_name(name) : NULL;
    if (!canonical)
        return false;
    for (size_t i = 0; i < sizeof spaces / sizeof spaces[0]; i++)
        if (strcmp(spaces[i].name, canonical) == 0) {
            memcpy(xy, spaces[i].xy, sizeof spaces[i].xy);
            return true;
        }
    return false;
}

const char *sl_meta_color_space(const sl_meta *meta)
{
    const char *named = sl_meta_get(meta, "setlight:colorspace");
    if (named && sl_color_space_name(named))
        return sl_color_space_name(named);
    if (meta->colorspace[0] && sl_color_space_name(meta->colorspace))
        return sl_color_space_name(meta->colorspace);
    if (meta->has_chromaticities)
        /* Linear spaces only: chromaticities do not say whether a curve was applied. */
        for (size_t i = 0; i < sizeof spaces / sizeof spaces[0]; i++) {
            const char *encoding = sl_color_space_encoding(spaces[i].name);
            if (!encoding || strcmp(encoding, "scene-linear") != 0)
                continue;
            bool same = true;
            for (int k = 0; k < 8; k++)
                same = same && fabsf(spaces[i].xy[k] - meta->chromaticities[k]) < 2e-3f;
            if (same)
                return spaces[i].name;
        }
    return NULL;
}

sl_result sl_meta_set_color_space(sl_meta *meta, const char *name, sl_error *err)
{
    const char *canonical = sl_color_space_name(name);
    if (!canonical)
        return sl_error_set(err, SL_ERR_USAGE, "unknown colour space '%s'", name);
    snprintf(meta->colorspace, sizeof meta->colorspace, "%s", canonical);
    meta->has_chromaticities = sl_color_space_chromaticities(canonical, meta->chromaticities);
    return sl_meta_set(meta, "setlight:colorspace", canonical, err);
}
