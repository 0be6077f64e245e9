/* SPDX-License-Identifier: BSD-3-Clause */
/* The one way images are read as scene-linear radiance (core/image_linear.c):
 * known codes through the sRGB and gamma curves, linear files left alone,
 * other primaries converted, and what is a lat-long. */
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "testing.h"

/* ((128/255 + 0.055) / 1.055)^2.4, (128/255)^2.2 */
#define SRGB_128 0.21586050011389926
#define GAMMA22_128 0.2195197180748679

/* A flat w x h image of `value` written as `name` (format by extension). */
static const char *write_flat(const char *name, int w, int h, int channels, float value,
                              int bits, sl_envmap envmap, const float *xy)
{
    const char *path = sl_test_path(name);
    sl_image img;
    sl_meta meta;
    sl_error err;
    sl_meta_init(&meta);
    meta.envmap = envmap;
    if (xy) {
        meta.has_chromaticities = true;
        memcpy(meta.chromaticities, xy, sizeof meta.chromaticities);
    }
    CHECK_OK(sl_image_alloc(&img, w, h, channels, &err), &err);
    sl_image_fill(&img, value);
    size_t n = strlen(path);
    if (n > 4 && !strcmp(path + n - 4, ".exr"))
        CHECK_OK(sl_exr_write(path, &img, &meta, SL_PIXEL_FLOAT, &err), &err);
    else
        CHECK_OK(sl_photo_write(path, &img, &meta, bits, &err), &err);
    sl_image_free(&img);
    sl_meta_free(&meta);
    return path;
}

static void check_all(const sl_image *img, int channels, double want, double tol)
{
    double worst = 0;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++)
            for (int c = 0; c < channels; c++) {
                double d = fabs(sl_image_pixel(img, x, y)[c] - want);
                worst = d > worst ? d : worst;
            }
    CHECK_NEAR(worst, 0, tol);
}

static void test_srgb_photos(void)
{
    /* Code 128 in 8-bit PNG and JPEG, code 32768 in a 16-bit PNG and TIFF. */
    struct {
        const char *name;
        int bits;
        float value;
        double want;
    } cases[] = {
        {"c128.png", 8, 128.0f / 255.0f, SRGB_128},
        {"c128.jpg", 8, 128.0f / 255.0f, SRGB_128},
        {"c128.tif", 8, 128.0f / 255.0f, SRGB_128},
        {"c32768.png", 16, 32768.0f / 65535.0f, 0.2140482022981852},
        {"c32768.tif", 16, 32768.0f / 65535.0f, 0.2140482022981852},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        const char *path = write_flat(cases[i].name, 16, 8, 3, cases[i].value, cases[i].bits,
                                      SL_ENVMAP_NONE, NULL);
        sl_image img;
        sl_meta meta;
        sl_read_info info;
        sl_error err;
        CHECK_OK(sl_image_read_linear(path, NULL, &img, &meta, &info, &err), &err);
        CHECK_MSG(info.converted && info.encoded && !strcmp(info.colorspace, "srgb"),
                  "%s: converted %d encoded %d from '%s'", path, info.converted, info.encoded,
                  info.colorspace);
        /* OCIO's sRGB curve is within 1e-5 of IEC's in encoded value. */
        check_all(&img, 3, cases[i].want, 2e-5);
        CHECK(!strcmp(sl_meta_color_space(&meta), "lin_rec709"));
        sl_image_free(&img);
        sl_meta_free(&meta);
    }
}

static void test_grey_photo_becomes_rgb(void)
{
    const char *path = write_flat("grey.png", 16, 8, 1, 128.0f / 255.0f, 8, SL_ENVMAP_NONE, NULL);
    sl_image img;
    sl_error err;
    CHECK_OK(sl_image_read_linear(path, NULL, &img, NULL, NULL, &err), &err);
    CHECK(img.channels == 3);
    check_all(&img, 3, SRGB_128, 2e-5);
    sl_image_free(&img);
}

static void test_linear_files_untouched(void)
{
    /* Float TIFF and EXR without a colour space: already scene-linear. */
    const char *names[] = {"flat.tif", "flat.exr"};
    for (int i = 0; i < 2; i++) {
        const char *path = write_flat(names[i], 16, 8, 3, 0.5f, 32, SL_ENVMAP_NONE, NULL);
        sl_image img;
        sl_read_info info;
        sl_error err;
        CHECK_OK(sl_image_read_linear(path, NULL, &img, NULL, &info, &err), &err);
        /* sl_exr_write names Rec.709; the TIFF names nothing. */
        CHECK(!info.converted && info.colorspace_assumed == (i == 0));
        CHECK(!strcmp(info.colorspace, "lin_rec709"));
        check_all(&img, 3, 0.5, 0);
        sl_image_free(&img);
    }
}

static void test_declared_spaces(void)
{
    sl_image img;
    sl_meta meta;
    sl_read_info info;
    sl_error err;
    /* OpenImageIO's names for a PNG gAMA chunk. */
    const char *gammas[] = {"GammaCorrected2.2", "GammaCorrected2.19998"};
    for (int i = 0; i < 2; i++) {
        CHECK_OK(sl_image_alloc(&img, 4, 2, 3, &err), &err);
        sl_image_fill(&img, 128.0f / 255.0f);
        sl_meta_init(&meta);
        snprintf(meta.format, sizeof meta.format, "png");
        meta.bits_per_sample = 8;
        snprintf(meta.colorspace, sizeof meta.colorspace, "%s", gammas[i]);
        CHECK_OK(sl_image_linearize(&img, &meta, "g.png", NULL, &info, &err), &err);
        CHECK(!strcmp(info.colorspace, "gamma22_rec709") && info.encoded);
        check_all(&img, 3, GAMMA22_128, 1e-6);
        sl_image_free(&img);
        sl_meta_free(&meta);
    }
    /* Camera raw (LibRaw, linear) and a PNG whose gAMA says linear: not
     * sRGB, whatever their integer samples. */
    const char *formats[] = {"raw", "png"}, *declared[] = {"", "GammaCorrected1"};
    for (int i = 0; i < 2; i++) {
        bool assumed;
        sl_meta_init(&meta);
        snprintf(meta.format, sizeof meta.format, "%s", formats[i]);
        snprintf(meta.colorspace, sizeof meta.colorspace, "%s", declared[i]);
        meta.bits_per_sample = 16;
        const char *cs = sl_file_color_space(&meta, &assumed);
        CHECK_MSG(cs && !strcmp(cs, "lin_rec709") && assumed == (i == 0), "%s: %s", formats[i],
                  cs ? cs : "NULL");
        sl_meta_free(&meta);
    }
    /* OpenImageIO's "Rec709" for Netpbm: PPM codes BT.709-encoded, PFM linear. */
    for (int is_float = 0; is_float < 2; is_float++) {
        CHECK_OK(sl_image_alloc(&img, 4, 2, 3, &err), &err);
        sl_image_fill(&img, 128.0f / 255.0f);
        sl_meta_init(&meta);
        meta.is_float = is_float;
        snprintf(meta.colorspace, sizeof meta.colorspace, "Rec709");
        CHECK_OK(sl_image_linearize(&img, &meta, "x.ppm", NULL, &info, &err), &err);
        CHECK(info.converted == !is_float);
        /* ((128/255 + 0.099) / 1.099)^(1/0.45) */
        check_all(&img, 3, is_float ? 128.0 / 255.0 : 0.26148150693314937, 1e-5);
        sl_image_free(&img);
        sl_meta_free(&meta);
    }
    /* A gamma or a space the config does not have: refused, naming both. */
    CHECK_OK(sl_image_alloc(&img, 4, 2, 3, &err), &err);
    sl_meta_init(&meta);
    snprintf(meta.colorspace, sizeof meta.colorspace, "GammaCorrected2.6");
    CHECK_RESULT(sl_image_linearize(&img, &meta, "odd.png", NULL, &info, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "odd.png") && strstr(err.message, "GammaCorrected2.6"));
    /* --input-colorspace style override wins over what the file says. */
    sl_image_fill(&img, 128.0f / 255.0f);
    CHECK_OK(sl_image_linearize(&img, &meta, "odd.png", "srgb", &info, &err), &err);
    check_all(&img, 3, SRGB_128, 2e-5);
    CHECK_RESULT(sl_image_linearize(&img, &meta, "odd.png", "nosuch", &info, &err), SL_ERR_USAGE,
                 &err);
    sl_image_free(&img);
    sl_meta_free(&meta);
}

static void test_other_primaries(void)
{
    /* ACEScg red: the first column of the AP1 -> Rec.709 matrix (Bradford). */
    const char *path = sl_test_path("acescg.exr");
    sl_image img;
    sl_meta meta;
    sl_read_info info;
    sl_error err;
    CHECK_OK(sl_image_alloc(&img, 4, 2, 3, &err), &err);
    sl_image_fill(&img, 0.0f);
    sl_image_pixel(&img, 0, 0)[0] = 1.0f;
    sl_meta_init(&meta);
    CHECK_OK(sl_meta_set_color_space(&meta, "acescg", &err), &err);
    CHECK_OK(sl_exr_write(path, &img, &meta, SL_PIXEL_FLOAT, &err), &err);
    sl_image_free(&img);
    sl_meta_free(&meta);
    CHECK_OK(sl_image_read_linear(path, NULL, &img, NULL, &info, &err), &err);
    CHECK(info.converted && !info.encoded && !strcmp(info.colorspace, "acescg"));
    const float *p = sl_image_pixel(&img, 0, 0);
    CHECK_NEAR(p[0], 1.70505, 2e-4);
    CHECK_NEAR(p[1], -0.13026, 2e-4);
    CHECK_NEAR(p[2], -0.02400, 2e-4);
    sl_image_free(&img);

    /* Rec.709 primaries adapted to D50 with a D50 white (Blender's city.exr
     * carries these): no named space, converted by their matrix, which is
     * the identity up to the file's 6 digits. */
    static const float d50[8] = {0.648447f, 0.330877f, 0.321187f, 0.597894f,
                                 0.155901f, 0.0660563f, 0.345708f, 0.358541f};
    path = write_flat("d50.exr", 4, 2, 3, 0.25f, 32, SL_ENVMAP_NONE, d50);
    CHECK_OK(sl_image_read_linear(path, NULL, &img, NULL, &info, &err), &err);
    CHECK(info.converted && !strcmp(info.colorspace, "chromaticities"));
    check_all(&img, 3, 0.25, 1e-4);
    sl_image_free(&img);
}

static void test_latlong(void)
{
    sl_image img;
    sl_meta meta;
    sl_read_info info;
    sl_error err;
    /* 2:1 without envmap: a lat-long, said so. */
    const char *path = write_flat("plain.exr", 16, 8, 3, 1.0f, 32, SL_ENVMAP_NONE, NULL);
    CHECK_OK(sl_latlong_read(path, NULL, &img, &meta, &info, &err), &err);
    CHECK(info.latlong_assumed && meta.envmap == SL_ENVMAP_LATLONG);
    sl_image_free(&img);
    sl_meta_free(&meta);
    /* With the attribute: nothing assumed. */
    path = write_flat("tagged.exr", 16, 8, 3, 1.0f, 32, SL_ENVMAP_LATLONG, NULL);
    CHECK_OK(sl_latlong_read(path, NULL, &img, NULL, &info, &err), &err);
    CHECK(!info.latlong_assumed);
    sl_image_free(&img);
    /* Not 2:1: refused, the image freed. */
    path = write_flat("wide.exr", 24, 8, 3, 1.0f, 32, SL_ENVMAP_NONE, NULL);
    CHECK_RESULT(sl_latlong_read(path, NULL, &img, NULL, &info, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "wide.exr") && strstr(err.message, "24x8 is not 2:1"));
    CHECK(img.data == NULL);
    /* ... but an environment of another shape is still read. */
    CHECK_OK(sl_env_read(path, NULL, &img, &meta, &info, &err), &err);
    CHECK(meta.envmap == SL_ENVMAP_NONE && !info.latlong_assumed);
    sl_image_free(&img);
    sl_meta_free(&meta);
    /* A square image: probably a probe, and the way to a lat-long. */
    path = write_flat("square.exr", 8, 8, 3, 1.0f, 32, SL_ENVMAP_NONE, NULL);
    CHECK_RESULT(sl_latlong_read(path, NULL, &img, NULL, &info, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "8x8 is not 2:1 (a mirror ball or angular map?"));
    /* A cube map says so, even when 2:1 would fit another reading. */
    path = write_flat("cube.exr", 4, 24, 3, 1.0f, 32, SL_ENVMAP_CUBE, NULL);
    CHECK_RESULT(sl_latlong_read(path, NULL, &img, NULL, &info, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "cube.exr") && strstr(err.message, "cube map"));
    /* An 8-bit PNG lat-long: linearised and taken as a lat-long. */
    path = write_flat("env128.png", 16, 8, 3, 128.0f / 255.0f, 8, SL_ENVMAP_NONE, NULL);
    CHECK_OK(sl_latlong_read(path, NULL, &img, NULL, &info, &err), &err);
    CHECK(info.latlong_assumed && info.converted);
    check_all(&img, 3, SRGB_128, 2e-5);
    sl_image_free(&img);
}

static void test_real_hdr(void)
{
    const char *path = sl_test_data("hdri/small/grace_256x128.hdr");
    if (!path)
        return;
    sl_image img;
    sl_read_info info;
    sl_error err;
    CHECK_OK(sl_latlong_read(path, NULL, &img, NULL, &info, &err), &err);
    CHECK(info.latlong_assumed && !info.converted && !strcmp(info.colorspace, "lin_rec709"));
    sl_image_free(&img);
}

/* Held notes: printed once each when the run succeeds, dropped when it
 * fails (the refusal stays one line); not held: printed at once. */
static void test_notes_held(void)
{
    const char *path = sl_test_path("notes.txt");
    fflush(stderr);
    int saved = dup(STDERR_FILENO);
    CHECK(freopen(path, "w", stderr) != NULL);
    sl_log_set_quiet(false);
    sl_log_hold_notes(true);
    sl_log_note(SL_LOG_INFO, "dropped %d", 1);
    sl_log_release_notes(false);
    sl_log_note(SL_LOG_WARN, "kept %d", 2);
    sl_log_note(SL_LOG_WARN, "kept %d", 2);
    sl_log(SL_LOG_INFO, "at once");
    sl_log_release_notes(true);
    sl_log_hold_notes(false);
    sl_log_note(SL_LOG_INFO, "unheld");
    sl_log_set_quiet(true);
    fflush(stderr);
    dup2(saved, STDERR_FILENO);
    close(saved);
    FILE *f = fopen(path, "r");
    char text[512] = "";
    size_t n = f ? fread(text, 1, sizeof text - 1, f) : 0;
    text[n] = 0;
    if (f)
        fclose(f);
    CHECK_MSG(!strcmp(text, "setlight: at once\nsetlight: warning: kept 2\nsetlight: unheld\n"),
              "stderr was '%s'", text);
}

int main(void)
{
    sl_log_set_quiet(true);
    RUN(test_srgb_photos);
    RUN(test_grey_photo_becomes_rgb);
    RUN(test_linear_files_untouched);
    RUN(test_declared_spaces);
    RUN(test_other_primaries);
    RUN(test_latlong);
    RUN(test_real_hdr);
    RUN(test_notes_held);
    return sl_test_finish();
}
