/* SPDX-License-Identifier: BSD-3-Clause */
/* Chart reference files: 24 patch values as CSV or JSON, in CIELAB D50,
 * CIE XYZ D50 or linear Rec.709, converted to linear Rec.709 (D65). */
#include <ctype.h>
#include <jansson.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

#include "setlight/stitch.h"

static void to_rec709(sl_chart_space space, const double in[3], double out[3])
{
    double xyz[3], d65[3], m[3][3];
    switch (space) {
    case SL_CHART_SPACE_LIN_REC709:
        memcpy(out, in, 3 * sizeof(double));
        return;
    case SL_CHART_SPACE_LAB_D50:
        sl_lab_to_xyz(in, SL_WHITE_D50, xyz);
        break;
    case SL_CHART_SPACE_XYZ_D50:
        memcpy(xyz, in, sizeof(xyz));
        break;
    }
    /* Published chart values are under D50; the working space's white is D65. */
    sl_bradford(SL_WHITE_D50, SL_WHITE_D65, m);
    sl_mat3_apply(m, xyz, d65);
    sl_xyz_to_rec709(d65, out);
}

static bool space_from_name(const char *s, sl_chart_space *space)
{
    if (!strcasecmp(s, "lab_d50") || !strcasecmp(s, "lab"))
        *space = SL_CHART_SPACE_LAB_D50;
    else if (!strcasecmp(s, "xyz_d50") || !strcasecmp(s, "xyz"))
        *space = SL_CHART_SPACE_XYZ_D50;
    else if (!strcasecmp(s, "lin_rec709") || !strcasecmp(s, "rgb"))
        *space = SL_CHART_SPACE_LIN_REC709;
    else
        return false;
    return true;
}

/* Splits a CSV line in place on commas (or semicolons), trimming blanks. */
static int split(char *line, char **f, int max)
{
    int n = 0;
    char *p = line;
    while (n < max) {
        while (*p == ' ' || *p == '\t')
            p++;
        f[n++] = p;
        char *e = p + strcspn(p, ",;\r\n");
        char sep = *e;
        char *t = e;
        while (t > p && (t[-1] == ' ' || t[-1] == '\t'))
            t--;
        *t = '\0';
        if (sep != ',' && sep != ';')
            break;
        p = e + 1;
    }
    return n;
}

static bool parse_num(const char *s, double *v)
{
    char *end;
    *v = strtod(s, &end);
    return end != s && *end == '\0' && isfinite(*v);
}

static sl_result read_csv(const char *path, FILE *f, double values[24][3], sl_chart_space *space,
                          sl_error *err)
{
    char line[1024];
    int lineno = 0, rows = 0, first = -1;
    bool header = false;
    while (fgets(line, sizeof line, f)) {
        lineno++;
        char *p = line;
        while (isspace((unsigned char)*p))
            p++;
        if (*p == '\0' || *p == '#')
            continue;
        char *fld[8];
        int n = split(p, fld, 8);
        if (!header) {
            /* The header names the space: L,a,b | X,Y,Z | R,G,B, after an optional label column. */
            if (n != 3 && n != 4)
                return sl_error_set(err, SL_ERR_INPUT,
                                    "%s:%d: header needs 3 value columns (L,a,b | X,Y,Z | R,G,B)",
                                    path, lineno);
            first = n - 3;
            char k[4] = {(char)toupper((unsigned char)fld[first][0]),
                         (char)toupper((unsigned char)fld[first + 1][0]),
                         (char)toupper((unsigned char)fld[first + 2][0]), 0};
            if (!strcmp(k, "LAB"))
                *space = SL_CHART_SPACE_LAB_D50;
            else if (!strcmp(k, "XYZ"))
                *space = SL_CHART_SPACE_XYZ_D50;
            else if (!strcmp(k, "RGB"))
                *space = SL_CHART_SPACE_LIN_REC709;
            else
                return sl_error_set(err, SL_ERR_INPUT,
                                    "%s:%d: header '%s,%s,%s' is none of L,a,b | X,Y,Z | R,G,B",
                                    path, lineno, fld[first], fld[first + 1], fld[first + 2]);
            header = true;
            continue;
        }
        if (n != first + 3)
            return sl_error_set(err, SL_ERR_INPUT, "%s:%d: %d columns, the header has %d", path,
                                lineno, n, first + 3);
        if (rows >= 24)
            return sl_error_set(err, SL_ERR_INPUT, "%s:%d: more than 24 patches", path, lineno);
        for (int c = 0; c < 3; c++)
            if (!parse_num(fld[first + c], &values[rows][c]))
                return sl_error_set(err, SL_ERR_INPUT, "%s:%d: '%s' is not a number", path,
                                    lineno, fld[first + c]);
        rows++;
    }
    if (!header || rows != 24)
        return sl_error_set(err, SL_ERR_INPUT, "%s: %d patches, a ColorChecker has 24", path, rows);
    return SL_OK;
}

static sl_result read_json(const char *path, double values[24][3], sl_chart_space *space,
                           sl_error *err)
{
    json_t *root;
    sl_result r = sl_json_load_file(path, "chart reference JSON", 0, &root, err);
    if (r)
        return r;
    json_t *sp = json_object_get(root, "space"), *pa = json_object_get(root, "patches");
    if (!json_is_string(sp) || !space_from_name(json_string_value(sp), space))
        r = sl_error_set(err, SL_ERR_INPUT,
                         "%s: \"space\" must be \"lab_d50\", \"xyz_d50\" or \"lin_rec709\"", path);
    else if (!json_is_array(pa) || json_array_size(pa) != 24)
        r = sl_error_set(err, SL_ERR_INPUT, "%s: \"patches\" must be an array of 24 [v1, v2, v3]",
                         path);
    for (size_t i = 0; !r && i < 24; i++) {
        json_t *row = json_array_get(pa, i);
        if (!json_is_array(row) || json_array_size(row) != 3)
            r = sl_error_set(err, SL_ERR_INPUT, "%s: patch %zu is not [v1, v2, v3]", path, i + 1);
        for (size_t c = 0; !r && c < 3; c++) {
            json_t *v = json_array_get(row, c);
            values[i][c] = json_number_value(v);
            if (!json_is_number(v) || !isfinite(values[i][c]))
                r = sl_error_set(err, SL_ERR_INPUT, "%s: patch %zu value %zu is not a number", path,
                                 i + 1, c + 1);
        }
    }
    json_decref(root);
    return r;
}

sl_result sl_chart_reference_read(const char *path, double reference[24][3], sl_chart_space *space,
                                  sl_error *err)
{
    memset(reference, 0, 24 * sizeof(reference[0]));
    sl_result r = sl_check_input_file(path, err);
    if (r)
        return r;
    double v[24][3];
    sl_chart_space sp = SL_CHART_SPACE_LIN_REC709;
    const char *dot = strrchr(path, '.');
    if (dot && !strcasecmp(dot, ".json")) {
        r = read_json(path, v, &sp, err);
    } else {
        FILE *f = fopen(path, "r");
        if (!f)
            return sl_error_set(err, SL_ERR_IO, "%s: cannot open", path);
        r = read_csv(path, f, v, &sp, err);
        fclose(f);
    }
    if (r)
        return r;
    /* XYZ given with white Y = 100 (as spectrophotometers print it). */
    if (sp == SL_CHART_SPACE_XYZ_D50 && v[18][1] > 2)
        for (int p = 0; p < 24; p++)
            for (int c = 0; c < 3; c++)
                v[p][c] /= 100;
    for (int p = 0; p < 24; p++) {
        to_rec709(sp, v[p], reference[p]);
        double y = sl_luminance(reference[p]);
        if (!(y > 0))
            return sl_error_set(err, SL_ERR_INPUT, "%s: patch %d has no positive luminance", path,
                                p + 1);
    }
    if (space)
        *space = sp;
    return SL_OK;
}
