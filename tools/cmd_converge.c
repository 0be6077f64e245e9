/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight converge: error against time for every sampling strategy. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "render_opts.h"
#include "setlight/render.h"

static void help(FILE *out)
{
    fprintf(out,
            "usage: setlight converge --env ENV | --rig RIG.json [--scene PRESET|FILE.json]\n"
            "                         [options] --svg PLOT.svg [--table TABLE.md]\n\n"
            "Renders the scene with each sampling strategy (uniform, cosine, bsdf, light, mis,\n"
            "mis+sobol), then with the closed form (closed-form: exact and control-variate\n"
            "pixels, mis+sobol for the rest), and measures the relative RMSE against a\n"
            "reference after every pass.\n\n"
            "  --env FILE / --rig FILE / --scene NAME|FILE / --width N / --view AZ,EL /\n"
            "  --background MODE / --bounces N / --seed N   as for 'setlight render'\n"
            "  --spp N             sample budget per strategy (default 256)\n"
            "  --reference IMG     the true image; otherwise a mis+sobol render of\n"
            "  --reference-spp N   samples per pixel (default 16 x --spp)\n"
            "  --pixel-centers     sample pixel centres only (lighting error without edge noise)\n"
            "  --target-error E    the error the table's 'to reach' columns use (default: what\n"
            "                      mis+sobol reaches at a quarter of the budget)\n"
            "  --svg FILE          log-log plot of relative RMSE against seconds\n"
            "  --table FILE        the same numbers as a Markdown table (also printed on stdout)\n"
            "\nexit codes: 0 success, 1 runtime failure, 2 usage error, 3 invalid input data\n");
}

int cmd_converge(int argc, char **argv, const sl_cli *cli)
{
    enum { O_ENV = 256, O_RIG, O_SCENE, O_WIDTH, O_VIEW, O_BG, O_BOUNCES, O_SEED, O_SPP, O_REF,
           O_REFSPP, O_CENTERS, O_TERR, O_SVG, O_TABLE };
    static const struct option opts[] = {
        {"env", required_argument, 0, O_ENV},         {"rig", required_argument, 0, O_RIG},
        {"scene", required_argument, 0, O_SCENE},     {"width", required_argument, 0, O_WIDTH},
        {"view", required_argument, 0, O_VIEW},       {"background", required_argument, 0, O_BG},
        {"bounces", required_argument, 0, O_BOUNCES}, {"seed", required_argument, 0, O_SEED},
        {"spp", required_argument, 0, O_SPP},         {"reference", required_argument, 0, O_REF},
        {"reference-spp", required_argument, 0, O_REFSPP},
        {"pixel-centers", no_argument, 0, O_CENTERS}, {"target-error", required_argument, 0, O_TERR},
        {"svg", required_argument, 0, O_SVG},         {"table", required_argument, 0, O_TABLE},
        {"help", no_argument, 0, 'h'},                {0, 0, 0, 0}};
    const char *env = NULL, *rig = NULL, *scene_arg = "refs", *ref_path = NULL, *svg = NULL,
               *table = NULL;
    int spp = 256, ref_spp = 0;
    double target = 0;
    bool centers = false;
    render_opts ro;
    render_opts_init(&ro, 128);
    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, ":h", opts, NULL)) != -1) {
        switch (c) {
        case 'h': help(stdout); return 0;
        case O_ENV: env = optarg; break;
        case O_RIG: rig = optarg; break;
        case O_SCENE: scene_arg = optarg; break;
        case O_REF: ref_path = optarg; break;
        case O_SVG: svg = optarg; break;
        case O_TABLE: table = optarg; break;
        case O_CENTERS: centers = true; break;
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
        case O_SPP:
            if (!cli_parse_int(optarg, &spp) || spp < 2)
                return cli_usage_error(cli, "--spp needs a whole number >= 2");
            break;
        case O_REFSPP:
            if (!cli_parse_int(optarg, &ref_spp) || ref_spp < 2)
                return cli_usage_error(cli, "--reference-spp needs a whole number >= 2");
            break;
        case O_TERR:
            if (!cli_parse_double(optarg, &target) || target <= 0)
                return cli_usage_error(cli, "--target-error needs a number > 0");
            break;
        case ':': return cli_usage_error(cli, "%s needs a value", argv[optind - 1]);
        default: return cli_usage_error(cli, "unknown option %s", argv[optind - 1]);
        }
    }
    if (optind < argc)
        return cli_usage_error(cli, "unexpected argument '%s'", argv[optind]);
    if (!env == !rig)
        return cli_usage_error(cli, "give exactly one of --env ENV and --rig RIG.json");
    if (!svg && !table)
        return cli_usage_error(cli, "--svg or --table is required");
    if (ref_spp == 0)
        ref_spp = spp > INT32_MAX / 16 ? INT32_MAX : 16 * spp;
    if (ref_spp < spp)
        return cli_usage_error(cli, "--reference-spp must be at least --spp");

    sl_error err = {0};
    sl_scene scene;
    sl_image ref = {0};
    sl_converge_report rep = {0};
    sl_scene_init(&scene);
    sl_result r = sl_scene_load(&scene, scene_arg, ro.width, env, NULL, 0, 1, rig, &err);
    if (r)
        goto fail;
    render_opts_apply(&ro, &scene);
    if (ref_path && (r = render_opts_read_reference(ref_path, &scene, &ref, &err)))
        goto fail;
    sl_render_options o;
    sl_render_options_init(&o);
    o.spp = spp;
    o.bounces = ro.bounces;
    o.seed = (uint64_t)ro.seed;
    o.pixel_centers = centers;
    if ((r = sl_converge_run(&scene, &o, ref_path ? &ref : NULL, ref_spp, &rep, &err)))
        goto fail;
    if (target <= 0) {
        const sl_converge_curve *best = &rep.curves[rep.count - 1];
        for (int k = 0; k < best->stats.pass_count; k++)
            if (best->stats.passes[k].spp <= spp / 4 || k == 0)
                target = best->stats.passes[k].ref_rel_rmse;
    }
    if (svg && (r = sl_converge_write_svg(&rep, svg, &err)))
        goto fail;
    if (table && (r = sl_converge_write_table(&rep, target, table, &err)))
        goto fail;
    if (cli->json)
        printf("{\"target_error\": %.6g, \"curves\": [", target);
    for (int i = 0; i < rep.count; i++) {
        const sl_converge_curve *cv = &rep.curves[i];
        double last = cv->stats.passes[cv->stats.pass_count - 1].ref_rel_rmse;
        double n = sl_converge_spp_to_reach(cv, target), t = sl_converge_seconds_to_reach(cv, target);
        if (cli->json)
            printf("%s\n  {\"strategy\": \"%s\", \"spp\": %lld, \"seconds\": %.6g, \"rel_rmse\": %.6g, "
                   "\"spp_to_target\": %.6g, \"seconds_to_target\": %.6g}",
                   i ? "," : "", cv->name, (long long)cv->stats.spp, cv->stats.seconds, last, n, t);
        else
            printf("%-10s %7lld spp %9.4f s  rel. RMSE %-10.4g to reach %.3g: %s%.4g spp, %.4g s\n",
                   cv->name, (long long)cv->stats.spp, cv->stats.seconds, last, target,
                   n < 0 ? "never (-1) " : "", n, t);
    }
    if (cli->json)
        printf("\n]}\n");
fail:
    sl_converge_report_free(&rep);
    sl_image_free(&ref);
    sl_scene_free(&scene);
    return r ? cli_fail(cli, &err) : 0;
}
