/* SPDX-License-Identifier: BSD-3-Clause */
/* The merge's timing by phase (sl_merge_timing): stretches of the command
 * charged to one phase, or split between phases by the CPU time their
 * tasks measured on their own threads. */
#include "merge_private.h"

const char *sl_merge_phase_name(sl_merge_phase phase)
{
    static const char *const names[SL_MERGE_PHASES] = {"decode", "sample", "fit",   "merge",
                                                      "write",  "align",  "other"};
    return phase >= 0 && phase < SL_MERGE_PHASES ? names[phase] : "?";
}

merge_clock merge_clock_start(void) { return (merge_clock){sl_seconds(), sl_cpu_seconds()}; }

merge_clock merge_clock_charge(sl_merge_timing *t, merge_clock since, sl_merge_phase phase)
{
    merge_clock now = merge_clock_start();
    t->wall[phase] += now.wall - since.wall;
    t->cpu[phase] += now.cpu - since.cpu;
    return now;
}

merge_clock merge_clock_split(sl_merge_timing *t, merge_clock since, double *task_cpu, int workers)
{
    merge_clock now = merge_clock_start();
    double wall = now.wall - since.wall, cpu = now.cpu - since.cpu, measured = 0;
    double task[SL_MERGE_PHASES] = {0};
    for (int w = 0; w < workers; w++)
        for (int p = 0; p < SL_MERGE_PHASES; p++) {
            task[p] += task_cpu[w * SL_MERGE_PHASES + p];
            task_cpu[w * SL_MERGE_PHASES + p] = 0;
        }
    for (int p = 0; p < SL_MERGE_PHASES; p++)
        measured += task[p];
    /* The clocks tick at different moments: never more than the stretch's CPU. */
    double scale = measured > cpu && measured > 0 ? cpu / measured : 1;
    for (int p = 0; p < SL_MERGE_PHASES; p++) {
        double c = task[p] * scale, w = cpu > 0 ? wall * c / cpu : 0;
        t->cpu[p] += c;
        t->wall[p] += w;
        wall -= w;
        cpu -= c;
    }
    t->cpu[SL_MERGE_OTHER] += cpu;
    t->wall[SL_MERGE_OTHER] += wall;
    return now;
}

void merge_clock_finish(sl_merge_result *res, merge_clock start)
{
    merge_clock now = merge_clock_start();
    sl_merge_timing *t = &res->timing;
    res->seconds = now.wall - start.wall;
    res->cpu_seconds = now.cpu - start.cpu;
    double wall = res->seconds, cpu = res->cpu_seconds;
    for (int p = 0; p < SL_MERGE_PHASES; p++)
        if (p != SL_MERGE_OTHER) {
            wall -= t->wall[p];
            cpu -= t->cpu[p];
        }
    t->wall[SL_MERGE_OTHER] = wall;
    t->cpu[SL_MERGE_OTHER] = cpu;
}
