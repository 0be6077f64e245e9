/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight process: plan the day, write its graph, run it, sum it up. */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

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

/* Whether job id's stamp says it ran to the end with its current key. */
static bool stamp_ok(const json_t *graph, const char *id)
{
    size_t i;
    json_t *job;
    json_array_foreach(json_object_get(graph, "jobs"), i, job) {
        if (strcmp(json_string_value(json_object_get(job, "id")), id))
            continue;
        char key[65];
        return pl_job_key(job, key) && pl_stamp_current(graph, job, key);
    }
    return false;
}

/* The graph through Slurm, all but the day's index: the index follows
 * every other job whatever its end (an afterok dependency would cancel it
 * with the first failure), so it runs here once Slurm is done. The jobs
 * Slurm runs are the same `setlight job JOBS.json ID` the local runner
 * starts, so they skip themselves when up to date and stamp what they ran. */
static sl_result run_slurm(const sl_pipeline_options *o, const json_t *graph,
                           const char *jobs_path, json_t *status, sl_pipeline_result *res,
                           sl_error *err)
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
    char farm_path[PATH_MAX + 32];
    snprintf(farm_path, sizeof farm_path, "%s.slurm.json", jobs_path);
    sl_pipeline_slurm_options so;
    sl_pipeline_slurm_options_init(&so);
    sl_pipeline_slurm_result sr;
    memset(&sr, 0, sizeof sr);
    sl_result r = pl_json_write(farm_path, farm, err);
    if (!r)
        r = sl_pipeline_slurm_run(farm_path, &so, &sr, err);
    for (int i = 0; !r && i < sr.job_count; i++) {
        const sl_pipeline_slurm_job *j = &sr.jobs[i];
        /* The local runner's words: a job Slurm ran may still have skipped
         * itself, which its stamp does not tell apart from a run. */
        const char *state = j->end == SL_SLURM_SKIPPED     ? "skipped"
                            : j->end == SL_SLURM_COMPLETED ? "ran"
                            : j->end == SL_SLURM_CANCELLED ? "not run"
                                                           : "failed";
        if (j->end == SL_SLURM_LOST && stamp_ok(graph, j->id))
            state = "ran"; /* purged from squeue before it was seen ending */
        json_object_set_new(status, j->id, json_string(state));
        res->jobs_run += j->end == SL_SLURM_COMPLETED || j->end == SL_SLURM_FAILED ||
                         j->end == SL_SLURM_LOST;
        res->jobs_skipped += j->end == SL_SLURM_SKIPPED;
        res->jobs_failed += j->end == SL_SLURM_FAILED || j->end == SL_SLURM_LOST;
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
    sl_result r = pl_plan(o, jobs_path, sizeof jobs_path, &graph, &setups, err);
    if (r)
        return r;
    snprintf(out_abs, sizeof out_abs, "%s", json_string_value(json_object_get(graph, "out")));
    if ((r = pl_json_write(jobs_path, graph, err)))
        goto done;
    json_t *status = json_object();
    if (!o->emit_jobs && o->farm == SL_FARM_SLURM)
        r = run_slurm(o, graph, jobs_path, status, res, err);
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
    res->json = json_dumps(doc, JSON_INDENT(2) | JSON_PRESERVE_ORDER);
    json_decref(doc);
    json_decref(status);
done:
    json_decref(graph);
    json_decref(setups);
    return r;
}
