/* SPDX-License-Identifier: BSD-3-Clause */
/* The render stage from files to files: a preset or scene file lit by an
 * environment or a rig, rendered to an EXR with its provenance and the
 * per-pass statistics, replaced together. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "setlight/render.h"

void sl_render_run_options_init(sl_render_run_options *o)
{
    memset(o, 0, sizeof *o);
    o->scene = "grey";
    o->width = 512;
    o->intensity = 1;
    sl_render_options_init(&o->render);
}

void sl_render_run_result_free(sl_render_run_result *res)
{
    sl_render_stats_free(&res->stats);
    free(res->json);
    res->json = NULL;
}

sl_result sl_render_read_reference(const char *path, const sl_scene *scene, sl_image *ref,
                                   sl_error *err)
{
    sl_result r = sl_image_read_linear(path, NULL, ref, NULL, NULL, err);
    if (r)
        return r;
    if (ref->width != scene->camera.width || ref->height != scene->camera.height ||
        ref->channels < 3)
        return sl_error_set(err, SL_ERR_INPUT, "%s: reference is %dx%d, the render %dx%d (RGB needed)",
                            path, ref->width, ref->height, scene->camera.width,
                            scene->camera.height);
    return SL_OK;
}

sl_result sl_render_run(const sl_render_run_options *ro, sl_render_run_result *res,
                        sl_error *err_out)
{
    memset(res, 0, sizeof *res);
    if (!ro->env_path == !ro->rig_path || !ro->out_path)
        return sl_error_set(err_out, SL_ERR_USAGE,
                            "render needs exactly one of an environment and a rig, and an output");
    sl_error err = {0};
    sl_scene scene;
    sl_image ref = {0}, img = {0};
    sl_render_options o = ro->render;
    sl_scene_init(&scene);
    sl_result r;
    if ((r = sl_scene_load(&scene, ro->scene, ro->width, ro->env_path, ro->input_colorspace,
                           ro->rotate_deg, ro->intensity, ro->rig_path, &err)))
        goto fail;
    if (ro->view) {
        if (sl_scene_arg_is_file(ro->scene)) {
            r = sl_error_set(&err, SL_ERR_USAGE, "--view turns a preset's validation camera; "
                                                 "scene files set their own camera");
            goto fail;
        }
        sl_camera *cam = &scene.camera;
        sl_camera_validation(cam, cam->width, cam->height, cam->ortho_width, ro->view_az,
                             ro->view_el);
    }
    if (ro->background_env)
        scene.background_env = true;
    if (ro->material) {
        int idx;
        if ((r = sl_scene_add_material(&scene, ro->material, &idx, &err)))
            goto fail;
        for (int i = 0; i < scene.shape_count; i++)
            scene.shapes[i].material = idx;
    }
    const char *light_src = ro->env_path ? ro->env_path : ro->rig_path;
    res->dome_bad_texels = scene.dome.bad_texels;
    if (scene.dome.bad_texels)
        sl_log(SL_LOG_WARN, "%s: %lld NaN, Inf or negative samples set to 0", light_src,
               (long long)scene.dome.bad_texels);
    if (ro->reference_path) {
        if ((r = sl_render_read_reference(ro->reference_path, &scene, &ref, &err)))
            goto fail;
        o.reference = &ref;
    }
    if ((r = sl_render(&scene, &o, &img, &res->stats, &err)))
        goto fail;
    const sl_render_stats *st = &res->stats;
    const sl_render_pass *last = st->pass_count ? &st->passes[st->pass_count - 1] : NULL;
    res->width = img.width;
    res->height = img.height;
    res->est_rel_rmse = last ? last->est_rel_rmse : 0.0;
    res->ref_rel_rmse = last ? last->ref_rel_rmse : -1.0;
    sl_meta meta;
    sl_meta_init(&meta);
    char buf[256];
    snprintf(buf, sizeof buf, "scene=%s %s=%s rotate=%g intensity=%g spp=%lld strategy=%s",
             scene.name, ro->env_path ? "env" : "rig", light_src, ro->rotate_deg, ro->intensity,
             (long long)st->spp, sl_strategy_name(o.strategy));
    sl_meta_set(&meta, "setlight:render", buf, NULL);
    snprintf(buf, sizeof buf, "%.6g", res->est_rel_rmse);
    sl_meta_set(&meta, "setlight:estimated_rel_rmse", buf, NULL);
    /* The image and its statistics are one set: both new or both as before. */
    const char *members[2] = {ro->out_path, ro->stats_path};
    if (!(r = sl_output_set_begin(members, 2, &err)) &&
        !(r = sl_exr_write(ro->out_path, &img, &meta, SL_PIXEL_FLOAT, &err)) &&
        !(r = ro->stats_path ? sl_render_stats_write_json(st, &o, ro->stats_path, &err) : SL_OK))
        r = sl_output_set_commit(&err);
    sl_meta_free(&meta);
    if (r)
        goto fail;
    const sl_closed_form_stats *cf = &st->closed_form;
    int64_t glossy_px = 0;
    double glossy_err = 0;
    for (int i = 0; i < cf->object_count; i++)
        if (cf->object_material[i] != SL_MAT_LAMBERT) {
            glossy_px += cf->object_exact[i] + cf->object_control[i];
            glossy_err = fmax(glossy_err, cf->object_max_rel_bound[i]);
        }
    size_t n = strlen(ro->out_path) + strlen(st->stop_reason) + 1024;
    if ((res->json = malloc(n)))
        snprintf(res->json, n,
                 "{\"output\": \"%s\", \"spp\": %lld, \"seconds\": %.6g, \"est_rel_rmse\": %.6g, "
                 "\"ref_rel_rmse\": %.6g, \"stop_reason\": \"%s\", \"dome_bad_texels\": %lld, "
                 "\"closed_form\": {\"used\": %s, \"exact_pixels\": %lld, "
                 "\"control_variate_pixels\": %lld, \"sampled_pixels\": %lld, "
                 "\"max_rel_bound\": %.6g, \"tolerance\": %.6g, \"finest_level\": %d, "
                 "\"glossy_pixels\": %lld, \"glossy_max_rel_error\": %.6g, "
                 "\"interpolated_pixels\": %lld, \"lights_exact\": %d, \"lights_sampled\": %d, "
                 "\"cut_by_time\": %s, \"cut_pixels\": %lld, \"seconds\": %.6g}}",
                 ro->out_path, (long long)st->spp, st->seconds, res->est_rel_rmse,
                 res->ref_rel_rmse, st->stop_reason, (long long)scene.dome.bad_texels,
                 cf->used ? "true" : "false", (long long)cf->exact_pixels,
                 (long long)cf->control_variate_pixels, (long long)cf->sampled_pixels,
                 cf->max_rel_bound, cf->tolerance, cf->finest_level, (long long)glossy_px,
                 glossy_err, (long long)cf->interpolated_pixels, cf->lights_exact,
                 cf->lights_sampled, cf->cut_by_time ? "true" : "false", (long long)cf->cut_pixels,
                 cf->seconds);
    else
        r = sl_error_set(&err, SL_ERR_NOMEM, "%s: out of memory", ro->out_path);
fail:
    if (r)
        sl_output_set_abort();
    sl_image_free(&img);
    sl_image_free(&ref);
    sl_scene_free(&scene);
    if (r && err_out)
        *err_out = err;
    return r;
}
