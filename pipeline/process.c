/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight process: plan the day, write its graph, run it, sum it up. */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include "pipeline_private.h"
#include "report_private.h"
#include "slurm.h"

void sl_pipeline_options_init(sl_pipeline_options *o)
{
    memset(o, 0, sizeof *o);
    o->farm = SL_FARM_LOCAL;
}

void sl_pipeline_result_free(sl_pipeline_result *res)
{
    free(res->json);
    free(res->failures);
    res->json = res->failures = NULL;
}

static void add_failure(sl_pipeline_result *res, const char *setup, const char *reason)
{
    size_t old = res->failures ? strlen(res->failures) : 0;
    size_t add = strlen(setup) + strlen(reason) + 4;
    char *p = realloc(res->failures, old + add);
    if (!p)
        return;
    snprintf(p + old, add, "%s: %s\n", setup, reason);
    res->failures = p;
}


/* Removes the folder path in a grandchild of this process, so that no
 * wait for any child here (the local runner's wait4(-1)) meets it, while
 * this process goes on. Returns the read end of a pipe whose write end
 * only the grandchild holds: it reads end-of-file once the folder is gone
 * (remove_wait). -1 when removed here, at once. */
static int remove_behind(const char *path)
{
    int fds[2];
    if (pipe2(fds, O_CLOEXEC)) {
        sl_remove_tree(path);
        return -1;
    }
    fflush(NULL); /* nothing buffered is written twice */
    pid_t child = fork();
    if (child == 0) {
        close(fds[0]);
        if (fork() > 0)
            _exit(0);
        sl_remove_tree(path); /* the grandchild, or the child if that fork failed */
        _exit(0);
    }
    close(fds[1]);
    if (child < 0) {
        close(fds[0]);
        sl_remove_tree(path);
        return -1;
    }
    while (waitpid(child, NULL, 0) < 0 && errno == EINTR) {
    }
    return fds[0];
}

static void remove_wait(int fd)
{
    if (fd < 0)
        return;
    char c;
    ssize_t n;
    /* errno is read only after a failed read: a stale EINTR at end-of-file
     * would loop for ever */
    while ((n = read(fd, &c, 1)) > 0 || (n < 0 && errno == EINTR)) {
    }
    close(fd);
}

/* The graph through Slurm, all but the day's index: the index follows
 * every other job whatever its end (an afterok dependency would cancel it
 * with the first failure), so it runs here once Slurm is done. The jobs
 * Slurm runs are the same `setlight job JOBS.json ID` the local runner
 * starts, so they skip themselves when up to date and stamp what they ran.
 * choices: per setup, grouped into one Slurm job or not (pl_farm_choices);
 * a grouped setup whose Slurm job was killed gets its "slurm_state".
 * *removing: remove_behind's pipe for the day's farm folder, or -1. */
static sl_result run_slurm(const sl_pipeline_options *o, const json_t *graph,
                           json_t *choices, const char *jobs_path, json_t *status,
                           sl_pipeline_result *res, int *removing, sl_error *err)
{
    json_t *farm = json_deep_copy(graph), *day = json_deep_copy(graph);
    json_t *farm_jobs = json_object_get(farm, "jobs"), *index_jobs = json_array();
    for (size_t i = json_array_size(farm_jobs); i-- > 0;) {
        json_t *job = json_array_get(farm_jobs, i);
        if (!strcmp(json_string_value(json_object_get(job, "stage")), "index")) {
            json_array_append(index_jobs, job);
            json_array_remove(farm_jobs, i);
        }
    }
    json_object_set_new(day, "jobs", index_jobs);
    const char *name;
    json_t *choice;
    bool grouping = false;
    json_object_foreach(choices, name, choice) {
        sl_log(SL_LOG_INFO, "farm: %s %s", name,
               json_string_value(json_object_get(choice, "reason")));
        grouping |= !strcmp(json_string_value(json_object_get(choice, "group")), "setup");
    }
    double t0 = pl_epoch_seconds();
    sl_result r = SL_OK;
    /* The grouped setups' scripts and claims, this run's own folder. */
    const char *out = json_string_value(json_object_get(graph, "out"));
    char group_dir[PATH_MAX + 64];
    snprintf(group_dir, sizeof group_dir, "%s/logs/farm-%ld-%.0f", out, (long)getpid(), t0 * 1e3);
    if (grouping)
        r = pl_farm_group(farm, choices, out, group_dir, err);
    char farm_path[PATH_MAX + 32];
    snprintf(farm_path, sizeof farm_path, "%s.slurm.json", jobs_path);
    sl_pipeline_slurm_options so;
    sl_pipeline_slurm_options_init(&so);
    if (grouping)
        so.wake_dir = group_dir; /* the grouped setups' scripts say there when they end */
    sl_pipeline_slurm_result sr;
    memset(&sr, 0, sizeof sr);
    if (!r)
        r = pl_json_write(farm_path, farm, err);
    if (!r)
        r = sl_pipeline_slurm_run(farm_path, &so, &sr, err);
    /* Kept only while a job submitted may still be on the cluster. Its
     * claims are a file or two a job (50 tiny setups: about 1700), whose
     * removal took about a second on this shared machine's disk: done
     * behind the day's index and the summaries, not before them. */
    *removing = grouping && (!r || !sr.sbatch_calls) ? remove_behind(group_dir) : -1;
    for (int i = 0; !r && i < sr.job_count; i++) {
        const sl_pipeline_slurm_job *j = &sr.jobs[i];
        json_t *c = json_object_get(choices, j->id);
        if (c && !strcmp(json_string_value(json_object_get(c, "group")), "setup")) {
            if (pl_farm_group_statuses(graph, j->id, j->submitted, t0, status))
                json_object_set_new(c, "slurm_state", json_string(j->state[0] ? j->state : "UNKNOWN"));
            continue;
        }
        /* The local runner's words: a job Slurm ran may still have skipped
         * itself, which its stamp does not tell apart from a run. */
        const char *state = j->end == SL_SLURM_SKIPPED     ? "skipped"
                            : j->end == SL_SLURM_COMPLETED ? "ran"
                            : j->end == SL_SLURM_CANCELLED ? "not run"
                                                           : "failed";
        if (j->end == SL_SLURM_LOST && pl_job_stamp_ok(graph, j->id))
            state = "ran"; /* purged from squeue before it was seen ending */
        json_object_set_new(status, j->id, json_string(state));
    }
    const char *k;
    json_t *v;
    json_object_foreach(status, k, v) {
        const char *state = json_string_value(v);
        res->jobs_run += !strcmp(state, "ran") || !strcmp(state, "failed");
        res->jobs_skipped += !strcmp(state, "skipped");
        res->jobs_failed += !strcmp(state, "failed");
    }
    sl_pipeline_slurm_result_free(&sr);
    if (!r) {
        r = pl_run_local(o, day, status, res, err);
        res->jobs = (int)json_array_size(json_object_get(graph, "jobs"));
    }
    json_decref(farm);
    json_decref(day);
    return r;
}

typedef struct job_span {
    double start, end, rss_mb;
} job_span;

static int cmp_span_start(const void *a, const void *b)
{
    double x = ((const job_span *)a)->start, y = ((const job_span *)b)->start;
    return (x > y) - (x < y);
}

/* The run's cost from the stamps of the jobs it ran (status "ran" or
 * "failed"): CPU and wait sums, and the peak of memory: at each job's
 * start, the sum of the peak RSS (command + `setlight job`) of the jobs
 * running then. Each job's peak counts for its whole life, so the sum is an
 * upper bound of what was resident at once. Also the most jobs at once. */
static json_t *run_cost(const sl_pipeline_options *o, const json_t *graph, const json_t *status,
                        sl_pipeline_result *res)
{
    json_t *jobs = json_object_get(graph, "jobs");
    size_t n = json_array_size(jobs), i, count = 0;
    job_span *spans = calloc(n + 1, sizeof *spans);
    json_t *job;
    json_array_foreach(jobs, i, job) {
        const char *st = json_string_value(
            json_object_get(status, json_string_value(json_object_get(job, "id"))));
        if (!st || (strcmp(st, "ran") && strcmp(st, "failed")))
            continue;
        json_t *stamp = pl_stamp_load(graph, job);
        if (!stamp)
            continue;
        res->cpu_seconds += json_number_value(json_object_get(stamp, "cpu_seconds"));
        res->cpu_wait_seconds += json_number_value(json_object_get(stamp, "cpu_wait_seconds"));
        if (spans && json_object_get(stamp, "started")) {
            job_span *sp = &spans[count++];
            sp->start = json_number_value(json_object_get(stamp, "started"));
            sp->end = json_number_value(json_object_get(stamp, "ended"));
            sp->rss_mb = json_number_value(json_object_get(stamp, "max_rss_mb")) +
                         json_number_value(json_object_get(stamp, "job_max_rss_mb"));
        }
        json_decref(stamp);
    }
    double peak_jobs_mb = 0;
    int most = 0;
    if (spans) {
        qsort(spans, count, sizeof *spans, cmp_span_start);
        for (size_t a = 0; a < count; a++) {
            double sum = 0;
            int at_once = 0;
            for (size_t b = 0; b <= a; b++)
                if (spans[b].end > spans[a].start || b == a)
                    sum += spans[b].rss_mb, at_once++;
            if (sum > peak_jobs_mb)
                peak_jobs_mb = sum;
            if (at_once > most)
                most = at_once;
        }
    }
    free(spans);
    struct rusage self;
    getrusage(RUSAGE_SELF, &self);
    res->runner_cpu_seconds += pl_cpu_seconds(&self);
    res->runner_cpu_wait_seconds += pl_runqueue_wait_seconds(0);
    res->peak_memory_mb = peak_jobs_mb + (double)self.ru_maxrss / 1024.0;
    long budget = o->memory_mb;
    if (budget <= 0)
        budget = (long)(sysconf(_SC_PHYS_PAGES) / 2 * (sysconf(_SC_PAGESIZE) / 1024) / 1024);
    int ran = res->jobs_run;
    json_t *c = json_pack("{s:f,s:i,s:i,s:f,s:f,s:f,s:f,s:f,s:f,s:I,s:i}", "wall_seconds",
                          res->seconds, "jobs_ran", ran, "slots", res->slots, "cpu_seconds", res->cpu_seconds,
                          "cpu_wait_seconds", res->cpu_wait_seconds, "job_process_cpu_seconds",
                          res->job_process_cpu_seconds, "runner_cpu_seconds",
                          res->runner_cpu_seconds, "runner_cpu_wait_seconds",
                          res->runner_cpu_wait_seconds, "peak_memory_mb", res->peak_memory_mb,
                          "memory_budget_mb", (json_int_t)budget, "most_jobs_at_once", most);
    /* What the slots gave beyond the commands' CPU, per job run: start-up,
     * scheduling, I/O; the second leaves out the time the machine's other
     * work took from the jobs and this runner (their run-queue waits). Only
     * for a local run, whose slots are known. */
    if (ran > 0 && res->seconds > 0) {
        json_object_set_new(c, "jobs_per_minute", json_real(60.0 * ran / res->seconds));
        if (res->slots > 0) {
            double idle = res->seconds * res->slots - res->cpu_seconds;
            json_object_set_new(c, "overhead_seconds_per_job", json_real(idle / ran));
            json_object_set_new(c, "overhead_share",
                                json_real(res->cpu_seconds > 0 ? idle / res->cpu_seconds : 0));
            double waits = res->cpu_wait_seconds + res->runner_cpu_wait_seconds;
            json_object_set_new(c, "overhead_seconds_per_job_less_wait",
                                json_real((idle - waits) / ran));
        }
    }
    return c;
}

sl_result sl_pipeline_process(const sl_pipeline_options *o, sl_pipeline_result *res,
                              sl_error *err)
{
    memset(res, 0, sizeof *res);
    res->input_failures_only = true;
    double t0 = sl_seconds();
    char jobs_path[PATH_MAX + 16] = "";
    if (o->emit_jobs) {
        /* The file's absolute name: the jobs' argv carry it. */
        char dir[PATH_MAX], rdir[PATH_MAX];
        snprintf(dir, sizeof dir, "%s", o->emit_jobs);
        char *slash = strrchr(dir, '/');
        const char *base = slash ? slash + 1 : o->emit_jobs;
        if (slash)
            *slash = 0;
        if (!realpath(slash ? (dir[0] ? dir : "/") : ".", rdir))
            return sl_error_set(err, SL_ERR_USAGE, "%s: its folder does not exist", o->emit_jobs);
        snprintf(jobs_path, sizeof jobs_path, "%s/%s", strcmp(rdir, "/") ? rdir : "", base);
    }
    json_t *graph = NULL, *setups = NULL;
    char out_abs[PATH_MAX];
    sl_result r = pl_plan(o, jobs_path, sizeof jobs_path, &graph, &setups, res, err);
    if (r)
        return r;
    snprintf(out_abs, sizeof out_abs, "%s", json_string_value(json_object_get(graph, "out")));
    if ((r = pl_graph_write(jobs_path, graph, err)))
        goto done;
    json_t *status = json_object();
    json_t *choices = o->farm == SL_FARM_SLURM && !o->emit_jobs
                          ? pl_farm_choices(graph, o->farm_group)
                          : NULL;
    int removing = -1;
    if (choices)
        r = run_slurm(o, graph, choices, jobs_path, status, res, &removing, err), res->slots = 0;
    else if (!o->emit_jobs)
        r = pl_run_local(o, graph, status, res, err);
    else
        res->jobs = (int)json_array_size(json_object_get(graph, "jobs"));
    res->seconds = sl_seconds() - t0;
    json_t *list = json_array();
    size_t i;
    json_t *s;
    json_array_foreach(setups, i, s) {
        const char *name = json_string_value(json_object_get(s, "name"));
        json_t *sum = pl_setup_summary(graph, s, status);
        json_t *choice = json_object_get(choices, name);
        if (choice)
            json_object_set(sum, "farm", choice);
        /* Killed with the Slurm job running it: say so, no stamp can. */
        const char *killed = json_string_value(json_object_get(choice, "slurm_state"));
        const char *why = json_string_value(json_object_get(sum, "reason"));
        if (killed && why) {
            char line[2600];
            snprintf(line, sizeof line, "%s (the setup's Slurm job ended %s before it ran)", why,
                     killed);
            json_object_set_new(sum, "reason", json_string(line));
        }
        /* Emitted only: nothing ran, nothing to judge but the planning. */
        if (o->emit_jobs && !strcmp(json_string_value(json_object_get(s, "status")), "ok")) {
            json_object_set_new(sum, "status", json_string("planned"));
            json_object_del(sum, "reason");
            json_object_del(sum, "exit");
        }
        const char *st = json_string_value(json_object_get(sum, "status"));
        res->setups++;
        if (st && !strcmp(st, "failed")) {
            res->setups_failed++;
            const char *why = json_string_value(json_object_get(sum, "reason"));
            add_failure(res, name, why ? why : "failed");
            if (json_integer_value(json_object_get(sum, "exit")) != 3)
                res->input_failures_only = false;
        }
        json_array_append_new(list, sum);
    }
    json_t *doc = json_pack("{s:s,s:s,s:f,s:{s:i,s:i,s:i,s:i},s:o}", "out", out_abs, "jobs_json",
                            jobs_path, "seconds", res->seconds, "jobs", "total", res->jobs, "ran",
                            res->jobs_run, "skipped", res->jobs_skipped, "failed",
                            res->jobs_failed, "setups", list);
    json_object_set_new(doc, "emitted_only", json_boolean(o->emit_jobs != NULL));
    if (!o->emit_jobs)
        json_object_set_new(doc, "run", run_cost(o, graph, status, res));
    res->json = json_dumps(doc, JSON_INDENT(2) | JSON_PRESERVE_ORDER);
    json_decref(doc);
    json_decref(status);
    json_decref(choices);
    remove_wait(removing); /* the farm folder is gone when this returns */
done:
    json_decref(graph);
    json_decref(setups);
    return r;
}
