/* SPDX-License-Identifier: BSD-3-Clause */
/* A Radiance RGBE (.hdr) file as the commands read an environment
 * (sl_image_read_linear: OpenImageIO's reader, then the working space). */
#include "fuzz.h"

static sl_result read_linear(const char *path, sl_image *img, sl_meta *meta, sl_error *err)
{
    return sl_image_read_linear(path, NULL, img, meta, NULL, err);
}

int sl_fuzz_hdr(const uint8_t *data, size_t size)
{
    sl_fuzz_image("input.hdr", data, size, read_linear);
    return 0;
}
