/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight merge and setlight response: brackets to HDR radiance, and the
 * camera response recovered from a bracket. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "setlight/stitch.h"

static const char *merge_help =
    "usage: setlight merge [options] -o OUT.exr FRAME...\n\n"
    "Merges a bracket of exposures (any order; PNG and JPEG read by libpng and\n"
    "libjpeg, any other format OpenImageIO reads, which costs ~0.4 s of CPU to load\n"
    "once) into one EXR of relative radiance, scaled like the middle exposure,\n"
    "written strip by strip as it is merged.\n\n"
    "  -o, --output OUT.exr   the radiance image (required)\n"
    "  --times T1,T2,...      exposure times in seconds (e.g. 1/30,1/250), in frame order;\n"
    "                         default: EXIF ExposureTime (with FNumber and ISO when every\n"
    "                         frame has them: relative exposure t * ISO / N^2)\n"
    "  --response MODE        auto (Debevec-Malik from the bracket, default), robertson\n"
    "                         (Robertson et al. from the bracket), linear (raw, linear\n"
    "                         TIFF/EXR), or a curve file from 'setlight response'\n"
    "  --exposures SRC        exif (default) or data: use exposure ratios measured from\n"
    "                         the pixels; either way disagreements are reported\n"
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
    "  --saturation Z         values at or above Z (0..1) are saturated (default 0.95;\n"
    "                         0.98 with --response linear)\n"
    "  --black Z              values at or below Z carry no weight (default 0.004)\n"
    "  --tolerance STOPS      EXIF vs data disagreement reported above (default 0.2)\n"
    "  --samples N            response samples per channel (default 4000)\n"
    "  --smoothness L         response smoothness (default 10 at 3-stop steps)\n"
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
    "  --tolerance, --align   as for setlight merge (alignment auto by default)\n"
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

static const char *align_mode_name(sl_align_mode mode)
{
    return mode == SL_ALIGN_ON ? "on" : mode == SL_ALIGN_AUTO ? "auto" : "off";
}

/* The alignment for --json: mode, decision, why, and what it cost. */
static json_t *align_json(const sl_merge_result *res)
{
    return json_pack("{s:s, s:b, s:o, s:s, s:f, s:f, s:f}", "mode",
                     align_mode_name(res->align_mode), "aligned", res->aligned, "misalignment_px",
                     res->misalignment_px >= 0 ? json_real(res->misalignment_px) : json_null(),
                     "note", res->align_note, "measure_cpu_seconds", res->align_measure_cpu,
                     "cpu_seconds", res->timing.cpu[SL_MERGE_ALIGN], "wall_seconds",
                     res->timing.wall[SL_MERGE_ALIGN]);
}

/* Per frame in the given order, for the summary line: "ref", "+0.03,-0.28"
 * (dx,dy in px), "?" when it could not be estimated. */
static void shifts_text(const sl_merge_result *res, char *out, size_t size)
{
    size_t n = 0;
    out[0] = '\0';
    for (int i = 0; i < res->frame_count && n < size; i++) {
        const sl_align_transform *t = &res->frames[i].align;
        int k = !strcmp(t->note, "reference") ? snprintf(out + n, size - n, "%sref", i ? " " : "")
                : t->refused ? snprintf(out + n, size - n, "%s?", i ? " " : "")
                             : snprintf(out + n, size - n, "%s%+.2f,%+.2f", i ? " " : "", t->dx, t->dy);
        n += k > 0 ? (size_t)k : 0;
    }
}

static json_t *frames_json(const sl_merge_result *res, bool aligned)
{
    json_t *a = json_array();
    for (int i = 0; i < res->frame_count; i++) {
        const sl_merge_frame *f = &res->frames[i];
        json_t *o;
        json_array_append_new(
            a, o = json_pack("{s:s, s:f, s:f, s:f, s:f, s:f, s:f, s:f, s:b, s:i, s:f, s:f}", "path",
                         f->path, "time", f->time, "f_number", f->f_number, "iso", f->iso,
                         "exif_exposure", f->exif_exposure, "fitted_exposure",
                         f->fitted_exposure, "exposure", f->exposure, "disagreement_stops",
                         f->disagreement_stops, "disagrees", f->disagrees, "rank", f->rank,
                         "saturated_fraction", f->saturated_fraction, "black_fraction",
                         f->black_fraction));
        if (aligned)
            json_object_set_new(o, "align",
                                json_pack("{s:f, s:f, s:f, s:f, s:I, s:b, s:b, s:s}", "dx",
                                          f->align.dx, "dy", f->align.dy, "angle_deg",
                                          f->align.angle, "displacement_px",
                                          sl_align_displacement(&f->align, res->width, res->height), "pixels",
                                          (json_int_t)f->align.pixels, "applied", f->align.applied,
                                          "refused", f->align.refused, "note", f->align.note));
    }
    return a;
}

/* Wall and CPU seconds per phase and in all; "process_cpu" adds the
 * process's start-up (loading the libraries) to the merge's CPU. */
static json_t *timing_json(const sl_merge_result *res)
{
    json_t *o = json_object();
    for (int p = 0; p < SL_MERGE_PHASES; p++)
        json_object_set_new(o, sl_merge_phase_name((sl_merge_phase)p),
                            json_pack("{s:f, s:f}", "wall", res->timing.wall[p], "cpu",
                                      res->timing.cpu[p]));
    json_object_set_new(o, "total",
                        json_pack("{s:f, s:f}", "wall", res->seconds, "cpu", res->cpu_seconds));
    json_object_set_new(o, "process_cpu", json_real(sl_cpu_seconds()));
    return o;
}

static void log_frames(const sl_merge_result *res, bool aligned, double auto_px)
{
    for (int i = 0; i < res->frame_count; i++) {
        const sl_merge_frame *f = &res->frames[i];
        if (aligned && !strcmp(f->align.note, "reference"))
            sl_log(SL_LOG_INFO, "%s: alignment reference", f->path);
        else if (aligned)
            sl_log(f->align.refused ? SL_LOG_WARN : SL_LOG_INFO,
                   "%s: shift %+.2f, %+.2f px, rotation %+.3f deg%s%s", f->path, f->align.dx,
                   f->align.dy, f->align.angle,
                   f->align.refused ? "; not aligned: " : f->align.note[0] ? "; " : "",
                   f->align.note);
        if (f->disagrees)
            sl_log(SL_LOG_WARN,
                   "%s: exposure from the pixels is %+.2f stops off what EXIF/--times says",
                   f->path, f->disagreement_stops);
    }
    if (res->fitted_ratios < res->frame_count - 1)
        sl_log(SL_LOG_WARN, "%d of %d exposure steps could not be measured from the pixels",
               res->frame_count - 1 - res->fitted_ratios, res->frame_count - 1);
    /* The camera moved and the frames were registered without being asked:
     * say so, and how to have them merged as shot. */
    if (res->align_mode == SL_ALIGN_AUTO && res->aligned)
        sl_log(SL_LOG_WARN, "frames registered before merging: %s (--align=off merges them as shot)",
               res->align_note);
    else if (res->align_mode == SL_ALIGN_AUTO &&
             (res->misalignment_px < 0 || res->misalignment_px > auto_px))
        sl_log(SL_LOG_WARN, "%s (--align=on registers them anyway)", res->align_note);
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
           OPT_COMPRESSION, OPT_HOLD };
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
        {0, 0, 0, 0}};
    sl_merge_options_init(&a->opt);
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

/* "dir/name.exr" -> "dir/name_SUFFIX.exr" */
static char *sidecar_path(const char *out, const char *suffix)
{
    size_t n = strlen(out);
    const char *dot = strrchr(out, '.'), *slash = strrchr(out, '/');
    size_t stem = dot && (!slash || dot > slash) ? (size_t)(dot - out) : n;
    char *p = malloc(n + strlen(suffix) + 8);
    if (p)
        snprintf(p, n + strlen(suffix) + 8, "%.*s_%s.exr", (int)stem, out, suffix);
    return p;
}

int cmd_merge(int argc, char **argv, const sl_cli *cli)
{
    merge_args a = {0};
    int rc = parse_args(argc, argv, cli, true, &a);
    if (rc >= 0) {
        free_args(&a);
        return rc;
    }
    sl_error err;
    sl_merge_result res;
    char *mask = a.no_mask ? NULL : a.mask ? strdup(a.mask) : sidecar_path(a.output, "clipped");
    char *ghost = !a.opt.deghost ? NULL : a.ghost_mask ? strdup(a.ghost_mask) : sidecar_path(a.output, "ghost");
    sl_result r = (!a.no_mask && !mask) || (a.opt.deghost && !ghost)
                      ? sl_error_set(&err, SL_ERR_NOMEM, "out of memory")
                      : sl_merge_to_exr((const char *const *)argv + optind, argc - optind,
                                        &a.opt, a.output, mask, ghost, &res, &err);
    if (r) {
        free(mask);
        free(ghost);
        sl_merge_result_free(&res);
        free_args(&a);
        return cli_fail(cli, &err);
    }
    bool measured = res.align_mode != SL_ALIGN_OFF;
    log_frames(&res, measured, a.opt.align_auto_px);
    char shifts[64 * 24] = "";
    if (measured)
        shifts_text(&res, shifts, sizeof shifts);
    sl_log(SL_LOG_INFO,
           "%s: %d frames, response %s, %lld pixels clipped in every frame (%.4f%%), "
           "shifts (px) %s (%s), %.2f s",
           a.output, res.frame_count, res.response.source, (long long)res.clipped_pixels,
           100 * res.clipped_fraction, measured ? shifts : "not measured",
           res.aligned ? "aligned" : "merged as shot", res.seconds);
    if (cli->json) {
        json_t *o = json_pack(
            "{s:s, s:s?, s:s?, s:I, s:i, s:i, s:s, s:s, s:o, s:o, s:i, s:I, s:[I,I,I], s:f, s:f, s:I, s:I, s:I, s:s, s:f, s:{s:f, s:f, s:f, s:f}, s:{s:s, s:s, s:f, s:s}, s:i, s:f, s:o}",
            "output", a.output, "mask", mask, "ghost_mask", ghost, "ghost_pixels",
            (json_int_t)res.ghost_pixels, "width", res.width, "height",
            res.height, "response", res.response.source, "exposures",
            a.opt.exposures == SL_EXPOSURES_DATA ? "data" : "exif", "frames", frames_json(&res, measured), "align", align_json(&res),
            "reference_frame", res.reference, "clipped_pixels", (json_int_t)res.clipped_pixels,
            "clipped_samples", (json_int_t)res.clipped_samples[0],
            (json_int_t)res.clipped_samples[1], (json_int_t)res.clipped_samples[2],
            "clipped_fraction", res.clipped_fraction, "clipped_solid_angle_sr",
            res.clipped_solid_angle, "underexposed_samples", (json_int_t)res.underexposed_samples,
            "disagreeing_frames", (json_int_t)res.disagreeing_frames, "nonfinite_samples",
            (json_int_t)res.nonfinite_samples, "units", res.absolute ? "cd/m^2" : "relative",
            "output_exposure", res.output_exposure, "weights", "noise_gain", res.noise_gain,
            "noise_floor", res.noise_floor, "black", res.black, "saturation", res.saturation,
            "encoding", "pixels", res.pixel_type == SL_PIXEL_HALF ? "half" : "float",
            "compression", cli_compression_name(res.compression), "max_value", res.max_value,
            "why", res.encoding_note, "frames_decoded_once", res.held_frames, "seconds",
            res.seconds, "timing", timing_json(&res));
        json_dumpf(o, stdout, JSON_INDENT(2));
        fputc('\n', stdout);
        json_decref(o);
    }
    free(mask);
    free(ghost);
    sl_merge_result_free(&res);
    free_args(&a);
    return 0;
}

int cmd_response(int argc, char **argv, const sl_cli *cli)
{
    merge_args a = {0};
    int rc = parse_args(argc, argv, cli, false, &a);
    if (rc >= 0) {
        free_args(&a);
        return rc;
    }
    sl_error err;
    sl_merge_result res;
    sl_result r =
        sl_merge_response((const char *const *)argv + optind, argc - optind, &a.opt, &res, &err);
    if (!r)
        r = sl_response_write(a.output, &res.response, &err);
    if (r) {
        sl_merge_result_free(&res);
        free_args(&a);
        return cli_fail(cli, &err);
    }
    log_frames(&res, res.align_mode != SL_ALIGN_OFF, a.opt.align_auto_px);
    if (cli->json) {
        double mid[3];
        for (int c = 0; c < 3; c++)
            mid[c] = sl_response_eval(&res.response, c, 0.5);
        json_t *o = json_pack("{s:s, s:s, s:i, s:[f,f,f], s:o, s:o, s:I, s:f, s:o}", "output",
                              a.output, "source", res.response.source, "nodes",
                              res.response.nodes, "linear_at_half", mid[0], mid[1], mid[2],
                              "frames", frames_json(&res, res.align_mode != SL_ALIGN_OFF),
                              "align", align_json(&res), "disagreeing_frames",
                              (json_int_t)res.disagreeing_frames, "seconds", res.seconds,
                              "timing", timing_json(&res));
        json_dumpf(o, stdout, JSON_INDENT(2));
        fputc('\n', stdout);
        json_decref(o);
    }
    sl_merge_result_free(&res);
    free_args(&a);
    return 0;
}
