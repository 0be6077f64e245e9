/* SPDX-License-Identifier: BSD-3-Clause */
/* Shared between the journal, session and capture files of the module. */
#ifndef SETLIGHT_CAPTURE_PRIVATE_H
#define SETLIGHT_CAPTURE_PRIVATE_H

#include <jansson.h>

#include "setlight/capture.h"

#define SL_JOURNAL_NAME "journal.jsonl"
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
 * caller (steals the references). */
sl_result sl_session_write_json(const char *dir, json_t *camera, json_t *views, json_t *problems,
                                sl_error *err);

/* Where a file stands among a shot's files (a body writing RAW+JPEG, or
 * the virtual set's JPEG, TIFF and linear TIFF, stores one shot in several):
 * 0 raw, 1 EXR or TIFF, 2 PNG, 3 the rest (JPEG). The frame's file is the
 * rawest, the others are its siblings. */
int sl_capture_file_rank(const char *name);

/* EXIF SubSecTimeOriginal (else SubSecTime) of a JPEG or TIFF as a fraction
 * of a second; -1 when absent. */
double sl_exif_subsec(const unsigned char *data, size_t size);
double sl_exif_subsec_file(const char *path);
/* Replaces a JPEG stream's APP0/APP1 segments with a camera's EXIF: make,
 * model, date, exposure time, f-number, ISO, focal length and
 * SubSecTimeOriginal (milliseconds). *jpeg is realloc'd. */
sl_result sl_jpeg_set_exif(unsigned char **jpeg, size_t *size, const sl_meta *meta, int subsec_ms,
                           sl_error *err);

#endif
