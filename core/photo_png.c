/* SPDX-License-Identifier: BSD-3-Clause */
/* PNG read through libpng, as OpenImageIO 2.4 reads it (photo_private.h
 * says what is the same and what is declined). libpng reports errors by
 * longjmp: everything that lives across a setjmp is in the reader. */
#include "photo_private.h"

#include <math.h>
#include <png.h>
#include <setjmp.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

struct sl_png_reader {
    FILE *file;
    png_structp png;
    png_infop info;
    char *path;
    int width, height, channels, code_bytes;
    int next_row;
    size_t row_bytes;
    unsigned char *row; /* one decoded row, when channels are dropped */
    char why[200];      /* libpng's last error */
};

static void on_error(png_structp png, png_const_charp message)
{
    sl_png_reader *r = png_get_error_ptr(png);
    snprintf(r->why, sizeof r->why, "%s", message ? message : "libpng error");
    png_longjmp(png, 1);
}

/* libpng would print its warnings (a bad ancillary chunk's CRC, a known
 * incorrect sRGB profile); the chunk is skipped, as in OpenImageIO. */
static void on_warning(png_structp png, png_const_charp message)
{
    sl_png_reader *r = png_get_error_ptr(png);
    sl_log(SL_LOG_DEBUG, "%s: libpng: %s", r->path, message ? message : "");
}

bool sl_png_is_png(const char *path)
{
    unsigned char sig[8];
    FILE *f = fopen(path, "rb");
    if (!f)
        return false;
    bool png = fread(sig, 1, sizeof sig, f) == sizeof sig && png_sig_cmp(sig, 0, sizeof sig) == 0;
    fclose(f);
    return png;
}

void sl_png_close(sl_png_reader *r)
{
    if (!r)
        return;
    if (r->png)
        png_destroy_read_struct(&r->png, r->info ? &r->info : NULL, NULL);
    if (r->file)
        fclose(r->file);
    free(r->row);
    free(r->path);
    free(r);
}

/* Metadata OpenImageIO turns into attributes this reader does not make. */
static bool declined_metadata(png_structp png, png_infop info)
{
    if (png_get_interlace_type(png, info) != PNG_INTERLACE_NONE)
        return true; /* OIIO decodes the whole image at once */
#ifdef PNG_eXIf_SUPPORTED
    if (png_get_valid(png, info, PNG_INFO_eXIf))
        return true;
#endif
    png_textp text;
    int n = 0;
    png_get_text(png, info, &text, &n);
    for (int i = 0; i < n; i++)
        if (strcasecmp(text[i].key, "XML:com.adobe.xmp") == 0 ||
            strncasecmp(text[i].key, "Raw profile type", 16) == 0)
            return true;
    return false;
}

/* The last text chunk named `key` (OIIO's attributes: later ones replace,
 * names match whatever their case), or NULL. */
static const char *text_value(png_textp text, int n, const char *key)
{
    const char *value = NULL;
    for (int i = 0; i < n; i++)
        if (strcasecmp(text[i].key, key) == 0)
            value = text[i].text;
    return value;
}

/* OIIO reads a number from a text attribute as a float. */
static double text_number(png_textp text, int n, const char *key)
{
    const char *s = text_value(text, n, key);
    return s ? (double)strtof(s, NULL) : 0.0;
}

static void copy_text(char *dst, size_t size, const char *src)
{
    snprintf(dst, size, "%s", src ? src : "");
}

static sl_result fill_meta(sl_png_reader *r, sl_meta *meta, sl_error *err)
{
    png_structp png = r->png;
    png_infop info = r->info;
    snprintf(meta->format, sizeof meta->format, "png");
    meta->is_float = false;
    meta->bits_per_sample = 8 * r->code_bytes;
    int intent;
    double gamma;
    if (png_get_sRGB(png, info, &intent))
        copy_text(meta->colorspace, sizeof meta->colorspace, "sRGB");
    else if (png_get_gAMA(png, info, &gamma) && gamma > 0) {
        /* As OIIO: the display gamma rounded to hundredths. */
        float g = roundf(100.0f * (float)(1.0 / gamma)) / 100.0f;
        if (g == 1.0f)
            copy_text(meta->colorspace, sizeof meta->colorspace, "linear");
        else
            snprintf(meta->colorspace, sizeof meta->colorspace, "Gamma%.2g", (double)g);
    } else
        copy_text(meta->colorspace, sizeof meta->colorspace, "sRGB");

    png_textp text;
    int n = 0;
    png_get_text(png, info, &text, &n);
    png_timep when;
    if (png_get_tIME(png, info, &when))
        snprintf(meta->datetime, sizeof meta->datetime, "%4d:%02d:%02d %02d:%02d:%02d",
                 when->year, when->month, when->day, when->hour, when->minute, when->second);
    meta->exposure_time = text_number(text, n, "ExposureTime");
    meta->f_number = text_number(text, n, "FNumber");
    meta->iso = text_number(text, n, "Exif:PhotographicSensitivity");
    if (meta->iso <= 0)
        meta->iso = text_number(text, n, "Exif:ISOSpeedRatings");
    meta->focal_length_mm = text_number(text, n, "Exif:FocalLength");
    copy_text(meta->make, sizeof meta->make, text_value(text, n, "Make"));
    copy_text(meta->model, sizeof meta->model, text_value(text, n, "Model"));
    const char *lens = text_value(text, n, "Exif:LensModel");
    copy_text(meta->lens, sizeof meta->lens, lens && *lens ? lens : text_value(text, n, "LensModel"));
    const char *date = text_value(text, n, "Exif:DateTimeOriginal");
    if (date && *date)
        copy_text(meta->datetime, sizeof meta->datetime, date);
    else if ((date = text_value(text, n, "DateTime")) != NULL)
        copy_text(meta->datetime, sizeof meta->datetime, date);
    const char *orientation = text_value(text, n, "Orientation");
    long o = orientation ? strtol(orientation, NULL, 10) : 0;
    meta->orientation = o >= 1 && o <= 8 ? (int)o : 0;
    /* setlight's own provenance, as text chunks. */
    for (int i = 0; i < n; i++)
        if (strncmp(text[i].key, "setlight:", 9) == 0 &&
            sl_meta_set(meta, text[i].key, text[i].text, NULL))
            return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory for metadata", r->path);
    return SL_OK;
}

/* The header: the transformations OIIO asks for, then the image's shape. */
static sl_result read_header(sl_png_reader *r, bool *declined, sl_error *err)
{
    if (setjmp(png_jmpbuf(r->png)))
        return sl_error_set(err, SL_ERR_INPUT, "%s: truncated or corrupt PNG (%s)", r->path,
                            r->why);
    png_init_io(r->png, r->file);
    png_read_info(r->png, r->info);
    if (declined_metadata(r->png, r->info)) {
        *declined = true;
        return SL_OK;
    }
    /* Palette to RGB, 1-, 2- and 4-bit grey to 8 bits, tRNS to alpha;
     * 16-bit samples in this machine's byte order. */
    png_set_expand(r->png);
#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
    png_set_swap(r->png);
#endif
    png_read_update_info(r->png, r->info);
    r->width = (int)png_get_image_width(r->png, r->info);
    r->height = (int)png_get_image_height(r->png, r->info);
    r->channels = png_get_channels(r->png, r->info);
    r->code_bytes = png_get_bit_depth(r->png, r->info) == 16 ? 2 : 1;
    r->row_bytes = png_get_rowbytes(r->png, r->info);
    if (r->width <= 0 || r->height <= 0 || r->channels < 1 || r->channels > 4 ||
        r->row_bytes != (size_t)r->width * (size_t)r->channels * (size_t)r->code_bytes)
        return sl_error_set(err, SL_ERR_INPUT, "%s: PNG of an unexpected shape (%dx%d, %d channels)",
                            r->path, r->width, r->height, r->channels);
    return SL_OK;
}

/* Every row of every pass and the chunks after them, decoded and dropped.
 * Called under check_decodes's setjmp. */
static void decode_all(sl_png_reader *r)
{
    int passes = png_set_interlace_handling(r->png);
    png_read_update_info(r->png, r->info);
    size_t bytes = png_get_rowbytes(r->png, r->info);
    r->row = malloc(bytes ? bytes : 1);
    if (!r->row)
        png_error(r->png, "out of memory for a row");
    for (int p = 0; p < passes; p++)
        for (int y = 0; y < r->height; y++)
            png_read_row(r->png, r->row, NULL);
    png_read_end(r->png, NULL);
}

/* A PNG that goes to OpenImageIO is decoded here first: OpenImageIO 2.4
 * leaves libpng's default handler, which prints "libpng error: ..." on
 * stderr before the error comes back, so a corrupt file must fail here,
 * with setlight's one line. */
static sl_result check_decodes(sl_png_reader *r, sl_error *err)
{
    r->height = (int)png_get_image_height(r->png, r->info);
    if (setjmp(png_jmpbuf(r->png)))
        return sl_error_set(err, SL_ERR_INPUT, "%s: truncated or corrupt PNG (%s)", r->path,
                            r->why);
    decode_all(r);
    return SL_OK;
}

sl_result sl_png_open(const char *path, sl_png_reader **reader, sl_meta *meta, bool *declined,
                      sl_error *err)
{
    *reader = NULL;
    *declined = false;
    sl_png_reader *r = calloc(1, sizeof *r);
    if (!r)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    r->path = strdup(path);
    r->file = r->path ? fopen(path, "rb") : NULL;
    if (!r->path) {
        sl_png_close(r);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    }
    if (!r->file) {
        sl_png_close(r);
        return sl_error_set(err, SL_ERR_IO, "%s: cannot open", path);
    }
    r->png = png_create_read_struct(PNG_LIBPNG_VER_STRING, r, on_error, on_warning);
    r->info = r->png ? png_create_info_struct(r->png) : NULL;
    if (!r->info) {
        sl_png_close(r);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    }
    sl_result res = read_header(r, declined, err);
    if (!res && *declined && (res = check_decodes(r, err)) != SL_OK)
        *declined = false;
    if (!res && !*declined && meta)
        res = fill_meta(r, meta, err);
    if (res || *declined) {
        sl_png_close(r);
        return res;
    }
    *reader = r;
    return SL_OK;
}

void sl_png_size(const sl_png_reader *r, int *width, int *height, int *channels,
                 int *code_bytes)
{
    *width = r->width;
    *height = r->height;
    *channels = r->channels;
    *code_bytes = r->code_bytes;
}

/* libpng's rows in order; rows before y0 are decoded and dropped. Called
 * under sl_png_read_rows's setjmp. */
static void decode_rows(sl_png_reader *r, int y0, int y1, int keep, unsigned char *dst)
{
    size_t pixel = (size_t)r->channels * (size_t)r->code_bytes;
    size_t kept = (size_t)keep * (size_t)r->code_bytes;
    for (; r->next_row < y1; r->next_row++) {
        bool wanted = r->next_row >= y0;
        if (wanted && keep == r->channels) {
            png_read_row(r->png, dst, NULL);
            dst += r->row_bytes;
            continue;
        }
        png_read_row(r->png, r->row, NULL);
        if (!wanted)
            continue;
        for (int x = 0; x < r->width; x++, dst += kept)
            memcpy(dst, r->row + (size_t)x * pixel, kept);
    }
}

sl_result sl_png_read_rows(sl_png_reader *r, int y0, int y1, int keep, void *codes,
                           sl_error *err)
{
    if (y0 < r->next_row || y1 > r->height || y0 > y1 || keep < 1 || keep > r->channels)
        return sl_error_set(err, SL_ERR_USAGE, "%s: rows %d-%d asked for after row %d", r->path,
                            y0, y1 - 1, r->next_row - 1);
    if (!r->row && !(r->row = malloc(r->row_bytes)))
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", r->path);
    if (setjmp(png_jmpbuf(r->png)))
        return sl_error_set(err, SL_ERR_INPUT, "%s: truncated or corrupt image at rows %d-%d (%s)",
                            r->path, y0, y1 - 1, r->why);
    decode_rows(r, y0, y1, keep, codes);
    return SL_OK;
}
