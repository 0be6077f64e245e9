/* SPDX-License-Identifier: BSD-3-Clause */
/* Camera response curves for the simulated camera: parametric shapes and
 * curve files (the Columbia DoRF database format, or "I B" text). */
#include <ctype.h>
#include <stdlib.h>
#include <string.h>

#include "vset_internal.h"

#define N SL_VSET_CRF_SAMPLES

static const char *const response_names[] = {"linear", "srgb", "filmic", "canon", NULL};

const char *const *sl_vset_response_names(void) { return response_names; }

static double srgb(double x)
{
    return x <= 0.0031308 ? 12.92 * x : 1.055 * pow(x, 1.0 / 2.4) - 0.055;
}

sl_result sl_vset_response_preset(const char *name, sl_vset_response *r, sl_error *err)
{
    memset(r, 0, sizeof *r);
    int kind = -1;
    for (int i = 0; response_names[i]; i++)
        if (name && !strcmp(name, response_names[i]))
            kind = i;
    if (kind < 0)
        return sl_error_set(err, SL_ERR_USAGE,
                            "%s: unknown response curve (linear, srgb, filmic, canon, or a file)",
                            name ? name : "");
    snprintf(r->name, sizeof r->name, "%s", name);
    /* filmic: a log-logistic S-curve (toe and shoulder) with 18% grey at
     * about 0.41; canon: sRGB with the brighter mid-tones and rolled-off
     * highlights of a camera JPEG picture style. */
    const double m = 0.25, g = 1.6, g1 = 1.0 / (1.0 + pow(m, g));
    for (int i = 0; i < N; i++) {
        double x = (double)i / (N - 1), y;
        switch (kind) {
        case 0: y = x; break;
        case 1: y = srgb(x); break;
        case 2: y = pow(x, g) / (pow(x, g) + pow(m, g)) / g1; break;
        default: y = 1.0 - pow(1.0 - srgb(x), 1.4); break;
        }
        r->curve[i] = y;
    }
    r->curve[0] = 0;
    r->curve[N - 1] = 1;
    return SL_OK;
}

double sl_vset_response_apply(const sl_vset_response *r, double x)
{
    if (!(x > 0))
        return r->curve[0];
    if (x >= 1)
        return r->curve[N - 1];
    double f = x * (N - 1);
    int i = (int)f;
    if (i >= N - 1)
        i = N - 2;
    double t = f - i;
    return r->curve[i] + (r->curve[i + 1] - r->curve[i]) * t;
}

double sl_vset_response_slope(const sl_vset_response *r, double x)
{
    double f = (x < 0 ? 0 : x > 1 ? 1 : x) * (N - 1);
    int i = (int)f;
    if (i >= N - 1)
        i = N - 2;
    return (r->curve[i + 1] - r->curve[i]) * (N - 1);
}

double sl_vset_response_invert(const sl_vset_response *r, double y)
{
    if (y <= r->curve[0])
        return 0;
    if (y >= r->curve[N - 1]) {
        int i = N - 1;
        while (i > 0 && r->curve[i - 1] >= y)
            i--;
        return (double)i / (N - 1);
    }
    int lo = 0, hi = N - 1; /* curve[lo] < y <= curve[hi] */
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (r->curve[mid] < y)
            lo = mid;
        else
            hi = mid;
    }
    double t = (y - r->curve[lo]) / (r->curve[hi] - r->curve[lo]);
    return (lo + t) / (N - 1);
}

/* Resamples (xs, ys) onto the uniform grid, then forces it monotonic and
 * spanning [0, 1]. */
static sl_result resample(const char *path, const double *xs, const double *ys, int n,
                          sl_vset_response *r, sl_error *err)
{
    if (n < 2)
        return sl_error_set(err, SL_ERR_INPUT, "%s: a response curve needs 2 or more samples",
                            path);
    for (int i = 0; i < n; i++) {
        if (!isfinite(xs[i]) || !isfinite(ys[i]) || (i > 0 && xs[i] <= xs[i - 1]))
            return sl_error_set(err, SL_ERR_INPUT,
                                "%s: response samples must be finite with increasing input",
                                path);
    }
    int k = 0;
    for (int i = 0; i < N; i++) {
        double x = xs[0] + (xs[n - 1] - xs[0]) * i / (N - 1);
        while (k < n - 2 && xs[k + 1] < x)
            k++;
        double t = (x - xs[k]) / (xs[k + 1] - xs[k]);
        r->curve[i] = ys[k] + (ys[k + 1] - ys[k]) * t;
    }
    for (int i = 1; i < N; i++)
        if (r->curve[i] < r->curve[i - 1])
            r->curve[i] = r->curve[i - 1];
    double lo = r->curve[0], hi = r->curve[N - 1];
    if (!(hi > lo))
        return sl_error_set(err, SL_ERR_INPUT, "%s: response curve is flat", path);
    for (int i = 0; i < N; i++)
        r->curve[i] = (r->curve[i] - lo) / (hi - lo);
    return SL_OK;
}

static char *read_all(const char *path, sl_error *err)
{
    if (sl_check_input_file(path, err))
        return NULL;
    FILE *f = fopen(path, "rb");
    if (!f) {
        sl_error_set(err, SL_ERR_IO, "%s: cannot open", path);
        return NULL;
    }
    fseek(f, 0, SEEK_END);
    long size = ftell(f);
    fseek(f, 0, SEEK_SET);
    char *buf = size >= 0 ? malloc((size_t)size + 1) : NULL;
    if (!buf || fread(buf, 1, (size_t)size, f) != (size_t)size) {
        free(buf);
        fclose(f);
        sl_error_set(err, SL_ERR_IO, "%s: cannot read", path);
        return NULL;
    }
    buf[size] = 0;
    fclose(f);
    return buf;
}

static int parse_numbers(char *s, double *out, int max)
{
    int n = 0;
    char *end;
    for (;;) {
        while (*s && isspace((unsigned char)*s))
            s++;
        if (!*s)
            break;
        double v = strtod(s, &end);
        if (end == s)
            return -1;
        if (n < max)
            out[n] = v;
        n++;
        s = end;
    }
    return n;
}

static char *next_line(char **cursor)
{
    char *s = *cursor;
    if (!s || !*s)
        return NULL;
    char *nl = strchr(s, '\n');
    if (nl) {
        *nl = 0;
        *cursor = nl + 1;
    } else {
        *cursor = s + strlen(s);
    }
    size_t len = strlen(s);
    while (len && (s[len - 1] == '\r' || isspace((unsigned char)s[len - 1])))
        s[--len] = 0;
    return s;
}

sl_result sl_vset_response_load(const char *path, const char *curve_name,
                                sl_vset_response *r, sl_error *err)
{
    memset(r, 0, sizeof *r);
    char *buf = read_all(path, err);
    if (!buf)
        return err ? err->code : SL_ERR_IO;
    enum { MAXS = 8192 };
    double *xs = malloc(MAXS * sizeof *xs), *ys = malloc(MAXS * sizeof *ys);
    sl_result res = SL_OK;
    if (!xs || !ys) {
        res = sl_error_set(err, SL_ERR_NOMEM, "%s: out of memory", path);
        goto done;
    }
    char *cur = buf, *line;
    char *first = NULL;
    while ((line = next_line(&cur)) && !*line)
        ;
    first = line;
    double probe[4];
    if (first && parse_numbers(first, probe, 4) == 2) {
        /* "I B" per line. */
        int n = 0;
        for (line = first; line; line = next_line(&cur)) {
            if (!*line || *line == '#')
                continue;
            double v[2];
            if (parse_numbers(line, v, 2) != 2 || n >= MAXS) {
                res = sl_error_set(err, SL_ERR_INPUT, "%s: expected two numbers per line: %.40s",
                                   path, line);
                goto done;
            }
            xs[n] = v[0];
            ys[n] = v[1];
            n++;
        }
        res = resample(path, xs, ys, n, r, err);
        if (!res)
            snprintf(r->name, sizeof r->name, "%s", path);
        goto done;
    }
    /* DoRF: blocks of name, type, "I =", samples, "B =", samples. */
    for (line = first; line;) {
        char *name = line, *type = next_line(&cur), *ilab = next_line(&cur);
        char *ival = next_line(&cur), *blab = next_line(&cur), *bval = next_line(&cur);
        if (!type || !ilab || !ival || !blab || !bval || strcmp(ilab, "I =") ||
            strcmp(blab, "B =")) {
            res = sl_error_set(err, SL_ERR_INPUT,
                               "%s: not a DoRF curve file or \"I B\" text (at curve '%.40s')",
                               path, name);
            goto done;
        }
        if (!curve_name || !strcmp(curve_name, name)) {
            int ni = parse_numbers(ival, xs, MAXS), nb = parse_numbers(bval, ys, MAXS);
            if (ni < 2 || ni != nb || ni > MAXS) {
                res = sl_error_set(err, SL_ERR_INPUT, "%s: curve %s: %d I and %d B samples",
                                   path, name, ni, nb);
                goto done;
            }
            res = resample(path, xs, ys, ni, r, err);
            if (!res)
                snprintf(r->name, sizeof r->name, "%s", name);
            goto done;
        }
        while ((line = next_line(&cur)) && !*line)
            ;
    }
    res = sl_error_set(err, SL_ERR_INPUT, "%s: no curve named '%s'", path,
                       curve_name ? curve_name : "");
done:
    free(xs);
    free(ys);
    free(buf);
    return res;
}
