/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight demo: the virtual stage simulated, processed as a shoot day's
 * setup, and every stage scored against its truth. */
#include <dirent.h>
#include <errno.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "cli.h"
#include "setlight/pipeline.h"
#include "setlight/vset.h"

static void help(FILE *out)
{
    fprintf(out,
            "usage: setlight demo [DIR] [--size tiny|small] [--seed N] [--force] [--check]\n"
            "                     [--json]\n\n"
            "Simulates the 'stage' virtual set into DIR/capture (no camera, no downloaded\n"
            "data), processes it as one setup of a shoot day ('setlight process', into\n"
            "DIR/process: merge, stitch, unwrap, calibrate, rig, validation renders) and\n"
            "scores every stage's output against the set's truth, which only the scoring\n"
            "reads. Writes DIR/report.html (the scores; the process's own report is\n"
            "DIR/process/capture/report.html) and DIR/score.json. DIR defaults to\n"
            "./setlight-demo.\n\n"
            "  --size S    small (default; 1024 lat-long, 720x480 frames) or tiny (256,\n"
            "              192x128)\n"
            "  --seed N    sensor-noise seed (default 1)\n"
            "  --force     replace an earlier demo in DIR (the process's jobs that are\n"
            "              still up to date are not redone)\n"
            "  --check     exit 1 when a stage is outside its tolerances\n"
            "  --json      print DIR/score.json: per stage its numbers against the truth,\n"
            "              its tolerances, pass or fail, wall and CPU seconds; the run's\n"
            "              cost and every process job's\n"
            "\nEach stage's verdict (pass or FAIL against its tolerance, docs/virtual-set.md)\n"
            "is in the summary, the report and --json. The calibrated map, its renders and\n"
            "its rig's light powers are scored against the truth with the chart's light made\n"
            "white, as the chart fit balances it.\n"
            "\nexit codes: 0 success (with --check: and every stage within its tolerances);\n"
            "1 runtime failure, or with --check a stage outside its tolerances (one line;\n"
            "the report and --json are still written); 2 usage error (DIR holds other files,\n"
            "or an earlier demo without --force); 3 invalid input data\n");
}

/* 0 absent or empty, 1 an earlier demo, 2 something else. */
static int dir_state(const char *dir)
{
    DIR *dp = opendir(dir);
    if (!dp)
        return 0;
    int files = 0;
    bool demo_page = false;
    struct dirent *e;
    while ((e = readdir(dp))) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
            continue;
        files++;
        if (!strcmp(e->d_name, "report.html") || !strcmp(e->d_name, "capture"))
            demo_page = true;
    }
    closedir(dp);
    return files == 0 ? 0 : demo_page ? 1 : 2;
}

int cmd_demo(int argc, char **argv, const sl_cli *cli)
{
    enum { O_SIZE = 256, O_SEED, O_FORCE, O_CHECK };
    static const struct option opts[] = {{"size", required_argument, 0, O_SIZE},
                                         {"check", no_argument, 0, O_CHECK},
                                         {"seed", required_argument, 0, O_SEED},
                                         {"force", no_argument, 0, O_FORCE},
                                         {"help", no_argument, 0, 'h'},
                                         {0, 0, 0, 0}};
    sl_vset_size size = SL_VSET_SIZE_SMALL;
    uint64_t seed = 1;
    bool force = false, check = false;
    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, ":h", opts, NULL)) != -1) {
        switch (c) {
        case 'h': help(stdout); return 0;
        case O_SIZE: {
            int s = sl_vset_size_from_name(optarg);
            if (s != SL_VSET_SIZE_TINY && s != SL_VSET_SIZE_SMALL)
                return cli_usage_error(cli, "--size is tiny or small, not '%s'", optarg);
            size = (sl_vset_size)s;
            break;
        }
        case O_SEED: {
            int v;
            if (!cli_parse_int(optarg, &v) || v < 0)
                return cli_usage_error(cli, "--seed needs a whole number >= 0, not '%s'", optarg);
            seed = (uint64_t)v;
            break;
        }
        case O_FORCE: force = true; break;
        case O_CHECK: check = true; break;
        case ':': return cli_usage_error(cli, "%s needs a value", argv[optind - 1]);
        default: return cli_usage_error(cli, "unknown option %s", argv[optind - 1]);
        }
    }
    if (argc - optind > 1)
        return cli_usage_error(cli, "unexpected argument '%s'", argv[optind + 1]);
    const char *dir = optind < argc ? argv[optind] : "setlight-demo";
    sl_error err;
    sl_error_clear(&err);
    int state = dir_state(dir);
    if (state == 2) {
        sl_error_set(&err, SL_ERR_USAGE, "%s: folder holds other files; choose another", dir);
        return cli_fail(cli, &err);
    }
    if (state == 1 && !force) {
        sl_error_set(&err, SL_ERR_USAGE, "%s: holds an earlier demo (use --force to replace it)",
                     dir);
        return cli_fail(cli, &err);
    }
    char exe[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n <= 0)
        return cli_usage_error(cli, "cannot find the setlight executable (/proc/self/exe)");
    exe[n] = 0;
    if (mkdir(dir, 0777) != 0 && errno != EEXIST) {
        sl_error_set(&err, SL_ERR_IO, "%s: cannot create folder: %s", dir, strerror(errno));
        return cli_fail(cli, &err);
    }
    char capture[PATH_MAX], out[PATH_MAX], jobs[PATH_MAX + 16], page[PATH_MAX + 32],
        json[PATH_MAX + 16];
    snprintf(capture, sizeof capture, "%s/capture", dir);
    snprintf(out, sizeof out, "%s/process", dir);
    snprintf(jobs, sizeof jobs, "%s/jobs.json", out);
    snprintf(page, sizeof page, "%s/capture/report.html", out);
    snprintf(json, sizeof json, "%s/score.json", dir);

    /* 1. the capture, as `setlight simulate --scene stage` writes it */
    sl_vset_desc desc;
    sl_result r = sl_vset_preset("stage", &desc, &err);
    if (r)
        return cli_fail(cli, &err);
    sl_vset_capture_opts co;
    sl_vset_capture_defaults(&co, &desc, size);
    co.seed = seed;
    co.force = force;
    sl_vset_capture_summary summary;
    double t0 = sl_seconds(), c0 = sl_cpu_seconds();
    if ((r = sl_vset_capture_write(&co, capture, &summary, &err)))
        return cli_fail(cli, &err);
    double sim_s = sl_seconds() - t0, sim_cpu = sl_cpu_seconds() - c0;

    /* 2. one setup of a shoot day, as `setlight process` runs it; the
     * virtual set's probe camera looks along -Z (azimuth 180) */
    const char *setups[1] = {capture};
    sl_pipeline_options po;
    sl_pipeline_options_init(&po);
    po.setups = setups;
    po.setup_count = 1;
    po.out = out;
    po.exe = exe;
    po.probe_azimuth_deg = 180;
    po.progress = !cli->quiet;
    sl_pipeline_result pr;
    if ((r = sl_pipeline_process(&po, &pr, &err))) {
        sl_pipeline_result_free(&pr);
        return cli_fail(cli, &err);
    }
    if (pr.setups_failed) {
        sl_error_set(&err, SL_ERR_INTERNAL, "%s: the process failed: %s", out,
                     pr.failures ? strtok(pr.failures, "\n") : "?");
        sl_pipeline_result_free(&pr);
        return cli_fail(cli, &err);
    }

    /* 3. every stage against the truth */
    sl_vset_score_options so;
    sl_vset_score_options_init(&so);
    so.capture = capture;
    so.jobs_json = jobs;
    so.setup = "capture";
    so.process_json = pr.json;
    so.process_report = page;
    so.report_dir = dir;
    so.json_path = json;
    so.simulate_seconds = sim_s;
    so.simulate_cpu_seconds = sim_cpu;
    so.seed = seed;
    sl_vset_score_result sr;
    r = sl_vset_score_setup(&so, &sr, &err);
    sl_pipeline_result_free(&pr);
    if (r)
        return cli_fail(cli, &err);
    if (cli->json)
        printf("%s\n", sr.json);
    else if (!cli->quiet)
        printf("%sreport: %s/report.html (the process's: %s)\n", sr.summary, dir, page);
    int rc = 0;
    if (sr.stages_failed && check) {
        sl_error_set(&err, SL_ERR_INTERNAL, "%s/report.html: %d of %d stages outside their "
                     "tolerances", dir, sr.stages_failed, sr.stages);
        rc = cli_fail(cli, &err);
    }
    sl_vset_score_result_free(&sr);
    return rc;
}
