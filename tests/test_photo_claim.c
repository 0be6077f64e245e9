/* SPDX-License-Identifier: BSD-3-Clause */
/* What a photo's header may claim (core/photo_claim.c, issue 22): claims
 * the file's size cannot back are refused for each format it knows, the
 * memory budget refuses what is over it and passes what is under, and no
 * real photograph or HDRI in the shared data is refused (the floors are
 * far from real files). */
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "../core/photo_private.h"
#include "testing.h"

static void write_bytes(const char *path, const void *data, size_t n)
{
    FILE *f = fopen(path, "wb");
    CHECK(f != NULL);
    if (f) {
        fwrite(data, 1, n, f);
        fclose(f);
    }
}

/* A Radiance header claiming w x h, then `payload` bytes. */
static const char *rgbe(const char *name, int w, int h, size_t payload)
{
    const char *path = sl_test_path(name);
    char head[128];
    int n =
        snprintf(head, sizeof head, "#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y %d +X %d\n", h, w);
    char *b = calloc(1, (size_t)n + payload);
    memcpy(b, head, (size_t)n);
    write_bytes(path, b, (size_t)n + payload);
    free(b);
    return path;
}

static void test_claims(void)
{
    sl_error err;
    /* 16 pixels a byte at most: 1000 x 1000 needs 62 500 bytes */
    CHECK_OK(sl_photo_claim_check(rgbe("ok.hdr", 1000, 1000, 62500), &err), &err);
    const char *bad = rgbe("bad.hdr", 1000, 1000, 60000);
    CHECK_RESULT(sl_photo_claim_check(bad, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, bad) && strstr(err.message, "1000x1000") &&
          strstr(err.message, "Radiance"));
    /* a PNG IHDR of 100000 x 100000 RGBA 16-bit in 33 bytes */
    unsigned char png[33] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 0, 0, 0, 13,
                             'I',  'H', 'D', 'R', 0,    1,    0x86, 0xa0, 0, 1, 0x86, 0xa0,
                             16,   6,   0,   0,   0};
    const char *p = sl_test_path("huge.png");
    write_bytes(p, png, sizeof png);
    CHECK_RESULT(sl_photo_claim_check(p, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "100000x100000") && strstr(err.message, "33-byte PNG"));
    /* the budget: 1000 x 1000 RGB floats are 12 MB */
    sl_memory_budget_set((uint64_t)8 << 20);
    const char *ok = sl_test_path("ok.hdr");
    CHECK_RESULT(sl_photo_claim_check(ok, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "needs 11 MB, over the memory budget of 8 MB"));
    sl_memory_budget_set((uint64_t)12 << 20);
    CHECK_OK(sl_photo_claim_check(ok, &err), &err);
    sl_memory_budget_set(0);
    CHECK(sl_memory_budget() == sl_memory_budget_default());
    CHECK(sl_memory_budget_default() >= (uint64_t)256 << 20);
    /* what it does not know is left to the readers */
    const char *txt = sl_test_path("plain.txt");
    write_bytes(txt, "hello", 5);
    CHECK_OK(sl_photo_claim_check(txt, &err), &err);
}

static bool is_photo(const char *name)
{
    const char *dot = strrchr(name, '.');
    static const char *const ext[] = {".jpg", ".jpeg", ".png", ".tif", ".tiff", ".hdr"};
    for (size_t i = 0; dot && i < sizeof ext / sizeof ext[0]; i++)
        if (!strcasecmp(dot, ext[i]))
            return true;
    return false;
}

/* Every photograph and HDRI under dir passes the header check. */
static int scan(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return 0;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (e->d_name[0] == '.')
            continue;
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        if (e->d_type == DT_DIR) {
            n += scan(path);
        } else if (is_photo(e->d_name)) {
            sl_error err;
            CHECK_OK(sl_photo_claim_check(path, &err), &err);
            n++;
        }
    }
    closedir(d);
    return n;
}

static void test_real_files_pass(void)
{
    const char *data = sl_test_data("hdri");
    if (!data)
        return;
    int n = scan(SETLIGHT_SHARED_DATA);
    printf("%d real photographs and HDRIs pass the header check\n", n);
    CHECK(n > 0);
}

/* A PNG whose text chunk claims 1.9 GB (found by fuzz_photo): refused from
 * the chunk's length by the metadata read too (merge and ingest read the
 * EXIF first), before libpng allocates the claim. */
static void test_chunk_claim_on_meta_read(void)
{
    char path[1024];
    snprintf(path, sizeof path, "%s/tests/fuzz_regressions/photo/png_text_chunk_meta.png",
             SETLIGHT_SOURCE_DIR);
    sl_error err = {0};
    sl_meta meta;
    int w, h, c;
    CHECK_RESULT(sl_photo_read_meta(path, &meta, &w, &h, &c, &err), SL_ERR_INPUT, &err);
    CHECK_MSG(strstr(err.message, "its tEXt chunk claims 1895825676 bytes, past the file's end"),
              "%s", err.message);
}

int main(void)
{
    RUN(test_claims);
    RUN(test_chunk_claim_on_meta_read);
    RUN(test_real_files_pass);
    return sl_test_finish();
}
