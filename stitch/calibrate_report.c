/* SPDX-License-Identifier: BSD-3-Clause */
/* The calibration's report section. */
#include <math.h>
#include <stdio.h>

#include "setlight/render.h"
#include "setlight/stitch.h"

sl_result sl_calibrate_report(sl_report *rep, const char *prefix, const sl_chart_patch *patches,
                              const sl_ccm_fit *chart, const sl_grey_fit *grey, sl_error *err)
{
    sl_report_section(rep, "Calibration");
    if (patches && chart) {
        double before[24], after[24];
        const char *why[24];
        char excluded[1024] = "";
        size_t len = 0;
        for (int p = 0; p < 24; p++) {
            before[p] = chart->de_before[p] < 0 ? NAN : chart->de_before[p];
            after[p] = chart->de_after[p] < 0 ? NAN : chart->de_after[p];
            why[p] = chart->used_patch[p] ? NULL
                     : chart->outlier[p]  ? "lit differently from the rest (outlier)"
                     : !patches[p].valid  ? "clipped or not uniform in the photo"
                                          : "left out of the fit";
            if (why[p] && len < sizeof excluded)
                len += (size_t)snprintf(excluded + len, sizeof excluded - len, "%s%s: %s",
                                        len ? "; " : " Excluded: ", SL_COLORCHECKER_NAMES[p],
                                        why[p]);
        }
        if (len && len < sizeof excluded)
            snprintf(excluded + len, sizeof excluded - len, ".");
        sl_report_text(rep,
                       "Chart: %d of 24 patches in the colour fit. CIEDE2000 mean %.2f (max %.2f) "
                       "before, %.2f (max %.2f) after.%s",
                       chart->used, chart->de_before_mean, chart->de_before_max,
                       chart->de_after_mean, chart->de_after_max, excluded);
        sl_report_text(rep, "Matrix (working RGB = M camera RGB): [%.5f %.5f %.5f; %.5f %.5f %.5f; "
                            "%.5f %.5f %.5f], gain %.5f.",
                       chart->m[0][0], chart->m[0][1], chart->m[0][2], chart->m[1][0],
                       chart->m[1][1], chart->m[1][2], chart->m[2][0], chart->m[2][1],
                       chart->m[2][2], chart->gain);
        /* ΔE per patch as bars, each excluded patch marked with why. */
        const sl_bar_series bars[2] = {{"before", before}, {"after the matrix", after}};
        char bars_file[256];
        snprintf(bars_file, sizeof bars_file, "%sdelta_e.svg", prefix);
        sl_result rb = sl_report_bars(rep, bars_file, "CIEDE2000 per patch", "ΔE00",
                                      SL_COLORCHECKER_NAMES, why, 24, bars, 2, err);
        if (rb)
            return rb;
        static const char *const head[] = {"patch", "name", "pixels", "clipped",
                                           "used", "ΔE before", "ΔE after"};
        sl_report_table_begin(rep, 7, head);
        for (int p = 0; p < 24; p++) {
            char c[5][32];
            snprintf(c[0], sizeof c[0], "%d", p + 1);
            snprintf(c[1], sizeof c[1], "%d", patches[p].pixels);
            snprintf(c[2], sizeof c[2], "%d", patches[p].clipped);
            snprintf(c[3], sizeof c[3], "%.2f", chart->de_before[p]);
            snprintf(c[4], sizeof c[4], "%.2f", chart->de_after[p]);
            const char *row[] = {c[0], SL_COLORCHECKER_NAMES[p], c[1], c[2],
                                 chart->used_patch[p] ? "yes"
                                 : chart->outlier[p]  ? "outlier (lit differently)"
                                 : !patches[p].valid  ? "excluded (clipped or non-uniform)"
                                                      : "excluded",
                                 chart->de_before[p] < 0 ? "-" : c[3],
                                 chart->de_after[p] < 0 ? "-" : c[4]};
            sl_report_table_row(rep, row);
        }
        sl_report_table_end(rep);
    }
    if (grey) {
        sl_report_text(rep,
                       "Grey sphere: gains %.4f %.4f %.4f (exposure scale %.4f, balance %.4f "
                       "%.4f %.4f); relative RMSE over %lld pixels %.2f%% with exposure only, "
                       "%.2f%% calibrated; 95%% of pixels within %.2f%%.",
                       grey->gain[0], grey->gain[1], grey->gain[2], grey->scale,
                       grey->balance[0], grey->balance[1], grey->balance[2],
                       (long long)grey->pixels, 100 * grey->rel_rmse_before,
                       100 * grey->rel_rmse_after, 100 * grey->error_p95);
        /* Shown at a common exposure: the photo's mean to mid grey. */
        double lsum = 0;
        int64_t n = 0;
        for (int y = 0; y < grey->photo.height; y++)
            for (int x = 0; x < grey->photo.width; x++) {
                const float *v = grey->photo.data + (size_t)y * grey->photo.stride + (size_t)x * 4;
                if (v[3] > 0) {
                    lsum += sl_luminance_px(v);
                    n++;
                }
            }
        double stops = n && lsum > 0 ? log2(0.18 * (double)n / lsum) : 0;
        char file[256];
        sl_result r;
        snprintf(file, sizeof file, "%sgrey_photo.png", prefix);
        if ((r = sl_report_image(rep, file, &grey->photo, stops, "grey sphere photo (used pixels)",
                                 err)))
            return r;
        snprintf(file, sizeof file, "%sgrey_render.png", prefix);
        if ((r = sl_report_image(rep, file, &grey->render, stops,
                                 "virtual grey sphere under the calibrated HDRI", err)))
            return r;
        /* Relative error from -10% (black) to +10% (white), 0 at half scale. */
        sl_image e = {0};
        if ((r = sl_image_alloc(&e, grey->error.width, grey->error.height, 3, err)))
            return r;
        for (int y = 0; y < e.height; y++)
            for (int x = 0; x < e.width; x++) {
                const float *v = grey->error.data + (size_t)y * grey->error.stride + (size_t)x * 4;
                float *o = e.data + (size_t)y * e.stride + (size_t)x * 3;
                for (int c = 0; c < 3; c++)
                    o[c] = v[3] > 0 ? (float)fmin(fmax((0.1 + v[c]) / 0.2, 0), 1) : 0.0f;
            }
        snprintf(file, sizeof file, "%sgrey_error.png", prefix);
        r = sl_report_image(rep, file, &e, 0,
                            "(render - photo) / photo: black -10%, half scale 0, white +10%",
                            err);
        sl_image_free(&e);
        if (r)
            return r;
    }
    return SL_OK;
}
