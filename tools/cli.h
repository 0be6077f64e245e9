/* SPDX-License-Identifier: BSD-3-Clause */
/* Shared pieces of the setlight command: global options, error reporting
 * and exit codes. Each command lives in cmd_<name>.c. */
#ifndef SETLIGHT_CLI_H
#define SETLIGHT_CLI_H

#include <getopt.h>
#include <stdbool.h>

#include "setlight/core.h"

typedef struct sl_cli {
    const char *command; /* e.g. "info" */
    bool json;           /* --json: machine-readable result on stdout */
    bool quiet;          /* --quiet: no progress or info on stderr */
    int threads;         /* --threads N, 0 = all cores */
} sl_cli;

typedef int (*sl_command_fn)(int argc, char **argv, const sl_cli *cli);

/* Prints "setlight CMD: message" on stderr and returns the exit code. */
int cli_fail(const sl_cli *cli, const sl_error *err);
/* Usage error: prints the message and a pointer to --help; returns 2. */
int cli_usage_error(const sl_cli *cli, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* getopt_long over argv with the given options; prints unknown-option errors
 * in the project's form. Resets getopt state first. */
void cli_getopt_reset(void);
/* Parses a whole positive int / finite double; false on junk. */
bool cli_parse_int(const char *s, int *out);
bool cli_parse_double(const char *s, double *out);
/* Exactly n comma-separated finite numbers ("1,2.5,3"); false on junk,
 * empty fields or a different count. */
bool cli_parse_list(const char *s, double *v, int n);
/* EXR compression names as the options take them: zip, piz, none, rle.
 * cli_parse_compression is false for any other name. */
const char *cli_compression_name(sl_exr_compression c);
bool cli_parse_compression(const char *s, sl_exr_compression *out);
/* "AZ,EL" in degrees with |EL| <= 90 (render and converge --view). */
bool cli_parse_view(const char *s, double *az, double *el);

/* Warns (one line naming the file) when a file's content is not the format
 * its name says, e.g. a PNG named .exr: it is read for what it is. */
void cli_warn_format_mismatch(const char *path, const sl_meta *meta);

/* Command entry points. */
int cmd_info(int argc, char **argv, const sl_cli *cli);
int cmd_convert(int argc, char **argv, const sl_cli *cli);
int cmd_furnace(int argc, char **argv, const sl_cli *cli);
int cmd_render(int argc, char **argv, const sl_cli *cli);
int cmd_converge(int argc, char **argv, const sl_cli *cli);
int cmd_simulate(int argc, char **argv, const sl_cli *cli);
int cmd_demo(int argc, char **argv, const sl_cli *cli);
int cmd_capture(int argc, char **argv, const sl_cli *cli);
int cmd_ingest(int argc, char **argv, const sl_cli *cli);
int cmd_cameras(int argc, char **argv, const sl_cli *cli);
int cmd_merge(int argc, char **argv, const sl_cli *cli);
int cmd_response(int argc, char **argv, const sl_cli *cli);
int cmd_rig(int argc, char **argv, const sl_cli *cli);
int cmd_unwrap(int argc, char **argv, const sl_cli *cli);
int cmd_stitch(int argc, char **argv, const sl_cli *cli);
int cmd_calibrate(int argc, char **argv, const sl_cli *cli);
int cmd_lens_calibrate(int argc, char **argv, const sl_cli *cli);
int cmd_process(int argc, char **argv, const sl_cli *cli);
/* Hidden: what the jobs of `process` run. */
int cmd_job(int argc, char **argv, const sl_cli *cli);
int cmd_process_report(int argc, char **argv, const sl_cli *cli);
int cmd_process_index(int argc, char **argv, const sl_cli *cli);

#endif
