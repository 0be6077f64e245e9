/* SPDX-License-Identifier: BSD-3-Clause */
/* The rig's validation (`setlight rig --validate`, sl_rig_run): the grey, chrome and
 * shadow scenes rendered under the map and under the rig, and their report. */
#include "lightrig_private.h"

#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "setlight/render.h"

static sl_result render_one(const char *preset, const sl_image *env, const char *rig_json,
                            int width, int64_t spp, uint64_t seed, sl_image *out,
                            int64_t *spp_done, sl_error *err)
{
    sl_scene s;
    sl_scene_init(&s);
    sl_result r = sl_scene_preset(&s, preset, width, err);
    if (!r)
        r = env ? sl_scene_set_dome(&s, env, 0, 1, "map", err)
                : sl_scene_read_rig(&s, rig_json, err);
    /* The lighting is compared, not the map seen behind the objects. */
    s.background_env = false;
    if (!r) {
        sl_render_options o;
        sl_render_options_init(&o);
        o.spp = spp;
        o.seed = seed;
        /* one bounce: the shadow scene's ground lights the sphere's underside */
        o.bounces = 1;
        sl_render_stats st;
        r = sl_render(&s, &o, out, &st, err);
        if (!r) {
            *spp_done = st.spp;
            sl_render_stats_free(&st);
        }
    }
    sl_scene_free(&s);
    return r;
}

void sl_rig_validation_free(sl_rig_validation *v)
{
    for (int k = 0; k < SL_RIG_VALIDATE_SCENES; k++) {
        sl_image_free(&v->map[k]);
        sl_image_free(&v->rig[k]);
    }
}

/* One scene: map and rig each rendered twice with half the samples and
 * seeds 1 and 2. The rig-minus-map differences of the two seeds share
 * their camera and BSDF samples as the final renders do, so half their
 * difference is the Monte Carlo noise of the final difference (the map's
 * and the rig's noise are strongly correlated: a chrome sphere's jittered
 * pixels see nearly the same directions under both). */
static sl_result validate_scene(sl_rig_validation *v, int k, const sl_image *env, const char *rig_json,
                                sl_error *err)
{
    sl_image a[2] = {{0}}, b[2] = {{0}};
    int64_t half = (v->spp + 1) / 2, done[4] = {0};
    sl_result r = SL_OK;
    for (int s = 0; s < 2 && !r; s++) {
        double t = sl_seconds();
        if ((r = render_one(v->scene[k], env, NULL, v->width, half, (uint64_t)s + 1, &a[s],
                            &done[2 * s], err)))
            break;
        v->seconds_map[k] += sl_seconds() - t;
        t = sl_seconds();
        r = render_one(v->scene[k], NULL, rig_json, v->width, half, (uint64_t)s + 1, &b[s],
                       &done[2 * s + 1], err);
        v->seconds_rig[k] += sl_seconds() - t;
    }
    if (!r && !(r = sl_image_copy(&a[0], &v->map[k], err)))
        r = sl_image_copy(&b[0], &v->rig[k], err);
    if (!r) {
        v->spp_done = done[0] + done[2];
        double num = 0, den = 0, noise = 0;
        for (int y = 0; y < a[0].height; y++)
            for (int x = 0; x < a[0].width; x++) {
                const float *a0 = sl_image_pixel(&a[0], x, y), *a1 = sl_image_pixel(&a[1], x, y),
                            *b0 = sl_image_pixel(&b[0], x, y), *b1 = sl_image_pixel(&b[1], x, y);
                float *pa = sl_image_pixel(&v->map[k], x, y), *pb = sl_image_pixel(&v->rig[k], x, y);
                /* Only the objects: a rig light seen directly (a rect far
                 * away) is not the map behind them. */
                float alpha = 0.5f * (a0[3] + a1[3]);
                for (int c = 0; c < 3; c++) {
                    pa[c] = alpha * 0.5f * (a0[c] + a1[c]);
                    pb[c] = alpha * 0.5f * (b0[c] + b1[c]);
                    double d = (double)pb[c] - pa[c];
                    double h = 0.5 * alpha * (((double)b0[c] - a0[c]) - ((double)b1[c] - a1[c]));
                    num += d * d;
                    den += (double)pa[c] * pa[c];
                    noise += h * h;
                }
                pa[3] = pb[3] = alpha;
            }
        v->error[k] = den > 0 ? sqrt(num / den) : 0;
        v->noise[k] = den > 0 ? sqrt(noise / den) : 0;
        /* E[error^2] = bias^2 + noise^2 */
        double e2 = num - noise;
        v->beyond_noise[k] = den > 0 && e2 > 0 ? sqrt(e2 / den) : 0;
    }
    for (int s = 0; s < 2; s++) {
        sl_image_free(&a[s]);
        sl_image_free(&b[s]);
    }
    return r;
}

sl_result sl_rig_validate(const sl_image *env, const char *rig_json, int width, int64_t spp,
                       sl_rig_validation *v, sl_error *err)
{
    static const char *const scenes[SL_RIG_VALIDATE_SCENES] = {"grey", "chrome", "shadow"};
    memset(v, 0, sizeof *v);
    double t0 = sl_seconds(), c0 = sl_cpu_seconds();
    v->width = width;
    v->spp = spp;
    for (int k = 0; k < SL_RIG_VALIDATE_SCENES; k++) {
        v->scene[k] = scenes[k];
        v->error[k] = -1;
    }
    sl_result r = SL_OK;
    for (int k = 0; k < SL_RIG_VALIDATE_SCENES && !r; k++)
        r = validate_scene(v, k, env, rig_json, err);
    v->seconds = sl_seconds() - t0;
    v->cpu_seconds = sl_cpu_seconds() - c0;
    if (!r)
        v->spp = v->spp_done;
    return r;
}

/* --- the report ------------------------------------------------------- */

/* The false-colour scale: log10 of the relative difference from
 * SCALE_LO (black) to SCALE_HI (red), two decades. */
#define SCALE_LO 0.003
#define SCALE_HI 0.3

static void false_colour(double t, float rgb[3])
{
    static const float stops[5][3] = {{0, 0, 0}, {0, 0, 1}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}};
    t = t < 0 ? 0 : t > 1 ? 1 : t;
    double f = t * 4;
    int i = f >= 4 ? 3 : (int)f;
    double w = f - i;
    /* the report sRGB-encodes: hand it linear values */
    for (int c = 0; c < 3; c++)
        rgb[c] = sl_srgb_to_linear((float)((1 - w) * stops[i][c] + w * stops[i + 1][c]));
}

static double scale_position(double e)
{
    return e > 0 ? (log10(e) - log10(SCALE_LO)) / (log10(SCALE_HI) - log10(SCALE_LO)) : 0;
}

/* Per pixel, the RMS over RGB of (rig - map) over the map render's RMS
 * over the objects: the RMS of this over the objects is the relative RMSE. */
static sl_result diff_image(const sl_image *a, const sl_image *b, sl_image *out, sl_error *err)
{
    sl_result r = sl_image_alloc(out, a->width, a->height, 3, err);
    if (r)
        return r;
    double sum2 = 0, cover = 0;
    for (int y = 0; y < a->height; y++)
        for (int x = 0; x < a->width; x++) {
            const float *p = sl_image_pixel(a, x, y);
            for (int c = 0; c < 3; c++)
                sum2 += (double)p[c] * p[c];
            cover += p[3];
        }
    double rms = cover > 0 ? sqrt(sum2 / (3 * cover)) : 0;
    float bg = sl_srgb_to_linear(0.5f);
    for (int y = 0; y < a->height; y++)
        for (int x = 0; x < a->width; x++) {
            const float *pa = sl_image_pixel(a, x, y), *pb = sl_image_pixel(b, x, y);
            double d2 = 0;
            for (int c = 0; c < 3; c++)
                d2 += ((double)pb[c] - pa[c]) * ((double)pb[c] - pa[c]);
            /* alpha-weighted: the difference of partly covered edge pixels
             * is already scaled by the coverage */
            double e = rms > 0 && pa[3] > 0 ? sqrt(d2 / 3) / (rms * pa[3]) : 0;
            float col[3], *o = sl_image_pixel(out, x, y);
            false_colour(scale_position(e), col);
            for (int c = 0; c < 3; c++)
                o[c] = pa[3] * col[c] + (1 - pa[3]) * bg;
        }
    return SL_OK;
}

/* Stops that put the log-average luminance of the objects at 18% grey. */
static double render_stops(const sl_image *a)
{
    double s = 0;
    long n = 0;
    for (int y = 0; y < a->height; y++)
        for (int x = 0; x < a->width; x++) {
            const float *p = sl_image_pixel(a, x, y);
            double lum = 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
            if (p[3] > 0.5 && lum > 0) {
                s += log(lum / p[3]);
                n++;
            }
        }
    return n ? log2(0.18 / exp(s / (double)n)) : 0;
}

sl_result sl_rig_validate_report(sl_report *rep, const sl_rig_validation *v, const char *prefix,
                              sl_error *err)
{
    static const char *const head[] = {
        "scene",          "relative RMSE (%)", "spp",           "size (px)",
        "map render (s)", "rig render (s)",    "noise (%)",     "beyond noise (%)"};
    sl_report_table_begin(rep, 8, head);
    for (int k = 0; k < SL_RIG_VALIDATE_SCENES; k++) {
        char c[8][48];
        snprintf(c[0], sizeof c[0], "%s", v->scene[k]);
        snprintf(c[1], sizeof c[1], "%.3f", 100 * v->error[k]);
        snprintf(c[2], sizeof c[2], "%lld", (long long)v->spp);
        snprintf(c[3], sizeof c[3], "%dx%d", v->map[k].width, v->map[k].height);
        snprintf(c[4], sizeof c[4], "%.2f", v->seconds_map[k]);
        snprintf(c[5], sizeof c[5], "%.2f", v->seconds_rig[k]);
        snprintf(c[6], sizeof c[6], "%.3f", 100 * v->noise[k]);
        snprintf(c[7], sizeof c[7], "%.3f", 100 * v->beyond_noise[k]);
        const char *cells[8] = {c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7]};
        sl_report_table_row(rep, cells);
    }
    sl_report_table_end(rep);
    sl_report_text(rep,
                   "Each scene under the map, under the rig (same exposure: the log-average of "
                   "the map render's objects at 18%% grey) and their difference in false "
                   "colour: per pixel the RMS over RGB of rig - map over the map render's RMS "
                   "over the objects (the relative RMSE is the RMS of this over the objects); "
                   "grey is the background. Monte Carlo noise at %lld spp is part of it. "
                   "'noise': each render is the mean of two with half the samples and seeds 1 "
                   "and 2, map and rig with the same seeds; half the difference of the two "
                   "seeds' rig-minus-map images is the noise of the final difference (relative "
                   "to the map render). 'beyond noise' = sqrt(RMSE^2 - noise^2): the rig's own "
                   "error, as far as the noise lets it show.",
                   (long long)v->spp);
    char file[512], cap[256];
    sl_image bar = {0};
    sl_result r = sl_image_alloc(&bar, 256, 16, 3, err);
    if (r)
        return r;
    for (int y = 0; y < bar.height; y++)
        for (int x = 0; x < bar.width; x++)
            false_colour((x + 0.5) / bar.width, sl_image_pixel(&bar, x, y));
    snprintf(file, sizeof file, "%sdiff_scale.png", prefix);
    r = sl_report_image(rep, file, &bar, 0,
                        "difference scale (log): black 0.3% or less, blue 1%, green 3%, "
                        "yellow 10%, red 30% or more",
                        err);
    sl_image_free(&bar);
    for (int k = 0; k < SL_RIG_VALIDATE_SCENES && !r; k++) {
        double stops = render_stops(&v->map[k]);
        snprintf(file, sizeof file, "%s%s_map.png", prefix, v->scene[k]);
        snprintf(cap, sizeof cap, "%s under the map (%+.1f stops)", v->scene[k], stops);
        if ((r = sl_report_image(rep, file, &v->map[k], stops, cap, err)))
            break;
        snprintf(file, sizeof file, "%s%s_rig.png", prefix, v->scene[k]);
        snprintf(cap, sizeof cap, "%s under the rig (%+.1f stops)", v->scene[k], stops);
        if ((r = sl_report_image(rep, file, &v->rig[k], stops, cap, err)))
            break;
        sl_image d = {0};
        if ((r = diff_image(&v->map[k], &v->rig[k], &d, err)))
            break;
        snprintf(file, sizeof file, "%s%s_diff.png", prefix, v->scene[k]);
        snprintf(cap, sizeof cap, "%s: |rig - map|, relative RMSE %.3f%%", v->scene[k],
                 100 * v->error[k]);
        r = sl_report_image(rep, file, &d, 0, cap, err);
        sl_image_free(&d);
    }
    return r;
}

static void report_lights(sl_report *rep, const sl_rig *rig)
{
    static const char *const head[] = {"light",        "shape",          "lat (deg)",
                                       "lon (deg)",    "size (deg)",     "solid angle (sr)",
                                       "share grey",   "share glossy",   "texture"};
    sl_report_table_begin(rep, 9, head);
    for (int i = 0; i < rig->light_count; i++) {
        const sl_rig_light *l = &rig->lights[i];
        char c[8][64];
        snprintf(c[0], 64, "%d", i + 1);
        snprintf(c[1], 64, "%s", sl_rig_shape_name(l->shape));
        snprintf(c[2], 64, "%.2f", asin(fmax(-1, fmin(1, l->direction[1]))) * 180 / M_PI);
        snprintf(c[3], 64, "%.2f", atan2(l->direction[0], l->direction[2]) * 180 / M_PI);
        snprintf(c[4], 64, "%.2f x %.2f", l->angular_size[0] * 180 / M_PI,
                 l->angular_size[1] * 180 / M_PI);
        snprintf(c[5], 64, "%.4g", l->solid_angle);
        snprintf(c[6], 64, "%.3f", l->share);
        snprintf(c[7], 64, "%.3f", l->share_glossy);
        const char *cells[9] = {c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7],
                                l->texture[0] ? l->texture : "-"};
        sl_report_table_row(rep, cells);
    }
    sl_report_table_end(rep);
}

/* The preview as the report shows it: written, read back, and re-encoded
 * by the report over the same file. */
static sl_result report_preview(sl_report *rep, const char *dir, const char *file,
                                const sl_rig *rig, const sl_image *env, sl_error *err)
{
    char path[4700];
    snprintf(path, sizeof path, "%s/%s", dir, file);
    sl_result r = sl_rig_write_preview(rig, env, path, err);
    if (r)
        return r;
    sl_image prev;
    sl_meta pm;
    if ((r = sl_photo_read(path, &prev, &pm, err)))
        return r;
    sl_meta_free(&pm);
    for (size_t i = 0; i < (size_t)prev.height * prev.stride; i++)
        prev.data[i] = sl_srgb_to_linear(prev.data[i]);
    r = sl_report_image(rep, file, &prev, 0, "the map with the rig's lights outlined and numbered",
                        err);
    sl_image_free(&prev);
    return r;
}

sl_result sl_rig_validate_report_check(const char *dir, const char *name, sl_error *err)
{
    char path[4096];
    struct stat st;
    snprintf(path, sizeof path, "%s/%s.html", dir, name);
    if (lstat(path, &st) == 0 && !S_ISREG(st.st_mode))
        return sl_error_set(err, SL_ERR_USAGE, "%s: exists and is not a file", path);
    snprintf(path, sizeof path, "%s/%s", dir, name);
    if (lstat(path, &st) == 0 && !S_ISDIR(st.st_mode))
        return sl_error_set(err, SL_ERR_USAGE, "%s: exists and is not a folder", path);
    return SL_OK;
}

static sl_result build_report(const char *tmp, const char *name, const char *about,
                              const sl_rig_validation *v, const sl_rig *rig, const sl_image *env,
                              sl_error *err)
{
    char sub[4400], prefix[512];
    snprintf(sub, sizeof sub, "%s/%s", tmp, name);
    if (mkdir(sub, 0777) != 0)
        return sl_error_set(err, SL_ERR_IO, "%s: cannot create folder: %s", sub, strerror(errno));
    snprintf(prefix, sizeof prefix, "%s/", name);
    sl_report *rep;
    char title[512];
    /* NAME is RIG.validate for RIG.usda */
    snprintf(title, sizeof title, "setlight rig validation: %.*s.usda",
             (int)(strlen(name) - strlen(".validate")), name);
    sl_result r = sl_report_new(&rep, tmp, name, title, err);
    if (r)
        return r;
    sl_report_text(rep, "%s", about);
    sl_report_section(rep, "Renders: map against rig");
    r = sl_rig_validate_report(rep, v, prefix, err);
    if (!r) {
        sl_report_section(rep, "Lights");
        report_lights(rep, rig);
        char file[600];
        snprintf(file, sizeof file, "%spreview.png", prefix);
        r = report_preview(rep, tmp, file, rig, env, err);
    }
    /* the renders as compared, for a closer look */
    for (int k = 0; k < SL_RIG_VALIDATE_SCENES && !r; k++) {
        char path[4700];
        snprintf(path, sizeof path, "%s/%s_map.exr", sub, v->scene[k]);
        if ((r = sl_exr_write(path, &v->map[k], NULL, SL_PIXEL_FLOAT, err)))
            break;
        snprintf(path, sizeof path, "%s/%s_rig.exr", sub, v->scene[k]);
        r = sl_exr_write(path, &v->rig[k], NULL, SL_PIXEL_FLOAT, err);
    }
    if (!r)
        sl_report_text(rep,
                       "The renders as compared (RGBA float EXR, objects only) are beside the "
                       "images: %s<scene>_map.exr and %s<scene>_rig.exr.",
                       prefix, prefix);
    if (r) {
        sl_report_free(rep);
        return r;
    }
    return sl_report_finish(rep, err);
}

sl_result sl_rig_validate_write_report(const char *dir, const char *name, const char *about,
                                    const sl_rig_validation *v, const sl_rig *rig,
                                    const sl_image *env, sl_rig_report_tmp *tmp, sl_error *err)
{
    tmp->path[0] = 0;
    tmp->handle = -1;
    sl_result r = sl_rig_validate_report_check(dir, name, err);
    if (r)
        return r;
    char folder[4400], page[4400], tmp_sub[4400], tmp_page[4400];
    snprintf(tmp->path, sizeof tmp->path, "%s/.%s.sl-tmp-%ld-XXXXXX", dir, name, (long)getpid());
    tmp->handle = sl_temp_dir_create(tmp->path); /* an interrupt removes it */
    if (tmp->handle < 0) {
        tmp->path[0] = 0;
        return sl_error_set(err, SL_ERR_IO, "%s: cannot create a temporary folder: %s", dir,
                            strerror(errno));
    }
    snprintf(folder, sizeof folder, "%s/%s", dir, name);
    snprintf(page, sizeof page, "%s/%s.html", dir, name);
    snprintf(tmp_sub, sizeof tmp_sub, "%s/%s", tmp->path, name);
    snprintf(tmp_page, sizeof tmp_page, "%s/%s.html", tmp->path, name);
    if ((r = build_report(tmp->path, name, about, v, rig, env, err)) ||
        (r = sl_output_set_adopt(folder, tmp_sub, err)) ||
        (r = sl_output_set_adopt(page, tmp_page, err))) {
        sl_temp_dir_remove(tmp->path, tmp->handle);
        tmp->path[0] = 0;
        tmp->handle = -1;
    }
    return r;
}
