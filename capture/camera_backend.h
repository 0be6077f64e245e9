/* SPDX-License-Identifier: BSD-3-Clause */
/* The one interface between sl_camera and its backends (camera.c). */
#ifndef SETLIGHT_CAMERA_BACKEND_H
#define SETLIGHT_CAMERA_BACKEND_H

#include "setlight/capture.h"

typedef struct sl_camera_ops {
    const char *name;
    sl_result (*shutter_speeds)(void *impl, double **speeds, int *count, sl_error *err);
    sl_result (*set)(void *impl, const sl_camera_settings *s, sl_error *err);
    sl_result (*get)(void *impl, sl_camera_settings *s, sl_error *err);
    sl_result (*capture)(void *impl, sl_camera_file *file, sl_error *err);
    void (*close)(void *impl);
} sl_camera_ops;

struct sl_camera {
    const sl_camera_ops *ops;
    void *impl;
    char model[128];
    char port[128];
};

/* libgphoto2 (camera_gphoto2.c). */
sl_result sl_gphoto2_open(const char *port, sl_camera *camera, sl_error *err);
sl_result sl_gphoto2_list(sl_camera_entry **list, int *count, sl_error *err);

#endif
