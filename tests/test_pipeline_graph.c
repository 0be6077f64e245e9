/* SPDX-License-Identifier: BSD-3-Clause */
/* pipeline: the job graph read back (sl_pipeline_graph_parse, what `setlight
 * job`, process-report and process-index load): good graphs in dependency
 * order, and every class of bad graph refused with one line naming the
 * file, the job and the problem: syntax, format, caps on the size, the jobs
 * and the lists, each field's type, ids, unknown and cyclic dependencies.
 * Then the same through sl_pipeline_job_run's file: refused before anything
 * is written. */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/pipeline.h"
#include "testing.h"

/* One job as process writes it; `extra` (",\"key\":value...") replaces
 * fields: jansson keeps the last of a repeated key, but the parser refuses
 * repeats, so the fields are built here without the ones overridden. */
static int job_text(char *buf, size_t size, const char *id, const char *deps, const char *over)
{
    static const char *const keys[] = {"setup", "stage", "argv", "command", "inputs", "outputs",
                                       "array", "memory_mb", "cpus", "log", "key", "up_to_date"};
    static const char *const values[] = {
        "\"s\"", "\"merge\"", "[\"/bin/setlight\",\"job\",\"/d/jobs.json\",\"x\"]",
        "[\"/bin/setlight\",\"merge\"]", "[\"/d/in.tif\"]", "[\"/d/out.exr\"]", "null", "100",
        "1", "\"/d/logs/x.log\"", "null", "false"};
    int len = snprintf(buf, size, "{\"id\":%s,\"deps\":[%s]", id, deps);
    for (size_t k = 0; k < sizeof keys / sizeof *keys; k++) {
        char quoted[64];
        snprintf(quoted, sizeof quoted, "\"%s\":", keys[k]);
        if (!strstr(over, quoted))
            len += snprintf(buf + len, size - (size_t)len, ",%s%s", quoted, values[k]);
    }
    return len + snprintf(buf + len, size - (size_t)len, "%s}", over);
}

/* A graph around `jobs` (a JSON list's contents). */
static char *graph_text(const char *jobs)
{
    size_t size = strlen(jobs) + 256;
    char *text = malloc(size);
    snprintf(text, size,
             "{\"format\":\"setlight-jobs\",\"version\":1,\"setlight\":\"0.1.0\",\"out\":\"/d\","
             "\"jobs\":[%s]}",
             jobs);
    return text;
}

static void expect_refused(const char *text, const char *message)
{
    sl_pipeline_graph *g = (sl_pipeline_graph *)1;
    sl_error err = {0};
    CHECK_RESULT(sl_pipeline_graph_parse("day/jobs.json", text, strlen(text), &g, &err),
                 SL_ERR_INPUT, &err);
    CHECK(g == NULL);
    CHECK_MSG(!strncmp(err.message, "day/jobs.json: ", 15) && strstr(err.message, message),
              "expected '%s', got '%s'", message, err.message);
    CHECK(!strchr(err.message, '\n'));
}

/* A graph of the given jobs (each "id|deps|overrides") refused with message. */
static void expect_jobs_refused(const char *const *jobs, int n, const char *message)
{
    char list[8192] = "";
    size_t len = 0;
    for (int i = 0; i < n; i++) {
        char id[64], deps[256] = "", over[512] = "";
        sscanf(jobs[i], "%63[^|]|%255[^|]|%511[^\n]", id, deps, over);
        if (!strcmp(deps, "-"))
            deps[0] = 0;
        len += (size_t)snprintf(list + len, sizeof list - len, "%s", i ? "," : "");
        len += (size_t)job_text(list + len, sizeof list - len, id, deps, over);
    }
    char *text = graph_text(list);
    expect_refused(text, message);
    free(text);
}

static void test_good_graphs(void)
{
    /* Listed against their order: a diamond, a repeated dependency, the index. */
    const char *const specs[][3] = {
        {"\"s/report\"", "\"s/render/0\",\"s/render/1\"", ",\"stage\":\"report\""},
        {"\"s/render/1\"", "\"s/rig\"", ",\"stage\":\"render\",\"array\":\"s/render\""},
        {"\"s/render/0\"", "\"s/rig\"", ",\"stage\":\"render\",\"array\":\"s/render\""},
        {"\"s/rig\"", "\"s/merge/0\",\"s/merge/0\"", ",\"stage\":\"rig\""},
        {"\"s/merge/0\"", "", ",\"key\":\"abc\",\"up_to_date\":true"},
        {"\"index\"", "\"s/report\"", ",\"stage\":\"index\",\"setup\":null"},
    };
    char list[8192] = "";
    size_t len = 0;
    for (int i = 0; i < 6; i++) {
        len += (size_t)snprintf(list + len, sizeof list - len, "%s", i ? "," : "");
        len += (size_t)job_text(list + len, sizeof list - len, specs[i][0], specs[i][1],
                                specs[i][2]);
    }
    char *text = graph_text(list);
    sl_pipeline_graph *g = NULL;
    sl_error err = {0};
    CHECK_OK(sl_pipeline_graph_parse("day/jobs.json", text, strlen(text), &g, &err), &err);
    free(text);
    CHECK(sl_pipeline_graph_job_count(g) == 6);
    const char *want[] = {"s/merge/0", "s/rig", "s/render/1", "s/render/0", "s/report", "index"};
    for (int k = 0; k < 6; k++)
        CHECK_MSG(sl_pipeline_graph_job_id(g, k) && !strcmp(sl_pipeline_graph_job_id(g, k), want[k]),
                  "order %d: %s, expected %s", k, sl_pipeline_graph_job_id(g, k), want[k]);
    CHECK(sl_pipeline_graph_job_id(g, 6) == NULL && sl_pipeline_graph_job_id(g, -1) == NULL);
    sl_pipeline_graph_free(g);

    /* No job at all (every setup failed before planning) is a graph; the
     * text need not end with a NUL. */
    const char *empty = "{\"format\":\"setlight-jobs\",\"version\":1,\"out\":\"/d\",\"jobs\":[]}XYZ";
    CHECK_OK(sl_pipeline_graph_parse("e.json", empty, strlen(empty) - 3, &g, &err), &err);
    CHECK(sl_pipeline_graph_job_count(g) == 0);
    sl_pipeline_graph_free(g);
}

static void test_document(void)
{
    expect_refused("{\"format\":", "not a job graph: line 1:");
    expect_refused("[1, 2]", "format is not \"setlight-jobs\"");
    expect_refused("{\"format\":\"setlight-rig\",\"version\":1,\"jobs\":[]}",
                   "format is not \"setlight-jobs\"");
    expect_refused("{\"format\":\"setlight-jobs\",\"version\":2,\"out\":\"/d\",\"jobs\":[]}",
                   "job graph version is not 1");
    expect_refused("{\"format\":\"setlight-jobs\",\"version\":\"1\",\"out\":\"/d\",\"jobs\":[]}",
                   "job graph version is not 1");
    expect_refused("{\"format\":\"setlight-jobs\",\"version\":1,\"out\":\"day\",\"jobs\":[]}",
                   "\"out\" is not an absolute path");
    expect_refused("{\"format\":\"setlight-jobs\",\"version\":1,\"jobs\":[]}",
                   "\"out\" is not a string");
    expect_refused("{\"format\":\"setlight-jobs\",\"version\":1,\"out\":\"/d\",\"jobs\":{}}",
                   "\"jobs\" is not a list");
    /* A key given twice: which one counts would be jansson's choice. */
    expect_refused("{\"format\":\"setlight-jobs\",\"version\":1,\"out\":\"/d\",\"out\":\"/e\","
                   "\"jobs\":[]}",
                   "duplicate object key");
    /* "out" that no path buffer holds. */
    char *longout = malloc(PATH_MAX + 128);
    int n = snprintf(longout, PATH_MAX + 128, "{\"format\":\"setlight-jobs\",\"version\":1,\"out\":\"/");
    memset(longout + n, 'a', PATH_MAX);
    snprintf(longout + n + PATH_MAX, 64, "\",\"jobs\":[]}");
    expect_refused(longout, "\"out\" is longer than PATH_MAX");
    free(longout);
}

static void test_caps(void)
{
    /* Over SL_MAX_JSON_BYTES: refused before jansson reads a byte. */
    size_t big = (size_t)SL_MAX_JSON_BYTES + 1;
    char *text = malloc(big);
    memset(text, ' ', big);
    sl_pipeline_graph *g = NULL;
    sl_error err = {0};
    CHECK_RESULT(sl_pipeline_graph_parse("big.json", text, big, &g, &err), SL_ERR_INPUT, &err);
    CHECK_MSG(strstr(err.message, "big.json: a job graph of 16777217 bytes, more than 16777216"),
              "%s", err.message);
    free(text);

    /* More jobs than SL_PIPELINE_MAX_JOBS: refused on the count, before
     * any job is looked at. */
    size_t n = SL_PIPELINE_MAX_JOBS + 1;
    char *list = malloc(3 * n + 1);
    for (size_t i = 0; i < n; i++)
        memcpy(list + 3 * i, i ? ",{}" : "{} ", 3);
    list[3 * n] = 0;
    text = graph_text(list);
    expect_refused(text, "32769 jobs, more than 32768");
    free(text);
    free(list);

    /* A list of one job over SL_PIPELINE_MAX_LIST entries. */
    size_t entries = SL_PIPELINE_MAX_LIST + 1;
    char *inputs = malloc(entries * 8 + 64);
    size_t len = (size_t)sprintf(inputs, ",\"inputs\":[");
    for (size_t i = 0; i < entries; i++)
        len += (size_t)sprintf(inputs + len, "%s\"/d/i\"", i ? "," : "");
    sprintf(inputs + len, "]");
    char *job = malloc(len + 1024);
    job_text(job, len + 1024, "\"a\"", "", inputs);
    text = graph_text(job);
    expect_refused(text, "job 'a': \"inputs\" has 4097 entries, more than 4096");
    free(text);
    free(job);
    free(inputs);
}

static void test_fields(void)
{
    const char *no_id[] = {"\"a\"|-|", "7|-|"};
    expect_jobs_refused(no_id, 2, "job 2: \"id\" is missing or not a string");
    char *text = graph_text("1");
    expect_refused(text, "job 1: not an object");
    free(text);
    const char *empty_id[] = {"\"\"|-|"};
    expect_jobs_refused(empty_id, 1, "job 1: \"id\" is not a relative path");
    /* Ids name the stamps OUT/<id>.stamp.json: none may lead outside OUT. */
    const char *escaping[] = {"\"../../etc/x\"|-|", "\"/abs\"|-|", "\"a//b\"|-|", "\"a/./b\"|-|",
                              "\"a/\"|-|", "\"a\\nb\"|-|"};
    for (int i = 0; i < 6; i++)
        expect_jobs_refused(&escaping[i], 1, "job 1: \"id\" is not a relative path");
    const char *dup[] = {"\"a\"|-|", "\"b\"|-|", "\"a\"|-|"};
    expect_jobs_refused(dup, 3, "job 'a': two jobs have this id");

    static const struct {
        const char *over, *message;
    } cases[] = {
        {",\"stage\":\"paint\"", "job 'a': \"stage\" is not one of merge"},
        {",\"stage\":null", "job 'a': \"stage\" is not one of merge"},
        {",\"setup\":3", "job 'a': \"setup\" is neither a string nor null"},
        {",\"argv\":[]", "job 'a': \"argv\" is empty"},
        {",\"argv\":\"setlight job\"", "job 'a': \"argv\" is not a list"},
        {",\"command\":[\"/bin/setlight\",1]", "job 'a': \"command\" entry 2 is not a string"},
        {",\"command\":[]", "job 'a': \"command\" is empty"},
        {",\"inputs\":[\"in.tif\"]", "job 'a': \"inputs\" entry 1 is not an absolute path"},
        {",\"inputs\":null", "job 'a': \"inputs\" is not a list"},
        {",\"outputs\":[\"/d/o.exr\",null]", "job 'a': \"outputs\" entry 2 is not a string"},
        {",\"log\":\"x.log\"", "job 'a': \"log\" is not an absolute path"},
        {",\"log\":[]", "job 'a': \"log\" is not a string"},
        {",\"array\":1", "job 'a': \"array\" is neither a string nor null"},
        {",\"key\":false", "job 'a': \"key\" is neither a string nor null"},
        {",\"memory_mb\":-1", "job 'a': \"memory_mb\" is not a whole number >= 0"},
        {",\"memory_mb\":1.5", "job 'a': \"memory_mb\" is not a whole number >= 0"},
        {",\"memory_mb\":4294967296", "job 'a': \"memory_mb\" is not a whole number >= 0"},
        {",\"cpus\":0", "job 'a': \"cpus\" is not a whole number >= 1"},
        {",\"cpu_seconds\":-0.5", "job 'a': \"cpu_seconds\" is not a number >= 0"},
        {",\"cpu_seconds\":\"1\"", "job 'a': \"cpu_seconds\" is not a number >= 0"},
        {",\"up_to_date\":1", "job 'a': \"up_to_date\" is not true or false"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof *cases; i++) {
        char spec[256];
        snprintf(spec, sizeof spec, "\"a\"|-|%s", cases[i].over);
        const char *one[] = {spec};
        expect_jobs_refused(one, 1, cases[i].message);
    }
    /* "deps" is a list of strings. */
    char job[2048];
    job_text(job, sizeof job, "\"a\"", "1", "");
    text = graph_text(job);
    expect_refused(text, "job 'a': \"deps\" entry 1 is not a string");
    free(text);
}

static void test_dependencies(void)
{
    const char *unknown[] = {"\"a\"|-|", "\"b\"|\"a\",\"nowhere\"|"};
    expect_jobs_refused(unknown, 2, "job 'b': dependency 'nowhere' is not a job of the graph");
    const char *self[] = {"\"a\"|\"a\"|"};
    expect_jobs_refused(self, 1, "job 'a': depends on itself");
    /* The cycle is named, not the job that only waits on it (d). */
    const char *cycle[] = {"\"d\"|\"a\"|", "\"a\"|\"c\"|", "\"b\"|\"a\"|", "\"c\"|\"b\"|",
                           "\"e\"|-|"};
    expect_jobs_refused(cycle, 5, "its dependencies form a cycle (");
    expect_jobs_refused(cycle, 5, "a -> c -> b -> a)");
    const char *pair[] = {"\"x\"|\"y\"|", "\"y\"|\"x\"|"};
    expect_jobs_refused(pair, 2, "job 'x': its dependencies form a cycle (x -> y -> x)");
}

/* The file through `setlight job`'s call: refused (exit 3) with the file's
 * name, and neither stamp nor log nor output folder written. */
static void test_job_run_refuses(void)
{
    const char *dir = sl_test_tmpdir();
    char jobs[1024], list[4096], over[1024], out_dir[1024];
    snprintf(jobs, sizeof jobs, "%s/jobs.json", dir);
    snprintf(out_dir, sizeof out_dir, "%s/day", dir);
    snprintf(over, sizeof over,
             ",\"command\":[\"/bin/true\"],\"outputs\":[\"%s/day/a/out.txt\"],\"inputs\":[],"
             "\"log\":\"%s/day/logs/a.log\"",
             dir, dir);
    int len = job_text(list, sizeof list, "\"a\"", "\"b\"", over);
    char doc[8192];
    snprintf(doc, sizeof doc,
             "{\"format\":\"setlight-jobs\",\"version\":1,\"out\":\"%s/day\",\"jobs\":[%.*s]}", dir,
             len, list);
    sl_error err = {0};
    CHECK_OK(sl_write_file_atomic(jobs, doc, strlen(doc), &err), &err);
    int code = -1;
    bool skipped = true;
    CHECK_RESULT(sl_pipeline_job_run(jobs, "a", &code, &skipped, &err), SL_ERR_INPUT, &err);
    CHECK_MSG(strstr(err.message, jobs) && strstr(err.message, "dependency 'b' is not a job"),
              "%s", err.message);
    CHECK(sl_result_exit_code(err.code) == 3);
    CHECK(!sl_test_file_exists(out_dir));
    /* The report and the index read the graph the same way. */
    CHECK_RESULT(sl_pipeline_report_index(jobs, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "dependency 'b' is not a job") != NULL);
    CHECK_RESULT(sl_pipeline_report_setup(jobs, "s", &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "dependency 'b' is not a job") != NULL);
    CHECK(!sl_test_file_exists(out_dir));
    /* A missing graph is not found. */
    snprintf(jobs, sizeof jobs, "%s/none.json", dir);
    CHECK_RESULT(sl_pipeline_job_run(jobs, "a", &code, &skipped, &err), SL_ERR_NOT_FOUND, &err);
}

int main(void)
{
    RUN(test_good_graphs);
    RUN(test_document);
    RUN(test_caps);
    RUN(test_fields);
    RUN(test_dependencies);
    RUN(test_job_run_refuses);
    return sl_test_finish();
}
