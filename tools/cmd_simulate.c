/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight simulate: a virtual film set photographed like a real shoot. */
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "cli.h"
#include "setlight/vset.h"

static void help(FILE *out)
{
    fprintf(out,
            "usage: setlight simulate --scene exterior|stage|night|FILE.json --out DIR\n"
            "                         [--seed N] [--size tiny|small|full] [--zenith]\n"
            "                         [--response NAME|FILE [--curve NAME]] [--raw-bits 12|14]\n"
            "                         [--jitter DEG] [--ghost] [--force]\n\n"
            "Generates a virtual film set (a ground-truth HDR lat-long and its lights) and\n"
            "photographs it as a data wrangler would: a bracket of 7 exposures 3 stops apart\n"
            "for each of 3 fisheye views 120 degrees apart on a nodal head, then a chrome\n"
            "ball, an 18%% grey ball and a ColorChecker with a 200 mm lens (DIR/probes),\n"
            "written as JPEG, 16-bit TIFF and linear TIFF with EXIF, plus the ground truth\n"
            "in DIR/truth (lat-long, lights, camera, probe positions and renders).\n"
            "The fisheye is not what its EXIF says (8 mm equisolid): its true focal length\n"
            "(8.12 mm), centre, distortion and vignetting, and the head's true poses (views\n"
            "after the first off their plan by up to 1 degree), are in truth/camera.json.\n\n"
            "  --scene NAME|FILE  built-in scene or a scene JSON file (docs/virtual-set.md)\n"
            "  -o, --out DIR      capture folder: created, or an empty folder\n"
            "  --seed N           sensor-noise and head-error seed (default 1); same seed,\n"
            "                     same files\n"
            "  --size S           small (1024 lat-long, 720x480 frames; default), full\n"
            "                     (4096 lat-long, 3000x2000 frames) or tiny (256, 192x128)\n"
            "  --zenith           add a fourth view straight up\n"
            "  --response R       camera response: linear, srgb, filmic, canon (default), or a\n"
            "                     curve file (DoRF dorfCurves.txt format, or \"I B\" lines)\n"
            "  --curve NAME       which curve of a DoRF file (default: the first)\n"
            "  --raw-bits N       raw quantisation, 12 or 14 (default)\n"
            "  --jitter DEG       hand-held: each frame's yaw, pitch and roll wander by this\n"
            "                     standard deviation (0..10; default 0, a locked nodal head)\n"
            "  --ghost            a person walks across the first view between frames\n"
            "  --force            replace a capture already in DIR\n"
            "\nexit codes: 0 success, 1 runtime failure (e.g. DIR not writable), 2 usage error\n"
            "(unknown scene, DIR already holds a capture or other files), 3 invalid scene file\n");
}

static const char *size_name(int size)
{
    return size == SL_VSET_SIZE_TINY ? "tiny" : size == SL_VSET_SIZE_FULL ? "full" : "small";
}

/* A folder named like a scene (often the --out of an earlier run:
 * "--scene night --out night") does not hide the built-in scene. */
static bool looks_like_file(const char *s)
{
    struct stat sb;
    size_t n = strlen(s);
    return strchr(s, '/') || (n > 5 && !strcmp(s + n - 5, ".json")) ||
           (n > 4 && !strcmp(s + n - 4, ".txt")) || (stat(s, &sb) == 0 && !S_ISDIR(sb.st_mode));
}

int cmd_simulate(int argc, char **argv, const sl_cli *cli)
{
    enum { O_SCENE = 256, O_SEED, O_SIZE, O_ZENITH, O_FORCE, O_JITTER, O_GHOST, O_RESP, O_CURVE,
           O_BITS };
    static const struct option opts[] = {
        {"scene", required_argument, 0, O_SCENE}, {"out", required_argument, 0, 'o'},
        {"seed", required_argument, 0, O_SEED},   {"size", required_argument, 0, O_SIZE},
        {"zenith", no_argument, 0, O_ZENITH},     {"force", no_argument, 0, O_FORCE},
        {"jitter", required_argument, 0, O_JITTER}, {"ghost", no_argument, 0, O_GHOST},
        {"response", required_argument, 0, O_RESP}, {"curve", required_argument, 0, O_CURVE},
        {"raw-bits", required_argument, 0, O_BITS},
        {"help", no_argument, 0, 'h'},            {0, 0, 0, 0}};
    const char *scene_arg = NULL, *out = NULL;
    int size = SL_VSET_SIZE_SMALL;
    bool zenith = false, force = false, ghost = false;
    double jitter = 0;
    const char *response = "canon", *curve = NULL;
    int raw_bits = 14;
    uint64_t seed = 1;
    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, ":ho:", opts, NULL)) != -1) {
        switch (c) {
        case 'h':
            help(stdout);
            return 0;
        case 'o': out = optarg; break;
        case O_SCENE: scene_arg = optarg; break;
        case O_SEED: {
            char *end;
            unsigned long long v = strtoull(optarg, &end, 10);
            if (end == optarg || *end || optarg[0] == '-')
                return cli_usage_error(cli, "--seed needs a whole number >= 0, not '%s'", optarg);
            seed = v;
            break;
        }
        case O_SIZE:
            size = sl_vset_size_from_name(optarg);
            if (size < 0)
                return cli_usage_error(cli, "--size is tiny, small or full, not '%s'", optarg);
            break;
        case O_ZENITH: zenith = true; break;
        case O_GHOST: ghost = true; break;
        case O_RESP: response = optarg; break;
        case O_CURVE: curve = optarg; break;
        case O_BITS:
            if (!cli_parse_int(optarg, &raw_bits) || (raw_bits != 12 && raw_bits != 14))
                return cli_usage_error(cli, "--raw-bits is 12 or 14, not '%s'", optarg);
            break;
        case O_JITTER:
            if (!cli_parse_double(optarg, &jitter) || jitter < 0 || jitter > 10)
                return cli_usage_error(cli, "--jitter needs degrees from 0 to 10, not '%s'",
                                       optarg);
            break;
        case O_FORCE: force = true; break;
        case ':': return cli_usage_error(cli, "%s needs a value", argv[optind - 1]);
        default: return cli_usage_error(cli, "unknown option %s", argv[optind - 1]);
        }
    }
    if (optind < argc)
        return cli_usage_error(cli, "unexpected argument '%s'", argv[optind]);
    if (!scene_arg)
        return cli_usage_error(cli, "--scene is required (exterior, stage, night or FILE.json)");
    if (!out)
        return cli_usage_error(cli, "--out DIR is required");

    sl_error err;
    sl_error_clear(&err);
    sl_vset_desc desc;
    sl_result r = looks_like_file(scene_arg) ? sl_vset_desc_read_json(scene_arg, &desc, &err)
                                             : sl_vset_preset(scene_arg, &desc, &err);
    if (r)
        return cli_fail(cli, &err);
    sl_vset_capture_opts o;
    sl_vset_capture_defaults(&o, &desc, (sl_vset_size)size);
    if (curve && looks_like_file(response) == false)
        return cli_usage_error(cli, "--curve picks a curve of a response file");
    r = looks_like_file(response) ? sl_vset_response_load(response, curve, &o.response, &err)
                                  : sl_vset_response_preset(response, &o.response, &err);
    if (r)
        return cli_fail(cli, &err);
    o.raw_bits = raw_bits;
    o.seed = seed;
    o.zenith = zenith;
    o.force = force;
    o.jitter_deg = jitter;
    o.ghost = ghost;
    sl_vset_capture_summary s;
    double t0 = sl_seconds();
    if ((r = sl_vset_capture_write(&o, out, &s, &err)))
        return cli_fail(cli, &err);
    double secs = sl_seconds() - t0;
    if (cli->json)
        printf("{\"out\": \"%s\", \"scene\": \"%s\", \"seed\": %" PRIu64
               ", \"size\": \"%s\", \"views\": %d, \"frames\": %d, \"probe_frames\": %d, "
               "\"f_number\": %g, \"iso\": %g, "
               "\"exposure_min_s\": %.9g, \"exposure_centre_s\": %.9g, \"exposure_max_s\": %.9g, "
               "\"seconds\": %.3f}\n",
               out, desc.name, seed, size_name(size), s.views, s.frames, s.probe_frames, s.f_number,
               s.iso, s.min_time_s, s.center_time_s, s.max_time_s, secs);
    else
        sl_log(SL_LOG_INFO, "%d frames (%d views) and %d probe frames, f/%g ISO %g, %.6g..%.6g s, "
               "in %.1f s", s.frames, s.views, s.probe_frames, s.f_number, s.iso, s.min_time_s,
               s.max_time_s, secs);
    return 0;
}
