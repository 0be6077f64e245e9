/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight demo: simulates the stage set, runs every pipeline stage that
 * exists on the capture, and writes DIR/report.html. New stages add a row
 * to `stages` below. */
#include <dirent.h>
#include <errno.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "demo.h"
#include "setlight/render.h"

static void help(FILE *out)
{
    fprintf(out,
            "usage: setlight demo [DIR] [--size tiny|small] [--seed N] [--force]\n\n"
            "Simulates the 'stage' virtual set (no camera, no downloaded data), runs every\n"
            "pipeline stage setlight has on the capture, and writes DIR/report.html with the\n"
            "stages, their numbers and pictures. DIR defaults to ./setlight-demo.\n"
            "The chain is the on-set one: each fisheye view's bracket merged, the views\n"
            "stitched to the HDRI (DIR/hdri.exr) from their EXIF lens, then calibrate, rig\n"
            "and render on that HDRI; the chrome-ball unwrap cross-checks it. Every stage\n"
            "is scored against the set's ground truth.\n\n"
            "  --size S    small (default; a few minutes at most on 2 cores) or tiny\n"
            "  --seed N    sensor-noise seed (default 1)\n"
            "  --force     replace an earlier demo in DIR\n"
            "  --json      print the report's path, each stage's time and the headline facts\n"
            "              (the stitch's solve, fallbacks and error against the truth; the\n"
            "              unwrap's difference from the stitch)\n"
            "\nexit codes: 0 success, 1 runtime failure, 2 usage error (DIR holds other files,\n"
            "or an earlier demo without --force), 3 invalid input data\n");
}

static sl_result stage_simulate(demo *d, char *note, size_t n, sl_error *err)
{
    sl_vset_desc desc;
    sl_result r = sl_vset_preset("stage", &desc, err);
    if (r)
        return r;
    sl_vset_capture_opts o;
    sl_vset_capture_defaults(&o, &desc, d->size);
    o.seed = d->seed;
    o.force = d->force;
    /* The HDRI frames 1.5 times the small preset's: at 720 x 480 the stage's
     * smooth surfaces give two of its three overlaps too few features for
     * the stitch's solve (they fall back to the nominal rotations, 1 degree
     * off, and the centre goes unsolved, 5 px off); at 1080 x 720 every pair
     * solves (docs/demo.md). */
    if (d->size == SL_VSET_SIZE_SMALL) {
        o.photo_width = 1080;
        o.photo_height = 720;
    }
    if ((r = sl_vset_capture_write(&o, d->capture, &d->summary, err)))
        return r;
    snprintf(note, n, "%d frames in %d views, f/%g ISO %g, %.6g to %g s", d->summary.frames,
             d->summary.views, d->summary.f_number, d->summary.iso, d->summary.min_time_s,
             d->summary.max_time_s);
    return SL_OK;
}

/* The ground truth, read back from the capture as any stage would. */
static sl_result stage_truth(demo *d, char *note, size_t n, sl_error *err)
{
    char path[4300];
    snprintf(path, sizeof path, "%s/truth/latlong.exr", d->capture);
    sl_image ll;
    sl_meta meta;
    sl_result r = sl_exr_read(path, &ll, &meta, err);
    sl_meta_free(&meta);
    if (r)
        return r;
    d->lavg = sl_vset_log_average(&ll);
    sl_report_section(d->rep, "Ground truth");
    sl_report_text(d->rep, "The set's HDR lat-long (%dx%d, log-average luminance %.3g cd/m^2), "
                           "shown with its log-average at 18%% grey.",
                   ll.width, ll.height, d->lavg);
    r = sl_report_image(d->rep, "truth.png", &ll, log2(0.18 / d->lavg), "truth/latlong.exr",
                        err);
    sl_image_free(&ll);
    if (r)
        return r;
    json_t *lights = demo_load_json(d->capture, "truth/lights.json", err);
    if (!lights)
        return err ? err->code : SL_ERR_INPUT;
    static const char *const head[] = {"light", "shape", "azimuth", "elevation",
                                       "solid angle (sr)", "luminance (cd/m^2)",
                                       "integral Y"};
    sl_report_table_begin(d->rep, 7, head);
    json_t *arr = json_object_get(lights, "lights");
    for (size_t i = 0; i < json_array_size(arr); i++) {
        json_t *l = json_array_get(arr, i);
        json_t *rad = json_object_get(l, "radiance_rgb"), *in = json_object_get(l, "integral_rgb");
        double y = 0.2126 * json_number_value(json_array_get(rad, 0)) +
                   0.7152 * json_number_value(json_array_get(rad, 1)) +
                   0.0722 * json_number_value(json_array_get(rad, 2));
        double iy = 0.2126 * json_number_value(json_array_get(in, 0)) +
                    0.7152 * json_number_value(json_array_get(in, 1)) +
                    0.0722 * json_number_value(json_array_get(in, 2));
        char c[7][64];
        snprintf(c[0], 64, "%s", json_string_value(json_object_get(l, "name")));
        snprintf(c[1], 64, "%s", json_string_value(json_object_get(l, "shape")));
        snprintf(c[2], 64, "%.1f", json_number_value(json_object_get(l, "azimuth_deg")));
        snprintf(c[3], 64, "%.1f", json_number_value(json_object_get(l, "elevation_deg")));
        snprintf(c[4], 64, "%.4g", json_number_value(json_object_get(l, "solid_angle_sr")));
        snprintf(c[5], 64, "%.4g", y);
        snprintf(c[6], 64, "%.4g", iy);
        const char *cells[7] = {c[0], c[1], c[2], c[3], c[4], c[5], c[6]};
        sl_report_table_row(d->rep, cells);
    }
    sl_report_table_end(d->rep);
    snprintf(note, n, "%zu lights, log-average %.3g cd/m^2", json_array_size(arr), d->lavg);
    json_decref(lights);
    return SL_OK;
}

/* The frames as a pipeline reads them: pixels and EXIF, checked against
 * the capture's plan. */
static sl_result stage_frames(demo *d, char *note, size_t n, sl_error *err)
{
    json_t *cap = demo_load_json(d->capture, "capture.json", err);
    if (!cap)
        return err ? err->code : SL_ERR_INPUT;
    json_t *frames = json_object_get(cap, "frames");
    int brackets = (int)json_integer_value(json_object_get(cap, "brackets"));
    int checked = 0, matched = 0;
    sl_result r = SL_OK;
    sl_report_section(d->rep, "Frames");
    sl_report_text(d->rep, "The middle exposure of each view, as the camera's JPEG.");
    for (size_t i = 0; i < json_array_size(frames) && !r; i++) {
        json_t *f = json_array_get(frames, i);
        const char *name = json_string_value(json_object_get(f, "name"));
        char path[4300];
        snprintf(path, sizeof path, "%s/hdri/%s.jpg", d->capture, name);
        sl_meta m;
        if ((r = sl_photo_read_meta(path, &m, NULL, NULL, NULL, err)))
            break;
        double t = json_number_value(json_object_get(f, "exposure_time_s"));
        checked++;
        if (fabs(m.exposure_time / t - 1) < 1e-4 &&
            fabs(m.f_number - json_number_value(json_object_get(f, "f_number"))) < 1e-4 &&
            fabs(m.iso - json_number_value(json_object_get(f, "iso"))) < 1e-6 &&
            !strcmp(m.datetime, json_string_value(json_object_get(f, "datetime"))))
            matched++;
        sl_meta_free(&m);
        if (json_integer_value(json_object_get(f, "bracket")) == brackets / 2) {
            sl_image img;
            sl_meta pm;
            if ((r = sl_photo_read(path, &img, &pm, err)))
                break;
            sl_meta_free(&pm);
            /* The report re-encodes as sRGB: undo that to show the JPEG as is. */
            for (int y = 0; y < img.height; y++)
                for (int x = 0; x < img.width * img.channels; x++) {
                    float *p = sl_image_pixel(&img, 0, y) + x;
                    *p = sl_srgb_to_linear(*p);
                }
            char file[96], caption[160];
            snprintf(file, sizeof file, "frame_%s.png", name);
            snprintf(caption, sizeof caption, "%s: view %d, yaw %.0f, %g s", name,
                     (int)json_integer_value(json_object_get(f, "view")),
                     json_number_value(json_object_get(f, "yaw_deg")), t);
            r = sl_report_image(d->rep, file, &img, 0, caption, err);
            sl_image_free(&img);
        }
    }
    json_decref(cap);
    if (r)
        return r;
    sl_report_text(d->rep, "EXIF read back through OpenImageIO matches the plan for %d of %d "
                           "frames.", matched, checked);
    snprintf(note, n, "%d frames read, EXIF matches the plan for %d", checked, matched);
    if (matched != checked)
        return sl_error_set(err, SL_ERR_INTERNAL, "%s: EXIF differs from the plan in %d frames",
                            d->capture, checked - matched);
    return SL_OK;
}


/* The capture folder ingested as a card would be: the shots (each a JPEG,
 * a 16-bit TIFF and a linear TIFF) grouped into views and brackets from
 * their EXIF alone, checked against the plan. */
static sl_result stage_ingest(demo *d, char *note, size_t n, sl_error *err)
{
    char src[4200], dst[4200];
    snprintf(src, sizeof src, "%s/hdri", d->capture);
    /* inside the capture folder, which a forced demo replaces whole */
    snprintf(dst, sizeof dst, "%s/session", d->capture);
    int frames = 0, views = 0;
    sl_result r = sl_ingest(src, dst, 0, NULL, &frames, &views, err);
    if (r)
        return r;
    json_t *cap = demo_load_json(d->capture, "capture.json", err);
    json_t *ses = cap ? demo_load_json(dst, "session.json", err) : NULL;
    if (!ses) {
        json_decref(cap);
        return err ? err->code : SL_ERR_INPUT;
    }
    /* frame i of view v in the session must be the plan's, by file name */
    json_t *plan = json_object_get(cap, "frames"), *sv = json_object_get(ses, "views");
    int planned = (int)json_array_size(plan), right = 0, siblings = 0;
    for (int i = 0; i < planned; i++) {
        json_t *f = json_array_get(plan, i);
        int v = (int)json_integer_value(json_object_get(f, "view"));
        int b = (int)json_integer_value(json_object_get(f, "bracket"));
        json_t *bs = json_object_get(json_array_get(sv, (size_t)v), "brackets");
        json_t *got = json_array_get(json_object_get(json_array_get(bs, 0), "frames"), (size_t)b);
        const char *source = json_string_value(json_object_get(got, "source"));
        const char *name = json_string_value(json_object_get(f, "name"));
        if (json_array_size(bs) == 1 && source && name &&
            !strncmp(source, name, strlen(name)) && source[strlen(name)] == '.')
            right++;
        siblings += (int)json_array_size(json_object_get(got, "siblings"));
    }
    int planned_views = (int)json_integer_value(json_object_get(cap, "views")) +
                        (json_is_true(json_object_get(cap, "zenith")) ? 1 : 0);
    json_decref(cap);
    json_decref(ses);
    sl_report_section(d->rep, "Ingest");
    sl_report_text(d->rep,
                   "The capture's hdri folder ingested as a card (setlight ingest, capture/session/): "
                   "%d frames in %d views grouped from EXIF time and exposure alone; %d of %d "
                   "planned frames in the right view, bracket and place; %d sibling files "
                   "(each shot's linear TIFF and JPEG beside its 16-bit TIFF).",
                   frames, views, right, planned, siblings);
    snprintf(note, n, "%d frames in %d views, %d of %d where the plan put them", frames, views,
             right, planned);
    if (frames != planned || views != planned_views || right != planned)
        return sl_error_set(err, SL_ERR_INTERNAL,
                            "%s: ingest grouped %d frames in %d views, %d of %d as planned", src,
                            frames, views, right, planned);
    return SL_OK;
}

/* True inverse response from truth/camera.json: x with curve(x) = z. */
static double true_inverse(json_t *curve, double z)
{
    size_t n = json_array_size(curve);
    double prev = 0;
    for (size_t i = 1; i < n; i++) {
        double c = json_number_value(json_array_get(curve, i));
        if (c >= z) {
            double t = c > prev ? (z - prev) / (c - prev) : 0;
            return ((double)(i - 1) + t) / (double)(n - 1);
        }
        prev = c;
    }
    return 1.0;
}

/* The first view's bracket merged with a self-calibrated response, which
 * is scored against the camera's true response curve. */
static sl_result stage_merge(demo *d, char *note, size_t n, sl_error *err)
{
    json_t *cap = demo_load_json(d->capture, "capture.json", err);
    if (!cap)
        return err ? err->code : SL_ERR_INPUT;
    json_t *cam = demo_load_json(d->capture, "truth/camera.json", err);
    if (!cam) {
        json_decref(cap);
        return err ? err->code : SL_ERR_INPUT;
    }
    json_t *frames = json_object_get(cap, "frames");
    char paths[64][4300];
    const char *ptrs[64];
    int count = 0;
    for (size_t i = 0; i < json_array_size(frames) && count < 64; i++) {
        json_t *f = json_array_get(frames, i);
        if (json_integer_value(json_object_get(f, "view")) != 0)
            continue;
        snprintf(paths[count], sizeof paths[count], "%s/hdri/%s.jpg", d->capture,
                 json_string_value(json_object_get(f, "name")));
        ptrs[count] = paths[count];
        count++;
    }
    sl_merge_options o;
    sl_merge_options_init(&o);
    o.response_mode = SL_RESPONSE_AUTO;
    sl_merge_result res;
    sl_result r = sl_merge(ptrs, count, &o, &res, err);
    if (r)
        goto done;
    char out[4300], mask[4300];
    snprintf(out, sizeof out, "%s/merge_view0.exr", d->dir);
    snprintf(mask, sizeof mask, "%s/merge_view0_clipped.exr", d->dir);
    if ((r = sl_merge_write(out, mask, NULL, &res, err)))
        goto done;
    /* Response error over the well-exposed range, green channel, after the
     * one free scale a self-calibrated curve has (Debevec-Malik recovers it
     * up to a factor): the median ratio to the true inverse. */
    json_t *curve = json_object_get(json_object_get(cam, "response"), "curve");
    double ratios[81], sorted[81], worst = 0;
    for (int i = 0; i <= 80; i++) {
        double z = 0.1 + 0.01 * i;
        ratios[i] = sorted[i] = sl_response_eval(&res.response, 1, z) / true_inverse(curve, z);
    }
    for (int i = 1; i <= 80; i++) /* insertion sort: 81 values */
        for (int j = i; j > 0 && sorted[j - 1] > sorted[j]; j--) {
            double t = sorted[j];
            sorted[j] = sorted[j - 1];
            sorted[j - 1] = t;
        }
    for (int i = 0; i <= 80; i++) {
        double e = fabs(ratios[i] / sorted[40] - 1);
        worst = e > worst ? e : worst;
    }
    double ref_exposure = res.frames[res.reference].exposure;
    sl_report_section(d->rep, "Merge");
    sl_report_text(d->rep, "View 0: %d JPEG frames merged with a self-calibrated (Debevec-Malik) "
                           "response in %.2f s. Recovered response vs the camera's true curve, "
                           "z in [0.1, 0.9], after the free scale: worst %.2f%% (goal 2%%). "
                           "Frames whose EXIF and pixel data "
                           "disagree: %lld. Pixels clipped in every frame: %.4f%%.",
                   count, res.seconds, 100 * worst, (long long)res.disagreeing_frames,
                   100 * res.clipped_fraction);
    {
        /* The recovered curve against the true one, both at the free scale
         * the fit above removed (the median ratio). */
        double zs[81], got[81], want[81];
        for (int i = 0; i <= 80; i++) {
            zs[i] = 0.1 + 0.01 * i;
            want[i] = true_inverse(curve, zs[i]);
            got[i] = sl_response_eval(&res.response, 1, zs[i]) / sorted[40];
        }
        const sl_plot_series curves[2] = {{"true (camera model)", zs, want, 81},
                                          {"recovered (self-calibrated)", zs, got, 81}};
        if ((r = sl_report_plot(d->rep, "merge_response.svg",
                                "inverse response, green: recovered vs true", "code (0-1)",
                                "relative exposure", false, true, curves, 2, err)))
            goto done;
    }
    r = sl_report_image(d->rep, "merge_view0.png", &res.radiance,
                        log2(0.18 / (d->lavg * ref_exposure > 0 ? d->lavg * ref_exposure : 1)) + 3,
                        "merge_view0.exr (camera RGB, relative radiance)", err);
    snprintf(note, n, "%d frames in %.1f s; response within %.1f%%; %lld frames disagree",
             count, res.seconds, 100 * worst, (long long)res.disagreeing_frames);
done:
    sl_merge_result_free(&res);
    json_decref(cap);
    json_decref(cam);
    return r;
}

/* Irradiance at a surface of normal n from a lat-long, summed over every
 * texel: the renderer's independent ground truth. */
static double irradiance_y(const sl_image *ll, const double n[3])
{
    double e = 0;
    for (int y = 0; y < ll->height; y++) {
        double dw = sl_latlong_texel_solid_angle(y, ll->width, ll->height);
        for (int x = 0; x < ll->width; x++) {
            double dir[3];
            sl_latlong_to_dir((x + 0.5) / ll->width, (y + 0.5) / ll->height, dir);
            double c = dir[0] * n[0] + dir[1] * n[1] + dir[2] * n[2];
            if (c <= 0)
                continue;
            const float *p = sl_image_pixel(ll, x, y);
            e += (0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2]) * c * dw;
        }
    }
    return e;
}

/* The on-set references (grey ball, chrome ball, chart) rendered under the
 * stitched HDRI, and the grey ball's centre checked against a
 * brute-force irradiance sum. */
static sl_result stage_render(demo *d, char *note, size_t n, sl_error *err)
{
    const char *path = d->hdri;
    sl_image ll, img = {0}, grey = {0};
    sl_result r = demo_hdri(d, &ll, err);
    if (r)
        return r;
    sl_scene scene;
    sl_scene_init(&scene);
    sl_render_options o;
    sl_render_options_init(&o);
    sl_render_stats st = {0}, gst = {0};
    o.spp = d->size == SL_VSET_SIZE_TINY ? 16 : 64;
    if ((r = sl_scene_preset(&scene, "refs", d->size == SL_VSET_SIZE_TINY ? 192 : 480, err)) ||
        (r = sl_scene_set_dome(&scene, &ll, 0, 1, path, err)) ||
        (r = sl_render(&scene, &o, &img, &st, err)))
        goto done;
    sl_report_section(d->rep, "Render");
    sl_report_text(d->rep, "Grey ball, chrome ball and ColorChecker under the stitched HDRI "
                           "(hdri.exr): %lld spp in %.2f s (%.3g samples/s), estimated relative "
                           "RMSE %.2f%%.",
                   (long long)st.spp, st.seconds, st.samples_per_second,
                   st.pass_count ? 100 * st.passes[st.pass_count - 1].est_rel_rmse : 0.0);
    if ((r = sl_report_image(d->rep, "render_refs.png", &img, log2(0.18 / d->lavg),
                             "refs under the stitched hdri.exr", err)))
        goto done;
    if (st.pass_count > 1) {
        double t[64], e[64];
        int m = st.pass_count < 64 ? st.pass_count : 64;
        for (int i = 0; i < m; i++) {
            t[i] = st.passes[i].seconds;
            e[i] = st.passes[i].est_rel_rmse;
        }
        const sl_plot_series conv = {"refs under the stitched HDRI", t, e, m};
        if ((r = sl_report_plot(d->rep, "render_convergence.svg",
                                "render convergence: estimated relative RMSE", "seconds",
                                "relative RMSE", true, true, &conv, 1, err)))
            goto done;
    }
    /* The grey ball alone, its centre pixel against the irradiance sum. */
    sl_scene_free(&scene);
    sl_scene_init(&scene);
    o.spp = 8192;
    o.pixel_centers = true;
    if ((r = sl_scene_preset(&scene, "grey", 9, err)) ||
        (r = sl_scene_set_dome(&scene, &ll, 0, 1, path, err)) ||
        (r = sl_render(&scene, &o, &grey, &gst, err)))
        goto done;
    {
        static const double toward_camera[3] = {0, 0, -1};
        double expected = 0.18 / M_PI * irradiance_y(&ll, toward_camera);
        const float *p = sl_image_pixel(&grey, 4, 4);
        double got = 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
        double rel = got / expected - 1;
        sl_report_text(d->rep, "Grey ball centre: rendered %.5g, brute-force irradiance sum "
                               "%.5g cd/m^2 (%+.2f%%, 8192 samples).",
                       got, expected, 100 * rel);
        snprintf(note, n, "refs %lld spp in %.1f s; grey centre vs irradiance sum %+.2f%%",
                 (long long)st.spp, st.seconds, 100 * rel);
    }
done:
    sl_render_stats_free(&st);
    sl_render_stats_free(&gst);
    sl_scene_free(&scene);
    sl_image_free(&img);
    sl_image_free(&grey);
    sl_image_free(&ll);
    return r;
}

static const struct {
    const char *name;
    const char *what;
    demo_stage_fn fn;
} stages[] = {
    {"simulate", "virtual set photographed: brackets, EXIF, ground truth", stage_simulate},
    {"truth", "ground-truth lat-long and light list read back", stage_truth},
    {"frames", "frames and EXIF read back and checked against the plan", stage_frames},
    {"ingest", "capture folder ingested as a card: views and brackets from EXIF, against the plan",
     stage_ingest},
    {"merge", "one view's bracket merged to HDR, response scored against the truth", stage_merge},
    {"stitch", "each fisheye view's bracket merged, the views stitched to the HDRI from their "
               "EXIF lens, scored against the truth",
     demo_stage_stitch},
    {"unwrap", "chrome-ball bracket merged, ball found, unwrapped: against the truth and as "
               "a cross-check of the stitched HDRI",
     demo_stage_unwrap},
    {"calibrate", "chart colour matrix; grey-ball gains of the stitched HDRI against the camera model",
     demo_stage_calibrate},
    {"rig", "light rig from the stitched HDRI, lights matched to the truth, energy ledger",
     demo_stage_rig},
    {"render", "grey ball, chrome ball and chart rendered under the stitched HDRI", stage_render},
};

/* 0 absent or empty, 1 an earlier demo, 2 something else. */
static int dir_state(const char *dir)
{
    DIR *dp = opendir(dir);
    if (!dp)
        return 0;
    int files = 0;
    bool demo_page = false;
    struct dirent *e;
    while ((e = readdir(dp))) {
        if (!strcmp(e->d_name, ".") || !strcmp(e->d_name, ".."))
            continue;
        files++;
        if (!strcmp(e->d_name, "report.html") || !strcmp(e->d_name, "capture"))
            demo_page = true;
    }
    closedir(dp);
    return files == 0 ? 0 : demo_page ? 1 : 2;
}

int cmd_demo(int argc, char **argv, const sl_cli *cli)
{
    enum { O_SIZE = 256, O_SEED, O_FORCE };
    static const struct option opts[] = {{"size", required_argument, 0, O_SIZE},
                                         {"seed", required_argument, 0, O_SEED},
                                         {"force", no_argument, 0, O_FORCE},
                                         {"help", no_argument, 0, 'h'},
                                         {0, 0, 0, 0}};
    demo d;
    memset(&d, 0, sizeof d);
    d.size = SL_VSET_SIZE_SMALL;
    d.seed = 1;
    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, ":h", opts, NULL)) != -1) {
        switch (c) {
        case 'h': help(stdout); return 0;
        case O_SIZE: {
            int s = sl_vset_size_from_name(optarg);
            if (s != SL_VSET_SIZE_TINY && s != SL_VSET_SIZE_SMALL)
                return cli_usage_error(cli, "--size is tiny or small, not '%s'", optarg);
            d.size = (sl_vset_size)s;
            break;
        }
        case O_SEED: {
            int v;
            if (!cli_parse_int(optarg, &v) || v < 0)
                return cli_usage_error(cli, "--seed needs a whole number >= 0, not '%s'", optarg);
            d.seed = (uint64_t)v;
            break;
        }
        case O_FORCE: d.force = true; break;
        case ':': return cli_usage_error(cli, "%s needs a value", argv[optind - 1]);
        default: return cli_usage_error(cli, "unknown option %s", argv[optind - 1]);
        }
    }
    if (argc - optind > 1)
        return cli_usage_error(cli, "unexpected argument '%s'", argv[optind + 1]);
    d.dir = optind < argc ? argv[optind] : "setlight-demo";
    sl_error err;
    sl_error_clear(&err);
    int state = dir_state(d.dir);
    if (state == 2) {
        sl_error_set(&err, SL_ERR_USAGE, "%s: folder holds other files; choose another", d.dir);
        return cli_fail(cli, &err);
    }
    if (state == 1 && !d.force) {
        sl_error_set(&err, SL_ERR_USAGE, "%s: holds an earlier demo (use --force to replace it)",
                     d.dir);
        return cli_fail(cli, &err);
    }
    if (mkdir(d.dir, 0777) != 0 && errno != EEXIST) {
        sl_error_set(&err, SL_ERR_IO, "%s: cannot create folder: %s", d.dir, strerror(errno));
        return cli_fail(cli, &err);
    }
    snprintf(d.capture, sizeof d.capture, "%s/capture", d.dir);
    sl_result r = sl_report_new(&d.rep, d.dir, "report", "setlight demo: the virtual stage", &err);
    if (r)
        return cli_fail(cli, &err);
    d.facts = json_object();
    sl_report_text(d.rep, "setlight %s simulated the 'stage' virtual set (seed %llu) and ran every "
                          "pipeline stage it has on the capture in %s.",
                   sl_version(), (unsigned long long)d.seed, d.capture);
    int count = (int)(sizeof stages / sizeof stages[0]);
    char notes[16][512];
    double secs[16];
    sl_progress bar;
    sl_progress_begin(&bar, "demo", count);
    for (int i = 0; i < count && !r; i++) {
        double t0 = sl_seconds();
        notes[i][0] = 0;
        r = stages[i].fn(&d, notes[i], sizeof notes[i], &err);
        secs[i] = sl_seconds() - t0;
        sl_log(SL_LOG_INFO, "%s: %s (%.1f s)", stages[i].name, r ? err.message : notes[i],
               secs[i]);
        sl_progress_add(&bar, 1);
    }
    sl_progress_end(&bar);
    sl_image_free(&d.confidence);
    if (r) {
        sl_report_free(d.rep);
        json_decref(d.facts);
        return cli_fail(cli, &err);
    }
    /* The summary is written last but stands at the top of the page. */
    sl_report_top_begin(d.rep);
    sl_report_section(d.rep, "Summary");
    double total = 0;
    for (int i = 0; i < count; i++)
        total += secs[i];
    sl_report_text(d.rep, "Every stage ran (%d stages, %.1f s in all); each one's headline number "
                          "against the ground truth is below, its details further down.",
                   count, total);
    static const char *const head[] = {"stage", "what", "result", "seconds"};
    sl_report_table_begin(d.rep, 4, head);
    for (int i = 0; i < count; i++) {
        char s[32];
        snprintf(s, sizeof s, "%.2f", secs[i]);
        const char *cells[4] = {stages[i].name, stages[i].what, notes[i], s};
        sl_report_table_row(d.rep, cells);
    }
    sl_report_table_end(d.rep);
    sl_report_top_end(d.rep);
    if ((r = sl_report_finish(d.rep, &err))) {
        json_decref(d.facts);
        return cli_fail(cli, &err);
    }
    if (cli->json) {
        char report[4200];
        snprintf(report, sizeof report, "%s/report.html", d.dir);
        json_t *out = json_pack("{s:s, s:[], s:O}", "report", report, "stages", "facts", d.facts);
        json_t *arr = json_object_get(out, "stages");
        for (int i = 0; i < count; i++)
            json_array_append_new(arr, json_pack("{s:s, s:f}", "name", stages[i].name,
                                                 "seconds", round(secs[i] * 1000) / 1000));
        char *text = json_dumps(out, JSON_REAL_PRECISION(6));
        if (text)
            printf("%s\n", text);
        free(text);
        json_decref(out);
    }
    json_decref(d.facts);
    return 0;
}
