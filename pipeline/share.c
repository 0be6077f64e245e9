/* SPDX-License-Identifier: BSD-3-Clause */
/* A grouped setup's jobs shared by the processes that run it (docs/slurm.md,
 * "A setup as one Slurm job"): the Slurm job that took the setup, and any
 * other that found no setup left and would otherwise leave its CPU idle
 * until the day's last setup ends. Each job is taken with a claim file made
 * with O_CREAT|O_EXCL in the setup's claims folder (atomic, on a shared file
 * system too), so it runs once; its end is a second file, N.done, holding
 * its exit code. A process takes, in the graph's order, any job nobody has
 * taken whose dependencies ended well, waits (inotify on the folder, no
 * busy polling) while the jobs left wait for jobs running elsewhere, and
 * returns once every job is taken. */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/inotify.h>
#include <sys/stat.h>
#include <unistd.h>

#include "pipeline_private.h"

enum { S_OPEN, S_TAKEN, S_OK, S_FAILED };

/* How often a process waiting on jobs taken elsewhere looks again whatever
 * inotify says: a file system shared between nodes tells inotify nothing
 * of the other nodes' writes. */
#define SHARE_RECHECK_MS 1000

static void claim_path(const char *dir, int i, const char *suffix, char *path, size_t size)
{
    snprintf(path, size, "%s/%d%s", dir, i, suffix);
}

/* Whether the process named in claim file `path` ("HOST PID SLURM_JOB_ID")
 * is gone: on this host no such process, or its Slurm job seen ended by the
 * Slurm runner without saying so itself (killed: FARM/ended/ID, FARM the
 * claims folder's grandparent) while the job has no N.done. An unreadable
 * or half-written claim is taken as alive. */
static bool claimant_gone(const char *dir, const char *path)
{
    char text[512] = "", host[256] = "", here[256] = "", slurm_id[64] = "";
    long pid = 0;
    FILE *f = fopen(path, "r");
    if (!f)
        return false;
    size_t n = fread(text, 1, sizeof text - 1, f);
    fclose(f);
    text[n] = 0;
    int got = sscanf(text, "%255s %ld %63s", host, &pid, slurm_id);
    if (got < 2 || pid <= 0)
        return false;
    if (!gethostname(here, sizeof here - 1) && !strcmp(host, here) &&
        kill((pid_t)pid, 0) != 0 && errno == ESRCH)
        return true;
    if (got == 3 && strcmp(slurm_id, "-")) {
        char ended[PATH_MAX + 128];
        struct stat sb;
        snprintf(ended, sizeof ended, "%s/../../ended/%s", dir, slurm_id);
        return !stat(ended, &sb);
    }
    return false;
}

/* Job i's state from its files; a job whose claimant is gone without
 * ending it counts as failed (its dependants are not run, as when the
 * setup's only Slurm job is killed). */
static int job_state(const char *dir, int i)
{
    char path[PATH_MAX + 64];
    claim_path(dir, i, ".done", path, sizeof path);
    FILE *f = fopen(path, "r");
    if (f) {
        int code = 1;
        if (fscanf(f, "%d", &code) != 1)
            code = 1;
        fclose(f);
        return code ? S_FAILED : S_OK;
    }
    claim_path(dir, i, "", path, sizeof path);
    if (access(path, F_OK))
        return S_OPEN;
    return claimant_gone(dir, path) ? S_FAILED : S_TAKEN;
}

/* Takes job i: 1 when this process made its claim file, 0 when another
 * process has it, -1 (errno set) when it cannot be made: no such folder,
 * no permission, the disk full. */
static int claim(const char *dir, int i)
{
    char path[PATH_MAX + 64], text[400], host[256] = "?";
    claim_path(dir, i, "", path, sizeof path);
    int fd = open(path, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
    if (fd < 0)
        return errno == EEXIST ? 0 : -1;
    gethostname(host, sizeof host - 1);
    const char *slurm_id = getenv("SLURM_JOB_ID");
    int len = snprintf(text, sizeof text, "%s %ld %s\n", host, (long)getpid(),
                       slurm_id && *slurm_id ? slurm_id : "-");
    if (write(fd, text, (size_t)len) != len) {
        /* a claim is its existence; what it says only helps find a dead one */
    }
    close(fd);
    return 1;
}

/* Job i ended with code (-1: not run): N.done, written whole then renamed
 * in, so a reader sees the code or nothing. */
static void mark_done(const char *dir, int i, int code)
{
    char tmp[PATH_MAX + 64], path[PATH_MAX + 64], text[32];
    snprintf(tmp, sizeof tmp, "%s/.%d.done.%ld", dir, i, (long)getpid());
    claim_path(dir, i, ".done", path, sizeof path);
    int len = snprintf(text, sizeof text, "%d\n", code);
    FILE *f = fopen(tmp, "w");
    if (f && fwrite(text, 1, (size_t)len, f) == (size_t)len && !fclose(f)) {
        if (rename(tmp, path))
            unlink(tmp);
        return;
    }
    if (f)
        fclose(f);
    unlink(tmp);
}

/* Of ids[0..count), the index of id, or -1. */
static int listed(char *const *ids, int count, const char *id)
{
    for (int k = 0; k < count; k++)
        if (!strcmp(ids[k], id))
            return k;
    return -1;
}

void sl_pipeline_jobs_share(const char *jobs_json, const char *claims_dir, char *const *ids,
                            int count, int *codes, sl_error *errs)
{
    json_t **graphs = calloc((size_t)count + 1, sizeof *graphs);
    json_t **jobs = calloc((size_t)count + 1, sizeof *jobs);
    int *state = calloc((size_t)count + 1, sizeof *state);
    sl_result *loaded = calloc((size_t)count + 1, sizeof *loaded);
    if (!graphs || !jobs || !state || !loaded) {
        for (int i = 0; i < count; i++) {
            codes[i] = sl_result_exit_code(SL_ERR_NOMEM);
            sl_error_set(&errs[i], SL_ERR_NOMEM, "%s: out of memory", ids[i]);
        }
        free(graphs), free(jobs), free(state), free(loaded);
        return;
    }
    for (int i = 0; i < count; i++) {
        bool checked_whole;
        sl_error_clear(&errs[i]);
        codes[i] = SL_PIPELINE_JOB_ELSEWHERE;
        /* a job that cannot be read is taken like any other and ends with
         * its error, so the processes sharing it agree on its end */
        loaded[i] = pl_graph_load_job(jobs_json, ids[i], &graphs[i], &jobs[i], &checked_whole,
                                      &errs[i]);
    }
    int watch = inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
    if (watch >= 0 && inotify_add_watch(watch, claims_dir, IN_MOVED_TO | IN_CREATE) < 0) {
        close(watch);
        watch = -1;
    }
    bool ran_any = false, stop = false;
    while (!stop) {
        for (int i = 0; i < count; i++)
            state[i] = job_state(claims_dir, i);
        bool waiting = false, took = false;
        for (int i = 0; i < count && !took; i++) {
            if (state[i] != S_OPEN)
                continue;
            bool blocked = false, ready = true;
            size_t d;
            json_t *dep;
            json_array_foreach(json_object_get(jobs[i], "deps"), d, dep) {
                int k = listed(ids, count, json_string_value(dep));
                if (k < 0)
                    continue; /* not of this group: done before it was submitted */
                blocked |= state[k] == S_FAILED;
                ready &= state[k] == S_OK;
            }
            if (!blocked && !ready) {
                waiting = true;
                continue;
            }
            int mine = claim(claims_dir, i);
            if (mine < 0) {
                /* not run here, and said: never an exit 0 for jobs not run */
                codes[i] = sl_result_exit_code(SL_ERR_IO);
                sl_error_set(&errs[i], SL_ERR_IO, "%s: cannot claim %s in %s: %s", jobs_json,
                             ids[i], claims_dir, strerror(errno));
                stop = true;
                break;
            }
            if (!mine)
                continue; /* taken meanwhile by another process */
            took = true;
            if (blocked) {
                codes[i] = -1;
            } else if (loaded[i]) {
                codes[i] = sl_result_exit_code(loaded[i]);
            } else {
                sl_result r = pl_job_run_next(jobs_json, graphs[i], jobs[i], !ran_any, &codes[i],
                                              &errs[i]);
                if (r)
                    codes[i] = sl_result_exit_code(r);
                ran_any = true;
            }
            mark_done(claims_dir, i, codes[i]);
        }
        if (took || stop)
            continue;
        if (!waiting)
            break; /* every job taken: nothing left here for this process */
        if (watch >= 0) {
            struct pollfd p = {.fd = watch, .events = POLLIN};
            if (poll(&p, 1, SHARE_RECHECK_MS) > 0) {
                char buf[4096];
                while (read(watch, buf, sizeof buf) > 0) {
                }
            }
        } else {
            usleep(1000 * SHARE_RECHECK_MS / 10);
        }
    }
    if (watch >= 0)
        close(watch);
    /* every job taken: the scripts skip this setup without a start of setlight */
    char all[PATH_MAX + 64];
    snprintf(all, sizeof all, "%s/all", claims_dir);
    int fd = stop ? -1 : open(all, O_WRONLY | O_CREAT | O_CLOEXEC, 0644);
    if (fd >= 0)
        close(fd);
    for (int i = 0; i < count; i++) {
        if (codes[i] == SL_PIPELINE_JOB_ELSEWHERE)
            sl_error_clear(&errs[i]); /* the process that took it says it */
        json_decref(jobs[i]);
        json_decref(graphs[i]);
    }
    free(graphs), free(jobs), free(state), free(loaded);
}
