/* SPDX-License-Identifier: BSD-3-Clause */
/* capture without a camera: SHA-256 against the FIPS 180-4 examples, shutter
 * text, bracket plans and snapping, the journal (append, fsync, corrupt
 * lines refused), session.json from a journal, and ingest grouping of
 * shuffled names into views and brackets by EXIF time and exposure. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "setlight/capture.h"
#include "testing.h"

/* Under LeakSanitizer: libgphoto2's USB port driver keeps the device list it
 * gets from libusb_get_device_list when it loads (outside setlight). */
const char *__lsan_default_suppressions(void);
const char *__lsan_default_suppressions(void)
{
    return "leak:libusb_get_device_list\n";
}
/* and the report of that suppression would break the one-line error rule */
const char *__lsan_default_options(void);
const char *__lsan_default_options(void)
{
    return "print_suppressions=0";
}

static void test_sha256(void)
{
    char hex[65];
    sl_sha256_hex("abc", 3, hex);
    CHECK(!strcmp(hex, "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"));
    unsigned char d[32];
    sl_sha256("abc", 3, d);
    CHECK(d[0] == 0xba && d[1] == 0x78 && d[30] == 0x15 && d[31] == 0xad);
    sl_sha256_hex("", 0, hex);
    CHECK(!strcmp(hex, "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855"));
    const char *two = "abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq";
    sl_sha256_hex(two, strlen(two), hex);
    CHECK(!strcmp(hex, "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1"));
    /* one million 'a': many blocks, and the file path agrees with memory */
    size_t n = 1000000;
    char *a = malloc(n);
    memset(a, 'a', n);
    sl_sha256_hex(a, n, hex);
    CHECK(!strcmp(hex, "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0"));
    const char *path = sl_test_path("million.bin");
    sl_error err;
    CHECK_OK(sl_write_file_atomic(path, a, n, &err), &err);
    char fhex[65];
    CHECK_OK(sl_sha256_file(path, fhex, &err), &err);
    CHECK(!strcmp(fhex, hex));
    CHECK_RESULT(sl_sha256_file(sl_test_path("absent.bin"), fhex, &err), SL_ERR_NOT_FOUND, &err);
    free(a);
}

static void test_shutter_text(void)
{
    CHECK_NEAR(sl_shutter_parse("1/30"), 1.0 / 30, 1e-12);
    CHECK_NEAR(sl_shutter_parse("0.0333s"), 0.0333, 1e-12);
    CHECK_NEAR(sl_shutter_parse("2"), 2.0, 1e-12);
    CHECK_NEAR(sl_shutter_parse("2.5\""), 2.5, 1e-12);
    CHECK_NEAR(sl_shutter_parse("1 1/3"), 4.0 / 3, 1e-12);
    CHECK(sl_shutter_parse("Bulb") == 0);
    CHECK(sl_shutter_parse("1/0") == 0);
    CHECK(sl_shutter_parse("-1") == 0);
    CHECK(sl_shutter_parse("1/30x") == 0);
    char buf[32];
    sl_shutter_format(1.0 / 250, buf, sizeof buf);
    CHECK(!strcmp(buf, "1/250"));
    sl_shutter_format(2.5, buf, sizeof buf);
    CHECK(!strcmp(buf, "2.5"));
}

static void test_bracket(void)
{
    sl_error err;
    double *t;
    int n;
    CHECK_OK(sl_bracket_plan_parse("7x3", 1.0 / 32, &t, &n, &err), &err);
    CHECK(n == 7);
    if (n == 7) {
        CHECK_NEAR(t[3], 1.0 / 32, 1e-15);
        CHECK_NEAR(t[0], 1.0 / 16384, 1e-15);
        CHECK_NEAR(t[6], 16.0, 1e-12);
        for (int i = 1; i < 7; i++)
            CHECK_NEAR(log2(t[i] / t[i - 1]), 3.0, 1e-12);
    }
    free(t);
    /* even counts straddle the centre */
    CHECK_OK(sl_bracket_plan_parse("2x2", 1.0, &t, &n, &err), &err);
    CHECK(n == 2 && fabs(t[0] - 0.5) < 1e-15 && fabs(t[1] - 2.0) < 1e-15);
    free(t);
    /* explicit lists are sorted */
    CHECK_OK(sl_bracket_plan_parse("1/15,1/1000,1/125", 0, &t, &n, &err), &err);
    CHECK(n == 3 && fabs(t[0] - 0.001) < 1e-15 && fabs(t[2] - 1.0 / 15) < 1e-15);

    /* snapping to third stops 1/8000 .. 30 s */
    double offered[64];
    int k = 0;
    for (int i = -39; i <= 15; i++)
        offered[k++] = exp2(i / 3.0);
    double moved[3];
    CHECK_OK(sl_bracket_snap(t, 3, offered, k, 1.0, moved, &err), &err);
    CHECK_NEAR(t[0], exp2(-10.0), 1e-12); /* 1/1000 -> 2^-10 */
    CHECK_NEAR(moved[0], log2(exp2(-10.0) / 0.001), 1e-12);
    CHECK(fabs(moved[1]) <= 1.0 / 6 + 1e-12);
    free(t);
    /* out of range: 7x3 around 4 s needs 2048 s */
    CHECK_OK(sl_bracket_plan_parse("7x3", 4.0, &t, &n, &err), &err);
    CHECK_RESULT(sl_bracket_snap(t, n, offered, k, 1.0, NULL, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "out of the camera's range") != NULL);
    free(t);
    /* two plan entries on one speed */
    double close[2] = {0.01, 0.0101};
    CHECK_RESULT(sl_bracket_snap(close, 2, offered, k, 1.0, NULL, &err), SL_ERR_USAGE, &err);
    /* junk */
    CHECK_RESULT(sl_bracket_plan_parse("0x3", 1, &t, &n, &err), SL_ERR_USAGE, &err);
    CHECK(t == NULL && n == 0);
    CHECK_RESULT(sl_bracket_plan_parse("7x0", 1, &t, &n, &err), SL_ERR_USAGE, &err);
    CHECK_RESULT(sl_bracket_plan_parse("7x3", 0, &t, &n, &err), SL_ERR_USAGE, &err);
    CHECK_RESULT(sl_bracket_plan_parse("1/30,,1/4", 0, &t, &n, &err), SL_ERR_USAGE, &err);
    CHECK_RESULT(sl_bracket_plan_parse("1/30,fast", 0, &t, &n, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "fast") != NULL);
}

static int count_lines(const char *path)
{
    FILE *f = fopen(path, "r");
    int n = 0, c;
    while (f && (c = fgetc(f)) != EOF)
        n += c == '\n';
    if (f)
        fclose(f);
    return n;
}

static void test_journal_and_session(void)
{
    const char *dir = sl_test_path("sess");
    mkdir(dir, 0755);
    sl_error err;
    char path[4096];
    snprintf(path, sizeof path, "%s/journal.jsonl", dir);
    /* a plan of 2 views x 2 frames, one frame rejected then retried */
    CHECK_OK(sl_journal_append(dir,
                               "{\"event\":\"session_start\",\"version\":1,\"camera\":"
                               "{\"model\":\"m\"},\"plan\":{\"times\":[0.01,0.08],"
                               "\"views\":2}}",
                               &err),
             &err);
    const char *frames[] = {
        "{\"event\":\"frame\",\"view\":0,\"index\":1,\"accepted\":true,\"file\":\"b.jpg\","
        "\"exposure_time\":0.08,\"sha256\":\"x\"}",
        "{\"event\":\"frame\",\"view\":0,\"index\":0,\"accepted\":true,\"file\":\"a.jpg\","
        "\"exposure_time\":0.01,\"sha256\":\"y\"}",
        "{\"event\":\"frame\",\"view\":1,\"index\":0,\"attempt\":1,\"accepted\":false,"
        "\"file\":\"c.jpg\",\"reason\":\"ignored\"}",
        "{\"event\":\"frame\",\"view\":1,\"index\":0,\"accepted\":true,\"file\":\"c2.jpg\","
        "\"exposure_time\":0.01,\"sha256\":\"z\"}"};
    for (int i = 0; i < 4; i++)
        CHECK_OK(sl_journal_append(dir, frames[i], &err), &err);
    CHECK(count_lines(path) == 5);
    CHECK_RESULT(sl_journal_append(dir, "{\"a\":1}\n{\"b\":2}", &err), SL_ERR_INTERNAL, &err);
    CHECK(count_lines(path) == 5);
    CHECK_OK(sl_session_write(dir, &err), &err);
    char sp[4096];
    snprintf(sp, sizeof sp, "%s/session.json", dir);
    json_error_t je;
    json_t *s = json_load_file(sp, 0, &je);
    CHECK(s != NULL);
    if (s) {
        CHECK(json_integer_value(json_object_get(s, "version")) == 1);
        json_t *views = json_object_get(s, "views");
        CHECK(json_array_size(views) == 2);
        json_t *f0 = json_object_get(
            json_array_get(json_object_get(json_array_get(views, 0), "brackets"), 0), "frames");
        /* ordered by exposure, whatever the journal order */
        CHECK(json_array_size(f0) == 2);
        CHECK(!strcmp(json_string_value(json_object_get(json_array_get(f0, 0), "file")), "a.jpg"));
        json_t *f1 = json_object_get(
            json_array_get(json_object_get(json_array_get(views, 1), "brackets"), 0), "frames");
        CHECK(json_array_size(f1) == 1);
        CHECK(json_array_size(json_object_get(s, "problems")) == 1);
        json_decref(s);
    }
    /* a torn last line is refused with its line number, and nothing changes */
    FILE *f = fopen(path, "a");
    fputs("{\"event\":\"frame\",\"vi", f);
    fclose(f);
    CHECK_RESULT(sl_session_write(dir, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "line 6") != NULL && strstr(err.message, path) != NULL);
    /* not a session */
    const char *empty = sl_test_path("notsession");
    mkdir(empty, 0755);
    CHECK_RESULT(sl_session_write(empty, &err), SL_ERR_NOT_FOUND, &err);
}

/* A photograph of a ramp exposed for t seconds, with EXIF time `when`. */
static void write_frame(const char *path, double t, int when)
{
    sl_image img;
    sl_error err;
    if (sl_image_alloc(&img, 32, 8, 3, &err))
        return;
    for (int y = 0; y < 8; y++)
        for (int x = 0; x < 32; x++)
            for (int c = 0; c < 3; c++)
                sl_image_pixel(&img, x, y)[c] =
                    sl_linear_to_srgb((float)fmin(1.0, exp2(-8.0 + x / 2.0) * t * 30));
    sl_meta meta;
    sl_meta_init(&meta);
    meta.exposure_time = t;
    meta.f_number = 8;
    meta.iso = 100;
    snprintf(meta.datetime, sizeof meta.datetime, "2026:03:04 10:%02d:%02d", when / 60, when % 60);
    CHECK_OK(sl_photo_write(path, &img, &meta, 8, &err), &err);
    sl_meta_free(&meta);
    sl_image_free(&img);
}

static void test_ingest(void)
{
    /* 3 views 40 s apart; view 1 holds two brackets (a repeated setup);
     * each bracket 5 exposures about 2 stops apart, shot 1 s apart; names
     * shuffled. (Exact powers of two are avoided: OIIO 2.4 writes them as
     * EXIF rationals that read back as infinity, which ingest treats as
     * unknown.) */
    const double speeds[5] = {1.0 / 1000, 1.0 / 250, 1.0 / 60, 1.0 / 15, 0.3};
    const char *src = sl_test_path("card");
    mkdir(src, 0755);
    const int brackets_per_view[3] = {1, 2, 1};
    int order[25], n = 0;
    double times[25];
    int whens[25];
    int clock = 0;
    for (int v = 0; v < 3; v++) {
        for (int b = 0; b < brackets_per_view[v]; b++)
            for (int i = 0; i < 5; i++) {
                times[n] = speeds[i];
                whens[n] = clock++;
                n++;
            }
        clock += 40;
    }
    for (int i = 0; i < n; i++)
        order[i] = i;
    uint64_t seed = 12345;
    sl_test_shuffle(order, n, &seed);
    for (int i = 0; i < n; i++) {
        char path[4096];
        snprintf(path, sizeof path, "%s/DSC_%04d.JPG", src, 9000 - 37 * order[i]);
        write_frame(path, times[i], whens[i]);
    }
    char junk[4096];
    snprintf(junk, sizeof junk, "%s/readme.txt", src);
    FILE *f = fopen(junk, "w");
    fputs("not a photo\n", f);
    fclose(f);

    const char *dir = sl_test_path("ingested");
    sl_error err;
    int frames, views;
    sl_progress bar;
    sl_progress_begin(&bar, "ingest", 0);
    CHECK_OK(sl_ingest(src, dir, 10, &bar, &frames, &views, &err), &err);
    CHECK(frames == 20);
    CHECK(views == 3);
    /* the bar learns the total from the scan (the readme is not a photograph) */
    CHECK(bar.total == 20 && bar.done == 20);
    sl_progress_end(&bar);
    char sp[4096];
    snprintf(sp, sizeof sp, "%s/session.json", dir);
    json_error_t je;
    json_t *s = json_load_file(sp, 0, &je);
    CHECK(s != NULL);
    if (s) {
        json_t *vs = json_object_get(s, "views");
        for (int v = 0; v < 3 && v < (int)json_array_size(vs); v++) {
            json_t *bs = json_object_get(json_array_get(vs, (size_t)v), "brackets");
            CHECK_MSG((int)json_array_size(bs) == brackets_per_view[v], "view %d: %zu brackets", v,
                      json_array_size(bs));
            for (size_t b = 0; b < json_array_size(bs); b++) {
                json_t *fr = json_object_get(json_array_get(bs, b), "frames");
                CHECK(json_array_size(fr) == 5);
                for (size_t i = 0; i < json_array_size(fr); i++) {
                    json_t *x = json_array_get(fr, i);
                    CHECK_NEAR(json_real_value(json_object_get(x, "exposure_time")), speeds[i],
                               1e-6);
                    CHECK(json_string_length(json_object_get(x, "sha256")) == 64);
                }
            }
        }
        json_t *problems = json_object_get(s, "problems");
        CHECK(json_array_size(problems) == 1 &&
              strstr(json_string_value(json_array_get(problems, 0)), "readme.txt"));
        json_decref(s);
    }
    /* again into the same folder: refused, never overwritten */
    CHECK_RESULT(sl_ingest(src, dir, 10, NULL, &frames, &views, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, dir) != NULL);
    /* no photographs at all */
    const char *none = sl_test_path("nophotos");
    mkdir(none, 0755);
    snprintf(junk, sizeof junk, "%s/a.txt", none);
    f = fopen(junk, "w");
    fputs("x", f);
    fclose(f);
    CHECK_RESULT(sl_ingest(none, sl_test_path("out2"), 10, NULL, &frames, &views, &err),
                 SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, none) != NULL);
    struct stat st;
    CHECK(stat(sl_test_path("out2"), &st) != 0);
}

static void test_bad_ports(void)
{
    sl_camera *cam = (sl_camera *)1;
    sl_error err;
    CHECK_RESULT(sl_camera_open("nonsense", &cam, &err), SL_ERR_USAGE, &err);
    CHECK(cam == NULL);
    CHECK(strstr(err.message, "nonsense") != NULL);
    CHECK_RESULT(sl_camera_open("carrierpigeon:1", &cam, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "unknown camera port") != NULL);
}

int main(void)
{
    RUN(test_sha256);
    RUN(test_shutter_text);
    RUN(test_bracket);
    RUN(test_journal_and_session);
    RUN(test_ingest);
    RUN(test_bad_ports);
    return sl_test_finish();
}
