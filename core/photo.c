/* SPDX-License-Identifier: BSD-3-Clause */
/* core.h's photo calls: PNG through libpng (photo_png.c), everything else,
 * and the PNGs it declines, through OpenImageIO (photo_module.c). Writing
 * always goes through OpenImageIO. */
#include "photo_private.h"

#include <stdlib.h>
#include <string.h>

/* 1 / 255 and 1 / 65535 as multipliers: OIIO's conversion, to the bit. */
static void codes_to_float(const void *codes, int code_bytes, size_t n, float *dst)
{
    if (code_bytes == 1) {
        const unsigned char *c = codes;
        for (size_t i = 0; i < n; i++)
            dst[i] = (float)c[i] * (1.0f / 255.0f);
    } else {
        const uint16_t *c = codes;
        for (size_t i = 0; i < n; i++)
            dst[i] = (float)c[i] * (1.0f / 65535.0f);
    }
}

/* The PNG reader for path, or NULL with *declined or an error. A missing or
 * empty file is refused here: OpenImageIO would not be loaded to say so. */
static sl_result png_open(const char *path, sl_png_reader **r, sl_meta *meta, bool pixels,
                          bool *declined, sl_error *err)
{
    *r = NULL;
    *declined = false;
    sl_result res = sl_check_input_file(path, err);
    /* Before any decoder (or OpenImageIO) starts: what the header claims
     * (libpng allocates a text chunk's claimed length even to read EXIF). */
    if (!res)
        res = pixels ? sl_photo_claim_check(path, err) : sl_photo_structure_check(path, err);
    if (res)
        return res;
    *declined = !sl_png_is_png(path);
    if (*declined)
        return SL_OK;
    return sl_png_open(path, r, meta, declined, err);
}

sl_result sl_photo_read(const char *path, sl_image *img, sl_meta *meta, sl_error *err)
{
    sl_png_reader *r;
    bool declined;
    memset(img, 0, sizeof *img);
    if (meta)
        sl_meta_init(meta);
    sl_result res = png_open(path, &r, meta, true, &declined, err);
    if (declined)
        return sl_oiio_read(path, img, meta, err);
    int w = 0, h = 0, ch = 0, b = 0;
    if (!res)
        sl_png_size(r, &w, &h, &ch, &b);
    if (!res && (res = sl_image_alloc(img, w, h, ch, NULL)) != SL_OK)
        sl_error_set(err, res, "%s: cannot hold a %dx%d image with %d channels", path, w, h, ch);
    size_t n = (size_t)w * (size_t)ch;
    void *codes = res ? NULL : malloc(n * (size_t)b);
    if (!res && !codes)
        res = sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    for (int y = 0; !res && y < h; y++)
        if ((res = sl_png_read_rows(r, y, y + 1, ch, codes, err)) == SL_OK)
            codes_to_float(codes, b, n, img->data + (size_t)y * n);
    free(codes);
    sl_png_close(r);
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
    int size[3] = {0, 0, 0}, code_bytes;
    int *out[3] = {width, height, channels};
    for (int i = 0; i < 3; i++)
        if (out[i])
            *out[i] = 0;
    if (meta)
        sl_meta_init(meta);
    sl_png_reader *r;
    bool declined;
    sl_result res = png_open(path, &r, meta, false, &declined, err);
    if (declined)
        return sl_oiio_read_meta(path, meta, width, height, channels, err);
    if (!res)
        sl_png_size(r, &size[0], &size[1], &size[2], &code_bytes);
    sl_png_close(r);
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
    sl_png_reader *png;
    char *path;
    int width, keep, code_bytes; /* PNG: channels kept (3 of RGB(A), 1 of grey(+alpha)) */
    void *codes;                 /* PNG: a strip's codes */
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
    sl_result res = png_open(path, &s->png, NULL, true, &declined, err);
    if (declined)
        res = sl_oiio_strips_open(path, &s->oiio, info, err);
    else if (!res) {
        int h, ch;
        sl_png_size(s->png, &s->width, &h, &ch, &s->code_bytes);
        s->keep = ch >= 3 ? 3 : 1;
        info->width = s->width;
        info->height = h;
        info->file_channels = ch;
        info->bits = 8 * s->code_bytes;
        info->code_bytes = s->code_bytes;
    }
    if (res) {
        sl_photo_strips_close(s);
        return res;
    }
    *strips = s;
    return SL_OK;
}

/* PNG rows [y0, y1) as codes in s->codes, RGB (grey repeated). */
static sl_result png_strip(sl_photo_strips *s, int y0, int y1, sl_error *err)
{
    size_t n = (size_t)(y1 - y0) * (size_t)s->width, b = (size_t)s->code_bytes;
    if (n * 3 * b > s->codes_size) {
        void *grown = realloc(s->codes, n * 3 * b);
        if (!grown)
            return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", s->path);
        s->codes = grown;
        s->codes_size = n * 3 * b;
    }
    sl_result res = sl_png_read_rows(s->png, y0, y1, s->keep, s->codes, err);
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
    sl_result res = png_strip(s, y0, y1, err);
    if (!res)
        codes_to_float(s->codes, s->code_bytes, (size_t)(y1 - y0) * (size_t)s->width * 3, rgb);
    return res;
}

sl_result sl_photo_strips_read_codes(sl_photo_strips *s, int y0, int y1, void *rgb,
                                     sl_error *err)
{
    if (s->oiio)
        return sl_oiio_strips_read_codes(s->oiio, y0, y1, rgb, err);
    sl_result res = png_strip(s, y0, y1, err);
    if (!res)
        memcpy(rgb, s->codes, (size_t)(y1 - y0) * (size_t)s->width * 3 * (size_t)s->code_bytes);
    return res;
}

void sl_photo_strips_close(sl_photo_strips *s)
{
    if (!s)
        return;
    sl_oiio_strips_close(s->oiio);
    sl_png_close(s->png);
    free(s->codes);
    free(s->path);
    free(s);
}
