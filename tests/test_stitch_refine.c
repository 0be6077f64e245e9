/* SPDX-License-Identifier: BSD-3-Clause */
/* The solve's sub-pixel refinement (solve_refine_matches) against a known
 * answer: two views of one smooth texture, view a the same as view b moved
 * by a known sub-pixel shift (and 1.7x brighter, as two exposures differ),
 * with identity poses, so the geometry predicts no shift at all. Each
 * match must be re-found at b's point plus the shift. The texture's blobs
 * are 5-15 patch samples across at each sample step, as the features' are
 * (the solve samples the patch at the features' scale). */
#include <math.h>

#include "../stitch/stitch_private.h"
#include "testing.h"

#define SIZE 256
static const double SHIFT[2] = {0.37, -0.23};

/* ln luminance of the texture at (u, v): smooth blobs about 10-30 units
 * across, nothing periodic within a patch. */
static double texture(double u, double v)
{
    return 0.4 * sin(0.21 * u + 0.5 * sin(0.05 * v)) + 0.3 * cos(0.17 * v - 0.09 * u) +
           0.2 * sin(0.11 * (u + v)) * cos(0.13 * (u - 2.0 * v));
}

/* Pixel centres at +0.5 (as sl_lens): view b sees texture point p at p,
 * view a sees it at p + SHIFT. */
static void render(sl_image *img, double gain, const double shift[2], double scale)
{
    sl_error err;
    CHECK_OK(sl_image_alloc(img, SIZE, SIZE, 3, &err), &err);
    for (int y = 0; y < SIZE; y++)
        for (int x = 0; x < SIZE; x++) {
            float l = (float)(gain * exp(texture((x + 0.5 - shift[0]) * scale, (y + 0.5 - shift[1]) * scale)));
            float *p = sl_image_pixel(img, x, y);
            p[0] = p[1] = p[2] = l;
        }
}

static void shifted_pair(double step)
{
    sl_image ia = {0}, ib = {0};
    const double none[2] = {0.0, 0.0};
    render(&ia, 1.7, SHIFT, 2.0 / step);
    render(&ib, 1.0, none, 2.0 / step);
    sl_stitch_view views[2] = {{.name = "a", .radiance = &ia}, {.name = "b", .radiance = &ib}};
    sl_lens lens;
    sl_lens_nominal(&lens, SL_LENS_EQUISOLID, SIZE, SIZE, 8.0, 36.0);
    double rot[2][3][3] = {{{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}, {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}};
    enum { N = 25 };
    solve_match m[N];
    for (int i = 0; i < N; i++) {
        /* b's point anywhere in a pixel; a's as SIFT might put it, 0.4 px off */
        double bx = 60.0 + 34.0 * (i % 5) + 0.13 * i, by = 60.0 + 34.0 * (i / 5) + 0.29 * (i % 3);
        m[i] = (solve_match){.a = 0, .b = 1, .pa = {bx + 0.4, by - 0.4}, .pb = {bx, by},
                             .inlier = true};
    }
    int refined = solve_refine_matches(views, m, N, rot, &lens, step);
    CHECK_MSG(refined == N, "step %.1f: %d of %d matches refined", step, refined, N);
    /* A point's whole error; an edge's across it (along it, by design,
     * the refinement does not move it and the adjustment ignores it). */
    double worst = 0.0;
    int edges = 0;
    for (int i = 0; i < N; i++) {
        if (!m[i].inlier)
            continue;
        double ex = m[i].pa[0] - (m[i].pb[0] + SHIFT[0]), ey = m[i].pa[1] - (m[i].pb[1] + SHIFT[1]);
        bool edge = m[i].normal[0] != 0.0 || m[i].normal[1] != 0.0;
        edges += edge;
        worst = fmax(worst, edge ? fabs(ex * m[i].normal[0] + ey * m[i].normal[1]) : hypot(ex, ey));
    }
    printf("  step %.1f px: %d of %d refined (%d edges), worst error %.4f px\n", step, refined, N,
           edges, worst);
    CHECK_MSG(edges <= N / 5, "step %.1f: %d of %d patches taken for edges", step, edges, N);
    CHECK_MSG(worst < 0.05, "step %.1f: a match %.4f px from the known shift", step, worst);
    sl_image_free(&ia);
    sl_image_free(&ib);
}

static void known_shift(void)
{
    shifted_pair(1.0);
    shifted_pair(2.0); /* features found on a copy reduced 2x */
}

int main(void)
{
    RUN(known_shift);
    return sl_test_finish();
}
