/* SPDX-License-Identifier: BSD-3-Clause */
/* The capture loop: views x bracket frames, each set, triggered, downloaded,
 * written atomically, checksummed, verified (EXIF exposure and the pixel
 * ratio to the previous frame) and journalled before the next trigger. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "camera_backend.h"
#include "capture_private.h"

typedef struct run_state {
    sl_camera *camera;
    const sl_capture_options *o;
    const char *dir;
    const double *times;
    int count, views;
    bool *done;       /* views x count: accepted frames */
    bool *stepped;    /* views: head moved for this view */
    sl_image prev;    /* the previous accepted frame of the view, linear */
    double prev_time; /* its EXIF exposure time */
    int prev_view;
    sl_image_format format; /* the plan's (KEEP: the camera's, untouched) */
    char format_label[64];  /* the camera's label for it */
    bool reset_format;      /* a frame came in another format: set it again */
    int shots_saved;        /* this run's, for options' disk_full_at */
} run_state;

/* One file of a shot as written into the session folder. */
typedef struct saved_file {
    char file[64];
    char source[256];
    char sha[65];
    sl_image_format kind;
} saved_file;

/* Linear light for ratio measurement: 8/16-bit photos are sRGB-encoded
 * (in-camera JPEG), camera raw and float files are linear. */
static void linearize(sl_image *img, const sl_meta *meta)
{
    if (meta->is_float || !strcmp(meta->format, "raw"))
        return;
    size_t n = (size_t)img->width * (size_t)img->height * (size_t)img->channels;
    for (size_t i = 0; i < n; i++)
        img->data[i] = sl_srgb_to_linear(img->data[i]);
}

/* Median of cur/prev over pixels well exposed in both (0 when too few):
 * between 0.005 and 0.85 of white (1, camera raw included: core reads it
 * relative to the white level). */
static double measure_ratio(const sl_image *prev, const sl_image *cur)
{
    if (!prev->data || prev->width != cur->width || prev->height != cur->height ||
        prev->channels != cur->channels)
        return 0;
    const float lo = 0.005f, hi = 0.85f;
    size_t n = (size_t)cur->width * (size_t)cur->height, k = 0;
    double *r = malloc(n * sizeof *r);
    if (!r)
        return 0;
    int c = cur->channels > 1 ? 1 : 0;
    for (size_t i = 0; i < n; i++) {
        double a = prev->data[i * (size_t)cur->channels + (size_t)c];
        double b = cur->data[i * (size_t)cur->channels + (size_t)c];
        if (a > lo && a < hi && b > lo && b < hi)
            r[k++] = b / a;
    }
    double m = 0;
    if (k >= 32) {
        qsort(r, k, sizeof *r, sl_cmp_double);
        m = k % 2 ? r[k / 2] : 0.5 * (r[k / 2 - 1] + r[k / 2]);
    }
    free(r);
    return m;
}

/* ".nef" from "/store/DSC_0001.NEF" (".jpg" when there is none). */
static void extension_of(const char *source, char ext[16])
{
    const char *dot = strrchr(source, '.');
    snprintf(ext, 16, "%s", !dot || strchr(dot, '/') || strlen(dot) > 8 ? ".jpg" : dot);
    for (char *c = ext; *c; c++)
        if (*c >= 'A' && *c <= 'Z')
            *c = (char)(*c - 'A' + 'a');
}

/* The names of a shot's files: v00_f03.nef and v00_f03.jpg, for a second
 * attempt v00_f03_r2.nef ...: the first suffix free for every file of the
 * shot, so nothing on disk is ever reused or overwritten. A second file
 * with the same extension gets _2. */
static sl_result shot_names(const run_state *s, int v, int i, const sl_camera_shot *shot,
                            saved_file *out, sl_error *err)
{
    for (int n = 1; n < 1000; n++) {
        bool free_all = true;
        for (int k = 0; k < shot->count && free_all; k++) {
            char ext[16], stem[32], path[4096];
            extension_of(shot->files[k].source, ext);
            int same = 0;
            for (int j = 0; j < k; j++)
                same += !strcmp(strrchr(out[j].file, '.'), ext);
            if (n == 1)
                snprintf(stem, sizeof stem, "v%02d_f%02d", v, i);
            else
                snprintf(stem, sizeof stem, "v%02d_f%02d_r%d", v, i, n);
            if (same)
                snprintf(out[k].file, sizeof out[k].file, "%s_%d%s", stem, same + 1, ext);
            else
                snprintf(out[k].file, sizeof out[k].file, "%s%s", stem, ext);
            sl_result r = sl_capture_path(path, sizeof path, s->dir, out[k].file, err);
            if (r)
                return r;
            struct stat st;
            free_all = stat(path, &st) != 0 && errno == ENOENT;
        }
        if (free_all)
            return SL_OK;
    }
    return sl_error_set(err, SL_ERR_IO, "%s: no free name for view %d frame %d", s->dir, v, i);
}

/* The rawest file first, as ingest orders a shot's files (files of one
 * rank stay in the camera's order). */
static void order_files(sl_camera_shot *shot)
{
    for (int k = 1; k < shot->count; k++)
        for (int j = k; j > 0 && sl_capture_file_rank(shot->files[j].source) <
                                     sl_capture_file_rank(shot->files[j - 1].source);
             j--) {
            sl_camera_file t = shot->files[j];
            shot->files[j] = shot->files[j - 1];
            shot->files[j - 1] = t;
        }
}

/* Writes every file of the shot atomically with its SHA-256. */
static sl_result save_shot(run_state *s, int v, int i, sl_camera_shot *shot, saved_file *out,
                           sl_error *err)
{
    order_files(shot);
    sl_result r = shot_names(s, v, i, shot, out, err);
    bool disk_full = !r && ++s->shots_saved == s->o->disk_full_at;
    for (int k = 0; k < shot->count && !r; k++) {
        char path[4096];
        const sl_camera_file *f = &shot->files[k];
        if ((r = sl_capture_path(path, sizeof path, s->dir, out[k].file, err)))
            break;
        /* The injected fault fails the shot's last file as the writer
         * does when the disk fills. */
        if (disk_full && k == shot->count - 1) {
            r = sl_error_set(err, SL_ERR_IO, "%s: write failed: %s", path, strerror(ENOSPC));
            break;
        }
        if ((r = sl_write_file_atomic(path, f->data, f->size, err)))
            break;
        snprintf(out[k].source, sizeof out[k].source, "%s", f->source);
        sl_sha256_hex(f->data, f->size, out[k].sha);
        out[k].kind = sl_image_format_of_file(f->source);
    }
    return r;
}

/* The file the verification decodes: the JPEG when there is one (what the
 * previous frame was measured on, and fast), else the first. */
static int verify_index(const saved_file *f, int n)
{
    for (int k = 0; k < n; k++)
        if (f[k].kind == SL_FORMAT_JPEG)
            return k;
    return 0;
}

/* The format a shot's files make up. */
static sl_image_format shot_format(const saved_file *f, int n)
{
    bool raw = false, jpeg = false, other = false;
    for (int k = 0; k < n; k++) {
        raw |= f[k].kind == SL_FORMAT_RAW;
        jpeg |= f[k].kind == SL_FORMAT_JPEG;
        other |= f[k].kind == SL_FORMAT_KEEP;
    }
    if (other)
        return SL_FORMAT_KEEP;
    return raw && jpeg ? SL_FORMAT_RAW_JPEG : raw ? SL_FORMAT_RAW : SL_FORMAT_JPEG;
}

/* "file", "source", "sha256" of the first file and "siblings" for the rest. */
static void journal_files(json_t *ev, const saved_file *f, int n)
{
    json_object_set_new(ev, "file", json_string(f[0].file));
    json_object_set_new(ev, "source", json_string(f[0].source));
    json_object_set_new(ev, "sha256", json_string(f[0].sha));
    if (n < 2)
        return;
    json_t *sib = json_array();
    for (int k = 1; k < n; k++)
        json_array_append_new(sib, json_pack("{s:s, s:s, s:s}", "file", f[k].file, "source",
                                             f[k].source, "sha256", f[k].sha));
    json_object_set_new(ev, "siblings", sib);
}

static sl_result journal_error(const run_state *s, int v, int i, int attempt, const sl_error *e,
                               sl_error *err)
{
    json_t *ev = json_object();
    json_object_set_new(ev, "event", json_string("error"));
    json_object_set_new(ev, "view", json_integer(v));
    json_object_set_new(ev, "index", json_integer(i));
    json_object_set_new(ev, "attempt", json_integer(attempt));
    json_object_set_new(ev, "code", json_string(sl_result_name(e->code)));
    json_object_set_new(ev, "message", json_string(e->message));
    sl_result r = sl_journal_event(s->dir, ev, err);
    json_decref(ev);
    return r;
}

static sl_result set_format(run_state *s, sl_error *err);

/* A shot the connection broke in the middle of (the JPEG landed, the raw
 * did not): its files are kept and journalled as an incomplete attempt, so
 * the frame is shot again under new names. */
static sl_result journal_incomplete(run_state *s, int v, int i, int attempt,
                                    sl_camera_shot *shot, const sl_error *why, sl_error *err)
{
    saved_file f[SL_SHOT_MAX_FILES];
    memset(f, 0, sizeof f);
    sl_result r = save_shot(s, v, i, shot, f, err);
    if (r)
        return r;
    json_t *ev = json_object();
    json_object_set_new(ev, "event", json_string("frame"));
    json_object_set_new(ev, "view", json_integer(v));
    json_object_set_new(ev, "bracket", json_integer(0));
    json_object_set_new(ev, "index", json_integer(i));
    json_object_set_new(ev, "attempt", json_integer(attempt));
    json_object_set_new(ev, "accepted", json_false());
    json_object_set_new(ev, "incomplete", json_true());
    journal_files(ev, f, shot->count);
    char reason[512];
    snprintf(reason, sizeof reason, "incomplete: %d of %d files arrived before: %.400s",
             shot->count, shot->expected, why->message);
    json_object_set_new(ev, "reason", json_string(reason));
    r = sl_journal_event(s->dir, ev, err);
    json_decref(ev);
    return r;
}

/* Closed loop on the decodable file: the EXIF exposure and the pixel ratio
 * to the previous accepted frame (two independent witnesses: the EXIF a
 * body writes can be wrong too, a stuck mechanism records the speed it was
 * asked for). A raw nothing can decode is checked by the configured speed
 * only. Fills rep; *img keeps the linear pixels when readable. */
static bool verify(run_state *s, int v, const char *path, sl_image_format kind, sl_image *img,
                   sl_meta *meta, sl_capture_report *rep, json_t *ev)
{
    double planned = rep->planned;
    double tol = s->o->tolerance_stops > 0 ? s->o->tolerance_stops : 1.0 / 3.0;
    sl_error rerr;
    bool readable = sl_photo_read(path, img, meta, &rerr) == SL_OK;
    if (!readable && kind == SL_FORMAT_RAW) {
        snprintf(rep->note, sizeof rep->note, "not measured: raw only (%.80s)", rerr.message);
        bool off = rep->configured > 0 && fabs(log2(rep->configured / planned)) > tol;
        if (off)
            snprintf(rep->reason, sizeof rep->reason,
                     "the camera's setting reads %.6g s, planned %.6g s", rep->configured, planned);
        return false;
    }
    if (!readable) {
        snprintf(rep->reason, sizeof rep->reason, "cannot read the file back: %.200s",
                 rerr.message);
        return false;
    }
    rep->reported = isfinite(meta->exposure_time) ? meta->exposure_time : 0;
    linearize(img, meta);
    if (s->prev.data && s->prev_view == v && s->prev_time > 0) {
        rep->measured_ratio =
            measure_ratio(&s->prev, img);
        rep->expected_ratio = planned / s->prev_time;
    }
    bool exif_bad = rep->reported > 0 && fabs(log2(rep->reported / planned)) > tol;
    bool pixels_bad =
        rep->measured_ratio > 0 &&
        fabs(log2(rep->measured_ratio / rep->expected_ratio)) > (tol > 0.5 ? tol : 0.5);
    json_object_set_new(ev, "exif_ok", rep->reported > 0 ? json_boolean(!exif_bad) : json_null());
    json_object_set_new(ev, "pixels_ok",
                        rep->measured_ratio > 0 ? json_boolean(!pixels_bad) : json_null());
    char exif_why[128] = "", pixel_why[96] = "";
    if (exif_bad)
        snprintf(exif_why, sizeof exif_why,
                 "the file says %.6g s, planned %.6g s, the camera's setting reads %.6g s",
                 rep->reported, planned, rep->configured);
    if (pixels_bad)
        snprintf(pixel_why, sizeof pixel_why,
                 "pixels are %.3g x the previous frame, the exposures say %.3g x",
                 rep->measured_ratio, rep->expected_ratio);
    if (exif_bad || pixels_bad)
        snprintf(rep->reason, sizeof rep->reason, "%s%s%s (the camera ignored the setting)",
                 exif_why, exif_bad && pixels_bad ? "; " : "", pixel_why);
    return true;
}

static json_t *positive(double v)
{
    return v > 0 ? json_real(v) : json_null();
}

/* One attempt at frame (v, i). *accepted tells whether it passed. */
static sl_result shoot(run_state *s, int v, int i, int attempt, bool *accepted, sl_error *err)
{
    const sl_capture_options *o = s->o;
    double planned = s->times[i];
    sl_capture_report rep;
    memset(&rep, 0, sizeof rep);
    rep.view = v;
    rep.index = i;
    rep.views = s->views;
    rep.count = s->count;
    rep.attempt = attempt;
    rep.planned = planned;
    *accepted = false;

    sl_result r;
    if (s->reset_format && (r = set_format(s, err)))
        return r;
    s->reset_format = false;
    sl_camera_settings set = {planned, 0, 0};
    if ((r = sl_camera_set(s->camera, &set, err)))
        return r;
    sl_camera_settings now;
    if (!sl_camera_get(s->camera, &now, NULL))
        rep.configured = now.exposure_time;
    sl_camera_shot shot;
    if ((r = sl_camera_capture(s->camera, &shot, err))) {
        if (shot.count > 0) {
            sl_error why = *err;
            sl_error jerr;
            if (journal_incomplete(s, v, i, attempt, &shot, &why, &jerr))
                *err = jerr;
            else
                *err = why;
        }
        sl_camera_shot_free(&shot);
        return r;
    }
    saved_file f[SL_SHOT_MAX_FILES];
    memset(f, 0, sizeof f);
    r = save_shot(s, v, i, &shot, f, err);
    int n = shot.count;
    rep.files = n;
    rep.busy_retries = shot.busy_retries;
    sl_camera_shot_free(&shot);
    if (r)
        return r;
    snprintf(rep.file, sizeof rep.file, "%s", f[0].file);
    snprintf(rep.source, sizeof rep.source, "%s", f[0].source);

    int vi = verify_index(f, n);
    char path[4096];
    sl_image img = {0};
    sl_meta meta;
    sl_meta_init(&meta);
    json_t *ev = json_object(), *checks = json_object();
    bool readable = !sl_capture_path(path, sizeof path, s->dir, f[vi].file, NULL) &&
                    verify(s, v, path, f[vi].kind, &img, &meta, &rep, checks);
    sl_image_format got = shot_format(f, n);
    if (s->format != SL_FORMAT_KEEP && got != s->format) {
        snprintf(rep.reason, sizeof rep.reason,
                 "the camera delivered %s, the plan is %s (it ignored the image format setting)",
                 got == SL_FORMAT_KEEP ? "other files" : sl_image_format_name(got),
                 sl_image_format_name(s->format));
        s->reset_format = true;
    }
    rep.accepted = !rep.reason[0];

    json_object_set_new(ev, "event", json_string("frame"));
    json_object_set_new(ev, "view", json_integer(v));
    json_object_set_new(ev, "bracket", json_integer(0));
    json_object_set_new(ev, "index", json_integer(i));
    json_object_set_new(ev, "attempt", json_integer(attempt));
    json_object_set_new(ev, "accepted", json_boolean(rep.accepted));
    journal_files(ev, f, n);
    json_object_set_new(ev, "planned", json_real(planned));
    json_object_set_new(ev, "configured", positive(rep.configured));
    json_object_set_new(ev, "exposure_time", positive(rep.reported));
    json_object_set_new(ev, "f_number", positive(readable ? meta.f_number : 0));
    json_object_set_new(ev, "iso", positive(readable ? meta.iso : 0));
    json_object_set_new(ev, "measured_ratio", positive(rep.measured_ratio));
    json_object_set_new(ev, "expected_ratio", positive(rep.expected_ratio));
    json_object_set_new(ev, "exif_ok", json_null());
    json_object_set_new(ev, "pixels_ok", json_null());
    json_object_update(ev, checks);
    json_decref(checks);
    if (n > 1)
        json_object_set_new(ev, "verified_on", json_string(f[vi].file));
    if (rep.note[0])
        json_object_set_new(ev, "note", json_string(rep.note));
    if (rep.busy_retries)
        json_object_set_new(ev, "busy_retries", json_integer(rep.busy_retries));
    if (!rep.accepted)
        json_object_set_new(ev, "reason", json_string(rep.reason));
    r = sl_journal_event(s->dir, ev, err);
    json_decref(ev);
    sl_meta_free(&meta);
    if (!r && rep.accepted && readable) {
        sl_image_free(&s->prev);
        s->prev = img;
        s->prev_time = rep.reported > 0 ? rep.reported : planned;
        s->prev_view = v;
        img.data = NULL;
    }
    sl_image_free(&img);
    if (r)
        return r;
    *accepted = rep.accepted;
    if (o->on_frame)
        o->on_frame(o->ctx, &rep);
    return SL_OK;
}

/* Loads an accepted frame from disk (the file its verification decoded)
 * as the reference for the next ratio. */
static void load_prev(run_state *s, int v, json_t *frame)
{
    const char *file = json_string_value(json_object_get(frame, "verified_on"));
    if (!file)
        file = json_string_value(json_object_get(frame, "file"));
    char path[4096];
    sl_image img = {0};
    sl_meta meta;
    if (!file || sl_capture_path(path, sizeof path, s->dir, file, NULL) ||
        sl_photo_read(path, &img, &meta, NULL))
        return;
    linearize(&img, &meta);
    sl_image_free(&s->prev);
    s->prev = img;
    s->prev_time = isfinite(meta.exposure_time) ? meta.exposure_time : 0;
    s->prev_view = v;
    sl_meta_free(&meta);
}

static void sleep_s(double seconds)
{
    struct timespec ts = {(time_t)seconds, (long)((seconds - floor(seconds)) * 1e9)};
    nanosleep(&ts, NULL);
}

/* Sets the plan's image format and journals what the camera says: a
 * camera that ignores the change (it reads back another choice) is set
 * again, up to max_attempts times. */
static sl_result set_format(run_state *s, sl_error *err)
{
    if (s->format == SL_FORMAT_KEEP)
        return SL_OK;
    int max_attempts = s->o->max_attempts > 0 ? s->o->max_attempts : 3;
    sl_result r = SL_OK;
    for (int a = 1; a <= max_attempts; a++) {
        char label[64];
        r = sl_camera_set_format(s->camera, s->format, label, err);
        json_t *ev = json_object();
        json_object_set_new(ev, "event", json_string("format"));
        json_object_set_new(ev, "format", json_string(sl_image_format_name(s->format)));
        json_object_set_new(ev, "label", json_string(label));
        json_object_set_new(ev, "attempt", json_integer(a));
        json_object_set_new(ev, "ok", json_boolean(r == SL_OK));
        if (r)
            json_object_set_new(ev, "message", json_string(err->message));
        sl_error jerr;
        sl_result jr = sl_journal_event(s->dir, ev, &jerr);
        json_decref(ev);
        if (jr) {
            *err = jerr;
            return jr;
        }
        if (!r || r != SL_ERR_CAMERA || s->camera->lost)
            return r;
    }
    return r;
}

static sl_result set_fixed(run_state *s, sl_error *err)
{
    const sl_capture_options *o = s->o;
    sl_camera_settings fixed = {0, o->f_number, o->iso};
    sl_result r = o->f_number > 0 || o->iso > 0 ? sl_camera_set(s->camera, &fixed, err) : SL_OK;
    return r ? r : set_format(s, err);
}

/* The connection is gone: reconnect with backoff (0.25 s doubling to 4 s)
 * within the options' window. On failure `err` keeps the disconnect and
 * says that the run gave up. Journalled either way. */
static sl_result reconnect(run_state *s, int v, int i, sl_error *err)
{
    double window = s->o->reconnect_seconds == 0 ? 10.0 : s->o->reconnect_seconds;
    double t0 = sl_seconds(), delay = 0.25;
    int tries = 0;
    sl_result r = SL_ERR_CAMERA;
    while (window > 0 && sl_seconds() - t0 + delay <= window) {
        sleep_s(delay);
        tries++;
        sl_error e;
        if (!(r = sl_camera_reconnect(s->camera, &e)) && !(r = set_fixed(s, &e)))
            break;
        delay = delay * 2 < 4 ? delay * 2 : 4;
    }
    json_t *ev = json_object();
    json_object_set_new(ev, "event", json_string("reconnect"));
    json_object_set_new(ev, "view", json_integer(v));
    json_object_set_new(ev, "index", json_integer(i));
    json_object_set_new(ev, "ok", json_boolean(r == SL_OK));
    json_object_set_new(ev, "tries", json_integer(tries));
    json_object_set_new(ev, "seconds", json_real(round((sl_seconds() - t0) * 1000) / 1000));
    sl_error jerr;
    sl_result jr = sl_journal_event(s->dir, ev, &jerr);
    json_decref(ev);
    if (jr) {
        *err = jerr;
        return jr;
    }
    if (r) {
        char first[SL_ERROR_MESSAGE_MAX];
        snprintf(first, sizeof first, "%s", err->message);
        return sl_error_set(err, SL_ERR_CAMERA,
                            "%.400s (no reconnection in %.0f s; --resume continues the session)",
                            first, window > 0 ? window : 0);
    }
    sl_camera_aim(s->camera, v, s->views);
    return SL_OK;
}

static sl_result run(run_state *s, sl_error *err)
{
    const sl_capture_options *o = s->o;
    int max_attempts = o->max_attempts > 0 ? o->max_attempts : 3;
    sl_result r = SL_OK;
    if ((r = set_fixed(s, err)))
        return r;
    for (int v = 0; v < s->views && !r; v++) {
        bool any = false, all = true;
        for (int i = 0; i < s->count; i++) {
            any |= s->done[v * s->count + i];
            all &= s->done[v * s->count + i];
        }
        if (all)
            continue;
        if (v > 0 && !any && !s->stepped[v]) {
            if (o->step && (r = o->step(o->ctx, v, err))) {
                journal_error(s, v, 0, 0, err, NULL);
                break;
            }
            json_t *ev = json_object();
            json_object_set_new(ev, "event", json_string("step"));
            json_object_set_new(ev, "view", json_integer(v));
            r = sl_journal_event(s->dir, ev, err);
            json_decref(ev);
            if (r)
                break;
            s->stepped[v] = true;
        }
        sl_camera_aim(s->camera, v, s->views);
        for (int i = 0; i < s->count && !r; i++) {
            if (s->done[v * s->count + i])
                continue;
            bool ok = false;
            int reconnects = 0;
            for (int a = 1; a <= max_attempts && !ok && !r; a++) {
                r = shoot(s, v, i, a, &ok, err);
                if (r) {
                    /* the journal keeps the failure; if even that fails, the
                     * first error is the one to report */
                    journal_error(s, v, i, a, err, NULL);
                    /* a lost connection is not the camera getting the frame
                     * wrong: it does not use up an attempt */
                    if (s->camera->lost && reconnects < 3 && s->o->reconnect_seconds >= 0) {
                        reconnects++;
                        if (!(r = reconnect(s, v, i, err)))
                            a--;
                    } else if (s->camera->lost) {
                        char first[SL_ERROR_MESSAGE_MAX];
                        snprintf(first, sizeof first, "%s", err->message);
                        r = sl_error_set(err, SL_ERR_CAMERA,
                                         "%.400s (--resume continues the session)", first);
                    }
                }
            }
            if (!r && !ok) {
                r = sl_error_set(err, SL_ERR_CAMERA,
                                 "%s: view %d frame %d still wrong after %d attempts (see the "
                                 "journal)",
                                 sl_camera_port(s->camera), v, i, max_attempts);
                journal_error(s, v, i, max_attempts, err, NULL);
            }
            if (!r)
                s->done[v * s->count + i] = true;
        }
    }
    if (!r) {
        json_t *ev = json_object();
        json_object_set_new(ev, "event", json_string("session_end"));
        json_object_set_new(ev, "frames", json_integer(s->views * s->count));
        r = sl_journal_event(s->dir, ev, err);
        json_decref(ev);
    }
    /* session.json reflects whatever is on disk, also after a failure */
    sl_error serr;
    sl_result sr = sl_session_write(s->dir, &serr);
    if (!r && sr) {
        r = sr;
        if (err)
            *err = serr;
    }
    return r;
}

static sl_result state_alloc(run_state *s, sl_error *err)
{
    s->done = calloc((size_t)s->views * (size_t)s->count, sizeof *s->done);
    s->stepped = calloc((size_t)s->views, sizeof *s->stepped);
    if (!s->done || !s->stepped)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", s->dir);
    return SL_OK;
}

static void state_free(run_state *s)
{
    free(s->done);
    free(s->stepped);
    sl_image_free(&s->prev);
}

sl_result sl_capture_run(sl_camera *camera, const sl_capture_options *o, sl_error *err)
{
    sl_error local; /* the journal needs the message even when the caller does not */
    if (!err)
        err = &local;
    if (!o->dir || !*o->dir)
        return sl_error_set(err, SL_ERR_USAGE, "capture: no output folder");
    if (o->views < 1 || o->views > 360)
        return sl_error_set(err, SL_ERR_USAGE, "%s: views must be 1 to 360, not %d", o->dir,
                            o->views);
    if (o->count < 1 || !o->times)
        return sl_error_set(err, SL_ERR_USAGE, "%s: empty bracket plan", o->dir);
    /* A format the camera does not offer is a plan it cannot do: refused
     * before anything is written. KEEP records what the camera is set to. */
    char label[64] = "";
    sl_image_format kept;
    sl_result r = o->format != SL_FORMAT_KEEP
                      ? sl_camera_format_choice(camera, o->format, label, err)
                      : (sl_camera_get_format(camera, &kept, label, NULL), SL_OK);
    if (r)
        return r;
    struct stat st;
    if (stat(o->dir, &st) == 0) {
        char jp[4096];
        if (!S_ISDIR(st.st_mode))
            return sl_error_set(err, SL_ERR_USAGE, "%s: exists and is not a folder", o->dir);
        if (!sl_capture_path(jp, sizeof jp, o->dir, SL_JOURNAL_NAME, NULL) && stat(jp, &st) == 0)
            return sl_error_set(err, SL_ERR_USAGE,
                                "%s: already holds a session (use --resume to continue it)",
                                o->dir);
    } else if (mkdir(o->dir, 0755) != 0)
        return sl_error_set(err, SL_ERR_IO, "%s: cannot create: %s", o->dir, strerror(errno));

    json_t *ev = json_object(), *cam = json_object(), *plan = json_object(), *times = json_array();
    json_object_set_new(ev, "event", json_string("session_start"));
    json_object_set_new(ev, "version", json_integer(1));
    json_object_set_new(cam, "model", json_string(sl_camera_model(camera)));
    json_object_set_new(cam, "port", json_string(sl_camera_port(camera)));
    json_object_set_new(cam, "backend", json_string(sl_camera_backend(camera)));
    json_object_set_new(ev, "camera", cam);
    for (int i = 0; i < o->count; i++)
        json_array_append_new(times, json_real(o->times[i]));
    json_object_set_new(plan, "times", times);
    json_object_set_new(plan, "views", json_integer(o->views));
    json_object_set_new(plan, "f_number", json_real(o->f_number));
    json_object_set_new(plan, "iso", json_real(o->iso));
    json_object_set_new(plan, "format", json_string(sl_image_format_name(o->format)));
    json_object_set_new(plan, "format_label", json_string(label));
    json_object_set_new(ev, "plan", plan);
    r = sl_journal_event(o->dir, ev, err);
    json_decref(ev);
    if (r)
        return r;
    run_state s = {.camera = camera,
                   .o = o,
                   .dir = o->dir,
                   .times = o->times,
                   .count = o->count,
                   .views = o->views,
                   .prev_view = -1,
                   .format = o->format};
    snprintf(s.format_label, sizeof s.format_label, "%s", label);
    if (!(r = state_alloc(&s, err)))
        r = run(&s, err);
    state_free(&s);
    return r;
}

/* The session's image format from its plan (journals before formats: KEEP);
 * a different one asked for on resume is refused. */
static sl_result plan_format(const char *dir, json_t *plan, sl_image_format asked, run_state *s,
                             sl_error *err)
{
    const char *name = json_string_value(json_object_get(plan, "format"));
    const char *label = json_string_value(json_object_get(plan, "format_label"));
    s->format = SL_FORMAT_KEEP;
    if (name && sl_image_format_parse(name, &s->format, NULL))
        return sl_error_set(err, SL_ERR_INPUT, "%s: the journal's plan has an unknown format '%s'",
                            dir, name);
    snprintf(s->format_label, sizeof s->format_label, "%s", label ? label : "");
    if (asked != SL_FORMAT_KEEP && asked != s->format)
        return sl_error_set(err, SL_ERR_USAGE,
                            "%s: the session is shot as %s; --format %s would mix formats (leave "
                            "--format out to continue as %s)",
                            dir, sl_image_format_name(s->format), sl_image_format_name(asked),
                            sl_image_format_name(s->format));
    return SL_OK;
}

/* An aperture or ISO asked for on resume that differs from the session's
 * (or that the session left to the camera) could mix exposures within its
 * brackets: refused. */
static sl_result plan_setting(const char *dir, json_t *plan, const char *key, const char *option,
                              double asked, sl_error *err)
{
    double planned = json_number_value(json_object_get(plan, key));
    if (asked <= 0 || (planned > 0 && fabs(asked / planned - 1) < 0.01))
        return SL_OK;
    if (planned <= 0)
        return sl_error_set(err, SL_ERR_USAGE,
                            "%s: the session left the %s to the camera; %s %g could mix "
                            "exposures (leave %s out)",
                            dir, option + 2, option, asked, option);
    return sl_error_set(err, SL_ERR_USAGE,
                        "%s: the session is shot at %s %g; %s %g would mix exposures (leave %s "
                        "out to continue at %g)",
                        dir, option + 2, planned, option, asked, option, planned);
}

/* Every file of a journalled frame (its siblings too) still has its
 * journalled SHA-256. */
static sl_result check_intact(const char *dir, json_t *frame, size_t line, sl_error *err)
{
    json_t *sib = json_object_get(frame, "siblings");
    for (size_t k = 0; k <= json_array_size(sib); k++) {
        json_t *f = k == 0 ? frame : json_array_get(sib, k - 1);
        const char *file = json_string_value(json_object_get(f, "file"));
        const char *sha = json_string_value(json_object_get(f, "sha256"));
        if (!file || !sha)
            return sl_error_set(err, SL_ERR_INPUT, "%s: corrupt journal: bad frame event %zu", dir,
                                line + 1);
        char path[4096], hex[65];
        sl_result r = sl_capture_path(path, sizeof path, dir, file, err);
        if (r)
            return r;
        if (sl_sha256_file(path, hex, NULL) || strcmp(hex, sha) != 0)
            return sl_error_set(err, SL_ERR_INPUT, "%s: missing or changed since it was journalled",
                                path);
    }
    return SL_OK;
}

sl_result sl_capture_resume(sl_camera *camera, const sl_capture_options *o, const char *dir,
                            sl_error *err)
{
    json_t *events;
    sl_result r = sl_journal_read(dir, &events, err);
    if (r)
        return r == SL_ERR_NOT_FOUND
                   ? sl_error_set(err, SL_ERR_INPUT, "%s: not a capture session (no %s)", dir,
                                  SL_JOURNAL_NAME)
                   : r;
    json_t *plan = json_object_get(json_array_get(events, 0), "plan");
    json_t *jt = json_object_get(plan, "times");
    size_t planned = json_array_size(jt);
    int count = planned > SL_BRACKET_MAX_FRAMES ? SL_BRACKET_MAX_FRAMES + 1 : (int)planned;
    int views = (int)json_integer_value(json_object_get(plan, "views"));
    double *times = calloc((size_t)(count > 0 ? count : 1), sizeof *times);
    run_state s = {.camera = camera,
                   .dir = dir,
                   .times = times,
                   .count = count,
                   .views = views,
                   .prev_view = -1};
    if (!times) {
        json_decref(events);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", dir);
    }
    for (int i = 0; i < count; i++)
        times[i] = json_number_value(json_array_get(jt, (size_t)i));
    if (count < 1 || count > SL_BRACKET_MAX_FRAMES || views < 1 || views > 360) {
        r = sl_error_set(err, SL_ERR_INPUT,
                         "%s: the journal's plan is not valid (%d frames a bracket, %d views; at "
                         "most %d and 360)",
                         dir, count, views, SL_BRACKET_MAX_FRAMES);
        goto out;
    }
    if ((r = plan_format(dir, plan, o->format, &s, err)) ||
        (r = plan_setting(dir, plan, "f_number", "--aperture", o->f_number, err)) ||
        (r = plan_setting(dir, plan, "iso", "--iso", o->iso, err)))
        goto out;
    if ((r = state_alloc(&s, err)))
        goto out;
    /* What is already done, and is it still intact? */
    size_t k;
    json_t *e;
    int done = 0, last_view = -1, last_index = -1;
    json_t *last_frame = NULL;
    const char *last_error = NULL;
    json_array_foreach(events, k, e)
    {
        const char *kind = json_string_value(json_object_get(e, "event"));
        int v = (int)json_integer_value(json_object_get(e, "view"));
        int i = (int)json_integer_value(json_object_get(e, "index"));
        if (!strcmp(kind, "step") && v >= 0 && v < views)
            s.stepped[v] = true;
        if (!strcmp(kind, "error"))
            last_error = json_string_value(json_object_get(e, "message"));
        if (strcmp(kind, "frame") != 0 || !json_is_true(json_object_get(e, "accepted")))
            continue;
        if (v < 0 || v >= views || i < 0 || i >= count) {
            r = sl_error_set(err, SL_ERR_INPUT, "%s: corrupt journal: bad frame event %zu", dir,
                             k + 1);
            goto out;
        }
        if ((r = check_intact(dir, e, k, err)))
            goto out;
        if (!s.done[v * count + i])
            done++;
        s.done[v * count + i] = true;
        last_view = v;
        last_index = i;
        last_frame = e;
    }
    /* The reference for the next ratio, when resuming inside a view. */
    int next_v = -1, next_i = -1;
    for (int q = 0; q < views * count && next_v < 0; q++)
        if (!s.done[q]) {
            next_v = q / count;
            next_i = q % count;
        }
    if (next_v < 0) {
        /* complete already: nothing to shoot, nothing to journal */
        r = sl_session_write(dir, err);
        goto out;
    }
    if (last_frame && next_v == last_view && next_i > last_index)
        load_prev(&s, last_view, last_frame);
    sl_capture_options opts = *o;
    opts.dir = dir;
    opts.times = times;
    opts.count = count;
    opts.views = views;
    s.o = &opts;
    if (opts.f_number <= 0)
        opts.f_number = json_number_value(json_object_get(plan, "f_number"));
    if (opts.iso <= 0)
        opts.iso = json_number_value(json_object_get(plan, "iso"));
    json_t *ev = json_object();
    json_object_set_new(ev, "event", json_string("resume"));
    json_object_set_new(ev, "frames_done", json_integer(done));
    json_object_set_new(ev, "next_view", json_integer(next_v));
    json_object_set_new(ev, "next_index", json_integer(next_i));
    json_object_set_new(ev, "after_error", last_error ? json_string(last_error) : json_null());
    json_object_set_new(ev, "camera", json_string(sl_camera_port(camera)));
    if (s.format == SL_FORMAT_KEEP) {
        /* how many files a trigger makes, from the camera's setting */
        sl_image_format kept;
        sl_camera_get_format(camera, &kept, NULL, NULL);
    }
    r = sl_journal_event(dir, ev, err);
    json_decref(ev);
    if (!r)
        r = run(&s, err);
out:
    state_free(&s);
    free(times);
    json_decref(events);
    return r;
}
