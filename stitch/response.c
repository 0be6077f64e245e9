/* SPDX-License-Identifier: BSD-3-Clause */
/* Inverse camera responses: the linear one, evaluation, and JSON files. */
#include <jansson.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "merge_private.h"
#include "setlight/stitch.h"

static sl_result response_alloc(sl_response *resp, int nodes, sl_error *err)
{
    memset(resp, 0, sizeof *resp);
    resp->inverse = calloc((size_t)nodes * 3, sizeof *resp->inverse);
    if (!resp->inverse)
        return sl_error_set(err, SL_ERR_NOMEM, "response: out of memory");
    resp->channels = 3;
    resp->nodes = nodes;
    return SL_OK;
}

sl_result sl_response_linear(sl_response *resp, int nodes, sl_error *err)
{
    if (nodes < 2)
        return sl_error_set(err, SL_ERR_USAGE, "response: needs at least 2 nodes, not %d", nodes);
    sl_result r = response_alloc(resp, nodes, err);
    if (r)
        return r;
    for (int c = 0; c < 3; c++)
        for (int k = 0; k < nodes; k++)
            resp->inverse[c * nodes + k] = (double)k / (nodes - 1);
    snprintf(resp->source, sizeof resp->source, "linear");
    return SL_OK;
}

void sl_response_free(sl_response *resp)
{
    if (!resp)
        return;
    free(resp->inverse);
    memset(resp, 0, sizeof *resp);
}

double sl_response_eval(const sl_response *resp, int channel, double z)
{
    return merge_response_at(resp, channel, z);
}

void merge_code_curve_init(merge_code_curve *t, const merge_samples *s, const sl_response *resp)
{
    t->codes = s->code_step == 1.0 / 255;
    for (int k = 0; t->codes && k < 256; k++) {
        t->z[k] = (float)k * (1.0f / 255);
        t->log_z[k] = log(t->z[k]);
        for (int c = 0; c < 3 && resp; c++) {
            double y = merge_response_at(resp, c, t->z[k]);
            t->y[c][k] = y;
            t->log_y[c][k] = y > 0 ? log(y) : NAN;
        }
    }
}

sl_result sl_response_write(const char *path, const sl_response *resp, sl_error *err)
{
    json_t *curves = json_array();
    for (int c = 0; c < resp->channels; c++) {
        json_t *row = json_array();
        for (int k = 0; k < resp->nodes; k++)
            json_array_append_new(row, json_real(resp->inverse[c * resp->nodes + k]));
        json_array_append_new(curves, row);
    }
    json_t *o = json_pack("{s:s, s:i, s:s, s:i, s:s, s:o}", "format", "setlight-response",
                          "version", 1, "source", resp->source, "nodes", resp->nodes,
                          "meaning",
                          "inverse[c][k]: linear exposure of value z = k/(nodes-1) in channel c "
                          "(R, G, B), interpolated linearly; inverse[c][nodes-1] = 1",
                          "inverse", curves);
    return stitch_json_write(path, o, 10, err);
}

sl_result stitch_json_write(const char *path, void *json, int precision, sl_error *err)
{
    json_t *o = json;
    sl_result r = sl_json_write_atomic(path, o, JSON_INDENT(1) | JSON_REAL_PRECISION(precision), err);
    json_decref(o);
    return r;
}

sl_result stitch_json_read(const char *path, void *out, sl_error *err)
{
    return sl_json_load_file(path, "JSON", 0, (json_t **)out, err);
}

sl_result sl_response_read(const char *path, sl_response *resp, sl_error *err)
{
    memset(resp, 0, sizeof *resp);
    json_t *o;
    sl_result r = stitch_json_read(path, &o, err);
    if (r)
        return r;
    const char *format = json_string_value(json_object_get(o, "format"));
    json_t *curves = json_object_get(o, "inverse");
    int nodes = (int)json_integer_value(json_object_get(o, "nodes"));
    if (!format || strcmp(format, "setlight-response") != 0 || !json_is_array(curves) ||
        json_array_size(curves) != 3 || nodes < 2 || nodes > 65536) {
        json_decref(o);
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s: not a setlight response (needs format setlight-response, "
                            "nodes >= 2 and three inverse curves)",
                            path);
    }
    if ((r = response_alloc(resp, nodes, err))) {
        json_decref(o);
        return r;
    }
    for (int c = 0; c < 3; c++) {
        json_t *row = json_array_get(curves, (size_t)c);
        if (!json_is_array(row) || (int)json_array_size(row) != nodes) {
            r = sl_error_set(err, SL_ERR_INPUT, "%s: curve %d does not have %d values", path, c,
                             nodes);
            break;
        }
        for (int k = 0; k < nodes && !r; k++) {
            json_t *v = json_array_get(row, (size_t)k);
            double x = json_number_value(v);
            double prev = k ? resp->inverse[c * nodes + k - 1] : -1;
            if (!json_is_number(v) || !isfinite(x) || x < 0 || x < prev)
                r = sl_error_set(err, SL_ERR_INPUT,
                                 "%s: curve %d value %d is not a finite, non-negative, "
                                 "non-decreasing number",
                                 path, c, k);
            resp->inverse[c * nodes + k] = x;
        }
        if (!r && !(resp->inverse[c * nodes + nodes - 1] > 0))
            r = sl_error_set(err, SL_ERR_INPUT, "%s: curve %d is all zero", path, c);
        if (r)
            break;
    }
    json_decref(o);
    if (r) {
        sl_response_free(resp);
        return r;
    }
    /* Curves keep their shape; the top maps to 1 so files from any tool agree. */
    for (int c = 0; c < 3; c++) {
        double top = resp->inverse[c * nodes + nodes - 1];
        for (int k = 0; k < nodes; k++)
            resp->inverse[c * nodes + k] /= top;
    }
    const char *base = strrchr(path, '/');
    snprintf(resp->source, sizeof resp->source, "%s", base ? base + 1 : path);
    return SL_OK;
}
