/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * setlight capture: cameras (libgphoto2, virtual, folder ingest), bracket
 * plans and grouping, the session journal, and the virtual set that
 * simulates a whole on-set capture with its ground truth.
 */
#ifndef SETLIGHT_CAPTURE_H
#define SETLIGHT_CAPTURE_H

#include "setlight/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ================================================================== */
/* Virtual set: scenes and the simulated camera                        */
/* ================================================================== */

/* ================================================================== */
/* Cameras, bracket plans, journal and sessions                        */
/* ================================================================== */

/* --- Shutter speeds and bracket plans (docs/capture.md) --- */

/* "1/30", "0.5", "2", "2s", "0.0333s", "1\"", "1 1/3" -> seconds; 0 when not a
 * shutter speed. */
double sl_shutter_parse(const char *text);
/* 1/30 -> "1/30", 0.5 -> "1/2", 2.5 -> "2.5". */
void sl_shutter_format(double seconds, char *buf, size_t size);

/* "NxS" (N exposures S stops apart, centred on `center` seconds; N odd or
 * even) or an explicit comma list of shutter speeds ("1/1000,1/125,1/15").
 * Result ascending, malloc'd. SL_ERR_USAGE for junk, N < 1 or > 64, S <= 0. */
sl_result sl_bracket_plan_parse(const char *spec, double center, double **times, int *count,
                                sl_error *err);
/* Snaps every planned time to the nearest offered speed (in stops). Writes
 * the snapped times into `times` and how many stops each moved into
 * `moved_stops` (may be NULL). SL_ERR_USAGE naming the speed when it is more
 * than `max_stops` from every offered speed (out of the camera's range) or
 * when two planned times snap to the same speed. */
sl_result sl_bracket_snap(double *times, int count, const double *offered, int offered_count,
                          double max_stops, double *moved_stops, sl_error *err);

/* --- Cameras --- */

typedef struct sl_camera sl_camera;

typedef struct sl_camera_settings {
    double exposure_time; /* seconds; 0 = unknown / leave as is */
    double f_number;
    double iso;
} sl_camera_settings;

typedef struct sl_camera_entry {
    char model[128];
    char port[128];
} sl_camera_entry;

/* Cameras libgphoto2 detects (USB and serial; network cameras are never
 * detected and are given as ptpip:HOST[:PORT]). *list is malloc'd. */
sl_result sl_camera_list(sl_camera_entry **list, int *count, sl_error *err);

/* Opens a camera: "auto" (the first detected), or a libgphoto2 port such as
 * "usb:001,004" or "ptpip:HOST[:PORT[:EVENTPORT]]". SL_ERR_USAGE for a port
 * libgphoto2 does not know, SL_ERR_CAMERA when nothing answers there. */
sl_result sl_camera_open(const char *port, sl_camera **camera, sl_error *err);
void sl_camera_close(sl_camera *camera);
/* "setlight PTP-IP test camera", "ptpip:127.0.0.1:15740", "gphoto2". */
const char *sl_camera_model(const sl_camera *camera);
const char *sl_camera_port(const sl_camera *camera);
const char *sl_camera_backend(const sl_camera *camera);

/* Shutter speeds the camera offers, ascending seconds (malloc'd). */
sl_result sl_camera_shutter_speeds(sl_camera *camera, double **speeds, int *count, sl_error *err);
/* Sets every non-zero field to the nearest value the camera offers; a busy
 * camera is retried with backoff. */
sl_result sl_camera_set(sl_camera *camera, const sl_camera_settings *settings, sl_error *err);
/* What the camera reports it is set to. */
sl_result sl_camera_get(sl_camera *camera, sl_camera_settings *settings, sl_error *err);

typedef struct sl_camera_file {
    unsigned char *data;
    size_t size;
    char source[256]; /* name on the card, e.g. "/store_00010001/IMG_0001.JPG" */
    int busy_retries; /* busy replies retried before the trigger was taken */
} sl_camera_file;

/* Triggers one exposure, waits for the camera's file-added event and
 * downloads that file (never deleted from the card). Busy replies are
 * retried with backoff; a lost connection is SL_ERR_CAMERA. */
sl_result sl_camera_capture(sl_camera *camera, sl_camera_file *file, sl_error *err);
void sl_camera_file_free(sl_camera_file *file);

/* --- SHA-256 (FIPS 180-4) --- */

void sl_sha256(const void *data, size_t size, unsigned char digest[32]);
/* 64 lowercase hex digits and a terminator. */
void sl_sha256_hex(const void *data, size_t size, char hex[65]);
sl_result sl_sha256_file(const char *path, char hex[65], sl_error *err);

/* --- Journal: DIR/journal.jsonl, one JSON object per line, append-only --- */

/* Appends one event (a JSON object text without newline) and fsyncs the
 * file before returning: nothing is triggered before the line is on disk. */
sl_result sl_journal_append(const char *dir, const char *json_line, sl_error *err);

/* --- Capture sessions --- */

typedef struct sl_capture_report {
    int view, index;        /* frame position in the plan */
    int views, count;       /* the plan's size */
    int attempt;            /* 1 for the first try */
    bool accepted;
    double planned;         /* seconds */
    double reported;        /* exposure time in the file's EXIF (0 unknown) */
    double configured;      /* exposure time the camera reported it was set to */
    double measured_ratio;  /* pixel ratio to the previous accepted frame, 0 if none */
    double expected_ratio;  /* what the EXIF exposures say that ratio should be */
    int busy_retries;       /* busy replies to this frame's trigger */
    char file[256];         /* name inside the session folder */
    char source[256];
    char reason[256];       /* why a frame was rejected */
} sl_capture_report;

/* Called between views (before view `next_view`, from 1): move the nodal
 * head. Return SL_OK to go on; anything else stops the capture cleanly. */
typedef sl_result (*sl_capture_step_fn)(void *ctx, int next_view, sl_error *err);
typedef void (*sl_capture_frame_fn)(void *ctx, const sl_capture_report *report);

typedef struct sl_capture_options {
    const char *dir;            /* session folder (created if absent) */
    const double *times;        /* planned exposure times, already snapped */
    int count;
    int views;                  /* >= 1 */
    double f_number, iso;       /* 0 = leave the camera's setting */
    int max_attempts;           /* per frame (default 3) */
    double tolerance_stops;     /* EXIF and measured-ratio tolerance (default 1/3) */
    sl_capture_step_fn step;    /* may be NULL */
    sl_capture_frame_fn on_frame; /* may be NULL */
    void *ctx;
} sl_capture_options;

/* A new session in an empty (or absent) folder: journals the plan, shoots
 * views x count frames, verifies each (EXIF exposure and pixel ratio) and
 * retries a frame the camera got wrong, writes session.json. Stops at the
 * first unrecoverable fault with the journal consistent (SL_ERR_CAMERA,
 * SL_ERR_IO for a full disk). */
sl_result sl_capture_run(sl_camera *camera, const sl_capture_options *options, sl_error *err);
/* Continues the session in `dir` with its journalled plan from the next
 * missing frame. SL_ERR_INPUT when dir is not a session or its journal is
 * corrupt (nothing is touched then). options->dir, times, count and views
 * are ignored (taken from the journal). */
sl_result sl_capture_resume(sl_camera *camera, const sl_capture_options *options,
                            const char *dir, sl_error *err);
/* Rewrites DIR/session.json (version 1) from the journal. */
sl_result sl_session_write(const char *dir, sl_error *err);

/* Groups the photographs in `src` into brackets and views by EXIF time,
 * exposure and sequence, copies them into `dir` (never overwriting) and
 * writes DIR/session.json. Non-image files are listed as problems; a folder
 * with no photographs is SL_ERR_INPUT. gap_seconds: a pause longer than this
 * between two frames starts a new view (0: 10 s). */
sl_result sl_ingest(const char *src, const char *dir, double gap_seconds, int *frames,
                    int *views, sl_error *err);

#ifdef __cplusplus
}
#endif

#endif /* SETLIGHT_CAPTURE_H */
