/* SPDX-License-Identifier: BSD-3-Clause */
/* What the capture tests share: the virtual camera they shoot with, the
 * plan, the journal read back, and the check that a session is whole
 * (every planned frame accepted exactly once, on disk with its checksum,
 * EXIF on plan, session.json grouping it). */
#ifndef SETLIGHT_TESTS_CAPTURE_CHECK_H
#define SETLIGHT_TESTS_CAPTURE_CHECK_H

#include <jansson.h>

#include "setlight/vset.h"

/* The exterior scene at 240 x 160 (160 x 112 under sanitizers), no faults. */
void cap_vopts(sl_virtual_camera_opts *o);
sl_camera *cap_open_virtual(const sl_virtual_camera_opts *o);
/* A plan snapped to the camera's speeds; centre 0: its metered setting. */
int cap_plan_of(sl_camera *cam, const char *spec, double centre, double **times);
/* The journal of `dir`, one object per line (a new array). */
json_t *cap_journal(const char *dir);
const char *cap_str(json_t *e, const char *k);
int cap_ival(json_t *e, const char *k);
/* The events of one kind, in order; accepted 1 or 0 filters frames, -1
 * takes all (borrowed references in a new array). */
json_t *cap_events(json_t *j, const char *kind, int accepted);
/* Every accepted (view, index) exactly once, every journalled file on disk
 * with its checksum, its EXIF exposure within 1/6 stop of the plan, and
 * session.json grouping views x count frames by exposure. */
void cap_check_session(const char *dir, int views, int count, const double *times);
/* DIR/session.json parsed (a new reference), NULL after a failed CHECK. */
json_t *cap_session_json(const char *dir);
sl_capture_options cap_options(const char *dir, const double *times, int count, int views);

#endif
