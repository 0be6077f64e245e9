/* SPDX-License-Identifier: BSD-3-Clause */
/* Errors, exit codes, image buffers, statistics, threads, atomic output. */
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "testing.h"

static void test_exit_codes(void)
{
    CHECK(sl_result_exit_code(SL_OK) == 0);
    CHECK(sl_result_exit_code(SL_ERR_USAGE) == 2);
    CHECK(sl_result_exit_code(SL_ERR_INPUT) == 3);
    CHECK(sl_result_exit_code(SL_ERR_NOT_FOUND) == 3);
    CHECK(sl_result_exit_code(SL_ERR_IO) == 1);
    CHECK(sl_result_exit_code(SL_ERR_NOMEM) == 1);
    sl_error err;
    CHECK(sl_error_set(&err, SL_ERR_INPUT, "%s: bad %d", "a.exr", 3) == SL_ERR_INPUT);
    CHECK(strcmp(err.message, "a.exr: bad 3") == 0);
    CHECK(strcmp(sl_result_name(999), "unknown error") == 0);
}

static void test_image_alloc_and_crop(void)
{
    sl_image img, crop;
    sl_error err;
    CHECK_RESULT(sl_image_alloc(&img, 0, 4, 3, &err), SL_ERR_INPUT, &err);
    CHECK_RESULT(sl_image_alloc(&img, 4, 4, 5, &err), SL_ERR_INPUT, &err);
    CHECK_RESULT(sl_image_alloc(&img, 70000, 70000, 3, &err), SL_ERR_INPUT, &err);
    CHECK_OK(sl_image_alloc(&img, 5, 4, 3, &err), &err);
    for (int y = 0; y < 4; y++)
        for (int x = 0; x < 5; x++)
            for (int c = 0; c < 3; c++)
                sl_image_pixel(&img, x, y)[c] = (float)(100 * y + 10 * x + c);
    CHECK_OK(sl_image_crop(&img, 1, 2, 3, 2, &crop, &err), &err);
    CHECK(crop.width == 3 && crop.height == 2);
    CHECK(sl_image_pixel(&crop, 0, 0)[0] == 210.0f);
    CHECK(sl_image_pixel(&crop, 2, 1)[2] == 332.0f);
    sl_image_free(&crop);
    CHECK_RESULT(sl_image_crop(&img, 3, 0, 3, 1, &crop, &err), SL_ERR_USAGE, &err);
    sl_image_free(&crop); /* safe after failure */
    sl_image_free(&img);
}

static void test_stats_wide_range(void)
{
    /* 1e9 once and 1e-6 a million times: float sums lose the small values,
     * the compensated double sum keeps them. */
    sl_image img;
    CHECK_OK(sl_image_alloc(&img, 1000, 1001, 1, NULL), NULL);
    sl_image_fill(&img, 1e-6f);
    img.data[0] = 1e9f;
    img.data[1] = NAN;
    img.data[2] = INFINITY;
    img.data[3] = -1.0f;
    sl_image_stats st;
    sl_image_stats_compute(&img, &st);
    CHECK(st.nan_count == 1);
    CHECK(st.inf_count == 1);
    CHECK(st.negative_count == 1);
    double expected = 1e9 - 1.0 + (1000.0 * 1001 - 4) * (double)1e-6f;
    CHECK_NEAR(st.sum[0], expected, 1e-6);
    CHECK(st.max[0] == 1e9);
    CHECK(st.min[0] == -1.0);
    CHECK(sl_image_sanitize(&img, 0.0f) == 2);
    sl_image_free(&img);
}

typedef struct sum_ctx {
    double partial[64];
} sum_ctx;

static void sum_chunk(void *ctx, int64_t begin, int64_t end, int worker)
{
    (void)worker;
    sum_ctx *s = ctx;
    double acc = 0;
    for (int64_t i = begin; i < end; i++)
        acc += 1.0 / (double)(i + 1);
    s->partial[begin / 1000] = acc;
}

static void test_parallel_deterministic(void)
{
    double totals[3];
    int counts[3] = {1, 2, 7};
    for (int t = 0; t < 3; t++) {
        sum_ctx s;
        memset(&s, 0, sizeof s);
        sl_threads_set(counts[t]);
        sl_parallel_for(64000, 1000, sum_chunk, &s);
        totals[t] = 0;
        for (int i = 0; i < 64; i++)
            totals[t] += s.partial[i];
    }
    sl_threads_set(0);
    CHECK(totals[0] == totals[1] && totals[1] == totals[2]);
    CHECK_NEAR(totals[0], 11.6438618, 1e-6); /* H(64000) */
}

static void test_atomic_output(void)
{
    sl_error err;
    const char *path = sl_test_path("out.txt");
    CHECK_OK(sl_write_file_atomic(path, "hello", 5, &err), &err);
    CHECK(sl_test_file_exists(path));
    /* abort leaves the old file and no temporary */
    sl_atomic_file f;
    CHECK_OK(sl_atomic_begin(&f, path, &err), &err);
    CHECK(strstr(f.temp_path, ".sl-tmp-") != NULL);
    CHECK(strcmp(f.temp_path + strlen(f.temp_path) - 4, ".txt") == 0);
    sl_atomic_abort(&f);
    CHECK(sl_test_count_files(sl_test_tmpdir()) == 1);
    /* a missing folder is a usage error naming the output */
    CHECK_RESULT(sl_write_file_atomic(sl_test_path("no/such/dir/x.txt"), "x", 1, &err),
                 SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "x.txt") != NULL);
    /* input checks */
    CHECK_RESULT(sl_check_input_file(sl_test_path("missing.exr"), &err), SL_ERR_NOT_FOUND, &err);
    CHECK_RESULT(sl_check_input_file(sl_test_tmpdir(), &err), SL_ERR_NOT_FOUND, &err);
    CHECK(strstr(err.message, "directory") != NULL);
    CHECK_OK(sl_write_file_atomic(sl_test_path("empty.exr"), "", 0, &err), &err);
    CHECK_RESULT(sl_check_input_file(sl_test_path("empty.exr"), &err), SL_ERR_INPUT, &err);
    CHECK_OK(sl_check_input_file(path, &err), &err);
}

static void test_meta(void)
{
    sl_meta m, c;
    sl_meta_init(&m);
    CHECK_OK(sl_meta_set(&m, "setlight:inputs", "a.jpg b.jpg", NULL), NULL);
    CHECK_OK(sl_meta_set(&m, "setlight:inputs", "c.jpg", NULL), NULL);
    CHECK(m.attr_count == 1);
    CHECK(strcmp(sl_meta_get(&m, "setlight:inputs"), "c.jpg") == 0);
    CHECK(sl_meta_get(&m, "missing") == NULL);
    CHECK_OK(sl_meta_copy(&m, &c, NULL), NULL);
    sl_meta_free(&m);
    CHECK(strcmp(sl_meta_get(&c, "setlight:inputs"), "c.jpg") == 0);
    sl_meta_free(&c);
}

static void test_progress_quiet_off_terminal(void)
{
    /* ctest's stderr is a pipe: no bar, and every call is safe. */
    sl_progress p;
    sl_progress_begin(&p, "test", 10);
    CHECK(!p.enabled);
    sl_progress_add(&p, 4);
    sl_progress_add(&p, 6);
    CHECK(p.done == 10);
    sl_progress_end(&p);
    sl_progress_add(NULL, 1);
}

int main(void)
{
    RUN(test_exit_codes);
    RUN(test_image_alloc_and_crop);
    RUN(test_stats_wide_range);
    RUN(test_parallel_deterministic);
    RUN(test_atomic_output);
    RUN(test_meta);
    RUN(test_progress_quiet_off_terminal);
    return sl_test_finish();
}
