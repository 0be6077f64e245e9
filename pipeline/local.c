/* SPDX-License-Identifier: BSD-3-Clause */
/* The local runner: the graph's jobs in dependency order, as many at once
 * as --jobs and the memory budget allow, each through `setlight job` (run in
 * a fork of this process); of the jobs ready, the one with the most work
 * after it first. */
#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "pipeline_private.h"

extern char **environ;

enum { J_PENDING, J_RUNNING, J_RAN, J_SKIPPED, J_FAILED, J_NOT_RUN };

static const char *const state_names[] = {"pending", "running", "ran", "skipped", "failed",
                                          "not run"};

typedef struct lj {
    json_t *job;
    int state;
    int *deps, dep_count;
    int memory_mb;
    pid_t pid;
    bool is_index;
    double rank; /* its CPU estimate plus that of the longest chain after it */
} lj;

static int find(lj *js, int n, const char *id)
{
    for (int i = 0; i < n; i++)
        if (!strcmp(json_string_value(json_object_get(js[i].job, "id")), id))
            return i;
    return -1;
}

/* PENDING -> ready (1), blocked for good (-1: a dependency failed), wait (0).
 * The index runs once everything else has finished, whatever its status:
 * it reports the failures too. */
static int readiness(const lj *js, int n, const lj *j)
{
    if (j->is_index) {
        for (int i = 0; i < n; i++)
            if (&js[i] != j && (js[i].state == J_PENDING || js[i].state == J_RUNNING))
                return 0;
        return 1;
    }
    int r = 1;
    for (int k = 0; k < j->dep_count; k++) {
        int s = js[j->deps[k]].state;
        if (s == J_FAILED || s == J_NOT_RUN)
            return -1;
        if (s != J_RAN && s != J_SKIPPED)
            r = 0;
    }
    return r;
}

/* Longest remaining work first (critical path): a job's rank is its
 * cpu_seconds (1 without an estimate) plus the largest rank of the jobs that
 * depend on it. Started in rank order, no setup's serial tail (stitch ->
 * calibrate -> rig -> renders -> report) is left to run alone at the end of
 * the day while the other slots have nothing to do. The graph lists each
 * job after its dependencies, so in reverse its dependants are ranked first.
 * The index runs last whatever its rank. */
static void rank_jobs(lj *js, int n)
{
    for (int i = n - 1; i >= 0; i--) {
        if (js[i].is_index)
            continue;
        json_t *c = json_object_get(js[i].job, "cpu_seconds");
        js[i].rank += json_is_number(c) ? json_number_value(c) : 1;
        for (int k = 0; k < js[i].dep_count; k++) {
            lj *d = &js[js[i].deps[k]];
            if (d->rank < js[i].rank)
                d->rank = js[i].rank;
        }
    }
}

/* Whether this process has a single thread: a fork copies only the
 * calling thread, so a lock another thread held would stay taken in the
 * child. */
static bool one_thread(void)
{
    return pl_self_status("Threads") == 1;
}

/* Starts job j, whose argv is argc words; key: its key, or NULL when it
 * could not be computed. A job that is `setlight job JOBS.json ID` of this
 * very setlight (pl_plan makes every one so) runs in a fork of this
 * process, which has the graph read and the key computed, instead of a
 * new setlight: its start (the binary, its libraries, OpenSSL's set-up)
 * was about half of the wrapper's cost (docs/process.md, "Cost of a run").
 * Not the index, which reads every job's stamp through JOBS.json (after
 * Slurm, this runner's graph holds the index alone); nor anything else,
 * nor while this process has other threads: those are started as their
 * argv says. 0, or the errno of the failure. */
static int start_job(const sl_pipeline_options *o, json_t *graph, lj *j, char **argv, size_t argc,
                     const char *key)
{
    const char *id = json_string_value(json_object_get(j->job, "id"));
    if (!j->is_index && argc == 4 && o->exe && !strcmp(argv[0], o->exe) &&
        !strcmp(argv[1], "job") && !strcmp(argv[3], id) && one_thread()) {
        fflush(NULL); /* nothing buffered is written twice */
        pid_t pid = fork();
        if (pid == 0) {
            /* Its peak memory (the stamp's job_max_rss_mb) from here on,
             * not the runner's before the fork. */
            int fd = open("/proc/self/clear_refs", O_WRONLY);
            if (fd >= 0) {
                if (write(fd, "5", 1) < 0) {
                    /* an older kernel: the peak includes the runner's */
                }
                close(fd);
            }
            _exit(pl_job_run_forked(argv[2], graph, j->job, key));
        }
        if (pid < 0)
            return errno;
        j->pid = pid;
        return 0;
    }
    return posix_spawn(&j->pid, argv[0], NULL, NULL, argv, environ);
}

sl_result pl_run_local(const sl_pipeline_options *o, json_t *graph, json_t *status,
                       sl_pipeline_result *res, sl_error *err)
{
    json_t *jobs = json_object_get(graph, "jobs");
    int n = (int)json_array_size(jobs);
    lj *js = calloc((size_t)n + 1, sizeof *js);
    pl_ranked *order = calloc((size_t)n + 1, sizeof *order);
    if (!js || !order) {
        free(js);
        free(order);
        return sl_error_set(err, SL_ERR_NOMEM, "out of memory");
    }
    for (int i = 0; i < n; i++) {
        js[i].job = json_array_get(jobs, (size_t)i);
        js[i].memory_mb = (int)json_integer_value(json_object_get(js[i].job, "memory_mb"));
        js[i].is_index = !strcmp(json_string_value(json_object_get(js[i].job, "stage")), "index");
        json_t *deps = json_object_get(js[i].job, "deps");
        js[i].deps = calloc(json_array_size(deps) + 1, sizeof(int));
        size_t k;
        json_t *d;
        json_array_foreach(deps, k, d) {
            int at = find(js, n, json_string_value(d));
            if (at >= 0 && js[i].deps)
                js[i].deps[js[i].dep_count++] = at;
        }
    }
    rank_jobs(js, n);
    for (int i = 0; i < n; i++)
        order[i] = (pl_ranked){js[i].rank, (size_t)i};
    qsort(order, (size_t)n, sizeof *order, pl_cmp_ranked); /* the graph's order on ties */
    int parallel = o->jobs > 0 ? o->jobs : (int)sysconf(_SC_NPROCESSORS_ONLN);
    if (parallel < 1)
        parallel = 1;
    long cores = sysconf(_SC_NPROCESSORS_ONLN);
    res->slots = cores > 0 && cores < parallel ? (int)cores : parallel;
    long budget = o->memory_mb;
    if (budget <= 0)
        budget = (long)(sysconf(_SC_PHYS_PAGES) / 2 * (sysconf(_SC_PAGESIZE) / 1024) / 1024);
    sl_progress bar;
    if (o->progress)
        sl_progress_begin(&bar, "process", n);
    int running = 0, done = 0;
    long used_mb = 0;
    sl_result r = SL_OK;
    const char *jobs_path = json_string_value(json_object_get(graph, "out"));
    while (done < n && !r) {
        /* Start what is ready, the most work after it first. */
        for (int i = 0; i < n && running < parallel; i++) {
            lj *j = &js[order[i].at];
            if (j->state != J_PENDING)
                continue;
            int ready = readiness(js, n, j);
            if (ready < 0) {
                j->state = J_NOT_RUN;
                done++;
                if (o->progress)
                    sl_progress_add(&bar, 1);
                i = -1; /* what depended on it is blocked too */
                continue;
            }
            if (!ready)
                continue;
            /* An up-to-date job costs its inputs' hashing, no process. */
            char key[65];
            if (j->is_index && (r = pl_index_prepare(graph, err)))
                break;
            bool keyed = pl_job_key(j->job, key);
            if (keyed && pl_stamp_current(graph, j->job, key)) {
                j->state = J_SKIPPED;
                done++;
                if (o->progress)
                    sl_progress_add(&bar, 1);
                i = -1;
                continue;
            }
            /* Within the memory budget; a job larger than it runs alone. */
            if (running > 0 && used_mb + j->memory_mb > budget)
                continue;
            json_t *argv_j = json_object_get(j->job, "argv");
            size_t argc = json_array_size(argv_j);
            char **argv = calloc(argc + 1, sizeof *argv);
            if (!argv) {
                r = sl_error_set(err, SL_ERR_NOMEM, "out of memory");
                break;
            }
            for (size_t a = 0; a < argc; a++)
                argv[a] = (char *)json_string_value(json_array_get(argv_j, a));
            int e = start_job(o, graph, j, argv, argc, keyed ? key : NULL);
            free(argv);
            if (e) {
                /* This job fails (its setup with it); the others go on. */
                sl_log(SL_LOG_WARN, "%s: cannot run %s: %s",
                       json_string_value(json_object_get(j->job, "id")),
                       json_string_value(json_array_get(argv_j, 0)), strerror(e));
                j->state = J_FAILED;
                done++;
                if (o->progress)
                    sl_progress_add(&bar, 1);
                i = -1;
                continue;
            }
            j->state = J_RUNNING;
            running++;
            used_mb += j->memory_mb;
        }
        if (r || done >= n)
            break;
        if (!running) {
            r = sl_error_set(err, SL_ERR_INTERNAL, "%s: the job graph has a cycle", jobs_path);
            break;
        }
        int st;
        struct rusage ru;
        pid_t pid = wait4(-1, &st, 0, &ru);
        if (pid < 0) {
            if (errno == EINTR)
                continue;
            r = sl_error_set(err, SL_ERR_IO, "waiting for the jobs: %s", strerror(errno));
            break;
        }
        for (int i = 0; i < n; i++)
            if (js[i].state == J_RUNNING && js[i].pid == pid) {
                running--;
                used_mb -= js[i].memory_mb;
                res->job_process_cpu_seconds += pl_cpu_seconds(&ru);
                done++;
                if (o->progress)
                    sl_progress_add(&bar, 1);
                /* `setlight job` exits 0 having run or skipped, else with the
                 * command's code; the stamp says which. */
                bool ok = WIFEXITED(st) && WEXITSTATUS(st) == 0;
                json_t *s = pl_stamp_load(graph, js[i].job);
                const char *ss = json_string_value(json_object_get(s, "status"));
                js[i].state = ok && ss && !strcmp(ss, "ok") ? J_RAN : J_FAILED;
                json_decref(s);
            }
    }
    /* Interrupted or broken: let the running jobs finish their atomic writes. */
    while (running > 0) {
        int st;
        if (waitpid(-1, &st, 0) < 0 && errno != EINTR)
            break;
        running--;
    }
    if (o->progress)
        sl_progress_end(&bar);
    for (int i = 0; i < n; i++) {
        json_object_set_new(status, json_string_value(json_object_get(js[i].job, "id")),
                            json_string(state_names[js[i].state]));
        res->jobs_run += js[i].state == J_RAN || js[i].state == J_FAILED;
        res->jobs_skipped += js[i].state == J_SKIPPED;
        res->jobs_failed += js[i].state == J_FAILED;
        free(js[i].deps);
    }
    res->jobs = n;
    free(js);
    free(order);
    return r;
}
