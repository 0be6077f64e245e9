/* SPDX-License-Identifier: BSD-3-Clause */
/* The virtual camera: the virtual set's simulated body and fisheye on a
 * nodal head, behind the same sl_camera interface as libgphoto2, so the
 * whole capture path (plan, snapping, verification, journal, resume) runs
 * without hardware. It can inject the faults real cameras show. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "camera_backend.h"
#include "setlight/vset.h"

/* Nominal third-stop speeds, as bodies label them and write them to EXIF. */
static const double k_speeds[] = {
    1.0 / 8000, 1.0 / 6400, 1.0 / 5000, 1.0 / 4000, 1.0 / 3200, 1.0 / 2500, 1.0 / 2000,
    1.0 / 1600, 1.0 / 1250, 1.0 / 1000, 1.0 / 800,  1.0 / 640,  1.0 / 500,  1.0 / 400,
    1.0 / 320,  1.0 / 250,  1.0 / 200,  1.0 / 160,  1.0 / 125,  1.0 / 100,  1.0 / 80,
    1.0 / 60,   1.0 / 50,   1.0 / 40,   1.0 / 30,   1.0 / 25,   1.0 / 20,   1.0 / 15,
    1.0 / 13,   1.0 / 10,   1.0 / 8,    1.0 / 6,    1.0 / 5,    1.0 / 4,    0.3,
    0.4,        0.5,        0.6,        0.8,        1,          1.3,        1.6,
    2,          2.5,        3.2,        4,          5,          6,          8,
    10,         13,         15,         20,         25,         30};
static const double k_fnumbers[] = {2.8, 4, 5.6, 8, 11, 16, 22};
static const double k_isos[] = {100, 200, 400, 800, 1600, 3200};
/* Image quality labels as a body's menu shows them; the raw is a DNG. */
static const char *const k_formats[] = {"JPEG Fine", "RAW", "RAW + JPEG Fine"};
#define COUNT(a) ((int)(sizeof(a) / sizeof(a)[0]))

/* The shoot day of the virtual clock: 2026-05-14 10:00:00 UTC. */
#define CLOCK_EPOCH 1778752800.0
#define FRAME_GAP_S 0.2 /* 5 frames a second, as a body in continuous drive */
#define HEAD_TURN_S 15.0

typedef struct vcam {
    sl_virtual_camera_opts o;
    sl_vset_scene scene;
    sl_vset_camera body;
    sl_lens lens; /* the virtual set's true fisheye */
    int width, height;
    sl_image radiance; /* the current view through the lens, cached */
    int view, views;
    double shutter;        /* what the camera reports it is set to */
    double actual_shutter; /* what it exposes with */
    double f_number, iso;
    int shutter_changes;
    int format;       /* index into k_formats: what the body writes */
    int format_shown; /* what its setting reads */
    int format_changes;
    int delivered; /* frames on the card */
    int busy_left, down_left;
    bool dropped, lost;
    double clock; /* seconds since CLOCK_EPOCH */
    char tmpdir[4096];
} vcam;

static double nearest(const double *v, int n, double x)
{
    double best = v[0];
    for (int i = 1; i < n; i++)
        if (fabs(log(v[i] / x)) < fabs(log(best / x)))
            best = v[i];
    return best;
}

static sl_result lost(sl_camera *c, sl_error *err)
{
    c->lost = true;
    return sl_error_set(err, SL_ERR_CAMERA, "%s: the connection to the camera is lost (I/O error)",
                        c->port);
}

static sl_result v_shutter_speeds(sl_camera *c, double **speeds, int *count, sl_error *err)
{
    vcam *v = c->impl;
    if (v->lost)
        return lost(c, err);
    double *s = malloc(sizeof k_speeds);
    if (!s)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", c->port);
    memcpy(s, k_speeds, sizeof k_speeds);
    *speeds = s;
    *count = COUNT(k_speeds);
    return SL_OK;
}

static sl_result v_set(sl_camera *c, const sl_camera_settings *s, sl_error *err)
{
    vcam *v = c->impl;
    if (v->lost)
        return lost(c, err);
    if (s->f_number > 0)
        v->f_number = nearest(k_fnumbers, COUNT(k_fnumbers), s->f_number);
    if (s->iso > 0)
        v->iso = nearest(k_isos, COUNT(k_isos), s->iso);
    if (s->exposure_time > 0) {
        double t = nearest(k_speeds, COUNT(k_speeds), s->exposure_time);
        if (v->o.refuse_shutter > 0 && fabs(log2(t / v->o.refuse_shutter)) < 1.0 / 6) {
            char a[32];
            sl_shutter_format(t, a, sizeof a);
            return sl_error_set(err, SL_ERR_CAMERA,
                                "%s: setting shutterspeed to %s s failed: the camera refused the "
                                "value",
                                c->port, a);
        }
        if (t != v->shutter && ++v->shutter_changes == v->o.ignore_shutter) {
            /* acknowledged, not applied; a body with a stuck mechanism even
             * reports and records the new speed */
            if (v->o.exif_lies)
                v->shutter = t;
        } else {
            v->shutter = t;
            v->actual_shutter = t;
        }
    }
    return SL_OK;
}

static sl_result v_get(sl_camera *c, sl_camera_settings *s, sl_error *err)
{
    vcam *v = c->impl;
    if (v->lost)
        return lost(c, err);
    s->exposure_time = v->shutter;
    s->f_number = v->f_number;
    s->iso = v->iso;
    return SL_OK;
}

/* The sRGB-encoded JPEG of one exposure, as the body's encoder writes it. */
static sl_result encode(sl_camera *c, const sl_image *img, unsigned char **data, size_t *size,
                        sl_error *err)
{
    vcam *v = c->impl;
    char path[4200];
    snprintf(path, sizeof path, "%s/frame.jpg", v->tmpdir);
    sl_meta none;
    sl_meta_init(&none);
    sl_result r = sl_photo_write(path, img, &none, 8, err);
    sl_meta_free(&none);
    if (r)
        return r;
    FILE *f = fopen(path, "rb");
    if (!f)
        return sl_error_set(err, SL_ERR_IO, "%s: cannot read back: %s", path, strerror(errno));
    fseek(f, 0, SEEK_END);
    long n = ftell(f);
    fseek(f, 0, SEEK_SET);
    *data = n > 0 ? malloc((size_t)n) : NULL;
    bool ok = *data && fread(*data, 1, (size_t)n, f) == (size_t)n;
    fclose(f);
    remove(path);
    if (!ok) {
        free(*data);
        *data = NULL;
        return sl_error_set(err, SL_ERR_IO, "%s: cannot read back", path);
    }
    *size = (size_t)n;
    return SL_OK;
}

static sl_result v_format_choices(sl_camera *c, char (*labels)[64], int max, int *count,
                                  char current[64], sl_error *err)
{
    vcam *v = c->impl;
    if (v->lost)
        return lost(c, err);
    *count = 0;
    for (int i = 0; i < COUNT(k_formats) && i < max; i++)
        snprintf(labels[(*count)++], 64, "%s", k_formats[i]);
    snprintf(current, 64, "%s", k_formats[v->format_shown]);
    return SL_OK;
}

static sl_result v_set_format(sl_camera *c, const char *label, sl_error *err)
{
    vcam *v = c->impl;
    if (v->lost)
        return lost(c, err);
    for (int i = 0; i < COUNT(k_formats); i++)
        if (!strcmp(label, k_formats[i])) {
            /* the k-th change is acknowledged, not applied (a body that
             * lies even reads back the new format) */
            bool ignored = i != v->format && ++v->format_changes == v->o.ignore_format;
            if (!ignored)
                v->format = i;
            if (!ignored || v->o.format_lies)
                v->format_shown = i;
            return SL_OK;
        }
    return sl_error_set(err, SL_ERR_CAMERA,
                        "%s: setting imagequality to '%s' failed: no such value", c->port, label);
}

/* The EXIF the body writes for the frame it is about to deliver. */
static void frame_meta(const vcam *v, sl_meta *meta, int *subsec_ms)
{
    sl_meta_init(meta);
    meta->exposure_time = v->shutter; /* what the body believes it used */
    meta->f_number = v->f_number;
    meta->iso = v->iso;
    meta->focal_length_mm = SL_VSET_FISHEYE_FOCAL_MM;
    snprintf(meta->lens, sizeof meta->lens, "%s", SL_VSET_FISHEYE_NAME);
    snprintf(meta->make, sizeof meta->make, "%s", v->body.make);
    snprintf(meta->model, sizeof meta->model, "%s", v->body.model);
    time_t when = (time_t)(CLOCK_EPOCH + floor(v->clock));
    struct tm tm;
    gmtime_r(&when, &tm);
    strftime(meta->datetime, sizeof meta->datetime, "%Y:%m:%d %H:%M:%S", &tm);
    *subsec_ms = (int)floor((v->clock - floor(v->clock)) * 1000.0);
}

static void deliver(sl_camera_shot *shot, unsigned char *data, size_t size, int frame,
                    const char *ext)
{
    sl_camera_file *f = &shot->files[shot->count++];
    f->data = data;
    f->size = size;
    snprintf(f->source, sizeof f->source, "/DCIM/100VSET/IMG_%04d.%s", frame, ext);
}

/* The in-camera JPEG (sRGB-encoded) and/or the raw (a DNG of the linear
 * output) of one exposure, as the image format says. */
static sl_result write_files(sl_camera *c, const sl_vset_shot *img, int frame, sl_camera_shot *shot,
                             sl_error *err)
{
    vcam *v = c->impl;
    sl_meta meta;
    int ms;
    frame_meta(v, &meta, &ms);
    unsigned char *data = NULL;
    size_t size = 0;
    sl_result r = SL_OK;
    if (v->format != 1) {
        r = encode(c, &img->encoded, &data, &size, err);
        if (!r && (r = sl_jpeg_set_exif(&data, &size, &meta, ms, err)))
            free(data);
        if (!r)
            deliver(shot, data, size, frame, "JPG");
    }
    if (!r && v->format == 2 && v->o.drop_before_raw == frame) {
        v->lost = true;
        r = lost(c, err);
    }
    if (!r && v->format != 0 && !(r = sl_dng_encode(&img->linear, &meta, ms, &data, &size, err)))
        deliver(shot, data, size, frame, "DNG");
    sl_meta_free(&meta);
    return r;
}

static sl_result v_capture(sl_camera *c, sl_camera_shot *shot, sl_error *err)
{
    vcam *v = c->impl;
    if (v->lost)
        return lost(c, err);
    int frame = v->delivered + 1;
    int drop_after = v->o.drop_at > 0 ? v->o.drop_at - 1 : v->o.drop_after;
    if ((drop_after > 0 || v->o.drop_at > 0) && !v->dropped && v->delivered == drop_after) {
        v->dropped = v->lost = true;
        v->down_left = v->o.down_attempts;
        return lost(c, err);
    }
    if (v->busy_left > 0 && frame >= (v->o.busy_at > 0 ? v->o.busy_at : 1)) {
        v->busy_left--;
        c->busy = true;
        return sl_error_set(err, SL_ERR_CAMERA, "%s: trigger failed: the camera is busy",
                            c->port);
    }
    sl_result r = SL_OK;
    if (!v->radiance.data) {
        const sl_view_pose view = {v->views > 0 ? 360.0 * v->view / v->views : 0, 0, 0};
        r = sl_vset_view_image(&v->lens, &view, &v->scene.latlong, 2, &v->radiance, err);
        if (r)
            return r;
    }
    sl_vset_exposure e = {v->actual_shutter, v->f_number, v->iso};
    sl_vset_shot img;
    if ((r = sl_vset_camera_shoot(&v->body, &e, &v->radiance, sl_splitmix64_hash(v->o.seed ^ (uint64_t)frame),
                                  &img, err)))
        return r;
    r = write_files(c, &img, frame, shot, err);
    sl_vset_shot_free(&img);
    /* the card holds what was written, also when the link then dropped */
    if (shot->count > 0) {
        v->clock += v->actual_shutter + FRAME_GAP_S;
        v->delivered = frame;
    }
    return r;
}

static void v_aim(sl_camera *c, int view, int views)
{
    vcam *v = c->impl;
    if (view == v->view && views == v->views)
        return;
    if (v->delivered > 0)
        v->clock += HEAD_TURN_S;
    v->view = view;
    v->views = views;
    sl_image_free(&v->radiance);
}

static sl_result v_reconnect(sl_camera *c, sl_error *err)
{
    vcam *v = c->impl;
    if (!v->lost)
        return SL_OK;
    if (v->down_left < 0 || v->down_left-- > 0)
        return sl_error_set(err, SL_ERR_CAMERA, "%s: no camera answers", c->port);
    v->lost = false;
    return SL_OK;
}

static void v_close(void *impl)
{
    vcam *v = impl;
    if (!v)
        return;
    if (v->tmpdir[0])
        rmdir(v->tmpdir);
    sl_image_free(&v->radiance);
    sl_vset_scene_free(&v->scene);
    free(v);
}

static const sl_camera_ops k_ops = {"virtual",        v_shutter_speeds, v_set,     v_get,
                                    v_format_choices, v_set_format,     v_capture, v_aim,
                                    v_reconnect,      v_close};

static sl_result virtual_open(const sl_virtual_camera_opts *o, sl_camera *c, sl_error *err)
{
    vcam *v = calloc(1, sizeof *v);
    if (!v)
        return sl_error_set(err, SL_ERR_NOMEM, "virtual camera: out of memory");
    v->o = *o;
    if (!v->o.scene[0])
        snprintf(v->o.scene, sizeof v->o.scene, "stage");
    if (!v->o.seed)
        v->o.seed = 1;
    v->width = o->width > 0 ? o->width : 360;
    v->height = o->height > 0 ? o->height : 240;
    v->busy_left = o->busy;
    v->views = 1;
    snprintf(c->port, sizeof c->port, "virtual:%.119s", v->o.scene);
    sl_result r = SL_OK;
    if (v->width < 16 || v->height < 16 || v->width > 8192 || v->height > 8192)
        r = sl_error_set(err, SL_ERR_USAGE, "%s: frame size %dx%d (16..8192)", c->port, v->width,
                         v->height);
    sl_vset_desc desc;
    const char *scene = v->o.scene;
    bool file = strchr(scene, '/') || strstr(scene, ".json");
    if (!r)
        r = file ? sl_vset_desc_read_json(scene, &desc, err) : sl_vset_preset(scene, &desc, err);
    if (r == SL_ERR_USAGE && !file)
        r = sl_error_set(err, SL_ERR_USAGE,
                         "%s: unknown virtual scene '%s' (exterior, stage, night, or a scene "
                         "JSON file)",
                         c->port, scene);
    if (!r)
        /* about two texels per pixel at the fisheye's centre */
        r = sl_vset_scene_make(&desc, 2 * (int)lround(0.7 * v->width), &v->scene, err);
    if (r) {
        v_close(v);
        return r;
    }
    /* Exposure as a wrangler would set it for this kind of scene, metered
     * to 12% of raw saturation at the log-average luminance. */
    sl_vset_capture_opts d;
    sl_vset_capture_defaults(&d, &desc, SL_VSET_SIZE_TINY);
    sl_vset_camera_default(&v->body, d.wb_kelvin);
    sl_vset_response_preset("srgb", &v->body.response, NULL);
    snprintf(v->body.model, sizeof v->body.model, "virtual camera");
    sl_vset_fisheye_true(&v->lens, v->width, v->height);
    v->f_number = nearest(k_fnumbers, COUNT(k_fnumbers), d.f_number);
    v->iso = nearest(k_isos, COUNT(k_isos), d.iso);
    double lavg = sl_vset_log_average(&v->scene.latlong);
    v->shutter = nearest(k_speeds, COUNT(k_speeds),
                         0.12 * v->f_number * v->f_number / (lavg * v->body.k * v->iso / 100.0));
    v->actual_shutter = v->shutter;
    const char *tmp = getenv("TMPDIR");
    snprintf(v->tmpdir, sizeof v->tmpdir, "%s/setlight-vcam.XXXXXX", tmp && *tmp ? tmp : "/tmp");
    if (!mkdtemp(v->tmpdir)) {
        r = sl_error_set(err, SL_ERR_IO, "%s: cannot create a temporary folder: %s", v->tmpdir,
                         strerror(errno));
        v->tmpdir[0] = 0;
        v_close(v);
        return r;
    }
    c->ops = &k_ops;
    c->impl = v;
    snprintf(c->model, sizeof c->model, "%.40s %.40s (%.40s)", v->body.make, v->body.model,
             v->scene.desc.name);
    return SL_OK;
}

/* The port "virtual[:SCENE]": the faultless camera of a preset or a scene
 * JSON file. */
static sl_result open_port(const char *args, sl_camera *c, sl_error *err)
{
    sl_virtual_camera_opts o;
    memset(&o, 0, sizeof o);
    if (args && strlen(args) >= sizeof o.scene)
        return sl_error_set(err, SL_ERR_USAGE, "virtual:%.200s...: scene name too long", args);
    if (args)
        strcpy(o.scene, args);
    return virtual_open(&o, c, err);
}

static const sl_camera_driver k_driver = {"virtual", open_port};

sl_result sl_vset_camera_register(sl_error *err)
{
    return sl_camera_driver_register(&k_driver, err);
}

sl_result sl_camera_open_virtual(const sl_virtual_camera_opts *o, sl_camera **camera,
                                 sl_error *err)
{
    *camera = NULL;
    sl_camera *c = calloc(1, sizeof *c);
    if (!c)
        return sl_error_set(err, SL_ERR_NOMEM, "virtual camera: out of memory");
    sl_result r = virtual_open(o, c, err);
    if (r) {
        free(c);
        return r;
    }
    *camera = c;
    return SL_OK;
}
