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

#endif
