/* SPDX-License-Identifier: BSD-3-Clause */
/* How far to trust the response a merge used: is it increasing, and do the
 * bracket's frames, linearised through it and divided by their exposures,
 * agree on the radiance of the same pixel? A curve bent away from the
 * camera's makes the frames disagree by the bend (a stop's step of the
 * curve shows as the frames' spread); a curve that fits leaves the noise. */
#include "merge_private.h"

#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Frames agree within this (RMS, stops) on a plausible curve: 16-bit and
 * raw frames of the virtual set agree within 0.01 stops, JPEG brackets of
 * real cameras within about 0.05 (docs/merge.md). */
#define AGREE_RMS_STOPS 0.15
#define MIN_CODE 0.1

void merge_judge_response(const merge_ctx *m, sl_merge_result *res, bool recovered)
{
    sl_merge_response_check *j = &res->response_check;
    memset(j, 0, sizeof *j);
    const sl_response *resp = &res->response;
    j->monotone = true;
    for (int c = 0; c < resp->channels; c++)
        for (int k = 1; k < resp->nodes; k++)
            j->monotone = j->monotone &&
                          resp->inverse[c * resp->nodes + k] >= resp->inverse[c * resp->nodes + k - 1];
    const merge_samples *s = &m->samples;
    int f = s->frames;
    double *dev = s->count > 0 && f > 1 ? malloc((size_t)s->count * f * 3 * sizeof *dev) : NULL;
    size_t n = 0;
    merge_code_curve curve;
    merge_code_curve_init(&curve, s, resp);
    double loge[MERGE_MAX_FRAMES];
    for (int r = 0; r < f; r++)
        loge[r] = log(res->frames[m->order[r]].exposure);
    for (int i = 0; dev && i < s->count; i++)
        for (int c = 0; c < 3; c++) {
            /* Frames well inside the curve (not near black or the shoulder):
             * their log radiance and its mean. */
            double lx[MERGE_MAX_FRAMES];
            int used = 0;
            double sum = 0;
            for (int r = 0; r < f; r++) {
                float z = s->z[((size_t)i * f + r) * 3 + c];
                /* Codes above 10% of the range: the noise of a dark frame
                 * or a hot pixel is not the curve's error. */
                if (!merge_usable(s, i, r, m->saturation) || !(z > MIN_CODE))
                    continue;
                int k = merge_code_of(&curve, z);
                double y = k >= 0 ? curve.y[c][k] : merge_response_at(resp, c, z);
                if (!(y > 0))
                    continue;
                lx[used] = (k >= 0 ? curve.log_y[c][k] : log(y)) - loge[r];
                sum += lx[used++];
            }
            if (used < 2)
                continue;
            for (int k = 0; k < used; k++)
                dev[n++] = (lx[k] - sum / used) / log(2) * sqrt((double)used / (used - 1));
        }
    if (n > 0) {
        double ss = 0;
        for (size_t k = 0; k < n; k++) {
            ss += dev[k] * dev[k];
            dev[k] = fabs(dev[k]);
        }
        /* The 90th percentile by selection: sorting a million deviations
         * was a fifth of a small bracket's fit. */
        size_t k = (size_t)(0.9 * (n - 1));
        if (n <= INT_MAX)
            j->frame_p90_stops = merge_select_kth(dev, (int)n, (int)k);
        else {
            qsort(dev, n, sizeof *dev, sl_cmp_double);
            j->frame_p90_stops = dev[k];
        }
        j->frame_rms_stops = sqrt(ss / n);
        j->compared = (int64_t)n;
    }
    free(dev);
    j->plausible = j->monotone && j->frame_rms_stops <= AGREE_RMS_STOPS &&
                   (j->compared > 0 || !recovered);
    if (!j->monotone)
        snprintf(j->note, sizeof j->note, "the response falls somewhere: not a camera's");
    else if (!j->compared)
        snprintf(j->note, sizeof j->note,
                 "no pixel well exposed in two frames: %s",
                 recovered ? "a curve fitted to such a bracket is a guess" : "not checked");
    else if (!j->plausible)
        snprintf(j->note, sizeof j->note,
                 "the frames disagree by %.3f stops RMS through the response (at most %.2f "
                 "expected): the curve or the exposures are wrong by about that",
                 j->frame_rms_stops, AGREE_RMS_STOPS);
    else
        snprintf(j->note, sizeof j->note, "the frames agree within %.3f stops RMS",
                 j->frame_rms_stops);
}
