/* SPDX-License-Identifier: BSD-3-Clause */
/* lens-calibrate's private parts: the chessboard finder behind OpenCV. */
#ifndef SETLIGHT_LENS_CALIBRATE_PRIVATE_H
#define SETLIGHT_LENS_CALIBRATE_PRIVATE_H

#include <stddef.h>

/* The cols x rows inner corners of a chessboard in an 8-bit grey image, to a
 * tenth of a pixel, row by row, as x, y pairs in `corners` (pixel-centre
 * coordinates as OpenCV gives them). 1 found, 0 not found, -1 OpenCV
 * failed (msg says why). */
int lens_chessboard_cxx(const unsigned char *gray, int width, int height, int cols, int rows,
                        float *corners, char *msg, size_t msg_size);

#endif
