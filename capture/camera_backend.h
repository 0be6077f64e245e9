/* SPDX-License-Identifier: BSD-3-Clause */
/* The one interface between sl_camera and its backends (camera.c). */
#ifndef SETLIGHT_CAMERA_BACKEND_H
#define SETLIGHT_CAMERA_BACKEND_H

#include "setlight/capture.h"

/* Every op fails with an sl_error naming the port; a backend marks a busy
 * reply (camera.c retries it with backoff) or a lost connection (the
 * capture loop reconnects) on the camera before returning. */
typedef struct sl_camera_ops {
    const char *name;
    sl_result (*shutter_speeds)(sl_camera *c, double **speeds, int *count, sl_error *err);
    sl_result (*set)(sl_camera *c, const sl_camera_settings *s, sl_error *err);
    sl_result (*get)(sl_camera *c, sl_camera_settings *s, sl_error *err);
    /* The image-format setting: its choice labels (at most `max`) and the
     * current label. NULL when the camera has no such setting. */
    sl_result (*format_choices)(sl_camera *c, char (*labels)[64], int max, int *count,
                                char current[64], sl_error *err);
    sl_result (*set_format)(sl_camera *c, const char *label, sl_error *err);
    /* One trigger, the wait for its c->files_per_shot new files (fewer when
     * the camera reports the capture complete first) and their download. */
    sl_result (*capture)(sl_camera *c, sl_camera_shot *shot, sl_error *err);
    /* The nodal head now points at view `view` of `views` (NULL: the
     * head is outside the camera's reach, as with real bodies). */
    void (*aim)(sl_camera *c, int view, int views);
    /* Opens the connection again after it was lost. */
    sl_result (*reconnect)(sl_camera *c, sl_error *err);
    void (*close)(void *impl);
} sl_camera_ops;

struct sl_camera {
    const sl_camera_ops *ops;
    void *impl;
    char model[128];
    char port[128];
    bool busy; /* the last failure was a busy reply */
    bool lost; /* the connection is gone until reconnect succeeds */
    int files_per_shot; /* what the image format writes per trigger (0: 1) */
};

/* libgphoto2 (camera_gphoto2.c). */
sl_result sl_gphoto2_open(const char *port, sl_camera *camera, sl_error *err);
sl_result sl_gphoto2_list(sl_camera_entry **list, int *count, sl_error *err);

/* A backend other than libgphoto2 (the virtual set's camera, vset/) opens
 * the ports "NAME" and "NAME:ARGS" (args NULL for the former), filling a
 * zeroed camera. It registers once at start-up, as libgphoto2's camera
 * drivers do; registering a name twice keeps the first. */
typedef struct sl_camera_driver {
    const char *name;
    sl_result (*open)(const char *args, sl_camera *camera, sl_error *err);
} sl_camera_driver;
sl_result sl_camera_driver_register(const sl_camera_driver *driver, sl_error *err);

/* Replaces a JPEG stream's APP0/APP1 segments with a camera's EXIF (exif.c):
 * make, model, date, exposure time, f-number, ISO, focal length and
 * SubSecTimeOriginal (milliseconds). *jpeg is realloc'd. For backends that
 * make their own files. */
sl_result sl_jpeg_set_exif(unsigned char **jpeg, size_t *size, const sl_meta *meta, int subsec_ms,
                           sl_error *err);

/* Sets the image-format choice `label`, busy replies retried with backoff
 * like every other setting. */
sl_result sl_camera_set_label(sl_camera *camera, const char *label, sl_error *err);
/* Reopens a lost connection; clears camera->lost on success. */
sl_result sl_camera_reconnect(sl_camera *camera, sl_error *err);

#endif
