/* SPDX-License-Identifier: BSD-3-Clause */
#include "cli.h"

#include <errno.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

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

void cli_warn_format_mismatch(const char *path, const sl_meta *meta)
{
    const char *dot = strrchr(path, '.');
    if (!dot || !meta->format[0])
        return;
    bool named_exr = strcasecmp(dot, ".exr") == 0;
    bool is_exr = strcmp(meta->format, "openexr") == 0;
    if (named_exr != is_exr)
        sl_log(SL_LOG_WARN, "%s: the file is %s, not what its name says; read as %s", path,
               meta->format, meta->format);
}

bool cli_parse_view(const char *s, double *az, double *el)
{
    char tail;
    return sscanf(s, "%lf,%lf%c", az, el, &tail) == 2 && isfinite(*az) && isfinite(*el) &&
           fabs(*el) <= 90;
}

bool cli_parse_list(const char *s, double *v, int n)
{
    char buf[512];
    if (strlen(s) >= sizeof buf)
        return false;
    strcpy(buf, s);
    char *p = buf;
    for (int i = 0; i < n; i++) {
        char *comma = strchr(p, ',');
        if ((comma == NULL) != (i == n - 1))
            return false;
        if (comma)
            *comma = 0;
        if (!cli_parse_double(p, &v[i]))
            return false;
        if (comma)
            p = comma + 1;
    }
    return true;
}

/* By sl_exr_compression value. */
const char *cli_compression_name(sl_exr_compression c)
{
    return sl_exr_compression_name(c);
}

bool cli_parse_compression(const char *s, sl_exr_compression *out)
{
    for (int k = 0; k <= SL_EXR_RLE; k++)
        if (!strcmp(s, sl_exr_compression_name((sl_exr_compression)k))) {
            *out = (sl_exr_compression)k;
            return true;
        }
    return false;
}
