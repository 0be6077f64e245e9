/* SPDX-License-Identifier: BSD-3-Clause */
/* sl_camera: the backend-independent face of a camera. */
#include <stdlib.h>
#include <string.h>

#include "camera_backend.h"

sl_result sl_camera_list(sl_camera_entry **list, int *count, sl_error *err)
{
    return sl_gphoto2_list(list, count, err);
}

sl_result sl_camera_open(const char *port, sl_camera **camera, sl_error *err)
{
    *camera = NULL;
    if (!port || !*port)
        return sl_error_set(err, SL_ERR_USAGE, "no camera port given (auto, usb:..., ptpip:HOST)");
    sl_camera *c = calloc(1, sizeof *c);
    if (!c)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", port);
    sl_result r = sl_gphoto2_open(port, c, err);
    if (r) {
        free(c);
        return r;
    }
    *camera = c;
    return SL_OK;
}

void sl_camera_close(sl_camera *camera)
{
    if (!camera)
        return;
    if (camera->ops)
        camera->ops->close(camera->impl);
    free(camera);
}

const char *sl_camera_model(const sl_camera *camera)
{
    return camera->model;
}
const char *sl_camera_port(const sl_camera *camera)
{
    return camera->port;
}
const char *sl_camera_backend(const sl_camera *camera)
{
    return camera->ops->name;
}

sl_result sl_camera_shutter_speeds(sl_camera *camera, double **speeds, int *count, sl_error *err)
{
    *speeds = NULL;
    *count = 0;
    return camera->ops->shutter_speeds(camera->impl, speeds, count, err);
}

sl_result sl_camera_set(sl_camera *camera, const sl_camera_settings *settings, sl_error *err)
{
    return camera->ops->set(camera->impl, settings, err);
}

sl_result sl_camera_get(sl_camera *camera, sl_camera_settings *settings, sl_error *err)
{
    memset(settings, 0, sizeof *settings);
    return camera->ops->get(camera->impl, settings, err);
}

sl_result sl_camera_capture(sl_camera *camera, sl_camera_file *file, sl_error *err)
{
    memset(file, 0, sizeof *file);
    return camera->ops->capture(camera->impl, file, err);
}

void sl_camera_file_free(sl_camera_file *file)
{
    if (!file)
        return;
    free(file->data);
    file->data = NULL;
    file->size = 0;
    file->busy_retries = 0;
}
