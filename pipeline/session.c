/* SPDX-License-Identifier: BSD-3-Clause */
/* A SETUP folder to its views: a session where it is, a virtual-set capture
 * or a plain folder ingested first (again only when the source changed). */
#include <errno.h>
#include <ftw.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "pipeline_private.h"
#include "setlight/capture.h"

static bool is_file(const char *p)
{
    struct stat st;
    return !stat(p, &st) && S_ISREG(st.st_mode);
}

static bool is_dir(const char *p)
{
    struct stat st;
    return !stat(p, &st) && S_ISDIR(st.st_mode);
}

/* --- Ingest, redone only when the source's file list, sizes or times change --- */

static char *g_listing;
static size_t g_listing_len, g_listing_cap;

static int list_entry(const char *path, const struct stat *st, int type, struct FTW *ftw)
{
    (void)ftw;
    if (type != FTW_F)
        return 0;
    char line[PATH_MAX + 96];
    int n = snprintf(line, sizeof line, "%s\t%lld\t%lld.%09ld\n", path, (long long)st->st_size,
                     (long long)st->st_mtim.tv_sec, st->st_mtim.tv_nsec);
    if (n < 0 || (size_t)n >= sizeof line)
        return 0;
    if (g_listing_len + (size_t)n + 1 > g_listing_cap) {
        size_t cap = (g_listing_cap + (size_t)n + 1) * 2;
        char *p = realloc(g_listing, cap);
        if (!p)
            return 1;
        g_listing = p;
        g_listing_cap = cap;
    }
    memcpy(g_listing + g_listing_len, line, (size_t)n + 1);
    g_listing_len += (size_t)n;
    return 0;
}

/* SHA-256 of every file's path, size and modification time under src. */
static bool source_fingerprint(const char *src, char hex[65])
{
    g_listing_len = 0;
    if (g_listing)
        g_listing[0] = 0;
    if (nftw(src, list_entry, 16, FTW_PHYS))
        return false;
    sl_sha256_hex(g_listing ? g_listing : "", g_listing_len, hex);
    free(g_listing);
    g_listing = NULL;
    g_listing_cap = 0;
    return true;
}

static sl_result ingest_cached(const char *src, const char *dst, sl_error *err)
{
    char fp[65], stamp[2 * PATH_MAX], sess[2 * PATH_MAX], tmp[2 * PATH_MAX];
    if (!source_fingerprint(src, fp))
        return sl_error_set(err, SL_ERR_INPUT, "%s: cannot read the folder", src);
    snprintf(stamp, sizeof stamp, "%s.source.json", dst);
    snprintf(sess, sizeof sess, "%s/session.json", dst);
    json_t *old = NULL;
    sl_error ignored;
    if (is_file(sess) && pl_json_load(stamp, &old, &ignored) == SL_OK) {
        const char *f = json_string_value(json_object_get(old, "fingerprint"));
        bool same = f && !strcmp(f, fp);
        json_decref(old);
        if (same)
            return SL_OK;
    }
    snprintf(tmp, sizeof tmp, "%s.new", dst);
    sl_remove_tree(tmp);
    int frames = 0, views = 0;
    sl_result r = sl_ingest(src, tmp, 0, NULL, &frames, &views, err);
    if (r) {
        sl_remove_tree(tmp);
        return r;
    }
    sl_remove_tree(dst);
    if (rename(tmp, dst)) {
        sl_remove_tree(tmp);
        return sl_error_set(err, SL_ERR_IO, "%s: cannot rename: %s", dst, strerror(errno));
    }
    json_t *st = json_pack("{s:s,s:s}", "source", src, "fingerprint", fp);
    r = pl_json_write(stamp, st, err);
    json_decref(st);
    return r;
}

/* --- Sessions to views --- */

static int probe_kind_name(const char *kind)
{
    if (!kind)
        return PROBE_NONE;
    return !strcmp(kind, "chrome") ? PROBE_CHROME
           : !strcmp(kind, "grey") ? PROBE_GREY
           : !strcmp(kind, "chart") ? PROBE_CHART
                                    : PROBE_NONE;
}

/* The virtual set's probes: frame name stem -> kind (capture.json). */
static int probe_kind_of(const json_t *capture, const char *source)
{
    const char *base = strrchr(source, '/');
    base = base ? base + 1 : source;
    size_t stem = strcspn(base, ".");
    size_t i, j;
    json_t *p, *f;
    json_array_foreach(json_object_get(capture, "probes"), i, p) {
        const char *kind = json_string_value(json_object_get(p, "kind"));
        json_array_foreach(json_object_get(p, "frames"), j, f) {
            const char *name = json_string_value(json_object_get(f, "name"));
            if (name && strlen(name) == stem && !strncmp(name, base, stem))
                return probe_kind_name(kind);
        }
    }
    return PROBE_NONE;
}

/* Reads DIR/session.json into views: each view's largest bracket. A view's
 * probe kind is its "kind" field, else the virtual set's (capture may be
 * NULL), else none: fisheye or unknown. */
static sl_result read_session(setup_plan *sp, const char *dir, const json_t *capture,
                              sl_error *err)
{
    char path[2 * PATH_MAX];
    snprintf(path, sizeof path, "%s/session.json", dir);
    json_t *s = NULL;
    sl_result r = pl_json_load(path, &s, err);
    if (r)
        return r;
    json_t *views = json_object_get(s, "views");
    if (!json_is_array(views)) {
        json_decref(s);
        return sl_error_set(err, SL_ERR_INPUT, "%s: no \"views\" array", path);
    }
    size_t i, j;
    json_t *v;
    json_array_foreach(json_object_get(s, "problems"), i, v) {
        if (json_is_string(v)) {
            char line[4 * PATH_MAX];
            snprintf(line, sizeof line, "%s: %s", path, json_string_value(v));
            json_array_append_new(sp->warnings, json_string(line));
        }
    }
    json_array_foreach(views, i, v) {
        json_t *best = NULL, *b;
        json_array_foreach(json_object_get(v, "brackets"), j, b) {
            json_t *fr = json_object_get(b, "frames");
            if (json_array_size(fr) > json_array_size(json_object_get(best, "frames")))
                best = b;
        }
        json_t *frames = json_object_get(best, "frames");
        if (json_array_size(frames) < 1)
            continue;
        if (sp->view_count == (int)(sizeof sp->views / sizeof sp->views[0])) {
            json_decref(s);
            return sl_error_set(err, SL_ERR_INPUT, "%s: more than %d views", path,
                                sp->view_count);
        }
        view *vw = &sp->views[sp->view_count];
        vw->frames = json_array();
        vw->focal_mm = json_number_value(json_object_get(json_object_get(v, "camera"),
                                                         "focal_length_mm"));
        vw->probe = probe_kind_name(json_string_value(json_object_get(v, "kind")));
        json_t *f;
        json_array_foreach(frames, j, f) {
            const char *file = json_string_value(json_object_get(f, "file"));
            char fp[2 * PATH_MAX];
            if (!file) {
                json_decref(vw->frames);
                json_decref(s);
                return sl_error_set(err, SL_ERR_INPUT, "%s: view %zu: a frame without \"file\"",
                                    path, i);
            }
            snprintf(fp, sizeof fp, "%s/%s", dir, file);
            if (!is_file(fp)) {
                /* the message before the session that holds the name goes */
                sl_result r = sl_error_set(err, SL_ERR_INPUT, "%s: names %s, which is missing",
                                           path, file);
                json_decref(vw->frames);
                json_decref(s);
                return r;
            }
            json_array_append_new(vw->frames, json_string(fp));
            /* The shot's files are named after the frame (IMG_0022.tif) or
             * not (IMG_0022_linear.tif): the frame's file or a sibling. */
            const char *source = json_string_value(json_object_get(f, "source"));
            if (!vw->probe && capture && source)
                vw->probe = probe_kind_of(capture, source);
            size_t k;
            json_t *sib;
            json_array_foreach(json_object_get(f, "siblings"), k, sib) {
                source = json_string_value(json_object_get(sib, "source"));
                if (!vw->probe && capture && source)
                    vw->probe = probe_kind_of(capture, source);
            }
        }
        sp->view_count++;
    }
    json_decref(s);
    return SL_OK;
}

sl_result pl_load_setup(setup_plan *sp, const char *src, sl_error *err)
{
    char path[2 * PATH_MAX], dst[2 * PATH_MAX];
    snprintf(path, sizeof path, "%s/session.json", src);
    if (is_file(path))
        return read_session(sp, src, NULL, err);
    if (!is_dir(src))
        return sl_error_set(err, SL_ERR_INPUT, "%s: not a folder", src);
    json_t *capture = NULL;
    sl_error ignored;
    snprintf(path, sizeof path, "%s/capture.json", src);
    if (pl_json_load(path, &capture, &ignored) == SL_OK &&
        json_is_string(json_object_get(capture, "setlight_capture"))) {
        /* A virtual set: its photographs, never its truth (only scoring reads that). */
        double sensor = json_number_value(json_object_get(capture, "sensor_width_mm"));
        if (sensor > 0 && !sp->sensor_mm)
            sp->sensor_mm = sensor;
        static const char *const parts[] = {"hdri", "probes"};
        sl_result r = SL_OK;
        for (int i = 0; i < 2 && !r; i++) {
            snprintf(path, sizeof path, "%s/%s", src, parts[i]);
            if (!is_dir(path))
                continue;
            snprintf(dst, sizeof dst, "%s/ingest", sp->dir);
            if (!(r = pl_mkdirs(dst, err)) &&
                snprintf(dst, sizeof dst, "%s/ingest/%s", sp->dir, parts[i]) > 0 &&
                !(r = ingest_cached(path, dst, err)))
                r = read_session(sp, dst, capture, err);
        }
        json_decref(capture);
        return r;
    }
    json_decref(capture);
    snprintf(dst, sizeof dst, "%s/ingest/frames", sp->dir);
    snprintf(path, sizeof path, "%s/ingest", sp->dir);
    sl_result r = pl_mkdirs(path, err);
    if (!r)
        r = ingest_cached(src, dst, err);
    if (!r)
        r = read_session(sp, dst, NULL, err);
    return r;
}
