/* SPDX-License-Identifier: BSD-3-Clause */
/* The whole capture path without hardware, through the virtual set's camera
 * (sl_camera_open_virtual): a full 3 x 7 session (frames, journal,
 * checksums, EXIF, session.json), the faults of the capture issue (a shutter
 * change ignored, caught by EXIF and by pixels independently; busy replies;
 * a refused setting; a disconnect with reconnection and one without, then
 * --resume; a resume folder that is not a session or has a corrupt journal),
 * image formats (raw+jpeg shots with siblings, raw alone verified on the
 * DNG, a format change ignored and caught, a link dropped between a shot's
 * JPEG and raw, then --resume; another --format refused), and ingest of
 * virtual-set frames in shuffled names, including frames shot less than a
 * second apart. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "capture_check.h"
#include "setlight/vset.h"
#include "testing.h"

/* The fault tests: 7 frames 2 stops apart around the metered speed. */
static int plan(sl_camera *cam, double **times)
{
    return cap_plan_of(cam, "7x2", 1.0 / 125, times);
}

static void test_camera_interface(void)
{
    sl_camera *cam = (sl_camera *)1;
    sl_error err;
    /* Before its backend registers, "virtual" is a port libgphoto2 does not know. */
    CHECK_RESULT(sl_camera_open("virtual:exterior", &cam, &err), SL_ERR_USAGE, &err);
    CHECK(cam == NULL && strstr(err.message, "virtual:exterior") != NULL);
    CHECK_OK(sl_vset_camera_register(&err), &err);
    CHECK_OK(sl_vset_camera_register(&err), &err); /* a second time does nothing */
    CHECK_RESULT(sl_camera_open("virtual:nowhere", &cam, &err), SL_ERR_USAGE, &err);
    CHECK(cam == NULL && strstr(err.message, "nowhere") && strstr(err.message, "virtual"));
    CHECK_RESULT(sl_camera_open("virtual:/no/such/scene.json", &cam, &err), SL_ERR_NOT_FOUND,
                 &err);
    CHECK(strstr(err.message, "/no/such/scene.json") != NULL);

    CHECK_OK(sl_camera_open("virtual:exterior", &cam, &err), &err);
    if (!cam)
        return;
    CHECK(!strcmp(sl_camera_backend(cam), "virtual"));
    CHECK(!strcmp(sl_camera_port(cam), "virtual:exterior"));
    double *speeds;
    int n;
    CHECK_OK(sl_camera_shutter_speeds(cam, &speeds, &n, &err), &err);
    CHECK(n == 55 && fabs(speeds[0] - 1.0 / 8000) < 1e-12 && speeds[n - 1] == 30);
    free(speeds);
    /* metered for daylight at f/16 ISO 100: a fast shutter */
    sl_camera_settings now;
    CHECK_OK(sl_camera_get(cam, &now, &err), &err);
    CHECK(now.f_number == 16 && now.iso == 100);
    CHECK_MSG(now.exposure_time > 1.0 / 8000 && now.exposure_time < 1.0 / 15, "metered %g s",
              now.exposure_time);
    /* settings snap to what the body offers */
    sl_camera_settings set = {1.0 / 120, 7.0, 300};
    CHECK_OK(sl_camera_set(cam, &set, &err), &err);
    CHECK_OK(sl_camera_get(cam, &now, &err), &err);
    CHECK_NEAR(now.exposure_time, 1.0 / 125, 1e-12);
    CHECK(now.f_number == 8 && now.iso == 400);
    sl_camera_shot shot;
    CHECK_OK(sl_camera_capture(cam, &shot, &err), &err);
    sl_camera_file *file = &shot.files[0];
    CHECK(shot.count == 1 && shot.expected == 1 && shot.busy_retries == 0);
    CHECK(!strcmp(file->source, "/DCIM/100VSET/IMG_0001.JPG"));
    const char *path = sl_test_path("one.jpg");
    CHECK_OK(sl_write_file_atomic(path, file->data, file->size, &err), &err);
    sl_camera_shot_free(&shot);
    sl_image img;
    sl_meta meta;
    CHECK_OK(sl_photo_read(path, &img, &meta, &err), &err);
    if (img.data) {
        CHECK(img.width == 360 && img.height == 240);
        CHECK_NEAR(meta.exposure_time, 1.0 / 125, 1e-6);
        CHECK(meta.f_number == 8 && meta.iso == 400);
        CHECK(!strcmp(meta.datetime, "2026:05:14 10:00:00"));
        CHECK(!strcmp(meta.make, "setlight") && !strcmp(meta.model, "virtual camera"));
        sl_image_free(&img);
        sl_meta_free(&meta);
    }
    sl_camera_close(cam);
}

static void test_full_capture(void)
{
    sl_virtual_camera_opts vo;
    cap_vopts(&vo);
    snprintf(vo.scene, sizeof vo.scene, "stage");
    sl_camera *cam = cap_open_virtual(&vo);
    if (!cam)
        return;
    double *times;
    int n = cap_plan_of(cam, "7x3", 1.0 / 30, &times);
    const char *dir = sl_test_path("full");
    sl_capture_options o = cap_options(dir, times, n, 3);
    sl_error err;
    double t0 = sl_seconds();
    CHECK_OK(sl_capture_run(cam, &o, &err), &err);
    printf("full 3x7 capture with the virtual camera: %.2f s\n", sl_seconds() - t0);
    cap_check_session(dir, 3, n, times);
    CHECK(sl_test_count_files(dir) == 21 + 2);
    /* the head turned: the views' centre frames differ */
    char a[4096], b[4096];
    snprintf(a, sizeof a, "%s/v00_f03.jpg", dir);
    snprintf(b, sizeof b, "%s/v01_f03.jpg", dir);
    sl_image ia, ib;
    if (!sl_photo_read(a, &ia, NULL, &err) && !sl_photo_read(b, &ib, NULL, &err)) {
        double d = 0;
        size_t m = (size_t)ia.width * ia.height * ia.channels;
        for (size_t i = 0; i < m; i++)
            d += fabs(ia.data[i] - ib.data[i]);
        CHECK_MSG(d / (double)m > 0.01, "views 0 and 1 look alike (%g)", d / (double)m);
        sl_image_free(&ia);
        sl_image_free(&ib);
    }
    /* a second session in the same folder is refused, nothing touched */
    CHECK_RESULT(sl_capture_run(cam, &o, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "already holds a session") != NULL);
    free(times);
    sl_camera_close(cam);
}

/* Runs a 1 x N session of plan `spec` (NxS around 1/125 s) in `format`
 * with these faults, reconnecting for `reconnect` seconds; returns the
 * journal. */
static json_t *run_format(const char *name, const char *spec, sl_virtual_camera_opts *vo,
                          sl_image_format format, double reconnect, sl_result want, sl_error *err,
                          double **times_out)
{
    sl_camera *cam = cap_open_virtual(vo);
    if (!cam)
        return json_array();
    double *times;
    int n = cap_plan_of(cam, spec, 1.0 / 125, &times);
    sl_capture_options o = cap_options(sl_test_path(name), times, n, 1);
    o.format = format;
    o.reconnect_seconds = reconnect;
    CHECK_RESULT(sl_capture_run(cam, &o, err), want, err);
    sl_camera_close(cam);
    if (want == SL_OK)
        cap_check_session(o.dir, 1, n, times);
    if (times_out)
        *times_out = times;
    else
        free(times);
    return cap_journal(o.dir);
}

/* 1 x 7, 2 stops apart, in the camera's format, reconnecting for 5 s. */
static json_t *run_with(const char *name, sl_virtual_camera_opts *vo, sl_result want, sl_error *err,
                        double **times_out)
{
    return run_format(name, "7x2", vo, SL_FORMAT_KEEP, 5, want, err, times_out);
}

static void test_ignored_shutter(void)
{
    sl_virtual_camera_opts vo;
    sl_error err;
    /* the first change (frame 0, nothing to compare pixels with): EXIF */
    cap_vopts(&vo);
    vo.ignore_shutter = 1;
    json_t *j = run_with("ignored1", &vo, SL_OK, &err, NULL);
    json_t *rej = cap_events(j, "frame", 0);
    CHECK(json_array_size(rej) == 1);
    json_t *r = json_array_get(rej, 0);
    CHECK(cap_ival(r, "index") == 0 && json_is_false(json_object_get(r, "exif_ok")) &&
          json_is_null(json_object_get(r, "pixels_ok")));
    json_decref(rej);
    json_decref(j);

    /* the fourth change: EXIF and pixels both see it */
    cap_vopts(&vo);
    vo.ignore_shutter = 4;
    j = run_with("ignored4", &vo, SL_OK, &err, NULL);
    rej = cap_events(j, "frame", 0);
    CHECK(json_array_size(rej) == 1);
    r = json_array_get(rej, 0);
    CHECK(cap_ival(r, "index") == 3 && cap_ival(r, "attempt") == 1);
    CHECK(json_is_false(json_object_get(r, "exif_ok")) &&
          json_is_false(json_object_get(r, "pixels_ok")));
    CHECK(strstr(cap_str(r, "reason"), "the file says") && strstr(cap_str(r, "reason"), "pixels are"));
    /* the pixels did not change: the old speed was used again */
    CHECK_NEAR(json_real_value(json_object_get(r, "measured_ratio")), 1.0, 0.1);
    json_t *acc = cap_events(j, "frame", 1);
    size_t i;
    json_t *e;
    json_array_foreach(acc, i, e) if (cap_ival(e, "index") == 3)
    {
        CHECK(cap_ival(e, "attempt") == 2 && json_is_true(json_object_get(e, "pixels_ok")));
        double ratio = json_real_value(json_object_get(e, "measured_ratio")) /
                       json_real_value(json_object_get(e, "expected_ratio"));
        CHECK_MSG(fabs(log2(ratio)) < 0.25, "retry ratio off by %g", ratio);
    }
    json_decref(acc);
    json_decref(rej);
    json_decref(j);

    /* a stuck mechanism: EXIF and the setting say the new speed, only the
     * pixels tell */
    cap_vopts(&vo);
    vo.ignore_shutter = 4;
    vo.exif_lies = true;
    j = run_with("lies", &vo, SL_OK, &err, NULL);
    rej = cap_events(j, "frame", 0);
    CHECK(json_array_size(rej) == 1);
    r = json_array_get(rej, 0);
    CHECK(cap_ival(r, "index") == 3 && json_is_true(json_object_get(r, "exif_ok")) &&
          json_is_false(json_object_get(r, "pixels_ok")));
    CHECK(!strstr(cap_str(r, "reason"), "the file says") && strstr(cap_str(r, "reason"), "pixels are"));
    json_decref(rej);
    json_decref(j);
}

static void test_busy(void)
{
    sl_virtual_camera_opts vo;
    sl_error err;
    cap_vopts(&vo);
    vo.busy = 3;
    vo.busy_at = 5;
    json_t *j = run_with("busy", &vo, SL_OK, &err, NULL);
    json_t *acc = cap_events(j, "frame", 1), *e;
    size_t i;
    int waited = 0;
    json_array_foreach(acc, i, e)
    {
        int b = cap_ival(e, "busy_retries");
        if (b)
            CHECK(cap_ival(e, "index") == 4 && b == 3);
        waited += b;
    }
    CHECK(waited == 3);
    json_t *errs = cap_events(j, "error", -1);
    CHECK(json_array_size(errs) == 0);
    json_decref(errs);
    json_decref(acc);
    json_decref(j);

    /* busy past the retries: a clear failure, earlier frames kept */
    cap_vopts(&vo);
    vo.busy = 1000;
    vo.busy_at = 3;
    j = run_with("busyforever", &vo, SL_ERR_CAMERA, &err, NULL);
    CHECK(strstr(err.message, "busy") && strstr(err.message, "virtual:exterior"));
    acc = cap_events(j, "frame", 1);
    errs = cap_events(j, "error", -1);
    CHECK(json_array_size(acc) == 2);
    CHECK(json_array_size(errs) == 1 && cap_ival(json_array_get(errs, 0), "index") == 2);
    json_decref(errs);
    json_decref(acc);
    json_decref(j);
}

static void test_refused_setting(void)
{
    sl_virtual_camera_opts vo;
    sl_error err;
    cap_vopts(&vo);
    vo.refuse_shutter = 1.0 / 125;
    double *times;
    json_t *j = run_with("refused", &vo, SL_ERR_CAMERA, &err, &times);
    CHECK(strstr(err.message, "refused") && strstr(err.message, "1/125") &&
          strstr(err.message, "virtual:exterior"));
    json_t *acc = cap_events(j, "frame", 1), *errs = cap_events(j, "error", -1),
           *rec = cap_events(j, "reconnect", -1);
    CHECK(json_array_size(acc) == 3);
    CHECK(json_array_size(errs) == 1 && cap_ival(json_array_get(errs, 0), "index") == 3);
    /* a refusal is not a lost connection */
    CHECK(json_array_size(rec) == 0);
    json_decref(rec);
    json_decref(errs);
    json_decref(acc);
    json_decref(j);
    /* session.json lists what is there and the failure */
    char sp[4096];
    snprintf(sp, sizeof sp, "%s/session.json", sl_test_path("refused"));
    json_error_t je;
    json_t *s = json_load_file(sp, 0, &je);
    CHECK(s && json_array_size(json_object_get(s, "problems")) == 1);
    json_decref(s);
    /* with a camera that takes 1/125, --resume finishes the bracket */
    cap_vopts(&vo);
    sl_camera *cam = cap_open_virtual(&vo);
    sl_capture_options o;
    memset(&o, 0, sizeof o);
    if (cam) {
        CHECK_OK(sl_capture_resume(cam, &o, sl_test_path("refused"), &err), &err);
        sl_camera_close(cam);
    }
    cap_check_session(sl_test_path("refused"), 1, 7, times);
    free(times);
}

static void test_reconnect(void)
{
    sl_virtual_camera_opts vo;
    cap_vopts(&vo);
    vo.drop_after = 10;
    vo.down_attempts = 2;
    sl_camera *cam = cap_open_virtual(&vo);
    if (!cam)
        return;
    double *times;
    int n = plan(cam, &times);
    const char *dir = sl_test_path("reconnect");
    sl_capture_options o = cap_options(dir, times, n, 3);
    sl_error err;
    CHECK_OK(sl_capture_run(cam, &o, &err), &err);
    sl_camera_close(cam);
    cap_check_session(dir, 3, n, times);
    json_t *j = cap_journal(dir);
    json_t *errs = cap_events(j, "error", -1), *rec = cap_events(j, "reconnect", -1);
    CHECK(json_array_size(errs) == 1 && cap_ival(json_array_get(errs, 0), "view") == 1 &&
          cap_ival(json_array_get(errs, 0), "index") == 3);
    CHECK(json_array_size(rec) == 1 && json_is_true(json_object_get(json_array_get(rec, 0), "ok")) &&
          cap_ival(json_array_get(rec, 0), "tries") == 3);
    /* card numbering goes on: every source once */
    json_t *fr = cap_events(j, "frame", -1), *e;
    size_t i;
    json_array_foreach(fr, i, e) for (size_t k = 0; k < i; k++)
        CHECK(strcmp(cap_str(e, "source"), cap_str(json_array_get(fr, k), "source")));
    json_decref(fr);
    json_decref(rec);
    json_decref(errs);
    json_decref(j);
    free(times);
}

static void test_disconnect_and_resume(void)
{
    sl_virtual_camera_opts vo;
    cap_vopts(&vo);
    vo.drop_after = 10;
    vo.down_attempts = -1;
    sl_camera *cam = cap_open_virtual(&vo);
    if (!cam)
        return;
    double *times;
    int n = plan(cam, &times);
    const char *dir = sl_test_path("drop");
    sl_capture_options o = cap_options(dir, times, n, 3);
    o.reconnect_seconds = 0.6;
    sl_error err;
    double t0 = sl_seconds();
    CHECK_RESULT(sl_capture_run(cam, &o, &err), SL_ERR_CAMERA, &err);
    double waited = sl_seconds() - t0;
    sl_camera_close(cam);
    CHECK(strstr(err.message, "virtual:exterior") && strstr(err.message, "lost") &&
          strstr(err.message, "--resume"));
    CHECK(!strchr(err.message, '\n'));
    CHECK_MSG(waited < 10, "gave up after %.1f s", waited);
    CHECK(sl_test_count_files(dir) == 10 + 2);
    json_t *j = cap_journal(dir);
    json_t *acc = cap_events(j, "frame", 1), *rec = cap_events(j, "reconnect", -1);
    CHECK(json_array_size(acc) == 10);
    CHECK(json_array_size(rec) == 1 && json_is_false(json_object_get(json_array_get(rec, 0), "ok")));
    json_decref(rec);
    json_decref(acc);
    json_decref(j);

    /* not a session, or a corrupt journal: refused, nothing written */
    const char *plain = sl_test_path("plain");
    mkdir(plain, 0755);
    cap_vopts(&vo);
    cam = cap_open_virtual(&vo);
    if (!cam)
        return;
    sl_capture_options ro;
    memset(&ro, 0, sizeof ro);
    CHECK_RESULT(sl_capture_resume(cam, &ro, plain, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, plain) && strstr(err.message, "not a capture session"));
    CHECK(sl_test_count_files(plain) == 0);
    char jp[4096], cmd[8192];
    snprintf(jp, sizeof jp, "%s/journal.jsonl", dir);
    size_t before_size;
    char *before = sl_test_read_file(jp, &before_size);
    const char *bad = sl_test_path("corrupt");
    snprintf(cmd, sizeof cmd, "cp -r '%s' '%s' && printf '{\"event\": \"fra' >> '%s/journal.jsonl'",
             dir, bad, bad);
    CHECK(system(cmd) == 0);
    snprintf(jp, sizeof jp, "%s/journal.jsonl", bad);
    size_t bad_size;
    char *bad_before = sl_test_read_file(jp, &bad_size);
    CHECK_RESULT(sl_capture_resume(cam, &ro, bad, &err), SL_ERR_INPUT, &err);
    int lines = 1;
    for (size_t i = 0; before && i < before_size; i++)
        lines += before[i] == '\n';
    char want[32];
    snprintf(want, sizeof want, "line %d", lines);
    CHECK_MSG(strstr(err.message, want) != NULL, "%s (want %s)", err.message, want);
    size_t after_size;
    char *bad_after = sl_test_read_file(jp, &after_size);
    CHECK(bad_before && bad_after && bad_size == after_size &&
          !memcmp(bad_before, bad_after, bad_size));
    free(bad_before);
    free(bad_after);

    /* resume: the next missing frame onwards, none twice */
    t0 = sl_seconds();
    CHECK_OK(sl_capture_resume(cam, &ro, dir, &err), &err);
    sl_camera_close(cam);
    cap_check_session(dir, 3, n, times);
    char *after = sl_test_read_file(sl_test_path("drop/journal.jsonl"), NULL);
    /* append-only: the old journal is a prefix of the new one */
    CHECK(before && after && !strncmp(before, after, before_size));
    free(before);
    free(after);
    j = cap_journal(dir);
    json_t *res = cap_events(j, "resume", -1);
    CHECK(json_array_size(res) == 1);
    json_t *r = json_array_get(res, 0);
    CHECK(cap_ival(r, "frames_done") == 10 && cap_ival(r, "next_view") == 1 && cap_ival(r, "next_index") == 3);
    /* the first frame after the gap is measured against the last before it */
    json_t *fr = cap_events(j, "frame", 1);
    json_t *first = json_array_get(fr, 10);
    CHECK(cap_ival(first, "view") == 1 && cap_ival(first, "index") == 3 &&
          json_real_value(json_object_get(first, "measured_ratio")) > 0);
    json_decref(fr);
    json_decref(res);
    json_decref(j);
    free(times);
}

/* Every accepted frame of `dir` is a DNG with one JPEG sibling, both on
 * disk with their journalled SHA-256; session.json lists the siblings and
 * the format with the camera's label. */
static void check_raw_jpeg(const char *dir, int count)
{
    json_t *j = cap_journal(dir);
    json_t *acc = cap_events(j, "frame", 1);
    size_t i;
    json_t *e;
    json_array_foreach(acc, i, e)
    {
        json_t *sib = json_object_get(e, "siblings");
        CHECK_MSG(strstr(cap_str(e, "file"), ".dng") && json_array_size(sib) == 1, "%s: %zu siblings",
                  cap_str(e, "file"), json_array_size(sib));
        json_t *f = json_array_get(sib, 0);
        CHECK(strstr(cap_str(f, "file"), ".jpg") && strstr(cap_str(f, "source"), ".JPG"));
        CHECK(!strcmp(cap_str(e, "verified_on"), cap_str(f, "file")));
        char path[4096], hex[65];
        sl_error err;
        snprintf(path, sizeof path, "%s/%s", dir, cap_str(f, "file"));
        CHECK_OK(sl_sha256_file(path, hex, &err), &err);
        CHECK_MSG(!strcmp(hex, cap_str(f, "sha256")), "%s: checksum differs", path);
    }
    CHECK((int)json_array_size(acc) == count);
    json_decref(acc);
    json_decref(j);
    char sp[4096];
    snprintf(sp, sizeof sp, "%s/session.json", dir);
    json_t *s = json_load_file(sp, 0, NULL);
    json_t *cam = json_object_get(s, "camera");
    CHECK(!strcmp(cap_str(cam, "format"), "raw+jpeg") &&
          !strcmp(cap_str(cam, "format_label"), "RAW + JPEG Fine"));
    json_t *fr = json_object_get(
        json_array_get(json_object_get(json_array_get(json_object_get(s, "views"), 0), "brackets"),
                       0),
        "frames");
    int with = 0;
    json_array_foreach(fr, i, e) with += json_array_size(json_object_get(e, "siblings")) == 1;
    CHECK_MSG(with == count, "%d of %d frames list their JPEG", with, count);
    json_decref(s);
}

static void test_raw_jpeg(void)
{
    sl_virtual_camera_opts vo;
    sl_error err;
    double *times;
    cap_vopts(&vo);
    double t0 = sl_seconds();
    json_t *j = run_format("rawjpeg", "7x2", &vo, SL_FORMAT_RAW_JPEG, 5, SL_OK, &err, &times);
    printf("1x7 raw+jpeg with the virtual camera: %.2f s\n", sl_seconds() - t0);
    check_raw_jpeg(sl_test_path("rawjpeg"), 7);
    CHECK(sl_test_count_files(sl_test_path("rawjpeg")) == 14 + 2);
    json_t *fmt = cap_events(j, "format", -1);
    CHECK(json_array_size(fmt) == 1 && json_is_true(json_object_get(json_array_get(fmt, 0), "ok")));
    json_decref(fmt);
    json_decref(j);
    free(times);

    /* raw alone: the DNG is decoded, so its pixels are measured too */
    cap_vopts(&vo);
    j = run_format("rawonly", "3x3", &vo, SL_FORMAT_RAW, 5, SL_OK, &err, &times);
    json_t *acc = cap_events(j, "frame", 1);
    size_t i;
    json_t *e;
    int measured = 0;
    json_array_foreach(acc, i, e)
    {
        CHECK(strstr(cap_str(e, "file"), ".dng") && !json_object_get(e, "siblings"));
        measured += json_is_true(json_object_get(e, "pixels_ok"));
    }
    CHECK_MSG(measured == 2, "%d raw frames measured", measured);
    CHECK(sl_test_count_files(sl_test_path("rawonly")) == 3 + 2);
    json_decref(acc);
    json_decref(j);
    free(times);
}

static void test_format_ignored(void)
{
    sl_virtual_camera_opts vo;
    sl_error err;
    double *times;
    /* the change is ignored and reads back unchanged: set again */
    cap_vopts(&vo);
    vo.ignore_format = 1;
    json_t *j = run_format("fmt_ignored", "3x3", &vo, SL_FORMAT_RAW_JPEG, 5, SL_OK, &err, &times);
    json_t *fmt = cap_events(j, "format", -1);
    CHECK(json_array_size(fmt) == 2);
    CHECK(json_is_false(json_object_get(json_array_get(fmt, 0), "ok")) &&
          strstr(cap_str(json_array_get(fmt, 0), "message"), "ignored the image format change"));
    CHECK(json_is_true(json_object_get(json_array_get(fmt, 1), "ok")));
    check_raw_jpeg(sl_test_path("fmt_ignored"), 3);
    json_decref(fmt);
    json_decref(j);
    free(times);

    /* it even reads back as changed: the first frame's files give it away,
     * the frame is rejected (kept, journalled) and shot again */
    cap_vopts(&vo);
    vo.ignore_format = 1;
    vo.format_lies = true;
    j = run_format("fmt_lies", "3x3", &vo, SL_FORMAT_RAW_JPEG, 5, SL_OK, &err, &times);
    json_t *rej = cap_events(j, "frame", 0);
    CHECK(json_array_size(rej) == 1);
    json_t *r = json_array_get(rej, 0);
    CHECK(cap_ival(r, "index") == 0 &&
          strstr(cap_str(r, "reason"), "delivered jpeg, the plan is raw+jpeg") &&
          !strcmp(cap_str(r, "file"), "v00_f00.jpg"));
    check_raw_jpeg(sl_test_path("fmt_lies"), 3);
    json_decref(rej);
    json_decref(j);
    free(times);
}

/* The link drops after frame 3's JPEG landed, before its raw: the JPEG is
 * kept and journalled incomplete; resume shoots frame 3 again under new
 * names and finishes; another format is refused. */
static void test_drop_between_files(void)
{
    sl_virtual_camera_opts vo;
    sl_error err;
    double *times;
    cap_vopts(&vo);
    vo.drop_before_raw = 3;
    json_t *j =
        run_format("fmt_drop", "3x3", &vo, SL_FORMAT_RAW_JPEG, -1, SL_ERR_CAMERA, &err, &times);
    const char *dir = sl_test_path("fmt_drop");
    json_t *rej = cap_events(j, "frame", 0);
    CHECK(json_array_size(rej) == 1);
    json_t *r = json_array_get(rej, 0);
    CHECK(cap_ival(r, "index") == 2 && json_is_true(json_object_get(r, "incomplete")) &&
          !strcmp(cap_str(r, "file"), "v00_f02.jpg") && strstr(cap_str(r, "reason"), "1 of 2 files"));
    char landed[65] = "";
    snprintf(landed, sizeof landed, "%s", cap_str(r, "sha256"));
    json_decref(rej);
    json_decref(j);
    CHECK(sl_test_count_files(dir) == 2 * 2 + 1 + 2); /* frames 1, 2, the JPEG of 3 */

    cap_vopts(&vo);
    sl_camera *cam = cap_open_virtual(&vo);
    if (!cam)
        return;
    sl_capture_options ro;
    memset(&ro, 0, sizeof ro);
    char *before = sl_test_read_file(sl_test_path("fmt_drop/journal.jsonl"), NULL);
    ro.format = SL_FORMAT_JPEG;
    CHECK_RESULT(sl_capture_resume(cam, &ro, dir, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, dir) && strstr(err.message, "raw+jpeg") &&
          strstr(err.message, "jpeg"));
    char *same = sl_test_read_file(sl_test_path("fmt_drop/journal.jsonl"), NULL);
    CHECK(before && same && !strcmp(before, same));
    free(before);
    free(same);
    ro.format = SL_FORMAT_KEEP; /* the session's format */
    CHECK_OK(sl_capture_resume(cam, &ro, dir, &err), &err);
    sl_camera_close(cam);
    cap_check_session(dir, 1, 3, times);
    check_raw_jpeg(dir, 3);
    CHECK(sl_test_count_files(dir) == 3 * 2 + 1 + 2);
    char path[4096], hex[65];
    snprintf(path, sizeof path, "%s/v00_f02.jpg", dir);
    CHECK_OK(sl_sha256_file(path, hex, &err), &err);
    CHECK_MSG(!strcmp(hex, landed), "%s: the landed JPEG was overwritten", path);
    j = cap_journal(dir);
    json_t *acc = cap_events(j, "frame", 1);
    json_t *f2 = json_array_get(acc, 2);
    CHECK(cap_ival(f2, "index") == 2 && !strcmp(cap_str(f2, "file"), "v00_f02_r2.dng"));
    json_decref(acc);
    json_decref(j);
    free(times);
}

typedef struct shot_rec {
    int view, bracket, index;
    double time;    /* EXIF exposure time */
    long second;    /* EXIF whole second */
    char sha[65];
} shot_rec;

/* Ingest of virtual-camera frames in shuffled names: three brackets back to
 * back in view 0 (5 frames a second, so brackets share EXIF seconds), one in
 * view 1 after a head turn. */
static void test_ingest_subsecond(void)
{
    static const double speeds[5] = {1.0 / 8000, 1.0 / 1000, 1.0 / 125, 1.0 / 15, 1.0 / 4};
    sl_virtual_camera_opts vo;
    cap_vopts(&vo);
    sl_camera *cam = cap_open_virtual(&vo);
    if (!cam)
        return;
    const char *card = sl_test_path("card");
    mkdir(card, 0755);
    shot_rec shots[20];
    int n = 0;
    sl_error err;
    uint64_t rng = 7;
    int names[20];
    for (int i = 0; i < 20; i++)
        names[i] = 1000 + i * 37;
    sl_test_shuffle(names, 20, &rng);
    const int brackets[2] = {3, 1};
    for (int v = 0; v < 2; v++) {
        sl_camera_aim(cam, v, 2);
        for (int b = 0; b < brackets[v]; b++)
            for (int k = 0; k < 5; k++) {
                sl_camera_settings s = {speeds[k], 0, 0};
                sl_camera_shot shot;
                CHECK_OK(sl_camera_set(cam, &s, &err), &err);
                CHECK_OK(sl_camera_capture(cam, &shot, &err), &err);
                const sl_camera_file f = shot.files[0];
                char path[4096];
                snprintf(path, sizeof path, "%s/X%04d.JPG", card, names[n]);
                CHECK_OK(sl_write_file_atomic(path, f.data, f.size, &err), &err);
                shot_rec *r = &shots[n++];
                r->view = v;
                r->bracket = b;
                r->index = k;
                sl_sha256_hex(f.data, f.size, r->sha);
                sl_camera_shot_free(&shot);
                sl_meta meta;
                int w, h, c;
                if (!sl_photo_read_meta(path, &meta, &w, &h, &c, &err)) {
                    r->time = meta.exposure_time;
                    r->second = atol(meta.datetime + 17) + 60 * atol(meta.datetime + 14);
                    sl_meta_free(&meta);
                }
            }
    }
    sl_camera_close(cam);
    /* the case that needs the sub-second field: a bracket's first frame in
     * the same EXIF second as the previous bracket's last, and faster */
    bool needs_subsec = false;
    for (int i = 1; i < n; i++)
        needs_subsec |= shots[i].bracket != shots[i - 1].bracket &&
                        shots[i].view == shots[i - 1].view &&
                        shots[i].second == shots[i - 1].second &&
                        shots[i].time < shots[i - 1].time;
    CHECK_MSG(needs_subsec, "no two brackets share an EXIF second: the test cannot fail");
    char junk[4096];
    snprintf(junk, sizeof junk, "%s/notes.txt", card);
    FILE *f = fopen(junk, "w");
    fputs("lens cap on for view 3\n", f);
    fclose(f);

    const char *dir = sl_test_path("card_session");
    int frames, views;
    CHECK_OK(sl_ingest(card, dir, 10, NULL, &frames, &views, &err), &err);
    CHECK(frames == 20 && views == 2);
    json_t *s = cap_session_json(dir);
    if (!s)
        return;
    json_t *vs = json_object_get(s, "views");
    CHECK(json_array_size(vs) == 2);
    for (int v = 0; v < 2 && v < (int)json_array_size(vs); v++) {
        json_t *bs = json_object_get(json_array_get(vs, (size_t)v), "brackets");
        CHECK_MSG((int)json_array_size(bs) == brackets[v], "view %d: %zu brackets", v,
                  json_array_size(bs));
        for (int b = 0; b < brackets[v] && b < (int)json_array_size(bs); b++) {
            json_t *fr = json_object_get(json_array_get(bs, (size_t)b), "frames");
            CHECK(json_array_size(fr) == 5);
            for (int k = 0; k < 5 && k < (int)json_array_size(fr); k++) {
                /* exactly the frame shot as view v, bracket b, exposure k */
                const char *sha = cap_str(json_array_get(fr, (size_t)k), "sha256");
                int at = -1;
                for (int i = 0; i < n; i++)
                    if (!strcmp(shots[i].sha, sha))
                        at = i;
                CHECK_MSG(at >= 0 && shots[at].view == v && shots[at].bracket == b &&
                              shots[at].index == k,
                          "view %d bracket %d frame %d is shot %d", v, b, k, at);
            }
        }
    }
    json_t *p = json_object_get(s, "problems");
    CHECK(json_array_size(p) == 1 && strstr(json_string_value(json_array_get(p, 0)), "notes.txt"));
    json_decref(s);
}

/* The virtual set's own capture folder (sl_vset_capture_write), its JPEGs
 * copied under shuffled names: grouped back into its views and brackets. */
static void test_ingest_vset(void)
{
    sl_vset_desc desc;
    sl_error err;
    CHECK_OK(sl_vset_preset("exterior", &desc, &err), &err);
    sl_vset_capture_opts o;
    sl_vset_capture_defaults(&o, &desc, SL_VSET_SIZE_TINY);
    o.photo_width = 96;
    o.photo_height = 64;
    o.latlong_width = 64;
    o.brackets = 5;
    const char *vdir = sl_test_path("vset");
    sl_vset_capture_summary sum;
    CHECK_OK(sl_vset_capture_write(&o, vdir, &sum, &err), &err);
    char cj[4096];
    snprintf(cj, sizeof cj, "%s/capture.json", vdir);
    json_error_t je;
    json_t *cap = json_load_file(cj, 0, &je);
    CHECK(cap != NULL);
    if (!cap)
        return;
    json_t *frames = json_object_get(cap, "frames");
    int n = (int)json_array_size(frames);
    CHECK(n == 15);
    int order[64];
    for (int i = 0; i < n; i++)
        order[i] = i;
    uint64_t rng = 99;
    sl_test_shuffle(order, n, &rng);
    const char *card = sl_test_path("vcard");
    mkdir(card, 0755);
    char shas[64][65];
    for (int i = 0; i < n; i++) {
        char from[4096], to[4096];
        snprintf(from, sizeof from, "%s/hdri/%s.jpg", vdir,
                 cap_str(json_array_get(frames, (size_t)i), "name"));
        snprintf(to, sizeof to, "%s/F%03d.jpg", card, order[i]);
        size_t size;
        char *data = sl_test_read_file(from, &size);
        CHECK(data != NULL);
        if (!data)
            continue;
        CHECK_OK(sl_write_file_atomic(to, data, size, &err), &err);
        sl_sha256_hex(data, size, shas[i]);
        free(data);
    }
    char junk[4096];
    snprintf(junk, sizeof junk, "%s/Thumbs.db", card);
    FILE *f = fopen(junk, "w");
    fputs("\x01\x02junk", f);
    fclose(f);
    const char *dir = sl_test_path("vset_session");
    int nf, nv;
    CHECK_OK(sl_ingest(card, dir, 10, NULL, &nf, &nv, &err), &err);
    CHECK(nf == 15 && nv == 3);
    char sp[4096];
    snprintf(sp, sizeof sp, "%s/session.json", dir);
    json_t *s = json_load_file(sp, 0, &je);
    CHECK(s != NULL);
    json_t *vs = json_object_get(s, "views");
    for (size_t v = 0; s && v < json_array_size(vs); v++) {
        json_t *bs = json_object_get(json_array_get(vs, v), "brackets");
        CHECK(json_array_size(bs) == 1);
        json_t *fr = json_object_get(json_array_get(bs, 0), "frames");
        CHECK(json_array_size(fr) == 5);
        for (size_t k = 0; k < json_array_size(fr); k++) {
            const char *sha = cap_str(json_array_get(fr, k), "sha256");
            int at = -1;
            for (int i = 0; i < n; i++)
                if (!strcmp(shas[i], sha))
                    at = i;
            json_t *truth = json_array_get(frames, (size_t)(at >= 0 ? at : 0));
            CHECK_MSG(at >= 0 && cap_ival(truth, "view") == (int)v && cap_ival(truth, "bracket") == (int)k,
                      "ingested view %zu frame %zu is capture frame %d", v, k, at);
        }
    }
    CHECK(s && json_array_size(json_object_get(s, "problems")) == 1);
    json_decref(s);
    json_decref(cap);
}

int main(void)
{
    RUN(test_camera_interface);
    RUN(test_full_capture);
    RUN(test_ignored_shutter);
    RUN(test_busy);
    RUN(test_refused_setting);
    RUN(test_reconnect);
    RUN(test_disconnect_and_resume);
    RUN(test_raw_jpeg);
    RUN(test_format_ignored);
    RUN(test_drop_between_files);
    RUN(test_ingest_subsecond);
    RUN(test_ingest_vset);
    return sl_test_finish();
}
