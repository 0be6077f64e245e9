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
    "axis, resizes it and changes its colour space. OUT's extension picks the format:\n"
    ".exr (half float unless --float), or .png/.jpg/.tif for previews (sRGB-encoded).\n\n"
    "  --from P            input projection: latlong, mirrorball, angular, cubemap\n"
    "                      (default: the file's envmap attribute, else latlong)\n"
    "  --to P              output projection (default latlong)\n"
    "  --width N           output lat-long-equivalent width (default: from the input;\n"
    "                      mirrorball/angular are N/2 square, cube faces N/4)\n"
    "  --rotate DEG        turn the environment about +Y; positive turns +Z toward +X\n"
    "  --colorspace NAME   output colour space (OCIO name, e.g. lin_rec709, acescg)\n"
    "  --input-colorspace NAME  override the input's colour space\n"
    "  --float             write 32-bit float EXR instead of half\n"
    "  --strict            NaN/Inf input pixels are an error (exit 3) instead of being\n"
    "                      counted, reported and replaced by 0\n"
    "  --json              print the result as JSON on stdout\n\n"
    "Projections follow OpenEXR's lat-long orientation; see docs/geometry.md.\n"
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

static bool is_ldr_path(const char *path)
{
    const char *dot = strrchr(path, '.');
    return dot && strcasecmp(dot, ".exr") != 0 && strcasecmp(dot, ".hdr") != 0;
}

int cmd_convert(int argc, char **argv, const sl_cli *cli)
{
    enum { OPT_FROM = 1000, OPT_TO, OPT_WIDTH, OPT_ROTATE, OPT_CS, OPT_INCS, OPT_FLOAT, OPT_STRICT };
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
        {0, 0, 0, 0}};
    int from = -1, to = SL_PROJ_LATLONG, width = 0;
    double rotate = 0;
    const char *out_cs = NULL, *in_cs = NULL;
    bool use_float = false, strict = false;

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
        default:
            return cli_usage_error(cli, "unknown option '%s'", argv[optind - 1]);
        }
    }
    if (argc - optind != 2)
        return cli_usage_error(cli, "needs an input and an output file");
    const char *in_path = argv[optind], *out_path = argv[optind + 1];
    double t0 = sl_seconds();

    sl_image src = {0}, dst = {0};
    sl_meta meta, out_meta;
    sl_meta_init(&out_meta);
    sl_error err;
    sl_result r = sl_image_read(in_path, &src, &meta, &err);
    if (r)
        return cli_fail(cli, &err);
    cli_warn_format_mismatch(in_path, &meta);
    /* A circular fisheye photo is no ball or angular map: refused, not swirled. */
    if (from == SL_PROJ_MIRRORBALL || from == SL_PROJ_ANGULAR) {
        sl_fisheye_evidence fisheye;
        if ((r = sl_fisheye_check(&src, !meta.is_float, in_path, &fisheye, &err)))
            goto fail;
    }

    if (from < 0)
        from = meta.envmap == SL_ENVMAP_CUBE ? SL_PROJ_CUBEMAP : SL_PROJ_LATLONG;
    if (from == SL_PROJ_LATLONG && !sl_is_latlong_shape(src.width, src.height)) {
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

    /* Colour: from the input's space (or scene-linear Rec.709) to the output's. */
    const char *src_cs = in_cs ? in_cs : sl_meta_color_space(&meta);
    if (!src_cs)
        src_cs = "lin_rec709";
    const char *dst_cs = out_cs ? out_cs : (is_ldr_path(out_path) ? "srgb" : src_cs);
    /* Reproject in linear light; encode at the end. */
    bool src_encoded = strcmp(src_cs, "srgb") == 0;
    if (src_encoded && (r = sl_color_convert(&src, src_cs, "lin_rec709", &err)))
        goto fail;
    const char *work_cs = src_encoded ? "lin_rec709" : src_cs;

    double rot[3][3];
    sl_rotation_y(rotate, rot);
    if (!width)
        width = output_width_default((sl_projection)from, &src);
    r = sl_reproject(&src, (sl_projection)from, (sl_projection)to, width, rotate != 0 ? rot : NULL,
                     &dst, &err);
    if (r)
        goto fail;
    if (strcmp(work_cs, dst_cs) != 0 && (r = sl_color_convert(&dst, work_cs, dst_cs, &err)))
        goto fail;

    out_meta.envmap = to == SL_PROJ_LATLONG ? SL_ENVMAP_LATLONG
                      : to == SL_PROJ_CUBEMAP ? SL_ENVMAP_CUBE
                                              : SL_ENVMAP_NONE;
    char buf[512];
    snprintf(buf, sizeof buf, "setlight %s convert --from %s --to %s --width %d --rotate %g",
             sl_version(), sl_projection_name((sl_projection)from),
             sl_projection_name((sl_projection)to), width, rotate);
    if ((r = sl_meta_set(&out_meta, "setlight:command", buf, &err)) ||
        (r = sl_meta_set(&out_meta, "setlight:source", in_path, &err)) ||
        (r = sl_meta_set_color_space(&out_meta, dst_cs, &err)))
        goto fail;
    if (nonfinite) {
        snprintf(buf, sizeof buf, "%lld", (long long)nonfinite);
        if ((r = sl_meta_set(&out_meta, "setlight:nonfinite_replaced", buf, &err)))
            goto fail;
    }
    r = sl_image_write(out_path, &dst, &out_meta, use_float ? SL_PIXEL_FLOAT : SL_PIXEL_HALF, &err);
    if (r)
        goto fail;

    if (cli->json) {
        json_t *o = json_pack("{s:s, s:s, s:s, s:s, s:i, s:i, s:f, s:s, s:I, s:f}", "input",
                              in_path, "output", out_path, "from",
                              sl_projection_name((sl_projection)from), "to",
                              sl_projection_name((sl_projection)to), "width", dst.width, "height",
                              dst.height, "rotate_degrees", rotate, "colorspace", dst_cs,
                              "nonfinite_replaced", (json_int_t)nonfinite, "seconds",
                              sl_seconds() - t0);
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
