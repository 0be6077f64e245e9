/* SPDX-License-Identifier: BSD-3-Clause */
/* JPEG read through libjpeg, as OpenImageIO 2.4 reads it (photo_private.h
 * says what is the same and what is declined). OIIO decodes with the same
 * libjpeg and its defaults (islow DCT, fancy upsampling), so the codes are
 * the same bytes. libjpeg reports errors by longjmp: everything that lives
 * across a setjmp is in the reader. */
#include "photo_private.h"

#include <jpeglib.h>
#include <setjmp.h>
#include <stdlib.h>
#include <string.h>

/* libjpeg's error manager first, so its pointer is the reader's. */
typedef struct jpeg_failure {
    struct jpeg_error_mgr pub;
    jmp_buf jump;
    char why[JMSG_LENGTH_MAX];
} jpeg_failure;

/* What the EXIF block gave: OIIO keeps the first value of a tag. */
typedef struct exif_found {
    unsigned long ifds_seen[8];
    int ifd_count;
    bool have_exposure, have_fnumber, have_iso, have_focal, have_orientation;
    bool have_make, have_model, have_lens, have_datetime, have_original;
    double exposure, fnumber, iso, focal;
    long orientation;
    char make[64], model[64], lens[128], datetime[32], original[32];
} exif_found;

struct sl_jpeg_reader {
    jpeg_failure fail;
    struct jpeg_decompress_struct cinfo;
    bool created;
    FILE *file;
    char *path;
    int width, height, channels, block_w, block_h;
    int next_row;
    unsigned char *row; /* one decoded row, when channels are dropped */
    exif_found exif;
};

static void on_error(j_common_ptr cinfo)
{
    jpeg_failure *f = (jpeg_failure *)cinfo->err;
    f->pub.format_message(cinfo, f->why);
    longjmp(f->jump, 1);
}

/* libjpeg's default prints warnings on stderr and goes on. OIIO 2.4 makes
 * the first one an error (corrupt data, a file cut short: libjpeg would pad
 * it with grey), and so does this reader. Trace messages are dropped. */
static void on_message(j_common_ptr cinfo, int level)
{
    if (level < 0)
        on_error(cinfo);
}

static void no_output(j_common_ptr cinfo) { (void)cinfo; }

/* SOI alone, as OIIO tells a JPEG: a file with bytes between SOI and its
 * first marker is libjpeg's "extraneous bytes" error here rather than a
 * file OIIO opens (and whose Photoshop block it then overreads). */
bool sl_jpeg_is_jpeg(const char *path)
{
    unsigned char sig[2];
    FILE *f = fopen(path, "rb");
    if (!f)
        return false;
    bool jpeg = fread(sig, 1, sizeof sig, f) == sizeof sig && sig[0] == 0xFF && sig[1] == 0xD8;
    fclose(f);
    return jpeg;
}

void sl_jpeg_close(sl_jpeg_reader *r)
{
    if (!r)
        return;
    if (r->created)
        jpeg_destroy_decompress(&r->cinfo);
    if (r->file)
        fclose(r->file);
    free(r->row);
    free(r->path);
    free(r);
}

/* ---- EXIF, as OIIO's decode_exif names and converts it --------------- */

/* The EXIF tags setlight reads (OIIO's attribute names in comments). */
enum {
    TAG_MAKE = 0x010F,          /* Make */
    TAG_MODEL = 0x0110,         /* Model */
    TAG_ORIENTATION = 0x0112,   /* Orientation */
    TAG_DATETIME = 0x0132,      /* DateTime */
    TAG_EXPOSURE = 0x829A,      /* ExposureTime */
    TAG_FNUMBER = 0x829D,       /* FNumber */
    TAG_EXIF_IFD = 0x8769,
    TAG_ISO = 0x8827,           /* Exif:PhotographicSensitivity */
    TAG_ORIGINAL = 0x9003,      /* Exif:DateTimeOriginal */
    TAG_FOCAL = 0x920A,         /* Exif:FocalLength */
    TAG_INTEROP_IFD = 0xA005,
    TAG_LENS = 0xA434,          /* Exif:LensModel */
};


/* The first value of a numeric entry as OIIO's attribute gives it as a
 * float: rationals are num / den in double then float, as OIIO stores them. */
static bool exif_number(const sl_tiff *t, unsigned type, unsigned long count, size_t at,
                        double *v)
{
    unsigned u16;
    unsigned long u32, den;
    if (count < 1)
        return false;
    switch (type) {
    case 1: /* BYTE */
        *v = t->p[at];
        return true;
    case 6: /* SBYTE */
        *v = (signed char)t->p[at];
        return true;
    case 3: /* SHORT */
        if (!sl_tiff_u16(t, at, &u16))
            return false;
        *v = u16;
        return true;
    case 8: /* SSHORT */
        if (!sl_tiff_u16(t, at, &u16))
            return false;
        *v = (int16_t)u16;
        return true;
    case 4: /* LONG */
        if (!sl_tiff_u32(t, at, &u32))
            return false;
        *v = (float)u32;
        return true;
    case 9: /* SLONG */
        if (!sl_tiff_u32(t, at, &u32))
            return false;
        *v = (float)(int32_t)u32;
        return true;
    case 5: /* RATIONAL */
        if (!sl_tiff_u32(t, at, &u32) || !sl_tiff_u32(t, at + 4, &den))
            return false;
        *v = (float)((double)u32 / (double)den);
        return true;
    case 10: /* SRATIONAL */
        if (!sl_tiff_u32(t, at, &u32) || !sl_tiff_u32(t, at + 4, &den))
            return false;
        *v = (float)((double)(int32_t)u32 / (double)(int32_t)den);
        return true;
    case 11: { /* FLOAT */
        float f;
        uint32_t bits;
        if (!sl_tiff_u32(t, at, &u32))
            return false;
        bits = (uint32_t)u32;
        memcpy(&f, &bits, sizeof f);
        *v = f;
        return true;
    }
    default: /* DOUBLE and the rest: not seen for these tags */
        return false;
    }
}

/* An ASCII entry up to its first NUL (what OIIO's string attribute holds
 * once copied out). */
static bool exif_text(const sl_tiff *t, unsigned type, unsigned long count, size_t at, char *dst,
                      size_t size)
{
    if (type != 2)
        return false;
    size_t n = 0;
    for (unsigned long i = 0; i < count && n + 1 < size && t->p[at + i]; i++)
        dst[n++] = (char)t->p[at + i];
    dst[n] = 0;
    return true;
}

static void exif_ifd(const sl_tiff *t, unsigned long ifd, exif_found *x);

static void exif_entry(const sl_tiff *t, unsigned tag, unsigned type, unsigned long count,
                       size_t at, exif_found *x)
{
    double v;
    unsigned long sub;
    switch (tag) {
    case TAG_EXIF_IFD:
    case TAG_INTEROP_IFD:
        if (sl_tiff_u32(t, at, &sub))
            exif_ifd(t, sub, x);
        break;
#define NUMBER(flag, field)                                                                        \
    if (!x->flag && exif_number(t, type, count, at, &v)) {                                         \
        x->flag = true;                                                                            \
        x->field = v;                                                                              \
    }                                                                                              \
    break;
#define TEXT(flag, field)                                                                          \
    if (!x->flag)                                                                                  \
        x->flag = exif_text(t, type, count, at, x->field, sizeof x->field);                        \
    break;
    case TAG_EXPOSURE:
        NUMBER(have_exposure, exposure)
    case TAG_FNUMBER:
        NUMBER(have_fnumber, fnumber)
    case TAG_ISO:
        NUMBER(have_iso, iso)
    case TAG_FOCAL:
        NUMBER(have_focal, focal)
    case TAG_ORIENTATION:
        if (!x->have_orientation && exif_number(t, type, count, at, &v)) {
            x->have_orientation = true;
            x->orientation = (long)v;
        }
        break;
    case TAG_MAKE:
        TEXT(have_make, make)
    case TAG_MODEL:
        TEXT(have_model, model)
    case TAG_LENS:
        TEXT(have_lens, lens)
    case TAG_DATETIME:
        TEXT(have_datetime, datetime)
    case TAG_ORIGINAL:
        TEXT(have_original, original)
#undef NUMBER
#undef TEXT
    default:
        break;
    }
}

/* Every entry of an IFD in order, sub-IFDs where they are pointed to
 * (each once: a loop of offsets ends). */
static void exif_ifd(const sl_tiff *t, unsigned long ifd, exif_found *x)
{
    for (int i = 0; i < x->ifd_count; i++)
        if (x->ifds_seen[i] == ifd)
            return;
    if (x->ifd_count == (int)(sizeof x->ifds_seen / sizeof x->ifds_seen[0]))
        return;
    x->ifds_seen[x->ifd_count++] = ifd;
    unsigned n, tag, type;
    unsigned long count;
    size_t at;
    if (!sl_tiff_u16(t, ifd, &n))
        return;
    /* OIIO skips an entry that reaches the end of the block. */
    for (unsigned i = 0; i < n && ifd + 2 + 12 * (size_t)(i + 1) < t->n; i++)
        if (sl_tiff_entry(t, ifd, i, &tag, &type, &count, &at))
            exif_entry(t, tag, type, count, at, x);
}

static void decode_exif(const unsigned char *p, size_t n, exif_found *x)
{
    sl_tiff t;
    unsigned long ifd0;
    unsigned entries;
    /* OIIO reads nothing from a first IFD that overruns the block. */
    if (sl_tiff_open(p, n, &t, &ifd0) && sl_tiff_u16(&t, ifd0, &entries) &&
        ifd0 + 2 + 12 * (size_t)entries <= n)
        exif_ifd(&t, ifd0, x);
}

static void copy_text(char *dst, size_t size, const char *src)
{
    snprintf(dst, size, "%s", src ? src : "");
}

/* The EXIF blocks, in file order. */
static void read_exif(const struct jpeg_decompress_struct *cinfo, exif_found *x)
{
    memset(x, 0, sizeof *x);
    for (jpeg_saved_marker_ptr m = cinfo->marker_list; m; m = m->next)
        if (m->marker == JPEG_APP0 + 1 && m->data_length >= 6 && !memcmp(m->data, "Exif\0", 5))
            decode_exif(m->data + 6, m->data_length - 6, x);
}

/* sl_meta as photo_cxx.cpp's fill_meta makes it from OIIO's attributes. */
static void fill_meta(const exif_found *x, sl_meta *meta)
{
    copy_text(meta->format, sizeof meta->format, "jpeg");
    meta->is_float = false;
    meta->bits_per_sample = 8;
    copy_text(meta->colorspace, sizeof meta->colorspace, "sRGB");
    meta->exposure_time = x->have_exposure ? x->exposure : 0;
    meta->f_number = x->have_fnumber ? x->fnumber : 0;
    meta->iso = x->have_iso ? x->iso : 0;
    meta->focal_length_mm = x->have_focal ? x->focal : 0;
    copy_text(meta->make, sizeof meta->make, x->make);
    copy_text(meta->model, sizeof meta->model, x->model);
    copy_text(meta->lens, sizeof meta->lens, x->lens);
    copy_text(meta->datetime, sizeof meta->datetime, x->original[0] ? x->original : x->datetime);
    meta->orientation = x->orientation >= 1 && x->orientation <= 8 ? (int)x->orientation : 0;
}

/* ---- XMP: read natively only when it cannot change what setlight reads */

/* XMP names (element or attribute, any case) that OIIO's decode_xmp turns
 * into, or keeps as, an attribute photo_cxx.cpp's fill_meta reads. */
static const char *const xmp_setlight_names[] = {
    "tiff:Make", "tiff:Model", "tiff:Orientation", "exifEX:PhotographicSensitivity",
    "exif:PhotographicSensitivity", "exif:ISOSpeedRatings", "exif:FocalLength",
    "exif:LensModel", "exif:DateTimeOriginal", "ExposureTime", "FNumber", "Make", "Model",
    "LensModel", "Orientation", "oiio:ColorSpace",
};
/* The ones that only give OIIO's "DateTime", which fill_meta reads only
 * when Exif:DateTimeOriginal is empty. */
static const char *const xmp_date_names[] = {
    "tiff:DateTime", "xmp:CreateDate", "photoshop:DateCreated", "DateTime",
};

static bool name_in(const char *name, size_t n, const char *const *list, size_t count)
{
    for (size_t i = 0; i < count; i++)
        if (strlen(list[i]) == n && !strncasecmp(name, list[i], n))
            return true;
    return false;
}

static bool xml_name_char(unsigned char c)
{
    return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
           c == ':' || c == '_' || c == '-' || c == '.' || c >= 0x80;
}

/* photo_private.h: every name in the packet is looked at, inside
 * rdf:Description or not. */
bool sl_xmp_matters(const unsigned char *p, size_t n, bool have_original)
{
    for (size_t i = 0; i < n; i++) {
        /* a name follows '<' or '</' (an element), or blank space (an attribute) */
        bool element = p[i] == '<';
        if (!element && p[i] != ' ' && p[i] != '\t' && p[i] != '\n' && p[i] != '\r')
            continue;
        size_t b = i + 1;
        if (element && b < n && p[b] == '/')
            b++;
        size_t e = b;
        while (e < n && xml_name_char(p[e]))
            e++;
        if (e == b)
            continue;
        const char *name = (const char *)p + b;
        size_t len = e - b;
        if (len >= 9 && !strncasecmp(name, "setlight:", 9))
            return true;
        if (name_in(name, len, xmp_setlight_names,
                    sizeof xmp_setlight_names / sizeof xmp_setlight_names[0]))
            return true;
        if (!have_original &&
            name_in(name, len, xmp_date_names, sizeof xmp_date_names / sizeof xmp_date_names[0]))
            return true;
        i = e - 1;
    }
    return false;
}

/* Markers whose attributes this reader does not reproduce: an XMP packet
 * that would change what setlight reads (OIIO's decode_xmp replaces EXIF's
 * values: the XMP date of some cameras' files wins). */
static bool declined_metadata(const struct jpeg_decompress_struct *cinfo, const exif_found *x)
{
    static const char xmp[] = "http://ns.adobe.com/xap/1.0/";
    bool have_original = x->original[0] != 0;
    for (jpeg_saved_marker_ptr m = cinfo->marker_list; m; m = m->next)
        if (m->marker == JPEG_APP0 + 1 && m->data_length >= sizeof xmp &&
            !memcmp(m->data, xmp, sizeof xmp) &&
            sl_xmp_matters(m->data + sizeof xmp, m->data_length - sizeof xmp, have_original))
            return true;
    return false;
}

/* OIIO's jpeg:subsampling from the sampling factors, and photo_cxx.cpp's
 * MCU for it (8x8 when OIIO names none). */
static void mcu_size(const struct jpeg_decompress_struct *cinfo, int *w, int *h)
{
    *w = *h = 8;
    if (cinfo->num_components != 3)
        return;
    const jpeg_component_info *c = cinfo->comp_info;
    if (c[1].h_samp_factor != 1 || c[1].v_samp_factor != 1 || c[2].h_samp_factor != 1 ||
        c[2].v_samp_factor != 1)
        return;
    if (c[0].h_samp_factor == 2 && c[0].v_samp_factor == 2)
        *w = *h = 16; /* 4:2:0 */
    else if (c[0].h_samp_factor == 2 && c[0].v_samp_factor == 1)
        *w = 16; /* 4:2:2 */
    else if (c[0].h_samp_factor == 4 && c[0].v_samp_factor == 1)
        *w = 32; /* 4:1:1 */
}

/* OIIO 2.4 reads a Photoshop APP13 block's IPTC data for the size the
 * block states, not the marker's (a heap overflow, found by fuzz_photo):
 * a file going to OIIO whose IPTC block claims more than its marker holds
 * is refused here. Layout: "Photoshop 3.0\0", "8BIM", type 0x0404, 4
 * bytes, a 2-byte size, the data. */
static bool iptc_overruns(const struct jpeg_decompress_struct *cinfo, unsigned *claimed,
                          unsigned *holds)
{
    static const char photoshop[] = "Photoshop 3.0";
    for (jpeg_saved_marker_ptr m = cinfo->marker_list; m; m = m->next) {
        const unsigned char *d = m->data;
        unsigned n = m->data_length;
        if (m->marker != JPEG_APP0 + 13 || n < sizeof photoshop ||
            memcmp(d, photoshop, sizeof photoshop) != 0)
            continue;
        /* OIIO reads the header's 12 bytes without checking the length */
        if (n < sizeof photoshop + 12) {
            *claimed = sizeof photoshop + 12;
            *holds = n;
            return true;
        }
        d += sizeof photoshop;
        if (memcmp(d, "8BIM", 4) != 0 || ((d[4] << 8) | d[5]) != 0x0404)
            continue;
        unsigned size = (unsigned)((d[10] << 8) | d[11]);
        unsigned left = n - (unsigned)(sizeof photoshop + 12);
        if (size > left) {
            *claimed = size;
            *holds = left;
            return true;
        }
    }
    return false;
}

/* The header, then the decoder started (a progressive file is read whole
 * here, as in OIIO). */
static sl_result read_header(sl_jpeg_reader *r, bool *declined, sl_error *err)
{
    if (setjmp(r->fail.jump))
        return sl_error_set(err, SL_ERR_INPUT, "%s: truncated or corrupt JPEG (%s)", r->path,
                            r->fail.why);
    jpeg_create_decompress(&r->cinfo);
    r->created = true;
    jpeg_stdio_src(&r->cinfo, r->file);
    for (int m = 0; m < 16; m++)
        jpeg_save_markers(&r->cinfo, JPEG_APP0 + m, 0xFFFF);
    jpeg_save_markers(&r->cinfo, JPEG_COM, 0xFFFF);
    if (jpeg_read_header(&r->cinfo, FALSE) != JPEG_HEADER_OK)
        return sl_error_set(err, SL_ERR_INPUT, "%s: JPEG without an image (tables only)",
                            r->path);
    read_exif(&r->cinfo, &r->exif);
    /* CMYK is converted by OIIO's own arithmetic; other component counts
     * than grey and colour are left to it too. */
    if (r->cinfo.jpeg_color_space == JCS_CMYK || r->cinfo.jpeg_color_space == JCS_YCCK ||
        (r->cinfo.num_components != 1 && r->cinfo.num_components != 3) ||
        declined_metadata(&r->cinfo, &r->exif)) {
        unsigned claimed, holds;
        if (iptc_overruns(&r->cinfo, &claimed, &holds))
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: truncated or corrupt JPEG (its Photoshop IPTC block claims "
                                "%u bytes, its marker holds %u)",
                                r->path, claimed, holds);
        *declined = true;
        return SL_OK;
    }
    jpeg_start_decompress(&r->cinfo);
    r->width = (int)r->cinfo.output_width;
    r->height = (int)r->cinfo.output_height;
    r->channels = r->cinfo.output_components;
    if (r->width <= 0 || r->height <= 0 || (r->channels != 1 && r->channels != 3))
        return sl_error_set(err, SL_ERR_INPUT, "%s: JPEG of an unexpected shape (%dx%d, %d channels)",
                            r->path, r->width, r->height, r->channels);
    mcu_size(&r->cinfo, &r->block_w, &r->block_h);
    return SL_OK;
}

sl_result sl_jpeg_open(const char *path, sl_jpeg_reader **reader, sl_meta *meta, bool *declined,
                       sl_error *err)
{
    *reader = NULL;
    *declined = false;
    sl_jpeg_reader *r = calloc(1, sizeof *r);
    if (!r)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    r->path = strdup(path);
    r->file = r->path ? fopen(path, "rb") : NULL;
    if (!r->path) {
        sl_jpeg_close(r);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    }
    if (!r->file) {
        sl_jpeg_close(r);
        return sl_error_set(err, SL_ERR_IO, "%s: cannot open", path);
    }
    r->cinfo.err = jpeg_std_error(&r->fail.pub);
    r->fail.pub.error_exit = on_error;
    r->fail.pub.emit_message = on_message;
    r->fail.pub.output_message = no_output;
    sl_result res = read_header(r, declined, err);
    if (!res && !*declined && meta)
        fill_meta(&r->exif, meta);
    if (res || *declined) {
        sl_jpeg_close(r);
        return res;
    }
    *reader = r;
    return SL_OK;
}

void sl_jpeg_size(const sl_jpeg_reader *r, int *width, int *height, int *channels, int *block_w,
                  int *block_h)
{
    *width = r->width;
    *height = r->height;
    *channels = r->channels;
    *block_w = r->block_w;
    *block_h = r->block_h;
}

/* libjpeg's rows in order; rows before y0 are decoded and dropped. Called
 * under sl_jpeg_read_rows's setjmp. */
static void decode_rows(sl_jpeg_reader *r, int y0, int y1, int keep, unsigned char *dst)
{
    size_t row_bytes = (size_t)r->width * (size_t)r->channels;
    for (; r->next_row < y1; r->next_row++) {
        bool wanted = r->next_row >= y0;
        JSAMPROW row = wanted && keep == r->channels ? dst : r->row;
        if (jpeg_read_scanlines(&r->cinfo, &row, 1) != 1) {
            snprintf(r->fail.why, sizeof r->fail.why, "no row decoded");
            longjmp(r->fail.jump, 1);
        }
        if (!wanted)
            continue;
        if (row == dst) {
            dst += row_bytes;
            continue;
        }
        for (int x = 0; x < r->width; x++, dst += keep)
            memcpy(dst, r->row + (size_t)x * (size_t)r->channels, (size_t)keep);
    }
}

sl_result sl_jpeg_read_rows(sl_jpeg_reader *r, int y0, int y1, int keep, unsigned char *codes,
                            sl_error *err)
{
    if (y0 < r->next_row || y1 > r->height || y0 > y1 || keep < 1 || keep > r->channels)
        return sl_error_set(err, SL_ERR_USAGE, "%s: rows %d-%d asked for after row %d", r->path,
                            y0, y1 - 1, r->next_row - 1);
    if (!r->row && !(r->row = malloc((size_t)r->width * (size_t)r->channels)))
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", r->path);
    if (setjmp(r->fail.jump))
        return sl_error_set(err, SL_ERR_INPUT, "%s: truncated or corrupt image at rows %d-%d (%s)",
                            r->path, y0, y1 - 1, r->fail.why);
    decode_rows(r, y0, y1, keep, codes);
    return SL_OK;
}
