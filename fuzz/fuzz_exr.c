/* SPDX-License-Identifier: BSD-3-Clause */
/* An OpenEXR file as every command reads one (sl_exr_read, which
 * sl_image_read picks by the magic bytes): core's own decoder for scanline
 * ZIP/ZIPS/uncompressed half and float channels, the OpenEXRCore path for
 * the other compressions, tiles and layers, OIIO's for DWA. */
#include "fuzz.h"
#include "setlight/core.h"

int sl_fuzz_exr(const uint8_t *data, size_t size)
{
    const char *path = sl_fuzz_file("input.exr", data, size);
    if (!path)
        return 0;
    sl_image img = {0};
    sl_meta meta;
    sl_meta_init(&meta);
    sl_error err = {0};
    if (sl_exr_read(path, &img, &meta, &err) == SL_OK)
        sl_image_free(&img);
    sl_meta_free(&meta);
    return 0;
}
