/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight unwrap -o OUT.exr BALL: chrome-ball photo to lat-long. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "ball_camera_opts.h"
#include "cli.h"
#include "setlight/stitch.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static const char *unwrap_help =
    "usage: setlight unwrap [options] -o OUT.exr BALL [BALL2]\n\n"
    "Unwraps a linear HDR photo of a chrome ball into a lat-long of the set's radiance\n"
    "(OpenEXR orientation, envmap attribute). The ball is found automatically unless\n"
    "--circle is given. The camera looks along +Z with +Y up unless turned with\n"
    "--camera-azimuth/--camera-elevation/--camera-roll, so the renderer's own chrome\n"
    "sphere unwraps to the environment it was lit by.\n\n"
    "  -o, --output OUT.exr   the lat-long (RGB plus confidence in A, see below)\n"
    "  --circle CX,CY,R       the ball's outline in pixels (image corner 0,0; pixel\n"
    "                         centres at +0.5); must lie inside the image\n"
    "  --camera MODEL         ortho or perspective (default: perspective when the\n"
    "                         focal length, field of view or distance is known)\n"
    "  --focal-mm F           lens focal length (default: the EXIF one when\n"
    "                         --sensor-mm is given)\n"
    "  --sensor-mm W          sensor width in mm (with the focal length)\n"
    "  --fov DEG              horizontal field of view of the whole image instead\n"
    "  --distance MM          camera to ball centre (needs --ball-diameter)\n"
    "  --ball-diameter MM     the ball's diameter\n"
    "  --camera-azimuth DEG   camera direction in the set: +90 looks along +X\n"
    "  --camera-elevation DEG +90 looks straight up\n"
    "  --camera-roll DEG      positive turns the camera's up toward its right\n"
    "  --reflectance R        ball reflectance: a number (1 = ideal mirror, the\n"
    "                         default), R,G,B, or 'chrome' (Fresnel of a conductor,\n"
    "                         0.55 head-on rising to 1 at grazing)\n"
    "  --reflectance-patch AZ,EL,RADIUS,L[,G,B]\n"
    "                         solve the reflectance instead: the set patch in direction\n"
    "                         AZ,EL (degrees, like the camera's) of RADIUS degrees has\n"
    "                         radiance L (or R,G,B), e.g. a grey card measured directly\n"
    "Second view (BALL2, the same ball from about 90 degrees around it):\n"
    "  --circle2 CX,CY,R      its circle (default: detected)\n"
    "  --camera2-azimuth DEG  its camera direction (default: --camera-azimuth + 90)\n"
    "  --camera2-elevation DEG, --camera2-roll DEG (default: view 1's)\n"
    "  --search DEG           refine view 2's azimuth within +-DEG from the overlap\n"
    "                         (default 20; 0 keeps it as given)\n"
    "  --occluder DEG         half-angle of the cone around each camera (the camera\n"
    "                         and photographer) taken from the other view (default 20)\n"
    "  --width N              output width (even; default: one texel per photo pixel\n"
    "                         where the ball faces the camera)\n"
    "  --no-confidence        write RGB only\n"
    "  --float                32-bit float EXR instead of half\n"
    "  --compression C        zip (default), piz, rle or none (all lossless)\n"
    "  --input-colorspace NAME  the photos' colour space (OCIO name), instead of the\n"
    "                         one the file names or the default (srgb for 8/16-bit)\n"
    "  --json                 print the result as JSON on stdout\n\n"
    "The A channel is the confidence: resolution relative to the ball's centre, 0 in\n"
    "the blind cone behind the ball (filled flat with the rim's median). An 8/16-bit\n"
    "photo (JPEG, PNG, TIFF) is converted to scene-linear through OpenColorIO from its\n"
    "colour space (sRGB unless the file says otherwise), with a warning: its\n"
    "highlights are clipped, so bright sources come out too dark (docs/color.md).\n"
    "The ball is found on tight crops (its outline touching the frame) and among\n"
    "clutter; discs, rings and clock faces are not balls, the largest ball is\n"
    "taken over ones under 0.7 of its radius, and the fit's standard error is\n"
    "reported (circle.uncertainty in --json). A light-probe map (a disc filling\n"
    "its square frame on black: Debevec's angular probes, mirror-ball maps) is no\n"
    "photo: use 'setlight convert --from angular|mirrorball', or --circle.\n"
    "Exit codes: 0 done, 1 failure, 2 usage error (bad option, circle outside the\n"
    "image), 3 bad input (unreadable, a circular fisheye photo (use 'setlight\n"
    "stitch'), a light-probe map without --circle, no ball, two balls, ball cut\n"
    "by the frame, outline fitted too weakly (give --circle), reflectance patch\n"
    "not seen).\n"
    "See docs/unwrap.md.\n";

int cmd_unwrap(int argc, char **argv, const sl_cli *cli)
{
    enum {
        OPT_CIRCLE = 1000, OPT_CAMERA, OPT_FOCAL, OPT_SENSOR, OPT_FOV, OPT_DIST, OPT_DIAM,
        OPT_AZ, OPT_EL, OPT_ROLL, OPT_REFL, OPT_WIDTH, OPT_NOCONF, OPT_FLOAT, OPT_PATCH,
        OPT_CIRCLE2, OPT_AZ2, OPT_EL2, OPT_ROLL2, OPT_SEARCH, OPT_OCCLUDER, OPT_COMPRESSION,
        OPT_INCS
    };
    static const struct option opts[] = {{"help", no_argument, NULL, 'h'},
                                         {"output", required_argument, NULL, 'o'},
                                         {"circle", required_argument, NULL, OPT_CIRCLE},
                                         {"camera", required_argument, NULL, OPT_CAMERA},
                                         {"focal-mm", required_argument, NULL, OPT_FOCAL},
                                         {"sensor-mm", required_argument, NULL, OPT_SENSOR},
                                         {"fov", required_argument, NULL, OPT_FOV},
                                         {"distance", required_argument, NULL, OPT_DIST},
                                         {"ball-diameter", required_argument, NULL, OPT_DIAM},
                                         {"camera-azimuth", required_argument, NULL, OPT_AZ},
                                         {"camera-elevation", required_argument, NULL, OPT_EL},
                                         {"camera-roll", required_argument, NULL, OPT_ROLL},
                                         {"reflectance", required_argument, NULL, OPT_REFL},
                                         {"reflectance-patch", required_argument, NULL, OPT_PATCH},
                                         {"width", required_argument, NULL, OPT_WIDTH},
                                         {"no-confidence", no_argument, NULL, OPT_NOCONF},
                                         {"float", no_argument, NULL, OPT_FLOAT},
                                         {"compression", required_argument, NULL, OPT_COMPRESSION},
                                         {"input-colorspace", required_argument, NULL, OPT_INCS},
                                         {"circle2", required_argument, NULL, OPT_CIRCLE2},
                                         {"camera2-azimuth", required_argument, NULL, OPT_AZ2},
                                         {"camera2-elevation", required_argument, NULL, OPT_EL2},
                                         {"camera2-roll", required_argument, NULL, OPT_ROLL2},
                                         {"search", required_argument, NULL, OPT_SEARCH},
                                         {"occluder", required_argument, NULL, OPT_OCCLUDER},
                                         {0, 0, 0, 0}};
    sl_unwrap_run_options ro;
    sl_unwrap_run_options_init(&ro);
    sl_unwrap_options *o = &ro.pair.views[0], *o2 = &ro.pair.views[1];
    bool have_refl = false;

    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, "ho:", opts, NULL)) != -1) {
        double v = 0;
        switch (c) {
        case 'h':
            fputs(unwrap_help, stdout);
            return 0;
        case 'o':
            ro.out_path = optarg;
            break;
        case OPT_CIRCLE:
        case OPT_CIRCLE2: {
            double xyz[3];
            if (!cli_parse_list(optarg, xyz, 3) || !(xyz[2] > 0))
                return cli_usage_error(cli, "%s needs CX,CY,R with R > 0, not '%s'",
                                       c == OPT_CIRCLE ? "--circle" : "--circle2", optarg);
            sl_ball_circle *ci = c == OPT_CIRCLE ? &o->circle : &o2->circle;
            ci->cx = xyz[0];
            ci->cy = xyz[1];
            ci->r = xyz[2];
            ro.have_circle[c == OPT_CIRCLE ? 0 : 1] = true;
            break;
        }
        case OPT_CAMERA:
        case OPT_FOCAL:
        case OPT_SENSOR:
        case OPT_FOV:
        case OPT_DIST:
        case OPT_DIAM: {
            int rc = ball_camera_opts_parse(cli, &ro.camera, c - OPT_CAMERA, optarg);
            if (rc)
                return rc;
            break;
        }
        case OPT_AZ:
        case OPT_EL:
        case OPT_ROLL:
        case OPT_AZ2:
        case OPT_EL2:
        case OPT_ROLL2:
            if (!cli_parse_double(optarg, &v) || !isfinite(v))
                return cli_usage_error(cli, "camera angles are numbers of degrees, not '%s'",
                                       optarg);
            if (c == OPT_AZ2 || c == OPT_EL2 || c == OPT_ROLL2) {
                int i = c == OPT_AZ2 ? 0 : (c == OPT_EL2 ? 1 : 2);
                ro.camera2[i] = v;
                ro.have_camera2[i] = true;
            } else {
                *(c == OPT_AZ   ? &o->geometry.azimuth_deg
                  : c == OPT_EL ? &o->geometry.elevation_deg
                                : &o->geometry.roll_deg) = v;
            }
            break;
        case OPT_SEARCH:
        case OPT_OCCLUDER:
            if (!cli_parse_double(optarg, &v) || !(v >= 0) ||
                !(v <= (c == OPT_SEARCH ? 90 : 60)))
                return cli_usage_error(cli, "%s needs degrees from 0 to %d, not '%s'",
                                       c == OPT_SEARCH ? "--search" : "--occluder",
                                       c == OPT_SEARCH ? 90 : 60, optarg);
            *(c == OPT_SEARCH ? &ro.pair.search_deg : &ro.pair.occluder_deg) = v;
            break;
        case OPT_REFL: {
            double rgb[3];
            have_refl = true;
            if (!strcmp(optarg, "chrome"))
                sl_reflectance_chrome(&o->reflectance);
            else if (cli_parse_list(optarg, rgb, 1) && rgb[0] > 0 && rgb[0] <= 1)
                sl_reflectance_constant(&o->reflectance, rgb[0], rgb[0], rgb[0]);
            else if (cli_parse_list(optarg, rgb, 3) && rgb[0] > 0 && rgb[1] > 0 && rgb[2] > 0 &&
                     rgb[0] <= 1 && rgb[1] <= 1 && rgb[2] <= 1)
                sl_reflectance_constant(&o->reflectance, rgb[0], rgb[1], rgb[2]);
            else
                return cli_usage_error(
                    cli, "--reflectance is R or R,G,B in (0, 1], or chrome, not '%s'", optarg);
            break;
        }
        case OPT_PATCH:
            if (cli_parse_list(optarg, ro.patch, 4)) {
                ro.patch[4] = ro.patch[5] = ro.patch[3];
            } else if (!cli_parse_list(optarg, ro.patch, 6)) {
                return cli_usage_error(cli, "--reflectance-patch needs AZ,EL,RADIUS,L or "
                                            "AZ,EL,RADIUS,R,G,B, not '%s'", optarg);
            }
            if (!(ro.patch[2] > 0 && ro.patch[2] < 90) || !(ro.patch[3] > 0 && ro.patch[4] > 0 && ro.patch[5] > 0))
                return cli_usage_error(cli, "--reflectance-patch needs a radius in (0, 90) degrees "
                                            "and a positive radiance, not '%s'", optarg);
            ro.have_patch = true;
            break;
        case OPT_WIDTH:
            if (!cli_parse_int(optarg, &o->width) || o->width < 8 || o->width > 65536 ||
                o->width % 2)
                return cli_usage_error(cli, "--width needs an even number from 8 to 65536, not "
                                            "'%s'", optarg);
            break;
        case OPT_INCS:
            if (!(ro.input_colorspace = sl_color_space_name(optarg)))
                return cli_usage_error(cli, "unknown colour space '%s' (see docs/color.md)", optarg);
            break;
        case OPT_NOCONF:
            ro.confidence = false;
            break;
        case OPT_FLOAT:
            ro.write_float = true;
            break;
        case OPT_COMPRESSION:
            if (!cli_parse_compression(optarg, &ro.compression))
                return cli_usage_error(cli, "--compression is piz, zip, rle or none, not '%s'",
                                       optarg);
            break;
        default:
            return cli_usage_error(cli, "unknown option '%s'", argv[optind - 1]);
        }
    }
    if (!ro.out_path)
        return cli_usage_error(cli, "needs an output file (-o OUT.exr)");
    int nviews = argc - optind;
    if (nviews < 1)
        return cli_usage_error(cli, "needs a ball photo");
    if (nviews > 2)
        return cli_usage_error(cli, "one or two ball photos, not %d", nviews);
    int rc = ball_camera_opts_check(cli, &ro.camera);
    if (rc)
        return rc;
    if (ro.have_patch && have_refl)
        return cli_usage_error(cli, "give --reflectance or --reflectance-patch, not both");
    if (nviews == 1 && (ro.have_circle[1] || ro.have_camera2[0] || ro.have_camera2[1] || ro.have_camera2[2]))
        return cli_usage_error(cli, "--circle2 and --camera2-* need a second ball photo");
    ro.photo_count = nviews;
    ro.photo_paths[0] = argv[optind];
    ro.photo_paths[1] = nviews == 2 ? argv[optind + 1] : NULL;
    sl_unwrap_run_result res;
    sl_error err;
    if (sl_unwrap_run(&ro, &res, &err))
        return cli_fail(cli, &err);
    if (cli->json)
        printf("%s\n", res.json);
    sl_unwrap_run_result_free(&res);
    return 0;
}
