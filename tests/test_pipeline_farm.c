/* SPDX-License-Identifier: BSD-3-Clause */
/* pipeline: how a day goes onto Slurm (pipeline/farm.c). Per setup, from
 * the graph's CPU estimates (cpu_seconds) of the jobs the runner would
 * submit, against Slurm's 0.5 s a job (0.9 s after a dependency): "auto"
 * groups a setup when its jobs one by one would cost over 2% of that
 * estimate, and leaves it job by job otherwise; "setup" and "job" decide
 * alone; a setup with nothing to submit is neither. Then the grouped
 * setups' jobs become one Slurm job each in the farm's graph, in their
 * setup's place, the others untouched, the longest grouped setup first. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../pipeline/pipeline_private.h"
#include "testing.h"

/* A setup as the planner builds it: 5 merges (no dependency), then 11 jobs
 * each after the one before (stitch ... report): 5 x 0.5 + 11 x 0.9 =
 * 12.4 s of Slurm one by one. Each job estimated cpu s, memory mb; the
 * first `fresh` jobs up to date (-1: none). */
static void add_setup(json_t *jobs, const char *setup, double cpu, int mb, int fresh)
{
    char prev[64] = "";
    for (int k = 0; k < 16; k++) {
        char id[64], log[128];
        snprintf(id, sizeof id, k < 5 ? "%s/merge/%d" : "%s/job/%d", setup, k);
        snprintf(log, sizeof log, "/d/logs/%s_%d.log", setup, k);
        json_t *deps = json_array();
        if (k == 5)
            for (int m = 0; m < 5; m++) {
                char dep[64];
                snprintf(dep, sizeof dep, "%s/merge/%d", setup, m);
                json_array_append_new(deps, json_string(dep));
            }
        else if (k > 5)
            json_array_append_new(deps, json_string(prev));
        json_t *job = json_pack("{s:s,s:s,s:s,s:[s,s,s,s],s:[s],s:[],s:[],s:o,s:n,s:i,s:i,s:s,"
                                "s:n,s:b}",
                                "id", id, "setup", setup, "stage", k < 5 ? "merge" : "render",
                                "argv", "/bin/setlight", "job", "/d/jobs.json", id, "command",
                                "/bin/true", "inputs", "outputs", "deps", deps, "array",
                                "memory_mb", mb, "cpus", 1, "log", log, "key", "up_to_date",
                                k < fresh);
        if (cpu >= 0)
            json_object_set_new(job, "cpu_seconds", json_real(cpu));
        json_array_append_new(jobs, job);
        snprintf(prev, sizeof prev, "%s", id);
    }
}

static json_t *day(json_t *jobs)
{
    json_array_append_new(jobs, json_pack("{s:s,s:n,s:s,s:[s],s:[s],s:[],s:[],s:[],s:n,s:i,s:i,"
                                          "s:s,s:n,s:b}",
                                          "id", "index", "setup", "stage", "index", "argv",
                                          "/bin/true", "command", "/bin/true", "inputs",
                                          "outputs", "deps", "array", "memory_mb", 1, "cpus", 1,
                                          "log", "/d/logs/index.log", "key", "up_to_date", 0));
    return json_pack("{s:s,s:i,s:s,s:s,s:o}", "format", "setlight-jobs", "version", 1,
                     "setlight", "test", "out", "/d", "jobs", jobs);
}

static const char *choice(const json_t *choices, const char *setup, const char *field)
{
    return json_string_value(json_object_get(json_object_get(choices, setup), field));
}

static double number(const json_t *choices, const char *setup, const char *field)
{
    return json_number_value(json_object_get(json_object_get(choices, setup), field));
}

/* The rule: 16 jobs cost Slurm 12.4 s one by one, 2% of 620 s. */
static void test_auto_threshold(void)
{
    json_t *jobs = json_array();
    add_setup(jobs, "short", 0.44, 160, -1);   /* the tiny size: 7 s */
    add_setup(jobs, "below", 600.0 / 16, 160, -1); /* 12.4 / 600 = 2.07% */
    add_setup(jobs, "above", 640.0 / 16, 160, -1); /* 12.4 / 640 = 1.94% */
    add_setup(jobs, "long", 60, 160, -1);
    json_t *graph = day(jobs), *c = pl_farm_choices(graph, SL_FARM_GROUP_AUTO);
    CHECK(json_object_size(c) == 4); /* the index is not the farm's */
    CHECK(!strcmp(choice(c, "short", "group"), "setup"));
    CHECK(!strcmp(choice(c, "below", "group"), "setup"));
    CHECK(!strcmp(choice(c, "above", "group"), "job"));
    CHECK(!strcmp(choice(c, "long", "group"), "job"));
    CHECK(json_integer_value(json_object_get(json_object_get(c, "short"), "jobs")) == 16);
    CHECK_NEAR(number(c, "short", "slurm_seconds"), 12.4, 1e-9);
    CHECK_NEAR(number(c, "short", "cpu_seconds"), 7.04, 1e-9);
    CHECK_NEAR(number(c, "short", "overhead_share"), 12.4 / 7.04, 1e-4);
    CHECK_NEAR(number(c, "long", "overhead_share"), 12.4 / 960, 1e-4);
    const char *why = choice(c, "short", "reason");
    CHECK_MSG(why && !strcmp(why, "grouped: 16 jobs of ~0.44 s each, Slurm costs ~0.5 s a job "
                                  "(0.9 s after a dependency): 12.4 s, 176% of their 7.0 s "
                                  "(grouped above 2%)"),
              "%s", why);
    why = choice(c, "long", "reason");
    CHECK_MSG(why && strstr(why, "job by job: 16 jobs of ~60 s each") == why &&
                  strstr(why, "1% of their 960.0 s (at most 2%: not grouped)"),
              "%s", why);
    json_decref(c);
    /* Explicit choices whatever the estimate. */
    c = pl_farm_choices(graph, SL_FARM_GROUP_SETUP);
    CHECK(!strcmp(choice(c, "long", "group"), "setup"));
    CHECK(strstr(choice(c, "long", "reason"), "(--farm-group setup)") != NULL);
    json_decref(c);
    c = pl_farm_choices(graph, SL_FARM_GROUP_JOB);
    CHECK(!strcmp(choice(c, "short", "group"), "job"));
    CHECK(strstr(choice(c, "short", "reason"), "(--farm-group job)") != NULL);
    json_decref(c);
    json_decref(graph);
}

/* Only what the runner would submit counts: on a rerun, the jobs not up to
 * date and those after them; a setup with none is not submitted at all. */
static void test_rerun_counts(void)
{
    json_t *jobs = json_array();
    add_setup(jobs, "tail", 60, 160, 14); /* job/14 and job/15 to run */
    add_setup(jobs, "done", 0.5, 160, 16);
    add_setup(jobs, "guess", -1, 160, -1); /* no estimates (another queue's graph) */
    json_t *graph = day(jobs), *c = pl_farm_choices(graph, SL_FARM_GROUP_AUTO);
    CHECK(json_integer_value(json_object_get(json_object_get(c, "tail"), "jobs")) == 2);
    /* job/14's dependency is up to date (not submitted): 0.5 s; job/15 0.9 s */
    CHECK_NEAR(number(c, "tail", "slurm_seconds"), 1.4, 1e-9);
    CHECK_NEAR(number(c, "tail", "cpu_seconds"), 120, 1e-9);
    CHECK(!strcmp(choice(c, "tail", "group"), "job")); /* 1.2% */
    CHECK(!strcmp(choice(c, "done", "group"), "none"));
    CHECK(!strcmp(choice(c, "done", "reason"), "up to date: nothing to submit"));
    CHECK(!strcmp(choice(c, "guess", "group"), "setup"));
    CHECK(json_is_null(json_object_get(json_object_get(c, "guess"), "overhead_share")));
    json_decref(c);
    json_decref(graph);
}

/* A day of one short and one long setup: the short one becomes one Slurm
 * job (its script in dir, memory the largest of the grouped jobs'), in its
 * place; the long one's jobs stay as they were. */
/* The day's graph as the Slurm runner sends it (the index left out: it runs
 * here), its grouped setups (choices c) grouped, scripts in the test's
 * folder `sub`, its path in dir. */
static json_t *grouped_farm(const json_t *graph, const json_t *c, const char *sub, char dir[1024])
{
    json_t *farm = json_deep_copy(graph), *jobs = json_object_get(farm, "jobs");
    json_array_remove(jobs, json_array_size(jobs) - 1);
    snprintf(dir, 1024, "%s/%s", sl_test_tmpdir(), sub);
    sl_error err = {0};
    CHECK_OK(pl_farm_group(farm, c, "/d", dir, &err), &err);
    return farm;
}

static void test_group_in_place(void)
{
    json_t *jobs = json_array();
    add_setup(jobs, "long", 60, 900, -1);
    add_setup(jobs, "short", 0.44, 160, -1);
    json_t *graph = day(jobs), *c = pl_farm_choices(graph, SL_FARM_GROUP_AUTO);
    char dir[1024];
    json_t *farm = grouped_farm(graph, c, "farm", dir);
    json_t *fj = json_object_get(farm, "jobs");
    CHECK(json_array_size(fj) == 17);
    for (size_t k = 0; k < 16 && k < json_array_size(fj); k++)
        CHECK(json_equal(json_array_get(fj, k), json_array_get(json_object_get(graph, "jobs"), k)));
    json_t *g = json_array_get(fj, 16);
    CHECK(!strcmp(json_string_value(json_object_get(g, "id")), "short"));
    CHECK(!strcmp(json_string_value(json_object_get(g, "stage")), "setup"));
    CHECK(json_integer_value(json_object_get(g, "memory_mb")) == 160);
    CHECK_NEAR(json_number_value(json_object_get(g, "cpu_seconds")), 7.04, 1e-9);
    CHECK(!strcmp(json_string_value(json_object_get(g, "log")), "/d/logs/short.slurm.log"));
    char script[1100];
    snprintf(script, sizeof script, "%s/0.sh", dir);
    char *text = sl_test_read_file(script, NULL);
    CHECK_MSG(text && strstr(text, "'short/job/15'") && !strstr(text, "long/"), "%s",
              text ? text : "(no script)");
    free(text);
    json_decref(farm);
    json_decref(c);
    json_decref(graph);
}

/* The grouped setups go longest first (estimated CPU): their Slurm jobs
 * submitted, and the setups taken, in that order, so the day ends on its
 * shortest; they take the grouped setups' places among the other jobs. Each
 * group's script runs its own setup, then the others in that order, then
 * cancels what is still pending of them, then helps each setup whose jobs
 * are not all taken. */
static void test_group_longest_first(void)
{
    /* Three short setups (grouped) round a long one (job by job). */
    const char *setups[] = {"a", "long", "b", "c"};
    const double cpu[] = {0.3, 60, 0.6, 0.44};
    json_t *jobs = json_array();
    for (int k = 0; k < 4; k++)
        add_setup(jobs, setups[k], cpu[k], k == 1 ? 900 : 100, -1);
    json_t *graph = day(jobs), *c = pl_farm_choices(graph, SL_FARM_GROUP_AUTO);
    char dir[1024];
    json_t *farm = grouped_farm(graph, c, "farm_order", dir);
    json_t *fj = json_object_get(farm, "jobs");
    CHECK(json_array_size(fj) == 19);
    const char *order[] = {"b", "c", "a"};
    size_t at[] = {0, 17, 18};
    for (int k = 0; k < 3; k++) {
        json_t *g = json_array_get(fj, at[k]);
        CHECK_MSG(!strcmp(json_string_value(json_object_get(g, "id")), order[k]),
                  "group %d is %s", k, json_string_value(json_object_get(g, "id")));
        char script[1100], own[64], run[32], claims[1200];
        snprintf(script, sizeof script, "%s/%d.sh", dir, k);
        char *text = sl_test_read_file(script, NULL);
        snprintf(own, sizeof own, "'%s/job/15'", order[k]);
        /* its jobs shared through the setup's claims folder */
        snprintf(claims, sizeof claims, "'job' --claims '%s/claims/%d' '/d/jobs.json'", dir, k);
        CHECK_MSG(text && strstr(text, own) && strstr(text, claims), "%s",
                  text ? text : "(no script)");
        free(text);
        const char *runner = json_string_value(json_array_get(json_object_get(g, "argv"), 2));
        snprintf(run, sizeof run, "\nrun %d\n", k);
        CHECK_MSG(runner && strstr(runner, run) && strstr(runner, "for k in 0 1 2;") &&
                      strstr(runner, "n='b,c,a'") && strstr(runner, "scancel") &&
                      strstr(runner, "for k in 0 1 2; do [ -e \"$d/claims/$k/all\" ] || "
                                     "/bin/sh \"$d/$k.sh\" 'helping '"),
                  "%s", runner ? runner : "(no runner)");
    }
    for (size_t k = 1; k < 17 && k < json_array_size(fj); k++)
        CHECK(json_equal(json_array_get(fj, k), json_array_get(json_object_get(graph, "jobs"), 15 + k)));
    json_decref(farm);
    json_decref(c);
    json_decref(graph);
}

int main(void)
{
    RUN(test_auto_threshold);
    RUN(test_rerun_counts);
    RUN(test_group_in_place);
    RUN(test_group_longest_first);
    return sl_test_finish();
}
