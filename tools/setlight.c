/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight <command> [options]: argument parsing and calls into the
 * libraries, nothing more. Exit codes: 0 success, 1 runtime failure,
 * 2 usage error, 3 invalid input data. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

typedef struct command {
    const char *name;
    sl_command_fn fn;
    const char *summary;
} command;

static const command commands[] = {
    {"demo", cmd_demo, "simulate the stage set, run every stage on it, write report.html"},
    {"simulate", cmd_simulate, "photograph a virtual film set, with its ground truth"},
    {"capture", cmd_capture, "tethered bracketing through libgphoto2 with journal and resume"},
    {"ingest", cmd_ingest, "group a card or folder of brackets into a session"},
    {"cameras", cmd_cameras, "list the cameras libgphoto2 detects"},
    {"merge", cmd_merge, "merge a bracket of exposures into HDR radiance (EXR)"},
    {"response", cmd_response, "recover a camera response curve from a bracket"},
    {"unwrap", cmd_unwrap, "chrome-ball photo to lat-long (finds the ball, exact perspective)"},
    {"calibrate", cmd_calibrate, "match the HDRI to the plate camera: ColorChecker and grey sphere"},
    {"lens-calibrate", cmd_lens_calibrate, "solve a lens profile from chessboard photos (for stitch)"},
    {"rig", cmd_rig, "extract area lights and a residual dome from a lat-long, as USD and JSON"},
    {"render", cmd_render, "render grey/chrome/chart references under an HDR environment"},
    {"converge", cmd_converge, "error against time for each sampling strategy (table, SVG)"},
    {"furnace", cmd_furnace, "white-furnace energy test of every BSDF"},
    {"info", cmd_info, "print size, channels, range, NaN/Inf, EXIF and colour facts of images"},
    {"convert", cmd_convert, "convert between lat-long, mirror ball, angular map and cube map"},
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
        fprintf(out, "  %-10s %s\n", commands[i].name, commands[i].summary);
    fprintf(out,
            "\noptions for every command:\n"
            "  --help        describe the command\n"
            "  --json        print a machine-readable result on stdout\n"
            "  --quiet       no progress or information on stderr\n"
            "  --threads N   worker threads (default: all cores); results do not depend on it\n"
            "\nexit codes: 0 success, 1 runtime failure, 2 usage error, 3 invalid input data\n"
            "docs: docs/index.md\n");
}

int main(int argc, char **argv)
{
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
        } else
            args[n++] = argv[i];
    }
    args[n] = NULL;
    sl_log_set_quiet(cli.quiet);
    sl_threads_set(cli.threads);
    sl_log_hold_notes(true);
    int rc = cmd->fn(n, args, &cli);
    sl_log_release_notes(rc == 0);
    free(args);
    fflush(stdout);
    return rc;
}
