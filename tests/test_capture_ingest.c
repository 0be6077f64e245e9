/* SPDX-License-Identifier: BSD-3-Clause */
/* ingest of a card holding frames of several setups: two setups shot at
 * interleaved times (same camera and two sizes, two cameras of one size, two
 * bodies of one model told apart by their EXIF serial, one picture stored
 * turned) are never grouped together, each becomes its own view with a clean
 * bracket, and session.json says what was kept apart and why; the real
 * stack_room, stack_ghost and memorial sets on one card (shared data). */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "../capture/capture_private.h" /* sl_exif_extra_read */
#include "setlight/capture.h"
#include "testing.h"

/* What a fake camera writes. A serial makes it a hand-written TIFF (the
 * image writer has no serial-number field), else a JPEG. */
typedef struct setup {
    const char *model;
    const char *serial;
    int width, height, orientation;
} setup;

/* 1/1000 .. 0.3 s about 2 stops apart (exact powers of two are avoided:
 * OIIO writes them as EXIF rationals that read back as infinity). */
static const double speeds[5] = {1.0 / 1000, 1.0 / 250, 1.0 / 60, 1.0 / 15, 0.3};

static void le(unsigned char *p, unsigned long v, int n)
{
    for (int i = 0; i < n; i++)
        p[i] = (unsigned char)(v >> (8 * i));
}

typedef struct tag {
    unsigned id, type;
    unsigned long count;
    const void *data; /* NULL: `value` inline */
    unsigned long value;
} tag;

/* One IFD at `at` in buf with its out-of-line values at *data. */
static void put_ifd(unsigned char *buf, size_t at, const tag *t, int n, size_t *data)
{
    le(buf + at, (unsigned long)n, 2);
    for (int i = 0; i < n; i++) {
        unsigned char *e = buf + at + 2 + 12 * i;
        le(e, t[i].id, 2);
        le(e + 2, t[i].type, 2);
        le(e + 4, t[i].count, 4);
        size_t bytes = t[i].type == 5 ? 8 * t[i].count : t[i].type == 3 ? 2 * t[i].count
                                                                          : t[i].count;
        if (!t[i].data && t[i].type == 3)
            le(e + 8, t[i].value, 2);
        else if (!t[i].data)
            le(e + 8, t[i].value, 4);
        else if (bytes <= 4)
            memcpy(e + 8, t[i].data, bytes);
        else {
            memcpy(buf + *data, t[i].data, bytes);
            le(e + 8, (unsigned long)*data, 4);
            *data += (bytes + 1) & ~(size_t)1;
        }
    }
    le(buf + at + 2 + 12 * n, 0, 4);
}

/* A grey w x h 8-bit RGB TIFF whose EXIF has make, model, DateTimeOriginal,
 * exposure time and BodySerialNumber. */
static void write_tiff(const char *path, const setup *s, double t, const char *date)
{
    int w = s->width, h = s->height;
    size_t pixels = (size_t)w * h * 3;
    unsigned char *buf = calloc(1, 4096 + pixels);
    unsigned char bits[6], exposure[8];
    le(bits, 8, 2);
    le(bits + 2, 8, 2);
    le(bits + 4, 8, 2);
    le(exposure, (unsigned long)lround(t * 1e6), 4);
    le(exposure + 4, 1000000, 4);
    size_t ifd0 = 8, exif = 400, data = 800, image = 4096;
    tag t0[] = {{0x100, 4, 1, NULL, (unsigned long)w},
                {0x101, 4, 1, NULL, (unsigned long)h},
                {0x102, 3, 3, bits, 0},
                {0x103, 3, 1, NULL, 1},
                {0x106, 3, 1, NULL, 2},
                {0x10F, 2, 6, "Maker", 0},
                {0x110, 2, strlen(s->model) + 1, s->model, 0},
                {0x111, 4, 1, NULL, (unsigned long)image},
                {0x112, 3, 1, NULL, (unsigned long)s->orientation},
                {0x115, 3, 1, NULL, 3},
                {0x116, 4, 1, NULL, (unsigned long)h},
                {0x117, 4, 1, NULL, (unsigned long)pixels},
                {0x8769, 4, 1, NULL, (unsigned long)exif}};
    tag t1[] = {{0x829A, 5, 1, exposure, 0},
                {0x9003, 2, 20, date, 0},
                {0xA431, 2, strlen(s->serial) + 1, s->serial, 0}};
    memcpy(buf, "II*\0", 4);
    le(buf + 4, (unsigned long)ifd0, 4);
    put_ifd(buf, ifd0, t0, (int)(sizeof t0 / sizeof t0[0]), &data);
    put_ifd(buf, exif, t1, (int)(sizeof t1 / sizeof t1[0]), &data);
    memset(buf + image, 128, pixels);
    FILE *f = fopen(path, "wb");
    CHECK(f && fwrite(buf, 1, 4096 + pixels, f) == 4096 + pixels);
    if (f)
        fclose(f);
    free(buf);
}

/* A grey w x h image of the level a t-second exposure gives, and its EXIF. */
static bool shot_image(sl_image *img, sl_meta *meta, int w, int h, const char *model, double t,
                       int orientation, const char *date)
{
    sl_error err;
    if (sl_image_alloc(img, w, h, 3, &err))
        return false;
    for (size_t i = 0; i < (size_t)w * h * 3; i++)
        img->data[i] = (float)fmin(1.0, t * 3);
    sl_meta_init(meta);
    snprintf(meta->make, sizeof meta->make, "Maker");
    snprintf(meta->model, sizeof meta->model, "%s", model);
    meta->exposure_time = t;
    meta->f_number = 8;
    meta->iso = 100;
    meta->orientation = orientation;
    snprintf(meta->datetime, sizeof meta->datetime, "%s", date);
    return true;
}

/* Frame `number` of a setup, exposed t seconds at `when` seconds. */
static void write_shot(const char *dir, const setup *s, int number, double t, int when)
{
    char path[4096], date[32];
    snprintf(date, sizeof date, "2026:03:04 10:%02d:%02d", when / 60, when % 60);
    snprintf(path, sizeof path, "%s/IMG_%04d.%s", dir, number, s->serial ? "TIF" : "JPG");
    if (s->serial) {
        write_tiff(path, s, t, date);
        return;
    }
    sl_image img;
    sl_meta meta;
    sl_error err;
    if (!shot_image(&img, &meta, s->width, s->height, s->model, t, s->orientation, date))
        return;
    CHECK_OK(sl_photo_write(path, &img, &meta, 8, &err), &err);
    sl_meta_free(&meta);
    sl_image_free(&img);
}

static json_t *load_session(const char *dir)
{
    char sp[4096];
    snprintf(sp, sizeof sp, "%s/session.json", dir);
    json_t *s = json_load_file(sp, 0, NULL);
    CHECK_MSG(s != NULL, "%s: no session.json", dir);
    return s;
}

/* The frames of the first bracket of session s's first view. */
static json_t *only_bracket(json_t *s)
{
    return json_object_get(
        json_array_get(json_object_get(json_array_get(json_object_get(s, "views"), 0), "brackets"),
                       0),
        "frames");
}

/* Two setups shooting 5-frame brackets at once, their frames interleaved
 * second by second (a's at even seconds, b's at odd), on one card. Each
 * must be one view of one bracket of its own frames, in exposure order,
 * and the one split line must name the difference `why`. */
static void check_pair(const char *name, const setup *a, const setup *b, const char *why)
{
    char card[4096], out[4096], out_name[64];
    snprintf(card, sizeof card, "%s", sl_test_path(name));
    snprintf(out_name, sizeof out_name, "%s.out", name);
    snprintf(out, sizeof out, "%s", sl_test_path(out_name));
    mkdir(card, 0755);
    for (int i = 0; i < 5; i++) {
        write_shot(card, a, 100 + i, speeds[i], 2 * i);
        write_shot(card, b, 200 + i, speeds[4 - i], 2 * i + 1);
    }
    sl_error err;
    int frames, views;
    CHECK_OK(sl_ingest(card, out, 10, NULL, &frames, &views, &err), &err);
    CHECK_MSG(frames == 10 && views == 2, "%s: %d frames in %d views", name, frames, views);
    json_t *s = load_session(out);
    json_t *vs = json_object_get(s, "views");
    for (int v = 0; v < 2 && v < (int)json_array_size(vs); v++) {
        const setup *want = v == 0 ? a : b; /* views in the order they began */
        json_t *view = json_array_get(vs, (size_t)v);
        json_t *cam = json_object_get(view, "camera");
        CHECK_MSG(json_integer_value(json_object_get(cam, "width")) == want->width &&
                      !strcmp(json_string_value(json_object_get(cam, "model")), want->model),
                  "%s: view %d is not the setup that began it", name, v);
        json_t *bs = json_object_get(view, "brackets");
        json_t *fr = json_object_get(json_array_get(bs, 0), "frames");
        CHECK_MSG(json_array_size(bs) == 1 && json_array_size(fr) == 5,
                  "%s: view %d has %zu brackets, the first %zu frames", name, v,
                  json_array_size(bs), json_array_size(fr));
        for (size_t i = 0; i < json_array_size(fr); i++) {
            json_t *f = json_array_get(fr, i);
            int number = atoi(json_string_value(json_object_get(f, "source")) + 4);
            CHECK_MSG(number / 100 == v + 1, "%s: view %d holds %s", name, v,
                      json_string_value(json_object_get(f, "source")));
            CHECK_NEAR(json_real_value(json_object_get(f, "exposure_time")), speeds[i], 1e-6);
        }
    }
    json_t *splits = json_object_get(s, "splits");
    const char *line = json_string_value(json_array_get(splits, 0));
    CHECK_MSG(json_array_size(splits) == 1 && line && strstr(line, why) &&
                  strstr(line, "IMG_0100") && strstr(line, "IMG_0200"),
              "%s: splits %s, want one line with '%s'", name, line ? line : "(none)", why);
    json_decref(s);
}

static void test_setups_apart(void)
{
    const setup small = {"Alpha", NULL, 32, 8, 1}, large = {"Alpha", NULL, 48, 8, 1};
    check_pair("sizes", &small, &large, "image size 32x8 vs 48x8");
    const setup beta = {"Beta", NULL, 32, 8, 1};
    check_pair("cameras", &small, &beta, "camera 'Maker Alpha' vs 'Maker Beta'");
    const setup one = {"Gamma", "1111", 32, 8, 1}, two = {"Gamma", "2222", 32, 8, 1};
    check_pair("serials", &one, &two, "body serial 1111 vs 2222");
    const setup turned = {"Alpha", NULL, 8, 32, 6};
    check_pair("turned", &small, &turned,
               "image size 32x8 vs 8x32 (one turned in camera); EXIF orientation 1 vs 6");
}

/* A new card `name` with one 5-frame bracket of setup s, frames
 * numbered from `number`, shot a second apart. */
static const char *bracket_card(const char *name, int number, const setup *s)
{
    const char *card = sl_test_path(name);
    mkdir(card, 0755);
    for (int i = 0; i < 5; i++)
        write_shot(card, s, number + i, speeds[i], i);
    return card;
}

/* One setup's bracket and a lone frame: no split, and the problems name
 * the bracket a merge cannot take. */
static void test_one_setup(void)
{
    const setup s = {"Alpha", NULL, 32, 8, 1};
    const char *card = bracket_card("single", 300, &s);
    write_shot(card, &s, 400, speeds[2], 100); /* a lone frame 95 s later */
    sl_error err;
    int frames, views;
    const char *out = sl_test_path("single.out");
    CHECK_OK(sl_ingest(card, out, 10, NULL, &frames, &views, &err), &err);
    CHECK(frames == 6 && views == 2);
    json_t *j = load_session(out);
    CHECK(json_array_size(json_object_get(j, "splits")) == 0);
    json_t *problems = json_object_get(j, "problems");
    const char *p = json_string_value(json_array_get(problems, 0));
    CHECK_MSG(json_array_size(problems) == 1 && p && strstr(p, "view 1 bracket 0: one frame") &&
                  strstr(p, "IMG_0400"),
              "problems: %s", p ? p : "(none)");
    json_decref(j);
}

/* The EXIF reader on every cut of a file (a card's damaged file): it reads
 * what lies inside the cut and never past it (ASan in CI). */
static void check_cuts(const char *path, const char *serial, const char *lens)
{
    size_t size;
    unsigned char *data = (unsigned char *)sl_test_read_file(path, &size);
    CHECK(data != NULL);
    if (!data)
        return;
    sl_exif_extra x;
    sl_exif_extra_read(data, size, &x);
    CHECK_MSG(!strcmp(x.serial, serial) && !strcmp(x.lens, lens), "%s: serial '%s', lens '%s'",
              path, x.serial, x.lens);
    int wrong = 0;
    for (size_t n = 0; n < size && n < 20000; n += 7) {
        unsigned char *cut = malloc(n ? n : 1);
        memcpy(cut, data, n);
        sl_exif_extra_read(cut, n, &x);
        wrong += (x.serial[0] && strcmp(x.serial, serial)) || (x.lens[0] && strcmp(x.lens, lens));
        free(cut);
    }
    CHECK_MSG(wrong == 0, "%s: %d cuts read a wrong serial or lens", path, wrong);
    free(data);
}

static void test_exif_cuts(void)
{
    const char *dir = sl_test_path("cuts");
    mkdir(dir, 0755);
    const setup s = {"Gamma", "SN-4242", 16, 8, 1};
    write_shot(dir, &s, 1, speeds[2], 0);
    char path[4096];
    snprintf(path, sizeof path, "%s/IMG_0001.TIF", dir);
    check_cuts(path, "SN-4242", "");
    const char *ghost = sl_test_data("brackets/stack_ghost/IMG_0959.JPG");
    if (ghost) /* Canon maker note */
        check_cuts(ghost, "1823918851", "EF-S18-55mm f/3.5-5.6 IS");
    const char *canon6d = sl_test_data("fisheye/sigma8mm_canon6d/IMG_2843.JPG");
    if (canon6d) /* EXIF BodySerialNumber and LensModel */
        check_cuts(canon6d, "158052003961", "8mm");
}

/* Shots of two files where only one tells the body serial (as a CR3, where
 * the EXIF reader finds none, beside its JPEG): each shot is still one
 * frame, its JPEG the sibling of its TIFF. */
static void test_siblings_one_serial(void)
{
    const setup tiff = {"Gamma", "77", 32, 8, 1}, jpeg = {"Gamma", NULL, 32, 8, 1};
    const char *card = bracket_card("pairs", 600, &tiff);
    for (int i = 0; i < 5; i++)
        write_shot(card, &jpeg, 600 + i, speeds[i], i);
    const char *out = sl_test_path("pairs.out");
    sl_error err;
    int frames, views;
    CHECK_OK(sl_ingest(card, out, 10, NULL, &frames, &views, &err), &err);
    CHECK_MSG(frames == 5 && views == 1, "%d frames in %d views", frames, views);
    json_t *s = load_session(out);
    json_t *fr = only_bracket(s);
    int paired = 0;
    for (size_t i = 0; i < json_array_size(fr); i++)
        paired += json_array_size(json_object_get(json_array_get(fr, i), "siblings")) == 1;
    CHECK_MSG(paired == 5, "%d of 5 frames have their JPEG as sibling", paired);
    json_decref(s);
}

/* Shot `number` as a camera and a raw converter leave it: an 8-bit JPEG,
 * a 16-bit display TIFF (IMG_N.tif) and, with `linear`, a 16-bit linear
 * TIFF carrying a linear ICC profile, named so that it sorts last
 * (IMG_N_x.tif): the pick must come from the files, not their names. */
static void write_formats(const char *dir, int number, double t, int when, bool linear)
{
    char path[4096], date[32];
    snprintf(date, sizeof date, "2026:03:04 11:%02d:%02d", when / 60, when % 60);
    sl_image img;
    sl_meta meta;
    sl_error err;
    if (!shot_image(&img, &meta, 32, 8, "Delta", t, 1, date))
        return;
    snprintf(path, sizeof path, "%s/IMG_%04d.jpg", dir, number);
    CHECK_OK(sl_photo_write(path, &img, &meta, 8, &err), &err);
    snprintf(path, sizeof path, "%s/IMG_%04d.tif", dir, number);
    CHECK_OK(sl_photo_write(path, &img, &meta, 16, &err), &err);
    if (linear) {
        snprintf(meta.colorspace, sizeof meta.colorspace, "lin_rec709");
        snprintf(path, sizeof path, "%s/IMG_%04d_x.tif", dir, number);
        CHECK_OK(sl_photo_write(path, &img, &meta, 16, &err), &err);
    }
    sl_meta_free(&meta);
    sl_image_free(&img);
}

/* A card of JPEG + display TIFF + linear TIFF shots: each frame's file is
 * the linear TIFF (by its ICC profile, though its name sorts last), the
 * others stay as siblings, session.json says what each holds and why the
 * frame's was chosen; without linear files the 16-bit TIFF comes before
 * the JPEG; a card of JPEGs alone still ingests. */
static void test_most_linear_file(void)
{
    const char *card = sl_test_path("formats");
    mkdir(card, 0755);
    for (int i = 0; i < 3; i++)
        write_formats(card, 300 + i, speeds[i], 2 * i, true);
    const char *out = sl_test_path("formats.out");
    sl_error err;
    int frames, views;
    CHECK_OK(sl_ingest(card, out, 10, NULL, &frames, &views, &err), &err);
    CHECK_MSG(frames == 3 && views == 1, "%d frames in %d views", frames, views);
    json_t *s = load_session(out);
    json_t *fr = only_bracket(s);
    for (size_t i = 0; i < json_array_size(fr); i++) {
        json_t *f = json_array_get(fr, i);
        const char *source = json_string_value(json_object_get(f, "source"));
        const char *content = json_string_value(json_object_get(f, "content"));
        const char *chosen = json_string_value(json_object_get(f, "chosen"));
        json_t *sib = json_object_get(f, "siblings");
        CHECK_MSG(source && strstr(source, "_x.tif"), "frame %zu is %s, not the linear TIFF", i,
                  source ? source : "(none)");
        CHECK_MSG(content && strstr(content, "scene-linear") && strstr(content, "lin_rec709"),
                  "frame %zu content: %s", i, content ? content : "(none)");
        CHECK_MSG(chosen && strstr(chosen, "more linear"), "frame %zu chosen: %s", i,
                  chosen ? chosen : "(none)");
        const char *alt0 = json_string_value(json_object_get(json_array_get(sib, 0), "content"));
        const char *alt1 = json_string_value(json_object_get(json_array_get(sib, 1), "content"));
        CHECK_MSG(json_array_size(sib) == 2 && alt0 && strstr(alt0, "16-bit tiff") && alt1 &&
                      strstr(alt1, "8-bit jpeg"),
                  "frame %zu alternates: %s, %s", i, alt0 ? alt0 : "-", alt1 ? alt1 : "-");
    }
    json_decref(s);

    const char *display = sl_test_path("display");
    mkdir(display, 0755);
    for (int i = 0; i < 3; i++)
        write_formats(display, 400 + i, speeds[i], 2 * i, false);
    out = sl_test_path("display.out");
    CHECK_OK(sl_ingest(display, out, 10, NULL, &frames, &views, &err), &err);
    s = load_session(out);
    const char *file = json_string_value(json_object_get(json_array_get(only_bracket(s), 0), "file"));
    CHECK_MSG(frames == 3 && file && strstr(file, ".tif"), "%d frames, the first %s", frames,
              file ? file : "(none)");
    json_decref(s);

    /* JPEGs alone: a frame each, no siblings, no choice to explain. */
    const char *jpegs = sl_test_path("jpegs");
    mkdir(jpegs, 0755);
    const setup j = {"Delta", NULL, 32, 8, 1};
    for (int i = 0; i < 3; i++)
        write_shot(jpegs, &j, 500 + i, speeds[i], 2 * i);
    out = sl_test_path("jpegs.out");
    CHECK_OK(sl_ingest(jpegs, out, 10, NULL, &frames, &views, &err), &err);
    CHECK_MSG(frames == 3 && views == 1, "JPEGs: %d frames in %d views", frames, views);
    s = load_session(out);
    json_t *f0 = json_array_get(only_bracket(s), 0);
    const char *content = json_string_value(json_object_get(f0, "content"));
    CHECK_MSG(content && strstr(content, "8-bit jpeg") && !json_object_get(f0, "siblings") &&
                  !json_object_get(f0, "chosen"),
              "JPEG frame: %s", content ? content : "(none)");
    json_decref(s);
}

/* A session folder already holding a file the ingest would write: refused
 * when it gets there, and the frames it copied before are taken back; the
 * file that was there stays, and so does the folder it did not make. */
static void test_takes_back(void)
{
    const setup s = {"Alpha", NULL, 32, 8, 1};
    const char *card = bracket_card("taken", 500, &s);
    const char *out = sl_test_path("taken.out");
    mkdir(out, 0755);
    char there[4096];
    snprintf(there, sizeof there, "%s/v00_b00_f02.jpg", out);
    FILE *f = fopen(there, "w");
    fputs("mine", f);
    fclose(f);
    sl_error err;
    int frames, views;
    CHECK_RESULT(sl_ingest(card, out, 10, NULL, &frames, &views, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "v00_b00_f02.jpg: exists; never overwritten") != NULL);
    CHECK(frames == 0 && views == 0);
    CHECK_MSG(sl_test_count_files(out) == 1, "%d files left in %s", sl_test_count_files(out),
              out);
    char *text = sl_test_read_file(there, NULL);
    CHECK(text && !strcmp(text, "mine"));
    free(text);
}

/* The real sets on one card. Their dates are years apart, so a gap as long
 * as that is what leaves only the setups to keep them apart (a card whose
 * clock was never set). */
static void test_real_sets(void)
{
    const char *room = sl_test_data("brackets/stack_room");
    const char *ghost = sl_test_data("brackets/stack_ghost");
    const char *memorial = sl_test_data("brackets/memorial");
    if (!room || !ghost || !memorial)
        return;
    const char *card = sl_test_path("real");
    char cmd[16384];
    snprintf(cmd, sizeof cmd, "mkdir -p '%s' && cp '%s'/*.jpg '%s'/*.JPG '%s'/*.png '%s'/", card,
             room, ghost, memorial, card);
    CHECK(system(cmd) == 0);
    sl_error err;
    int frames, views;
    const char *out = sl_test_path("real.out");
    CHECK_OK(sl_ingest(card, out, 1e9, NULL, &frames, &views, &err), &err);
    CHECK_MSG(frames == 26 && views == 3, "%d frames in %d views", frames, views);
    json_t *s = load_session(out);
    json_t *vs = json_object_get(s, "views");
    /* by time: memorial (2007, no EXIF), stack_ghost (2011), stack_room (2015) */
    static const int counts[3] = {16, 3, 7};
    static const char *const first[3] = {"memorial0061.png", "IMG_0960.JPG",
                                         "stack_room_exp_6.jpg"};
    for (int v = 0; v < 3 && v < (int)json_array_size(vs); v++) {
        json_t *bs = json_object_get(json_array_get(vs, (size_t)v), "brackets");
        json_t *fr = json_object_get(json_array_get(bs, 0), "frames");
        CHECK_MSG(json_array_size(bs) == 1 && (int)json_array_size(fr) == counts[v] &&
                      !strcmp(json_string_value(json_object_get(json_array_get(fr, 0), "source")),
                              first[v]),
                  "view %d: %zu brackets, %zu frames", v, json_array_size(bs),
                  json_array_size(fr));
    }
    /* the Canon maker note's serial and lens, which OpenImageIO's metadata
     * in setlight does not carry */
    json_t *cam = json_object_get(json_array_get(vs, 1), "camera");
    CHECK(!strcmp(json_string_value(json_object_get(cam, "serial")), "1823918851"));
    CHECK(!strcmp(json_string_value(json_object_get(cam, "lens")), "EF-S18-55mm f/3.5-5.6 IS"));
    json_t *splits = json_object_get(s, "splits");
    const char *a = json_string_value(json_array_get(splits, 0));
    const char *b = json_string_value(json_array_get(splits, 1));
    CHECK_MSG(json_array_size(splits) == 2 && a && b &&
                  strstr(a, "memorial0061.png..memorial0076.png (16 frames) and "
                            "IMG_0959.JPG..IMG_0961.JPG (3 frames)") &&
                  strstr(a, "camera none vs 'Canon EOS REBEL T2i'") &&
                  strstr(b, "image size 900x600 vs 640x427") &&
                  strstr(b, "focal length 18 vs 36 mm"),
              "splits: %s | %s", a ? a : "-", b ? b : "-");
    json_t *problems = json_object_get(s, "problems");
    const char *p = json_string_value(json_array_get(problems, 0));
    CHECK_MSG(json_array_size(problems) == 1 && p &&
                  strstr(p, "view 0 bracket 0: 16 of 16 frames (memorial0061.png, ...) have no "
                            "EXIF exposure time"),
              "problems: %s", p ? p : "(none)");
    json_decref(s);
}

int main(void)
{
    RUN(test_setups_apart);
    RUN(test_one_setup);
    RUN(test_siblings_one_serial);
    RUN(test_most_linear_file);
    RUN(test_takes_back);
    RUN(test_exif_cuts);
    RUN(test_real_sets);
    return sl_test_finish();
}
