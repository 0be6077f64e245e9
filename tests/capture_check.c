/* SPDX-License-Identifier: BSD-3-Clause */
#include "capture_check.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "testing.h"

/* The exterior (sky and sun) builds in half the time of the stage room: the
 * fault tests use it, the full capture the stage. */
void cap_vopts(sl_virtual_camera_opts *o)
{
    memset(o, 0, sizeof *o);
    snprintf(o->scene, sizeof o->scene, "exterior");
    /* smaller frames under sanitizers, same assertions */
    o->width = sl_test_sanitized() ? 160 : 240;
    o->height = sl_test_sanitized() ? 112 : 160;
}

sl_camera *cap_open_virtual(const sl_virtual_camera_opts *o)
{
    sl_camera *cam = NULL;
    sl_error err;
    CHECK_OK(sl_camera_open_virtual(o, &cam, &err), &err);
    return cam;
}

/* A plan snapped to the camera's speeds; centre 0: the camera's metered
 * setting. */
int cap_plan_of(sl_camera *cam, const char *spec, double centre, double **times)
{
    sl_error err;
    int n = 0, k = 0;
    double *offered = NULL;
    *times = NULL;
    if (centre <= 0) {
        sl_camera_settings now;
        CHECK_OK(sl_camera_get(cam, &now, &err), &err);
        centre = now.exposure_time;
    }
    CHECK_OK(sl_bracket_plan_parse(spec, centre, times, &n, &err), &err);
    CHECK_OK(sl_camera_shutter_speeds(cam, &offered, &k, &err), &err);
    if (*times && offered)
        CHECK_OK(sl_bracket_snap(*times, n, offered, k, 1.0, NULL, &err), &err);
    free(offered);
    return n;
}

json_t *cap_journal(const char *dir)
{
    char path[4096];
    snprintf(path, sizeof path, "%s/journal.jsonl", dir);
    json_t *a = json_array();
    FILE *f = fopen(path, "r");
    char line[8192];
    while (f && fgets(line, sizeof line, f)) {
        json_error_t je;
        json_t *e = json_loads(line, 0, &je);
        CHECK_MSG(e != NULL, "%s: line does not parse: %s", path, line);
        if (e)
            json_array_append_new(a, e);
    }
    if (f)
        fclose(f);
    return a;
}

const char *cap_str(json_t *e, const char *k)
{
    const char *s = json_string_value(json_object_get(e, k));
    return s ? s : "";
}

int cap_ival(json_t *e, const char *k)
{
    return (int)json_integer_value(json_object_get(e, k));
}

/* The events of one kind, in order (borrowed references in a new array). */
json_t *cap_events(json_t *j, const char *kind, int accepted)
{
    json_t *out = json_array(), *e;
    size_t i;
    json_array_foreach(j, i, e)
    {
        if (strcmp(cap_str(e, "event"), kind))
            continue;
        if (accepted >= 0 && json_is_true(json_object_get(e, "accepted")) != (accepted == 1))
            continue;
        json_array_append(out, e);
    }
    return out;
}

void cap_check_session(const char *dir, int views, int count, const double *times)
{
    json_t *j = cap_journal(dir);
    CHECK(!strcmp(cap_str(json_array_get(j, 0), "event"), "session_start"));
    json_t *acc = cap_events(j, "frame", 1);
    CHECK_MSG((int)json_array_size(acc) == views * count, "%s: %zu accepted frames, want %d",
              dir, json_array_size(acc), views * count);
    int *seen = calloc((size_t)(views * count), sizeof *seen);
    size_t i;
    json_t *e;
    json_array_foreach(acc, i, e)
    {
        int v = cap_ival(e, "view"), k = cap_ival(e, "index");
        if (v >= 0 && v < views && k >= 0 && k < count)
            seen[v * count + k]++;
        char path[4096], hex[65];
        sl_error err;
        snprintf(path, sizeof path, "%s/%s", dir, cap_str(e, "file"));
        CHECK_OK(sl_sha256_file(path, hex, &err), &err);
        CHECK_MSG(!strcmp(hex, cap_str(e, "sha256")), "%s: checksum differs", path);
        sl_meta meta;
        int w, h, c;
        if (!sl_photo_read_meta(path, &meta, &w, &h, &c, &err)) {
            CHECK_MSG(fabs(log2(meta.exposure_time / times[k])) < 1.0 / 6,
                      "%s: EXIF %g s, planned %g s", path, meta.exposure_time, times[k]);
            sl_meta_free(&meta);
        } else
            CHECK_MSG(false, "%s", err.message);
    }
    for (int q = 0; q < views * count; q++)
        CHECK_MSG(seen[q] == 1, "view %d frame %d accepted %d times", q / count, q % count,
                  seen[q]);
    free(seen);
    json_t *ends = cap_events(j, "session_end", -1);
    CHECK(json_array_size(ends) == 1);
    json_decref(ends);
    json_decref(acc);
    json_decref(j);

    json_t *s = cap_session_json(dir);
    if (!s)
        return;
    CHECK(cap_ival(s, "version") == 1);
    CHECK(!strcmp(cap_str(json_object_get(s, "camera"), "backend"), "virtual"));
    json_t *vs = json_object_get(s, "views");
    CHECK((int)json_array_size(vs) == views);
    for (size_t v = 0; v < json_array_size(vs); v++) {
        json_t *bs = json_object_get(json_array_get(vs, v), "brackets");
        CHECK(json_array_size(bs) == 1);
        json_t *fr = json_object_get(json_array_get(bs, 0), "frames");
        CHECK((int)json_array_size(fr) == count);
        int measured = 0;
        for (size_t k = 0; k < json_array_size(fr); k++) {
            json_t *f = json_array_get(fr, k);
            CHECK(fabs(log2(json_real_value(json_object_get(f, "exposure_time")) / times[k])) <
                  1.0 / 6);
            measured += json_real_value(json_object_get(f, "measured_ratio")) > 0;
        }
        /* a view's first frame has nothing to compare with; the fastest
         * frames of a dim view share few mid-tones with their neighbour */
        CHECK_MSG(measured >= count - 3, "view %zu: %d ratios measured", v, measured);
    }
    json_decref(s);
}

json_t *cap_session_json(const char *dir)
{
    char sp[4096];
    snprintf(sp, sizeof sp, "%s/session.json", dir);
    json_error_t je;
    json_t *s = json_load_file(sp, 0, &je);
    CHECK_MSG(s != NULL, "%s: %s", sp, je.text);
    return s;
}

sl_capture_options cap_options(const char *dir, const double *times, int count, int views)
{
    sl_capture_options o;
    memset(&o, 0, sizeof o);
    o.dir = dir;
    o.times = times;
    o.count = count;
    o.views = views;
    o.reconnect_seconds = 5;
    return o;
}
