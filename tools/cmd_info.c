/* SPDX-License-Identifier: BSD-3-Clause */
/* setlight info FILE...: what a data wrangler checks first about an image. */
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "cli.h"

static const char *info_help =
    "usage: setlight info [--json] FILE...\n\n"
    "Prints, for each image: size, channels, pixel type, data range and mean per channel,\n"
    "NaN/Inf/negative counts, EXIF exposure (shutter, f-number, ISO, EV100), camera, lens,\n"
    "date, orientation, envmap type and colour space, and setlight provenance attributes.\n"
    "Reads OpenEXR (R,G,B[,A], else Y[,A], else the first layer's; other channels are\n"
    "dropped; every compression, scanline or tiled: docs/formats.md), PNG (libpng), JPEG\n"
    "(libjpeg), TIFF (libtiff: 8/16-bit, float, strips or tiles) and anything else\n"
    "OpenImageIO reads (HDR, DNG, camera raw, CMYK JPEG, palette or CMYK TIFF: the first\n"
    "such file costs ~0.4 s of CPU loading OpenImageIO, once per process).\n\n"
    "Every file is examined even when one fails; the exit code is that of the first failure.\n"
    "  --json   one JSON object on stdout: {\"files\": [{...}, ...]}\n";

static const char *envmap_name(sl_envmap e)
{
    return e == SL_ENVMAP_LATLONG ? "latlong" : e == SL_ENVMAP_CUBE ? "cube" : "none";
}

/* The colour space every command reads the file in (sl_file_color_space:
 * named by the file, else assumed from its samples); what the file says
 * when OCIO does not know it; "" when nothing. */
static const char *colour_space_of(const sl_meta *m, bool *assumed)
{
    const char *cs = sl_file_color_space(m, assumed);
    if (cs)
        return cs;
    if (m->colorspace[0])
        return m->colorspace; /* what the file says, even if OCIO does not know it */
    return m->has_chromaticities ? "custom chromaticities" : "";
}

/* How commands take that colour space (docs/color.md). */
static const char *colour_reading(const sl_meta *m, const char *cs, bool assumed)
{
    const char *encoding = sl_color_space_encoding(cs);
    if (!encoding)
        return m->has_chromaticities && !m->colorspace[0]
                   ? "converted to lin_rec709 by the matrix of its chromaticities"
                   : "not in setlight's OCIO config: commands refuse the file";
    if (!strcmp(cs, SL_WORKING_SPACE) || !strcmp(encoding, "data"))
        return assumed ? "assumed: the file names none; read as it is" : "read as it is";
    return assumed ? "assumed: the file names none; converted to lin_rec709 through OpenColorIO"
                   : "converted to lin_rec709 through OpenColorIO";
}

static double ev100(const sl_meta *m)
{
    if (m->exposure_time <= 0 || m->f_number <= 0)
        return NAN;
    double iso = m->iso > 0 ? m->iso : 100.0;
    return log2(m->f_number * m->f_number / m->exposure_time) - log2(iso / 100.0);
}

static json_t *info_json(const char *path, const sl_image *img, const sl_meta *m,
                         const sl_image_stats *st)
{
    json_t *o = json_object();
    json_object_set_new(o, "file", json_string(path));
    json_object_set_new(o, "width", json_integer(img->width));
    json_object_set_new(o, "height", json_integer(img->height));
    json_object_set_new(o, "channels", json_integer(img->channels));
    json_object_set_new(o, "format", json_string(m->format));
    json_object_set_new(o, "bits_per_sample", json_integer(m->bits_per_sample));
    json_object_set_new(o, "float", json_boolean(m->is_float));
    json_t *ch = json_array();
    for (int c = 0; c < img->channels; c++) {
        json_t *s = json_object();
        json_object_set_new(s, "min", json_real(st->min[c]));
        json_object_set_new(s, "max", json_real(st->max[c]));
        json_object_set_new(s, "mean", json_real(st->mean[c]));
        json_array_append_new(ch, s);
    }
    json_object_set_new(o, "channel_stats", ch);
    json_object_set_new(o, "nan_count", json_integer(st->nan_count));
    json_object_set_new(o, "inf_count", json_integer(st->inf_count));
    json_object_set_new(o, "negative_count", json_integer(st->negative_count));
    json_object_set_new(o, "envmap", json_string(envmap_name(m->envmap)));
    json_object_set_new(o, "latlong_shape", json_boolean(sl_is_latlong_shape(img->width, img->height)));
    bool assumed;
    const char *cs = colour_space_of(m, &assumed);
    json_object_set_new(o, "colorspace", *cs ? json_string(cs) : json_null());
    json_object_set_new(o, "colorspace_assumed", json_boolean(assumed));
    json_t *exif = json_object();
    json_object_set_new(exif, "exposure_time", m->exposure_time > 0 ? json_real(m->exposure_time) : json_null());
    json_object_set_new(exif, "f_number", m->f_number > 0 ? json_real(m->f_number) : json_null());
    json_object_set_new(exif, "iso", m->iso > 0 ? json_real(m->iso) : json_null());
    double ev = ev100(m);
    json_object_set_new(exif, "ev100", isfinite(ev) ? json_real(ev) : json_null());
    json_object_set_new(exif, "focal_length_mm", m->focal_length_mm > 0 ? json_real(m->focal_length_mm) : json_null());
    json_object_set_new(exif, "make", json_string(m->make));
    json_object_set_new(exif, "model", json_string(m->model));
    json_object_set_new(exif, "lens", json_string(m->lens));
    json_object_set_new(exif, "datetime", json_string(m->datetime));
    json_object_set_new(exif, "orientation", json_integer(m->orientation));
    json_object_set_new(o, "exif", exif);
    json_t *attrs = json_object();
    for (int i = 0; i < m->attr_count; i++)
        json_object_set_new(attrs, m->attrs[i].name, json_string(m->attrs[i].value));
    json_object_set_new(o, "attributes", attrs);
    return o;
}

static void info_print(const char *path, const sl_image *img, const sl_meta *m,
                       const sl_image_stats *st)
{
    static const char *names[4] = {"R", "G", "B", "A"};
    printf("%s\n", path);
    printf("  size        %d x %d, %d channel%s, %s %d-bit%s\n", img->width, img->height,
           img->channels, img->channels > 1 ? "s" : "", m->format[0] ? m->format : "?",
           m->bits_per_sample, m->is_float ? " float" : "");
    for (int c = 0; c < img->channels; c++)
        printf("  %-11s min %-12.6g max %-12.6g mean %.6g\n",
               img->channels == 1 ? "Y" : names[c], st->min[c], st->max[c], st->mean[c]);
    printf("  non-finite  %lld NaN, %lld Inf; %lld negative\n", (long long)st->nan_count,
           (long long)st->inf_count, (long long)st->negative_count);
    bool assumed;
    const char *cs = colour_space_of(m, &assumed);
    printf("  envmap      %s%s\n", envmap_name(m->envmap),
           m->envmap == SL_ENVMAP_NONE && sl_is_latlong_shape(img->width, img->height)
               ? " (2:1: commands take it as a lat-long)"
               : "");
    printf("  colour      %s (%s)\n", cs, colour_reading(m, cs, assumed));
    if (m->exposure_time > 0 || m->f_number > 0 || m->iso > 0) {
        printf("  exposure   ");
        if (m->exposure_time > 0) {
            if (m->exposure_time < 1)
                printf(" 1/%.4g s", 1.0 / m->exposure_time);
            else
                printf(" %.4g s", m->exposure_time);
        }
        if (m->f_number > 0)
            printf(" f/%.3g", m->f_number);
        if (m->iso > 0)
            printf(" ISO %.0f", m->iso);
        double ev = ev100(m);
        if (isfinite(ev))
            printf(" (EV100 %.2f)", ev);
        printf("\n");
    } else
        printf("  exposure    no EXIF exposure\n");
    if (m->make[0] || m->model[0])
        printf("  camera      %s %s\n", m->make, m->model);
    if (m->lens[0] || m->focal_length_mm > 0)
        printf("  lens        %s%s%.4g mm\n", m->lens, m->lens[0] ? ", " : "", m->focal_length_mm);
    if (m->datetime[0])
        printf("  date        %s\n", m->datetime);
    if (m->orientation)
        printf("  orientation %d\n", m->orientation);
    for (int i = 0; i < m->attr_count; i++)
        printf("  %-11s %s\n", m->attrs[i].name, m->attrs[i].value);
}

int cmd_info(int argc, char **argv, const sl_cli *cli)
{
    static const struct option opts[] = {{"help", no_argument, NULL, 'h'}, {0, 0, 0, 0}};
    cli_getopt_reset();
    int c;
    while ((c = getopt_long(argc, argv, "h", opts, NULL)) != -1) {
        if (c == 'h') {
            fputs(info_help, stdout);
            return 0;
        }
        return cli_usage_error(cli, "unknown option '%s'", argv[optind - 1]);
    }
    if (optind >= argc)
        return cli_usage_error(cli, "no input file");

    int rc = 0;
    json_t *files = json_array();
    for (int i = optind; i < argc; i++) {
        sl_image img;
        sl_meta meta;
        sl_error err;
        sl_result r = sl_image_read(argv[i], &img, &meta, &err);
        if (r) {
            int code = cli_fail(cli, &err);
            if (!rc)
                rc = code;
            if (cli->json) {
                json_t *o = json_object();
                json_object_set_new(o, "file", json_string(argv[i]));
                json_object_set_new(o, "error", json_string(err.message));
                json_array_append_new(files, o);
            }
            continue;
        }
        cli_warn_format_mismatch(argv[i], &meta);
        sl_image_stats st;
        sl_image_stats_compute(&img, &st);
        if (cli->json)
            json_array_append_new(files, info_json(argv[i], &img, &meta, &st));
        else
            info_print(argv[i], &img, &meta, &st);
        sl_image_free(&img);
        sl_meta_free(&meta);
    }
    if (cli->json) {
        json_t *root = json_object();
        json_object_set_new(root, "files", files);
        json_dumpf(root, stdout, JSON_INDENT(2));
        fputc('\n', stdout);
        json_decref(root);
    } else
        json_decref(files);
    return rc;
}
