/* SPDX-License-Identifier: BSD-3-Clause */
/* Scoring a whole processed setup: which job made which file comes from
 * the process's job graph (OUT/jobs.json), what it should have been from
 * the capture's truth/. Every stage gets its numbers, its tolerances and a
 * verdict, and the run's cost from the process result. */
#include <jansson.h>
#include <libgen.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/render.h"
#include "vset_internal.h"

void sl_vset_score_options_init(sl_vset_score_options *o)
{
    memset(o, 0, sizeof *o);
    o->band_deg = SL_VSET_SCORE_BAND_DEG;
    o->truth_spp = 128;
    o->seed = 1;
}

void sl_vset_score_result_free(sl_vset_score_result *res)
{
    free(res->json);
    free(res->summary);
    res->json = res->summary = NULL;
}

typedef struct score_ctx {
    const sl_vset_score_options *o;
    json_t *cap, *cam, *probes, *graph, *jobs, *stages, *cost;
    sl_image truth;
    double rec709_from_camera[3][3];
    double calibrated_scale; /* calibrated lat-long / truth, for the rig */
    double white_gain[3];    /* the truth to the calibration's white, per channel */
    double white_scale;      /* calibrated lat-long / truth in that white */
    bool chart_white;        /* that white is the chart's light made white */
    json_t *grey_job;        /* the grey ball's merge: the photo calibrate ties the map to */
    sl_image stitch_error;   /* where the stitch is off, for the report */
    sl_image white_truth;    /* the truth in the calibration's white (empty: no calibration) */
    sl_report *rep;
    char summary[4096];
    int failed;
} score_ctx;

static json_t *load(const char *dir, const char *name, sl_error *err)
{
    char path[4400];
    snprintf(path, sizeof path, "%s/%s", dir, name);
    json_t *j = NULL;
    sl_json_load_file(path, "JSON", 0, &j, err);
    return j;
}

/* A JSON string, "" when absent. */
static const char *jstr(const json_t *j)
{
    const char *s = json_string_value(j);
    return s ? s : "";
}

/* The setup's job of this stage (and index, -1 for none). */
static json_t *job_of(score_ctx *c, const char *stage, int index)
{
    char id[512];
    if (index >= 0)
        snprintf(id, sizeof id, "%s/%s/%d", c->o->setup, stage, index);
    else
        snprintf(id, sizeof id, "%s/%s", c->o->setup, stage);
    size_t i;
    json_t *j;
    json_array_foreach(c->jobs, i, j) {
        const char *s = json_string_value(json_object_get(j, "id"));
        if (s && !strcmp(s, id))
            return j;
    }
    return NULL;
}


/* The value after `flag` in the job's command, or NULL. */
static const char *arg_of(json_t *job, const char *flag)
{
    json_t *cmd = json_object_get(job, "command");
    for (size_t i = 0; i + 1 < json_array_size(cmd); i++)
        if (!strcmp(jstr(json_array_get(cmd, i)), flag))
            return json_string_value(json_array_get(cmd, i + 1));
    return NULL;
}

static void json_vec3_get(json_t *a, double v[3])
{
    for (int c = 0; c < 3; c++)
        v[c] = json_number_value(json_array_get(a, (size_t)c));
}

/* A merge job's image (clipped false) or its clipped mask. */
static const char *merge_output(json_t *job, bool clipped)
{
    size_t i;
    json_t *p;
    json_array_foreach(json_object_get(job, "outputs"), i, p) {
        const char *s = json_string_value(p);
        size_t n = s ? strlen(s) : 0;
        bool is_mask = n > 12 && !strcmp(s + n - 12, "_clipped.exr");
        if (n > 4 && !strcmp(s + n - 4, ".exr") && is_mask == clipped)
            return s;
    }
    return NULL;
}

static sl_result read_exr(const char *path, sl_image *img, sl_error *err)
{
    if (!path)
        return sl_error_set(err, SL_ERR_INPUT, "score: a job of the graph declares no such output");
    sl_meta meta;
    sl_result r = sl_exr_read(path, img, &meta, err);
    sl_meta_free(&meta);
    return r;
}

/* Per-stage cost from the process result's jobs. */
static void stage_cost(score_ctx *c, const char *stage, double *seconds, double *cpu, int *ran)
{
    *seconds = *cpu = 0;
    *ran = 0;
    json_t *jobs = json_object_get(json_array_get(json_object_get(c->cost, "setups"), 0), "jobs");
    size_t i;
    json_t *j;
    json_array_foreach(jobs, i, j) {
        if (strcmp(jstr(json_object_get(j, "stage")), stage))
            continue;
        *seconds += json_number_value(json_object_get(j, "seconds"));
        *cpu += json_number_value(json_object_get(j, "cpu_seconds"));
        *ran += !strcmp(jstr(json_object_get(j, "status")), "ran");
    }
}

/* Appends a stage: its numbers, tolerances, verdict and cost (steals the
 * two objects); one line of the summary. */
static void add_stage(score_ctx *c, const char *name, bool pass, json_t *numbers, json_t *tol,
                      const char *line)
{
    double secs, cpu;
    int ran;
    stage_cost(c, name, &secs, &cpu, &ran);
    if (!strcmp(name, "simulate")) {
        secs = c->o->simulate_seconds;
        cpu = c->o->simulate_cpu_seconds;
    }
    /* seconds are the jobs' as their stamps recorded them; jobs_ran says
     * how many ran in this run (the others were up to date) */
    json_array_append_new(c->stages,
                          json_pack("{s:s, s:b, s:o, s:o, s:f, s:f, s:i}", "name", name, "pass",
                                    pass, "numbers", numbers, "tolerances", tol, "seconds", secs,
                                    "cpu_seconds", cpu, "jobs_ran", ran));
    c->failed += !pass;
    size_t used = strlen(c->summary);
    snprintf(c->summary + used, sizeof c->summary - used, "%-9s %s  %s (%.1f s, %.1f CPU s)\n",
             name, pass ? "pass" : "FAIL", line, secs, cpu);
    if (c->rep) {
        char s[2][64];
        snprintf(s[0], 64, "%.1f", secs);
        snprintf(s[1], 64, "%.1f", cpu);
        const char *cells[5] = {name, pass ? "pass" : "FAIL", line, s[0], s[1]};
        sl_report_table_row(c->rep, cells);
    }
}

static json_t *image_score_json(const sl_vset_image_score *s)
{
    return json_pack("{s:f, s:f, s:f, s:f, s:I}", "scale", s->scale, "median_rel_error",
                     s->median, "p95_rel_error", s->p95, "power_ratio", s->power, "pixels",
                     (json_int_t)s->pixels);
}

/* A file of a shot: the shot's name, or its name and a suffix after '_'
 * (the virtual set writes IMG_0001.jpg, IMG_0001.tif, IMG_0001_linear.tif). */
static bool is_file_of_shot(const char *stem, const char *shot)
{
    size_t n = strlen(shot);
    return n && !strncmp(stem, shot, n) && (stem[n] == 0 || stem[n] == '_');
}

/* Where a frame came from: its session.json names the capture's file, the
 * capture's plan its view (>= 0) or probe kind. */
static sl_result frame_origin(score_ctx *c, const char *frame, int *view, char *kind, size_t n,
                              sl_error *err)
{
    char dir[4096], base[1024];
    snprintf(dir, sizeof dir, "%s", frame);
    snprintf(base, sizeof base, "%s", strrchr(frame, '/') ? strrchr(frame, '/') + 1 : frame);
    char *slash = strrchr(dir, '/');
    if (slash)
        *slash = 0;
    json_t *ses = load(slash ? dir : ".", "session.json", err);
    if (!ses)
        return err->code;
    const char *source = NULL;
    size_t i, k, f;
    json_t *v, *b, *fr;
    json_array_foreach(json_object_get(ses, "views"), i, v)
        json_array_foreach(json_object_get(v, "brackets"), k, b)
            json_array_foreach(json_object_get(b, "frames"), f, fr)
                if (!strcmp(jstr(json_object_get(fr, "file")), base))
                    source = json_string_value(json_object_get(fr, "source"));
    char name[1024] = "";
    if (source) {
        snprintf(name, sizeof name, "%s", source);
        char *dot = strrchr(name, '.');
        if (dot)
            *dot = 0;
    }
    json_decref(ses);
    *view = -1;
    kind[0] = 0;
    json_array_foreach(json_object_get(c->cap, "frames"), i, fr)
        if (is_file_of_shot(name, jstr(json_object_get(fr, "name"))))
            *view = (int)json_integer_value(json_object_get(fr, "view"));
    json_array_foreach(json_object_get(c->cap, "probes"), i, v)
        json_array_foreach(json_object_get(v, "frames"), k, fr)
            if (is_file_of_shot(name, jstr(json_object_get(fr, "name"))))
                snprintf(kind, n, "%s", jstr(json_object_get(v, "kind")));
    if (*view < 0 && !kind[0])
        return sl_error_set(err, SL_ERR_INPUT, "%s: not a frame of the capture %s", frame,
                            c->o->capture);
    return SL_OK;
}

/* The truth a merge should give: the view through the true lens and head,
 * or the probe's render at the sensor. */
static sl_result merge_truth(score_ctx *c, int view, const char *kind, sl_image *out,
                             sl_error *err)
{
    if (kind[0]) {
        char path[4400];
        snprintf(path, sizeof path, "%s/truth/probe_%s.exr", c->o->capture, kind);
        return read_exr(path, out, err);
    }
    json_t *lj = json_object_get(c->cam, "lens"), *vj = json_array_get(json_object_get(c->cam, "views"), (size_t)view);
    int proj = sl_lens_projection_from_name(jstr(json_object_get(lj, "projection")));
    if (proj < 0 || !vj)
        return sl_error_set(err, SL_ERR_INPUT, "%s/truth/camera.json: no lens or view %d",
                            c->o->capture, view);
    sl_lens lens;
    memset(&lens, 0, sizeof lens);
    lens.projection = (sl_lens_projection)proj;
    lens.width = (int)json_integer_value(json_object_get(lj, "width"));
    lens.height = (int)json_integer_value(json_object_get(lj, "height"));
    lens.focal_px = json_number_value(json_object_get(lj, "focal_px"));
    lens.cx = json_number_value(json_object_get(lj, "cx"));
    lens.cy = json_number_value(json_object_get(lj, "cy"));
    json_vec3_get(json_object_get(lj, "k"), lens.k);
    json_vec3_get(json_object_get(lj, "vignette"), lens.vignette);
    lens.max_theta_deg = json_number_value(json_object_get(lj, "max_theta_deg"));
    lens.circle_radius_px = json_number_value(json_object_get(lj, "circle_radius_px"));
    sl_view_pose pose = {json_number_value(json_object_get(vj, "yaw_deg")),
                         json_number_value(json_object_get(vj, "pitch_deg")),
                         json_number_value(json_object_get(vj, "roll_deg"))};
    return sl_vset_view_image(&lens, &pose, &c->truth, 2, out, err);
}

/* Each view's and probe's merge against what its frames saw, up to the
 * one free scale of a merge without absolute units. */
static sl_result score_merge(score_ctx *c, sl_error *err)
{
    json_t *list = json_array();
    double worst = 0, lo = 0, hi = 0;
    sl_result r = SL_OK;
    int count = 0, views = 0;
    for (int i = 0; !r; i++) {
        json_t *job = job_of(c, "merge", i);
        if (!job)
            break;
        const char *frame = json_string_value(json_array_get(json_object_get(job, "inputs"), 0));
        int view = -1;
        char kind[32] = "";
        sl_image merged = {0}, clipped = {0}, truth = {0};
        sl_vset_image_score s;
        if (!frame)
            r = sl_error_set(err, SL_ERR_INPUT, "%s: merge job %d has no frames", c->o->jobs_json,
                             i);
        if (!r)
            r = frame_origin(c, frame, &view, kind, sizeof kind, err);
        if (!r)
            r = read_exr(merge_output(job, false), &merged, err);
        if (!r)
            r = read_exr(merge_output(job, true), &clipped, err);
        if (!r)
            r = merge_truth(c, view, kind, &truth, err);
        if (!r)
            r = sl_vset_score_image(&merged, (const double(*)[3])c->rec709_from_camera, &truth,
                                    &clipped, &s, err);
        if (!r) {
            char what[48];
            if (kind[0])
                snprintf(what, sizeof what, "%s", kind);
            else
                snprintf(what, sizeof what, "view %d", view);
            json_t *j = image_score_json(&s);
            json_object_set_new(j, "job", json_string(json_string_value(json_object_get(job, "id"))));
            json_object_set_new(j, "what", json_string(what));
            json_array_append_new(list, j);
            worst = fmax(worst, s.median);
            if (!strcmp(kind, "grey"))
                c->grey_job = job;
            if (!kind[0] && s.scale > 0) {
                lo = views++ ? fmin(lo, s.scale) : s.scale;
                hi = fmax(hi, s.scale);
            }
            count++;
        }
        sl_image_free(&merged);
        sl_image_free(&clipped);
        sl_image_free(&truth);
    }
    if (r) {
        json_decref(list);
        return r;
    }
    double spread = lo > 0 ? hi / lo : 0;
    bool pass = count > 0 && worst <= SL_VSET_TOL_MERGE_MEDIAN &&
                (views < 2 || spread <= SL_VSET_TOL_MERGE_SCALE_SPREAD);
    char line[256];
    snprintf(line, sizeof line, "%d merges against the truth radiance: worst median error %.1f%%; "
             "the fisheye views' scales %.3gx apart", count, 100 * worst, spread);
    add_stage(c, "merge", pass,
              json_pack("{s:i, s:f, s:f, s:o}", "merges", count, "worst_median_rel_error", worst,
                        "view_scale_spread", spread, "images", list),
              json_pack("{s:f, s:f}", "median_rel_error", SL_VSET_TOL_MERGE_MEDIAN,
                        "view_scale_spread", SL_VSET_TOL_MERGE_SCALE_SPREAD),
              line);
    return SL_OK;
}

static bool latlong_ok(const sl_vset_image_score *s)
{
    return s->pixels > 0 && s->median <= SL_VSET_TOL_LATLONG_MEDIAN &&
           s->p95 <= SL_VSET_TOL_LATLONG_P95 && fabs(s->power - 1) <= SL_VSET_TOL_POWER;
}

static json_t *latlong_tolerances(void)
{
    return json_pack("{s:f, s:f, s:f}", "median_rel_error", SL_VSET_TOL_LATLONG_MEDIAN,
                     "p95_rel_error", SL_VSET_TOL_LATLONG_P95, "power_ratio_off",
                     SL_VSET_TOL_POWER);
}

#define FAR_OFF_BANDS 8 /* bands of latitude over the scored band (15 degrees each for 60) */

/* Where the stitch is off: per texel of the band |test / (scale truth) - 1|
 * capped at 1 (white: off by its own value or more; black outside the
 * band), and per eighth of the band's latitudes the share of texels off
 * by more than their own value (what sets the p95). */
static sl_result stitch_error_map(score_ctx *c, const sl_image *test, double scale,
                                  double far_off[FAR_OFF_BANDS], sl_image *map, sl_error *err)
{
    sl_result r = sl_image_alloc(map, test->width, test->height, 3, err);
    if (r)
        return r;
    double count[FAR_OFF_BANDS] = {0}, band = c->o->band_deg, step = 2 * band / FAR_OFF_BANDS;
    for (int k = 0; k < FAR_OFF_BANDS; k++)
        far_off[k] = 0;
    for (int y = 0; y < test->height; y++) {
        double v = (y + 0.5) / test->height, lat = 90 - 180 * v;
        for (int x = 0; x < test->width; x++) {
            const float *p = sl_image_pixel(test, x, y);
            float t[4], *o = sl_image_pixel(map, x, y);
            sl_latlong_lookup(&c->truth, (x + 0.5) / test->width, v, t);
            double in[3] = {p[0], p[1], p[2]}, rec[3];
            sl_mat3_apply((const double(*)[3])c->rec709_from_camera, in, rec);
            double b = scale * sl_luminance_px(t);
            if (fabs(lat) > band || (test->channels == 4 && !(p[3] > 0)) || !(b > VSET_SCORE_DARK))
                continue;
            double e = fabs(sl_luminance(rec) / b - 1);
            o[0] = o[1] = o[2] = (float)fmin(e, 1);
            int k = (int)fmin(FAR_OFF_BANDS - 1, floor((lat + band) / step));
            count[k]++;
            far_off[k] += e > 1;
        }
    }
    for (int k = 0; k < FAR_OFF_BANDS; k++)
        far_off[k] = count[k] > 0 ? far_off[k] / count[k] : 0;
    return SL_OK;
}

/* The stitched lat-long (camera RGB) against the truth, and where it is off. */
static sl_result score_stitch(score_ctx *c, sl_image *stitched, double *scale, sl_error *err)
{
    json_t *job = job_of(c, "stitch", -1);
    sl_vset_image_score s;
    double far_off[FAR_OFF_BANDS];
    sl_result r = read_exr(job ? sl_json_string_ending(json_object_get(job, "outputs"), "/hdri.exr") : NULL, stitched, err);
    if (!r)
        r = sl_vset_score_latlong(stitched, (const double(*)[3])c->rec709_from_camera, &c->truth,
                                  c->o->band_deg, NULL, &s, err);
    if (!r)
        r = stitch_error_map(c, stitched, s.scale, far_off, &c->stitch_error, err);
    if (r)
        return r;
    *scale = s.scale;
    char line[256];
    snprintf(line, sizeof line, "lat-long within %.0f deg of the horizon: median %.1f%%, p95 "
             "%.1f%%, power %.3f of the truth's (after the scale %.4g)", c->o->band_deg,
             100 * s.median, 100 * s.p95, s.power, s.scale);
    json_t *n = image_score_json(&s), *share = json_array();
    for (int k = 0; k < FAR_OFF_BANDS; k++)
        json_array_append_new(share, json_real(far_off[k]));
    json_object_set_new(n, "far_off_by_latitude",
                        json_pack("{s:f, s:f, s:o}", "from_deg", -c->o->band_deg, "step_deg",
                                  2 * c->o->band_deg / FAR_OFF_BANDS, "share", share));
    add_stage(c, "stitch", latlong_ok(&s), n, latlong_tolerances(), line);
    return SL_OK;
}

/* The chrome ball's unwrap against the truth over the half of the set
 * facing the probe camera (what a ball shows well), and against the stitch
 * there: the cross-check the process makes, scored. */
static sl_result score_unwrap(score_ctx *c, const sl_image *stitched, sl_error *err)
{
    json_t *job = job_of(c, "unwrap", -1);
    if (!job)
        return SL_OK; /* no chrome ball shot */
    json_t *probe = NULL;
    size_t i;
    json_t *p;
    json_array_foreach(json_object_get(c->probes, "probes"), i, p)
        if (!strcmp(jstr(json_object_get(p, "kind")), "chrome"))
            probe = p;
    if (!probe)
        return sl_error_set(err, SL_ERR_INPUT, "%s/truth/probes.json: no chrome ball",
                            c->o->capture);
    double fwd[3], toward[3];
    json_vec3_get(json_object_get(json_object_get(probe, "camera"), "forward"), fwd);
    for (int k = 0; k < 3; k++)
        toward[k] = -fwd[k];
    sl_image ball = {0};
    sl_vset_image_score s, x;
    sl_result r = read_exr(sl_json_string_ending(json_object_get(job, "outputs"), "/chrome.exr"), &ball, err);
    if (!r)
        r = sl_vset_score_latlong(&ball, (const double(*)[3])c->rec709_from_camera, &c->truth,
                                  c->o->band_deg, toward, &s, err);
    if (!r)
        r = sl_vset_score_latlong(&ball, NULL, stitched, c->o->band_deg, toward, &x, err);
    sl_image_free(&ball);
    if (r)
        return r;
    bool pass = s.pixels > 0 && s.median <= SL_VSET_TOL_UNWRAP_MEDIAN;
    char line[256];
    snprintf(line, sizeof line, "chrome ball, half facing the camera: median %.1f%% against the "
             "truth (tolerance %.0f%%), %.1f%% against the stitch", 100 * s.median,
             100 * SL_VSET_TOL_UNWRAP_MEDIAN, 100 * x.median);
    json_t *n = image_score_json(&s);
    json_object_set_new(n, "vs_stitch", image_score_json(&x));
    add_stage(c, "unwrap", pass, n, json_pack("{s:f}", "median_rel_error", SL_VSET_TOL_UNWRAP_MEDIAN),
              line);
    return SL_OK;
}

/* Median over the band of each channel's share of luminance, calibrated
 * over truth: 1, 1, 1 when the calibration's colour is right. */
static void channel_balance(const sl_image *test, const sl_image *truth, double band_deg,
                            double *work, double out[3])
{
    for (int ch = 0; ch < 3; ch++) {
        size_t n = 0;
        for (int y = 0; y < test->height; y++) {
            double v = (y + 0.5) / test->height;
            if (fabs(90 - 180 * v) > band_deg)
                continue;
            for (int x = 0; x < test->width; x++) {
                const float *p = sl_image_pixel(test, x, y);
                float t[4];
                sl_latlong_lookup(truth, (x + 0.5) / test->width, v, t);
                double a = sl_luminance_px(p), b = sl_luminance_px(t);
                if (a > VSET_SCORE_DARK && b > VSET_SCORE_DARK && t[ch] > VSET_SCORE_DARK)
                    work[n++] = (p[ch] / a) / (t[ch] / b);
            }
        }
        qsort(work, n, sizeof *work, sl_cmp_double);
        out[ch] = n ? work[n / 2] : 0;
    }
}

/* In place: every pixel's channels times `gain`. */
static void scale_channels(sl_image *img, const double gain[3])
{
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            float *p = sl_image_pixel(img, x, y);
            for (int ch = 0; ch < 3; ch++)
                p[ch] = (float)(p[ch] * gain[ch]);
        }
}

/* The white a chart fit balances to: fitting the chart's photo to the
 * reference reflectances (given for a white light) makes the light on the
 * chart white at its luminance. So the truth a chart-calibrated map should
 * match is the truth with that light made white: per channel times
 * Y(E) / E, E the chart's irradiance. Without a chart the gains are 1. */
static sl_result chart_white(score_ctx *c, bool chart_used, double light[3], double gain[3],
                             sl_error *err)
{
    for (int ch = 0; ch < 3; ch++)
        light[ch] = gain[ch] = 1;
    if (!chart_used)
        return SL_OK;
    json_t *probe = NULL, *p;
    size_t i;
    json_array_foreach(json_object_get(c->probes, "probes"), i, p)
        if (!strcmp(jstr(json_object_get(p, "kind")), "chart"))
            probe = p;
    double fwd[3], n[3], e[3] = {0, 0, 0};
    json_vec3_get(json_object_get(json_object_get(probe, "camera"), "forward"), fwd);
    for (int k = 0; k < 3; k++)
        n[k] = -fwd[k]; /* the chart faces its camera */
    if (probe)
        sl_vset_irradiance(&c->truth, n, e);
    double y = sl_luminance(e);
    if (!(y > 0) || !(e[0] > 0) || !(e[1] > 0) || !(e[2] > 0))
        return sl_error_set(err, SL_ERR_INPUT, "%s/truth/probes.json: no chart lit by the set "
                            "(its irradiance %g %g %g)", c->o->capture, e[0], e[1], e[2]);
    for (int ch = 0; ch < 3; ch++) {
        light[ch] = e[ch] / y;
        gain[ch] = y / e[ch];
    }
    return SL_OK;
}

/* The grey ball's photo as calibrate reads it (through the plate matrix
 * when a chart was used) against its radiance at the sensor in the
 * calibration's white: the units the calibration ties the map to. */
static sl_result grey_photo_scale(score_ctx *c, json_t *plate, const double gain[3],
                                  double *scale, sl_error *err)
{
    *scale = 0;
    if (!c->grey_job)
        return SL_OK;
    double m[3][3];
    for (int i = 0; i < 3; i++)
        json_vec3_get(json_array_get(plate, (size_t)i), m[i]);
    sl_image photo = {0}, clipped = {0}, truth = {0};
    sl_vset_image_score s;
    sl_result r = read_exr(merge_output(c->grey_job, false), &photo, err);
    if (!r)
        r = read_exr(merge_output(c->grey_job, true), &clipped, err);
    if (!r)
        r = merge_truth(c, -1, "grey", &truth, err);
    if (!r) {
        scale_channels(&truth, gain);
        r = sl_vset_score_image(&photo, json_is_array(plate) ? (const double(*)[3])m : NULL,
                                &truth, &clipped, &s, err);
    }
    if (!r)
        *scale = s.scale;
    sl_image_free(&photo);
    sl_image_free(&clipped);
    sl_image_free(&truth);
    return r;
}

/* The calibrated lat-long against the truth in the white the calibration
 * balanced to, and its scale and colour: the channel balance (and the same
 * against the physical radiance), the scale against the grey ball's photo
 * read the same way. */
static sl_result score_calibrate(score_ctx *c, sl_error *err)
{
    json_t *job = job_of(c, "calibrate", -1);
    if (!job)
        return SL_OK;
    sl_image cal = {0}, white_truth = {0};
    sl_vset_image_score s, radiance;
    json_t *res = NULL;
    double *work = NULL, balance[3], balance_radiance[3], light[3], gain[3], grey_scale = 0;
    const char *rpath = sl_json_string_ending(json_object_get(job, "outputs"), "calibrate.result.json");
    sl_result r = rpath ? sl_json_load_file(rpath, "calibrate result", 0, &res, err)
                        : sl_error_set(err, SL_ERR_INPUT, "%s: the calibrate job has no result",
                                       c->o->jobs_json);
    json_t *plate = json_object_get(res, "plate_matrix");
    bool chart_used = json_is_true(json_object_get(json_object_get(res, "chart"), "used"));
    if (!r)
        r = chart_white(c, chart_used, light, gain, err);
    if (!r)
        r = sl_image_copy(&c->truth, &white_truth, err);
    if (!r) {
        scale_channels(&white_truth, gain);
        r = read_exr(sl_json_string_ending(json_object_get(job, "outputs"), "/hdri.exr"), &cal, err);
    }
    if (!r)
        r = sl_vset_score_latlong(&cal, NULL, &white_truth, c->o->band_deg, NULL, &s, err);
    if (!r)
        r = sl_vset_score_latlong(&cal, NULL, &c->truth, c->o->band_deg, NULL, &radiance, err);
    if (!r)
        r = grey_photo_scale(c, plate, gain, &grey_scale, err);
    if (!r && !(work = malloc(sizeof *work * (size_t)cal.width * cal.height)))
        r = sl_error_set(err, SL_ERR_NOMEM, "score: out of memory");
    if (!r) {
        channel_balance(&cal, &white_truth, c->o->band_deg, work, balance);
        channel_balance(&cal, &c->truth, c->o->band_deg, work, balance_radiance);
    }
    free(work);
    sl_image_free(&cal);
    if (r) {
        sl_image_free(&white_truth);
        json_decref(res);
        return r;
    }
    /* the validation renders and the rig are made from the calibrated map */
    c->white_truth = white_truth;
    c->calibrated_scale = radiance.scale;
    c->white_scale = s.scale;
    memcpy(c->white_gain, gain, sizeof c->white_gain);
    c->chart_white = chart_used;
    const char *units = jstr(json_object_get(res, "units"));
    bool absolute = strcmp(units, "relative") != 0;
    double applied = json_number_value(json_object_get(res, "scale"));
    double worst_balance = 0;
    for (int k = 0; k < 3; k++)
        worst_balance = fmax(worst_balance, fabs(balance[k] - 1));
    /* In relative units (no ISO in the files) the calibration ties the map
     * to the grey ball's photo: the map over the truth should be that
     * photo, read as calibrate reads it, over its truth. In cd/m2 it should
     * be 1. */
    double vs_grey = grey_scale > 0 ? s.scale / grey_scale : 0;
    bool pass = latlong_ok(&s) && worst_balance <= SL_VSET_TOL_BALANCE &&
                (!absolute || fabs(s.scale - 1) <= SL_VSET_TOL_ABSOLUTE) &&
                (grey_scale <= 0 || fabs(vs_grey - 1) <= SL_VSET_TOL_EXPOSURE);
    json_t *n = image_score_json(&s);
    json_t *grey = json_object_get(res, "grey");
    json_object_set_new(n, "units", json_string(units));
    json_object_set_new(n, "white", json_string(chart_used ? "chart" : "radiance"));
    json_object_set_new(n, "chart_light", json_pack("[f,f,f]", light[0], light[1], light[2]));
    json_object_set_new(n, "scale_applied", json_real(applied));
    json_object_set_new(n, "scale_truth", json_real(s.scale > 0 ? applied / s.scale : 0));
    json_object_set_new(n, "exposure_vs_grey", json_real(vs_grey));
    json_object_set_new(n, "channel_balance", json_pack("[f,f,f]", balance[0], balance[1], balance[2]));
    json_object_set_new(n, "vs_radiance", image_score_json(&radiance));
    json_object_set_new(json_object_get(n, "vs_radiance"), "channel_balance",
                        json_pack("[f,f,f]", balance_radiance[0], balance_radiance[1],
                                  balance_radiance[2]));
    json_object_set_new(n, "grey_gain", json_deep_copy(json_object_get(grey, "gain")));
    json_t *tol = latlong_tolerances();
    json_object_set_new(tol, "channel_balance_off", json_real(SL_VSET_TOL_BALANCE));
    json_object_set_new(tol, "absolute_scale_off", json_real(SL_VSET_TOL_ABSOLUTE));
    json_object_set_new(tol, "exposure_vs_grey_off", json_real(SL_VSET_TOL_EXPOSURE));
    char line[400];
    snprintf(line, sizeof line, "calibrated lat-long against the truth in the %s white: median "
             "%.1f%%, p95 %.1f%%, power %.3f; exposure %.3f of the grey ball's (%s units); "
             "channel balance %.3f %.3f %.3f", chart_used ? "chart's" : "radiance's",
             100 * s.median, 100 * s.p95, s.power, vs_grey, units, balance[0], balance[1],
             balance[2]);
    add_stage(c, "calibrate", pass, n, tol, line);
    json_decref(res);
    return SL_OK;
}

static sl_result score_rig(score_ctx *c, double stitched_scale, sl_error *err)
{
    json_t *job = job_of(c, "rig", -1);
    if (!job)
        return SL_OK;
    char lights[4400];
    snprintf(lights, sizeof lights, "%s/truth/lights.json", c->o->capture);
    /* The rig is made from the calibrated lat-long when there is one: its
     * lights are the lamps in the calibration's white, as the calibrate and
     * render scores compare; the physical lamps beside it (vs_radiance). */
    bool calibrated = job_of(c, "calibrate", -1) != NULL;
    sl_vset_rig_score s, radiance;
    const char *rig = sl_json_string_ending(json_object_get(job, "outputs"), "/rig.json");
    if (!rig)
        return sl_error_set(err, SL_ERR_INPUT, "%s: the rig job has no rig.json", c->o->jobs_json);
    sl_result r = sl_vset_score_rig(rig, lights, calibrated ? c->white_scale : stitched_scale,
                                    calibrated ? c->white_gain : NULL, SL_VSET_SCORE_MATCH_DEG, &s,
                                    err);
    if (!r)
        r = sl_vset_score_rig(rig, lights, calibrated ? c->calibrated_scale : stitched_scale, NULL,
                              SL_VSET_SCORE_MATCH_DEG, &radiance, err);
    if (r)
        return r;
    bool pass = s.matched >= SL_VSET_TOL_RIG_MATCHED * s.truth_lights &&
                s.direction_worst_deg <= SL_VSET_TOL_RIG_DIRECTION_DEG &&
                fabs(s.power_median - 1) <= SL_VSET_TOL_RIG_POWER;
    bool chart_white = calibrated && c->chart_white;
    char line[300];
    snprintf(line, sizeof line, "%d rig lights; %d of %d true lamps matched, direction off by "
             "%.2f deg at worst; power %.3f of the truth's in the %s white (median; %.3f of the "
             "physical lamps')", s.rig_lights, s.matched, s.truth_lights, s.direction_worst_deg,
             s.power_median, chart_white ? "chart's" : "radiance's", radiance.power_median);
    add_stage(c, "rig", pass,
              json_pack("{s:i, s:i, s:i, s:f, s:f, s:f, s:f, s:s, s:{s:f, s:f}}", "rig_lights",
                        s.rig_lights, "truth_lights", s.truth_lights, "matched", s.matched,
                        "direction_mean_deg", s.direction_mean_deg, "direction_worst_deg",
                        s.direction_worst_deg, "power_median", s.power_median, "power_worst",
                        s.power_worst, "white", chart_white ? "chart" : "radiance",
                        "vs_radiance", "power_median", radiance.power_median, "power_worst",
                        radiance.power_worst),
              json_pack("{s:f, s:f, s:f, s:f}", "matched_fraction", SL_VSET_TOL_RIG_MATCHED,
                        "direction_deg", SL_VSET_TOL_RIG_DIRECTION_DEG, "power_off",
                        SL_VSET_TOL_RIG_POWER, "match_within_deg", SL_VSET_SCORE_MATCH_DEG),
              line);
    return SL_OK;
}

/* A validation scene rendered under the truth lat-long (in the
 * calibration's white, as the map the process rendered from), at the
 * process render's size. */
static sl_result truth_render(score_ctx *c, const char *scene_name, int width, sl_image *out,
                              sl_error *err)
{
    sl_scene scene;
    sl_scene_init(&scene);
    sl_render_options ro;
    sl_render_options_init(&ro);
    ro.spp = c->o->truth_spp;
    ro.seed = c->o->seed;
    sl_render_stats st;
    memset(&st, 0, sizeof st);
    sl_result r = sl_scene_preset(&scene, scene_name, width, err);
    if (!r)
        r = sl_scene_set_dome(&scene, c->white_truth.data ? &c->white_truth : &c->truth, 0, 1,
                              "truth/latlong.exr", err);
    if (!r)
        r = sl_render(&scene, &ro, out, &st, err);
    sl_render_stats_free(&st);
    sl_scene_free(&scene);
    return r;
}

/* Relative RMSE over RGB of test / s against truth, s the ratio of their
 * luminance sums (the free scale of relative units). */
static double scaled_rel_rmse(const sl_image *test, const sl_image *truth, double *scale)
{
    double st = 0, sr = 0;
    for (int y = 0; y < test->height; y++)
        for (int x = 0; x < test->width; x++) {
            st += sl_luminance_px(sl_image_pixel(test, x, y));
            sr += sl_luminance_px(sl_image_pixel(truth, x, y));
        }
    *scale = sr > 0 ? st / sr : 0;
    double e = 0, b = 0, s = *scale > 0 ? *scale : 1;
    for (int y = 0; y < test->height; y++)
        for (int x = 0; x < test->width; x++) {
            const float *p = sl_image_pixel(test, x, y), *q = sl_image_pixel(truth, x, y);
            for (int k = 0; k < 3; k++) {
                e += (p[k] / s - q[k]) * (p[k] / s - q[k]);
                b += (double)q[k] * q[k];
            }
        }
    return b > 0 ? sqrt(e / b) : 0;
}

/* Each validation render (under the lat-long and under the rig) against
 * the same scene rendered under the truth. */
static sl_result score_render(score_ctx *c, sl_error *err)
{
    json_t *list = json_array();
    double worst = 0, worst_chrome = 0, worst_diffuse = 0; /* worst: error / tolerance */
    int count = 0;
    sl_result r = SL_OK;
    /* the truth's render of each scene, shared by the map's and the rig's */
    enum { MAX_SCENES = 8 };
    char seen[MAX_SCENES][80];
    sl_image truths[MAX_SCENES];
    memset(truths, 0, sizeof truths);
    int scenes = 0;
    for (int i = 0; !r; i++) {
        json_t *job = job_of(c, "render", i);
        if (!job)
            break;
        const char *scene = arg_of(job, "--scene"), *width = arg_of(job, "--width");
        const char *out = arg_of(job, "-o");
        bool rig = arg_of(job, "--rig") != NULL;
        sl_image test = {0}, *truth = NULL;
        if (!scene || !width || !out)
            r = sl_error_set(err, SL_ERR_INPUT, "%s: render job %d lacks --scene, --width or -o",
                             c->o->jobs_json, i);
        if (!r)
            r = read_exr(out, &test, err);
        char key[80];
        snprintf(key, sizeof key, "%s %s", scene ? scene : "", width ? width : "");
        for (int k = 0; !r && k < scenes && !truth; k++)
            if (!strcmp(seen[k], key))
                truth = &truths[k];
        if (!r && !truth && scenes == MAX_SCENES)
            r = sl_error_set(err, SL_ERR_INPUT, "%s: more than %d render scenes", c->o->jobs_json,
                             MAX_SCENES);
        if (!r && !truth) {
            snprintf(seen[scenes], sizeof seen[scenes], "%s", key);
            truth = &truths[scenes++];
            r = truth_render(c, scene, atoi(width), truth, err);
        }
        if (!r && (truth->width != test.width || truth->height != test.height))
            r = sl_error_set(err, SL_ERR_INPUT, "%s: %dx%d, the scene at width %s is %dx%d", out,
                             test.width, test.height, width, truth->width, truth->height);
        if (!r) {
            double scale, e = scaled_rel_rmse(&test, truth, &scale);
            bool chrome = !strcmp(scene, "chrome");
            double tol = chrome ? SL_VSET_TOL_RENDER_CHROME_RMSE : SL_VSET_TOL_RENDER_RMSE;
            json_array_append_new(list, json_pack("{s:s, s:s, s:f, s:f, s:b}", "scene", scene,
                                                  "light", rig ? "rig" : "latlong", "rel_rmse", e,
                                                  "scale", scale, "pass", e <= tol));
            worst = fmax(worst, e / tol);
            if (chrome)
                worst_chrome = fmax(worst_chrome, e);
            else
                worst_diffuse = fmax(worst_diffuse, e);
            count++;
        }
        sl_image_free(&test);
    }
    for (int k = 0; k < scenes; k++)
        sl_image_free(&truths[k]);
    if (r) {
        json_decref(list);
        return r;
    }
    if (count == 0) {
        json_decref(list);
        return SL_OK;
    }
    char line[256];
    snprintf(line, sizeof line, "%d renders against the truth's (%lld spp): worst relative RMSE "
             "%.1f%% (grey, chart), %.1f%% (chrome)", count, (long long)c->o->truth_spp,
             100 * worst_diffuse, 100 * worst_chrome);
    add_stage(c, "render", worst <= 1,
              json_pack("{s:i, s:f, s:f, s:o}", "renders", count, "worst_rel_rmse", worst_diffuse,
                        "worst_chrome_rel_rmse", worst_chrome, "images", list),
              json_pack("{s:f, s:f}", "rel_rmse", SL_VSET_TOL_RENDER_RMSE, "chrome_rel_rmse",
                        SL_VSET_TOL_RENDER_CHROME_RMSE),
              line);
    return SL_OK;
}

static sl_result load_camera(score_ctx *c, sl_error *err)
{
    double m[3][3];
    json_t *rows = json_object_get(c->cam, "output_from_rec709");
    for (int i = 0; i < 3; i++)
        json_vec3_get(json_array_get(rows, (size_t)i), m[i]);
    if (!sl_mat3_invert(m, c->rec709_from_camera))
        return sl_error_set(err, SL_ERR_INPUT, "%s/truth/camera.json: no invertible "
                            "output_from_rec709", c->o->capture);
    return SL_OK;
}

sl_result sl_vset_score_setup(const sl_vset_score_options *o, sl_vset_score_result *res,
                              sl_error *err)
{
    memset(res, 0, sizeof *res);
    double t0 = sl_seconds(), c0 = sl_cpu_seconds();
    score_ctx c;
    memset(&c, 0, sizeof c);
    c.o = o;
    sl_image stitched = {0};
    sl_result r = SL_OK;
    char path[4400];
    if (!(c.cap = load(o->capture, "capture.json", err)) ||
        !(c.cam = load(o->capture, "truth/camera.json", err)) ||
        !(c.probes = load(o->capture, "truth/probes.json", err))) {
        r = err->code;
        goto done;
    }
    if ((r = sl_json_load_file(o->jobs_json, "job graph", 0, &c.graph, err)))
        goto done;
    c.jobs = json_object_get(c.graph, "jobs");
    if (o->process_json)
        c.cost = json_loads(o->process_json, 0, NULL);
    snprintf(path, sizeof path, "%s/truth/latlong.exr", o->capture);
    if ((r = read_exr(path, &c.truth, err)) || (r = load_camera(&c, err)))
        goto done;
    c.stages = json_array();
    if (o->report_dir) {
        if ((r = sl_report_new(&c.rep, o->report_dir, "report", "setlight demo: the virtual stage",
                               err)))
            goto done;
        sl_report_text(c.rep, "setlight %s simulated the virtual set into %s, processed it with "
                       "`setlight process` (its own report: %s) and scored every stage's output "
                       "against the set's truth; only the scoring reads the truth. Errors are "
                       "after the one free scale of relative units.",
                       sl_version(), o->capture, o->process_report ? o->process_report : "-");
        static const char *const head[] = {"stage", "verdict", "against the truth", "wall s",
                                           "CPU s"};
        sl_report_table_begin(c.rep, 5, head);
    }
    add_stage(&c, "simulate", true, json_object(), json_object(), "the capture and its truth");
    double stitched_scale = 0;
    if ((r = score_merge(&c, err)) || (r = score_stitch(&c, &stitched, &stitched_scale, err)) ||
        (r = score_unwrap(&c, &stitched, err)) || (r = score_calibrate(&c, err)) ||
        (r = score_rig(&c, stitched_scale, err)) || (r = score_render(&c, err)))
        goto done;
    double score_s = sl_seconds() - t0, score_cpu = sl_cpu_seconds() - c0;
    if (c.rep) {
        char s[2][64];
        snprintf(s[0], 64, "%.1f", score_s);
        snprintf(s[1], 64, "%.1f", score_cpu);
        const char *cells[5] = {"score", "", "this page: the truth read, the truth renders", s[0],
                                s[1]};
        sl_report_table_row(c.rep, cells);
        sl_report_table_end(c.rep);
        double lavg = sl_vset_log_average(&c.truth);
        double stops = log2(0.18 / (lavg > 0 ? lavg : 1));
        if ((r = sl_report_image(c.rep, "truth.png", &c.truth, stops, "truth/latlong.exr", err)))
            goto done;
        /* the stitch as the truth's exposure shows it: its scale divided out */
        if (stitched_scale > 0 &&
            (r = sl_report_image(c.rep, "stitched.png", &stitched, stops - log2(stitched_scale),
                                 "process/capture/stitch/hdri.exr (camera RGB) at the truth's "
                                 "exposure", err)))
            goto done;
        if (c.stitch_error.data &&
            (r = sl_report_image(c.rep, "stitch_error.png", &c.stitch_error, 0,
                                 "where the stitch is off: |stitch / (scale x truth) - 1| within "
                                 "60 deg of the horizon; black 0, white off by its own value or "
                                 "more (what sets the p95)", err)))
            goto done;
        r = sl_report_finish(c.rep, err);
        c.rep = NULL;
        if (r)
            goto done;
    }
    res->stages = (int)json_array_size(c.stages);
    res->stages_failed = c.failed;
    json_t *pc = json_object_get(c.cost, "seconds");
    json_t *doc = json_pack("{s:b, s:i, s:s, s:s, s:f, s:O, s:{s:f, s:f, s:f, s:f, s:f}}",
                            "passed", c.failed == 0, "stages_failed", c.failed, "capture",
                            o->capture, "jobs_json", o->jobs_json, "band_deg", o->band_deg,
                            "stages", c.stages, "cost", "simulate_seconds",
                            o->simulate_seconds, "simulate_cpu_seconds", o->simulate_cpu_seconds,
                            "process_seconds", json_number_value(pc), "score_seconds", score_s,
                            "score_cpu_seconds", score_cpu);
    if (o->process_report)
        json_object_set_new(doc, "process_report", json_string(o->process_report));
    if (o->report_dir) {
        snprintf(path, sizeof path, "%s/report.html", o->report_dir);
        json_object_set_new(doc, "report", json_string(path));
    }
    json_t *cost = json_object_get(doc, "cost"), *counts = json_object_get(c.cost, "jobs");
    json_t *jobs = json_object_get(json_array_get(json_object_get(c.cost, "setups"), 0), "jobs");
    if (counts)
        json_object_set(cost, "process_job_counts", counts);
    if (jobs)
        json_object_set(cost, "process_jobs", jobs);
    res->json = json_dumps(doc, JSON_INDENT(2) | JSON_PRESERVE_ORDER | JSON_REAL_PRECISION(6));
    res->summary = strdup(c.summary);
    json_decref(doc);
    if (!res->json || !res->summary)
        r = sl_error_set(err, SL_ERR_NOMEM, "score: out of memory");
    else if (o->json_path)
        r = sl_write_file_atomic(o->json_path, res->json, strlen(res->json), err);
done:
    if (c.rep)
        sl_report_free(c.rep);
    sl_image_free(&stitched);
    sl_image_free(&c.stitch_error);
    sl_image_free(&c.white_truth);
    sl_image_free(&c.truth);
    json_decref(c.cap);
    json_decref(c.cam);
    json_decref(c.probes);
    json_decref(c.graph);
    json_decref(c.stages);
    json_decref(c.cost);
    if (r)
        sl_vset_score_result_free(res);
    return r;
}
