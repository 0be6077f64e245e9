/* SPDX-License-Identifier: BSD-3-Clause */
/* The blend's lens table (stitch_view_pixel: q(u) = r^2 / u, one sqrt a
 * lookup) against the lens model itself (sl_lens_ray_to_pixel), for every
 * projection with a radial correction and an off-centre optical axis: the
 * same pixel to a thousandth of a pixel, the same rays refused. */
#include "testing.h"

#include "../stitch/stitch_blend_private.h" /* stitch_prepare_views, stitch_view_pixel */

#include <math.h>
#include <stdint.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static double uniform(uint64_t *s)
{
    *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(*s >> 11) / 9007199254740992.0;
}

static void table_matches_lens(void)
{
    static const sl_lens_projection proj[] = {SL_LENS_EQUISOLID, SL_LENS_EQUIDISTANT,
                                              SL_LENS_STEREOGRAPHIC, SL_LENS_ORTHOGRAPHIC,
                                              SL_LENS_RECTILINEAR};
    sl_image img;
    sl_error err;
    CHECK_OK(sl_image_alloc(&img, 1200, 800, 3, &err), &err);
    for (size_t k = 0; k < sizeof proj / sizeof *proj; k++) {
        sl_lens lens;
        bool rect = proj[k] == SL_LENS_RECTILINEAR;
        sl_lens_nominal(&lens, proj[k], 1200, 800, rect ? 24.0 : 8.0, 36.0);
        lens.cx += 7.3;
        lens.cy -= 4.1;
        lens.k[0] = rect ? -0.05 : 0.02;
        lens.k[1] = rect ? 0.01 : -0.01;
        lens.vignette[0] = -0.1;
        if (!rect)
            lens.circle_radius_px = 0.98 * sl_lens_radius(&lens, lens.max_theta_deg * M_PI / 180);
        sl_stitch_view view = {"view", &img, NULL, lens, {0, 0, 0}};
        sl_stitch_blend_options opt;
        sl_stitch_blend_options_init(&opt);
        stitch_view_prep prep;
        memset(&prep, 0, sizeof prep);
        CHECK_OK(stitch_prepare_views(&view, 1, &opt, NULL, false, &prep, &err), &err);
        uint64_t seed = 7 + k;
        double worst = 0.0;
        int disagree = 0, seen = 0;
        for (int i = 0; i < 200000 && prep.q_table; i++) {
            /* uniform on the sphere */
            double z = 2.0 * uniform(&seed) - 1.0, phi = 2.0 * M_PI * uniform(&seed);
            double s = sqrt(1.0 - z * z), ray[3] = {s * cos(phi), s * sin(phi), z};
            double x0, y0, x1, y1, r2;
            bool a = sl_lens_ray_to_pixel(&lens, ray, &x0, &y0);
            bool b = stitch_view_pixel(&prep, ray, &x1, &y1, &r2);
            if (a != b) {
                disagree++;
                continue;
            }
            if (!a)
                continue;
            seen++;
            worst = fmax(worst, hypot(x1 - x0, y1 - y0));
            double g = sl_lens_vignette(&lens, x0, y0), s2 = r2 / (lens.focal_px * lens.focal_px);
            worst = fmax(worst, 1e3 * fabs(1.0 + s2 * lens.vignette[0] - g));
        }
        stitch_release_views(&prep, 1);
        printf("  %s: %d rays seen, worst %.2e px, %d on the field's edge disagree\n",
               sl_lens_projection_name(proj[k]), seen, worst, disagree);
        CHECK(seen > 10000);
        CHECK_MSG(worst < 1e-3, "%s: %.2e px", sl_lens_projection_name(proj[k]), worst);
        /* only rays within rounding of the circle or the field's edge */
        CHECK(disagree < 5);
    }
    sl_image_free(&img);
}

int main(void)
{
    RUN(table_matches_lens);
    return sl_test_finish();
}
