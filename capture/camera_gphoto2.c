/* SPDX-License-Identifier: BSD-3-Clause */
/* The libgphoto2 backend: any port libgphoto2 knows (usb:, ptpip:, serial:).
 * Exposure settings go through the camera's config widgets; a capture is a
 * trigger, a wait for the file-added event and a download of that file. */
#include <gphoto2/gphoto2.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "camera_backend.h"

typedef struct gp_impl {
    Camera *camera;
    GPContext *context;
    char port[128];
    char last_error[512]; /* libgphoto2's own words for the last failure */
} gp_impl;

static void on_error(GPContext *context, const char *text, void *data)
{
    (void)context;
    gp_impl *g = data;
    snprintf(g->last_error, sizeof g->last_error, "%s", text);
    /* one line: libgphoto2 sometimes ends its messages with newlines */
    for (char *c = g->last_error; *c; c++)
        if (*c == '\n' || *c == '\r')
            *c = ' ';
}

/* Results that mean the connection itself is gone (cable out, camera off,
 * network down): the capture loop reconnects. */
static bool connection_lost(int gr)
{
    return gr == GP_ERROR_IO || gr == GP_ERROR_TIMEOUT || gr == GP_ERROR_IO_INIT ||
           gr == GP_ERROR_IO_READ || gr == GP_ERROR_IO_WRITE || gr == GP_ERROR_IO_UPDATE ||
           gr == GP_ERROR_IO_USB_FIND || gr == GP_ERROR_IO_USB_CLAIM ||
           gr == GP_ERROR_IO_USB_CLEAR_HALT;
}

/* A libgphoto2 failure as an sl_error naming the port; marks busy replies
 * and lost connections on the camera. The ptp2 driver reports a PTP/IP
 * socket that went away as a generic error (PTP General Error): during a
 * trigger or a download that is taken as a lost connection (`io`); while
 * setting a value, only when the setting cannot be read back either. */
static sl_result gp_fail_io(sl_camera *c, gp_impl *g, int gr, bool io, const char *what,
                            sl_error *err)
{
    if (c) {
        c->busy = gr == GP_ERROR_CAMERA_BUSY;
        c->lost = connection_lost(gr) || (io && gr == GP_ERROR);
    }
    return sl_error_set(err, SL_ERR_CAMERA, "%s: %s failed: %s%s%s", g->port, what,
                        gp_result_as_string(gr), g->last_error[0] ? ": " : "", g->last_error);
}

static sl_result gp_fail_on(sl_camera *c, gp_impl *g, int gr, const char *what, sl_error *err)
{
    return gp_fail_io(c, g, gr, false, what, err);
}

static sl_result gp_fail(gp_impl *g, int gr, const char *what, sl_error *err)
{
    return gp_fail_on(NULL, g, gr, what, err);
}

/* Widget names by setting, in the order libgphoto2's drivers use them. */
static const char *const k_shutter_names[] = {"shutterspeed", "shutterspeed2", "exptime", NULL};
static const char *const k_fnumber_names[] = {"f-number", "aperture", "fnumber", NULL};
static const char *const k_iso_names[] = {"iso", "isospeed", "exposureindex", NULL};
/* ptp2: "imageformat" (Canon EOS), "imagequality" (PTP CompressionSetting
 * 0x5004: Nikon, Sony, Fuji), "imgquality" (older drivers). */
static const char *const k_format_names[] = {"imageformat", "imagequality", "imgquality", NULL};

enum { SET_SHUTTER, SET_FNUMBER, SET_ISO, SET_FORMAT };

/* "0.0323s", "1/30", "f/4", "f4", "ISO 100", "100" -> number; 0 if not one. */
static double choice_value(int kind, const char *text)
{
    if (!text)
        return 0;
    if (kind == SET_SHUTTER)
        return sl_shutter_parse(text);
    while (*text && (*text < '0' || *text > '9') && *text != '.')
        text++;
    char *end;
    double v = strtod(text, &end);
    if (end == text || !(v > 0))
        return 0;
    return v;
}

static sl_result find_widget(sl_camera *c, int kind, CameraWidget **widget, const char **name,
                             sl_error *err)
{
    gp_impl *g = c->impl;
    const char *const *names = kind == SET_SHUTTER   ? k_shutter_names
                               : kind == SET_FNUMBER ? k_fnumber_names
                               : kind == SET_ISO     ? k_iso_names
                                                     : k_format_names;
    *widget = NULL;
    for (int i = 0; names[i]; i++) {
        g->last_error[0] = 0;
        int gr = gp_camera_get_single_config(g->camera, names[i], widget, g->context);
        if (gr == GP_OK) {
            *name = names[i];
            return SL_OK;
        }
        if (gr != GP_ERROR_BAD_PARAMETERS && gr != GP_ERROR_NOT_SUPPORTED && gr != GP_ERROR)
            return gp_fail_on(c, g, gr, "reading the camera settings", err);
    }
    return sl_error_set(err, SL_ERR_CAMERA, "%s: the camera has no %s setting", g->port,
                        kind == SET_SHUTTER   ? "shutter speed"
                        : kind == SET_FNUMBER ? "aperture"
                        : kind == SET_ISO     ? "ISO"
                                              : "image format");
}

static sl_result gp_shutter_speeds(sl_camera *c, double **speeds, int *count, sl_error *err)
{
    gp_impl *g = c->impl;
    CameraWidget *w;
    const char *name;
    sl_result r = find_widget(c, SET_SHUTTER, &w, &name, err);
    if (r)
        return r;
    int n = gp_widget_count_choices(w);
    double *v = malloc(sizeof *v * (size_t)(n > 0 ? n : 1));
    if (!v) {
        gp_widget_free(w);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", g->port);
    }
    int k = 0;
    for (int i = 0; i < n; i++) {
        const char *c = NULL;
        double t;
        if (gp_widget_get_choice(w, i, &c) == GP_OK && (t = choice_value(SET_SHUTTER, c)) > 0)
            v[k++] = t;
    }
    gp_widget_free(w);
    qsort(v, (size_t)k, sizeof *v, sl_cmp_double);
    if (k == 0) {
        free(v);
        return sl_error_set(err, SL_ERR_CAMERA,
                            "%s: the camera offers no shutter speeds (is it "
                            "in manual mode?)",
                            g->port);
    }
    *speeds = v;
    *count = k;
    return SL_OK;
}

/* Writes `value` to widget `w` (named `name`) and frees it. */
static sl_result write_widget(sl_camera *c, CameraWidget *w, const char *name, const char *value,
                              const char *what, sl_error *err)
{
    gp_impl *g = c->impl;
    g->last_error[0] = 0;
    int gr = gp_widget_set_value(w, value);
    if (gr == GP_OK)
        gr = gp_camera_set_single_config(g->camera, name, w, g->context);
    gp_widget_free(w);
    if (gr == GP_OK)
        return SL_OK;
    char msg[sizeof g->last_error];
    snprintf(msg, sizeof msg, "%s", g->last_error);
    /* A refusal, or a connection that went away in the middle (the ptp2
     * driver then says "General Error" or "Property not found"): if the
     * setting cannot even be read back, it is the latter (the capture loop
     * then reconnects). */
    bool gone = false;
    if (!connection_lost(gr)) {
        CameraWidget *probe = NULL;
        gone = gp_camera_get_single_config(g->camera, name, &probe, g->context) != GP_OK;
        if (probe)
            gp_widget_free(probe);
    }
    snprintf(g->last_error, sizeof g->last_error, "%s", msg);
    sl_result r = gp_fail_on(c, g, gr, what, err);
    c->lost = c->lost || gone;
    return r;
}

/* Sets one setting to the offered choice nearest `value` (in stops). */
static sl_result set_one(sl_camera *c, int kind, double value, sl_error *err)
{
    gp_impl *g = c->impl;
    CameraWidget *w;
    const char *name;
    sl_result r = find_widget(c, kind, &w, &name, err);
    if (r)
        return r;
    const char *best = NULL;
    double best_d = INFINITY;
    for (int i = 0; i < gp_widget_count_choices(w); i++) {
        const char *c = NULL;
        double v;
        if (gp_widget_get_choice(w, i, &c) != GP_OK || !(v = choice_value(kind, c)))
            continue;
        double d = fabs(log2(v / value));
        if (d < best_d) {
            best_d = d;
            best = c;
        }
    }
    if (!best) {
        gp_widget_free(w);
        return sl_error_set(err, SL_ERR_CAMERA, "%s: setting %s offers no values", g->port, name);
    }
    char what[96];
    snprintf(what, sizeof what, "setting %s to %g", name, value);
    return write_widget(c, w, name, best, what, err);
}

static sl_result gp_format_choices(sl_camera *c, char (*labels)[64], int max, int *count,
                                   char current[64], sl_error *err)
{
    CameraWidget *w;
    const char *name, *value = NULL;
    sl_result r = find_widget(c, SET_FORMAT, &w, &name, err);
    if (r)
        return r;
    *count = 0;
    for (int i = 0; i < gp_widget_count_choices(w) && *count < max; i++) {
        const char *label = NULL;
        if (gp_widget_get_choice(w, i, &label) == GP_OK && label)
            snprintf(labels[(*count)++], 64, "%s", label);
    }
    snprintf(current, 64, "%s", gp_widget_get_value(w, &value) == GP_OK && value ? value : "");
    gp_widget_free(w);
    return SL_OK;
}

static sl_result gp_set_format(sl_camera *c, const char *label, sl_error *err)
{
    CameraWidget *w;
    const char *name;
    sl_result r = find_widget(c, SET_FORMAT, &w, &name, err);
    if (r)
        return r;
    char what[128];
    snprintf(what, sizeof what, "setting %s to '%.60s'", name, label);
    return write_widget(c, w, name, label, what, err);
}

static sl_result gp_set(sl_camera *c, const sl_camera_settings *s, sl_error *err)
{
    sl_result r = SL_OK;
    if (s->f_number > 0)
        r = set_one(c, SET_FNUMBER, s->f_number, err);
    if (!r && s->iso > 0)
        r = set_one(c, SET_ISO, s->iso, err);
    if (!r && s->exposure_time > 0)
        r = set_one(c, SET_SHUTTER, s->exposure_time, err);
    return r;
}

static double get_one(sl_camera *c, int kind)
{
    CameraWidget *w;
    const char *name;
    if (find_widget(c, kind, &w, &name, NULL))
        return 0;
    const char *value = NULL;
    double v = 0;
    if (gp_widget_get_value(w, &value) == GP_OK)
        v = choice_value(kind, value);
    gp_widget_free(w);
    return v;
}

static sl_result gp_get(sl_camera *c, sl_camera_settings *s, sl_error *err)
{
    (void)err;
    s->exposure_time = get_one(c, SET_SHUTTER);
    s->f_number = get_one(c, SET_FNUMBER);
    s->iso = get_one(c, SET_ISO);
    return SL_OK;
}

static sl_result download(sl_camera *c, const CameraFilePath *path, sl_camera_file *file,
                          sl_error *err)
{
    gp_impl *g = c->impl;
    CameraFile *f = NULL;
    int gr = gp_file_new(&f);
    if (gr == GP_OK) {
        g->last_error[0] = 0;
        gr = gp_camera_file_get(g->camera, path->folder, path->name, GP_FILE_TYPE_NORMAL, f,
                                g->context);
    }
    const char *data = NULL;
    unsigned long size = 0;
    if (gr == GP_OK)
        gr = gp_file_get_data_and_size(f, &data, &size);
    if (gr != GP_OK) {
        if (f)
            gp_file_unref(f);
        char what[400];
        snprintf(what, sizeof what, "downloading %.200s/%.128s", path->folder, path->name);
        return gp_fail_io(c, g, gr, true, what, err);
    }
    file->data = malloc(size ? size : 1);
    if (!file->data) {
        gp_file_unref(f);
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", g->port);
    }
    memcpy(file->data, data, size);
    file->size = size;
    snprintf(file->source, sizeof file->source, "%.120s%s%.120s", path->folder,
             strcmp(path->folder, "/") ? "/" : "", path->name);
    gp_file_unref(f);
    if (size == 0) {
        free(file->data);
        memset(file, 0, sizeof *file);
        return sl_error_set(err, SL_ERR_CAMERA, "%s: %s is empty", g->port, path->name);
    }
    return SL_OK;
}

/* Downloads the next file of the shot. */
static sl_result take(sl_camera *c, const CameraFilePath *path, sl_camera_shot *shot, sl_error *err)
{
    sl_result r = download(c, path, &shot->files[shot->count], err);
    if (!r)
        shot->count++;
    return r;
}

/* Waits up to timeout_ms for one event of the trigger: a new file is
 * downloaded into the shot (a shot already full is an error), a capture
 * complete after its first file sets *complete, no event at all *quiet. */
static sl_result next_event(sl_camera *c, sl_camera_shot *shot, int timeout_ms, bool *complete,
                            bool *quiet, sl_error *err)
{
    gp_impl *g = c->impl;
    CameraEventType type;
    void *data = NULL;
    g->last_error[0] = 0;
    int gr = gp_camera_wait_for_event(g->camera, timeout_ms, &type, &data, g->context);
    if (gr != GP_OK) {
        free(data);
        return gp_fail_io(c, g, gr, true, "waiting for the new file", err);
    }
    if (type == GP_EVENT_FILE_ADDED && data) {
        CameraFilePath path = *(CameraFilePath *)data;
        free(data);
        if (shot->count == SL_SHOT_MAX_FILES)
            return sl_error_set(err, SL_ERR_CAMERA, "%s: more than %d files from one trigger",
                                g->port, SL_SHOT_MAX_FILES);
        return take(c, &path, shot, err);
    }
    /* every other event's data is ours to free too */
    free(data);
    *complete = type == GP_EVENT_CAPTURE_COMPLETE && shot->count > 0;
    *quiet = type == GP_EVENT_TIMEOUT;
    return SL_OK;
}

static sl_result gp_capture(sl_camera *c, sl_camera_shot *shot, sl_error *err)
{
    gp_impl *g = c->impl;
    g->last_error[0] = 0;
    int gr = gp_camera_trigger_capture(g->camera, g->context);
    if (gr == GP_ERROR_NOT_SUPPORTED) {
        /* Drivers without a separate trigger wait for the new file themselves. */
        CameraFilePath path;
        memset(&path, 0, sizeof path);
        gr = gp_camera_capture(g->camera, GP_CAPTURE_IMAGE, &path, g->context);
        if (gr != GP_OK)
            return gp_fail_io(c, g, gr, true, "capture", err);
        return take(c, &path, shot, err);
    }
    if (gr != GP_OK)
        return gp_fail_io(c, g, gr, true, "trigger", err);
    /* Wait for the trigger's files: long exposures and slow cards get 60 s
     * for the first, a raw written after its JPEG 15 s more. A capture
     * complete before all arrived ends the wait (a body that writes fewer
     * files than its format says: the capture loop rejects the frame); one
     * left over from the previous trigger comes before any file and is
     * skipped. */
    bool complete = false, quiet = false;
    double deadline = sl_seconds() + 60.0;
    while (!complete && shot->count < shot->expected && sl_seconds() < deadline) {
        int before = shot->count;
        sl_result r = next_event(c, shot, 1000, &complete, &quiet, err);
        if (r)
            return r;
        if (shot->count > before)
            deadline = sl_seconds() + 15.0;
    }
    if (shot->count == 0) {
        c->lost = true;
        return sl_error_set(err, SL_ERR_CAMERA, "%s: no new file 60 s after the trigger",
                            g->port);
    }
    /* More files than the format said (a mode whose label setlight cannot
     * read) come before the capture complete: taken too, so that none is
     * mistaken for the next trigger's. At most 1 s, and 100 ms of quiet
     * ends it (bodies that send no capture complete). */
    deadline = sl_seconds() + 1.0;
    quiet = false;
    while (!complete && !quiet && sl_seconds() < deadline) {
        sl_result r = next_event(c, shot, 100, &complete, &quiet, err);
        if (r)
            return r;
    }
    return SL_OK;
}

static sl_result gp_reconnect(sl_camera *c, sl_error *err)
{
    gp_impl *g = c->impl;
    gp_camera_exit(g->camera, g->context);
    g->last_error[0] = 0;
    int gr = gp_camera_init(g->camera, g->context);
    if (gr < GP_OK)
        return sl_error_set(err, SL_ERR_CAMERA, "%s: no camera answers: %s%s%s", g->port,
                            gp_result_as_string(gr), g->last_error[0] ? ": " : "",
                            g->last_error);
    return SL_OK;
}

static void gp_close(void *impl)
{
    gp_impl *g = impl;
    if (g->camera) {
        gp_camera_exit(g->camera, g->context);
        gp_camera_unref(g->camera);
    }
    if (g->context)
        gp_context_unref(g->context);
    free(g);
}

static const sl_camera_ops k_ops = {"gphoto2",         gp_shutter_speeds, gp_set,     gp_get,
                                    gp_format_choices, gp_set_format,     gp_capture, NULL,
                                    gp_reconnect,      gp_close};

static sl_result autodetect(GPContext *ctx, CameraList **list, sl_error *err)
{
    int gr = gp_list_new(list);
    if (gr == GP_OK)
        gr = gp_camera_autodetect(*list, ctx);
    if (gr < GP_OK) {
        if (*list)
            gp_list_free(*list);
        *list = NULL;
        return sl_error_set(err, SL_ERR_CAMERA, "camera detection failed: %s",
                            gp_result_as_string(gr));
    }
    return SL_OK;
}

sl_result sl_gphoto2_list(sl_camera_entry **list, int *count, sl_error *err)
{
    *list = NULL;
    *count = 0;
    GPContext *ctx = gp_context_new();
    CameraList *cl = NULL;
    sl_result r = autodetect(ctx, &cl, err);
    if (r) {
        gp_context_unref(ctx);
        return r;
    }
    int n = gp_list_count(cl);
    sl_camera_entry *e = calloc((size_t)(n > 0 ? n : 1), sizeof *e);
    if (!e) {
        gp_list_free(cl);
        gp_context_unref(ctx);
        return sl_error_set(err, SL_ERR_NOMEM, "camera list: out of memory");
    }
    for (int i = 0; i < n; i++) {
        const char *name = NULL, *value = NULL;
        gp_list_get_name(cl, i, &name);
        gp_list_get_value(cl, i, &value);
        snprintf(e[i].model, sizeof e[i].model, "%s", name ? name : "");
        snprintf(e[i].port, sizeof e[i].port, "%s", value ? value : "");
    }
    gp_list_free(cl);
    gp_context_unref(ctx);
    *list = e;
    *count = n;
    return SL_OK;
}

/* Which driver a port needs: PTP/IP has one generic model; anything else is
 * whatever libgphoto2 detects on that port. */
static sl_result model_for_port(gp_impl *g, char *port, char *model, size_t size, sl_error *err)
{
    if (!strncmp(port, "ptpip:", 6)) {
        /* libgphoto2 2.5.30 connects events to 15740 unless a second port is
         * given; a camera on another port serves both channels there. */
        const char *host = port + 6, *colon = strchr(host, ':');
        if (colon && !strchr(colon + 1, ':') && strlen(port) + strlen(colon) < 128) {
            char event_port[128];
            snprintf(event_port, sizeof event_port, "%s", colon);
            strcat(port, event_port);
        }
        snprintf(model, size, "PTP/IP Camera");
        return SL_OK;
    }
    CameraList *cl = NULL;
    sl_result r = autodetect(g->context, &cl, err);
    if (r)
        return r;
    int n = gp_list_count(cl);
    bool found = false;
    for (int i = 0; i < n && !found; i++) {
        const char *name = NULL, *value = NULL;
        gp_list_get_name(cl, i, &name);
        gp_list_get_value(cl, i, &value);
        if (!strcmp(port, "auto") || (value && !strcmp(value, port))) {
            snprintf(model, size, "%s", name ? name : "");
            if (!strcmp(port, "auto"))
                snprintf(port, 128, "%s", value ? value : "");
            found = true;
        }
    }
    gp_list_free(cl);
    if (!found)
        return sl_error_set(err, SL_ERR_CAMERA, "%s: no camera found%s", port,
                            strcmp(port, "auto") ? " on this port" : " (is it on and connected?)");
    return SL_OK;
}

sl_result sl_gphoto2_open(const char *port_in, sl_camera *camera, sl_error *err)
{
    gp_impl *g = calloc(1, sizeof *g);
    if (!g)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", port_in);
    snprintf(g->port, sizeof g->port, "%s", port_in);
    char port[128], model[128];
    snprintf(port, sizeof port, "%s", port_in);
    g->context = gp_context_new();
    gp_context_set_error_func(g->context, on_error, g);

    GPPortInfoList *pil = NULL;
    CameraAbilitiesList *al = NULL;
    sl_result r = SL_OK;
    int gr;
    if (strcmp(port, "auto") != 0 && !strchr(port, ':')) {
        r = sl_error_set(err, SL_ERR_USAGE,
                         "%s: unknown camera port (auto, usb:BUS,DEV, "
                         "ptpip:HOST[:PORT], serial:DEVICE)",
                         port_in);
        goto done;
    }
    if ((gr = gp_port_info_list_new(&pil)) < GP_OK || (gr = gp_port_info_list_load(pil)) < GP_OK ||
        (gr = gp_abilities_list_new(&al)) < GP_OK ||
        (gr = gp_abilities_list_load(al, g->context)) < GP_OK) {
        r = gp_fail(g, gr, "loading the libgphoto2 drivers", err);
        goto done;
    }
    if (strcmp(port, "auto") != 0 && gp_port_info_list_lookup_path(pil, port) < GP_OK) {
        r = sl_error_set(err, SL_ERR_USAGE,
                         "%s: unknown camera port (auto, usb:BUS,DEV, "
                         "ptpip:HOST[:PORT], serial:DEVICE)",
                         port_in);
        goto done;
    }
    if ((r = model_for_port(g, port, model, sizeof model, err)))
        goto done;
    int mi = gp_abilities_list_lookup_model(al, model);
    int pi = gp_port_info_list_lookup_path(pil, port);
    CameraAbilities abilities;
    GPPortInfo info;
    if (mi < GP_OK || pi < GP_OK ||
        (gr = gp_abilities_list_get_abilities(al, mi, &abilities)) < GP_OK ||
        (gr = gp_port_info_list_get_info(pil, pi, &info)) < GP_OK) {
        r = sl_error_set(err, SL_ERR_CAMERA, "%s: libgphoto2 has no driver for '%s'", port_in,
                         model);
        goto done;
    }
    if ((gr = gp_camera_new(&g->camera)) < GP_OK ||
        (gr = gp_camera_set_abilities(g->camera, abilities)) < GP_OK ||
        (gr = gp_camera_set_port_info(g->camera, info)) < GP_OK) {
        r = gp_fail(g, gr, "setting up the camera", err);
        goto done;
    }
    g->last_error[0] = 0;
    gr = gp_camera_init(g->camera, g->context);
    if (gr < GP_OK) {
        r = sl_error_set(err, SL_ERR_CAMERA, "%s: no camera answers: %s%s%s", port_in,
                         gp_result_as_string(gr), g->last_error[0] ? ": " : "", g->last_error);
        gp_camera_unref(g->camera);
        g->camera = NULL;
        goto done;
    }
    camera->ops = &k_ops;
    camera->impl = g;
    snprintf(camera->model, sizeof camera->model, "%s", model);
    snprintf(camera->port, sizeof camera->port, "%s", port_in);
    /* Generic drivers (PTP/IP) know the model only from the camera itself. */
    CameraText summary;
    if (gp_camera_get_summary(g->camera, &summary, g->context) == GP_OK) {
        const char *m = strstr(summary.text, "Manufacturer: ");
        const char *d = strstr(summary.text, "Model: ");
        if (m && d) {
            int ml = (int)strcspn(m + 14, "\n"), dl = (int)strcspn(d + 7, "\n");
            snprintf(camera->model, sizeof camera->model, "%.*s %.*s", ml, m + 14, dl, d + 7);
        }
    }
done:
    if (al)
        gp_abilities_list_free(al);
    if (pil)
        gp_port_info_list_free(pil);
    if (r)
        gp_close(g);
    return r;
}
