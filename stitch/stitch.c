/* SPDX-License-Identifier: BSD-3-Clause */
/* sl_stitch: HDR fisheye views (files) to one lat-long EXR: the views read
 * and checked, the nominal lens and poses, the overlaps checked, then the
 * blend written a strip at a time. */
#include "stitch_blend_private.h"

#include <libgen.h>
#include <math.h>
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

#define DEG (M_PI / 180.0)
/* Two views overlap when their fields share a band at least this wide. */
#define MIN_OVERLAP_DEG 2.0

static const char *const phase_names[SL_STITCH_PHASES] = {"read", "circle", "solve", "blend"};

void sl_stitch_result_free(sl_stitch_result *res)
{
    if (res)
        sl_stitch_solve_result_free(&res->solve);
}

const char *sl_stitch_phase_name(sl_stitch_phase phase)
{
    return phase >= 0 && phase < SL_STITCH_PHASES ? phase_names[phase] : "unknown";
}

void sl_stitch_options_init(sl_stitch_options *opt)
{
    memset(opt, 0, sizeof *opt);
    sl_stitch_blend_options_init(&opt->blend);
    opt->projection = -1;
    opt->solve = true;
    opt->pixel_type = SL_PIXEL_HALF;
    opt->compression = SL_EXR_ZIP;
}

/* Views wider than this are solved on a copy reduced by a whole factor:
 * twice the features' width, so the features see the same pixels. */
#define SOLVE_MAX_WIDTH 3072

/* One view as read: its radiance (float, or half once read), metadata,
 * confidence, the solve's reduced copies and its image circle. */
typedef struct view_file {
    const char *path;
    int width, height;
    sl_image radiance, weight;   /* radiance empty when `half` holds it */
    stitch_half_image half;
    int solve_factor;            /* 1: the solve uses radiance and weight */
    bool as_half;                /* a large view, held as half */
    sl_image solve_radiance, solve_weight;
    sl_meta meta;
    double peak; /* largest RGB sample */
    sl_stitch_circle circle;     /* found as the view is read, used for a fisheye */
    sl_result circle_status;
    sl_error circle_err;
    double circle_cpu;
    pthread_t circle_thread;     /* finding it beside the next views' reading */
    bool circle_running;
} view_file;

/* Runs fn(arg) on a thread of its own, or here when none can be started:
 * true when on a thread (then joined by join_beside). */
static bool run_beside(pthread_t *thread, void *(*fn)(void *), void *arg)
{
    if (pthread_create(thread, NULL, fn, arg) == 0)
        return true;
    fn(arg);
    return false;
}

static void join_beside(pthread_t thread, bool *running)
{
    if (*running)
        pthread_join(thread, NULL);
    *running = false;
}

/* Blocks freed on a thread of its own beside what comes next: a 24 MP
 * half view takes about 0.016 s to unmap and a solve copy 0.007 s, and at
 * the end of the stitch nothing else is left to run. */
typedef struct release {
    pthread_t thread;
    bool running;
    int count;
    void *blocks[4 * SL_STITCH_MAX_VIEWS];
} release;

static void *release_main(void *arg)
{
    release *r = arg;
    for (int i = 0; i < r->count; i++)
        free(r->blocks[i]);
    return NULL;
}

/* Takes a block (*block set to NULL); false when full (then the owner frees it). */
static bool release_block(release *r, void **block)
{
    if (!*block || r->count >= (int)(sizeof r->blocks / sizeof r->blocks[0]))
        return false;
    r->blocks[r->count++] = *block;
    *block = NULL;
    return true;
}

/* Takes an image's memory (the image is left empty). */
static void release_image(release *r, sl_image *img)
{
    void *data = img->data;
    if (release_block(r, &data))
        memset(img, 0, sizeof *img);
}

static void release_start(release *r)
{
    r->running = r->count > 0 && run_beside(&r->thread, release_main, r);
}

static void release_wait(release *r)
{
    join_beside(r->thread, &r->running);
    r->count = 0;
}

/* The merge's clipped mask named by the radiance (as given to merge, or
 * beside the radiance) as a confidence: 1, or 1e-3 where a channel is
 * clipped in every frame (a lower bound: any unclipped view wins). */
static sl_result read_confidence(view_file *v, sl_stitch_view_result *vr, sl_error *err)
{
    const char *mask = sl_meta_get(&v->meta, "setlight:merge:clipped_mask");
    if (!mask || !mask[0])
        return SL_OK;
    char beside[4096];
    const char *found = NULL;
    FILE *f = fopen(mask, "rb");
    if (f) {
        found = mask;
    } else {
        char dir[4096], base[4096];
        snprintf(dir, sizeof dir, "%s", v->path);
        snprintf(base, sizeof base, "%s", mask);
        snprintf(beside, sizeof beside, "%s/%s", dirname(dir), basename(base));
        if ((f = fopen(beside, "rb")))
            found = beside;
    }
    if (!f) {
        sl_log_note(SL_LOG_WARN, "%s: its clipped mask %s is not there: every pixel weighted as "
                                 "unclipped", v->path, mask);
        return SL_OK;
    }
    fclose(f);
    sl_image m = {0};
    sl_result r = sl_exr_read(found, &m, NULL, err);
    if (r)
        return r;
    if (m.width != v->width || m.height != v->height) {
        sl_image_free(&m);
        return sl_error_set(err, SL_ERR_INPUT, "%s: its clipped mask %s is %dx%d, not %dx%d",
                            v->path, found, m.width, m.height, v->width, v->height);
    }
    if ((r = sl_image_alloc(&v->weight, m.width, m.height, 1, err))) {
        sl_image_free(&m);
        return r;
    }
    for (int y = 0; y < m.height; y++)
        for (int x = 0; x < m.width; x++) {
            const float *p = sl_image_pixel(&m, x, y);
            float c = p[0];
            for (int k = 1; k < m.channels && k < 3; k++)
                c = fmaxf(c, p[k]);
            sl_image_pixel(&v->weight, x, y)[0] = c > 0.5f ? 1e-3f : 1.0f;
        }
    sl_image_free(&m);
    vr->confidence = true;
    snprintf(vr->confidence_source, sizeof vr->confidence_source, "%s", found);
    return SL_OK;
}

/* "make model" of a view's camera, as a lens profile names it. */
static void camera_name(const sl_meta *m, char *buf, size_t size)
{
    snprintf(buf, size, "%s%s%s", m->make, m->make[0] && m->model[0] ? " " : "", m->model);
}

/* The nominal lens: a profile, the options, the files' EXIF, in that order. */
static sl_result nominal_lens(const view_file *views, int count, const sl_stitch_options *opt,
                              sl_lens *lens, char *source, size_t source_size, sl_error *err)
{
    const view_file *v0 = &views[0];
    int w = v0->width, h = v0->height;
    /* One camera and lens: the EXIF of every view must agree. */
    for (int i = 1; i < count; i++) {
        const sl_meta *a = &v0->meta, *b = &views[i].meta;
        if (strcmp(a->lens, b->lens) || strcmp(a->model, b->model) ||
            fabs(a->focal_length_mm - b->focal_length_mm) > 1e-6)
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: another camera or lens than %s (%s %s %gmm vs %s %s %gmm): "
                                "one stitch is one camera and lens",
                                views[i].path, v0->path, b->model, b->lens, b->focal_length_mm,
                                a->model, a->lens, a->focal_length_mm);
    }
    if (opt->lens) {
        if (opt->lens->width != w || opt->lens->height != h)
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: the lens given is for %dx%d images, the view is %dx%d",
                                v0->path, opt->lens->width, opt->lens->height, w, h);
        *lens = *opt->lens;
        snprintf(source, source_size, "given");
        return SL_OK;
    }
    if (opt->lens_profile) {
        sl_lens_profile prof;
        sl_result r = sl_lens_profile_read(opt->lens_profile, &prof, err);
        if (r)
            return r;
        char camera[160], why[512];
        camera_name(&v0->meta, camera, sizeof camera);
        if (!sl_lens_profile_fits(&prof, w, h, camera, v0->meta.lens, lens, why, sizeof why))
            return sl_error_set(err, SL_ERR_INPUT, "%s: %s", opt->lens_profile, why);
        snprintf(source, source_size, "lens profile %.400s (%s%s%.400s)", opt->lens_profile,
                 sl_lens_source_name(prof.source), why[0] ? "; " : "", why);
        return SL_OK;
    }
    sl_lens_projection p = opt->projection >= 0 ? (sl_lens_projection)opt->projection
                                                : SL_LENS_EQUISOLID;
    if (opt->focal_mm > 0 && opt->sensor_mm[0] > 0) {
        sl_lens_nominal(lens, p, w, h, opt->focal_mm, opt->sensor_mm[0]);
        snprintf(source, source_size, "%s, %g mm on a %g mm wide sensor (options)",
                 sl_lens_projection_name(p), opt->focal_mm, opt->sensor_mm[0]);
        return SL_OK;
    }
    /* The file's EXIF, with what the options give in its place. */
    sl_meta m;
    sl_result r = sl_meta_copy(&v0->meta, &m, err);
    if (r)
        return r;
    char sensor[64], why[512];
    if (opt->focal_mm > 0)
        m.focal_length_mm = opt->focal_mm;
    snprintf(sensor, sizeof sensor, "%.6g x %.6g", opt->sensor_mm[0],
             opt->sensor_mm[1] > 0 ? opt->sensor_mm[1] : opt->sensor_mm[0] * h / w);
    if (opt->sensor_mm[0] > 0)
        r = sl_meta_set(&m, SL_ATTR_SENSOR_MM, sensor, err);
    bool ok = !r && sl_stitch_lens_from_meta(&m, p, w, h, lens, why, sizeof why);
    if (ok)
        snprintf(source, source_size, "%s, %g mm (%s), sensor %g mm wide (%s)",
                 sl_lens_projection_name(p), m.focal_length_mm,
                 opt->focal_mm > 0 ? "option" : "EXIF", lens->focal_px > 0 ? m.focal_length_mm * w / lens->focal_px : 0,
                 opt->sensor_mm[0] > 0 ? "option" : "file");
    sl_meta_free(&m);
    if (r)
        return r;
    if (!ok)
        return sl_error_set(err, SL_ERR_INPUT, "%s: %s, or --lens-profile", v0->path, why);
    return SL_OK;
}

/* What a view keeps once read: the report's thumbnail and the solve's
 * reduced copies; beside them, on a thread of its own, its image circle
 * is found on the radiance (float, or the half view as read: both only
 * read it; a float view becomes half after, in place). The circle (one
 * core) goes on while the next views are read and decoded. */
static sl_result hold_copies(view_file *v, sl_image *thumb, sl_error *err)
{
    sl_result r = SL_OK;
    int k = v->solve_factor;
    if (k > 1 && (r = v->half.rgb ? stitch_reduce_half(&v->half, k, &v->solve_radiance, err)
                                  : stitch_reduce(&v->radiance, k, &v->solve_radiance, err)))
        return r;
    /* a view read as half has a solve copy when a thumbnail is wanted */
    const sl_image *img = v->half.rgb ? &v->solve_radiance : &v->radiance;
    if (thumb) {
        int tw = img->width < 320 ? img->width : 320;
        int th = (int)lround((double)img->height * tw / img->width);
        if ((r = sl_image_resample(img, tw, th > 0 ? th : 1, thumb, err)))
            return r;
    }
    if (k > 1 && v->weight.data && (r = stitch_reduce(&v->weight, k, &v->solve_weight, err)))
        return r;
    return SL_OK;
}

static void *circle_main(void *arg)
{
    view_file *v = arg;
    double c0 = sl_thread_cpu_seconds();
    v->circle_status = v->half.rgb
                           ? stitch_circle_find_half(&v->half, v->path, &v->circle, &v->circle_err)
                           : sl_stitch_circle_find(&v->radiance, v->path, NULL, &v->circle,
                                                   &v->circle_err);
    v->circle_cpu = sl_thread_cpu_seconds() - c0;
    return NULL;
}

static void circle_start(view_file *v)
{
    v->circle_running = run_beside(&v->circle_thread, circle_main, v);
}

static void circle_wait(view_file *v)
{
    join_beside(v->circle_thread, &v->circle_running);
}

/* A view read as half (sl_exr_read_half_rgb) is kept so when it is in the
 * working space (no conversion), large, and solved on a reduced copy (or
 * not solved and no thumbnail wanted); else its float values go the float
 * view's way. */
static sl_result read_half_view(view_file *v, const sl_stitch_options *opt, bool solving,
                                bool thumb, bool *kept, sl_error *err)
{
    *kept = false;
    if (opt->input_colorspace)
        return SL_OK;
    int w, h;
    sl_result r = sl_exr_read_half_rgb(v->path, &v->half.rgb, &w, &h, &v->meta, err);
    if (r || !v->half.rgb)
        return r;
    v->half.width = w;
    v->half.height = h;
    bool assumed;
    const char *cs = sl_file_color_space(&v->meta, &assumed);
    int k = w > SOLVE_MAX_WIDTH && solving ? stitch_solve_factor(w, h, SOLVE_MAX_WIDTH) : 1;
    if (cs && !strcmp(cs, SL_WORKING_SPACE) && w > SOLVE_MAX_WIDTH &&
        (k > 1 || (!solving && !thumb))) {
        *kept = true;
        return SL_OK;
    }
    /* what sl_image_read_linear gives */
    if (!(r = stitch_half_to_float(&v->half, &v->radiance, err)))
        r = sl_image_linearize(&v->radiance, &v->meta, v->path, NULL, NULL, err);
    return r;
}

/* Reads one view, refuses NaN/Inf and a size other than view 0's, finds
 * its circle and keeps it as it will be used. */
static sl_result read_view(view_file *v, const sl_stitch_options *opt, bool solving,
                           sl_stitch_view_result *vr, const view_file *v0, sl_image *thumb,
                           sl_error *err)
{
    bool as_read_half = false;
    sl_result r = read_half_view(v, opt, solving, thumb != NULL, &as_read_half, err);
    if (!r && !as_read_half && !v->radiance.data) {
        sl_meta_free(&v->meta);
        r = sl_image_read_linear(v->path, opt->input_colorspace, &v->radiance, &v->meta, NULL,
                                 err);
    }
    if (!r && !as_read_half)
        r = sl_image_ensure_rgb(&v->radiance, v->path, err);
    int64_t bad = 0;
    bool half_exact = as_read_half;
    double magnitude = 0.0;
    if (!r)
        r = as_read_half
                ? stitch_half_scan(&v->half, &bad, &v->peak, err)
                : stitch_view_scan(&v->radiance, &bad, &v->peak, &magnitude, &half_exact, err);
    if (r)
        return r;
    if (bad)
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s: %lld NaN/Inf samples (a damaged file: merge never writes them)",
                            v->path, (long long)bad);
    v->width = vr->width = as_read_half ? v->half.width : v->radiance.width;
    v->height = vr->height = as_read_half ? v->half.height : v->radiance.height;
    if (v0 && (v->width != v0->width || v->height != v0->height))
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s: %dx%d, but %s is %dx%d: one stitch is one camera, lens and size",
                            v->path, v->width, v->height, v0->path, v0->width, v0->height);
    if ((r = read_confidence(v, vr, err)))
        return r;
    /* A large view is solved on a reduced copy and blended from half (a
     * float one scaled by a power of two and rounded unless its samples
     * are half values); a small one (or one whose size the factors do not
     * divide) is solved at full resolution, so it stays float. */
    bool big = v->width > SOLVE_MAX_WIDTH;
    v->solve_factor = solving && big ? stitch_solve_factor(v->width, v->height, SOLVE_MAX_WIDTH)
                                     : 1;
    int exp2 = 0; /* the scale a view not of half values is held at */
    bool fits = half_exact || stitch_half_exponent(magnitude, &exp2);
    v->as_half = big && fits && (v->solve_factor > 1 || !solving);
    circle_start(v);
    if ((r = hold_copies(v, thumb, err)))
        return r;
    /* in the float view's memory once the circle and the copies are made
     * (from the float samples) */
    bool convert = v->as_half && !as_read_half;
    if (convert)
        circle_wait(v);
    stitch_half_loss loss = {0, 0};
    if (convert &&
        stitch_view_take_half(&v->radiance, exp2, &v->half,
                              half_exact ? NULL : &loss)) {
        vr->half_rounded = !half_exact;
        vr->half_exp2 = v->half.exp2;
        vr->below_half_normal = loss.below_normal;
        vr->flushed_to_zero = loss.flushed;
    }
    vr->held_as_half = v->half.rgb != NULL;
    return SL_OK;
}

/* The solve on the views' reduced copies (when they have them), its lens
 * and pixel errors scaled back to the full views. */
static sl_result solve_reduced(const view_file *files, sl_stitch_view *views, int count,
                               const sl_stitch_solve_options *so, sl_stitch_solve_result *res,
                               sl_error *err)
{
    int k = files[0].solve_factor, w = files[0].width, h = files[0].height;
    sl_stitch_view sv[SL_STITCH_MAX_VIEWS];
    /* The circles found as the views were read, in the solve's pixels. */
    sl_stitch_circle circles[SL_STITCH_MAX_VIEWS];
    sl_stitch_solve_options opt = *so;
    opt.circles = circles;
    for (int i = 0; i < count; i++) {
        circles[i] = files[i].circle;
        circles[i].cx /= k;
        circles[i].cy /= k;
        circles[i].radius /= k;
        circles[i].rms_px /= k;
        if (files[i].circle_status != SL_OK)
            opt.circles = NULL;
    }
    so = &opt;
    for (int i = 0; i < count; i++) {
        sv[i] = views[i];
        if (k > 1) {
            sv[i].radiance = &files[i].solve_radiance;
            sv[i].weight = files[i].weight.data ? &files[i].solve_weight : NULL;
            stitch_lens_scale(&sv[i].lens, 1.0 / k, w / k, h / k);
        }
    }
    sl_result r = sl_stitch_solve(sv, count, so, res, err);
    if (r || k == 1) {
        for (int i = 0; !r && i < count; i++) {
            views[i].lens = sv[i].lens;
            views[i].pose = sv[i].pose;
        }
        return r;
    }
    for (int i = 0; i < count; i++) {
        views[i].pose = sv[i].pose;
        views[i].lens = sv[i].lens;
        stitch_lens_scale(&views[i].lens, k, w, h);
    }
    stitch_lens_scale(&res->lens_nominal, k, w, h);
    stitch_lens_scale(&res->lens, k, w, h);
    res->rms_px *= k;
    res->max_px *= k;
    for (int a = 0; a < 2; a++) {
        res->circle_centre[a] *= k;
        res->circle_sigma[a] *= k;
        res->overlap_centre[a] *= k;
        res->overlap_sigma[a] *= k;
    }
    for (int p = 0; p < res->pairs; p++) {
        res->pair[p].rms_px *= k;
        res->pair[p].max_px *= k;
    }
    return SL_OK;
}

static double axis_angle_deg(const sl_view_pose *a, const sl_view_pose *b)
{
    double ma[3][3], mb[3][3];
    sl_view_pose_matrix(a, ma);
    sl_view_pose_matrix(b, mb);
    double c = ma[0][2] * mb[0][2] + ma[1][2] * mb[1][2] + ma[2][2] * mb[2][2];
    return acos(fmin(1.0, fmax(-1.0, c))) / DEG;
}

/* Every view must share a field band with the others (one connected
 * overlap graph), else the solve cannot tie it and the stitch would be
 * pieces: the first view not reached and its nearest view are named. */
static sl_result check_overlaps(const sl_stitch_view *views, int count, sl_error *err)
{
    if (count < 2)
        return SL_OK;
    bool reached[SL_STITCH_MAX_VIEWS] = {true};
    for (bool grew = true; grew;) {
        grew = false;
        for (int i = 0; i < count; i++)
            for (int j = 0; j < count && !reached[i]; j++)
                if (reached[j] &&
                    axis_angle_deg(&views[i].pose, &views[j].pose) <
                        views[i].lens.max_theta_deg + views[j].lens.max_theta_deg -
                            MIN_OVERLAP_DEG)
                    reached[i] = grew = true;
    }
    for (int i = 0; i < count; i++) {
        if (reached[i])
            continue;
        int near = 0;
        double best = 1e9;
        for (int j = 0; j < count; j++)
            if (reached[j] && axis_angle_deg(&views[i].pose, &views[j].pose) < best) {
                best = axis_angle_deg(&views[i].pose, &views[j].pose);
                near = j;
            }
        return sl_error_set(err, SL_ERR_INPUT,
                            "%s and %s do not overlap (their axes are %.1f deg apart, their "
                            "fields %.1f and %.1f deg): check --yaw/--pitch",
                            views[near].name, views[i].name, best,
                            views[near].lens.max_theta_deg, views[i].lens.max_theta_deg);
    }
    return SL_OK;
}

/* The output file, opened at the first strip. */
typedef struct out_file {
    const char *path;
    const sl_stitch_options *opt;
    sl_meta *meta;
    int width, height;
    sl_exr_stream *stream;
    stitch_report_images *report; /* NULL: no report; else its map is summed here */
} out_file;

/* The report's map: each strip's texels summed into the map's pixels (RGBA;
 * and filled texels, all texels), divided into means after the last. */
static void add_to_map(stitch_report_images *ri, const float *rows, int y0, int count,
                       size_t stride, int width, int height)
{
    sl_image *m = &ri->map, *f = &ri->filled;
    for (int r = 0; r < count; r++) {
        int my = (y0 + r) * m->height / height;
        const float *row = rows + (size_t)r * stride;
        for (int x = 0; x < width; x++) {
            float *o = sl_image_pixel(m, x * m->width / width, my);
            float *n = sl_image_pixel(f, x * m->width / width, my);
            const float *p = row + (size_t)x * 4;
            for (int c = 0; c < 4; c++)
                o[c] += p[c];
            n[0] += !(p[3] > 0);
            n[1] += 1.0f;
        }
    }
}

static void map_means(stitch_report_images *ri)
{
    for (int y = 0; y < ri->map.height; y++)
        for (int x = 0; x < ri->map.width; x++) {
            float *o = sl_image_pixel(&ri->map, x, y), *n = sl_image_pixel(&ri->filled, x, y);
            float k = n[1] > 0 ? 1.0f / n[1] : 0.0f;
            for (int c = 0; c < 4; c++)
                o[c] *= k;
            n[0] *= k;
        }
}

static sl_result write_rows(void *user, const float *rows, int y0, int count, size_t stride,
                            sl_error *err)
{
    out_file *o = user;
    sl_result r;
    if (y0 == 0 && (r = sl_exr_stream_open(o->path, o->width, o->height, 4, o->meta,
                                           o->opt->pixel_type, o->opt->compression, &o->stream,
                                           err)))
        return r;
    if (o->report)
        add_to_map(o->report, rows, y0, count, stride, o->width, o->height);
    r = sl_exr_stream_write(o->stream, rows, count, stride, err);
    if (r)
        o->stream = NULL; /* a failed write aborts the stream */
    return r;
}

/* Coverage numbers known only after the last strip, at a fixed width (the
 * header is written with a placeholder of the same length first). */
static void coverage_text(const sl_stitch_coverage *c, int64_t texels, char *buf, size_t size)
{
    int digits = snprintf(NULL, 0, "%lld", (long long)texels);
    snprintf(buf, size,
             "seen %.6e sr, filled %.6e sr (masked %.6e sr), confidence under 0.5 %.6e sr, "
             "ghost texels %*lld (%.6e sr)",
             c->seen_sr, c->filled_sr, c->masked_sr, c->low_sr, digits,
             (long long)c->ghost_texels, c->ghost_sr);
}

static sl_result output_meta(const sl_stitch_view *views, int count, const sl_stitch_result *res,
                             const sl_stitch_options *opt, int width, sl_meta *meta,
                             sl_error *err)
{
    meta->envmap = SL_ENVMAP_LATLONG;
    sl_result r = sl_meta_set_color_space(meta, SL_WORKING_SPACE, err);
    char buf[8192];
    size_t len = 0;
    for (int i = 0; i < count && len < sizeof buf; i++)
        len += (size_t)snprintf(buf + len, sizeof buf - len, "%s yaw=%.4f pitch=%.4f roll=%.4f%s\n",
                                views[i].name, views[i].pose.yaw_deg, views[i].pose.pitch_deg,
                                views[i].pose.roll_deg,
                                res->views[i].confidence ? " (clipped mask weighted)" : "");
    if (!r)
        r = sl_meta_set(meta, "setlight:version", sl_version(), err);
    if (!r)
        r = sl_meta_set(meta, "setlight:stitch:views", buf, err);
    const sl_lens *l = &res->lens;
    snprintf(buf, sizeof buf,
             "%s %dx%d focal_px=%.4f cx=%.4f cy=%.4f k=%.6g,%.6g,%.6g vignette=%.6g,%.6g,%.6g "
             "max_theta_deg=%.4f circle_radius_px=%.4f (%s; %s)",
             sl_lens_projection_name(l->projection), l->width, l->height, l->focal_px, l->cx,
             l->cy, l->k[0], l->k[1], l->k[2], l->vignette[0], l->vignette[1], l->vignette[2],
             l->max_theta_deg, l->circle_radius_px, res->lens_source,
             res->solved ? "solved" : res->solve_note);
    if (!r)
        r = sl_meta_set(meta, "setlight:stitch:lens", buf, err);
    snprintf(buf, sizeof buf,
             "weighted mean of radiance / vignetting, weight (1 + cos theta) / 2 x cos^2 ramp "
             "over the last %g deg of the field x merge confidence; ghost test %g; nadir "
             "mask %g deg%s",
             opt->blend.ramp_deg, opt->blend.ghost_ratio, opt->blend.nadir_mask_deg,
             opt->blend.mask ? "; mask image" : "");
    (void)width;
    if (!r)
        r = sl_meta_set(meta, "setlight:stitch:blend", buf, err);
    if (!r)
        r = sl_meta_set(meta, "setlight:alpha",
                        "confidence: min(1, sum of the views' blend weights), 0 where filled", err);
    coverage_text(&res->coverage, (int64_t)width * (width / 2), buf, sizeof buf);
    if (!r)
        r = sl_meta_set(meta, "setlight:stitch:coverage", buf, err);
    return r;
}

static void phase_end(sl_stitch_result *res, sl_stitch_phase ph, double *t, double *c)
{
    double t1 = sl_seconds(), c1 = sl_cpu_seconds();
    res->wall[ph] += t1 - *t;
    res->cpu[ph] += c1 - *c;
    *t = t1;
    *c = c1;
}

sl_result sl_stitch(const char *const *view_paths, int count, const char *out_path,
                    const sl_stitch_options *opt_in, sl_stitch_result *res_out, sl_error *err)
{
    sl_stitch_options opt;
    if (opt_in)
        opt = *opt_in;
    else
        sl_stitch_options_init(&opt);
    sl_stitch_result *res = calloc(1, sizeof *res);
    view_file *files = calloc(SL_STITCH_MAX_VIEWS, sizeof *files);
    sl_stitch_view views[SL_STITCH_MAX_VIEWS];
    sl_meta meta;
    sl_meta_init(&meta);
    out_file out = {0};
    release freeing = {0}; /* memory freed beside what comes next */
    stitch_report_images *report = NULL;
    if (res_out)
        memset(res_out, 0, sizeof *res_out);
    if (!res || !files) {
        free(res);
        free(files);
        return sl_error_set(err, SL_ERR_NOMEM, "stitch: out of memory");
    }
    double t0 = sl_seconds(), c0 = sl_cpu_seconds(), t = t0, c = c0;
    sl_result r = SL_OK;
    if (count < 1 || count > SL_STITCH_MAX_VIEWS) {
        r = sl_error_set(err, SL_ERR_USAGE, "stitch: 1 to %d views, not %d", SL_STITCH_MAX_VIEWS,
                         count);
        goto done;
    }
    res->view_count = count;
    /* The report's thumbnails, while the views are float. */
    if (opt.report && !(report = calloc(1, sizeof *report))) {
        r = sl_error_set(err, SL_ERR_NOMEM, "stitch: out of memory");
        goto done;
    }
    for (int i = 0; i < count && !r; i++) {
        view_file *v = &files[i];
        v->path = view_paths[i];
        sl_meta_init(&v->meta);
        snprintf(res->views[i].path, sizeof res->views[i].path, "%s", v->path);
        r = read_view(v, &opt, opt.solve && count >= 2, &res->views[i], i > 0 ? &files[0] : NULL,
                      report ? &report->thumb[i] : NULL, err);
    }
    /* The circles were found beside the reading: their threads' CPU time
     * is the circle phase's, not the read's, and the wall time the stitch
     * waits for them after the last view is read. */
    phase_end(res, SL_STITCH_READ, &t, &c);
    double circle_cpu = 0.0;
    for (int i = 0; i < count; i++) {
        circle_wait(&files[i]);
        circle_cpu += files[i].circle_cpu;
    }
    phase_end(res, SL_STITCH_CIRCLE, &t, &c);
    res->cpu[SL_STITCH_READ] += res->cpu[SL_STITCH_CIRCLE] - circle_cpu;
    res->cpu[SL_STITCH_CIRCLE] = circle_cpu;
    if (r)
        goto done;
    if ((r = nominal_lens(files, count, &opt, &res->lens_nominal, res->lens_source,
                          sizeof res->lens_source, err)))
        goto done;
    for (int i = 0; i < count; i++) {
        sl_stitch_view *v = &views[i];
        v->name = files[i].path;
        v->radiance = files[i].radiance.data ? &files[i].radiance : NULL;
        v->weight = files[i].weight.data ? &files[i].weight : NULL;
        v->lens = res->lens_nominal;
        v->pose.yaw_deg = i < opt.yaw_count ? opt.yaw_deg[i] : 360.0 * i / count;
        v->pose.pitch_deg = i < opt.pitch_count ? opt.pitch_deg[i] : 0.0;
        v->pose.roll_deg = i < opt.roll_count ? opt.roll_deg[i] : 0.0;
        res->views[i].nominal = v->pose;
    }
    phase_end(res, SL_STITCH_READ, &t, &c);
    /* A circular fisheye's image circle, found in every view: the optical
     * centre and the circle the solve starts from (a profile keeps its own). */
    bool given = opt.lens || opt.lens_profile;
    if (res->lens_nominal.projection != SL_LENS_RECTILINEAR &&
        res->lens_nominal.circle_radius_px > 0) {
        double sx = 0, sy = 0, sr = 0;
        for (int i = 0; i < count; i++) {
            sl_stitch_circle circ = files[i].circle;
            if ((r = files[i].circle_status)) {
                *err = files[i].circle_err;
                goto done;
            }
            if (res->lens_nominal.circle_radius_px > 0.0)
                circ.radius_vs_nominal = circ.radius / res->lens_nominal.circle_radius_px;
            if (i == 0)
                res->circle = circ;
            if (report) {
                double f = (double)report->thumb[i].width / res->views[i].width;
                report->circle[i][0] = circ.cx * f;
                report->circle[i][1] = circ.cy * f;
                report->circle[i][2] = circ.radius * f;
            }
            sx += circ.cx;
            sy += circ.cy;
            sr += circ.radius;
        }
        res->circle_found = true;
        if (!given) {
            for (int i = 0; i < count; i++) {
                views[i].lens.cx = sx / count;
                views[i].lens.cy = sy / count;
                views[i].lens.circle_radius_px = sr / count;
            }
        }
    }
    phase_end(res, SL_STITCH_CIRCLE, &t, &c);
    if ((r = check_overlaps(views, count, err)))
        goto done;
    if (opt.solve && count >= 2) {
        sl_stitch_solve_options so;
        sl_stitch_solve_options_init(&so);
        if (given) { /* the lens is known: only the poses */
            so.solve_focal = so.solve_centre = so.solve_vignette = false;
            so.radial_terms = 0;
        }
        if ((r = solve_reduced(files, views, count, &so, &res->solve, err)))
            goto done;
        res->solved = true;
        snprintf(res->solve_note, sizeof res->solve_note,
                 "solved from the overlaps: %d pairs solved, %d placed by their radiance, %d "
                 "fell back to the nominal rotation, %d matches, reprojection RMS %.3f px, max "
                 "%.3f px%s%s",
                 res->solve.pairs_solved, res->solve.pairs_radiance, res->solve.pairs_fallback,
                 res->solve.inliers,
                 res->solve.rms_px, res->solve.max_px, res->solve.lens_held ? "; " : "",
                 res->solve.lens_held ? res->solve.lens_note : "");
    } else {
        snprintf(res->solve_note, sizeof res->solve_note, "%s",
                 count < 2   ? "not solved: one view, lens and pose as given"
                 : opt.solve ? ""
                             : "not solved (--no-solve): lens and poses as given");
    }
    res->lens = views[0].lens;
    for (int i = 0; i < count; i++)
        res->views[i].pose = views[i].pose;
    if (opt.save_lens) {
        sl_lens_profile prof;
        memset(&prof, 0, sizeof prof);
        prof.lens = res->lens;
        camera_name(&files[0].meta, prof.camera, sizeof prof.camera);
        snprintf(prof.lens_name, sizeof prof.lens_name, "%s", files[0].meta.lens);
        prof.source = res->solved && !given ? SL_LENS_SOURCE_OVERLAPS : SL_LENS_SOURCE_NOMINAL;
        prof.rms_px = res->solved ? res->solve.rms_px : -1;
        prof.max_px = res->solved ? res->solve.max_px : -1;
        prof.images = res->solved ? count : 0;
        if ((r = sl_lens_profile_write(opt.save_lens, &prof, err)))
            goto done;
    }
    phase_end(res, SL_STITCH_SOLVE, &t, &c);
    /* The solve's copies are done with: freed beside the blend. */
    for (int i = 0; i < count; i++) {
        release_image(&freeing, &files[i].solve_radiance);
        release_image(&freeing, &files[i].solve_weight);
    }
    release_start(&freeing);

    int width = opt.blend.width > 0 ? opt.blend.width
                                    : sl_stitch_default_width(&res->lens, opt.blend.max_width);
    opt.blend.width = width;
    /* Half holds values up to 65504: brighter views (a lamp, the sun) are
     * written as float rather than clipped. */
    if (opt.pixel_type == SL_PIXEL_HALF) {
        double peak = 0, edge_gain = fmax(1e-6, sl_lens_vignette(&res->lens,
                          res->lens.cx + fmax(res->lens.circle_radius_px,
                                              0.5 * hypot(res->lens.width, res->lens.height)),
                          res->lens.cy));
        for (int i = 0; i < count; i++)
            peak = fmax(peak, files[i].peak);
        if (peak / fmin(1.0, edge_gain) > 65504.0) {
            opt.pixel_type = SL_PIXEL_FLOAT;
            res->float_samples = true;
        }
    }
    /* The header goes out with placeholders for the coverage. */
    if ((r = output_meta(views, count, res, &opt, width, &meta, err)))
        goto done;
    if (report) {
        int mw = width < 512 ? width : 512;
        if ((r = sl_image_alloc(&report->map, mw, mw / 2, 4, err)) ||
            (r = sl_image_alloc(&report->filled, mw, mw / 2, 2, err)))
            goto done;
        sl_image_fill(&report->map, 0.0f);
        sl_image_fill(&report->filled, 0.0f);
    }
    out = (out_file){out_path, &opt, &meta, width, width / 2, NULL, report};
    stitch_half_image half[SL_STITCH_MAX_VIEWS];
    for (int i = 0; i < count; i++)
        half[i] = files[i].half;
    r = stitch_blend_run(views, count, half, true, &opt.blend, write_rows, &out, NULL, &res->coverage,
                         err);
    if (r)
        goto done;
    {
        /* Final header values, the same lengths as the placeholders. */
        sl_meta final;
        sl_meta_init(&final);
        char buf[1024];
        coverage_text(&res->coverage, (int64_t)width * (width / 2), buf, sizeof buf);
        r = sl_meta_set(&final, "setlight:stitch:coverage", buf, err);
        /* The report before the lat-long moves into place: a failed report
         * leaves no output. */
        if (!r && report) {
            map_means(report);
            r = stitch_report_write(opt.report, res, report, out_path, err);
        }
        if (!r) {
            r = sl_exr_stream_finish(out.stream, &final, err);
            out.stream = NULL;
        }
        sl_meta_free(&final);
    }
    phase_end(res, SL_STITCH_BLEND, &t, &c);

done:
    sl_exr_stream_abort(out.stream);
    res->seconds = sl_seconds() - t0;
    res->cpu_seconds = sl_cpu_seconds() - c0;
    release_wait(&freeing);
    /* every other view's memory freed on a thread of its own beside the rest */
    for (int i = 1; i < SL_STITCH_MAX_VIEWS; i += 2) {
        void *half = files[i].half.rgb;
        if (release_block(&freeing, &half))
            files[i].half.rgb = NULL;
        release_image(&freeing, &files[i].radiance);
    }
    release_start(&freeing);
    if (!r && res_out)
        *res_out = *res; /* the solve's arrays go with it */
    else
        sl_stitch_solve_result_free(&res->solve);
    for (int i = 0; i < SL_STITCH_MAX_VIEWS; i++) {
        sl_image_free(&files[i].radiance);
        sl_image_free(&files[i].weight);
        stitch_half_free(&files[i].half);
        sl_image_free(&files[i].solve_radiance);
        sl_image_free(&files[i].solve_weight);
        if (files[i].path)
            sl_meta_free(&files[i].meta);
    }
    release_wait(&freeing);
    sl_meta_free(&meta);
    if (report) {
        for (int i = 0; i < SL_STITCH_MAX_VIEWS; i++)
            sl_image_free(&report->thumb[i]);
        sl_image_free(&report->map);
        sl_image_free(&report->filled);
        free(report);
    }
    free(files);
    free(res);
    return r;
}
