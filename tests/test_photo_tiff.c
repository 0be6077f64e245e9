/* SPDX-License-Identifier: BSD-3-Clause */
/* TIFF read through libtiff (core/photo_tiff.c) against OpenImageIO on the
 * same files: synthetic ones written by libtiff (8/16-bit and float, grey,
 * grey + alpha, RGB, RGBA, strips and tiles, each compression, both byte
 * orders, EXIF, ICC, XMP), the virtual set's frames as it writes them
 * (through OpenImageIO: 16-bit curve and linear with an ICC profile) and
 * every TIFF in the shared data: the same pixels to the bit, the same size
 * and channels, the same metadata (but ISO, which OIIO 2.4 drops), the same
 * strips; declined files go to OpenImageIO; corrupt files are refused
 * naming the file, with nothing printed; and reading the native ones never
 * starts OpenImageIO. */
#include <ftw.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <tiffio.h>
#include <unistd.h>

#include "../core/photo_private.h"
#include "test_photo_common.h"
#include "testing.h"

/* ---- synthetic TIFFs -------------------------------------------------- */

typedef struct variant {
    const char *name;
    int width, height, spp, bits;
    bool real;        /* 32-bit float samples */
    int photometric;  /* PHOTOMETRIC_* */
    int compression;  /* COMPRESSION_* */
    int predictor;    /* 0 none */
    int tile;         /* tile size, 0 strips */
    int rows;         /* rows per strip */
    bool big_endian;
    int alpha;        /* ExtraSamples: -1 none, else EXTRASAMPLE_* */
    int exif;         /* 0 none, 1 full (ISO too), 2 ColorSpace uncalibrated */
    bool icc, planar_separate;
    int orientation;  /* 0: tag absent */
    int xmp;          /* 0 none, 1 nothing setlight reads, 2 a date it reads */
    bool native;      /* read by libtiff (else declined) */
} variant;

#define P_RGB PHOTOMETRIC_RGB
#define P_GREY PHOTOMETRIC_MINISBLACK
#define C_NONE COMPRESSION_NONE
#define C_ZIP COMPRESSION_ADOBE_DEFLATE

static const variant variants[] = {
    {"rgb8.tif", 37, 21, 3, 8, false, P_RGB, C_NONE, 0, 0, 8, false, -1, 1, false, false, 1, 0, true},
    {"rgb16_zip.tif", 45, 31, 3, 16, false, P_RGB, C_ZIP, 2, 0, 32, false, -1, 1, true, false, 6, 0, true},
    {"rgb16_lzw_be.tif", 33, 17, 3, 16, false, P_RGB, COMPRESSION_LZW, 2, 0, 5, true, -1, 1, false, false, 0, 0, true},
    {"rgb8_packbits.tif", 29, 19, 3, 8, false, P_RGB, COMPRESSION_PACKBITS, 0, 0, 19, false, -1, 0, false, false, 0, 0, true},
    {"rgbf.tif", 26, 14, 3, 32, true, P_RGB, C_ZIP, 3, 0, 4, false, -1, 0, false, false, 1, 0, true},
    {"rgbf_be.tif", 26, 14, 3, 32, true, P_RGB, C_NONE, 0, 0, 3, true, -1, 2, false, false, 1, 0, true},
    {"grey8.tif", 20, 12, 1, 8, false, P_GREY, C_ZIP, 2, 0, 12, false, -1, 0, false, false, 0, 0, true},
    {"grey16_alpha.tif", 20, 12, 2, 16, false, P_GREY, C_NONE, 0, 0, 7, false, EXTRASAMPLE_UNASSALPHA, 0, false, false, 0, 0, true},
    {"rgba8_unassoc.tif", 23, 13, 4, 8, false, P_RGB, COMPRESSION_LZW, 2, 0, 6, false, EXTRASAMPLE_UNASSALPHA, 1, false, false, 1, 0, true},
    {"rgba16_assoc.tif", 23, 13, 4, 16, false, P_RGB, C_ZIP, 0, 0, 13, true, EXTRASAMPLE_ASSOCALPHA, 0, false, false, 0, 0, true},
    {"tiled16.tif", 50, 37, 3, 16, false, P_RGB, C_ZIP, 2, 16, 0, false, -1, 1, true, false, 1, 0, true},
    {"tiledf_be.tif", 40, 20, 3, 32, true, P_RGB, C_NONE, 0, 16, 0, true, -1, 0, false, false, 0, 0, true},
    {"zstd16.tif", 30, 10, 3, 16, false, P_RGB, COMPRESSION_ZSTD, 2, 0, 4, false, -1, 0, false, false, 0, 0, true},
    {"xmp_other.tif", 20, 12, 3, 8, false, P_RGB, C_NONE, 0, 0, 12, false, -1, 1, false, false, 1, 1, true},
    /* declined: OpenImageIO reads these */
    {"palette.tif", 20, 12, 1, 8, false, PHOTOMETRIC_PALETTE, C_NONE, 0, 0, 12, false, -1, 0, false, false, 0, 0, false},
    {"cmyk.tif", 20, 12, 4, 8, false, PHOTOMETRIC_SEPARATED, C_NONE, 0, 0, 12, false, -1, 0, false, false, 0, 0, false},
    {"separate.tif", 20, 12, 3, 8, false, P_RGB, C_NONE, 0, 0, 12, false, -1, 0, false, true, 0, 0, false},
    {"white_is_zero.tif", 20, 12, 1, 8, false, PHOTOMETRIC_MINISWHITE, C_NONE, 0, 0, 12, false, -1, 0, false, false, 0, 0, false},
    {"grey1.tif", 20, 12, 1, 1, false, P_GREY, C_NONE, 0, 0, 12, false, -1, 0, false, false, 0, 0, false},
    {"xmp_date.tif", 20, 12, 3, 8, false, P_RGB, C_NONE, 0, 0, 12, false, -1, 0, false, false, 1, 2, false},
};
#define VARIANTS (int)(sizeof variants / sizeof variants[0])

/* One sample of pixel (x, y), channel c: ramps, edges, every code range. */
static double sample(int x, int y, int c, int w)
{
    double v = (double)((x * 97 + y * 31 + c * 53 + ((x / 3 + y / 2) % 2) * 71) % 256) / 255.0;
    return c == 3 ? (double)(x + y) / (double)(w + 20) : v * (1.0 + (double)x / (double)w) / 2.0;
}

static void store(unsigned char *p, const variant *v, int x, int y, int c)
{
    double s = sample(x, y, c, v->width);
    if (v->real) {
        float f = (float)(s * 3.0 - 0.25); /* beyond [0, 1] both ways: float keeps it */
        memcpy(p, &f, 4);
    } else if (v->bits == 16) {
        uint16_t u = (uint16_t)(s * 65535.0 + 0.5);
        memcpy(p, &u, 2);
    } else if (v->bits == 8) {
        *p = (unsigned char)(s * 255.0 + 0.5);
    }
}

static void write_exif(TIFF *tif, const variant *v, uint64_t *at)
{
    TIFFCreateEXIFDirectory(tif);
    if (v->exif == 1) {
        uint16_t iso = 400;
        TIFFSetField(tif, EXIFTAG_EXPOSURETIME, 1.0 / 250.0);
        TIFFSetField(tif, EXIFTAG_FNUMBER, 2.8);
        TIFFSetField(tif, EXIFTAG_ISOSPEEDRATINGS, 1, &iso);
        TIFFSetField(tif, EXIFTAG_FOCALLENGTH, 42.5);
        TIFFSetField(tif, EXIFTAG_DATETIMEORIGINAL, "2024:02:03 04:05:06");
        TIFFSetField(tif, EXIFTAG_LENSMODEL, "EF 85mm f/1.8 USM");
    } else {
        TIFFSetField(tif, EXIFTAG_EXPOSURETIME, 1.0 / 8.0);
        TIFFSetField(tif, EXIFTAG_COLORSPACE, 0xFFFF);
    }
    TIFFWriteCustomDirectory(tif, at);
}

static bool write_variant(const char *path, const variant *v)
{
    TIFF *tif = TIFFOpen(path, v->big_endian ? "wb" : "wl");
    if (!tif)
        return false;
    TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, v->width);
    TIFFSetField(tif, TIFFTAG_IMAGELENGTH, v->height);
    TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, v->spp);
    TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, v->bits);
    TIFFSetField(tif, TIFFTAG_SAMPLEFORMAT, v->real ? SAMPLEFORMAT_IEEEFP : SAMPLEFORMAT_UINT);
    TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, v->photometric);
    TIFFSetField(tif, TIFFTAG_COMPRESSION, v->compression);
    TIFFSetField(tif, TIFFTAG_PLANARCONFIG, v->planar_separate ? PLANARCONFIG_SEPARATE
                                                               : PLANARCONFIG_CONTIG);
    if (v->predictor)
        TIFFSetField(tif, TIFFTAG_PREDICTOR, v->predictor);
    if (v->alpha >= 0) {
        uint16_t extra = (uint16_t)v->alpha;
        TIFFSetField(tif, TIFFTAG_EXTRASAMPLES, 1, &extra);
    }
    if (v->orientation)
        TIFFSetField(tif, TIFFTAG_ORIENTATION, v->orientation);
    if (v->photometric == PHOTOMETRIC_PALETTE) {
        static uint16_t map[3][256];
        for (int i = 0; i < 256; i++) {
            map[0][i] = (uint16_t)(i * 257);
            map[1][i] = (uint16_t)((255 - i) * 257);
            map[2][i] = (uint16_t)((i * 7 % 256) * 257);
        }
        TIFFSetField(tif, TIFFTAG_COLORMAP, map[0], map[1], map[2]);
    }
    if (v->exif) {
        TIFFSetField(tif, TIFFTAG_MAKE, "Canon");
        TIFFSetField(tif, TIFFTAG_MODEL, "Canon EOS 5D Mark IV");
        TIFFSetField(tif, TIFFTAG_DATETIME, "2024:02:03 09:09:09");
        TIFFSetField(tif, TIFFTAG_EXIFIFD, (uint64_t)0);
    }
    if (v->icc) {
        unsigned char icc[1024];
        size_t n = sl_icc_linear_rec709(icc, sizeof icc);
        TIFFSetField(tif, TIFFTAG_ICCPROFILE, (uint32_t)n, icc);
    }
    if (v->xmp) {
        static const char *const xmps[] = {
            NULL,
            "<x:xmpmeta xmlns:x='adobe:ns:meta/'><rdf:RDF><rdf:Description rdf:about='' "
            "aux:SerialNumber='1823918851' xmp:Rating='3'/></rdf:RDF></x:xmpmeta>",
            "<x:xmpmeta xmlns:x='adobe:ns:meta/'><rdf:RDF><rdf:Description rdf:about='' "
            "xmp:CreateDate='2017-10-31T22:39:43'/></rdf:RDF></x:xmpmeta>",
        };
        TIFFSetField(tif, TIFFTAG_XMLPACKET, (uint32_t)strlen(xmps[v->xmp]), xmps[v->xmp]);
    }
    size_t b = v->bits <= 8 ? 1 : (size_t)v->bits / 8;
    bool ok = true;
    if (v->tile) {
        TIFFSetField(tif, TIFFTAG_TILEWIDTH, v->tile);
        TIFFSetField(tif, TIFFTAG_TILELENGTH, v->tile);
        size_t n = (size_t)TIFFTileSize(tif);
        unsigned char *t = calloc(n, 1);
        for (int ty = 0; ty < v->height; ty += v->tile)
            for (int tx = 0; tx < v->width; tx += v->tile) {
                memset(t, 0, n);
                for (int y = ty; y < ty + v->tile && y < v->height; y++)
                    for (int x = tx; x < tx + v->tile && x < v->width; x++)
                        for (int c = 0; c < v->spp; c++)
                            store(t + (((size_t)(y - ty) * (size_t)v->tile + (size_t)(x - tx)) *
                                           (size_t)v->spp + (size_t)c) * b,
                                  v, x, y, c);
                ok &= TIFFWriteEncodedTile(tif, TIFFComputeTile(tif, (uint32_t)tx, (uint32_t)ty, 0, 0),
                                           t, (tmsize_t)n) >= 0;
            }
        free(t);
    } else {
        TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, v->rows);
        int planes = v->planar_separate ? v->spp : 1, per = v->planar_separate ? 1 : v->spp;
        size_t row = v->bits == 1 ? ((size_t)v->width + 7) / 8 : (size_t)v->width * (size_t)per * b;
        unsigned char *line = calloc(row, 1);
        for (int s = 0; s < planes; s++)
            for (int y = 0; y < v->height; y++) {
                memset(line, 0, row);
                for (int x = 0; x < v->width; x++)
                    for (int c = 0; c < per; c++) {
                        if (v->bits == 1) {
                            if (sample(x, y, 0, v->width) > 0.4)
                                line[x / 8] |= (unsigned char)(0x80 >> (x % 8));
                        } else
                            store(line + ((size_t)x * (size_t)per + (size_t)c) * b, v, x, y,
                                  planes > 1 ? s : c);
                    }
                ok &= TIFFWriteScanline(tif, line, (uint32_t)y, (uint16_t)s) == 1;
            }
        free(line);
    }
    ok &= TIFFWriteDirectory(tif) == 1;
    if (v->exif) {
        uint64_t at = 0;
        write_exif(tif, v, &at);
        ok &= TIFFSetDirectory(tif, 0) == 1;
        TIFFSetField(tif, TIFFTAG_EXIFIFD, at);
        ok &= TIFFRewriteDirectory(tif) == 1;
    }
    TIFFClose(tif);
    return ok;
}

/* ---- comparisons ------------------------------------------------------ */

/* Row y of an image as strips give it: RGB, grey repeated. */
static void strip_row(const sl_image *img, int y, float *rgb)
{
    for (int x = 0; x < img->width; x++)
        for (int c = 0; c < 3; c++)
            rgb[3 * x + c] = sl_image_pixel(img, x, y)[img->channels >= 3 ? c : 0];
}

/* Strips of `path` both ways: the same info, rows skipped and read again,
 * floats and codes (float files have none, both ways), and the rows of the
 * whole read. OIIO 2.4's strips of a tiled TIFF die of a division by zero
 * (SIGFPE in ImageInput::read_scanlines): `tiled` compares with the whole
 * read only. */
static void compare_strips(const char *path, const sl_image *whole, bool tiled)
{
    sl_error err;
    sl_photo_strips *mine;
    sl_oiio_strips *ref;
    sl_photo_strip_info a, b;
    CHECK_OK(sl_photo_strips_open(path, &mine, &a, &err), &err);
    CHECK_OK(sl_oiio_strips_open(path, &ref, &b, &err), &err);
    if (mine && ref) {
        CHECK_MSG(memcmp(&a, &b, sizeof a) == 0,
                  "%s: strip info differs (%dx%d %d ch %d bits float %d codes %d vs %dx%d %d ch "
                  "%d bits float %d codes %d)",
                  path, a.width, a.height, a.file_channels, a.bits, a.is_float, a.code_bytes,
                  b.width, b.height, b.file_channels, b.bits, b.is_float, b.code_bytes);
        int h = a.height;
        size_t n = (size_t)a.width * 3 * (size_t)h;
        float *fa = calloc(n, sizeof *fa), *fb = calloc(n, sizeof *fb);
        unsigned char *ca = calloc(n, 2), *cb = calloc(n, 2);
        int rows[][2] = {{1, 3}, {4, 5}, {5, h}, {0, 2}};
        for (int r = 0; r < 4; r++) {
            int y0 = rows[r][0], y1 = rows[r][1];
            size_t m = (size_t)(y1 - y0) * (size_t)a.width * 3;
            if (r == 1) {
                sl_result want = a.code_bytes ? SL_OK : SL_ERR_USAGE;
                CHECK_RESULT(sl_photo_strips_read_codes(mine, y0, y1, ca, &err), want, &err);
                if (!tiled) {
                    CHECK_RESULT(sl_oiio_strips_read_codes(ref, y0, y1, cb, &err), want, &err);
                    CHECK_MSG(memcmp(ca, cb, m * (size_t)a.code_bytes) == 0, "%s: codes differ",
                              path);
                }
                continue;
            }
            CHECK_OK(sl_photo_strips_read(mine, y0, y1, fa, &err), &err);
            for (int y = y0; y < y1; y++)
                strip_row(whole, y, fb + (size_t)(y - y0) * (size_t)a.width * 3);
            CHECK_MSG(memcmp(fa, fb, m * sizeof *fa) == 0, "%s: rows %d-%d differ from the image",
                      path, y0, y1 - 1);
            if (!tiled) {
                CHECK_OK(sl_oiio_strips_read(ref, y0, y1, fb, &err), &err);
                CHECK_MSG(memcmp(fa, fb, m * sizeof *fa) == 0, "%s: rows %d-%d differ", path,
                          y0, y1 - 1);
            }
        }
        free(fa);
        free(fb);
        free(ca);
        free(cb);
    }
    sl_photo_strips_close(mine);
    sl_oiio_strips_close(ref);
}

/* Whole reads and metadata reads of `path` both ways; `iso`: what the file's
 * EXIF says (OIIO 2.4 gives 0). */
static void compare_reads(const char *path, const sl_image *native, const sl_meta *native_meta,
                          double iso)
{
    sl_error err;
    sl_image ref;
    sl_meta ref_meta, meta, oiio_meta;
    int w, h, c, ow, oh, oc;
    CHECK_OK(sl_oiio_read(path, &ref, &ref_meta, &err), &err);
    CHECK_MSG(photo_same_pixels(native, &ref), "%s: pixels differ from OpenImageIO's", path);
    CHECK_MSG(native_meta->iso == iso && ref_meta.iso == 0, "%s: ISO %g, OIIO %g", path,
              native_meta->iso, ref_meta.iso);
    ref_meta.iso = iso;
    CHECK_MSG(sl_test_same_meta(path, native_meta, &ref_meta), "%s: metadata differs", path);
    CHECK_OK(sl_photo_read_meta(path, &meta, &w, &h, &c, &err), &err);
    CHECK_OK(sl_oiio_read_meta(path, &oiio_meta, &ow, &oh, &oc, &err), &err);
    CHECK_MSG(w == ow && h == oh && c == oc, "%s: %dx%d %d ch, OIIO %dx%d %d ch", path, w, h, c,
              ow, oh, oc);
    oiio_meta.iso = iso;
    CHECK_MSG(sl_test_same_meta(path, &meta, &oiio_meta), "%s: read_meta differs", path);
    sl_image_free(&ref);
    sl_meta_free(&ref_meta);
    sl_meta_free(&meta);
    sl_meta_free(&oiio_meta);
}

static bool is_native(const char *path)
{
    sl_error err;
    sl_tiff_reader *r = NULL;
    bool declined = false;
    bool native = sl_tiff_reader_open(path, &r, NULL, &declined, &err) == SL_OK && r;
    sl_tiff_reader_close(r);
    return native;
}

/* ---- tests ------------------------------------------------------------ */

static sl_image native[VARIANTS];
static sl_meta native_meta[VARIANTS];

static void test_tiff_does_not_start_oiio(void)
{
    sl_error err;
    for (int i = 0; i < VARIANTS; i++)
        CHECK_MSG(write_variant(sl_test_path(variants[i].name), &variants[i]), "writing %s",
                  variants[i].name);
    for (int i = 0; i < VARIANTS; i++)
        if (variants[i].native)
            CHECK_OK(sl_photo_read(sl_test_path(variants[i].name), &native[i], &native_meta[i],
                                   &err),
                     &err);
    CHECK_MSG(sl_oiio_start_count() == 0, "reading TIFFs started OpenImageIO");

    /* Known answers: the EXIF as written, no rotation, grey as grey. */
    const sl_meta *m = &native_meta[1];
    CHECK(strcmp(m->make, "Canon") == 0 && strcmp(m->model, "Canon EOS 5D Mark IV") == 0);
    CHECK(m->exposure_time == (double)(float)(1.0 / 250) && m->f_number == (double)2.8f);
    CHECK(m->iso == 400 && m->focal_length_mm == 42.5 && m->orientation == 6);
    CHECK(strcmp(m->lens, "EF 85mm f/1.8 USM") == 0);
    CHECK(strcmp(m->datetime, "2024:02:03 04:05:06") == 0);
    CHECK_MSG(strcmp(m->colorspace, "lin_rec709") == 0, "ICC: '%s'", m->colorspace);
    CHECK(strcmp(native_meta[0].colorspace, "sRGB") == 0 && strcmp(m->format, "tiff") == 0);
    CHECK(native_meta[3].colorspace[0] == 0 && native_meta[3].make[0] == 0); /* no EXIF */
    CHECK(native_meta[5].exposure_time == 0.125 && native_meta[5].colorspace[0] == 0);
    CHECK(native[1].width == 45 && native[1].height == 31 && native[1].channels == 3);
    CHECK(native_meta[1].bits_per_sample == 16 && !native_meta[1].is_float);
    CHECK(native_meta[4].bits_per_sample == 32 && native_meta[4].is_float);
    CHECK(native[6].channels == 1 && native[7].channels == 2 && native[8].channels == 4);
    CHECK(native_meta[2].iso == 400); /* big-endian */
    /* The samples as written: 16-bit codes / 65535, float as stored (below
     * 0 and above 1 kept), 8-bit / 255. */
    CHECK(native[1].data[3 * 45 * 2 + 3 * 5 + 1] ==
          (float)(uint16_t)(sample(5, 2, 1, 45) * 65535.0 + 0.5) * (1.0f / 65535.0f));
    CHECK(native[4].data[3 * 26 * 9 + 3 * 7 + 2] == (float)(sample(7, 9, 2, 26) * 3.0 - 0.25));
    CHECK(native[10].data[3 * (50 * 36 + 49)] ==
          (float)(uint16_t)(sample(49, 36, 0, 50) * 65535.0 + 0.5) * (1.0f / 65535.0f));
    bool below = false, above = false;
    for (int i = 0; i < 26 * 14 * 3; i++) {
        below |= native[4].data[i] < 0;
        above |= native[4].data[i] > 1;
    }
    CHECK(below && above);
}

static void test_tiff_matches_oiio(void)
{
    for (int i = 0; i < VARIANTS; i++) {
        if (!variants[i].native)
            continue;
        compare_reads(sl_test_path(variants[i].name), &native[i], &native_meta[i],
                      variants[i].exif == 1 ? 400 : 0);
        compare_strips(sl_test_path(variants[i].name), &native[i], variants[i].tile != 0);
    }
}

static void test_declined_go_to_oiio(void)
{
    sl_error err;
    for (int i = 0; i < VARIANTS; i++) {
        const char *path = sl_test_path(variants[i].name);
        CHECK_MSG(is_native(path) == variants[i].native, "%s: %s", variants[i].name,
                  variants[i].native ? "declined" : "not declined");
        if (variants[i].native)
            continue;
        sl_image img;
        sl_meta meta;
        CHECK_OK(sl_photo_read(path, &img, &meta, &err), &err);
        CHECK_MSG(img.width == variants[i].width && img.height == variants[i].height,
                  "%s through OpenImageIO", variants[i].name);
        sl_image_free(&img);
        sl_meta_free(&meta);
    }
    CHECK(sl_oiio_start_count() == 1);
}

/* The virtual set's frames as vset_capture.c writes them: 16-bit through
 * the curve, 16-bit linear with its ICC profile, and 8-bit and float. */
static void test_vset_tiffs_match_oiio(void)
{
    sl_error err;
    sl_image img;
    CHECK_OK(sl_image_alloc(&img, 61, 43, 3, NULL), &err);
    for (size_t i = 0; i < (size_t)61 * 43 * 3; i++)
        img.data[i] = (float)((i * 7919) % 1000) / 999.0f;
    sl_meta meta;
    sl_meta_init(&meta);
    meta.exposure_time = 1.0 / 125;
    meta.f_number = 16;
    meta.iso = 100;
    meta.focal_length_mm = 8;
    meta.orientation = 1;
    snprintf(meta.make, sizeof meta.make, "setlight");
    snprintf(meta.model, sizeof meta.model, "virtual full-frame");
    snprintf(meta.lens, sizeof meta.lens, "8mm f/3.5 equisolid fisheye");
    snprintf(meta.datetime, sizeof meta.datetime, "2026:05:14 10:00:00");
    const struct {
        const char *name, *space;
        int bits;
    } frames[] = {
        {"IMG_0001.tif", "", 16},
        {"IMG_0001_linear.tif", SL_WORKING_SPACE, 16},
        {"frame8.tif", "", 8},
        {"framef.tif", SL_WORKING_SPACE, 32},
    };
    for (size_t k = 0; k < sizeof frames / sizeof frames[0]; k++) {
        const char *path = sl_test_path(frames[k].name);
        snprintf(meta.colorspace, sizeof meta.colorspace, "%s", frames[k].space);
        CHECK_OK(sl_photo_write(path, &img, &meta, frames[k].bits, &err), &err);
        sl_image got;
        sl_meta got_meta;
        CHECK_MSG(is_native(path), "%s declined", frames[k].name);
        CHECK_OK(sl_photo_read(path, &got, &got_meta, &err), &err);
        compare_reads(path, &got, &got_meta, 0);
        compare_strips(path, &got, false);
        CHECK(got_meta.exposure_time == (double)(float)(1.0 / 125) && got_meta.f_number == 16);
        if (k == 1)
            CHECK_MSG(strcmp(got_meta.colorspace, "lin_rec709") == 0, "linear TIFF: '%s'",
                      got_meta.colorspace);
        sl_image_free(&got);
        sl_meta_free(&got_meta);
    }
    sl_image_free(&img);
}

static bool tiled_file(const char *path)
{
    TIFF *tif = TIFFOpen(path, "r");
    bool tiled = tif && TIFFIsTiled(tif);
    if (tif)
        TIFFClose(tif);
    return tiled;
}

/* Every TIFF in the shared data, both ways. */
static int real_count, real_native;

static int visit(const char *path, const struct stat *st, int kind, struct FTW *ftw)
{
    (void)st;
    (void)ftw;
    const char *dot = strrchr(path, '.');
    if (kind != FTW_F || !dot || (strcasecmp(dot, ".tif") && strcasecmp(dot, ".tiff")))
        return 0;
    real_count++;
    if (!is_native(path))
        return 0; /* OpenImageIO both ways */
    real_native++;
    sl_error err;
    sl_image img;
    sl_meta meta;
    CHECK_OK(sl_photo_read(path, &img, &meta, &err), &err);
    compare_reads(path, &img, &meta, meta.iso);
    compare_strips(path, &img, tiled_file(path));
    sl_image_free(&img);
    sl_meta_free(&meta);
    return 0;
}

static void test_real_tiffs_match_oiio(void)
{
    const char *data = sl_test_data("");
    if (!data)
        return;
    CHECK(nftw(data, visit, 16, FTW_PHYS) == 0);
    printf("  %d TIFFs in the shared data, %d read by libtiff, the rest declined\n", real_count,
           real_native);
}

/* Cut short or damaged: refused naming the file, nothing returned, and
 * nothing printed by libtiff. */
static void test_corrupt_tiff(void)
{
    sl_error err;
    size_t size;
    char *whole = sl_test_read_file(sl_test_path("rgb16_zip.tif"), &size);
    CHECK(whole && size > 400);
    if (!whole)
        return;
    char *bad = malloc(size);
    memcpy(bad, whole, size);
    /* The first strip's deflate stream (right after the header) garbled. */
    memset(bad + 10, 0xA5, 40);
    const struct {
        const char *name;
        const char *bytes;
        size_t keep;
        const char *what;
    } cuts[] = {
        {"cut_header.tif", whole, 6, "truncated or corrupt TIFF"},
        {"cut_directory.tif", whole, size - 60, "truncated or corrupt TIFF"},
        {"garbled_strip.tif", bad, size, "truncated or corrupt image at rows 0-"},
    };
    stderr_catch caught = stderr_catch_begin();
    for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++)
        photo_check_refused(cuts[i].name, cuts[i].bytes, cuts[i].keep, cuts[i].what);
    /* The strips see the damage at the rows it hits. */
    sl_photo_strips *s;
    sl_photo_strip_info info;
    const char *path = sl_test_path("garbled_strip.tif");
    CHECK_OK(sl_photo_strips_open(path, &s, &info, &err), &err);
    float rgb[45 * 3 * 31];
    if (s) {
        CHECK_OK(sl_photo_strips_read(s, 0, 0, rgb, &err), &err);
        CHECK_RESULT(sl_photo_strips_read(s, 0, 31, rgb, &err), SL_ERR_INPUT, &err);
        CHECK_MSG(strstr(err.message, path) != NULL, "%s", err.message);
        sl_photo_strips_close(s);
    }
    size_t printed;
    char *text = stderr_catch_end(&caught, &printed);
    CHECK_MSG(printed == 0, "libtiff printed: %s", text ? text : "");
    free(text);
    free(bad);
    free(whole);
}

/* Which files store their codes exactly (the merge saturates those only at
 * the clip code): lossless TIFF codecs, native or through OpenImageIO, but
 * not a JPEG-compressed TIFF nor float samples. */
static void test_lossless_flag(void)
{
    sl_error err;
    const char *jpeg_tif = sl_test_path("rgb8_jpeg.tif");
    TIFF *tif = TIFFOpen(jpeg_tif, "w");
    CHECK(tif != NULL);
    if (!tif)
        return;
    enum { W = 32, H = 16 };
    TIFFSetField(tif, TIFFTAG_IMAGEWIDTH, W);
    TIFFSetField(tif, TIFFTAG_IMAGELENGTH, H);
    TIFFSetField(tif, TIFFTAG_SAMPLESPERPIXEL, 3);
    TIFFSetField(tif, TIFFTAG_BITSPERSAMPLE, 8);
    TIFFSetField(tif, TIFFTAG_PHOTOMETRIC, PHOTOMETRIC_RGB);
    TIFFSetField(tif, TIFFTAG_PLANARCONFIG, PLANARCONFIG_CONTIG);
    TIFFSetField(tif, TIFFTAG_COMPRESSION, COMPRESSION_JPEG);
    TIFFSetField(tif, TIFFTAG_ROWSPERSTRIP, 16);
    unsigned char row[W * 3];
    bool written = true;
    for (int y = 0; y < H; y++) {
        for (int x = 0; x < W * 3; x++)
            row[x] = (unsigned char)(x * 7 + y * 13);
        written = written && TIFFWriteScanline(tif, row, (uint32_t)y, 0) == 1;
    }
    TIFFClose(tif);
    CHECK(written);
    const struct {
        const char *path;
        bool lossless;
    } files[] = {{sl_test_path("rgb8.tif"), true},       {sl_test_path("rgb16_zip.tif"), true},
                 {sl_test_path("rgbf.tif"), false},      {sl_test_path("palette.tif"), true},
                 {jpeg_tif, false}};
    for (size_t i = 0; i < sizeof files / sizeof files[0]; i++) {
        sl_photo_strips *s;
        sl_photo_strip_info info;
        CHECK_OK(sl_photo_strips_open(files[i].path, &s, &info, &err), &err);
        if (!s)
            continue;
        CHECK_MSG(info.lossless == files[i].lossless, "%s: lossless %d", files[i].path,
                  info.lossless);
        sl_photo_strips_close(s);
    }
}

int main(void)
{
    RUN(test_tiff_does_not_start_oiio);
    RUN(test_corrupt_tiff);
    RUN(test_tiff_matches_oiio);
    RUN(test_declined_go_to_oiio);
    RUN(test_vset_tiffs_match_oiio);
    RUN(test_real_tiffs_match_oiio);
    RUN(test_lossless_flag); /* last: it starts OpenImageIO for a JPEG TIFF */
    for (int i = 0; i < VARIANTS; i++) {
        sl_image_free(&native[i]);
        sl_meta_free(&native_meta[i]);
    }
    return sl_test_finish();
}
