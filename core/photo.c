/* SPDX-License-Identifier: BSD-3-Clause */
/* core.h's photo calls: PNG through libpng (photo_png.c), JPEG through
 * libjpeg (photo_jpeg.c), TIFF through libtiff (photo_tiff.c), everything
 * else, and the files those decline, through OpenImageIO (photo_module.c).
 * Writing always goes through OpenImageIO. */
#include "photo_private.h"

#include <stdlib.h>
#include <string.h>

/* 1 / 255 and 1 / 65535 as multipliers: OIIO's conversion, to the bit;
 * float samples (4 bytes) as they are. */
static void codes_to_float(const void *codes, int code_bytes, size_t n, float *dst)
{
    if (code_bytes == 4) {
        memcpy(dst, codes, n * sizeof *dst);
    } else if (code_bytes == 1) {
        const unsigned char *c = codes;
        for (size_t i = 0; i < n; i++)
            dst[i] = (float)c[i] * (1.0f / 255.0f);
    } else {
        const uint16_t *c = codes;
        for (size_t i = 0; i < n; i++)
            dst[i] = (float)c[i] * (1.0f / 65535.0f);
    }
}

/* A file core decodes itself: one of the three readers. code_bytes 4:
 * float samples. */
typedef struct native {
    sl_png_reader *png;
    sl_jpeg_reader *jpeg;
    sl_tiff_reader *tiff;
    int width, height, channels, code_bytes, block_w, block_h;
    bool is_float;
} native;

static void native_close(native *n)
{
    sl_png_close(n->png);
    sl_jpeg_close(n->jpeg);
    sl_tiff_reader_close(n->tiff);
    n->png = NULL;
    n->jpeg = NULL;
    n->tiff = NULL;
}

/* The reader for path, or *declined (a format or file left to
 * OpenImageIO) or an error. A missing or empty file is refused here:
 * OpenImageIO would not be loaded to say so. */
static sl_result native_open(const char *path, native *n, sl_meta *meta, bool pixels,
                             bool *declined, sl_error *err)
{
    memset(n, 0, sizeof *n);
    *declined = false;
    sl_result res = sl_check_input_file(path, err);
    /* Before any decoder (or OpenImageIO) starts: what the header claims
     * (libpng allocates a text chunk's claimed length even to read EXIF). */
    if (!res)
        res = pixels ? sl_photo_claim_check(path, err) : sl_photo_structure_check(path, err);
    if (res)
        return res;
    if (sl_png_is_png(path)) {
        res = sl_png_open(path, &n->png, meta, declined, err);
        if (n->png)
            sl_png_size(n->png, &n->width, &n->height, &n->channels, &n->code_bytes);
    } else if (sl_jpeg_is_jpeg(path)) {
        res = sl_jpeg_open(path, &n->jpeg, meta, declined, err);
        n->code_bytes = 1;
        if (n->jpeg)
            sl_jpeg_size(n->jpeg, &n->width, &n->height, &n->channels, &n->block_w,
                         &n->block_h);
    } else if (sl_tiff_is_tiff(path)) {
        res = sl_tiff_reader_open(path, &n->tiff, meta, declined, err);
        if (n->tiff)
            sl_tiff_reader_size(n->tiff, &n->width, &n->height, &n->channels, &n->code_bytes,
                                &n->is_float);
    } else
        *declined = true;
    return res;
}

/* Rows [y0, y1) in order as the file's codes, channels [0, keep) kept. */
static sl_result native_rows(native *n, int y0, int y1, int keep, void *codes, sl_error *err)
{
    if (n->jpeg)
        return sl_jpeg_read_rows(n->jpeg, y0, y1, keep, codes, err);
    if (n->tiff)
        return sl_tiff_reader_rows(n->tiff, y0, y1, keep, codes, err);
    return sl_png_read_rows(n->png, y0, y1, keep, codes, err);
}

sl_result sl_photo_read(const char *path, sl_image *img, sl_meta *meta, sl_error *err)
{
    native r;
    bool declined;
    memset(img, 0, sizeof *img);
    if (meta)
        sl_meta_init(meta);
    sl_result res = native_open(path, &r, meta, true, &declined, err);
    if (declined)
        return sl_oiio_read(path, img, meta, err);
    int w = r.width, h = r.height, ch = r.channels, b = r.code_bytes;
    if (!res && (res = sl_image_alloc(img, w, h, ch, NULL)) != SL_OK)
        sl_error_set(err, res, "%s: cannot hold a %dx%d image with %d channels", path, w, h, ch);
    size_t n = (size_t)w * (size_t)ch;
    void *codes = res ? NULL : malloc(n * (size_t)b);
    if (!res && !codes)
        res = sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    for (int y = 0; !res && y < h; y++)
        if ((res = native_rows(&r, y, y + 1, ch, codes, err)) == SL_OK)
            codes_to_float(codes, b, n, img->data + (size_t)y * n);
    free(codes);
    native_close(&r);
    if (res) {
        sl_image_free(img);
        if (meta)
            sl_meta_free(meta);
    }
    return res;
}

sl_result sl_photo_read_meta(const char *path, sl_meta *meta, int *width, int *height,
                             int *channels, sl_error *err)
{
    int *out[3] = {width, height, channels};
    for (int i = 0; i < 3; i++)
        if (out[i])
            *out[i] = 0;
    if (meta)
        sl_meta_init(meta);
    native r;
    bool declined;
    sl_result res = native_open(path, &r, meta, false, &declined, err);
    if (declined)
        return sl_oiio_read_meta(path, meta, width, height, channels, err);
    int size[3] = {r.width, r.height, r.channels};
    native_close(&r);
    if (res && meta)
        sl_meta_free(meta);
    for (int i = 0; i < 3; i++)
        if (out[i])
            *out[i] = size[i];
    return res;
}

sl_result sl_photo_write(const char *path, const sl_image *img, const sl_meta *meta, int bits,
                         sl_error *err)
{
    return sl_oiio_write(path, img, meta, bits, err);
}

struct sl_photo_strips {
    sl_oiio_strips *oiio;
    native file;
    char *path;
    int width, keep, code_bytes; /* channels kept (3 of RGB(A), 1 of grey(+alpha)) */
    void *codes;                 /* a strip's codes */
    size_t codes_size;
};

sl_result sl_photo_strips_open(const char *path, sl_photo_strips **strips,
                               sl_photo_strip_info *info, sl_error *err)
{
    *strips = NULL;
    memset(info, 0, sizeof *info);
    sl_photo_strips *s = calloc(1, sizeof *s);
    if (!s)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    bool declined;
    s->path = strdup(path);
    if (!s->path) {
        free(s);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    }
    sl_result res = native_open(path, &s->file, NULL, true, &declined, err);
    if (declined)
        res = sl_oiio_strips_open(path, &s->oiio, info, err);
    else if (!res) {
        s->width = s->file.width;
        s->code_bytes = s->file.code_bytes;
        s->keep = s->file.channels >= 3 ? 3 : 1;
        info->width = s->width;
        info->height = s->file.height;
        info->file_channels = s->file.channels;
        info->bits = 8 * s->code_bytes;
        info->is_float = s->file.is_float;
        info->code_bytes = s->file.is_float ? 0 : s->code_bytes;
        info->block_w = s->file.block_w;
        info->block_h = s->file.block_h;
        info->lossless = !s->file.jpeg && !s->file.is_float; /* PNG, or TIFF of a lossless codec */
    }
    if (res) {
        sl_photo_strips_close(s);
        return res;
    }
    *strips = s;
    return SL_OK;
}

/* Rows [y0, y1) as codes in s->codes, RGB (grey repeated). */
static sl_result native_strip(sl_photo_strips *s, int y0, int y1, sl_error *err)
{
    size_t n = (size_t)(y1 - y0) * (size_t)s->width, b = (size_t)s->code_bytes;
    if (n * 3 * b > s->codes_size) {
        void *grown = realloc(s->codes, n * 3 * b);
        if (!grown)
            return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", s->path);
        s->codes = grown;
        s->codes_size = n * 3 * b;
    }
    sl_result res = native_rows(&s->file, y0, y1, s->keep, s->codes, err);
    unsigned char *c = s->codes;
    if (!res && s->keep == 1)
        for (size_t i = n; i-- > 0;)
            for (int k = 3; k-- > 0;)
                memmove(c + (3 * i + (size_t)k) * b, c + i * b, b);
    return res;
}

sl_result sl_photo_strips_read(sl_photo_strips *s, int y0, int y1, float *rgb, sl_error *err)
{
    if (s->oiio)
        return sl_oiio_strips_read(s->oiio, y0, y1, rgb, err);
    sl_result res = native_strip(s, y0, y1, err);
    if (!res)
        codes_to_float(s->codes, s->code_bytes, (size_t)(y1 - y0) * (size_t)s->width * 3, rgb);
    return res;
}

sl_result sl_photo_strips_read_codes(sl_photo_strips *s, int y0, int y1, void *rgb,
                                     sl_error *err)
{
    if (s->oiio)
        return sl_oiio_strips_read_codes(s->oiio, y0, y1, rgb, err);
    if (s->file.is_float)
        return sl_error_set(err, SL_ERR_USAGE, "%s: no integer codes (float samples)", s->path);
    sl_result res = native_strip(s, y0, y1, err);
    if (!res)
        memcpy(rgb, s->codes, (size_t)(y1 - y0) * (size_t)s->width * 3 * (size_t)s->code_bytes);
    return res;
}

void sl_photo_strips_close(sl_photo_strips *s)
{
    if (!s)
        return;
    sl_oiio_strips_close(s->oiio);
    native_close(&s->file);
    free(s->codes);
    free(s->path);
    free(s);
}
