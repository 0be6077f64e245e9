/* SPDX-License-Identifier: BSD-3-Clause */
/* pipeline: the graph checked once, where it is written (pl_graph_write),
 * and a job read alone while the file is unchanged (pl_graph_load_job):
 * the job read alone is the job of the graph; a graph that does not hold
 * together is not written; a graph edited afterwards (broken, or valid but
 * changed), a sidecar that is stale or corrupt, and the index's job all go
 * through the whole check, so an edited graph is refused as before. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../pipeline/pipeline_private.h"
#include "testing.h"

static json_t *job(const char *dir, const char *id, const char *stage, const char *dep)
{
    char log[1024], out[1024];
    snprintf(log, sizeof log, "%s/day/logs/%s.log", dir, id);
    snprintf(out, sizeof out, "%s/day/%s.txt", dir, id);
    return json_pack("{s:s,s:s,s:s,s:[s,s,s,s],s:[s,s],s:[],s:[s],s:[s*],s:n,s:i,s:i,s:s,s:n,"
                     "s:b}",
                     "id", id, "setup", "s", "stage", stage, "argv", "/bin/setlight", "job",
                     "/d/jobs.json", id, "command", "/bin/echo", id, "inputs", "outputs", out,
                     "deps", dep, "array", "memory_mb", 1, "cpus", 1, "log", log, "key",
                     "up_to_date", 0);
}

static json_t *day(const char *dir)
{
    char out[1024];
    snprintf(out, sizeof out, "%s/day", dir);
    json_t *jobs = json_array();
    json_array_append_new(jobs, job(dir, "s/merge/0", "merge", NULL));
    json_array_append_new(jobs, job(dir, "s/stitch", "stitch", "s/merge/0"));
    json_array_append_new(jobs, job(dir, "index", "index", "s/stitch"));
    return json_pack("{s:s,s:i,s:s,s:s,s:o}", "format", "setlight-jobs", "version", 1,
                     "setlight", "test", "out", out, "jobs", jobs);
}

/* Loads job id and checks it is the graph's own, by value. */
static void expect_job(const char *path, const json_t *graph, const char *id, bool whole)
{
    json_t *doc = NULL, *one = NULL;
    bool checked_whole = !whole;
    sl_error err = {0};
    CHECK_OK(pl_graph_load_job(path, id, &doc, &one, &checked_whole, &err), &err);
    CHECK_MSG(checked_whole == whole, "%s: checked whole %d, expected %d", id, checked_whole,
              whole);
    size_t i;
    json_t *j, *want = NULL;
    json_array_foreach(json_object_get(graph, "jobs"), i, j)
        if (!strcmp(json_string_value(json_object_get(j, "id")), id))
            want = j;
    CHECK_MSG(want && json_equal(one, want), "%s: not the graph's job", id);
    CHECK(json_equal(json_object_get(doc, "out"), json_object_get(graph, "out")));
    json_decref(doc);
    json_decref(one);
}

static char *slurp(const char *path, size_t *n)
{
    return sl_test_read_file(path, n);
}

static void spit(const char *path, const char *text, size_t n)
{
    sl_error err;
    CHECK_OK(sl_write_file_atomic(path, text, n, &err), &err);
}

static void test_checked_once(void)
{
    const char *dir = sl_test_tmpdir();
    char path[1024], side[1100];
    snprintf(path, sizeof path, "%s/jobs.json", dir);
    snprintf(side, sizeof side, "%s.checked", path);
    json_t *graph = day(dir);
    sl_error err = {0};
    CHECK_OK(pl_graph_write(path, graph, &err), &err);
    CHECK(sl_test_file_exists(side));
    /* What was written parses back whole to the same graph. */
    sl_pipeline_graph *g = NULL;
    CHECK_OK(pl_graph_load(path, &g, &err), &err);
    CHECK(g && json_equal(g->root, graph));
    sl_pipeline_graph_free(g);

    /* Unchanged: each job read alone; the index's job reads them all. */
    expect_job(path, graph, "s/merge/0", false);
    expect_job(path, graph, "s/stitch", false);
    expect_job(path, graph, "index", true);
    json_t *doc, *one;
    bool whole;
    CHECK_RESULT(pl_graph_load_job(path, "s/none", &doc, &one, &whole, &err), SL_ERR_USAGE, &err);
    CHECK(strstr(err.message, "no job 's/none'") != NULL);

    /* Edited into a graph that does not hold together (the merge's
     * dependency renamed, same length): refused, naming the problem, even
     * for a job the edit did not touch. */
    size_t n = 0;
    char *text = slurp(path, &n);
    char *at = text ? strstr(text, "\"deps\":[\"s/merge/0\"]") : NULL;
    CHECK(at != NULL);
    if (at) {
        memcpy(at + 9, "s/merge/9", 9);
        spit(path, text, n);
        CHECK_RESULT(pl_graph_load_job(path, "s/merge/0", &doc, &one, &whole, &err),
                     SL_ERR_INPUT, &err);
        CHECK_MSG(strstr(err.message, "dependency 's/merge/9' is not a job of the graph"), "%s",
                  err.message);
        memcpy(at + 9, "s/merge/0", 9);
    }
    /* Edited but valid (a job's command changed): checked whole, and the
     * job read is the edited one. */
    char *cmd = text ? strstr(text, "\"/bin/echo\",\"s/stitch\"") : NULL;
    CHECK(cmd != NULL);
    if (cmd) {
        memcpy(cmd + 1, "/bin/true", 9); /* as long as /bin/echo */
        spit(path, text, n);
        sl_pipeline_graph *edited = NULL;
        CHECK_OK(pl_graph_load(path, &edited, &err), &err);
        if (edited)
            expect_job(path, edited->root, "s/stitch", true);
        sl_pipeline_graph_free(edited);
    }
    free(text);

    /* Written again: read alone again. A sidecar that does not parse, or
     * whose offsets point elsewhere, sends the job to the whole check. */
    CHECK_OK(pl_graph_write(path, graph, &err), &err);
    expect_job(path, graph, "s/stitch", false);
    char *good = slurp(side, &n);
    spit(side, "{", 1);
    expect_job(path, graph, "s/stitch", true);
    if (good) {
        char *moved = strstr(good, "\"s/stitch\":[");
        CHECK(moved != NULL);
        if (moved) {
            char *digit = moved + strlen("\"s/stitch\":[");
            *digit = *digit == '9' ? '1' : (char)(*digit + 1);
            spit(side, good, n);
            expect_job(path, graph, "s/stitch", true);
        }
        free(good);
    }

    /* A graph that does not hold together is not written, and the old
     * file's sidecar stays true to it. */
    CHECK_OK(pl_graph_write(path, graph, &err), &err);
    char *before = slurp(path, &n);
    json_t *bad = day(dir);
    json_t *jobs = json_object_get(bad, "jobs");
    json_array_append_new(json_object_get(json_array_get(jobs, 0), "deps"),
                          json_string("s/stitch")); /* merge <-> stitch */
    CHECK_RESULT(pl_graph_write(path, bad, &err), SL_ERR_INPUT, &err);
    CHECK_MSG(strstr(err.message, "cycle") != NULL, "%s", err.message);
    size_t m = 0;
    char *after = slurp(path, &m);
    CHECK(before && after && n == m && !memcmp(before, after, n));
    expect_job(path, graph, "s/merge/0", false);
    free(before);
    free(after);
    json_decref(bad);
    json_decref(graph);
}

int main(void)
{
    RUN(test_checked_once);
    return sl_test_finish();
}
