/* SPDX-License-Identifier: BSD-3-Clause */
/* sl_exr_stream_*: rows written in uneven pieces round-trip for every
 * compression and thread count (float exactly, half rounded to nearest),
 * all-zero chunks (compressed once, reused) come back zero, attributes are
 * finished in place, the disk holds no more than the file's bytes, and
 * every misuse leaves no file. */
#include <dirent.h>
#include <math.h>
#include <sys/stat.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "testing.h"

enum { W = 61, H = 300, C = 3, PAD = 5 };

/* Rows 0-69 and 256-287 zero: whole chunks of every compression's height,
 * and on one thread (batches of 8 chunks) zero chunks in a later batch than
 * the first, which reuse its bytes. The rest spans half's normal and
 * subnormal range. */
static float value(int x, int y, int c)
{
    if (y < 70 || (y >= 256 && y < 288))
        return 0;
    return (float)(exp2(-20 + 34 * (0.5 + 0.5 * sin(0.37 * x + 0.11 * y * (c + 1))))) *
           (x % 7 == 3 ? -1.0f : 1.0f);
}

/* Temporary files of the atomic writer left in the test folder. */
static int leftovers(void)
{
    int n = 0;
    DIR *d = opendir(sl_test_tmpdir());
    for (struct dirent *e = d ? readdir(d) : NULL; e; e = readdir(d))
        n += strstr(e->d_name, ".sl-tmp-") != NULL;
    if (d)
        closedir(d);
    return n;
}

static void round_trip(sl_pixel_type type, sl_exr_compression comp, int threads)
{
    sl_error err;
    /* Rows further apart than their width: the stride is honoured. */
    static float src[H][W * C + PAD];
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int c = 0; c < C; c++)
                src[y][x * C + c] = value(x, y, c);
    char name[64];
    snprintf(name, sizeof name, "stream_%d_%d_%d.exr", (int)type, (int)comp, threads);
    const char *path = sl_test_path(name);
    sl_threads_set(threads);
    sl_exr_stream *s;
    CHECK_OK(sl_exr_stream_open(path, W, H, C, NULL, type, comp, &s, &err), &err);
    const int pieces[] = {1, 7, 50, 3, 239};
    int y = 0;
    for (size_t k = 0; k < sizeof pieces / sizeof pieces[0] && s; k++) {
        CHECK_OK(sl_exr_stream_write(s, src[y], pieces[k], W * C + PAD, &err), &err);
        y += pieces[k];
    }
    CHECK(y == H);
    /* Nothing at the path before the finish. */
    CHECK(access(path, F_OK) != 0);
    CHECK_OK(sl_exr_stream_finish(s, NULL, &err), &err);
    sl_threads_set(0);
    sl_image back = {0};
    CHECK_OK(sl_exr_read(path, &back, NULL, &err), &err);
    double worst_rel = 0, worst_abs = 0;
    int64_t zero_bad = 0;
    for (int yy = 0; yy < H && back.data; yy++)
        for (int x = 0; x < W; x++)
            for (int c = 0; c < C; c++) {
                float a = value(x, yy, c), b = sl_image_pixel(&back, x, yy)[c];
                if (a == 0) {
                    zero_bad += b != 0;
                    continue;
                }
                if (fabsf(a) >= 0x1p-14f)
                    worst_rel = fmax(worst_rel, fabs(b / a - 1));
                else
                    worst_abs = fmax(worst_abs, fabs(b - a));
            }
    CHECK(zero_bad == 0);
    if (type == SL_PIXEL_FLOAT)
        CHECK(worst_rel == 0 && worst_abs == 0);
    else {
        /* Rounded to nearest: half a step (truncation would reach a whole one). */
        CHECK_MSG(worst_rel <= 0x1p-11, "relative %g (compression %d, %d threads)", worst_rel, (int)comp, threads);
        CHECK_MSG(worst_abs <= 0x1p-25, "absolute %g", worst_abs);
    }
    sl_image_free(&back);
}

static void test_round_trips(void)
{
    for (int comp = SL_EXR_ZIP; comp <= SL_EXR_RLE; comp++)
        for (int threads = 1; threads <= 3; threads += 2) {
            round_trip(SL_PIXEL_HALF, (sl_exr_compression)comp, threads);
            round_trip(SL_PIXEL_FLOAT, (sl_exr_compression)comp, threads);
        }
    CHECK(leftovers() == 0);
}

/* Half saturates at 65504 instead of writing Inf. */
static void test_half_clamp(void)
{
    sl_error err;
    sl_exr_stream *s;
    const char *path = sl_test_path("stream_clamp.exr");
    float row[2 * 3] = {1e6f, -1e6f, 65504.0f, 65519.0f, 1.0f, 0.0f};
    CHECK_OK(sl_exr_stream_open(path, 2, 1, 3, NULL, SL_PIXEL_HALF, SL_EXR_PIZ, &s, &err), &err);
    CHECK_OK(sl_exr_stream_write(s, row, 1, 6, &err), &err);
    CHECK_OK(sl_exr_stream_finish(s, NULL, &err), &err);
    sl_image back = {0};
    CHECK_OK(sl_exr_read(path, &back, NULL, &err), &err);
    if (back.data) {
        CHECK(back.data[0] == 65504.0f && back.data[1] == -65504.0f && back.data[2] == 65504.0f);
        CHECK(back.data[3] == 65504.0f && back.data[4] == 1.0f && back.data[5] == 0.0f);
    }
    sl_image_free(&back);
}

static sl_exr_stream *open_small(const char *path, const char *count, sl_error *err)
{
    sl_meta meta;
    sl_meta_init(&meta);
    sl_meta_set(&meta, "setlight:test:count", count, NULL);
    sl_meta_set(&meta, "setlight:test:other", "kept", NULL);
    sl_exr_stream *s = NULL;
    CHECK_OK(sl_exr_stream_open(path, 8, 4, 1, &meta, SL_PIXEL_FLOAT, SL_EXR_ZIP, &s, err), err);
    sl_meta_free(&meta);
    return s;
}

static void write_rows(sl_exr_stream *s, int rows, sl_error *err)
{
    float buf[4 * 8];
    for (int i = 0; i < 4 * 8; i++)
        buf[i] = (float)i;
    CHECK_OK(sl_exr_stream_write(s, buf, rows, 8, err), err);
}

/* A count known only after the pixels replaces its same-length placeholder. */
static void test_finish_update(void)
{
    sl_error err;
    const char *path = sl_test_path("stream_update.exr");
    sl_exr_stream *s = open_small(path, "   0", &err);
    if (!s)
        return;
    write_rows(s, 4, &err);
    sl_meta upd;
    sl_meta_init(&upd);
    sl_meta_set(&upd, "setlight:test:count", "  42", NULL);
    CHECK_OK(sl_exr_stream_finish(s, &upd, &err), &err);
    sl_meta_free(&upd);
    sl_image back = {0};
    sl_meta meta;
    CHECK_OK(sl_exr_read(path, &back, &meta, &err), &err);
    if (back.data) {
        const char *count = sl_meta_get(&meta, "setlight:test:count");
        const char *other = sl_meta_get(&meta, "setlight:test:other");
        CHECK(count && strcmp(count, "  42") == 0);
        CHECK(other && strcmp(other, "kept") == 0);
        CHECK(back.data[31] == 31.0f);
        sl_meta_free(&meta);
    }
    sl_image_free(&back);
}

static void test_misuse_leaves_nothing(void)
{
    sl_error err;
    const char *path = sl_test_path("stream_bad.exr");
    /* A replacement of another length cannot be written in place. */
    sl_exr_stream *s = open_small(path, "   0", &err);
    write_rows(s, 4, &err);
    sl_meta upd;
    sl_meta_init(&upd);
    sl_meta_set(&upd, "setlight:test:count", "12345", NULL);
    CHECK_RESULT(sl_exr_stream_finish(s, &upd, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, path) != NULL);
    sl_meta_free(&upd);
    CHECK(access(path, F_OK) != 0);
    /* Too few rows at the finish. */
    s = open_small(path, "   0", &err);
    write_rows(s, 3, &err);
    CHECK_RESULT(sl_exr_stream_finish(s, NULL, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, path) != NULL);
    CHECK(access(path, F_OK) != 0);
    /* Too many rows: the stream is aborted. */
    s = open_small(path, "   0", &err);
    write_rows(s, 3, &err);
    float more[2 * 8] = {0};
    CHECK_RESULT(sl_exr_stream_write(s, more, 2, 8, &err), SL_ERR_USAGE, &err);
    CHECK(access(path, F_OK) != 0);
    /* Bad arguments. */
    CHECK_RESULT(sl_exr_stream_open(path, 0, 4, 3, NULL, SL_PIXEL_HALF, SL_EXR_PIZ, &s, &err),
                 SL_ERR_USAGE, &err);
    CHECK(s == NULL);
    CHECK_RESULT(sl_exr_stream_open(path, 4, 4, 3, NULL, SL_PIXEL_HALF, (sl_exr_compression)9, &s,
                                    &err),
                 SL_ERR_USAGE, &err);
    sl_exr_stream_abort(NULL);
    CHECK(access(path, F_OK) != 0);
    CHECK(leftovers() == 0);
}

/* The blocks reserved for the pixels uncompressed (12 MB here) are given
 * back at the finish: a black image's file holds only its own bytes. */
static void test_no_blocks_past_the_end(void)
{
    enum { BW = 1000, BH = 1000 };
    static float black[BW * 3];
    sl_error err;
    const char *path = sl_test_path("stream_black.exr");
    sl_exr_stream *s;
    CHECK_OK(sl_exr_stream_open(path, BW, BH, 3, NULL, SL_PIXEL_FLOAT, SL_EXR_ZIP, &s, &err), &err);
    for (int y = 0; y < BH && s; y++)
        CHECK_OK(sl_exr_stream_write(s, black, 1, BW * 3, &err), &err);
    CHECK_OK(sl_exr_stream_finish(s, NULL, &err), &err);
    struct stat st;
    CHECK(stat(path, &st) == 0);
    CHECK_MSG((int64_t)st.st_blocks * 512 <= st.st_size + 65536,
              "%lld bytes on disk for a file of %lld", (long long)st.st_blocks * 512,
              (long long)st.st_size);
    unlink(path);
}

int main(void)
{
    RUN(test_round_trips);
    RUN(test_half_clamp);
    RUN(test_finish_update);
    RUN(test_misuse_leaves_nothing);
    RUN(test_no_blocks_past_the_end);
    return sl_test_finish();
}
