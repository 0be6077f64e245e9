/* SPDX-License-Identifier: BSD-3-Clause */
/* TIFF read through libtiff, as OpenImageIO 2.4 reads it (photo_private.h
 * says what is the same and what is declined). OIIO decodes with the same
 * libtiff, so the samples are the same bytes; this reader keeps a band of
 * decoded rows (a strip, or a row of tiles) and hands out any rows. */
#include "photo_private.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <tiffio.h>

struct sl_tiff_reader {
    TIFF *tif;
    char *path;
    int width, height, channels, code_bytes, samples; /* samples: per pixel in the file */
    bool is_float, tiled;
    uint32_t band_rows, tile_w;    /* rows a strip or tile holds; a tile's width */
    int band_y0;                   /* first row of the decoded band, -1 none */
    unsigned char *band, *tile;    /* the band's samples; one tile */
    size_t band_bytes, tile_bytes;
    char why[240]; /* libtiff's first error */
};

/* The first error, as "module: text" (libtiff names a module, or the file,
 * which the message names already). */
static void note(sl_tiff_reader *r, const char *module, const char *fmt, va_list ap)
{
    if (!r || r->why[0])
        return;
    char text[200];
    vsnprintf(text, sizeof text, fmt, ap);
    if (module && r->path && strcmp(module, r->path) == 0)
        module = NULL;
    snprintf(r->why, sizeof r->why, "%s%s%s", module ? module : "", module ? ": " : "", text);
}

static int on_error(TIFF *tif, void *user, const char *module, const char *fmt, va_list ap)
{
    (void)tif;
    note(user, module, fmt, ap);
    return 1; /* handled: libtiff's global handler would print */
}

/* Warnings (unknown tags, odd but readable fields) are OIIO's to ignore
 * too, but for a tag's values past the end of the file: libtiff drops the
 * tag ("IO error ... tag ignored"), which for the ICC profile would make a
 * linear file read as sRGB. That one is an error. */
static int on_warning(TIFF *tif, void *user, const char *module, const char *fmt, va_list ap)
{
    (void)tif;
    va_list copy;
    va_copy(copy, ap);
    char text[200];
    vsnprintf(text, sizeof text, fmt, copy);
    va_end(copy);
    if (strstr(text, "IO error"))
        note(user, module, fmt, ap);
    return 1;
}

bool sl_tiff_is_tiff(const char *path)
{
    unsigned char sig[4];
    FILE *f = fopen(path, "rb");
    if (!f)
        return false;
    bool tiff = fread(sig, 1, sizeof sig, f) == sizeof sig &&
                ((sig[0] == 'I' && sig[1] == 'I' && (sig[2] == 42 || sig[2] == 43) && !sig[3]) ||
                 (sig[0] == 'M' && sig[1] == 'M' && !sig[2] && (sig[3] == 42 || sig[3] == 43)));
    fclose(f);
    return tiff;
}

void sl_tiff_reader_close(sl_tiff_reader *r)
{
    if (!r)
        return;
    if (r->tif)
        TIFFClose(r->tif);
    free(r->band);
    free(r->tile);
    free(r->path);
    free(r);
}

/* ---- tags ------------------------------------------------------------- */

/* A text tag, or NULL. Some tags are passed with their count, some without. */
static const char *tag_text(TIFF *tif, uint32_t tag)
{
    const TIFFField *f = TIFFFindField(tif, tag, TIFF_ANY);
    char *s = NULL;
    if (!f || TIFFFieldDataType(f) != TIFF_ASCII)
        return NULL;
    if (TIFFFieldPassCount(f)) {
        uint32_t n32 = 0;
        uint16_t n16 = 0;
        bool ok = TIFFFieldReadCount(f) == TIFF_VARIABLE2 ? TIFFGetField(tif, tag, &n32, &s)
                                                          : TIFFGetField(tif, tag, &n16, &s);
        return ok ? s : NULL;
    }
    return TIFFGetField(tif, tag, &s) ? s : NULL;
}

/* The first value of a numeric tag as OIIO's float attribute holds it. */
static bool tag_number(TIFF *tif, uint32_t tag, double *v)
{
    const TIFFField *f = TIFFFindField(tif, tag, TIFF_ANY);
    if (!f)
        return false;
    TIFFDataType type = TIFFFieldDataType(f);
    int size = TIFFFieldSetGetSize(f);
    const void *p = NULL;
    union {
        double d;
        float f;
        uint32_t u32;
        uint16_t u16;
        uint64_t pad[2];
    } one;
    memset(&one, 0, sizeof one);
    if (TIFFFieldPassCount(f)) {
        uint32_t n32 = 0;
        uint16_t n16 = 0;
        void *data = NULL;
        bool ok = TIFFFieldReadCount(f) == TIFF_VARIABLE2 ? TIFFGetField(tif, tag, &n32, &data)
                                                          : TIFFGetField(tif, tag, &n16, &data);
        if (!ok || !data || (n32 == 0 && n16 == 0))
            return false;
        p = data;
    } else {
        if (!TIFFGetField(tif, tag, &one))
            return false;
        p = &one;
    }
    switch (type) {
    case TIFF_SHORT:
        *v = *(const uint16_t *)p;
        return true;
    case TIFF_LONG:
        *v = (float)*(const uint32_t *)p;
        return true;
    case TIFF_RATIONAL:
    case TIFF_SRATIONAL:
    case TIFF_FLOAT:
    case TIFF_DOUBLE:
        *v = size == 8 ? (float)*(const double *)p : *(const float *)p;
        return true;
    default:
        return false;
    }
}

static void copy_text(char *dst, size_t size, const char *src)
{
    snprintf(dst, size, "%s", src ? src : "");
}

/* The EXIF directory's values, then back to the image's directory. An EXIF
 * directory libtiff cannot read leaves the values unset, as in OIIO.
 * *colorspace_tag: EXIF's ColorSpace (0 absent, -1 no EXIF). */
static bool read_exif(sl_tiff_reader *r, sl_meta *meta, int *colorspace_tag, bool *have_original)
{
    TIFF *tif = r->tif;
    uint64_t at = 0;
    *colorspace_tag = -1;
    *have_original = false;
    if (!TIFFGetField(tif, TIFFTAG_EXIFIFD, &at) || !at)
        return true;
    char why[sizeof r->why];
    memcpy(why, r->why, sizeof why);
    if (TIFFReadEXIFDirectory(tif, at)) {
        double v = 0;
        *colorspace_tag = tag_number(tif, EXIFTAG_COLORSPACE, &v) ? (int)v : 0;
        if (meta) {
            if (tag_number(tif, EXIFTAG_EXPOSURETIME, &v))
                meta->exposure_time = v;
            if (tag_number(tif, EXIFTAG_FNUMBER, &v))
                meta->f_number = v;
            if (tag_number(tif, EXIFTAG_ISOSPEEDRATINGS, &v))
                meta->iso = v;
            if (tag_number(tif, EXIFTAG_FOCALLENGTH, &v))
                meta->focal_length_mm = v;
            copy_text(meta->lens, sizeof meta->lens, tag_text(tif, EXIFTAG_LENSMODEL));
        }
        const char *original = tag_text(tif, EXIFTAG_DATETIMEORIGINAL);
        if (original && *original) {
            *have_original = true;
            if (meta)
                copy_text(meta->datetime, sizeof meta->datetime, original);
        }
    }
    memcpy(r->why, why, sizeof why); /* a bad EXIF directory is not the image's error */
    return TIFFSetDirectory(tif, 0) == 1;
}

/* The image directory's layout, or *declined for what OIIO reads differently
 * or libtiff alone does not turn into RGB / grey samples. */
static bool layout_fits(sl_tiff_reader *r)
{
    TIFF *tif = r->tif;
    uint32_t w = 0, h = 0;
    uint16_t bits = 1, spp = 1, format = SAMPLEFORMAT_UINT, photometric = 0, planar = 1,
             compression = COMPRESSION_NONE, fill = FILLORDER_MSB2LSB;
    if (!TIFFGetField(tif, TIFFTAG_IMAGEWIDTH, &w) || !TIFFGetField(tif, TIFFTAG_IMAGELENGTH, &h) ||
        !TIFFGetField(tif, TIFFTAG_PHOTOMETRIC, &photometric))
        return false;
    TIFFGetFieldDefaulted(tif, TIFFTAG_BITSPERSAMPLE, &bits);
    TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLESPERPIXEL, &spp);
    TIFFGetFieldDefaulted(tif, TIFFTAG_SAMPLEFORMAT, &format);
    TIFFGetFieldDefaulted(tif, TIFFTAG_PLANARCONFIG, &planar);
    TIFFGetFieldDefaulted(tif, TIFFTAG_COMPRESSION, &compression);
    TIFFGetFieldDefaulted(tif, TIFFTAG_FILLORDER, &fill);
    bool integer = format == SAMPLEFORMAT_UINT && (bits == 8 || bits == 16);
    bool real = format == SAMPLEFORMAT_IEEEFP && bits == 32;
    bool shape = (photometric == PHOTOMETRIC_MINISBLACK && spp <= 2) ||
                 (photometric == PHOTOMETRIC_RGB && spp >= 3 && spp <= 4);
    /* Compressions libtiff decodes to the stored samples; JPEG-in-TIFF
     * (OIIO sets its colour mode), old JPEG and the rest go to OIIO. */
    bool codec = compression == COMPRESSION_NONE || compression == COMPRESSION_LZW ||
                 compression == COMPRESSION_ADOBE_DEFLATE || compression == COMPRESSION_DEFLATE ||
                 compression == COMPRESSION_PACKBITS || compression == COMPRESSION_ZSTD ||
                 compression == COMPRESSION_LZMA;
    if (!(integer || real) || !shape || planar != PLANARCONFIG_CONTIG || !codec ||
        !TIFFIsCODECConfigured(compression) || fill != FILLORDER_MSB2LSB || w < 1 || h < 1 ||
        w > INT32_MAX / 8 || h > INT32_MAX)
        return false;
    r->width = (int)w;
    r->height = (int)h;
    r->samples = spp;
    r->channels = spp;
    r->code_bytes = bits / 8;
    r->is_float = real;
    r->tiled = TIFFIsTiled(tif);
    if (r->tiled) {
        uint32_t tw = 0, th = 0;
        if (!TIFFGetField(tif, TIFFTAG_TILEWIDTH, &tw) || !TIFFGetField(tif, TIFFTAG_TILELENGTH, &th) ||
            tw < 1 || th < 1)
            return false;
        r->tile_w = tw;
        r->band_rows = th;
    } else {
        uint32_t rows = h;
        TIFFGetFieldDefaulted(tif, TIFFTAG_ROWSPERSTRIP, &rows);
        r->band_rows = rows < 1 || rows > h ? h : rows;
    }
    return true;
}

/* sl_meta as photo_cxx.cpp's fill_meta makes it from OIIO's attributes:
 * the colour space "sRGB" when the file has EXIF not saying
 * "uncalibrated", the ICC profile's linear space over it. ISO is read from
 * EXIF, which OIIO 2.4 drops (its TIFF reader asks libtiff for one SHORT
 * where the tag has a count). */
static void fill_meta(sl_tiff_reader *r, sl_meta *meta, int colorspace_tag)
{
    TIFF *tif = r->tif;
    copy_text(meta->format, sizeof meta->format, "tiff");
    meta->is_float = r->is_float;
    meta->bits_per_sample = 8 * r->code_bytes;
    if (colorspace_tag >= 0 && colorspace_tag != 0xFFFF)
        copy_text(meta->colorspace, sizeof meta->colorspace, "sRGB");
    uint32_t icc_size = 0;
    const unsigned char *icc = NULL;
    if (TIFFGetField(tif, TIFFTAG_ICCPROFILE, &icc_size, &icc) && icc) {
        const char *linear = sl_icc_linear_space(icc, icc_size);
        if (linear)
            copy_text(meta->colorspace, sizeof meta->colorspace, linear);
    }
    copy_text(meta->make, sizeof meta->make, tag_text(tif, TIFFTAG_MAKE));
    copy_text(meta->model, sizeof meta->model, tag_text(tif, TIFFTAG_MODEL));
    if (!meta->datetime[0])
        copy_text(meta->datetime, sizeof meta->datetime, tag_text(tif, TIFFTAG_DATETIME));
    uint16_t orientation = 0;
    if (TIFFGetField(tif, TIFFTAG_ORIENTATION, &orientation))
        meta->orientation = orientation >= 1 && orientation <= 8 ? orientation : 0;
}

/* XMP that OIIO would let change what setlight reads. */
static bool xmp_matters(TIFF *tif, bool have_original)
{
    uint32_t n = 0;
    const unsigned char *xmp = NULL;
    return TIFFGetField(tif, TIFFTAG_XMLPACKET, &n, &xmp) && xmp &&
           sl_xmp_matters(xmp, n, have_original);
}

static sl_result read_header(sl_tiff_reader *r, sl_meta *meta, bool *declined, sl_error *err)
{
    TIFFOpenOptions *opts = TIFFOpenOptionsAlloc();
    if (!opts)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", r->path);
    TIFFOpenOptionsSetErrorHandlerExtR(opts, on_error, r);
    TIFFOpenOptionsSetWarningHandlerExtR(opts, on_warning, r);
    r->tif = TIFFOpenExt(r->path, "r", opts);
    TIFFOpenOptionsFree(opts);
    /* An error reading the directory (a tag's values past the end of a
     * file cut short: the ICC profile that says it is linear) refuses the
     * file, where libtiff would go on without the tag. */
    if (!r->tif || r->why[0])
        return sl_error_set(err, SL_ERR_INPUT, "%s: truncated or corrupt TIFF (%s)", r->path,
                            r->why[0] ? r->why : "no image directory");
    if (!layout_fits(r)) {
        *declined = true;
        return SL_OK;
    }
    sl_meta scratch;
    sl_meta *m = meta ? meta : &scratch;
    memset(&scratch, 0, sizeof scratch);
    int colorspace_tag;
    bool have_original;
    if (!read_exif(r, m, &colorspace_tag, &have_original))
        return sl_error_set(err, SL_ERR_INPUT, "%s: truncated or corrupt TIFF (%s)", r->path,
                            r->why[0] ? r->why : "image directory unreadable after EXIF");
    if (xmp_matters(r->tif, have_original)) {
        *declined = true;
        return SL_OK;
    }
    fill_meta(r, m, colorspace_tag);
    return SL_OK;
}

sl_result sl_tiff_reader_open(const char *path, sl_tiff_reader **reader, sl_meta *meta,
                              bool *declined, sl_error *err)
{
    *reader = NULL;
    *declined = false;
    sl_tiff_reader *r = calloc(1, sizeof *r);
    if (!r || !(r->path = strdup(path))) {
        free(r);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    }
    r->band_y0 = -1;
    sl_result res = read_header(r, meta, declined, err);
    if (res || *declined) {
        if (meta) {
            sl_meta_free(meta);
            sl_meta_init(meta);
        }
        sl_tiff_reader_close(r);
        return res;
    }
    *reader = r;
    return SL_OK;
}

void sl_tiff_reader_size(const sl_tiff_reader *r, int *width, int *height, int *channels,
                         int *code_bytes, bool *is_float)
{
    *width = r->width;
    *height = r->height;
    *channels = r->channels;
    *code_bytes = r->code_bytes;
    *is_float = r->is_float;
}

/* Decodes the band holding row y: a strip, or a row of tiles cut to the
 * image's width. false with r->why set. */
static bool decode_band(sl_tiff_reader *r, int y)
{
    uint32_t y0 = (uint32_t)y / r->band_rows * r->band_rows;
    size_t pixel = (size_t)r->samples * (size_t)r->code_bytes;
    size_t row_bytes = (size_t)r->width * pixel;
    size_t need = row_bytes * r->band_rows;
    if (need > r->band_bytes) {
        free(r->band);
        r->band_bytes = 0;
        if (!(r->band = malloc(need))) {
            snprintf(r->why, sizeof r->why, "out of memory");
            return false;
        }
        r->band_bytes = need;
    }
    r->band_y0 = -1;
    uint32_t rows = (uint32_t)r->height - y0 < r->band_rows ? (uint32_t)r->height - y0 : r->band_rows;
    if (!r->tiled) {
        tmsize_t want = (tmsize_t)(row_bytes * rows);
        tmsize_t got = TIFFReadEncodedStrip(r->tif, TIFFComputeStrip(r->tif, y0, 0), r->band, want);
        if (got != want) {
            if (!r->why[0])
                snprintf(r->why, sizeof r->why, "strip of %lld bytes, %lld expected",
                         (long long)got, (long long)want);
            return false;
        }
    } else {
        tmsize_t tile_size = TIFFTileSize(r->tif);
        if (tile_size <= 0 || (size_t)tile_size < (size_t)r->tile_w * r->band_rows * pixel) {
            snprintf(r->why, sizeof r->why, "tiles of an unexpected size");
            return false;
        }
        if ((size_t)tile_size > r->tile_bytes) {
            free(r->tile);
            r->tile_bytes = 0;
            if (!(r->tile = malloc((size_t)tile_size))) {
                snprintf(r->why, sizeof r->why, "out of memory");
                return false;
            }
            r->tile_bytes = (size_t)tile_size;
        }
        for (uint32_t x0 = 0; x0 < (uint32_t)r->width; x0 += r->tile_w) {
            ttile_t t = TIFFComputeTile(r->tif, x0, y0, 0, 0);
            if (TIFFReadEncodedTile(r->tif, t, r->tile, tile_size) != tile_size) {
                if (!r->why[0])
                    snprintf(r->why, sizeof r->why, "tile %u unreadable", (unsigned)t);
                return false;
            }
            uint32_t cols = (uint32_t)r->width - x0 < r->tile_w ? (uint32_t)r->width - x0 : r->tile_w;
            for (uint32_t k = 0; k < rows; k++)
                memcpy(r->band + k * row_bytes + x0 * pixel,
                       r->tile + (size_t)k * r->tile_w * pixel, cols * pixel);
        }
    }
    r->band_y0 = (int)y0;
    return true;
}

sl_result sl_tiff_reader_rows(sl_tiff_reader *r, int y0, int y1, int keep, void *codes,
                              sl_error *err)
{
    if (y0 < 0 || y1 > r->height || y0 > y1 || keep < 1 || keep > r->channels)
        return sl_error_set(err, SL_ERR_USAGE, "%s: rows %d-%d of %d asked for", r->path, y0,
                            y1 - 1, r->height);
    size_t b = (size_t)r->code_bytes, pixel = (size_t)r->samples * b;
    size_t row_bytes = (size_t)r->width * pixel;
    unsigned char *dst = codes;
    for (int y = y0; y < y1; y++) {
        if (r->band_y0 < 0 || y < r->band_y0 || y >= r->band_y0 + (int)r->band_rows) {
            r->why[0] = 0;
            if (!decode_band(r, y))
                return sl_error_set(err, SL_ERR_INPUT,
                                    "%s: truncated or corrupt image at rows %d-%d (%s)", r->path,
                                    y0, y1 - 1, r->why);
        }
        const unsigned char *src = r->band + (size_t)(y - r->band_y0) * row_bytes;
        if ((size_t)keep == (size_t)r->samples) {
            memcpy(dst, src, row_bytes);
            dst += row_bytes;
            continue;
        }
        for (int x = 0; x < r->width; x++, dst += (size_t)keep * b)
            memcpy(dst, src + (size_t)x * pixel, (size_t)keep * b);
    }
    return SL_OK;
}
