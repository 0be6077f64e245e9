/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight convert IN OUT: environment projections, rotation, size, colour. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <string.h>
#include <strings.h>

#include "cli.h"
#include "setlight/stitch.h"

static const char *convert_help =
    "usage: setlight convert [options] IN OUT\n\n"
    "Converts an environment image between projections, turns it about the vertical\n"
    "axis, resizes it and changes its colour space. An input that is no environment\n"
    "(not 2:1, no envmap attribute, no --from: a merged view, a render) is converted\n"
    "as an image, same size unless --width. OUT's extension picks the format: .exr\n"
    "(half float unless --float), or .png/.jpg/.tif for an 8-bit preview: RGB only\n"
    "(a confidence or mask channel never becomes alpha), an exposure, then an\n"
    "OpenColorIO display view.\n\n"
    "  --from P            input projection: latlong, mirrorball, angular, cubemap\n"
    "                      (default: the file's envmap attribute, else latlong; a 2:1\n"
    "                      image without one is taken as a lat-long with a note)\n"
    "  --to P              output projection (default latlong)\n"
    "  --width N           output lat-long-equivalent width (default: from the input;\n"
    "                      mirrorball/angular are N/2 square, cube faces N/4); an\n"
    "                      image: N wide, its aspect kept\n"
    "  --rotate DEG        turn the environment about +Y; positive turns +Z toward +X\n"
    "  --colorspace NAME   EXR output colour space (OCIO name, e.g. lin_rec709, acescg)\n"
    "  --input-colorspace NAME  override the input's colour space (default: the one\n"
    "                      the file names, else srgb for 8/16-bit, linear for float;\n"
    "                      docs/color.md)\n"
    "  --exposure STOPS    preview exposure: pixels times 2^STOPS (default auto: the\n"
    "                      median luminance of the non-black pixels to 0.18)\n"
    "  --view NAME         preview view of the sRGB display: Standard (sRGB curve,\n"
    "                      the default) or Raw (linear values, clamped)\n"
    "  --float             write 32-bit float EXR instead of half\n"
    "  --strict            NaN/Inf input pixels are an error (exit 3) instead of being\n"
    "                      counted, reported and replaced by 0\n"
    "  --json              print the result as JSON on stdout\n\n"
    "Projections follow OpenEXR's lat-long orientation; an angular map (Debevec's\n"
    "light probes) has its centre, the forward direction, at the lat-long's centre\n"
    "column, unmirrored; see docs/geometry.md.\n"
    "A circular fisheye photo given as angular or mirrorball is refused (exit 3):\n"
    "use 'setlight stitch'.\n";

static int output_width_default(sl_projection from, const sl_image *img)
{
    switch (from) {
    case SL_PROJ_LATLONG:
        return img->width;
    case SL_PROJ_MIRRORBALL:
    case SL_PROJ_ANGULAR:
        return 2 * img->width;
    case SL_PROJ_CUBEMAP:
        return 4 * img->width;
    default:
        return img->width;
    }
}

enum output_kind { OUT_UNKNOWN, OUT_EXR, OUT_PREVIEW };

static enum output_kind output_kind(const char *path)
{
    static const char *const previews[] = {".png", ".jpg", ".jpeg", ".tif", ".tiff"};
    const char *slash = strrchr(path, '/');
    const char *dot = strrchr(slash ? slash + 1 : path, '.');
    if (!dot)
        return OUT_UNKNOWN;
    if (strcasecmp(dot, ".exr") == 0)
        return OUT_EXR;
    for (size_t i = 0; i < sizeof previews / sizeof previews[0]; i++)
        if (strcasecmp(dot, previews[i]) == 0)
            return OUT_PREVIEW;
    return OUT_UNKNOWN;
}

int cmd_convert(int argc, char **argv, const sl_cli *cli)
{
    enum {
        OPT_FROM = 1000, OPT_TO, OPT_WIDTH, OPT_ROTATE, OPT_CS, OPT_INCS, OPT_FLOAT, OPT_STRICT,
        OPT_EXPOSURE, OPT_VIEW
    };
    static const struct option opts[] = {
        {"help", no_argument, NULL, 'h'},
        {"from", required_argument, NULL, OPT_FROM},
        {"to", required_argument, NULL, OPT_TO},
        {"width", required_argument, NULL, OPT_WIDTH},
        {"rotate", required_argument, NULL, OPT_ROTATE},
        {"colorspace", required_argument, NULL, OPT_CS},
        {"input-colorspace", required_argument, NULL, OPT_INCS},
        {"float", no_argument, NULL, OPT_FLOAT},
        {"strict", no_argument, NULL, OPT_STRICT},
        {"exposure", required_argument, NULL, OPT_EXPOSURE},
        {"view", required_argument, NULL, OPT_VIEW},
        {0, 0, 0, 0}};
    int from = -1, to = SL_PROJ_LATLONG, width = 0;
    double rotate = 0;
    const char *out_cs = NULL, *in_cs = NULL;
    bool use_float = false, strict = false, to_given = false;
    sl_preview_options preview = {.auto_exposure = true};

    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, "h", opts, NULL)) != -1) {
        switch (c) {
        case 'h':
            fputs(convert_help, stdout);
            return 0;
        case OPT_FROM:
        case OPT_TO: {
            int p = sl_projection_from_name(optarg);
            if (p < 0)
                return cli_usage_error(cli, "unknown projection '%s' (latlong, mirrorball, angular, cubemap)", optarg);
            if (c == OPT_FROM)
                from = p;
            else
                to = p;
            to_given = to_given || c == OPT_TO;
            break;
        }
        case OPT_WIDTH:
            if (!cli_parse_int(optarg, &width) || width < 4 || width > 65536)
                return cli_usage_error(cli, "--width needs a whole number from 4 to 65536, not '%s'", optarg);
            break;
        case OPT_ROTATE:
            if (!cli_parse_double(optarg, &rotate))
                return cli_usage_error(cli, "--rotate needs a number of degrees, not '%s'", optarg);
            break;
        case OPT_CS:
        case OPT_INCS: {
            const char *name = sl_color_space_name(optarg);
            if (!name)
                return cli_usage_error(cli, "unknown colour space '%s' (see docs/color.md)", optarg);
            if (c == OPT_CS)
                out_cs = name;
            else
                in_cs = name;
            break;
        }
        case OPT_FLOAT:
            use_float = true;
            break;
        case OPT_STRICT:
            strict = true;
            break;
        case OPT_EXPOSURE:
            if (!cli_parse_double(optarg, &preview.exposure_stops) ||
                fabs(preview.exposure_stops) > 64)
                return cli_usage_error(cli, "--exposure needs a number of stops from -64 to 64, not '%s'",
                                       optarg);
            preview.auto_exposure = false;
            break;
        case OPT_VIEW:
            preview.view = optarg;
            break;
        default:
            return cli_usage_error(cli, "unknown option '%s'", argv[optind - 1]);
        }
    }
    if (argc - optind != 2)
        return cli_usage_error(cli, "needs an input and an output file");
    const char *in_path = argv[optind], *out_path = argv[optind + 1];
    enum output_kind out_kind = output_kind(out_path);
    if (out_kind == OUT_UNKNOWN)
        return cli_usage_error(cli, "%s: unknown image extension (use .exr, .png, .jpg, .jpeg, .tif, .tiff)",
                               out_path);
    bool is_preview = out_kind == OUT_PREVIEW;
    if (is_preview && out_cs)
        return cli_usage_error(cli, "%s: --colorspace sets an EXR's colour space; a preview takes --view",
                               out_path);
    if (!is_preview && (preview.view || !preview.auto_exposure))
        return cli_usage_error(cli, "%s: --exposure and --view are for PNG, JPEG and TIFF previews",
                               out_path);
    double t0 = sl_seconds();

    sl_image src = {0}, dst = {0};
    sl_meta meta, out_meta;
    sl_meta_init(&out_meta);
    sl_error err;
    if (preview.view && sl_color_display_view(NULL, "lin_rec709", NULL, preview.view, NULL, 0, &err))
        return cli_fail(cli, &err);
    /* Scene-linear in the working space, as every command reads; the
     * envmap decided unless --from says. */
    sl_read_info info;
    sl_result r = from < 0 ? sl_env_read(in_path, in_cs, &src, &meta, &info, &err)
                           : sl_image_read_linear(in_path, in_cs, &src, &meta, &info, &err);
    if (r)
        return cli_fail(cli, &err);
    cli_warn_format_mismatch(in_path, &meta);
    /* A circular fisheye photo is no ball or angular map: refused, not swirled. */
    if (from == SL_PROJ_MIRRORBALL || from == SL_PROJ_ANGULAR) {
        sl_fisheye_evidence fisheye;
        if ((r = sl_fisheye_check(&src, false, in_path, &fisheye, &err)))
            goto fail;
    }

    /* Not a known environment projection: converted as an image. */
    bool is_env = from >= 0 || meta.envmap != SL_ENVMAP_NONE ||
                  sl_is_latlong_shape(src.width, src.height);
    if (from < 0)
        from = meta.envmap == SL_ENVMAP_CUBE ? SL_PROJ_CUBEMAP : SL_PROJ_LATLONG;
    if (from == SL_PROJ_LATLONG && !sl_is_latlong_shape(src.width, src.height) &&
        (is_env || to_given || rotate != 0)) {
        sl_error_set(&err, SL_ERR_INPUT,
                     "%s: not a lat-long: %dx%d is not 2:1 (give --from for other projections)",
                     in_path, src.width, src.height);
        goto fail;
    }
    if (from == SL_PROJ_CUBEMAP && src.height != 6 * src.width) {
        sl_error_set(&err, SL_ERR_INPUT, "%s: not a cube map: %dx%d is not 1:6", in_path,
                     src.width, src.height);
        goto fail;
    }
    if ((from == SL_PROJ_MIRRORBALL || from == SL_PROJ_ANGULAR) && src.width != src.height) {
        sl_error_set(&err, SL_ERR_INPUT, "%s: a %s image must be square, not %dx%d", in_path,
                     sl_projection_name(from), src.width, src.height);
        goto fail;
    }

    sl_image_stats st;
    sl_image_stats_compute(&src, &st);
    int64_t nonfinite = st.nan_count + st.inf_count;
    if (nonfinite) {
        if (strict) {
            sl_error_set(&err, SL_ERR_INPUT, "%s: %lld NaN and %lld Inf samples (--strict)",
                         in_path, (long long)st.nan_count, (long long)st.inf_count);
            goto fail;
        }
        sl_log(SL_LOG_WARN, "%s: %lld NaN and %lld Inf samples replaced by 0", in_path,
               (long long)st.nan_count, (long long)st.inf_count);
        sl_image_sanitize(&src, 0.0f);
    }

    /* Colour: reprojected in the working space; an EXR out in --colorspace,
     * else the input's own when it is scene-linear (an ACEScg EXR stays
     * ACEScg); a preview through the display view. */
    const char *in_space = sl_color_space_encoding(info.colorspace);
    const char *src_cs = in_space && !strcmp(in_space, "scene-linear") ? info.colorspace
                                                                         : SL_WORKING_SPACE;
    const char *dst_cs = out_cs ? out_cs : src_cs;
    const char *work_cs = SL_WORKING_SPACE;

    double rot[3][3];
    sl_rotation_y(rotate, rot);
    if (!is_env) {
        int height = width ? (int)fmax(1.0, floor((double)width * src.height / src.width + 0.5))
                           : src.height;
        r = width ? sl_image_resample(&src, width, height, &dst, &err)
                  : sl_image_copy(&src, &dst, &err);
        width = dst.width;
    } else {
        if (!width)
            width = output_width_default((sl_projection)from, &src);
        r = sl_reproject(&src, (sl_projection)from, (sl_projection)to, width,
                         rotate != 0 ? rot : NULL, &dst, &err);
    }
    if (r)
        goto fail;
    if (!is_preview && strcmp(work_cs, dst_cs) != 0 &&
        ((r = sl_image_ensure_rgb(&dst, out_path, &err)) ||
         (r = sl_color_convert(&dst, work_cs, dst_cs, &err))))
        goto fail;

    out_meta.envmap = !is_env                 ? SL_ENVMAP_NONE
                      : to == SL_PROJ_LATLONG ? SL_ENVMAP_LATLONG
                      : to == SL_PROJ_CUBEMAP ? SL_ENVMAP_CUBE
                                              : SL_ENVMAP_NONE;
    const char *from_name = is_env ? sl_projection_name((sl_projection)from) : "image";
    const char *to_name = is_env ? sl_projection_name((sl_projection)to) : "image";
    char buf[512];
    snprintf(buf, sizeof buf, "setlight %s convert --from %s --to %s --width %d --rotate %g",
             sl_version(), from_name, to_name, width, rotate);
    if ((r = sl_meta_set(&out_meta, "setlight:command", buf, &err)) ||
        (r = sl_meta_set(&out_meta, "setlight:source", in_path, &err)) ||
        (!is_preview && (r = sl_meta_set_color_space(&out_meta, dst_cs, &err))))
        goto fail;
    if (nonfinite) {
        snprintf(buf, sizeof buf, "%lld", (long long)nonfinite);
        if ((r = sl_meta_set(&out_meta, "setlight:nonfinite_replaced", buf, &err)))
            goto fail;
    }
    sl_preview_result shown = {0};
    preview.colorspace = work_cs;
    r = is_preview ? sl_preview_write(out_path, &dst, &out_meta, &preview, &shown, &err)
                   : sl_image_write(out_path, &dst, &out_meta,
                                    use_float ? SL_PIXEL_FLOAT : SL_PIXEL_HALF, &err);
    if (r)
        goto fail;

    if (cli->json) {
        json_t *o = json_pack("{s:s, s:s, s:s, s:s, s:i, s:i, s:f, s:s?, s:I, s:f}", "input",
                              in_path, "output", out_path, "from", from_name, "to", to_name,
                              "width", dst.width, "height", dst.height, "rotate_degrees", rotate,
                              "colorspace", is_preview ? NULL : dst_cs, "nonfinite_replaced",
                              (json_int_t)nonfinite, "seconds", sl_seconds() - t0);
        if (is_preview)
            json_object_set_new(o, "preview",
                                json_pack("{s:f, s:b, s:f, s:s}", "exposure_stops",
                                          shown.exposure_stops, "auto_exposure",
                                          preview.auto_exposure, "median_luminance",
                                          shown.median_luminance, "view", shown.view));
        json_dumpf(o, stdout, JSON_INDENT(2));
        fputc('\n', stdout);
        json_decref(o);
    }
    sl_image_free(&src);
    sl_image_free(&dst);
    sl_meta_free(&meta);
    sl_meta_free(&out_meta);
    return 0;

fail:
    sl_image_free(&src);
    sl_image_free(&dst);
    sl_meta_free(&meta);
    sl_meta_free(&out_meta);
    return cli_fail(cli, &err);
}
