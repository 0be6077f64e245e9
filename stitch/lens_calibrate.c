/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight lens-calibrate: chessboard photos to a lens profile. The board is
 * found by OpenCV (lens_calibrate_cxx.cpp); the lens is solved on the
 * project's own model (lens_calibrate_solve.c), the one stitch uses. */
#include "setlight/stitch.h"

#include "lens_calibrate_private.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

/* A board whose corners sit this far off the solved lens (RMS, and this
 * many times the median board's) was misdetected: left out, solved again. */
#define OUTLIER_MIN_PX 2.0
#define OUTLIER_RATIO 4.0

void sl_lens_calibrate_result_free(sl_lens_calibrate_result *res)
{
    free(res->photos);
    memset(res, 0, sizeof *res);
}

/* "Make Model", or Model alone when it already starts with the make (Canon). */
static void camera_name(const sl_meta *m, char *out, size_t size)
{
    if (!m->make[0] || strncasecmp(m->model, m->make, strlen(m->make)) == 0)
        snprintf(out, size, "%s", m->model);
    else
        snprintf(out, size, "%s %s", m->make, m->model);
}

/* 8-bit grey for the board finder: photos (JPEG, PNG) as encoded; linear
 * data (EXR, raw) brought to display range with its 99.5th percentile at
 * white and a 1/2.2 power. */
static unsigned char *grey_bytes(const sl_image *img, bool linear)
{
    size_t n = (size_t)img->width * img->height;
    unsigned char *g = malloc(n);
    float *y = malloc(n * sizeof *y);
    if (!g || !y) {
        free(g);
        free(y);
        return NULL;
    }
    for (int r = 0; r < img->height; r++)
        for (int c = 0; c < img->width; c++) {
            const float *p = sl_image_pixel(img, c, r);
            float v = img->channels >= 3 ? sl_luminancef(p) : p[0];
            y[(size_t)r * img->width + c] = isfinite(v) && v > 0 ? v : 0.0f;
        }
    double white = 1.0;
    if (linear) {
        int hist[4096] = {0};
        float top = 0;
        for (size_t i = 0; i < n; i++)
            top = fmaxf(top, y[i]);
        for (size_t i = 0; top > 0 && i < n; i++)
            hist[(int)fminf(4095.0f, y[i] / top * 4095.0f)]++;
        size_t seen = 0;
        int k = 0;
        while (k < 4095 && (seen += (size_t)hist[k]) < (size_t)(0.995 * n))
            k++;
        white = top > 0 ? (k + 1) * top / 4095.0 : 1.0;
    }
    for (size_t i = 0; i < n; i++) {
        double v = y[i] / white;
        v = linear ? pow(fmin(v, 1.0), 1.0 / 2.2) : fmin(v, 1.0);
        g[i] = (unsigned char)lrint(255.0 * v);
    }
    free(y);
    return g;
}

/* Reads one photo and finds the board: 1 found (corners filled), 0 not. */
static sl_result find_board(const char *path, const sl_lens_calibrate_options *opt,
                            sl_meta *meta, int *width, int *height, float *corners, int *found,
                            sl_error *err)
{
    sl_image img = {0};
    sl_result r = sl_image_read(path, &img, meta, err);
    if (r)
        return r;
    *width = img.width;
    *height = img.height;
    bool linear = meta->is_float || strcmp(meta->format, "raw") == 0;
    unsigned char *g = grey_bytes(&img, linear);
    sl_image_free(&img);
    if (!g)
        return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
    char msg[256] = "";
    *found = lens_chessboard_cxx(g, *width, *height, opt->board_cols, opt->board_rows, corners,
                                 msg, sizeof msg);
    free(g);
    if (*found < 0)
        return sl_error_set(err, SL_ERR_UNSUPPORTED, "%s: chessboard detection failed: %s", path,
                            msg);
    return SL_OK;
}

/* A term more of radial correction than the boards need trades with the
 * focal length and bends the radius beyond the boards (the Sigma 8mm photos:
 * two terms move the image circle 12 px inwards for 8% less RMS); auto
 * (radial_terms < 0) adds terms while each cuts the RMS by AUTO_TERM_GAIN. */
#define AUTO_TERM_GAIN 0.10

static sl_result solve_terms(const double *corners, int used,
                             const sl_lens_calibrate_options *opt, sl_lens_calibrate_result *res,
                             double *rms, double *mx, sl_error *err)
{
    int lo = opt->radial_terms < 0 ? 0 : opt->radial_terms;
    int hi = opt->radial_terms < 0 ? 3 : opt->radial_terms;
    double *trial_rms = malloc((size_t)used * sizeof *trial_rms);
    double *trial_mx = malloc((size_t)used * sizeof *trial_mx);
    if (!trial_rms || !trial_mx) {
        free(trial_rms);
        free(trial_mx);
        return sl_error_set(err, SL_ERR_NOMEM, "lens-calibrate: out of memory");
    }
    sl_result best = SL_ERR_INTERNAL;
    for (int terms = lo; terms <= hi; terms++) {
        sl_lens_calibrate_options o = *opt;
        o.radial_terms = terms;
        sl_lens lens = res->nominal;
        double all_rms, all_max;
        sl_error e2;
        sl_result r = sl_lens_calibrate_corners(corners, used, &o, &lens, trial_rms, trial_mx,
                                                &all_rms, &all_max, &e2);
        if (r && best == SL_OK)
            break; /* more terms turned the radius back: keep the fewer */
        if (r) {
            *err = e2;
            best = r;
            break;
        }
        if (best == SL_OK && all_rms > (1.0 - AUTO_TERM_GAIN) * res->profile.rms_px)
            break;
        best = SL_OK;
        res->profile.lens = lens;
        res->profile.rms_px = all_rms;
        res->profile.max_px = all_max;
        res->radial_terms = terms;
        memcpy(rms, trial_rms, (size_t)used * sizeof *rms);
        memcpy(mx, trial_mx, (size_t)used * sizeof *mx);
    }
    free(trial_rms);
    free(trial_mx);
    return best;
}

/* Solves from the used photos; leaves out misdetected boards and solves again. */
static sl_result solve_used(const double *all, int count, int n,
                            const sl_lens_calibrate_options *opt, sl_lens_calibrate_result *res,
                            sl_error *err)
{
    double *corners = malloc((size_t)count * n * 2 * sizeof *corners);
    double *rms = malloc((size_t)count * sizeof *rms), *mx = malloc((size_t)count * sizeof *mx);
    int *index = malloc((size_t)count * sizeof *index);
    sl_result r = (corners && rms && mx && index)
                      ? SL_OK
                      : sl_error_set(err, SL_ERR_NOMEM, "lens-calibrate: out of memory");
    for (int round = 0; round < 3 && !r; round++) {
        int used = 0;
        for (int i = 0; i < count; i++)
            if (res->photos[i].used) {
                memcpy(corners + (size_t)used * n * 2, all + (size_t)i * n * 2,
                       (size_t)n * 2 * sizeof *corners);
                index[used++] = i;
            }
        res->used = used;
        r = solve_terms(corners, used, opt, res, rms, mx, err);
        if (r)
            break;
        double *sorted = malloc((size_t)used * sizeof *sorted);
        if (!sorted) {
            r = sl_error_set(err, SL_ERR_NOMEM, "lens-calibrate: out of memory");
            break;
        }
        memcpy(sorted, rms, (size_t)used * sizeof *sorted);
        for (int i = 1; i < used; i++)
            for (int j = i; j > 0 && sorted[j - 1] > sorted[j]; j--) {
                double t = sorted[j];
                sorted[j] = sorted[j - 1];
                sorted[j - 1] = t;
            }
        double median = sorted[used / 2];
        free(sorted);
        int dropped = 0;
        for (int k = 0; k < used; k++) {
            sl_lens_calibrate_photo *ph = &res->photos[index[k]];
            ph->rms_px = rms[k];
            ph->max_px = mx[k];
            if (round < 2 && used - dropped > 3 && rms[k] > OUTLIER_MIN_PX && rms[k] > OUTLIER_RATIO * median) {
                ph->used = false;
                snprintf(ph->why, sizeof ph->why,
                         "corners %.2f px RMS off the lens the other boards solve: misdetected",
                         rms[k]);
                dropped++;
            }
        }
        if (!dropped)
            break;
    }
    free(corners);
    free(rms);
    free(mx);
    free(index);
    return r;
}

sl_result sl_lens_calibrate(const char *const *paths, int count,
                            const sl_lens_calibrate_options *opt, sl_lens_calibrate_result *res,
                            sl_error *err)
{
    memset(res, 0, sizeof *res);
    int n = opt->board_cols * opt->board_rows;
    if (opt->board_cols < 2 || opt->board_rows < 2 || n > 10000)
        return sl_error_set(err, SL_ERR_USAGE, "lens-calibrate: --board %dx%d: at least 2x2",
                            opt->board_cols, opt->board_rows);
    if (!(opt->sensor_width_mm > 0))
        return sl_error_set(err, SL_ERR_USAGE,
                            "lens-calibrate: the sensor width (--sensor-mm) is needed to turn "
                            "the focal length into pixels");
    if (count < 1)
        return sl_error_set(err, SL_ERR_USAGE, "lens-calibrate: no photos");
    res->photos = calloc((size_t)count, sizeof *res->photos);
    float *found_xy = malloc((size_t)n * 2 * sizeof *found_xy);
    double *all = malloc((size_t)count * n * 2 * sizeof *all);
    if (!res->photos || !found_xy || !all) {
        free(found_xy);
        free(all);
        return sl_error_set(err, SL_ERR_NOMEM, "lens-calibrate: out of memory");
    }
    res->photo_count = count;
    sl_result r = SL_OK;
    int width = 0, height = 0, found_count = 0;
    double focal_mm = opt->focal_mm;
    char camera[128] = "", lens_name[128] = "";
    const char *first_missing = NULL;
    for (int i = 0; i < count && !r; i++) {
        sl_lens_calibrate_photo *ph = &res->photos[i];
        snprintf(ph->name, sizeof ph->name, "%s", paths[i]);
        sl_meta meta;
        sl_meta_init(&meta);
        int w = 0, h = 0, found = 0;
        r = find_board(paths[i], opt, &meta, &w, &h, found_xy, &found, err);
        char cam[128];
        camera_name(&meta, cam, sizeof cam);
        if (!r && i == 0) {
            width = w;
            height = h;
        } else if (!r && (w != width || h != height)) {
            r = sl_error_set(err, SL_ERR_INPUT, "%s: %dx%d, but %s is %dx%d: one lens and size "
                             "per calibration", paths[i], w, h, paths[0], width, height);
        } else if (!r && cam[0] && camera[0] && strcasecmp(cam, camera) != 0) {
            r = sl_error_set(err, SL_ERR_INPUT, "%s: camera \"%s\", but another photo is from "
                             "\"%s\": one camera per calibration", paths[i], cam, camera);
        }
        if (!r && !camera[0]) /* the first photo that names its camera */
            snprintf(camera, sizeof camera, "%s", cam);
        if (!r && !lens_name[0])
            snprintf(lens_name, sizeof lens_name, "%s", meta.lens);
        if (!r && !(opt->focal_mm > 0) && meta.focal_length_mm > 0) {
            if (focal_mm > 0 && fabs(meta.focal_length_mm - focal_mm) > 1e-6 * focal_mm)
                r = sl_error_set(err, SL_ERR_INPUT, "%s: EXIF focal length %g mm, but another "
                                 "photo has %g mm: one lens per calibration", paths[i],
                                 meta.focal_length_mm, focal_mm);
            else
                focal_mm = meta.focal_length_mm;
        }
        sl_meta_free(&meta);
        if (r)
            break;
        ph->found = ph->used = found == 1;
        if (found == 1) {
            for (int k = 0; k < 2 * n; k++)
                all[(size_t)i * n * 2 + k] = found_xy[k] + 0.5; /* OpenCV's pixel centres */
            found_count++;
        } else {
            snprintf(ph->why, sizeof ph->why, "no %dx%d chessboard (inner corners) found",
                     opt->board_cols, opt->board_rows);
            if (!first_missing)
                first_missing = paths[i];
        }
    }
    free(found_xy);
    if (!r && !(focal_mm > 0))
        r = sl_error_set(err, SL_ERR_INPUT,
                         "%s: no focal length in EXIF (nor in any other photo): give the nominal "
                         "one with --focal-mm", paths[0]);
    if (!r && found_count < 3)
        r = sl_error_set(err, SL_ERR_INPUT,
                         "%s: only %d of %d photos show a %dx%d chessboard (inner corners); at "
                         "least 3 are needed",
                         first_missing ? first_missing : paths[0], found_count, count,
                         opt->board_cols, opt->board_rows);
    if (!r) {
        sl_lens_nominal(&res->nominal, opt->projection, width, height, focal_mm,
                        opt->sensor_width_mm);
        res->nominal_focal_mm = focal_mm;
        r = solve_used(all, count, n, opt, res, err);
    }
    free(all);
    if (r)
        return r;
    sl_lens_profile *p = &res->profile;
    snprintf(p->camera, sizeof p->camera, "%s", camera);
    snprintf(p->lens_name, sizeof p->lens_name, "%s", lens_name);
    p->source = SL_LENS_SOURCE_CHESSBOARD;
    p->images = res->used;
    res->focal_mm = p->lens.focal_px * opt->sensor_width_mm / width;
    return SL_OK;
}
