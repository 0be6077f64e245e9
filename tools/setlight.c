/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight <command> [options]: argument parsing and calls into the
 * libraries, nothing more. Exit codes: 0 success, 1 runtime failure,
 * 2 usage error, 3 invalid input data. */
#include <malloc.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#ifdef SETLIGHT_HAVE_VSET
#include "setlight/vset.h"
#endif

typedef struct command {
    const char *name;
    sl_command_fn fn;
    const char *summary;
} command;

static const command commands[] = {
    {"demo", cmd_demo, "simulate the stage set, process it, score every stage against its truth"},
    {"simulate", cmd_simulate, "photograph a virtual film set, with its ground truth"},
    {"capture", cmd_capture, "tethered bracketing through libgphoto2 with journal and resume"},
    {"ingest", cmd_ingest, "group a card or folder of brackets into a session"},
    {"cameras", cmd_cameras, "list the cameras libgphoto2 detects"},
    {"merge", cmd_merge, "merge a bracket of exposures into HDR radiance (EXR)"},
    {"response", cmd_response, "recover a camera response curve from a bracket"},
    {"stitch", cmd_stitch, "HDR fisheye views to one lat-long: lens and rotations solved, blended in radiance"},
    {"unwrap", cmd_unwrap, "chrome-ball photo to lat-long (finds the ball, exact perspective)"},
    {"calibrate", cmd_calibrate, "match the HDRI to the plate camera: ColorChecker and grey sphere"},
    {"lens-calibrate", cmd_lens_calibrate, "solve a lens profile from chessboard photos (for stitch)"},
    {"rig", cmd_rig, "extract area lights and a residual dome from a lat-long, as USD and JSON"},
    {"render", cmd_render, "render grey/chrome/chart references under an HDR environment"},
    {"converge", cmd_converge, "error against time for each sampling strategy (table, SVG)"},
    {"furnace", cmd_furnace, "white-furnace energy test of every BSDF"},
    {"info", cmd_info, "print size, channels, range, NaN/Inf, EXIF and colour facts of images"},
    {"convert", cmd_convert, "convert between lat-long, mirror ball, angular map and cube map"},
    {"process", cmd_process, "a shoot day end to end: every setup's stages as jobs, the day's index"},
    /* Hidden (no summary): the jobs of a process graph. */
    {"job", cmd_job, NULL},
    {"process-report", cmd_process_report, NULL},
    {"process-index", cmd_process_index, NULL},
};
static const int command_count = (int)(sizeof commands / sizeof commands[0]);

static void print_help(FILE *out)
{
    fprintf(out,
            "usage: setlight <command> [options]\n"
            "       setlight --version | --help\n\n"
            "On-set HDRI and lighting-reference pipeline.\n\n"
            "commands:\n");
    for (int i = 0; i < command_count; i++)
        if (commands[i].summary)
            fprintf(out, "  %-10s %s\n", commands[i].name, commands[i].summary);
    fprintf(out,
            "\noptions for every command:\n"
            "  --help        describe the command\n"
            "  --json        print a machine-readable result on stdout\n"
            "  --quiet       no progress or information on stderr\n"
            "  --threads N   worker threads (default: all cores); results do not depend on it\n"
            "  --max-memory-mb N\n"
            "                memory budget for what is read (default: half the RAM;\n"
            "                also SETLIGHT_MAX_MEMORY_MB): larger images are refused (exit 3)\n"
            "\nexit codes: 0 success, 1 runtime failure, 2 usage error, 3 invalid input data;\n"
            "interrupted (SIGINT, SIGTERM): ends by the signal (130, 143), no temporary or\n"
            "partial output left, earlier outputs untouched\n"
            "docs: docs/index.md\n");
}

int main(int argc, char **argv)
{
    /* An interrupt removes every temporary output and never renames a
     * partial file into place (docs/conventions.md). */
    sl_interrupt_install();
    /* glibc maps every block above 128 kB fresh and gives it back on free,
     * so each round of a merge's fit faulted its buffers in again (12 000
     * page faults, a tenth of a small bracket's CPU): blocks up to 2 MB
     * (the rounds' own) come from the heap, and up to 8 MB freed at its
     * top is kept for the next. Larger blocks are mapped as before, so the
     * peak grows by a few MB at most (docs/performance.md). */
    mallopt(M_MMAP_THRESHOLD, 2 << 20);
    mallopt(M_TRIM_THRESHOLD, 8 << 20);
#ifdef SETLIGHT_HAVE_VSET
    /* The virtual camera joins the camera backends ("--camera virtual"). */
    if (sl_vset_camera_register(NULL))
        return 1;
#endif
    if (argc < 2) {
        print_help(stderr);
        return 2;
    }
    if (!strcmp(argv[1], "--version") || !strcmp(argv[1], "version")) {
        printf("setlight %s\n", sl_version());
        return 0;
    }
    if (!strcmp(argv[1], "--help") || !strcmp(argv[1], "-h") || !strcmp(argv[1], "help")) {
        print_help(stdout);
        return 0;
    }
    const command *cmd = NULL;
    for (int i = 0; i < command_count; i++)
        if (!strcmp(argv[1], commands[i].name))
            cmd = &commands[i];
    if (!cmd) {
        fprintf(stderr, "setlight: unknown command '%s' (see 'setlight --help')\n", argv[1]);
        return 2;
    }

    /* Global options may stand anywhere after the command; strip them here. */
    sl_cli cli = {.command = cmd->name};
    /* The memory budget: --max-memory-mb, else SETLIGHT_MAX_MEMORY_MB. */
    int memory_mb = 0;
    const char *env_mb = getenv("SETLIGHT_MAX_MEMORY_MB");
    if (env_mb && *env_mb && (!cli_parse_int(env_mb, &memory_mb) || memory_mb < 1))
        return cli_usage_error(&cli, "SETLIGHT_MAX_MEMORY_MB needs a whole number of MB >= 1");
    char **args = calloc((size_t)argc + 1, sizeof *args);
    if (!args)
        return 1;
    int n = 0;
    args[n++] = argv[1];
    for (int i = 2; i < argc; i++) {
        if (!strcmp(argv[i], "--")) {
            while (i < argc)
                args[n++] = argv[i++];
            break;
        }
        if (!strcmp(argv[i], "--json"))
            cli.json = true;
        else if (!strcmp(argv[i], "--quiet") || !strcmp(argv[i], "-q"))
            cli.quiet = true;
        else if (!strcmp(argv[i], "--threads") || !strncmp(argv[i], "--threads=", 10)) {
            const char *v = argv[i][9] == '=' ? argv[i] + 10 : (i + 1 < argc ? argv[++i] : NULL);
            if (!v || !cli_parse_int(v, &cli.threads) || cli.threads < 0) {
                free(args);
                return cli_usage_error(&cli, "--threads needs a whole number >= 0");
            }
        } else if (!strcmp(argv[i], "--max-memory-mb") ||
                   !strncmp(argv[i], "--max-memory-mb=", 16)) {
            const char *v = argv[i][15] == '=' ? argv[i] + 16 : (i + 1 < argc ? argv[++i] : NULL);
            if (!v || !cli_parse_int(v, &memory_mb) || memory_mb < 1) {
                free(args);
                return cli_usage_error(&cli, "--max-memory-mb needs a whole number of MB >= 1");
            }
        } else
            args[n++] = argv[i];
    }
    if (memory_mb)
        sl_memory_budget_set((uint64_t)memory_mb << 20);
    args[n] = NULL;
    sl_log_set_quiet(cli.quiet);
    sl_threads_set(cli.threads);
    sl_log_hold_notes(true);
    int rc = cmd->fn(n, args, &cli);
    sl_output_set_abort(); /* a set a command left open: its temporaries go */
    sl_log_release_notes(rc == 0);
    free(args);
    fflush(stdout);
    return rc;
}
