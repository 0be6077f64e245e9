/* SPDX-License-Identifier: BSD-3-Clause */
/* session.json (version 1): what a session holds, by view and bracket, for
 * wrangling scripts. Built from the journal, or by ingest. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "capture_private.h"

static int cmp_exposure(const void *a, const void *b)
{
    double x = json_real_value(json_object_get(*(json_t *const *)a, "exposure_time"));
    double y = json_real_value(json_object_get(*(json_t *const *)b, "exposure_time"));
    return x < y ? -1 : x > y;
}

/* Orders each bracket's frames by exposure (ties keep their order). */
static void sort_brackets(json_t *views)
{
    size_t vi, bi;
    json_t *view, *bracket;
    json_array_foreach(views, vi, view)
    {
        json_array_foreach(json_object_get(view, "brackets"), bi, bracket)
        {
            json_t *frames = json_object_get(bracket, "frames");
            size_t n = json_array_size(frames);
            json_t **items = malloc(sizeof *items * (n ? n : 1));
            if (!items)
                continue;
            for (size_t i = 0; i < n; i++)
                items[i] = json_incref(json_array_get(frames, i));
            qsort(items, n, sizeof *items, cmp_exposure);
            json_array_clear(frames);
            for (size_t i = 0; i < n; i++)
                json_array_append_new(frames, items[i]);
            free(items);
        }
    }
}

sl_result sl_session_write_json(const char *dir, json_t *camera, json_t *views, json_t *problems,
                                json_t *splits, sl_error *err)
{
    sort_brackets(views);
    json_t *root = json_object();
    json_object_set_new(root, "version", json_integer(1));
    json_object_set_new(root, "camera", camera ? camera : json_object());
    json_object_set_new(root, "views", views);
    json_object_set_new(root, "problems", problems ? problems : json_array());
    if (splits)
        json_object_set_new(root, "splits", splits);
    char path[4096];
    sl_result r = sl_capture_path(path, sizeof path, dir, SL_SESSION_NAME, err);
    if (!r)
        r = sl_json_write_atomic(path, root,
                                 JSON_INDENT(2) | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(10), err);
    json_decref(root);
    return r;
}

static const char *str(json_t *e, const char *key)
{
    const char *s = json_string_value(json_object_get(e, key));
    return s ? s : "";
}

sl_result sl_session_write(const char *dir, sl_error *err)
{
    json_t *events;
    sl_result r = sl_journal_read(dir, &events, err);
    if (r)
        return r;
    json_t *start = json_array_get(events, 0);
    json_t *camera = json_deep_copy(json_object_get(start, "camera"));
    json_t *plan = json_object_get(start, "plan");
    int nviews = (int)json_integer_value(json_object_get(plan, "views"));
    /* the image format asked for and the camera's label for it */
    if (camera && json_object_get(plan, "format")) {
        json_object_set(camera, "format", json_object_get(plan, "format"));
        json_object_set(camera, "format_label", json_object_get(plan, "format_label"));
    }
    json_t *views = json_array(), *problems = json_array();
    for (int v = 0; v < nviews; v++) {
        json_t *view = json_object(), *bracket = json_object();
        json_object_set_new(view, "view", json_integer(v));
        json_object_set_new(bracket, "frames", json_array());
        json_t *brackets = json_array();
        json_array_append_new(brackets, bracket);
        json_object_set_new(view, "brackets", brackets);
        json_array_append_new(views, view);
    }
    size_t i;
    json_t *e;
    json_array_foreach(events, i, e)
    {
        const char *kind = str(e, "event");
        int v = (int)json_integer_value(json_object_get(e, "view"));
        if (!strcmp(kind, "frame") && json_is_true(json_object_get(e, "accepted")) && v >= 0 &&
            v < nviews) {
            json_t *frame = json_object();
            static const char *const keys[] = {"file", "source",  "exposure_time",  "f_number",
                                               "iso",  "planned", "measured_ratio", "sha256"};
            for (size_t k = 0; k < sizeof keys / sizeof keys[0]; k++) {
                json_t *value = json_object_get(e, keys[k]);
                json_object_set(frame, keys[k], value ? value : json_null());
            }
            if (json_object_get(e, "siblings"))
                json_object_set(frame, "siblings", json_object_get(e, "siblings"));
            json_t *bracket =
                json_array_get(json_object_get(json_array_get(views, (size_t)v), "brackets"), 0);
            json_array_append_new(json_object_get(bracket, "frames"), frame);
        } else if (!strcmp(kind, "frame")) {
            char msg[512];
            snprintf(msg, sizeof msg, "view %d frame %d attempt %d (%s) rejected: %s", v,
                     (int)json_integer_value(json_object_get(e, "index")),
                     (int)json_integer_value(json_object_get(e, "attempt")), str(e, "file"),
                     str(e, "reason"));
            json_array_append_new(problems, json_string(msg));
        } else if (!strcmp(kind, "error")) {
            char msg[1024];
            snprintf(msg, sizeof msg, "view %d frame %d failed: %s", v,
                     (int)json_integer_value(json_object_get(e, "index")), str(e, "message"));
            json_array_append_new(problems, json_string(msg));
        }
    }
    json_decref(events);
    return sl_session_write_json(dir, camera, views, problems, NULL, err);
}
