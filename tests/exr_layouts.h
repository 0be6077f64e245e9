/* SPDX-License-Identifier: BSD-3-Clause */
/* EXR files written and decoded by OpenEXR's C++ library
 * (exr_layouts_cxx.cpp), for test_exr_layouts. */
#ifndef SETLIGHT_TEST_EXR_LAYOUTS_H
#define SETLIGHT_TEST_EXR_LAYOUTS_H

#include <stdbool.h>
#include <stddef.h>

#ifdef __cplusplus
extern "C" {
#endif

typedef struct exr_layout_channel {
    const char *name;
    int type;     /* exr_pixel_type_t: 0 uint, 1 half, 2 float */
    int sampling; /* x and y sampling; 0 or 1: every pixel */
} exr_layout_channel;

typedef struct exr_layout {
    int width, height;         /* data window, from (data_x, data_y) */
    int data_x, data_y;
    int display_w, display_h; /* display window from (0, 0); 0: the data window */
    int compression;   /* exr_compression_t (the same numbers as Imf::Compression) */
    int tile;          /* tile side (one level), 0: scanlines */
    int nch;
    exr_layout_channel channels[8];
} exr_layout;

/* The value of channel c (index in exr_layout.channels) at pixel (x, y). */
typedef float (*exr_layout_value)(int c, int x, int y);

/* Writes l to path; false with the library's message in why. */
bool exr_layout_write(const char *path, const exr_layout *l, exr_layout_value value, char *why,
                      size_t why_size);

/* OpenEXR's own decoding of the full-resolution channel `name` over the
 * data window (width x height) into out. */
bool exr_layout_decode(const char *path, const char *name, float *out, int width, int height,
                       char *why, size_t why_size);

/* Writes width x height RGB(A) (channels 3 or 4, interleaved) the way
 * OpenEXR's RGBA interface does with WRITE_YC(A): luminance Y and 2 x 2
 * subsampled chroma RY, BY. */
bool exr_layout_write_yc(const char *path, const float *pixels, int width, int height,
                         int channels, char *why, size_t why_size);

/* OpenEXR's own RGBA decoding of any file into width x height x 4 floats. */
bool exr_layout_decode_rgba(const char *path, float *out, int width, int height, char *why,
                            size_t why_size);

#ifdef __cplusplus
}
#endif

#endif
