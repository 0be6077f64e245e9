/* SPDX-License-Identifier: BSD-3-Clause */
/* A Radiance RGBE (.hdr) file as the commands read an environment
 * (sl_image_read_linear: OpenImageIO's reader, then the working space). */
#include "fuzz.h"
#include "setlight/core.h"

int sl_fuzz_hdr(const uint8_t *data, size_t size)
{
    const char *path = sl_fuzz_file("input.hdr", data, size);
    if (!path)
        return 0;
    sl_image img = {0};
    sl_meta meta;
    sl_meta_init(&meta);
    sl_error err = {0};
    if (sl_image_read_linear(path, NULL, &img, &meta, NULL, &err) == SL_OK)
        sl_image_free(&img);
    sl_meta_free(&meta);
    return 0;
}
