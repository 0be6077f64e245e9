/* SPDX-License-Identifier: BSD-3-Clause */
/* JPEG read through libjpeg (core/photo_jpeg.c) against OpenImageIO on the
 * same files, synthetic ones and every JPEG in the shared data: the same
 * pixels to the bit, the same size and channels, the same metadata, the
 * same strips; declined files (CMYK, XMP) go to OpenImageIO; corrupt files
 * are refused naming the file, with nothing printed; and reading the
 * native ones never starts OpenImageIO. */
#include <ftw.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include <jpeglib.h> /* after stdio.h */

#include "../core/photo_private.h"
#include "test_photo_common.h"
#include "testing.h"

/* ---- synthetic JPEGs ------------------------------------------------- */

typedef struct variant {
    const char *name;
    int width, height, components; /* 1 grey, 3 colour, 4 CMYK */
    int h0, v0;                     /* luma sampling (chroma 1x1) */
    bool progressive, arithmetic, big_endian_exif;
    int xmp; /* 0 none, 1 XMP's DateTimeOriginal, 2 dates and names setlight
              * does not read, 3 CreateDate (OIIO's DateTime) */
    bool restart;
    int exif; /* 0 none, 1 full, 2 IFD0 only (DateTime, no original), 3 tags twice */
    int block_w, block_h; /* what OIIO's strips report */
} variant;

static const variant variants[] = {
    {"rgb444.jpg", 37, 21, 3, 1, 1, false, false, false, false, false, 1, 8, 8},
    {"rgb420.jpg", 45, 31, 3, 2, 2, false, false, true, false, false, 1, 16, 16},
    {"rgb422.jpg", 33, 17, 3, 2, 1, false, false, false, false, true, 2, 16, 8},
    {"rgb411.jpg", 70, 9, 3, 4, 1, false, false, false, false, false, 0, 32, 8},
    {"grey.jpg", 29, 19, 1, 1, 1, false, false, false, false, false, 1, 8, 8},
    {"progressive.jpg", 41, 23, 3, 2, 2, true, false, true, false, false, 1, 16, 16},
    {"arithmetic.jpg", 26, 14, 3, 2, 2, false, true, false, false, false, 0, 16, 16},
    {"xmp_other.jpg", 20, 12, 3, 2, 2, false, false, false, 2, false, 1, 16, 16},
    {"xmp_date.jpg", 20, 12, 3, 2, 2, false, false, true, 3, false, 1, 16, 16},
    {"exif_twice.jpg", 20, 12, 3, 1, 1, false, false, false, 0, false, 3, 8, 8},
    /* declined: OpenImageIO reads these */
    {"cmyk.jpg", 20, 12, 4, 1, 1, false, false, false, 0, false, 0, 8, 8},
    {"xmp.jpg", 20, 12, 3, 2, 2, false, false, false, 1, false, 1, 16, 16},
    {"xmp_date_no_original.jpg", 20, 12, 3, 2, 2, false, false, false, 3, false, 2, 16, 16},
};
#define VARIANTS (int)(sizeof variants / sizeof variants[0])
#define NATIVE 10

/* A little TIFF writer for the EXIF block: one IFD at a time. */
typedef struct tiff_out {
    unsigned char b[1024];
    size_t n;
    bool big;
} tiff_out;

static void put(tiff_out *t, size_t at, unsigned long v, int bytes)
{
    for (int i = 0; i < bytes; i++)
        t->b[at + (size_t)i] =
            (unsigned char)(v >> (8 * (t->big ? bytes - 1 - i : i)));
}

typedef struct entry {
    unsigned tag, type;
    unsigned long count;
    const void *value; /* ASCII text, or NULL for a number in num/den */
    unsigned long num, den;
} entry;

/* Writes the IFD at t->n (its values after it); returns its offset. The
 * entry with tag `link` gets `link_to` as its LONG value. */
static size_t write_ifd(tiff_out *t, const entry *e, int count)
{
    size_t at = t->n, data = at + 2 + 12 * (size_t)count + 4;
    put(t, at, (unsigned long)count, 2);
    for (int i = 0; i < count; i++) {
        size_t d = at + 2 + 12 * (size_t)i;
        put(t, d, e[i].tag, 2);
        put(t, d + 2, e[i].type, 2);
        put(t, d + 4, e[i].count, 4);
        if (e[i].type == 2) {
            size_t len = e[i].count;
            size_t where = len <= 4 ? d + 8 : data;
            memcpy(t->b + where, e[i].value, len);
            if (len > 4) {
                put(t, d + 8, (unsigned long)data, 4);
                data += len + (len & 1);
            }
        } else if (e[i].type == 5) {
            put(t, d + 8, (unsigned long)data, 4);
            put(t, data, e[i].num, 4);
            put(t, data + 4, e[i].den, 4);
            data += 8;
        } else if (e[i].type == 3) {
            put(t, d + 8, e[i].num, 2);
        } else {
            put(t, d + 8, e[i].num, 4);
        }
    }
    put(t, at + 2 + 12 * (size_t)count, 0, 4);
    t->n = data;
    return at;
}

#define TEXT(tag, s) {tag, 2, sizeof(s), s, 0, 0}

/* "Exif\0\0" and a TIFF: IFD0 (Make, Model, Orientation, DateTime, and the
 * Exif IFD's offset) and the Exif IFD (exposure, aperture, ISO, original
 * date, focal length, lens). */
static size_t make_exif(unsigned char *out, bool big, int mode)
{
    bool full = mode != 2;
    tiff_out t;
    memset(&t, 0, sizeof t);
    t.big = big;
    memcpy(t.b, big ? "MM\0*" : "II*\0", 4);
    put(&t, 4, 8, 4);
    t.n = 8;
    entry exif[] = {
        {0x829A, 5, 1, NULL, 1, 250},      /* ExposureTime */
        {0x829D, 5, 1, NULL, 28, 10},      /* FNumber */
        {0x8827, 3, 1, NULL, 400, 0},      /* ISO */
        TEXT(0x9003, "2024:02:03 04:05:06"), /* DateTimeOriginal */
        {0x920A, 5, 1, NULL, 85, 2},       /* FocalLength */
        TEXT(0xA434, "EF 85mm f/1.8 USM"), /* LensModel */
    };
    entry ifd0[] = {
        TEXT(0x010F, "Canon"),
        TEXT(0x0110, "Canon EOS 5D Mark IV"),
        {0x0112, 3, 1, NULL, 6, 0},
        TEXT(0x0132, "2024:02:03 09:09:09"),
        {0x8769, 4, 1, NULL, 0, 0},
    };
    /* mode 3: Make and ExposureTime in both IFDs (OIIO keeps the first),
     * a focal length of 7/0 */
    entry twice[] = {
        {0x829A, 5, 1, NULL, 1, 250},
        TEXT(0x010F, "BBB"),
        {0x920A, 5, 1, NULL, 7, 0},
    };
    entry first[] = {
        TEXT(0x010F, "AAA"),
        {0x829A, 5, 1, NULL, 1, 100},
        {0x8769, 4, 1, NULL, 0, 0},
    };
    if (mode == 3) {
        size_t at0 = write_ifd(&t, first, 3);
        size_t exif_at = write_ifd(&t, twice, 3);
        put(&t, at0 + 2 + 12 * 2 + 8, (unsigned long)exif_at, 4);
        memcpy(out, "Exif\0\0", 6);
        memcpy(out + 6, t.b, t.n);
        return 6 + t.n;
    }
    int n0 = full ? 5 : 4;
    /* IFD0 first; the Exif IFD after its values, then IFD0's link patched. */
    size_t at0 = write_ifd(&t, ifd0, n0);
    if (full) {
        size_t exif_at = write_ifd(&t, exif, (int)(sizeof exif / sizeof exif[0]));
        put(&t, at0 + 2 + 12 * 4 + 8, (unsigned long)exif_at, 4);
    }
    memcpy(out, "Exif\0\0", 6);
    memcpy(out + 6, t.b, t.n);
    return 6 + t.n;
}

static bool write_variant(const char *path, const variant *v)
{
    FILE *f = fopen(path, "wb");
    if (!f)
        return false;
    struct jpeg_compress_struct c;
    struct jpeg_error_mgr jerr;
    c.err = jpeg_std_error(&jerr);
    jpeg_create_compress(&c);
    jpeg_stdio_dest(&c, f);
    c.image_width = (JDIMENSION)v->width;
    c.image_height = (JDIMENSION)v->height;
    c.input_components = v->components;
    c.in_color_space = v->components == 1 ? JCS_GRAYSCALE : v->components == 3 ? JCS_RGB : JCS_CMYK;
    jpeg_set_defaults(&c);
    jpeg_set_quality(&c, 85, TRUE);
    c.comp_info[0].h_samp_factor = v->h0;
    c.comp_info[0].v_samp_factor = v->v0;
    if (v->progressive)
        jpeg_simple_progression(&c);
    c.arith_code = v->arithmetic;
    if (v->restart)
        c.restart_in_rows = 1;
    jpeg_start_compress(&c, TRUE);
    unsigned char app1[1100];
    if (v->exif)
        jpeg_write_marker(&c, JPEG_APP0 + 1, app1, (unsigned)make_exif(app1, v->big_endian_exif, v->exif));
    static const char *const xmps[] = {
        NULL,
        /* as the stack_ghost bracket's: XMP's original date wins */
        "<rdf:Description xmlns:exif='http://ns.adobe.com/exif/1.0/'><exif:DateTimeOriginal>"
        "2011:12:13 03:09:10</exif:DateTimeOriginal><exif:Make>Nikon</exif:Make>"
        "</rdf:Description>",
        /* as Apple Photos' and Canon's: nothing setlight reads */
        "<rdf:Description rdf:about='' xmlns:aux='http://ns.adobe.com/exif/1.0/aux/' "
        "aux:Lens='Canon EF-S 18-55mm f/3.5-5.6 IS' aux:SerialNumber='1823918851' "
        "xmp:ModifyDate='2015-08-21T09:11:58' xmp:Rating='3'/>",
        /* OIIO's DateTime, which setlight reads without an original date */
        "<rdf:Description rdf:about='' xmp:CreateDate='2017-10-31T22:39:43.629' "
        "photoshop:DateCreated='2017-10-31T22:39:43.629'/>",
    };
    if (v->xmp) {
        char xmp[1024];
        int n = snprintf(xmp, sizeof xmp,
                         "http://ns.adobe.com/xap/1.0/%c<x:xmpmeta xmlns:x='adobe:ns:meta/'>"
                         "<rdf:RDF xmlns:rdf='http://www.w3.org/1999/02/22-rdf-syntax-ns#'>%s"
                         "</rdf:RDF></x:xmpmeta>",
                         0, xmps[v->xmp]);
        jpeg_write_marker(&c, JPEG_APP0 + 1, (const JOCTET *)xmp, (unsigned)n);
    }
    size_t stride = (size_t)v->width * (size_t)v->components;
    unsigned char *row = malloc(stride);
    for (int y = 0; y < v->height; y++) {
        /* Smooth ramps and a few sharp edges: every code range, ringing. */
        for (size_t i = 0; i < stride; i++)
            row[i] = (unsigned char)((i * 255 / stride + (size_t)y * 9 + (i % 3) * 40 +
                                      ((i / 7 + (size_t)y / 5) % 2) * 90) & 0xFF);
        jpeg_write_scanlines(&c, &row, 1);
    }
    jpeg_finish_compress(&c);
    jpeg_destroy_compress(&c);
    free(row);
    return fclose(f) == 0;
}

/* ---- comparisons ------------------------------------------------------ */

/* Strips of `path` both ways: the same info, rows skipped, floats and codes.
 * `native`: read by libjpeg, whose rows go forward only (OIIO reopens). */
static void compare_strips(const char *path, bool native)
{
    sl_error err;
    sl_photo_strips *mine;
    sl_oiio_strips *ref;
    sl_photo_strip_info a, b;
    CHECK_OK(sl_photo_strips_open(path, &mine, &a, &err), &err);
    CHECK_OK(sl_oiio_strips_open(path, &ref, &b, &err), &err);
    if (mine && ref) {
        CHECK_MSG(memcmp(&a, &b, sizeof a) == 0,
                  "%s: strip info differs (%dx%d %d ch, block %dx%d vs %dx%d %d ch, block %dx%d)",
                  path, a.width, a.height, a.file_channels, a.block_w, a.block_h, b.width,
                  b.height, b.file_channels, b.block_w, b.block_h);
        int h = a.height < 20 ? a.height : 20;
        size_t n = (size_t)a.width * 3 * (size_t)h;
        float *fa = calloc(n, sizeof *fa), *fb = calloc(n, sizeof *fb);
        unsigned char *ca = calloc(n, 1), *cb = calloc(n, 1);
        int rows[][2] = {{1, 3}, {4, 5}, {5, h}};
        for (int r = 0; r < 3; r++) {
            int y0 = rows[r][0], y1 = rows[r][1];
            size_t m = (size_t)(y1 - y0) * (size_t)a.width * 3;
            if (r == 1) {
                CHECK_OK(sl_photo_strips_read_codes(mine, y0, y1, ca, &err), &err);
                CHECK_OK(sl_oiio_strips_read_codes(ref, y0, y1, cb, &err), &err);
                CHECK_MSG(memcmp(ca, cb, m) == 0, "%s: codes differ", path);
            } else {
                CHECK_OK(sl_photo_strips_read(mine, y0, y1, fa, &err), &err);
                CHECK_OK(sl_oiio_strips_read(ref, y0, y1, fb, &err), &err);
                CHECK_MSG(memcmp(fa, fb, m * sizeof *fa) == 0, "%s: rows %d-%d differ", path,
                          y0, y1 - 1);
            }
        }
        if (native)
            CHECK_RESULT(sl_photo_strips_read(mine, 0, 1, fa, &err), SL_ERR_USAGE, &err);
        free(fa);
        free(fb);
        free(ca);
        free(cb);
    }
    sl_photo_strips_close(mine);
    sl_oiio_strips_close(ref);
}

/* Whole reads and metadata reads of `path` both ways. */
static void compare_reads(const char *path, const sl_image *native, const sl_meta *native_meta)
{
    sl_error err;
    sl_image ref;
    sl_meta ref_meta, meta, oiio_meta;
    int w, h, c, ow, oh, oc;
    CHECK_OK(sl_oiio_read(path, &ref, &ref_meta, &err), &err);
    CHECK_MSG(photo_same_pixels(native, &ref), "%s: pixels differ from OpenImageIO's", path);
    CHECK_MSG(sl_test_same_meta(path, native_meta, &ref_meta), "%s: metadata differs", path);
    CHECK_OK(sl_photo_read_meta(path, &meta, &w, &h, &c, &err), &err);
    CHECK_OK(sl_oiio_read_meta(path, &oiio_meta, &ow, &oh, &oc, &err), &err);
    CHECK_MSG(w == ow && h == oh && c == oc, "%s: %dx%d %d ch, OIIO %dx%d %d ch", path, w, h, c,
              ow, oh, oc);
    CHECK_MSG(sl_test_same_meta(path, &meta, &oiio_meta), "%s: read_meta differs", path);
    sl_image_free(&ref);
    sl_meta_free(&ref_meta);
    sl_meta_free(&meta);
    sl_meta_free(&oiio_meta);
}

/* ---- tests ------------------------------------------------------------ */

static sl_image native[VARIANTS];
static sl_meta native_meta[VARIANTS];

static void test_jpeg_does_not_start_oiio(void)
{
    sl_error err;
    for (int i = 0; i < VARIANTS; i++)
        CHECK_MSG(write_variant(sl_test_path(variants[i].name), &variants[i]), "writing %s",
                  variants[i].name);
    for (int i = 0; i < NATIVE; i++)
        CHECK_OK(sl_photo_read(sl_test_path(variants[i].name), &native[i], &native_meta[i], &err),
                 &err);
    CHECK_MSG(sl_oiio_start_count() == 0, "reading JPEGs started OpenImageIO");

    /* Known answers: the EXIF as written, no rotation, grey as grey. */
    const sl_meta *m = &native_meta[0];
    CHECK(strcmp(m->make, "Canon") == 0 && strcmp(m->model, "Canon EOS 5D Mark IV") == 0);
    CHECK(m->exposure_time == (double)(float)(1.0 / 250) && m->f_number == (double)2.8f);
    CHECK(m->iso == 400 && m->focal_length_mm == 42.5 && m->orientation == 6);
    CHECK(strcmp(m->lens, "EF 85mm f/1.8 USM") == 0);
    CHECK(strcmp(m->datetime, "2024:02:03 04:05:06") == 0);
    CHECK(strcmp(m->colorspace, "sRGB") == 0 && strcmp(m->format, "jpeg") == 0);
    CHECK(native[0].width == 37 && native[0].height == 21 && native[0].channels == 3);
    CHECK(strcmp(native_meta[2].datetime, "2024:02:03 09:09:09") == 0); /* IFD0 only */
    CHECK(native_meta[3].exposure_time == 0 && native_meta[3].make[0] == 0);
    CHECK(native[4].channels == 1);
    CHECK(native_meta[1].orientation == 6 && native_meta[1].iso == 400); /* big-endian */
    /* XMP that changes nothing setlight reads: EXIF's original date stays. */
    CHECK(strcmp(native_meta[7].datetime, "2024:02:03 04:05:06") == 0);
    CHECK(strcmp(native_meta[8].datetime, "2024:02:03 04:05:06") == 0);
    /* A tag twice: the first value (IFD0's), as OIIO keeps it. */
    CHECK(strcmp(native_meta[9].make, "AAA") == 0 &&
          native_meta[9].exposure_time == (double)(float)(1.0 / 100));
}

static void test_jpeg_matches_oiio(void)
{
    for (int i = 0; i < NATIVE; i++)
        compare_reads(sl_test_path(variants[i].name), &native[i], &native_meta[i]);
    for (int i = 0; i < VARIANTS; i++)
        compare_strips(sl_test_path(variants[i].name), i < NATIVE);
    sl_error err;
    sl_photo_strips *s;
    sl_photo_strip_info info;
    for (int i = 0; i < NATIVE; i++) {
        CHECK_OK(sl_photo_strips_open(sl_test_path(variants[i].name), &s, &info, &err), &err);
        CHECK_MSG(info.block_w == variants[i].block_w && info.block_h == variants[i].block_h,
                  "%s: block %dx%d", variants[i].name, info.block_w, info.block_h);
        sl_photo_strips_close(s);
    }
}

static void test_declined_go_to_oiio(void)
{
    sl_error err;
    sl_image img;
    sl_meta meta;
    int before = sl_oiio_start_count();
    (void)before;
    CHECK_OK(sl_photo_read(sl_test_path("cmyk.jpg"), &img, &meta, &err), &err);
    CHECK(img.width == 20 && img.height == 12 && img.channels == 3);
    sl_image_free(&img);
    sl_meta_free(&meta);
    for (int i = NATIVE; i < VARIANTS; i++) {
        sl_jpeg_reader *r = NULL;
        bool declined = false;
        CHECK_OK(sl_jpeg_open(sl_test_path(variants[i].name), &r, NULL, &declined, &err), &err);
        CHECK_MSG(declined && !r, "%s not declined", variants[i].name);
        sl_jpeg_close(r);
    }
    /* XMP's date wins over EXIF's in OpenImageIO. */
    CHECK_OK(sl_photo_read_meta(sl_test_path("xmp.jpg"), &meta, NULL, NULL, NULL, &err), &err);
    CHECK_MSG(strcmp(meta.datetime, "2011:12:13 03:09:10") == 0, "XMP date '%s'", meta.datetime);
    sl_meta_free(&meta);
}

/* Every JPEG in the shared data that libjpeg reads, both ways. */
static int real_count, real_native;

static int visit(const char *path, const struct stat *st, int kind, struct FTW *ftw)
{
    (void)st;
    (void)ftw;
    const char *dot = strrchr(path, '.');
    if (kind != FTW_F || !dot || (strcasecmp(dot, ".jpg") && strcasecmp(dot, ".jpeg")))
        return 0;
    sl_error err;
    sl_image img;
    sl_meta meta;
    real_count++;
    sl_jpeg_reader *r = NULL;
    bool declined = false;
    bool native = sl_jpeg_open(path, &r, NULL, &declined, &err) == SL_OK && r;
    real_native += native;
    sl_jpeg_close(r);
    if (!native)
        return 0; /* OpenImageIO both ways */
    CHECK_OK(sl_photo_read(path, &img, &meta, &err), &err);
    compare_reads(path, &img, &meta);
    compare_strips(path, native);
    sl_image_free(&img);
    sl_meta_free(&meta);
    return 0;
}

static void test_real_jpegs_match_oiio(void)
{
    const char *data = sl_test_data("");
    if (!data)
        return;
    CHECK(nftw(data, visit, 16, FTW_PHYS) == 0);
    printf("  %d JPEGs in the shared data, %d read by libjpeg, the rest declined\n", real_count,
           real_native);
    CHECK(real_count > 0);
}

/* Cut short or damaged: refused naming the file, nothing returned, and
 * nothing printed by libjpeg. */
static void test_corrupt_jpeg(void)
{
    sl_error err;
    size_t size;
    char *whole = sl_test_read_file(sl_test_path("rgb420.jpg"), &size);
    CHECK(whole && size > 400);
    if (!whole)
        return;
    char *bad = malloc(size + 16);
    memcpy(bad, whole, size);
    /* A stray marker in the middle of the scan: libjpeg's "Corrupt JPEG
     * data" warning, after which it would fill the rest with grey. */
    memcpy(bad + size - 150, "\xFF\xC8", 2);
    const struct {
        const char *name;
        const char *bytes;
        size_t keep;
        const char *what;
    } cuts[] = {
        {"cut_header.jpg", whole, 30, "truncated or corrupt JPEG"},
        {"cut_pixels.jpg", whole, size - 200, "truncated or corrupt image at rows"},
        {"stray_marker.jpg", bad, size, "truncated or corrupt image at rows"},
    };
    stderr_catch caught = stderr_catch_begin();
    for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++)
        photo_check_refused(cuts[i].name, cuts[i].bytes, cuts[i].keep, cuts[i].what);
    /* The strips see the cut at the rows it hits. */
    sl_photo_strips *s;
    sl_photo_strip_info info;
    const char *path = sl_test_path("cut_pixels.jpg");
    CHECK_OK(sl_photo_strips_open(path, &s, &info, &err), &err);
    float rgb[45 * 3 * 31];
    if (s) {
        CHECK_RESULT(sl_photo_strips_read(s, 0, 31, rgb, &err), SL_ERR_INPUT, &err);
        CHECK_MSG(strstr(err.message, path) != NULL, "%s", err.message);
        sl_photo_strips_close(s);
    }
    size_t printed;
    char *text = stderr_catch_end(&caught, &printed);
    CHECK_MSG(printed == 0, "libjpeg printed: %s", text ? text : "");
    free(text);
    free(bad);
    free(whole);
}

int main(void)
{
    RUN(test_jpeg_does_not_start_oiio);
    RUN(test_jpeg_matches_oiio);
    RUN(test_declined_go_to_oiio);
    RUN(test_real_jpegs_match_oiio);
    RUN(test_corrupt_jpeg);
    for (int i = 0; i < VARIANTS; i++) {
        sl_image_free(&native[i]);
        sl_meta_free(&native_meta[i]);
    }
    return sl_test_finish();
}
