/* SPDX-License-Identifier: BSD-3-Clause */
/* The scene options `render` and `converge` share: --width, --view,
 * --background, --bounces, --seed, and the --reference image (private to
 * tools/). */
#ifndef SETLIGHT_RENDER_OPTS_H
#define SETLIGHT_RENDER_OPTS_H

#include "cli.h"
#include "setlight/render.h"

/* The options in this order; a command's getopt codes for them are
 * consecutive, so `code - first` is the kind. */
enum { RENDER_OPT_WIDTH, RENDER_OPT_VIEW, RENDER_OPT_BACKGROUND, RENDER_OPT_BOUNCES,
       RENDER_OPT_SEED, RENDER_OPT_COUNT };

typedef struct render_opts {
    int width, bounces, seed;
    double az, el;
    bool view, background_env;
} render_opts;

void render_opts_init(render_opts *ro, int width);
/* One option (kind RENDER_OPT_*, its value); 0, or the usage error's exit
 * code after printing it. */
int render_opts_parse(const sl_cli *cli, render_opts *ro, int kind, const char *arg);
/* Turns the preset's validation camera (--view) and sets the background. */
void render_opts_apply(const render_opts *ro, sl_scene *scene);
/* Reads the reference image, which must be RGB at the render's size
 * (SL_ERR_INPUT naming the file otherwise). */
sl_result render_opts_read_reference(const char *path, const sl_scene *scene, sl_image *ref,
                                     sl_error *err);

#endif
