/* SPDX-License-Identifier: BSD-3-Clause */
/* The photos' lens EXIF through merge into the merged EXR, and back into a
 * nominal lens: simulate -> merge -> the EXR's attributes -> the lens the
 * EXIF states (not the true one), and the merged view's image circle on the
 * true lens's circle. A bracket mixing lenses is refused; missing values are
 * named. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/vset.h"
#include "setlight/stitch.h"
#include "testing.h"

#define W 360
#define H 240

static const char *capture_dir(void)
{
    static bool made;
    const char *dir = sl_test_path("lens_meta_capture");
    if (made)
        return dir;
    sl_vset_desc desc;
    sl_vset_capture_opts o;
    sl_error err;
    CHECK_OK(sl_vset_preset("stage", &desc, &err), &err);
    sl_vset_capture_defaults(&o, &desc, SL_VSET_SIZE_TINY);
    o.photo_width = W;
    o.photo_height = H;
    o.probe_width = 0;
    o.views = 2;
    o.brackets = 5;
    o.force = true;
    CHECK_OK(sl_vset_capture_write(&o, dir, NULL, &err), &err);
    made = true;
    return dir;
}

static void frame_paths(const char *dir, int first, int count, const char *ext,
                        char paths[][4096], const char **ptrs)
{
    for (int i = 0; i < count; i++) {
        snprintf(paths[i], 4096, "%s/hdri/IMG_%04d%s", dir, first + i, ext);
        ptrs[i] = paths[i];
    }
}

static void merged_exr_carries_lens(void)
{
    const char *dir = capture_dir();
    char paths[5][4096];
    const char *ptrs[5];
    frame_paths(dir, 6, 5, "_linear.tif", paths, ptrs); /* view 1 */
    const char *out = sl_test_path("view1.exr");
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    sl_merge_result res;
    sl_error err;
    CHECK_OK(sl_merge_to_exr(ptrs, 5, &opt, out, NULL, NULL, &res, &err), &err);
    CHECK_NEAR(res.focal_length_mm, 8, 1e-6);
    sl_merge_result_free(&res);

    sl_image img;
    sl_meta meta;
    CHECK_OK(sl_exr_read(out, &img, &meta, &err), &err);
    printf("  merged EXR: nominalFocalLength %g, cameraMake '%s', cameraModel '%s', lensModel "
           "'%s', %s '%s', %s '%s'\n",
           meta.focal_length_mm, meta.make, meta.model, meta.lens, SL_ATTR_SENSOR_MM,
           sl_meta_get(&meta, SL_ATTR_SENSOR_MM), SL_ATTR_FOCAL_35MM,
           sl_meta_get(&meta, SL_ATTR_FOCAL_35MM));
    CHECK_NEAR(meta.focal_length_mm, SL_VSET_FISHEYE_FOCAL_MM, 1e-6);
    CHECK(!strcmp(meta.make, "setlight"));
    CHECK(strstr(meta.model, "virtual") != NULL);
    CHECK(!strcmp(meta.lens, SL_VSET_FISHEYE_NAME));
    const char *sensor = sl_meta_get(&meta, SL_ATTR_SENSOR_MM);
    CHECK(sensor && !strcmp(sensor, "36 x 24"));
    const char *f35 = sl_meta_get(&meta, SL_ATTR_FOCAL_35MM);
    CHECK(f35 && fabs(atof(f35) - 8.0) < 0.01);

    /* Back to the lens the EXIF states: the nominal one, not the true glass. */
    sl_lens lens, nominal, truth;
    char why[256];
    CHECK(sl_stitch_lens_from_meta(&meta, SL_LENS_EQUISOLID, img.width, img.height, &lens, why,
                                   sizeof why));
    sl_vset_fisheye_nominal(&nominal, W, H);
    sl_vset_fisheye_true(&truth, W, H);
    CHECK(img.width == W && img.height == H);
    CHECK_NEAR(lens.focal_px, nominal.focal_px, 1e-9);
    CHECK_NEAR(lens.cx, nominal.cx, 1e-9);
    CHECK_NEAR(lens.cy, nominal.cy, 1e-9);
    CHECK_NEAR(lens.circle_radius_px, nominal.circle_radius_px, 1e-9);
    CHECK(lens.projection == SL_LENS_EQUISOLID && lens.k[0] == 0 && lens.vignette[0] == 0);

    /* The merged view's circle is the true lens's, not the nominal one. */
    sl_stitch_circle c;
    CHECK_OK(sl_stitch_circle_find(&img, out, &lens, &c, &err), &err);
    double off = hypot(c.cx - truth.cx, c.cy - truth.cy);
    printf("  merged view 1 (%dx%d): circle %.3f,%.3f r %.3f; true %.3f,%.3f r %.3f: off %.3f "
           "px, radius %+.3f px, rms %.3f px, %.1f%% of rays; nominal r %.3f\n",
           W, H, c.cx, c.cy, c.radius, truth.cx, truth.cy, truth.circle_radius_px, off,
           c.radius - truth.circle_radius_px, c.rms_px, 100 * c.support,
           nominal.circle_radius_px);
    CHECK(off < 0.5);
    CHECK_NEAR(c.radius, truth.circle_radius_px, 0.5);
    sl_image_free(&img);
    sl_meta_free(&meta);
}

/* A frame of another lens in the bracket: refused, naming it, nothing written. */
static void mixed_lenses_refused(void)
{
    const char *dir = capture_dir();
    char paths[5][4096];
    const char *ptrs[5];
    frame_paths(dir, 1, 5, "_linear.tif", paths, ptrs);
    sl_image img;
    sl_meta meta;
    sl_error err;
    CHECK_OK(sl_photo_read(paths[3], &img, &meta, &err), &err);
    snprintf(meta.lens, sizeof meta.lens, "15mm f/2.8 diagonal fisheye");
    meta.focal_length_mm = 15;
    const char *odd = sl_test_path("IMG_odd.tif");
    CHECK_OK(sl_photo_write(odd, &img, &meta, 16, &err), &err);
    sl_image_free(&img);
    sl_meta_free(&meta);
    ptrs[3] = odd;
    const char *out = sl_test_path("mixed.exr");
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    sl_merge_result res;
    CHECK_RESULT(sl_merge_to_exr(ptrs, 5, &opt, out, NULL, NULL, &res, &err), SL_ERR_INPUT,
                 &err);
    printf("  refused: %s\n", err.message);
    CHECK(strstr(err.message, odd) == err.message && strstr(err.message, "different lenses"));
    CHECK(!sl_test_file_exists(out));
}

static void missing_values_named(void)
{
    sl_meta meta;
    sl_meta_init(&meta);
    sl_lens lens;
    char why[256];
    CHECK(!sl_stitch_lens_from_meta(&meta, SL_LENS_EQUISOLID, 600, 400, &lens, why, sizeof why));
    CHECK(strstr(why, "focal length") && strstr(why, "--focal-mm"));
    meta.focal_length_mm = 8;
    snprintf(meta.make, sizeof meta.make, "Acme");
    snprintf(meta.model, sizeof meta.model, "Obscura 1");
    CHECK(!sl_stitch_lens_from_meta(&meta, SL_LENS_EQUISOLID, 600, 400, &lens, why, sizeof why));
    CHECK(strstr(why, "Acme Obscura 1") && strstr(why, "--sensor-mm"));
    /* A known body, but a square crop of its frame: the millimetres are unknown. */
    snprintf(meta.make, sizeof meta.make, "Canon");
    snprintf(meta.model, sizeof meta.model, "Canon EOS 6D Mark II");
    CHECK(!sl_stitch_lens_from_meta(&meta, SL_LENS_EQUISOLID, 1600, 1600, &lens, why, sizeof why));
    CHECK(strstr(why, "1600x1600") && strstr(why, "--sensor-mm"));
    printf("  %s\n", why);
    /* The whole frame, either way up. */
    CHECK(sl_stitch_lens_from_meta(&meta, SL_LENS_EQUISOLID, 6240, 4160, &lens, why, sizeof why));
    CHECK_NEAR(lens.focal_px, 8 * 6240 / 35.9, 1e-9);
    CHECK(sl_stitch_lens_from_meta(&meta, SL_LENS_EQUISOLID, 4160, 6240, &lens, why, sizeof why));
    CHECK_NEAR(lens.focal_px, 8 * 4160 / 24.0, 1e-9);
    /* An explicit sensor attribute wins over the table. */
    sl_error err;
    CHECK_OK(sl_meta_set(&meta, SL_ATTR_SENSOR_MM, "36 x 24", &err), &err);
    CHECK(sl_stitch_lens_from_meta(&meta, SL_LENS_EQUISOLID, 6240, 4160, &lens, why, sizeof why));
    CHECK_NEAR(lens.focal_px, 8 * 6240 / 36.0, 1e-9);
    sl_meta_free(&meta);
}

int main(void)
{
    RUN(merged_exr_carries_lens);
    RUN(mixed_lenses_refused);
    RUN(missing_values_named);
    return sl_test_finish();
}
