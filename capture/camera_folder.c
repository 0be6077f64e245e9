/* SPDX-License-Identifier: BSD-3-Clause */
/* Ingest: a card or a folder of photographs grouped into views and brackets
 * by EXIF time, exposure and sequence, copied into a session folder. */
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <time.h>

#include "capture_private.h"

typedef struct shot {
    char path[4096];
    char name[256];
    double when;   /* EXIF time in seconds (0 unknown) */
    long sequence; /* the number in the file name, -1 if none */
    int rank;      /* format preference among a shot's files: raw first */
    sl_meta meta;
} shot;

typedef struct shots {
    shot *items;
    int count, cap;
    json_t *problems;
} shots;

static double exif_seconds(const char *dt)
{
    struct tm tm;
    memset(&tm, 0, sizeof tm);
    if (sscanf(dt, "%d:%d:%d %d:%d:%d", &tm.tm_year, &tm.tm_mon, &tm.tm_mday, &tm.tm_hour,
               &tm.tm_min, &tm.tm_sec) != 6)
        return 0;
    tm.tm_year -= 1900;
    tm.tm_mon -= 1;
    return (double)timegm(&tm);
}

static long sequence_of(const char *name)
{
    long best = -1;
    for (const char *c = name; *c; c++)
        if (*c >= '0' && *c <= '9' && (c == name || c[-1] < '0' || c[-1] > '9'))
            best = strtol(c, NULL, 10);
    return best;
}

int sl_capture_file_rank(const char *name)
{
    static const char *const order[] = {"exr", "tif", "tiff", "png"};
    if (sl_image_format_of_file(name) == SL_FORMAT_RAW)
        return 0;
    const char *dot = strrchr(name, '.');
    for (int i = 0; dot && i < 4; i++)
        if (!strcasecmp(dot + 1, order[i]))
            return i < 3 ? 1 : 2;
    return 3;
}

static sl_result scan(const char *dir, const char *rel, shots *s, int depth, sl_error *err)
{
    DIR *d = opendir(dir);
    if (!d)
        return sl_error_set(err, SL_ERR_IO, "%s: cannot read: %s", dir, strerror(errno));
    struct dirent *e;
    sl_result r = SL_OK;
    while (!r && (e = readdir(d))) {
        if (e->d_name[0] == '.')
            continue;
        char path[4096], name[256];
        if (snprintf(path, sizeof path, "%s/%s", dir, e->d_name) >= (int)sizeof path)
            continue;
        snprintf(name, sizeof name, "%.120s%s%.120s", rel, rel[0] ? "/" : "", e->d_name);
        struct stat st;
        if (stat(path, &st) != 0)
            continue;
        if (S_ISDIR(st.st_mode)) {
            if (depth < 4)
                r = scan(path, name, s, depth + 1, err);
            continue;
        }
        if (!S_ISREG(st.st_mode))
            continue;
        sl_meta meta;
        int w, h, c;
        sl_error perr;
        if (st.st_size == 0 || sl_photo_read_meta(path, &meta, &w, &h, &c, &perr)) {
            char msg[512];
            snprintf(msg, sizeof msg, "%s: not a photograph, skipped", name);
            json_array_append_new(s->problems, json_string(msg));
            continue;
        }
        if (s->count == s->cap) {
            int cap = s->cap ? 2 * s->cap : 64;
            shot *n = realloc(s->items, (size_t)cap * sizeof *n);
            if (!n) {
                sl_meta_free(&meta);
                r = sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", dir);
                break;
            }
            s->items = n;
            s->cap = cap;
        }
        shot *x = &s->items[s->count++];
        snprintf(x->path, sizeof x->path, "%s", path);
        snprintf(x->name, sizeof x->name, "%s", name);
        x->when = exif_seconds(meta.datetime);
        /* Bodies in continuous drive shoot several frames a second: the
         * EXIF sub-second field orders them (else exposure and sequence). */
        double subsec = x->when > 0 ? sl_exif_subsec_file(path) : -1;
        if (subsec >= 0)
            x->when += subsec;
        x->sequence = sequence_of(e->d_name);
        x->rank = sl_capture_file_rank(e->d_name);
        /* a broken EXIF rational reads back as infinity: unknown */
        if (!isfinite(meta.exposure_time))
            meta.exposure_time = 0;
        x->meta = meta;
    }
    closedir(d);
    return r;
}

/* A shot's files: rawest first, then by name. */
static int cmp_format(const void *a, const void *b)
{
    const shot *x = a, *y = b;
    return x->rank != y->rank ? (x->rank < y->rank ? -1 : 1) : strcmp(x->name, y->name);
}

/* By EXIF time (with its sub-second part when the camera writes one), then
 * exposure (a bracket is shot within a second or two), then the sequence
 * number. */
static int cmp_shot(const void *a, const void *b)
{
    const shot *x = a, *y = b;
    if (x->when != y->when)
        return x->when < y->when ? -1 : 1;
    if (x->meta.exposure_time != y->meta.exposure_time)
        return x->meta.exposure_time < y->meta.exposure_time ? -1 : 1;
    if (x->sequence != y->sequence)
        return x->sequence < y->sequence ? -1 : 1;
    return cmp_format(a, b);
}

/* Files of one shot: the same EXIF time (known), exposure and file number. */
static bool same_shot(const shot *a, const shot *b)
{
    double ta = a->meta.exposure_time, tb = b->meta.exposure_time;
    return a->when > 0 && a->when == b->when && a->sequence >= 0 &&
           a->sequence == b->sequence && ta > 0 && tb > 0 && fabs(log2(ta / tb)) < 0.1;
}

static bool in_bracket(json_t *frames, double t)
{
    size_t i;
    json_t *f;
    json_array_foreach(frames, i, f)
    {
        double u = json_number_value(json_object_get(f, "exposure_time"));
        if (u > 0 && t > 0 && fabs(log2(u / t)) < 0.1)
            return true;
    }
    return false;
}

static sl_result copy_file(const char *from, const char *to, char sha[65], sl_error *err)
{
    FILE *f = fopen(from, "rb");
    if (!f)
        return sl_error_set(err, SL_ERR_NOT_FOUND, "%s: cannot open", from);
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    unsigned char *data = n > 0 ? malloc((size_t)n) : NULL;
    bool ok = data && fread(data, 1, (size_t)n, f) == (size_t)n;
    fclose(f);
    if (!ok) {
        free(data);
        return sl_error_set(err, SL_ERR_IO, "%s: read failed", from);
    }
    sl_sha256_hex(data, (size_t)n, sha);
    sl_result r = sl_write_file_atomic(to, data, (size_t)n, err);
    free(data);
    return r;
}

/* Copies one file of a shot as STEM.ext (the frame's file) or STEM_N.ext
 * (its N-th sibling); never overwrites. */
static sl_result copy_shot_file(const shot *x, const char *dir, const char *stem, int n,
                                char name[64], char sha[65], sl_error *err)
{
    const char *dot = strrchr(x->name, '.');
    char suffix[16] = "";
    if (n > 0)
        snprintf(suffix, sizeof suffix, "_%d", n);
    snprintf(name, 64, "%s%s%.8s", stem, suffix, dot ? dot : "");
    for (char *c = name; *c; c++)
        if (*c >= 'A' && *c <= 'Z')
            *c = (char)(*c - 'A' + 'a');
    char to[4096];
    struct stat st;
    sl_result r = sl_capture_path(to, sizeof to, dir, name, err);
    if (r)
        return r;
    if (stat(to, &st) == 0)
        return sl_error_set(err, SL_ERR_USAGE, "%s: exists; never overwritten", to);
    return copy_file(x->path, to, sha, err);
}

sl_result sl_ingest(const char *src, const char *dir, double gap, sl_progress *progress,
                    int *frames, int *nviews, sl_error *err)
{
    *frames = *nviews = 0;
    if (gap <= 0)
        gap = 10.0;
    struct stat st;
    if (stat(src, &st) != 0 || !S_ISDIR(st.st_mode))
        return sl_error_set(err, SL_ERR_NOT_FOUND, "%s: not a folder", src);
    char jp[4096];
    sl_result r;
    if ((r = sl_capture_path(jp, sizeof jp, dir, SL_SESSION_NAME, err)))
        return r;
    if (stat(jp, &st) == 0)
        return sl_error_set(err, SL_ERR_USAGE, "%s: already holds a session; never overwritten",
                            dir);
    shots s = {.problems = json_array()};
    r = scan(src, "", &s, 0, err);
    if (!r && s.count == 0)
        r = sl_error_set(err, SL_ERR_INPUT, "%s: no photographs found", src);
    if (!r && stat(dir, &st) != 0 && mkdir(dir, 0755) != 0)
        r = sl_error_set(err, SL_ERR_IO, "%s: cannot create: %s", dir, strerror(errno));
    json_t *views = json_array();
    if (!r) {
        qsort(s.items, (size_t)s.count, sizeof *s.items, cmp_shot);
        if (progress)
            progress->total = s.count;
        json_t *view = NULL, *brackets = NULL, *bracket = NULL;
        int v = -1, b = 0, k = 0;
        for (int i = 0; i < s.count && !r; i++) {
            shot *x = &s.items[i];
            bool new_view = !view || (x->when > 0 && s.items[i - 1].when > 0 &&
                                      x->when - s.items[i - 1].when > gap);
            if (new_view) {
                view = json_object();
                brackets = json_array();
                json_object_set_new(view, "view", json_integer(++v));
                json_object_set_new(view, "brackets", brackets);
                json_array_append_new(views, view);
                bracket = NULL;
                b = 0;
            }
            /* A repeated exposure starts the next bracket. */
            if (!bracket || in_bracket(json_object_get(bracket, "frames"), x->meta.exposure_time)) {
                bracket = json_object();
                json_object_set_new(bracket, "frames", json_array());
                json_array_append_new(brackets, bracket);
                if (json_array_size(brackets) > 1)
                    b++;
                k = 0;
            }
            /* The shot's other files follow it in the sort order. */
            int n = 1;
            while (i + n < s.count && same_shot(x, &s.items[i + n]))
                n++;
            /* Formats may round the exposure differently: order the shot's
             * files by format here, not by their exposures. */
            qsort(x, (size_t)n, sizeof *x, cmp_format);
            char stem[48];
            snprintf(stem, sizeof stem, "v%02d_b%02d_f%02d", v, b, k++);
            json_t *f = json_object(), *siblings = json_array();
            double t = 0, fn = 0, iso = 0;
            for (int m = 0; m < n && !r; m++) {
                const shot *y = &s.items[i + m];
                char name[64], sha[65];
                if ((r = copy_shot_file(y, dir, stem, m, name, sha, err)))
                    break;
                sl_progress_add(progress, 1);
                /* OpenImageIO drops some EXIF from some formats (ISO from
                 * TIFF): a sibling fills what the frame's file lacks. */
                t = t > 0 ? t : y->meta.exposure_time;
                fn = fn > 0 ? fn : y->meta.f_number;
                iso = iso > 0 ? iso : y->meta.iso;
                if (m == 0) {
                    json_object_set_new(f, "file", json_string(name));
                    json_object_set_new(f, "source", json_string(y->name));
                    json_object_set_new(f, "sha256", json_string(sha));
                } else {
                    json_array_append_new(siblings,
                                          json_pack("{s:s, s:s, s:s}", "file", name, "source",
                                                    y->name, "sha256", sha));
                }
            }
            if (r) {
                json_decref(f);
                json_decref(siblings);
                break;
            }
            json_object_set_new(f, "exposure_time", t > 0 ? json_real(t) : json_null());
            json_object_set_new(f, "f_number", fn > 0 ? json_real(fn) : json_null());
            json_object_set_new(f, "iso", iso > 0 ? json_real(iso) : json_null());
            json_object_set_new(f, "measured_ratio", json_null());
            if (json_array_size(siblings))
                json_object_set_new(f, "siblings", siblings);
            else
                json_decref(siblings);
            json_array_append_new(json_object_get(bracket, "frames"), f);
            i += n - 1;
            (*frames)++;
        }
        *nviews = v + 1;
    }
    for (int i = 0; i < s.count; i++)
        sl_meta_free(&s.items[i].meta);
    free(s.items);
    if (r) {
        json_decref(views);
        json_decref(s.problems);
        *frames = *nviews = 0;
        return r;
    }
    json_t *camera = json_object();
    json_object_set_new(camera, "backend", json_string("folder"));
    json_object_set_new(camera, "port", json_string(src));
    return sl_session_write_json(dir, camera, views, s.problems, err);
}
