/* SPDX-License-Identifier: BSD-3-Clause */
/* OpenEXR I/O: round trips (half and float, 1 to 4 channels, metadata),
 * files written here with the OpenEXR C API in shapes sl_exr_write never
 * makes (tiled, mipmapped, uint, layers, offset data window), real files
 * checked against OpenImageIO, and corrupt input. */
#include <dirent.h>
#include <float.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <openexr.h>

#include "testing.h"

/* Half keeps 11 significant bits: relative error at most 2^-11. */
#define HALF_REL 4.9e-4

static bool message_names(const sl_error *err, const char *path)
{
    return strstr(err->message, path) != NULL;
}

/* A value exactly representable in half, unique enough to catch misplaced
 * pixels or channels: integers below 2048. */
static float known(int x, int y, int c) { return (float)((x + 31 * y + 7 * c + 2048 * 4) % 2048); }

/* ------------------------------------------------------------------ */
/* A small C-API writer for shapes sl_exr_write does not produce.      */
/* ------------------------------------------------------------------ */

typedef struct test_exr_spec {
    exr_storage_t storage;
    exr_tile_level_mode_t levels;
    int tile; /* tile size when tiled */
    exr_attr_box2i_t display;
    exr_attr_box2i_t data;
    int nch;
    const char *names[8]; /* any order; the library sorts */
    exr_pixel_type_t types[8];
} test_exr_spec;

static exr_attr_box2i_t box(int x0, int y0, int x1, int y1)
{
    exr_attr_box2i_t b;
    memset(&b, 0, sizeof b);
    b.min.x = x0;
    b.min.y = y0;
    b.max.x = x1;
    b.max.y = y1;
    return b;
}

/* Channel c of the chunk at file position (x0, y0), level `level`: level 0
 * holds known(x, y, c); other levels hold 1000 + level so that reading them
 * by mistake shows. */
static void fill_chunk(const test_exr_spec *s, int c, int x0, int y0, int w, int h, int level,
                       void *buf)
{
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            float v = level ? 1000.0f + (float)level : known(x0 + x, y0 + y, c);
            size_t i = (size_t)y * (size_t)w + (size_t)x;
            if (s->types[c] == EXR_PIXEL_UINT)
                ((uint32_t *)buf)[i] = (uint32_t)v;
            else
                ((float *)buf)[i] = v;
        }
}

static exr_result_t encode_chunk(exr_context_t ctx, const test_exr_spec *s, exr_chunk_info_t *ci,
                                 int x0, int y0, int level, exr_encode_pipeline_t *enc, bool *init,
                                 void **bufs)
{
    exr_result_t rv =
        *init ? exr_encoding_update(ctx, 0, ci, enc) : exr_encoding_initialize(ctx, 0, ci, enc);
    if (rv)
        return rv;
    *init = true;
    for (int i = 0; i < enc->channel_count; i++) {
        exr_coding_channel_info_t *ch = &enc->channels[i];
        int c = 0;
        while (strcmp(s->names[c], ch->channel_name) != 0)
            c++;
        fill_chunk(s, c, x0, y0, ci->width, ci->height, level, bufs[c]);
        ch->encode_from_ptr = bufs[c];
        ch->user_pixel_stride = 4;
        ch->user_line_stride = 4 * ci->width;
        ch->user_data_type = s->types[c] == EXR_PIXEL_UINT ? EXR_PIXEL_UINT : EXR_PIXEL_FLOAT;
        ch->user_bytes_per_element = 4;
    }
    rv = exr_encoding_choose_default_routines(ctx, 0, enc);
    return rv ? rv : exr_encoding_run(ctx, 0, enc);
}

/* The compression write_test_exr uses. */
static exr_compression_t test_compression = EXR_COMPRESSION_ZIP;

static bool write_test_exr(const char *path, const test_exr_spec *s)
{
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    exr_context_t ctx;
    int part = 0;
    exr_attr_v2f_t center;
    memset(&center, 0, sizeof center);
    exr_result_t rv = exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv)
        return false;
    rv = exr_add_part(ctx, "test", s->storage, &part);
    if (!rv)
        rv = exr_initialize_required_attr(ctx, part, &s->display, &s->data, 1.0f, &center, 1.0f,
                                          EXR_LINEORDER_INCREASING_Y, test_compression);
    for (int c = 0; c < s->nch && !rv; c++)
        rv = exr_add_channel(ctx, part, s->names[c], s->types[c], EXR_PERCEPTUALLY_LOGARITHMIC, 1,
                             1);
    if (!rv && s->storage == EXR_STORAGE_TILED)
        rv = exr_set_tile_descriptor(ctx, part, (uint32_t)s->tile, (uint32_t)s->tile, s->levels,
                                     EXR_TILE_ROUND_DOWN);
    if (!rv)
        rv = exr_write_header(ctx);
    int dw = s->data.max.x - s->data.min.x + 1, dh = s->data.max.y - s->data.min.y + 1;
    void *bufs[8] = {0};
    for (int c = 0; c < s->nch; c++)
        bufs[c] = malloc((size_t)dw * (size_t)dh * 4);
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    bool inited = false;
    exr_chunk_info_t ci;
    if (s->storage == EXR_STORAGE_SCANLINE) {
        int32_t lines = 1;
        if (!rv)
            rv = exr_get_scanlines_per_chunk(ctx, part, &lines);
        for (int y = s->data.min.y; y <= s->data.max.y && !rv; y += lines) {
            rv = exr_write_scanline_chunk_info(ctx, part, y, &ci);
            if (!rv)
                rv = encode_chunk(ctx, s, &ci, s->data.min.x, y, 0, &enc, &inited, bufs);
        }
    } else {
        int32_t nlx = 1, nly = 1;
        if (!rv)
            rv = exr_get_tile_levels(ctx, part, &nlx, &nly);
        for (int l = 0; l < nlx && !rv; l++) {
            int32_t lw = 0, lh = 0;
            rv = exr_get_level_sizes(ctx, part, l, l, &lw, &lh);
            for (int ty = 0; ty * s->tile < lh && !rv; ty++)
                for (int tx = 0; tx * s->tile < lw && !rv; tx++) {
                    rv = exr_write_tile_chunk_info(ctx, part, tx, ty, l, l, &ci);
                    if (!rv)
                        rv = encode_chunk(ctx, s, &ci, s->data.min.x + tx * s->tile,
                                          s->data.min.y + ty * s->tile, l, &enc, &inited, bufs);
                }
        }
    }
    if (inited)
        exr_encoding_destroy(ctx, &enc);
    for (int c = 0; c < s->nch; c++)
        free(bufs[c]);
    exr_result_t frv = exr_finish(&ctx);
    return rv == EXR_ERR_SUCCESS && frv == EXR_ERR_SUCCESS;
}

/* Checks img against known() over the display window of s. */
static void check_known(const sl_image *img, const test_exr_spec *s, const int *channel_of)
{
    int w = s->display.max.x - s->display.min.x + 1, h = s->display.max.y - s->display.min.y + 1;
    CHECK(img->width == w && img->height == h);
    if (img->width != w || img->height != h)
        return;
    int bad = 0;
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            int fx = x + s->display.min.x, fy = y + s->display.min.y;
            bool inside = fx >= s->data.min.x && fx <= s->data.max.x && fy >= s->data.min.y &&
                          fy <= s->data.max.y;
            for (int c = 0; c < img->channels; c++) {
                float want = inside ? known(fx, fy, channel_of[c]) : 0.0f;
                if (sl_image_pixel(img, x, y)[c] != want)
                    bad++;
            }
        }
    CHECK_MSG(bad == 0, "%d samples differ from the written values", bad);
}

/* ------------------------------------------------------------------ */

static void fill_test_values(sl_image *img)
{
    /* Spans half's range: large, tiny, negative, fractional. */
    static const float special[] = {6.0e4f, 1.0e-4f, -3.5f, 0.5f, 65504.0f, 6.2e-5f, 1234.567f};
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++)
            for (int c = 0; c < img->channels; c++) {
                int i = (y * img->width + x) * img->channels + c;
                sl_image_pixel(img, x, y)[c] =
                    i < 7 ? special[i] : (float)(0.001 * (x + 1) * (y + 2) + 0.37 * c);
            }
}

static void test_roundtrip(void)
{
    sl_error err;
    for (int t = 0; t < 2; t++)
        for (int nc = 1; nc <= 4; nc++) {
            sl_pixel_type type = t ? SL_PIXEL_FLOAT : SL_PIXEL_HALF;
            sl_image img, back;
            sl_meta meta, got;
            CHECK_OK(sl_image_alloc(&img, 37, 41, nc, &err), &err);
            fill_test_values(&img);
            sl_meta_init(&meta);
            meta.envmap = SL_ENVMAP_LATLONG;
            /* ACEScg (AP1) primaries: not the default, so they must be written. */
            const float ap1[8] = {0.713f, 0.293f, 0.165f,   0.830f,
                                  0.128f, 0.044f, 0.32168f, 0.33767f};
            memcpy(meta.chromaticities, ap1, sizeof ap1);
            meta.has_chromaticities = true;
            meta.exposure_time = 1.0 / 250;
            meta.f_number = 8;
            meta.iso = 200;
            meta.focal_length_mm = 35;
            strcpy(meta.make, "Canon");
            strcpy(meta.model, "EOS R5");
            strcpy(meta.lens, "RF15-35mm F2.8 L IS USM");
            strcpy(meta.datetime, "2026:11:21 10:30:00");
            CHECK_OK(sl_meta_set(&meta, "setlight:inputs", "a.exr b.exr", &err), &err);
            CHECK_OK(sl_meta_set(&meta, "setlight:version", sl_version(), &err), &err);
            CHECK_OK(sl_meta_set(&meta, "setlight:exposures", "[0.004, 0.016]", &err), &err);
            /* Longer than EXR's classic 31-byte name limit. */
            CHECK_OK(sl_meta_set(&meta, "setlight:calibration_matrix_source", "macbeth.json", &err),
                     &err);
            char name[64];
            snprintf(name, sizeof name, "rt_%s_%d.exr", t ? "float" : "half", nc);
            const char *path = sl_test_path(name);
            CHECK_OK(sl_exr_write(path, &img, &meta, type, &err), &err);
            CHECK_OK(sl_exr_read(path, &back, &got, &err), &err);
            CHECK(back.width == 37 && back.height == 41 && back.channels == nc);
            if (back.data && back.channels == nc) {
                double worst = 0;
                for (int y = 0; y < 41; y++)
                    for (int x = 0; x < 37; x++)
                        for (int c = 0; c < nc; c++) {
                            float a = sl_image_pixel(&img, x, y)[c],
                                  b = sl_image_pixel(&back, x, y)[c];
                            double e = fabs((double)a - b) / fabs((double)a);
                            if (e > worst)
                                worst = e;
                        }
                if (t)
                    CHECK_MSG(worst == 0, "float round trip not exact: rel %g", worst);
                else
                    CHECK_MSG(worst <= HALF_REL, "half round trip rel error %g", worst);
                CHECK_NEAR(back.data[0], 6.0e4f, t ? 0 : 6.0e4 * HALF_REL);
                if (nc >= 2)
                    CHECK_NEAR(back.data[1], 1.0e-4f, t ? 0 : 1.0e-4 * HALF_REL);
            }
            CHECK(strcmp(got.format, "openexr") == 0);
            CHECK(got.bits_per_sample == (t ? 32 : 16) && got.is_float);
            CHECK(got.envmap == SL_ENVMAP_LATLONG);
            CHECK(got.has_chromaticities && memcmp(got.chromaticities, ap1, sizeof ap1) == 0);
            CHECK_NEAR(got.exposure_time, 1.0 / 250, 1e-9);
            CHECK(got.f_number == 8 && got.iso == 200 && got.focal_length_mm == 35);
            CHECK(strcmp(got.make, "Canon") == 0 && strcmp(got.model, "EOS R5") == 0);
            CHECK(strcmp(got.lens, meta.lens) == 0 && strcmp(got.datetime, meta.datetime) == 0);
            const char *v = sl_meta_get(&got, "setlight:inputs");
            CHECK(v && strcmp(v, "a.exr b.exr") == 0);
            v = sl_meta_get(&got, "setlight:exposures");
            CHECK(v && strcmp(v, "[0.004, 0.016]") == 0);
            v = sl_meta_get(&got, "setlight:calibration_matrix_source");
            CHECK(v && strcmp(v, "macbeth.json") == 0);
            v = sl_meta_get(&got, "setlight:version");
            CHECK(v && strcmp(v, sl_version()) == 0);
            sl_image_free(&img);
            sl_image_free(&back);
            sl_meta_free(&meta);
            sl_meta_free(&got);
        }
}

/* Half rounding: every float written as half must come back as the half
 * nearest to it, ties to even (OpenEXR's rule), whichever conversion the
 * writer picked (the processor's F16C or the portable one): normal and
 * subnormal halves, values exactly halfway between two halves, either sign,
 * through RGB rows whose width is not a multiple of four. */
static double nearest_half(double v)
{
    double a = fabs(v);
    if (a >= 65504.0)
        return v < 0 ? -65504.0 : 65504.0;
    int e;
    frexp(a, &e); /* a = m 2^e, 0.5 <= m < 1 */
    double step = ldexp(1.0, (e - 1 < -14 ? -14 : e - 1) - 10);
    double q = nearbyint(a / step) * step; /* default rounding: to even */
    return v < 0 ? -q : q;
}

static void test_half_rounding(void)
{
    sl_error err;
    sl_image img, back;
    const int w = 1023, h = 96; /* w % 4 == 3 */
    CHECK_OK(sl_image_alloc(&img, w, h, 3, &err), &err);
    size_t n = (size_t)w * h * 3;
    uint32_t state = 12345u;
    for (size_t i = 0; i < n; i++) {
        state = state * 1664525u + 1013904223u;
        double mag = ldexp(1.0, (int)(state >> 27) - 26); /* 2^-26 .. 2^5 */
        double frac = (double)((state >> 8) & 0x7ffff) / 0x80000;
        double v = mag * (1.0 + frac);
        if (i % 3 == 1) { /* a tie: halfway between two halves */
            double lo = nearest_half(v), step = fabs(nearest_half(v * (1 + 1e-3)) - lo);
            v = lo + 0.5 * (step > 0 ? step : ldexp(1.0, -24));
        }
        img.data[i] = (float)((state & 1) ? -v : v);
    }
    img.data[0] = 65519.0f; /* rounds to 65504 */
    img.data[1] = 3.0e-8f;  /* under half the smallest subnormal: 0 */
    const char *path = sl_test_path("half_rounding.exr");
    CHECK_OK(sl_exr_write(path, &img, NULL, SL_PIXEL_HALF, &err), &err);
    CHECK_OK(sl_exr_read(path, &back, NULL, &err), &err);
    size_t wrong = 0, ties = 0;
    if (back.data)
        for (size_t i = 0; i < n; i++) {
            double want = nearest_half(img.data[i]);
            wrong += back.data[i] != (float)want;
            ties += i % 3 == 1;
        }
    printf("    half rounding: %zu of %zu samples (%zu ties) not the nearest half\n", wrong, n,
           ties);
    CHECK(back.data && wrong == 0);
    sl_image_free(&back);
    sl_image_free(&img);
}

/* Out-of-range and non-finite values: half clamps to +-65504, NaN becomes 0. */
static void test_write_clamps(void)
{
    sl_error err;
    sl_image img, back;
    sl_meta got;
    CHECK_OK(sl_image_alloc(&img, 4, 1, 1, &err), &err);
    img.data[0] = 1.0e6f;
    img.data[1] = -INFINITY;
    img.data[2] = NAN;
    img.data[3] = INFINITY;
    const char *path = sl_test_path("clamp.exr");
    CHECK_OK(sl_exr_write(path, &img, NULL, SL_PIXEL_HALF, &err), &err);
    CHECK_OK(sl_exr_read(path, &back, &got, &err), &err);
    if (back.data) {
        CHECK(back.data[0] == 65504.0f && back.data[1] == -65504.0f);
        CHECK(back.data[2] == 0.0f && back.data[3] == 65504.0f);
    }
    /* No meta given: Rec.709 chromaticities, no envmap. */
    CHECK(got.has_chromaticities && fabsf(got.chromaticities[0] - 0.64f) < 1e-6f &&
          fabsf(got.chromaticities[7] - 0.329f) < 1e-6f);
    CHECK(got.envmap == SL_ENVMAP_NONE);
    sl_image_free(&back);
    sl_meta_free(&got);
    CHECK_OK(sl_exr_write(path, &img, NULL, SL_PIXEL_FLOAT, &err), &err);
    CHECK_OK(sl_exr_read(path, &back, NULL, &err), &err);
    if (back.data)
        CHECK(back.data[0] == 1.0e6f && back.data[1] == -FLT_MAX && back.data[2] == 0.0f &&
              back.data[3] == FLT_MAX);
    sl_image_free(&back);
    sl_image_free(&img);
}

static void test_windows_tiles_types(void)
{
    sl_error err;
    sl_image img;
    sl_meta meta;
    static const int rgb_order[4] = {0, 1, 2, 3};

    /* Scanline, data window inside an offset display window. */
    test_exr_spec s = {EXR_STORAGE_SCANLINE,
                       EXR_TILE_ONE_LEVEL,
                       0,
                       box(-4, 10, 45, 39),
                       box(3, 14, 30, 35),
                       3,
                       {"R", "G", "B"},
                       {EXR_PIXEL_HALF, EXR_PIXEL_HALF, EXR_PIXEL_HALF}};
    const char *path = sl_test_path("window.exr");
    CHECK(write_test_exr(path, &s));
    CHECK_OK(sl_exr_read(path, &img, &meta, &err), &err);
    check_known(&img, &s, rgb_order);
    CHECK(meta.bits_per_sample == 16);
    sl_image_free(&img);
    sl_meta_free(&meta);

    /* Data window bigger than the display window: overscan is cropped. */
    s.display = box(10, 20, 29, 29);
    s.data = box(0, 0, 49, 59);
    path = sl_test_path("overscan.exr");
    CHECK(write_test_exr(path, &s));
    CHECK_OK(sl_exr_read(path, &img, NULL, &err), &err);
    check_known(&img, &s, rgb_order);
    sl_image_free(&img);

    /* Tiled, 16x16 tiles not dividing the size, RGBA float, offset data window. */
    test_exr_spec t = {EXR_STORAGE_TILED,
                       EXR_TILE_ONE_LEVEL,
                       16,
                       box(5, 7, 57, 43),
                       box(5, 7, 57, 43),
                       4,
                       {"A", "B", "G", "R"},
                       {EXR_PIXEL_FLOAT, EXR_PIXEL_FLOAT, EXR_PIXEL_FLOAT, EXR_PIXEL_FLOAT}};
    static const int abgr[4] = {3, 2, 1, 0}; /* output R,G,B,A from names A,B,G,R */
    path = sl_test_path("tiled.exr");
    CHECK(write_test_exr(path, &t));
    CHECK_OK(sl_exr_read(path, &img, &meta, &err), &err);
    CHECK(img.channels == 4);
    check_known(&img, &t, abgr);
    CHECK(meta.bits_per_sample == 32 && meta.is_float);
    sl_image_free(&img);
    sl_meta_free(&meta);

    /* Mipmapped tiles: only level 0 is read (other levels hold 1000+). */
    t.levels = EXR_TILE_MIPMAP_LEVELS;
    t.display = t.data = box(0, 0, 63, 31);
    path = sl_test_path("mipmap.exr");
    CHECK(write_test_exr(path, &t));
    CHECK_OK(sl_exr_read(path, &img, NULL, &err), &err);
    check_known(&img, &t, abgr);
    sl_image_free(&img);

    /* uint channels come back as their integer values. */
    test_exr_spec u = {EXR_STORAGE_SCANLINE,
                       EXR_TILE_ONE_LEVEL,
                       0,
                       box(0, 0, 20, 18),
                       box(0, 0, 20, 18),
                       3,
                       {"R", "G", "B"},
                       {EXR_PIXEL_UINT, EXR_PIXEL_UINT, EXR_PIXEL_UINT}};
    path = sl_test_path("uint.exr");
    CHECK(write_test_exr(path, &u));
    CHECK_OK(sl_exr_read(path, &img, &meta, &err), &err);
    check_known(&img, &u, rgb_order);
    CHECK(!meta.is_float && meta.bits_per_sample == 32);
    sl_image_free(&img);
    sl_meta_free(&meta);

    /* Luminance only: one channel; Y + A: two. */
    test_exr_spec y = {
        EXR_STORAGE_SCANLINE, EXR_TILE_ONE_LEVEL, 0, box(0, 0, 15, 9), box(0, 0, 15, 9), 1, {"Y"},
        {EXR_PIXEL_HALF}};
    path = sl_test_path("y.exr");
    CHECK(write_test_exr(path, &y));
    CHECK_OK(sl_exr_read(path, &img, NULL, &err), &err);
    CHECK(img.channels == 1);
    check_known(&img, &y, rgb_order);
    sl_image_free(&img);
    y.nch = 2;
    y.names[1] = "A";
    y.types[1] = EXR_PIXEL_HALF;
    path = sl_test_path("ya.exr");
    CHECK(write_test_exr(path, &y));
    CHECK_OK(sl_exr_read(path, &img, NULL, &err), &err);
    CHECK(img.channels == 2);
    check_known(&img, &y, rgb_order);
    sl_image_free(&img);

    /* No plain RGB: the first layer (sorted) with R,G,B wins; Z is ignored. */
    test_exr_spec l = {EXR_STORAGE_SCANLINE,
                       EXR_TILE_ONE_LEVEL,
                       0,
                       box(0, 0, 11, 7),
                       box(0, 0, 11, 7),
                       7,
                       {"spec.R", "spec.G", "spec.B", "diffuse.B", "diffuse.G", "diffuse.R", "Z"},
                       {EXR_PIXEL_HALF, EXR_PIXEL_HALF, EXR_PIXEL_HALF, EXR_PIXEL_FLOAT,
                        EXR_PIXEL_FLOAT, EXR_PIXEL_FLOAT, EXR_PIXEL_FLOAT}};
    static const int diffuse[3] = {5, 4, 3};
    path = sl_test_path("layers.exr");
    CHECK(write_test_exr(path, &l));
    CHECK_OK(sl_exr_read(path, &img, &meta, &err), &err);
    CHECK(img.channels == 3);
    check_known(&img, &l, diffuse);
    CHECK(meta.bits_per_sample == 32);
    sl_image_free(&img);
    sl_meta_free(&meta);
    /* Through OIIO the same 7-channel file keeps its first four channels. */
    CHECK_OK(sl_photo_read(path, &img, NULL, &err), &err);
    CHECK(img.channels == 4 && img.width == 12);
    sl_image_free(&img);

    /* Luminance/chroma with full-resolution chroma (not what OpenEXR's RGBA
     * interface writes, nor can read): refused rather than read as grey.
     * The 2 x 2 files are read as colour (test_exr_layouts). */
    test_exr_spec yc = {EXR_STORAGE_SCANLINE,
                        EXR_TILE_ONE_LEVEL,
                        0,
                        box(0, 0, 7, 7),
                        box(0, 0, 7, 7),
                        3,
                        {"Y", "RY", "BY"},
                        {EXR_PIXEL_HALF, EXR_PIXEL_HALF, EXR_PIXEL_HALF}};
    path = sl_test_path("yc.exr");
    CHECK(write_test_exr(path, &yc));
    CHECK_RESULT(sl_exr_read(path, &img, NULL, &err), SL_ERR_INPUT, &err);
    CHECK(message_names(&err, path) && strstr(err.message, "sampled 2 x 2") && img.data == NULL);

    /* Only Z: nothing to read as colour. */
    test_exr_spec z = {
        EXR_STORAGE_SCANLINE, EXR_TILE_ONE_LEVEL, 0, box(0, 0, 3, 3), box(0, 0, 3, 3), 1, {"Z"},
        {EXR_PIXEL_FLOAT}};
    path = sl_test_path("zonly.exr");
    CHECK(write_test_exr(path, &z));
    CHECK_RESULT(sl_exr_read(path, &img, &meta, &err), SL_ERR_INPUT, &err);
    CHECK(message_names(&err, path) && img.data == NULL && meta.attrs == NULL);
}

/* Scanline ZIP, ZIPS and uncompressed files are decoded by core itself
 * (libdeflate): mixed half/float channels with unpicked ones between them
 * (a uint among them), offset windows; RLE goes through OpenEXR's pipeline
 * for comparison. Then every finite half value through both decoders. */
static void test_own_decoder(void)
{
    sl_error err;
    sl_image img;
    static const int rgb_order[4] = {0, 1, 2, 3};
    static const exr_compression_t comps[] = {EXR_COMPRESSION_NONE, EXR_COMPRESSION_ZIP,
                                             EXR_COMPRESSION_ZIPS, EXR_COMPRESSION_RLE};
    test_exr_spec s = {EXR_STORAGE_SCANLINE,
                       EXR_TILE_ONE_LEVEL,
                       0,
                       box(-3, 2, 70, 41),
                       box(1, -5, 66, 44),
                       5,
                       {"R", "G", "B", "N", "Z"},
                       {EXR_PIXEL_HALF, EXR_PIXEL_FLOAT, EXR_PIXEL_HALF, EXR_PIXEL_FLOAT,
                        EXR_PIXEL_UINT}};
    for (size_t i = 0; i < sizeof comps / sizeof comps[0]; i++) {
        test_compression = comps[i];
        const char *path = sl_test_path("own_decoder.exr");
        CHECK(write_test_exr(path, &s));
        CHECK_OK(sl_exr_read(path, &img, NULL, &err), &err);
        CHECK(img.channels == 3);
        check_known(&img, &s, rgb_order);
        sl_image_free(&img);
    }
    test_compression = EXR_COMPRESSION_ZIP;

    /* All 63488 finite halves, as exact floats from their definition. */
    sl_image all;
    CHECK_OK(sl_image_alloc(&all, 256, 248, 1, &err), &err);
    int n = 0;
    for (int h = 0; h < 65536 && all.data; h++) {
        int e = (h >> 10) & 31, m = h & 1023;
        if (e == 31)
            continue;
        double v = e ? ldexp(1024 + m, e - 25) : ldexp(m, -24);
        all.data[n++] = (float)(h & 0x8000 ? -v : v);
    }
    CHECK(n == 256 * 248);
    static const sl_exr_compression write_with[2] = {SL_EXR_ZIP, SL_EXR_PIZ};
    for (int k = 0; k < 2 && all.data; k++) {
        const char *path = sl_test_path("all_halves.exr");
        CHECK_OK(sl_exr_write_compressed(path, &all, NULL, SL_PIXEL_HALF, write_with[k], &err),
                 &err);
        CHECK_OK(sl_exr_read(path, &img, NULL, &err), &err);
        int bad = 0;
        for (int i = 0; img.data && i < n; i++)
            bad += memcmp(&img.data[i], &all.data[i], sizeof(float)) != 0;
        CHECK_MSG(img.data && bad == 0, "%s: %d of %d halves differ", k ? "PIZ" : "ZIP", bad, n);
        sl_image_free(&img);
    }
    sl_image_free(&all);
}

/* A scanline file's channels (names in sl_image order) decoded by
 * OpenEXR's own pipeline, not core's decoder, as interleaved floats. */
static bool openexr_decode(const char *path, int w, int h, int nc, const char *const *names,
                           float *out)
{
    exr_context_t ctx;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    if (exr_start_read(&ctx, path, &init) != EXR_ERR_SUCCESS)
        return false;
    int32_t lines = 1;
    exr_result_t rv = exr_get_scanlines_per_chunk(ctx, 0, &lines);
    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    bool inited = false;
    for (int y = 0; y < h && rv == EXR_ERR_SUCCESS; y += lines) {
        exr_chunk_info_t ci;
        rv = exr_read_scanline_chunk_info(ctx, 0, y, &ci);
        if (rv == EXR_ERR_SUCCESS)
            rv = inited ? exr_decoding_update(ctx, 0, &ci, &dec)
                        : exr_decoding_initialize(ctx, 0, &ci, &dec);
        if (rv != EXR_ERR_SUCCESS)
            break;
        inited = true;
        for (int i = 0; i < dec.channel_count && rv == EXR_ERR_SUCCESS; i++) {
            exr_coding_channel_info_t *ch = &dec.channels[i];
            int c = 0;
            while (c < nc && strcmp(names[c], ch->channel_name) != 0)
                c++;
            if (c == nc) {
                rv = EXR_ERR_INVALID_ARGUMENT;
                break;
            }
            ch->decode_to_ptr = (uint8_t *)(out + (size_t)y * (size_t)w * (size_t)nc + c);
            ch->user_pixel_stride = nc * 4;
            ch->user_line_stride = w * nc * 4;
            ch->user_data_type = EXR_PIXEL_FLOAT;
            ch->user_bytes_per_element = 4;
        }
        if (rv == EXR_ERR_SUCCESS)
            rv = exr_decoding_choose_default_routines(ctx, 0, &dec);
        if (rv == EXR_ERR_SUCCESS)
            rv = exr_decoding_run(ctx, 0, &dec);
    }
    if (inited)
        exr_decoding_destroy(ctx, &dec);
    exr_finish(&ctx);
    return rv == EXR_ERR_SUCCESS;
}

/* A finite half from a random number, as the float it is exactly. */
static float random_half(uint32_t r)
{
    int e = (int)(r >> 10 & 31) % 31, m = (int)(r & 1023);
    double v = e ? ldexp(1024 + m, e - 25) : ldexp(m, -24);
    return (float)(r & 0x8000 ? -v : v);
}

/* Files core writes with its own ZIP encoder (exr_zip.c) decode to the
 * same halves and floats through OpenEXR's library and core's decoder:
 * zero rows and columns (runs, the reused all-zero chunk), smooth ramps
 * (runs of one difference), noise (literals; float noise does not
 * compress, so those chunks are stored), a partial last chunk, odd widths
 * and several Huffman blocks per chunk; 4096 wide, two blocks a half with
 * enough noise literals for the pair codes (tests/test_exr_zip.c covers
 * the encoder's paths one by one). */
static void test_own_zip_encoder(void)
{
    static const char *names[4][4] = {{"Y"}, {"Y", "A"}, {"R", "G", "B"}, {"R", "G", "B", "A"}};
    static const struct {
        int w, h, nc;
        sl_pixel_type type;
        bool noise; /* noise only, but for the zero rows */
    } cases[] = {{1031, 37, 3, SL_PIXEL_HALF, false}, {67, 21, 4, SL_PIXEL_FLOAT, true},
                 {2051, 17, 1, SL_PIXEL_HALF, false}, {9, 40, 2, SL_PIXEL_HALF, false},
                 {515, 33, 3, SL_PIXEL_FLOAT, false}, {4096, 17, 3, SL_PIXEL_HALF, false}};
    sl_error err;
    uint32_t seed = 12345;
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        int w = cases[k].w, h = cases[k].h, nc = cases[k].nc;
        bool half = cases[k].type == SL_PIXEL_HALF;
        sl_image img, back;
        CHECK_OK(sl_image_alloc(&img, w, h, nc, &err), &err);
        for (int y = 0; img.data && y < h; y++)
            for (int x = 0; x < w; x++)
                for (int c = 0; c < nc; c++) {
                    seed = seed * 1664525u + 1013904223u;
                    float v = 0.0f;
                    if (y >= 16 && y < 32)
                        v = 0.0f;
                    else if (x < w / 3 && !cases[k].noise)
                        v = x < w / 6 ? 0.0f : 1.0f + c;
                    else if (x < 2 * w / 3 && !cases[k].noise)
                        v = (float)((x + 3 * y + c) % 2048) * 0.25f; /* exact in half */
                    else if (half)
                        v = random_half(seed >> 8);
                    else {
                        uint32_t bits = seed & 0xbfffffffu; /* exponent below 255: finite */
                        memcpy(&v, &bits, sizeof v);
                    }
                    sl_image_pixel(&img, x, y)[c] = v;
                }
        const char *path = sl_test_path("own_zip.exr");
        CHECK_OK(sl_exr_write_compressed(path, &img, NULL, cases[k].type, SL_EXR_ZIP, &err),
                 &err);
        float *dec = calloc((size_t)w * (size_t)h * (size_t)nc, sizeof(float));
        CHECK(dec && openexr_decode(path, w, h, nc, names[nc - 1], dec));
        CHECK_OK(sl_exr_read(path, &back, NULL, &err), &err);
        size_t n = (size_t)w * (size_t)h * (size_t)nc, bad_lib = 0, bad_own = 0;
        for (size_t i = 0; dec && back.data && img.data && i < n; i++) {
            bad_lib += memcmp(&dec[i], &img.data[i], sizeof(float)) != 0;
            bad_own += memcmp(&back.data[i], &img.data[i], sizeof(float)) != 0;
        }
        CHECK_MSG(bad_lib == 0 && bad_own == 0,
                  "%dx%dx%d %s: %zu (OpenEXR) and %zu (core) of %zu samples differ", w, h, nc,
                  half ? "half" : "float", bad_lib, bad_own, n);
        /* The zero and ramp thirds compress: the file is well under raw
         * size (small ones are mostly header). */
        struct stat st;
        size_t raw = n * (half ? 2 : 4);
        CHECK(stat(path, &st) == 0);
        CHECK_MSG(raw < 65536 || (size_t)st.st_size < raw * 3 / 4, "%zu bytes for %zu raw",
                  (size_t)st.st_size, raw);
        free(dec);
        sl_image_free(&back);
        sl_image_free(&img);
    }
}

/* Every EXR in the shared data reads and matches OpenImageIO's reading. */
static void check_against_oiio(const char *path)
{
    sl_error err;
    sl_image a, b;
    sl_meta meta;
    CHECK_OK(sl_exr_read(path, &a, &meta, &err), &err);
    CHECK_OK(sl_photo_read(path, &b, NULL, &err), &err);
    CHECK(strcmp(meta.format, "openexr") == 0);
    if (a.data && b.data) {
        CHECK_MSG(a.width == b.width && a.height == b.height && a.channels == b.channels,
                  "%s: %dx%dx%d vs OIIO %dx%dx%d", path, a.width, a.height, a.channels, b.width,
                  b.height, b.channels);
        if (a.width == b.width && a.height == b.height && a.channels == b.channels) {
            size_t n = (size_t)a.height * a.stride, bad = 0;
            for (size_t i = 0; i < n; i++)
                if (!(fabs((double)a.data[i] - b.data[i]) <= fabs((double)b.data[i]) * HALF_REL))
                    bad++;
            CHECK_MSG(bad == 0, "%s: %zu samples differ from OIIO", path, bad);
            printf("  %s: %dx%dx%d, %d-bit, matches OIIO\n", path, a.width, a.height, a.channels,
                   meta.bits_per_sample);
        }
    }
    sl_image_free(&a);
    sl_image_free(&b);
    sl_meta_free(&meta);
}

static void check_folder(const char *relative)
{
    const char *dir = sl_test_data(relative);
    if (!dir)
        return;
    DIR *d = opendir(dir);
    CHECK(d != NULL);
    if (!d)
        return;
    char saved[4096];
    snprintf(saved, sizeof saved, "%s", dir);
    struct dirent *e;
    int count = 0;
    while ((e = readdir(d))) {
        size_t len = strlen(e->d_name);
        if (len > 4 && strcmp(e->d_name + len - 4, ".exr") == 0) {
            char path[8192];
            snprintf(path, sizeof path, "%s/%s", saved, e->d_name);
            check_against_oiio(path);
            count++;
        }
    }
    closedir(d);
    CHECK(count > 0);
}

static void test_real_files(void)
{
    check_folder("hdri/exr_variants");
    check_folder("hdri/blender_studiolights");                             /* DWAB, B,G,R float */
    check_folder("hdri/synthetic");                                        /* ZIPS half */
    const char *memorial = sl_test_data("brackets/memorial/memorial.exr"); /* PIZ half */
    if (memorial)
        check_against_oiio(memorial);
}

/* ------------------------------------------------------------------ */
/* Bad input                                                           */
/* ------------------------------------------------------------------ */

static bool copy_prefix(const char *src, const char *dst, long length)
{
    FILE *in = fopen(src, "rb"), *out = fopen(dst, "wb");
    bool ok = in && out;
    for (long i = 0; ok && i < length; i++) {
        int ch = fgetc(in);
        ok = ch != EOF && fputc(ch, out) != EOF;
    }
    if (in)
        fclose(in);
    if (out && fclose(out))
        ok = false;
    return ok;
}

static long file_size(const char *path)
{
    struct stat st;
    return stat(path, &st) == 0 ? (long)st.st_size : -1;
}

static void expect_bad(const char *path, sl_result code, const char *fragment)
{
    sl_error err;
    sl_image img;
    sl_meta meta;
    CHECK_RESULT(sl_exr_read(path, &img, &meta, &err), code, &err);
    CHECK_MSG(message_names(&err, path), "message does not name the file: %s", err.message);
    CHECK_MSG(!fragment || strstr(err.message, fragment), "message lacks \"%s\": %s", fragment,
              err.message);
    bool one_line = true;
    for (const char *p = err.message; *p; p++)
        one_line = one_line && (unsigned char)*p >= 0x20 && (unsigned char)*p < 0x7f;
    CHECK_MSG(one_line, "message is not one printable line: %s", err.message);
    CHECK(img.data == NULL && meta.attrs == NULL);
    sl_image_free(&img);
    sl_meta_free(&meta);
}

/* The own ZIP / uncompressed decoder on damaged files: four bytes
 * overwritten anywhere (header, chunk table, chunk sizes, data) in ZIP and
 * uncompressed files, 120 seeded mutations each. Every read either succeeds or fails with
 * SL_ERR_INPUT naming the file, nothing else (the sanitizer run checks
 * that nothing is read or written out of bounds). */
static void test_damaged_chunks(void)
{
    sl_error err;
    sl_image img;
    CHECK_OK(sl_image_alloc(&img, 48, 80, 3, &err), &err);
    for (size_t i = 0; i < (size_t)48 * 80 * 3; i++)
        img.data[i] = (float)((i * 37) % 101) / 50.0f;
    const sl_exr_compression comps[] = {SL_EXR_ZIP, SL_EXR_NONE};
    uint32_t state = 777;
    for (int c = 0; c < 2; c++) {
        const char *good = sl_test_path(c ? "none.exr" : "zip.exr");
        CHECK_OK(sl_exr_write_compressed(good, &img, NULL, c ? SL_PIXEL_FLOAT : SL_PIXEL_HALF,
                                         comps[c], &err),
                 &err);
        FILE *f = fopen(good, "rb");
        unsigned char buf[65536];
        size_t n = f ? fread(buf, 1, sizeof buf, f) : 0;
        if (f)
            fclose(f);
        CHECK(n > 400 && n < sizeof buf);
        size_t from = 0;
        int ok = 0, bad = 0;
        for (int k = 0; k < 120; k++) {
            unsigned char m[65536];
            memcpy(m, buf, n);
            for (int j = 0; j < 4; j++) {
                state = state * 1664525u + 1013904223u;
                size_t at = from + (state >> 8) % (n - from);
                state = state * 1664525u + 1013904223u;
                m[at] = (unsigned char)(state >> 24);
            }
            const char *path = sl_test_path("damaged.exr");
            CHECK_OK(sl_write_file_atomic(path, m, n, &err), &err);
            sl_image out;
            sl_result r = sl_exr_read(path, &out, NULL, &err);
            if (r == SL_OK) {
                ok++;
                sl_image_free(&out);
            } else {
                bad++;
                CHECK_MSG(r == SL_ERR_INPUT && message_names(&err, path), "result %d: %s", r,
                          err.message);
            }
        }
        printf("damaged %s chunks: %d read, %d refused\n", c ? "uncompressed" : "ZIP", ok, bad);
        CHECK(bad > 0);
    }
    sl_image_free(&img);
}

static void test_bad_input(void)
{
    sl_error err;
    /* A noisy float image compresses badly, so it spans many sizeable chunks. */
    sl_image img;
    CHECK_OK(sl_image_alloc(&img, 64, 96, 3, &err), &err);
    uint32_t state = 12345;
    for (size_t i = 0; i < (size_t)64 * 96 * 3; i++) {
        state = state * 1664525u + 1013904223u;
        img.data[i] = (float)(state >> 8) / 16777216.0f;
    }
    const char *good = sl_test_path("good.exr");
    CHECK_OK(sl_exr_write(good, &img, NULL, SL_PIXEL_FLOAT, &err), &err);
    sl_image_free(&img);
    long size = file_size(good);
    CHECK(size > 64 * 96 * 3 * 3);
    /* Magic only, part of the header, half the chunks, all but the last bytes. */
    long cuts[] = {4, 8, 200, size / 2, size - 16, size - 1};
    for (size_t i = 0; i < sizeof cuts / sizeof cuts[0]; i++) {
        char name[64];
        snprintf(name, sizeof name, "cut_%ld.exr", cuts[i]);
        const char *cut = sl_test_path(name);
        CHECK(copy_prefix(good, cut, cuts[i]));
        expect_bad(cut, SL_ERR_INPUT, "truncated or corrupt EXR");
    }

    const char *missing = sl_test_path("missing.exr");
    expect_bad(missing, SL_ERR_NOT_FOUND, NULL);
    expect_bad(sl_test_tmpdir(), SL_ERR_NOT_FOUND, NULL);
    const char *empty = sl_test_path("empty.exr");
    CHECK_OK(sl_write_file_atomic(empty, "", 0, &err), &err);
    expect_bad(empty, SL_ERR_INPUT, NULL);

    unsigned char noise[4096];
    for (size_t i = 0; i < sizeof noise; i++) {
        state = state * 1664525u + 1013904223u;
        noise[i] = (unsigned char)(state >> 24);
    }
    const char *random = sl_test_path("random.exr");
    CHECK_OK(sl_write_file_atomic(random, noise, sizeof noise, &err), &err);
    expect_bad(random, SL_ERR_INPUT, NULL);
    /* The EXR magic followed by noise. */
    noise[0] = 0x76, noise[1] = 0x2f, noise[2] = 0x31, noise[3] = 0x01, noise[4] = 2;
    noise[5] = noise[6] = noise[7] = 0;
    const char *fake = sl_test_path("magic_noise.exr");
    CHECK_OK(sl_write_file_atomic(fake, noise, sizeof noise, &err), &err);
    expect_bad(fake, SL_ERR_INPUT, "truncated or corrupt EXR");
    sl_image out;
    CHECK_RESULT(sl_image_read(fake, &out, NULL, &err), SL_ERR_INPUT, &err);
    CHECK(message_names(&err, fake));
    CHECK_RESULT(sl_image_read(random, &out, NULL, &err), SL_ERR_INPUT, &err);
    CHECK(message_names(&err, random) && strstr(err.message, "not an image file"));
}

/* Failed writes leave nothing behind, and the message names the output. */
static void test_write_failures(void)
{
    sl_error err;
    sl_image img;
    CHECK_OK(sl_image_alloc(&img, 8, 4, 3, &err), &err);
    sl_image_fill(&img, 0.25f);
    const char *dir = sl_test_path("writes");
    mkdir(dir, 0755);
    char path[4200];
    snprintf(path, sizeof path, "%s/no/such/folder/out.exr", dir);
    sl_result r = sl_exr_write(path, &img, NULL, SL_PIXEL_HALF, &err);
    CHECK(r == SL_ERR_USAGE || r == SL_ERR_IO);
    CHECK(message_names(&err, path));
    /* A regular file used as a folder. */
    char file[4200];
    snprintf(file, sizeof file, "%s/plain", dir);
    CHECK_OK(sl_write_file_atomic(file, "x", 1, &err), &err);
    snprintf(path, sizeof path, "%s/plain/out.exr", dir);
    r = sl_exr_write(path, &img, NULL, SL_PIXEL_FLOAT, &err);
    CHECK(r == SL_ERR_USAGE || r == SL_ERR_IO);
    CHECK(message_names(&err, path));
    /* Writing over a directory. */
    snprintf(path, sizeof path, "%s/adir.exr", dir);
    mkdir(path, 0755);
    CHECK_RESULT(sl_exr_write(path, &img, NULL, SL_PIXEL_HALF, &err), SL_ERR_USAGE, &err);
    /* Unknown extension through sl_image_write. */
    snprintf(path, sizeof path, "%s/out.xyz", dir);
    CHECK_RESULT(sl_image_write(path, &img, NULL, SL_PIXEL_HALF, &err), SL_ERR_USAGE, &err);
    CHECK(message_names(&err, path));
    /* Only "plain" and "adir.exr" remain: no temp files. */
    CHECK_MSG(sl_test_count_files(dir) == 2, "%d entries in %s", sl_test_count_files(dir), dir);
    /* An attribute clashing with a required one of another type. */
    sl_meta bad;
    sl_meta_init(&bad);
    CHECK_OK(sl_meta_set(&bad, "compression", "zip", &err), &err);
    snprintf(path, sizeof path, "%s/clash.exr", dir);
    CHECK_RESULT(sl_exr_write(path, &img, &bad, SL_PIXEL_HALF, &err), SL_ERR_USAGE, &err);
    CHECK(message_names(&err, path) && !sl_test_file_exists(path));
    sl_meta_free(&bad);
    CHECK_MSG(sl_test_count_files(dir) == 2, "%d entries in %s", sl_test_count_files(dir), dir);
    /* An image with no pixels is refused before anything is created. */
    sl_image none = {0};
    snprintf(path, sizeof path, "%s/none.exr", dir);
    CHECK_RESULT(sl_exr_write(path, &none, NULL, SL_PIXEL_HALF, &err), SL_ERR_USAGE, &err);
    CHECK(!sl_test_file_exists(path));
    sl_image_free(&img);
}

int main(void)
{
    RUN(test_roundtrip);
    RUN(test_write_clamps);
    RUN(test_half_rounding);
    RUN(test_windows_tiles_types);
    RUN(test_own_decoder);
    RUN(test_own_zip_encoder);
    RUN(test_real_files);
    RUN(test_bad_input);
    RUN(test_damaged_chunks);
    RUN(test_write_failures);
    return sl_test_finish();
}
