/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight furnace: white-furnace test of every BSDF. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "setlight/render.h"

static void usage(FILE *out)
{
    fprintf(out,
            "usage: setlight furnace [--samples N] [--json]\n\n"
            "White furnace: the directional albedo (integral of f cos over the hemisphere)\n"
            "of every white BSDF lobe - Lambert, GGX conductor with F = 1 (isotropic and\n"
            "anisotropic 0.8), white Lambert under a GGX dielectric coat of index 1.5 -\n"
            "for roughness 0, 0.1, ..., 1 and incidence cos 0.02 ... 1, with and without\n"
            "Kulla-Conty energy compensation. An energy-preserving lobe has albedo 1; the\n"
            "uncompensated GGX shows the energy single scattering loses.\n\n"
            "options:\n"
            "  --samples N   stratified samples per case (default 16384, at least 16)\n"
            "  --json        print {\"cases\": [{\"bsdf\", \"roughness\", \"cos_theta\",\n"
            "                \"compensated\", \"albedo\", \"expected\"}, ...]} on stdout\n\n"
            "Without --json a table per lobe is printed: one row per roughness, one column\n"
            "per incidence cosine. See docs/render-bsdf.md.\n");
}

static void print_table(const sl_furnace *f)
{
    int i = 0;
    while (i < f->count) {
        const sl_furnace_case *first = &f->cases[i];
        printf("\n%s, %s\n  rough ", first->bsdf,
               first->compensated ? "compensated" : "not compensated");
        int ncos = 0;
        while (i + ncos < f->count && f->cases[i + ncos].roughness == first->roughness &&
               f->cases[i + ncos].compensated == first->compensated &&
               !strcmp(f->cases[i + ncos].bsdf, first->bsdf))
            printf(" %6.2f", f->cases[i + ncos++].cos_theta);
        printf("   (cos theta)\n");
        double lo = 1e300, hi = -1e300;
        while (i < f->count && !strcmp(f->cases[i].bsdf, first->bsdf) &&
               f->cases[i].compensated == first->compensated) {
            printf("  %5.2f ", f->cases[i].roughness);
            for (int c = 0; c < ncos && i < f->count; c++, i++) {
                double a = f->cases[i].albedo;
                lo = a < lo ? a : lo;
                hi = a > hi ? a : hi;
                printf(" %6.4f", a);
            }
            printf("\n");
        }
        printf("  min %.4f  max %.4f\n", lo, hi);
    }
}

int cmd_furnace(int argc, char **argv, const sl_cli *cli)
{
    static const struct option opts[] = {
        {"samples", required_argument, NULL, 's'},
        {"help", no_argument, NULL, 'h'},
        {NULL, 0, NULL, 0},
    };
    int samples = 16384;
    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, ":h", opts, NULL)) != -1) {
        switch (c) {
        case 's':
            if (!cli_parse_int(optarg, &samples) || samples < 16)
                return cli_usage_error(cli, "--samples needs a whole number >= 16");
            break;
        case 'h':
            usage(stdout);
            return 0;
        case ':':
            return cli_usage_error(cli, "%s needs a value", argv[optind - 1]);
        default:
            return cli_usage_error(cli, "unknown option '%s'", argv[optind - 1]);
        }
    }
    if (optind < argc)
        return cli_usage_error(cli, "unexpected argument '%s'", argv[optind]);

    sl_error err = {0};
    sl_furnace f;
    if (sl_furnace_run(samples, &f, &err) != SL_OK)
        return cli_fail(cli, &err);
    if (cli->json) {
        char *json;
        if (sl_furnace_json(&f, &json, &err) != SL_OK) {
            sl_furnace_free(&f);
            return cli_fail(cli, &err);
        }
        printf("%s\n", json);
        free(json);
    } else {
        printf("white furnace: directional albedo, %d samples per case (expected 1)\n", samples);
        print_table(&f);
    }
    sl_furnace_free(&f);
    return 0;
}
