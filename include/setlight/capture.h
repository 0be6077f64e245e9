/* SPDX-License-Identifier: BSD-3-Clause */
/*
 * setlight capture: cameras (a backend table: libgphoto2 built in, others
 * such as the virtual set's camera, vset.h, registered at start-up), bracket
 * plans, tethered capture with its journal, card and folder ingest, sessions.
 */
#ifndef SETLIGHT_CAPTURE_H
#define SETLIGHT_CAPTURE_H

#include "setlight/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ================================================================== */
/* Cameras, bracket plans, journal and sessions                        */
/* ================================================================== */

/* --- Shutter speeds and bracket plans (docs/capture.md) --- */

/* "1/30", "0.5", "2", "2s", "0.0333s", "1\"", "1 1/3" -> seconds; 0 when not a
 * shutter speed. */
double sl_shutter_parse(const char *text);
/* 1/30 -> "1/30", 0.5 -> "1/2", 2.5 -> "2.5". */
void sl_shutter_format(double seconds, char *buf, size_t size);

/* The most exposures a bracket may have (a plan, a journal's plan). */
#define SL_BRACKET_MAX_FRAMES 64

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

/* Opens a camera: "auto" (the first detected), a libgphoto2 port such as
 * "usb:001,004" or "ptpip:HOST[:PORT[:EVENTPORT]]", or "NAME[:ARGS]" of a
 * registered backend (capture/camera_backend.h), e.g. "virtual[:SCENE]" once
 * sl_vset_camera_register has run. SL_ERR_USAGE for a port libgphoto2 does
 * not know or a backend refuses (an unknown scene), SL_ERR_CAMERA when
 * nothing answers there. */
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

/* The files one trigger writes. KEEP leaves the camera's setting alone. */
typedef enum {
    SL_FORMAT_KEEP = 0,
    SL_FORMAT_JPEG,
    SL_FORMAT_RAW,
    SL_FORMAT_RAW_JPEG
} sl_image_format;

/* "keep", "jpeg", "raw", "raw+jpeg". */
const char *sl_image_format_name(sl_image_format format);
/* The names above; SL_ERR_USAGE naming the text otherwise. */
sl_result sl_image_format_parse(const char *text, sl_image_format *format, sl_error *err);
/* What a camera's image-format choice label means ("NEF+Fine", "RAW + Large
 * Fine JPEG", "JPEG Fine", "cRAW", "Standard"...): JPEG, RAW, RAW_JPEG, or
 * KEEP for a label that is neither (TIFF, HEIF, unknown). *rank (may be
 * NULL) orders labels of one kind: full-size raw before mRAW/sRAW/cRAW,
 * then JPEG quality (extra fine, fine, normal, basic), then size. */
sl_image_format sl_image_format_of_label(const char *label, int *rank);
/* A file's kind from its name: RAW (.cr2 .cr3 .nef .nrw .arw .dng .raf
 * .orf .rw2 .pef .srw .iiq), JPEG (.jpg .jpeg), else KEEP. */
sl_image_format sl_image_format_of_file(const char *name);

/* The label of the best choice the camera offers for `format` (64 bytes),
 * without changing anything. SL_ERR_USAGE when it offers none (a plan the
 * camera cannot do; the message lists its choices), SL_ERR_CAMERA when it
 * has no image-format setting. */
sl_result sl_camera_format_choice(sl_camera *camera, sl_image_format format, char *label,
                                  sl_error *err);
/* Sets that choice (busy replies retried with backoff) and reads it back;
 * `label` (may be NULL) gets it. SL_ERR_CAMERA when the camera refuses or
 * still reads another choice after the change (it ignored it). */
sl_result sl_camera_set_format(sl_camera *camera, sl_image_format format, char *label,
                               sl_error *err);
/* What the camera is set to (KEEP when it cannot tell) and its label. */
sl_result sl_camera_get_format(sl_camera *camera, sl_image_format *format, char *label,
                               sl_error *err);

typedef struct sl_camera_file {
    unsigned char *data;
    size_t size;
    char source[256]; /* name on the card, e.g. "/store_00010001/IMG_0001.JPG" */
} sl_camera_file;

#define SL_SHOT_MAX_FILES 4

/* What one trigger delivered: RAW+JPEG bodies write two files. */
typedef struct sl_camera_shot {
    sl_camera_file files[SL_SHOT_MAX_FILES];
    int count;        /* files downloaded */
    int expected;     /* files the camera's format makes per trigger */
    int busy_retries; /* busy replies retried before the trigger was taken */
} sl_camera_shot;

/* Triggers one exposure, waits for the camera's file-added events of that
 * trigger (as many as its image format writes, or until it reports the
 * capture complete) and downloads each file (never deleted from the card).
 * Busy replies are retried with backoff; a lost connection is
 * SL_ERR_CAMERA, with the files downloaded before it kept in `shot`. */
sl_result sl_camera_capture(sl_camera *camera, sl_camera_shot *shot, sl_error *err);
void sl_camera_shot_free(sl_camera_shot *shot);
/* The nodal head now points at view `view` of `views`: turns the virtual
 * camera's head; real bodies cannot be aimed (the step command or the
 * wrangler turns the head), so for them it does nothing. */
void sl_camera_aim(sl_camera *camera, int view, int views);

/* A camera raw for the virtual and test cameras: a DNG (LinearRaw, 16-bit
 * RGB, uncompressed, camera RGB = linear Rec.709, as-shot neutral white)
 * of `linear` (RGB, clipped to [0,1]) with the EXIF of sl_jpeg_set_exif.
 * OpenImageIO (LibRaw) reads it back linear, so the capture verification
 * measures its pixels like a real camera's raw. *data is malloc'd. */
sl_result sl_dng_encode(const sl_image *linear, const sl_meta *meta, int subsec_ms,
                        unsigned char **data, size_t *size, sl_error *err);

/* --- SHA-256 (FIPS 180-4, through OpenSSL's EVP) --- */

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
    int files;              /* files the trigger delivered (2 for RAW+JPEG) */
    char file[256];         /* name inside the session folder (the rawest file) */
    char source[256];
    char reason[256];       /* why a frame was rejected */
    char note[128];         /* e.g. "not measured: raw only" */
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
    sl_image_format format;     /* KEEP = leave the camera's setting */
    int max_attempts;           /* per frame (default 3) */
    double reconnect_seconds;   /* after a lost connection, keep reconnecting with
                                   backoff this long (0: 10 s; < 0: give up at once) */
    double tolerance_stops;     /* EXIF and measured-ratio tolerance (default 1/3) */
    sl_capture_step_fn step;    /* may be NULL */
    sl_capture_frame_fn on_frame; /* may be NULL */
    void *ctx;
    int disk_full_at;           /* fault injection (tests): the Nth shot this run
                                   saves fails as on a full disk (ENOSPC); 0: never */
} sl_capture_options;

/* A new session in an empty (or absent) folder: journals the plan, shoots
 * views x count frames, verifies each (EXIF exposure and pixel ratio) and
 * retries a frame the camera got wrong, reconnects a lost camera (journal
 * "reconnect"), writes session.json. Stops at the first unrecoverable fault
 * with the journal consistent (SL_ERR_CAMERA, SL_ERR_IO for a full disk). */
sl_result sl_capture_run(sl_camera *camera, const sl_capture_options *options, sl_error *err);
/* Continues the session in `dir` with its journalled plan from the next
 * missing frame. SL_ERR_INPUT when dir is not a session or its journal is
 * corrupt (nothing is touched then); SL_ERR_USAGE when options->format is
 * not KEEP and differs from the session's. options->dir, times, count and
 * views are ignored (taken from the journal). */
sl_result sl_capture_resume(sl_camera *camera, const sl_capture_options *options,
                            const char *dir, sl_error *err);
/* Rewrites DIR/session.json (version 1) from the journal. */
sl_result sl_session_write(const char *dir, sl_error *err);

/* Groups the photographs in `src` into brackets and views by EXIF time,
 * exposure and sequence, copies them into `dir` (never overwriting) and
 * writes DIR/session.json. Frames of different setups (camera make, model,
 * serial; lens, its serial and focal length; stored size, EXIF orientation,
 * file format, samples) are grouped apart: session.json's "splits" has one
 * line per two setups kept apart saying why, each also logged as a warning,
 * and each view its "camera" setup. Non-image files, one-frame brackets and
 * frames without an EXIF exposure time are listed as problems; a folder
 * with no photographs is SL_ERR_INPUT. gap_seconds: a pause longer than this
 * between two frames of one setup starts a new view (0: 10 s). progress (may be NULL): a
 * bar the caller began; its total is set to the photographs found and one is
 * added per frame copied. */
sl_result sl_ingest(const char *src, const char *dir, double gap_seconds, sl_progress *progress,
                    int *frames, int *views, sl_error *err);

#ifdef __cplusplus
}
#endif

#endif /* SETLIGHT_CAPTURE_H */
