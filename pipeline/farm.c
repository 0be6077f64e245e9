/* SPDX-License-Identifier: BSD-3-Clause */
/* How a day's graph goes onto Slurm (docs/slurm.md): per setup, its jobs
 * one Slurm job each, or the whole setup as one Slurm job ("grouped"),
 * chosen from the graph's CPU estimates against Slurm's cost of a job; the
 * grouped setups' scripts; and their jobs' statuses read back from their
 * stamps. */
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "pipeline_private.h"

/* Whether job id's stamp says it ran to the end with its current key. */
bool pl_job_stamp_ok(const json_t *graph, const char *id)
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

/* Slurm's cost of a job, measured on the test cluster (docs/slurm.md, "What
 * the farm costs"): the slot a job frees idles until the controller's next
 * scheduling pass, about 0.5 s on average; a job waiting for another starts
 * about 0.9 s after it ended. No setting of Slurm 22.05 makes these shorter.
 * Grouped, a setup pays one pass; "auto" groups a setup when its jobs one by
 * one would cost more than FARM_GROUP_SHARE of their estimated CPU time. */
#define FARM_JOB_SECONDS 0.5
#define FARM_DEP_JOB_SECONDS 0.9
#define FARM_GROUP_SHARE 0.02

json_t *pl_farm_choices(const json_t *graph, sl_farm_group mode)
{
    json_t *choices = json_object(), *submit = json_object();
    size_t i;
    json_t *job;
    /* In the graph's order (dependencies first): what the Slurm runner
     * submits, the jobs not up to date and every job after one of them. */
    json_array_foreach(json_object_get(graph, "jobs"), i, job) {
        const char *setup = json_string_value(json_object_get(job, "setup"));
        const char *id = json_string_value(json_object_get(job, "id"));
        if (!setup)
            continue; /* the index runs on the submitting machine */
        bool run = !json_is_true(json_object_get(job, "up_to_date")), after_run = false;
        size_t d;
        json_t *dep;
        json_array_foreach(json_object_get(job, "deps"), d, dep)
            after_run |= json_is_true(json_object_get(submit, json_string_value(dep)));
        json_object_set_new(submit, id, json_boolean(run || after_run));
        json_t *c = json_object_get(choices, setup);
        if (!c) {
            c = json_pack("{s:s,s:i,s:f,s:f}", "group", "none", "jobs", 0, "cpu_seconds", 0.0,
                          "slurm_seconds", 0.0);
            json_object_set_new(choices, setup, c);
        }
        if (!(run || after_run))
            continue;
        json_object_set_new(c, "jobs", json_integer(json_integer_value(json_object_get(c, "jobs")) + 1));
        json_object_set_new(c, "cpu_seconds",
                            json_real(json_number_value(json_object_get(c, "cpu_seconds")) +
                                      json_number_value(json_object_get(job, "cpu_seconds"))));
        json_object_set_new(c, "slurm_seconds",
                            json_real(json_number_value(json_object_get(c, "slurm_seconds")) +
                                      (after_run ? FARM_DEP_JOB_SECONDS : FARM_JOB_SECONDS)));
    }
    json_decref(submit);
    const char *setup;
    json_t *c;
    json_object_foreach(choices, setup, c) {
        json_int_t n = json_integer_value(json_object_get(c, "jobs"));
        double cpu = json_number_value(json_object_get(c, "cpu_seconds"));
        double slurm = json_number_value(json_object_get(c, "slurm_seconds"));
        /* No estimate (a graph from elsewhere): short as far as is known. */
        double share = cpu > 0 ? slurm / cpu : INFINITY;
        bool grouped = mode == SL_FARM_GROUP_SETUP ||
                       (mode == SL_FARM_GROUP_AUTO && share > FARM_GROUP_SHARE);
        char why[400];
        if (n == 0) {
            snprintf(why, sizeof why, "up to date: nothing to submit");
        } else {
            char cost[300];
            int len = snprintf(cost, sizeof cost, "%lld jobs of ~%.2g s each, Slurm costs ~%.1f s a job "
                               "(%.1f s after a dependency): %.1f s",
                               (long long)n, cpu / (double)n, FARM_JOB_SECONDS,
                               FARM_DEP_JOB_SECONDS, slurm);
            if (cpu > 0)
                snprintf(cost + len, sizeof cost - (size_t)len, ", %.0f%% of their %.1f s",
                         100 * share, cpu);
            snprintf(why, sizeof why, "%s: %s%s", grouped ? "grouped" : "job by job", cost,
                     mode == SL_FARM_GROUP_AUTO ? (grouped ? " (grouped above 2%)"
                                                           : " (at most 2%: not grouped)")
                     : mode == SL_FARM_GROUP_SETUP ? " (--farm-group setup)"
                                                   : " (--farm-group job)");
        }
        json_object_set_new(c, "group", json_string(n == 0 ? "none" : grouped ? "setup" : "job"));
        json_object_set_new(c, "cpu_seconds", json_real(round(cpu * 100) / 100));
        json_object_set_new(c, "slurm_seconds", json_real(round(slurm * 10) / 10));
        json_object_set_new(c, "overhead_share",
                            cpu > 0 ? json_real(round(share * 1e4) / 1e4) : json_null());
        json_object_set_new(c, "reason", json_string(why));
    }
    return choices;
}

static bool is_grouped(const json_t *choices, const char *setup)
{
    const char *g = json_string_value(json_object_get(json_object_get(choices, setup), "group"));
    return g && !strcmp(g, "setup");
}

/* s as one shell word: single-quoted, ' as '\''. */
static void put_quoted(FILE *f, const char *s)
{
    fputc('\'', f);
    for (; *s; s++)
        if (*s == '\'')
            fputs("'\\''", f);
        else
            fputc(*s, f);
    fputc('\'', f);
}

/* A grouped setup's script, dir/K.sh: its jobs in the graph's order, in one
 * `setlight job --claims DIR/claims/K JOBS.json ID...` (one start-up for the
 * setup), shared with any Slurm job that runs the script to help it
 * (sl_pipeline_jobs_share: each job run once, each only when the jobs it
 * depends on succeeded; exit 1 when one it took failed or did not run). Its
 * first argument: what the Slurm job's log says before the setup's name
 * ("" for the job that took the setup, "helping " for a helper). NULL when
 * out of memory. */
static char *setup_script(const char *name, const char *dir, size_t k, const json_t *members)
{
    char *script = NULL;
    size_t len = 0, i;
    FILE *f = open_memstream(&script, &len);
    if (!f)
        return NULL;
    fputs("echo \"setlight: ${1}setup \"", f);
    put_quoted(f, name);
    fputc('\n', f);
    json_t *m;
    json_array_foreach(members, i, m) {
        json_t *argv = json_object_get(m, "argv"); /* EXE job JOBS.json ID */
        for (size_t a = i ? 3 : 0; a < 4; a++) {
            const char *word = json_string_value(json_array_get(argv, a));
            put_quoted(f, word ? word : "");
            fputc(a == 3 && i + 1 == json_array_size(members) ? '\n' : ' ', f);
            if (i == 0 && a == 1) {
                char claims[PATH_MAX + 330];
                snprintf(claims, sizeof claims, "%s/claims/%zu", dir, k);
                fputs("--claims ", f);
                put_quoted(f, claims);
                fputc(' ', f);
            }
        }
    }
    fclose(f);
    return script;
}

/* What the Slurm job of setup `own` runs: that setup, then each of `all`
 * (" 0 3 4": the setups submitted) that no job has taken yet. Then every
 * setup is taken, and the Slurm jobs of this run still pending (by their
 * names, `names`, and working folder, `out`) would only start to find theirs
 * taken, a scheduling pass each, ahead of the day's index: the first job to
 * get here cancels them (where the node has squeue and scancel; else they
 * start and end at once). Then, rather than leave its CPU idle while
 * another Slurm job runs the day's last setup (the day's tail), it helps
 * each setup that still has jobs nobody took (claims/K/all absent): it runs
 * the setup's script, which takes the jobs that are ready and ends when
 * every job is taken. Each says it ended with a file in dir
 * (ended.SLURM_JOB_ID), which wakes the runner's wait for its squeue. */
static char *runner_script(const char *dir, size_t own, const char *all, const char *names,
                           const char *out)
{
    char *script = NULL;
    size_t len = 0;
    FILE *f = open_memstream(&script, &len);
    if (!f)
        return NULL;
    fputs("d=", f);
    put_quoted(f, dir);
    fprintf(f, "\nf=0\nrun() { mkdir \"$d/claims/$1\" 2>/dev/null || return 0; "
               "/bin/sh \"$d/$1.sh\" || f=1; }\nrun %zu\nfor k in%s; do run \"$k\"; done\n",
            own, all);
    fputs("o=", f);
    put_quoted(f, out);
    fputs(" n=", f);
    put_quoted(f, names);
    fputs("\nif mkdir \"$d/claims/cancel\" 2>/dev/null && command -v squeue >/dev/null &&\n"
          "  command -v scancel >/dev/null; then\n"
          "  ids=$(squeue -h -t PD -u \"$(id -un)\" -n \"$n\" -o '%i|%Z' 2>/dev/null |"
          " o=\"$o\" awk -F'|' '$2 == ENVIRON[\"o\"] { print $1 }')\n"
          "  [ -z \"$ids\" ] || scancel $ids 2>/dev/null\nfi\n",
          f);
    fprintf(f, "for k in%s; do [ -e \"$d/claims/$k/all\" ] || /bin/sh \"$d/$k.sh\" 'helping ' || f=1; "
               "done\n",
            all);
    fputs(": >\"$d/ended.${SLURM_JOB_ID:-$$}\" 2>/dev/null\nexit $f\n", f);
    fclose(f);
    return script;
}

/* Reorders groups, and their places in list, longest first: the Slurm jobs
 * are submitted, and take the grouped setups, in this order, so the day
 * ends on its shortest setups (the CPU that finishes first waits for the
 * other's last setup). Left as they are when out of memory. */
static void longest_first(json_t *groups, json_t *list)
{
    size_t n = json_array_size(groups), k, i, next = 0;
    pl_ranked *r = calloc(n + 1, sizeof *r);
    json_t *sorted = json_array();
    if (!r || !sorted) {
        free(r);
        json_decref(sorted);
        return;
    }
    json_t *g;
    json_array_foreach(groups, k, g)
        r[k] = (pl_ranked){json_number_value(json_object_get(g, "cpu_seconds")), k};
    qsort(r, n, sizeof *r, pl_cmp_ranked); /* the most estimated CPU first */
    for (k = 0; k < n; k++)
        json_array_append(sorted, json_array_get(groups, r[k].at));
    free(r);
    json_array_foreach(list, i, g)
        if (json_object_get(g, "members") && next < n)
            json_array_set(list, i, json_array_get(sorted, next++));
    json_array_clear(groups);
    json_array_extend(groups, sorted);
    json_decref(sorted);
}

/* The grouped setups (choices, pl_farm_choices): one Slurm job per setup,
 * its jobs one at a time (setup_script, in dir/K.sh). Slurm's latency is
 * paid once per setup, not once per job. And a CPU does not wait for
 * Slurm's next pass while grouped setups are left: the Slurm job of setup K
 * runs its own setup, then any grouped setup no job has taken yet (taken by
 * mkdir dir/claims/K, atomic, on a shared file system too); a job whose
 * setup was taken ends at once, and one that finds every setup taken
 * cancels the ones still pending. So those jobs ask for the largest memory
 * of the grouped jobs. The grouped setups go longest first (longest_first).
 * A setup whose jobs are all up to date is not submitted.
 * The other setups' jobs stay as they are; each group takes the place of
 * its setup's first job in farm's "jobs" (the graph's jobs less the index). */
sl_result pl_farm_group(json_t *farm, const json_t *choices, const char *out, const char *dir,
                        sl_error *err)
{
    json_t *jobs = json_object_get(farm, "jobs"), *groups = json_array(), *list = json_array();
    size_t i, k;
    json_t *job, *g;
    json_int_t group_mb = 1;
    json_array_foreach(jobs, i, job) {
        const char *setup = json_string_value(json_object_get(job, "setup"));
        if (!setup || !is_grouped(choices, setup)) {
            json_array_append(list, job);
            continue;
        }
        json_t *found = NULL;
        json_array_foreach(groups, k, g)
            if (!strcmp(json_string_value(json_object_get(g, "id")), setup))
                found = g;
        if (!found) {
            char log[PATH_MAX + 300];
            snprintf(log, sizeof log, "%s/logs/%s.slurm.log", out, setup);
            found = json_pack("{s:s,s:s,s:s,s:[],s:[],s:[],s:[],s:[],s:n,s:i,s:i,s:f,s:s,s:n,s:b,"
                              "s:[]}",
                              "id", setup, "setup", setup, "stage", "setup", "argv", "command",
                              "inputs", "outputs", "deps", "array", "memory_mb", 1, "cpus", 1,
                              "cpu_seconds", 0.0, "log", log, "key", "up_to_date", 1, "members");
            json_array_append_new(groups, found);
            json_array_append(list, found);
        }
        json_array_append(json_object_get(found, "members"), job);
        double cpu = json_number_value(json_object_get(found, "cpu_seconds")) +
                     json_number_value(json_object_get(job, "cpu_seconds"));
        json_object_set_new(found, "cpu_seconds", json_real(round(cpu * 100) / 100));
        json_int_t mb = json_integer_value(json_object_get(job, "memory_mb"));
        group_mb = mb > group_mb ? mb : group_mb;
        if (!json_is_true(json_object_get(job, "up_to_date")))
            json_object_set_new(found, "up_to_date", json_false());
    }
    longest_first(groups, list);
    char claims[PATH_MAX + 300];
    snprintf(claims, sizeof claims, "%s/claims", dir);
    sl_result r = json_array_size(groups) ? pl_mkdirs(claims, err) : SL_OK;
    sl_text all = {0}, names = {0};
    json_array_foreach(groups, k, g) {
        if (r)
            break;
        if (!json_is_true(json_object_get(g, "up_to_date"))) {
            sl_text_printf(&all, " %zu", k);
            sl_text_printf(&names, "%s%s", names.len ? "," : "",
                           json_string_value(json_object_get(g, "id")));
        }
        char *script = setup_script(json_string_value(json_object_get(g, "id")), dir, k,
                                    json_object_get(g, "members"));
        char path[PATH_MAX + 300];
        snprintf(path, sizeof path, "%s/%zu.sh", dir, k);
        r = script ? sl_write_file_atomic(path, script, strlen(script), err)
                   : sl_error_set(err, SL_ERR_NOMEM, "out of memory");
        free(script);
        json_object_del(g, "members");
        json_object_set_new(g, "memory_mb", json_integer(group_mb));
    }
    json_array_foreach(groups, k, g) {
        char *script = r || all.failed || names.failed
                           ? NULL
                           : runner_script(dir, k, all.s ? all.s : "", names.s ? names.s : "", out);
        if (!r && !script)
            r = sl_error_set(err, SL_ERR_NOMEM, "out of memory");
        if (r)
            break;
        json_array_append_new(json_object_get(g, "argv"), json_string("/bin/sh"));
        json_array_append_new(json_object_get(g, "argv"), json_string("-c"));
        json_array_append_new(json_object_get(g, "argv"), json_string(script));
        json_object_set(g, "command", json_object_get(g, "argv"));
        free(script);
    }
    sl_text_free(&all);
    sl_text_free(&names);
    json_decref(groups);
    if (r) {
        json_decref(list);
        return r;
    }
    json_object_set_new(farm, "jobs", list);
    return SL_OK;
}

bool pl_farm_group_statuses(const json_t *graph, const char *setup, bool submitted, double t0,
                            json_t *status)
{
    size_t i;
    json_t *job;
    bool failed = false;
    json_t *first_not_run = NULL;
    json_array_foreach(json_object_get(graph, "jobs"), i, job) {
        const char *own = json_string_value(json_object_get(job, "setup"));
        if (!own || strcmp(own, setup))
            continue;
        const char *id = json_string_value(json_object_get(job, "id"));
        json_t *stamp = pl_stamp_load(graph, job);
        const char *st = json_string_value(json_object_get(stamp, "status"));
        bool fresh = st && json_number_value(json_object_get(stamp, "started")) >= t0;
        const char *state = !submitted                   ? "skipped"
                            : fresh && !strcmp(st, "ok") ? "ran"
                            : fresh                      ? "failed"
                            : pl_job_stamp_ok(graph, id) ? "skipped"
                                                         : "not run";
        json_decref(stamp);
        /* Up to date from before, but after a job that failed: the script
         * did not run it (the local runner's "not run"). */
        size_t d;
        json_t *dep;
        json_array_foreach(json_object_get(job, "deps"), d, dep) {
            const char *ds = json_string_value(json_object_get(status, json_string_value(dep)));
            if (ds && (!strcmp(ds, "failed") || !strcmp(ds, "not run")))
                state = "not run";
        }
        failed |= !strcmp(state, "failed");
        if (!first_not_run && !strcmp(state, "not run"))
            first_not_run = job;
        json_object_set_new(status, id, json_string(state));
    }
    /* Not all run, none failed: the Slurm job that ran the setup (its own
     * or one that took it) was killed. */
    if (submitted && !failed && first_not_run) {
        json_object_set_new(status, json_string_value(json_object_get(first_not_run, "id")),
                            json_string("failed"));
        return true;
    }
    return false;
}
