/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight render: the validation renderer on the command line. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"
#include "render_opts.h"
#include "setlight/render.h"

static void help(FILE *out)
{
    fprintf(out,
            "usage: setlight render --env ENV | --rig RIG.json [--scene PRESET|FILE.json] [options]\n"
            "                       -o OUT.exr\n\n"
            "Renders validation references (grey ball, chrome ball, Macbeth chart...) lit by an\n"
            "HDR lat-long or a light rig, progressively, with an error estimate after each pass.\n\n"
            "  --env FILE          lat-long environment (EXR, HDR or any image; width = 2 x height;\n"
            "                      an 8/16-bit one is converted to scene-linear through\n"
            "                      OpenColorIO from its colour space, sRGB unless it names\n"
            "                      one, with a warning; docs/color.md)\n"
            "  --input-colorspace NAME  the --env map's colour space (OCIO name), instead of\n"
            "                      the one the file names or the default\n"
            "  --rig FILE          light rig JSON: rect/disk/sphere/distant lights and an optional\n"
            "                      dome (docs/render.md)\n"
            "  --rotate DEG        turn the environment about +Y (default 0; --env only)\n"
            "  --intensity X       multiply the environment (default 1; --env only)\n"
            "  --scene NAME|FILE   preset (%s) or a scene JSON file\n"
            "                      (docs/render.md); default grey\n"
            "  --material SPEC     give every object this material: lambert:R,G,B | chrome |\n"
            "                      conductor:R,G,B:ROUGHNESS | plastic:R,G,B:ROUGHNESS\n"
            "  --width N           image width in pixels (default 512; height from the scene)\n"
            "  --view AZ,EL        turn the validation camera (degrees; presets only)\n"
            "  --background MODE   black (default) or env: what camera rays that miss see\n"
            "  --pixel-centers     sample each pixel's centre only (no box filter), as a\n"
            "                      renderer with a vanishing pixel filter does\n"
            "  --spp N             stop at N samples per pixel (default 64 unless --time or\n"
            "                      --target-error is given)\n"
            "  --time SECONDS      the render's wall-time budget, closed form included:\n"
            "                      a Lambert object's closed form is first coarse over\n"
            "                      the whole object, then refined worst block first,\n"
            "                      until 80%% of it (40%% with a shadowed part to\n"
            "                      sample); a cut leaves each pixel its value and bound\n"
            "                      (stats: rms_rel_bound, at_tolerance_share); a glossy\n"
            "                      object's sun is computed first at every pixel, and\n"
            "                      where its plan is cut the pixel keeps that sun exact\n"
            "                      and samples only the rest of the map (stats:\n"
            "                      sun_exact_pixels); no pass starts that would end\n"
            "                      past it (the first pass, 2 spp, always runs)\n"
            "  --target-error E    stop when the estimated relative RMSE is at most E; from\n"
            "                      16 spp on, each pixel stops once its error (pooled over\n"
            "                      3x3 pixels) is within its share of E (adaptive sampling)\n"
            "  --bounces N         indirect bounces after the first hit (default 0: direct)\n"
            "  --strategy NAME     mis (default), bsdf, light, cosine or uniform\n"
            "  --sampler NAME      sobol (Owen-scrambled, default) or random\n"
            "  --closed-form MODE  on (default): pixels of an unoccluded Lambert object under\n"
            "                      the dome and the rig's lights (all but textured rects), or\n"
            "                      of a rough glossy (conductor, plastic) object under the\n"
            "                      dome alone, are computed by quadrature (no samples;\n"
            "                      Lambert, and glossy with --pixel-centers: the sun per\n"
            "                      pixel, the rest of the map interpolated in checked\n"
            "                      blocks);\n"
            "                      shadowed ones sample only the shadowed part; off: sample\n"
            "                      everything\n"
            "  --seed N            sample seed (default 1); same seed, same bytes\n"
            "  --reference IMG     image of the same size: true relative RMSE per pass\n"
            "  --stats FILE.json   error against time per pass, rays, skipped work\n"
            "  -o, --output FILE   output EXR (float RGBA; alpha = coverage), written atomically\n"
            "\nexit codes: 0 success, 1 runtime failure, 2 usage error, 3 invalid input data\n",
            sl_scene_preset_names());
}

static bool parse_rgb(const char *s, double rgb[3], const char **rest)
{
    char *end;
    for (int i = 0; i < 3; i++) {
        rgb[i] = strtod(s, &end);
        if (end == s || !isfinite(rgb[i]) || rgb[i] < 0)
            return false;
        s = end;
        if (i < 2) {
            if (*s != ',')
                return false;
            s++;
        }
    }
    *rest = s;
    return true;
}

static bool parse_material(const char *spec, sl_material *m)
{
    double rgb[3], rough;
    const char *rest;
    if (!strcmp(spec, "chrome")) {
        sl_material_chrome(m);
        return true;
    }
    if (!strncmp(spec, "lambert:", 8))
        return parse_rgb(spec + 8, rgb, &rest) && !*rest &&
               (sl_material_lambert(m, rgb[0], rgb[1], rgb[2]), true);
    bool conductor = !strncmp(spec, "conductor:", 10), plastic = !strncmp(spec, "plastic:", 8);
    if (!conductor && !plastic)
        return false;
    if (!parse_rgb(spec + (conductor ? 10 : 8), rgb, &rest) || *rest != ':' ||
        !cli_parse_double(rest + 1, &rough) || rough < 0)
        return false;
    if (conductor) {
        const double tint[3] = {1, 1, 1};
        sl_material_conductor(m, rgb, tint, rough);
    } else {
        sl_material_plastic(m, rgb, 1.5, rough);
    }
    return true;
}

static void show_pass(void *ctx, const sl_render_pass *p)
{
    (void)ctx;
    fprintf(stderr, "\r%lld spp, %.2f s, estimated relative RMSE %.4g   ", (long long)p->spp,
            p->seconds, p->est_rel_rmse);
    fflush(stderr);
}

int cmd_render(int argc, char **argv, const sl_cli *cli)
{
    enum { O_ENV = 256, O_ROT, O_INT, O_SCENE, O_MAT, O_WIDTH, O_VIEW, O_BG, O_BOUNCES, O_SEED,
           O_SPP, O_TIME, O_TERR, O_STRAT, O_SAMPLER, O_REF, O_STATS, O_RIG, O_CENTERS, O_INCS,
           O_CLOSED };
    static const struct option opts[] = {
        {"env", required_argument, 0, O_ENV},         {"rotate", required_argument, 0, O_ROT},
        {"intensity", required_argument, 0, O_INT},   {"scene", required_argument, 0, O_SCENE},
        {"material", required_argument, 0, O_MAT},    {"width", required_argument, 0, O_WIDTH},
        {"view", required_argument, 0, O_VIEW},       {"background", required_argument, 0, O_BG},
        {"spp", required_argument, 0, O_SPP},         {"time", required_argument, 0, O_TIME},
        {"target-error", required_argument, 0, O_TERR},
        {"bounces", required_argument, 0, O_BOUNCES}, {"strategy", required_argument, 0, O_STRAT},
        {"sampler", required_argument, 0, O_SAMPLER}, {"closed-form", required_argument, 0, O_CLOSED}, {"seed", required_argument, 0, O_SEED},
        {"rig", required_argument, 0, O_RIG},         {"reference", required_argument, 0, O_REF},   {"stats", required_argument, 0, O_STATS},
        {"pixel-centers", no_argument, 0, O_CENTERS},
        {"input-colorspace", required_argument, 0, O_INCS},
        {"output", required_argument, 0, 'o'},        {"help", no_argument, 0, 'h'},
        {0, 0, 0, 0}};
    const char *rig_path = NULL, *env_path = NULL, *scene_arg = "grey", *mat_spec = NULL, *ref_path = NULL,
               *stats_path = NULL, *out_path = NULL, *in_cs = NULL;
    double rotate = 0, intensity = 1;
    bool spp_given = false;
    render_opts ro;
    render_opts_init(&ro, 512);
    sl_render_options o;
    sl_render_options_init(&o);
    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, ":ho:", opts, NULL)) != -1) {
        switch (c) {
        case 'h':
            help(stdout);
            return 0;
        case 'o': out_path = optarg; break;
        case O_ENV: env_path = optarg; break;
        case O_INCS:
            if (!(in_cs = sl_color_space_name(optarg)))
                return cli_usage_error(cli, "unknown colour space '%s' (see docs/color.md)", optarg);
            break;
        case O_RIG: rig_path = optarg; break;
        case O_SCENE: scene_arg = optarg; break;
        case O_MAT: mat_spec = optarg; break;
        case O_REF: ref_path = optarg; break;
        case O_STATS: stats_path = optarg; break;
        case O_CENTERS: o.pixel_centers = true; break;
        case O_ROT:
            if (!cli_parse_double(optarg, &rotate))
                return cli_usage_error(cli, "--rotate needs a number of degrees");
            break;
        case O_INT:
            if (!cli_parse_double(optarg, &intensity) || intensity < 0)
                return cli_usage_error(cli, "--intensity needs a number >= 0");
            break;
        case O_WIDTH:
        case O_VIEW:
        case O_BG:
        case O_BOUNCES:
        case O_SEED: {
            int rc = render_opts_parse(cli, &ro, c - O_WIDTH, optarg);
            if (rc)
                return rc;
            break;
        }
        case O_SPP: {
            int n;
            if (!cli_parse_int(optarg, &n) || n < 1)
                return cli_usage_error(cli, "--spp needs a whole number >= 1");
            o.spp = n;
            spp_given = true;
            break;
        }
        case O_TIME:
            if (!cli_parse_double(optarg, &o.time_limit) || o.time_limit <= 0)
                return cli_usage_error(cli, "--time needs a number of seconds > 0");
            break;
        case O_TERR:
            if (!cli_parse_double(optarg, &o.target_error) || o.target_error <= 0)
                return cli_usage_error(cli, "--target-error needs a number > 0");
            break;
        case O_STRAT: {
            int s = sl_strategy_from_name(optarg);
            if (s < 0)
                return cli_usage_error(cli, "unknown --strategy '%s' (mis, bsdf, light, cosine, uniform)",
                                       optarg);
            o.strategy = (sl_strategy)s;
            break;
        }
        case O_SAMPLER:
            if (strcmp(optarg, "sobol") && strcmp(optarg, "random"))
                return cli_usage_error(cli, "--sampler is sobol or random");
            o.low_discrepancy = !strcmp(optarg, "sobol");
            break;
        case O_CLOSED:
            if (strcmp(optarg, "on") && strcmp(optarg, "off"))
                return cli_usage_error(cli, "--closed-form is on or off");
            o.closed_form = !strcmp(optarg, "on");
            break;
        case ':': return cli_usage_error(cli, "%s needs a value", argv[optind - 1]);
        default: return cli_usage_error(cli, "unknown option %s", argv[optind - 1]);
        }
    }
    if (optind < argc)
        return cli_usage_error(cli, "unexpected argument '%s'", argv[optind]);
    if (!env_path == !rig_path)
        return cli_usage_error(cli, "give exactly one of --env ENV and --rig RIG.json");
    if (rig_path && (rotate != 0 || intensity != 1))
        return cli_usage_error(cli, "--rotate and --intensity apply to --env; a rig sets its dome's");
    if (!out_path)
        return cli_usage_error(cli, "-o OUT.exr is required");
    if (!spp_given && (o.time_limit > 0 || o.target_error > 0))
        o.spp = 0;
    sl_material mat;
    if (mat_spec && !parse_material(mat_spec, &mat))
        return cli_usage_error(cli, "bad --material '%s'", mat_spec);

    sl_render_run_options rr;
    sl_render_run_options_init(&rr);
    rr.scene = scene_arg;
    rr.env_path = env_path;
    rr.rig_path = rig_path;
    rr.input_colorspace = in_cs;
    rr.rotate_deg = rotate;
    rr.intensity = intensity;
    rr.width = ro.width;
    rr.view = ro.view;
    rr.view_az = ro.az;
    rr.view_el = ro.el;
    rr.background_env = ro.background_env;
    rr.material = mat_spec ? &mat : NULL;
    rr.reference_path = ref_path;
    rr.stats_path = stats_path;
    rr.out_path = out_path;
    o.bounces = ro.bounces;
    o.seed = (uint64_t)ro.seed;
    if (!cli->quiet && isatty(2))
        o.on_pass = show_pass;
    rr.render = o;
    sl_render_run_result res;
    sl_error err;
    sl_result r = sl_render_run(&rr, &res, &err);
    if (o.on_pass)
        fputc('\n', stderr);
    if (!r && cli->json)
        printf("%s\n", res.json);
    else if (!r)
        sl_log(SL_LOG_INFO, "%s: %dx%d, %lld spp in %.3f s, estimated relative RMSE %.4g (%s)",
               out_path, res.width, res.height, (long long)res.stats.spp, res.stats.seconds,
               res.est_rel_rmse, res.stats.stop_reason);
    if (!r && !cli->json) {
        const sl_closed_form_stats *cf = &res.stats.closed_form;
        char words[640];
        if (cf->used)
            sl_log(SL_LOG_INFO,
                   "closed form: %lld pixels exact, %lld control variate, %lld sampled; bound "
                   "%.3g (tolerance %.3g); %s; %lld evaluations in %.3f s",
                   (long long)cf->exact_pixels, (long long)cf->control_variate_pixels,
                   (long long)cf->sampled_pixels, cf->max_rel_bound, cf->tolerance,
                   sl_closed_form_describe(cf, words, sizeof words), (long long)cf->evaluations,
                   cf->seconds);
        else
            sl_log(SL_LOG_INFO, "closed form not used: %s", cf->reason);
        static const char *const kind[SL_MAT_COUNT] = {"Lambert", "conductor", "plastic"};
        for (int i = 0; cf->used && i < cf->object_count; i++)
            sl_log(SL_LOG_INFO,
                   "closed form, object %d (%s): %lld exact, %lld control variate, %lld of them "
                   "interpolated; %s %.3g",
                   cf->objects[i], cf->object_material[i] < SL_MAT_COUNT ? kind[cf->object_material[i]] : "?",
                   (long long)cf->object_exact[i], (long long)cf->object_control[i],
                   (long long)cf->object_interpolated[i],
                   cf->object_material[i] == SL_MAT_LAMBERT && !cf->object_interpolated[i] ? "proven bound"
                                                                                           : "error estimate",
                   cf->object_max_rel_bound[i]);
        if (cf->interpolated_pixels)
            sl_log(SL_LOG_INFO, "closed form: %lld pixels with the map's rest interpolated in checked "
                   "blocks; the sun (%lld texels, %.0f%% of the power) at every pixel",
                   (long long)cf->interpolated_pixels, (long long)cf->sun_texels, 100 * cf->sun_share);
    }
    sl_render_run_result_free(&res);
    return r ? cli_fail(cli, &err) : 0;
}
