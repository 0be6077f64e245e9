/* SPDX-License-Identifier: BSD-3-Clause */
/* An OpenEXR file as every command reads one (sl_exr_read, which
 * sl_image_read picks by the magic bytes): core's own decoder for scanline
 * ZIP/ZIPS/uncompressed half and float channels, the OpenEXRCore path for
 * the other compressions, tiles and layers, OIIO's for DWA. */
#include "fuzz.h"

int sl_fuzz_exr(const uint8_t *data, size_t size)
{
    sl_fuzz_image("input.exr", data, size, sl_exr_read);
    return 0;
}
