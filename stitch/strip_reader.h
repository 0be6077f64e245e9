/* SPDX-License-Identifier: BSD-3-Clause */
/* Reads an image a strip of rows at a time through OpenImageIO, so a merge
 * holds one strip per frame instead of whole decoded frames. */
#ifndef SETLIGHT_STITCH_STRIP_READER_H
#define SETLIGHT_STITCH_STRIP_READER_H

#include "setlight/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct merge_strip_reader merge_strip_reader;

typedef struct merge_strip_info {
    int width, height;
    int file_channels;
    int bits;      /* bits per sample in the file */
    bool is_float; /* float or half samples */
} merge_strip_info;

/* Opens `path` (camera raw read linear, as sl_photo_read does). */
sl_result merge_strip_open(const char *path, merge_strip_reader **reader, merge_strip_info *info,
                           sl_error *err);
/* Rows [y0, y1) as RGB float (grey repeated, alpha dropped), width * 3
 * floats per row. Rows must be asked for in increasing order. */
sl_result merge_strip_read(merge_strip_reader *reader, int y0, int y1, float *rgb, sl_error *err);
void merge_strip_close(merge_strip_reader *reader);

#ifdef __cplusplus
}
#endif

#endif
