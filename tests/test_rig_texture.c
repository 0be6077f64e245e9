/* SPDX-License-Identifier: BSD-3-Clause */
/* Issue 8's textured rects, a known answer: a map whose only light is a
 * tinted rectangle with a bright corner. Extracted with --textures and read
 * back by the renderer, the rig's radiance seen from the capture point along
 * every map texel inside the rectangle must be the map's (less the residual
 * dome under it), and grey and glossy spheres must render as under the map. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "../render/scene_internal.h"
#include "rig_scenes.h"
#include "setlight/render.h"
#include "testing.h"

static const double TINT[3] = {1.0, 0.7, 0.4};
static const double A = 0.45, B = 0.25; /* half-sides in tangent units */

/* Emission at rect coordinates (x, y) in [-1, 1]: a bright +u+v corner. */
static double shade(double x, double y)
{
    double s = 0.5 * (1 + x), t = 0.5 * (1 + y);
    return 8 + 60 * s * s * s * t * t;
}

/* Paints the rectangle (centre d, axes u and v = d x u) with sub-texel
 * coverage; *edge is set where a texel is not wholly inside. */
static void paint(sl_image *img, const double d[3], const double u[3], const double v[3],
                  bool *edge)
{
    const int S = 8;
    for (int y = 0; y < img->height; y++)
        for (int x = 0; x < img->width; x++) {
            double acc = 0;
            int in = 0;
            for (int j = 0; j < S; j++)
                for (int i = 0; i < S; i++) {
                    double p[3];
                    sl_latlong_to_dir((x + (i + 0.5) / S) / img->width,
                                      (y + (j + 0.5) / S) / img->height, p);
                    double z = sc_dot(p, d);
                    if (z <= 0)
                        continue;
                    double X = sc_dot(p, u) / z / A, Y = sc_dot(p, v) / z / B;
                    if (fabs(X) <= 1 && fabs(Y) <= 1) {
                        acc += shade(X, Y);
                        in++;
                    }
                }
            edge[(size_t)y * img->width + x] = in > 0 && in < S * S;
            if (!in)
                continue;
            /* the background stays under uncovered sub-texels */
            float *px = sl_image_pixel(img, x, y);
            for (int k = 0; k < 3; k++)
                px[k] = (float)(px[k] * (S * S - in) / (S * S) + TINT[k] * acc / (S * S));
        }
}

int main(void)
{
    const int w = 256, h = 128;
    sl_image env;
    CHECK_OK(sl_image_alloc(&env, w, h, 3, NULL), NULL);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++)
            for (int k = 0; k < 3; k++)
                sl_image_pixel(&env, x, y)[k] = 0.05f;
    /* rolled, off the axes, so that a swap or a flip of either side shows */
    double d[3], u[3], v[3];
    sc_frame(25, 40, 0.3 * 180 / M_PI, d, u, v);
    bool *edge = calloc((size_t)w * h, sizeof *edge);
    CHECK(edge != NULL);
    paint(&env, d, u, v, edge);

    sl_rig_options opt;
    sl_rig_options_default(&opt);
    sl_rig rig;
    sl_error err = {0};
    CHECK_OK(sl_rig_extract(&env, &opt, &rig, &err), &err);
    CHECK(rig.light_count == 1);
    CHECK(rig.light_count >= 1 && rig.lights[0].shape == SL_RIG_RECT);
    CHECK_OK(sl_exr_write(sl_test_path("tex_residual.exr"), &rig.residual, NULL,
                          SL_PIXEL_FLOAT, &err), &err);
    CHECK_OK(sl_rig_write_textures(&rig, &env, sl_test_path("tex"), &err), &err);
    const char *json = sl_test_path("tex.json");
    CHECK_OK(sl_rig_write_json(&rig, json, "tex_residual.exr", &err), &err);

    sl_scene s;
    sl_scene_init(&s);
    CHECK_OK(sl_scene_read_rig(&s, json, &err), &err);
    CHECK(s.light_count == 1 && s.lights[0].type == SL_LIGHT_RECT && s.lights[0].texture.data);
    /* Per texel: the rig's light along the texel's centre against the map
     * less the residual there (inner texels: the texture resamples the map's
     * nearest texel). The ratio must be one number for every texel and
     * channel: a flipped or swapped side moves the bright corner, a colour
     * counted twice splits the channels. It is a little above 1: the rim's
     * partly covered texels leave some of the region's power outside the
     * rectangle, and the texture's mean keeps the power. */
    int n = 0, missed = 0;
    double *ratio = malloc((size_t)w * h * 3 * sizeof *ratio);
    CHECK(ratio != NULL);
    for (int y = 0; y < h && ratio && s.light_count == 1; y++)
        for (int x = 0; x < w; x++) {
            size_t i = (size_t)y * w + x;
            if (rig.labels[i] != 1 || edge[i])
                continue;
            bool near_edge = false;
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    int yy = y + dy, xx = (x + dx + w) % w;
                    if (yy >= 0 && yy < h && (edge[(size_t)yy * w + xx] ||
                                              rig.labels[(size_t)yy * w + xx] != 1))
                        near_edge = true;
                }
            if (near_edge)
                continue;
            double c[3], o[3] = {0, 0, 0}, t, L[3];
            sl_latlong_to_dir((x + 0.5) / w, (y + 0.5) / h, c);
            if (!sl_light_intersect(&s.lights[0], o, c, INFINITY, &t, L)) {
                missed++;
                continue;
            }
            const float *m = sl_image_pixel(&env, x, y), *r = sl_image_pixel(&rig.residual, x, y);
            for (int k = 0; k < 3; k++)
                ratio[3 * n + k] = L[k] / (m[k] - r[k]);
            n++;
        }
    double mean = 0, worst = 0;
    for (int i = 0; i < 3 * n; i++)
        mean += ratio[i] / (3 * n);
    for (int i = 0; i < 3 * n; i++)
        worst = fmax(worst, fabs(ratio[i] / mean - 1));
    printf("  %d inner texels, %d missed; rig / map %.4f, worst texel off that by %.4f\n", n,
           missed, mean, worst);
    CHECK(n > 400);
    CHECK(missed == 0);
    /* measured 1.039 and 0.016 (the colour counted twice: 1.508 / 1.053 /
     * 0.598 for red, green and blue) */
    CHECK_MSG(mean >= 1 && mean < 1.06, "rig / map %.4f", mean);
    CHECK_MSG(worst < 0.025, "worst %.4f", worst);
    free(ratio);
    sl_scene_free(&s);

    /* The spheres: what the texture is for. */
    /* measured 1.6% and 3.0% (before the fix 26% and 34%; the rim's power
     * spread over the whole rectangle is most of what is left) */
    const double bound[2] = {0.025, 0.045};
    for (int g = 0; g < 2; g++) {
        sl_image ref, a;
        sc_render_sphere(&env, NULL, g, 16, 256, &ref);
        sc_render_sphere(NULL, json, g, 16, 256, &a);
        double e = 1;
        CHECK_OK(sl_relative_rmse(&a, &ref, &e, NULL), NULL);
        printf("  %s: relative RMSE textured rig %.4f\n", g ? "glossy GGX 0.3" : "grey", e);
        CHECK_MSG(e <= bound[g], "%s %.4f > %.2f", g ? "glossy" : "grey", e, bound[g]);
        sl_image_free(&ref);
        sl_image_free(&a);
    }
    sl_rig_free(&rig);
    free(edge);
    sl_image_free(&env);
    return sl_test_finish();
}
