/* SPDX-License-Identifier: BSD-3-Clause */
/* How the stitch holds its views (stitch/stitch_hold.c) and what the blend
 * does with them: a view kept as half only when every sample converts
 * exactly, the blend of half views the same bytes as of the float views,
 * the solve's reduction factor, and the per-row spans of the views' fields
 * never losing a direction a view sees (the seen solid angle of one view is
 * its field's, wherever it points). */
#include "testing.h"

#include "../stitch/stitch_blend_private.h"

#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#ifndef M_PI
#define M_PI 3.14159265358979323846
#endif

static double uniform(uint64_t *s)
{
    *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
    return (double)(*s >> 11) / 9007199254740992.0;
}

/* Radiance over 1e-3..1e3 with hard steps (hot texels), every sample a
 * half value (as merge writes them): each is the table's value of a
 * random half pattern in that range. */
static void half_valued(sl_image *img, uint64_t seed)
{
    const float *table = stitch_half_table();
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            float *p = sl_image_pixel(img, x, y);
            bool lamp = ((x / 37) + (y / 23)) % 5 == 0;
            for (int c = 0; c < 3; c++) {
                /* halves 0x1400 (~1e-3) .. 0x6000 (~512) */
                uint16_t h = (uint16_t)(0x1400 + (int)(uniform(&seed) * (0x6000 - 0x1400)));
                p[c] = table[lamp ? h | 0x0800 : h];
            }
        }
}

static void half_only_when_exact(void)
{
    sl_error err;
    sl_image img;
    CHECK_OK(sl_image_alloc(&img, 97, 13, 3, &err), &err); /* odd width: F16C's tail too */
    half_valued(&img, 3);
    stitch_half_image h;
    CHECK(stitch_view_to_half(&img, &h, &err));
    const float *table = stitch_half_table();
    int same = 0;
    for (int y = 0; h.rgb && y < img.height; y++)
        for (int x = 0; x < img.width; x++)
            for (int c = 0; c < 3; c++)
                same += table[h.rgb[((size_t)y * img.width + x) * 3 + c]] ==
                        sl_image_pixel(&img, x, y)[c];
    CHECK_MSG(same == 97 * 13 * 3, "%d of %d samples kept", same, 97 * 13 * 3);
    stitch_half_free(&h);
    /* one sample half cannot hold, at the tail or in the vector body */
    const float odd[] = {0.1f, 70000.0f, 1e-9f, 1.0f + 1.0f / 4096.0f};
    for (size_t k = 0; k < sizeof odd / sizeof *odd; k++) {
        half_valued(&img, 3);
        int x = k % 2 ? 96 : 5;
        sl_image_pixel(&img, x, 7)[k % 3] = odd[k];
        CHECK_MSG(!stitch_view_to_half(&img, &h, &err), "%g was taken as half", odd[k]);
        CHECK(h.rgb == NULL);
    }
    sl_image_free(&img);
}

static void solve_factor(void)
{
    CHECK(stitch_solve_factor(6000, 4000, 3072) == 2);
    CHECK(stitch_solve_factor(12000, 8000, 3072) == 4);
    CHECK(stitch_solve_factor(3072, 2048, 3072) == 1); /* small enough */
    CHECK(stitch_solve_factor(6001, 4000, 3072) == 1); /* 2 does not divide it: full size */
    CHECK(stitch_solve_factor(6000, 4001, 3072) == 1);
    sl_lens lens;
    sl_lens_nominal(&lens, SL_LENS_EQUISOLID, 6000, 4000, 8.0, 36.0);
    lens.cx += 3.7;
    sl_lens back = lens;
    stitch_lens_scale(&back, 0.5, 3000, 2000);
    CHECK(back.width == 3000 && back.focal_px == 0.5 * lens.focal_px);
    stitch_lens_scale(&back, 2.0, 6000, 4000);
    CHECK(!memcmp(&back, &lens, sizeof lens)); /* there and back exactly */
}

static void blend_of_half_is_blend_of_float(void)
{
    sl_error err;
    sl_image img[3];
    stitch_half_image half[3];
    sl_stitch_view v[3];
    for (int i = 0; i < 3; i++) {
        CHECK_OK(sl_image_alloc(&img[i], 360, 240, 3, &err), &err);
        half_valued(&img[i], 11 + (uint64_t)i);
        CHECK(stitch_view_to_half(&img[i], &half[i], &err));
        sl_lens lens;
        sl_lens_nominal(&lens, SL_LENS_EQUISOLID, 360, 240, 8.0, 36.0);
        lens.k[0] = 0.02;
        lens.vignette[0] = -0.2;
        lens.circle_radius_px = sl_lens_radius(&lens, M_PI / 2);
        v[i] = (sl_stitch_view){"view", &img[i], NULL, lens, {120.0 * i, 10.0 * i, -5.0 * i}};
    }
    sl_stitch_blend_options opt;
    sl_stitch_blend_options_init(&opt);
    opt.width = 512;
    sl_image from_float = {0}, from_half = {0};
    sl_stitch_coverage cf, ch;
    CHECK_OK(stitch_blend_run(v, 3, NULL, false, &opt, NULL, NULL, &from_float, &cf, &err), &err);
    sl_stitch_view only_half[3]; /* no float image: the half one is what is read */
    for (int i = 0; i < 3; i++) {
        only_half[i] = v[i];
        only_half[i].radiance = NULL;
    }
    CHECK_OK(stitch_blend_run(only_half, 3, half, true, &opt, NULL, NULL, &from_half, &ch, &err),
             &err);
    CHECK_MSG(cf.hot_texels > 1000, "%lld texels sampled finely: the edges are not tested",
              (long long)cf.hot_texels);
    CHECK(cf.hot_texels == ch.hot_texels && cf.ghost_texels == ch.ghost_texels);
    size_t bytes = (size_t)from_float.height * from_float.stride * sizeof(float);
    CHECK(from_half.data && !memcmp(from_float.data, from_half.data, bytes));
    sl_image_free(&from_float);
    sl_image_free(&from_half);
    for (int i = 0; i < 3; i++) {
        stitch_half_free(&half[i]);
        sl_image_free(&img[i]);
    }
}

/* One view of a 60-degree field, pointed anywhere (up to the pole, across
 * the longitude seam): every texel whose centre is inside its field (less
 * a tenth of a degree, where the edge ramp is still above 0) is seen,
 * every texel a tenth of a degree beyond it is not: a row span cut short would leave
 * seen texels unseen. */
static void spans_lose_nothing(void)
{
    sl_error err;
    sl_image img;
    CHECK_OK(sl_image_alloc(&img, 400, 400, 3, &err), &err);
    sl_image_fill(&img, 1.0f);
    static const sl_view_pose poses[] = {{0, 0, 0},    {179.5, 0, 0}, {-179.5, 20, 0},
                                         {30, 50, 10}, {90, 89, 0},   {200, -75, 0}};
    for (size_t k = 0; k < sizeof poses / sizeof *poses; k++) {
        sl_lens lens;
        sl_lens_nominal(&lens, SL_LENS_EQUISOLID, 400, 400, 8.0, 24.0);
        lens.max_theta_deg = 60.0;
        lens.circle_radius_px = sl_lens_radius(&lens, M_PI / 3);
        sl_stitch_view v = {"view", &img, NULL, lens, poses[k]};
        sl_stitch_blend_options opt;
        sl_stitch_blend_options_init(&opt);
        opt.width = 720;
        opt.supersample = 1; /* one sample, at the texel's centre */
        sl_image out = {0};
        sl_stitch_coverage cov;
        CHECK_OK(sl_stitch_blend(&v, 1, &opt, &out, &cov, &err), &err);
        double m[3][3];
        sl_view_pose_matrix(&poses[k], m);
        int lost = 0, extra = 0, inside = 0;
        for (int y = 0; out.data && y < out.height; y++)
            for (int x = 0; x < out.width; x++) {
                double lon = M_PI * (1.0 - 2.0 * (x + 0.5) / out.width);
                double lat = M_PI * (0.5 - (y + 0.5) / out.height);
                double d[3] = {sin(lon) * cos(lat), sin(lat), cos(lon) * cos(lat)};
                double theta = acos(fmin(1.0, d[0] * m[0][2] + d[1] * m[1][2] + d[2] * m[2][2]));
                bool seen = sl_image_pixel(&out, x, y)[3] > 0.0f;
                inside += theta < 59.9 * M_PI / 180;
                lost += theta < 59.9 * M_PI / 180 && !seen;
                extra += theta > 60.1 * M_PI / 180 && seen;
            }
        CHECK_MSG(lost == 0 && extra == 0 && inside > 10000,
                  "pose %zu: %d texels inside the field unseen, %d outside seen (of %d)", k, lost,
                  extra, inside);
        sl_image_free(&out);
    }
    sl_image_free(&img);
}

int main(void)
{
    RUN(half_only_when_exact);
    RUN(solve_factor);
    RUN(blend_of_half_is_blend_of_float);
    RUN(spans_lose_nothing);
    return sl_test_finish();
}
