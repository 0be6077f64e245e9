/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight rig ENV.exr -o RIG.usda: area lights plus a residual dome. */
#include <jansson.h>
#include <libgen.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/stat.h>

#include "cli.h"
#include "setlight/lightrig.h"

static const char *rig_help =
    "usage: setlight rig [options] ENV.exr -o RIG.usda [--json RIG.json]\n"
    "                    [--residual RES.exr] [--preview PREVIEW.png]\n\n"
    "Extracts the bright regions of a lat-long HDRI into area lights and paints them\n"
    "out of a residual dome, so that lights + dome carry exactly the map's energy.\n"
    "Writes USD (UsdLux), optionally the same rig as JSON and a preview PNG.\n"
    "ENV is read as every command reads an environment (docs/color.md): converted to\n"
    "scene-linear Rec.709 through OpenColorIO from its colour space (an 8/16-bit\n"
    "JPEG/PNG/TIFF is sRGB unless it says otherwise; a warning says so), and taken as\n"
    "a lat-long when 2:1 without an envmap attribute (a note says so).\n\n"
    "  -o, --output FILE     the rig as USD ASCII (.usda)\n"
    "  --json [FILE.json]    print a summary as JSON on stdout; when followed by a\n"
    "                        name ending in .json, also write rig.json there\n"
    "  --residual FILE.exr   the residual dome (default: RIG_residual.exr beside RIG.usda)\n"
    "  --preview FILE.png    the map with every light outlined and numbered\n"
    "  --energy F            keep the fewest lights carrying this share of the\n"
    "                        directional energy (default 0.9)\n"
    "  --max-lights N        at most N lights (N >= 1)\n"
    "  --threshold K         a light's texels are above K x the map's median\n"
    "                        luminance (solid-angle weighted; default 8)\n"
    "  --peak-fraction F     ... and at least F x the brightest texel of their bright\n"
    "                        area, so a lamp is not joined to the wall it lights\n"
    "                        (default 0.02; 0 keeps whole areas)\n"
    "  --max-solid-angle SR  wider regions stay in the dome (default 0.4; 0: no limit)\n"
    "  --merge DEG           fragments closer than DEG are one fixture (default 2)\n"
    "  --unresolved DEG      angular diameter given to sources smaller than the\n"
    "                        texels (default 0.53, the sun)\n"
    "  --distance D          place lights on a sphere of radius D (metres)\n"
    "  --room W,D,H          place lights on a box W wide (X), D deep (Z), H high (Y)\n"
    "  --capture-height H    height of the capture point in the room (needs --room)\n"
    "  --method M            regions (default) or mediancut (Debevec 2005; needs\n"
    "                        --max-lights)\n"
    "  --include LAT,LON     always keep the light there (degrees; grown from the\n"
    "                        brightest texel within 2 degrees if none was found)\n"
    "  --exclude LAT,LON     leave the light there in the dome (both repeatable)\n"
    "  --textures            texture every rect light (positioned or at infinity):\n"
    "                        the region's crop as RIG_light_NN.exr beside RIG.usda;\n"
    "                        by default only graded ones are (variation >= 0.25)\n"
    "  --no-textures         no textured lights\n"
    "  --input-colorspace NAME  the map's colour space (OCIO name), instead of the one\n"
    "                        the file names or the default (srgb for 8/16-bit)\n"
    "  --assume-latlong      no effect (kept for old scripts): a 2:1 image without\n"
    "                        the envmap attribute is taken as a lat-long, with a note\n"
    "  --validate[=SPP]      render the grey, chrome and shadow scenes (96 px) under\n"
    "                        the map and under the rig and report their relative\n"
    "                        RMSE (SPP samples per pixel, default 64); the report\n"
    "                        with the images is RIG.validate.html, its files in\n"
    "                        RIG.validate/ beside RIG.usda\n\n"
    "Exit codes: 0 done (also for a black map: an empty rig), 2 bad option (including\n"
    "--max-lights 0 and a room that does not contain the capture point), 3 bad input\n"
    "(missing, corrupt, not a lat-long), 1 could not write; 130/143 interrupted.\n"
    "The USD, JSON, residual, preview, textures and validation report are replaced\n"
    "together: a failure or an interrupt leaves every earlier one as it was. See\n"
    "docs/lightrig.md.\n";

/* The folder of an output exists: checked for every output before any is
 * written, so a run that fails on the last one has not written the first. */
static bool out_dir_ok(const char *path)
{
    char buf[PATH_MAX];
    struct stat st;
    snprintf(buf, sizeof buf, "%s", path);
    return stat(dirname(buf), &st) == 0 && S_ISDIR(st.st_mode);
}

static bool has_suffix(const char *s, const char *suffix)
{
    size_t n = strlen(s), m = strlen(suffix);
    return n >= m && strcasecmp(s + n - m, suffix) == 0;
}

int cmd_rig(int argc, char **argv, const sl_cli *cli)
{
    enum {
        OPT_RESIDUAL = 1000, OPT_PREVIEW, OPT_ENERGY, OPT_MAX, OPT_THRESHOLD, OPT_MERGE,
        OPT_UNRESOLVED, OPT_DISTANCE, OPT_ROOM, OPT_HEIGHT, OPT_METHOD, OPT_ASSUME, OPT_JSONFILE,
        OPT_INCLUDE, OPT_EXCLUDE, OPT_TEXTURES, OPT_NO_TEXTURES, OPT_PEAK, OPT_MAXSA, OPT_VALIDATE,
        OPT_INCS
    };
    static const struct option opts[] = {
        {"help", no_argument, NULL, 'h'},
        {"output", required_argument, NULL, 'o'},
        {"json", required_argument, NULL, OPT_JSONFILE}, /* only as --json=FILE */
        {"residual", required_argument, NULL, OPT_RESIDUAL},
        {"preview", required_argument, NULL, OPT_PREVIEW},
        {"energy", required_argument, NULL, OPT_ENERGY},
        {"max-lights", required_argument, NULL, OPT_MAX},
        {"threshold", required_argument, NULL, OPT_THRESHOLD},
        {"merge", required_argument, NULL, OPT_MERGE},
        {"unresolved", required_argument, NULL, OPT_UNRESOLVED},
        {"distance", required_argument, NULL, OPT_DISTANCE},
        {"room", required_argument, NULL, OPT_ROOM},
        {"capture-height", required_argument, NULL, OPT_HEIGHT},
        {"method", required_argument, NULL, OPT_METHOD},
        {"assume-latlong", no_argument, NULL, OPT_ASSUME},
        {"include", required_argument, NULL, OPT_INCLUDE},
        {"exclude", required_argument, NULL, OPT_EXCLUDE},
        {"textures", no_argument, NULL, OPT_TEXTURES},
        {"no-textures", no_argument, NULL, OPT_NO_TEXTURES},
        {"peak-fraction", required_argument, NULL, OPT_PEAK},
        {"max-solid-angle", required_argument, NULL, OPT_MAXSA},
        {"validate", optional_argument, NULL, OPT_VALIDATE},
        {"input-colorspace", required_argument, NULL, OPT_INCS},
        {0, 0, 0, 0}};
    sl_rig_options opt;
    sl_rig_options_default(&opt);
    const char *out_path = NULL, *json_path = NULL, *res_path = NULL, *preview_path = NULL;
    const char *in_cs = NULL;
    bool have_height = false, max_given = false;
    sl_rig_texture_mode textures = SL_RIG_TEXTURES_AUTO;
    long long validate_spp = 0;

    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, "ho:", opts, NULL)) != -1) {
        switch (c) {
        case 'h':
            fputs(rig_help, stdout);
            return 0;
        case 'o':
            out_path = optarg;
            break;
        case OPT_VALIDATE: {
            char *end = NULL;
            validate_spp = optarg ? strtoll(optarg, &end, 10) : 64;
            if (optarg && (end == optarg || *end || validate_spp < 1 || validate_spp > 1 << 20))
                return cli_usage_error(cli, "--validate needs samples per pixel in 1..%d, not '%s'",
                                       1 << 20, optarg);
            break;
        }
        case OPT_JSONFILE:
            json_path = optarg;
            break;
        case OPT_RESIDUAL:
            res_path = optarg;
            break;
        case OPT_PREVIEW:
            preview_path = optarg;
            break;
        case OPT_ENERGY:
            if (!cli_parse_double(optarg, &opt.energy) || !(opt.energy > 0 && opt.energy <= 1))
                return cli_usage_error(cli, "--energy needs a share in (0, 1], not '%s'", optarg);
            break;
        case OPT_MAX:
            if (!cli_parse_int(optarg, &opt.max_lights) || opt.max_lights < 1)
                return cli_usage_error(cli,
                                       "--max-lights needs a whole number of 1 or more, not '%s' "
                                       "(for no lights, use the map itself as the dome)",
                                       optarg);
            max_given = true;
            break;
        case OPT_THRESHOLD:
            if (!cli_parse_double(optarg, &opt.threshold) || !(opt.threshold > 1))
                return cli_usage_error(cli, "--threshold needs a number above 1, not '%s'", optarg);
            break;
        case OPT_PEAK:
            if (!cli_parse_double(optarg, &opt.peak_fraction) || opt.peak_fraction < 0 ||
                opt.peak_fraction > 1)
                return cli_usage_error(cli, "--peak-fraction needs a number in [0, 1], not '%s'",
                                       optarg);
            break;
        case OPT_MAXSA:
            if (!cli_parse_double(optarg, &opt.max_solid_angle) || opt.max_solid_angle < 0 ||
                opt.max_solid_angle > 4 * M_PI)
                return cli_usage_error(cli, "--max-solid-angle needs sr in [0, 4 pi], not '%s'",
                                       optarg);
            break;
        case OPT_MERGE:
            if (!cli_parse_double(optarg, &opt.merge_degrees) || opt.merge_degrees < 0 ||
                opt.merge_degrees > 90)
                return cli_usage_error(cli, "--merge needs degrees from 0 to 90, not '%s'", optarg);
            break;
        case OPT_UNRESOLVED:
            if (!cli_parse_double(optarg, &opt.unresolved_degrees) ||
                !(opt.unresolved_degrees > 0 && opt.unresolved_degrees < 10))
                return cli_usage_error(cli, "--unresolved needs degrees in (0, 10), not '%s'",
                                       optarg);
            break;
        case OPT_DISTANCE:
            if (!cli_parse_double(optarg, &opt.distance) || !(opt.distance > 0))
                return cli_usage_error(cli, "--distance needs a positive number, not '%s'", optarg);
            break;
        case OPT_ROOM: {
            char tail;
            if (sscanf(optarg, "%lf,%lf,%lf%c", &opt.room[0], &opt.room[1], &opt.room[2],
                       &tail) != 3 ||
                !(opt.room[0] > 0 && opt.room[1] > 0 && opt.room[2] > 0) ||
                !isfinite(opt.room[0] + opt.room[1] + opt.room[2]))
                return cli_usage_error(cli, "--room needs W,D,H (three positive sizes), not '%s'",
                                       optarg);
            break;
        }
        case OPT_HEIGHT:
            if (!cli_parse_double(optarg, &opt.capture_height))
                return cli_usage_error(cli, "--capture-height needs a number, not '%s'", optarg);
            have_height = true;
            break;
        case OPT_METHOD:
            if (!strcmp(optarg, "regions"))
                opt.method = SL_RIG_METHOD_REGIONS;
            else if (!strcmp(optarg, "mediancut"))
                opt.method = SL_RIG_METHOD_MEDIANCUT;
            else
                return cli_usage_error(cli, "unknown method '%s' (regions, mediancut)", optarg);
            break;
        case OPT_ASSUME: /* the default now: a 2:1 image is a lat-long */
            break;
        case OPT_INCS:
            if (!(in_cs = sl_color_space_name(optarg)))
                return cli_usage_error(cli, "unknown colour space '%s' (see docs/color.md)", optarg);
            break;
        case OPT_TEXTURES:
        case OPT_NO_TEXTURES:
            if (textures != SL_RIG_TEXTURES_AUTO &&
                textures != (c == OPT_TEXTURES ? SL_RIG_TEXTURES_ALL : SL_RIG_TEXTURES_NONE))
                return cli_usage_error(cli, "--textures and --no-textures exclude each other");
            textures = c == OPT_TEXTURES ? SL_RIG_TEXTURES_ALL : SL_RIG_TEXTURES_NONE;
            break;
        case OPT_INCLUDE:
        case OPT_EXCLUDE: {
            bool inc = c == OPT_INCLUDE;
            int *n = inc ? &opt.include_count : &opt.exclude_count;
            double *t = inc ? opt.include[*n < SL_RIG_MAX_TAGS ? *n : 0]
                            : opt.exclude[*n < SL_RIG_MAX_TAGS ? *n : 0];
            char tail;
            if (*n >= SL_RIG_MAX_TAGS)
                return cli_usage_error(cli, "at most %d --%s tags", SL_RIG_MAX_TAGS,
                                       inc ? "include" : "exclude");
            if (sscanf(optarg, "%lf,%lf%c", &t[0], &t[1], &tail) != 2 || !(fabs(t[0]) <= 90) ||
                !(fabs(t[1]) <= 180))
                return cli_usage_error(cli,
                                       "--%s needs LAT,LON in degrees (latitude within +-90, "
                                       "longitude within +-180), not '%s'",
                                       inc ? "include" : "exclude", optarg);
            (*n)++;
            break;
        }
        default:
            return cli_usage_error(cli, "unknown option '%s'", argv[optind - 1]);
        }
    }
    int npos = argc - optind;
    /* The global --json is taken before this parser sees it; a .json name
     * that followed it is left as a second operand. */
    if (npos == 2 && cli->json && has_suffix(argv[optind + 1], ".json") && !json_path) {
        json_path = argv[optind + 1];
        npos = 1;
    }
    if (npos != 1)
        return cli_usage_error(cli, "needs one input map (and -o RIG.usda)");
    if (!out_path)
        return cli_usage_error(cli, "needs -o RIG.usda");
    if (!has_suffix(out_path, ".usda"))
        return cli_usage_error(
            cli, "the rig is written as USD ASCII: -o needs a .usda name, not '%s'", out_path);
    if (json_path && !has_suffix(json_path, ".json"))
        return cli_usage_error(cli, "--json needs a .json name, not '%s'", json_path);
    if (res_path && !has_suffix(res_path, ".exr"))
        return cli_usage_error(cli, "--residual needs an .exr name, not '%s'", res_path);
    if (preview_path && !has_suffix(preview_path, ".png"))
        return cli_usage_error(cli, "--preview needs a .png name, not '%s'", preview_path);
    bool room = opt.room[0] > 0;
    if (room != have_height)
        return cli_usage_error(cli, "--room and --capture-height go together");
    if (room && opt.distance > 0)
        return cli_usage_error(cli, "give --distance or --room, not both");
    if (room && !(opt.capture_height > 0 && opt.capture_height < opt.room[2]))
        return cli_usage_error(cli,
                               "the room (%g high) does not contain the capture point at height %g",
                               opt.room[2], opt.capture_height);
    if (opt.method == SL_RIG_METHOD_MEDIANCUT && !max_given)
        return cli_usage_error(cli, "--method mediancut needs --max-lights N");
    const char *in_path = argv[optind];
    char res_buf[PATH_MAX];
    if (!res_path) {
        size_t n = strlen(out_path) - 5;
        snprintf(res_buf, sizeof res_buf, "%.*s_residual.exr", (int)n, out_path);
        res_path = res_buf;
    }
    const char *outs[4] = {out_path, res_path, json_path, preview_path};
    for (int k = 0; k < 4; k++)
        if (outs[k] && !out_dir_ok(outs[k]))
            return cli_usage_error(cli, "%s: output folder missing", outs[k]);
    /* The validation report: RIG.validate.html and RIG.validate/ beside the USD. */
    char rep_dir[PATH_MAX], rep_name[PATH_MAX];
    {
        char a[PATH_MAX], b[PATH_MAX];
        snprintf(a, sizeof a, "%s", out_path);
        snprintf(b, sizeof b, "%s", out_path);
        snprintf(rep_dir, sizeof rep_dir, "%s", dirname(a));
        const char *base = basename(b);
        snprintf(rep_name, sizeof rep_name, "%.*s.validate", (int)(strlen(base) - 5), base);
    }
    if (validate_spp > 0) {
        sl_error e;
        if (sl_rig_validate_report_check(rep_dir, rep_name, &e))
            return cli_usage_error(cli, "%s", e.message);
    }
    sl_rig_run_options ro;
    sl_rig_run_options_init(&ro);
    ro.input_path = in_path;
    ro.input_colorspace = in_cs;
    ro.out_path = out_path;
    ro.json_path = json_path;
    ro.residual_path = res_path;
    ro.preview_path = preview_path;
    ro.rig = opt;
    ro.textures = textures;
    ro.validate_spp = validate_spp;
    sl_rig_run_result res;
    sl_error err;
    if (sl_rig_run(&ro, &res, &err)) {
        sl_rig_run_result_free(&res);
        return cli_fail(cli, &err);
    }
    if (cli->json)
        printf("%s\n", res.json);
    else if (!sl_log_is_quiet())
        sl_log(SL_LOG_INFO, "%s: %d lights, %d skipped, ledger error %.2g", out_path,
               res.rig.light_count, res.rig.skipped_count, res.rig.relative_error);
    sl_rig_run_result_free(&res);
    return 0;
}
