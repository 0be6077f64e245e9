/* SPDX-License-Identifier: BSD-3-Clause */
/* sl_camera: the backend-independent face of a camera. Busy replies are
 * retried here, with the same backoff for every backend. */
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "camera_backend.h"

sl_result sl_camera_list(sl_camera_entry **list, int *count, sl_error *err)
{
    return sl_gphoto2_list(list, count, err);
}

/* The drivers other than libgphoto2, as registered (a fixed table: a
 * handful at most, registered at start-up before any thread opens one). */
#define MAX_DRIVERS 8
static const sl_camera_driver *g_drivers[MAX_DRIVERS];
static int g_driver_count;

sl_result sl_camera_driver_register(const sl_camera_driver *driver, sl_error *err)
{
    for (int i = 0; i < g_driver_count; i++)
        if (!strcmp(g_drivers[i]->name, driver->name))
            return SL_OK;
    if (g_driver_count == MAX_DRIVERS)
        return sl_error_set(err, SL_ERR_INTERNAL, "camera driver %s: the table is full (%d)",
                            driver->name, MAX_DRIVERS);
    g_drivers[g_driver_count++] = driver;
    return SL_OK;
}

/* The registered driver whose name is the port ("virtual") or its prefix
 * before ':' ("virtual:stage"), or NULL. */
static const sl_camera_driver *driver_of_port(const char *port, const char **args)
{
    for (int i = 0; i < g_driver_count; i++) {
        size_t n = strlen(g_drivers[i]->name);
        if (!strncmp(port, g_drivers[i]->name, n) && (port[n] == '\0' || port[n] == ':')) {
            *args = port[n] == ':' ? port + n + 1 : NULL;
            return g_drivers[i];
        }
    }
    return NULL;
}

sl_result sl_camera_open(const char *port, sl_camera **camera, sl_error *err)
{
    *camera = NULL;
    if (!port || !*port)
        return sl_error_set(err, SL_ERR_USAGE,
                            "no camera port given (auto, usb:..., ptpip:HOST, virtual)");
    sl_camera *c = calloc(1, sizeof *c);
    if (!c)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", port);
    const char *args = NULL;
    const sl_camera_driver *driver = driver_of_port(port, &args);
    sl_result r = driver ? driver->open(args, c, err) : sl_gphoto2_open(port, c, err);
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
    return camera->ops->shutter_speeds(camera, speeds, count, err);
}

/* Busy: the camera is still writing the last frame. 20 ms doubling to 640 ms. */
static void backoff(int attempt)
{
    int ms = 20 << (attempt < 5 ? attempt : 5);
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

/* One backend op, retried with backoff while the camera answers busy, at
 * most `max` times; *retries (may be NULL) gets how many retries it took. */
typedef sl_result (*camera_op)(sl_camera *c, void *arg, sl_error *err);

static sl_result retry_busy(sl_camera *c, camera_op op, void *arg, int max, int *retries,
                            sl_error *err)
{
    sl_result r;
    int n = 0;
    for (;; n++) {
        c->busy = false;
        r = op(c, arg, err);
        if (!r || !c->busy || n >= max)
            break;
        backoff(n);
    }
    if (retries)
        *retries = n;
    return r;
}

/* The ops through one signature; the void * is the op's own argument. */
static sl_result op_set(sl_camera *c, void *arg, sl_error *err)
{
    return c->ops->set(c, arg, err);
}

static sl_result op_set_format(sl_camera *c, void *arg, sl_error *err)
{
    return c->ops->set_format(c, arg, err);
}

static sl_result op_capture(sl_camera *c, void *arg, sl_error *err)
{
    return c->ops->capture(c, arg, err);
}

sl_result sl_camera_set(sl_camera *camera, const sl_camera_settings *settings, sl_error *err)
{
    return retry_busy(camera, op_set, (void *)settings, 8, NULL, err);
}

sl_result sl_camera_set_label(sl_camera *camera, const char *label, sl_error *err)
{
    return retry_busy(camera, op_set_format, (void *)label, 8, NULL, err);
}

sl_result sl_camera_get(sl_camera *camera, sl_camera_settings *settings, sl_error *err)
{
    memset(settings, 0, sizeof *settings);
    return camera->ops->get(camera, settings, err);
}

sl_result sl_camera_capture(sl_camera *camera, sl_camera_shot *shot, sl_error *err)
{
    memset(shot, 0, sizeof *shot);
    shot->expected = camera->files_per_shot > 0 ? camera->files_per_shot : 1;
    return retry_busy(camera, op_capture, shot, 10, &shot->busy_retries, err);
}

void sl_camera_aim(sl_camera *camera, int view, int views)
{
    if (camera->ops->aim)
        camera->ops->aim(camera, view, views);
}

sl_result sl_camera_reconnect(sl_camera *camera, sl_error *err)
{
    sl_result r = camera->ops->reconnect(camera, err);
    if (!r)
        camera->lost = false;
    return r;
}

void sl_camera_shot_free(sl_camera_shot *shot)
{
    if (!shot)
        return;
    for (int i = 0; i < shot->count; i++)
        free(shot->files[i].data);
    memset(shot, 0, sizeof *shot);
}
