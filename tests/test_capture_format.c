/* SPDX-License-Identifier: BSD-3-Clause */
/* Image formats without a camera: the vendors' choice labels (libgphoto2's
 * ptp2 driver) mapped onto raw, jpeg and raw+jpeg, the best label chosen,
 * file kinds by name, and the DNG the virtual and test cameras write read
 * back linear by OpenImageIO (LibRaw) with its EXIF. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/capture.h"
#include "testing.h"

static sl_image_format kind(const char *label)
{
    return sl_image_format_of_label(label, NULL);
}

static void test_labels(void)
{
    /* Nikon (PTP CompressionSetting 0x5004, "imagequality") */
    CHECK(kind("JPEG Basic") == SL_FORMAT_JPEG);
    CHECK(kind("JPEG Fine*") == SL_FORMAT_JPEG);
    CHECK(kind("NEF (Raw)") == SL_FORMAT_RAW);
    CHECK(kind("NEF+Fine") == SL_FORMAT_RAW_JPEG);
    CHECK(kind("NEF+Basic*") == SL_FORMAT_RAW_JPEG);
    CHECK(kind("TIFF (RGB)") == SL_FORMAT_KEEP);
    /* Canon EOS ("imageformat") */
    CHECK(kind("RAW") == SL_FORMAT_RAW);
    CHECK(kind("cRAW") == SL_FORMAT_RAW);
    CHECK(kind("mRAW") == SL_FORMAT_RAW);
    CHECK(kind("Large Fine JPEG") == SL_FORMAT_JPEG);
    CHECK(kind("RAW + Large Fine JPEG") == SL_FORMAT_RAW_JPEG);
    CHECK(kind("cRAW + Small Normal JPEG") == SL_FORMAT_RAW_JPEG);
    /* Sony and Fuji */
    CHECK(kind("Standard") == SL_FORMAT_JPEG);
    CHECK(kind("Extra Fine") == SL_FORMAT_JPEG);
    CHECK(kind("RAW+JPEG") == SL_FORMAT_RAW_JPEG);
    CHECK(kind("RAW+JPEG (X.Fine)") == SL_FORMAT_RAW_JPEG);
    CHECK(kind("RAW+HEIF (Fine)") == SL_FORMAT_KEEP);
    CHECK(kind("Unknown value 0003") == SL_FORMAT_KEEP);
    CHECK(kind("Drawing") == SL_FORMAT_KEEP);
    /* ranks: full raw over cRAW over mRAW, fine over normal over basic,
     * large over small, plain over starred */
    int a, b;
    sl_image_format_of_label("RAW", &a);
    sl_image_format_of_label("cRAW", &b);
    CHECK(a > b);
    sl_image_format_of_label("cRAW", &a);
    sl_image_format_of_label("sRAW", &b);
    CHECK(a > b);
    sl_image_format_of_label("JPEG Fine", &a);
    sl_image_format_of_label("JPEG Normal", &b);
    CHECK(a > b);
    sl_image_format_of_label("Extra Fine", &a);
    sl_image_format_of_label("Fine", &b);
    CHECK(a > b);
    sl_image_format_of_label("Large Fine JPEG", &a);
    sl_image_format_of_label("Small Fine JPEG", &b);
    CHECK(a > b);
    sl_image_format_of_label("JPEG Fine", &a);
    sl_image_format_of_label("JPEG Fine*", &b);
    CHECK(a > b);
    sl_image_format_of_label("RAW + Large Fine JPEG", &a);
    sl_image_format_of_label("RAW + Large Normal JPEG", &b);
    CHECK(a > b);
}

static void test_names(void)
{
    sl_image_format f;
    sl_error err;
    CHECK_OK(sl_image_format_parse("RAW+JPEG", &f, &err), &err);
    CHECK(f == SL_FORMAT_RAW_JPEG && !strcmp(sl_image_format_name(f), "raw+jpeg"));
    CHECK_OK(sl_image_format_parse("keep", &f, &err), &err);
    CHECK(f == SL_FORMAT_KEEP);
    CHECK_RESULT(sl_image_format_parse("tiff", &f, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "'tiff'") != NULL);
    CHECK(sl_image_format_of_file("/store_00010001/DSC_0001.NEF") == SL_FORMAT_RAW);
    CHECK(sl_image_format_of_file("IMG_0001.cr3") == SL_FORMAT_RAW);
    CHECK(sl_image_format_of_file("IMG_0001.JPG") == SL_FORMAT_JPEG);
    CHECK(sl_image_format_of_file("IMG_0001.tif") == SL_FORMAT_KEEP);
    CHECK(sl_image_format_of_file("README") == SL_FORMAT_KEEP);
}

/* A ramp through sl_dng_encode and back through sl_photo_read: linear
 * (values and ratios kept), EXIF exposure kept. */
static void test_dng(void)
{
    sl_image img;
    sl_error err;
    CHECK_OK(sl_image_alloc(&img, 256, 64, 3, &err), &err);
    for (int y = 0; y < 64; y++)
        for (int x = 0; x < 256; x++) {
            float *p = sl_image_pixel(&img, x, y);
            p[0] = p[1] = p[2] = (float)(x / 4 + 1) / 64.0f;
        }
    sl_meta meta;
    sl_meta_init(&meta);
    meta.exposure_time = 1.0 / 125;
    meta.f_number = 8;
    meta.iso = 200;
    meta.focal_length_mm = 8;
    snprintf(meta.make, sizeof meta.make, "setlight");
    snprintf(meta.model, sizeof meta.model, "test");
    snprintf(meta.datetime, sizeof meta.datetime, "2026:05:14 10:00:00");
    unsigned char *data;
    size_t size;
    CHECK_OK(sl_dng_encode(&img, &meta, 0, &data, &size, &err), &err);
    const char *path = sl_test_path("ramp.dng");
    CHECK_OK(sl_write_file_atomic(path, data, size, &err), &err);
    free(data);
    sl_image back = {0};
    sl_meta got;
    CHECK_OK(sl_photo_read(path, &back, &got, &err), &err);
    if (back.data) {
        CHECK(back.width == 256 && back.height == 64 && !strcmp(got.format, "raw"));
        CHECK_NEAR(got.exposure_time, 1.0 / 125, 1e-6);
        CHECK_NEAR(got.f_number, 8, 1e-6);
        /* linear: ratio 4 between 1/8 and 1/2 */
        float a = sl_image_pixel(&back, 29, 8)[1], b = sl_image_pixel(&back, 125, 8)[1];
        printf("dng (%s): %.5f at 1/8, %.5f at 1/2 (ratio %.4f), %.5f at 1\n", got.format, a, b,
               b / a, sl_image_pixel(&back, 253, 8)[1]);
        CHECK_NEAR(b / a, 4.0, 0.02);
        /* values relative to the white level: the ramp comes back as
         * written (OpenImageIO's scene-linear scale of 2.22 is not applied) */
        CHECK_NEAR(b, 0.5, 0.005);
        CHECK_NEAR(sl_image_pixel(&back, 253, 8)[1], 1.0, 0.01);
        sl_meta_free(&got);
    }
    sl_image_free(&back);
    sl_image_free(&img);
    sl_meta_free(&meta);
}

int main(void)
{
    RUN(test_labels);
    RUN(test_names);
    RUN(test_dng);
    return sl_test_finish();
}
