/* SPDX-License-Identifier: BSD-3-Clause */
/* A frame read a strip at a time, resampled on the fly onto the reference
 * frame's pixel grid when it was aligned (bilinear, edges clamped). Holds
 * only the source rows the current strip reaches. */
#ifndef SETLIGHT_STITCH_WARP_READER_H
#define SETLIGHT_STITCH_WARP_READER_H

#include "setlight/stitch.h"

typedef struct merge_frame_reader merge_frame_reader;

/* align: NULL or not applied reads the frame as it is. max_rows: the
 * tallest strip that will be asked for. */
sl_result merge_frame_open(const char *path, const sl_align_transform *align, int max_rows,
                           merge_frame_reader **reader, sl_error *err);
/* Rows [y0, y1) of the reference grid as RGB float, in increasing order. */
sl_result merge_frame_read(merge_frame_reader *reader, int y0, int y1, float *rgb, sl_error *err);
/* The same rows as the file's integer codes (uint8_t or uint16_t by the
 * strip info's code_bytes); only for a frame read as it is (no warp). */
sl_result merge_frame_read_codes(merge_frame_reader *reader, int y0, int y1, void *codes,
                                 sl_error *err);
void merge_frame_close(merge_frame_reader *reader);
/* Whether reference pixel (x, y) lands inside a frame of w x h moved by align. */
bool merge_frame_covers(const sl_align_transform *align, int w, int h, int x, int y);

#endif
