/* SPDX-License-Identifier: BSD-3-Clause */
/* Format dispatch. Reading goes by content, never by name: a file that
 * starts with the OpenEXR magic number goes to sl_exr_read, anything else to
 * OpenImageIO, and meta->format says what the file really is (a PNG named
 * .exr reads as a PNG with format "png"). Writing goes by extension. */
#include "setlight/core.h"

#include <ctype.h>
#include <stdio.h>
#include <string.h>

static bool has_exr_magic(const char *path)
{
    unsigned char b[4] = {0};
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return false;
    size_t n = fread(b, 1, sizeof b, fp);
    fclose(fp);
    /* 20000630 little-endian, OpenEXR's magic number. */
    return n == 4 && b[0] == 0x76 && b[1] == 0x2f && b[2] == 0x31 && b[3] == 0x01;
}

sl_result sl_image_read(const char *path, sl_image *img, sl_meta *meta, sl_error *err)
{
    memset(img, 0, sizeof *img);
    if (meta)
        sl_meta_init(meta);
    sl_result r = sl_check_input_file(path, err);
    if (r)
        return r;
    if (has_exr_magic(path))
        return sl_exr_read(path, img, meta, err);
    return sl_photo_read(path, img, meta, err);
}

/* Lower-case extension without the dot, "" when none. */
static void extension(const char *path, char *ext, size_t size)
{
    const char *slash = strrchr(path, '/');
    const char *base = slash ? slash + 1 : path;
    const char *dot = strrchr(base, '.');
    size_t i = 0;
    if (dot && dot != base)
        for (const char *p = dot + 1; *p && i + 1 < size; p++)
            ext[i++] = (char)tolower((unsigned char)*p);
    ext[i] = 0;
}

sl_result sl_image_write(const char *path, const sl_image *img, const sl_meta *meta,
                         sl_pixel_type exr_type, sl_error *err)
{
    if (!path || !*path)
        return sl_error_set(err, SL_ERR_USAGE, "empty output path");
    char ext[8];
    extension(path, ext, sizeof ext);
    if (strcmp(ext, "exr") == 0)
        return sl_exr_write(path, img, meta, exr_type, err);
    /* Deepest integer depth each format holds; JPEG is 8-bit only. */
    if (strcmp(ext, "png") == 0 || strcmp(ext, "tif") == 0 || strcmp(ext, "tiff") == 0)
        return sl_photo_write(path, img, meta, 16, err);
    if (strcmp(ext, "jpg") == 0 || strcmp(ext, "jpeg") == 0)
        return sl_photo_write(path, img, meta, 8, err);
    return sl_error_set(err, SL_ERR_USAGE,
                        "%s: unknown image extension (use .exr, .png, .jpg, .jpeg, .tif, .tiff)",
                        path);
}
