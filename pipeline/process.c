/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight process: plan the day, write its graph, run it, sum it up. */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline_private.h"
#include "report_private.h"

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

sl_result sl_pipeline_process(const sl_pipeline_options *o, sl_pipeline_result *res,
                              sl_error *err)
{
    memset(res, 0, sizeof *res);
    res->input_failures_only = true;
    double t0 = sl_seconds();
    if (o->farm == SL_FARM_SLURM && !o->emit_jobs)
        /* pipeline/slurm.c (sl_pipeline_slurm_run) joins here when it lands. */
        return sl_error_set(err, SL_ERR_UNSUPPORTED,
                            "--farm slurm: the Slurm runner is not built yet (use --emit-jobs)");
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
    if (!o->emit_jobs)
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
