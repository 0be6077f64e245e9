/* SPDX-License-Identifier: BSD-3-Clause */
/* A camera or preview photo (JPEG, PNG, TIFF) as the commands read it:
 * the EXIF that merge and ingest read first (sl_photo_read_meta), the whole
 * image (sl_image_read: libpng for PNG, OpenImageIO for the others), and
 * the strips merge streams a bracket through. The file is named by its
 * magic bytes, as a camera names it. */
#include <stdlib.h>
#include <string.h>

#include "fuzz.h"
#include "setlight/core.h"

static const char *name_for(const uint8_t *data, size_t size)
{
    if (size >= 4 && !memcmp(data, "\x89PNG", 4))
        return "input.png";
    if (size >= 4 && (!memcmp(data, "II*", 4) || !memcmp(data, "MM\0*", 4)))
        return "input.tif";
    return "input.jpg";
}

static void read_strips(const char *path)
{
    sl_photo_strips *strips = NULL;
    sl_photo_strip_info info;
    sl_error err = {0};
    if (sl_photo_strips_open(path, &strips, &info, &err) != SL_OK)
        return;
    /* a few rows at a time, in order, as merge asks for them */
    enum { ROWS = 16 };
    float *rgb = malloc(sizeof *rgb * 3 * (size_t)info.width * ROWS);
    for (int y = 0; rgb && y < info.height; y += ROWS) {
        int y1 = y + ROWS < info.height ? y + ROWS : info.height;
        if (sl_photo_strips_read(strips, y, y1, rgb, &err) != SL_OK)
            break;
    }
    free(rgb);
    sl_photo_strips_close(strips);
}

int sl_fuzz_photo(const uint8_t *data, size_t size)
{
    const char *path = sl_fuzz_file(name_for(data, size), data, size);
    if (!path)
        return 0;
    sl_meta meta;
    sl_meta_init(&meta);
    sl_error err = {0};
    int w, h, c;
    sl_result r = sl_photo_read_meta(path, &meta, &w, &h, &c, &err);
    sl_meta_free(&meta);
    if (r != SL_OK)
        return 0;
    sl_image img = {0};
    sl_meta_init(&meta);
    r = sl_image_read(path, &img, &meta, &err);
    sl_image_free(&img);
    sl_meta_free(&meta);
    if (r == SL_OK)
        read_strips(path);
    return 0;
}
