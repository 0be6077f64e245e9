/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight calibrate: the HDRI made to match the plate camera through a
 * ColorChecker and a grey sphere shot in the same light. */
#include <errno.h>
#include <float.h>
#include <jansson.h>
#include <math.h>
#include <sys/stat.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "cli.h"
#include "setlight/render.h"
#include "setlight/stitch.h"

static const char *calibrate_help =
    "usage: setlight calibrate --hdri ENV.exr [--chart CHART] [--grey GREY.exr\n"
    "                          [--grey-circle CX,CY,R]] -o ENV_CAL.exr [options]\n\n"
    "The chart photo (plate camera) gives a colour matrix from camera RGB to linear\n"
    "Rec.709, scaled to keep the neutral patch's luminance. The grey-sphere photo, shot\n"
    "on the same camera, goes through that matrix; then the HDRI gets the exposure and\n"
    "channel gains that make a virtual grey sphere rendered under it match the photo.\n"
    "With a chart alone, the HDRI is taken to come from the chart's camera and gets the\n"
    "matrix. Transform in the output's setlight:calibration_matrix (and\n"
    "setlight:plate_matrix). At least one of --chart, --grey.\n\n"
    "  --hdri FILE           the lat-long to calibrate (linear)\n"
    "  -o, --output FILE     the calibrated lat-long (EXR, half unless --float)\n"
    "  --chart FILE          chart photo: EXR is read as linear, other formats as sRGB;\n"
    "                        the chart is found automatically (OpenCV mcc)\n"
    "  --chart-corners X1,Y1,X2,Y2,X3,Y3,X4,Y4\n"
    "                        centres of patches 1 (dark skin), 6 (bluish green),\n"
    "                        24 (black), 19 (white) in pixels, instead of detection\n"
    "  --chart-reference R   reference values: classic24 (X-Rite, post-2014)\n"
    "  --white-preserving    the neutral patch maps exactly to its reference\n"
    "  --clip LEVEL          chart/grey pixels at or above are clipped (default: none\n"
    "                        for EXR, 0.999 for 8/16-bit photos)\n"
    "  --grey FILE           grey-sphere photo (linear EXR)\n"
    "  --grey-circle CX,CY,R the sphere's outline in the grey photo, pixels (default:\n"
    "                        found as unwrap finds a ball; none or several: exit 3)\n"
    "  --grey-albedo A       the sphere's albedo (default 0.18)\n"
    "  --grey-view AZ,EL     the photo's view as the validation camera (default 0,0)\n"
    "  --spp N               samples per pixel of the virtual sphere (default 256)\n"
    "  --colorspace NAME     output colour space (OCIO name, default lin_rec709)\n"
    "  --chart-colorspace NAME  the chart photo's colour space (default: srgb for\n"
    "                        8/16-bit photos, the file's own or lin_rec709 for EXR)\n"
    "  --float               write 32-bit float\n"
    "  --report DIR          write DIR/calibrate.html (chart table, grey sphere photo,\n"
    "                        render and error images) and DIR/calibrate.json\n"
    "  --json                print the result as JSON on stdout\n\n"
    "Exit codes: 0 done, 2 usage, 3 bad or missing input (no chart found and no grey\n"
    "sphere, no sphere found or none in the circle), 1 other failures. See\n"
    "docs/calibrate.md.\n";

static bool parse_list(const char *s, double *v, int n)
{
    char buf[512];
    if (strlen(s) >= sizeof buf)
        return false;
    strcpy(buf, s);
    char *save = NULL, *tok = strtok_r(buf, ",", &save);
    for (int i = 0; i < n; i++, tok = strtok_r(NULL, ",", &save))
        if (!tok || !cli_parse_double(tok, &v[i]))
            return false;
    return tok == NULL;
}

static bool is_ldr_path(const char *path)
{
    const char *dot = strrchr(path, '.');
    return dot && strcasecmp(dot, ".exr") != 0 && strcasecmp(dot, ".hdr") != 0;
}

static void mat_apply(const double m[3][3], float *v)
{
    double r[3];
    for (int c = 0; c < 3; c++)
        r[c] = m[c][0] * v[0] + m[c][1] * v[1] + m[c][2] * v[2];
    for (int c = 0; c < 3; c++)
        v[c] = (float)r[c];
}

static void apply_image(sl_image *img, const double m[3][3])
{
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++)
            mat_apply(m, img->data + (size_t)y * img->stride + (size_t)x * img->channels);
}

static json_t *json_matrix(const double m[3][3])
{
    json_t *a = json_array();
    for (int i = 0; i < 3; i++)
        json_array_append_new(a, json_pack("[f,f,f]", m[i][0], m[i][1], m[i][2]));
    return a;
}

int cmd_calibrate(int argc, char **argv, const sl_cli *cli)
{
    enum {
        OPT_HDRI = 1000, OPT_CHART, OPT_CORNERS, OPT_REF, OPT_WP, OPT_CLIP, OPT_GREY,
        OPT_CIRCLE, OPT_ALBEDO, OPT_VIEW, OPT_SPP, OPT_FLOAT, OPT_REPORT, OPT_CS, OPT_CHART_CS
    };
    static const struct option opts[] = {
        {"help", no_argument, NULL, 'h'},
        {"output", required_argument, NULL, 'o'},
        {"hdri", required_argument, NULL, OPT_HDRI},
        {"chart", required_argument, NULL, OPT_CHART},
        {"chart-corners", required_argument, NULL, OPT_CORNERS},
        {"chart-reference", required_argument, NULL, OPT_REF},
        {"white-preserving", no_argument, NULL, OPT_WP},
        {"clip", required_argument, NULL, OPT_CLIP},
        {"grey", required_argument, NULL, OPT_GREY},
        {"grey-circle", required_argument, NULL, OPT_CIRCLE},
        {"grey-albedo", required_argument, NULL, OPT_ALBEDO},
        {"grey-view", required_argument, NULL, OPT_VIEW},
        {"spp", required_argument, NULL, OPT_SPP},
        {"float", no_argument, NULL, OPT_FLOAT},
        {"report", required_argument, NULL, OPT_REPORT},
        {"colorspace", required_argument, NULL, OPT_CS},
        {"chart-colorspace", required_argument, NULL, OPT_CHART_CS},
        {0, 0, 0, 0}};
    const char *hdri_path = NULL, *out_path = NULL, *chart_path = NULL, *grey_path = NULL,
               *report_dir = NULL, *out_cs = "lin_rec709", *chart_cs = NULL;
    double corners[4][2], clip = -1, view[2] = {0, 0};
    bool have_corners = false, have_circle = false, use_float = false;
    sl_ccm_options copt;
    sl_ccm_options_init(&copt);
    sl_grey_options gopt;
    sl_grey_options_init(&gopt);

    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, "+ho:", opts, NULL)) != -1) {
        switch (c) {
        case 'h':
            fputs(calibrate_help, stdout);
            return 0;
        case 'o':
            out_path = optarg;
            break;
        case OPT_HDRI:
            hdri_path = optarg;
            break;
        case OPT_CHART:
            chart_path = optarg;
            break;
        case OPT_CORNERS:
            if (!parse_list(optarg, &corners[0][0], 8))
                return cli_usage_error(cli, "--chart-corners needs 8 numbers, not '%s'", optarg);
            have_corners = true;
            break;
        case OPT_REF:
            if (strcmp(optarg, "classic24") != 0)
                return cli_usage_error(cli, "unknown chart reference '%s' (classic24)", optarg);
            break;
        case OPT_WP:
            copt.white_preserving = true;
            break;
        case OPT_CLIP:
            if (!cli_parse_double(optarg, &clip) || !(clip > 0))
                return cli_usage_error(cli, "--clip needs a positive level, not '%s'", optarg);
            break;
        case OPT_GREY:
            grey_path = optarg;
            break;
        case OPT_CIRCLE:
            if (!parse_list(optarg, gopt.circle, 3) || !(gopt.circle[2] > 0))
                return cli_usage_error(cli, "--grey-circle needs CX,CY,R with R > 0, not '%s'",
                                       optarg);
            have_circle = true;
            break;
        case OPT_ALBEDO:
            if (!cli_parse_double(optarg, &gopt.albedo) || !(gopt.albedo > 0 && gopt.albedo <= 1))
                return cli_usage_error(cli, "--grey-albedo needs a number in (0, 1], not '%s'",
                                       optarg);
            break;
        case OPT_VIEW:
            if (!parse_list(optarg, view, 2))
                return cli_usage_error(cli, "--grey-view needs AZ,EL in degrees, not '%s'", optarg);
            break;
        case OPT_SPP: {
            int spp;
            if (!cli_parse_int(optarg, &spp) || spp < 1)
                return cli_usage_error(cli, "--spp needs a positive whole number, not '%s'", optarg);
            gopt.spp = spp;
            break;
        }
        case OPT_FLOAT:
            use_float = true;
            break;
        case OPT_REPORT:
            report_dir = optarg;
            break;
        case OPT_CS:
        case OPT_CHART_CS: {
            const char *name = sl_color_space_name(optarg);
            if (!name)
                return cli_usage_error(cli, "unknown colour space '%s' (see docs/color.md)", optarg);
            if (c == OPT_CS)
                out_cs = name;
            else
                chart_cs = name;
            break;
        }
        default:
            return cli_usage_error(cli, "unknown option '%s'", argv[optind - 1]);
        }
    }
    if (optind < argc)
        return cli_usage_error(cli, "unexpected argument '%s'", argv[optind]);
    if (!hdri_path || !out_path)
        return cli_usage_error(cli, "needs --hdri and -o");
    if (!chart_path && !grey_path)
        return cli_usage_error(cli, "needs --chart, --grey or both");
    if (have_corners && !chart_path)
        return cli_usage_error(cli, "--chart-corners needs --chart");
    gopt.azimuth_deg = view[0];
    gopt.elevation_deg = view[1];

    sl_image hdri = {0}, chart = {0}, grey = {0};
    sl_meta hmeta, cmeta, gmeta, out_meta;
    sl_meta_init(&hmeta);
    sl_meta_init(&cmeta);
    sl_meta_init(&gmeta);
    sl_meta_init(&out_meta);
    sl_grey_fit gfit = {0};
    sl_error err;
    sl_result r;
    json_t *js = json_object();
    double t[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, plate[3][3];
    bool chart_used = false;
    sl_chart_patch p[24];
    sl_ccm_fit fit;

    if ((r = sl_image_read(hdri_path, &hdri, &hmeta, &err)))
        goto fail;
    if (!sl_is_latlong_shape(hdri.width, hdri.height) || hdri.channels < 3) {
        r = sl_error_set(&err, SL_ERR_INPUT, "%s: not an RGB lat-long (%dx%d, %d channels)",
                         hdri_path, hdri.width, hdri.height, hdri.channels);
        goto fail;
    }
    {
        sl_image_stats st;
        sl_image_stats_compute(&hdri, &st);
        if (st.nan_count + st.inf_count) {
            sl_log(SL_LOG_WARN, "%s: %lld NaN and %lld Inf samples replaced by 0", hdri_path,
                   (long long)st.nan_count, (long long)st.inf_count);
            sl_image_sanitize(&hdri, 0.0f);
        }
    }
    if (chart_path) {
        if ((r = sl_image_read(chart_path, &chart, &cmeta, &err)))
            goto fail;
        if (chart.channels < 3) {
            r = sl_error_set(&err, SL_ERR_INPUT, "%s: the chart photo needs RGB", chart_path);
            goto fail;
        }
        double level = clip;
        const char *cs = chart_cs ? chart_cs
                         : is_ldr_path(chart_path) ? "srgb"
                         : sl_meta_color_space(&cmeta) ? sl_meta_color_space(&cmeta)
                                                       : "lin_rec709";
        /* Clipping is judged on the file's values, before any conversion;
         * clipped pixels then carry FLT_MAX, which the sampler counts as clipped. */
        if (level < 0 && is_ldr_path(chart_path))
            level = 0.999;
        unsigned char *clipped = NULL;
        if (level > 0) {
            clipped = calloc((size_t)chart.width * chart.height, 1);
            if (!clipped) {
                r = sl_error_set(&err, SL_ERR_NOMEM, "%s: out of memory", chart_path);
                goto fail;
            }
            for (int y = 0; y < chart.height; y++)
                for (int x = 0; x < chart.width; x++) {
                    const float *v =
                        chart.data + (size_t)y * chart.stride + (size_t)x * chart.channels;
                    clipped[(size_t)y * chart.width + x] =
                        v[0] >= level || v[1] >= level || v[2] >= level;
                }
        }
        if (strcmp(cs, "lin_rec709") != 0 &&
            (r = sl_color_convert(&chart, cs, "lin_rec709", &err))) {
            free(clipped);
            goto fail;
        }
        if (clipped) {
            for (int y = 0; y < chart.height; y++)
                for (int x = 0; x < chart.width; x++)
                    if (clipped[(size_t)y * chart.width + x]) {
                        float *v =
                            chart.data + (size_t)y * chart.stride + (size_t)x * chart.channels;
                        v[0] = v[1] = v[2] = FLT_MAX;
                    }
            free(clipped);
            level = FLT_MAX;
        } else {
            level = 0;
        }
        double centers[24][2];
        json_t *jc = json_object();
        json_object_set_new(js, "chart", jc);
        json_object_set_new(jc, "file", json_string(chart_path));
        if (have_corners) {
            r = sl_chart_centers_from_corners((const double(*)[2])corners, centers, &err);
            json_object_set_new(jc, "located", json_string("corners"));
        } else {
            sl_chart_detection det;
            r = sl_chart_detect(&chart, level, chart_path, &det, &err);
            if (!r)
                memcpy(centers, det.centers, sizeof(centers));
            json_object_set_new(jc, "located", json_string(r ? "not found" : "detected"));
        }
        if (r == SL_ERR_INPUT && !have_corners && grey_path) {
            /* No chart: the grey sphere alone still calibrates exposure and balance. */
            sl_log(SL_LOG_WARN, "%s; continuing with the grey sphere alone", err.message);
        } else if (r) {
            goto fail;
        } else {
            if ((r = sl_chart_sample(&chart, (const double(*)[2])centers, 0, level, p, &err)))
                goto fail;
            if ((r = sl_ccm_fit_chart(p, SL_COLORCHECKER_LINEAR, &copt, &fit, &err))) {
                sl_error_set(&err, r, "%s: %s", chart_path, err.message);
                goto fail;
            }
            sl_ccm_plate_matrix(p, &fit, t);
            chart_used = true;
            json_t *jp = json_array();
            int excluded = 0;
            for (int q = 0; q < 24; q++) {
                excluded += !fit.used_patch[q];
                json_array_append_new(
                    jp, json_pack("{s:i, s:s, s:[f,f], s:i, s:i, s:b, s:f, s:f}", "patch", q + 1,
                                  "name", SL_COLORCHECKER_NAMES[q], "center", p[q].center[0],
                                  p[q].center[1], "pixels", p[q].pixels, "clipped", p[q].clipped,
                                  "used", fit.used_patch[q], "delta_e_before", fit.de_before[q],
                                  "delta_e_after", fit.de_after[q]));
            }
            if (excluded)
                sl_log(SL_LOG_WARN, "%s: %d patches excluded (clipped, shadowed or unusable)",
                       chart_path, excluded);
            json_object_set_new(jc, "patches", jp);
            json_object_set_new(jc, "matrix", json_matrix(fit.m));
            json_object_set_new(jc, "patches_used", json_integer(fit.used));
            json_object_set_new(jc, "delta_e_before_mean", json_real(fit.de_before_mean));
            json_object_set_new(jc, "delta_e_before_max", json_real(fit.de_before_max));
            json_object_set_new(jc, "delta_e_after_mean", json_real(fit.de_after_mean));
            json_object_set_new(jc, "delta_e_after_max", json_real(fit.de_after_max));
            memcpy(plate, t, sizeof(plate));
        }
    }
    if (grey_path) {
        if ((r = sl_image_read(grey_path, &grey, &gmeta, &err)))
            goto fail;
        if (grey.channels < 3) {
            r = sl_error_set(&err, SL_ERR_INPUT, "%s: the grey-sphere photo needs RGB", grey_path);
            goto fail;
        }
        if (!have_circle) {
            /* Found as unwrap finds a chrome ball: Hough candidates, sub-pixel edge fit. */
            sl_ball_circle bc;
            if ((r = sl_ball_detect(&grey, grey_path, &bc, &err))) {
                if (r == SL_ERR_INPUT)
                    sl_error_set(&err, r,
                                 "%s: no grey sphere found (one whole sphere in the frame is "
                                 "needed; or give --grey-circle CX,CY,R)",
                                 grey_path);
                goto fail;
            }
            gopt.circle[0] = bc.cx, gopt.circle[1] = bc.cy, gopt.circle[2] = bc.r;
        }
        if (chart_used) {
            /* The grey sphere was shot on the plate's camera, like the chart:
             * into the working space through the chart's matrix, clipped
             * pixels marked first (the fit skips non-finite ones). */
            for (int y = 0; y < grey.height; y++)
                for (int x = 0; x < grey.width; x++) {
                    float *v = grey.data + (size_t)y * grey.stride + (size_t)x * grey.channels;
                    if (clip > 0 && (v[0] >= clip || v[1] >= clip || v[2] >= clip))
                        v[0] = v[1] = v[2] = NAN;
                }
            apply_image(&grey, plate);
        } else {
            gopt.clip_level = clip > 0 ? clip : 0;
        }
        if ((r = sl_grey_sphere_fit(&hdri, &grey, &gopt, &gfit, &err))) {
            sl_error_set(&err, r, "%s: %s", grey_path, err.message);
            goto fail;
        }
        memset(t, 0, sizeof(t));
        for (int i = 0; i < 3; i++)
            t[i][i] = gfit.gain[i];
        apply_image(&hdri, t);
        json_object_set_new(js, "grey",
                            json_pack("{s:s, s:[f,f,f], s:[f,f,f], s:f, s:[f,f,f], s:I, s:I, s:f, s:f, s:f}",
                                      "file", grey_path, "circle", gopt.circle[0],
                                      gopt.circle[1], gopt.circle[2], "gain", gfit.gain[0],
                                      gfit.gain[1],
                                      gfit.gain[2], "scale", gfit.scale, "balance",
                                      gfit.balance[0], gfit.balance[1], gfit.balance[2], "pixels",
                                      (json_int_t)gfit.pixels, "rejected",
                                      (json_int_t)gfit.rejected, "rel_rmse_before",
                                      gfit.rel_rmse_before, "rel_rmse_after",
                                      gfit.rel_rmse_after, "error_p95", gfit.error_p95));
    } else if (chart_used) {
        /* Chart alone: the HDRI is taken to come from the chart's camera. */
        apply_image(&hdri, plate);
    } else {
        r = sl_error_set(&err, SL_ERR_INPUT, "%s: nothing to calibrate with", hdri_path);
        goto fail;
    }
    char buf[512];
    snprintf(buf, sizeof buf, "%.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g", t[0][0], t[0][1],
             t[0][2], t[1][0], t[1][1], t[1][2], t[2][0], t[2][1], t[2][2]);
    if ((r = sl_meta_set(&out_meta, "setlight:calibration_matrix", buf, &err)))
        goto fail;
    if (chart_used) {
        snprintf(buf, sizeof buf, "%.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g %.9g", plate[0][0],
                 plate[0][1], plate[0][2], plate[1][0], plate[1][1], plate[1][2], plate[2][0],
                 plate[2][1], plate[2][2]);
        if ((r = sl_meta_set(&out_meta, "setlight:plate_matrix", buf, &err)))
            goto fail;
    }
    snprintf(buf, sizeof buf, "%.9g", grey_path ? gfit.scale : 1.0);
    if ((r = sl_meta_set(&out_meta, "setlight:calibration_scale", buf, &err)) ||
        (r = sl_meta_set(&out_meta, "setlight:source", hdri_path, &err)))
        goto fail;
    snprintf(buf, sizeof buf, "setlight %s calibrate%s%s%s%s", sl_version(),
             chart_used ? " --chart " : "", chart_used ? chart_path : "",
             grey_path ? " --grey " : "", grey_path ? grey_path : "");
    if ((r = sl_meta_set(&out_meta, "setlight:command", buf, &err)) ||
        (r = sl_meta_set_color_space(&out_meta, out_cs, &err)))
        goto fail;
    if (strcmp(out_cs, "lin_rec709") != 0 &&
        (r = sl_color_convert(&hdri, "lin_rec709", out_cs, &err)))
        goto fail;
    out_meta.envmap = SL_ENVMAP_LATLONG;
    if ((r = sl_image_write(out_path, &hdri, &out_meta, use_float ? SL_PIXEL_FLOAT : SL_PIXEL_HALF,
                            &err)))
        goto fail;
    json_object_set_new(js, "hdri", json_string(hdri_path));
    json_object_set_new(js, "output", json_string(out_path));
    json_object_set_new(js, "matrix", json_matrix(t));
    if (chart_used)
        json_object_set_new(js, "plate_matrix", json_matrix(plate));
    json_object_set_new(js, "scale", json_real(grey_path ? gfit.scale : 1.0));
    if (report_dir) {
        if (mkdir(report_dir, 0777) && errno != EEXIST) {
            r = sl_error_set(&err, SL_ERR_IO, "%s: cannot create the report folder: %s",
                             report_dir, strerror(errno));
            goto fail;
        }
        sl_report *rep = NULL;
        if ((r = sl_report_new(&rep, report_dir, "calibrate", "setlight calibrate", &err)))
            goto fail;
        sl_report_text(rep, "HDRI %s calibrated to %s.", hdri_path, out_path);
        if ((r = sl_calibrate_report(rep, "", chart_used ? p : NULL, chart_used ? &fit : NULL,
                                     grey_path ? &gfit : NULL, &err))) {
            sl_report_free(rep);
            goto fail;
        }
        if ((r = sl_report_finish(rep, &err)))
            goto fail;
        char *text = json_dumps(js, JSON_INDENT(2));
        char path[4096];
        snprintf(path, sizeof path, "%s/calibrate.json", report_dir);
        r = text ? sl_write_file_atomic(path, text, strlen(text), &err)
                 : sl_error_set(&err, SL_ERR_NOMEM, "%s: out of memory", path);
        free(text);
        if (r)
            goto fail;
    }
    if (cli->json) {
        json_dumpf(js, stdout, JSON_INDENT(2));
        fputc('\n', stdout);
    }
    json_decref(js);
    sl_grey_fit_free(&gfit);
    sl_image_free(&hdri);
    sl_image_free(&chart);
    sl_image_free(&grey);
    sl_meta_free(&hmeta);
    sl_meta_free(&cmeta);
    sl_meta_free(&gmeta);
    sl_meta_free(&out_meta);
    return 0;

fail:
    json_decref(js);
    sl_grey_fit_free(&gfit);
    sl_image_free(&hdri);
    sl_image_free(&chart);
    sl_image_free(&grey);
    sl_meta_free(&hmeta);
    sl_meta_free(&cmeta);
    sl_meta_free(&gmeta);
    sl_meta_free(&out_meta);
    return cli_fail(cli, &err);
}
