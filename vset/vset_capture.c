/* SPDX-License-Identifier: BSD-3-Clause */
/* A whole simulated set capture: the bracket plan, frames written like a
 * camera's (JPEG, 16-bit TIFF, linear TIFF, EXIF), the manifest and the
 * ground truth. The folder is assembled beside its final name and renamed
 * into place at the end. */
#include <dirent.h>
#include <errno.h>
#include <jansson.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "vset_internal.h"

int sl_vset_size_from_name(const char *name)
{
    static const char *const names[] = {"tiny", "small", "full"};
    for (int i = 0; i < 3; i++)
        if (name && !strcmp(name, names[i]))
            return i;
    return -1;
}

void sl_vset_capture_defaults(sl_vset_capture_opts *o, const sl_vset_desc *scene,
                              sl_vset_size size)
{
    static const int ll[3] = {256, SL_VSET_SMALL_WIDTH, SL_VSET_FULL_WIDTH};
    static const int pw[3] = {192, 720, 3000}, ph[3] = {128, 480, 2000}, ss[3] = {2, 2, 3};
    static const int qw[3] = {192, 480, 1500}, qh[3] = {128, 320, 1000};
    static const int64_t spp_aa[3] = {4, 8, 16}, spp_grey[3] = {8, 16, 128};
    memset(o, 0, sizeof *o);
    o->scene = *scene;
    o->latlong_width = ll[size];
    o->photo_width = pw[size];
    o->photo_height = ph[size];
    o->supersample = ss[size];
    o->probe_width = qw[size];
    o->probe_height = qh[size];
    o->probe_spp_aa = spp_aa[size];
    o->probe_spp_grey = spp_grey[size];
    sl_vset_response_preset("canon", &o->response, NULL);
    o->raw_bits = 14;
    o->seed = 1;
    o->views = 3;
    o->brackets = 7;
    o->stops = 3;
    o->iso = 100;
    switch (scene->background) {
    case SL_VSET_BG_SKY:
        o->f_number = 16;
        o->wb_kelvin = 5500;
        break;
    case SL_VSET_BG_ROOM:
        /* The stage's key lights are daylight-balanced. */
        o->f_number = 8;
        o->wb_kelvin = 5600;
        break;
    default:
        o->f_number = 4;
        o->iso = 400;
        o->wb_kelvin = 3200;
        break;
    }
}

/* The full-stop shutter speeds a camera offers and writes to EXIF. The
 * simulated exposure uses the nominal time, so EXIF and truth agree. */
static const double shutter[] = {1.0 / 8000, 1.0 / 4000, 1.0 / 2000, 1.0 / 1000, 1.0 / 500,
                                 1.0 / 250,  1.0 / 125,  1.0 / 60,   1.0 / 30,   1.0 / 15,
                                 1.0 / 8,    1.0 / 4,    1.0 / 2,    1,          2,
                                 4,          8,          15,         30};
#define SHUTTER_COUNT ((int)(sizeof shutter / sizeof shutter[0]))

double sl_vset_log_average(const sl_image *latlong)
{
    double acc = 0, wsum = 0;
    for (int y = 0; y < latlong->height; y++) {
        double dw = sl_latlong_texel_solid_angle(y, latlong->width, latlong->height);
        for (int x = 0; x < latlong->width; x++) {
            const float *p = sl_image_pixel(latlong, x, y);
            double l = sl_luminance_px(p);
            acc += dw * log(l > 1e-6 ? l : 1e-6);
            wsum += dw;
        }
    }
    return exp(acc / wsum);
}

/* Returns the metered log-average luminance. */
static double plan_exposures(const sl_vset_capture_opts *o, const sl_vset_camera *cam,
                             const sl_image *latlong, double *times)
{
    /* Meter the log-average luminance to 12% of raw saturation. */
    double lavg = sl_vset_log_average(latlong);
    double t = 0.12 * o->f_number * o->f_number / (lavg * cam->k * o->iso / 100.0);
    int centre = 0, step = (int)o->stops;
    for (int i = 1; i < SHUTTER_COUNT; i++)
        if (fabs(log(shutter[i] / t)) < fabs(log(shutter[centre] / t)))
            centre = i;
    int half = (o->brackets - 1) / 2 * step;
    int first = centre - half;
    int last = first + (o->brackets - 1) * step;
    if (last > SHUTTER_COUNT - 1)
        first -= last - (SHUTTER_COUNT - 1);
    if (first < 0)
        first = 0;
    for (int k = 0; k < o->brackets; k++)
        times[k] = shutter[first + k * step];
    return lavg;
}

/* A person 0.5 m wide and 1.8 m tall, 3 m away, walking across the first
 * view between frames: the ghosting case for merges. */
#define GHOST_WIDTH_DEG 9.5
#define GHOST_EL_LOW (-28.0)
#define GHOST_EL_HIGH 4.0

static double ghost_azimuth(int bracket) { return -20.0 + 4.0 * bracket; }

static sl_result paint_ghost(const sl_image *src, double az, double lum, sl_image *dst,
                             sl_error *err)
{
    sl_result r = sl_image_copy(src, dst, err);
    if (r)
        return r;
    static const double tint[3] = {0.9, 0.8, 0.7};
    for (int y = 0; y < dst->height; y++) {
        double el = 90.0 - 180.0 * (y + 0.5) / dst->height;
        if (el < GHOST_EL_LOW || el > GHOST_EL_HIGH)
            continue;
        for (int x = 0; x < dst->width; x++) {
            double lon = 180.0 * (1.0 - 2.0 * (x + 0.5) / dst->width);
            double dz = fmod(lon - az + 540.0, 360.0) - 180.0;
            if (fabs(dz) > 0.5 * GHOST_WIDTH_DEG)
                continue;
            float *p = sl_image_pixel(dst, x, y);
            for (int c = 0; c < 3; c++)
                p[c] = (float)(lum * tint[c]);
        }
    }
    return SL_OK;
}

static sl_result make_dir(const char *path, sl_error *err)
{
    if (mkdir(path, 0777) != 0)
        return sl_error_set(err, SL_ERR_IO, "%s: cannot create folder: %s", path, strerror(errno));
    return SL_OK;
}

/* 0 empty, 1 holds a capture, 2 holds something else, -1 absent. */
static int folder_state(const char *dir)
{
    DIR *d = opendir(dir);
    if (!d)
        return -1;
    int state = 0;
    struct dirent *e;
    while ((e = readdir(d))) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
            continue;
        if (!strcmp(e->d_name, "capture.json"))
            state = 1;
        else if (state == 0)
            state = 2;
    }
    closedir(d);
    if (state == 2) {
        char p[4096];
        snprintf(p, sizeof p, "%s/capture.json", dir);
        if (access(p, F_OK) == 0)
            state = 1;
    }
    return state;
}

static json_t *mat3(const double m[3][3])
{
    return json_pack("[[fff][fff][fff]]", m[0][0], m[0][1], m[0][2], m[1][0], m[1][1], m[1][2],
                     m[2][0], m[2][1], m[2][2]);
}

static sl_result write_json(const char *path, json_t *root, sl_error *err)
{
    sl_result r = sl_json_write_atomic(path, root, JSON_INDENT(2) | JSON_REAL_PRECISION(10), err);
    json_decref(root);
    return r;
}

/* Every field of a core lens, so a test can rebuild it exactly. */
static json_t *lens_json(const sl_lens *l)
{
    return json_pack("{s:s, s:i, s:i, s:f, s:f, s:f, s:[fff], s:[fff], s:f, s:f}", "projection",
                     sl_lens_projection_name(l->projection), "width", l->width, "height",
                     l->height, "focal_px", l->focal_px, "cx", l->cx, "cy", l->cy, "k", l->k[0],
                     l->k[1], l->k[2], "vignette", l->vignette[0], l->vignette[1],
                     l->vignette[2], "max_theta_deg", l->max_theta_deg, "circle_radius_px",
                     l->circle_radius_px);
}

/* The HDRI lens as it is and as its EXIF states it, and the true pose of
 * every view and frame (capture.json keeps the plan). */
static json_t *hdri_truth_json(const sl_lens *lens, const sl_lens *nominal, json_t *views,
                               json_t *frames)
{
    json_t *l = lens_json(lens);
    json_object_set_new(l, "name", json_string(SL_VSET_FISHEYE_NAME));
    json_object_set_new(l, "focal_mm", json_real(lens->focal_px * SL_VSET_SENSOR_WIDTH_MM /
                                                 lens->width));
    json_object_set_new(l, "sensor_width_mm", json_real(SL_VSET_SENSOR_WIDTH_MM));
    json_object_set_new(l, "nominal", lens_json(nominal));
    json_object_set_new(json_object_get(l, "nominal"), "focal_mm",
                        json_real(SL_VSET_FISHEYE_FOCAL_MM));
    return json_pack("{s:o, s:s, s:O, s:O}", "lens", l, "axes",
                     "camera frame x image right, y image down, z forward (sl_lens); poses as "
                     "sl_view_pose (degrees); view 0 defines the frame of truth/latlong.exr",
                     "views", views, "frames", frames);
}

static sl_result write_camera_json(const char *path, const sl_vset_camera *cam,
                                   json_t *hdri, const sl_vset_capture_opts *o,
                                   sl_error *err)
{
    json_t *curve = json_array();
    for (int i = 0; i < SL_VSET_CRF_SAMPLES; i++)
        json_array_append_new(curve, json_real(cam->response.curve[i]));
    double out[3][3];
    sl_vset_camera_output_matrix(cam, out);
    json_t *root = json_pack(
        "{s:s, s:s, s:s, s:f, s:f, s:f, s:f, s:f, s:i, s:o, s:[fff], s:o, s:o, s:f, "
        "s:{s:s, s:i, s:o}}",
        "make", cam->make, "model", cam->model, "exposure_model",
        "X = L * t * (ISO/100) * k / N^2, X = 1 at raw saturation", "k", cam->k,
        "full_well_e_iso100", cam->full_well_e, "read_noise_pre_e", cam->read_noise_pre_e,
        "read_noise_post_e_iso100", cam->read_noise_post_e, "raw_black_level", 0.125,
        "raw_bits", cam->raw_bits, "cam_from_rec709", mat3(cam->cam_from_rec709), "wb",
        cam->wb[0], cam->wb[1], cam->wb[2], "ccm", mat3(cam->ccm), "output_from_rec709",
        mat3(out), "wb_kelvin", o->wb_kelvin, "response", "name", cam->response.name,
        "samples", SL_VSET_CRF_SAMPLES, "curve", curve);
    json_object_update(root, hdri);
    return write_json(path, root, err);
}

static void exif_time(int seconds, char *out, size_t size)
{
    /* A fixed shoot day keeps the files identical for the same seed. */
    int h = 10 + seconds / 3600, m = (seconds / 60) % 60, s = seconds % 60;
    snprintf(out, size, "2026:05:14 %02d:%02d:%02d", h, m, s);
}

/* EXIF of a frame; the camera's clock moves on by the exposure and a second. */
static void frame_meta(sl_meta *meta, const sl_vset_camera *cam, const char *lens_name,
                       double focal_mm, const sl_vset_exposure *e, int *clock)
{
    sl_meta_init(meta);
    meta->exposure_time = e->time_s;
    meta->f_number = e->f_number;
    meta->iso = e->iso;
    meta->focal_length_mm = focal_mm;
    meta->orientation = 1;
    snprintf(meta->make, sizeof meta->make, "%s", cam->make);
    snprintf(meta->model, sizeof meta->model, "%s", cam->model);
    snprintf(meta->lens, sizeof meta->lens, "%s", lens_name);
    exif_time(*clock, meta->datetime, sizeof meta->datetime);
    *clock += 1 + (int)ceil(e->time_s);
}

/* A frame as the camera writes it: 8-bit JPEG and 16-bit TIFF through the
 * response, and the linear 16-bit TIFF (a raw converter's linear export:
 * its ICC profile says it is linear Rec.709). */
static sl_result write_frame(const char *tmp, const char *folder, const char *name,
                             const sl_vset_shot *shot, const sl_meta *meta, sl_error *err)
{
    char path[4200];
    snprintf(path, sizeof path, "%s/%s/%s.jpg", tmp, folder, name);
    sl_result r = sl_photo_write(path, &shot->encoded, meta, 8, err);
    if (!r) {
        snprintf(path, sizeof path, "%s/%s/%s.tif", tmp, folder, name);
        r = sl_photo_write(path, &shot->encoded, meta, 16, err);
    }
    if (!r) {
        snprintf(path, sizeof path, "%s/%s/%s_linear.tif", tmp, folder, name);
        sl_meta linear = *meta; /* shallow: only colorspace differs */
        snprintf(linear.colorspace, sizeof linear.colorspace, "%s", SL_WORKING_SPACE);
        r = sl_photo_write(path, &shot->linear, &linear, 16, err);
    }
    return r;
}

static json_t *pose_json(const sl_view_pose *p)
{
    return json_pack("{s:f, s:f, s:f}", "yaw_deg", p->yaw_deg, "pitch_deg", p->pitch_deg,
                     "roll_deg", p->roll_deg);
}

/* The HDRI: each view's bracket through the true lens at the head's true
 * pose; capture.json gets the plan, the truth what really happened. */
static sl_result shoot_frames(const sl_vset_capture_opts *o, const char *tmp,
                              const sl_vset_camera *cam, const sl_lens *lens,
                              const sl_image *latlong, const double *times, double lavg,
                              json_t *frames, json_t *truth_views, json_t *truth_frames,
                              int *frame, int *clock, sl_error *err)
{
    int nviews = o->views + (o->zenith ? 1 : 0);
    bool per_frame = o->jitter_deg > 0 || o->ghost;
    sl_result r = SL_OK;
    for (int v = 0; v < nviews && !r; v++) {
        const sl_view_pose plan = {v < o->views ? 360.0 * v / o->views : 0,
                                   v < o->views ? 0 : 90, 0};
        sl_view_pose base;
        sl_vset_head_pose(o->seed, v, &plan, &base);
        json_t *tv = pose_json(&base);
        json_object_set_new(tv, "view", json_integer(v));
        json_object_set_new(tv, "plan", pose_json(&plan));
        json_array_append_new(truth_views, tv);
        sl_image rad = {0};
        if (!per_frame &&
            (r = sl_vset_view_image(lens, &base, latlong, o->supersample, &rad, err)))
            break;
        for (int k = 0; k < o->brackets && !r; k++) {
            sl_view_pose view = base;
            bool ghost = o->ghost && v == 0;
            if (per_frame) {
                /* Hand-held or loose head: the view wanders a little per frame. */
                uint64_t id = (uint64_t)(v * 64 + k) * 3u;
                view.yaw_deg += o->jitter_deg * vset_gauss(o->seed, 9, id);
                view.pitch_deg += o->jitter_deg * vset_gauss(o->seed, 9, id + 1);
                view.roll_deg += o->jitter_deg * vset_gauss(o->seed, 9, id + 2);
                sl_image env = {0};
                const sl_image *use = latlong;
                if (ghost) {
                    if ((r = paint_ghost(latlong, ghost_azimuth(k), 0.5 * lavg, &env, err)))
                        break;
                    use = &env;
                }
                sl_image_free(&rad);
                r = sl_vset_view_image(lens, &view, use, o->supersample, &rad, err);
                sl_image_free(&env);
                if (r)
                    break;
            }
            sl_vset_exposure e = {times[k], o->f_number, o->iso};
            sl_vset_shot shot;
            uint64_t seed = sl_splitmix64_hash(o->seed ^ sl_splitmix64_hash((uint64_t)(v * 64 + k)));
            if ((r = sl_vset_camera_shoot(cam, &e, &rad, seed, &shot, err)))
                break;
            (*frame)++;
            sl_meta meta;
            char name[64];
            snprintf(name, sizeof name, "IMG_%04d", *frame);
            frame_meta(&meta, cam, SL_VSET_FISHEYE_NAME, SL_VSET_FISHEYE_FOCAL_MM, &e, clock);
            r = write_frame(tmp, "hdri", name, &shot, &meta, err);
            if (!r) {
                json_t *g = ghost ? json_pack("{s:f, s:f, s:f, s:f}", "azimuth_deg",
                                              ghost_azimuth(k), "width_deg", GHOST_WIDTH_DEG,
                                              "elevation_low_deg", GHOST_EL_LOW,
                                              "elevation_high_deg", GHOST_EL_HIGH)
                                  : json_null();
                json_array_append_new(
                    frames,
                    json_pack("{s:s, s:i, s:f, s:f, s:f, s:i, s:f, s:f, s:f, s:s, s:o}", "name",
                              name, "view", v, "yaw_deg", plan.yaw_deg, "pitch_deg",
                              plan.pitch_deg, "roll_deg", plan.roll_deg, "bracket", k,
                              "exposure_time_s", e.time_s, "f_number", e.f_number, "iso", e.iso,
                              "datetime", meta.datetime, "ghost", g));
                json_t *tf = pose_json(&view);
                json_object_set_new(tf, "name", json_string(name));
                json_object_set_new(tf, "view", json_integer(v));
                json_array_append_new(truth_frames, tf);
            }
            sl_meta_free(&meta);
            sl_vset_shot_free(&shot);
        }
        *clock += 20; /* turning the nodal head */
        sl_image_free(&rad);
    }
    return r;
}

static json_t *points(const double (*pt)[2], int n)
{
    json_t *a = json_array();
    for (int i = 0; i < n; i++)
        json_array_append_new(a, json_pack("[ff]", pt[i][0], pt[i][1]));
    return a;
}

/* The probe's ground truth: where it is in the photo and how it was made. */
static json_t *probe_truth(const sl_vset_probe *p, const sl_vset_probe_geometry *g,
                           json_t *names, const char *radiance_file)
{
    double f[3], r[3], u[3];
    vset_view_frame(&p->view, f, r, u);
    json_t *j = json_pack(
        "{s:s, s:o, s:s, s:i, s:i, s:f, s:f, s:f, s:f, s:f, s:{s:f, s:f, s:f, s:[fff]}, "
        "s:{s:I, s:f}}",
        "kind", sl_vset_probe_name(p->kind), "frames", names, "radiance", radiance_file,
        "width", p->width, "height", p->height, "focal_mm", p->lens.focal_mm, "sensor_width_mm",
        p->lens.sensor_width_mm, "sensor_height_mm",
        p->lens.sensor_width_mm * p->height / p->width, "focal_px", g->focal_px, "distance_m",
        p->distance_m, "camera", "yaw_deg", p->view.yaw_deg, "pitch_deg", p->view.pitch_deg,
        "roll_deg", p->view.roll_deg, "forward", f[0], f[1], f[2], "render", "spp",
        (json_int_t)g->spp, "est_rel_rmse", g->render_rel_rmse);
    if (p->kind == SL_VSET_PROBE_CHART) {
        json_object_set_new(
            j, "chart",
            json_pack("{s:s, s:f, s:f, s:o, s:o, s:o}", "reference", "SL_COLORCHECKER_LINEAR",
                      "width_m", p->size_m, "height_m", p->size_m * 0.68, "corners",
                      points((const double(*)[2])g->corners, 4), "outline",
                      points((const double(*)[2])g->outline, 4), "patch_centers",
                      points((const double(*)[2])g->patch_centers, 24)));
    } else {
        json_t *mat = p->kind == SL_VSET_PROBE_CHROME
                          ? json_pack("{s:s, s:[fff], s:[fff], s:f}", "model",
                                      "conductor, Gulbrandsen artist Fresnel (sl_material_chrome)",
                                      "base_color", 0.549, 0.556, 0.554, "edge_tint", 0.559,
                                      0.559, 0.559, "roughness", 0.0)
                          : json_pack("{s:s, s:f}", "model", "lambert", "albedo", 0.18);
        json_object_set_new(
            j, "ball",
            json_pack("{s:f, s:f, s:f, s:f, s:f, s:f, s:o}", "cx", g->cx, "cy", g->cy, "r_px",
                      g->r, "diameter_m", p->size_m, "distance_radii",
                      p->distance_m / (0.5 * p->size_m), "angular_radius_deg",
                      g->ball_angle_deg, "material", mat));
    }
    return j;
}

static int cmp_float(const void *a, const void *b)
{
    float x = *(const float *)a, y = *(const float *)b;
    return x < y ? -1 : x > y;
}

static double percentile_luminance(const sl_image *img, double q)
{
    size_t n = (size_t)img->width * (size_t)img->height;
    float *l = malloc(n * sizeof *l);
    if (!l)
        return 1;
    for (size_t i = 0; i < n; i++) {
        const float *p = img->data + i * (size_t)img->channels;
        l[i] = sl_luminancef(p);
    }
    qsort(l, n, sizeof *l, cmp_float);
    double v = l[(size_t)(q * (double)(n - 1))];
    free(l);
    return v > 1e-9 ? v : 1e-9;
}

/* Chrome ball, grey ball and chart with the long lens: rendered under the
 * truth, photographed (the chrome ball with the HDRI's bracket, the others
 * with three exposures two stops apart round one metered on the probe), the
 * render kept as truth. */
static sl_result shoot_probes(const sl_vset_capture_opts *o, const char *tmp,
                              const sl_vset_camera *cam, const sl_image *latlong,
                              const double *times, json_t *probes, json_t *truth,
                              int *frame, int *clock, sl_error *err)
{
    sl_result r = SL_OK;
    for (int kind = 0; kind < 3 && !r; kind++) {
        sl_vset_probe p;
        sl_vset_probe_default(&p, (sl_vset_probe_kind)kind, o->probe_width, o->probe_height);
        p.spp = kind == SL_VSET_PROBE_GREY ? o->probe_spp_grey : o->probe_spp_aa;
        /* The render is truth: the same for every sensor-noise seed. */
        p.seed = 0x9000u + (uint64_t)kind;
        sl_vset_probe_geometry g;
        sl_image rad;
        if ((r = sl_vset_probe_render(&p, latlong, &rad, &g, err)))
            break;
        double pt[16];
        int n = 0, centre;
        if (kind == SL_VSET_PROBE_CHROME) {
            for (n = 0; n < o->brackets; n++)
                pt[n] = times[n];
        } else {
            /* Metered on the probe, as a wrangler spot-meters the chart:
             * its bright end (98th percentile) at 70% of saturation. */
            double t = 0.7 * o->f_number * o->f_number /
                       (percentile_luminance(&rad, 0.98) * cam->k * o->iso / 100.0);
            centre = 0;
            for (int i = 1; i < SHUTTER_COUNT; i++)
                if (fabs(log(shutter[i] / t)) < fabs(log(shutter[centre] / t)))
                    centre = i;
            for (int d = -2; d <= 2; d += 2) {
                int i = centre + d < 0 ? 0 : centre + d >= SHUTTER_COUNT ? SHUTTER_COUNT - 1
                                                                         : centre + d;
                if (n == 0 || shutter[i] != pt[n - 1])
                    pt[n++] = shutter[i];
            }
        }
        json_t *fr = json_array(), *names = json_array();
        for (int k = 0; k < n && !r; k++) {
            sl_vset_exposure e = {pt[k], o->f_number, o->iso};
            sl_vset_shot shot;
            uint64_t seed = sl_splitmix64_hash(o->seed ^ sl_splitmix64_hash(0x7000u + (uint64_t)(kind * 64 + k)));
            if ((r = sl_vset_camera_shoot(cam, &e, &rad, seed, &shot, err)))
                break;
            (*frame)++;
            char name[64];
            snprintf(name, sizeof name, "IMG_%04d", *frame);
            sl_meta meta;
            frame_meta(&meta, cam, p.lens.name, p.lens.focal_mm, &e, clock);
            r = write_frame(tmp, "probes", name, &shot, &meta, err);
            if (!r) {
                json_array_append_new(fr, json_pack("{s:s, s:i, s:f, s:f, s:f, s:s}", "name",
                                                    name, "bracket", k, "exposure_time_s",
                                                    e.time_s, "f_number", e.f_number, "iso",
                                                    e.iso, "datetime", meta.datetime));
                json_array_append_new(names, json_string(name));
            }
            sl_meta_free(&meta);
            sl_vset_shot_free(&shot);
        }
        *clock += 10; /* the next probe into place */
        char file[64], path[4200];
        snprintf(file, sizeof file, "truth/probe_%s.exr", sl_vset_probe_name(p.kind));
        snprintf(path, sizeof path, "%s/%s", tmp, file);
        if (!r) {
            sl_meta meta;
            sl_meta_init(&meta);
            sl_meta_set_rec709(&meta);
            r = sl_meta_set(&meta, "setlight:units",
                            "radiance at the sensor (vignetting applied), 1 = 1 cd/m^2", err);
            if (!r)
                r = sl_exr_write(path, &rad, &meta, SL_PIXEL_FLOAT, err);
            sl_meta_free(&meta);
        }
        sl_image_free(&rad);
        if (!r) {
            json_array_append_new(probes, json_pack("{s:s, s:s, s:f, s:o}", "kind",
                                                    sl_vset_probe_name(p.kind), "lens",
                                                    p.lens.name, "focal_mm", p.lens.focal_mm,
                                                    "frames", fr));
            json_array_append_new(truth, probe_truth(&p, &g, names, file));
        } else {
            json_decref(fr);
            json_decref(names);
        }
    }
    return r;
}

static sl_result check_opts(const sl_vset_capture_opts *o, sl_error *err)
{
    if (o->views < 1 || o->views > 12 || o->brackets < 1 || o->stops < 1 || o->stops > 4 ||
        o->stops != floor(o->stops) || (o->brackets - 1) * (int)o->stops > 18)
        return sl_error_set(err, SL_ERR_USAGE,
                            "capture plan: 1..12 views, 1..4 whole stops apart, brackets "
                            "spanning at most the camera's 18 stops (1/8000..30 s)");
    if (o->photo_width < 16 || o->photo_height < 16 || o->photo_width > 16384 ||
        o->photo_height > 16384 || o->supersample < 1 || o->supersample > 8)
        return sl_error_set(err, SL_ERR_USAGE, "frame size %dx%d or supersampling %d invalid",
                            o->photo_width, o->photo_height, o->supersample);
    if (o->probe_width != 0 &&
        (o->probe_width < 16 || o->probe_height < 16 || o->probe_width > 16384 ||
         o->probe_height > 16384 || o->probe_spp_aa < 1 || o->probe_spp_grey < 1))
        return sl_error_set(err, SL_ERR_USAGE, "probe photo size %dx%d or samples invalid",
                            o->probe_width, o->probe_height);
    if (o->raw_bits != 12 && o->raw_bits != 14)
        return sl_error_set(err, SL_ERR_USAGE, "raw bit depth %d (12 or 14)", o->raw_bits);
    if (o->response.curve[SL_VSET_CRF_SAMPLES - 1] != 1.0 || o->response.curve[0] != 0.0)
        return sl_error_set(err, SL_ERR_USAGE, "response curve '%s' is not normalised to 0..1",
                            o->response.name);
    if (!(o->jitter_deg >= 0 && o->jitter_deg <= 10))
        return sl_error_set(err, SL_ERR_USAGE, "jitter %g degrees (0..10)", o->jitter_deg);
    if (!(o->f_number >= 1 && o->f_number <= 64 && o->iso >= 25 && o->iso <= 409600))
        return sl_error_set(err, SL_ERR_USAGE, "aperture f/%g or ISO %g invalid", o->f_number,
                            o->iso);
    return SL_OK;
}

sl_result sl_vset_capture_write(const sl_vset_capture_opts *o, const char *dir,
                                sl_vset_capture_summary *summary, sl_error *err)
{
    if (summary)
        memset(summary, 0, sizeof *summary);
    sl_result r = check_opts(o, err);
    if (r)
        return r;
    if (strlen(dir) == 0 || strlen(dir) > 3000)
        return sl_error_set(err, SL_ERR_USAGE, "output folder name is empty or too long");
    int state = folder_state(dir);
    if (state == 2)
        return sl_error_set(err, SL_ERR_USAGE,
                            "%s: folder is not empty and holds no capture; choose another", dir);
    if (state == 1 && !o->force)
        return sl_error_set(err, SL_ERR_USAGE,
                            "%s: already holds a capture (use --force to replace it)", dir);
    char tmp[4096], old[4096];
    snprintf(tmp, sizeof tmp, "%s.sl-tmp-%ld-XXXXXX", dir, (long)getpid());
    snprintf(old, sizeof old, "%s.sl-old-%ld", dir, (long)getpid());
    char sub[4200];
    int tmp_handle = sl_temp_dir_create(tmp); /* an interrupt removes it */
    if (tmp_handle < 0)
        return sl_error_set(err, SL_ERR_IO, "%s: cannot create the capture folder: %s", dir,
                            strerror(errno));
    sl_vset_scene scene;
    if ((r = sl_vset_scene_make(&o->scene, o->latlong_width, &scene, err))) {
        sl_temp_dir_remove(tmp, tmp_handle);
        return r;
    }
    snprintf(sub, sizeof sub, "%s/hdri", tmp);
    if (!r)
        r = make_dir(sub, err);
    snprintf(sub, sizeof sub, "%s/truth", tmp);
    if (!r)
        r = make_dir(sub, err);

    sl_vset_camera cam;
    sl_vset_camera_default(&cam, o->wb_kelvin);
    cam.response = o->response;
    cam.raw_bits = o->raw_bits;
    sl_lens lens, nominal;
    sl_vset_fisheye_true(&lens, o->photo_width, o->photo_height);
    sl_vset_fisheye_nominal(&nominal, o->photo_width, o->photo_height);
    double times[16];
    int frame = 0, clock = 0;
    double lavg = plan_exposures(o, &cam, &scene.latlong, times);
    json_t *frames = json_array(), *probes = json_array(), *probes_truth = json_array();
    json_t *truth_views = json_array(), *truth_frames = json_array();
    if (!r)
        r = shoot_frames(o, tmp, &cam, &lens, &scene.latlong, times, lavg, frames, truth_views,
                         truth_frames, &frame, &clock, err);
    if (!r && o->probe_width > 0) {
        snprintf(sub, sizeof sub, "%s/probes", tmp);
        r = make_dir(sub, err);
        if (!r)
            r = shoot_probes(o, tmp, &cam, &scene.latlong, times, probes, probes_truth,
                             &frame, &clock, err);
        if (!r) {
            snprintf(sub, sizeof sub, "%s/truth/probes.json", tmp);
            r = write_json(sub, json_pack("{s:s, s:O}", "axes",
                                          "pixels: (0, 0) is the top-left corner of the "
                                          "top-left pixel; world as truth/latlong.exr",
                                          "probes", probes_truth),
                           err);
        }
    }
    if (!r) {
        sl_meta meta;
        sl_meta_init(&meta);
        meta.envmap = SL_ENVMAP_LATLONG;
        sl_meta_set_rec709(&meta);
        r = sl_meta_set(&meta, "setlight:units", "luminance-scaled Rec.709, 1 = 1 cd/m^2", err);
        if (!r)
            r = sl_meta_set(&meta, "setlight:scene", scene.desc.name, err);
        snprintf(sub, sizeof sub, "%s/truth/latlong.exr", tmp);
        if (!r)
            r = sl_exr_write(sub, &scene.latlong, &meta, SL_PIXEL_FLOAT, err);
        sl_meta_free(&meta);
    }
    if (!r) {
        char *js = sl_vset_lights_json(&scene);
        snprintf(sub, sizeof sub, "%s/truth/lights.json", tmp);
        r = js ? sl_write_file_atomic(sub, js, strlen(js), err)
               : sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", sub);
        free(js);
    }
    if (!r) {
        snprintf(sub, sizeof sub, "%s/truth/camera.json", tmp);
        json_t *hdri = hdri_truth_json(&lens, &nominal, truth_views, truth_frames);
        r = write_camera_json(sub, &cam, hdri, o, err);
        json_decref(hdri);
    }
    if (!r) {
        json_t *times_js = json_array();
        for (int k = 0; k < o->brackets; k++)
            json_array_append_new(times_js, json_real(times[k]));
        json_t *root = json_pack(
            "{s:s, s:s, s:s, s:I, s:i, s:b, s:i, s:f, s:o, s:f, s:f, s:s, s:i, s:i, s:f, s:b, s:o, "
            "s:{s:s, s:s, s:s}}",
            "setlight_capture", "virtual set", "version", sl_version(), "scene", scene.desc.name,
            "seed", (json_int_t)o->seed, "views", o->views, "zenith", o->zenith, "brackets",
            o->brackets, "stops", o->stops, "exposure_times_s", times_js, "f_number",
            o->f_number, "iso", o->iso, "lens", SL_VSET_FISHEYE_NAME, "width", o->photo_width, "height",
            o->photo_height, "jitter_deg", o->jitter_deg, "ghost", o->ghost, "frames", frames,
            "truth", "latlong", "truth/latlong.exr", "lights", "truth/lights.json", "camera",
            "truth/camera.json");
        frames = NULL;
        json_object_set(root, "probes", probes);
        /* The lens as its EXIF states it: what a wrangler knows. */
        json_object_set_new(root, "focal_mm", json_real(SL_VSET_FISHEYE_FOCAL_MM));
        json_object_set_new(root, "sensor_width_mm", json_real(SL_VSET_SENSOR_WIDTH_MM));
        if (o->probe_width > 0)
            json_object_set_new(json_object_get(root, "truth"), "probes", json_string("truth/probes.json"));
        snprintf(sub, sizeof sub, "%s/capture.json", tmp);
        r = write_json(sub, root, err);
    }
    json_decref(frames);
    json_decref(probes);
    json_decref(probes_truth);
    json_decref(truth_views);
    json_decref(truth_frames);
    sl_vset_scene_free(&scene);
    if (!r) {
        /* Swap the finished folder in; an old capture goes only after. */
        bool had_old = state == 1;
        if (had_old && rename(dir, old) != 0)
            r = sl_error_set(err, SL_ERR_IO, "%s: cannot move the old capture aside: %s", dir,
                             strerror(errno));
        if (!r && state == 0 && rmdir(dir) != 0)
            r = sl_error_set(err, SL_ERR_IO, "%s: cannot replace empty folder: %s", dir,
                             strerror(errno));
        if (!r && rename(tmp, dir) != 0) {
            r = sl_error_set(err, SL_ERR_IO, "%s: cannot rename the capture into place: %s", dir,
                             strerror(errno));
            if (had_old)
                rename(old, dir);
        }
        if (!r && had_old)
            sl_remove_tree(old);
    }
    sl_temp_dir_remove(tmp, tmp_handle); /* gone when renamed: unregisters it */
    if (r)
        return r;
    if (summary) {
        summary->frames = (o->views + (o->zenith ? 1 : 0)) * o->brackets;
        summary->probe_frames = frame - summary->frames;
        summary->views = o->views + (o->zenith ? 1 : 0);
        summary->center_time_s = times[o->brackets / 2];
        summary->min_time_s = times[0];
        summary->max_time_s = times[o->brackets - 1];
        summary->f_number = o->f_number;
        summary->iso = o->iso;
    }
    return SL_OK;
}
