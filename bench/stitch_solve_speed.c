/* SPDX-License-Identifier: BSD-3-Clause */
/* The stitch's solve alone on views of a given size: the virtual set's
 * scene seen through its true fisheye (sl_vset_fisheye_true) from its
 * seeded head (sl_vset_head_pose), yaws 0/120/240, solved from the
 * nominal lens and the plan. Prints the wall and CPU time of the solve,
 * its stages, the reprojection error and the solved lens against the truth.
 *
 * With `blend`, then the blend of the solved views streamed (a strip at a
 * time, nothing kept) to an OUT_WIDTH lat-long (default 8192): its wall and
 * CPU time and the program's peak memory.
 *
 * With `write DIR`, the three views are written to DIR/view0.exr ...
 * (half, as merge writes them) and nothing is solved: the input of a timed
 * `setlight stitch --focal-mm 8 --sensor-mm 36,24` (docs/stitch.md, "Speed").
 *
 *   ./build/bench/bench_stitch_solve [WIDTH HEIGHT [SCENE [blend [OUT_WIDTH] | write DIR]]]
 *   (6000 4000 stage)
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

#include "setlight/vset.h"
#include "setlight/stitch.h"

/* The blend's rows go nowhere: only its time and memory are measured. */
static sl_result discard_rows(void *user, const float *rows, int y0, int count, size_t stride,
                              sl_error *err)
{
    (void)user, (void)rows, (void)y0, (void)count, (void)stride, (void)err;
    return SL_OK;
}

int main(int argc, char **argv)
{
    int width = argc > 2 ? atoi(argv[1]) : 6000, height = argc > 2 ? atoi(argv[2]) : 4000;
    const char *scene_name = argc > 3 ? argv[3] : "stage";
    sl_error err;
    sl_vset_desc desc;
    sl_vset_scene scene;
    if (sl_vset_preset(scene_name, &desc, &err) || sl_vset_scene_make(&desc, 2048, &scene, &err)) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    sl_lens truth, nominal;
    sl_vset_fisheye_true(&truth, width, height);
    sl_vset_fisheye_nominal(&nominal, width, height);
    nominal.circle_radius_px = truth.circle_radius_px; /* as the circle detection finds it */
    static const sl_view_pose plan[3] = {{0, 0, 0}, {120, 0, 0}, {240, 0, 0}};
    sl_image img[3] = {{0}};
    sl_stitch_view views[3];
    for (int i = 0; i < 3; i++) {
        sl_view_pose pose;
        sl_vset_head_pose(7, i, &plan[i], &pose);
        if (sl_vset_view_image(&truth, &pose, &scene.latlong, 1, &img[i], &err)) {
            fprintf(stderr, "%s\n", err.message);
            return 1;
        }
        views[i] = (sl_stitch_view){.name = "view", .radiance = &img[i], .lens = nominal,
                                    .pose = plan[i]};
    }
    if (argc > 5 && !strcmp(argv[4], "write")) {
        for (int i = 0; i < 3; i++) {
            char path[4096];
            snprintf(path, sizeof path, "%s/view%d.exr", argv[5], i);
            if (sl_exr_write(path, &img[i], NULL, SL_PIXEL_HALF, &err)) {
                fprintf(stderr, "%s\n", err.message);
                return 1;
            }
            sl_image_free(&img[i]);
        }
        sl_vset_scene_free(&scene);
        return 0;
    }
    sl_stitch_solve_result res;
    sl_stitch_solve_options opt;
    sl_stitch_solve_options_init(&opt);
    /* "features": without the radiance steps (the lens refined, views placed) */
    opt.radiance_lens = opt.radiance_poses = !(argc > 4 && !strcmp(argv[4], "features"));
    double wall = sl_seconds(), cpu = sl_cpu_seconds();
    sl_result r = sl_stitch_solve(views, 3, &opt, &res, &err);
    wall = sl_seconds() - wall;
    cpu = sl_cpu_seconds() - cpu;
    if (r != SL_OK) {
        fprintf(stderr, "%s\n", err.message);
        return 1;
    }
    printf("%s, 3 views of %dx%d: %.2f s wall, %.2f s CPU (features %.2f, matching %.2f, "
           "adjustment %.2f, radiance %.2f s wall)\n",
           scene_name, width, height, wall, cpu, res.seconds_features, res.seconds_match,
           res.seconds_adjust, res.seconds_radiance);
    printf("pairs solved %d of %d, %d inliers, reprojection rms %.3f px, max %.2f px\n",
           res.pairs_solved, res.pairs, res.inliers, res.rms_px, res.max_px);
    printf("focal %+.3f%% of the truth, centre %.2f px off, k1 %.4f (true %.4f), k2 %.4f (true "
           "%.4f)\n",
           100.0 * (res.lens.focal_px / truth.focal_px - 1.0),
           hypot(res.lens.cx - truth.cx, res.lens.cy - truth.cy), res.lens.k[0], truth.k[0],
           res.lens.k[1], truth.k[1]);
    if (argc > 4 && !strcmp(argv[4], "blend")) {
        sl_stitch_blend_options bo;
        sl_stitch_blend_options_init(&bo);
        bo.width = argc > 5 ? atoi(argv[5]) : 8192;
        sl_stitch_coverage cov;
        wall = sl_seconds(), cpu = sl_cpu_seconds();
        r = sl_stitch_blend_stream(views, 3, &bo, discard_rows, NULL, &cov, &err);
        wall = sl_seconds() - wall;
        cpu = sl_cpu_seconds() - cpu;
        if (r != SL_OK) {
            fprintf(stderr, "%s\n", err.message);
            return 1;
        }
        struct rusage ru;
        getrusage(RUSAGE_SELF, &ru);
        printf("blend to %dx%d (%d samples per texel side, %d on edges, %lld such texels): "
               "%.2f s wall, %.2f s CPU; peak memory of the program %.0f MB\n",
               cov.width, cov.height, cov.supersample, cov.supersample_hot,
               (long long)cov.hot_texels, wall, cpu, ru.ru_maxrss / 1024.0);
    }
    sl_stitch_solve_result_free(&res);
    for (int i = 0; i < 3; i++)
        sl_image_free(&img[i]);
    sl_vset_scene_free(&scene);
    return 0;
}
