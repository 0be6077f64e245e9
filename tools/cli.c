/* SPDX-License-Identifier: BSD-3-Clause */
#include "cli.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>

int cli_fail(const sl_cli *cli, const sl_error *err)
{
    fprintf(stderr, "setlight %s: %s\n", cli->command, err->message[0] ? err->message : sl_result_name(err->code));
    return sl_result_exit_code(err->code);
}

int cli_usage_error(const sl_cli *cli, const char *fmt, ...)
{
    va_list ap;
    fprintf(stderr, "setlight %s: ", cli->command);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, " (see 'setlight %s --help')\n", cli->command);
    return 2;
}

void cli_getopt_reset(void)
{
    optind = 0; /* glibc: 0 forces full reinitialisation */
    opterr = 0; /* we print our own messages */
}

bool cli_parse_int(const char *s, int *out)
{
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || end == s || *end || v < -2147483647L || v > 2147483647L)
        return false;
    *out = (int)v;
    return true;
}

bool cli_parse_double(const char *s, double *out)
{
    char *end;
    errno = 0;
    double v = strtod(s, &end);
    if (errno || end == s || *end || !isfinite(v))
        return false;
    *out = v;
    return true;
}
