/* SPDX-License-Identifier: BSD-3-Clause */
/* The camera of a ball photo as `unwrap` and `calibrate` take it on the
 * command line: --camera, --focal-mm, --sensor-mm, --fov, --distance,
 * --ball-diameter (private to tools/). */
#ifndef SETLIGHT_BALL_CAMERA_OPTS_H
#define SETLIGHT_BALL_CAMERA_OPTS_H

#include "cli.h"
#include "setlight/stitch.h"

/* The options in this order; a command's getopt codes for them are
 * consecutive, so `code - first` is the kind. */
enum { BALL_OPT_CAMERA, BALL_OPT_FOCAL, BALL_OPT_SENSOR, BALL_OPT_FOV, BALL_OPT_DIST,
       BALL_OPT_DIAM, BALL_OPT_COUNT };

typedef sl_ball_lens ball_camera_opts;

/* One option (kind BALL_OPT_*, its value); 0, or the usage error's exit
 * code after printing it. */
int ball_camera_opts_parse(const sl_cli *cli, ball_camera_opts *bc, int kind, const char *arg);
/* The options together (distance with diameter, focal length or field of
 * view, focal length with sensor width); 0 or the usage error's exit code. */
int ball_camera_opts_check(const sl_cli *cli, const ball_camera_opts *bc);

#endif
