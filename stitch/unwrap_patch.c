/* SPDX-License-Identifier: BSD-3-Clause */
/* The ball's reflectance from a patch of the set whose radiance is known
 * (a grey card or a light panel measured with a spot meter, or a region of
 * a directly shot HDRI): what the ball shows there over what is there. */
#include "setlight/stitch.h"

#include <math.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

sl_result sl_unwrap_patch_reflectance(const sl_image *ll, const double dir[3],
                                      double radius_rad, const double radiance[3],
                                      double reflectance[3], sl_error *err)
{
    for (int k = 0; k < 3; k++)
        reflectance[k] = 0.0;
    if (!ll || !ll->data || ll->channels != 4 || ll->width != 2 * ll->height)
        return sl_error_set(err, SL_ERR_USAGE,
                            "reflectance patch: needs an unwrapped lat-long with confidence");
    double n = sqrt(dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]);
    if (!(n > 0.0) || !(radius_rad > 0.0 && radius_rad < M_PI / 2) ||
        !(radiance[0] > 0.0 && radiance[1] > 0.0 && radiance[2] > 0.0 && isfinite(radiance[0]) &&
          isfinite(radiance[1]) && isfinite(radiance[2])))
        return sl_error_set(err, SL_ERR_USAGE,
                            "reflectance patch: needs a direction, a radius below 90 deg and a "
                            "positive radiance");
    double d[3] = {dir[0] / n, dir[1] / n, dir[2] / n}, cosr = cos(radius_rad);
    int w = ll->width, h = ll->height;
    double sum[3] = {0, 0, 0}, seen = 0.0, all = 0.0;
    for (int y = 0; y < h; y++) {
        double dw = sl_latlong_texel_solid_angle(y, w, h);
        for (int x = 0; x < w; x++) {
            double t[3];
            sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / h, t);
            if (t[0] * d[0] + t[1] * d[1] + t[2] * d[2] < cosr)
                continue;
            const float *p = sl_image_pixel(ll, x, y);
            all += dw;
            if (p[3] < 0.25f)
                continue;
            seen += dw;
            for (int k = 0; k < 3; k++)
                sum[k] += dw * p[k];
        }
    }
    if (!(all > 0.0))
        return sl_error_set(err, SL_ERR_USAGE,
                            "reflectance patch: %.3g deg is smaller than a texel of the %dx%d "
                            "lat-long", radius_rad * 180.0 / M_PI, w, h);
    if (seen < 0.9 * all)
        return sl_error_set(err, SL_ERR_INPUT,
                            "reflectance patch: only %.0f%% of it is seen with confidence by the "
                            "ball (it lies behind the ball or near the rim)", 100.0 * seen / all);
    for (int k = 0; k < 3; k++) {
        reflectance[k] = sum[k] / seen / radiance[k];
        if (!(reflectance[k] > 0.0) || !isfinite(reflectance[k])) {
            for (int j = 0; j < 3; j++)
                reflectance[j] = 0.0;
            return sl_error_set(err, SL_ERR_INPUT,
                                "reflectance patch: the ball shows no light there");
        }
    }
    return SL_OK;
}
