/* SPDX-License-Identifier: BSD-3-Clause */
/* The optical centre from the image circles. A circular fisheye's image
 * circle is its field stop, centred on its optical axis, so the circle's
 * centre measures the optical centre apart from the overlaps, which pin it
 * poorly: a shift of the centre is nearly a tilt of every view, and with
 * view 0 held the two trade (docs/stitch.md, "Solve"). */
#include "stitch_private.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A circle fit's centre is known to at least this (px, per axis): the
 * rendered views' circles are within 0.015 px of the true centre where the
 * rim is a clean step (test_stitch_circle), and its 720 edge points alone
 * would claim 0.004 px. */
#define CIRCLE_SIGMA_FLOOR 0.02
/* A view whose circle is further than this many of its standard
 * deviations from the views' median is left out: scene structure on its
 * rim (a panel's edge along it) has moved its fit. */
#define CIRCLE_OUTLIER_SIGMAS 4.0
/* Chi-square of 2 degrees of freedom at 99.9%: the overlaps' centre and
 * the circles' disagree beyond chance, so the circle is not centred on the
 * axis (a decentred lens) or not the lens's. */
#define CENTRE_AGREE_CHI2 13.8
/* The overlaps' centre is known to no better than this (px, per axis),
 * whatever their covariance claims: it trades with the views' tilts (a
 * shift of the centre is nearly a tilt of every view), a bias the
 * residuals do not show. Measured: 0.15 px off at a claimed 0.06 px on the
 * stage with 3 views, 0.23 px at 0.035 px with a zenith (docs/stitch.md,
 * "Accuracy of the solved stitch"). */
#define OVERLAP_CENTRE_SIGMA_FLOOR 0.1

void solve_centre_note(sl_stitch_solve_result *res, const char *fmt, ...)
{
    size_t used = strlen(res->centre_note);
    if (used + 3 >= sizeof res->centre_note)
        return;
    if (used)
        used += (size_t)snprintf(res->centre_note + used, sizeof res->centre_note - used, "; ");
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(res->centre_note + used, sizeof res->centre_note - used, fmt, ap);
    va_end(ap);
}

static int compare_double(const void *a, const void *b)
{
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

bool solve_centre_from_circles(const sl_stitch_view *views, int count,
                               const sl_stitch_solve_options *opt, solve_centre_prior *prior,
                               sl_stitch_solve_result *res)
{
    const sl_lens *lens = &views[0].lens;
    if (lens->projection == SL_LENS_RECTILINEAR || !(lens->circle_radius_px > 0.0) ||
        count > SL_STITCH_MAX_VIEWS)
        return false;
    double cx[SL_STITCH_MAX_VIEWS], cy[SL_STITCH_MAX_VIEWS], sigma[SL_STITCH_MAX_VIEWS];
    int found = 0, index[SL_STITCH_MAX_VIEWS];
    for (int v = 0; v < count; v++) {
        sl_stitch_circle c;
        sl_error err;
        if (opt->circles)
            c = opt->circles[v];
        else if (sl_stitch_circle_find(views[v].radiance, views[v].name, NULL, &c, &err) != SL_OK)
            continue;
        if (!(c.radius > 0.0) || c.edges < 8)
            continue;
        cx[found] = c.cx;
        cy[found] = c.cy;
        sigma[found] = fmax(CIRCLE_SIGMA_FLOOR, c.rms_px * sqrt(2.0 / c.edges));
        index[found++] = v;
    }
    if (found == 0) {
        solve_centre_note(res, "no image circle found: the centre from the overlaps alone");
        return false;
    }
    double sorted[SL_STITCH_MAX_VIEWS], mx, my;
    memcpy(sorted, cx, (size_t)found * sizeof *sorted);
    qsort(sorted, (size_t)found, sizeof *sorted, compare_double);
    mx = found % 2 ? sorted[found / 2] : 0.5 * (sorted[found / 2 - 1] + sorted[found / 2]);
    memcpy(sorted, cy, (size_t)found * sizeof *sorted);
    qsort(sorted, (size_t)found, sizeof *sorted, compare_double);
    my = found % 2 ? sorted[found / 2] : 0.5 * (sorted[found / 2 - 1] + sorted[found / 2]);
    bool keep[SL_STITCH_MAX_VIEWS];
    int kept = 0;
    for (int i = 0; i < found; i++) {
        keep[i] = found < 3 || hypot(cx[i] - mx, cy[i] - my) <= CIRCLE_OUTLIER_SIGMAS * sigma[i];
        kept += keep[i];
    }
    for (int i = 0; i < found && kept == 0; i++)
        keep[i] = true, kept++;
    for (int i = 0; i < found; i++)
        if (!keep[i])
            solve_centre_note(res, "%s's circle is %.0f sigma from the views' median: left out",
                              views[index[i]].name ? views[index[i]].name : "a view",
                              hypot(cx[i] - mx, cy[i] - my) / sigma[i]);
    /* Inverse-variance mean, its spread widened by the scatter of the
     * views' centres beyond their own uncertainty. */
    double sw = 0, sx = 0, sy = 0, chi2 = 0;
    for (int i = 0; i < found; i++)
        if (keep[i]) {
            double w = 1.0 / (sigma[i] * sigma[i]);
            sw += w;
            sx += w * cx[i];
            sy += w * cy[i];
        }
    prior->cx = sx / sw;
    prior->cy = sy / sw;
    for (int i = 0; i < found; i++)
        if (keep[i])
            chi2 += (pow(cx[i] - prior->cx, 2) + pow(cy[i] - prior->cy, 2)) / (sigma[i] * sigma[i]);
    double widen = kept > 1 ? fmax(1.0, sqrt(chi2 / (2.0 * (kept - 1)))) : 1.0;
    prior->sigma_x = prior->sigma_y = widen / sqrt(sw);
    res->circle_views = kept;
    res->circle_centre[0] = prior->cx;
    res->circle_centre[1] = prior->cy;
    res->circle_sigma[0] = prior->sigma_x;
    res->circle_sigma[1] = prior->sigma_y;
    return true;
}

bool solve_centre_agrees(const solve_centre_prior *prior, const sl_lens *overlaps,
                         const double cov[3], sl_stitch_solve_result *res)
{
    res->overlap_centre[0] = overlaps->cx;
    res->overlap_centre[1] = overlaps->cy;
    res->overlap_sigma[0] = sqrt(fmax(0.0, cov[0]));
    res->overlap_sigma[1] = sqrt(fmax(0.0, cov[2]));
    double floor2 = OVERLAP_CENTRE_SIGMA_FLOOR * OVERLAP_CENTRE_SIGMA_FLOOR;
    double a = fmax(cov[0], floor2) + prior->sigma_x * prior->sigma_x, b = cov[1],
           c = fmax(cov[2], floor2) + prior->sigma_y * prior->sigma_y, det = a * c - b * b;
    double dx = overlaps->cx - prior->cx, dy = overlaps->cy - prior->cy;
    double chi2 = det > 0.0 ? (c * dx * dx - 2.0 * b * dx * dy + a * dy * dy) / det : HUGE_VAL;
    bool agree = chi2 <= CENTRE_AGREE_CHI2;
    solve_centre_note(res,
                      agree ? "centre from the image circles (%d views) and the overlaps (%.1f "
                              "sigma apart)"
                            : "the image circles' centre (%d views) is %.1f sigma from the "
                              "overlaps': not used, the centre from the overlaps alone",
                      res->circle_views, sqrt(chi2));
    return agree;
}
