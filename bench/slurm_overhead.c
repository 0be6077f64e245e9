/* SPDX-License-Identifier: BSD-3-Clause */
/* Slurm's cost per job as sl_pipeline_slurm_run sees it, on the cluster
 * SLURM_CONF names (bench/slurm_overhead.sh starts one): N jobs of
 * `sleep SECONDS` submitted three ways (independent jobs, one array, a
 * dependency chain), each run's wall time against the ideal on CPUS cores.
 *
 *   bench_slurm_overhead N SECONDS CPUS DIR
 *
 * One line per shape; docs/slurm.md quotes them. Or, to run a job graph:
 *
 *   bench_slurm_overhead --run JOBS.json    (the result as JSON on stdout)
 */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "slurm.h"

static int write_graph(const char *path, const char *dir, int n, double seconds, int shape)
{
    FILE *f = fopen(path, "w");
    if (!f)
        return -1;
    fprintf(f, "{\"format\":\"setlight-jobs\",\"version\":1,\"setlight\":\"bench\",\"out\":\"%s\","
               "\"jobs\":[", dir);
    for (int i = 0; i < n; i++) {
        char deps[64] = "";
        if (shape == 2 && i > 0)
            snprintf(deps, sizeof deps, "\"j%d\"", i - 1);
        fprintf(f,
                "%s{\"id\":\"j%d\",\"setup\":null,\"stage\":\"merge\",\"command\":[\"sleep\"],"
                "\"inputs\":[],\"outputs\":[],\"key\":null,\"argv\":[\"sleep\",\"%g\"],\"deps\":[%s],\"array\":%s,"
                "\"memory_mb\":16,\"cpus\":1,\"log\":\"%s/logs/j%d.log\",\"up_to_date\":false}",
                i ? "," : "", i, seconds, deps, shape == 1 ? "\"all\"" : "null", dir, i);
    }
    fprintf(f, "]}\n");
    return fclose(f);
}

int main(int argc, char **argv)
{
    sl_pipeline_slurm_options o;
    sl_pipeline_slurm_options_init(&o);
    o.poll_seconds = 0.1;
    o.poll_max_seconds = 0.1; /* Slurm's latency, not the poll's */
    sl_pipeline_slurm_result res;
    sl_error err = {0};
    if (argc == 3 && strcmp(argv[1], "--run") == 0) {
        sl_result r = sl_pipeline_slurm_run(argv[2], &o, &res, &err);
        json_t *j = sl_pipeline_slurm_result_json(&res);
        if (j)
            json_dumpf(j, stdout, JSON_INDENT(1));
        printf("\n");
        json_decref(j);
        sl_pipeline_slurm_result_free(&res);
        if (r != SL_OK)
            fprintf(stderr, "bench_slurm_overhead: %s\n", err.message);
        return r == SL_OK ? 0 : sl_result_exit_code(r);
    }
    if (argc != 5) {
        fprintf(stderr, "usage: bench_slurm_overhead N SECONDS CPUS DIR | --run JOBS.json\n");
        return 2;
    }
    int n = atoi(argv[1]), cpus = atoi(argv[3]);
    double seconds = atof(argv[2]);
    const char *dir = argv[4];
    if (n < 1 || cpus < 1 || !(seconds >= 0)) {
        fprintf(stderr, "bench_slurm_overhead: bad N, SECONDS or CPUS\n");
        return 2;
    }
    mkdir(dir, 0777);
    static const char *const shapes[] = {"independent", "array", "chain"};
    for (int shape = 0; shape < 3; shape++) {
        char path[4200];
        snprintf(path, sizeof path, "%s/%s.json", dir, shapes[shape]);
        if (write_graph(path, dir, n, seconds, shape) != 0) {
            fprintf(stderr, "bench_slurm_overhead: cannot write %s\n", path);
            return 1;
        }
        sl_result r = sl_pipeline_slurm_run(path, &o, &res, &err);
        if (r != SL_OK || res.completed != n) {
            fprintf(stderr, "bench_slurm_overhead: %s: %s (%d of %d completed)\n", shapes[shape],
                    r != SL_OK ? err.message : "jobs failed", res.completed, n);
            sl_pipeline_slurm_result_free(&res);
            return 1;
        }
        double ideal = shape == 2 ? n * seconds : ceil((double)n / cpus) * seconds;
        printf("%-11s %3d jobs of %.2f s: wall %6.2f s (ideal %6.2f), %d sbatch in %.3f s, "
               "overhead %.3f s per job\n",
               shapes[shape], n, seconds, res.wall_seconds, ideal, res.sbatch_calls,
               res.submit_seconds, (res.wall_seconds - ideal) / n);
        sl_pipeline_slurm_result_free(&res);
    }
    return 0;
}
