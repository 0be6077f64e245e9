/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight calibrate: the HDRI made to match the plate camera through a
 * ColorChecker and a grey sphere shot in the same light. */
#include <stdio.h>
#include <string.h>

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
    "grey photo the result is in cd/m^2. Transform in the output's metadata. The chart's\n"
    "references are for a white light, so with a chart the light on it comes out white\n"
    "(setlight:calibration_white chart); the grey sphere alone keeps the photo's white\n"
    "balance (camera). At least one of --chart, --grey.\n\n"
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
    sl_calibrate_run_options o;
    sl_calibrate_run_options_init(&o);
    double view[2] = {0, 0};

    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, "ho:", opts, NULL)) != -1) {
        switch (c) {
        case 'h':
            fputs(calibrate_help, stdout);
            return 0;
        case 'o':
            o.out_path = optarg;
            break;
        case OPT_HDRI:
            o.hdri_path = optarg;
            break;
        case OPT_CHART:
            o.chart_path = optarg;
            break;
        case OPT_CORNERS:
            if (!cli_parse_list(optarg, &o.corners[0][0], 8))
                return cli_usage_error(cli, "--chart-corners needs 8 numbers, not '%s'", optarg);
            o.have_corners = true;
            break;
        case OPT_REF:
            /* A name is built in; anything else is a file. */
            o.chart_reference = strcmp(optarg, "classic24") != 0 ? optarg : NULL;
            if (o.chart_reference && !strchr(o.chart_reference, '.') && !strchr(o.chart_reference, '/'))
                return cli_usage_error(cli, "unknown chart reference '%s' (classic24 or a .csv/.json file)",
                                       optarg);
            break;
        case OPT_HDRI_IN:
            if (strcmp(optarg, "chart") && strcmp(optarg, "working"))
                return cli_usage_error(cli, "--hdri-in needs chart or working, not '%s'", optarg);
            o.hdri_in_chart = !strcmp(optarg, "chart");
            break;
        case OPT_MASK:
            o.clipped_mask = optarg;
            break;
        case OPT_SUN_SIZE:
            if (!cli_parse_double(optarg, &o.sun.diameter_deg) ||
                !(o.sun.diameter_deg > 0 && o.sun.diameter_deg < 90))
                return cli_usage_error(cli, "--sun-size needs degrees in (0, 90), not '%s'", optarg);
            break;
        case OPT_NO_REPAIR:
            o.sun_repair = false;
            break;
        case OPT_NO_ABS:
            o.absolute = false;
            break;
        case OPT_EXP_TOL:
            if (!cli_parse_double(optarg, &o.exposure_tolerance) || !(o.exposure_tolerance > 0))
                return cli_usage_error(cli, "--exposure-tolerance needs stops > 0, not '%s'", optarg);
            break;
        case OPT_WP:
            o.ccm.white_preserving = true;
            break;
        case OPT_CLIP:
            if (!cli_parse_double(optarg, &o.clip) || !(o.clip > 0))
                return cli_usage_error(cli, "--clip needs a positive level, not '%s'", optarg);
            break;
        case OPT_GREY:
            o.grey_path = optarg;
            break;
        case OPT_CIRCLE:
            if (!cli_parse_list(optarg, o.grey.circle, 3) || !(o.grey.circle[2] > 0))
                return cli_usage_error(cli, "--grey-circle needs CX,CY,R with R > 0, not '%s'",
                                       optarg);
            break;
        case OPT_ALBEDO:
            if (!cli_parse_double(optarg, &o.grey.albedo) || !(o.grey.albedo > 0 && o.grey.albedo <= 1))
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
            int rc = ball_camera_opts_parse(cli, &o.camera, c - OPT_CAMERA, optarg);
            if (rc)
                return rc;
            break;
        }
        case OPT_SPP: {
            int spp;
            if (!cli_parse_int(optarg, &spp) || spp < 1)
                return cli_usage_error(cli, "--spp needs a positive whole number, not '%s'", optarg);
            o.grey.spp = spp;
            break;
        }
        case OPT_FLOAT:
            o.write_float = true;
            break;
        case OPT_REPORT:
            o.report_dir = optarg;
            break;
        case OPT_CS:
        case OPT_CHART_CS:
        case OPT_GREY_CS: {
            const char *name = sl_color_space_name(optarg);
            if (!name)
                return cli_usage_error(cli, "unknown colour space '%s' (see docs/color.md)", optarg);
            if (c == OPT_CS)
                o.out_colorspace = name;
            else if (c == OPT_CHART_CS)
                o.chart_colorspace = name;
            else
                o.grey_colorspace = name;
            break;
        }
        default:
            return cli_usage_error(cli, "unknown option '%s'", argv[optind - 1]);
        }
    }
    if (optind < argc)
        return cli_usage_error(cli, "unexpected argument '%s'", argv[optind]);
    if (!o.hdri_path || !o.out_path)
        return cli_usage_error(cli, "needs --hdri and -o");
    if (!o.chart_path && !o.grey_path)
        return cli_usage_error(cli, "needs --chart, --grey or both");
    if (o.have_corners && !o.chart_path)
        return cli_usage_error(cli, "--chart-corners needs --chart");
    int rc = ball_camera_opts_check(cli, &o.camera);
    if (rc)
        return rc;
    o.grey.azimuth_deg = view[0];
    o.grey.elevation_deg = view[1];

    sl_calibrate_run_result res;
    sl_error err;
    if (sl_calibrate_run(&o, &res, &err))
        return cli_fail(cli, &err);
    if (cli->json)
        printf("%s\n", res.json);
    sl_calibrate_run_result_free(&res);
    return 0;
}
