/* SPDX-License-Identifier: BSD-3-Clause */
/* Inside the pipeline module: the graph is kept as the JSON it is written
 * as (docs/process.md), so the planner, the runners and `setlight job`
 * share one representation. */
#ifndef SETLIGHT_PIPELINE_PRIVATE_H
#define SETLIGHT_PIPELINE_PRIVATE_H

#include <jansson.h>
#include <limits.h>
#include <stdbool.h>
#include <stdint.h>
#include <sys/types.h>

#include "setlight/pipeline.h"

enum { PROBE_NONE = 0, PROBE_CHROME, PROBE_GREY, PROBE_CHART };

typedef struct view {
    json_t *frames; /* absolute paths, in exposure order */
    double focal_mm;
    int probe;      /* PROBE_* */
} view;

typedef struct setup_plan {
    const sl_pipeline_options *o;
    const char *name;
    char dir[PATH_MAX + 300]; /* OUT/<name> */
    view views[64];
    int view_count;
    double sensor_mm;    /* the probe camera's sensor width, 0: unknown */
    json_t *warnings;    /* the sessions' problems (ingest's skipped files, short brackets) */
} setup_plan;

/* SETUP (a folder: session, virtual-set capture or frames) -> sp's views,
 * ingesting into sp->dir/ingest when needed; sp->warnings gets the
 * sessions' problems. */
sl_result pl_load_setup(setup_plan *sp, const char *src, sl_error *err);

/* mkdir -p. */
sl_result pl_mkdirs(const char *path, sl_error *err);
/* Loads a JSON file: SL_ERR_NOT_FOUND when absent, SL_ERR_INPUT naming the
 * file and line when it does not parse. */
sl_result pl_json_load(const char *path, json_t **out, sl_error *err);
/* Writes a JSON value atomically (indented, sorted as built). */
sl_result pl_json_write(const char *path, const json_t *value, sl_error *err);

/* A graph read back (graph.c): the document, checked whole. */
struct sl_pipeline_graph {
    json_t *root;    /* the file's JSON */
    json_t *jobs;    /* root's "jobs" */
    json_t *ids;     /* id -> its index in jobs (a JSON integer) */
    const char *out; /* root's "out" */
    int count;
    int *order;      /* indices into jobs, each after its dependencies */
};

/* Reads the file (refused over SL_MAX_JSON_BYTES before it is read;
 * SL_ERR_NOT_FOUND when missing) and sl_pipeline_graph_parse's it. */
sl_result pl_graph_load(const char *path, sl_pipeline_graph **graph, sl_error *err);
/* The job of that id, or NULL. */
json_t *pl_graph_job(const sl_pipeline_graph *graph, const char *id);
/* Writes the graph (a job a line) after checking it whole with
 * sl_pipeline_graph_parse, and beside it PATH.checked: the file's SHA-256
 * and each job's bytes in it. Nothing is written when the check fails. */
sl_result pl_graph_write(const char *path, const json_t *graph, sl_error *err);
/* The job `id` of the graph at path and the graph's document (new
 * references): while the file is byte for byte what pl_graph_write wrote,
 * only the job is parsed and *graph holds the graph's fields but "jobs";
 * otherwise (edited, no sidecar, the index's job, which reads every job)
 * the graph is checked whole as pl_graph_load does and *checked_whole is
 * set. SL_ERR_USAGE when the graph has no such job. */
sl_result pl_graph_load_job(const char *path, const char *id, json_t **graph, json_t **job,
                            bool *checked_whole, sl_error *err);

/* The graph (its jobs' argv name jobs_path; "" there: OUT/jobs.json, set)
 * and the setups as planned: name, source, status "ok" or "failed" and the
 * reason (also OUT/setups.json). The CPU and CPU waits of the processes
 * that ingest the setups ahead of the plan are added to cost's runner
 * figures. */
sl_result pl_plan(const sl_pipeline_options *o, char *jobs_path, size_t jobs_path_size,
                  json_t **graph, json_t **setups, sl_pipeline_result *cost, sl_error *err);

/* The pictures a setup's report writes beside report.html (OUT/SETUP/):
 * the lat-long, then the renders under the HDRI and under the rig. They are
 * the report job's declared outputs, so a killed report's temporaries are
 * swept; the index shows the first as the setup's thumbnail. */
#define PL_REPORT_PICTURES 7
extern const char *const pl_report_pictures[PL_REPORT_PICTURES];

/* A job's key: SHA-256 hex of the version, its command (argv[0] left out:
 * the same setlight anywhere) and its input files' contents. false when an
 * input does not exist (yet) or is not a regular file. */
bool pl_job_key(const json_t *job, char key[65]);
/* Where a job's stamp lives: OUT/<id>.stamp.json. */
void pl_stamp_path(const json_t *graph, const json_t *job, char *path, size_t size);
/* True when the stamp says "ok" with this key and every output exists. */
bool pl_stamp_current(const json_t *graph, const json_t *job, const char *key);
/* The stamp (NULL when absent or unreadable). */
json_t *pl_stamp_load(const json_t *graph, const json_t *job);
/* In a process the local runner forked for it: runs job of graph (the
 * runner's, whole) as `setlight job JOBS.json ID` would, and returns that
 * command's exit code, an error said on stderr as it says it. key: NULL,
 * or the job's key just computed by the runner, which found its stamp not
 * current. */
int pl_job_run_forked(const char *jobs_json, json_t *graph, json_t *job, const char *key);
/* Runs job of graph (both as pl_graph_load_job gives them; the caller keeps
 * its references) as `setlight job JOBS.json ID` would, in a process that
 * runs several jobs: the process's start and its CPU waits before its first
 * job (first) count to that job. *exit_code: the command's, 0 when up to
 * date. */
sl_result pl_job_run_next(const char *jobs_json, json_t *graph, json_t *job, bool first,
                          int *exit_code, sl_error *err);
/* Writes OUT/status.json, the index job's input: every other job's stamp
 * status and key (rewritten only when one changed). */
sl_result pl_index_prepare(const json_t *graph, sl_error *err);

/* An item of a list (its index, at) ranked for qsort by pl_cmp_ranked: the
 * highest rank first, then the list's order. */
typedef struct pl_ranked {
    double rank;
    size_t at;
} pl_ranked;
int pl_cmp_ranked(const void *a, const void *b);

/* User + system CPU time of a getrusage or wait4 answer. */
struct rusage;
double pl_cpu_seconds(const struct rusage *ru);

/* The number of a field of /proc/self/status ("VmHWM" in kB, "Threads"),
 * or -1 when it cannot be read. */
double pl_self_status(const char *field);

/* Wall-clock time since the epoch: stamps of jobs run on different nodes
 * (or by different runners) are compared by it. */
double pl_epoch_seconds(void);

/* How long process pid (0: this one) waited for a CPU while runnable: the
 * second field of /proc/PID/schedstat (its main thread), readable until it
 * is reaped; 0 where it cannot be read. On a machine shared with other work
 * this is the time it lost to the others, which its CPU time does not show. */
double pl_runqueue_wait_seconds(pid_t pid);

/* Waits for child pid and reaps it: its wait status, its wait4 usage (ru)
 * and how long it waited for a CPU (cpu_wait, read before the reaping). */
int pl_reap(pid_t pid, struct rusage *ru, double *cpu_wait);

/* Whether job id's stamp says it ran to the end with its current key. */
bool pl_job_stamp_ok(const json_t *graph, const char *id);

/* farm.c: per setup of the graph, what the Slurm runner does with it
 * (docs/slurm.md): {"group": "setup" (one Slurm job), "job" (a Slurm job a
 * job) or "none" (up to date), "jobs" and "cpu_seconds" (the jobs to submit
 * and their CPU estimate), "slurm_seconds" (Slurm's cost of them one by
 * one), "overhead_share" (that over the estimate, null without one),
 * "reason" (one line)}. mode SL_FARM_GROUP_AUTO groups a setup when its
 * jobs one by one would cost Slurm more than 2% of their estimate. */
json_t *pl_farm_choices(const json_t *graph, sl_farm_group mode);
/* Replaces the grouped setups' jobs in farm's "jobs" by one job each, a
 * script in dir running them one at a time (then any grouped setup not yet
 * taken); out: the day's folder (the groups' logs). */
sl_result pl_farm_group(json_t *farm, const json_t *choices, const char *out, const char *dir,
                        sl_error *err);
/* A grouped setup's jobs' statuses into status, from their stamps: "ran"
 * or "failed" when written after t0 (the epoch), "skipped" when up to date
 * from before (or the setup was not submitted), else "not run", as is a job
 * after one that failed or did not run; when none failed but some did not
 * run (the Slurm job was killed: memory, time limit, node), the first not
 * run is the failed one, and true is returned. */
bool pl_farm_group_statuses(const json_t *graph, const char *setup, bool submitted, double t0,
                            json_t *status);

/* Runs the graph on this machine; fills the job counts of res and a status
 * per job id in *status ("skipped", "ran", "failed", "not run"). */
sl_result pl_run_local(const sl_pipeline_options *o, json_t *graph, json_t *status,
                       sl_pipeline_result *res, sl_error *err);

#endif
