/* SPDX-License-Identifier: BSD-3-Clause */
/* Photo I/O through OpenImageIO and the content-sniffing dispatch:
 * pixel round trips per format and depth, EXIF written and read back,
 * real camera JPEGs against the exposure table in SOURCES.md, Radiance
 * .hdr files, and bad input. */
#include <dirent.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "testing.h"

static bool names(const sl_error *err, const char *path)
{
    return strstr(err->message, path) != NULL;
}

/* A smooth ramp in [0, 1] per channel (smooth so JPEG's error stays small),
 * with an alpha that reaches 0 (so nothing may divide by it). */
static void fill_ramp(sl_image *img)
{
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++)
            for (int c = 0; c < img->channels; c++)
                sl_image_pixel(img, x, y)[c] =
                    (float)(x + y + 5 * c) / (float)(img->width + img->height + 13);
    if (img->channels == 4)
        sl_image_pixel(img, 0, 0)[3] = 0.0f;
}

static double max_diff(const sl_image *a, const sl_image *b)
{
    double worst = 0;
    for (int y = 0; y < a->height; y++)
        for (int x = 0; x < a->width; x++)
            for (int c = 0; c < a->channels; c++) {
                double d = fabs((double)sl_image_pixel(a, x, y)[c] - sl_image_pixel(b, x, y)[c]);
                if (!(d <= worst))
                    worst = d;
            }
    return worst;
}

/* Writes and reads back: integer formats are exact to half a code value. */
static void roundtrip(const char *name, int channels, int bits, double tol, const char *format)
{
    sl_error err;
    sl_image img, back;
    sl_meta meta;
    CHECK_OK(sl_image_alloc(&img, 48, 32, channels, &err), &err);
    fill_ramp(&img);
    const char *path = sl_test_path(name);
    CHECK_OK(sl_photo_write(path, &img, NULL, bits, &err), &err);
    CHECK_OK(sl_image_read(path, &back, &meta, &err), &err);
    CHECK_MSG(back.width == 48 && back.height == 32 && back.channels == channels, "%s: %dx%dx%d",
              name, back.width, back.height, back.channels);
    if (back.data && back.channels == channels) {
        double d = max_diff(&img, &back);
        CHECK_MSG(d <= tol, "%s: max difference %g > %g", name, d, tol);
        printf("  %s: %d-bit, max difference %.3g (bound %.3g)\n", name, bits, d, tol);
    }
    CHECK_MSG(strcmp(meta.format, format) == 0, "%s: format %s", name, meta.format);
    CHECK_MSG(meta.bits_per_sample == bits, "%s: bits %d", name, meta.bits_per_sample);
    CHECK(meta.is_float == (bits == 32));
    sl_image_free(&img);
    sl_image_free(&back);
    sl_meta_free(&meta);
}

static void test_pixel_roundtrips(void)
{
    roundtrip("rgb8.png", 3, 8, 0.5 / 255 + 1e-6, "png");
    roundtrip("rgba16.png", 4, 16, 0.5 / 65535 + 1e-7, "png");
    roundtrip("gray16.png", 1, 16, 0.5 / 65535 + 1e-7, "png");
    roundtrip("rgb16.tif", 3, 16, 0.5 / 65535 + 1e-7, "tiff");
    roundtrip("rgba8.tiff", 4, 8, 0.5 / 255 + 1e-6, "tiff");
    roundtrip("rgb32.tif", 3, 32, 0, "tiff");
    /* JPEG is lossy; on a smooth ramp at quality 95 the error stays small. */
    roundtrip("rgb8.jpg", 3, 8, 0.02, "jpeg");

    /* Integer formats clamp; float TIFF keeps values beyond [0, 1]. */
    sl_error err;
    sl_image img, back;
    CHECK_OK(sl_image_alloc(&img, 4, 1, 1, &err), &err);
    img.data[0] = -2.0f;
    img.data[1] = 7.5f;
    img.data[2] = NAN;
    img.data[3] = 0.25f;
    const char *png = sl_test_path("clamp.png");
    CHECK_OK(sl_photo_write(png, &img, NULL, 16, &err), &err);
    CHECK_OK(sl_photo_read(png, &back, NULL, &err), &err);
    if (back.data)
        CHECK(back.data[0] == 0.0f && back.data[1] == 1.0f && back.data[2] == 0.0f &&
              fabsf(back.data[3] - 0.25f) < 1e-4f);
    sl_image_free(&back);
    const char *tif = sl_test_path("float.tif");
    CHECK_OK(sl_photo_write(tif, &img, NULL, 32, &err), &err);
    CHECK_OK(sl_photo_read(tif, &back, NULL, &err), &err);
    if (back.data)
        CHECK(back.data[0] == -2.0f && back.data[1] == 7.5f && back.data[2] == 0.0f &&
              back.data[3] == 0.25f);
    sl_image_free(&back);
    sl_image_free(&img);
}

/* sl_image_write picks the format and depth from the extension. */
static void test_image_write_dispatch(void)
{
    static const struct {
        const char *name;
        const char *format;
        int bits;
    } cases[] = {
        {"d.exr", "openexr", 16}, {"d.png", "png", 16},  {"d.jpg", "jpeg", 8},
        {"d.jpeg", "jpeg", 8},    {"d.tif", "tiff", 16}, {"d.TIFF", "tiff", 16},
    };
    sl_error err;
    sl_image img;
    CHECK_OK(sl_image_alloc(&img, 16, 8, 3, &err), &err);
    fill_ramp(&img);
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const char *path = sl_test_path(cases[i].name);
        sl_meta meta;
        int w = 0, h = 0, c = 0;
        CHECK_OK(sl_image_write(path, &img, NULL, SL_PIXEL_HALF, &err), &err);
        CHECK_OK(sl_photo_read_meta(path, &meta, &w, &h, &c, &err), &err);
        CHECK_MSG(strcmp(meta.format, cases[i].format) == 0 &&
                      meta.bits_per_sample == cases[i].bits,
                  "%s: %s %d-bit", cases[i].name, meta.format, meta.bits_per_sample);
        CHECK(w == 16 && h == 8 && c == 3);
        sl_meta_free(&meta);
    }
    sl_image_free(&img);
}

static void set_camera(sl_meta *meta)
{
    sl_meta_init(meta);
    meta->exposure_time = 1.0 / 250;
    meta->f_number = 8;
    meta->iso = 200;
    meta->focal_length_mm = 24;
    strcpy(meta->make, "Canon");
    strcpy(meta->model, "Canon EOS 5D Mark IV");
    strcpy(meta->lens, "EF8-15mm f/4L FISHEYE USM");
    strcpy(meta->datetime, "2026:11:21 14:05:09");
    meta->orientation = 6;
}

static void test_exif_roundtrip(void)
{
    const char *files[] = {"exif.jpg", "exif16.tif", "exif16.png"};
    int bits[] = {8, 16, 16};
    sl_error err;
    sl_image img;
    CHECK_OK(sl_image_alloc(&img, 24, 16, 3, &err), &err);
    fill_ramp(&img);
    sl_meta meta;
    set_camera(&meta);
    CHECK_OK(sl_meta_set(&meta, "setlight:inputs", "a.cr2 b.cr2", &err), &err);
    for (int i = 0; i < 3; i++) {
        const char *path = sl_test_path(files[i]);
        sl_meta got;
        int w, h, c;
        CHECK_OK(sl_photo_write(path, &img, &meta, bits[i], &err), &err);
        CHECK_OK(sl_photo_read_meta(path, &got, &w, &h, &c, &err), &err);
        CHECK(w == 24 && h == 16 && c == 3);
        /* OIIO 2.4 keeps the ISO tag in JPEG EXIF only, not in TIFF, and
         * PNG keeps only text attributes (no numbers, no orientation). */
        if (i < 2) {
            CHECK_NEAR(got.exposure_time, 1.0 / 250, 1e-7);
            CHECK_NEAR(got.f_number, 8, 1e-6);
            CHECK_NEAR(got.focal_length_mm, 24, 1e-6);
            CHECK_MSG(got.orientation == 6, "%s: orientation %d", files[i], got.orientation);
        }
        if (i == 0)
            CHECK_NEAR(got.iso, 200, 0);
        CHECK_MSG(strcmp(got.make, meta.make) == 0, "%s: make '%s'", files[i], got.make);
        CHECK_MSG(strcmp(got.model, meta.model) == 0, "%s: model '%s'", files[i], got.model);
        CHECK_MSG(strcmp(got.lens, meta.lens) == 0, "%s: lens '%s'", files[i], got.lens);
        CHECK_MSG(strcmp(got.datetime, meta.datetime) == 0, "%s: datetime '%s'", files[i],
                  got.datetime);
        CHECK(got.bits_per_sample == bits[i]);
        const char *v = sl_meta_get(&got, "setlight:inputs");
        printf("  %s: setlight:inputs %s\n", files[i], v ? "kept" : "not kept");
        if (i == 2) /* PNG keeps it as a text chunk */
            CHECK(v && strcmp(v, "a.cr2 b.cr2") == 0);
        sl_meta_free(&got);
        /* Reading the pixels does not rotate them: the size stays 24x16. */
        sl_image back;
        CHECK_OK(sl_photo_read(path, &back, NULL, &err), &err);
        CHECK(back.width == 24 && back.height == 16);
        sl_image_free(&back);
    }
    sl_meta_free(&meta);
    sl_image_free(&img);
}

/* Canon EOS REBEL T2i bracket, f/4.5, ISO 200 (SOURCES.md). */
static void test_real_jpegs(void)
{
    static const double times[7] = {2, 0.5, 1.0 / 8, 1.0 / 30, 1.0 / 125, 1.0 / 1000, 1.0 / 4000};
    for (int i = 0; i < 7; i++) {
        char rel[128];
        snprintf(rel, sizeof rel, "brackets/stack_room/stack_room_exp_%d.jpg", i);
        const char *path = sl_test_data(rel);
        if (!path)
            return;
        sl_error err;
        sl_image img;
        sl_meta meta;
        CHECK_OK(sl_image_read(path, &img, &meta, &err), &err);
        CHECK_MSG(fabs(meta.exposure_time - times[i]) <= times[i] * 1e-4, "%s: t = %g, expected %g",
                  path, meta.exposure_time, times[i]);
        CHECK_NEAR(meta.f_number, 4.5, 1e-4);
        CHECK_NEAR(meta.iso, 200, 0);
        CHECK(strcmp(meta.make, "Canon") == 0);
        CHECK_MSG(strstr(meta.model, "REBEL T2i") != NULL, "model '%s'", meta.model);
        CHECK(strcmp(meta.format, "jpeg") == 0 && meta.bits_per_sample == 8 && !meta.is_float);
        CHECK(img.width == 640 && img.height == 427 && img.channels == 3);
        if (img.data) {
            sl_image_stats st;
            sl_image_stats_compute(&img, &st);
            CHECK(st.nan_count == 0 && st.min[0] >= 0 && st.max[0] <= 1 && st.max[0] > 0.5);
        }
        if (i == 0)
            printf("  %s: t=%g f/%g ISO %g %s %s %s\n", path, meta.exposure_time, meta.f_number,
                   meta.iso, meta.make, meta.model, meta.datetime);
        sl_image_free(&img);
        sl_meta_free(&meta);
    }
}

/* Radiance files: float, three channels, finite, non-negative, HDR range. */
static void test_real_hdr(void)
{
    const char *dir = sl_test_data("hdri");
    if (!dir)
        return;
    char saved[4096];
    snprintf(saved, sizeof saved, "%s", dir);
    DIR *d = opendir(saved);
    CHECK(d != NULL);
    if (!d)
        return;
    struct dirent *e;
    int count = 0;
    while ((e = readdir(d)) && count < 3) {
        size_t len = strlen(e->d_name);
        if (len < 5 || strcmp(e->d_name + len - 4, ".hdr") != 0)
            continue;
        char path[8192];
        snprintf(path, sizeof path, "%s/%s", saved, e->d_name);
        sl_error err;
        sl_image img;
        sl_meta meta;
        CHECK_OK(sl_image_read(path, &img, &meta, &err), &err);
        CHECK(strcmp(meta.format, "hdr") == 0 && meta.is_float && img.channels == 3);
        if (img.data) {
            sl_image_stats st;
            sl_image_stats_compute(&img, &st);
            CHECK_MSG(st.nan_count == 0 && st.inf_count == 0 && st.negative_count == 0,
                      "%s: %lld NaN %lld Inf %lld negative", path, (long long)st.nan_count,
                      (long long)st.inf_count, (long long)st.negative_count);
            CHECK_MSG(st.max[1] > 1.0, "%s: max %g is not HDR", path, st.max[1]);
            printf("  %s: %dx%d, max G %.4g, mean G %.4g\n", path, img.width, img.height, st.max[1],
                   st.mean[1]);
        }
        sl_image_free(&img);
        sl_meta_free(&meta);
        count++;
    }
    closedir(d);
    CHECK(count > 0);
}

/* A PNG named .exr reads as the PNG it is. */
static void test_content_sniffing(void)
{
    sl_error err;
    sl_image img, back;
    sl_meta meta;
    CHECK_OK(sl_image_alloc(&img, 8, 8, 3, &err), &err);
    fill_ramp(&img);
    const char *png = sl_test_path("really.png");
    CHECK_OK(sl_photo_write(png, &img, NULL, 16, &err), &err);
    const char *fake = sl_test_path("renamed.exr");
    CHECK(rename(png, fake) == 0);
    CHECK_OK(sl_image_read(fake, &back, &meta, &err), &err);
    CHECK(strcmp(meta.format, "png") == 0 && back.width == 8);
    sl_image_free(&back);
    sl_meta_free(&meta);
    /* Asking for EXR explicitly is an input error naming the file. */
    CHECK_RESULT(sl_exr_read(fake, &back, &meta, &err), SL_ERR_INPUT, &err);
    CHECK(names(&err, fake) && back.data == NULL);
    sl_image_free(&img);
}

static void expect_bad(const char *path, sl_result code, const char *fragment)
{
    sl_error err;
    sl_image img;
    sl_meta meta;
    CHECK_RESULT(sl_image_read(path, &img, &meta, &err), code, &err);
    CHECK_MSG(names(&err, path), "message does not name the file: %s", err.message);
    CHECK_MSG(!fragment || strstr(err.message, fragment), "message lacks \"%s\": %s", fragment,
              err.message);
    CHECK(img.data == NULL && meta.attrs == NULL);
    CHECK_RESULT(sl_photo_read(path, &img, &meta, &err), code, &err);
    CHECK(names(&err, path) && img.data == NULL);
    int w = -1;
    CHECK_RESULT(sl_photo_read_meta(path, &meta, &w, NULL, NULL, &err), code, &err);
    CHECK(w == 0);
}

static void test_bad_input(void)
{
    sl_error err;
    expect_bad(sl_test_path("missing.png"), SL_ERR_NOT_FOUND, "no such file");
    expect_bad(sl_test_tmpdir(), SL_ERR_NOT_FOUND, "directory");
    const char *empty = sl_test_path("empty.jpg");
    CHECK_OK(sl_write_file_atomic(empty, "", 0, &err), &err);
    expect_bad(empty, SL_ERR_INPUT, "empty");
    unsigned char noise[3000];
    uint32_t s = 99;
    for (size_t i = 0; i < sizeof noise; i++) {
        s = s * 1664525u + 1013904223u;
        noise[i] = (unsigned char)(s >> 24);
    }
    const char *junk = sl_test_path("junk.png");
    CHECK_OK(sl_write_file_atomic(junk, noise, sizeof noise, &err), &err);
    expect_bad(junk, SL_ERR_INPUT, "not an image file");
    const char *junk_exr = sl_test_path("junk.exr");
    CHECK_OK(sl_write_file_atomic(junk_exr, noise, sizeof noise, &err), &err);
    expect_bad(junk_exr, SL_ERR_INPUT, "not an image file");

    /* A TIFF cut in half: the header reads, the pixels cannot (a cut PNG:
     * test_photo_png). */
    sl_image img;
    CHECK_OK(sl_image_alloc(&img, 64, 64, 3, &err), &err);
    for (size_t i = 0; i < (size_t)64 * 64 * 3; i++) {
        s = s * 1664525u + 1013904223u;
        img.data[i] = (float)(s >> 8) / 16777216.0f;
    }
    const char *full = sl_test_path("full.tif");
    CHECK_OK(sl_photo_write(full, &img, NULL, 8, &err), &err);
    sl_image_free(&img);
    FILE *fp = fopen(full, "rb");
    unsigned char buf[8192];
    size_t n = fp ? fread(buf, 1, sizeof buf, fp) : 0;
    if (fp)
        fclose(fp);
    CHECK(n > 4000);
    const char *cut = sl_test_path("cut.tif");
    CHECK_OK(sl_write_file_atomic(cut, buf, n / 2, &err), &err);
    sl_image back;
    CHECK_RESULT(sl_image_read(cut, &back, NULL, &err), SL_ERR_INPUT, &err);
    CHECK(names(&err, cut) && back.data == NULL);
}

static void test_write_failures(void)
{
    sl_error err;
    sl_image img;
    CHECK_OK(sl_image_alloc(&img, 8, 4, 3, &err), &err);
    sl_image_fill(&img, 0.5f);
    const char *dir = sl_test_path("writes");
    mkdir(dir, 0755);
    char path[4200];
    snprintf(path, sizeof path, "%s/none/out.png", dir);
    sl_result r = sl_photo_write(path, &img, NULL, 8, &err);
    CHECK(r == SL_ERR_USAGE || r == SL_ERR_IO);
    CHECK(names(&err, path));
    char file[4200];
    snprintf(file, sizeof file, "%s/plain", dir);
    CHECK_OK(sl_write_file_atomic(file, "x", 1, &err), &err);
    snprintf(path, sizeof path, "%s/plain/out.jpg", dir);
    r = sl_image_write(path, &img, NULL, SL_PIXEL_HALF, &err);
    CHECK(r == SL_ERR_USAGE || r == SL_ERR_IO);
    CHECK(names(&err, path));
    /* Impossible depth for the format, unknown extension: usage errors. */
    snprintf(path, sizeof path, "%s/deep.jpg", dir);
    CHECK_RESULT(sl_photo_write(path, &img, NULL, 16, &err), SL_ERR_USAGE, &err);
    CHECK(names(&err, path));
    snprintf(path, sizeof path, "%s/float.png", dir);
    CHECK_RESULT(sl_photo_write(path, &img, NULL, 32, &err), SL_ERR_USAGE, &err);
    snprintf(path, sizeof path, "%s/out.bmp", dir);
    CHECK_RESULT(sl_photo_write(path, &img, NULL, 8, &err), SL_ERR_USAGE, &err);
    CHECK(names(&err, path));
    CHECK_RESULT(sl_image_write(path, &img, NULL, SL_PIXEL_HALF, &err), SL_ERR_USAGE, &err);
    snprintf(path, sizeof path, "%s/noext", dir);
    CHECK_RESULT(sl_image_write(path, &img, NULL, SL_PIXEL_HALF, &err), SL_ERR_USAGE, &err);
    CHECK(names(&err, path));
    /* Only "plain" is left: no partial or temporary files. */
    CHECK_MSG(sl_test_count_files(dir) == 1, "%d entries in %s", sl_test_count_files(dir), dir);
    sl_image_free(&img);
}

int main(void)
{
    RUN(test_pixel_roundtrips);
    RUN(test_image_write_dispatch);
    RUN(test_exif_roundtrip);
    RUN(test_real_jpegs);
    RUN(test_real_hdr);
    RUN(test_content_sniffing);
    RUN(test_bad_input);
    RUN(test_write_failures);
    return sl_test_finish();
}
