/* SPDX-License-Identifier: BSD-3-Clause */
/* Reading an image as scene-linear radiance in the working space, the same
 * way for every command: the file's colour space (named, or assumed from
 * its samples) converted through OpenColorIO, and a 2:1 image without an
 * envmap attribute taken as a lat-long. Each thing done to the pixels is
 * one note (sl_log_note), worded here once so every command says the same. */
#include "setlight/core.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

/* OpenImageIO's names that are not the config's. "Rec709" is what it calls
 * every Netpbm file: PPM/PGM codes are BT.709-encoded by the Netpbm spec,
 * PFM floats are linear. A PNG's gAMA is "GammaCorrected<g>" with g as
 * stored (1 / 0.45455 prints as 2.19998): the nearest power curve. */
static const char *oiio_space(const sl_meta *meta)
{
    if (strcmp(meta->colorspace, "Rec709") == 0)
        return sl_color_space_name(meta->is_float ? SL_WORKING_SPACE : "rec709_camera");
    double g;
    char tail;
    if (sscanf(meta->colorspace, "GammaCorrected%lf%c", &g, &tail) != 1)
        return NULL;
    if (fabs(g - 1.0) < 0.02)
        return sl_color_space_name(SL_WORKING_SPACE);
    if (fabs(g - 1.8) < 0.02)
        return sl_color_space_name("gamma18_rec709");
    if (fabs(g - 2.2) < 0.02)
        return sl_color_space_name("gamma22_rec709");
    return NULL;
}

const char *sl_file_color_space(const sl_meta *meta, bool *assumed)
{
    *assumed = false;
    const char *cs = sl_meta_color_space(meta);
    if (cs)
        return cs;
    if (meta->colorspace[0])
        return oiio_space(meta);
    if (meta->has_chromaticities)
        return NULL;
    *assumed = true;
    /* LibRaw is set up for linear output (core/photo_cxx.cpp). */
    if (!meta->is_float && strcmp(meta->format, "raw") != 0)
        return sl_color_space_name("srgb");
    return sl_color_space_name(SL_WORKING_SPACE);
}

bool sl_file_is_scene_linear(const sl_meta *meta)
{
    if (meta->is_float || !strcmp(meta->format, "raw"))
        return true;
    bool assumed;
    const char *cs = sl_file_color_space(meta, &assumed);
    const char *encoding = cs && !assumed ? sl_color_space_encoding(cs) : NULL;
    return encoding && !strcmp(encoding, "scene-linear");
}

/* "8-bit png", "half openexr", "float tiff". */
static void sample_text(const sl_meta *meta, char *buf, size_t size)
{
    const char *format = meta->format[0] ? meta->format : "image";
    if (meta->is_float)
        snprintf(buf, size, "%s %s", meta->bits_per_sample == 16 ? "half" : "float", format);
    else
        snprintf(buf, size, "%d-bit %s", meta->bits_per_sample, format);
}

static void apply_matrix(sl_image *img, const double m[3][3])
{
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            float *p = sl_image_pixel(img, x, y);
            double v[3] = {p[0], p[1], p[2]}, out[3];
            sl_mat3_apply(m, v, out);
            for (int c = 0; c < 3; c++)
                p[c] = (float)out[c];
        }
}

sl_result sl_image_linearize(sl_image *img, sl_meta *meta, const char *path, const char *from,
                             sl_read_info *info, sl_error *err)
{
    sl_read_info local;
    if (!info)
        info = &local;
    memset(info, 0, sizeof *info);
    bool assumed = false;
    const char *cs;
    if (from) {
        cs = sl_color_space_name(from);
        if (!cs)
            return sl_error_set(err, SL_ERR_USAGE, "unknown colour space '%s' (see docs/color.md)",
                                from);
    } else {
        cs = sl_file_color_space(meta, &assumed);
        if (!cs && (meta->colorspace[0] || !meta->has_chromaticities))
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: colour space '%s' is not in setlight's OCIO config (%s; "
                                "docs/color.md)",
                                path, meta->colorspace[0] ? meta->colorspace : "?",
                                sl_color_config_path());
    }
    const char *encoding = cs ? sl_color_space_encoding(cs) : "scene-linear";
    snprintf(info->colorspace, sizeof info->colorspace, "%s", cs ? cs : "chromaticities");
    info->colorspace_assumed = assumed;
    if ((cs && strcmp(cs, SL_WORKING_SPACE) == 0) || (encoding && !strcmp(encoding, "data")))
        return SL_OK;

    char samples[64], space[160];
    sample_text(meta, samples, sizeof samples);
    sl_result r = sl_image_ensure_rgb(img, path, err);
    if (r)
        return r;
    if (cs) {
        if ((r = sl_color_convert(img, cs, SL_WORKING_SPACE, err)))
            return r;
        snprintf(space, sizeof space, "%s%s", cs,
                 from ? " (given)" : assumed ? " (assumed: the file names no colour space)" : "");
    } else {
        /* Linear RGB of primaries no named space has (an EXR's chromaticities). */
        double m[3][3];
        const float *xy = meta->chromaticities;
        sl_chromaticities_to_rec709(xy, m);
        apply_matrix(img, m);
        snprintf(space, sizeof space,
                 "chromaticities r %.4g,%.4g g %.4g,%.4g b %.4g,%.4g white %.4g,%.4g", xy[0],
                 xy[1], xy[2], xy[3], xy[4], xy[5], xy[6], xy[7]);
    }
    info->converted = true;
    info->encoded = encoding && strcmp(encoding, "scene-linear") != 0;
    /* Not HDR when the samples are integers: a warning, not a note. */
    bool ldr = !meta->is_float && strcmp(meta->format, "raw") != 0;
    sl_log_note(ldr ? SL_LOG_WARN : SL_LOG_INFO,
                "%s: %s in %s, converted to scene-linear %s through %s%s", path, samples, space,
                SL_WORKING_SPACE, cs ? "OpenColorIO" : "a 3x3 matrix (Bradford)",
                ldr ? "; not HDR: clipped highlights make bright sources too dark" : "");
    return sl_meta_set_color_space(meta, SL_WORKING_SPACE, err);
}

typedef enum { READ_IMAGE, READ_ENV, READ_LATLONG } read_kind;

static sl_result read_as(const char *path, const char *from, read_kind kind, sl_image *img,
                         sl_meta *meta, sl_read_info *info, sl_error *err)
{
    sl_meta local;
    sl_meta *m = meta ? meta : &local;
    sl_read_info local_info;
    if (!info)
        info = &local_info;
    sl_result r = sl_image_read(path, img, m, err);
    if (!r)
        r = sl_image_linearize(img, m, path, from, info, err);
    /* Published HDRIs (.hdr, most EXRs) carry no envmap attribute. */
    if (!r && kind != READ_IMAGE && m->envmap == SL_ENVMAP_NONE &&
        sl_is_latlong_shape(img->width, img->height)) {
        m->envmap = SL_ENVMAP_LATLONG;
        info->latlong_assumed = true;
        sl_log_note(SL_LOG_INFO, "%s: no envmap attribute; %dx%d is 2:1, taken as a lat-long",
                    path, img->width, img->height);
    }
    if (!r && kind == READ_LATLONG && m->envmap == SL_ENVMAP_CUBE)
        r = sl_error_set(err, SL_ERR_INPUT,
                         "%s: a cube map (envmap attribute), not a lat-long: convert it first "
                         "(setlight convert --to latlong)",
                         path);
    else if (!r && kind == READ_LATLONG && !sl_is_latlong_shape(img->width, img->height))
        r = sl_error_set(err, SL_ERR_INPUT, "%s: not a lat-long: %dx%d is not 2:1%s", path,
                         img->width, img->height,
                         img->width == img->height
                             ? " (a mirror ball or angular map? setlight convert --from "
                               "mirrorball or angular makes a lat-long)"
                         : img->height == 6 * img->width
                             ? " (a cube map? setlight convert --from cubemap makes a lat-long)"
                             : "");
    if (r || !meta)
        sl_meta_free(m);
    if (r)
        sl_image_free(img);
    return r;
}

sl_result sl_image_read_linear(const char *path, const char *from, sl_image *img, sl_meta *meta,
                               sl_read_info *info, sl_error *err)
{
    return read_as(path, from, READ_IMAGE, img, meta, info, err);
}

sl_result sl_env_read(const char *path, const char *from, sl_image *img, sl_meta *meta,
                      sl_read_info *info, sl_error *err)
{
    return read_as(path, from, READ_ENV, img, meta, info, err);
}

sl_result sl_latlong_read(const char *path, const char *from, sl_image *img, sl_meta *meta,
                          sl_read_info *info, sl_error *err)
{
    return read_as(path, from, READ_LATLONG, img, meta, info, err);
}
