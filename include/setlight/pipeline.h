/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight pipeline: a shoot day as a graph of file-to-file jobs.
 *
 * Each SETUP (a capture session folder with session.json, a virtual-set
 * capture from `setlight simulate`, or a plain folder of frames, ingested
 * first) becomes a chain of jobs, each one setlight command line:
 * merge (per view and per probe) -> stitch -> unwrap (chrome ball, a
 * cross-check) -> calibrate (grey ball, chart) -> rig -> render (grey,
 * chrome, chart under the HDRI and under the rig) -> report; then one index
 * for the day. A job's key is the SHA-256 of its input files' contents, its
 * command line and the setlight version; a stamp beside its outputs records
 * it, so a rerun skips what is up to date. The graph is written as JSON
 * (format "setlight-jobs", docs/process.md) and run locally, on Slurm, or by
 * any queue through `setlight job JOBS.json ID`. */
#ifndef SETLIGHT_PIPELINE_H
#define SETLIGHT_PIPELINE_H

#include <stdbool.h>
#include <stddef.h>

#include "setlight/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum { SL_FARM_LOCAL = 0, SL_FARM_SLURM } sl_farm;
/* What one Slurm job runs: per setup, chosen from the graph's CPU estimates
 * against Slurm's cost of a job (auto, the default: grouped when its jobs
 * one by one would cost over 2% of their CPU time), or for every setup one
 * job of the graph (the merges of a setup as an array), or a whole setup,
 * its jobs one after the other. */
typedef enum { SL_FARM_GROUP_AUTO = 0, SL_FARM_GROUP_JOB, SL_FARM_GROUP_SETUP } sl_farm_group;

typedef struct sl_pipeline_options {
    const char *const *setups; /* SETUP folders */
    int setup_count;
    const char *out;           /* OUT folder (created) */
    const char *exe;           /* the setlight executable the jobs run (absolute) */
    const char *emit_jobs;     /* write the graph there and run nothing (NULL: run) */
    sl_farm farm;              /* local (default) or slurm */
    sl_farm_group farm_group;  /* slurm: a Slurm job per setup or per job (default: auto) */
    int jobs;                  /* parallel jobs (0: the cores) */
    int memory_mb;             /* memory budget of the running jobs (0: half the RAM) */
    double probe_azimuth_deg;  /* where the probe camera looks in the set (unwrap, */
    double probe_elevation_deg;/* calibrate's grey view); default 0, 0 */
    double probe_sensor_mm;    /* probe camera's sensor width (0: the capture's, else none) */
    bool progress;             /* a progress line on stderr (when it is a terminal) */
} sl_pipeline_options;

void sl_pipeline_options_init(sl_pipeline_options *o);

typedef struct sl_pipeline_result {
    int setups, setups_failed;
    int jobs, jobs_run, jobs_skipped, jobs_failed;
    bool input_failures_only;  /* every failure was bad input (exit 3, else 1) */
    double seconds;
    /* The run's cost (its "run" object in --json; docs/process.md), over the
     * jobs run this time, from their stamps: */
    int slots;                 /* jobs at once: --jobs or the cores (local), 0 (slurm) */
    double cpu_seconds;        /* the commands' CPU time */
    double cpu_wait_seconds;   /* the jobs' wait for a CPU (others' load): commands and
                                  `setlight job` */
    double job_process_cpu_seconds; /* local: every job process, `setlight job` included */
    double runner_cpu_seconds; /* this process: planning, ingest, up-to-date checks */
    double runner_cpu_wait_seconds; /* and its wait for a CPU */
    double peak_memory_mb;     /* max over time of the running jobs' peak RSS (command +
                                  `setlight job`) summed, plus this process's */
    char *json;                /* the --json result (free()) */
    char *failures;            /* one "SETUP: reason" line per failed setup (free()) */
} sl_pipeline_result;

/* Plans every setup, writes OUT/jobs.json (or options->emit_jobs), then runs
 * the graph. A setup that fails (bad session, missing or corrupt frame, a
 * failed job) is reported (sl_log error naming it, the index, the result)
 * and the others go on: SL_OK is returned with setups_failed > 0.
 * SL_ERR_USAGE for two setups of one name or an OUT that is not a folder
 * (nothing written then). */
sl_result sl_pipeline_process(const sl_pipeline_options *o, sl_pipeline_result *res,
                              sl_error *err);
void sl_pipeline_result_free(sl_pipeline_result *res);

/* Runs one job of an emitted graph: nothing when its stamp is up to date,
 * else its command (stdout to its *.result.json output, stderr to its log),
 * then its stamp. *exit_code is the command's exit status (0 when skipped);
 * SL_OK also when the command failed (a failed stamp is written). */
sl_result sl_pipeline_job_run(const char *jobs_json, const char *id, int *exit_code,
                              bool *skipped, sl_error *err);

/* Jobs ids[0..count) of the graph in turn in one process (what a grouped
 * setup's Slurm job runs, docs/slurm.md: one start-up for the setup), each
 * as sl_pipeline_job_run and only when the jobs of ids it depends on
 * succeeded. codes[i]: its exit code (0 also when up to date); -1 when not
 * run (a dependency failed or was not run); when it could not run, the exit
 * code of its error, errs[i] (else cleared). */
void sl_pipeline_jobs_run(const char *jobs_json, char *const *ids, int count, int *codes,
                          sl_error *errs);

/* sl_pipeline_jobs_share's code of a job another process took. */
#define SL_PIPELINE_JOB_ELSEWHERE (-2)

/* Jobs ids[0..count) of the graph (a grouped setup's, docs/slurm.md) shared
 * with the other processes given the same claims_dir (an existing folder,
 * one per run and group): each job is run once, by the process that takes
 * it (an O_CREAT|O_EXCL claim file in claims_dir), as sl_pipeline_job_run
 * would; a process takes, in the list's order, any job nobody has taken
 * whose dependencies among ids succeeded, marks one whose dependency failed
 * (or whose claimant is gone without ending it) not run, waits without busy
 * polling while the jobs left wait for jobs run elsewhere, and returns once
 * every job is taken. codes[i] and errs[i] as sl_pipeline_jobs_run's for the
 * jobs this process took; SL_PIPELINE_JOB_ELSEWHERE for the others. */
void sl_pipeline_jobs_share(const char *jobs_json, const char *claims_dir, char *const *ids,
                            int count, int *codes, sl_error *errs);

/* A job graph read back ("setlight-jobs" version 1, docs/process.md): what
 * `setlight job`, the report and the index act on, checked whole first. */
typedef struct sl_pipeline_graph sl_pipeline_graph;

/* The caps of a graph, checked where it is parsed: the jobs (256 setups of
 * 64 views make about 19 500), the entries of one job's argv, command,
 * inputs, outputs or deps, and the bytes of an id. */
#define SL_PIPELINE_MAX_JOBS 32768
#define SL_PIPELINE_MAX_LIST 4096
#define SL_PIPELINE_MAX_ID 511

/* Parses and checks a job graph held in memory (`size` bytes of `text`,
 * no NUL needed); `name` (its file) starts every message. Reads and writes
 * no file and runs nothing. SL_ERR_INPUT with one line "NAME: problem" or
 * "NAME: job 'ID': problem" for: more than SL_MAX_JSON_BYTES, JSON that does
 * not parse or repeats a key, another format or version, "out" not an
 * absolute path, more than SL_PIPELINE_MAX_JOBS jobs; a job whose id is
 * missing, repeated or not a safe relative path, whose stage is unknown,
 * whose argv or command is not a non-empty list of strings, whose inputs,
 * outputs or log are not absolute paths, whose lists hold more than
 * SL_PIPELINE_MAX_LIST entries, whose memory_mb, cpus, up_to_date, setup,
 * array or key have the wrong type; a dependency that is not a job of the
 * graph, on itself, or on a cycle (named). *graph is the caller's to free. */
sl_result sl_pipeline_graph_parse(const char *name, const char *text, size_t size,
                                  sl_pipeline_graph **graph, sl_error *err);
int sl_pipeline_graph_job_count(const sl_pipeline_graph *graph);
/* The k-th job's id in an order where every job comes after its
 * dependencies (Kahn's: the jobs with none first, in the file's order, then
 * each as its last dependency is placed); NULL out of range. */
const char *sl_pipeline_graph_job_id(const sl_pipeline_graph *graph, int k);
void sl_pipeline_graph_free(sl_pipeline_graph *graph);

/* The report job: OUT/SETUP/report.html and report.json from the setup's
 * job results. */
sl_result sl_pipeline_report_setup(const char *jobs_json, const char *setup, sl_error *err);
/* The index job: OUT/index.html and index.json, every setup with its
 * thumbnail, key numbers, warnings, cost, or the reason it failed. */
sl_result sl_pipeline_report_index(const char *jobs_json, sl_error *err);

/* Compares two lat-longs within band_deg of the horizon (the reference
 * resampled to the test's size), texel by texel over texels where the
 * reference is positive: the median luminance ratio s = test/ref, the
 * median relative luminance error |test - ref| / ref, and the same after
 * the test is divided by s (what is left once the exposure is matched).
 * The report's unwrap cross-check; the tests' score against a virtual
 * set's truth. */
sl_result sl_pipeline_latlong_compare(const char *test_path, const char *ref_path,
                                      double band_deg, double *median_ratio,
                                      double *median_rel_error, double *median_rel_error_scaled,
                                      sl_error *err);

#ifdef __cplusplus
}
#endif

#endif /* SETLIGHT_PIPELINE_H */
