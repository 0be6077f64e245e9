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
#include <unistd.h>

#include "capture_private.h"

/* One file found in the source. */
typedef struct photo {
    char path[4096];
    char name[256];
    double when;   /* EXIF time in seconds (0 unknown) */
    long sequence; /* the number in the file name, -1 if none */
    int rank;      /* preference among a shot's files: rawest first (content_rank) */
    char kind[160]; /* what the file holds, for session.json */
    sl_meta meta;
    sl_frame_setup setup;
} photo;

typedef struct photos {
    photo *items;
    int count, cap;
    json_t *problems;
} photos;

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

/* Where a file stands among a shot's files, by what the file says it holds
 * (not its name): 0 camera raw, 1 scene-linear (float samples, as EXR; or
 * integer samples whose file names a scene-linear colour space, as a raw
 * converter's linear TIFF export does with its ICC profile), 2
 * display-referred deeper than 8 bits, 3 display-referred 8-bit. `kind`
 * says which in words. */
static int content_rank(const char *name, const sl_meta *meta, char *kind, size_t size)
{
    const char *format = meta->format[0] ? meta->format : "image";
    int bits = meta->bits_per_sample;
    if (sl_image_format_of_file(name) == SL_FORMAT_RAW || !strcmp(meta->format, "raw")) {
        snprintf(kind, size, "camera raw (%s)", format);
        return 0;
    }
    if (meta->is_float) {
        snprintf(kind, size, "scene-linear: %s %s samples", bits == 16 ? "half" : "float",
                 format);
        return 1;
    }
    bool assumed;
    const char *cs = sl_file_color_space(meta, &assumed);
    if (sl_file_is_scene_linear(meta)) {
        snprintf(kind, size, "scene-linear: %d-bit %s marked %s", bits, format, cs);
        return 1;
    }
    snprintf(kind, size, "display-referred: %d-bit %s (%s%s)", bits, format,
             cs ? cs : meta->colorspace, assumed ? ", assumed" : "");
    return bits > 8 ? 2 : 3;
}

static sl_result scan(const char *dir, const char *rel, photos *s, int depth, sl_error *err)
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
            photo *n = realloc(s->items, (size_t)cap * sizeof *n);
            if (!n) {
                sl_meta_free(&meta);
                r = sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", dir);
                break;
            }
            s->items = n;
            s->cap = cap;
        }
        photo *x = &s->items[s->count++];
        snprintf(x->path, sizeof x->path, "%s", path);
        snprintf(x->name, sizeof x->name, "%s", name);
        x->when = exif_seconds(meta.datetime);
        sl_exif_extra extra;
        sl_exif_extra_file(path, &extra);
        /* Bodies in continuous drive shoot several frames a second: the
         * EXIF sub-second field orders them (else exposure and sequence). */
        if (x->when > 0 && extra.subsec >= 0)
            x->when += extra.subsec;
        sl_frame_setup_fill(&x->setup, &meta, &extra, w, h);
        x->sequence = sequence_of(e->d_name);
        x->rank = content_rank(e->d_name, &meta, x->kind, sizeof x->kind);
        /* a broken EXIF rational reads back as infinity: unknown */
        if (!isfinite(meta.exposure_time))
            meta.exposure_time = 0;
        x->meta = meta;
    }
    closedir(d);
    return r;
}

/* A shot's files: rawest first, then the deepest samples, then by name. */
static int cmp_format(const void *a, const void *b)
{
    const photo *x = a, *y = b;
    if (x->rank != y->rank)
        return x->rank < y->rank ? -1 : 1;
    int bx = x->meta.bits_per_sample, by = y->meta.bits_per_sample;
    if (bx != by)
        return bx > by ? -1 : 1;
    return strcmp(x->name, y->name);
}

/* The camera model that took a photograph (make, model). */
static int cmp_camera(const photo *x, const photo *y)
{
    int c = strcasecmp(x->setup.make, y->setup.make);
    return c ? c : strcasecmp(x->setup.model, y->setup.model);
}

/* By EXIF time (with its sub-second part when the camera writes one), then
 * exposure (a bracket is shot within a second or two), then the sequence
 * number, then the camera (two may share a second and a number). */
static int cmp_photo(const void *a, const void *b)
{
    const photo *x = a, *y = b;
    if (x->when != y->when)
        return x->when < y->when ? -1 : 1;
    if (x->meta.exposure_time != y->meta.exposure_time)
        return x->meta.exposure_time < y->meta.exposure_time ? -1 : 1;
    if (x->sequence != y->sequence)
        return x->sequence < y->sequence ? -1 : 1;
    int c = cmp_camera(x, y);
    return c ? c : cmp_format(a, b);
}

/* Files of one shot: the same camera, EXIF time (known), exposure and file
 * number, and the same body serial where both files tell it (the reader
 * finds none in some raw formats, CR3 among them, that the JPEG beside
 * them has). */
static bool same_shot(const photo *a, const photo *b)
{
    double ta = a->meta.exposure_time, tb = b->meta.exposure_time;
    const char *sa = a->setup.serial, *sb = b->setup.serial;
    return a->when > 0 && a->when == b->when && a->sequence >= 0 &&
           a->sequence == b->sequence && ta > 0 && tb > 0 && fabs(log2(ta / tb)) < 0.1 &&
           !cmp_camera(a, b) && (!sa[0] || !sb[0] || !strcmp(sa, sb));
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
static sl_result copy_shot_file(const photo *x, const char *dir, const char *stem, int n,
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

/* A shot: files [first, first + count) of the sorted photographs, the
 * rawest first; its setup is that file's. */
typedef struct shot {
    int first, count;
    int group;
} shot;

/* The shots of one setup, grouped into views and brackets as they come. */
typedef struct setup_group {
    const sl_frame_setup *setup;
    int frames, first_shot, last_shot;
    json_t *view, *brackets, *bracket; /* the current ones, borrowed */
    int v, b, k;                       /* their numbers, and the next frame's */
    double last_when;                  /* of the group's previous shot */
} setup_group;

/* Sorts the photographs and cuts them into shots. */
static sl_result find_shots(photos *s, shot **out, int *count, sl_error *err)
{
    qsort(s->items, (size_t)s->count, sizeof *s->items, cmp_photo);
    shot *shots = malloc((size_t)s->count * sizeof *shots);
    if (!shots)
        return sl_error_set(err, SL_ERR_NOMEM, "ingest: out of memory");
    int n = 0;
    for (int i = 0; i < s->count;) {
        int m = 1;
        while (i + m < s->count && same_shot(&s->items[i], &s->items[i + m]))
            m++;
        /* Formats may round the exposure differently: order the shot's
         * files by format here, not by their exposures. */
        qsort(&s->items[i], (size_t)m, sizeof *s->items, cmp_format);
        shots[n++] = (shot){i, m, -1};
        i += m;
    }
    *out = shots;
    *count = n;
    return SL_OK;
}

/* Puts each shot in the group of its setup, a new group for a new setup. */
static sl_result group_by_setup(const photos *s, shot *shots, int n, setup_group **out,
                                int *count, sl_error *err)
{
    setup_group *g = NULL;
    int ng = 0;
    char why[8];
    for (int j = 0; j < n; j++) {
        const sl_frame_setup *setup = &s->items[shots[j].first].setup;
        int k = 0;
        while (k < ng && sl_frame_setup_differs(g[k].setup, setup, why, sizeof why))
            k++;
        if (k == ng) {
            setup_group *more = realloc(g, (size_t)(ng + 1) * sizeof *g);
            if (!more) {
                free(g);
                return sl_error_set(err, SL_ERR_NOMEM, "ingest: out of memory");
            }
            g = more;
            g[ng++] = (setup_group){.setup = setup, .first_shot = j};
        }
        shots[j].group = k;
        g[k].frames++;
        g[k].last_shot = j;
    }
    *out = g;
    *count = ng;
    return SL_OK;
}

/* "first..last (N frames)" of a group, by the names in the source. */
static void group_name(const photos *s, const shot *shots, const setup_group *g, char *buf,
                       size_t size)
{
    const char *first = s->items[shots[g->first_shot].first].name;
    const char *last = s->items[shots[g->last_shot].first].name;
    if (g->frames == 1)
        snprintf(buf, size, "%s (1 frame)", first);
    else
        snprintf(buf, size, "%s..%s (%d frames)", first, last, g->frames);
}

/* One line for each two setups whose shots follow each other in time:
 * what was kept apart and why. */
static sl_result split_lines(const photos *s, const shot *shots, int n, const setup_group *g,
                             int ng, json_t *lines, sl_error *err)
{
    bool *told = calloc((size_t)ng * (size_t)ng, sizeof *told);
    if (!told)
        return sl_error_set(err, SL_ERR_NOMEM, "ingest: out of memory");
    for (int j = 1; j < n; j++) {
        int a = shots[j - 1].group, b = shots[j].group;
        if (a > b) {
            int t = a;
            a = b;
            b = t;
        }
        if (a == b || told[a * ng + b])
            continue;
        told[a * ng + b] = true;
        char why[1024], first[600], second[600], line[2400];
        sl_frame_setup_differs(g[a].setup, g[b].setup, why, sizeof why);
        group_name(s, shots, &g[a], first, sizeof first);
        group_name(s, shots, &g[b], second, sizeof second);
        snprintf(line, sizeof line, "%s and %s not grouped together: %s", first, second, why);
        json_array_append_new(lines, json_string(line));
    }
    free(told);
    return SL_OK;
}

/* A view of a group's setup numbered `v`, appended to `views`. */
static void start_view(setup_group *g, json_t *views, int v)
{
    g->view = json_object();
    g->brackets = json_array();
    json_object_set_new(g->view, "view", json_integer(v));
    json_object_set_new(g->view, "camera", sl_frame_setup_json(g->setup));
    json_object_set_new(g->view, "brackets", g->brackets);
    json_array_append_new(views, g->view);
    g->bracket = NULL;
    g->v = v;
    g->b = 0;
}

/* Copies a shot's files as STEM and STEM_N (siblings), their names added to
 * `written`, and returns its frame entry. */
static sl_result copy_shot(const photo *files, int n, const char *dir, const char *stem,
                           sl_progress *progress, json_t *written, json_t **frame, sl_error *err)
{
    json_t *f = json_object(), *siblings = json_array();
    double t = 0, fn = 0, iso = 0;
    sl_result r = SL_OK;
    for (int m = 0; m < n && !r; m++) {
        const photo *y = &files[m];
        char name[64], sha[65];
        if ((r = copy_shot_file(y, dir, stem, m, name, sha, err)))
            break;
        json_array_append_new(written, json_string(name));
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
            json_object_set_new(f, "content", json_string(y->kind));
        } else {
            json_array_append_new(siblings,
                                  json_pack("{s:s, s:s, s:s, s:s}", "file", name, "source",
                                            y->name, "sha256", sha, "content", y->kind));
        }
    }
    if (r) {
        json_decref(f);
        json_decref(siblings);
        return r;
    }
    json_object_set_new(f, "exposure_time", t > 0 ? json_real(t) : json_null());
    json_object_set_new(f, "f_number", fn > 0 ? json_real(fn) : json_null());
    json_object_set_new(f, "iso", iso > 0 ? json_real(iso) : json_null());
    json_object_set_new(f, "measured_ratio", json_null());
    if (json_array_size(siblings)) {
        /* Why this file and not the others (kept as alternates). */
        char why[400];
        snprintf(why, sizeof why, "the most linear and deepest of the shot's %d files (%s)", n,
                 files[1].rank > files[0].rank    ? "more linear than the others"
                 : files[1].meta.bits_per_sample < files[0].meta.bits_per_sample
                     ? "as linear, more bits"
                     : "as linear and deep as another: first by name");
        json_object_set_new(f, "chosen", json_string(why));
        json_object_set_new(f, "siblings", siblings);
    } else {
        json_decref(siblings);
    }
    *frame = f;
    return SL_OK;
}

/* Within each setup's shots in time order: a pause longer than `gap`
 * starts a new view, a repeated exposure a new bracket. Views are numbered
 * by their first shot's time, whatever their setup. */
static sl_result group_and_copy(const photos *s, const shot *shots, int n, setup_group *groups,
                                double gap, const char *dir, sl_progress *progress,
                                json_t *views, json_t *written, int *frames, int *nviews,
                                sl_error *err)
{
    sl_result r = SL_OK;
    for (int j = 0; j < n && !r; j++) {
        const photo *x = &s->items[shots[j].first];
        setup_group *g = &groups[shots[j].group];
        if (!g->view || (x->when > 0 && g->last_when > 0 && x->when - g->last_when > gap))
            start_view(g, views, (*nviews)++);
        g->last_when = x->when;
        /* A repeated exposure starts the next bracket. */
        if (!g->bracket ||
            in_bracket(json_object_get(g->bracket, "frames"), x->meta.exposure_time)) {
            g->bracket = json_object();
            json_object_set_new(g->bracket, "frames", json_array());
            json_array_append_new(g->brackets, g->bracket);
            g->b = (int)json_array_size(g->brackets) - 1;
            g->k = 0;
        }
        char stem[48];
        snprintf(stem, sizeof stem, "v%02d_b%02d_f%02d", g->v, g->b, g->k++);
        json_t *frame;
        if ((r = copy_shot(x, shots[j].count, dir, stem, progress, written, &frame, err)))
            break;
        json_array_append_new(json_object_get(g->bracket, "frames"), frame);
        (*frames)++;
    }
    return r;
}

/* One problem line for each bracket a merge cannot take as it is: frames
 * with no EXIF exposure time (grouped by time and name alone; a merge needs
 * their times given), or a single frame (nothing to merge: often a bracket
 * shot slower than --gap). */
static void note_unmergeable(json_t *views, json_t *problems, double gap)
{
    size_t vi, bi, fi;
    json_t *view, *bracket, *frame;
    json_array_foreach(views, vi, view)
    {
        json_array_foreach(json_object_get(view, "brackets"), bi, bracket)
        {
            json_t *fr = json_object_get(bracket, "frames");
            int missing = 0;
            const char *first = NULL;
            json_array_foreach(fr, fi, frame)
            {
                if (!json_is_number(json_object_get(frame, "exposure_time"))) {
                    missing++;
                    first = first ? first : json_string_value(json_object_get(frame, "source"));
                }
            }
            char msg[512];
            if (json_array_size(fr) == 1) {
                char alone[160] = "";
                if (json_array_size(json_object_get(view, "brackets")) == 1)
                    snprintf(alone, sizeof alone,
                             " (alone in its view: kept apart by its setup, or by a pause "
                             "longer than the gap, %g s)",
                             gap);
                snprintf(msg, sizeof msg, "view %d bracket %d: one frame (%s): nothing to merge%s",
                         (int)json_integer_value(json_object_get(view, "view")), (int)bi,
                         json_string_value(json_object_get(json_array_get(fr, 0), "source")),
                         alone);
                json_array_append_new(problems, json_string(msg));
            }
            if (!missing)
                continue;
            snprintf(msg, sizeof msg,
                     "view %d bracket %d: %d of %zu frames (%s%s) have no EXIF exposure time: "
                     "grouped by time and name only; merge needs their times (--times)",
                     (int)json_integer_value(json_object_get(view, "view")), (int)bi, missing,
                     json_array_size(fr), first ? first : "?", missing > 1 ? ", ..." : "");
            json_array_append_new(problems, json_string(msg));
        }
    }
}

/* A failed ingest takes back what it copied (the frames stay on the card),
 * and the folder when it made it. */
static void remove_written(const char *dir, json_t *written, bool made_dir)
{
    size_t i;
    json_t *name;
    json_array_foreach(written, i, name)
    {
        char path[4096];
        if (!sl_capture_path(path, sizeof path, dir, json_string_value(name), NULL))
            unlink(path);
    }
    if (made_dir)
        rmdir(dir);
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
    photos s = {.problems = json_array()};
    r = scan(src, "", &s, 0, err);
    if (!r && s.count == 0)
        r = sl_error_set(err, SL_ERR_INPUT, "%s: no photographs found", src);
    shot *shots = NULL;
    setup_group *groups = NULL;
    int nshots = 0, ngroups = 0;
    json_t *views = json_array(), *splits = json_array();
    if (!r)
        r = find_shots(&s, &shots, &nshots, err);
    if (!r)
        r = group_by_setup(&s, shots, nshots, &groups, &ngroups, err);
    if (!r)
        r = split_lines(&s, shots, nshots, groups, ngroups, splits, err);
    bool made_dir = false;
    if (!r && stat(dir, &st) != 0) {
        if (mkdir(dir, 0755) != 0)
            r = sl_error_set(err, SL_ERR_IO, "%s: cannot create: %s", dir, strerror(errno));
        made_dir = !r;
    }
    json_t *written = json_array();
    if (!r) {
        if (progress)
            progress->total = s.count;
        r = group_and_copy(&s, shots, nshots, groups, gap, dir, progress, views, written, frames,
                           nviews, err);
    }
    for (int i = 0; i < s.count; i++)
        sl_meta_free(&s.items[i].meta);
    free(s.items);
    free(shots);
    free(groups);
    if (!r) {
        size_t i;
        json_t *line;
        json_array_foreach(splits, i, line)
            sl_log(SL_LOG_WARN, "%s: %s", src, json_string_value(line));
        note_unmergeable(views, s.problems, gap);
        json_t *camera = json_object();
        json_object_set_new(camera, "backend", json_string("folder"));
        json_object_set_new(camera, "port", json_string(src));
        r = sl_session_write_json(dir, camera, views, s.problems, splits, err);
    } else {
        json_decref(views);
        json_decref(splits);
        json_decref(s.problems);
    }
    if (r) {
        remove_written(dir, written, made_dir);
        *frames = *nviews = 0;
    }
    json_decref(written);
    return r;
}
