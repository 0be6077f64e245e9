/* SPDX-License-Identifier: BSD-3-Clause */
/* The few EXIF bits capture needs that OIIO's metadata does not carry:
 * SubSecTimeOriginal (frames shot less than a second apart), the body's
 * serial number and the lens for ingest, and a camera-style APP1 segment
 * for the virtual camera's JPEGs. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "camera_backend.h"
#include "capture_private.h"

/* ---- reading ------------------------------------------------------- */

/* ASCII digits of a SubSecTime tag as a fraction of a second. */
static double subsec_value(const sl_tiff *t, unsigned long ifd, unsigned tag)
{
    unsigned type;
    unsigned long count;
    size_t at;
    if (!sl_tiff_find(t, ifd, tag, &type, &count, &at) || type != 2)
        return -1;
    double v = 0, scale = 0.1;
    int digits = 0;
    for (unsigned long i = 0; i < count && i < 9; i++) {
        unsigned char c = t->p[at + i];
        if (c == 0 || c == ' ')
            break;
        if (c < '0' || c > '9')
            return -1;
        v += scale * (c - '0');
        scale *= 0.1;
        digits++;
    }
    return digits ? v : -1;
}

/* An ASCII tag's text, trailing spaces and NULs dropped; "" when absent. */
static void ascii_value(const sl_tiff *t, unsigned long ifd, unsigned tag, char *buf, size_t size)
{
    unsigned type;
    unsigned long count;
    size_t at;
    buf[0] = 0;
    if (!sl_tiff_find(t, ifd, tag, &type, &count, &at) || (type != 2 && type != 7))
        return;
    size_t n = 0;
    for (unsigned long i = 0; i < count && n + 1 < size; i++) {
        unsigned char c = t->p[at + i];
        if (c == 0)
            break;
        buf[n++] = c >= 32 && c < 127 ? (char)c : '?';
    }
    while (n > 0 && buf[n - 1] == ' ')
        n--;
    buf[n] = 0;
}

/* Body serial and lens from the maker note of a Canon (a bare IFD with
 * offsets from the TIFF header: 0x000C serial number, 0x0095 lens model)
 * or a Nikon ("Nikon\0", version, then a TIFF of its own: 0x001D serial). */
static void maker_note_ids(const sl_tiff *t, unsigned long exif, const char *make,
                           sl_exif_extra *x)
{
    unsigned type;
    unsigned long count;
    size_t note, at;
    if (!sl_tiff_find(t, exif, 0x927C, &type, &count, &note))
        return;
    if (!strncasecmp(make, "Canon", 5)) {
        unsigned long serial;
        if (!x->serial[0] && sl_tiff_find(t, note, 0x000C, &type, &count, &at) && type == 4 &&
            sl_tiff_u32(t, at, &serial) && serial)
            snprintf(x->serial, sizeof x->serial, "%lu", serial);
        if (!x->lens[0])
            ascii_value(t, note, 0x0095, x->lens, sizeof x->lens);
    } else if (!strncasecmp(make, "Nikon", 5) && count > 18 && note + 18 <= t->n &&
               !memcmp(t->p + note, "Nikon\0", 6)) {
        sl_tiff nt;
        unsigned long ifd;
        if (!x->serial[0] && sl_tiff_open(t->p + note + 10, t->n - note - 10, &nt, &ifd))
            ascii_value(&nt, ifd, 0x001D, x->serial, sizeof x->serial);
    }
}

static void tiff_extra(const unsigned char *p, size_t n, sl_exif_extra *x)
{
    sl_tiff t;
    unsigned long ifd0, exif;
    unsigned type;
    unsigned long count;
    size_t at;
    if (!sl_tiff_open(p, n, &t, &ifd0))
        return;
    ascii_value(&t, ifd0, 0xC62F, x->serial, sizeof x->serial); /* DNG CameraSerialNumber */
    if (!sl_tiff_find(&t, ifd0, 0x8769, &type, &count, &at) || !sl_tiff_u32(&t, at, &exif))
        return;
    x->subsec = subsec_value(&t, exif, 0x9291); /* SubSecTimeOriginal */
    if (x->subsec < 0)
        x->subsec = subsec_value(&t, exif, 0x9290); /* SubSecTime */
    char serial[64];
    ascii_value(&t, exif, 0xA431, serial, sizeof serial); /* BodySerialNumber */
    if (serial[0])
        snprintf(x->serial, sizeof x->serial, "%s", serial);
    ascii_value(&t, exif, 0xA434, x->lens, sizeof x->lens);               /* LensModel */
    ascii_value(&t, exif, 0xA435, x->lens_serial, sizeof x->lens_serial); /* LensSerialNumber */
    char make[64];
    ascii_value(&t, ifd0, 0x010F, make, sizeof make);
    maker_note_ids(&t, exif, make, x);
}

void sl_exif_extra_read(const unsigned char *data, size_t size, sl_exif_extra *x)
{
    memset(x, 0, sizeof *x);
    x->subsec = -1;
    if (size >= 4 && (!memcmp(data, "II*\0", 4) || !memcmp(data, "MM\0*", 4))) {
        tiff_extra(data, size, x);
        return;
    }
    if (size < 4 || data[0] != 0xFF || data[1] != 0xD8)
        return;
    size_t i = 2;
    while (i + 4 <= size && data[i] == 0xFF) {
        unsigned marker = data[i + 1];
        size_t len = (size_t)data[i + 2] << 8 | data[i + 3];
        if (marker == 0xDA || len < 2 || i + 2 + len > size)
            break; /* the EXIF segment comes before the scan */
        if (marker == 0xE1 && len >= 8 && !memcmp(data + i + 4, "Exif\0\0", 6)) {
            tiff_extra(data + i + 10, len - 8, x);
            return;
        }
        i += 2 + len;
    }
}

void sl_exif_extra_file(const char *path, sl_exif_extra *x)
{
    /* EXIF lives in the first 64 KiB of a JPEG (one APP1 segment) and, in
     * camera TIFFs and TIFF-based raws, near the start. */
    FILE *f = fopen(path, "rb");
    unsigned char *buf = f ? malloc(1 << 17) : NULL;
    size_t n = buf ? fread(buf, 1, 1 << 17, f) : 0;
    if (f)
        fclose(f);
    sl_exif_extra_read(buf ? buf : (const unsigned char *)"", n, x);
    free(buf);
}

/* ---- writing ------------------------------------------------------- */

typedef struct out {
    unsigned char *p;
    size_t n, cap;
    bool failed;
} out;

static void grow(out *o, size_t n)
{
    if (o->failed || o->n + n <= o->cap)
        return;
    size_t cap = (o->n + n) * 2;
    unsigned char *q = realloc(o->p, cap);
    if (!q) {
        o->failed = true;
        return;
    }
    o->p = q;
    o->cap = cap;
}

static void w8(out *o, const void *p, size_t n)
{
    grow(o, n);
    if (o->failed)
        return;
    memcpy(o->p + o->n, p, n);
    o->n += n;
}

static void w16(out *o, unsigned v)
{
    unsigned char b[2] = {(unsigned char)v, (unsigned char)(v >> 8)};
    w8(o, b, 2);
}

static void w32(out *o, unsigned long v)
{
    unsigned char b[4] = {(unsigned char)v, (unsigned char)(v >> 8), (unsigned char)(v >> 16),
                          (unsigned char)(v >> 24)};
    w8(o, b, 4);
}

typedef struct entry {
    unsigned tag, type;
    unsigned long count;
    unsigned char value[80]; /* little-endian bytes */
} entry;

static void ascii(entry *e, unsigned tag, const char *s)
{
    e->tag = tag;
    e->type = 2;
    size_t n = strlen(s);
    if (n > sizeof e->value - 1)
        n = sizeof e->value - 1;
    memcpy(e->value, s, n);
    e->value[n] = 0;
    e->count = (unsigned long)n + 1;
}

static void le32(unsigned char *b, unsigned long v)
{
    for (int i = 0; i < 4; i++)
        b[i] = (unsigned char)(v >> (8 * i));
}

static void rational(entry *e, unsigned tag, unsigned long num, unsigned long den)
{
    e->tag = tag;
    e->type = 5;
    e->count = 1;
    le32(e->value, num);
    le32(e->value + 4, den);
}

static void short1(entry *e, unsigned tag, unsigned v)
{
    e->tag = tag;
    e->type = 3;
    e->count = 1;
    e->value[0] = (unsigned char)v;
    e->value[1] = (unsigned char)(v >> 8);
}

static size_t entry_bytes(const entry *e)
{
    static const size_t size[] = {0, 1, 1, 2, 4, 8, 1, 1, 2, 4, 8, 4, 8};
    return (e->type < 13 ? size[e->type] : 1) * e->count;
}

/* Bytes of an IFD with its out-of-line values. */
static size_t ifd_bytes(const entry *e, int n)
{
    size_t total = 2 + 12 * (size_t)n + 4;
    for (int i = 0; i < n; i++) {
        size_t b = entry_bytes(&e[i]);
        if (b > 4)
            total += b + (b & 1);
    }
    return total;
}

static void long1(entry *e, unsigned tag, unsigned long v)
{
    e->tag = tag;
    e->type = 4;
    e->count = 1;
    le32(e->value, v);
}

/* One IFD at TIFF offset `at` with its out-of-line values after it; returns
 * the offset just past them. */
static size_t write_ifd(out *o, size_t at, const entry *e, int n)
{
    size_t data = at + 2 + 12 * (size_t)n + 4;
    w16(o, (unsigned)n);
    for (int i = 0; i < n; i++) {
        w16(o, e[i].tag);
        w16(o, e[i].type);
        w32(o, e[i].count);
        size_t b = entry_bytes(&e[i]);
        if (b <= 4) {
            unsigned char v[4] = {0};
            memcpy(v, e[i].value, b);
            w8(o, v, 4);
        } else {
            w32(o, (unsigned long)data);
            data += b + (b & 1);
        }
    }
    w32(o, 0); /* no next IFD */
    for (int i = 0; i < n; i++) {
        size_t b = entry_bytes(&e[i]);
        if (b > 4) {
            w8(o, e[i].value, b);
            if (b & 1)
                w8(o, "", 1);
        }
    }
    return data;
}

/* Exposure time as a camera writes it: 1/N below a second, tenths above. */
static void exposure_rational(double t, unsigned long *num, unsigned long *den)
{
    if (t < 1.0 && fabs(1.0 / t - round(1.0 / t)) < 0.02 * (1.0 / t)) {
        *num = 1;
        *den = (unsigned long)round(1.0 / t);
    } else if (t < 1.0) {
        *num = (unsigned long)round(t * 1e6);
        *den = 1000000;
    } else {
        *num = (unsigned long)round(t * 10);
        *den = 10;
    }
}

/* The Exif IFD (6 entries, in tag order): exposure time, f-number, ISO,
 * DateTimeOriginal, focal length, SubSecTimeOriginal. */
static int exif_entries(const sl_meta *meta, int subsec_ms, entry exif[6])
{
    int n = 0;
    memset(exif, 0, 6 * sizeof *exif);
    unsigned long num, den;
    exposure_rational(meta->exposure_time, &num, &den);
    rational(&exif[n++], 0x829A, num, den);
    rational(&exif[n++], 0x829D, (unsigned long)round(meta->f_number * 10), 10);
    short1(&exif[n++], 0x8827, (unsigned)lround(meta->iso));
    ascii(&exif[n++], 0x9003, meta->datetime);
    rational(&exif[n++], 0x920A, (unsigned long)round(meta->focal_length_mm * 10), 10);
    char ss[8];
    snprintf(ss, sizeof ss, "%03d", subsec_ms < 0 ? 0 : subsec_ms % 1000);
    ascii(&exif[n++], 0x9291, ss);
    return n;
}

sl_result sl_jpeg_set_exif(unsigned char **jpeg, size_t *size, const sl_meta *meta,
                           int subsec_ms, sl_error *err)
{
    unsigned char *src = *jpeg;
    size_t n = *size;
    if (n < 4 || src[0] != 0xFF || src[1] != 0xD8)
        return sl_error_set(err, SL_ERR_INTERNAL, "EXIF: not a JPEG stream");
    entry ifd0[5], exif[6];
    int n0 = 0, n1 = exif_entries(meta, subsec_ms, exif);
    memset(ifd0, 0, sizeof ifd0);
    ascii(&ifd0[n0++], 0x010F, meta->make);
    ascii(&ifd0[n0++], 0x0110, meta->model);
    short1(&ifd0[n0++], 0x0112, 1);
    ascii(&ifd0[n0++], 0x0132, meta->datetime);
    entry *link = &ifd0[n0++];
    link->tag = 0x8769;
    link->type = 4;
    link->count = 1;

    /* TIFF: header, IFD0 and its values, then the Exif IFD. */
    le32(link->value, (unsigned long)(8 + ifd_bytes(ifd0, n0)));
    out t = {0};
    w8(&t, "II*\0", 4);
    w32(&t, 8);
    size_t end = write_ifd(&t, 8, ifd0, n0);
    write_ifd(&t, end, exif, n1);
    if (t.failed || t.n + 8 > 65535) {
        free(t.p);
        return sl_error_set(err, SL_ERR_NOMEM, "EXIF: out of memory");
    }

    /* SOI, our APP1, then the stream without its own APP0/APP1 segments. */
    out j = {0};
    w8(&j, "\xFF\xD8\xFF\xE1", 4);
    size_t len = t.n + 8;
    unsigned char l[2] = {(unsigned char)(len >> 8), (unsigned char)len};
    w8(&j, l, 2);
    w8(&j, "Exif\0\0", 6);
    w8(&j, t.p, t.n);
    free(t.p);
    size_t i = 2;
    while (i + 4 <= n && src[i] == 0xFF) {
        unsigned marker = src[i + 1];
        size_t seg = (size_t)src[i + 2] << 8 | src[i + 3];
        if (marker == 0xDA || seg < 2 || i + 2 + seg > n)
            break;
        if (marker != 0xE0 && marker != 0xE1)
            w8(&j, src + i, 2 + seg);
        i += 2 + seg;
    }
    w8(&j, src + i, n - i);
    if (j.failed) {
        free(j.p);
        return sl_error_set(err, SL_ERR_NOMEM, "EXIF: out of memory");
    }
    free(src);
    *jpeg = j.p;
    *size = j.n;
    return SL_OK;
}

static void bytes4(entry *e, unsigned tag, const unsigned char v[4])
{
    e->tag = tag;
    e->type = 1;
    e->count = 4;
    memcpy(e->value, v, 4);
}

static void shorts(entry *e, unsigned tag, const unsigned *v, int n)
{
    e->tag = tag;
    e->type = 3;
    e->count = (unsigned long)n;
    for (int i = 0; i < n; i++) {
        e->value[2 * i] = (unsigned char)v[i];
        e->value[2 * i + 1] = (unsigned char)(v[i] >> 8);
    }
}

/* n (signed) rationals of v[i] / den. */
static void rationals(entry *e, unsigned tag, unsigned type, const long *v, int n, long den)
{
    e->tag = tag;
    e->type = type;
    e->count = (unsigned long)n;
    for (int i = 0; i < n; i++) {
        le32(e->value + 8 * i, (unsigned long)v[i]);
        le32(e->value + 8 * i + 4, (unsigned long)den);
    }
}

sl_result sl_dng_encode(const sl_image *linear, const sl_meta *meta, int subsec_ms,
                        unsigned char **data, size_t *size, sl_error *err)
{
    *data = NULL;
    *size = 0;
    if (linear->channels != 3)
        return sl_error_set(err, SL_ERR_INTERNAL, "DNG: needs RGB, not %d channels",
                            linear->channels);
    entry ifd0[24], exif[6];
    int n0 = 0, n1 = exif_entries(meta, subsec_ms, exif);
    memset(ifd0, 0, sizeof ifd0);
    unsigned long w = (unsigned long)linear->width, h = (unsigned long)linear->height;
    const unsigned bits[3] = {16, 16, 16};
    /* camera RGB is linear Rec.709: ColorMatrix1 is XYZ (D65) to Rec.709 */
    static const long xyz_to_rgb[9] = {32406, -15372, -4986, -9689, 18758, 415, 557, -2040, 10570};
    static const long neutral[3] = {1, 1, 1};
    long1(&ifd0[n0++], 0x00FE, 0); /* NewSubFileType: the main image */
    long1(&ifd0[n0++], 0x0100, w);
    long1(&ifd0[n0++], 0x0101, h);
    shorts(&ifd0[n0++], 0x0102, bits, 3);
    short1(&ifd0[n0++], 0x0103, 1);     /* uncompressed */
    short1(&ifd0[n0++], 0x0106, 34892); /* LinearRaw */
    ascii(&ifd0[n0++], 0x010F, meta->make);
    ascii(&ifd0[n0++], 0x0110, meta->model);
    entry *strip = &ifd0[n0];
    long1(&ifd0[n0++], 0x0111, 0); /* StripOffsets, filled below */
    short1(&ifd0[n0++], 0x0112, 1);
    short1(&ifd0[n0++], 0x0115, 3);
    long1(&ifd0[n0++], 0x0116, h);
    long1(&ifd0[n0++], 0x0117, w * h * 6);
    short1(&ifd0[n0++], 0x011C, 1); /* chunky */
    ascii(&ifd0[n0++], 0x0132, meta->datetime);
    entry *link = &ifd0[n0];
    long1(&ifd0[n0++], 0x8769, 0);                                     /* Exif IFD, filled below */
    bytes4(&ifd0[n0++], 0xC612, (const unsigned char[4]){1, 4, 0, 0}); /* DNGVersion */
    ascii(&ifd0[n0++], 0xC614, meta->model);                           /* UniqueCameraModel */
    long1(&ifd0[n0++], 0xC61D, 65535);                                 /* WhiteLevel */
    rationals(&ifd0[n0++], 0xC621, 10, xyz_to_rgb, 9, 10000);          /* ColorMatrix1 */
    rationals(&ifd0[n0++], 0xC628, 5, neutral, 3, 1);                  /* AsShotNeutral */
    /* WhiteLevel 65535 and BlackLevel 0 are the defaults for 16 bits;
     * CalibrationIlluminant1 must follow AsShotNeutral in tag order. */
    short1(&ifd0[n0++], 0xC65A, 21); /* D65 */
    size_t exif_at = 8 + ifd_bytes(ifd0, n0);
    size_t pixels_at = exif_at + ifd_bytes(exif, n1);
    le32(link->value, (unsigned long)exif_at);
    le32(strip->value, (unsigned long)pixels_at);
    out t = {0};
    w8(&t, "II*\0", 4);
    w32(&t, 8);
    write_ifd(&t, 8, ifd0, n0);
    write_ifd(&t, exif_at, exif, n1);
    size_t n = (size_t)w * h * 3;
    for (size_t i = 0; i < n && !t.failed; i++) {
        float v = linear->data[i];
        w16(&t, (unsigned)lround((v > 1 ? 1 : v > 0 ? v : 0) * 65535.0));
    }
    if (t.failed) {
        free(t.p);
        return sl_error_set(err, SL_ERR_NOMEM, "DNG: out of memory");
    }
    *data = t.p;
    *size = t.n;
    return SL_OK;
}
