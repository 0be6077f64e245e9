/* SPDX-License-Identifier: BSD-3-Clause */
/* The local runner (pl_run_local) on jobs that are shell lines: the memory
 * budget keeps jobs apart (a lock folder each takes while it runs: two at
 * once would find it taken), a wider budget lets them overlap, a job larger
 * than the budget still runs (alone), dependencies come first, and a failed
 * job's dependants are not run while the index runs anyway; of the jobs
 * ready, the one with the longest chain of work after it starts first. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "../pipeline/pipeline_private.h"
#include "testing.h"

/* A job whose argv is `sh -c LINE`; LINE ends by writing an "ok" stamp
 * (as `setlight job` would) unless it fails first. */
static json_t *shell_job(const char *dir, const char *id, const char *stage, const char *line,
                         int memory_mb, const char *dep)
{
    char script[4096], flat[64];
    snprintf(flat, sizeof flat, "%s", id);
    for (char *p = flat; *p; p++)
        if (*p == '/')
            *p = '_';
    snprintf(script, sizeof script,
             "%s && mkdir -p %s/s/merge && echo '{\"status\": \"ok\", \"key\": \"-\", \"outputs\": []}' > %s/%s.stamp.json",
             line, dir, dir, id);
    json_t *job = json_pack("{s:s,s:s,s:s,s:[sss],s:[],s:[],s:[],s:[],s:n,s:i,s:i,s:s,s:n,s:b}",
                            "id", id, "setup", "s", "stage", stage, "argv", "/bin/sh", "-c", script,
                            "command", "inputs", "outputs", "deps", "array", "memory_mb",
                            memory_mb, "cpus", 1, "log", "/dev/null", "key", "up_to_date", 0);
    if (dep)
        json_array_append_new(json_object_get(job, "deps"), json_string(dep));
    return job;
}

/* Runs jobs (taken) as a graph out of dir, at most `slots` at once within
 * budget_mb (0: the default); the jobs' statuses (the caller's to free). */
static json_t *run_jobs(const char *dir, json_t *jobs, int slots, int budget_mb,
                        sl_pipeline_result *res)
{
    json_t *graph = json_pack("{s:s,s:i,s:s,s:s,s:o}", "format", "setlight-jobs", "version", 1,
                              "setlight", sl_version(), "out", dir, "jobs", jobs);
    sl_pipeline_options o;
    sl_pipeline_options_init(&o);
    o.jobs = slots;
    o.memory_mb = budget_mb;
    memset(res, 0, sizeof *res);
    json_t *status = json_object();
    sl_error err;
    CHECK_OK(pl_run_local(&o, graph, status, res, &err), &err);
    json_decref(graph);
    return status;
}

/* Four jobs that each hold OUT/lock for 0.2 s, run with a budget. */
static int overlaps(int budget_mb, int job_mb, int *ran)
{
    const char *dir = sl_test_tmpdir();
    char cmd[1024], line[1024];
    snprintf(cmd, sizeof cmd, "rm -rf %s/s %s/lock %s/overlap", dir, dir, dir);
    CHECK(system(cmd) == 0);
    json_t *jobs = json_array();
    for (int i = 0; i < 4; i++) {
        char id[32];
        snprintf(id, sizeof id, "s/merge/%d", i);
        snprintf(line, sizeof line,
                 "{ mkdir %s/lock 2>/dev/null || touch %s/overlap; }; sleep 0.2; rmdir %s/lock 2>/dev/null; true",
                 dir, dir, dir);
        json_array_append_new(jobs, shell_job(dir, id, "merge", line, job_mb, NULL));
    }
    sl_pipeline_result res;
    json_decref(run_jobs(dir, jobs, 4, budget_mb, &res));
    *ran = res.jobs_run - res.jobs_failed;
    char path[1024];
    snprintf(path, sizeof path, "%s/overlap", dir);
    return sl_test_file_exists(path);
}

static void test_memory_budget(void)
{
    int ran = 0;
    /* 60 MB each in 100 MB: one at a time. */
    CHECK(!overlaps(100, 60, &ran));
    CHECK(ran == 4);
    /* Larger than the budget: each still runs, alone. */
    CHECK(!overlaps(100, 500, &ran));
    CHECK(ran == 4);
    /* A budget for all four: they overlap (the check above can fail). */
    CHECK(overlaps(1000, 60, &ran));
    CHECK(ran == 4);
}

static void test_dependencies(void)
{
    const char *dir = sl_test_tmpdir();
    char cmd[1024], a[1024], b[1024], fail[1024];
    snprintf(cmd, sizeof cmd, "rm -rf %s/s %s/a_done %s/index_ran %s/status.json", dir, dir, dir, dir);
    CHECK(system(cmd) == 0);
    snprintf(a, sizeof a, "sleep 0.1; touch %s/a_done", dir);
    snprintf(b, sizeof b, "test -e %s/a_done", dir); /* fails unless a ran first */
    snprintf(fail, sizeof fail, "exit 3");
    char idx[1024];
    snprintf(idx, sizeof idx, "touch %s/index_ran", dir);
    json_t *jobs = json_array();
    json_array_append_new(jobs, shell_job(dir, "s/merge/0", "merge", a, 10, NULL));
    json_array_append_new(jobs, shell_job(dir, "s/stitch", "stitch", b, 10, "s/merge/0"));
    json_array_append_new(jobs, shell_job(dir, "s/merge/1", "merge", fail, 10, NULL));
    json_array_append_new(jobs, shell_job(dir, "s/unwrap", "unwrap", "true", 10, "s/merge/1"));
    json_t *index = shell_job(dir, "index", "index", idx, 10, "s/stitch");
    json_object_set_new(index, "setup", json_null());
    json_array_append_new(jobs, index);
    sl_pipeline_result res;
    json_t *status = run_jobs(dir, jobs, 3, 0, &res);
    CHECK(!strcmp(json_string_value(json_object_get(status, "s/merge/0")), "ran"));
    CHECK(!strcmp(json_string_value(json_object_get(status, "s/stitch")), "ran"));
    CHECK(!strcmp(json_string_value(json_object_get(status, "s/merge/1")), "failed"));
    CHECK(!strcmp(json_string_value(json_object_get(status, "s/unwrap")), "not run"));
    CHECK(!strcmp(json_string_value(json_object_get(status, "index")), "ran"));
    CHECK(res.jobs == 5 && res.jobs_failed == 1 && res.jobs_run == 4);
    json_decref(status);
}

/* Eight independent jobs of 0.2 s listed before a chain of three jobs of
 * 0.3 s, on two slots. In the graph's order the eight would start first and
 * leave the chain to run alone at the end (0.8 s, then 0.9 s on one slot);
 * longest remaining work first, the chain's head starts at once, each next
 * link as soon as the last ends, and the short jobs fill the other slot
 * (the chain done at 0.9 s, the short jobs at 1.6 s). Checked on the order
 * the jobs started in. */
static void test_critical_path_first(void)
{
    const char *dir = sl_test_tmpdir();
    char cmd[2200], line[1200], starts[1024];
    snprintf(starts, sizeof starts, "%s/starts", dir);
    snprintf(cmd, sizeof cmd, "rm -rf %s/s %s", dir, starts);
    CHECK(system(cmd) == 0);
    json_t *jobs = json_array();
    for (int i = 0; i < 8; i++) {
        char id[32];
        snprintf(id, sizeof id, "s/merge/%d", i);
        snprintf(line, sizeof line, "echo %s >>%s; sleep 0.2", id, starts);
        json_t *job = shell_job(dir, id, "merge", line, 10, NULL);
        json_object_set_new(job, "cpu_seconds", json_real(0.2));
        json_array_append_new(jobs, job);
    }
    const char *chain[] = {"s/stitch", "s/calibrate", "s/rig"};
    for (int i = 0; i < 3; i++) {
        snprintf(line, sizeof line, "echo %s >>%s; sleep 0.3", chain[i], starts);
        json_t *job = shell_job(dir, chain[i], chain[i] + 2, line, 10, i ? chain[i - 1] : NULL);
        json_object_set_new(job, "cpu_seconds", json_real(0.3));
        json_array_append_new(jobs, job);
    }
    sl_pipeline_result res;
    json_t *status = run_jobs(dir, jobs, 2, 0, &res);
    CHECK(res.jobs_run == 11 && res.jobs_failed == 0);
    /* The order of starts: the chain's head among the first two (the
     * graph's order would start two merges), and its last link before the
     * last merge (the graph's order would start it last of all). */
    char order[16][32];
    int count = 0, head = -1, last_link = -1, last_merge = -1;
    FILE *f = fopen(starts, "r");
    CHECK(f != NULL);
    while (f && count < 16 && fscanf(f, "%31s", order[count]) == 1) {
        if (!strcmp(order[count], "s/stitch"))
            head = count;
        if (!strcmp(order[count], "s/rig"))
            last_link = count;
        if (!strncmp(order[count], "s/merge/", 8))
            last_merge = count;
        count++;
    }
    if (f)
        fclose(f);
    CHECK(count == 11);
    CHECK_MSG(head >= 0 && head < 2, "the chain's head started %d-th", head + 1);
    CHECK_MSG(last_link >= 0 && last_link < last_merge,
              "the chain's last link started %d-th, the last merge %d-th", last_link + 1,
              last_merge + 1);
    json_decref(status);
}

/* A job as pl_plan makes them, `EXE job JOBS.json ID` running command line
 * `line` with one input and one output. */
static json_t *wrapped_job(const char *dir, const char *exe, const char *id, const char *line)
{
    char jobs[1024], in[1024], out[1024], log[1024];
    snprintf(jobs, sizeof jobs, "%s/jobs.json", dir);
    snprintf(in, sizeof in, "%s/in.txt", dir);
    snprintf(out, sizeof out, "%s/%s.txt", dir, id);
    snprintf(log, sizeof log, "%s/%s.log", dir, id);
    return json_pack("{s:s,s:s,s:s,s:[ssss],s:[sss],s:[s],s:[s],s:[],s:n,s:i,s:i,s:s,s:n,s:b}",
                     "id", id, "setup", "s", "stage", "merge", "argv", exe, "job", jobs, id,
                     "command", "/bin/sh", "-c", line, "inputs", in, "outputs", out, "deps",
                     "array", "memory_mb", 10, "cpus", 1, "log", log, "key", "up_to_date", 0);
}

/* `setlight job` runs in a fork of the runner when the argv is this very
 * setlight's (o.exe, here a path no file has: starting it would fail): the
 * command runs and the stamp has the key of its input; a failing command's
 * code is in its stamp; a job whose argv is another program's is started
 * as its argv says (here: cannot be, so it fails). */
static void forked_jobs(void)
{
    const char *dir = sl_test_tmpdir();
    char cmd[1200], line[1200], in[1024];
    snprintf(cmd, sizeof cmd, "rm -rf %s/s && mkdir -p %s/s", dir, dir);
    CHECK(system(cmd) == 0);
    snprintf(in, sizeof in, "%s/in.txt", dir);
    CHECK(sl_write_file_atomic(in, "frame", 5, NULL) == SL_OK);
    const char *exe = "/nonexistent/setlight";
    json_t *jobs = json_array();
    snprintf(line, sizeof line, "printf made >%s/s/ok.txt", dir);
    json_array_append_new(jobs, wrapped_job(dir, exe, "s/ok", line));
    json_array_append_new(jobs, wrapped_job(dir, exe, "s/fails", "exit 3"));
    json_array_append_new(jobs, wrapped_job(dir, "/nonexistent/other", "s/other", "true"));
    json_t *graph = json_pack("{s:s,s:i,s:s,s:s,s:O}", "format", "setlight-jobs", "version", 1,
                              "setlight", sl_version(), "out", dir, "jobs", jobs);
    sl_pipeline_options o;
    sl_pipeline_options_init(&o);
    o.jobs = 2;
    o.exe = exe;
    sl_pipeline_result res;
    memset(&res, 0, sizeof res);
    json_t *status = json_object();
    sl_error err;
    CHECK_OK(pl_run_local(&o, graph, status, &res, &err), &err);
    CHECK(!strcmp(json_string_value(json_object_get(status, "s/ok")), "ran"));
    CHECK(!strcmp(json_string_value(json_object_get(status, "s/fails")), "failed"));
    CHECK(!strcmp(json_string_value(json_object_get(status, "s/other")), "failed"));
    char path[1200], key[65];
    snprintf(path, sizeof path, "%s/s/ok.txt", dir);
    CHECK(sl_test_file_exists(path));
    CHECK(pl_job_key(json_array_get(jobs, 0), key));
    json_t *st = pl_stamp_load(graph, json_array_get(jobs, 0));
    CHECK(st && !strcmp(json_string_value(json_object_get(st, "status")), "ok"));
    CHECK(st && !strcmp(json_string_value(json_object_get(st, "key")), key));
    CHECK(st && json_number_value(json_object_get(st, "job_max_rss_mb")) > 0);
    json_decref(st);
    st = pl_stamp_load(graph, json_array_get(jobs, 1));
    CHECK(st && !strcmp(json_string_value(json_object_get(st, "status")), "failed") &&
          json_integer_value(json_object_get(st, "exit")) == 3);
    json_decref(st);
    CHECK(pl_stamp_load(graph, json_array_get(jobs, 2)) == NULL);
    json_decref(status);
    json_decref(jobs);
    json_decref(graph);
}

/* forked_jobs in a child of its own: a fork copies only the calling
 * thread, so its runner is single-threaded (and forks its jobs) whatever
 * threads this process or a sanitizer's runtime has started. */
static void test_forked_jobs(void)
{
    fflush(NULL);
    pid_t pid = fork();
    if (pid == 0) {
        int before = sl_test_failed;
        forked_jobs();
        fflush(NULL);
        _exit(sl_test_failed != before);
    }
    int status = 0;
    CHECK(pid > 0 && waitpid(pid, &status, 0) == pid && WIFEXITED(status) && WEXITSTATUS(status) == 0);
}

int main(void)
{
    RUN(test_memory_budget);
    RUN(test_dependencies);
    RUN(test_critical_path_first);
    RUN(test_forked_jobs);
    return sl_test_finish();
}
