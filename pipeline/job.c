/* SPDX-License-Identifier: BSD-3-Clause */
/* One job: its key, its stamp, and `setlight job JOBS.json ID`. */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <signal.h>
#include <spawn.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include "pipeline_private.h"
#include "setlight/capture.h"

extern char **environ;

/* The first input that is not a regular file, or NULL; *exists: whether
 * it is there at all (a folder, a FIFO or /dev/zero in an edited graph
 * would block or never end the hashing). */
static const char *input_not_regular(const json_t *job, bool *exists)
{
    size_t i;
    json_t *x;
    json_array_foreach(json_object_get(job, "inputs"), i, x) {
        struct stat sb;
        const char *path = json_string_value(x);
        *exists = path && !stat(path, &sb);
        if (!*exists || !S_ISREG(sb.st_mode))
            return path ? path : "(not a string)";
    }
    return NULL;
}

/* What is hashed: "setlight-job 1", the version, each argument after
 * argv[0], then each input's path and the SHA-256 of its contents, every
 * field ended by a NUL. */
bool pl_job_key(const json_t *job, char key[65])
{
    key[0] = 0;
    size_t cap = 4096, len = 0;
    char *buf = malloc(cap);
    if (!buf)
        return false;
#define ADD(s)                                                                                   \
    do {                                                                                         \
        size_t n_ = strlen(s) + 1;                                                               \
        if (len + n_ > cap) {                                                                    \
            while (len + n_ > cap)                                                               \
                cap *= 2;                                                                        \
            char *p_ = realloc(buf, cap);                                                        \
            if (!p_) {                                                                           \
                free(buf);                                                                       \
                return false;                                                                    \
            }                                                                                    \
            buf = p_;                                                                            \
        }                                                                                        \
        memcpy(buf + len, s, n_);                                                                \
        len += n_;                                                                               \
    } while (0)
    ADD("setlight-job 1");
    ADD(sl_version());
    size_t i;
    json_t *x;
    json_array_foreach(json_object_get(job, "command"), i, x) {
        if (i > 0)
            ADD(json_string_value(x) ? json_string_value(x) : "");
    }
    bool exists;
    if (input_not_regular(job, &exists)) {
        free(buf);
        return false;
    }
    json_array_foreach(json_object_get(job, "inputs"), i, x) {
        const char *path = json_string_value(x);
        char hex[65];
        sl_error err;
        if (!path || sl_sha256_file(path, hex, &err) != SL_OK || !hex[0]) {
            free(buf);
            return false;
        }
        ADD(path);
        ADD(hex);
    }
#undef ADD
    sl_sha256_hex(buf, len, key);
    free(buf);
    return key[0] != 0;
}

void pl_stamp_path(const json_t *graph, const json_t *job, char *path, size_t size)
{
    snprintf(path, size, "%s/%s.stamp.json", json_string_value(json_object_get(graph, "out")),
             json_string_value(json_object_get(job, "id")));
}

json_t *pl_stamp_load(const json_t *graph, const json_t *job)
{
    char path[PATH_MAX + 600];
    pl_stamp_path(graph, job, path, sizeof path);
    json_t *s = NULL;
    sl_error err;
    pl_json_load(path, &s, &err);
    return s;
}

bool pl_stamp_current(const json_t *graph, const json_t *job, const char *key)
{
    json_t *s = pl_stamp_load(graph, job);
    const char *sk = json_string_value(json_object_get(s, "key"));
    const char *st = json_string_value(json_object_get(s, "status"));
    bool ok = sk && st && !strcmp(sk, key) && !strcmp(st, "ok");
    size_t i;
    json_t *o;
    json_array_foreach(json_object_get(s, "outputs"), i, o) {
        struct stat sb;
        const char *p = json_string_value(json_object_get(o, "path"));
        if (!ok || !p || stat(p, &sb) ||
            (json_int_t)sb.st_size != json_integer_value(json_object_get(o, "size")))
            ok = false;
    }
    json_decref(s);
    return ok;
}

/* The output that takes the command's stdout (its --json result), or NULL. */
static const char *result_output(const json_t *job)
{
    size_t i;
    json_t *x;
    json_array_foreach(json_object_get(job, "outputs"), i, x) {
        const char *p = json_string_value(x);
        size_t n = p ? strlen(p) : 0;
        if (n > 12 && !strcmp(p + n - 12, ".result.json"))
            return p;
    }
    return NULL;
}

/* The last non-empty line of the log: the command's error. */
static void last_line(const char *log, char *line, size_t size)
{
    line[0] = 0;
    FILE *f = fopen(log, "r");
    if (!f)
        return;
    char buf[2048];
    while (fgets(buf, sizeof buf, f)) {
        buf[strcspn(buf, "\n")] = 0;
        if (buf[0])
            snprintf(line, size, "%s", buf);
    }
    fclose(f);
}

static sl_result make_parent(const char *path, sl_error *err)
{
    char dir[PATH_MAX];
    snprintf(dir, sizeof dir, "%s", path);
    char *slash = strrchr(dir, '/');
    if (!slash || slash == dir)
        return SL_OK;
    *slash = 0;
    return pl_mkdirs(dir, err);
}

/* The index reads every job's outcome: OUT/status.json, each job's stamp
 * status and key, is its input, rewritten only when an outcome changed, so
 * the index reruns exactly when something it shows did. */
sl_result pl_index_prepare(const json_t *graph, sl_error *err)
{
    json_t *doc = json_object();
    size_t i;
    json_t *job;
    json_array_foreach(json_object_get(graph, "jobs"), i, job) {
        if (!strcmp(json_string_value(json_object_get(job, "stage")), "index"))
            continue;
        json_t *st = pl_stamp_load(graph, job);
        json_t *e = json_object();
        json_object_set(e, "status", json_object_get(st, "status") ? json_object_get(st, "status")
                                                                   : json_null());
        json_object_set(e, "key", json_object_get(st, "key") ? json_object_get(st, "key")
                                                             : json_null());
        json_object_set_new(doc, json_string_value(json_object_get(job, "id")), e);
        json_decref(st);
    }
    char path[PATH_MAX + 16];
    snprintf(path, sizeof path, "%s/status.json", json_string_value(json_object_get(graph, "out")));
    json_t *old = NULL;
    sl_error ignored;
    sl_result r = SL_OK;
    pl_json_load(path, &old, &ignored);
    sl_atomic_sweep(path); /* what an index job killed while writing it left */
    if (!old || !json_equal(old, doc))
        r = pl_json_write(path, doc, err);
    json_decref(old);
    json_decref(doc);
    return r;
}

double pl_epoch_seconds(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

double pl_runqueue_wait_seconds(pid_t pid)
{
    char path[64];
    if (pid)
        snprintf(path, sizeof path, "/proc/%d/schedstat", (int)pid);
    else
        snprintf(path, sizeof path, "/proc/self/schedstat");
    FILE *f = fopen(path, "r");
    if (!f)
        return 0;
    unsigned long long run_ns = 0, wait_ns = 0;
    int n = fscanf(f, "%llu %llu", &run_ns, &wait_ns);
    fclose(f);
    return n == 2 ? 1e-9 * (double)wait_ns : 0;
}

int pl_reap(pid_t pid, struct rusage *ru, double *cpu_wait)
{
    siginfo_t info;
    while (waitid(P_PID, (id_t)pid, &info, WEXITED | WNOWAIT) < 0 && errno == EINTR) {
    }
    *cpu_wait = pl_runqueue_wait_seconds(pid); /* readable until the child is reaped */
    int status = 0;
    memset(ru, 0, sizeof *ru);
    while (wait4(pid, &status, 0, ru) < 0 && errno == EINTR) {
    }
    return status;
}

/* This process's own peak resident memory (VmHWM), in MB. Not getrusage's
 * ru_maxrss: a process started by posix_spawn inherits in it the peak of
 * the process that spawned it (the runner), whose memory it shared until
 * its exec. */
static double own_peak_rss_mb(void)
{
    double kb = pl_self_status("VmHWM");
    return kb > 0 ? kb / 1024.0 : 0;
}

/* The job `id` of graph (both loaded by pl_graph_load_job, references
 * taken) from `started` (the epoch) on, when this process had waited
 * wait0 s for a CPU: what sl_pipeline_job_run does once it has read the
 * job. known_key: NULL, or the job's key the local runner computed just
 * before it forked this process and found the stamp not current. */
static sl_result job_run(const char *jobs_json, const char *id, json_t *graph, json_t *job,
                         const char *known_key, double started, double wait0, int *exit_code,
                         bool *skipped, sl_error *err)
{
    sl_result r = SL_OK;
    *exit_code = 0;
    *skipped = false;
    char key[65];
    if (!strcmp(json_string_value(json_object_get(job, "stage")), "index") &&
        (r = pl_index_prepare(graph, err))) {
        json_decref(job);
        json_decref(graph);
        return r;
    }
    bool exists = false;
    const char *input = input_not_regular(job, &exists);
    if (input) {
        r = exists ? sl_error_set(err, SL_ERR_INPUT, "%s: job '%s': input %s is not a regular file",
                                  jobs_json, id, input)
                   : sl_error_set(err, SL_ERR_INPUT,
                                  "%s: input %s is missing (did its dependencies run?)", id, input);
        json_decref(job);
        json_decref(graph);
        return r;
    }
    if (known_key)
        snprintf(key, sizeof key, "%s", known_key);
    else if (!pl_job_key(job, key)) {
        json_decref(job);
        json_decref(graph);
        return sl_error_set(err, SL_ERR_INPUT, "%s: an input cannot be read", id);
    }
    if (!known_key && pl_stamp_current(graph, job, key)) {
        *skipped = true;
        json_decref(job);
        json_decref(graph);
        return SL_OK;
    }
    json_t *command = json_object_get(job, "command");
    size_t argc = json_array_size(command), i;
    char **argv = calloc(argc + 1, sizeof *argv);
    const char *log = json_string_value(json_object_get(job, "log"));
    const char *result = result_output(job);
    char partial[PATH_MAX + 16] = "", stamp[PATH_MAX + 600];
    json_t *x;
    if (!argv) {
        json_decref(job);
        json_decref(graph);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", id);
    }
    json_array_foreach(command, i, x)
        argv[i] = (char *)json_string_value(x);
    /* a run of this job killed outright (SIGKILL, power) left its temporaries */
    json_array_foreach(json_object_get(job, "outputs"), i, x) {
        if ((r = make_parent(json_string_value(x), err)))
            goto done;
        sl_atomic_sweep(json_string_value(x));
    }
    pl_stamp_path(graph, job, stamp, sizeof stamp);
    sl_atomic_sweep(stamp);
    if ((r = make_parent(log, err)))
        goto done;
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    if (result) {
        snprintf(partial, sizeof partial, "%s.partial", result);
        posix_spawn_file_actions_addopen(&fa, 1, partial, O_WRONLY | O_CREAT | O_TRUNC, 0666);
    } else
        posix_spawn_file_actions_addopen(&fa, 1, "/dev/null", O_WRONLY, 0);
    posix_spawn_file_actions_addopen(&fa, 2, log, O_WRONLY | O_CREAT | O_TRUNC, 0666);
    pid_t pid;
    double t0 = sl_seconds();
    int e = posix_spawn(&pid, argv[0], &fa, NULL, argv, environ);
    posix_spawn_file_actions_destroy(&fa);
    if (e) {
        r = sl_error_set(err, SL_ERR_IO, "%s: cannot run %s: %s", id, argv[0], strerror(e));
        goto done;
    }
    struct rusage ru;
    double cpu_wait;
    int status = pl_reap(pid, &ru, &cpu_wait);
    double wall = sl_seconds() - t0;
    double cpu = pl_cpu_seconds(&ru);
    *exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
    char message[2048] = "";
    if (!*exit_code && result && rename(partial, result))
        *exit_code = 1, snprintf(message, sizeof message, "%s: cannot rename: %s", result,
                                 strerror(errno));
    if (partial[0])
        unlink(partial);
    json_t *outs = json_array();
    json_array_foreach(json_object_get(job, "outputs"), i, x) {
        struct stat sb;
        const char *p = json_string_value(x);
        if (stat(p, &sb)) {
            if (!*exit_code) {
                *exit_code = 1;
                snprintf(message, sizeof message, "%s: not written by the command", p);
            }
            continue;
        }
        json_array_append_new(outs, json_pack("{s:s,s:I}", "path", p, "size",
                                               (json_int_t)sb.st_size));
    }
    if (*exit_code && !message[0])
        last_line(log, message, sizeof message);
    cpu_wait += pl_runqueue_wait_seconds(0) - wait0; /* and this process's own */
    json_t *st = json_pack("{s:s,s:s,s:s,s:i,s:f,s:f,s:f,s:f,s:f,s:f,s:f,s:o}", "id", id, "key",
                           key, "status", *exit_code ? "failed" : "ok", "exit", *exit_code,
                           "seconds", wall, "cpu_seconds", cpu, "cpu_wait_seconds", cpu_wait,
                           "max_rss_mb", (double)ru.ru_maxrss / 1024.0, "job_max_rss_mb",
                           own_peak_rss_mb(), "started", started, "ended", pl_epoch_seconds(),
                           "outputs", outs);
    if (*exit_code)
        json_object_set_new(st, "message", json_string(message));
    r = pl_json_write(stamp, st, err);
    json_decref(st);
done:
    free(argv);
    json_decref(job);
    json_decref(graph);
    return r;
}

sl_result sl_pipeline_job_run(const char *jobs_json, const char *id, int *exit_code,
                              bool *skipped, sl_error *err)
{
    double started = pl_epoch_seconds();
    *exit_code = 0;
    *skipped = false;
    /* Checked whole when it was written (pl_graph_write): while unchanged,
     * only this job is read; an edited graph is checked whole again. */
    json_t *graph = NULL, *job = NULL;
    bool checked_whole;
    sl_result r = pl_graph_load_job(jobs_json, id, &graph, &job, &checked_whole, err);
    return r ? r : job_run(jobs_json, id, graph, job, NULL, started, 0, exit_code, skipped, err);
}

int pl_job_run_forked(const char *jobs_json, json_t *graph, json_t *job, const char *key)
{
    double started = pl_epoch_seconds();
    int code;
    bool skipped;
    sl_error err;
    const char *id = json_string_value(json_object_get(job, "id"));
    json_incref(graph);
    json_incref(job);
    if (job_run(jobs_json, id, graph, job, key, started, 0, &code, &skipped, &err)) {
        /* as `setlight job` says it */
        fprintf(stderr, "setlight job: %s\n", err.message[0] ? err.message : sl_result_name(err.code));
        return sl_result_exit_code(err.code);
    }
    return code;
}

sl_result pl_job_run_next(const char *jobs_json, json_t *graph, json_t *job, bool first,
                          int *exit_code, sl_error *err)
{
    /* the process's start and its waits till now go to its first job */
    double started = pl_epoch_seconds(), wait0 = first ? 0 : pl_runqueue_wait_seconds(0);
    bool skipped;
    json_incref(graph);
    json_incref(job);
    return job_run(jobs_json, json_string_value(json_object_get(job, "id")), graph, job, NULL,
                   started, wait0, exit_code, &skipped, err);
}

/* Whether job depends on a job of ids[0..count) that did not succeed
 * (codes). */
static bool after_failure(const json_t *job, char *const *ids, const int *codes, int count)
{
    size_t d;
    json_t *dep;
    json_array_foreach(json_object_get(job, "deps"), d, dep)
        for (int k = 0; k < count; k++)
            if (codes[k] && !strcmp(ids[k], json_string_value(dep)))
                return true;
    return false;
}

void sl_pipeline_jobs_run(const char *jobs_json, char *const *ids, int count, int *codes,
                          sl_error *errs)
{
    for (int i = 0; i < count; i++) {
        json_t *graph = NULL, *job = NULL;
        bool checked_whole;
        sl_error_clear(&errs[i]);
        sl_result r = pl_graph_load_job(jobs_json, ids[i], &graph, &job, &checked_whole, &errs[i]);
        if (!r && after_failure(job, ids, codes, i))
            codes[i] = -1;
        else if (!r)
            r = pl_job_run_next(jobs_json, graph, job, i == 0, &codes[i], &errs[i]);
        json_decref(job);
        json_decref(graph);
        if (r)
            codes[i] = sl_result_exit_code(r);
    }
}
