/* SPDX-License-Identifier: BSD-3-Clause */
/* Runs a job graph (the "setlight-jobs" JSON that `setlight process
 * --emit-jobs` writes, docs/process.md) on a Slurm cluster: one sbatch per
 * job, or one job array per "array" group, chained with
 * --dependency=afterok and --kill-on-invalid-dep=yes (so a failed job's
 * dependents end CANCELLED instead of pending forever); waits by polling
 * squeue (no accounting database is needed) and reports every job's end.
 *
 * Jobs marked up_to_date are not submitted and dependencies on them are
 * dropped, except that a job depending on a submitted job is submitted too
 * (its inputs are about to change; it skips itself when they do not). So a
 * rerun after a failure submits the failed jobs and what follows them.
 *
 * Nothing is written but the jobs' log folders (made when missing); the
 * jobs write their own outputs. docs/slurm.md. */
#ifndef SETLIGHT_PIPELINE_SLURM_H
#define SETLIGHT_PIPELINE_SLURM_H

#include <stdbool.h>

#include "setlight/core.h"

typedef struct sl_pipeline_slurm_options {
    /* The Slurm commands: names looked up on PATH, or paths. */
    const char *sbatch; /* "sbatch" */
    const char *squeue; /* "squeue" */
    const char *scontrol; /* "scontrol" (ping: is the controller up) */
    const char *partition; /* NULL: the cluster's default */
    double poll_seconds; /* 0.25: squeue's first period while waiting */
    double poll_max_seconds; /* 2: the period grows by 1.5x a poll up to this */
    double timeout_seconds; /* 0: wait as long as the jobs take */
    /* NULL, or a folder the jobs write ended.SLURM_ID in as their last act
     * (a grouped setup's script does, docs/slurm.md): while waiting, such a
     * file or a change of the folder (looked at every 50 ms) brings the
     * next squeue forward, and a job that wrote its file and that squeue
     * shows COMPLETING has ended, with the exit code squeue gives. */
    const char *wake_dir;
} sl_pipeline_slurm_options;

void sl_pipeline_slurm_options_init(sl_pipeline_slurm_options *o);

/* How a job ended. SL_SLURM_SKIPPED: up to date, not submitted. */
typedef enum {
    SL_SLURM_SKIPPED = 0,
    SL_SLURM_COMPLETED, /* exit 0 */
    SL_SLURM_FAILED, /* non-zero exit, killed, timed out, out of memory, node failure */
    SL_SLURM_CANCELLED, /* cancelled: a dependency failed, or scancel */
    SL_SLURM_LOST /* gone from squeue before it was seen ending */
} sl_pipeline_slurm_end;

const char *sl_pipeline_slurm_end_name(sl_pipeline_slurm_end end);

typedef struct sl_pipeline_slurm_job {
    char *id; /* the graph's job id */
    char *log; /* the job's log file */
    bool submitted;
    char slurm_id[32]; /* "123", or "123_4" for an array task; "" when skipped */
    sl_pipeline_slurm_end end;
    char state[24]; /* Slurm's final state: COMPLETED, FAILED, CANCELLED, OUT_OF_MEMORY... */
    int exit_code; /* the job's exit status (-1 when it did not run) */
    int signal; /* the signal that ended it, or 0 */
    double queue_seconds; /* submit to start (Slurm's whole-second clock) */
    double wall_seconds; /* start to end (Slurm's whole-second clock) */
} sl_pipeline_slurm_job;

typedef struct sl_pipeline_slurm_result {
    sl_pipeline_slurm_job *jobs; /* in the file's order */
    int job_count;
    int skipped, submitted, completed, failed, cancelled, lost;
    int sbatch_calls; /* one per single job, one per array */
    double submit_seconds; /* spent in sbatch */
    double wait_seconds; /* last submission to the last job's end */
    double wall_seconds; /* the whole call */
    double queue_seconds_mean; /* mean submit-to-start over jobs that ran */
    double job_seconds_sum; /* sum of the jobs' wall times */
} sl_pipeline_slurm_result;

/* Submits the graph in jobs_json, waits for it and fills res (freed with
 * sl_pipeline_slurm_result_free, also after a failure). SL_OK when every
 * submitted job ended (res says how; a failed job is not an error of this
 * call); SL_ERR_INPUT naming the file for a graph that does not parse or
 * does not hold together; SL_ERR_UNSUPPORTED when sbatch is not installed;
 * SL_ERR_IO when the cluster is down, refuses a submission (what was
 * submitted is cancelled) or the timeout passes. */
sl_result sl_pipeline_slurm_run(const char *jobs_json, const sl_pipeline_slurm_options *opts,
                                sl_pipeline_slurm_result *res, sl_error *err);

void sl_pipeline_slurm_result_free(sl_pipeline_slurm_result *res);

/* The result as JSON for --json (docs/slurm.md): {"submitted":..,
 * "jobs":[{"id","submitted","slurm_id","end","state","exit_code","signal",
 * "log","queue_seconds","wall_seconds"}], ...}; a new reference, or NULL
 * when out of memory. Declared as void * so callers need not include
 * jansson.h: it is a json_t *. */
void *sl_pipeline_slurm_result_json(const sl_pipeline_slurm_result *res);

#endif
