/* SPDX-License-Identifier: BSD-3-Clause */
/* JSON files read whole and written atomically (core.h). */
#include <jansson.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/core.h"

sl_result sl_json_load_file(const char *path, const char *what, size_t flags, json_t **out,
                            sl_error *err)
{
    *out = NULL;
    sl_result r = sl_check_input_size(path, SL_MAX_JSON_BYTES, what, err);
    if (r)
        return r;
    json_error_t jerr;
    *out = json_load_file(path, flags, &jerr);
    if (!*out)
        return sl_error_set(err, SL_ERR_INPUT, "%s: line %d: JSON syntax error: %s", path,
                            jerr.line, jerr.text);
    return SL_OK;
}

sl_result sl_json_write_atomic(const char *path, const json_t *root, size_t flags, sl_error *err)
{
    char *text = root ? json_dumps(root, flags) : NULL;
    if (!text)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    size_t n = strlen(text);
    char *line = realloc(text, n + 2);
    if (!line) {
        free(text);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    }
    line[n] = '\n';
    line[n + 1] = '\0';
    sl_result r = sl_write_file_atomic(path, line, n + 1, err);
    free(line);
    return r;
}

const char *sl_json_string_ending(const json_t *array, const char *suffix)
{
    size_t i, n = strlen(suffix);
    json_t *x;
    json_array_foreach(array, i, x) {
        const char *p = json_string_value(x);
        if (p && strlen(p) >= n && !strcmp(p + strlen(p) - n, suffix))
            return p;
    }
    return NULL;
}
