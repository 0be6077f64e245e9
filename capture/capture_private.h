/* SPDX-License-Identifier: BSD-3-Clause */
/* Shared between the journal, session and capture files of the module. */
#ifndef SETLIGHT_CAPTURE_PRIVATE_H
#define SETLIGHT_CAPTURE_PRIVATE_H

#include <jansson.h>

#include "setlight/capture.h"

#define SL_JOURNAL_NAME "journal.jsonl"
/* A journal is a few kB a bracket: over this it is not one (refused unread). */
#define SL_JOURNAL_MAX_BYTES ((uint64_t)256 << 20)
#define SL_SESSION_NAME "session.json"

/* Appends a JSON object as one line (adds "time": UTC ISO 8601). */
sl_result sl_journal_event(const char *dir, json_t *event, sl_error *err);
/* Reads every journal line into a JSON array. SL_ERR_NOT_FOUND when there is
 * no journal, SL_ERR_INPUT naming the line when one does not parse or the
 * first is not a version-1 session start. */
sl_result sl_journal_read(const char *dir, json_t **events, sl_error *err);
/* dir + "/" + name into buf; SL_ERR_USAGE when too long. */
sl_result sl_capture_path(char *buf, size_t size, const char *dir, const char *name, sl_error *err);
/* Writes session.json from a version, a camera object and views built by the
 * caller (steals the references); `splits` (ingest's, may be NULL: left out)
 * says which frames were kept apart and why. */
sl_result sl_session_write_json(const char *dir, json_t *camera, json_t *views, json_t *problems,
                                json_t *splits, sl_error *err);

/* Where a file stands among a shot's files (a body writing RAW+JPEG, or
 * the virtual set's JPEG, TIFF and linear TIFF, stores one shot in several):
 * 0 raw, 1 EXR or TIFF, 2 PNG, 3 the rest (JPEG). The frame's file is the
 * rawest, the others are its siblings. */
int sl_capture_file_rank(const char *name);

/* What ingest needs from a JPEG's or TIFF's (TIFF-based raw's) EXIF that
 * OpenImageIO's sl_meta lacks; "" or -1 when absent. */
typedef struct sl_exif_extra {
    double subsec;        /* SubSecTimeOriginal (else SubSecTime), in seconds */
    char serial[64];      /* BodySerialNumber, DNG CameraSerialNumber, or the
                             Canon or Nikon maker note's */
    char lens[128];       /* LensModel, else the Canon maker note's */
    char lens_serial[64]; /* LensSerialNumber */
} sl_exif_extra;
void sl_exif_extra_read(const unsigned char *data, size_t size, sl_exif_extra *extra);
void sl_exif_extra_file(const char *path, sl_exif_extra *extra);
/* What the frames of one merge must share (ingest never groups frames of
 * two setups): make, model and serial of the body, lens, its serial and
 * focal length, stored size, EXIF orientation, file format and samples. */
typedef struct sl_frame_setup {
    char make[64], model[64], serial[64];
    char lens[128], lens_serial[64];
    double focal_mm; /* 0 unknown */
    int width, height, orientation;
    char format[32];
    int bits;
    bool is_float;
} sl_frame_setup;
void sl_frame_setup_fill(sl_frame_setup *setup, const sl_meta *meta, const sl_exif_extra *extra,
                         int width, int height);
/* True when a and b cannot share a bracket; `why` gets what differs, as
 * "image size 900x600 vs 640x427; lens 'EF-S18-55mm' vs none". An unknown
 * serial or lens differs from a known one (a bracket's frames come from one
 * body that writes the same tags); an unknown focal length does not. */
bool sl_frame_setup_differs(const sl_frame_setup *a, const sl_frame_setup *b, char *why,
                            size_t size);
/* The setup as a JSON object (unknown strings null). */
json_t *sl_frame_setup_json(const sl_frame_setup *setup);


#endif
