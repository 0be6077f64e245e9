/* SPDX-License-Identifier: BSD-3-Clause */
/* Private: OpenEXR pixels through OpenEXR's C++ library (in the module
 * that links OpenImageIO, which links it), for what the OpenEXR 3.1 C API
 * cannot decode (DWAA, DWAB) or decodes wrong (B44 with float channels,
 * subsampled channels), and luminance/chroma (Y, RY, BY) files back to RGB
 * through its RGBA interface. */
#ifndef SETLIGHT_CORE_EXR_OIIO_H
#define SETLIGHT_CORE_EXR_OIIO_H

#include "setlight/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Reads part 0's channels `names[0..count)` into img, which is already
 * allocated to the display window whose top-left is (x0, y0) and zeroed.
 * Data outside the display window is dropped, as sl_exr_read does. */
sl_result sl_exr_read_pixels_oiio(const char *path, const char *const *names, int count, int x0,
                                  int y0, sl_image *img, sl_error *err);

#ifdef __cplusplus
}
#endif

#endif
