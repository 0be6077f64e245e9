/* SPDX-License-Identifier: BSD-3-Clause */
/* Lens profiles: a written profile reads back to the same doubles; each kind
 * of bad file is refused with one line naming the file and the field; a
 * profile fits its own camera and size, a downsized copy with its focal
 * length, centre and circle scaled, and nothing else. */
#include "testing.h"

#include "setlight/stitch.h"

#include <stdlib.h>
#include <string.h>

static sl_lens_profile sample_profile(void)
{
    sl_lens_profile p;
    memset(&p, 0, sizeof p);
    sl_lens_nominal(&p.lens, SL_LENS_EQUISOLID, 1600, 1600, 8.0, 24.0);
    p.lens.focal_px = 541.123456789012345;
    p.lens.cx = 801.25;
    p.lens.cy = 797.5;
    p.lens.k[0] = 0.015625;
    p.lens.k[1] = -0.00390625;
    p.lens.vignette[0] = -0.125;
    p.lens.circle_radius_px = 770.0;
    snprintf(p.camera, sizeof p.camera, "Canon EOS 6D Mark II");
    snprintf(p.lens_name, sizeof p.lens_name, "8mm");
    p.source = SL_LENS_SOURCE_CHESSBOARD;
    p.rms_px = 0.42;
    p.max_px = 1.3;
    p.images = 14;
    return p;
}

/* Field by field: struct copies need not copy the padding. */
static bool lens_equal(const sl_lens *a, const sl_lens *b)
{
    return a->projection == b->projection && a->width == b->width && a->height == b->height &&
           a->focal_px == b->focal_px && a->cx == b->cx && a->cy == b->cy &&
           memcmp(a->k, b->k, sizeof a->k) == 0 &&
           memcmp(a->vignette, b->vignette, sizeof a->vignette) == 0 &&
           a->max_theta_deg == b->max_theta_deg && a->circle_radius_px == b->circle_radius_px;
}

static void round_trip(void)
{
    sl_error err;
    sl_lens_profile p = sample_profile(), q;
    const char *path = sl_test_path("lens.json");
    CHECK_OK(sl_lens_profile_write(path, &p, &err), &err);
    CHECK_OK(sl_lens_profile_read(path, &q, &err), &err);
    CHECK(lens_equal(&p.lens, &q.lens));
    CHECK(strcmp(q.camera, p.camera) == 0 && strcmp(q.lens_name, p.lens_name) == 0);
    CHECK(q.source == SL_LENS_SOURCE_CHESSBOARD && q.images == 14);
    CHECK(q.rms_px == p.rms_px && q.max_px == p.max_px);
    /* A profile read would refuse is not written either, and nothing is left. */
    p.lens.k[0] = -0.4;
    const char *bad = sl_test_path("bad_written.json");
    CHECK_RESULT(sl_lens_profile_write(bad, &p, &err), SL_ERR_INPUT, &err);
    CHECK(!sl_test_file_exists(bad));
}

/* Writes the sample profile with `from` replaced by `to` in its text. */
static const char *edited(const char *name, const char *from, const char *to)
{
    sl_error err;
    sl_lens_profile p = sample_profile();
    const char *path = sl_test_path(name);
    if (sl_lens_profile_write(path, &p, &err))
        return path;
    char *text = sl_test_read_file(path, NULL);
    char *at = text ? strstr(text, from) : NULL;
    CHECK_MSG(at != NULL, "%s not in the profile", from);
    if (at) {
        FILE *f = fopen(path, "w");
        fprintf(f, "%.*s%s%s", (int)(at - text), text, to, at + strlen(from));
        fclose(f);
    }
    free(text);
    return path;
}

static void expect_refused(const char *path, const char *what)
{
    sl_error err;
    sl_lens_profile q;
    sl_result r = sl_lens_profile_read(path, &q, &err);
    CHECK_MSG(r == SL_ERR_INPUT, "%s: %s, expected SL_ERR_INPUT", path, sl_result_name(r));
    CHECK_MSG(strstr(err.message, path) != NULL && strstr(err.message, what) != NULL &&
                  strchr(err.message, '\n') == NULL,
              "message \"%s\" should name %s and say %s on one line", err.message, path, what);
}

static void bad_files(void)
{
    expect_refused(edited("missing.json", "\"focal_px\"", "\"focal\""),
                   "\"focal_px\" is missing");
    expect_refused(edited("type.json", "\"cx\": 801.25", "\"cx\": \"801\""),
                   "\"cx\" is not a finite number");
    expect_refused(edited("projection.json", "\"equisolid\"", "\"fisheye\""),
                   "unknown projection \"fisheye\"");
    /* k1 = -0.3: r = f q (1 - 0.3 q^2) peaks at q = 1.05, 63 deg off-axis. */
    expect_refused(edited("monotone.json", "0.015625", "-0.3"), "stop increasing");
    expect_refused(edited("nan.json", "0.015625", "NaN"), "JSON syntax error");
    expect_refused(edited("vignette.json", "-0.125", "-0.8"), "vignetting");
    expect_refused(edited("centre.json", "\"cy\": 797.5", "\"cy\": 1700"), "off the");
    expect_refused(edited("k.json", "\"k\": [", "\"k\": [1, "), "\"k\" is not three");
    expect_refused(edited("format.json", "setlight-lens", "setlight-response"), "format");
    sl_error err;
    sl_lens_profile q;
    CHECK_RESULT(sl_lens_profile_read(sl_test_path("absent.json"), &q, &err), SL_ERR_NOT_FOUND,
                 &err);
}

static void fits(void)
{
    sl_lens_profile p = sample_profile();
    sl_lens l;
    char why[256];
    CHECK(sl_lens_profile_fits(&p, 1600, 1600, "canon eos 6d mark ii", "8mm", &l, why, sizeof why));
    CHECK(why[0] == '\0' && lens_equal(&l, &p.lens));
    /* EXIF's make + model names the camera too. */
    CHECK(sl_lens_profile_fits(&p, 1600, 1600, "Canon Canon EOS 6D Mark II", "8mm", &l, why,
                               sizeof why));
    CHECK(!sl_lens_profile_fits(&p, 1600, 1600, "Canon EOS 6D Mark", NULL, &l, why, sizeof why));
    CHECK(!sl_lens_profile_fits(&p, 1600, 1600, "Canon EOS 60D Mark II", NULL, &l, why, sizeof why));
    /* Unknown camera or lens on either side is not compared. */
    CHECK(sl_lens_profile_fits(&p, 1600, 1600, "", NULL, &l, why, sizeof why));
    CHECK(!sl_lens_profile_fits(&p, 1600, 1600, "NIKON D850", "8mm", &l, why, sizeof why));
    CHECK(strstr(why, "NIKON D850") != NULL);
    CHECK(!sl_lens_profile_fits(&p, 1600, 1600, NULL, "Sigma 15mm", &l, why, sizeof why));
    CHECK(strstr(why, "lens") != NULL);
    CHECK(!sl_lens_profile_fits(&p, 1600, 1200, NULL, NULL, &l, why, sizeof why));
    CHECK(strstr(why, "1600x1200") != NULL);
    /* Downsized to half: the same rays land on half the pixel coordinates. */
    CHECK(sl_lens_profile_fits(&p, 800, 800, NULL, NULL, &l, why, sizeof why));
    CHECK(strstr(why, "scaled") != NULL);
    CHECK_NEAR(l.focal_px, 0.5 * p.lens.focal_px, 1e-12);
    CHECK_NEAR(l.cx, 400.625, 1e-12);
    CHECK_NEAR(l.circle_radius_px, 385.0, 1e-12);
    double ray[3], x, y;
    CHECK(sl_lens_pixel_to_ray(&p.lens, 1200.0, 500.0, ray));
    CHECK(sl_lens_ray_to_pixel(&l, ray, &x, &y));
    CHECK_NEAR(x, 600.0, 1e-9);
    CHECK_NEAR(y, 250.0, 1e-9);
}

int main(void)
{
    RUN(round_trip);
    RUN(bad_files);
    RUN(fits);
    return sl_test_finish();
}
