/* SPDX-License-Identifier: BSD-3-Clause */
#include "ball_camera_opts.h"

#include <string.h>

#include "setlight/stitch.h"

int ball_camera_opts_parse(const sl_cli *cli, ball_camera_opts *bc, int kind, const char *arg)
{
    static const char *const names[BALL_OPT_COUNT] = {
        "--camera", "--focal-mm", "--sensor-mm", "--fov", "--distance", "--ball-diameter"};
    if (kind == BALL_OPT_CAMERA) {
        if (!strcmp(arg, "ortho") || !strcmp(arg, "orthographic"))
            bc->camera = SL_BALL_ORTHOGRAPHIC;
        else if (!strcmp(arg, "perspective"))
            bc->camera = SL_BALL_PERSPECTIVE;
        else
            return cli_usage_error(cli, "--camera is ortho or perspective, not '%s'", arg);
        return 0;
    }
    double v;
    if (!cli_parse_double(arg, &v) || !(v > 0) || (kind == BALL_OPT_FOV && !(v < 180)))
        return cli_usage_error(cli, "%s needs a positive number%s, not '%s'", names[kind],
                               kind == BALL_OPT_FOV ? " of degrees below 180" : "", arg);
    *(kind == BALL_OPT_FOCAL    ? &bc->focal_mm
      : kind == BALL_OPT_SENSOR ? &bc->sensor_mm
      : kind == BALL_OPT_FOV    ? &bc->fov_deg
      : kind == BALL_OPT_DIST   ? &bc->distance_mm
                                : &bc->diameter_mm) = v;
    return 0;
}

int ball_camera_opts_check(const sl_cli *cli, const ball_camera_opts *bc)
{
    if ((bc->distance_mm > 0) != (bc->diameter_mm > 0))
        return cli_usage_error(cli, "--distance and --ball-diameter go together");
    if (bc->distance_mm > 0 && !(bc->distance_mm > 0.5 * bc->diameter_mm))
        return cli_usage_error(cli, "--distance %g mm puts the camera inside a %g mm ball",
                               bc->distance_mm, bc->diameter_mm);
    if (bc->focal_mm > 0 && bc->fov_deg > 0)
        return cli_usage_error(cli, "give --focal-mm or --fov, not both");
    if (bc->focal_mm > 0 && bc->sensor_mm == 0)
        return cli_usage_error(cli, "--focal-mm needs --sensor-mm (the sensor width)");
    return 0;
}
