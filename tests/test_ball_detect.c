/* SPDX-License-Identifier: BSD-3-Clause */
/* Chrome-ball detection on ray-traced photos with clutter (radius and centre
 * within 0.5 px of the traced outline), the refusals (no ball, two balls, a
 * ball cut by the frame) and the real iPhone probe photos when present. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "ball_fixture.h"
#include "setlight/stitch.h"
#include "setlight/vset.h"
#include "testing.h"

/* Finds the ball in f's photo and prints the errors and the CPU seconds:
 * both errors must be within `tolerance` px; a negative one (the slow rows
 * below) only prints, a refusal too. */
static void detect_case(const ball_fixture *f, const char *what, double tolerance)
{
    sl_image photo = {0};
    sl_error err;
    CHECK_OK(ball_fixture_render(f, &photo, &err), &err);
    sl_ball_circle want, got;
    ball_fixture_circle(f, 0, &want);
    double t = sl_cpu_seconds();
    sl_result r = sl_ball_detect(&photo, what, &got, &err);
    t = sl_cpu_seconds() - t;
    sl_image_free(&photo);
    if (r) {
        printf("  %s: refused, %.2f s CPU: %s\n", what, t, err.message);
        CHECK_MSG(tolerance < 0.0, "%s: %s", what, err.message);
        return;
    }
    double dc = hypot(got.cx - want.cx, got.cy - want.cy), dr = fabs(got.r - want.r);
    printf("  %s: true %.2f,%.2f r %.2f, found %.2f,%.2f r %.2f: centre %.3f px, radius %.3f "
           "px, residual %.3f px, standard error %.3f px, %d edge points, %.2f s CPU\n",
           what, want.cx, want.cy, want.r, got.cx, got.cy, got.r, dc, dr, got.residual,
           got.uncertainty, got.edge_points, t);
    fflush(stdout);
    if (tolerance >= 0.0) {
        CHECK_MSG(dr <= tolerance, "%s: radius off by %.3f px", what, dr);
        CHECK_MSG(dc <= tolerance, "%s: centre off by %.3f px", what, dc);
    }
}

static void test_synthetic(void)
{
    ball_fixture f;
    ball_fixture_init(&f, 240, 180);
    f.ss = 3;
    f.balls[0].px = 131.4;
    f.balls[0].py = 84.7;
    f.balls[0].r = 50.3;
    detect_case(&f, "orthographic, clutter", 0.5);
    f.clutter = false;
    detect_case(&f, "orthographic, flat background", 0.5);
    f.clutter = true;
    sl_reflectance_chrome(&f.reflectance);
    f.perspective = true;
    f.focal_px = 200;
    f.balls[0].distance = 4.0;
    f.balls[0].px = 100.2;
    f.balls[0].py = 95.6;
    detect_case(&f, "perspective chrome, clutter", 0.5);
    f.balls[0].px = 150;
    f.balls[0].py = 70;
    f.balls[0].distance = 5.5;
    detect_case(&f, "perspective chrome, off-centre, small", 0.5);
}


/* A ball filling its frame, the format most published probes come in: its
 * outline touches the four sides, only the corners hold background. */
static void test_fill_frame(void)
{
    int largest = sl_test_sanitized() ? 256 : 512;
    for (int n = 128; n <= largest; n *= 2)
        for (int clutter = 0; clutter < 2; clutter++) {
            ball_fixture f;
            ball_fixture_init(&f, n, n);
            f.ss = 3;
            f.ss_rim_only = true;
            f.clutter = clutter;
            f.balls[0].px = f.balls[0].py = f.balls[0].r = 0.5 * n;
            char what[64];
            snprintf(what, sizeof what, "filling %dx%d, %s", n, n, clutter ? "clutter" : "flat");
            detect_case(&f, what, 0.3);
        }
    /* A hand crop: the outline touches top and bottom, 4 px short of the
     * sides; then five times larger: on its copy (a fifth of the size) the
     * clutter in the corners, averaged, pulled the outline past the frame,
     * so the frame's candidate is also walked in on the full image. */
    for (int scale = 1; scale <= (sl_test_sanitized() ? 1 : 5); scale += 4) {
        ball_fixture f;
        ball_fixture_init(&f, 480 * scale, 472 * scale);
        f.ss = 3;
        f.ss_rim_only = true;
        f.balls[0].px = 240.3 * scale;
        f.balls[0].py = 236.2 * scale;
        f.balls[0].r = 235.5 * scale;
        sl_reflectance_chrome(&f.reflectance);
        char what[64];
        snprintf(what, sizeof what, "crop %dx%d, chrome", f.width, f.height);
        detect_case(&f, what, scale == 1 ? 0.4 : 0.3);
    }
}

/* The ball among round things that are not balls (a disc, a dark disc, a
 * ring, a clock face) and a second, smaller ball, laid out on a 1600x1200
 * frame and scaled to `width`: the large ball is the probe. */
static void round_clutter_scene(ball_fixture *f, int width)
{
    double s = width / 1600.0;
    ball_fixture_init(f, width, (int)lround(1200 * s));
    f->ss = 2;
    f->ss_rim_only = true;
    f->ball_count = 2;
    f->balls[0].px = 900 * s;
    f->balls[0].py = 640 * s;
    f->balls[0].r = 220 * s;
    f->balls[1] = f->balls[0];
    f->balls[1].px = 300 * s;
    f->balls[1].py = 950 * s;
    f->balls[1].r = 110 * s;
    sl_reflectance_chrome(&f->reflectance);
    f->thing_count = 4;
    f->things[0] = (ball_thing){BALL_THING_DISC, 250 * s, 260 * s, 180 * s, 0, 0.7};
    f->things[1] = (ball_thing){BALL_THING_RING, 1380 * s, 300 * s, 170 * s, 120 * s, 0.9};
    f->things[2] = (ball_thing){BALL_THING_DIAL, 1350 * s, 900 * s, 200 * s, 0, 0.85};
    f->things[3] = (ball_thing){BALL_THING_DISC, 620 * s, 230 * s, 90 * s, 0, 0.02};
}

static void test_round_clutter(void)
{
    if (sl_test_sanitized())
        return;
    ball_fixture f;
    round_clutter_scene(&f, 1200);
    detect_case(&f, "1200x900, disc, ring, dial, a smaller ball", 0.5);
}

static void expect_refusal(const ball_fixture *f, const char *what, const char *text)
{
    sl_image photo = {0};
    sl_error err;
    CHECK_OK(ball_fixture_render(f, &photo, &err), &err);
    sl_ball_circle got;
    CHECK_RESULT(sl_ball_detect(&photo, what, &got, &err), SL_ERR_INPUT, &err);
    printf("  %s: %s\n", what, err.message);
    CHECK_MSG(strstr(err.message, text) != NULL, "%s: message lacks '%s'", what, text);
    CHECK(strncmp(err.message, what, strlen(what)) == 0);
    sl_image_free(&photo);
}

/* Two whole balls (x, y, r) of which neither is the probe. */
static void expect_two_balls(int width, int height, const double a[3], const double b[3],
                             const char *what)
{
    ball_fixture f;
    ball_fixture_init(&f, width, height);
    f.ss = 2;
    f.ss_rim_only = true;
    f.ball_count = 2;
    const double *ab[2] = {a, b};
    for (int i = 0; i < 2; i++) {
        f.balls[i].px = ab[i][0];
        f.balls[i].py = ab[i][1];
        f.balls[i].r = ab[i][2];
    }
    expect_refusal(&f, what, "2 balls");
}

static void test_refusals(void)
{
    ball_fixture f;
    ball_fixture_init(&f, 240, 180);
    f.ss = 2;
    f.ball_count = 0;
    expect_refusal(&f, "clutter.exr", "no chrome ball");
    expect_two_balls(240, 180, (const double[3]){65, 90, 40}, (const double[3]){170, 90, 45},
                     "two.exr");
    /* One ball fills the frame's height, another beside it: the frame's
     * own candidate finds the first, and the search goes on (room for a
     * rival) to the second. */
    expect_two_balls(800, 300, (const double[3]){400, 150, 148}, (const double[3]){130, 150, 110},
                     "two_wide.exr");
    ball_fixture_init(&f, 240, 180);
    f.ss = 2;
    f.ball_count = 1;
    f.balls[0].px = 205;
    f.balls[0].py = 80;
    f.balls[0].r = 55;
    expect_refusal(&f, "clipped.exr", "cut by the frame edge");
}

static void test_real_probes(void)
{
    static const char *names[] = {"probes/chromeball_iphone7/10.JPG",
                                  "probes/chromeball_iphone7/40.JPG",
                                  "probes/chromeball_iphone7/160.JPG"};
    /* Under sanitizers (slow) only the last, whole one. */
    int first = sl_test_sanitized() ? 2 : 0;
    double r0 = 0.0;
    for (int i = first; i < 3; i++) {
        const char *path = sl_test_data(names[i]);
        if (!path)
            return;
        sl_image img = {0};
        sl_meta meta;
        sl_error err;
        CHECK_OK(sl_image_read(path, &img, &meta, &err), &err);
        sl_meta_free(&meta);
        if (!img.data)
            return;
        for (size_t k = 0; k < img.stride * img.height; k++)
            img.data[k] = sl_srgb_to_linear(img.data[k]);
        /* These crops hold the ball edge to edge; some cut a few pixels off
         * its top. Either way the ball must be found, and a cut one refused. */
        sl_ball_circle c;
        sl_result r = sl_ball_detect(&img, path, &c, &err);
        bool cut = c.cy - c.r < -1.0 || c.cx - c.r < -1.0 || c.cx + c.r > img.width + 1.0 ||
                   c.cy + c.r > img.height + 1.0;
        printf("  %s (%dx%d): %.2f,%.2f r %.2f, residual %.3f px, %d edge points %s\n",
               names[i], img.width, img.height, c.cx, c.cy, c.r, c.residual, c.edge_points,
               r ? err.message : "");
        CHECK(r == (cut ? SL_ERR_INPUT : SL_OK));
        CHECK_MSG(cut == (i == 0), "%s: %s", names[i], cut ? "cut" : "whole"); /* 10.JPG's top is cut */
        if (r)
            CHECK(strstr(err.message, "cut by the frame edge") != NULL);
        CHECK(c.r > 0.45 * img.height && c.r < 0.55 * img.height);
        CHECK(fabs(c.cx - 0.5 * img.width) < 0.1 * img.width);
        CHECK(c.residual < 2.0);
        if (i == first)
            r0 = c.r;
        else
            CHECK_NEAR(c.r, r0, 12.0); /* the same blurred ball; crops differ by a few pixels */
        sl_image_free(&img);
    }
}

static void expect_fisheye(const sl_image *img, bool srgb, const char *what, bool fisheye)
{
    sl_fisheye_evidence ev;
    sl_error err;
    sl_result r = sl_fisheye_check(img, srgb, what, &ev, &err);
    printf("  %s: border %.3g, round %d (%.1f,%.1f r %.1f), dark outside %.3f, margin %.3f, rim "
           "%.2f: %s\n",
           what, ev.border_level, ev.round, ev.cx, ev.cy, ev.r, ev.dark_outside, ev.margin,
           ev.rim_ratio, r ? err.message : "not a fisheye");
    CHECK_MSG(ev.fisheye == fisheye, "%s: taken for %s", what, ev.fisheye ? "a fisheye" : "no fisheye");
    CHECK(r == (fisheye ? SL_ERR_INPUT : SL_OK));
    if (r) {
        CHECK(strncmp(err.message, what, strlen(what)) == 0);
        CHECK(strstr(err.message, "circular fisheye") && strstr(err.message, "'setlight stitch'"));
    }
}

/* A circular fisheye is told from a ball photo and from the angular and
 * mirror-ball maps of the same environment, which are dark outside too. */
static void test_fisheye(void)
{
    sl_image img = {0}, ll = {0}, map = {0};
    sl_error err;
    CHECK_OK(ball_fixture_fisheye(300, 200, 90, &img, &err), &err);
    expect_fisheye(&img, false, "fisheye.exr", true);
    sl_image_free(&img);
    /* cropped square around its circle, still with a black band */
    CHECK_OK(ball_fixture_fisheye(200, 200, 94, &img, &err), &err);
    expect_fisheye(&img, false, "fisheye_square.exr", true);
    sl_image_free(&img);

    ball_fixture f;
    ball_fixture_init(&f, 256, 8);
    CHECK_OK(ball_fixture_truth(&f, 256, 2, &ll, &err), &err);
    CHECK_OK(sl_reproject(&ll, SL_PROJ_LATLONG, SL_PROJ_ANGULAR, 512, NULL, &map, &err), &err);
    expect_fisheye(&map, false, "angular.exr", false);
    sl_image_free(&map);
    CHECK_OK(sl_reproject(&ll, SL_PROJ_LATLONG, SL_PROJ_MIRRORBALL, 512, NULL, &map, &err), &err);
    expect_fisheye(&map, false, "mirrorball.exr", false);
    sl_image_free(&map);
    sl_image_free(&ll);

    ball_fixture_init(&f, 240, 180);
    f.ss = 1;
    CHECK_OK(ball_fixture_render(&f, &img, &err), &err);
    expect_fisheye(&img, false, "ball.exr", false);
    sl_image_free(&img);
    f.clutter = false; /* a ball on a dark backdrop: its rim and the backdrop */
    CHECK_OK(ball_fixture_render(&f, &img, &err), &err);
    expect_fisheye(&img, false, "ball_dark.exr", false);
    sl_image_free(&img);

}

static void expect_map(const sl_image *img, const char *what, bool map)
{
    bool is_map = !map;
    sl_error err;
    sl_result r = sl_probe_map_check(img, what, &is_map, &err);
    printf("  %s: %s\n", what, r ? err.message : "not a map");
    CHECK_MSG(is_map == map, "%s: taken for %s", what, is_map ? "a map" : "a photo");
    CHECK(r == (map ? SL_ERR_INPUT : SL_OK));
    if (r) {
        CHECK(strncmp(err.message, what, strlen(what)) == 0);
        CHECK(strstr(err.message, "light-probe map") &&
              strstr(err.message, "'setlight convert --from angular'") &&
              strstr(err.message, "--circle"));
    }
}

/* Angular and mirror-ball maps (a disc inscribed in a square frame, black
 * around it) are told from photos of a ball filling its frame, whose
 * corners show the set, dark or busy. */
static void test_probe_maps(void)
{
    sl_image ll = {0}, map = {0}, img = {0};
    sl_error err;
    ball_fixture f;
    ball_fixture_init(&f, 256, 8);
    CHECK_OK(ball_fixture_truth(&f, 256, 2, &ll, &err), &err);
    CHECK_OK(sl_reproject(&ll, SL_PROJ_LATLONG, SL_PROJ_ANGULAR, 512, NULL, &map, &err), &err);
    expect_map(&map, "angular.exr", true);
    sl_image_free(&map);
    CHECK_OK(sl_reproject(&ll, SL_PROJ_LATLONG, SL_PROJ_MIRRORBALL, 512, NULL, &map, &err), &err);
    expect_map(&map, "mirrorball.exr", true);
    sl_image_free(&map);
    /* The back hemisphere 10^-3 of the front (a sunset's ground): its disc
     * at the fisheye check's level is smaller than the frame, yet the map
     * is lit to the frame's edge, so it is a map, not a fisheye. */
    for (int y = 0; y < ll.height; y++)
        for (int x = 0; x < ll.width; x++)
            if (x < ll.width / 4 || x >= 3 * ll.width / 4 || y > ll.height * 3 / 5)
                for (int k = 0; k < 3; k++)
                    sl_image_pixel(&ll, x, y)[k] *= 1e-3f;
    CHECK_OK(sl_reproject(&ll, SL_PROJ_LATLONG, SL_PROJ_ANGULAR, 512, NULL, &map, &err), &err);
    sl_fisheye_evidence ev;
    CHECK_OK(sl_fisheye_check(&map, false, "dark_back.exr", &ev, &err), &err);
    CHECK(!ev.fisheye);
    expect_map(&map, "dark_back.exr", true);
    sl_image_free(&map);
    sl_image_free(&ll);
    for (int clutter = 0; clutter < 2; clutter++) {
        ball_fixture_init(&f, 128, 128);
        f.ss = 2;
        f.ss_rim_only = true;
        f.clutter = clutter;
        f.balls[0].px = f.balls[0].py = f.balls[0].r = 64;
        CHECK_OK(ball_fixture_render(&f, &img, &err), &err);
        expect_map(&img, clutter ? "ball_fill_clutter.exr" : "ball_fill_dark.exr", false);
        sl_image_free(&img);
    }
}

/* Real round images when present: the Sigma 8 mm fisheyes, the iPhone
 * ball crops, Debevec's angular Grace probe; each told as a fisheye (or
 * not) and as a light-probe map (or not). */
static void test_real_round_images(void)
{
    static const struct {
        const char *name;
        bool fisheye, map;
    } real[] = {{"fisheye/sigma8mm_canon6d/IMG_2843.JPG", true, false},
                {"fisheye/sigma8mm_canon6d/IMG_2938.JPG", true, false},
                {"probes/chromeball_iphone7/160.JPG", false, false},
                {"probes/chromeball_iphone7/10.JPG", false, false},
                {"probes/grace_probe_angular.hdr", false, true}};
    for (size_t i = 0; i < sizeof real / sizeof real[0]; i++) {
        const char *path = sl_test_data(real[i].name);
        if (!path)
            continue;
        sl_image img;
        sl_meta meta;
        sl_error err;
        CHECK_OK(sl_image_read(path, &img, &meta, &err), &err);
        expect_fisheye(&img, !meta.is_float, path, real[i].fisheye);
        expect_map(&img, path, real[i].map);
        sl_meta_free(&meta);
        sl_image_free(&img);
    }
}

/* The rows of docs/unwrap.md's detection table that are too slow for the
 * suite: `test_ball_detect --rows [TEXT]` runs those whose name holds TEXT
 * and prints each one's errors or refusal and its CPU seconds (no timing is
 * asserted: the machine is shared). */
static void row(const ball_fixture *f, const char *what, const char *filter)
{
    if (!filter || strstr(what, filter))
        detect_case(f, what, -1.0);
}

static void rows(const char *filter)
{
    static const int fills[] = {1024, 2048, 2600, 3000, 4096};
    for (size_t i = 0; i < sizeof fills / sizeof fills[0]; i++)
        for (int clutter = 0; clutter < 2; clutter++) {
            ball_fixture f;
            ball_fixture_init(&f, fills[i], fills[i]);
            f.ss = fills[i] >= 4096 ? 1 : 3;
            f.ss_rim_only = true;
            f.clutter = clutter;
            f.balls[0].px = f.balls[0].py = f.balls[0].r = 0.5 * fills[i];
            char what[64];
            snprintf(what, sizeof what, "filling %dx%d, %s", fills[i], fills[i],
                     clutter ? "clutter" : "flat");
            row(&f, what, filter);
        }
    static const int scenes[] = {800, 1200, 1600};
    for (size_t i = 0; i < sizeof scenes / sizeof scenes[0]; i++) {
        ball_fixture f;
        round_clutter_scene(&f, scenes[i]);
        char what[64];
        snprintf(what, sizeof what, "scene %dx%d", f.width, f.height);
        row(&f, what, filter);
    }
}

/* The night scene's chrome ball, shot and merged as `setlight process`
 * does at the tiny size: a ball darker than a noisy sky (ISO 400), with
 * lamps reflected in it millions of times brighter than the sky. The log's
 * offset taken from those lamps flattened the whole frame (no ball found). */
static void test_night_ball(void)
{
    sl_vset_desc desc;
    sl_vset_capture_opts o;
    sl_error err;
    CHECK_OK(sl_vset_preset("night", &desc, &err), &err);
    sl_vset_capture_defaults(&o, &desc, SL_VSET_SIZE_TINY);
    o.views = 1;
    o.force = true;
    const char *dir = sl_test_path("night_ball_capture");
    CHECK_OK(sl_vset_capture_write(&o, dir, NULL, &err), &err);
    /* The chrome ball's bracket: the first probe frames. */
    char paths[16][4096];
    const char *ptrs[16];
    int n = 0;
    for (int i = 1; i < 200 && n < o.brackets && n < 16; i++) {
        snprintf(paths[n], sizeof paths[n], "%s/probes/IMG_%04d_linear.tif", dir, i);
        FILE *fp = fopen(paths[n], "rb");
        if (fp) {
            fclose(fp);
            ptrs[n] = paths[n];
            n++;
        }
    }
    CHECK(n == o.brackets);
    sl_merge_options opt;
    sl_merge_options_init(&opt);
    sl_merge_result m;
    CHECK_OK(sl_merge(ptrs, n, &opt, &m, &err), &err);
    if (!m.radiance.data)
        return;
    sl_vset_probe p;
    sl_vset_probe_default(&p, SL_VSET_PROBE_CHROME, m.radiance.width, m.radiance.height);
    /* On the axis: the ball's silhouette is the circle at the frame's
     * centre of radius f tan(asin(R / d)). */
    double focal_px = p.lens.focal_mm * m.radiance.width / p.lens.sensor_width_mm;
    sl_ball_circle truth = {.cx = 0.5 * m.radiance.width, .cy = 0.5 * m.radiance.height,
                            .r = focal_px * tan(asin(0.5 * p.size_m / p.distance_m))};
    const sl_ball_circle *geo = &truth;
    sl_ball_circle got;
    CHECK_OK(sl_ball_detect(&m.radiance, "night ball", &got, &err), &err);
    double dc = hypot(got.cx - geo->cx, got.cy - geo->cy), dr = fabs(got.r - geo->r);
    printf("  night ball: true %.2f,%.2f r %.2f, found %.2f,%.2f r %.2f (centre %.3f px, "
           "radius %.3f px, standard error %.3f px)\n",
           geo->cx, geo->cy, geo->r, got.cx, got.cy, got.r, dc, dr, got.uncertainty);
    CHECK_MSG(dc < 1.0, "night ball: centre off by %.3f px", dc);
    CHECK_MSG(dr < 1.0, "night ball: radius off by %.3f px", dr);

    /* Pure noise at the night sky's level with a few lamp-bright specks:
     * no ball. */
    sl_image noise = {0};
    CHECK_OK(sl_image_alloc(&noise, m.radiance.width, m.radiance.height, 3, &err), &err);
    uint64_t seed = 7;
    for (int y = 0; y < noise.height; y++)
        for (int x = 0; x < noise.width; x++) {
            seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
            double u = (double)(seed >> 11) / 9007199254740992.0;
            seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
            double v = (double)(seed >> 11) / 9007199254740992.0;
            double g = sqrt(-2.0 * log(u + 1e-300)) * cos(2.0 * M_PI * v);
            double l = fmax(0.0, 1e-5 * (1.0 + 0.2 * g));
            if ((x * 31 + y * 17) % 997 == 0)
                l = 30.0;
            float *px = sl_image_pixel(&noise, x, y);
            px[0] = px[1] = px[2] = (float)l;
        }
    CHECK_RESULT(sl_ball_detect(&noise, "noise.exr", &got, &err), SL_ERR_INPUT, &err);
    printf("  noise.exr: %s\n", err.message);
    CHECK(strstr(err.message, "no chrome ball") != NULL);
    sl_image_free(&noise);
    sl_merge_result_free(&m);
}

int main(int argc, char **argv)
{
    if (argc > 1 && strcmp(argv[1], "--rows") == 0) {
        rows(argc > 2 ? argv[2] : NULL);
        return sl_test_finish();
    }
    RUN(test_fisheye);
    RUN(test_probe_maps);
    RUN(test_real_round_images);
    RUN(test_synthetic);
    RUN(test_fill_frame);
    RUN(test_round_clutter);
    RUN(test_refusals);
    RUN(test_real_probes);
    RUN(test_night_ball);
    return sl_test_finish();
}
