/* SPDX-License-Identifier: BSD-3-Clause */
/* Bracket plans: shutter-speed text, "NxS" around a centre or an explicit
 * list, and snapping to the speeds a camera offers. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/capture.h"

double sl_shutter_parse(const char *text)
{
    if (!text)
        return 0;
    while (*text == ' ')
        text++;
    double whole = 0, num = 0, den = 0;
    char tail[8] = "";
    /* "1 1/3": whole seconds and a fraction (as cameras print long exposures) */
    if (sscanf(text, "%lf %lf/%lf%7s", &whole, &num, &den, tail) >= 3 && den > 0 &&
        strchr(text, ' ') && (!tail[0] || !strcmp(tail, "s")))
        return whole + num / den;
    tail[0] = 0;
    int n = sscanf(text, "%lf/%lf%7s", &num, &den, tail);
    double v = 0;
    if (n >= 2 && strchr(text, '/')) {
        if (den <= 0 || (tail[0] && strcmp(tail, "s") != 0))
            return 0;
        v = num / den;
    } else {
        char *end;
        v = strtod(text, &end);
        if (end == text)
            return 0;
        if (*end && strcmp(end, "s") != 0 && strcmp(end, "\"") != 0 && strcmp(end, " s") != 0 &&
            strcmp(end, "sec") != 0)
            return 0;
    }
    return isfinite(v) && v > 0 ? v : 0;
}

void sl_shutter_format(double t, char *buf, size_t size)
{
    if (t <= 0 || !isfinite(t))
        snprintf(buf, size, "?");
    else if (t < 0.3) {
        double den = 1.0 / t;
        if (fabs(den - round(den)) < 0.05 * den)
            snprintf(buf, size, "1/%.0f", round(den));
        else
            snprintf(buf, size, "%.4g", t);
    } else
        snprintf(buf, size, "%.3g", t);
}

sl_result sl_bracket_plan_parse(const char *spec, double center, double **times, int *count,
                                sl_error *err)
{
    *times = NULL;
    *count = 0;
    if (!spec || !*spec)
        return sl_error_set(err, SL_ERR_USAGE, "empty bracket plan");
    int n = 0;
    double stops = 0;
    char tail;
    double *t;
    if (sscanf(spec, "%dx%lf%c", &n, &stops, &tail) == 2) {
        if (n < 1 || n > SL_BRACKET_MAX_FRAMES)
            return sl_error_set(err, SL_ERR_USAGE, "bracket %s: 1 to %d exposures, not %d", spec,
                                SL_BRACKET_MAX_FRAMES, n);
        if (!(stops > 0 && stops <= 6))
            return sl_error_set(err, SL_ERR_USAGE, "bracket %s: stops apart must be in (0, 6]",
                                spec);
        if (!(center > 0))
            return sl_error_set(err, SL_ERR_USAGE, "bracket %s needs a centre shutter speed", spec);
        t = malloc((size_t)n * sizeof *t);
        if (!t)
            return sl_error_set(err, SL_ERR_NOMEM, "bracket plan: out of memory");
        for (int i = 0; i < n; i++)
            t[i] = center * exp2(stops * (i - (n - 1) / 2.0));
    } else {
        /* explicit list */
        n = 1;
        for (const char *c = spec; *c; c++)
            n += *c == ',';
        if (n > SL_BRACKET_MAX_FRAMES)
            return sl_error_set(err, SL_ERR_USAGE, "bracket %s: more than %d exposures", spec,
                                SL_BRACKET_MAX_FRAMES);
        t = malloc((size_t)n * sizeof *t);
        char *copy = strdup(spec);
        if (!t || !copy) {
            free(t);
            free(copy);
            return sl_error_set(err, SL_ERR_NOMEM, "bracket plan: out of memory");
        }
        int k = 0;
        for (char *save = NULL, *tok = strtok_r(copy, ",", &save); tok;
             tok = strtok_r(NULL, ",", &save)) {
            double v = sl_shutter_parse(tok);
            if (!(v > 0)) {
                sl_error_set(err, SL_ERR_USAGE,
                             "bracket '%s': '%s' is not a shutter speed (use NxS or a list "
                             "such as 1/1000,1/125,1/15)",
                             spec, tok);
                free(copy);
                free(t);
                return SL_ERR_USAGE;
            }
            t[k++] = v;
        }
        free(copy);
        if (k != n) {
            free(t);
            return sl_error_set(err, SL_ERR_USAGE, "bracket '%s': empty entry in the list", spec);
        }
    }
    qsort(t, (size_t)n, sizeof *t, sl_cmp_double);
    *times = t;
    *count = n;
    return SL_OK;
}

sl_result sl_bracket_snap(double *times, int count, const double *offered, int offered_count,
                          double max_stops, double *moved_stops, sl_error *err)
{
    if (offered_count < 1)
        return sl_error_set(err, SL_ERR_CAMERA, "the camera offers no shutter speeds");
    for (int i = 0; i < count; i++) {
        int best = 0;
        double best_d = INFINITY;
        for (int j = 0; j < offered_count; j++) {
            double d = fabs(log2(offered[j] / times[i]));
            if (d < best_d) {
                best_d = d;
                best = j;
            }
        }
        if (best_d > max_stops) {
            char want[32], lo[32], hi[32];
            sl_shutter_format(times[i], want, sizeof want);
            sl_shutter_format(offered[0], lo, sizeof lo);
            sl_shutter_format(offered[offered_count - 1], hi, sizeof hi);
            return sl_error_set(err, SL_ERR_USAGE,
                                "shutter %s s is out of the camera's range (%s to %s s)", want, lo,
                                hi);
        }
        if (moved_stops)
            moved_stops[i] = log2(offered[best] / times[i]);
        times[i] = offered[best];
    }
    for (int i = 1; i < count; i++)
        if (times[i] == times[i - 1]) {
            char s[32];
            sl_shutter_format(times[i], s, sizeof s);
            return sl_error_set(err, SL_ERR_USAGE,
                                "two planned exposures snap to the same shutter speed %s s", s);
        }
    return SL_OK;
}
