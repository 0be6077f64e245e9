/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight calibrate: the HDRI made to match the plate camera through a
 * ColorChecker and a grey sphere shot in the same light. */
#include <errno.h>
#include <float.h>
#include <jansson.h>
#include <math.h>
#include <sys/stat.h>
#include <unistd.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "ball_camera_opts.h"
#include "cli.h"
#include "setlight/render.h"
#include "setlight/stitch.h"

static const char *calibrate_help =
    "usage: setlight calibrate --hdri ENV.exr [--chart CHART] [--grey GREY.exr\n"
    "                          [--grey-circle CX,CY,R]] -o ENV_CAL.exr [options]\n\n"
    "The chart photo gives a colour matrix P from camera RGB to linear Rec.709, scaled\n"
    "to keep the neutral patch's luminance. The grey-sphere photo, shot on the same\n"
    "camera, goes through P, and so does the HDRI (--hdri-in chart, the default); then\n"
    "the HDRI gets the gains g that make a virtual grey sphere rendered under it match\n"
    "the photo: T = diag(g) P. A source clipped in every frame of the merge (the merge's\n"
    "clipped mask) is repaired from the grey sphere first. With EXIF exposure on the\n"
    "grey photo the result is in cd/m^2. Transform in the output's metadata. At least\n"
    "one of --chart, --grey.\n\n"
    "  --hdri FILE           the lat-long to calibrate (read as every command reads an\n"
    "                        environment: scene-linear through OpenColorIO, a 2:1\n"
    "                        image without envmap attribute taken as a lat-long)\n"
    "  -o, --output FILE     the calibrated lat-long (EXR, half unless --float)\n"
    "  --chart FILE          chart photo, converted to linear from its colour space\n"
    "                        (8/16-bit: sRGB unless the file names one; docs/color.md);\n"
    "                        the chart is found automatically (OpenCV mcc), then judged:\n"
    "                        most patches under one light, the neutral row darkening\n"
    "                        step by step with the chart's contrast, the colour patches\n"
    "                        saturated and in hue order, a camera's matrix, CIEDE2000\n"
    "                        after the fit below the patches' own spacing. A chart that\n"
    "                        fails is not used: the grey sphere alone calibrates, or\n"
    "                        exit 3 with every reason. On success one line on stderr:\n"
    "                        patches used, CIEDE2000 before and after\n"
    "  --chart-corners X1,Y1,X2,Y2,X3,Y3,X4,Y4\n"
    "                        centres of patches 1 (dark skin), 6 (bluish green),\n"
    "                        24 (black), 19 (white) in pixels, instead of detection\n"
    "  --chart-reference R   reference values: classic24 (X-Rite, post-2014) or a CSV\n"
    "                        or JSON file of 24 values (Lab D50, XYZ D50 or linear\n"
    "                        Rec.709; docs/calibrate.md)\n"
    "  --white-preserving    the neutral patch maps exactly to its reference\n"
    "  --clip LEVEL          chart/grey pixels at or above are clipped (default: none\n"
    "                        for float files, 0.999 for 8/16-bit photos)\n"
    "  --grey FILE           grey-sphere photo (read as the chart photo)\n"
    "  --grey-colorspace NAME  its colour space (default as for the chart photo)\n"
    "  --hdri-in SPACE       chart: the HDRI is in the chart camera's RGB and goes\n"
    "                        through P (default); working: it is already linear\n"
    "                        Rec.709 from its own camera, only the gains apply\n"
    "  --clipped-mask FILE   the merge's clipped mask (default: the HDRI's\n"
    "                        setlight:merge:clipped_mask, when that file exists)\n"
    "  --sun-size DEG        angular diameter of the clipped source (default 0.53)\n"
    "  --no-sun-repair       leave clipped sources as they are\n"
    "  --no-absolute         keep the grey photo's units instead of cd/m^2\n"
    "  --exposure-tolerance STOPS  grey photo's EXIF vs the HDRI's allowed (default 1)\n"
    "  --grey-circle CX,CY,R the sphere's outline in the grey photo, pixels (default:\n"
    "                        found as unwrap finds a ball; none or several: exit 3)\n"
    "  --grey-albedo A       the sphere's albedo (default 0.18)\n"
    "  --grey-view AZ,EL     the photo's view as the validation camera (default 0,0)\n"
    "  --camera MODEL        grey photo's camera, ortho or perspective (default:\n"
    "                        perspective when the focal length, field of view or\n"
    "                        distance is known; as setlight unwrap)\n"
    "  --focal-mm F          lens focal length (default: the EXIF one when\n"
    "                        --sensor-mm is given)\n"
    "  --sensor-mm W         sensor width in mm (with the focal length)\n"
    "  --fov DEG             horizontal field of view of the whole grey photo instead\n"
    "  --distance MM         camera to sphere centre (needs --ball-diameter)\n"
    "  --ball-diameter MM    the grey sphere's diameter\n"
    "  --spp N               samples per pixel of the virtual sphere (default 256)\n"
    "  --colorspace NAME     output colour space (OCIO name, default lin_rec709)\n"
    "  --chart-colorspace NAME  the chart photo's colour space (default: the one the\n"
    "                        file names, else srgb for 8/16-bit, lin_rec709 for float)\n"
    "  --float               write 32-bit float\n"
    "  --report DIR          write DIR/calibrate.html (chart table, where the patches\n"
    "                        were found with each excluded one's reason, the chart's\n"
    "                        verdict, grey sphere photo, render and error images) and\n"
    "                        DIR/calibrate.json\n"
    "  --json                print the result as JSON on stdout\n\n"
    "Output samples a matrix sends below zero are set to 0 (counted on stderr and in\n"
    "the JSON's negative_clamped).\n\n"
    "Exit codes: 0 done, 2 usage, 3 bad or missing input (no chart found, or not a\n"
    "usable ColorChecker, and no grey sphere; no sphere found or none in the circle;\n"
    "a grey photo whose exposure contradicts the HDRI's), 1 other failures, 130/143\n"
    "interrupted. The HDRI and the report's files are replaced together: a failure or\n"
    "an interrupt leaves every earlier one as it was. See docs/calibrate.md.\n";

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

/* Brings a photo into the working space (linear Rec.709) as every command
 * does (sl_image_linearize: from `cs`, or NULL for the file's own space,
 * sRGB for 8/16-bit photos that name none). Clipping is judged on the
 * file's values before the conversion (*level: the --clip level, < 0 for
 * the default: 0.999 for 8/16-bit photos, none for float); clipped pixels
 * then carry `marker` and *level becomes what the later stages test against. */
static sl_result to_working(sl_image *img, const char *path, sl_meta *meta, const char *cs,
                            double *level, float marker, sl_error *err)
{
    if (*level < 0 && !meta->is_float)
        *level = 0.999;
    /* No level given for a float file: values pinned at its top are clipped. */
    double pinned[3] = {0, 0, 0};
    int64_t pinned_count = *level < 0 ? sl_pinned_maximum(img, pinned) : 0;
    if (pinned_count)
        sl_log(SL_LOG_WARN, "%s: %lld pixels pinned at the image's maximum (%g %g %g per "
               "channel, 0: none) taken as clipped (--clip LEVEL sets the level)", path,
               (long long)pinned_count, pinned[0], pinned[1], pinned[2]);
    unsigned char *clipped = NULL;
    if (*level > 0 || pinned_count) {
        clipped = calloc((size_t)img->width * img->height, 1);
        if (!clipped)
            return sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
        for (int y = 0; y < img->height; y++)
            for (int x = 0; x < img->width; x++) {
                const float *v = img->data + (size_t)y * img->stride + (size_t)x * img->channels;
                bool over = *level > 0 && (v[0] >= *level || v[1] >= *level || v[2] >= *level);
                for (int c = 0; c < 3; c++)
                    over = over || (pinned[c] > 0 && v[c] >= pinned[c]);
                clipped[(size_t)y * img->width + x] = over;
            }
    }
    sl_result r = sl_image_linearize(img, meta, path, cs, NULL, err);
    if (r) {
        free(clipped);
        return r;
    }
    if (clipped) {
        for (int y = 0; y < img->height; y++)
            for (int x = 0; x < img->width; x++)
                if (clipped[(size_t)y * img->width + x]) {
                    float *v = img->data + (size_t)y * img->stride + (size_t)x * img->channels;
                    v[0] = v[1] = v[2] = marker;
                }
        free(clipped);
        *level = isnan(marker) ? 0 : marker;
    } else {
        *level = 0;
    }
    return SL_OK;
}

static json_t *json_matrix(const double m[3][3])
{
    json_t *a = json_array();
    for (int i = 0; i < 3; i++)
        json_array_append_new(a, json_pack("[f,f,f]", m[i][0], m[i][1], m[i][2]));
    return a;
}

static json_t *judgement_json(const sl_chart_judgement *j)
{
    return json_pack("{s:b, s:s, s:i, s:i, s:i, s:f, s:i, s:f, s:f, s:i, s:f, s:f}", "plausible",
                     j->plausible, "reasons", j->text, "patches_used", j->used, "neutrals_used",
                     j->neutrals_used, "order_breaks", j->order_breaks, "neutral_slope",
                     j->neutral_slope, "colours_usable", j->colours_usable, "colour_chroma",
                     j->colour_chroma, "neutral_chroma", j->neutral_chroma, "hue_turns",
                     j->hue_turns, "condition", j->condition, "delta_e_limit", j->de_limit);
}

int cmd_calibrate(int argc, char **argv, const sl_cli *cli)
{
    enum {
        OPT_HDRI = 1000, OPT_CHART, OPT_CORNERS, OPT_REF, OPT_WP, OPT_CLIP, OPT_GREY,
        OPT_CIRCLE, OPT_ALBEDO, OPT_VIEW, OPT_SPP, OPT_FLOAT, OPT_REPORT, OPT_CS, OPT_CHART_CS,
        OPT_GREY_CS, OPT_HDRI_IN, OPT_MASK, OPT_SUN_SIZE, OPT_NO_REPAIR, OPT_NO_ABS, OPT_EXP_TOL,
        OPT_CAMERA, OPT_FOCAL, OPT_SENSOR, OPT_FOV, OPT_DIST, OPT_DIAM
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
        {"grey-colorspace", required_argument, NULL, OPT_GREY_CS},
        {"hdri-in", required_argument, NULL, OPT_HDRI_IN},
        {"clipped-mask", required_argument, NULL, OPT_MASK},
        {"sun-size", required_argument, NULL, OPT_SUN_SIZE},
        {"no-sun-repair", no_argument, NULL, OPT_NO_REPAIR},
        {"no-absolute", no_argument, NULL, OPT_NO_ABS},
        {"exposure-tolerance", required_argument, NULL, OPT_EXP_TOL},
        {"camera", required_argument, NULL, OPT_CAMERA},
        {"focal-mm", required_argument, NULL, OPT_FOCAL},
        {"sensor-mm", required_argument, NULL, OPT_SENSOR},
        {"fov", required_argument, NULL, OPT_FOV},
        {"distance", required_argument, NULL, OPT_DIST},
        {"ball-diameter", required_argument, NULL, OPT_DIAM},
        {0, 0, 0, 0}};
    const char *hdri_path = NULL, *out_path = NULL, *chart_path = NULL, *grey_path = NULL,
               *report_dir = NULL, *out_cs = "lin_rec709", *chart_cs = NULL, *grey_cs = NULL,
               *ref_path = NULL, *mask_path = NULL;
    double corners[4][2], clip = -1, view[2] = {0, 0}, exp_tol = 1;
    ball_camera_opts bc;
    ball_camera_opts_init(&bc);
    bool have_corners = false, have_circle = false, use_float = false, hdri_in_chart = true,
         sun_repair = true, absolute = true;
    sl_sun_options sopt;
    sl_sun_options_init(&sopt);
    sl_ccm_options copt;
    sl_ccm_options_init(&copt);
    sl_grey_options gopt;
    sl_grey_options_init(&gopt);

    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, "ho:", opts, NULL)) != -1) {
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
            if (!cli_parse_list(optarg, &corners[0][0], 8))
                return cli_usage_error(cli, "--chart-corners needs 8 numbers, not '%s'", optarg);
            have_corners = true;
            break;
        case OPT_REF:
            /* A name is built in; anything else is a file. */
            ref_path = strcmp(optarg, "classic24") != 0 ? optarg : NULL;
            if (ref_path && !strchr(ref_path, '.') && !strchr(ref_path, '/'))
                return cli_usage_error(cli, "unknown chart reference '%s' (classic24 or a .csv/.json file)",
                                       optarg);
            break;
        case OPT_HDRI_IN:
            if (strcmp(optarg, "chart") && strcmp(optarg, "working"))
                return cli_usage_error(cli, "--hdri-in needs chart or working, not '%s'", optarg);
            hdri_in_chart = !strcmp(optarg, "chart");
            break;
        case OPT_MASK:
            mask_path = optarg;
            break;
        case OPT_SUN_SIZE:
            if (!cli_parse_double(optarg, &sopt.diameter_deg) ||
                !(sopt.diameter_deg > 0 && sopt.diameter_deg < 90))
                return cli_usage_error(cli, "--sun-size needs degrees in (0, 90), not '%s'", optarg);
            break;
        case OPT_NO_REPAIR:
            sun_repair = false;
            break;
        case OPT_NO_ABS:
            absolute = false;
            break;
        case OPT_EXP_TOL:
            if (!cli_parse_double(optarg, &exp_tol) || !(exp_tol > 0))
                return cli_usage_error(cli, "--exposure-tolerance needs stops > 0, not '%s'", optarg);
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
            if (!cli_parse_list(optarg, gopt.circle, 3) || !(gopt.circle[2] > 0))
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
            if (!cli_parse_list(optarg, view, 2))
                return cli_usage_error(cli, "--grey-view needs AZ,EL in degrees, not '%s'", optarg);
            break;
        case OPT_CAMERA:
        case OPT_FOCAL:
        case OPT_SENSOR:
        case OPT_FOV:
        case OPT_DIST:
        case OPT_DIAM: {
            int rc = ball_camera_opts_parse(cli, &bc, c - OPT_CAMERA, optarg);
            if (rc)
                return rc;
            break;
        }
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
        case OPT_CHART_CS:
        case OPT_GREY_CS: {
            const char *name = sl_color_space_name(optarg);
            if (!name)
                return cli_usage_error(cli, "unknown colour space '%s' (see docs/color.md)", optarg);
            if (c == OPT_CS)
                out_cs = name;
            else if (c == OPT_CHART_CS)
                chart_cs = name;
            else
                grey_cs = name;
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
    int rc = ball_camera_opts_check(cli, &bc);
    if (rc)
        return rc;
    gopt.azimuth_deg = view[0];
    gopt.elevation_deg = view[1];

    sl_image hdri = {0}, chart = {0}, grey = {0}, mask = {0};
    sl_meta hmeta, cmeta, gmeta, mmeta, out_meta;
    sl_meta_init(&hmeta);
    sl_meta_init(&cmeta);
    sl_meta_init(&gmeta);
    sl_meta_init(&mmeta);
    sl_meta_init(&out_meta);
    sl_grey_fit gfit = {0};
    sl_sun_repair sun = {0};
    sl_error err;
    sl_result r;
    json_t *js = json_object();
    double t[3][3] = {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, plate[3][3], reference[24][3];
    bool chart_used = false, plate_on_hdri = false;
    double abs_scale = 0; /* cd/m^2 per unit of the calibrated HDRI, 0: relative */
    char abs_from[256] = "";
    char mask_buf[4096];
    sl_chart_patch p[24];
    sl_ccm_fit fit;
    sl_chart_judgement judgement;
    bool chart_sampled = false;
    memset(&fit, 0, sizeof(fit));
    memset(&judgement, 0, sizeof(judgement));

    memcpy(reference, SL_COLORCHECKER_LINEAR, sizeof(reference));
    if (ref_path && (r = sl_chart_reference_read(ref_path, reference, NULL, &err)))
        goto fail;
    /* Scene-linear Rec.709, as every command reads a lat-long. */
    if ((r = sl_latlong_read(hdri_path, NULL, &hdri, &hmeta, NULL, &err)))
        goto fail;
    if (hdri.channels < 3) {
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
        if ((r = to_working(&chart, chart_path, &cmeta, chart_cs, &level, FLT_MAX, &err)))
            goto fail;
        double centers[24][2];
        json_t *jc = json_object();
        json_object_set_new(js, "chart", jc);
        json_object_set_new(jc, "file", json_string(chart_path));
        json_object_set_new(jc, "reference", json_string(ref_path ? ref_path : "classic24"));
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
            chart_sampled = true;
            if ((r = sl_ccm_fit_chart(p, (const double(*)[3])reference, &copt, &fit, &err))) {
                if (r != SL_ERR_INPUT || !grey_path) {
                    sl_error_set(&err, r, "%s: %s", chart_path, err.message);
                    goto fail;
                }
                /* Too few patches for any matrix: judged as such below. */
                memset(&fit, 0, sizeof(fit));
                snprintf(judgement.text, sizeof judgement.text, "%.600s", err.message);
                judgement.reasons = SL_CHART_FEW_PATCHES;
            } else {
                sl_chart_judge(p, &fit, (const double(*)[3])reference, &judgement);
            }
            json_t *jp = json_array();
            int invalid = 0;
            for (int q = 0; q < 24; q++) {
                invalid += !p[q].valid;
                json_array_append_new(
                    jp, json_pack("{s:i, s:s, s:[f,f], s:i, s:i, s:f, s:b, s:b, s:f, s:f}", "patch",
                                  q + 1, "name", SL_COLORCHECKER_NAMES[q], "center",
                                  p[q].center[0], p[q].center[1], "pixels", p[q].pixels,
                                  "clipped", p[q].clipped, "spread", p[q].spread, "outlier",
                                  fit.outlier[q], "used", fit.used_patch[q], "delta_e_before",
                                  fit.de_before[q], "delta_e_after", fit.de_after[q]));
            }
            json_object_set_new(jc, "patches", jp);
            json_object_set_new(jc, "matrix", json_matrix(fit.m));
            json_object_set_new(jc, "patches_used", json_integer(fit.used));
            json_object_set_new(jc, "patches_invalid", json_integer(invalid));
            json_object_set_new(jc, "patches_outliers", json_integer(fit.outliers));
            json_object_set_new(jc, "delta_e_before_mean", json_real(fit.de_before_mean));
            json_object_set_new(jc, "delta_e_before_max", json_real(fit.de_before_max));
            json_object_set_new(jc, "delta_e_after_mean", json_real(fit.de_after_mean));
            json_object_set_new(jc, "delta_e_after_max", json_real(fit.de_after_max));
            json_object_set_new(jc, "judgement", judgement_json(&judgement));
            if (!judgement.plausible) {
                /* Not a ColorChecker, or not one a matrix can be trusted from. */
                if (!grey_path) {
                    r = sl_error_set(&err, SL_ERR_INPUT, "%s: not a usable ColorChecker: %s",
                                     chart_path, judgement.text);
                    goto fail;
                }
                sl_log(SL_LOG_WARN, "%s: not a usable ColorChecker (%s); calibrating with the "
                       "grey sphere alone", chart_path, judgement.text);
            } else {
                sl_ccm_plate_matrix(p, &fit, plate);
                chart_used = true;
                sl_log(SL_LOG_INFO,
                       "%s: ColorChecker, %d of 24 patches used (%d excluded, %d lit "
                       "differently); CIEDE2000 mean %.2f -> %.2f, max %.2f -> %.2f",
                       chart_path, fit.used, invalid, fit.outliers, fit.de_before_mean,
                       fit.de_after_mean, fit.de_before_max, fit.de_after_max);
            }
            json_object_set_new(jc, "used", json_boolean(chart_used));
        }
    }
    if (chart_used && (hdri_in_chart || !grey_path)) {
        /* The HDRI in the chart camera's RGB: into the working space through P. */
        apply_image(&hdri, plate);
        memcpy(t, plate, sizeof(t));
        plate_on_hdri = true;
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
        /* Clipped pixels are judged on the file's values and carry NaN from
         * then on, which the fit skips. */
        double level = clip;
        if ((r = to_working(&grey, grey_path, &gmeta, grey_cs, &level, NAN, &err)))
            goto fail;
        if (chart_used) {
            /* Shot on the plate's camera, like the chart. */
            apply_image(&grey, plate);
        }
        gopt.clip_level = level;
        /* The photo's camera, as unwrap takes it: focal length in pixels of
         * this image from the lens (EXIF when only the sensor is given) or
         * the field of view; distance in sphere radii. */
        ball_camera_opts_geometry(&bc, grey.width, gmeta.focal_length_mm, &gopt.focal_px,
                                  &gopt.distance);
        if (bc.camera == SL_BALL_ORTHOGRAPHIC)
            gopt.focal_px = gopt.distance = 0;
        else if (bc.camera == SL_BALL_PERSPECTIVE && gopt.focal_px == 0 && gopt.distance == 0) {
            r = sl_error_set(&err, SL_ERR_USAGE,
                             "%s: --camera perspective needs the focal length (--focal-mm and "
                             "--sensor-mm, EXIF, or --fov) or --distance", grey_path);
            goto fail;
        }
        /* The merge's clipped mask: a source clipped in every frame. */
        const char *mp = mask_path ? mask_path : sl_meta_get(&hmeta, "setlight:merge:clipped_mask");
        if (mp && !mask_path && access(mp, R_OK) != 0) {
            /* Recorded relative to where the merge ran: try beside the HDRI. */
            const char *slash = strrchr(hdri_path, '/'), *base = strrchr(mp, '/');
            snprintf(mask_buf, sizeof mask_buf, "%.*s%s", slash ? (int)(slash - hdri_path + 1) : 0,
                     hdri_path, base ? base + 1 : mp);
            if (access(mask_buf, R_OK) == 0) {
                mp = mask_buf;
            } else {
                sl_log(SL_LOG_WARN, "%s: its clipped mask %s is missing; no sun repair", hdri_path,
                       mp);
                mp = NULL;
            }
        }
        if (mp && sun_repair) {
            if ((r = sl_image_read(mp, &mask, &mmeta, &err)))
                goto fail;
            r = sl_sun_repair_fit(&hdri, &mask, &grey, &gopt, &sopt, &sun, &err);
            if (r == SL_ERR_INPUT) {
                sl_log(SL_LOG_WARN, "%s: %s; not repaired", mp, err.message);
                json_object_set_new(js, "sun_repair", json_pack("{s:s, s:s}", "mask", mp,
                                                                "error", err.message));
                memset(&sun, 0, sizeof(sun));
            } else if (r) {
                goto fail;
            }
        }
        if ((r = sl_grey_sphere_fit(&hdri, &grey, &gopt, &gfit, &err))) {
            sl_error_set(&err, r, "%s: %s", grey_path, err.message);
            goto fail;
        }
        double g[3][3] = {{gfit.gain[0], 0, 0}, {0, gfit.gain[1], 0}, {0, 0, gfit.gain[2]}};
        apply_image(&hdri, g);
        sl_mat3_mul(g, t, t);
        /* Absolute: the grey photo's exposure gives cd/m^2 per unit. */
        double lp = sl_exposure_luminance(gmeta.exposure_time, gmeta.f_number, gmeta.iso);
        if (lp > 0) {
            /* The HDRI's own exposure: its EXIF, else the merge's reference frame. */
            double eh = hmeta.exposure_time > 0 && hmeta.f_number > 0 && hmeta.iso > 0
                            ? hmeta.exposure_time * hmeta.iso / (hmeta.f_number * hmeta.f_number)
                            : 0;
            const char *ref = sl_meta_get(&hmeta, "setlight:merge:reference_exposure");
            if (!(eh > 0) && ref)
                eh = strtod(ref, NULL);
            double ep = gmeta.exposure_time * gmeta.iso / (gmeta.f_number * gmeta.f_number);
            if (eh > 0 && isfinite(eh)) {
                /* Photo units per HDRI unit: the metadata says ep / eh, the sphere says scale. */
                double stops = log2(gfit.scale * eh / ep);
                json_object_set_new(js, "exposure_check",
                                    json_pack("{s:f, s:f, s:f, s:f}", "hdri_exposure", eh,
                                              "grey_exposure", ep, "disagreement_stops", stops,
                                              "tolerance_stops", exp_tol));
                if (!(fabs(stops) <= exp_tol)) {
                    r = sl_error_set(&err, SL_ERR_INPUT,
                                     "%s: exposure metadata (%g s, f/%g, ISO %g) contradicts "
                                     "the HDRI's (reference exposure %g): the grey sphere puts "
                                     "them %.2f stops apart (tolerance %g)",
                                     grey_path, gmeta.exposure_time, gmeta.f_number, gmeta.iso,
                                     eh, stops, exp_tol);
                    goto fail;
                }
            }
            if (absolute) {
                abs_scale = lp;
                snprintf(abs_from, sizeof abs_from, "%s: %g s, f/%g, ISO %g", grey_path,
                         gmeta.exposure_time, gmeta.f_number, gmeta.iso);
                double a[3][3] = {{lp, 0, 0}, {0, lp, 0}, {0, 0, lp}};
                apply_image(&hdri, a);
                sl_mat3_mul(a, t, t);
            }
        }
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
        json_object_set_new(json_object_get(js, "grey"), "camera",
                            json_pack("{s:s, s:f, s:f}", "model",
                                      gopt.focal_px > 0 || gopt.distance > 0 ? "perspective"
                                                                             : "orthographic",
                                      "focal_px", gopt.focal_px, "distance_radii", gopt.distance));
        if (sun.repaired) {
            /* In the output's units: times the gains and the absolute scale. */
            double k = abs_scale > 0 ? abs_scale : 1, rad[3], sig[3], added[3], before[3];
            for (int ch = 0; ch < 3; ch++) {
                rad[ch] = sun.radiance[ch] * gfit.gain[ch] * k;
                sig[ch] = sun.radiance_sigma[ch] * gfit.gain[ch] * k;
                added[ch] = sun.energy_added[ch] * gfit.gain[ch] * k;
                before[ch] = sun.energy_before[ch] * gfit.gain[ch] * k;
            }
            double la = 0.2126 * added[0] + 0.7152 * added[1] + 0.0722 * added[2];
            double lb = 0.2126 * before[0] + 0.7152 * before[1] + 0.0722 * before[2];
            sl_log(SL_LOG_INFO,
                   "%s: clipped source at azimuth %.2f, elevation %.2f repaired: radiance %.4g "
                   "(+-%.2f%%), %.1f%% energy added; grey sphere error %.2f%% -> %.2f%%",
                   hdri_path, sun.azimuth_deg, sun.elevation_deg,
                   0.2126 * rad[0] + 0.7152 * rad[1] + 0.0722 * rad[2],
                   100 * sun.radiance_sigma[1] / fmax(sun.fitted[1], 1e-30),
                   lb > 0 ? 100 * la / lb : 0, 100 * sun.rel_rmse_before,
                   100 * gfit.rel_rmse_after);
            json_object_set_new(
                js, "sun_repair",
                json_pack("{s:s, s:I, s:f, s:f, s:f, s:f, s:f, s:[f,f,f], s:[f,f,f], s:[f,f,f], "
                          "s:[f,f,f], s:f, s:f, s:f}",
                          "mask", mp, "clipped_texels",
                          (json_int_t)sun.clipped_texels, "clipped_solid_angle_sr",
                          sun.solid_angle, "azimuth_deg", sun.azimuth_deg, "elevation_deg",
                          sun.elevation_deg, "diameter_deg", sopt.diameter_deg,
                          "source_solid_angle_sr", sun.source_solid_angle, "radiance", rad[0],
                          rad[1], rad[2], "radiance_sigma", sig[0], sig[1], sig[2],
                          "energy_before", before[0], before[1], before[2], "energy_added",
                          added[0], added[1], added[2], "energy_added_fraction",
                          lb > 0 ? la / lb : 0, "rel_rmse_before", sun.rel_rmse_before,
                          "rel_rmse_after", sun.rel_rmse_after));
        }
    } else if (!chart_used) {
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
        if ((r = sl_meta_set(&out_meta, "setlight:plate_matrix", buf, &err)) ||
            (r = sl_meta_set(&out_meta, "setlight:calibration_hdri_in",
                             plate_on_hdri ? "chart" : "working", &err)))
            goto fail;
    }
    snprintf(buf, sizeof buf, "%.9g", grey_path ? gfit.scale : 1.0);
    if ((r = sl_meta_set(&out_meta, "setlight:calibration_scale", buf, &err)) ||
        (r = sl_meta_set(&out_meta, "setlight:source", hdri_path, &err)) ||
        (r = sl_meta_set(&out_meta, "setlight:units", abs_scale > 0 ? "cd/m^2" : "relative",
                         &err)))
        goto fail;
    if (abs_scale > 0) {
        snprintf(buf, sizeof buf, "%.9g", abs_scale);
        if ((r = sl_meta_set(&out_meta, "setlight:absolute_scale", buf, &err)) ||
            (r = sl_meta_set(&out_meta, "setlight:absolute_from", abs_from, &err)))
            goto fail;
    }
    if (sun.repaired) {
        snprintf(buf, sizeof buf,
                 "azimuth %.4f elevation %.4f diameter %.4f radiance %.9g %.9g %.9g sigma %.9g %.9g "
                 "%.9g (before the calibration transform)",
                 sun.azimuth_deg, sun.elevation_deg, sopt.diameter_deg, sun.radiance[0],
                 sun.radiance[1], sun.radiance[2], sun.radiance_sigma[0], sun.radiance_sigma[1],
                 sun.radiance_sigma[2]);
        if ((r = sl_meta_set(&out_meta, "setlight:sun_repair", buf, &err)))
            goto fail;
    }
    snprintf(buf, sizeof buf, "setlight %s calibrate%s%s%s%s", sl_version(),
             chart_used ? " --chart " : "", chart_used ? chart_path : "",
             grey_path ? " --grey " : "", grey_path ? grey_path : "");
    if ((r = sl_meta_set(&out_meta, "setlight:command", buf, &err)) ||
        (r = sl_meta_set_color_space(&out_meta, out_cs, &err)))
        goto fail;
    if (strcmp(out_cs, "lin_rec709") != 0 &&
        (r = sl_color_convert(&hdri, "lin_rec709", out_cs, &err)))
        goto fail;
    {
        /* Never negative radiance: colours outside the working gamut and
         * noise round black come out of a matrix below zero. */
        double neg_fraction;
        int64_t neg = sl_calibrate_clamp_negative(&hdri, &neg_fraction);
        if (neg)
            sl_log(SL_LOG_WARN, "%s: %lld samples below zero after calibration (colours outside "
                   "the output's gamut, noise round black) set to 0: %.3g%% of the light",
                   hdri_path, (long long)neg, 100 * neg_fraction);
        json_object_set_new(js, "negative_clamped",
                            json_pack("{s:I, s:f}", "samples", (json_int_t)neg, "fraction",
                                      neg_fraction));
    }
    out_meta.envmap = SL_ENVMAP_LATLONG;
    /* The HDRI and the report are one set, renamed into place together:
     * an interrupt or a failure leaves every earlier one as it was. */
    char report_glob[4096];
    snprintf(report_glob, sizeof report_glob, "%s/*", report_dir ? report_dir : "");
    const char *members[2] = {out_path, report_dir ? report_glob : NULL};
    if ((r = sl_output_set_begin(members, 2, &err)))
        goto fail;
    if ((r = sl_image_write(out_path, &hdri, &out_meta, use_float ? SL_PIXEL_FLOAT : SL_PIXEL_HALF,
                            &err)))
        goto fail;
    json_object_set_new(js, "hdri", json_string(hdri_path));
    json_object_set_new(js, "output", json_string(out_path));
    json_object_set_new(js, "hdri_in", json_string(plate_on_hdri ? "chart" : "working"));
    json_object_set_new(js, "matrix", json_matrix(t));
    if (chart_used)
        json_object_set_new(js, "plate_matrix", json_matrix(plate));
    json_object_set_new(js, "scale", json_real(grey_path ? gfit.scale : 1.0));
    json_object_set_new(js, "units", json_string(abs_scale > 0 ? "cd/m^2" : "relative"));
    if (abs_scale > 0)
        json_object_set_new(js, "absolute",
                            json_pack("{s:f, s:s}", "cd_m2_per_unit", abs_scale, "from", abs_from));
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
        if (sun.repaired)
            sl_report_text(rep,
                           "Clipped source at azimuth %.2f, elevation %.2f (%lld texels clipped): "
                           "fitted radiance %.4g (+-%.2f%%, in the HDRI's units before the "
                           "transform); grey sphere error with the clipped map %.2f%%, with "
                           "the repair %.2f%%.",
                           sun.azimuth_deg, sun.elevation_deg, (long long)sun.clipped_texels,
                           0.2126 * sun.radiance[0] + 0.7152 * sun.radiance[1] +
                               0.0722 * sun.radiance[2],
                           100 * sun.radiance_sigma[1] / fmax(sun.fitted[1], 1e-30),
                           100 * sun.rel_rmse_before, 100 * sun.rel_rmse_after);
        if (abs_scale > 0)
            sl_report_text(rep, "Absolute: %.6g cd/m^2 per unit of the grey photo (%s).",
                           abs_scale, abs_from);
        if ((r = sl_calibrate_report(rep, "", chart_used ? p : NULL, chart_used ? &fit : NULL,
                                     grey_path ? &gfit : NULL, &err)) ||
            (chart_sampled &&
             (r = sl_calibrate_report_chart(rep, "chart_patches.png", &chart, p, &fit, &judgement,
                                            &err)))) {
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
    if ((r = sl_output_set_commit(&err)))
        goto fail;
    if (cli->json) {
        json_dumpf(js, stdout, JSON_INDENT(2));
        fputc('\n', stdout);
    }
    r = SL_OK;

fail:
    if (r)
        sl_output_set_abort();
    json_decref(js);
    sl_grey_fit_free(&gfit);
    sl_image_free(&hdri);
    sl_image_free(&chart);
    sl_image_free(&grey);
    sl_image_free(&mask);
    sl_meta_free(&hmeta);
    sl_meta_free(&cmeta);
    sl_meta_free(&gmeta);
    sl_meta_free(&mmeta);
    sl_meta_free(&out_meta);
    return r ? cli_fail(cli, &err) : 0;
}
