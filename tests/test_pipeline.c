/* SPDX-License-Identifier: BSD-3-Clause */
/* pipeline: one job's stamp and key through `setlight job`'s library call
 * (sl_pipeline_job_run), with plain commands (cp, sh) so the machinery is
 * tested apart from the stages: run, skip when up to date, rerun when an
 * input changes, a failure keeps the earlier output and is retried, an
 * output not written is a failure, stdout to the *.result.json output. And
 * the lat-long comparison on known answers. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/pipeline.h"
#include "testing.h"

static void write_text(const char *path, const char *text)
{
    sl_error err;
    CHECK_OK(sl_write_file_atomic(path, text, strlen(text), &err), &err);
}

static bool file_is(const char *path, const char *text)
{
    char *s = sl_test_read_file(path, NULL);
    bool same = s && !strcmp(s, text);
    free(s);
    return same;
}

/* A graph of single jobs, each given as its command (a JSON array text),
 * inputs and outputs. */
static void write_graph(const char *jobs, const char *out, const char *const *id,
                        const char *const *command, const char *const *inputs,
                        const char *const *outputs, int n)
{
    char text[16384];
    int len = snprintf(text, sizeof text,
                       "{\"format\":\"setlight-jobs\",\"version\":1,\"setlight\":\"%s\",\"out\":\"%s\",\"jobs\":[",
                       sl_version(), out);
    for (int i = 0; i < n; i++)
        len += snprintf(text + len, sizeof text - (size_t)len,
                        "%s{\"id\":\"%s\",\"setup\":\"s\",\"stage\":\"merge\",\"argv\":[\"setlight\"],"
                        "\"command\":%s,\"inputs\":%s,\"outputs\":%s,\"deps\":[],\"array\":null,"
                        "\"memory_mb\":1,\"cpus\":1,\"log\":\"%s/logs/%d.log\",\"key\":null,"
                        "\"up_to_date\":false}",
                        i ? "," : "", id[i], command[i], inputs[i], outputs[i], out, i);
    snprintf(text + len, sizeof text - (size_t)len, "]}");
    write_text(jobs, text);
}

static void test_job_stamps(void)
{
    char in[1024], out[1024], kept[1024], res[1024], jobs[1024], dir[512];
    snprintf(dir, sizeof dir, "%s", sl_test_tmpdir());
    snprintf(in, sizeof in, "%s/in.txt", dir);
    snprintf(out, sizeof out, "%s/s/copy.txt", dir);
    snprintf(kept, sizeof kept, "%s/s/kept.txt", dir);
    snprintf(res, sizeof res, "%s/s/echo.result.json", dir);
    snprintf(jobs, sizeof jobs, "%s/jobs.json", dir);
    write_text(in, "first\n");
    char cmd0[2300], in0[1100], out0[1100], cmd1[256], out1[1100], cmd2[64], out2[1100],
        cmd3[64], out3[1100];
    snprintf(cmd0, sizeof cmd0, "[\"/bin/cp\",\"%s\",\"%s\"]", in, out);
    snprintf(in0, sizeof in0, "[\"%s\"]", in);
    snprintf(out0, sizeof out0, "[\"%s\"]", out);
    snprintf(cmd1, sizeof cmd1, "[\"/bin/sh\",\"-c\",\"echo warming >&2; echo boom >&2; exit 3\"]");
    snprintf(out1, sizeof out1, "[\"%s\"]", kept);
    snprintf(cmd2, sizeof cmd2, "[\"/bin/true\"]");
    snprintf(out2, sizeof out2, "[\"%s/s/never.txt\"]", dir);
    snprintf(cmd3, sizeof cmd3, "[\"/bin/echo\",\"{}\"]");
    snprintf(out3, sizeof out3, "[\"%s\"]", res);
    const char *ids[] = {"s/copy", "s/fail", "s/silent", "s/echo"};
    const char *cmds[] = {cmd0, cmd1, cmd2, cmd3};
    const char *ins[] = {in0, in0, in0, in0};
    const char *outs[] = {out0, out1, out2, out3};
    write_graph(jobs, dir, ids, cmds, ins, outs, 4);

    sl_error err;
    int code = -1;
    bool skipped = true;
    /* Runs, stamps. */
    CHECK_OK(sl_pipeline_job_run(jobs, "s/copy", &code, &skipped, &err), &err);
    CHECK(code == 0 && !skipped);
    CHECK(file_is(out, "first\n"));
    char stamp[1100];
    snprintf(stamp, sizeof stamp, "%s/s/copy.stamp.json", dir);
    char *st = sl_test_read_file(stamp, NULL);
    CHECK(st && strstr(st, "\"status\": \"ok\"") && strstr(st, "\"key\": \""));
    free(st);
    /* Up to date: skipped, the output untouched. */
    write_text(out, "first\n");
    CHECK_OK(sl_pipeline_job_run(jobs, "s/copy", &code, &skipped, &err), &err);
    CHECK(code == 0 && skipped);
    /* The input's contents change: it runs again. */
    write_text(in, "second\n");
    CHECK_OK(sl_pipeline_job_run(jobs, "s/copy", &code, &skipped, &err), &err);
    CHECK(code == 0 && !skipped && file_is(out, "second\n"));
    /* The output changed behind the stamp's back (another size): runs again. */
    write_text(out, "x\n");
    CHECK_OK(sl_pipeline_job_run(jobs, "s/copy", &code, &skipped, &err), &err);
    CHECK(code == 0 && !skipped && file_is(out, "second\n"));

    /* A failure: the command's code, its last stderr line in the stamp, the
     * earlier output kept, and the next run tries again. */
    write_text(kept, "good\n");
    CHECK_OK(sl_pipeline_job_run(jobs, "s/fail", &code, &skipped, &err), &err);
    CHECK(code == 3 && !skipped);
    CHECK(file_is(kept, "good\n"));
    snprintf(stamp, sizeof stamp, "%s/s/fail.stamp.json", dir);
    st = sl_test_read_file(stamp, NULL);
    CHECK(st && strstr(st, "\"status\": \"failed\"") && strstr(st, "\"message\": \"boom\""));
    free(st);
    CHECK_OK(sl_pipeline_job_run(jobs, "s/fail", &code, &skipped, &err), &err);
    CHECK(code == 3 && !skipped);

    /* Exit 0 without writing a declared output is a failure. */
    CHECK_OK(sl_pipeline_job_run(jobs, "s/silent", &code, &skipped, &err), &err);
    CHECK(code == 1);
    snprintf(stamp, sizeof stamp, "%s/s/silent.stamp.json", dir);
    st = sl_test_read_file(stamp, NULL);
    CHECK(st && strstr(st, "not written by the command"));
    free(st);

    /* stdout to the result output, no partial file left. */
    CHECK_OK(sl_pipeline_job_run(jobs, "s/echo", &code, &skipped, &err), &err);
    CHECK(code == 0 && file_is(res, "{}\n"));
    char partial[1100];
    snprintf(partial, sizeof partial, "%s.partial", res);
    CHECK(!sl_test_file_exists(partial));

    /* An unknown id, a missing graph. */
    CHECK_RESULT(sl_pipeline_job_run(jobs, "s/none", &code, &skipped, &err), SL_ERR_USAGE, &err);
    CHECK_RESULT(sl_pipeline_job_run(sl_test_path("nothing.json"), "s/copy", &code, &skipped, &err),
                 SL_ERR_NOT_FOUND, &err);
    /* An input gone: no key, exit 3 (did its dependencies run?). */
    remove(in);
    CHECK_RESULT(sl_pipeline_job_run(jobs, "s/copy", &code, &skipped, &err), SL_ERR_INPUT, &err);
    CHECK_MSG(strstr(err.message, "s/copy: input ") && strstr(err.message, "in.txt is missing"), "%s",
              err.message);
}

/* Known answer: the test map is 2x the reference times 1, 1.1 or 0.9 (a
 * third of the texels each) within the band, 100x outside it: median
 * ratio 2, median error |2 f - 1| = 1, after the scale |f - 1| = 0.1. */
static void test_latlong_compare(void)
{
    sl_image ref = {0}, test = {0};
    sl_error err;
    CHECK_OK(sl_image_alloc(&ref, 96, 48, 3, &err), &err);
    CHECK_OK(sl_image_alloc(&test, 96, 48, 3, &err), &err);
    static const double f[] = {1.0, 1.1, 0.9};
    for (int y = 0; y < 48; y++) {
        double lat = 90.0 - 180.0 * (y + 0.5) / 48;
        for (int x = 0; x < 96; x++) {
            float *r = sl_image_pixel(&ref, x, y), *t = sl_image_pixel(&test, x, y);
            double v = 0.5 + (x * 7 + y * 3) % 11;
            double g = fabs(lat) <= 60 ? 2.0 * f[(x + y) % 3] : 100.0;
            for (int c = 0; c < 3; c++) {
                r[c] = (float)v;
                t[c] = (float)(v * g);
            }
        }
    }
    sl_meta meta;
    sl_meta_init(&meta);
    meta.envmap = SL_ENVMAP_LATLONG;
    const char *rp = sl_test_path("ref.exr"), *tp = sl_test_path("test.exr");
    CHECK_OK(sl_exr_write(rp, &ref, &meta, SL_PIXEL_FLOAT, &err), &err);
    CHECK_OK(sl_exr_write(tp, &test, &meta, SL_PIXEL_FLOAT, &err), &err);
    double ratio, rel, scaled;
    CHECK_OK(sl_pipeline_latlong_compare(tp, rp, 60, &ratio, &rel, &scaled, &err), &err);
    CHECK_NEAR(ratio, 2.0, 1e-5);
    CHECK_NEAR(rel, 1.0, 1e-5);
    CHECK_NEAR(scaled, 0.1, 1e-5);
    CHECK_RESULT(sl_pipeline_latlong_compare(sl_test_path("none.exr"), rp, 60, &ratio, &rel,
                                             &scaled, &err),
                 SL_ERR_NOT_FOUND, &err);
    sl_meta_free(&meta);
    sl_image_free(&ref);
    sl_image_free(&test);
}

int main(void)
{
    RUN(test_job_stamps);
    RUN(test_latlong_compare);
    return sl_test_finish();
}
