/* SPDX-License-Identifier: BSD-3-Clause */
#include "render_opts.h"

#include <string.h>

void render_opts_init(render_opts *ro, int width)
{
    memset(ro, 0, sizeof *ro);
    ro->width = width;
    ro->seed = 1;
}

int render_opts_parse(const sl_cli *cli, render_opts *ro, int kind, const char *arg)
{
    switch (kind) {
    case RENDER_OPT_WIDTH:
        if (!cli_parse_int(arg, &ro->width) || ro->width < 1 || ro->width > 65536)
            return cli_usage_error(cli, "--width needs a whole number from 1 to 65536");
        return 0;
    case RENDER_OPT_VIEW:
        if (!cli_parse_view(arg, &ro->az, &ro->el))
            return cli_usage_error(cli, "--view needs AZ,EL in degrees (|EL| <= 90)");
        ro->view = true;
        return 0;
    case RENDER_OPT_BACKGROUND:
        if (strcmp(arg, "env") && strcmp(arg, "black"))
            return cli_usage_error(cli, "--background is env or black");
        ro->background_env = !strcmp(arg, "env");
        return 0;
    case RENDER_OPT_BOUNCES:
        if (!cli_parse_int(arg, &ro->bounces) || ro->bounces < 0 || ro->bounces > 64)
            return cli_usage_error(cli, "--bounces needs a whole number from 0 to 64");
        return 0;
    default:
        if (!cli_parse_int(arg, &ro->seed) || ro->seed < 0)
            return cli_usage_error(cli, "--seed needs a whole number >= 0");
        return 0;
    }
}

void render_opts_apply(const render_opts *ro, sl_scene *scene)
{
    if (ro->view) {
        sl_camera *cam = &scene->camera;
        sl_camera_validation(cam, cam->width, cam->height, cam->ortho_width, ro->az, ro->el);
    }
    if (ro->background_env)
        scene->background_env = true;
}

sl_result render_opts_read_reference(const char *path, const sl_scene *scene, sl_image *ref,
                                     sl_error *err)
{
    return sl_render_read_reference(path, scene, ref, err);
}
