/* SPDX-License-Identifier: BSD-3-Clause */
/* pipeline: a grouped setup's jobs shared by two processes through claim
 * files (sl_pipeline_jobs_share, pipeline/share.c: what a grouped setup's
 * Slurm job and a Slurm job helping it run, docs/slurm.md). A setup of
 * shell jobs shaped like the planner's (four independent "merges", a
 * "stitch" after them, three "renders" after it, a "report" after those),
 * each job counting its runs in a file of its own: two workers started
 * together split its jobs, each job runs exactly once and the outputs are
 * those of one worker alone; a failed job's dependants are not run by
 * either; a job whose claimant died without ending it (on this host, or
 * with its Slurm job said ended) does not leave the other waiting; a claims
 * folder that takes no claim runs nothing and says so. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include "../pipeline/pipeline_private.h"
#include "testing.h"

enum { N = 9 };
static const char *const ids[N] = {"s/merge/0", "s/merge/1", "s/merge/2", "s/merge/3", "s/stitch",
                                   "s/render/0", "s/render/1", "s/render/2", "s/report"};

/* Job k's output: OUT/ID.txt, beside its stamp. Its command appends a line to OUT/ran/k
 * (the count of its runs), sleeps a little (so that two workers overlap)
 * and writes its output from its inputs' contents; fail: the one job made
 * to exit 1. */
static void write_setup(const char *out, const char *jobs, int fail)
{
    json_t *list = json_array();
    for (int k = 0; k < N; k++) {
        char output[1024], log[1024], cmd[4096] = "", inputs_text[2048] = "";
        snprintf(output, sizeof output, "%s/%s.txt", out, ids[k]);
        snprintf(log, sizeof log, "%s/logs/%d.log", out, k);
        json_t *inputs = json_array(), *deps = json_array();
        int from = k < 4 ? 0 : k == 4 ? 0 : k < 8 ? 4 : 5, to = k < 4 ? 0 : k == 4 ? 4 : k < 8 ? 5 : 8;
        for (int d = from; d < to; d++) {
            char in[1024];
            snprintf(in, sizeof in, "%s/%s.txt", out, ids[d]);
            json_array_append_new(inputs, json_string(in));
            json_array_append_new(deps, json_string(ids[d]));
            size_t len = strlen(inputs_text);
            snprintf(inputs_text + len, sizeof inputs_text - len, " '%s'", in);
        }
        char cat[2100] = "";
        if (inputs_text[0])
            snprintf(cat, sizeof cat, "cat%s;", inputs_text);
        snprintf(cmd, sizeof cmd, "echo x >>'%s/ran/%d' && sleep 0.15 && %s { echo %d; %s } >'%s'",
                 out, k, k == fail ? "exit 1 &&" : "", k, cat, output);
        const char *stage = k < 4 ? "merge" : k == 4 ? "stitch" : k < 8 ? "render" : "report";
        json_array_append_new(
            list, json_pack("{s:s,s:s,s:s,s:[s,s,s,s],s:[s,s,s],s:o,s:[s],s:o,s:n,s:i,s:i,s:s,"
                            "s:n,s:b}",
                            "id", ids[k], "setup", "s", "stage", stage, "argv", "/bin/setlight",
                            "job", jobs, ids[k], "command", "/bin/sh", "-c", cmd, "inputs", inputs,
                            "outputs", output, "deps", deps, "array", "memory_mb", 1, "cpus", 1,
                            "log", log, "key", "up_to_date", 0));
    }
    json_t *graph = json_pack("{s:s,s:i,s:s,s:s,s:o}", "format", "setlight-jobs", "version", 1,
                              "setlight", sl_version(), "out", out, "jobs", list);
    char dir[1100];
    snprintf(dir, sizeof dir, "%s/ran", out);
    sl_error err;
    CHECK_OK(pl_mkdirs(dir, &err), &err);
    snprintf(dir, sizeof dir, "%s/farm/claims/0", out);
    CHECK_OK(pl_mkdirs(dir, &err), &err);
    CHECK_OK(pl_json_write(jobs, graph, &err), &err);
    json_decref(graph);
}

/* Runs the setup's jobs in `workers` processes sharing out's claims,
 * released together; each worker's count of the jobs it took (ran or
 * marked not run) in took[], its codes in codes[w][]. */
static void share(const char *out, const char *jobs, int workers, int took[2], int codes[2][N])
{
    char claims[1100];
    snprintf(claims, sizeof claims, "%s/farm/claims/0", out);
    int go[2], back[2][2];
    pid_t pid[2];
    CHECK(pipe(go) == 0);
    for (int w = 0; w < workers; w++) {
        CHECK(pipe(back[w]) == 0);
        fflush(NULL);
        pid[w] = fork();
        if (pid[w] == 0) {
            char c;
            close(go[1]);
            if (read(go[0], &c, 1) < 0)
                _exit(99);
            int mine[N];
            sl_error errs[N];
            sl_pipeline_jobs_share(jobs, claims, (char *const *)ids, N, mine, errs);
            _exit(write(back[w][1], mine, sizeof mine) == (ssize_t)sizeof mine ? 0 : 98);
        }
        close(back[w][1]);
    }
    close(go[0]);
    close(go[1]); /* every worker's read returns at once */
    for (int w = 0; w < workers; w++) {
        int status;
        CHECK(read(back[w][0], codes[w], sizeof codes[w]) == (ssize_t)sizeof codes[w]);
        close(back[w][0]);
        waitpid(pid[w], &status, 0);
        CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
        took[w] = 0;
        for (int k = 0; k < N; k++)
            took[w] += codes[w][k] != SL_PIPELINE_JOB_ELSEWHERE;
    }
}

static int runs_of(const char *out, int k)
{
    char path[1100];
    snprintf(path, sizeof path, "%s/ran/%d", out, k);
    char *text = sl_test_read_file(path, NULL);
    int lines = 0;
    for (char *p = text; p && *p; p++)
        lines += *p == '\n';
    free(text);
    return lines;
}

static void test_two_workers_split_a_setup(void)
{
    char one[1024], two[1024], jobs_one[1100], jobs_two[1100];
    snprintf(one, sizeof one, "%s/one", sl_test_tmpdir());
    snprintf(two, sizeof two, "%s/two", sl_test_tmpdir());
    snprintf(jobs_one, sizeof jobs_one, "%s/jobs.json", one);
    snprintf(jobs_two, sizeof jobs_two, "%s/jobs.json", two);
    write_setup(one, jobs_one, -1);
    write_setup(two, jobs_two, -1);
    int took[2], codes[2][N];
    share(one, jobs_one, 1, took, codes);
    CHECK(took[0] == N);
    for (int k = 0; k < N; k++)
        CHECK_MSG(codes[0][k] == 0 && runs_of(one, k) == 1, "one worker: job %d code %d, %d runs",
                  k, codes[0][k], runs_of(one, k));
    share(two, jobs_two, 2, took, codes);
    CHECK_MSG(took[0] >= 1 && took[1] >= 1 && took[0] + took[1] == N,
              "the two workers took %d and %d of %d jobs", took[0], took[1], N);
    for (int k = 0; k < N; k++) {
        int mine = (codes[0][k] != SL_PIPELINE_JOB_ELSEWHERE) + (codes[1][k] != SL_PIPELINE_JOB_ELSEWHERE);
        CHECK_MSG(mine == 1 && runs_of(two, k) == 1, "job %d: taken by %d workers, run %d times", k,
                  mine, runs_of(two, k));
        char a[1100], b[1100];
        snprintf(a, sizeof a, "%s/%s.txt", one, ids[k]);
        snprintf(b, sizeof b, "%s/%s.txt", two, ids[k]);
        char *ta = sl_test_read_file(a, NULL), *tb = sl_test_read_file(b, NULL);
        CHECK_MSG(ta && tb && !strcmp(ta, tb), "job %d's output differs", k);
        free(ta);
        free(tb);
        /* stamped as `setlight job` stamps: ok with its key */
        json_t *stamp = NULL;
        sl_error err;
        snprintf(b, sizeof b, "%s/%s.stamp.json", two, ids[k]);
        CHECK_OK(pl_json_load(b, &stamp, &err), &err);
        const char *status = json_string_value(json_object_get(stamp, "status"));
        CHECK_MSG(status && !strcmp(status, "ok"), "job %d's stamp", k);
        json_decref(stamp);
    }
    /* the setup marked all taken: a script skips it without a start of setlight */
    char all[1100];
    snprintf(all, sizeof all, "%s/farm/claims/0/all", two);
    CHECK(sl_test_file_exists(all));
}

static void test_failure_not_run_by_either(void)
{
    char out[1024], jobs[1100];
    snprintf(out, sizeof out, "%s/failed", sl_test_tmpdir());
    snprintf(jobs, sizeof jobs, "%s/jobs.json", out);
    write_setup(out, jobs, 2);
    int took[2], codes[2][N];
    share(out, jobs, 2, took, codes);
    CHECK(took[0] + took[1] == N);
    for (int k = 0; k < N; k++) {
        int code = codes[0][k] != SL_PIPELINE_JOB_ELSEWHERE ? codes[0][k] : codes[1][k];
        int want = k < 4 ? (k == 2 ? 1 : 0) : -1;
        CHECK_MSG(code == want, "job %d: code %d, not %d", k, code, want);
        CHECK_MSG(runs_of(out, k) == (k < 4), "job %d ran %d times", k, runs_of(out, k));
    }
}

/* A claim of `text` planted for job k, as a killed worker leaves it. */
static void plant_claim(const char *out, int k, const char *text)
{
    char path[1100];
    snprintf(path, sizeof path, "%s/farm/claims/0/%d", out, k);
    FILE *f = fopen(path, "w");
    CHECK(f && fputs(text, f) >= 0);
    if (f)
        fclose(f);
}

static void test_gone_claimant(void)
{
    char out[1024], jobs[1100], host[256] = "", text[400];
    gethostname(host, sizeof host - 1);
    /* on this host: a process that has exited */
    pid_t dead = fork();
    if (dead == 0)
        _exit(0);
    waitpid(dead, NULL, 0);
    for (int way = 0; way < 2; way++) {
        snprintf(out, sizeof out, "%s/gone%d", sl_test_tmpdir(), way);
        snprintf(jobs, sizeof jobs, "%s/jobs.json", out);
        write_setup(out, jobs, -1);
        if (way == 0) {
            snprintf(text, sizeof text, "%s %ld 5\n", host, (long)dead);
        } else {
            /* on another node, its Slurm job seen ended by the runner */
            snprintf(text, sizeof text, "elsewhere.invalid 1 4242\n");
            char ended[1100];
            snprintf(ended, sizeof ended, "%s/farm/ended", out);
            CHECK(mkdir(ended, 0755) == 0);
            snprintf(ended, sizeof ended, "%s/farm/ended/4242", out);
            FILE *f = fopen(ended, "w");
            CHECK(f != NULL);
            if (f)
                fclose(f);
        }
        plant_claim(out, 1, text);
        int took[2], codes[2][N];
        double t0 = sl_seconds();
        share(out, jobs, 1, took, codes);
        CHECK_MSG(sl_seconds() - t0 < 60, "the worker waited %.0f s", sl_seconds() - t0);
        CHECK(codes[0][1] == SL_PIPELINE_JOB_ELSEWHERE && runs_of(out, 1) == 0);
        for (int k = 0; k < N; k++)
            if (k != 1)
                CHECK_MSG(codes[0][k] == (k < 4 ? 0 : -1), "way %d: job %d code %d", way, k,
                          codes[0][k]);
    }
}

/* A claims folder that cannot take a claim: nothing run, and said (not an
 * exit 0 with every job "taken elsewhere"). */
static void test_claims_folder_missing(void)
{
    char out[1024], jobs[1100], claims[1100];
    snprintf(out, sizeof out, "%s/noclaims", sl_test_tmpdir());
    snprintf(jobs, sizeof jobs, "%s/jobs.json", out);
    snprintf(claims, sizeof claims, "%s/farm/none", out);
    write_setup(out, jobs, -1);
    int codes[N];
    sl_error errs[N];
    sl_pipeline_jobs_share(jobs, claims, (char *const *)ids, N, codes, errs);
    CHECK_MSG(codes[0] == sl_result_exit_code(SL_ERR_IO) && errs[0].code == SL_ERR_IO &&
                  strstr(errs[0].message, "cannot claim s/merge/0"),
              "code %d: %s", codes[0], errs[0].message);
    CHECK(runs_of(out, 0) == 0);
}

int main(void)
{
    RUN(test_two_workers_split_a_setup);
    RUN(test_failure_not_run_by_either);
    RUN(test_gone_claimant);
    RUN(test_claims_folder_missing);
    return sl_test_finish();
}
