/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight merge and setlight response: brackets to HDR radiance, and the
 * camera response recovered from a bracket. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "setlight/stitch.h"

static const char *merge_help =
    "usage: setlight merge [options] -o OUT.exr FRAME...\n\n"
    "Merges a bracket of exposures (any order; PNG, JPEG and TIFF read by libpng,\n"
    "libjpeg and libtiff, any other format OpenImageIO reads, which costs ~0.4 s of\n"
    "CPU to load once) into one EXR of relative radiance, scaled like the middle exposure,\n"
    "written strip by strip as it is merged.\n\n"
    "  -o, --output OUT.exr   the radiance image (required)\n"
    "  --times T1,T2,...      exposure times in seconds (e.g. 1/30,1/250), in frame order;\n"
    "                         default: EXIF ExposureTime (with FNumber and ISO when every\n"
    "                         frame has them: relative exposure t * ISO / N^2)\n"
    "  --response MODE        auto (Debevec-Malik from the bracket, default; frames\n"
    "                         whose files say they are linear, raw or a linear ICC\n"
    "                         profile, are taken as linear), robertson (Robertson et\n"
    "                         al. from the bracket), linear (raw, linear TIFF/EXR), or\n"
    "                         a curve file from 'setlight response'; --json's\n"
    "                         response_check says how well the frames agree through it\n"
    "  --exposures SRC        exif (default) or data: use exposure ratios measured from\n"
    "                         the pixels; either way disagreements are reported, and a\n"
    "                         fitted curve takes the measured exposure of a frame that\n"
    "                         disagrees (of every JPEG frame: its coding moves its codes)\n"
    "  --mask PATH            clipped mask EXR (R,G,B = 1 where saturated in every\n"
    "                         frame); default OUT_clipped.exr; --no-mask to skip\n"
    "  --deghost              leave out, per pixel, frames that disagree with the others\n"
    "                         beyond the noise model (moving people, cars, leaves); the\n"
    "                         ghost mask (Y = 1 where a frame was left out) goes to\n"
    "                         OUT_ghost.exr unless --ghost-mask PATH\n"
    "  --align MODE           auto (default): measure every frame's shift against the\n"
    "                         middle exposure while sampling, and register the frames\n"
    "                         (translation and small rotation, sub-pixel) when one moved\n"
    "                         more than 0.5 px anywhere on the frame and more than twice\n"
    "                         what the fit can tell (little texture: warned, merged as\n"
    "                         shot); on: always register; off: merge as shot, nothing\n"
    "                         measured. Also --align=MODE; --align alone is on. Shifts\n"
    "                         per frame in the summary line, --json and the EXR\n"
    "  --align-max-shift PX   larger shifts are refused (default 64)\n"
    "  --align-max-angle DEG  larger rotations are refused (default 2, at most 10)\n"
    "  --noise GAIN,FLOOR     noise model var = GAIN * y + FLOOR, y in 0..1 (default\n"
    "                         2e-5,1e-6: a 50000-electron well); it weights the frames\n"
    "                         and, from 8/16-bit lossless frames, the response's fit\n"
    "                         (a 4000-electron well, 3 e- read noise: 2.5e-4,5.6e-7)\n"
    "  --saturation Z         values at or above Z (0..1) are saturated (default: 0.95\n"
    "                         through a curve from JPEG, the clip code 1 from lossless\n"
    "                         PNG/TIFF, 0.98 with --response linear or raw)\n"
    "  --black Z              values at or below Z carry no weight (default 0.004)\n"
    "  --tolerance STOPS      EXIF vs data disagreement reported above (default 0.2)\n"
    "  --samples N            response samples per channel (default 4000)\n"
    "  --smoothness L         response smoothness (default 10 at 3-stop steps)\n"
    "  --response-prior P     a prior on the self-calibrated curve's shape: off (default)\n"
    "                         or dorf (the 201 camera and film curves of Columbia's DoRF\n"
    "                         database; left out when the curve fitted without it is far\n"
    "                         from them). For film-like curves and scenes spanning the\n"
    "                         codes; it bends the scale of pure gamma curves (docs/merge.md)\n"
    "  --response-refine R    off (default) or on: the self-calibrated curve from 8-bit\n"
    "                         lossless frames refined by maximum likelihood under the\n"
    "                         sensor's noise, fitted from the frames: 1-2 s more, and\n"
    "                         the curve nearer the truth (docs/merge.md). setlight\n"
    "                         response refines by default\n"
    "  --absolute             output in cd/m^2 from EXIF time, f-number and ISO:\n"
    "                         L = 120 y N^2 / (t ISO), y linear with 1 = saturation (ISO\n"
    "                         12232 saturation speed, lens factor 0.65); default relative\n"
    "  --half, --float        radiance samples; default: half when every value fits\n"
    "                         (below 65504) and its rounding stays under a quarter of the\n"
    "                         noise model's deviation, else float (docs/merge.md)\n"
    "  --compression C        zip (default), piz, rle or none (all lossless)\n"
    "  --hold-mb MB           8/16-bit frames kept decoded between the sample and merge\n"
    "                         passes up to MB (default 384); the rest are decoded twice\n"
    "  --json                 print the result (frames, exposures, clipping) as JSON\n\n"
    "Exit codes: 0 merged, 1 runtime failure, 2 usage error, 3 bad input (frames of\n"
    "different sizes or bit depths, duplicate exposures, no exposure information,\n"
    "corrupt, all black or all saturated frames); 130/143 interrupted. The radiance\n"
    "and its masks are replaced together: a failure or an interrupt leaves every\n"
    "earlier one as it was. See docs/merge.md.\n";

static const char *response_help =
    "usage: setlight response [options] -o CRF.json FRAME...\n\n"
    "Recovers the camera response (Debevec-Malik) from one bracket and saves it for\n"
    "'setlight merge --response CRF.json' on the rest of a shoot.\n\n"
    "  -o, --output CRF.json  the response curve file (required)\n"
    "  --times, --exposures, --saturation, --black, --samples, --smoothness,\n"
    "  --response-prior, --response-refine, --tolerance, --align\n"
    "                         as for setlight merge (alignment auto, and the curve\n"
    "                         refined under the noise, by default)\n"
    "  --json                 print the exposure check and curve summary as JSON\n";


static bool parse_time(const char *s, double *out)
{
    const char *slash = strchr(s, '/');
    if (!slash)
        return cli_parse_double(s, out) && *out > 0;
    char num[64];
    size_t n = (size_t)(slash - s);
    if (n == 0 || n >= sizeof num)
        return false;
    memcpy(num, s, n);
    num[n] = '\0';
    double a, b;
    if (!cli_parse_double(num, &a) || !cli_parse_double(slash + 1, &b) || !(b > 0))
        return false;
    *out = a / b;
    return *out > 0;
}

/* "1/30,1/4,2" -> times; returns the count or -1 on junk. */
static int parse_times(const char *s, double **times)
{
    int n = 1;
    for (const char *p = s; *p; p++)
        n += *p == ',';
    *times = calloc((size_t)n, sizeof **times);
    char *copy = strdup(s);
    if (!*times || !copy) {
        free(copy);
        return -1;
    }
    int k = 0;
    char *save = NULL;
    for (char *tok = strtok_r(copy, ",", &save); tok; tok = strtok_r(NULL, ",", &save))
        if (k >= n || !parse_time(tok, &(*times)[k++])) {
            free(copy);
            return -1;
        }
    free(copy);
    return k == n ? n : -1;
}

typedef struct merge_args {
    sl_merge_options opt;
    const char *output;
    const char *mask;
    const char *ghost_mask;
    bool no_mask;
    double *times;
    int time_count;
    sl_response response;
} merge_args;

static bool parse_align_mode(const char *s, sl_align_mode *mode)
{
    if (!strcmp(s, "auto"))
        *mode = SL_ALIGN_AUTO;
    else if (!strcmp(s, "on"))
        *mode = SL_ALIGN_ON;
    else if (!strcmp(s, "off"))
        *mode = SL_ALIGN_OFF;
    else
        return false;
    return true;
}

/* Parses options shared by merge and response; returns -1 to go on, else an exit code. */
static int parse_args(int argc, char **argv, const sl_cli *cli, bool is_merge, merge_args *a)
{
    enum { OPT_TIMES = 1000, OPT_RESP, OPT_EXPO, OPT_MASK, OPT_NOMASK, OPT_NOISE, OPT_SAT,
           OPT_BLACK, OPT_TOL, OPT_SAMPLES, OPT_SMOOTH, OPT_DEGHOST, OPT_GHOSTMASK,
           OPT_ABS, OPT_ALIGN, OPT_ALIGN_SHIFT, OPT_ALIGN_ANGLE, OPT_HALF, OPT_FLOAT,
           OPT_COMPRESSION, OPT_HOLD, OPT_PRIOR, OPT_REFINE };
    static const struct option opts[] = {
        {"help", no_argument, NULL, 'h'},
        {"output", required_argument, NULL, 'o'},
        {"times", required_argument, NULL, OPT_TIMES},
        {"response", required_argument, NULL, OPT_RESP},
        {"exposures", required_argument, NULL, OPT_EXPO},
        {"mask", required_argument, NULL, OPT_MASK},
        {"no-mask", no_argument, NULL, OPT_NOMASK},
        {"noise", required_argument, NULL, OPT_NOISE},
        {"saturation", required_argument, NULL, OPT_SAT},
        {"black", required_argument, NULL, OPT_BLACK},
        {"tolerance", required_argument, NULL, OPT_TOL},
        {"samples", required_argument, NULL, OPT_SAMPLES},
        {"smoothness", required_argument, NULL, OPT_SMOOTH},
        {"deghost", no_argument, NULL, OPT_DEGHOST},
        {"ghost-mask", required_argument, NULL, OPT_GHOSTMASK},
        {"absolute", no_argument, NULL, OPT_ABS},
        {"align", optional_argument, NULL, OPT_ALIGN},
        {"align-max-shift", required_argument, NULL, OPT_ALIGN_SHIFT},
        {"align-max-angle", required_argument, NULL, OPT_ALIGN_ANGLE},
        {"half", no_argument, NULL, OPT_HALF},
        {"float", no_argument, NULL, OPT_FLOAT},
        {"compression", required_argument, NULL, OPT_COMPRESSION},
        {"hold-mb", required_argument, NULL, OPT_HOLD},
        {"response-prior", required_argument, NULL, OPT_PRIOR},
        {"response-refine", required_argument, NULL, OPT_REFINE},
        {0, 0, 0, 0}};
    sl_merge_options_init(&a->opt);
    /* a curve made once for a shoot is worth the refinement's second or two */
    a->opt.refine_response = !is_merge;
    a->opt.response_mode = SL_RESPONSE_AUTO;
    cli_getopt_reset();
    int c, which = 0;
    while ((c = getopt_long(argc, argv, "ho:", opts, &which)) != -1) {
        bool merge_only = c == OPT_RESP || c == OPT_MASK || c == OPT_NOMASK || c == OPT_NOISE ||
                          c == OPT_DEGHOST || c == OPT_GHOSTMASK || c == OPT_ABS ||
                          c == OPT_HALF || c == OPT_FLOAT || c == OPT_COMPRESSION ||
                          c == OPT_HOLD;
        if (merge_only && !is_merge)
            return cli_usage_error(cli, "unknown option '--%s'", opts[which].name);
        switch (c) {
        case 'h':
            fputs(is_merge ? merge_help : response_help, stdout);
            return 0;
        case 'o':
            a->output = optarg;
            break;
        case OPT_HALF:
        case OPT_FLOAT:
            a->opt.pixels = c == OPT_HALF ? SL_MERGE_PIXELS_HALF : SL_MERGE_PIXELS_FLOAT;
            break;
        case OPT_HOLD:
            if (!cli_parse_double(optarg, &a->opt.hold_mb) || !(a->opt.hold_mb >= 0))
                return cli_usage_error(cli, "--hold-mb needs a non-negative number, not '%s'",
                                       optarg);
            break;
        case OPT_COMPRESSION:
            if (!cli_parse_compression(optarg, &a->opt.compression))
                return cli_usage_error(cli, "--compression is piz, zip, rle or none, not '%s'",
                                       optarg);
            break;
        case OPT_TIMES:
            free(a->times);
            if ((a->time_count = parse_times(optarg, &a->times)) < 0)
                return cli_usage_error(cli, "--times needs positive seconds like 1/30,1/4,2, not '%s'",
                                       optarg);
            break;
        case OPT_RESP:
            sl_response_free(&a->response);
            if (!strcmp(optarg, "auto"))
                a->opt.response_mode = SL_RESPONSE_AUTO;
            else if (!strcmp(optarg, "robertson"))
                a->opt.response_mode = SL_RESPONSE_ROBERTSON;
            else if (!strcmp(optarg, "linear"))
                a->opt.response_mode = SL_RESPONSE_LINEAR;
            else {
                sl_error err;
                if (sl_response_read(optarg, &a->response, &err))
                    return cli_fail(cli, &err);
                a->opt.response_mode = SL_RESPONSE_GIVEN;
                a->opt.response = &a->response;
            }
            break;
        case OPT_EXPO:
            if (!strcmp(optarg, "exif"))
                a->opt.exposures = SL_EXPOSURES_EXIF;
            else if (!strcmp(optarg, "data"))
                a->opt.exposures = SL_EXPOSURES_DATA;
            else
                return cli_usage_error(cli, "--exposures is exif or data, not '%s'", optarg);
            break;
        case OPT_MASK:
            a->mask = optarg;
            break;
        case OPT_NOMASK:
            a->no_mask = true;
            break;
        case OPT_DEGHOST:
            a->opt.deghost = true;
            break;
        case OPT_ABS:
            a->opt.absolute = true;
            break;
        case OPT_GHOSTMASK:
            a->ghost_mask = optarg;
            a->opt.deghost = true;
            break;
        case OPT_ALIGN: {
            /* --align alone is on (as before modes); --align=MODE, and --align
             * MODE when the next word is a mode (getopt only attaches with '='). */
            const char *mode = optarg;
            if (!mode && optind < argc && parse_align_mode(argv[optind], &a->opt.align))
                mode = argv[optind++];
            if (!mode)
                a->opt.align = SL_ALIGN_ON;
            else if (!parse_align_mode(mode, &a->opt.align))
                return cli_usage_error(cli, "--align is auto, on or off, not '%s'", mode);
            break;
        }
        case OPT_ALIGN_SHIFT:
        case OPT_ALIGN_ANGLE: {
            double v;
            double top = c == OPT_ALIGN_SHIFT ? 1e6 : 10;
            if (!cli_parse_double(optarg, &v) || !(v > 0) || v > top)
                return cli_usage_error(cli, "--%s needs a number above 0%s, not '%s'",
                                       opts[which].name, c == OPT_ALIGN_ANGLE ? " and at most 10" : "",
                                       optarg);
            if (c == OPT_ALIGN_SHIFT)
                a->opt.align_max_shift = v;
            else
                a->opt.align_max_angle = v;
            break;
        }
        case OPT_NOISE: {
            double *v = NULL;
            int n = parse_times(optarg, &v);
            if (n != 2) {
                free(v);
                return cli_usage_error(cli, "--noise needs GAIN,FLOOR (two positive numbers), not '%s'",
                                       optarg);
            }
            a->opt.noise_gain = v[0];
            a->opt.noise_floor = v[1];
            free(v);
            break;
        }
        case OPT_SAT:
        case OPT_BLACK:
        case OPT_TOL:
        case OPT_SMOOTH: {
            double v;
            if (!cli_parse_double(optarg, &v) || v < 0)
                return cli_usage_error(cli, "--%s needs a non-negative number, not '%s'",
                                       opts[which].name, optarg);
            if (c == OPT_SAT)
                a->opt.saturation = v;
            else if (c == OPT_BLACK)
                a->opt.black = v;
            else if (c == OPT_TOL)
                a->opt.tolerance_stops = v;
            else
                a->opt.smoothness = v;
            break;
        }
        case OPT_SAMPLES:
            if (!cli_parse_int(optarg, &a->opt.samples) || a->opt.samples < 16)
                return cli_usage_error(cli, "--samples needs a whole number >= 16, not '%s'", optarg);
            break;
        case OPT_PRIOR:
            if (strcmp(optarg, "off") != 0 && strcmp(optarg, "dorf") != 0)
                return cli_usage_error(cli, "--response-prior needs dorf or off, not '%s'", optarg);
            a->opt.use_response_prior = strcmp(optarg, "dorf") == 0;
            break;
        case OPT_REFINE:
            if (strcmp(optarg, "off") != 0 && strcmp(optarg, "on") != 0)
                return cli_usage_error(cli, "--response-refine needs on or off, not '%s'", optarg);
            a->opt.refine_response = strcmp(optarg, "on") == 0;
            break;
        default:
            return cli_usage_error(cli, "unknown option '%s'", argv[optind - 1]);
        }
    }
    if (!a->output)
        return cli_usage_error(cli, "needs -o %s", is_merge ? "OUT.exr" : "CRF.json");
    if (argc - optind < 1)
        return cli_usage_error(cli, "needs the bracket's frames");
    if (a->times && a->time_count != argc - optind)
        return cli_usage_error(cli, "--times gives %d times for %d frames", a->time_count,
                               argc - optind);
    a->opt.times = a->times;
    return -1;
}

static void free_args(merge_args *a)
{
    free(a->times);
    sl_response_free(&a->response);
}

/* Runs merge or response on the parsed arguments and prints the result. */
static int run(int argc, char **argv, const sl_cli *cli, bool is_merge)
{
    merge_args a = {0};
    int rc = parse_args(argc, argv, cli, is_merge, &a);
    if (rc >= 0) {
        free_args(&a);
        return rc;
    }
    sl_merge_run_options o;
    sl_merge_run_options_init(&o);
    o.frame_paths = (const char *const *)argv + optind;
    o.frame_count = argc - optind;
    o.out_path = a.output;
    o.mask_path = a.mask;
    o.no_mask = a.no_mask;
    o.ghost_path = a.ghost_mask;
    o.merge = a.opt;
    sl_merge_run_result res;
    sl_error err;
    sl_result r = is_merge ? sl_merge_run(&o, &res, &err) : sl_response_run(&o, &res, &err);
    if (!r && cli->json)
        printf("%s\n", res.json);
    sl_merge_run_result_free(&res);
    free_args(&a);
    return r ? cli_fail(cli, &err) : 0;
}

int cmd_merge(int argc, char **argv, const sl_cli *cli)
{
    return run(argc, argv, cli, true);
}

int cmd_response(int argc, char **argv, const sl_cli *cli)
{
    return run(argc, argv, cli, false);
}
