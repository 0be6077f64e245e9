/* SPDX-License-Identifier: BSD-3-Clause */
/* Private: the photo readers behind core.h's sl_photo_* calls
 * (core/photo.c chooses). PNG is read by libpng directly (photo_png.c),
 * JPEG by libjpeg (photo_jpeg.c):
 * loading OpenImageIO costs a process ~0.3 s of CPU binding the symbols of
 * its ~260 libraries, more than a small bracket's whole merge. Everything
 * else, and the files those two decline, goes to OpenImageIO
 * (photo_cxx.cpp, loaded on first use by photo_module.c). */
#ifndef SETLIGHT_CORE_PHOTO_PRIVATE_H
#define SETLIGHT_CORE_PHOTO_PRIVATE_H

#include "setlight/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* OpenImageIO's reader and writer: the semantics core.h gives sl_photo_*. */
typedef struct sl_oiio_strips sl_oiio_strips;
sl_result sl_oiio_read(const char *path, sl_image *img, sl_meta *meta, sl_error *err);
sl_result sl_oiio_read_meta(const char *path, sl_meta *meta, int *width, int *height,
                            int *channels, sl_error *err);
sl_result sl_oiio_write(const char *path, const sl_image *img, const sl_meta *meta, int bits,
                        sl_error *err);
sl_result sl_oiio_strips_open(const char *path, sl_oiio_strips **strips,
                              sl_photo_strip_info *info, sl_error *err);
sl_result sl_oiio_strips_read(sl_oiio_strips *strips, int y0, int y1, float *rgb, sl_error *err);
sl_result sl_oiio_strips_read_codes(sl_oiio_strips *strips, int y0, int y1, void *rgb,
                                    sl_error *err);
void sl_oiio_strips_close(sl_oiio_strips *strips);

/* PNG through libpng, giving what OpenImageIO 2.4 gives for the same file:
 * the same pixels (codes / 255 or / 65535, palette and low bit depths
 * expanded, transparency as alpha, alpha unassociated) and the same sl_meta
 * (colour space from sRGB / gAMA, text chunks as attributes, tIME as
 * DateTime). A PNG whose reading it does not reproduce (interlaced, or
 * with EXIF, XMP or raw-profile metadata) is declined: *declined set, err
 * untouched, for the caller to hand to OpenImageIO, once it has decoded
 * whole here (a corrupt one is refused here, with one message: OpenImageIO
 * lets libpng print its own). */
typedef struct sl_png_reader sl_png_reader;
/* Whether the file starts with PNG's signature (false when unreadable). */
bool sl_png_is_png(const char *path);
/* Opens and reads the header of a file sl_check_input_file passed; meta
 * may be NULL. */
sl_result sl_png_open(const char *path, sl_png_reader **reader, sl_meta *meta, bool *declined,
                      sl_error *err);
void sl_png_size(const sl_png_reader *reader, int *width, int *height, int *channels,
                 int *code_bytes);
/* Rows [y0, y1) after the rows read so far, as the file's codes (uint8 or
 * uint16, native order), channels [0, keep) of each pixel kept. */
sl_result sl_png_read_rows(sl_png_reader *reader, int y0, int y1, int keep, void *codes,
                           sl_error *err);
void sl_png_close(sl_png_reader *reader);

/* JPEG through libjpeg, giving what OpenImageIO 2.4 gives for the same
 * file: the same codes (the same libjpeg, its default DCT and upsampling),
 * grey as one channel, no rotation (the EXIF Orientation is reported), the
 * colour space "sRGB", EXIF's ExposureTime, FNumber, ISO, FocalLength,
 * Make, Model, LensModel, DateTime(Original) and Orientation converted as
 * OIIO converts them, and OIIO's MCU for the strips. Declined (*declined
 * set, err untouched, for OpenImageIO): CMYK and YCCK, component counts
 * other than 1 and 3, and files with XMP. A libjpeg warning (corrupt
 * data, a file cut short) is an error, as in OIIO; nothing is printed. */
typedef struct sl_jpeg_reader sl_jpeg_reader;
/* Whether the file starts with JPEG's SOI and a marker (false when unreadable). */
bool sl_jpeg_is_jpeg(const char *path);
sl_result sl_jpeg_open(const char *path, sl_jpeg_reader **reader, sl_meta *meta, bool *declined,
                       sl_error *err);
void sl_jpeg_size(const sl_jpeg_reader *reader, int *width, int *height, int *channels,
                  int *block_w, int *block_h);
/* Rows [y0, y1) after the rows read so far, as 8-bit codes, channels
 * [0, keep) of each pixel kept. */
sl_result sl_jpeg_read_rows(sl_jpeg_reader *reader, int y0, int y1, int keep,
                            unsigned char *codes, sl_error *err);
void sl_jpeg_close(sl_jpeg_reader *reader);

/* TIFF through libtiff, giving what OpenImageIO 2.4 gives for the same
 * file: the same samples (the same libtiff; 8- and 16-bit codes scaled by
 * OIIO's multipliers, 32-bit float as stored, alpha as stored), strips or
 * tiles, no rotation (Orientation is reported), and the same sl_meta:
 * Make, Model, DateTime, Orientation from the image directory; ExposureTime,
 * FNumber, FocalLength, LensModel, DateTimeOriginal from EXIF's; the colour
 * space "sRGB" when there is EXIF whose ColorSpace is not "uncalibrated",
 * or the linear space the ICC profile names (core/icc.c). One difference:
 * EXIF's ISO is read, where OIIO 2.4 drops it. Declined (*declined set,
 * err untouched, for OpenImageIO): palette, CMYK, YCbCr, Lab and
 * white-is-zero photometrics, planar-separate samples, bit depths other
 * than 8/16-bit unsigned and 32-bit float, fill order LSB-first,
 * compressions other than none, LZW, deflate, PackBits, ZSTD and LZMA
 * (JPEG-in-TIFF among them), and XMP that names an attribute setlight
 * reads. Any rows can be read, in any order. */
typedef struct sl_tiff_reader sl_tiff_reader;
/* Whether the file starts with a TIFF or BigTIFF header (false when unreadable). */
bool sl_tiff_is_tiff(const char *path);
sl_result sl_tiff_reader_open(const char *path, sl_tiff_reader **reader, sl_meta *meta,
                              bool *declined, sl_error *err);
void sl_tiff_reader_size(const sl_tiff_reader *reader, int *width, int *height, int *channels,
                         int *code_bytes, bool *is_float);
/* Rows [y0, y1) as the file's samples (uint8, uint16 or float, native
 * order), channels [0, keep) of each pixel kept. */
sl_result sl_tiff_reader_rows(sl_tiff_reader *reader, int y0, int y1, int keep, void *codes,
                              sl_error *err);
void sl_tiff_reader_close(sl_tiff_reader *reader);

/* Whether OIIO's reading of this XMP packet (without its namespace prefix)
 * could differ from the EXIF-only metadata: some element or attribute name
 * that reaches photo_cxx.cpp's fill_meta (the date names only when there is
 * no EXIF DateTimeOriginal). photo_jpeg.c and photo_tiff.c decline such
 * files. */
bool sl_xmp_matters(const unsigned char *p, size_t n, bool have_original);

/* SL_ERR_INPUT naming the file when a JPEG, PNG, TIFF or Radiance header
 * claims more pixels than a file of its size can hold, or an image over
 * the memory budget (photo_claim.c); SL_OK for other files, left to their
 * reader. Reads only the header, before any decoder is started. */
sl_result sl_photo_claim_check(const char *path, sl_error *err);
/* The same without the memory budget, for a read of the metadata only: a
 * header or chunk that claims more than the file holds is still corrupt. */
sl_result sl_photo_structure_check(const char *path, sl_error *err);

/* How many times this process has started OpenImageIO (0 or 1): a test
 * checks that reading what core reads itself never does. */
int sl_oiio_start_count(void);

#ifdef __cplusplus
}
#endif

#endif
