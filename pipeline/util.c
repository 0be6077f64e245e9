/* SPDX-License-Identifier: BSD-3-Clause */
/* Small helpers of the pipeline: folders, JSON files, CPU time. */
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>

#include "pipeline_private.h"

sl_result pl_mkdirs(const char *path, sl_error *err)
{
    char buf[4096];
    if (snprintf(buf, sizeof buf, "%s", path) >= (int)sizeof buf)
        return sl_error_set(err, SL_ERR_USAGE, "%s: path too long", path);
    for (char *p = buf + 1;; p++) {
        if (*p == '/' || !*p) {
            char c = *p;
            *p = 0;
            struct stat st;
            if (mkdir(buf, 0777) && errno != EEXIST)
                return sl_error_set(err, SL_ERR_IO, "%s: cannot create: %s", buf, strerror(errno));
            if (stat(buf, &st) || !S_ISDIR(st.st_mode))
                return sl_error_set(err, SL_ERR_USAGE, "%s: not a folder", buf);
            *p = c;
            if (!c)
                break;
        }
    }
    return SL_OK;
}

sl_result pl_json_load(const char *path, json_t **out, sl_error *err)
{
    *out = NULL;
    struct stat st;
    if (stat(path, &st))
        return sl_error_set(err, SL_ERR_NOT_FOUND, "%s: missing", path);
    json_error_t je;
    *out = json_load_file(path, 0, &je);
    if (!*out)
        return sl_error_set(err, SL_ERR_INPUT, "%s: does not parse (line %d: %s)", path, je.line,
                            je.text);
    return SL_OK;
}

sl_result pl_json_write(const char *path, const json_t *value, sl_error *err)
{
    char *text = json_dumps(value, JSON_INDENT(1) | JSON_PRESERVE_ORDER);
    if (!text)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    size_t n = strlen(text);
    text[n] = '\n'; /* json_dumps leaves room for the NUL only: write n bytes plus it */
    sl_result r = sl_write_file_atomic(path, text, n + 1, err);
    free(text);
    return r;
}

int pl_cmp_ranked(const void *a, const void *b)
{
    const pl_ranked *x = a, *y = b;
    return x->rank > y->rank ? -1 : x->rank < y->rank ? 1 : (x->at > y->at) - (x->at < y->at);
}

double pl_cpu_seconds(const struct rusage *ru)
{
    return (double)ru->ru_utime.tv_sec + 1e-6 * (double)ru->ru_utime.tv_usec +
           (double)ru->ru_stime.tv_sec + 1e-6 * (double)ru->ru_stime.tv_usec;
}

double pl_self_status(const char *field)
{
    FILE *f = fopen("/proc/self/status", "r");
    if (!f)
        return -1;
    char line[256];
    size_t n = strlen(field);
    double value = -1;
    while (fgets(line, sizeof line, f))
        if (!strncmp(line, field, n) && line[n] == ':' && sscanf(line + n + 1, "%lf", &value) == 1)
            break;
    fclose(f);
    return value;
}
