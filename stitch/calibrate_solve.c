/* SPDX-License-Identifier: BSD-3-Clause */
#include <math.h>

#include "calibrate_internal.h"

bool sl_cal_solve(double *a, double *b, int n)
{
    double scale = 0;
    for (int i = 0; i < n * n; i++)
        scale = fmax(scale, fabs(a[i]));
    if (!(scale > 0))
        return false;
    for (int k = 0; k < n; k++) {
        int p = k;
        for (int i = k + 1; i < n; i++)
            if (fabs(a[i * n + k]) > fabs(a[p * n + k]))
                p = i;
        if (!(fabs(a[p * n + k]) > 1e-14 * scale))
            return false;
        if (p != k) {
            for (int j = 0; j < n; j++) {
                double t = a[k * n + j];
                a[k * n + j] = a[p * n + j];
                a[p * n + j] = t;
            }
            double t = b[k];
            b[k] = b[p];
            b[p] = t;
        }
        for (int i = k + 1; i < n; i++) {
            double f = a[i * n + k] / a[k * n + k];
            for (int j = k; j < n; j++)
                a[i * n + j] -= f * a[k * n + j];
            b[i] -= f * b[k];
        }
    }
    for (int i = n - 1; i >= 0; i--) {
        double s = b[i];
        for (int j = i + 1; j < n; j++)
            s -= a[i * n + j] * b[j];
        b[i] = s / a[i * n + i];
    }
    return true;
}

double sl_exposure_luminance(double time_s, double f_number, double iso)
{
    if (!(time_s > 0 && f_number > 0 && iso > 0) || !isfinite(time_s * f_number * iso))
        return 0;
    /* ISO 12232 saturation-based speed: a focal-plane exposure of 78 / S
     * lux s saturates; H = q L t / N^2 with q = 0.65. */
    return 78.0 * f_number * f_number / (0.65 * iso * time_s);
}

int64_t sl_calibrate_clamp_negative(sl_image *img, double *fraction)
{
    int64_t count = 0;
    double negative = 0, total = 0;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            float *v = sl_image_pixel(img, x, y);
            for (int c = 0; c < 3 && c < img->channels; c++) {
                total += fabs((double)v[c]);
                if (v[c] < 0) {
                    negative -= v[c];
                    v[c] = 0;
                    count++;
                }
            }
        }
    if (fraction)
        *fraction = total > 0 ? negative / total : 0;
    return count;
}
