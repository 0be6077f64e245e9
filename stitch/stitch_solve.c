/* SPDX-License-Identifier: BSD-3-Clause */
/* The solve of a fisheye stitch: the views' poses and their shared lens
 * from the overlaps (docs/stitch.md, "Solve"). */
#include "setlight/stitch.h"

#include <stdlib.h>
#include <string.h>

void sl_stitch_solve_options_init(sl_stitch_solve_options *o)
{
    memset(o, 0, sizeof *o);
    o->solve_poses = true;
    o->solve_focal = true;
    o->solve_centre = true;
    o->radial_terms = 1;
    o->solve_vignette = true;
    o->detector = "sift";
    o->feature_width = 1536;
    o->max_features = 6000;
    o->circle_margin = 0.02;
    o->ratio = 0.8;
    o->ransac_deg = 0.5;
    o->ransac_iterations = 2000;
    o->min_inliers = 25;
    o->max_correction_deg = 10.0;
    o->seed = 1;
}

const char *sl_stitch_pair_status_name(sl_stitch_pair_status s)
{
    switch (s) {
    case SL_STITCH_PAIR_SOLVED:
        return "solved";
    case SL_STITCH_PAIR_NO_OVERLAP:
        return "no overlap";
    case SL_STITCH_PAIR_FEW_MATCHES:
        return "too few matches";
    case SL_STITCH_PAIR_INCONSISTENT:
        return "inconsistent with the nominal poses";
    }
    return "unknown";
}

void sl_stitch_solve_result_free(sl_stitch_solve_result *res)
{
    if (!res)
        return;
    free(res->pose_nominal);
    free(res->pose);
    free(res->gain);
    free(res->features);
    free(res->pair);
    memset(res, 0, sizeof *res);
}

sl_result sl_stitch_solve(sl_stitch_view *views, int count, const sl_stitch_solve_options *opt,
                          sl_stitch_solve_result *res, sl_error *err)
{
    (void)views;
    (void)count;
    (void)opt;
    memset(res, 0, sizeof *res);
    return sl_error_set(err, SL_ERR_UNSUPPORTED, "stitch solve: not implemented yet");
}
