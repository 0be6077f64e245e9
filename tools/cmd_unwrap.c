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
    "reported (circle.uncertainty in --json).\n"
    "Exit codes: 0 done, 1 failure, 2 usage error (bad option, circle outside the\n"
    "image), 3 bad input (unreadable, a circular fisheye photo (use 'setlight\n"
    "stitch'), no ball, two balls, ball cut by the frame, outline fitted too\n"
    "weakly (give --circle), reflectance patch not seen).\n"
    "See docs/unwrap.md.\n";

static void reflectance_text(const sl_reflectance *r, char *buf, size_t size)
{
    if (r->kind == SL_REFLECTANCE_CONDUCTOR)
        snprintf(buf, size, "conductor n=%g,%g,%g k=%g,%g,%g", r->n[0], r->n[1], r->n[2],
                 r->k[0], r->k[1], r->k[2]);
    else
        snprintf(buf, size, "%g,%g,%g", r->value[0], r->value[1], r->value[2]);
}

/* One photo: read as scene-linear (an 8/16-bit one linearised with a
 * warning, as every command reads), its circle
 * given or detected, and its focal length in pixels. */
typedef struct view_in {
    const char *path;
    const char *colorspace; /* --input-colorspace, NULL: the file's */
    sl_image photo;
    sl_meta meta;
    bool ldr, detected; /* ldr: 8/16-bit, linearised from input_space */
    char input_space[64];
    int64_t nonfinite;
} view_in;

static sl_result load_view(view_in *v, sl_unwrap_options *o, bool have_circle,
                           const ball_camera_opts *bc, sl_error *err)
{
    sl_read_info info;
    sl_result r = sl_image_read_linear(v->path, v->colorspace, &v->photo, &v->meta, &info, err);
    if (r)
        return r;
    v->ldr = info.converted && !v->meta.is_float;
    snprintf(v->input_space, sizeof v->input_space, "%s", info.colorspace);
    /* A fisheye is refused in one line (the reading's notes are dropped then). */
    sl_fisheye_evidence fisheye;
    if ((r = sl_fisheye_check(&v->photo, false, v->path, &fisheye, err)))
        return r;
    /* Geometry: focal length in pixels of this image (lens or field of view),
     * distance in ball radii. */
    double focal_px, distance;
    sl_ball_lens_geometry(bc, v->photo.width, v->meta.focal_length_mm, &focal_px, &distance);
    if (focal_px > 0)
        o->geometry.focal_px = focal_px;
    if (distance > 0)
        o->geometry.distance = distance;
    v->detected = !have_circle;
    if (have_circle) {
        const sl_ball_circle *c = &o->circle;
        if (c->cx - c->r < 0 || c->cy - c->r < 0 || c->cx + c->r > v->photo.width ||
            c->cy + c->r > v->photo.height)
            return sl_error_set(err, SL_ERR_USAGE, "--circle %g,%g,%g is not inside the %dx%d image %s",
                                c->cx, c->cy, c->r, v->photo.width, v->photo.height, v->path);
        return SL_OK;
    }
    return sl_ball_detect(&v->photo, v->path, &o->circle, err);
}

static void view_free(view_in *v)
{
    sl_image_free(&v->photo);
    sl_meta_free(&v->meta);
}

/* NaN (not measured) as null. */
static json_t *number(double v)
{
    return isfinite(v) ? json_real(v) : json_null();
}

static json_t *circle_json(const sl_ball_circle *c, bool detected)
{
    return json_pack("{s:f, s:f, s:f, s:f, s:f, s:i, s:b}", "cx", c->cx, "cy", c->cy, "r", c->r,
                     "residual", c->residual, "uncertainty", c->uncertainty, "edge_points",
                     c->edge_points, "detected", detected);
}

/* The output: its header from everything known before the pixels, and
 * the stream the rows go to when they are written as they are done. */
typedef struct out_job {
    const char *path;
    const view_in *views;
    int nviews;
    const sl_unwrap_pair_options *po;
    const sl_unwrap_pair_info *pinfo;
    int camera;
    bool confidence, have_patch;
    const double *patch;
    sl_pixel_type type;
    sl_exr_compression compression;
    sl_meta *meta;
    sl_exr_stream *stream;
    double write_s, write_cpu; /* time in the rows' conversion, encoding and writing */
} out_job;

/* The reflectance as the header and the JSON give it. */
static void reflectance_desc(const out_job *j, char *buf, size_t size)
{
    reflectance_text(&j->po->views[0].reflectance, buf, size);
    if (j->have_patch) {
        size_t len = strlen(buf);
        snprintf(buf + len, size - len, " (from a patch at %g,%g, %g deg)", j->patch[0],
                 j->patch[1], j->patch[2]);
    }
}

static sl_result output_meta(const out_job *j, sl_error *err)
{
    const view_in *views = j->views;
    const sl_unwrap_pair_options *po = j->po;
    const sl_unwrap_pair_info *pinfo = j->pinfo;
    int nviews = j->nviews;
    j->meta->envmap = SL_ENVMAP_LATLONG;
    char buf[1024], refl[160];
    reflectance_desc(j, refl, sizeof refl);
    const char *cs = sl_meta_color_space(&views[0].meta);
    if (!cs || !strcmp(cs, "srgb"))
        cs = "lin_rec709";
    struct {
        const char *name;
        char value[256];
    } attrs[16];
    int na = 0;
    for (int i = 0; i < nviews; i++) {
        const sl_unwrap_options *oi = &po->views[i];
        const sl_unwrap_info *ii = &pinfo->views[i];
        snprintf(attrs[na].value, sizeof attrs[na].value, "%.4f,%.4f,%.4f", oi->circle.cx,
                 oi->circle.cy, oi->circle.r);
        attrs[na++].name = i ? "setlight:ball2_circle" : "setlight:ball_circle";
        snprintf(attrs[na].value, sizeof attrs[na].value,
                 "%s, fit residual %.3f px, standard error %.3f px, %d edge points",
                 views[i].detected ? "detected" : "given", oi->circle.residual,
                 oi->circle.uncertainty, oi->circle.edge_points);
        attrs[na++].name = i ? "setlight:ball2_circle_source" : "setlight:ball_circle_source";
        snprintf(attrs[na].value, sizeof attrs[na].value,
                 "%s, focal %.3f px, distance %.4f ball radii, ball %.3f deg, off axis %.3f deg",
                 j->camera == SL_BALL_PERSPECTIVE ? "perspective" : "orthographic", ii->focal_px,
                 ii->distance, ii->ball_angle_deg, ii->off_axis_deg);
        attrs[na++].name = i ? "setlight:ball2_camera" : "setlight:ball_camera";
        snprintf(attrs[na].value, sizeof attrs[na].value, "azimuth %g, elevation %g, roll %g deg",
                 i ? pinfo->azimuth_deg : oi->geometry.azimuth_deg, oi->geometry.elevation_deg,
                 oi->geometry.roll_deg);
        attrs[na++].name = i ? "setlight:camera2_orientation" : "setlight:camera_orientation";
    }
    if (nviews == 2) {
        snprintf(attrs[na].value, sizeof attrs[na].value,
                 "view 2 azimuth %.3f deg (given %.3f, searched +-%g), median |log| luminance "
                 "difference %.4f (%.4f as given), overlap %.3f of the sphere, occluder cones "
                 "%g deg",
                 pinfo->azimuth_deg, pinfo->azimuth_given_deg, po->search_deg, pinfo->residual,
                 pinfo->residual_given, pinfo->overlap_fraction, po->occluder_deg);
        attrs[na++].name = "setlight:two_views";
    }
    snprintf(attrs[na].value, sizeof attrs[na].value, "%s", refl);
    attrs[na++].name = "setlight:ball_reflectance";
    snprintf(attrs[na].value, sizeof attrs[na].value, "%.3f", pinfo->views[0].blind_angle_deg);
    attrs[na++].name = "setlight:blind_cone_deg";
    if (j->confidence) {
        snprintf(attrs[na].value, sizeof attrs[na].value,
                 "confidence: resolution relative to the ball centre, 0 where unseen");
        attrs[na++].name = "setlight:alpha";
    }
    if (views[0].ldr || views[1].ldr) {
        const view_in *v = views[0].ldr ? &views[0] : &views[1];
        snprintf(attrs[na].value, sizeof attrs[na].value,
                 "8/16-bit input linearised from %s through OpenColorIO", v->input_space);
        attrs[na++].name = "setlight:input_note";
    }
    snprintf(buf, sizeof buf, "setlight %s unwrap", sl_version());
    sl_result r;
    if ((r = sl_meta_set(j->meta, "setlight:command", buf, err)) ||
        (r = sl_meta_set(j->meta, "setlight:source", views[0].path, err)) ||
        (nviews == 2 && (r = sl_meta_set(j->meta, "setlight:source2", views[1].path, err))) ||
        (r = sl_meta_set_color_space(j->meta, cs, err)))
        return r;
    for (int i = 0; i < na; i++)
        if ((r = sl_meta_set(j->meta, attrs[i].name, attrs[i].value, err)))
            return r;
    return SL_OK;
}

/* Adds the wall and CPU time since t, c to the output's writing time. */
static void writing_took(out_job *j, double t, double c)
{
    j->write_s += sl_seconds() - t;
    j->write_cpu += sl_cpu_seconds() - c;
}

/* sl_unwrap_sink: the header once the geometry is known, then the rows. */
static sl_result stream_begin(void *user, const sl_unwrap_info *info, int channels,
                              sl_error *err)
{
    out_job *j = user;
    double t = sl_seconds(), c = sl_cpu_seconds();
    sl_result r = output_meta(j, err);
    if (!r)
        r = sl_exr_stream_open(j->path, info->width, info->height, channels, j->meta, j->type,
                               j->compression, &j->stream, err);
    writing_took(j, t, c);
    return r;
}

/* Called while the next rows are unwrapped (sl_unwrap_stream overlaps
 * the two): its time is the unwrap stage's, not the writing's. */
static sl_result stream_rows(void *user, const float *rows, int count, size_t stride,
                             sl_error *err)
{
    out_job *j = user;
    sl_result r = sl_exr_stream_write(j->stream, rows, count, stride, err);
    if (r)
        j->stream = NULL; /* a failed write aborts the stream */
    return r;
}

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
    const char *out_path = NULL, *in_cs = NULL;
    sl_unwrap_pair_options po;
    memset(&po, 0, sizeof po);
    sl_unwrap_options *o = &po.views[0], *o2 = &po.views[1];
    sl_reflectance_constant(&o->reflectance, 1, 1, 1);
    po.search_deg = 20;
    po.occluder_deg = 20;
    bool have_circle = false, have_circle2 = false, confidence = true, use_float = false;
    sl_exr_compression compression = SL_EXR_ZIP;
    bool have_refl = false, have_patch = false, have[3] = {false, false, false};
    double cam2[3] = {0, 0, 0}, patch[6] = {0};
    ball_camera_opts bc;
    sl_ball_lens_init(&bc);

    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, "ho:", opts, NULL)) != -1) {
        double v = 0;
        switch (c) {
        case 'h':
            fputs(unwrap_help, stdout);
            return 0;
        case 'o':
            out_path = optarg;
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
            *(c == OPT_CIRCLE ? &have_circle : &have_circle2) = true;
            break;
        }
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
                cam2[i] = v;
                have[i] = true;
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
            *(c == OPT_SEARCH ? &po.search_deg : &po.occluder_deg) = v;
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
            if (cli_parse_list(optarg, patch, 4)) {
                patch[4] = patch[5] = patch[3];
            } else if (!cli_parse_list(optarg, patch, 6)) {
                return cli_usage_error(cli, "--reflectance-patch needs AZ,EL,RADIUS,L or "
                                            "AZ,EL,RADIUS,R,G,B, not '%s'", optarg);
            }
            if (!(patch[2] > 0 && patch[2] < 90) || !(patch[3] > 0 && patch[4] > 0 && patch[5] > 0))
                return cli_usage_error(cli, "--reflectance-patch needs a radius in (0, 90) degrees "
                                            "and a positive radiance, not '%s'", optarg);
            have_patch = true;
            break;
        case OPT_WIDTH:
            if (!cli_parse_int(optarg, &o->width) || o->width < 8 || o->width > 65536 ||
                o->width % 2)
                return cli_usage_error(cli, "--width needs an even number from 8 to 65536, not "
                                            "'%s'", optarg);
            break;
        case OPT_INCS:
            if (!(in_cs = sl_color_space_name(optarg)))
                return cli_usage_error(cli, "unknown colour space '%s' (see docs/color.md)", optarg);
            break;
        case OPT_NOCONF:
            confidence = false;
            break;
        case OPT_FLOAT:
            use_float = true;
            break;
        case OPT_COMPRESSION:
            if (!cli_parse_compression(optarg, &compression))
                return cli_usage_error(cli, "--compression is piz, zip, rle or none, not '%s'",
                                       optarg);
            break;
        default:
            return cli_usage_error(cli, "unknown option '%s'", argv[optind - 1]);
        }
    }
    if (!out_path)
        return cli_usage_error(cli, "needs an output file (-o OUT.exr)");
    int nviews = argc - optind;
    if (nviews < 1)
        return cli_usage_error(cli, "needs a ball photo");
    if (nviews > 2)
        return cli_usage_error(cli, "one or two ball photos, not %d", nviews);
    int rc = ball_camera_opts_check(cli, &bc);
    if (rc)
        return rc;
    if (have_patch && have_refl)
        return cli_usage_error(cli, "give --reflectance or --reflectance-patch, not both");
    if (nviews == 1 && (have_circle2 || have[0] || have[1] || have[2]))
        return cli_usage_error(cli, "--circle2 and --camera2-* need a second ball photo");
    double t0 = sl_seconds(), cpu0 = sl_cpu_seconds();

    view_in views[2];
    memset(views, 0, sizeof views);
    views[0].colorspace = views[1].colorspace = in_cs;
    views[0].path = argv[optind];
    views[1].path = nviews == 2 ? argv[optind + 1] : NULL;
    sl_image out = {0};
    sl_meta out_meta;
    sl_meta_init(&out_meta);
    out_job job;
    memset(&job, 0, sizeof job);
    sl_error err;
    sl_result r;

    if ((r = load_view(&views[0], o, have_circle, &bc, &err)))
        goto fail;
    if (nviews == 2) {
        o2->geometry = o->geometry;
        o2->geometry.focal_px = 0;
        o2->geometry.azimuth_deg = have[0] ? cam2[0] : o->geometry.azimuth_deg + 90.0;
        if (have[1])
            o2->geometry.elevation_deg = cam2[1];
        if (have[2])
            o2->geometry.roll_deg = cam2[2];
        o2->reflectance = o->reflectance;
        o2->width = o->width;
        if ((r = load_view(&views[1], o2, have_circle2, &bc, &err)))
            goto fail;
    }
    int camera = bc.camera;
    if (camera < 0)
        camera = o->geometry.focal_px > 0 || o->geometry.distance > 0 ? SL_BALL_PERSPECTIVE
                                                                     : SL_BALL_ORTHOGRAPHIC;
    o->geometry.camera = o2->geometry.camera = (sl_ball_camera)camera;

    /* The patch is found with the confidence, the merge weighs by it. */
    o->no_confidence = !confidence && !have_patch && nviews == 1;
    double t1 = sl_seconds(), cpu1 = sl_cpu_seconds();
    sl_unwrap_pair_info pinfo;
    memset(&pinfo, 0, sizeof pinfo);
    sl_unwrap_info *info = &pinfo.views[0];
    double refl_patch[3] = {0, 0, 0};
    job = (out_job){.path = out_path, .views = views, .nviews = nviews, .po = &po,
                    .pinfo = &pinfo, .camera = camera, .confidence = confidence,
                    .have_patch = have_patch, .patch = patch,
                    .type = use_float ? SL_PIXEL_FLOAT : SL_PIXEL_HALF,
                    .compression = compression, .meta = &out_meta};
    /* One photo, nothing to do after the unwrap: rows go to the file as
     * they are done (no whole lat-long in memory, encoding strip by strip). */
    bool streamed = nviews == 1 && !have_patch;
    if (streamed) {
        sl_unwrap_sink sink = {stream_begin, stream_rows, &job};
        r = sl_unwrap_stream(&views[0].photo, o, &sink, info, &err);
        if (!r) {
            double ts = sl_seconds(), cs = sl_cpu_seconds();
            r = sl_exr_stream_finish(job.stream, NULL, &err);
            job.stream = NULL;
            writing_took(&job, ts, cs);
        }
        if (r)
            goto fail;
    } else {
        if (nviews == 2)
            r = sl_unwrap_pair(&views[0].photo, &views[1].photo, &po, &out, &pinfo, &err);
        else
            r = sl_unwrap(&views[0].photo, o, &out, info, &err);
        if (r)
            goto fail;
    }
    if (have_patch) {
        double az = patch[0] * M_PI / 180.0, el = patch[1] * M_PI / 180.0;
        double dir[3] = {sin(az) * cos(el), sin(el), cos(az) * cos(el)};
        if ((r = sl_unwrap_patch_reflectance(&out, dir, patch[2] * M_PI / 180.0, patch + 3,
                                             refl_patch, &err))) {
            char why[sizeof err.message];
            snprintf(why, sizeof why, "%s", err.message);
            sl_error_set(&err, r, "%s: %s", views[0].path, why);
            goto fail;
        }
        for (int y = 0; y < out.height; y++)
            for (int x = 0; x < out.width; x++) {
                float *p = sl_image_pixel(&out, x, y);
                for (int k = 0; k < 3; k++)
                    p[k] = (float)(p[k] / refl_patch[k]);
            }
        sl_reflectance_constant(&o->reflectance, refl_patch[0], refl_patch[1], refl_patch[2]);
        sl_log(SL_LOG_INFO, "ball reflectance from the patch: %.4f, %.4f, %.4f", refl_patch[0],
               refl_patch[1], refl_patch[2]);
    }
    /* The streamed unwrap's time includes its rows' conversion, encoding
     * and writing (overlapped with it), not the file's opening and finish. */
    double t_unwrap = sl_seconds() - t1 - job.write_s;
    double cpu_unwrap = sl_cpu_seconds() - cpu1 - job.write_cpu;
    for (int i = 0; i < nviews; i++)
        if (pinfo.views[i].nonfinite)
            sl_log(SL_LOG_WARN, "%s: %lld NaN/Inf samples replaced by 0", views[i].path,
                   (long long)pinfo.views[i].nonfinite);
    if (nviews == 2 && po.search_deg > 0)
        sl_log(SL_LOG_INFO,
               "%s: view 2 azimuth %.3f deg (given %.3f), median log luminance difference "
               "%.4f (%.4f as given) over %.1f%% of the sphere",
               views[1].path, pinfo.azimuth_deg, pinfo.azimuth_given_deg, pinfo.residual,
               pinfo.residual_given, 100.0 * pinfo.overlap_fraction);
    if (!streamed) {
        if (!confidence && out.channels == 4) {
            sl_image rgb;
            if ((r = sl_image_convert_channels(&out, 3, &rgb, &err)))
                goto fail;
            sl_image_free(&out);
            out = rgb;
        }
        double t3 = sl_seconds(), c3 = sl_cpu_seconds();
        if ((r = output_meta(&job, &err)) ||
            (r = sl_exr_write_compressed(out_path, &out, &out_meta, job.type, compression, &err)))
            goto fail;
        writing_took(&job, t3, c3);
    }
    char refl[160];
    reflectance_desc(&job, refl, sizeof refl);
    int out_w = streamed ? info->width : out.width, out_h = streamed ? info->height : out.height;

    if (cli->json) {
        json_t *j = json_pack(
            "{s:s, s:s, s:o, s:s, s:f, s:f, s:f, s:f, s:f, s:i, s:i, s:s, s:f, s:I, s:b, s:f, "
            "s:{s:f, s:f, s:f, s:f, s:f, s:f, s:b}}",
            "input", views[0].path, "output", out_path, "circle",
            circle_json(&o->circle, views[0].detected), "camera",
            camera == SL_BALL_PERSPECTIVE ? "perspective" : "orthographic", "focal_px",
            info->focal_px, "distance_radii", info->distance, "ball_angle_deg",
            info->ball_angle_deg, "off_axis_deg", info->off_axis_deg, "centre_px_per_rad",
            info->centre_px_per_rad, "width", out_w, "height", out_h, "reflectance",
            refl, "blind_fraction", info->blind_fraction, "nonfinite_replaced",
            (json_int_t)(pinfo.views[0].nonfinite + pinfo.views[1].nonfinite), "ldr_linearised",
            views[0].ldr || views[1].ldr, "seconds", sl_seconds() - t0, "timing", "read_detect",
            t1 - t0, "read_detect_cpu", cpu1 - cpu0, "unwrap", t_unwrap, "unwrap_cpu", cpu_unwrap,
            "write", job.write_s, "write_cpu", job.write_cpu, "streamed", streamed);
        json_object_set_new(j, "encoding",
                            json_pack("{s:s, s:s}", "pixel", use_float ? "float" : "half",
                                      "compression", cli_compression_name(compression)));
        if (have_patch)
            json_object_set_new(j, "reflectance_patch",
                                json_pack("{s:[f, f, f], s:[f, f, f]}", "radiance", patch[3],
                                          patch[4], patch[5], "reflectance", refl_patch[0],
                                          refl_patch[1], refl_patch[2]));
        if (nviews == 2)
            json_object_set_new(
                j, "view2",
                json_pack("{s:s, s:o, s:f, s:f, s:o, s:o, s:o, s:f, s:f}", "input",
                          views[1].path, "circle", circle_json(&o2->circle, views[1].detected),
                          "azimuth_given_deg", pinfo.azimuth_given_deg, "azimuth_deg",
                          pinfo.azimuth_deg, "residual_given", number(pinfo.residual_given),
                          "residual", number(pinfo.residual), "overlap_fraction",
                          number(pinfo.overlap_fraction),
                          "focal_px", pinfo.views[1].focal_px, "distance_radii",
                          pinfo.views[1].distance));
        json_dumpf(j, stdout, JSON_INDENT(2));
        fputc('\n', stdout);
        json_decref(j);
    }
    view_free(&views[0]);
    view_free(&views[1]);
    sl_image_free(&out);
    sl_meta_free(&out_meta);
    return 0;

fail:
    sl_exr_stream_abort(job.stream);
    view_free(&views[0]);
    view_free(&views[1]);
    sl_image_free(&out);
    sl_meta_free(&out_meta);
    return cli_fail(cli, &err);
}
