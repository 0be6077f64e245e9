/* SPDX-License-Identifier: BSD-3-Clause */
/* A job graph on Slurm: sbatch per job or per array group, afterok chains,
 * squeue polling. See slurm.h and docs/slurm.md. */
#include "slurm.h"

#include "pipeline_private.h"

#include <errno.h>
#include <fcntl.h>
#include <jansson.h>
#include <limits.h>
#include <stdarg.h>
#include <poll.h>
#include <pthread.h>
#include <signal.h>
#include <spawn.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

extern char **environ;

void sl_pipeline_slurm_options_init(sl_pipeline_slurm_options *o)
{
    memset(o, 0, sizeof(*o));
    o->sbatch = "sbatch";
    o->squeue = "squeue";
    o->scontrol = "scontrol";
    o->poll_seconds = 0.25;
    o->poll_max_seconds = 2;
}

const char *sl_pipeline_slurm_end_name(sl_pipeline_slurm_end end)
{
    switch (end) {
    case SL_SLURM_SKIPPED: return "skipped";
    case SL_SLURM_COMPLETED: return "completed";
    case SL_SLURM_FAILED: return "failed";
    case SL_SLURM_CANCELLED: return "cancelled";
    case SL_SLURM_LOST: return "lost";
    }
    return "?";
}

/* ------------------------------------------------------------------ */
/* Running a command                                                   */
/* ------------------------------------------------------------------ */

/* The shell word for s: single-quoted, ' as '\''. */
static bool text_add_quoted(sl_text *t, const char *s)
{
    if (!sl_text_add_str(t, "'"))
        return false;
    for (const char *p = s; *p; p++) {
        if (*p == '\'') {
            if (!sl_text_add_str(t, "'\\''"))
                return false;
        } else if (!sl_text_add(t, p, 1)) {
            return false;
        }
    }
    return sl_text_add_str(t, "'");
}

/* The first line of s (at most 300 characters), for a one-line message. */
static const char *first_line(const char *s, char *buf, size_t size)
{
    if (!s)
        s = "";
    while (*s == '\n' || *s == ' ')
        s++;
    size_t n = strcspn(s, "\n");
    if (n > 300)
        n = 300;
    if (n >= size)
        n = size - 1;
    memcpy(buf, s, n);
    buf[n] = '\0';
    return buf;
}

static bool old_mask_has_pipe(const sigset_t *mask)
{
    return sigismember(mask, SIGPIPE) == 1;
}

/* Runs argv (looked up on PATH) with `input` on its stdin; its stdout and
 * stderr in *out and *errout (NUL-terminated, malloc'd), its wait status in
 * *status. SL_ERR_UNSUPPORTED when the program is not there. */
static sl_result run_command(char *const argv[], const char *input, char **out, char **errout,
                             int *status, sl_error *err)
{
    int in_pipe[2] = {-1, -1}, out_pipe[2] = {-1, -1}, err_pipe[2] = {-1, -1};
    sl_text o = {0}, e = {0};
    *out = *errout = NULL;
    if (pipe2(in_pipe, O_CLOEXEC) || pipe2(out_pipe, O_CLOEXEC) || pipe2(err_pipe, O_CLOEXEC)) {
        sl_error_set(err, SL_ERR_IO, "%s: cannot make a pipe: %s", argv[0], strerror(errno));
        goto fail;
    }
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, in_pipe[0], 0);
    posix_spawn_file_actions_adddup2(&fa, out_pipe[1], 1);
    posix_spawn_file_actions_adddup2(&fa, err_pipe[1], 2);
    pid_t pid;
    int rc = posix_spawnp(&pid, argv[0], &fa, NULL, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) {
        sl_error_set(err, rc == ENOENT ? SL_ERR_UNSUPPORTED : SL_ERR_IO, "%s: %s", argv[0],
                     rc == ENOENT ? "not found on PATH (Slurm's client commands are not installed)"
                                  : strerror(rc));
        goto fail;
    }
    close(in_pipe[0]);
    close(out_pipe[1]);
    close(err_pipe[1]);
    in_pipe[0] = out_pipe[1] = err_pipe[1] = -1;

    size_t in_len = input ? strlen(input) : 0, in_done = 0;
    /* never block on a full pipe while the child blocks on its output */
    fcntl(in_pipe[1], F_SETFL, fcntl(in_pipe[1], F_GETFL) | O_NONBLOCK);
    if (in_len == 0) {
        close(in_pipe[1]);
        in_pipe[1] = -1;
    }
    /* A child that exits without reading all its stdin must not kill us
     * with SIGPIPE: blocked here, a pending one taken back below. */
    sigset_t pipe_set, old_mask;
    sigemptyset(&pipe_set);
    sigaddset(&pipe_set, SIGPIPE);
    pthread_sigmask(SIG_BLOCK, &pipe_set, &old_mask);
    bool nomem = false;
    while (out_pipe[0] >= 0 || err_pipe[0] >= 0 || in_pipe[1] >= 0) {
        struct pollfd fds[3] = {{in_pipe[1], POLLOUT, 0}, {out_pipe[0], POLLIN, 0},
                                {err_pipe[0], POLLIN, 0}};
        if (poll(fds, 3, -1) < 0) {
            if (errno == EINTR)
                continue;
            kill(pid, SIGKILL); /* nothing can be read: do not wait on it */
            for (int k = 0; k < 2; k++) {
                int *fd = k ? &err_pipe[0] : &out_pipe[0];
                close(*fd);
                *fd = -1;
            }
            if (in_pipe[1] >= 0)
                close(in_pipe[1]);
            in_pipe[1] = -1;
            nomem = true;
            break;
        }
        if (in_pipe[1] >= 0 && (fds[0].revents & (POLLOUT | POLLERR | POLLHUP))) {
            ssize_t n = write(in_pipe[1], input + in_done, in_len - in_done);
            if (n > 0)
                in_done += (size_t)n;
            if ((n < 0 && errno != EINTR && errno != EAGAIN) || in_done == in_len) {
                close(in_pipe[1]);
                in_pipe[1] = -1;
            }
        }
        for (int k = 1; k < 3; k++) {
            int *fd = k == 1 ? &out_pipe[0] : &err_pipe[0];
            if (*fd < 0 || !(fds[k].revents & (POLLIN | POLLHUP | POLLERR)))
                continue;
            char buf[4096];
            ssize_t n = read(*fd, buf, sizeof buf);
            if (n > 0) {
                if (!sl_text_add(k == 1 ? &o : &e, buf, (size_t)n)) {
                    nomem = true;
                    kill(pid, SIGKILL);
                    close(*fd);
                    *fd = -1;
                }
            } else if (n == 0 || errno != EINTR) {
                close(*fd);
                *fd = -1;
            }
        }
    }
    bool reaped = true;
    while (waitpid(pid, status, 0) < 0) {
        if (errno != EINTR) {
            reaped = false;
            break;
        }
    }
    if (!(old_mask_has_pipe(&old_mask))) {
        struct timespec zero = {0, 0};
        while (sigtimedwait(&pipe_set, NULL, &zero) == SIGPIPE) {
        }
    }
    pthread_sigmask(SIG_SETMASK, &old_mask, NULL);
    if (!reaped) {
        sl_error_set(err, SL_ERR_IO, "%s: waitpid: %s", argv[0], strerror(errno));
        goto fail;
    }
    if (nomem) {
        sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory (or poll failed) reading its output",
                     argv[0]);
        goto fail;
    }
    *out = o.s ? o.s : strdup("");
    *errout = e.s ? e.s : strdup("");
    if (!*out || !*errout) {
        free(*out);
        free(*errout);
        *out = *errout = NULL;
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", argv[0]);
    }
    return SL_OK;
fail:
    for (int k = 0; k < 2; k++) {
        if (in_pipe[k] >= 0)
            close(in_pipe[k]);
        if (out_pipe[k] >= 0)
            close(out_pipe[k]);
        if (err_pipe[k] >= 0)
            close(err_pipe[k]);
    }
    free(o.s);
    free(e.s);
    return err->code;
}

/* ------------------------------------------------------------------ */
/* The graph                                                           */
/* ------------------------------------------------------------------ */

typedef struct job {
    const char *id, *array, *log;
    json_t *argv;
    int *deps; /* indices into the job list */
    int dep_count;
    long memory_mb, cpus;
    bool up_to_date;
    bool submit;
    int batch; /* the sbatch call that submits it */
    int task; /* its index in an array, or -1 */
    int missing; /* polls it was not in squeue's answer */
    bool done;
    bool held_warned;
} job;

typedef struct batch {
    int first; /* a member job (the one whose deps the batch waits for) */
    int *members;
    int count;
    bool array;
    long slurm_id;
    bool running; /* squeue said RUNNING or COMPLETING */
    bool said_ended; /* its script wrote wake_dir/ended.SLURM_ID, its last act */
} batch;

typedef struct graph {
    const char *path;
    json_t *root;
    const char *out;
    job *jobs;
    int count;
    int *order; /* topological */
    batch *batches;
    int batch_count;
} graph;

static void graph_free(graph *g)
{
    for (int i = 0; i < g->count; i++)
        free(g->jobs[i].deps);
    for (int b = 0; b < g->batch_count; b++)
        free(g->batches[b].members);
    free(g->jobs);
    free(g->order);
    free(g->batches);
    json_decref(g->root);
}

/* The graph through sl_pipeline_graph_parse, the one parser every reader
 * of a graph uses (and the fuzzer feeds): fields, caps, ids, dependencies
 * and their order are checked there; here its jobs become the submission's
 * records, in the parsed order. */
static sl_result graph_load(const char *path, graph *g, sl_error *err)
{
    memset(g, 0, sizeof(*g));
    g->path = path;
    sl_pipeline_graph *pg = NULL;
    sl_result r = pl_graph_load(path, &pg, err);
    if (r != SL_OK)
        return r;
    g->root = json_incref(pg->root);
    g->out = pg->out;
    g->count = pg->count;
    g->jobs = calloc((size_t)g->count + 1, sizeof(job));
    g->order = calloc((size_t)g->count + 1, sizeof(int));
    if (!g->jobs || !g->order) {
        sl_pipeline_graph_free(pg);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory for %d jobs", path, g->count);
    }
    memcpy(g->order, pg->order, (size_t)g->count * sizeof(int));
    for (int i = 0; i < g->count && !r; i++) {
        json_t *o = json_array_get(pg->jobs, (size_t)i), *deps = json_object_get(o, "deps");
        job *j = &g->jobs[i];
        j->batch = j->task = -1;
        j->id = json_string_value(json_object_get(o, "id"));
        j->argv = json_object_get(o, "argv");
        j->log = json_string_value(json_object_get(o, "log"));
        j->array = json_string_value(json_object_get(o, "array"));
        j->memory_mb = (long)json_integer_value(json_object_get(o, "memory_mb"));
        j->cpus = (long)json_integer_value(json_object_get(o, "cpus"));
        j->up_to_date = json_is_true(json_object_get(o, "up_to_date"));
        j->deps = calloc(json_array_size(deps) + 1, sizeof(int));
        if (!j->deps) {
            r = sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
            break;
        }
        for (size_t k = 0; k < json_array_size(deps); k++)
            j->deps[j->dep_count++] = (int)json_integer_value(
                json_object_get(pg->ids, json_string_value(json_array_get(deps, k))));
    }
    sl_pipeline_graph_free(pg); /* g->root holds the strings */
    return r;
}

static int cmp_int(const void *a, const void *b)
{
    int x = *(const int *)a, y = *(const int *)b;
    return (x > y) - (x < y);
}

/* The submitted dependencies of job i, sorted, in deps (room for dep_count). */
static int submitted_deps(const graph *g, int i, int *deps)
{
    int n = 0;
    for (int d = 0; d < g->jobs[i].dep_count; d++)
        if (g->jobs[g->jobs[i].deps[d]].submit)
            deps[n++] = g->jobs[i].deps[d];
    qsort(deps, (size_t)n, sizeof(int), cmp_int);
    /* one entry per job, whatever the file repeats */
    int m = 0;
    for (int k = 0; k < n; k++)
        if (m == 0 || deps[m - 1] != deps[k])
            deps[m++] = deps[k];
    return m;
}

static bool same_submitted_deps(const graph *g, int a, int b, int *buf_a, int *buf_b)
{
    int na = submitted_deps(g, a, buf_a), nb = submitted_deps(g, b, buf_b);
    return na == nb && memcmp(buf_a, buf_b, (size_t)na * sizeof(int)) == 0;
}

/* Chooses what to submit and how: in topological order, a job is submitted
 * when it is not up to date or a job it depends on is; the submitted jobs of
 * one "array" group that wait for the same jobs go as one array. */
static sl_result plan_batches(graph *g, sl_error *err)
{
    for (int k = 0; k < g->count; k++) {
        job *j = &g->jobs[g->order[k]];
        j->submit = !j->up_to_date;
        for (int d = 0; d < j->dep_count && !j->submit; d++)
            j->submit = g->jobs[j->deps[d]].submit;
    }
    g->batches = calloc((size_t)g->count + 1, sizeof(batch));
    int *buf_a = calloc((size_t)g->count + 1, sizeof(int));
    int *buf_b = calloc((size_t)g->count + 1, sizeof(int));
    if (!g->batches || !buf_a || !buf_b) {
        free(buf_a);
        free(buf_b);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", g->path);
    }
    for (int k = 0; k < g->count; k++) {
        int i = g->order[k];
        job *j = &g->jobs[i];
        if (!j->submit || j->batch >= 0)
            continue;
        batch *b = &g->batches[g->batch_count];
        b->first = i;
        b->members = calloc((size_t)g->count + 1, sizeof(int));
        if (!b->members) {
            free(buf_a);
            free(buf_b);
            return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", g->path);
        }
        b->members[b->count++] = i;
        j->batch = g->batch_count;
        if (j->array) {
            for (int m = k + 1; m < g->count; m++) {
                int o = g->order[m];
                job *oj = &g->jobs[o];
                if (oj->submit && oj->batch < 0 && oj->array && strcmp(oj->array, j->array) == 0 &&
                    same_submitted_deps(g, i, o, buf_a, buf_b)) {
                    oj->batch = g->batch_count;
                    b->members[b->count++] = o;
                }
            }
        }
        b->array = b->count > 1;
        for (int m = 0; m < b->count; m++)
            g->jobs[b->members[m]].task = b->array ? m : -1;
        g->batch_count++;
    }
    free(buf_a);
    free(buf_b);
    return SL_OK;
}

/* ------------------------------------------------------------------ */
/* Submission                                                          */
/* ------------------------------------------------------------------ */

static bool add_command_line(sl_text *t, const job *j)
{
    bool ok = sl_text_add_str(t, "exec");
    for (size_t k = 0; k < json_array_size(j->argv) && ok; k++)
        ok = sl_text_add_str(t, " ") && text_add_quoted(t, json_string_value(json_array_get(j->argv, k)));
    return ok;
}

/* The batch script: the job's command line; for an array, a case on
 * SLURM_ARRAY_TASK_ID with each task's output sent to its own log. */
static bool batch_script(const graph *g, const batch *b, sl_text *t)
{
    bool ok = sl_text_printf(t, "#!/bin/sh\n# setlight: %s of %s\n",
                          b->array ? g->jobs[b->first].array : g->jobs[b->first].id, g->path);
    if (!b->array)
        return ok && add_command_line(t, &g->jobs[b->first]) && sl_text_add_str(t, "\n");
    ok = ok && sl_text_add_str(t, "case \"$SLURM_ARRAY_TASK_ID\" in\n");
    for (int m = 0; m < b->count && ok; m++) {
        const job *j = &g->jobs[b->members[m]];
        ok = sl_text_printf(t, "%d) ", m) && add_command_line(t, j) && sl_text_add_str(t, " >") &&
             text_add_quoted(t, j->log) && sl_text_add_str(t, " 2>&1 ;;\n");
    }
    return ok && sl_text_add_str(t, "esac\necho \"no task $SLURM_ARRAY_TASK_ID in this array\" >&2\n"
                                 "exit 1\n");
}

/* mkdir -p of the folder holding `path`. */
static sl_result make_parent(const char *path, sl_error *err)
{
    char dir[4096];
    if (snprintf(dir, sizeof dir, "%s", path) >= (int)sizeof dir)
        return sl_error_set(err, SL_ERR_INPUT, "%s: path too long", path);
    char *slash = strrchr(dir, '/');
    if (!slash || slash == dir)
        return SL_OK;
    *slash = '\0';
    for (char *p = dir + 1;; p++) {
        if (*p == '/' || *p == '\0') {
            char c = *p;
            *p = '\0';
            if (mkdir(dir, 0777) != 0 && errno != EEXIST)
                return sl_error_set(err, SL_ERR_IO, "%s: cannot create the folder: %s", dir,
                                    strerror(errno));
            *p = c;
            if (c == '\0')
                break;
        }
    }
    struct stat st;
    if (stat(dir, &st) != 0 || !S_ISDIR(st.st_mode))
        return sl_error_set(err, SL_ERR_IO, "%s: not a folder", dir);
    return SL_OK;
}

/* "123" or "123_4": what afterok and the report name a job by. */
static void slurm_name(const graph *g, const job *j, char *buf, size_t size)
{
    long id = g->batches[j->batch].slurm_id;
    if (j->task >= 0)
        snprintf(buf, size, "%ld_%d", id, j->task);
    else
        snprintf(buf, size, "%ld", id);
}

static sl_result submit_batch(graph *g, int bi, const sl_pipeline_slurm_options *o, sl_error *err)
{
    batch *b = &g->batches[bi];
    const job *first = &g->jobs[b->first];
    long memory_mb = 0, cpus = 1;
    for (int m = 0; m < b->count; m++) {
        const job *j = &g->jobs[b->members[m]];
        if (j->memory_mb > memory_mb)
            memory_mb = j->memory_mb;
        if (j->cpus > cpus)
            cpus = j->cpus;
    }
    sl_text dep = {0}, script = {0};
    char *args[16];
    char name[600], output[4200], chdir_arg[4200], mem[48], ncpu[48], part[300], array[48];
    int n = 0;
    args[n++] = (char *)o->sbatch;
    args[n++] = "--parsable";
    snprintf(name, sizeof name, "--job-name=%s", b->array ? first->array : first->id);
    args[n++] = name;
    snprintf(output, sizeof output, "--output=%s", b->array ? "/dev/null" : first->log);
    args[n++] = output;
    snprintf(chdir_arg, sizeof chdir_arg, "--chdir=%s", g->out);
    args[n++] = chdir_arg;
    args[n++] = "--kill-on-invalid-dep=yes";
    snprintf(ncpu, sizeof ncpu, "--cpus-per-task=%ld", cpus);
    args[n++] = ncpu;
    if (memory_mb > 0) {
        snprintf(mem, sizeof mem, "--mem=%ldM", memory_mb);
        args[n++] = mem;
    }
    if (o->partition) {
        snprintf(part, sizeof part, "--partition=%s", o->partition);
        args[n++] = part;
    }
    if (b->array) {
        snprintf(array, sizeof array, "--array=0-%d", b->count - 1);
        args[n++] = array;
    }
    int *deps = calloc((size_t)first->dep_count + 1, sizeof(int));
    bool ok = deps != NULL;
    int nd = ok ? submitted_deps(g, b->first, deps) : 0;
    for (int d = 0; d < nd && ok; d++) {
        char s[48];
        slurm_name(g, &g->jobs[deps[d]], s, sizeof s);
        ok = sl_text_add_str(&dep, d ? ":" : "--dependency=afterok:") && sl_text_add_str(&dep, s);
    }
    free(deps);
    if (nd > 0 && ok)
        args[n++] = dep.s;
    args[n] = NULL;
    ok = ok && batch_script(g, b, &script);
    if (!ok) {
        free(dep.s);
        free(script.s);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", g->path);
    }

    char *out = NULL, *errout = NULL;
    int status = 0;
    sl_result r = run_command(args, script.s, &out, &errout, &status, err);
    free(dep.s);
    free(script.s);
    if (r != SL_OK)
        return r;
    char line[400];
    char *end = NULL;
    long id = strtol(out, &end, 10);
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0 || id <= 0 || end == out) {
        r = sl_error_set(err, SL_ERR_IO, "sbatch refused %s '%s': %s", b->array ? "array" : "job",
                         b->array ? first->array : first->id,
                         first_line(errout[0] ? errout : out, line, sizeof line));
    }
    b->slurm_id = id;
    free(out);
    free(errout);
    return r;
}

/* scancel of what was submitted, after a refused submission. */
static void cancel_batches(const graph *g, int count)
{
    for (int b = 0; b < count; b++) {
        char id[32], *out = NULL, *errout = NULL;
        int status;
        sl_error e = {0};
        snprintf(id, sizeof id, "%ld", g->batches[b].slurm_id);
        char *args[] = {"scancel", id, NULL};
        if (run_command(args, NULL, &out, &errout, &status, &e) == SL_OK) {
            free(out);
            free(errout);
        }
    }
}

/* ------------------------------------------------------------------ */
/* Waiting                                                             */
/* ------------------------------------------------------------------ */

/* Seconds since the epoch of Slurm's "2026-11-27T23:57:34" (local time),
 * or -1 for "N/A", "Unknown" or "None". */
static double slurm_time(const char *s)
{
    struct tm tm;
    memset(&tm, 0, sizeof tm);
    const char *end = strptime(s, "%Y-%m-%dT%H:%M:%S", &tm);
    if (!end || *end)
        return -1;
    tm.tm_isdst = -1;
    return (double)mktime(&tm);
}

static bool state_is_final(const char *s, sl_pipeline_slurm_end *end)
{
    static const char *const failed[] = {"FAILED",     "TIMEOUT",   "NODE_FAIL",
                                         "OUT_OF_MEMORY", "BOOT_FAIL", "DEADLINE",
                                         "PREEMPTED",  "REVOKED",   NULL};
    if (strcmp(s, "COMPLETED") == 0) {
        *end = SL_SLURM_COMPLETED;
        return true;
    }
    if (strcmp(s, "CANCELLED") == 0) {
        *end = SL_SLURM_CANCELLED;
        return true;
    }
    for (int k = 0; failed[k]; k++)
        if (strcmp(s, failed[k]) == 0) {
            *end = SL_SLURM_FAILED;
            return true;
        }
    return false;
}

/* One squeue row: JobID|ArrayJobID|ArrayTaskID|State|exit_code|SubmitTime|StartTime|EndTime|Reason| */
/* squeue's rows for the jobs in ids ("1,2,3"). */
static sl_result squeue_rows(const sl_pipeline_slurm_options *o, char *ids, char **out,
                             char **errout, int *status, sl_error *err)
{
    char *args[] = {(char *)o->squeue, "--noheader", "--states=all", "--jobs", ids,
                    "--Format=JobID:|,ArrayJobID:|,ArrayTaskID:|,State:|,exit_code:|,"
                    "SubmitTime:|,StartTime:|,EndTime:|,Reason:|",
                    NULL};
    return run_command(args, NULL, out, errout, status, err);
}

/* Whether task is in squeue's ArrayTaskID list of tasks not yet started,
 * "0-5", "2,4-7" or "3-9%2" (at most 2 at a time). */
static bool in_task_range(const char *spec, long task)
{
    for (const char *p = spec; *p;) {
        char *end;
        long lo = strtol(p, &end, 10), hi = lo;
        if (end == p)
            return false;
        if (*end == '-')
            hi = strtol(end + 1, &end, 10);
        if (task >= lo && task <= hi)
            return true;
        if (*end == '%')
            return false;
        p = *end == ',' ? end + 1 : end;
        if (*end != ',')
            break;
    }
    return false;
}

/* Whether the Slurm job said it ended: a grouped setup's script writes
 * wake_dir/ended.SLURM_ID as its last act (pipeline/farm.c). */
static bool said_it_ended(const char *wake_dir, long slurm_id)
{
    if (!wake_dir)
        return false;
    char path[PATH_MAX + 64];
    snprintf(path, sizeof path, "%s/ended.%ld", wake_dir, slurm_id);
    return access(path, F_OK) == 0;
}

static void apply_row(graph *g, const char *wake_dir, char *row, bool *seen,
                      sl_pipeline_slurm_result *res)
{
    char *f[10];
    int n = 0;
    for (char *p = row; n < 10;) {
        f[n++] = p;
        char *bar = strchr(p, '|');
        if (!bar)
            break;
        *bar = '\0';
        p = bar + 1;
    }
    if (n < 9)
        return;
    for (int k = 0; k < 9; k++) /* squeue pads some fields */
        for (char *e = f[k] + strlen(f[k]); e > f[k] && e[-1] == ' ';)
            *--e = '\0';
    long job_id = strtol(f[0], NULL, 10), array_id = strtol(f[1], NULL, 10);
    char *end;
    long task = strtol(f[2], &end, 10);
    bool one_task = end != f[2] && *end == '\0';
    bool task_range = !one_task && strcmp(f[2], "N/A") != 0;
    for (int i = 0; i < g->count; i++) {
        job *j = &g->jobs[i];
        if (!j->submit || j->done)
            continue;
        long id = g->batches[j->batch].slurm_id;
        bool match = j->task < 0 ? (!one_task && !task_range && id == job_id)
                                 : (id == array_id && (task_range ? in_task_range(f[2], j->task)
                                                                  : one_task && task == j->task));
        if (!match)
            continue;
        seen[i] = true;
        sl_pipeline_slurm_job *rj = &res->jobs[i];
        sl_pipeline_slurm_end e;
        const char *state = f[3];
        long raw = strtol(f[4], NULL, 10);
        batch *b = &g->batches[j->batch];
        b->running = !strcmp(state, "RUNNING") || !strcmp(state, "COMPLETING");
        /* A script that said it ended, shown completing, has run its last
         * command and exited with the code squeue gives: Slurm's final
         * state follows from it. Waited for, it can come seconds later
         * (slurmd looks for the job's processes again a second later when
         * they were still exiting), and the day's index waits for it. */
        if (!strcmp(state, "COMPLETING") && said_it_ended(wake_dir, job_id)) {
            e = raw == 0 ? SL_SLURM_COMPLETED : SL_SLURM_FAILED;
            state = raw == 0 ? "COMPLETED" : "FAILED";
        } else if (!state_is_final(state, &e)) {
            /* A range row is an array's tasks that never started: final
             * only when they were cancelled together (a dependency failed).
             * A held job (an admin hold, or a launch that failed and was
             * requeued held) waits for `scontrol release`: said once. */
            if (!j->held_warned && (strcasestr(f[8], "held") || strstr(state, "HOLD"))) {
                j->held_warned = true;
                sl_log(SL_LOG_WARN, "Slurm job %s (%s) is held (%s): it runs once released "
                       "(scontrol release)", f[0], j->id, f[8]);
            }
            continue;
        }
        j->done = true;
        rj->end = e;
        snprintf(rj->state, sizeof rj->state, "%s", state);
        double submit = slurm_time(f[5]), start = slurm_time(f[6]), stop = slurm_time(f[7]);
        bool ran = !(e == SL_SLURM_CANCELLED && raw == 0) && start >= 0;
        rj->exit_code = ran ? (int)((raw >> 8) & 0xff) : -1;
        rj->signal = ran ? (int)(raw & 0x7f) : 0;
        rj->queue_seconds = ran && submit >= 0 ? start - submit : 0;
        rj->wall_seconds = ran && stop >= start ? stop - start : 0;
    }
}

/* The mtime of o->wake_dir (0 without one). */
static double wake_mtime(const sl_pipeline_slurm_options *o)
{
    struct stat st;
    if (!o->wake_dir || stat(o->wake_dir, &st))
        return 0;
    return (double)st.st_mtim.tv_sec + 1e-9 * (double)st.st_mtim.tv_nsec;
}

static bool batch_open(const graph *g, const batch *b)
{
    for (int m = 0; m < b->count; m++)
        if (!g->jobs[b->members[m]].done)
            return true;
    return false;
}

/* Looks for the ended file of each open batch squeue last showed running:
 * true when one has said it ended since. A look per running job, so at
 * most one per CPU of the cluster. */
static bool newly_ended(graph *g, const char *wake_dir)
{
    bool any = false;
    for (int k = 0; wake_dir && k < g->batch_count; k++) {
        batch *b = &g->batches[k];
        if (b->running && !b->said_ended && batch_open(g, b) && said_it_ended(wake_dir, b->slurm_id))
            b->said_ended = any = true;
    }
    return any;
}

/* Sleeps `pause` s, less when a job says it ended meanwhile: its file
 * (newly_ended), or any change of the wake folder (its mtime: a job
 * that started and ended between two squeue), looked at every 50 ms. */
static bool pause_or_wake(graph *g, const sl_pipeline_slurm_options *o, double pause,
                          double *seen)
{
    double step = o->wake_dir ? 0.05 : pause, left = pause;
    while (left > 0) {
        double d = step < left ? step : left;
        struct timespec ts = {(time_t)d, (long)((d - (double)(time_t)d) * 1e9)};
        nanosleep(&ts, NULL);
        left -= d;
        double m = wake_mtime(o);
        bool ended = newly_ended(g, o->wake_dir);
        if (m != *seen || ended) {
            *seen = m;
            return true;
        }
    }
    return false;
}

/* A job seen ending that did not say so itself in o->wake_dir (killed:
 * scancel, a time or memory limit) is said for it in the folder's ended/
 * (ended/SLURM_ID, a subfolder: its files do not wake this wait): a
 * grouped setup's job it had taken is then known not to end, on any node
 * (sl_pipeline_jobs_share). */
static void say_ended(const graph *g, const sl_pipeline_slurm_options *o, const bool *was_done,
                      const sl_pipeline_slurm_result *res)
{
    for (int i = 0; o->wake_dir && i < g->count; i++) {
        if (was_done[i] || !g->jobs[i].done || !res->jobs[i].slurm_id[0])
            continue;
        char path[PATH_MAX + 64];
        snprintf(path, sizeof path, "%s/ended.%s", o->wake_dir, res->jobs[i].slurm_id);
        if (!access(path, F_OK))
            continue; /* it said so itself */
        snprintf(path, sizeof path, "%s/ended", o->wake_dir);
        mkdir(path, 0755);
        snprintf(path, sizeof path, "%s/ended/%s", o->wake_dir, res->jobs[i].slurm_id);
        int fd = open(path, O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
        if (fd >= 0)
            close(fd);
    }
}

static sl_result wait_jobs(graph *g, const sl_pipeline_slurm_options *o,
                           sl_pipeline_slurm_result *res, double t_start, sl_error *err)
{
    bool *seen = calloc((size_t)g->count + 1, sizeof(bool));
    bool *was_done = calloc((size_t)g->count + 1, sizeof(bool));
    if (!seen || !was_done) {
        free(seen);
        free(was_done);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", g->path);
    }
    double failing_since = -1;
    /* Nothing here waits on a job's end (Slurm starts the dependants), so
     * the period grows from poll_seconds to poll_max_seconds: on a small
     * cluster the controller and squeue share the CPUs with the jobs. */
    if (o->wake_dir) { /* made now, so that say_ended's files do not wake this wait */
        char path[PATH_MAX + 16];
        snprintf(path, sizeof path, "%s/ended", o->wake_dir);
        mkdir(path, 0755);
    }
    double pause = o->poll_seconds, woken = wake_mtime(o);
    sl_result r = SL_OK;
    for (;;) {
        /* squeue -j of the batches with a job still running */
        sl_text ids = {0};
        bool ok = true;
        int left = 0;
        for (int b = 0; b < g->batch_count && ok; b++) {
            bool open = batch_open(g, &g->batches[b]);
            if (open)
                ok = sl_text_printf(&ids, "%s%ld", ids.len ? "," : "", g->batches[b].slurm_id);
            left += open;
        }
        if (!ok) {
            free(ids.s);
            r = sl_error_set(err, SL_ERR_NOMEM, "out of memory");
            break;
        }
        if (left == 0) {
            free(ids.s);
            break;
        }
        if (o->timeout_seconds > 0 && sl_seconds() - t_start > o->timeout_seconds) {
            r = sl_error_set(err, SL_ERR_IO,
                             "%s: Slurm jobs %s still queued or running after %.0f s (left on the "
                             "cluster)",
                             g->path, ids.s, o->timeout_seconds);
            free(ids.s);
            break;
        }
        char *out = NULL, *errout = NULL;
        int status = 0;
        r = squeue_rows(o, ids.s, &out, &errout, &status, err);
        if (r == SL_OK && WIFEXITED(status) && WEXITSTATUS(status) != 0 && errout &&
            strstr(errout, "Invalid job id")) {
            /* One id the controller no longer knows (purged) fails the
             * whole query: ask for each batch alone, so the others are
             * still seen and the gone one counts as missing. */
            free(out);
            free(errout);
            out = errout = NULL;
            status = 0;
            sl_text rows = {0};
            for (char *id = strtok(ids.s, ","); id && r == SL_OK; id = strtok(NULL, ",")) {
                char *one = NULL, *one_err = NULL;
                int one_status = 0;
                r = squeue_rows(o, id, &one, &one_err, &one_status, err);
                if (r == SL_OK && WIFEXITED(one_status) && WEXITSTATUS(one_status) == 0 && one &&
                    !sl_text_printf(&rows, "%s", one))
                    r = sl_error_set(err, SL_ERR_NOMEM, "out of memory");
                free(one);
                free(one_err);
            }
            out = rows.s;
        }
        free(ids.s);
        if (r != SL_OK) {
            free(out);
            free(errout);
            break;
        }
        if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
            /* the controller restarting: keep asking for a minute */
            double now = sl_seconds();
            if (failing_since < 0)
                failing_since = now;
            if (now - failing_since > 60) {
                char line[400];
                r = sl_error_set(err, SL_ERR_IO, "squeue failed for a minute: %s",
                                 first_line(errout, line, sizeof line));
                free(out);
                free(errout);
                break;
            }
        } else {
            failing_since = -1;
            memset(seen, 0, (size_t)g->count * sizeof(bool));
            for (int i = 0; i < g->count; i++)
                was_done[i] = g->jobs[i].done;
            for (char *line = out, *next; line && *line; line = next) {
                next = strchr(line, '\n');
                if (next)
                    *next++ = '\0';
                apply_row(g, o->wake_dir, line, seen, res);
            }
            /* A job squeue no longer knows (purged, MinJobAge) before it
             * was seen ending: lost, after three polls to be sure. */
            for (int i = 0; i < g->count; i++) {
                job *j = &g->jobs[i];
                if (j->submit && !j->done && !seen[i] && ++j->missing >= 3) {
                    j->done = true;
                    res->jobs[i].end = SL_SLURM_LOST;
                    snprintf(res->jobs[i].state, sizeof res->jobs[i].state, "UNKNOWN");
                } else if (seen[i]) {
                    j->missing = 0;
                }
            }
            say_ended(g, o, was_done, res);
        }
        free(out);
        free(errout);
        bool all_done = true;
        for (int i = 0; i < g->count; i++)
            all_done &= !g->jobs[i].submit || g->jobs[i].done;
        if (all_done)
            continue; /* the loop's head ends it */
        /* A job that said it ended is running or completing in Slurm for
         * a moment: asked again at a short period, the shortest after a
         * wake. */
        double next = pause;
        for (int b = 0; b < g->batch_count; b++)
            if (g->batches[b].said_ended && batch_open(g, &g->batches[b]) && next > 0.1)
                next = 0.1;
        if (pause_or_wake(g, o, next, &woken))
            pause = o->poll_seconds;
        else
            pause = pause * 1.5 < o->poll_max_seconds ? pause * 1.5
                    : o->poll_max_seconds > o->poll_seconds ? o->poll_max_seconds
                                                            : o->poll_seconds;
    }
    free(seen);
    free(was_done);
    return r;
}

/* ------------------------------------------------------------------ */
/* The call                                                            */
/* ------------------------------------------------------------------ */

void sl_pipeline_slurm_result_free(sl_pipeline_slurm_result *res)
{
    if (!res)
        return;
    for (int i = 0; i < res->job_count; i++) {
        free(res->jobs[i].id);
        free(res->jobs[i].log);
    }
    free(res->jobs);
    memset(res, 0, sizeof(*res));
}

void *sl_pipeline_slurm_result_json(const sl_pipeline_slurm_result *res)
{
    json_t *jobs = json_array();
    for (int i = 0; jobs && i < res->job_count; i++) {
        const sl_pipeline_slurm_job *j = &res->jobs[i];
        json_t *o = json_pack("{s:s, s:b, s:s?, s:s, s:s?, s:i, s:i, s:s, s:f, s:f}", "id", j->id,
                              "submitted", j->submitted, "slurm_id",
                              j->slurm_id[0] ? j->slurm_id : NULL, "end",
                              sl_pipeline_slurm_end_name(j->end), "state",
                              j->state[0] ? j->state : NULL, "exit_code", j->exit_code, "signal",
                              j->signal, "log", j->log, "queue_seconds", j->queue_seconds,
                              "wall_seconds", j->wall_seconds);
        if (!o || json_array_append_new(jobs, o) != 0) {
            json_decref(jobs);
            return NULL;
        }
    }
    if (!jobs)
        return NULL;
    return json_pack("{s:i, s:i, s:i, s:i, s:i, s:i, s:i, s:i, s:f, s:f, s:f, s:f, s:f, s:o}",
                     "jobs_total", res->job_count, "skipped", res->skipped, "submitted",
                     res->submitted, "completed", res->completed, "failed", res->failed,
                     "cancelled", res->cancelled, "lost", res->lost, "sbatch_calls",
                     res->sbatch_calls, "submit_seconds", res->submit_seconds, "wait_seconds",
                     res->wait_seconds, "wall_seconds", res->wall_seconds, "queue_seconds_mean",
                     res->queue_seconds_mean, "job_seconds_sum", res->job_seconds_sum, "jobs",
                     jobs);
}

/* Is the controller up: `scontrol ping` (exit 0 when it answers). */
static sl_result check_cluster(const sl_pipeline_slurm_options *o, sl_error *err)
{
    char *args[] = {(char *)o->scontrol, "ping", NULL};
    char *out = NULL, *errout = NULL;
    int status = 0;
    sl_result r = run_command(args, NULL, &out, &errout, &status, err);
    if (r != SL_OK)
        return r;
    if (!WIFEXITED(status) || WEXITSTATUS(status) != 0) {
        char line[400];
        r = sl_error_set(err, SL_ERR_IO, "the Slurm controller does not answer (cluster down?): %s",
                         first_line(out[0] ? out : errout, line, sizeof line));
    }
    free(out);
    free(errout);
    return r;
}

/* Is `prog` there to run (on PATH, or a path)? */
static bool program_exists(const char *prog)
{
    if (strchr(prog, '/'))
        return access(prog, X_OK) == 0;
    const char *path = getenv("PATH");
    if (!path)
        path = "/usr/bin:/bin";
    for (const char *p = path; *p;) {
        size_t n = strcspn(p, ":");
        char full[4096];
        if (n > 0 && snprintf(full, sizeof full, "%.*s/%s", (int)n, p, prog) < (int)sizeof full &&
            access(full, X_OK) == 0)
            return true;
        p += n;
        if (*p == ':')
            p++;
    }
    return false;
}

sl_result sl_pipeline_slurm_run(const char *jobs_json, const sl_pipeline_slurm_options *opts,
                                sl_pipeline_slurm_result *res, sl_error *err)
{
    double t0 = sl_seconds();
    memset(res, 0, sizeof(*res));
    sl_error_clear(err);
    sl_pipeline_slurm_options defaults;
    sl_pipeline_slurm_options_init(&defaults);
    if (!opts)
        opts = &defaults;
    if (!(opts->poll_seconds > 0 && opts->poll_seconds < 3600) ||
        !(opts->poll_max_seconds >= 0 && opts->poll_max_seconds < 3600) ||
        !(opts->timeout_seconds >= 0))
        return sl_error_set(err, SL_ERR_USAGE, "Slurm poll period or timeout out of range");

    graph g;
    sl_result r = graph_load(jobs_json, &g, err);
    if (r == SL_OK)
        r = plan_batches(&g, err);
    if (r != SL_OK) {
        graph_free(&g);
        return r;
    }
    res->jobs = calloc((size_t)g.count + 1, sizeof(sl_pipeline_slurm_job));
    if (!res->jobs) {
        graph_free(&g);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", jobs_json);
    }
    res->job_count = g.count;
    for (int i = 0; i < g.count; i++) {
        sl_pipeline_slurm_job *rj = &res->jobs[i];
        rj->id = strdup(g.jobs[i].id);
        rj->log = strdup(g.jobs[i].log);
        rj->exit_code = -1;
        rj->submitted = g.jobs[i].submit;
        if (!rj->id || !rj->log) {
            graph_free(&g);
            return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", jobs_json);
        }
    }

    if (g.batch_count > 0) {
        if (!program_exists(opts->sbatch))
            r = sl_error_set(err, SL_ERR_UNSUPPORTED,
                             "%s: not found (Slurm's client commands are not installed)",
                             opts->sbatch);
        if (r == SL_OK)
            r = check_cluster(opts, err);
        /* the jobs' working folder (--chdir) and log folders */
        char out_dot[4200];
        snprintf(out_dot, sizeof out_dot, "%s/.", g.out);
        if (r == SL_OK)
            r = make_parent(out_dot, err);
        for (int i = 0; i < g.count && r == SL_OK; i++)
            if (g.jobs[i].submit)
                r = make_parent(g.jobs[i].log, err);
        double ts = sl_seconds();
        int b = 0;
        for (; b < g.batch_count && r == SL_OK; b++) {
            r = submit_batch(&g, b, opts, err);
            for (int m = 0; m < g.batches[b].count && r == SL_OK; m++) {
                int i = g.batches[b].members[m];
                slurm_name(&g, &g.jobs[i], res->jobs[i].slurm_id, sizeof res->jobs[i].slurm_id);
            }
        }
        if (r != SL_OK && b > 0)
            cancel_batches(&g, b - 1);
        double tw = sl_seconds();
        res->submit_seconds = tw - ts;
        res->sbatch_calls = b;
        if (r == SL_OK)
            r = wait_jobs(&g, opts, res, t0, err);
        res->wait_seconds = sl_seconds() - tw;
    }

    int ran = 0;
    double queued = 0;
    for (int i = 0; i < g.count; i++) {
        sl_pipeline_slurm_job *rj = &res->jobs[i];
        if (!rj->submitted) {
            res->skipped++;
            continue;
        }
        res->submitted++;
        switch (rj->end) {
        case SL_SLURM_COMPLETED: res->completed++; break;
        case SL_SLURM_FAILED: res->failed++; break;
        case SL_SLURM_CANCELLED: res->cancelled++; break;
        case SL_SLURM_LOST: res->lost++; break;
        case SL_SLURM_SKIPPED: break;
        }
        if (rj->exit_code >= 0) {
            ran++;
            queued += rj->queue_seconds;
            res->job_seconds_sum += rj->wall_seconds;
        }
    }
    res->queue_seconds_mean = ran ? queued / ran : 0;
    res->wall_seconds = sl_seconds() - t0;
    graph_free(&g);
    return r;
}
