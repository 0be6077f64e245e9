/* SPDX-License-Identifier: BSD-3-Clause */
/* sl_pipeline_slurm_run on a real single-node Slurm cluster started by
 * tests/slurm/cluster.sh (skipped, with its reason, where the daemons cannot
 * start): a hand-written job graph of shell commands with a dependency
 * chain, an array group of three and one job made to fail. The failed job's
 * dependents end cancelled (not pending forever); a rerun after the fix
 * submits only the failed job and what follows it. The graph checks and
 * the missing-sbatch and cluster-down errors need no cluster. */
#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "slurm.h"
#include "testing.h"

static char cluster_dir[4096];
static bool cluster_up;
static bool cluster_in_tmp; /* a folder of its own in /tmp, removed after */

static void run_stop(void)
{
    char cmd[8400];
    snprintf(cmd, sizeof cmd, "bash '%s/tests/slurm/cluster.sh' stop '%s'", SETLIGHT_SOURCE_DIR,
             cluster_dir);
    if (system(cmd) != 0)
        fprintf(stderr, "warning: %s failed\n", cmd);
    if (cluster_in_tmp) {
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", cluster_dir);
        if (system(cmd) != 0)
            fprintf(stderr, "warning: %s failed\n", cmd);
    }
}

static void stop_cluster(void)
{
    if (cluster_up)
        run_stop();
    cluster_up = false;
}

/* A child that stops the cluster when this process ends, however it ends
 * (a failed check, a sanitizer abort, SIGKILL from ctest's timeout): it
 * waits for the end of a pipe only this process holds. */
static void watch_cluster(void)
{
    int fds[2];
    if (pipe2(fds, O_CLOEXEC) != 0)
        return;
    pid_t pid = fork();
    if (pid == 0) {
        close(fds[1]);
        char c;
        while (read(fds[0], &c, 1) < 0 && errno == EINTR) {
        }
        run_stop();
        _exit(0);
    }
    close(fds[0]); /* fds[1] stays open until this process ends */
}

/* Starts the cluster; false (and a skip line with cluster.sh's reason) when
 * it cannot. Outside the test's own folder, which is cleared at start: a
 * cluster a killed run left there is stopped by the next start. */
static bool start_cluster(void)
{
    snprintf(cluster_dir, sizeof cluster_dir, "%s/slurm_cluster", SETLIGHT_TEST_TMP);
    /* munged's socket path must fit a sockaddr_un (107 bytes) */
    if (strlen(cluster_dir) + strlen("/munge/munge.sock") > 107) {
        snprintf(cluster_dir, sizeof cluster_dir, "/tmp/sl-slurm-test-XXXXXX");
        if (!mkdtemp(cluster_dir)) {
            sl_test_skip("Slurm tests: cannot make a folder for the cluster in /tmp");
            return false;
        }
        chmod(cluster_dir, 0755);
        cluster_in_tmp = true;
    }
    char cmd[8400], reason_path[4200];
    snprintf(reason_path, sizeof reason_path, "%s/cluster_start.err", sl_test_tmpdir());
    snprintf(cmd, sizeof cmd, "bash '%s/tests/slurm/cluster.sh' start '%s' >/dev/null 2>'%s'",
             SETLIGHT_SOURCE_DIR, cluster_dir, reason_path);
    int rc = system(cmd);
    if (rc != 0) {
        char *reason = sl_test_read_file(reason_path, NULL);
        char what[600];
        snprintf(what, sizeof what, "Slurm tests: the cluster did not start: %.500s",
                 reason && reason[0] ? strtok(reason, "\n") : "(no reason given)");
        sl_test_skip(what);
        free(reason);
        return false;
    }
    cluster_up = true;
    watch_cluster();
    char conf[4200];
    snprintf(conf, sizeof conf, "%s/slurm.conf", cluster_dir);
    setenv("SLURM_CONF", conf, 1);
    return true;
}

/* Paths kept (sl_test_path's buffer rotates). */
static const char *out_dir(void)
{
    static char dir[1024];
    if (!dir[0])
        snprintf(dir, sizeof dir, "%.1000s", sl_test_path("out"));
    return dir;
}

static const char *keep_path(const char *name)
{
    static char paths[4][4096];
    static int next;
    char *p = paths[next++ % 4];
    snprintf(p, 4096, "%s", sl_test_path(name));
    return p;
}

/* One job of the graph: its command is `sh -c SCRIPT` with @ standing for
 * the output folder. */
typedef struct tjob {
    const char *id, *script, *deps, *array;
    bool up_to_date;
} tjob;

static const tjob day[] = {
    {"a/prep", "echo a > @/a.txt && echo prepared", "", NULL, false},
    {"a/merge/0", "{ cat @/a.txt; echo 0; } > @/m0.txt && echo merge 0", "\"a/prep\"", "a/merge",
     false},
    {"a/merge/1",
     "if [ -e @/fail ]; then echo 'view 1: frame corrupt' >&2; exit 3; fi; "
     "{ cat @/a.txt; echo 1; } > @/m1.txt",
     "\"a/prep\"", "a/merge", false},
    {"a/merge/2", "{ cat @/a.txt; echo 2; } > @/m2.txt", "\"a/prep\"", "a/merge", false},
    {"a/stitch", "cat @/m0.txt @/m1.txt @/m2.txt > @/stitch.txt",
     "\"a/merge/0\",\"a/merge/1\",\"a/merge/2\"", NULL, false},
    {"a/report", "wc -l < @/stitch.txt > @/report.txt", "\"a/stitch\"", NULL, false},
    {"b/prep", "echo b > @/b.txt", "", NULL, false},
    {"b/report", "cat @/b.txt @/b.txt > @/b_report.txt", "\"b/prep\"", NULL, false},
};
enum { DAY_JOBS = sizeof day / sizeof day[0] };

static int job_at(const sl_pipeline_slurm_result *res, const char *id)
{
    for (int i = 0; i < res->job_count; i++)
        if (strcmp(res->jobs[i].id, id) == 0)
            return i;
    return -1;
}

/* Writes the graph to `path`; up_to_date[i] overrides day[i]'s when given. */
static void write_graph(const char *path, const bool *up_to_date)
{
    FILE *f = fopen(path, "w");
    if (!f) {
        CHECK_MSG(0, "cannot write %s", path);
        return;
    }
    fprintf(f, "{\"format\":\"setlight-jobs\",\"version\":1,\"setlight\":\"%s\",\"out\":\"%s\",\"jobs\":[",
            SETLIGHT_VERSION, out_dir());
    for (int i = 0; i < DAY_JOBS; i++) {
        char script[8192], log[2048], *w = script;
        for (const char *s = day[i].script; *s; s++) {
            if (*s == '@')
                w += sprintf(w, "%s", out_dir());
            else
                *w++ = *s;
        }
        *w = '\0';
        snprintf(log, sizeof log, "%s/logs/%s.log", out_dir(), day[i].id);
        for (char *p = log + strlen(out_dir()) + 6; *p; p++)
            if (*p == '/')
                *p = '_';
        /* JSON-escape the script's quotes */
        char escaped[16384], *e = escaped;
        for (const char *s = script; *s; s++) {
            if (*s == '"' || *s == '\\')
                *e++ = '\\';
            *e++ = *s;
        }
        *e = '\0';
        char array[64];
        snprintf(array, sizeof array, day[i].array ? "\"%s\"" : "null", day[i].array);
        fprintf(f,
                "%s{\"id\":\"%s\",\"setup\":\"%.1s\",\"stage\":\"merge\","
                "\"argv\":[\"/bin/sh\",\"-c\",\"%s\"],\"command\":[\"sh\"],\"inputs\":[],\"outputs\":[],"
                "\"deps\":[%s],\"array\":%s,\"memory_mb\":64,\"cpus\":1,\"log\":\"%s\","
                "\"key\":null,\"up_to_date\":%s}",
                i ? "," : "", day[i].id, day[i].id, escaped, day[i].deps, array, log,
                (up_to_date ? up_to_date[i] : day[i].up_to_date) ? "true" : "false");
    }
    fprintf(f, "]}\n");
    fclose(f);
}

static char *out_file(const char *name)
{
    char path[4200];
    snprintf(path, sizeof path, "%s/%s", out_dir(), name);
    return sl_test_read_file(path, NULL);
}

static void test_day_on_slurm(void)
{
    mkdir(out_dir(), 0755);
    char flag[4200];
    snprintf(flag, sizeof flag, "%s/fail", out_dir());
    FILE *f = fopen(flag, "w");
    CHECK(f != NULL);
    if (f)
        fclose(f);
    const char *graph = keep_path("jobs.json");
    write_graph(graph, NULL);

    sl_pipeline_slurm_options o;
    sl_pipeline_slurm_options_init(&o);
    o.poll_seconds = 0.1;
    o.timeout_seconds = 60;
    /* where a grouped setup's script says it ended; the runner says it in
     * ended/ for a job that did not (a killed one: a grouped setup's job it
     * had taken will not end, sl_pipeline_jobs_share) */
    char wake[4200];
    snprintf(wake, sizeof wake, "%s/wake", out_dir());
    mkdir(wake, 0755);
    o.wake_dir = wake;
    sl_pipeline_slurm_result res;
    sl_error err = {0};
    double t0 = sl_seconds();
    CHECK_OK(sl_pipeline_slurm_run(graph, &o, &res, &err), &err);
    double first_run = sl_seconds() - t0;
    printf("first run: %.2f s, %d sbatch calls in %.3f s, mean queue wait %.2f s\n", first_run,
           res.sbatch_calls, res.submit_seconds, res.queue_seconds_mean);
    CHECK(res.job_count == DAY_JOBS);
    CHECK(res.submitted == DAY_JOBS && res.skipped == 0);
    CHECK(res.completed == 5);
    CHECK(res.failed == 1);
    CHECK(res.cancelled == 2); /* a/stitch, a/report: not pending forever */
    CHECK(res.lost == 0);
    CHECK(res.sbatch_calls == 6); /* the three merges as one array */
    int m0 = job_at(&res, "a/merge/0"), m1 = job_at(&res, "a/merge/1"),
        m2 = job_at(&res, "a/merge/2"), st = job_at(&res, "a/stitch"),
        rep = job_at(&res, "a/report"), bp = job_at(&res, "b/report");
    CHECK(m0 >= 0 && m1 >= 0 && m2 >= 0 && st >= 0 && rep >= 0 && bp >= 0);
    if (m0 < 0 || m1 < 0 || m2 < 0 || st < 0 || rep < 0 || bp < 0) {
        sl_pipeline_slurm_result_free(&res);
        return;
    }
    /* one array: 123_0, 123_1, 123_2 */
    const char *u0 = strchr(res.jobs[m0].slurm_id, '_'), *u2 = strchr(res.jobs[m2].slurm_id, '_');
    CHECK(u0 && strcmp(u0, "_0") == 0 && u2 && strcmp(u2, "_2") == 0);
    CHECK(u0 && u2 && u0 - res.jobs[m0].slurm_id == u2 - res.jobs[m2].slurm_id &&
          strncmp(res.jobs[m0].slurm_id, res.jobs[m2].slurm_id, (size_t)(u0 - res.jobs[m0].slurm_id)) == 0);
    CHECK(strchr(res.jobs[st].slurm_id, '_') == NULL);
    CHECK(res.jobs[m1].end == SL_SLURM_FAILED);
    CHECK_MSG(res.jobs[m1].exit_code == 3, "failed job's exit code %d (state %s)",
              res.jobs[m1].exit_code, res.jobs[m1].state);
    CHECK(strcmp(res.jobs[m1].state, "FAILED") == 0);
    CHECK(res.jobs[st].end == SL_SLURM_CANCELLED && res.jobs[st].exit_code == -1);
    CHECK(res.jobs[rep].end == SL_SLURM_CANCELLED);
    char said[4300];
    snprintf(said, sizeof said, "%s/ended/%s", wake, res.jobs[st].slurm_id);
    CHECK_MSG(sl_test_file_exists(said), "%s not written for the cancelled stitch", said);
    CHECK(res.jobs[m0].end == SL_SLURM_COMPLETED && res.jobs[m0].exit_code == 0);
    CHECK(res.jobs[bp].end == SL_SLURM_COMPLETED);
    /* the outputs: what ran, and nothing after the failure */
    char *a = out_file("a.txt"), *mm0 = out_file("m0.txt"), *mm1 = out_file("m1.txt"),
         *stitch = out_file("stitch.txt"), *b = out_file("b_report.txt");
    CHECK(a && strcmp(a, "a\n") == 0);
    CHECK(mm0 && strcmp(mm0, "a\n0\n") == 0);
    CHECK(mm1 == NULL && stitch == NULL);
    CHECK(b && strcmp(b, "b\nb\n") == 0);
    free(a), free(mm0), free(mm1), free(stitch), free(b);
    /* each job's log: a single job's through --output, an array task's
     * through the generated script */
    char *log_prep = sl_test_read_file(res.jobs[job_at(&res, "a/prep")].log, NULL);
    char *log_m0 = sl_test_read_file(res.jobs[m0].log, NULL);
    char *log_m1 = sl_test_read_file(res.jobs[m1].log, NULL);
    CHECK(log_prep && strcmp(log_prep, "prepared\n") == 0);
    CHECK(log_m0 && strcmp(log_m0, "merge 0\n") == 0);
    CHECK(log_m1 && strstr(log_m1, "view 1: frame corrupt"));
    free(log_prep), free(log_m0), free(log_m1);
    sl_pipeline_slurm_result_free(&res);

    /* The fix, and the rerun: up to date is what completed, except that
     * a/report claims to be while a/stitch, which it reads, is not. */
    unlink(flag);
    bool fresh[DAY_JOBS];
    for (int i = 0; i < DAY_JOBS; i++)
        fresh[i] = strcmp(day[i].id, "a/merge/1") != 0 && strcmp(day[i].id, "a/stitch") != 0;
    write_graph(graph, fresh);
    t0 = sl_seconds();
    CHECK_OK(sl_pipeline_slurm_run(graph, &o, &res, &err), &err);
    printf("rerun: %.2f s, %d submitted\n", sl_seconds() - t0, res.submitted);
    CHECK(res.submitted == 3 && res.skipped == DAY_JOBS - 3);
    CHECK(res.completed == 3 && res.failed == 0 && res.cancelled == 0);
    CHECK(res.sbatch_calls == 3); /* the array's one job alone */
    int i1 = job_at(&res, "a/merge/1"), i0 = job_at(&res, "a/merge/0");
    CHECK(i1 >= 0 && res.jobs[i1].submitted && strchr(res.jobs[i1].slurm_id, '_') == NULL);
    CHECK(i0 >= 0 && !res.jobs[i0].submitted && res.jobs[i0].end == SL_SLURM_SKIPPED &&
          res.jobs[i0].slurm_id[0] == '\0');
    int ir = job_at(&res, "a/report");
    CHECK(ir >= 0 && res.jobs[ir].submitted && res.jobs[ir].end == SL_SLURM_COMPLETED);
    stitch = out_file("stitch.txt");
    char *report = out_file("report.txt");
    CHECK(stitch && strcmp(stitch, "a\n0\na\n1\na\n2\n") == 0);
    CHECK(report && strcmp(report, "6\n") == 0);
    free(stitch), free(report);
    sl_pipeline_slurm_result_free(&res);

    /* Everything up to date: nothing submitted, no Slurm needed. */
    bool all[DAY_JOBS];
    for (int i = 0; i < DAY_JOBS; i++)
        all[i] = true;
    write_graph(graph, all);
    sl_pipeline_slurm_options none = o;
    none.sbatch = "/nonexistent/sbatch";
    CHECK_OK(sl_pipeline_slurm_run(graph, &none, &res, &err), &err);
    CHECK(res.submitted == 0 && res.skipped == DAY_JOBS && res.sbatch_calls == 0);
    sl_pipeline_slurm_result_free(&res);

    /* A submission refused (more memory than the node has): one line
     * naming the job and Slurm's reason; what was submitted before it is
     * cancelled, not left to run. */
    const char *big = keep_path("jobs_big.json");
    f = fopen(big, "w");
    CHECK(f != NULL);
    if (f) {
        fprintf(f,
                "{\"format\":\"setlight-jobs\",\"version\":1,\"out\":\"%s\",\"jobs\":["
                "{\"id\":\"first\",\"setup\":null,\"stage\":\"merge\",\"command\":[\"x\"],\"inputs\":[],\"outputs\":[],\"key\":null,\"argv\":[\"sleep\",\"30\"],\"deps\":[],\"array\":null,"
                "\"memory_mb\":16,\"cpus\":1,\"log\":\"%s/logs/first.log\",\"up_to_date\":false},"
                "{\"id\":\"huge\",\"setup\":null,\"stage\":\"merge\",\"command\":[\"x\"],\"inputs\":[],\"outputs\":[],\"key\":null,\"argv\":[\"true\"],\"deps\":[\"first\"],\"array\":null,"
                "\"memory_mb\":100000000,\"cpus\":1,\"log\":\"%s/logs/huge.log\",\"up_to_date\":false}]}\n",
                out_dir(), out_dir(), out_dir());
        fclose(f);
    }
    CHECK_RESULT(sl_pipeline_slurm_run(big, &o, &res, &err), SL_ERR_IO, &err);
    CHECK_MSG(strstr(err.message, "sbatch refused job 'huge': ") != NULL, "%s", err.message);
    CHECK(strchr(err.message, '\n') == NULL);
    CHECK(res.jobs && res.jobs[0].slurm_id[0] != '\0');
    if (res.jobs && res.jobs[0].slurm_id[0]) {
        char cmd[256], path[4200];
        snprintf(path, sizeof path, "%s/first_state.txt", sl_test_tmpdir());
        snprintf(cmd, sizeof cmd, "squeue -h -t all -j %.40s -o %%T > '%.150s'", res.jobs[0].slurm_id,
                 path);
        CHECK(system(cmd) == 0);
        char *state = sl_test_read_file(path, NULL);
        CHECK_MSG(state && strncmp(state, "CANCELLED", 9) == 0, "first job: %s",
                  state ? state : "(none)");
        free(state);
    }
    sl_pipeline_slurm_result_free(&res);

    /* A timeout: one line naming the jobs left on the cluster. */
    const char *slow = keep_path("jobs_slow.json");
    f = fopen(slow, "w");
    if (f) {
        fprintf(f,
                "{\"format\":\"setlight-jobs\",\"version\":1,\"out\":\"%s\",\"jobs\":["
                "{\"id\":\"slow\",\"setup\":null,\"stage\":\"merge\",\"command\":[\"x\"],\"inputs\":[],\"outputs\":[],\"key\":null,\"argv\":[\"sleep\",\"30\"],\"deps\":[],\"array\":null,"
                "\"memory_mb\":16,\"cpus\":1,\"log\":\"%s/logs/slow.log\",\"up_to_date\":false}]}\n",
                out_dir(), out_dir());
        fclose(f);
    }
    sl_pipeline_slurm_options quick = o;
    quick.timeout_seconds = 1;
    CHECK_RESULT(sl_pipeline_slurm_run(slow, &quick, &res, &err), SL_ERR_IO, &err);
    CHECK_MSG(strstr(err.message, "still queued or running after 1 s") != NULL, "%s", err.message);
    sl_pipeline_slurm_result_free(&res);

    /* The cluster down: one line naming the problem, nothing written. */
    stop_cluster();
    write_graph(graph, NULL);
    char logs[4200];
    snprintf(logs, sizeof logs, "%s/logs", out_dir());
    sl_remove_tree(logs);
    CHECK_RESULT(sl_pipeline_slurm_run(graph, &o, &res, &err), SL_ERR_IO, &err);
    CHECK_MSG(strstr(err.message, "Slurm controller does not answer") != NULL, "%s", err.message);
    CHECK(strchr(err.message, '\n') == NULL);
    CHECK(!sl_test_file_exists(logs));
    sl_pipeline_slurm_result_free(&res);
}

/* sbatch not installed: SL_ERR_UNSUPPORTED naming it, nothing written. */
static void test_sbatch_missing(void)
{
    const char *graph = keep_path("jobs_nosbatch.json");
    write_graph(graph, NULL);
    char logs[4200];
    snprintf(logs, sizeof logs, "%s/logs", out_dir());
    sl_remove_tree(logs);
    sl_pipeline_slurm_options o;
    sl_pipeline_slurm_options_init(&o);
    o.sbatch = "sbatch-not-installed";
    sl_pipeline_slurm_result res;
    sl_error err = {0};
    CHECK_RESULT(sl_pipeline_slurm_run(graph, &o, &res, &err), SL_ERR_UNSUPPORTED, &err);
    CHECK_MSG(strstr(err.message, "sbatch-not-installed: not found") != NULL, "%s", err.message);
    CHECK(strchr(err.message, '\n') == NULL);
    CHECK(!sl_test_file_exists(logs));
    sl_pipeline_slurm_result_free(&res);
}

/* A graph that does not hold together: SL_ERR_INPUT naming the file and
 * the job, before anything is submitted. */
static void expect_bad_graph(const char *name, const char *jobs, const char *message)
{
    const char *path = keep_path(name);
    FILE *f = fopen(path, "w");
    CHECK(f != NULL);
    if (!f)
        return;
    fprintf(f, "{\"format\":\"setlight-jobs\",\"version\":1,\"out\":\"/tmp\",\"jobs\":[%s]}", jobs);
    fclose(f);
    sl_pipeline_slurm_options o;
    sl_pipeline_slurm_options_init(&o);
    o.sbatch = "/nonexistent/sbatch"; /* never reached */
    sl_pipeline_slurm_result res;
    sl_error err = {0};
    CHECK_RESULT(sl_pipeline_slurm_run(path, &o, &res, &err), SL_ERR_INPUT, &err);
    CHECK_MSG(strstr(err.message, path) && strstr(err.message, message), "%s: %s", name,
              err.message);
    sl_pipeline_slurm_result_free(&res);
}

#define JOB(id, deps)                                                                        \
    "{\"id\":\"" id "\",\"setup\":null,\"stage\":\"merge\",\"command\":[\"x\"],\"inputs\":[],\"outputs\":[],\"key\":null,\"argv\":[\"true\"],\"deps\":[" deps "],\"array\":null,"         \
    "\"memory_mb\":0,\"cpus\":1,\"log\":\"/tmp/x.log\",\"up_to_date\":false}"

static void test_bad_graphs(void)
{
    expect_bad_graph("unknown_dep.json", JOB("a", "\"b\""),
                     "job 'a': dependency 'b' is not a job of the graph");
    expect_bad_graph("cycle.json", JOB("a", "\"b\"") "," JOB("b", "\"a\"") "," JOB("c", ""),
                     "dependencies form a cycle");
    expect_bad_graph("duplicate.json", JOB("a", "") "," JOB("a", ""), "two jobs have this id");
    expect_bad_graph("no_argv.json",
                     "{\"id\":\"a\",\"setup\":null,\"stage\":\"merge\",\"command\":[\"x\"],\"inputs\":[],\"outputs\":[],\"key\":null,\"argv\":[],\"deps\":[],\"array\":null,\"memory_mb\":0,"
                     "\"cpus\":1,\"log\":\"/tmp/x.log\",\"up_to_date\":false}",
                     "job 'a': \"argv\" is empty");
    expect_bad_graph("not_json.json", "{", "not a job graph");
    /* Refused by the graph parser the rest of the pipeline (and the fuzzer)
     * uses: an id that climbs out of OUT, an input path that is relative. */
    expect_bad_graph("climbing_id.json", JOB("../a", ""),
                     "\"id\" is not a relative path of at most");
    expect_bad_graph("relative_input.json",
                     "{\"id\":\"a\",\"setup\":null,\"stage\":\"merge\",\"command\":[\"x\"],"
                     "\"inputs\":[\"frame.tif\"],\"outputs\":[],\"key\":null,\"argv\":[\"true\"],"
                     "\"deps\":[],\"array\":null,\"memory_mb\":0,\"cpus\":1,\"log\":\"/tmp/x.log\","
                     "\"up_to_date\":false}",
                     "job 'a': \"inputs\" entry 1 is not an absolute path");

    const char *path = keep_path("other_format.json");
    FILE *f = fopen(path, "w");
    if (f) {
        fputs("{\"format\":\"setlight-rig\",\"version\":1,\"jobs\":[]}", f);
        fclose(f);
    }
    sl_pipeline_slurm_result res;
    sl_error err = {0};
    CHECK_RESULT(sl_pipeline_slurm_run(path, NULL, &res, &err), SL_ERR_INPUT, &err);
    CHECK(strstr(err.message, "format is not \"setlight-jobs\"") != NULL);
    sl_pipeline_slurm_result_free(&res);
}

/* A fake Slurm command, DIR/NAME, running body. */
static void fake_command(const char *dir, const char *name, const char *body)
{
    char path[4200];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    FILE *f = fopen(path, "w");
    CHECK(f != NULL);
    if (!f)
        return;
    fprintf(f, "#!/bin/sh\n%s\n", body);
    fclose(f);
    CHECK(chmod(path, 0755) == 0);
}

/* A grouped setup's script writes wake_dir/ended.SLURM_ID as its last act;
 * Slurm then shows the job COMPLETING until slurmd has seen its processes
 * gone, which can take seconds. A job that said it ended and is shown
 * completing has ended, with the exit code squeue gives; without its
 * file, COMPLETING is no end (a cancelled job completes too). Fake
 * commands: squeue answers COMPLETING forever. */
static void test_said_ended_and_completing(void)
{
    char bin[4200], wake[4200], ended[4300];
    snprintf(bin, sizeof bin, "%s", keep_path("fake_slurm"));
    snprintf(wake, sizeof wake, "%s", keep_path("fake_wake"));
    sl_remove_tree(bin);
    sl_remove_tree(wake);
    CHECK(mkdir(bin, 0755) == 0 && mkdir(wake, 0755) == 0);
    fake_command(bin, "scontrol", "exit 0");
    char body[8800];
    snprintf(body, sizeof body,
             "cat >/dev/null; n=$(cat '%s/n' 2>/dev/null || echo 40); n=$((n + 1)); "
             "echo $n >'%s/n'; echo $n",
             bin, bin);
    fake_command(bin, "sbatch", body);
    fake_command(bin, "squeue",
                 "t=2026-11-29T00:30:56\n"
                 "echo \"41|41|N/A|COMPLETING|0|$t|$t|$t|None|\"\n"
                 "echo \"42|42|N/A|COMPLETING|256|$t|$t|$t|None|\"");
    const char *graph = keep_path("jobs_completing.json");
    FILE *f = fopen(graph, "w");
    CHECK(f != NULL);
    if (!f)
        return;
    fprintf(f, "{\"format\":\"setlight-jobs\",\"version\":1,\"out\":\"%s\",\"jobs\":[", out_dir());
    for (int k = 0; k < 2; k++)
        fprintf(f,
                "%s{\"id\":\"%c\",\"setup\":null,\"stage\":\"merge\",\"command\":[\"x\"],"
                "\"inputs\":[],\"outputs\":[],\"key\":null,\"argv\":[\"true\"],\"deps\":[],"
                "\"array\":null,\"memory_mb\":16,\"cpus\":1,\"log\":\"%s/logs/%c.log\","
                "\"up_to_date\":false}",
                k ? "," : "", 'a' + k, out_dir(), 'a' + k);
    fputs("]}\n", f);
    fclose(f);
    for (int k = 41; k <= 42; k++) {
        snprintf(ended, sizeof ended, "%s/ended.%d", wake, k);
        int fd = open(ended, O_WRONLY | O_CREAT, 0644);
        CHECK(fd >= 0);
        if (fd >= 0)
            close(fd);
    }

    char sbatch[4300], squeue[4300], scontrol[4300];
    snprintf(sbatch, sizeof sbatch, "%s/sbatch", bin);
    snprintf(squeue, sizeof squeue, "%s/squeue", bin);
    snprintf(scontrol, sizeof scontrol, "%s/scontrol", bin);
    sl_pipeline_slurm_options o;
    sl_pipeline_slurm_options_init(&o);
    o.sbatch = sbatch;
    o.squeue = squeue;
    o.scontrol = scontrol;
    o.wake_dir = wake;
    o.timeout_seconds = 3;
    sl_pipeline_slurm_result res;
    sl_error err = {0};
    double t0 = sl_seconds();
    CHECK_RESULT(sl_pipeline_slurm_run(graph, &o, &res, &err), SL_OK, &err);
    CHECK_MSG(sl_seconds() - t0 < 2, "%.2f s", sl_seconds() - t0); /* the first squeue */
    CHECK(res.job_count == 2 && res.completed == 1 && res.failed == 1);
    if (res.job_count == 2) {
        CHECK(!strcmp(res.jobs[0].slurm_id, "41") && res.jobs[0].end == SL_SLURM_COMPLETED &&
              !strcmp(res.jobs[0].state, "COMPLETED") && res.jobs[0].exit_code == 0);
        CHECK(!strcmp(res.jobs[1].slurm_id, "42") && res.jobs[1].end == SL_SLURM_FAILED &&
              !strcmp(res.jobs[1].state, "FAILED") && res.jobs[1].exit_code == 1);
    }
    sl_pipeline_slurm_result_free(&res);

    /* Job 42 did not say it ended: it is still waited for. */
    snprintf(ended, sizeof ended, "%s/ended.42", wake);
    CHECK(unlink(ended) == 0);
    snprintf(ended, sizeof ended, "%s/n", bin);
    unlink(ended);
    o.timeout_seconds = 1;
    CHECK_RESULT(sl_pipeline_slurm_run(graph, &o, &res, &err), SL_ERR_IO, &err);
    CHECK_MSG(strstr(err.message, "Slurm jobs 42 still queued or running") != NULL, "%s",
              err.message);
    if (res.job_count == 2)
        CHECK(res.jobs[0].end == SL_SLURM_COMPLETED && res.jobs[1].end != SL_SLURM_COMPLETED);
    sl_pipeline_slurm_result_free(&res);
}

int main(void)
{
    sl_test_tmpdir();
    RUN(test_bad_graphs);
    RUN(test_sbatch_missing);
    RUN(test_said_ended_and_completing);
    if (start_cluster())
        RUN(test_day_on_slurm);
    stop_cluster();
    return sl_test_finish();
}
