/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight capture / ingest / cameras: tethered bracketing through
 * libgphoto2, folder ingest, camera detection (docs/capture.md). */
#include <jansson.h>
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "setlight/capture.h"

/* Under LeakSanitizer: libgphoto2's USB port driver keeps the device list it
 * gets from libusb_get_device_list when it loads (outside setlight). */
const char *__lsan_default_suppressions(void);
const char *__lsan_default_suppressions(void) { return "leak:libusb_get_device_list\n"; }
/* and the report of that suppression would break the one-line error rule */
const char *__lsan_default_options(void);
const char *__lsan_default_options(void) { return "print_suppressions=0"; }

static const char *capture_help =
    "usage: setlight capture [options] -o DIR\n"
    "       setlight capture [options] --resume DIR\n\n"
    "Shoots bracketed exposures through libgphoto2, one bracket per view, verifies\n"
    "every frame (EXIF exposure and pixel ratio to the previous frame), retries a\n"
    "frame the camera got wrong, and keeps an append-only journal in DIR so that\n"
    "--resume continues after a crash or a disconnect. Nothing is ever deleted from\n"
    "the card or overwritten on disk.\n\n"
    "  --camera PORT        auto (first detected, default), usb:BUS,DEV, ptpip:HOST[:PORT],\n"
    "                       virtual[:SCENE] (the virtual set's camera: exterior, stage,\n"
    "                       night or a scene JSON file; default stage)\n"
    "  --bracket PLAN       NxS: N exposures S stops apart around --center (default 7x3),\n"
    "                       or a list of shutter speeds: 1/1000,1/125,1/15\n"
    "  --center SPEED       centre shutter speed, e.g. 1/30 (default: the camera's setting)\n"
    "  --aperture F         set the f-number first (default: leave it)\n"
    "  --iso N              set the ISO first (default: leave it)\n"
    "  --format FORMAT      raw, jpeg or raw+jpeg: set the camera's image format to its\n"
    "                       best matching choice (reported); keep (default): leave it.\n"
    "                       A format the camera does not offer is a usage error (exit 2)\n"
    "  --views N            directions on the nodal head (default 1)\n"
    "  --step-command CMD   run CMD (sh -c, SETLIGHT_VIEW set) between views to turn the head\n"
    "  --no-prompt          do not wait for Enter between views\n"
    "  --max-attempts N     tries per frame before giving up (default 3)\n"
    "  --reconnect SECONDS  after a disconnect keep reconnecting this long (default 10;\n"
    "                       0: stop at once, --resume continues)\n"
    "  -o, --output DIR     new session folder\n"
    "  --resume DIR         continue the session in DIR from its next missing frame\n"
    "                       with its own plan (--bracket, --center, --views unused);\n"
    "                       a --format, --aperture or --iso other than the session's\n"
    "                       is refused, exit 2\n"
    "  --json               print the result as JSON on stdout (dir, ok, camera,\n"
    "                       format and the camera's label for it, frames shot in this\n"
    "                       run, plan with its snapping, error)\n\n"
    "Plans are snapped to the camera's shutter speeds (reported); a speed more than\n"
    "one stop outside the camera's range is a usage error (exit 2).\n";

typedef struct step_ctx {
    const sl_cli *cli;
    const char *command;
    bool prompt;
    sl_progress progress; /* frames accepted, on a terminal */
    int accepted;         /* frames accepted in this run */
} step_ctx;

static sl_result step(void *ctx, int next_view, sl_error *err)
{
    step_ctx *s = ctx;
    if (s->command) {
        char env[32];
        snprintf(env, sizeof env, "%d", next_view);
        setenv("SETLIGHT_VIEW", env, 1);
        fflush(stdout);
        int rc = system(s->command);
        if (rc != 0)
            return sl_error_set(err, SL_ERR_CANCELLED,
                                "step command '%s' failed before view %d (status %d)", s->command,
                                next_view, rc);
        return SL_OK;
    }
    if (!s->prompt)
        return SL_OK;
    if (s->progress.enabled)
        fputs("\r\033[K", stderr); /* the prompt replaces the bar's line */
    fprintf(stderr, "Turn the head to view %d and press Enter (Ctrl-D stops)... ", next_view + 1);
    fflush(stderr);
    char line[64];
    if (!fgets(line, sizeof line, stdin))
        return sl_error_set(err, SL_ERR_CANCELLED, "stopped before view %d", next_view);
    return SL_OK;
}

/* One line per frame (planned, reported and measured exposure) above the
 * progress bar. */
static void on_frame(void *ctx, const sl_capture_report *r)
{
    step_ctx *s = ctx;
    s->accepted += r->accepted;
    if (s->cli->quiet)
        return;
    if (!s->progress.label)
        sl_progress_begin(&s->progress, "capture", (int64_t)r->views * r->count);
    char plan[32], got[32], ratio[64] = "";
    sl_shutter_format(r->planned, plan, sizeof plan);
    sl_shutter_format(r->reported, got, sizeof got);
    if (r->measured_ratio > 0)
        snprintf(ratio, sizeof ratio, "  ratio %.2f (expected %.2f)", r->measured_ratio,
                 r->expected_ratio);
    sl_log(SL_LOG_INFO, "view %d/%d frame %d/%d  planned %s s  file says %s s%s  %s %s",
           r->view + 1, r->views, r->index + 1, r->count, plan, got, ratio,
           r->accepted ? "ok" : "REJECTED", r->file);
    if (!r->accepted)
        sl_log(SL_LOG_INFO, "  rejected: %s", r->reason);
    if (r->accepted)
        sl_progress_add(&s->progress, 1);
}

int cmd_capture(int argc, char **argv, const sl_cli *cli)
{
    /* A network camera that drops mid-request leaves libgphoto2 writing to
     * a closed socket: that must be an I/O error to recover from (the
     * journal, reconnection), not SIGPIPE killing the session. */
    signal(SIGPIPE, SIG_IGN);
    enum { OPT_CAMERA = 1000, OPT_BRACKET, OPT_CENTER, OPT_APERTURE, OPT_ISO, OPT_VIEWS, OPT_STEP,
           OPT_NOPROMPT, OPT_ATTEMPTS, OPT_RESUME, OPT_RECONNECT, OPT_FORMAT };
    static const struct option opts[] = {
        {"help", no_argument, NULL, 'h'},
        {"camera", required_argument, NULL, OPT_CAMERA},
        {"bracket", required_argument, NULL, OPT_BRACKET},
        {"center", required_argument, NULL, OPT_CENTER},
        {"aperture", required_argument, NULL, OPT_APERTURE},
        {"iso", required_argument, NULL, OPT_ISO},
        {"views", required_argument, NULL, OPT_VIEWS},
        {"step-command", required_argument, NULL, OPT_STEP},
        {"no-prompt", no_argument, NULL, OPT_NOPROMPT},
        {"max-attempts", required_argument, NULL, OPT_ATTEMPTS},
        {"output", required_argument, NULL, 'o'},
        {"resume", required_argument, NULL, OPT_RESUME},
        {"reconnect", required_argument, NULL, OPT_RECONNECT},
        {"format", required_argument, NULL, OPT_FORMAT},
        {0, 0, 0, 0}};
    const char *port = "auto", *bracket = "7x3", *out = NULL, *resume = NULL;
    double center = 0, aperture = 0, iso = 0, reconnect = 10;
    int views = 1, attempts = 3;
    const char *plan_option = NULL; /* a plan option given (ignored on --resume) */
    sl_image_format format = SL_FORMAT_KEEP;
    step_ctx sc = {.cli = cli, .prompt = true};
    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, "ho:", opts, NULL)) != -1) {
        switch (c) {
        case 'h':
            fputs(capture_help, stdout);
            return 0;
        case OPT_CAMERA:
            port = optarg;
            break;
        case OPT_BRACKET:
            bracket = optarg;
            plan_option = "--bracket";
            break;
        case OPT_CENTER:
            if (!((center = sl_shutter_parse(optarg)) > 0))
                return cli_usage_error(cli, "--center needs a shutter speed such as 1/30, not '%s'",
                                       optarg);
            plan_option = "--center";
            break;
        case OPT_APERTURE:
            if (!cli_parse_double(optarg, &aperture) || aperture <= 0)
                return cli_usage_error(cli, "--aperture needs an f-number such as 8, not '%s'",
                                       optarg);
            break;
        case OPT_ISO:
            if (!cli_parse_double(optarg, &iso) || iso <= 0)
                return cli_usage_error(cli, "--iso needs a number such as 100, not '%s'", optarg);
            break;
        case OPT_VIEWS:
            if (!cli_parse_int(optarg, &views) || views < 1 || views > 360)
                return cli_usage_error(cli, "--views needs a whole number from 1 to 360, not '%s'",
                                       optarg);
            plan_option = "--views";
            break;
        case OPT_STEP:
            sc.command = optarg;
            break;
        case OPT_NOPROMPT:
            sc.prompt = false;
            break;
        case OPT_ATTEMPTS:
            if (!cli_parse_int(optarg, &attempts) || attempts < 1 || attempts > 20)
                return cli_usage_error(cli, "--max-attempts needs 1 to 20, not '%s'", optarg);
            break;
        case 'o':
            out = optarg;
            break;
        case OPT_RESUME:
            resume = optarg;
            break;
        case OPT_FORMAT: {
            sl_error e;
            if (sl_image_format_parse(optarg, &format, &e))
                return cli_usage_error(cli, "--format: %s", e.message);
            break;
        }
        case OPT_RECONNECT:
            if (!cli_parse_double(optarg, &reconnect) || reconnect < 0 || reconnect > 3600)
                return cli_usage_error(cli, "--reconnect needs 0 to 3600 seconds, not '%s'",
                                       optarg);
            break;
        default:
            return cli_usage_error(cli, "unknown option '%s'", argv[optind - 1]);
        }
    }
    if (optind != argc)
        return cli_usage_error(cli, "unexpected argument '%s'", argv[optind]);
    if (!out == !resume)
        return cli_usage_error(cli, "needs either -o DIR (new session) or --resume DIR");
    if (resume && plan_option)
        sl_log(SL_LOG_WARN, "%s is not used with --resume: the session's own plan continues",
               plan_option);
    double t0 = sl_seconds();
    sl_error err;
    sl_camera *camera = NULL;
    double *times = NULL, *moved = NULL, *offered = NULL;
    int count = 0, noffered = 0;
    sl_result r = SL_OK;
    /* A plan that cannot be parsed fails before any camera is touched. */
    if (!resume && !strchr(bracket, 'x') &&
        (r = sl_bracket_plan_parse(bracket, 1.0, &times, &count, &err)))
        return cli_fail(cli, &err);
    free(times);
    times = NULL;
    if (!resume && strchr(bracket, 'x') && center <= 0 &&
        (r = sl_bracket_plan_parse(bracket, 1.0, &times, &count, &err)))
        return cli_fail(cli, &err);
    free(times);
    times = NULL;
    if ((r = sl_camera_open(port, &camera, &err)))
        return cli_fail(cli, &err);
    sl_capture_options o = {.dir = out, .views = views, .f_number = aperture, .iso = iso,
                            .format = format, .max_attempts = attempts,
                            .reconnect_seconds = reconnect > 0 ? reconnect : -1,
                            .step = step, .on_frame = on_frame, .ctx = &sc};
    json_t *snaps = json_array();
    if (resume) {
        r = sl_capture_resume(camera, &o, resume, &err);
    } else {
        if (center <= 0) {
            sl_camera_settings now;
            if (!sl_camera_get(camera, &now, NULL))
                center = now.exposure_time;
            if (center <= 0) {
                r = sl_error_set(&err, SL_ERR_CAMERA,
                                 "%s: cannot read the shutter speed; give --center", port);
                goto done;
            }
        }
        if ((r = sl_bracket_plan_parse(bracket, center, &times, &count, &err)) ||
            (r = sl_camera_shutter_speeds(camera, &offered, &noffered, &err)))
            goto done;
        moved = calloc((size_t)count, sizeof *moved);
        double *planned = malloc((size_t)count * sizeof *planned);
        if (!moved || !planned) {
            free(planned);
            r = sl_error_set(&err, SL_ERR_NOMEM, "out of memory");
            goto done;
        }
        memcpy(planned, times, (size_t)count * sizeof *times);
        if ((r = sl_bracket_snap(times, count, offered, noffered, 1.0, moved, &err))) {
            free(planned);
            goto done;
        }
        for (int i = 0; i < count; i++) {
            json_t *s = json_object();
            json_object_set_new(s, "planned", json_real(planned[i]));
            json_object_set_new(s, "snapped", json_real(times[i]));
            json_object_set_new(s, "moved_stops", json_real(moved[i]));
            json_array_append_new(snaps, s);
            if (fabs(moved[i]) > 0.05) {
                char a[32], b[32];
                sl_shutter_format(planned[i], a, sizeof a);
                sl_shutter_format(times[i], b, sizeof b);
                sl_log(SL_LOG_INFO, "plan: %s s snapped to %s s (%+.2f stops)", a, b, moved[i]);
            }
        }
        free(planned);
        o.times = times;
        o.count = count;
        r = sl_capture_run(camera, &o, &err);
    }
done:
    if (sc.progress.label)
        sl_progress_end(&sc.progress);
    /* the image format and the camera's label for it, as the session holds them */
    char sp[4096];
    snprintf(sp, sizeof sp, "%s/session.json", resume ? resume : out);
    json_t *session = json_load_file(sp, 0, NULL);
    json_t *jformat = json_object_get(json_object_get(session, "camera"), "format");
    json_t *jlabel = json_object_get(json_object_get(session, "camera"), "format_label");
    if (!r && json_string_value(jlabel) && *json_string_value(jlabel) && !cli->quiet && !cli->json)
        sl_log(SL_LOG_INFO, "image format %s: the camera's '%s'", json_string_value(jformat),
               json_string_value(jlabel));
    if (cli->json) {
        json_t *j = json_object();
        json_object_set_new(j, "dir", json_string(resume ? resume : out));
        json_object_set_new(j, "ok", json_boolean(r == SL_OK));
        json_object_set_new(j, "camera",
                            json_pack("{s:s, s:s, s:s}", "model", sl_camera_model(camera), "port",
                                      sl_camera_port(camera), "backend",
                                      sl_camera_backend(camera)));
        json_object_set_new(j, "format", jformat ? json_incref(jformat) : json_null());
        json_object_set_new(j, "format_label", jlabel ? json_incref(jlabel) : json_null());
        json_object_set_new(j, "frames", json_integer(sc.accepted));
        json_object_set_new(j, "plan", snaps);
        json_object_set_new(j, "seconds", json_real(sl_seconds() - t0));
        if (r)
            json_object_set_new(j, "error", json_string(err.message));
        char *text = json_dumps(j, JSON_INDENT(2) | JSON_PRESERVE_ORDER);
        if (text)
            printf("%s\n", text);
        free(text);
        json_decref(j);
    } else
        json_decref(snaps);
    json_decref(session);
    sl_camera_close(camera);
    free(times);
    free(moved);
    free(offered);
    if (r)
        return cli_fail(cli, &err);
    if (!cli->quiet)
        sl_log(SL_LOG_INFO, "%s: done in %.1f s", resume ? resume : out, sl_seconds() - t0);
    return 0;
}

static const char *cameras_help =
    "usage: setlight cameras [--json]\n\n"
    "Lists the cameras libgphoto2 detects (USB and serial). Network cameras are not\n"
    "detected; give them to capture as --camera ptpip:HOST[:PORT]. The virtual set's\n"
    "camera is always there as --camera virtual[:SCENE] and is not listed.\n";

int cmd_cameras(int argc, char **argv, const sl_cli *cli)
{
    static const struct option opts[] = {{"help", no_argument, NULL, 'h'}, {0, 0, 0, 0}};
    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, "h", opts, NULL)) != -1) {
        if (c == 'h') {
            fputs(cameras_help, stdout);
            return 0;
        }
        return cli_usage_error(cli, "unknown option '%s'", argv[optind - 1]);
    }
    if (optind != argc)
        return cli_usage_error(cli, "unexpected argument '%s'", argv[optind]);
    sl_camera_entry *list;
    int n;
    sl_error err;
    if (sl_camera_list(&list, &n, &err))
        return cli_fail(cli, &err);
    if (cli->json) {
        json_t *j = json_object(), *a = json_array();
        for (int i = 0; i < n; i++) {
            json_t *e = json_object();
            json_object_set_new(e, "model", json_string(list[i].model));
            json_object_set_new(e, "port", json_string(list[i].port));
            json_array_append_new(a, e);
        }
        json_object_set_new(j, "cameras", a);
        char *text = json_dumps(j, JSON_INDENT(2) | JSON_PRESERVE_ORDER);
        if (text)
            printf("%s\n", text);
        free(text);
        json_decref(j);
    } else {
        for (int i = 0; i < n; i++)
            printf("%-40s %s\n", list[i].model, list[i].port);
        if (n == 0)
            sl_log(SL_LOG_INFO, "no cameras detected");
    }
    free(list);
    return 0;
}

static const char *ingest_help =
    "usage: setlight ingest [options] SRC -o DIR\n\n"
    "Groups the photographs in SRC (a card or a folder, searched 4 levels deep) into\n"
    "views and brackets by EXIF time, exposure and sequence, copies them into DIR\n"
    "(never overwriting) and writes DIR/session.json. Frames of different setups\n"
    "(camera make, model or serial, lens, focal length, image size, orientation,\n"
    "file format or bit depth) are never grouped together: one warning line per two\n"
    "setups kept apart says why (also in session.json 'splits'). Files that are not\n"
    "photographs, brackets of one frame and frames without an EXIF exposure time\n"
    "are listed as problems in session.json.\n\n"
    "  -o, --output DIR   session folder to create\n"
    "  --gap SECONDS      a pause longer than this starts a new view (default 10)\n"
    "  --json             print the result as JSON on stdout (dir, frames, views,\n"
    "                     splits, problems)\n";

int cmd_ingest(int argc, char **argv, const sl_cli *cli)
{
    enum { OPT_GAP = 1000 };
    static const struct option opts[] = {{"help", no_argument, NULL, 'h'},
                                         {"output", required_argument, NULL, 'o'},
                                         {"gap", required_argument, NULL, OPT_GAP},
                                         {0, 0, 0, 0}};
    const char *out = NULL;
    double gap = 10;
    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, "ho:", opts, NULL)) != -1) {
        switch (c) {
        case 'h':
            fputs(ingest_help, stdout);
            return 0;
        case 'o':
            out = optarg;
            break;
        case OPT_GAP:
            if (!cli_parse_double(optarg, &gap) || gap <= 0)
                return cli_usage_error(cli, "--gap needs a number of seconds > 0, not '%s'",
                                       optarg);
            break;
        default:
            return cli_usage_error(cli, "unknown option '%s'", argv[optind - 1]);
        }
    }
    if (argc - optind != 1 || !out)
        return cli_usage_error(cli, "needs a source folder and -o DIR");
    sl_error err;
    int frames, views;
    sl_progress bar;
    sl_progress_begin(&bar, "ingest", 0); /* the total is known once the source is scanned */
    sl_result r = sl_ingest(argv[optind], out, gap, &bar, &frames, &views, &err);
    sl_progress_end(&bar);
    if (r)
        return cli_fail(cli, &err);
    /* what was kept apart and what a merge cannot take, as the session says */
    char sp[4096];
    snprintf(sp, sizeof sp, "%s/session.json", out);
    json_t *session = json_load_file(sp, 0, NULL);
    json_t *splits = json_object_get(session, "splits");
    json_t *problems = json_object_get(session, "problems");
    if (cli->json) {
        json_t *j = json_pack("{s:s, s:i, s:i, s:O, s:O}", "dir", out, "frames", frames, "views",
                              views, "splits", splits ? splits : json_array(), "problems",
                              problems ? problems : json_array());
        char *text = j ? json_dumps(j, JSON_INDENT(2) | JSON_PRESERVE_ORDER) : NULL;
        if (text)
            printf("%s\n", text);
        free(text);
        json_decref(j);
    } else {
        size_t np = json_array_size(problems);
        if (np)
            sl_log(SL_LOG_INFO, "%s: %d frames in %d views; %zu problem%s listed in %s", out,
                   frames, views, np, np > 1 ? "s" : "", sp);
        else
            sl_log(SL_LOG_INFO, "%s: %d frames in %d views", out, frames, views);
    }
    json_decref(session);
    return 0;
}
