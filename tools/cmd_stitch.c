/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight stitch -o OUT.exr VIEW...: HDR fisheye views to one lat-long. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "setlight/stitch.h"

static const char *stitch_help =
    "usage: setlight stitch [options] -o OUT.exr VIEW...\n\n"
    "Stitches HDR views of one circular fisheye on a nodal head (what 'setlight merge'\n"
    "writes, one per view) into one lat-long of the set's radiance: each view's image\n"
    "circle is found, the lens (focal length, centre, radial correction, vignetting) and\n"
    "the views' rotations are solved from their overlaps starting from the nominal lens\n"
    "(the optical centre also from the image circles' centre, unless the overlaps\n"
    "disagree with it), and the views are blended in radiance (a weighted mean: no light\n"
    "made or lost).\n"
    "View 1 fixes the frame: its axis is +Z on the horizon.\n\n"
    "  -o, --output OUT.exr     the lat-long: RGB and the confidence in A (0 where filled)\n"
    "  --projection NAME        equisolid (default), equidistant, stereographic,\n"
    "                           orthographic or rectilinear\n"
    "  --focal-mm F             nominal focal length (default: the files' EXIF)\n"
    "  --sensor-mm W[,H]        sensor size (default: the files' or the camera body's)\n"
    "  --lens-profile FILE      a solved lens (setlight-lens JSON) instead of the nominal\n"
    "                           one; only the rotations are solved\n"
    "  --save-lens FILE         write the lens used (solved) as a profile\n"
    "  --report FILE.html       an HTML report: the solved lens, pairs, reprojection\n"
    "                           error, coverage and confidence map, the views and their\n"
    "                           circles (images beside it as FILE_*.png)\n"
    "  --yaw Y1,Y2,...          nominal yaws in degrees (default: evenly over 360)\n"
    "  --pitch P1,P2,...        nominal pitches (default 0; +90 looks up)\n"
    "  --roll R1,R2,...         nominal rolls (default 0)\n"
    "  --no-solve               blend with the nominal (or profile) lens and poses\n"
    "  --nadir-mask DEG|IMAGE   leave out directions within DEG of the nadir (a tripod,\n"
    "                           a head), or where a lat-long mask image is above 0.5;\n"
    "                           filled smoothly from around and flagged\n"
    "  --width N                output width (even; default: the views' pixel density on\n"
    "                           the horizon, 2 pi focal_px, at most 8192)\n"
    "  --ghost R                views that disagree by more than this fraction take the\n"
    "                           best single view (default 0.3; 0: off)\n"
    "  --float                  32-bit float EXR (default half; float anyway when the\n"
    "                           radiance exceeds half's range)\n"
    "  --compression C          zip (default), piz, rle or none (all lossless)\n"
    "  --input-colorspace NAME  the views' colour space, instead of the one the file names\n"
    "  --json                   print the result as JSON on stdout\n\n"
    "Views wider than 3072 px are solved on a copy reduced 2x (or 4x) and kept as half\n"
    "when every sample is a half value (as merge writes them): three 24 MP views to\n"
    "8192 x 4096 take under 1 GB.\n"
    "A view's merge mask (setlight:merge:clipped_mask) lowers the weight of its clipped\n"
    "pixels. The report (stderr, --json) gives the solved values and their change from\n"
    "the nominal ones, the matches per pair (a pair without enough falls back to its\n"
    "nominal rotation, and says so), the reprojection error, and the solid angle seen,\n"
    "filled and masked.\n"
    "Exit codes: 0 done, 1 failure, 2 usage error, 3 bad input (unreadable, views of\n"
    "different sizes or cameras, no image circle, no lens information, NaN/Inf samples,\n"
    "views that do not overlap, a lens profile for another camera).\n"
    "See docs/stitch.md.\n";

/* A comma-separated list of up to max numbers; its count, or -1. */
static int parse_angles(const char *s, double *v, int max)
{
    int n = 1;
    for (const char *p = s; *p; p++)
        n += *p == ',';
    if (n > max || !cli_parse_list(s, v, n))
        return -1;
    return n;
}

int cmd_stitch(int argc, char **argv, const sl_cli *cli)
{
    enum {
        OPT_PROJ = 1000, OPT_FOCAL, OPT_SENSOR, OPT_PROFILE, OPT_SAVE, OPT_YAW, OPT_PITCH,
        OPT_ROLL, OPT_NOSOLVE, OPT_NADIR, OPT_WIDTH, OPT_GHOST, OPT_FLOAT, OPT_COMPRESSION,
        OPT_INCS, OPT_REPORT
    };
    static const struct option opts[] = {{"help", no_argument, NULL, 'h'},
                                         {"output", required_argument, NULL, 'o'},
                                         {"projection", required_argument, NULL, OPT_PROJ},
                                         {"focal-mm", required_argument, NULL, OPT_FOCAL},
                                         {"sensor-mm", required_argument, NULL, OPT_SENSOR},
                                         {"lens-profile", required_argument, NULL, OPT_PROFILE},
                                         {"save-lens", required_argument, NULL, OPT_SAVE},
                                         {"report", required_argument, NULL, OPT_REPORT},
                                         {"yaw", required_argument, NULL, OPT_YAW},
                                         {"pitch", required_argument, NULL, OPT_PITCH},
                                         {"roll", required_argument, NULL, OPT_ROLL},
                                         {"no-solve", no_argument, NULL, OPT_NOSOLVE},
                                         {"nadir-mask", required_argument, NULL, OPT_NADIR},
                                         {"width", required_argument, NULL, OPT_WIDTH},
                                         {"ghost", required_argument, NULL, OPT_GHOST},
                                         {"float", no_argument, NULL, OPT_FLOAT},
                                         {"compression", required_argument, NULL, OPT_COMPRESSION},
                                         {"input-colorspace", required_argument, NULL, OPT_INCS},
                                         {0, 0, 0, 0}};
    const char *out_path = NULL, *mask_path = NULL;
    sl_stitch_options o;
    sl_stitch_options_init(&o);
    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, "ho:", opts, NULL)) != -1) {
        double v = 0, wh[2];
        switch (c) {
        case 'h':
            fputs(stitch_help, stdout);
            return 0;
        case 'o':
            out_path = optarg;
            break;
        case OPT_PROJ:
            if ((o.projection = sl_lens_projection_from_name(optarg)) < 0)
                return cli_usage_error(cli, "--projection is equisolid, equidistant, "
                                            "stereographic, orthographic or rectilinear, not '%s'",
                                       optarg);
            break;
        case OPT_FOCAL:
            if (!cli_parse_double(optarg, &o.focal_mm) || !(o.focal_mm > 0 && o.focal_mm < 2000))
                return cli_usage_error(cli, "--focal-mm needs millimetres > 0, not '%s'", optarg);
            break;
        case OPT_SENSOR:
            if (cli_parse_list(optarg, wh, 2) && wh[0] > 0 && wh[1] > 0) {
                o.sensor_mm[0] = wh[0];
                o.sensor_mm[1] = wh[1];
            } else if (cli_parse_double(optarg, &v) && v > 0) {
                o.sensor_mm[0] = v;
            } else {
                return cli_usage_error(cli, "--sensor-mm needs W or W,H in millimetres, not '%s'",
                                       optarg);
            }
            break;
        case OPT_PROFILE:
            o.lens_profile = optarg;
            break;
        case OPT_SAVE:
            o.save_lens = optarg;
            break;
        case OPT_REPORT:
            o.report = optarg;
            break;
        case OPT_YAW:
        case OPT_PITCH:
        case OPT_ROLL: {
            double *list = c == OPT_YAW ? o.yaw_deg : c == OPT_PITCH ? o.pitch_deg : o.roll_deg;
            int n = parse_angles(optarg, list, SL_STITCH_MAX_VIEWS);
            if (n < 0)
                return cli_usage_error(cli, "--%s needs up to %d comma-separated degrees, not '%s'",
                                       c == OPT_YAW ? "yaw" : c == OPT_PITCH ? "pitch" : "roll",
                                       SL_STITCH_MAX_VIEWS, optarg);
            *(c == OPT_YAW ? &o.yaw_count : c == OPT_PITCH ? &o.pitch_count : &o.roll_count) = n;
            break;
        }
        case OPT_NOSOLVE:
            o.solve = false;
            break;
        case OPT_NADIR:
            if (cli_parse_double(optarg, &v)) {
                if (!(v > 0 && v < 90))
                    return cli_usage_error(cli, "--nadir-mask needs degrees in (0, 90) or a mask "
                                                "image, not '%s'", optarg);
                o.blend.nadir_mask_deg = v;
            } else {
                mask_path = optarg;
            }
            break;
        case OPT_WIDTH:
            if (!cli_parse_int(optarg, &o.blend.width) || o.blend.width < 16 ||
                o.blend.width > 65536 || o.blend.width % 2)
                return cli_usage_error(cli, "--width needs an even number from 16 to 65536, not "
                                            "'%s'", optarg);
            break;
        case OPT_GHOST:
            if (!cli_parse_double(optarg, &o.blend.ghost_ratio) || !(o.blend.ghost_ratio >= 0))
                return cli_usage_error(cli, "--ghost needs a fraction >= 0, not '%s'", optarg);
            break;
        case OPT_FLOAT:
            o.pixel_type = SL_PIXEL_FLOAT;
            break;
        case OPT_COMPRESSION:
            if (!cli_parse_compression(optarg, &o.compression))
                return cli_usage_error(cli, "--compression is piz, zip, rle or none, not '%s'",
                                       optarg);
            break;
        case OPT_INCS:
            if (!(o.input_colorspace = sl_color_space_name(optarg)))
                return cli_usage_error(cli, "unknown colour space '%s' (see docs/color.md)",
                                       optarg);
            break;
        default:
            return cli_usage_error(cli, "unknown option '%s'", argv[optind - 1]);
        }
    }
    if (!out_path)
        return cli_usage_error(cli, "needs an output file (-o OUT.exr)");
    int count = argc - optind;
    if (count < 1)
        return cli_usage_error(cli, "needs at least one view");
    if (count > SL_STITCH_MAX_VIEWS)
        return cli_usage_error(cli, "at most %d views, not %d", SL_STITCH_MAX_VIEWS, count);
    if (o.yaw_count > count || o.pitch_count > count || o.roll_count > count)
        return cli_usage_error(cli, "more --yaw/--pitch/--roll values than the %d views", count);
    if (o.lens_profile && (o.focal_mm > 0 || o.sensor_mm[0] > 0 || o.projection >= 0))
        return cli_usage_error(cli, "give --lens-profile or --projection/--focal-mm/--sensor-mm, "
                                    "not both");
    sl_stitch_run_options so;
    sl_stitch_run_options_init(&so);
    so.view_paths = (const char *const *)argv + optind;
    so.view_count = count;
    so.out_path = out_path;
    so.mask_path = mask_path;
    so.stitch = o;
    sl_stitch_run_result res;
    sl_error err;
    if (sl_stitch_run(&so, &res, &err)) {
        sl_stitch_run_result_free(&res);
        return cli_fail(cli, &err);
    }
    if (cli->json)
        printf("%s\n", res.json);
    sl_stitch_run_result_free(&res);
    return 0;
}
