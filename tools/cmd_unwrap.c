/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight unwrap -o OUT.exr BALL: chrome-ball photo to lat-long. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "setlight/stitch.h"

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static const char *unwrap_help =
    "usage: setlight unwrap [options] -o OUT.exr BALL\n\n"
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
    "  --width N              output width (even; default: one texel per photo pixel\n"
    "                         where the ball faces the camera)\n"
    "  --no-confidence        write RGB only\n"
    "  --float                32-bit float EXR instead of half\n"
    "  --json                 print the result as JSON on stdout\n\n"
    "The A channel is the confidence: resolution relative to the ball's centre, 0 in\n"
    "the blind cone behind the ball (filled flat with the rim's median). An 8-bit\n"
    "photo (JPEG, PNG) is taken as sRGB, linearised with a warning: its highlights\n"
    "are clipped, so bright sources come out too dark.\n"
    "Exit codes: 0 done, 1 failure, 2 usage error (bad option, circle outside the\n"
    "image), 3 bad input (unreadable, no ball, two balls, ball cut by the frame).\n"
    "See docs/unwrap.md.\n";

static bool parse_list(const char *s, double *v, int n)
{
    char buf[256];
    if (strlen(s) >= sizeof buf)
        return false;
    strcpy(buf, s);
    char *p = buf;
    for (int i = 0; i < n; i++) {
        char *comma = strchr(p, ',');
        if ((comma == NULL) != (i == n - 1))
            return false;
        if (comma)
            *comma = 0;
        if (!cli_parse_double(p, &v[i]))
            return false;
        p = comma + 1;
    }
    return true;
}

static void reflectance_text(const sl_reflectance *r, char *buf, size_t size)
{
    if (r->kind == SL_REFLECTANCE_CONDUCTOR)
        snprintf(buf, size, "conductor n=%g,%g,%g k=%g,%g,%g", r->n[0], r->n[1], r->n[2],
                 r->k[0], r->k[1], r->k[2]);
    else
        snprintf(buf, size, "%g,%g,%g", r->value[0], r->value[1], r->value[2]);
}

int cmd_unwrap(int argc, char **argv, const sl_cli *cli)
{
    enum {
        OPT_CIRCLE = 1000, OPT_CAMERA, OPT_FOCAL, OPT_SENSOR, OPT_FOV, OPT_DIST, OPT_DIAM,
        OPT_AZ, OPT_EL, OPT_ROLL, OPT_REFL, OPT_WIDTH, OPT_NOCONF, OPT_FLOAT
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
                                         {"width", required_argument, NULL, OPT_WIDTH},
                                         {"no-confidence", no_argument, NULL, OPT_NOCONF},
                                         {"float", no_argument, NULL, OPT_FLOAT},
                                         {0, 0, 0, 0}};
    const char *out_path = NULL;
    sl_unwrap_options o;
    memset(&o, 0, sizeof o);
    sl_reflectance_constant(&o.reflectance, 1, 1, 1);
    bool have_circle = false, confidence = true, use_float = false;
    int camera = -1;
    double focal_mm = 0, sensor_mm = 0, fov = 0, dist_mm = 0, diam_mm = 0;
    char refl_arg[64] = "1";

    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, "+ho:", opts, NULL)) != -1) {
        double v = 0;
        switch (c) {
        case 'h':
            fputs(unwrap_help, stdout);
            return 0;
        case 'o':
            out_path = optarg;
            break;
        case OPT_CIRCLE: {
            double xyz[3];
            if (!parse_list(optarg, xyz, 3) || !(xyz[2] > 0))
                return cli_usage_error(cli, "--circle needs CX,CY,R with R > 0, not '%s'",
                                       optarg);
            o.circle.cx = xyz[0];
            o.circle.cy = xyz[1];
            o.circle.r = xyz[2];
            have_circle = true;
            break;
        }
        case OPT_CAMERA:
            if (!strcmp(optarg, "ortho") || !strcmp(optarg, "orthographic"))
                camera = SL_BALL_ORTHOGRAPHIC;
            else if (!strcmp(optarg, "perspective"))
                camera = SL_BALL_PERSPECTIVE;
            else
                return cli_usage_error(cli, "--camera is ortho or perspective, not '%s'", optarg);
            break;
        case OPT_FOCAL:
        case OPT_SENSOR:
        case OPT_FOV:
        case OPT_DIST:
        case OPT_DIAM:
            if (!cli_parse_double(optarg, &v) || !(v > 0) || (c == OPT_FOV && !(v < 180)))
                return cli_usage_error(cli, "%s needs a positive number%s, not '%s'",
                                       argv[optind - 1] ? argv[optind - 1] : "option",
                                       c == OPT_FOV ? " of degrees below 180" : "", optarg);
            *(c == OPT_FOCAL    ? &focal_mm
              : c == OPT_SENSOR ? &sensor_mm
              : c == OPT_FOV    ? &fov
              : c == OPT_DIST   ? &dist_mm
                                : &diam_mm) = v;
            break;
        case OPT_AZ:
        case OPT_EL:
        case OPT_ROLL:
            if (!cli_parse_double(optarg, &v))
                return cli_usage_error(cli, "camera angles are numbers of degrees, not '%s'",
                                       optarg);
            *(c == OPT_AZ   ? &o.geometry.azimuth_deg
              : c == OPT_EL ? &o.geometry.elevation_deg
                            : &o.geometry.roll_deg) = v;
            break;
        case OPT_REFL: {
            double rgb[3];
            snprintf(refl_arg, sizeof refl_arg, "%s", optarg);
            if (!strcmp(optarg, "chrome"))
                sl_reflectance_chrome(&o.reflectance);
            else if (parse_list(optarg, rgb, 1) && rgb[0] > 0 && rgb[0] <= 1)
                sl_reflectance_constant(&o.reflectance, rgb[0], rgb[0], rgb[0]);
            else if (parse_list(optarg, rgb, 3) && rgb[0] > 0 && rgb[1] > 0 && rgb[2] > 0 &&
                     rgb[0] <= 1 && rgb[1] <= 1 && rgb[2] <= 1)
                sl_reflectance_constant(&o.reflectance, rgb[0], rgb[1], rgb[2]);
            else
                return cli_usage_error(
                    cli, "--reflectance is R or R,G,B in (0, 1], or chrome, not '%s'", optarg);
            break;
        }
        case OPT_WIDTH:
            if (!cli_parse_int(optarg, &o.width) || o.width < 8 || o.width > 65536 ||
                o.width % 2)
                return cli_usage_error(cli, "--width needs an even number from 8 to 65536, not "
                                            "'%s'", optarg);
            break;
        case OPT_NOCONF:
            confidence = false;
            break;
        case OPT_FLOAT:
            use_float = true;
            break;
        default:
            return cli_usage_error(cli, "unknown option '%s'", argv[optind - 1]);
        }
    }
    if (!out_path)
        return cli_usage_error(cli, "needs an output file (-o OUT.exr)");
    if (argc - optind != 1)
        return cli_usage_error(cli, argc - optind > 1 ? "one ball photo at a time (two-view "
                                                        "merging is not available yet)"
                                                      : "needs a ball photo");
    if ((dist_mm > 0) != (diam_mm > 0))
        return cli_usage_error(cli, "--distance and --ball-diameter go together");
    if (dist_mm > 0 && !(dist_mm > 0.5 * diam_mm))
        return cli_usage_error(cli, "--distance %g mm puts the camera inside a %g mm ball",
                               dist_mm, diam_mm);
    if (focal_mm > 0 && fov > 0)
        return cli_usage_error(cli, "give --focal-mm or --fov, not both");
    const char *in_path = argv[optind];
    double t0 = sl_seconds();

    sl_image photo = {0}, out = {0};
    sl_meta meta, out_meta;
    sl_meta_init(&out_meta);
    sl_error err;
    sl_result r = sl_image_read(in_path, &photo, &meta, &err);
    if (r) {
        sl_meta_free(&out_meta);
        return cli_fail(cli, &err);
    }
    double t1 = sl_seconds();
    bool ldr = !meta.is_float;
    if (ldr) {
        sl_log(SL_LOG_WARN,
               "%s: %d-bit %s, not HDR: taken as sRGB and linearised; clipped highlights make "
               "bright sources too dark",
               in_path, meta.bits_per_sample, meta.format);
        for (size_t i = 0; i < photo.stride * (size_t)photo.height; i++)
            photo.data[i] = sl_srgb_to_linear(photo.data[i]);
    }

    /* Geometry: focal length in pixels of this image, from the lens or the field of view. */
    if (focal_mm == 0 && sensor_mm > 0 && meta.focal_length_mm > 0)
        focal_mm = meta.focal_length_mm;
    if (focal_mm > 0 && sensor_mm == 0) {
        sl_error_set(&err, SL_ERR_USAGE, "--focal-mm needs --sensor-mm (the sensor width)");
        goto fail;
    }
    if (focal_mm > 0)
        o.geometry.focal_px = focal_mm * photo.width / sensor_mm;
    else if (fov > 0)
        o.geometry.focal_px = 0.5 * photo.width / tan(0.5 * fov * M_PI / 180.0);
    if (dist_mm > 0)
        o.geometry.distance = dist_mm / (0.5 * diam_mm);
    bool known = o.geometry.focal_px > 0 || o.geometry.distance > 0;
    if (camera < 0)
        camera = known ? SL_BALL_PERSPECTIVE : SL_BALL_ORTHOGRAPHIC;
    o.geometry.camera = (sl_ball_camera)camera;

    bool detected = !have_circle;
    if (have_circle) {
        if (o.circle.cx - o.circle.r < 0 || o.circle.cy - o.circle.r < 0 ||
            o.circle.cx + o.circle.r > photo.width || o.circle.cy + o.circle.r > photo.height) {
            sl_error_set(&err, SL_ERR_USAGE,
                         "--circle %g,%g,%g is not inside the %dx%d image %s", o.circle.cx,
                         o.circle.cy, o.circle.r, photo.width, photo.height, in_path);
            goto fail;
        }
    } else if ((r = sl_ball_detect(&photo, in_path, &o.circle, &err))) {
        goto fail;
    }

    sl_unwrap_info info;
    double t_read = t1 - t0, t2 = sl_seconds();
    if ((r = sl_unwrap(&photo, &o, &out, &info, &err)))
        goto fail;
    double t_detect = t2 - t1, t_unwrap = sl_seconds() - t2;
    if (info.nonfinite)
        sl_log(SL_LOG_WARN, "%s: %lld NaN/Inf samples replaced by 0", in_path,
               (long long)info.nonfinite);
    if (!confidence) {
        sl_image rgb;
        if ((r = sl_image_convert_channels(&out, 3, &rgb, &err)))
            goto fail;
        sl_image_free(&out);
        out = rgb;
    }

    out_meta.envmap = SL_ENVMAP_LATLONG;
    char buf[1024], refl[160];
    reflectance_text(&o.reflectance, refl, sizeof refl);
    const char *cs = sl_meta_color_space(&meta);
    if (!cs || !strcmp(cs, "srgb"))
        cs = "lin_rec709";
    struct {
        const char *name;
        char value[256];
    } attrs[10];
    int na = 0;
    snprintf(attrs[na].value, sizeof attrs[na].value, "%.4f,%.4f,%.4f", o.circle.cx,
             o.circle.cy, o.circle.r);
    attrs[na++].name = "setlight:ball_circle";
    snprintf(attrs[na].value, sizeof attrs[na].value, "%s, fit residual %.3f px, %d edge points",
             detected ? "detected" : "given", o.circle.residual, o.circle.edge_points);
    attrs[na++].name = "setlight:ball_circle_source";
    snprintf(attrs[na].value, sizeof attrs[na].value,
             "%s, focal %.3f px, distance %.4f ball radii, ball %.3f deg, off axis %.3f deg",
             camera == SL_BALL_PERSPECTIVE ? "perspective" : "orthographic", info.focal_px,
             info.distance, info.ball_angle_deg, info.off_axis_deg);
    attrs[na++].name = "setlight:ball_camera";
    snprintf(attrs[na].value, sizeof attrs[na].value, "azimuth %g, elevation %g, roll %g deg",
             o.geometry.azimuth_deg, o.geometry.elevation_deg, o.geometry.roll_deg);
    attrs[na++].name = "setlight:camera_orientation";
    snprintf(attrs[na].value, sizeof attrs[na].value, "%s", refl);
    attrs[na++].name = "setlight:ball_reflectance";
    snprintf(attrs[na].value, sizeof attrs[na].value, "%.3f", info.blind_angle_deg);
    attrs[na++].name = "setlight:blind_cone_deg";
    if (confidence) {
        snprintf(attrs[na].value, sizeof attrs[na].value,
                 "confidence: resolution relative to the ball centre, 0 where unseen");
        attrs[na++].name = "setlight:alpha";
    }
    if (ldr) {
        snprintf(attrs[na].value, sizeof attrs[na].value, "8-bit sRGB input linearised");
        attrs[na++].name = "setlight:input_note";
    }
    snprintf(buf, sizeof buf, "setlight %s unwrap", sl_version());
    if ((r = sl_meta_set(&out_meta, "setlight:command", buf, &err)) ||
        (r = sl_meta_set(&out_meta, "setlight:source", in_path, &err)) ||
        (r = sl_meta_set_color_space(&out_meta, cs, &err)))
        goto fail;
    for (int i = 0; i < na; i++)
        if ((r = sl_meta_set(&out_meta, attrs[i].name, attrs[i].value, &err)))
            goto fail;
    double t3 = sl_seconds();
    r = sl_exr_write(out_path, &out, &out_meta, use_float ? SL_PIXEL_FLOAT : SL_PIXEL_HALF, &err);
    if (r)
        goto fail;
    double t_write = sl_seconds() - t3;

    if (cli->json) {
        json_t *j = json_pack(
            "{s:s, s:s, s:{s:f, s:f, s:f, s:f, s:i, s:b}, s:s, s:f, s:f, s:f, s:f, s:f, s:i, "
            "s:i, s:s, s:f, s:I, s:b, s:f, s:{s:f, s:f, s:f, s:f}}",
            "input", in_path, "output", out_path, "circle", "cx", o.circle.cx, "cy", o.circle.cy,
            "r", o.circle.r, "residual", o.circle.residual, "edge_points", o.circle.edge_points,
            "detected", detected, "camera",
            camera == SL_BALL_PERSPECTIVE ? "perspective" : "orthographic", "focal_px",
            info.focal_px, "distance_radii", info.distance, "ball_angle_deg",
            info.ball_angle_deg, "off_axis_deg", info.off_axis_deg, "centre_px_per_rad",
            info.centre_px_per_rad, "width", out.width, "height", out.height, "reflectance",
            refl, "blind_fraction", info.blind_fraction, "nonfinite_replaced",
            (json_int_t)info.nonfinite, "ldr_linearised", ldr, "seconds", sl_seconds() - t0, "timing", "read", t_read,
            "detect", t_detect, "unwrap", t_unwrap, "write", t_write);
        json_dumpf(j, stdout, JSON_INDENT(2));
        fputc('\n', stdout);
        json_decref(j);
    }
    sl_image_free(&photo);
    sl_image_free(&out);
    sl_meta_free(&meta);
    sl_meta_free(&out_meta);
    return 0;

fail:
    sl_image_free(&photo);
    sl_image_free(&out);
    sl_meta_free(&meta);
    sl_meta_free(&out_meta);
    return cli_fail(cli, &err);
}
