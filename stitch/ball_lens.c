/* SPDX-License-Identifier: BSD-3-Clause */
/* A ball photo's camera as the user states it, to pixels and radii. */
#include <math.h>
#include <string.h>

#include "setlight/stitch.h"

void sl_ball_lens_init(sl_ball_lens *lens)
{
    memset(lens, 0, sizeof *lens);
    lens->camera = -1;
}

void sl_ball_lens_geometry(const sl_ball_lens *lens, int width, double exif_focal_mm,
                           double *focal_px, double *distance)
{
    double fmm = lens->focal_mm > 0 || lens->sensor_mm == 0 ? lens->focal_mm : exif_focal_mm;
    *focal_px = 0;
    if (fmm > 0 && lens->sensor_mm > 0)
        *focal_px = fmm * width / lens->sensor_mm;
    else if (lens->fov_deg > 0)
        *focal_px = 0.5 * width / tan(0.5 * lens->fov_deg * M_PI / 180.0);
    *distance = lens->distance_mm > 0 ? lens->distance_mm / (0.5 * lens->diameter_mm) : 0;
}
