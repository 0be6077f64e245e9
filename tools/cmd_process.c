/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight process SETUP... -o OUT, and the hidden commands its jobs run:
 * job (one job of a graph), process-report, process-index. */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "setlight/pipeline.h"

static const char process_help[] =
    "usage: setlight process [options] SETUP... -o OUT\n"
    "\n"
    "Processes a shoot day: each SETUP (a capture session folder with session.json,\n"
    "a folder 'setlight simulate' wrote, or a plain folder or card of frames, ingested\n"
    "first into OUT/SETUP/ingest) becomes a graph of jobs, each one setlight command:\n"
    "merge each view's bracket -> stitch -> unwrap the chrome ball (a cross-check) ->\n"
    "calibrate with the grey ball and chart -> rig -> validation renders (grey,\n"
    "chrome, chart under the HDRI and under the rig) -> the setup's report\n"
    "(OUT/SETUP/report.html); then the day's index, OUT/index.html. A job's key is\n"
    "the SHA-256 of its input files, its command line and the setlight version,\n"
    "stamped beside its outputs: a rerun does only what changed, a killed run\n"
    "resumes (a job removes the temporaries a killed run left for its outputs, the\n"
    "report's pictures among them). A failed setup is listed in the index with its\n"
    "reason; the others go on.\n"
    "\n"
    "  -o, --output OUT       the day's folder (created)\n"
    "  -j, --jobs N           jobs at once (default: the cores)\n"
    "  --memory-mb MB         memory budget of the jobs running at once (default: half\n"
    "                         the RAM; a job estimated larger runs alone)\n"
    "  --farm local|slurm     where the jobs run (default local)\n"
    "  --farm-group auto|job|setup\n"
    "                         what one Slurm job runs: 'setup', a whole setup, its\n"
    "                         jobs one after the other, then any grouped setup not\n"
    "                         yet taken (Slurm's 0.5-0.9 s a job paid about once a\n"
    "                         CPU); 'job', one job of the graph (a setup's merges\n"
    "                         as one array); 'auto' (default), per setup: grouped\n"
    "                         when its jobs one by one would cost Slurm over 2% of\n"
    "                         their CPU time as the graph estimates it (cpu_seconds),\n"
    "                         e.g. 16 jobs of ~0.5 s; the choice and its reason per\n"
    "                         setup are logged and in --json (setups[].farm)\n"
    "  --emit-jobs FILE       write the job graph as JSON (docs/process.md) and run\n"
    "                         nothing: for other queues, through 'setlight job FILE ID'\n"
    "                         (a graph edited by hand is checked whole there: see\n"
    "                         'setlight job --help')\n"
    "  --probe-view AZ,EL     where the probe camera (chrome and grey ball) looked in\n"
    "                         the set, degrees as 'setlight unwrap' takes them\n"
    "                         (default 0,0: along +Z)\n"
    "  --probe-sensor-mm W    the probe camera's sensor width (default: the capture's,\n"
    "                         else an orthographic ball)\n"
    "  --json                 print the result: per setup its status, outputs, key\n"
    "                         numbers, warnings, and each job's status and cost; the\n"
    "                         run's cost (wall and CPU time, CPU wait, peak memory,\n"
    "                         jobs per minute, overhead per job)\n"
    "\n"
    "Exit codes: 0 every setup processed; 3 some setups failed on their input (a\n"
    "folder with no frames, a session.json that does not parse or names missing\n"
    "files, a corrupt frame): one line each on stderr, the others processed and the\n"
    "index written; 1 a setup failed otherwise, or the run could not go on; 2 usage\n"
    "(two setups of one name, OUT a file: nothing written). See docs/process.md;\n"
    "the job graph's JSON Schema is docs/jobs.schema.json.\n";

int cmd_process(int argc, char **argv, const sl_cli *cli)
{
    enum { OPT_MEMORY = 1000, OPT_FARM, OPT_FARM_GROUP, OPT_EMIT, OPT_PROBE_VIEW, OPT_PROBE_SENSOR };
    static const struct option opts[] = {{"help", no_argument, NULL, 'h'},
                                         {"output", required_argument, NULL, 'o'},
                                         {"jobs", required_argument, NULL, 'j'},
                                         {"memory-mb", required_argument, NULL, OPT_MEMORY},
                                         {"farm", required_argument, NULL, OPT_FARM},
                                         {"farm-group", required_argument, NULL, OPT_FARM_GROUP},
                                         {"emit-jobs", required_argument, NULL, OPT_EMIT},
                                         {"probe-view", required_argument, NULL, OPT_PROBE_VIEW},
                                         {"probe-sensor-mm", required_argument, NULL,
                                          OPT_PROBE_SENSOR},
                                         {0, 0, 0, 0}};
    sl_pipeline_options o;
    sl_pipeline_options_init(&o);
    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, ":ho:j:", opts, NULL)) != -1) {
        switch (c) {
        case 'h':
            fputs(process_help, stdout);
            return 0;
        case 'o':
            o.out = optarg;
            break;
        case 'j':
            if (!cli_parse_int(optarg, &o.jobs) || o.jobs < 1)
                return cli_usage_error(cli, "--jobs needs a whole number >= 1, not '%s'", optarg);
            break;
        case OPT_MEMORY:
            if (!cli_parse_int(optarg, &o.memory_mb) || o.memory_mb < 1)
                return cli_usage_error(cli, "--memory-mb needs a whole number >= 1, not '%s'",
                                       optarg);
            break;
        case OPT_FARM:
            if (!strcmp(optarg, "local"))
                o.farm = SL_FARM_LOCAL;
            else if (!strcmp(optarg, "slurm"))
                o.farm = SL_FARM_SLURM;
            else
                return cli_usage_error(cli, "--farm is local or slurm, not '%s'", optarg);
            break;
        case OPT_FARM_GROUP:
            if (!strcmp(optarg, "auto"))
                o.farm_group = SL_FARM_GROUP_AUTO;
            else if (!strcmp(optarg, "job"))
                o.farm_group = SL_FARM_GROUP_JOB;
            else if (!strcmp(optarg, "setup"))
                o.farm_group = SL_FARM_GROUP_SETUP;
            else
                return cli_usage_error(cli, "--farm-group is auto, job or setup, not '%s'", optarg);
            break;
        case OPT_EMIT:
            o.emit_jobs = optarg;
            break;
        case OPT_PROBE_VIEW:
            if (!cli_parse_view(optarg, &o.probe_azimuth_deg, &o.probe_elevation_deg))
                return cli_usage_error(cli, "--probe-view needs AZ,EL in degrees, not '%s'",
                                       optarg);
            break;
        case OPT_PROBE_SENSOR:
            if (!cli_parse_double(optarg, &o.probe_sensor_mm) || o.probe_sensor_mm <= 0)
                return cli_usage_error(cli, "--probe-sensor-mm needs a width in mm > 0, not '%s'",
                                       optarg);
            break;
        case ':':
            return cli_usage_error(cli, "%s needs a value", argv[optind - 1]);
        default:
            return cli_usage_error(cli, "unknown option %s", argv[optind - 1]);
        }
    }
    if (!o.out)
        return cli_usage_error(cli, "needs -o OUT");
    if (optind >= argc)
        return cli_usage_error(cli, "needs at least one SETUP folder");
    o.setups = (const char *const *)argv + optind;
    o.setup_count = argc - optind;
    /* The jobs run this very executable. */
    char exe[PATH_MAX];
    ssize_t n = readlink("/proc/self/exe", exe, sizeof exe - 1);
    if (n <= 0)
        return cli_usage_error(cli, "cannot find the setlight executable (/proc/self/exe)");
    exe[n] = 0;
    o.exe = exe;
    o.progress = !cli->quiet;
    sl_pipeline_result res;
    sl_error err;
    sl_result r = sl_pipeline_process(&o, &res, &err);
    if (r) {
        sl_pipeline_result_free(&res); /* a run that could not go on still summed up */
        return cli_fail(cli, &err);
    }
    for (char *line = res.failures; line && *line;) {
        char *end = strchr(line, '\n');
        fprintf(stderr, "setlight process: %.*s\n", (int)(end ? end - line : (long)strlen(line)),
                line);
        line = end ? end + 1 : line + strlen(line);
    }
    if (cli->json && res.json)
        printf("%s\n", res.json);
    else if (!cli->quiet)
        sl_log(SL_LOG_INFO, "%s: %d setups (%d failed), %d jobs: %d run, %d up to date, %d failed, %.1f s",
               o.out, res.setups, res.setups_failed, res.jobs, res.jobs_run, res.jobs_skipped,
               res.jobs_failed, res.seconds);
    int rc = res.setups_failed ? (res.input_failures_only ? 3 : 1) : 0;
    sl_pipeline_result_free(&res);
    return rc;
}

static const char job_help[] =
    "usage: setlight job [--claims DIR] JOBS.json ID [ID...]\n"
    "\n"
    "Runs one job of a graph that 'setlight process --emit-jobs' wrote (docs/process.md):\n"
    "nothing when its stamp says it is up to date with its inputs, else its command\n"
    "(stdout to its *.result.json output, stderr to its log), then its stamp. What a\n"
    "queue runs for each job, in dependency order. The graph is checked whole first\n"
    "(by 'setlight process' as it wrote it: while the file is byte for byte that one,\n"
    "its SHA-256 in JOBS.json.checked, only this job is read):\n"
    "a file edited into one that does not hold together (a field missing or of the\n"
    "wrong type, a path not absolute, an id leading out of OUT, two jobs of one id,\n"
    "a dependency on no job or on a cycle, over 32768 jobs or 4096 entries in a list,\n"
    "over 16 MB) is refused before anything is written or run.\n"
    "\n"
    "Exit codes: the command's (0 also when up to date); 3 a graph that does not hold\n"
    "together, one line naming the file and the job; 2 usage, or no job of that id.\n"
    "\n"
    "With several IDs (a grouped setup's Slurm job, docs/slurm.md): each in turn in this\n"
    "one process, a job only when the jobs listed before it that it depends on\n"
    "succeeded; a line for each that could not run; exit 1 when one failed or was not\n"
    "run, else 0.\n"
    "\n"
    "--claims DIR: the IDs are shared with the other processes given the same DIR (an\n"
    "existing folder; a grouped setup's Slurm job and one helping it, docs/slurm.md):\n"
    "each job runs once, in the process that takes it (a claim file in DIR); this one\n"
    "takes any job nobody has taken whose dependencies succeeded, waits while the jobs\n"
    "left wait for jobs running elsewhere, and exits once every job is taken: 1 when a\n"
    "job it took failed or was not run, else 0.\n";

/* setlight job JOBS.json ID: exits 0 at once when the job is up to date,
 * else with its command's code. */
int cmd_job(int argc, char **argv, const sl_cli *cli)
{
    if (argc == 2 && (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h"))) {
        fputs(job_help, stdout);
        return 0;
    }
    const char *claims = NULL;
    if (argc >= 3 && !strcmp(argv[1], "--claims")) {
        claims = argv[2];
        argc -= 2;
        argv += 2;
    }
    if (argc < 3)
        return cli_usage_error(cli, "usage: setlight job [--claims DIR] JOBS.json ID [ID...]");
    if (argc > 3 || claims) {
        /* A grouped setup's jobs: exit 1 when one failed or was not run. */
        int n = argc - 2, rc = 0;
        int *codes = calloc((size_t)n, sizeof *codes);
        sl_error *errs = calloc((size_t)n, sizeof *errs);
        if (codes && errs) {
            if (claims)
                sl_pipeline_jobs_share(argv[1], claims, argv + 2, n, codes, errs);
            else
                sl_pipeline_jobs_run(argv[1], argv + 2, n, codes, errs);
            int took = 0;
            for (int i = 0; i < n; i++) {
                if (errs[i].code)
                    cli_fail(cli, &errs[i]);
                rc |= codes[i] != 0 && codes[i] != SL_PIPELINE_JOB_ELSEWHERE;
                took += codes[i] != SL_PIPELINE_JOB_ELSEWHERE && !errs[i].code;
            }
            if (claims && !cli->quiet) /* the Slurm job's log: who ran what */
                fprintf(stderr, "setlight job: took %d of %d jobs\n", took, n);
        } else {
            fprintf(stderr, "setlight %s: out of memory\n", cli->command);
            rc = 1;
        }
        free(codes);
        free(errs);
        return rc;
    }
    int code;
    bool skipped;
    sl_error err;
    if (sl_pipeline_job_run(argv[1], argv[2], &code, &skipped, &err))
        return cli_fail(cli, &err);
    return code;
}

int cmd_process_report(int argc, char **argv, const sl_cli *cli)
{
    if (argc != 3)
        return cli_usage_error(cli, "usage: setlight process-report JOBS.json SETUP");
    sl_error err;
    if (sl_pipeline_report_setup(argv[1], argv[2], &err))
        return cli_fail(cli, &err);
    return 0;
}

int cmd_process_index(int argc, char **argv, const sl_cli *cli)
{
    if (argc != 2)
        return cli_usage_error(cli, "usage: setlight process-index JOBS.json");
    sl_error err;
    if (sl_pipeline_report_index(argv[1], &err))
        return cli_fail(cli, &err);
    return 0;
}
