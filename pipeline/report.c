/* SPDX-License-Identifier: BSD-3-Clause */
/* The setup's report and the day's index (the report and index jobs), and
 * the summaries --json prints. */
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "report_private.h"

static const char *str(const json_t *o, const char *k)
{
    return json_string_value(json_object_get(o, k));
}

static json_t *load_quiet(const char *path)
{
    json_t *v = NULL;
    sl_error e;
    pl_json_load(path, &v, &e);
    return v;
}



#define INDEX_WARNINGS 5 /* a setup's warnings shown on the day's index */

const char *const pl_report_pictures[PL_REPORT_PICTURES] = {
    "report_latlong.png",    "report_env_grey.png", "report_env_chrome.png",
    "report_env_chart.png",  "report_rig_grey.png", "report_rig_chrome.png",
    "report_rig_chart.png"};

sl_result sl_pipeline_latlong_compare(const char *test_path, const char *ref_path,
                                      double band_deg, double *median_ratio,
                                      double *median_rel_error, double *median_rel_error_scaled,
                                      sl_error *err)
{
    sl_image a = {0}, b = {0}, bs = {0};
    sl_meta ma, mb;
    sl_meta_init(&ma);
    sl_meta_init(&mb);
    sl_result r = sl_exr_read(test_path, &a, &ma, err);
    if (!r)
        r = sl_exr_read(ref_path, &b, &mb, err);
    if (!r && (a.width != b.width || a.height != b.height))
        r = sl_image_resample(&b, a.width, a.height, &bs, err);
    const sl_image *ref = bs.data ? &bs : &b;
    double *ratio = NULL, *rel = NULL;
    size_t n = 0;
    if (!r) {
        ratio = malloc(sizeof(double) * (size_t)a.width * (size_t)a.height);
        rel = malloc(sizeof(double) * (size_t)a.width * (size_t)a.height);
        if (!ratio || !rel)
            r = sl_error_set(err, SL_ERR_NOMEM, "out of memory");
    }
    for (int y = 0; !r && y < a.height; y++) {
        double lat = 90.0 - 180.0 * (y + 0.5) / a.height;
        if (fabs(lat) > band_deg)
            continue;
        for (int x = 0; x < a.width; x++) {
            double la = sl_luminance_px(sl_image_pixel((sl_image *)&a, x, y));
            double lb = sl_luminance_px(sl_image_pixel((sl_image *)ref, x, y));
            if (!(la >= 0) || !(lb > 0) || !isfinite(la) || !isfinite(lb))
                continue;
            ratio[n++] = la / lb;
        }
    }
    if (!r && !n)
        r = sl_error_set(err, SL_ERR_INPUT, "%s: no texel to compare with %s", test_path, ref_path);
    if (!r) {
        /* |t - r| / r = |t/r - 1|; after the scale s: |t/(s r) - 1|. */
        for (size_t i = 0; i < n; i++)
            rel[i] = ratio[i];
        qsort(ratio, n, sizeof *ratio, sl_cmp_double);
        double s = ratio[n / 2];
        *median_ratio = s;
        for (size_t i = 0; i < n; i++)
            ratio[i] = fabs(rel[i] - 1);
        qsort(ratio, n, sizeof *ratio, sl_cmp_double);
        *median_rel_error = ratio[n / 2];
        for (size_t i = 0; i < n; i++)
            rel[i] = s > 0 ? fabs(rel[i] / s - 1) : INFINITY;
        qsort(rel, n, sizeof *rel, sl_cmp_double);
        *median_rel_error_scaled = rel[n / 2];
    }
    free(ratio);
    free(rel);
    sl_image_free(&a);
    sl_image_free(&b);
    sl_image_free(&bs);
    sl_meta_free(&ma);
    sl_meta_free(&mb);
    return r;
}

/* Relative RMSE of a render against another of the same scene. */
static double render_rel_rmse(const char *test_path, const char *ref_path)
{
    sl_image a = {0}, b = {0};
    sl_meta ma, mb;
    sl_meta_init(&ma);
    sl_meta_init(&mb);
    sl_error e;
    double num = 0, den = 0, out = NAN;
    if (!sl_exr_read(test_path, &a, &ma, &e) && !sl_exr_read(ref_path, &b, &mb, &e) &&
        a.width == b.width && a.height == b.height) {
        for (int y = 0; y < a.height; y++)
            for (int x = 0; x < a.width; x++) {
                const float *p = sl_image_pixel(&a, x, y), *q = sl_image_pixel(&b, x, y);
                for (int c = 0; c < 3; c++) {
                    num += ((double)p[c] - q[c]) * ((double)p[c] - q[c]);
                    den += (double)q[c] * q[c];
                }
            }
        if (den > 0)
            out = sqrt(num / den);
    }
    sl_image_free(&a);
    sl_image_free(&b);
    sl_meta_free(&ma);
    sl_meta_free(&mb);
    return out;
}

static void set_num(json_t *o, const char *k, json_t *v)
{
    if (json_is_number(v))
        json_object_set_new(o, k, json_real(json_number_value(v)));
}

/* Key numbers of one job's result. */
static void numbers_of(const json_t *job, json_t *nums)
{
    const char *stage = str(job, "stage");
    const char *res = sl_json_string_ending(json_object_get(job, "outputs"), ".result.json");
    json_t *r = res ? load_quiet(res) : NULL;
    if (!strcmp(stage, "merge") && r) {
        double worst = json_number_value(json_object_get(nums, "merge_clipped_fraction_max"));
        double f = json_number_value(json_object_get(r, "clipped_fraction"));
        json_object_set_new(nums, "merge_clipped_fraction_max", json_real(fmax(worst, f)));
    } else if (!strcmp(stage, "stitch") && r) {
        set_num(nums, "stitch_width", json_object_get(r, "width"));
        json_t *rp = json_object_get(r, "reprojection");
        set_num(nums, "stitch_pairs_solved", json_object_get(rp, "pairs_solved"));
        set_num(nums, "stitch_pairs_fallback", json_object_get(rp, "pairs_fallback"));
        set_num(nums, "stitch_reprojection_rms_px", json_object_get(rp, "rms_px"));
        set_num(nums, "stitch_filled_percent",
                json_object_get(json_object_get(r, "coverage"), "filled_percent"));
    } else if (!strcmp(stage, "calibrate") && r) {
        set_num(nums, "calibrate_scale", json_object_get(r, "scale"));
        json_t *ch = json_object_get(r, "chart"), *g = json_object_get(r, "grey");
        set_num(nums, "chart_delta_e_before", json_object_get(ch, "delta_e_before_mean"));
        set_num(nums, "chart_delta_e_after", json_object_get(ch, "delta_e_after_mean"));
        set_num(nums, "grey_rel_rmse_after", json_object_get(g, "rel_rmse_after"));
        if (str(r, "units"))
            json_object_set_new(nums, "units", json_string(str(r, "units")));
    } else if (!strcmp(stage, "rig") && r) {
        set_num(nums, "rig_lights", json_object_get(r, "lights"));
        set_num(nums, "rig_relative_error", json_object_get(r, "relative_error"));
    } else if (!strcmp(stage, "unwrap") && r) {
        set_num(nums, "unwrap_width", json_object_get(r, "width"));
    }
    json_decref(r);
}

/* "warning:" lines of a log. */
static void warnings_of(const char *log, json_t *list)
{
    FILE *f = log ? fopen(log, "r") : NULL;
    if (!f)
        return;
    char buf[2048];
    while (fgets(buf, sizeof buf, f)) {
        buf[strcspn(buf, "\n")] = 0;
        if (strstr(buf, "warning:"))
            json_array_append_new(list, json_string(buf));
    }
    fclose(f);
}

json_t *pl_setup_summary(const json_t *graph, const json_t *entry, const json_t *status)
{
    const char *name = str(entry, "name");
    json_t *sum = json_pack("{s:s,s:s}", "name", name, "source", str(entry, "source"));
    /* The sessions' problems first: what ingest skipped or could not group. */
    json_t *warn = json_deep_copy(json_object_get(entry, "warnings"));
    if (!warn)
        warn = json_array();
    if (!strcmp(str(entry, "status"), "failed")) {
        json_object_set_new(sum, "status", json_string("failed"));
        json_object_set(sum, "reason", json_object_get(entry, "reason"));
        json_object_set(sum, "exit", json_object_get(entry, "exit"));
        json_object_set_new(sum, "warnings", warn);
        return sum;
    }
    json_t *jobs = json_array(), *nums = json_object(), *outs = json_object();
    double wall = 0, cpu = 0, rss = 0;
    const char *reason = NULL;
    json_int_t exit_code = 0;
    char reason_buf[2300];
    size_t i;
    json_t *job;
    json_array_foreach(json_object_get(graph, "jobs"), i, job) {
        const char *setup = str(job, "setup");
        if (!setup || strcmp(setup, name))
            continue;
        const char *id = str(job, "id"), *stage = str(job, "stage");
        json_t *stamp = pl_stamp_load(graph, job);
        const char *state = status ? str(status, id) : NULL;
        if (!state) {
            /* Outside a run (the report job): the stamp's word. */
            const char *ss = str(stamp, "status");
            state = !ss ? "not run" : !strcmp(ss, "ok") ? "done" : "failed";
        }
        bool is_report = !strcmp(stage, "report");
        if (!reason && !is_report && (!strcmp(state, "failed") || !strcmp(state, "not run"))) {
            const char *msg = str(stamp, "message");
            snprintf(reason_buf, sizeof reason_buf, "%s: %s", id,
                     msg ? msg : !strcmp(state, "failed") ? "failed" : "not run");
            reason = reason_buf;
            exit_code = json_integer_value(json_object_get(stamp, "exit"));
        }
        if (!strcmp(state, "failed") && is_report && !reason) {
            snprintf(reason_buf, sizeof reason_buf, "%s: %s", id,
                     str(stamp, "message") ? str(stamp, "message") : "failed");
            reason = reason_buf;
            exit_code = 1;
        }
        double js = json_number_value(json_object_get(stamp, "seconds"));
        double jc = json_number_value(json_object_get(stamp, "cpu_seconds"));
        double jr = json_number_value(json_object_get(stamp, "max_rss_mb"));
        wall += js;
        cpu += jc;
        rss = fmax(rss, jr);
        json_t *row = json_pack("{s:s,s:s,s:s,s:f,s:f,s:f}", "id", id, "stage", stage, "status",
                                state, "seconds", js, "cpu_seconds", jc, "max_rss_mb", jr);
        if (str(stamp, "message") && str(stamp, "status") && !strcmp(str(stamp, "status"), "failed"))
            json_object_set_new(row, "message", json_string(str(stamp, "message")));
        json_array_append_new(jobs, row);
        json_decref(stamp);
        numbers_of(job, nums);
        warnings_of(str(job, "log"), warn);
        const json_t *o0 = json_array_get(json_object_get(job, "outputs"), 0);
        if (!strcmp(stage, "stitch"))
            json_object_set(outs, "stitched", (json_t *)o0);
        else if (!strcmp(stage, "calibrate"))
            json_object_set(outs, "calibrated", (json_t *)o0);
        else if (!strcmp(stage, "unwrap"))
            json_object_set(outs, "unwrapped", (json_t *)o0);
        else if (!strcmp(stage, "rig")) {
            json_object_set(outs, "rig_usda", (json_t *)o0);
            json_object_set(outs, "rig_json", json_array_get(json_object_get(job, "outputs"), 1));
        } else if (is_report)
            json_object_set(outs, "report", (json_t *)o0);
    }
    /* What the report job measured (renders, the unwrap cross-check). */
    if (!reason && str(outs, "report")) {
        char rj[PATH_MAX + 16];
        snprintf(rj, sizeof rj, "%s", str(outs, "report"));
        char *dot = strrchr(rj, '.');
        if (dot && !strcmp(dot, ".html")) {
            strcpy(dot, ".json");
            json_t *prev = load_quiet(rj);
            json_object_update_missing(nums, json_object_get(prev, "numbers"));
            json_decref(prev);
        }
    }
    json_t *latlong = json_object_get(outs, "calibrated");
    if (!latlong)
        latlong = json_object_get(outs, "stitched");
    if (latlong)
        json_object_set(outs, "latlong", latlong);
    json_object_set_new(sum, "status", json_string(reason ? "failed" : "ok"));
    if (reason) {
        json_object_set_new(sum, "reason", json_string(reason));
        json_object_set_new(sum, "exit", json_integer(exit_code ? exit_code : 1));
    }
    json_object_set_new(sum, "outputs", outs);
    json_object_set_new(sum, "numbers", nums);
    json_object_set_new(sum, "warnings", warn);
    json_object_set_new(sum, "cost", json_pack("{s:f,s:f,s:f}", "seconds", wall, "cpu_seconds",
                                               cpu, "max_rss_mb", rss));
    json_object_set_new(sum, "jobs", jobs);
    return sum;
}

/* Display exposure for a lat-long: its median luminance at mid grey. */
static double display_stops(const sl_image *img)
{
    size_t n = 0, cap = (size_t)img->width * (size_t)img->height;
    double *l = malloc(cap * sizeof *l);
    if (!l)
        return 0;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            double v = sl_luminance_px(sl_image_pixel((sl_image *)img, x, y));
            if (v > 0 && isfinite(v))
                l[n++] = v;
        }
    double stops = 0;
    if (n) {
        qsort(l, n, sizeof *l, sl_cmp_double);
        stops = log2(0.18 / l[n / 2]);
    }
    free(l);
    return stops;
}

/* An EXR shown in the report (RGB, at most width px wide). */
static sl_result show_exr(sl_report *rep, const char *file, const char *path, int width,
                          const char *caption, sl_error *err)
{
    sl_image img = {0}, rgb = {0}, small = {0};
    sl_meta meta;
    sl_meta_init(&meta);
    sl_result r = sl_exr_read(path, &img, &meta, err);
    if (!r)
        r = sl_image_convert_channels(&img, 3, &rgb, err);
    if (!r && rgb.width > width)
        r = sl_image_resample(&rgb, width, (int)((double)rgb.height * width / rgb.width + 0.5),
                              &small, err);
    if (!r) {
        const sl_image *show = small.data ? &small : &rgb;
        r = sl_report_image(rep, file, show, display_stops(show), caption, err);
    }
    sl_image_free(&img);
    sl_image_free(&rgb);
    sl_image_free(&small);
    sl_meta_free(&meta);
    return r;
}

static void numbers_table(sl_report *rep, const json_t *nums)
{
    static const char *const head[] = {"number", "value"};
    sl_report_table_begin(rep, 2, head);
    const char *k;
    json_t *v;
    json_object_foreach((json_t *)nums, k, v) {
        char val[64];
        if (json_is_string(v))
            snprintf(val, sizeof val, "%s", json_string_value(v));
        else
            snprintf(val, sizeof val, "%.4g", json_number_value(v));
        const char *row[] = {k, val};
        sl_report_table_row(rep, row);
    }
    sl_report_table_end(rep);
}

static json_t *find_setup_entry(const json_t *setups_doc, const char *name)
{
    size_t i;
    json_t *s;
    json_array_foreach(json_object_get(setups_doc, "setups"), i, s)
        if (!strcmp(str(s, "name"), name))
            return s;
    return NULL;
}

/* The graph checked whole (graph.c), then OUT/setups.json beside it. */
static sl_result load_graph_and_setups(const char *jobs_json, sl_pipeline_graph **g,
                                       json_t **setups, sl_error *err)
{
    sl_result r = pl_graph_load(jobs_json, g, err);
    if (r)
        return r;
    char path[PATH_MAX + 16];
    snprintf(path, sizeof path, "%s/setups.json", (*g)->out);
    r = pl_json_load(path, setups, err);
    /* Written by process beside the graph; its fields are compared below. */
    size_t i;
    json_t *s;
    json_array_foreach(json_object_get(*setups, "setups"), i, s)
        if (!r && (!str(s, "name") || !str(s, "source") || !str(s, "status")))
            r = sl_error_set(err, SL_ERR_INPUT, "%s: setup %zu has no name, source or status",
                             path, i + 1);
    if (r) {
        json_decref(*setups);
        *setups = NULL;
        sl_pipeline_graph_free(*g);
        *g = NULL;
    }
    return r;
}

sl_result sl_pipeline_report_setup(const char *jobs_json, const char *setup, sl_error *err)
{
    sl_pipeline_graph *g;
    json_t *setups;
    sl_result r = load_graph_and_setups(jobs_json, &g, &setups, err);
    if (r)
        return r;
    const json_t *graph = g->root;
    json_t *entry = find_setup_entry(setups, setup);
    if (!entry) {
        sl_pipeline_graph_free(g);
        json_decref(setups);
        return sl_error_set(err, SL_ERR_USAGE, "%s: no setup '%s'", jobs_json, setup);
    }
    json_t *sum = pl_setup_summary(graph, entry, NULL);
    json_t *outs = json_object_get(sum, "outputs"), *nums = json_object_get(sum, "numbers");
    char dir[PATH_MAX + 300], path[PATH_MAX + 400];
    snprintf(dir, sizeof dir, "%s/%s", str(graph, "out"), setup);
    /* The validation renders: the rig against the HDRI, scene by scene; the
     * chrome ball's unwrap against the stitch within 60 degrees of the horizon. */
    static const char *const scenes[] = {"grey", "chrome", "chart"};
    for (int k = 0; k < 3; k++) {
        char a[PATH_MAX + 400], b[PATH_MAX + 400], key[64];
        snprintf(a, sizeof a, "%s/render/rig_%s.exr", dir, scenes[k]);
        snprintf(b, sizeof b, "%s/render/env_%s.exr", dir, scenes[k]);
        double e = render_rel_rmse(a, b);
        snprintf(key, sizeof key, "render_rig_vs_env_%s_rel_rmse", scenes[k]);
        if (isfinite(e))
            json_object_set_new(nums, key, json_real(e));
    }
    if (str(outs, "unwrapped") && str(outs, "stitched")) {
        double ratio, rel, scaled;
        sl_error ignored;
        if (!sl_pipeline_latlong_compare(str(outs, "unwrapped"), str(outs, "stitched"), 60,
                                         &ratio, &rel, &scaled, &ignored)) {
            json_object_set_new(nums, "unwrap_vs_stitch_median_ratio", json_real(ratio));
            json_object_set_new(nums, "unwrap_vs_stitch_median_rel_error_scaled",
                                json_real(scaled));
        }
    }
    char title[600];
    snprintf(title, sizeof title, "setlight process: %s", setup);
    sl_report *rep;
    if ((r = sl_report_new(&rep, dir, "report", title, err)))
        goto done;
    sl_report_text(rep, "Setup %s from %s: %s.", setup, str(sum, "source"), str(sum, "status"));
    if (str(outs, "latlong"))
        r = show_exr(rep, pl_report_pictures[0], str(outs, "latlong"), 512,
                     "the lat-long (calibrated when a grey ball or chart was shot)", err);
    sl_report_section(rep, "Numbers");
    numbers_table(rep, nums);
    sl_report_section(rep, "Validation renders: under the HDRI, under the rig");
    for (int k = 0; k < 6 && !r; k++) {
        char cap[128];
        snprintf(path, sizeof path, "%s/render/%s_%s.exr", dir, k < 3 ? "env" : "rig", scenes[k % 3]);
        snprintf(cap, sizeof cap, "%s under the %s", scenes[k % 3], k < 3 ? "HDRI" : "rig");
        r = show_exr(rep, pl_report_pictures[1 + k], path, 256, cap, err);
    }
    sl_report_section(rep, "Warnings");
    size_t i;
    json_t *w;
    json_array_foreach(json_object_get(sum, "warnings"), i, w)
        sl_report_text(rep, "%s", json_string_value(w));
    if (!json_array_size(json_object_get(sum, "warnings")))
        sl_report_text(rep, "none");
    sl_report_section(rep, "Jobs");
    static const char *const head[] = {"job", "status", "wall s", "CPU s", "peak MB"};
    sl_report_table_begin(rep, 5, head);
    json_array_foreach(json_object_get(sum, "jobs"), i, w) {
        if (!strcmp(str(w, "stage"), "report"))
            continue;
        char a[32], b[32], c[32];
        snprintf(a, sizeof a, "%.2f", json_number_value(json_object_get(w, "seconds")));
        snprintf(b, sizeof b, "%.2f", json_number_value(json_object_get(w, "cpu_seconds")));
        snprintf(c, sizeof c, "%.0f", json_number_value(json_object_get(w, "max_rss_mb")));
        const char *row[] = {str(w, "id"), str(w, "status"), a, b, c};
        sl_report_table_row(rep, row);
    }
    sl_report_table_end(rep);
    if (r) {
        sl_report_free(rep);
        goto done;
    }
    if ((r = sl_report_finish(rep, err)))
        goto done;
    snprintf(path, sizeof path, "%s/report.json", dir);
    r = pl_json_write(path, sum, err);
done:
    json_decref(sum);
    sl_pipeline_graph_free(g);
    json_decref(setups);
    return r;
}

sl_result sl_pipeline_report_index(const char *jobs_json, sl_error *err)
{
    sl_pipeline_graph *g;
    json_t *setups;
    sl_result r = load_graph_and_setups(jobs_json, &g, &setups, err);
    if (r)
        return r;
    const json_t *graph = g->root;
    const char *out = str(graph, "out");
    sl_report *rep;
    if ((r = sl_report_new(&rep, out, "index", "setlight process: the day", err))) {
        sl_pipeline_graph_free(g);
        json_decref(setups);
        return r;
    }
    json_t *list = json_array();
    size_t i;
    json_t *entry;
    int failed = 0, total = 0;
    json_array_foreach(json_object_get(setups, "setups"), i, entry) {
        json_t *sum = pl_setup_summary(graph, entry, NULL);
        const char *name = str(sum, "name");
        bool ok = !strcmp(str(sum, "status"), "ok");
        failed += !ok;
        total++;
        sl_report_section(rep, name);
        if (!ok)
            sl_report_text(rep, "FAILED: %s", str(sum, "reason"));
        else {
            /* The report's own picture of the lat-long: written by a job
             * that declares it, and current when the setup is ok. */
            char file[600], path[PATH_MAX + 700];
            snprintf(file, sizeof file, "%s/%s", name, pl_report_pictures[0]);
            snprintf(path, sizeof path, "%s/%s", out, file);
            if (access(path, R_OK) == 0)
                sl_report_figure(rep, file, 256, "lat-long");
            else
                sl_report_text(rep, "(no thumbnail: %s is missing)", path);
            char page[PATH_MAX];
            snprintf(page, sizeof page, "%s/report.html", name);
            sl_report_link(rep, page, "the setup's report");
            numbers_table(rep, json_object_get(sum, "numbers"));
        }
        json_t *cost = json_object_get(sum, "cost");
        if (cost)
            sl_report_text(rep, "Cost: %.1f s of job time, %.1f s CPU, peak %.0f MB.",
                           json_number_value(json_object_get(cost, "seconds")),
                           json_number_value(json_object_get(cost, "cpu_seconds")),
                           json_number_value(json_object_get(cost, "max_rss_mb")));
        /* A night setup can carry dozens (a merge's frames not aligned):
         * the first few here, all of them in the setup's report. */
        size_t k, nwarn = json_array_size(json_object_get(sum, "warnings"));
        json_t *w;
        json_array_foreach(json_object_get(sum, "warnings"), k, w) {
            if (k == INDEX_WARNINGS && nwarn > INDEX_WARNINGS + 1) {
                sl_report_text(rep, "... and %zu more warnings (all in %s/report.html)",
                               nwarn - k, name);
                break;
            }
            sl_report_text(rep, "%s", json_string_value(w));
        }
        json_array_append_new(list, sum);
    }
    sl_report_top_begin(rep);
    sl_report_text(rep, "%d setups, %d processed, %d failed.", total, total - failed, failed);
    sl_report_top_end(rep);
    r = sl_report_finish(rep, err);
    if (!r) {
        char path[PATH_MAX + 16];
        snprintf(path, sizeof path, "%s/index.json", out);
        json_t *doc = json_pack("{s:i,s:i,s:o}", "setups_total", total, "setups_failed", failed,
                                "setups", list);
        r = pl_json_write(path, doc, err);
        json_decref(doc);
    } else
        json_decref(list);
    sl_pipeline_graph_free(g);
    json_decref(setups);
    return r;
}
