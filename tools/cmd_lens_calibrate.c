/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight lens-calibrate -o PROFILE.json PHOTO...: a lens profile from
 * chessboard photos. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "setlight/stitch.h"

static const char *lens_calibrate_help =
    "usage: setlight lens-calibrate [options] --board COLSxROWS --sensor-mm W[,H]\n"
    "                               -o PROFILE.json PHOTO...\n\n"
    "Solves a lens profile (docs/formats.md, \"Lens profiles\") from photos of a flat\n"
    "chessboard taken through the lens, for `setlight stitch --lens-profile`. The board's\n"
    "corners are found in each photo (OpenCV); the lens is solved on setlight's own\n"
    "model (the one stitch uses, rays up to 90 degrees off-axis and beyond): focal\n"
    "length, optical centre and as many radial terms as the corners support, together\n"
    "with every board's pose. Photos without the board are reported and left out; at\n"
    "least 3 must show it, spread over the field for the radial terms to mean anything.\n\n"
    "  -o, --output FILE     the profile (JSON, written atomically)\n"
    "  --board COLSxROWS     inner corners of the board (a board of 8 x 11 squares has\n"
    "                        7x10); required\n"
    "  --square-mm S         side of a square (default 25; moves only the board poses)\n"
    "  --projection NAME     equisolid (default: 8 mm circular fisheyes), equidistant,\n"
    "                        stereographic, orthographic, rectilinear\n"
    "  --focal-mm F          nominal focal length (default: the photos' EXIF)\n"
    "  --sensor-mm W[,H]     width (and height) of the sensor area the photo shows, in mm;\n"
    "                        required (a square crop of a 36 x 24 mm frame is 24,24)\n"
    "  --radial-terms N      solve exactly N radial terms (0..3; default: add terms while\n"
    "                        each cuts the RMS by 10%%)\n\n"
    "Prints, per photo, the board found or why not and its RMS reprojection error;\n"
    "then the solved lens and its change from the nominal one (--json: the same as JSON).\n\n"
    "Exit codes: 0 solved, 2 bad option, 3 bad input (a photo missing or unreadable,\n"
    "photos of different sizes or cameras, fewer than 3 boards found, no focal length\n"
    "anywhere, a solve that does not converge), 1 could not write.\n";

static json_t *result_json(const sl_lens_calibrate_result *res, const char *out_path)
{
    const sl_lens *l = &res->profile.lens, *n = &res->nominal;
    json_t *photos = json_array();
    for (int i = 0; i < res->photo_count; i++) {
        const sl_lens_calibrate_photo *p = &res->photos[i];
        json_t *o = json_pack("{s:s, s:b, s:b}", "file", p->name, "found", p->found, "used",
                              p->used);
        if (p->found) {
            json_object_set_new(o, "rms_px", json_real(p->rms_px));
            json_object_set_new(o, "max_px", json_real(p->max_px));
        }
        if (!p->used)
            json_object_set_new(o, "why", json_string(p->why));
        json_array_append_new(photos, o);
    }
    return json_pack(
        "{s:s, s:s, s:s, s:i, s:i, s:f, s:f, s:i, s:{s:f, s:f, s:f, s:f, s:f, s:f, s:f, s:f}, "
        "s:{s:f, s:f, s:f, s:f}, s:o}",
        "profile", out_path, "camera", res->profile.camera, "projection",
        sl_lens_projection_name(l->projection), "photos_used", res->used, "radial_terms",
        res->radial_terms, "rms_px", res->profile.rms_px, "max_px", res->profile.max_px, "width",
        l->width, "solved", "focal_px", l->focal_px, "focal_mm", res->focal_mm, "cx", l->cx, "cy",
        l->cy, "k1", l->k[0], "k2", l->k[1], "k3", l->k[2], "circle_radius_px",
        l->circle_radius_px, "nominal", "focal_px", n->focal_px, "focal_mm",
        res->nominal_focal_mm, "cx", n->cx, "cy", n->cy, "photos", photos);
}

static void print_result(const sl_lens_calibrate_result *res, const char *out_path)
{
    const sl_lens *l = &res->profile.lens, *n = &res->nominal;
    for (int i = 0; i < res->photo_count; i++) {
        const sl_lens_calibrate_photo *p = &res->photos[i];
        if (p->used)
            printf("%s: board found, RMS %.3f px, max %.3f px\n", p->name, p->rms_px, p->max_px);
        else
            printf("%s: left out: %s\n", p->name, p->why);
    }
    printf("lens (%s, %s, %dx%d) from %d of %d photos, %d radial terms: RMS %.3f px, max %.3f "
           "px\n",
           res->profile.camera[0] ? res->profile.camera : "camera unknown",
           sl_lens_projection_name(l->projection), l->width, l->height, res->used,
           res->photo_count, res->radial_terms, res->profile.rms_px, res->profile.max_px);
    printf("  focal   %.2f px = %.3f mm  (nominal %.2f px = %.3f mm, %+.2f%%)\n", l->focal_px,
           res->focal_mm, n->focal_px, res->nominal_focal_mm,
           100.0 * (l->focal_px / n->focal_px - 1.0));
    printf("  centre  (%.2f, %.2f) px  (image centre %+.2f, %+.2f px)\n", l->cx, l->cy,
           l->cx - n->cx, l->cy - n->cy);
    printf("  radial  k1 %.5f  k2 %.5f  k3 %.5f\n", l->k[0], l->k[1], l->k[2]);
    if (l->circle_radius_px > 0)
        printf("  circle  %.1f px at %.0f deg off-axis (nominal %.1f px)\n", l->circle_radius_px,
               l->max_theta_deg, n->circle_radius_px);
    printf("wrote %s\n", out_path);
}

int cmd_lens_calibrate(int argc, char **argv, const sl_cli *cli)
{
    enum { OPT_BOARD = 1000, OPT_SQUARE, OPT_PROJECTION, OPT_FOCAL, OPT_SENSOR, OPT_TERMS };
    static const struct option opts[] = {
        {"help", no_argument, NULL, 'h'},
        {"output", required_argument, NULL, 'o'},
        {"board", required_argument, NULL, OPT_BOARD},
        {"square-mm", required_argument, NULL, OPT_SQUARE},
        {"projection", required_argument, NULL, OPT_PROJECTION},
        {"focal-mm", required_argument, NULL, OPT_FOCAL},
        {"sensor-mm", required_argument, NULL, OPT_SENSOR},
        {"radial-terms", required_argument, NULL, OPT_TERMS},
        {NULL, 0, NULL, 0},
    };
    sl_lens_calibrate_options opt;
    sl_lens_calibrate_options_init(&opt);
    const char *out_path = NULL;
    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, ":ho:", opts, NULL)) != -1) {
        switch (c) {
        case 'h':
            fputs(lens_calibrate_help, stdout);
            return 0;
        case 'o':
            out_path = optarg;
            break;
        case OPT_BOARD: {
            char tail;
            if (sscanf(optarg, "%dx%d%c", &opt.board_cols, &opt.board_rows, &tail) != 2 ||
                opt.board_cols < 2 || opt.board_rows < 2 || opt.board_cols > 100 ||
                opt.board_rows > 100)
                return cli_usage_error(cli, "--board needs COLSxROWS inner corners (2..100 each), "
                                            "not '%s'", optarg);
            break;
        }
        case OPT_SQUARE:
            if (!cli_parse_double(optarg, &opt.square_mm) || !(opt.square_mm > 0))
                return cli_usage_error(cli, "--square-mm needs a positive size, not '%s'", optarg);
            break;
        case OPT_PROJECTION: {
            int p = sl_lens_projection_from_name(optarg);
            if (p < 0)
                return cli_usage_error(cli, "unknown projection '%s' (equisolid, equidistant, "
                                            "stereographic, orthographic, rectilinear)", optarg);
            opt.projection = (sl_lens_projection)p;
            break;
        }
        case OPT_FOCAL:
            if (!cli_parse_double(optarg, &opt.focal_mm) || !(opt.focal_mm > 0))
                return cli_usage_error(cli, "--focal-mm needs a positive length, not '%s'", optarg);
            break;
        case OPT_SENSOR: {
            double wh[2];
            if (cli_parse_list(optarg, wh, 2) && wh[0] > 0 && wh[1] > 0)
                opt.sensor_width_mm = wh[0];
            else if (!cli_parse_double(optarg, &opt.sensor_width_mm) ||
                     !(opt.sensor_width_mm > 0))
                return cli_usage_error(cli, "--sensor-mm needs W or W,H in mm, not '%s'", optarg);
            break;
        }
        case OPT_TERMS:
            if (!cli_parse_int(optarg, &opt.radial_terms) || opt.radial_terms < 0 ||
                opt.radial_terms > 3)
                return cli_usage_error(cli, "--radial-terms needs 0, 1, 2 or 3, not '%s'", optarg);
            break;
        case ':':
            return cli_usage_error(cli, "%s needs a value", argv[optind - 1]);
        default:
            return cli_usage_error(cli, "unknown option '%s'", argv[optind - 1]);
        }
    }
    if (!out_path)
        return cli_usage_error(cli, "-o PROFILE.json is required");
    if (!opt.board_cols)
        return cli_usage_error(cli, "--board COLSxROWS (inner corners) is required");
    if (!(opt.sensor_width_mm > 0))
        return cli_usage_error(cli, "--sensor-mm W[,H] is required (the sensor area the photo "
                                    "shows, in mm)");
    if (optind >= argc)
        return cli_usage_error(cli, "no photos");

    sl_error err = {0};
    sl_lens_calibrate_result res;
    sl_result r = sl_lens_calibrate((const char *const *)(argv + optind), argc - optind, &opt,
                                    &res, &err);
    if (!r)
        r = sl_lens_profile_write(out_path, &res.profile, &err);
    if (r) {
        sl_lens_calibrate_result_free(&res);
        return cli_fail(cli, &err);
    }
    if (cli->json) {
        json_t *o = result_json(&res, out_path);
        char *text = o ? json_dumps(o, JSON_INDENT(1) | JSON_REAL_PRECISION(8)) : NULL;
        if (text)
            printf("%s\n", text);
        free(text);
        json_decref(o);
    } else if (!cli->quiet) {
        print_result(&res, out_path);
    }
    sl_lens_calibrate_result_free(&res);
    return 0;
}
