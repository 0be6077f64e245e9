/* SPDX-License-Identifier: BSD-3-Clause */
/* Simulated set captures: the files a seed makes, EXIF read back through
 * OpenImageIO against the exposure plan, ground truth, and refusing to
 * overwrite. Frames are tiny so the test stays fast. */
#include <jansson.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "setlight/vset.h"
#include "testing.h"

static void tiny_opts(sl_vset_capture_opts *o, const char *scene, uint64_t seed)
{
    sl_vset_desc d;
    sl_vset_preset(scene, &d, NULL);
    sl_vset_capture_defaults(o, &d, SL_VSET_SIZE_TINY);
    o->latlong_width = 128;
    o->photo_width = 96;
    o->photo_height = 64;
    o->supersample = 1;
    o->probe_width = 0;
    o->seed = seed;
}

/* The probe photos as the capture lists them, read back: EXIF as the plan
 * says, and the truth's geometry consistent with the lens and the files. */
static void check_probes(const char *dir, const sl_vset_capture_opts *o)
{
    char path[4096];
    json_error_t je;
    sl_error err;
    snprintf(path, sizeof path, "%s/capture.json", dir);
    json_t *cap = json_load_file(path, 0, &je);
    snprintf(path, sizeof path, "%s/truth/probes.json", dir);
    json_t *truth = json_load_file(path, 0, &je);
    CHECK(cap && truth);
    if (!cap || !truth)
        return;
    json_t *probes = json_object_get(cap, "probes"), *tp = json_object_get(truth, "probes");
    CHECK(json_array_size(probes) == 3 && json_array_size(tp) == 3);
    static const char *const kinds[3] = {"chrome", "grey", "chart"};
    static const size_t counts[3] = {7, 3, 3};
    int frame = 22; /* after the 21 HDRI frames */
    for (size_t i = 0; i < 3 && i < json_array_size(probes); i++) {
        json_t *p = json_array_get(probes, i), *t = json_array_get(tp, i);
        CHECK(strcmp(json_string_value(json_object_get(p, "kind")), kinds[i]) == 0);
        CHECK(strcmp(json_string_value(json_object_get(t, "kind")), kinds[i]) == 0);
        json_t *frames = json_object_get(p, "frames"), *names = json_object_get(t, "frames");
        CHECK(json_array_size(frames) == counts[i] && json_array_size(names) == counts[i]);
        double focal = json_number_value(json_object_get(t, "focal_mm"));
        double sw = json_number_value(json_object_get(t, "sensor_width_mm"));
        int w = (int)json_integer_value(json_object_get(t, "width"));
        int h = (int)json_integer_value(json_object_get(t, "height"));
        CHECK(w == o->probe_width && h == o->probe_height);
        CHECK_NEAR(json_number_value(json_object_get(t, "focal_px")), focal * w / sw, 1e-6);
        json_t *ball = json_object_get(t, "ball");
        if (ball) {
            double dist = json_number_value(json_object_get(t, "distance_m"));
            double dia = json_number_value(json_object_get(ball, "diameter_m"));
            CHECK_NEAR(json_number_value(json_object_get(ball, "r_px")),
                       focal * w / sw * tan(asin(0.5 * dia / dist)), 1e-6);
            CHECK_NEAR(json_number_value(json_object_get(ball, "cx")), 0.5 * w, 1e-9);
            CHECK_NEAR(json_number_value(json_object_get(ball, "distance_radii")),
                       dist / (0.5 * dia), 1e-9);
        } else {
            CHECK(json_array_size(json_object_get(json_object_get(t, "chart"), "patch_centers")) ==
                  24);
        }
        double prev = 0;
        for (size_t k = 0; k < json_array_size(frames); k++) {
            json_t *f = json_array_get(frames, k);
            const char *name = json_string_value(json_object_get(f, "name"));
            char want[32];
            snprintf(want, sizeof want, "IMG_%04d", frame++);
            CHECK(strcmp(name, want) == 0);
            CHECK(strcmp(name, json_string_value(json_array_get(names, k))) == 0);
            double t_s = json_number_value(json_object_get(f, "exposure_time_s"));
            CHECK(t_s > prev);
            prev = t_s;
            const char *exts[] = {".jpg", ".tif", "_linear.tif"};
            for (int e = 0; e < 3; e++) {
                snprintf(path, sizeof path, "%s/probes/%s%s", dir, name, exts[e]);
                sl_meta m;
                int pw, ph, pc;
                CHECK_OK(sl_photo_read_meta(path, &m, &pw, &ph, &pc, &err), &err);
                CHECK(pw == w && ph == h && pc == 3);
                CHECK_NEAR(m.exposure_time / t_s, 1, 1e-4);
                CHECK_NEAR(m.f_number, o->f_number, 1e-5);
                CHECK(e != 0 || fabs(m.iso - o->iso) < 1e-9);
                CHECK_NEAR(m.focal_length_mm, focal, 1e-5);
                CHECK(strstr(m.lens, "200mm") != NULL);
                CHECK(strcmp(m.datetime, json_string_value(json_object_get(f, "datetime"))) ==
                      0);
                sl_meta_free(&m);
            }
        }
        /* The render kept as truth is the probe photo's size. */
        snprintf(path, sizeof path, "%s/%s", dir,
                 json_string_value(json_object_get(t, "radiance")));
        sl_image img;
        sl_meta m;
        CHECK_OK(sl_exr_read(path, &img, &m, &err), &err);
        CHECK(img.width == w && img.height == h);
        sl_image_free(&img);
        sl_meta_free(&m);
    }
    /* The chrome ball is bracketed like the HDRI. */
    json_t *f0 = json_array_get(json_object_get(json_array_get(probes, 0), "frames"), 0);
    json_t *h0 = json_array_get(json_object_get(cap, "frames"), 0);
    CHECK(json_number_value(json_object_get(f0, "exposure_time_s")) ==
          json_number_value(json_object_get(h0, "exposure_time_s")));
    json_decref(cap);
    json_decref(truth);
}

static int same_file(const char *a, const char *b)
{
    size_t na, nb;
    char *x = sl_test_read_file(a, &na), *y = sl_test_read_file(b, &nb);
    int same = x && y && na == nb && memcmp(x, y, na) == 0;
    free(x);
    free(y);
    return same;
}

static void test_capture_and_exif(void)
{
    sl_vset_capture_opts o;
    sl_error err;
    sl_vset_capture_summary s;
    tiny_opts(&o, "exterior", 1);
    o.probe_width = 96;
    o.probe_height = 64;
    const char *a = sl_test_path("cap_a");
    CHECK_OK(sl_vset_capture_write(&o, a, &s, &err), &err);
    CHECK(s.frames == 21 && s.views == 3 && s.probe_frames == 13);
    check_probes(a, &o);
    /* The classic 7 x 3-stop bracket on nominal shutter speeds. */
    CHECK_NEAR(s.min_time_s, 1.0 / 8000, 1e-12);
    CHECK_NEAR(s.max_time_s, 30, 1e-12);

    char path[4096];
    snprintf(path, sizeof path, "%s/capture.json", a);
    json_error_t je;
    json_t *root = json_load_file(path, 0, &je);
    CHECK(root != NULL);
    json_t *frames = json_object_get(root, "frames");
    CHECK(json_array_size(frames) == 21);
    int checked = 0;
    for (size_t i = 0; i < json_array_size(frames); i++) {
        json_t *f = json_array_get(frames, i);
        const char *name = json_string_value(json_object_get(f, "name"));
        double t = json_number_value(json_object_get(f, "exposure_time_s"));
        int bracket = (int)json_integer_value(json_object_get(f, "bracket"));
        /* Nominal speeds: 3 stops apart to within a tenth of a stop each. */
        CHECK_NEAR(log2(t / s.center_time_s), 3 * (bracket - 3), 0.1 * abs(bracket - 3) + 1e-8);
        const char *exts[] = {".jpg", ".tif", "_linear.tif"};
        for (int e = 0; e < 3; e++) {
            snprintf(path, sizeof path, "%s/hdri/%s%s", a, name, exts[e]);
            sl_meta m;
            int w, h, c;
            CHECK_OK(sl_photo_read_meta(path, &m, &w, &h, &c, &err), &err);
            CHECK(w == 96 && h == 64 && c == 3);
            /* EXIF rationals as OIIO forms them: within 1e-4. */
            CHECK_NEAR(m.exposure_time / t, 1, 1e-4);
            CHECK_NEAR(m.f_number, o.f_number, 1e-5);
            /* OIIO 2.4 keeps ISO in JPEG EXIF but not in TIFF (core docs). */
            CHECK(e != 0 || fabs(m.iso - o.iso) < 1e-9);
            CHECK_NEAR(m.focal_length_mm, 8, 1e-5);
            CHECK(strcmp(m.make, "setlight") == 0);
            CHECK(strstr(m.model, "virtual") != NULL);
            CHECK(strstr(m.lens, "fisheye") != NULL);
            CHECK(strcmp(m.datetime, json_string_value(json_object_get(f, "datetime"))) == 0);
            CHECK(e != 1 || m.bits_per_sample == 16);
            sl_meta_free(&m);
            checked++;
        }
    }
    CHECK(checked == 63);
    json_decref(root);

    /* Ground truth beside the frames. */
    sl_image ll;
    sl_meta m;
    snprintf(path, sizeof path, "%s/truth/latlong.exr", a);
    CHECK_OK(sl_exr_read(path, &ll, &m, &err), &err);
    CHECK(ll.width == 128 && ll.height == 64 && m.envmap == SL_ENVMAP_LATLONG);
    sl_vset_scene sc;
    CHECK_OK(sl_vset_scene_make(&o.scene, 128, &sc, &err), &err);
    CHECK(memcmp(ll.data, sc.latlong.data, sizeof(float) * 128 * 64 * 3) == 0);
    sl_vset_scene_free(&sc);
    sl_image_free(&ll);
    sl_meta_free(&m);
    snprintf(path, sizeof path, "%s/truth/lights.json", a);
    root = json_load_file(path, 0, &je);
    CHECK(root && json_array_size(json_object_get(root, "lights")) == 1);
    json_decref(root);
    snprintf(path, sizeof path, "%s/truth/camera.json", a);
    root = json_load_file(path, 0, &je);
    CHECK(root && json_array_size(json_object_get(json_object_get(root, "response"), "curve")) ==
                      SL_VSET_CRF_SAMPLES);
    json_decref(root);

    /* Same seed, same bytes; another seed, other noise and head errors but
     * the same scene and probes. */
    const char *b = sl_test_path("cap_b"), *c = sl_test_path("cap_c");
    sl_threads_set(1);
    CHECK_OK(sl_vset_capture_write(&o, b, NULL, &err), &err);
    sl_threads_set(0);
    tiny_opts(&o, "exterior", 2);
    o.probe_width = 96;
    o.probe_height = 64;
    CHECK_OK(sl_vset_capture_write(&o, c, NULL, &err), &err);
    const char *files[] = {"capture.json",          "hdri/IMG_0001.jpg",
                           "hdri/IMG_0010.tif",     "hdri/IMG_0021_linear.tif",
                           "probes/IMG_0022.jpg",   "probes/IMG_0030.tif",
                           "probes/IMG_0034_linear.tif", "truth/latlong.exr",
                           "truth/camera.json",     "truth/probes.json",
                           "truth/probe_chrome.exr", "truth/probe_chart.exr"};
    for (int i = 0; i < 12; i++) {
        char pa[4096], pb[4096], pc[4096];
        snprintf(pa, sizeof pa, "%s/%s", a, files[i]);
        snprintf(pb, sizeof pb, "%s/%s", b, files[i]);
        snprintf(pc, sizeof pc, "%s/%s", c, files[i]);
        CHECK_MSG(same_file(pa, pb), "%s differs between runs with one seed", files[i]);
        /* The head's true poses (truth/camera.json) come from the seed too. */
        bool truth = strncmp(files[i], "truth/", 6) == 0 && strcmp(files[i], "truth/camera.json");
        CHECK_MSG(same_file(pa, pc) == truth, "%s: seed changes %s", files[i],
                  truth ? "the truth" : "nothing");
    }
}

static void test_refusals(void)
{
    sl_vset_capture_opts o;
    sl_error err;
    tiny_opts(&o, "night", 3);
    o.views = 1;
    o.brackets = 2;
    const char *top = sl_test_path("refusals");
    mkdir(top, 0777);
    char d[2048];
    snprintf(d, sizeof d, "%s/cap", top);
    CHECK_OK(sl_vset_capture_write(&o, d, NULL, &err), &err);
    char path[4096];
    snprintf(path, sizeof path, "%s/capture.json", d);
    size_t n0;
    char *before = sl_test_read_file(path, &n0);
    /* A capture is there: refused, untouched, no temporary left. */
    o.seed = 4;
    o.brackets = 3;
    CHECK_RESULT(sl_vset_capture_write(&o, d, NULL, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, d) && strstr(err.message, "--force"));
    size_t n1;
    char *after = sl_test_read_file(path, &n1);
    CHECK(before && after && n0 == n1 && memcmp(before, after, n0) == 0);
    free(after);
    CHECK(sl_test_count_files(top) == 1);
    /* --force replaces it. */
    o.force = true;
    CHECK_OK(sl_vset_capture_write(&o, d, NULL, &err), &err);
    after = sl_test_read_file(path, &n1);
    CHECK(after && (n0 != n1 || memcmp(before, after, n0) != 0));
    snprintf(path, sizeof path, "%s/hdri", d);
    CHECK(sl_test_count_files(path) == 9);
    free(before);
    free(after);
    CHECK(sl_test_count_files(top) == 1);

    /* A folder holding other files is never touched, even with force. */
    const char *other = sl_test_path("photos");
    mkdir(other, 0777);
    snprintf(path, sizeof path, "%s/keep.txt", other);
    FILE *f = fopen(path, "w");
    fputs("mine\n", f);
    fclose(f);
    CHECK_RESULT(sl_vset_capture_write(&o, other, NULL, &err), SL_ERR_USAGE, &err);
    CHECK(sl_test_count_files(other) == 1);
    /* An empty folder is filled. */
    const char *empty = sl_test_path("empty");
    mkdir(empty, 0777);
    o.force = false;
    CHECK_OK(sl_vset_capture_write(&o, empty, NULL, &err), &err);
    CHECK(sl_test_count_files(empty) == 3);
    /* Cannot create: an I/O error naming the folder. */
    CHECK_RESULT(sl_vset_capture_write(&o, "/proc/setlight-no/cap", NULL, &err), SL_ERR_IO, &err);
    CHECK(strstr(err.message, "/proc/setlight-no/cap") != NULL);
    /* A bad plan. */
    o.brackets = 0;
    CHECK_RESULT(sl_vset_capture_write(&o, sl_test_path("never"), NULL, &err), SL_ERR_USAGE, &err);
    CHECK(!sl_test_file_exists(sl_test_path("never")));
}

static double jnum(json_t *o, const char *key) { return json_number_value(json_object_get(o, key)); }

static json_t *frames_of(const char *dir)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/capture.json", dir);
    json_error_t je;
    return json_load_file(path, 0, &je);
}

static json_t *camera_truth_of(const char *dir)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/truth/camera.json", dir);
    json_error_t je;
    return json_load_file(path, 0, &je);
}

static double frame_num(json_t *root, int i, const char *key)
{
    return json_number_value(json_object_get(json_array_get(json_object_get(root, "frames"), (size_t)i), key));
}

/* Zenith view, hand-held jitter and a walking person. */
static void test_views_jitter_ghost(void)
{
    sl_vset_capture_opts o;
    sl_error err;
    sl_vset_capture_summary s;
    tiny_opts(&o, "stage", 9);
    o.zenith = true;
    o.brackets = 3;
    const char *plain = sl_test_path("plain"), *moved = sl_test_path("moved");
    CHECK_OK(sl_vset_capture_write(&o, plain, &s, &err), &err);
    CHECK(s.frames == 12 && s.views == 4);
    json_t *plan = frames_of(plain);
    CHECK(frame_num(plan, 11, "pitch_deg") == 90 && frame_num(plan, 3, "yaw_deg") == 120);
    CHECK(frame_num(plan, 4, "roll_deg") == 0);
    CHECK(jnum(plan, "focal_mm") == 8 && jnum(plan, "sensor_width_mm") == 36);
    CHECK(json_is_null(json_object_get(json_array_get(json_object_get(plan, "frames"), 0), "ghost")));
    json_decref(plan);
    /* The head is off its plan by the documented amounts; view 0 defines the frame. */
    json_t *a = camera_truth_of(plain);
    json_t *views = json_object_get(a, "views");
    CHECK(json_array_size(views) == 4);
    for (size_t v = 0; v < json_array_size(views); v++) {
        json_t *tv = json_array_get(views, v), *pv = json_object_get(tv, "plan");
        double dy = jnum(tv, "yaw_deg") - jnum(pv, "yaw_deg");
        double dp = jnum(tv, "pitch_deg") - jnum(pv, "pitch_deg");
        double dr = jnum(tv, "roll_deg") - jnum(pv, "roll_deg");
        printf("  view %zu: head off its plan by yaw %+.3f, pitch %+.3f, roll %+.3f deg\n", v, dy,
               dp, dr);
        if (v == 0) {
            CHECK(dy == 0 && dp == 0 && dr == 0);
            continue;
        }
        CHECK(fabs(dy) >= 0.5 && fabs(dy) <= 1.0);
        CHECK(fabs(dp) >= 0.3 && fabs(dp) <= 0.5);
        CHECK(fabs(dr) >= 0.3 && fabs(dr) <= 0.5);
        if (v == 3)
            CHECK(dp < 0); /* the zenith view tilts down from the zenith */
    }

    o.jitter_deg = 0.5;
    o.ghost = true;
    CHECK_OK(sl_vset_capture_write(&o, moved, &s, &err), &err);
    json_t *b = camera_truth_of(moved);
    double wander = 0;
    for (int i = 0; i < 12; i++) {
        double dy = frame_num(b, i, "yaw_deg") - frame_num(a, i, "yaw_deg");
        double dp = frame_num(b, i, "pitch_deg") - frame_num(a, i, "pitch_deg");
        double dr = frame_num(b, i, "roll_deg") - frame_num(a, i, "roll_deg");
        wander += dy * dy + dp * dp + dr * dr;
    }
    double sd = sqrt(wander / (3 * 12));
    printf("  jitter: measured %.3f deg for 0.5 asked\n", sd);
    CHECK(sd > 0.3 && sd < 0.7);
    /* The ghost walks across view 0 only, 4 degrees per frame. */
    json_t *moved_plan = frames_of(moved);
    json_t *f0 = json_array_get(json_object_get(moved_plan, "frames"), 0);
    json_t *f1 = json_array_get(json_object_get(moved_plan, "frames"), 1);
    json_t *f7 = json_array_get(json_object_get(moved_plan, "frames"), 3);
    CHECK_NEAR(json_number_value(json_object_get(json_object_get(f1, "ghost"), "azimuth_deg")) -
                   json_number_value(json_object_get(json_object_get(f0, "ghost"), "azimuth_deg")),
               4, 1e-9);
    CHECK(json_is_null(json_object_get(f7, "ghost")));
    json_decref(moved_plan);
    json_decref(a);
    json_decref(b);
    /* Ghost without jitter: view 0 frames change, the others stay the same bytes. */
    const char *ghost = sl_test_path("ghost");
    o.jitter_deg = 0;
    CHECK_OK(sl_vset_capture_write(&o, ghost, &s, &err), &err);
    char p1[4096], p2[4096];
    snprintf(p1, sizeof p1, "%s/hdri/IMG_0002.tif", plain);
    snprintf(p2, sizeof p2, "%s/hdri/IMG_0002.tif", ghost);
    CHECK(!same_file(p1, p2));
    snprintf(p1, sizeof p1, "%s/hdri/IMG_0005.tif", plain);
    snprintf(p2, sizeof p2, "%s/hdri/IMG_0005.tif", ghost);
    CHECK(same_file(p1, p2));
    o.jitter_deg = 11;
    CHECK_RESULT(sl_vset_capture_write(&o, sl_test_path("never2"), NULL, &err), SL_ERR_USAGE, &err);
}


/* A core lens from truth/camera.json's record of it. */
static void lens_of(json_t *j, sl_lens *l)
{
    memset(l, 0, sizeof *l);
    l->projection = (sl_lens_projection)sl_lens_projection_from_name(
        json_string_value(json_object_get(j, "projection")));
    l->width = (int)json_integer_value(json_object_get(j, "width"));
    l->height = (int)json_integer_value(json_object_get(j, "height"));
    l->focal_px = jnum(j, "focal_px");
    l->cx = jnum(j, "cx");
    l->cy = jnum(j, "cy");
    for (int i = 0; i < 3; i++) {
        l->k[i] = json_number_value(json_array_get(json_object_get(j, "k"), (size_t)i));
        l->vignette[i] =
            json_number_value(json_array_get(json_object_get(j, "vignette"), (size_t)i));
    }
    l->max_theta_deg = jnum(j, "max_theta_deg");
    l->circle_radius_px = jnum(j, "circle_radius_px");
}

/* The frames, inverted with nothing but the files of the capture (EXIF and
 * truth/camera.json), give back the ground-truth lat-long: the camera,
 * lens, EXIF and truth agree. */
static void test_frames_invert_to_truth(void)
{
    sl_vset_capture_opts o;
    sl_error err;
    tiny_opts(&o, "exterior", 5);
    o.photo_width = 240;
    o.photo_height = 160;
    o.supersample = 1; /* point samples at pixel centres: what a lookup gives */
    const char *dir = sl_test_path("invert");
    CHECK_OK(sl_vset_capture_write(&o, dir, NULL, &err), &err);
    char path[4096];
    snprintf(path, sizeof path, "%s/truth/camera.json", dir);
    json_error_t je;
    json_t *cam = json_load_file(path, 0, &je);
    CHECK(cam != NULL);
    if (!cam)
        return;
    sl_vset_response resp;
    memset(&resp, 0, sizeof resp);
    json_t *curve = json_object_get(json_object_get(cam, "response"), "curve");
    for (int i = 0; i < SL_VSET_CRF_SAMPLES; i++)
        resp.curve[i] = json_number_value(json_array_get(curve, (size_t)i));
    double m[3][3], minv[3][3];
    json_t *mj = json_object_get(cam, "output_from_rec709");
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            m[i][j] = json_number_value(json_array_get(json_array_get(mj, (size_t)i), (size_t)j));
    double det = m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
                 m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
                 m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            int a = (j + 1) % 3, b = (j + 2) % 3, c = (i + 1) % 3, d = (i + 2) % 3;
            minv[i][j] = (m[a][c] * m[b][d] - m[a][d] * m[b][c]) / det;
        }
    sl_lens lens;
    lens_of(json_object_get(cam, "lens"), &lens);
    /* The truth records every lens field: the one the frames were made with. */
    sl_lens made;
    sl_vset_fisheye_true(&made, 240, 160);
    CHECK(lens.projection == made.projection && lens.width == 240 && lens.height == 160);
    CHECK_NEAR(lens.focal_px, made.focal_px, 1e-6);
    CHECK_NEAR(lens.cx, made.cx, 1e-6);
    CHECK_NEAR(lens.cy, made.cy, 1e-6);
    CHECK_NEAR(lens.circle_radius_px, made.circle_radius_px, 1e-6);
    for (int i = 0; i < 3; i++) {
        CHECK_NEAR(lens.k[i], made.k[i], 1e-9);
        CHECK_NEAR(lens.vignette[i], made.vignette[i], 1e-9);
    }
    CHECK(lens.focal_px != 8.0 * 240 / 36 && lens.cx != 120); /* not the nominal lens */
    json_t *true_frames = json_incref(json_object_get(cam, "frames"));
    double k = jnum(cam, "k");
    json_decref(cam);

    sl_image truth;
    sl_meta tm;
    snprintf(path, sizeof path, "%s/truth/latlong.exr", dir);
    CHECK_OK(sl_exr_read(path, &truth, &tm, &err), &err);
    sl_meta_free(&tm);
    json_t *capj = frames_of(dir);
    json_t *frames = json_object_get(capj, "frames");
    int used = 0, close = 0;
    double sum_rel = 0;
    for (size_t f = 0; f < json_array_size(frames); f++) {
        json_t *fr = json_array_get(frames, f);
        snprintf(path, sizeof path, "%s/hdri/%s.tif", dir,
                 json_string_value(json_object_get(fr, "name")));
        sl_image img;
        sl_meta meta;
        CHECK_OK(sl_photo_read(path, &img, &meta, &err), &err);
        /* Exposure from EXIF (TIFF loses ISO in OIIO 2.4: it is in the plan). */
        double scale = meta.exposure_time * (jnum(fr, "iso") / 100.0) * k /
                       (meta.f_number * meta.f_number);
        json_t *tf = json_array_get(true_frames, f);
        CHECK(!strcmp(json_string_value(json_object_get(tf, "name")),
                      json_string_value(json_object_get(fr, "name"))));
        sl_view_pose view = {jnum(tf, "yaw_deg"), jnum(tf, "pitch_deg"), jnum(tf, "roll_deg")};
        double rot[3][3];
        sl_view_pose_matrix(&view, rot);
        for (int y = 4; y < img.height - 4; y += 2)
            for (int x = 4; x < img.width - 4; x += 2) {
                const float *p = sl_image_pixel(&img, x, y);
                double lin[3], est[3] = {0, 0, 0}, dir3[3], ok = 1;
                for (int c = 0; c < 3; c++) {
                    lin[c] = sl_vset_response_invert(&resp, p[c]);
                    if (lin[c] < 0.1 || lin[c] > 0.7)
                        ok = 0;
                }
                double ray[3];
                if (!ok || !sl_lens_pixel_to_ray(&lens, x + 0.5, y + 0.5, ray))
                    continue;
                sl_mat3_apply(rot, ray, dir3);
                double g = sl_lens_vignette(&lens, x + 0.5, y + 0.5);
                for (int i = 0; i < 3; i++)
                    for (int j = 0; j < 3; j++)
                        est[i] += minv[i][j] * lin[j] / (scale * g);
                double u, v;
                sl_dir_to_latlong(dir3, &u, &v);
                float ref[3];
                sl_latlong_lookup(&truth, u, v, ref);
                double ly = sl_luminance(est);
                double ry = sl_luminance_px(ref);
                double rel = ly / ry - 1;
                used++;
                sum_rel += rel;
                /* 5% is over 2.5 sigma of shot noise at the darkest pixels used. */
                if (fabs(rel) < 0.05)
                    close++;
            }
        sl_image_free(&img);
        sl_meta_free(&meta);
    }
    json_decref(capj);
    json_decref(true_frames);
    sl_image_free(&truth);
    printf("  %d well-exposed pixels: %.2f%% within 5%% of the truth, mean error %.3f%%\n", used,
           100.0 * close / used, 100.0 * sum_rel / used);
    CHECK(used > 2000);
    CHECK((double)close / used > 0.995);
    CHECK(fabs(sum_rel / used) < 0.002);
}

int main(void)
{
    RUN(test_capture_and_exif);
    RUN(test_refusals);
    RUN(test_views_jitter_ghost);
    RUN(test_frames_invert_to_truth);
    return sl_test_finish();
}
