/* SPDX-License-Identifier: BSD-3-Clause */
/* PNG read through libpng (core/photo_png.c) against OpenImageIO on the same
 * files: the same pixels to the bit, the same metadata, the same strips;
 * declined files (interlaced, EXIF) go to OpenImageIO; corrupt files are
 * refused naming the file; and none of the PNG reading starts OpenImageIO. */
#include <png.h>
#include <stdlib.h>
#include <string.h>

#include "../core/photo_private.h"
#include "testing.h"

typedef struct variant {
    const char *name;
    int width, height, depth, color_type;
    bool interlaced;
    int gamma;     /* gAMA * 100000, 0 none */
    bool srgb;     /* sRGB chunk */
    bool trns;     /* tRNS chunk */
    bool text;     /* text chunks and tIME */
    bool exif;     /* eXIf chunk */
} variant;

static const variant variants[] = {
    {"rgb8.png", 37, 11, 8, PNG_COLOR_TYPE_RGB, false, 0, false, false, false, false},
    {"srgb.png", 16, 9, 8, PNG_COLOR_TYPE_RGB, false, 0, true, false, false, false},
    {"linear.png", 16, 9, 8, PNG_COLOR_TYPE_RGB, false, 100000, false, false, false, false},
    {"gamma22.png", 16, 9, 8, PNG_COLOR_TYPE_RGB, false, 45455, false, false, false, false},
    {"gamma245.png", 16, 9, 8, PNG_COLOR_TYPE_RGB, false, 40833, false, false, false, false},
    {"rgba16.png", 23, 13, 16, PNG_COLOR_TYPE_RGB_ALPHA, false, 0, false, false, true, false},
    {"rgb16.png", 19, 7, 16, PNG_COLOR_TYPE_RGB, false, 0, false, false, false, false},
    {"grey16.png", 9, 9, 16, PNG_COLOR_TYPE_GRAY, false, 0, false, false, false, false},
    {"grey1.png", 21, 5, 1, PNG_COLOR_TYPE_GRAY, false, 0, false, false, false, false},
    {"grey4.png", 13, 6, 4, PNG_COLOR_TYPE_GRAY, false, 0, false, false, false, false},
    {"grey_trns.png", 12, 6, 8, PNG_COLOR_TYPE_GRAY, false, 0, false, true, false, false},
    {"grey_alpha.png", 12, 6, 8, PNG_COLOR_TYPE_GRAY_ALPHA, false, 0, false, false, false, false},
    {"palette.png", 17, 8, 8, PNG_COLOR_TYPE_PALETTE, false, 0, false, true, false, false},
    {"palette2.png", 17, 8, 2, PNG_COLOR_TYPE_PALETTE, false, 0, false, false, false, false},
    {"text.png", 10, 4, 8, PNG_COLOR_TYPE_RGB, false, 0, false, false, true, false},
    /* declined: OpenImageIO reads these */
    {"interlaced.png", 15, 10, 8, PNG_COLOR_TYPE_RGB, true, 0, false, false, false, false},
    {"exif.png", 10, 4, 8, PNG_COLOR_TYPE_RGB, false, 0, false, false, false, true},
};
#define VARIANTS (int)(sizeof variants / sizeof variants[0])
#define NATIVE 15 /* the variants libpng reads itself */

static void add_text(png_structp png, png_infop info)
{
    static const char *const kv[][2] = {
        {"Make", "Canon"},
        {"Model", "EOS 5D"},
        {"Exif:LensModel", "EF 8-15mm"},
        {"ExposureTime", "0.004"},
        {"FNumber", "8"},
        {"Exif:ISOSpeedRatings", "200"},
        {"Exif:FocalLength", "8.5"},
        {"Orientation", "6"},
        {"setlight:inputs", "a.cr2 b.cr2"},
        {"setlight:note", "first"},
        {"setlight:note", "second"},
    };
    png_text t[sizeof kv / sizeof kv[0]];
    for (size_t i = 0; i < sizeof kv / sizeof kv[0]; i++) {
        memset(&t[i], 0, sizeof t[i]);
        t[i].compression = i % 2 ? PNG_TEXT_COMPRESSION_zTXt : PNG_TEXT_COMPRESSION_NONE;
        t[i].key = (char *)kv[i][0];
        t[i].text = (char *)kv[i][1];
    }
    png_set_text(png, info, t, (int)(sizeof t / sizeof t[0]));
    png_time when = {2024, 5, 6, 7, 8, 9};
    png_set_tIME(png, info, &when);
}

/* Writes the variant with codes that cover the whole range of its depth. */
static bool write_variant(const char *path, const variant *v)
{
    FILE *f = fopen(path, "wb");
    if (!f)
        return false;
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png_create_info_struct(png);
    unsigned char *row = NULL;
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        fclose(f);
        free(row);
        return false;
    }
    png_init_io(png, f);
    png_set_IHDR(png, info, (png_uint_32)v->width, (png_uint_32)v->height, v->depth,
                 v->color_type, v->interlaced ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    int samples = v->color_type == PNG_COLOR_TYPE_RGB         ? 3
                  : v->color_type == PNG_COLOR_TYPE_RGB_ALPHA ? 4
                  : v->color_type == PNG_COLOR_TYPE_GRAY_ALPHA ? 2
                                                               : 1;
    if (v->color_type == PNG_COLOR_TYPE_PALETTE) {
        png_color pal[4] = {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}, {10, 20, 30}};
        png_set_PLTE(png, info, pal, 4);
        if (v->trns) {
            png_byte alpha[2] = {128, 0};
            png_set_tRNS(png, info, alpha, 2, NULL);
        }
    } else if (v->trns) {
        png_color_16 grey = {0, 0, 0, 0, 10};
        png_set_tRNS(png, info, NULL, 0, &grey);
    }
    if (v->srgb)
        png_set_sRGB(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
    if (v->gamma)
        png_set_gAMA_fixed(png, info, v->gamma);
    if (v->text)
        add_text(png, info);
    if (v->exif) {
        /* Big-endian TIFF header, one IFD entry: Make = "Nik". */
        static png_byte exif[] = {'M', 'M', 0, 42, 0, 0, 0, 8, 0, 1, 1, 15, 0, 2,
                                  0, 0, 0, 4, 'N', 'i', 'k', 0, 0, 0, 0, 0};
        png_set_eXIf_1(png, info, sizeof exif, exif);
    }
    png_write_info(png, info);
    size_t row_bytes = png_get_rowbytes(png, info);
    row = malloc(row_bytes);
    int passes = png_set_interlace_handling(png);
    for (int pass = 0; pass < passes; pass++)
        for (int y = 0; y < v->height; y++) {
            for (size_t i = 0; i < row_bytes; i++)
                row[i] = (unsigned char)(i * 37 + (size_t)y * 101 + (size_t)samples * 7);
            if (v->color_type == PNG_COLOR_TYPE_PALETTE) /* indices 0..3 */
                for (size_t i = 0; i < row_bytes; i++)
                    row[i] = v->depth == 8 ? (unsigned char)((i + (size_t)y) % 4) : 0x1b;
            png_write_row(png, row);
        }
    png_write_end(png, info);
    png_destroy_write_struct(&png, &info);
    free(row);
    return fclose(f) == 0;
}

/* The native reads come first: nothing before them may start OpenImageIO. */
static sl_image native[VARIANTS];
static sl_meta native_meta[VARIANTS];

static void test_png_does_not_start_oiio(void)
{
    sl_error err;
    for (int i = 0; i < VARIANTS; i++)
        CHECK_MSG(write_variant(sl_test_path(variants[i].name), &variants[i]), "writing %s",
                  variants[i].name);
    for (int i = 0; i < NATIVE; i++) {
        CHECK_OK(sl_photo_read(sl_test_path(variants[i].name), &native[i], &native_meta[i], &err),
                 &err);
        sl_meta m;
        int w, h, c;
        CHECK_OK(sl_photo_read_meta(sl_test_path(variants[i].name), &m, &w, &h, &c, &err), &err);
        CHECK(w == variants[i].width && h == variants[i].height && c == native[i].channels);
        CHECK(sl_test_same_meta(variants[i].name, &m, &native_meta[i]));
        sl_meta_free(&m);
    }
    /* Nor does refusing a missing or empty file. */
    sl_image none;
    CHECK_RESULT(sl_photo_read(sl_test_path("missing.png"), &none, NULL, &err), SL_ERR_NOT_FOUND,
                 &err);
    const char *empty = sl_test_path("empty.jpg");
    CHECK_OK(sl_write_file_atomic(empty, "", 0, &err), &err);
    CHECK_RESULT(sl_photo_read_meta(empty, NULL, NULL, NULL, NULL, &err), SL_ERR_INPUT, &err);
    CHECK_MSG(sl_oiio_start_count() == 0, "reading PNGs started OpenImageIO");

    /* Known answers: palette 0 is red at alpha 128; 1-bit grey expands to 0 / 1. */
    const sl_image *pal = &native[12];
    CHECK(pal->channels == 4);
    if (pal->data)
        CHECK(pal->data[0] == 1.0f && pal->data[1] == 0.0f && pal->data[3] == 128.0f / 255.0f);
    const sl_image *g1 = &native[8];
    for (size_t i = 0; g1->data && i < (size_t)g1->width * (size_t)g1->height; i++)
        CHECK_MSG(g1->data[i] == 0.0f || g1->data[i] == 1.0f, "1-bit sample %g", g1->data[i]);
    CHECK(strcmp(native_meta[3].colorspace, "Gamma2.2") == 0);
    CHECK(strcmp(native_meta[2].colorspace, "linear") == 0);
    const sl_meta *t = &native_meta[14];
    CHECK(strcmp(t->make, "Canon") == 0 && t->orientation == 6 && t->f_number == 8.0);
    CHECK(strcmp(t->datetime, "2024:05:06 07:08:09") == 0);
    CHECK(sl_meta_get(t, "setlight:note") && strcmp(sl_meta_get(t, "setlight:note"), "second") == 0);
}

static void test_png_matches_oiio(void)
{
    sl_error err;
    for (int i = 0; i < NATIVE; i++) {
        sl_image ref;
        sl_meta ref_meta;
        const char *path = sl_test_path(variants[i].name);
        CHECK_OK(sl_oiio_read(path, &ref, &ref_meta, &err), &err);
        bool same = ref.width == native[i].width && ref.height == native[i].height &&
                    ref.channels == native[i].channels && ref.data && native[i].data &&
                    memcmp(ref.data, native[i].data,
                           sizeof(float) * (size_t)ref.width * (size_t)ref.height *
                               (size_t)ref.channels) == 0;
        CHECK_MSG(same, "%s: pixels differ from OpenImageIO's", variants[i].name);
        CHECK_MSG(sl_test_same_meta(variants[i].name, &native_meta[i], &ref_meta),
                  "%s: metadata differs from OpenImageIO's", variants[i].name);
        sl_image_free(&ref);
        sl_meta_free(&ref_meta);
    }
    CHECK(sl_oiio_start_count() == 1);
}

/* Strips (rows skipped, grey repeated, alpha dropped) as floats and codes. */
static void test_png_strips_match_oiio(void)
{
    sl_error err;
    static const int which[] = {0, 5, 7, 11, 12};
    for (size_t k = 0; k < sizeof which / sizeof which[0]; k++) {
        const variant *v = &variants[which[k]];
        const char *path = sl_test_path(v->name);
        sl_photo_strips *mine;
        sl_oiio_strips *ref;
        sl_photo_strip_info a, b;
        CHECK_OK(sl_photo_strips_open(path, &mine, &a, &err), &err);
        CHECK_OK(sl_oiio_strips_open(path, &ref, &b, &err), &err);
        if (!mine || !ref)
            continue;
        CHECK_MSG(memcmp(&a, &b, sizeof a) == 0, "%s: strip info differs", v->name);
        size_t n = (size_t)v->width * 3 * (size_t)v->height;
        float *fa = calloc(n, sizeof *fa), *fb = calloc(n, sizeof *fb);
        uint16_t *ca = calloc(n, 2), *cb = calloc(n, 2);
        int rows[][2] = {{1, 3}, {4, 5}, {5, v->height}};
        for (int r = 0; r < 3; r++) {
            int y0 = rows[r][0], y1 = rows[r][1];
            size_t m = (size_t)(y1 - y0) * (size_t)v->width * 3;
            if (r == 1) {
                CHECK_OK(sl_photo_strips_read_codes(mine, y0, y1, ca, &err), &err);
                CHECK_OK(sl_oiio_strips_read_codes(ref, y0, y1, cb, &err), &err);
                CHECK_MSG(memcmp(ca, cb, m * (size_t)a.code_bytes) == 0, "%s: codes differ",
                          v->name);
            } else {
                CHECK_OK(sl_photo_strips_read(mine, y0, y1, fa, &err), &err);
                CHECK_OK(sl_oiio_strips_read(ref, y0, y1, fb, &err), &err);
                CHECK_MSG(memcmp(fa, fb, m * sizeof *fa) == 0, "%s: rows %d-%d differ", v->name,
                          y0, y1 - 1);
            }
        }
        /* Rows go forward only. */
        CHECK_RESULT(sl_photo_strips_read(mine, 0, 1, fa, &err), SL_ERR_USAGE, &err);
        free(fa);
        free(fb);
        free(ca);
        free(cb);
        sl_photo_strips_close(mine);
        sl_oiio_strips_close(ref);
    }
}

static void test_declined_go_to_oiio(void)
{
    sl_error err;
    sl_image img;
    sl_meta meta;
    CHECK_OK(sl_photo_read(sl_test_path("interlaced.png"), &img, &meta, &err), &err);
    CHECK(img.width == 15 && img.height == 10 && strcmp(meta.format, "png") == 0);
    sl_image_free(&img);
    sl_meta_free(&meta);
    CHECK_OK(sl_photo_read_meta(sl_test_path("exif.png"), &meta, NULL, NULL, NULL, &err), &err);
    CHECK_MSG(strcmp(meta.make, "Nik") == 0, "EXIF Make '%s'", meta.make);
    sl_meta_free(&meta);
}

/* A PNG cut short: refused naming the file, nothing returned. */
static void test_corrupt_png(void)
{
    sl_error err;
    size_t size;
    char *whole = sl_test_read_file(sl_test_path("rgba16.png"), &size);
    CHECK(whole && size > 200);
    if (!whole)
        return;
    const struct {
        const char *name;
        size_t keep;
        const char *what;
    } cuts[] = {
        {"cut_header.png", 20, "truncated or corrupt PNG"},
        {"cut_pixels.png", size - 120, "truncated or corrupt image at rows"},
    };
    for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++) {
        const char *path = sl_test_path(cuts[i].name);
        CHECK_OK(sl_write_file_atomic(path, whole, cuts[i].keep, &err), &err);
        sl_image img;
        sl_meta meta;
        CHECK_RESULT(sl_photo_read(path, &img, &meta, &err), SL_ERR_INPUT, &err);
        CHECK_MSG(strstr(err.message, path) && strstr(err.message, cuts[i].what), "%s",
                  err.message);
        CHECK(img.data == NULL && meta.attrs == NULL);
    }
    /* The strips see the cut at the rows it hits. */
    sl_photo_strips *s;
    sl_photo_strip_info info;
    const char *path = sl_test_path("cut_pixels.png");
    CHECK_OK(sl_photo_strips_open(path, &s, &info, &err), &err);
    float rgb[23 * 3 * 13];
    if (s) {
        CHECK_RESULT(sl_photo_strips_read(s, 0, 13, rgb, &err), SL_ERR_INPUT, &err);
        CHECK_MSG(strstr(err.message, path) != NULL, "%s", err.message);
        sl_photo_strips_close(s);
    }
    free(whole);
}

int main(void)
{
    RUN(test_png_does_not_start_oiio);
    RUN(test_png_matches_oiio);
    RUN(test_png_strips_match_oiio);
    RUN(test_declined_go_to_oiio);
    RUN(test_corrupt_png);
    for (int i = 0; i < VARIANTS; i++) {
        sl_image_free(&native[i]);
        sl_meta_free(&native_meta[i]);
    }
    return sl_test_finish();
}
